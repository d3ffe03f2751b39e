//! Memory under churn (docs/reliability.md): 20 000 viewers joining and leaving a live session
//! leave the server's resident memory and its stats reply bounded; ended sessions and departed
//! viewers are kept as a bounded summary with exact totals.

use crate::loopback::{Serve, frame_lines, header_with_session, read_message, viewer};
use mimic_stream::wire::ViewerMessage;
use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::time::Duration;

/// Resident memory of process `pid` in KiB (`VmRSS` of /proc/PID/status).
fn rss_kib(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let line = status.lines().find(|l| l.starts_with("VmRSS:")).unwrap();
    line.split_whitespace().nth(1).unwrap().parse().unwrap()
}

/// The raw stats reply line (its length is what a client has to hold).
fn stats_line(addr: &str) -> String {
    let mut s = crate::loopback::connect(addr);
    s.write_all(b"{\"type\":\"stats\"}\n").unwrap();
    let mut line = String::new();
    BufReader::new(s).read_line(&mut line).unwrap();
    line
}

/// `n` viewers of `session`, one after the other: each joins, reads the SESSION message (so
/// the server has attached it), and leaves with a reset (no TIME_WAIT left on this side).
fn churn(addr: &str, session: &str, n: usize) {
    for _ in 0..n {
        let mut s = viewer(addr, session, false);
        match read_message(&mut s) {
            Some(ViewerMessage::Session(_)) => {}
            other => panic!("expected the session message, got {other:?}"),
        }
        socket2::SockRef::from(&s)
            .set_linger(Some(Duration::ZERO))
            .unwrap();
        drop::<TcpStream>(s);
    }
}

#[test]
fn twenty_thousand_viewer_churns_leave_memory_and_stats_bounded() {
    let server = Serve::start(&["--rig", "candide3", "--idle-timeout", "600"]);
    // A live session to churn on: a tracker that sent its header and a few frames.
    let rec = "recordings/openface_test.jsonl";
    let mut tracker = crate::loopback::connect(&server.tcp);
    tracker
        .write_all(header_with_session(rec, "churn").as_bytes())
        .unwrap();
    for l in &frame_lines(rec)[..10] {
        tracker.write_all(l.as_bytes()).unwrap();
    }
    server.wait_for_session("churn", "10 frames", |s| s["frames"] == 10);
    // Warm-up (allocator arenas, task pools), then the measured churn, 4 clients at once.
    let (warm, threads, per_thread) = (2000, 4, 4500);
    churn(&server.tcp, "churn", warm);
    server.wait_for("the warm-up viewers to leave", |s| s["viewers_active"] == 0);
    let before = rss_kib(server.pid());
    let clients: Vec<_> = (0..threads)
        .map(|k| {
            let addr = server.tcp.clone();
            mimic_testkit::spawn(&format!("churn {k}"), move || {
                churn(&addr, "churn", per_thread)
            })
        })
        .collect();
    for c in clients {
        c.join().unwrap();
    }
    let total = (warm + threads * per_thread) as u64;
    assert_eq!(total, 20_000);
    let s = server.wait_for_session("churn", "every viewer gone", |s| {
        s["viewers_total"] == total
            && s["viewers"]
                .as_array()
                .unwrap()
                .iter()
                .all(|v| v["connected"] == false)
    });
    let after = rss_kib(server.pid());
    let line = stats_line(&server.tcp);
    // Exact totals; the list keeps only the last 16 departed viewers.
    assert_eq!(s["viewers_total"], total);
    assert_eq!(s["viewers"].as_array().unwrap().len(), 16);
    assert_eq!(server.stats()["viewers_active"], 0);
    assert!(
        after.saturating_sub(before) < 10 * 1024,
        "RSS grew from {before} KiB to {after} KiB over {} churns",
        threads * per_thread
    );
    assert!(
        line.len() < 64 * 1024,
        "stats reply is {} bytes",
        line.len()
    );
    eprintln!(
        "churn: RSS {before} -> {after} KiB over {} churns; stats reply {} bytes",
        threads * per_thread,
        line.len()
    );
    drop(tracker);
    server.stop();
}
