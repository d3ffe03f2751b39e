//! Protected mode (docs/protocol.md, docs/reliability.md): without a token `mimic serve` listens
//! on loopback only; with one every hello must present it, and UDP frames are taken only with
//! the session's key from the tracker's address.

use crate::loopback::{
    Serve, connect, connect_from, frame_lines, header_with_session, read_json_line, read_message,
};
use crate::{mimic, repo, text};
use mimic_stream::wire::ViewerMessage;
use serde_json::Value;
use std::io::{BufReader, Write};
use std::net::{Shutdown, UdpSocket};
use std::process::Command;

/// `mimic ARGS` without MIMIC_TOKEN in its environment.
fn mimic_no_env_token(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_mimic"))
        .args(args)
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .env_remove("MIMIC_TOKEN")
        .output()
        .unwrap()
}

#[test]
fn serve_refuses_a_non_loopback_address_without_a_token() {
    for extra in [
        &["--listen", "0.0.0.0:0"][..],
        &["--listen", "127.0.0.1:0", "--udp", "0.0.0.0:0"][..],
    ] {
        let mut args = vec!["serve", "--rig", "candide3"];
        args.extend_from_slice(extra);
        let out = mimic_no_env_token(&args);
        let (_, err) = text(&out);
        assert!(!out.status.success(), "{args:?} started: {err}");
        assert!(
            err.contains("--token") && err.contains("0.0.0.0:0"),
            "{args:?}: {err}"
        );
        let what = if extra.len() == 2 { "TCP" } else { "UDP" };
        assert!(err.contains(what), "{args:?}: {err}");
    }
}

#[test]
fn with_a_token_every_hello_must_present_it() {
    let token = "s3cret-token";
    let server = Serve::start(&["--rig", "candide3", "--token", token]);
    let rec = "recordings/openface_test.jsonl";
    // A tracker without the token: one error line, then closed; no session.
    let mut t = connect(&server.tcp);
    t.write_all(header_with_session(rec, "a").as_bytes())
        .unwrap();
    let reply = read_json_line(&mut BufReader::new(t));
    assert_eq!(reply["code"], "bad_token", "{reply}");
    assert!(reply["message"].as_str().unwrap().contains("--token"));
    // A wrong token and a stats request without one: the same.
    let mut wrong: Value = serde_json::from_str(&header_with_session(rec, "a")).unwrap();
    wrong["token"] = Value::from("s3cret-tokeN");
    let mut t = connect(&server.tcp);
    t.write_all(format!("{wrong}\n").as_bytes()).unwrap();
    assert_eq!(read_json_line(&mut BufReader::new(t))["code"], "bad_token");
    let mut st = connect(&server.tcp);
    st.write_all(b"{\"type\":\"stats\"}\n").unwrap();
    assert_eq!(read_json_line(&mut BufReader::new(st))["code"], "bad_token");
    // A viewer without it gets an ERROR message.
    let mut v = crate::loopback::viewer(&server.tcp, "a", false);
    match read_message(&mut v) {
        Some(ViewerMessage::Error(e)) => assert_eq!(e["code"], "bad_token", "{e}"),
        other => panic!("expected bad_token, got {other:?}"),
    }
    let s = server.stats();
    assert_eq!(s["refused"], 4, "{s}");
    assert_eq!(s["sessions"].as_array().unwrap().len(), 0, "{s}");
    // `mimic send --token` and MIMIC_TOKEN open sessions.
    let out = mimic_no_env_token(&[
        "send",
        rec,
        "--to",
        &server.tcp,
        "--session",
        "b",
        "--fast",
        "--token",
        token,
    ]);
    assert!(out.status.success(), "{}", text(&out).1);
    let out = Command::new(env!("CARGO_BIN_EXE_mimic"))
        .args(["send", rec, "--to", &server.tcp, "--session", "c", "--fast"])
        .current_dir(repo())
        .env("MIMIC_TOKEN", token)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out).1);
    let out = mimic_no_env_token(&["send", rec, "--to", &server.tcp, "--session", "d"]);
    assert!(!out.status.success());
    for name in ["b", "c"] {
        server.wait_for_session(name, "all frames", |s| s["frames"] == 100);
    }
    server.stop();
    // Without a token on the server, a hello's token is ignored (old clients and new agree).
    let open = Serve::start(&["--rig", "candide3"]);
    let out = mimic(&[
        "send",
        rec,
        "--to",
        &open.tcp,
        "--session",
        "e",
        "--fast",
        "--token",
        "any",
    ]);
    assert!(out.status.success(), "{}", text(&out).1);
    open.wait_for_session("e", "all frames", |s| s["frames"] == 100);
    open.stop();
}

