//! Issue 15: a wild timestamp (first or in the middle) is refused and counted and the session
//! goes on; duration options out of range are refused at parse time; `mimic send` reports the
//! server's `bye` when the server ends the session while it is still sending.

use crate::loopback::{Serve, connect, frame_lines, header_with_session, read_json_line};
use crate::{mimic, text};
use serde_json::Value;
use std::io::{BufReader, Write};
use std::net::Shutdown;

const REC: &str = "recordings/openface_test.jsonl";

/// A frame line of `REC` moved to time `t_us`.
fn retimed(line: &str, t_us: i64) -> String {
    let mut v: Value = serde_json::from_str(line).unwrap();
    v["t_us"] = Value::from(t_us);
    format!("{v}\n")
}

/// Sends `lines` as session `name`, closes the write side and returns the `bye` and the error
/// codes the server answered before it.
fn session(server: &Serve, name: &str, lines: &[String]) -> (Value, Vec<String>) {
    let mut s = connect(&server.tcp);
    s.write_all(header_with_session(REC, name).as_bytes())
        .unwrap();
    let mut replies = BufReader::new(s.try_clone().unwrap());
    let welcome = read_json_line(&mut replies);
    assert_eq!(welcome["type"], "welcome", "{welcome}");
    s.write_all(lines.concat().as_bytes()).unwrap();
    s.shutdown(Shutdown::Write).unwrap();
    let mut codes = Vec::new();
    loop {
        let r = read_json_line(&mut replies);
        if r["type"] == "bye" {
            return (r, codes);
        }
        codes.push(r["code"].as_str().unwrap_or("?").to_string());
    }
}

/// (frames, late, future) of a `bye`.
fn counts(bye: &Value) -> (Option<u64>, Option<u64>, Option<u64>) {
    (
        bye["frames"].as_u64(),
        bye["late"].as_u64(),
        bye["future"].as_u64(),
    )
}

#[test]
fn a_wild_first_frame_is_refused_and_the_next_29_are_taken() {
    let server = Serve::start(&["--rig", "candide3"]);
    let lines = frame_lines(REC);
    for (k, (wild, late)) in [
        (i64::MAX, false),
        (1_000_000_000_000_000_000, false),
        (i64::MIN, true),
    ]
    .into_iter()
    .enumerate()
    {
        let name = format!("wild{k}");
        let mut sent = vec![retimed(&lines[0], wild)];
        sent.extend_from_slice(&lines[..29]);
        let (bye, codes) = session(&server, &name, &sent);
        let (want_late, want_future) = if late { (1, 0) } else { (0, 1) };
        assert_eq!(
            counts(&bye),
            (Some(29), Some(want_late), Some(want_future)),
            "first t_us {wild}: {bye}"
        );
        // Today's replies: `future_timestamp` for a frame from the future, nothing for a late one.
        let want_codes = if late {
            vec![]
        } else {
            vec!["future_timestamp"]
        };
        assert_eq!(codes, want_codes, "first t_us {wild}");
        let s = server.wait_for_session(&name, "the ended session", |s| s["active"] == false);
        assert_eq!(
            (
                s["frames"].as_u64(),
                s["late"].as_u64(),
                s["future"].as_u64()
            ),
            (Some(29), Some(want_late), Some(want_future)),
            "stats after first t_us {wild}: {s}"
        );
    }
    server.stop();
}

#[test]
fn wild_frames_in_the_middle_are_refused_and_the_session_goes_on() {
    let server = Serve::start(&["--rig", "candide3"]);
    let lines = frame_lines(REC);
    let mut sent: Vec<String> = lines[..10].to_vec();
    sent.push(retimed(&lines[10], i64::MAX));
    sent.extend_from_slice(&lines[10..20]);
    sent.push(retimed(&lines[20], i64::MIN));
    sent.extend_from_slice(&lines[20..25]);
    sent.push(retimed(&lines[25], 1_000_000_000_000_000_000));
    sent.extend_from_slice(&lines[25..29]);
    let (bye, codes) = session(&server, "middle", &sent);
    assert_eq!(counts(&bye), (Some(29), Some(1), Some(2)), "{bye}");
    assert_eq!(codes, ["future_timestamp", "future_timestamp"]);
    server.stop();
}

#[test]
fn duration_options_out_of_range_are_refused_naming_the_option() {
    let cases: [(&[&str], &str); 9] = [
        (&["serve", "--idle-timeout", "1e19"], "--idle-timeout"),
        (&["serve", "--shutdown-grace", "1e19"], "--shutdown-grace"),
        (
            &["serve", "--viewer-write-timeout", "1e7"],
            "--viewer-write-timeout",
        ),
        (&["serve", "--max-time-jump=-1"], "--max-time-jump"),
        (&["serve", "--idle-timeout", "nan"], "--idle-timeout"),
        (&["serve", "--lost-hold", "inf"], "--lost-hold"),
        (&["send", REC, "--speed", "1e-300"], "--speed"),
        (&["send", REC, "--speed", "0"], "--speed"),
        (&["send", "--weights", "x.csv", "--rate", "1e300"], "--rate"),
    ];
    for (args, option) in cases {
        let out = mimic(args);
        let (_, stderr) = text(&out);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(stderr.contains(option), "{args:?}: {stderr}");
        assert!(stderr.contains("out of range"), "{args:?}: {stderr}");
    }
}

/// Waits (at most a minute) for a child to exit and returns its output.
fn wait_output(mut child: std::process::Child, what: &str) -> std::process::Output {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if std::time::Instant::now() > deadline {
            let _ = child.kill();
            panic!("{what} did not exit");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

#[test]
fn send_reports_the_servers_bye_when_the_server_shuts_down_mid_send() {
    let server = Serve::start(&["--rig", "candide3"]);
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_mimic"))
        .args(["send", REC, "--loop", "--to", &server.tcp, "--session", "s"])
        .current_dir(crate::repo())
        .env_remove("RUST_LOG")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    server.wait_for_session("s", "frames arriving", |s| {
        s["frames"].as_u64().is_some_and(|f| f >= 3)
    });
    server.stop();
    let out = wait_output(child, "mimic send");
    let (stdout, stderr) = text(&out);
    // Exit status 3 (docs/protocol.md): the server ended the session, its reason reported.
    assert_eq!(out.status.code(), Some(3), "{stdout}\n{stderr}");
    assert!(stderr.contains("(shutdown)"), "{stderr}");
    assert!(!stderr.contains("Broken pipe"), "{stderr}");
    assert!(stdout.contains("(\"shutdown\")"), "{stdout}");
}

#[test]
fn send_stops_reading_a_reply_line_over_64_kib() {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    // A fake server: a 100 KiB line without end, then it reads until `send` is done.
    let fake = mimic_testkit::spawn("fake server", move || {
        let (mut s, _) = listener.accept().unwrap();
        s.write_all(&vec![b'x'; 100 * 1024]).unwrap();
        let mut got = Vec::new();
        std::io::Read::read_to_end(&mut s, &mut got).unwrap();
        got.len()
    });
    let out = mimic(&["send", REC, "--fast", "--max-frames", "5", "--to", &addr]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("over 65536 bytes"), "{stderr}");
    assert!(stdout.contains("sent 5 frames"), "{stdout}");
    assert!(stdout.contains("no reply from the server"), "{stdout}");
    // The header and 5 frames reached the fake server.
    assert!(fake.join().unwrap() > 0);
}