#[test]
fn udp_frames_with_the_wrong_key_or_from_another_address_are_counted_and_dropped() {
    let token = "udp-token";
    let server = Serve::start(&["--rig", "candide3", "--token", token]);
    let rec = "recordings/openface_test.jsonl";
    let mut header: Value = serde_json::from_str(&header_with_session(rec, "u")).unwrap();
    header["token"] = Value::from(token);
    let mut t = connect(&server.tcp);
    t.write_all(format!("{header}\n").as_bytes()).unwrap();
    let lines = frame_lines(rec);
    for l in &lines[..10] {
        t.write_all(l.as_bytes()).unwrap();
    }
    let welcome = read_json_line(&mut BufReader::new(t.try_clone().unwrap()));
    let id = welcome["session_id"].as_u64().unwrap() as u32;
    let key = welcome["udp_key"].as_u64().unwrap() as u32;
    server.wait_for_session("u", "10 TCP frames", |s| s["frames"] == 10);
    let frames: Vec<_> = mimic_capture::RecordingReader::open(&repo().join(rec), None)
        .unwrap()
        .map(|f| f.unwrap().frame)
        .collect();
    let packet = |k: usize, key: u32| mimic_stream::wire::encode_udp_frame(id, key, &frames[k]);
    let counts = |s: &Value| {
        (
            Serve::session(s, "u", 0)["udp_frames"].as_u64().unwrap(),
            s["udp_wrong_key"].as_u64().unwrap(),
            s["udp_wrong_source"].as_u64().unwrap(),
        )
    };
    let good = UdpSocket::bind("127.0.0.1:0").unwrap();
    // The wrong key, from the tracker's address.
    good.send_to(&packet(10, key ^ 0x8000_0000), &server.udp)
        .unwrap();
    server.wait_for("the wrong key", |s| counts(s) == (0, 1, 0));
    // The right key from another loopback address than the tracker's hello came from.
    let other = UdpSocket::bind("127.0.0.2:0").unwrap();
    other.send_to(&packet(10, key), &server.udp).unwrap();
    server.wait_for("the wrong address", |s| counts(s) == (0, 1, 1));
    // The right key from the tracker's address: taken, and its port pinned from then on.
    good.send_to(&packet(10, key), &server.udp).unwrap();
    server.wait_for("the good packet", |s| counts(s) == (1, 1, 1));
    let second_port = UdpSocket::bind("127.0.0.1:0").unwrap();
    second_port.send_to(&packet(11, key), &server.udp).unwrap();
    server.wait_for("another port", |s| counts(s) == (1, 1, 2));
    good.send_to(&packet(11, key), &server.udp).unwrap();
    let s = server.wait_for("the next good packet", |s| counts(s) == (2, 1, 2));
    assert_eq!(s["udp_bad_packets"], 3, "{s}");
    assert_eq!(Serve::session(&s, "u", 0)["frames"], 12);
    // A TCP tracker from 127.0.0.2 with the token is a session of its own (its hello's address).
    let mut t2 = connect_from("127.0.0.2", &server.tcp);
    let mut h2: Value = serde_json::from_str(&header_with_session(rec, "u2")).unwrap();
    h2["token"] = Value::from(token);
    t2.write_all(format!("{h2}\n").as_bytes()).unwrap();
    let w2 = read_json_line(&mut BufReader::new(t2.try_clone().unwrap()));
    assert_eq!(w2["type"], "welcome", "{w2}");
    t2.shutdown(Shutdown::Write).unwrap();
    t.shutdown(Shutdown::Write).unwrap();
    server.stop();
}

/// `mimic view --connect` on a server with a token: refused without it, follows the session
/// with it (here from MIMIC_TOKEN). Needs the renderer, like tests/integration/view.rs.
#[test]
fn view_presents_the_token() {
    if std::env::var_os("MIMIC_SKIP_GPU_TESTS").is_some() {
        eprintln!("MIMIC_SKIP_GPU_TESTS is set: skipping a GPU test");
        return;
    }
    let token = "view-token";
    let server = Serve::start(&["--rig", "candide3", "--token", token]);
    let view = |env_token: Option<&str>| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_mimic"));
        c.args([
            "view",
            "--connect",
            &server.tcp,
            "--session",
            "live",
            "--size",
            "64x64",
            "--headless-frames",
            "5",
            "--headless-timeout",
            "60",
        ])
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .env_remove("MIMIC_TOKEN")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped());
        if let Some(t) = env_token {
            c.env("MIMIC_TOKEN", t);
        }
        c.spawn().unwrap()
    };
    let refused = view(None).wait_with_output().unwrap();
    let (out, err) = text(&refused);
    assert!(
        !refused.status.success() || !out.contains("5 new frames"),
        "{out}{err}"
    );
    assert!(format!("{out}{err}").contains("bad_token"), "{out}{err}");
    let follows = view(Some(token));
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let sent = mimic_no_env_token(&[
        "send",
        "recordings/openface_test.jsonl",
        "--to",
        &server.tcp,
        "--session",
        "live",
        "--speed",
        "1",
        "--token",
        token,
    ]);
    assert!(sent.status.success(), "{}", text(&sent).1);
    let o = follows.wait_with_output().unwrap();
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    assert!(stdout.contains("5 new frames"), "{stdout}");
    server.stop();
}
