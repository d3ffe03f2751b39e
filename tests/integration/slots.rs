//! Connection slots (docs/reliability.md): one peer's held sockets cannot lock out another
//! peer's tracker or the stats, refusals are answered at once, and a viewer waiting for a
//! session that never starts is closed after the viewer idle timeout.
//!
//! "Peers" are loopback source addresses: on Linux all of 127.0.0.0/8 reaches the server on
//! 127.0.0.1, each with its own address.

use crate::loopback::{
    Serve, connect_from, frame_lines, header_with_session, read_json_line, read_message, viewer,
};
use mimic_stream::wire::ViewerMessage;
use std::io::{BufRead, BufReader, Read, Write};
use std::time::{Duration, Instant};

#[test]
fn four_hundred_sockets_from_one_peer_do_not_lock_out_another_peer() {
    let mut server = Serve::start(&["--rig", "candide3"]);
    // Polled from an address of its own: from 127.0.0.1, at its share, a poll would compete for
    // the 4 stats slots with the refused viewers' tasks still holding them, and one refused
    // would count in `refused` (or, past 256 refusals in flight, find its socket closed): the
    // flake seen when the browser test's Chromium starves the server (docs/reliability.md).
    server.stats_from = Some("127.0.0.3".into());
    let per_peer = 64;
    // 400 viewers from 127.0.0.1 waiting for a session that never starts.
    let mut held = Vec::new();
    for _ in 0..400 {
        held.push(viewer(&server.tcp, "never", false));
    }
    // The first 64 are admitted and wait; every later one is refused: past the peer's share a
    // connection may still take one of the 4 slots kept for stats requests, and is then refused
    // for not being one ("no connection slot left but those kept ..."), else it is refused for
    // the peer's share ("at most 64 connections from 127.0.0.1"). Each answer is a viewer ERROR
    // message or, on a starved machine (the browser test's Chromium on both cores) where the
    // server had not read the hello within its wait, the error line: the same code and message.
    // Refusals are answered while at most 256 are in flight and closed unanswered past that
    // (docs/reliability.md), which a starved server reaches when it accepts the backlog faster
    // than its refusal tasks run. The stats below show that none of them was admitted.
    let mut for_the_share = 0;
    for (i, v) in held.iter_mut().enumerate().skip(per_peer as usize) {
        let mut first = [0u8; 1];
        match v.read(&mut first) {
            Ok(0) => {}
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => {}
            Ok(_) => {
                if refusal_reply(first[0], v).contains("at most 64 connections from 127.0.0.1") {
                    for_the_share += 1;
                }
            }
            Err(e) => panic!("viewer {i}: {e}"),
        }
    }
    assert!(
        for_the_share > 0,
        "no refusal named the peer's share of 64 connections"
    );
    let s = server.wait_for("400 sockets seen", |s| {
        s["viewers_active"] == per_peer && s["refused"] == 400 - per_peer
    });
    assert!(s["connections"].as_u64().unwrap() >= 400, "{s}");
    // The full peer's own stats requests come through the slots kept for them.
    stats_through_the_kept_slots(&server.tcp);
    // A tracker from 127.0.0.2 gets its session at once.
    let rec = "recordings/openface_test.jsonl";
    let started = Instant::now();
    let mut t = connect_from("127.0.0.2", &server.tcp);
    t.write_all(header_with_session(rec, "other").as_bytes())
        .unwrap();
    for l in &frame_lines(rec)[..30] {
        t.write_all(l.as_bytes()).unwrap();
    }
    server.wait_for_session("other", "the second peer's frames", |s| s["frames"] == 30);
    // Locked out, it would wait for a held viewer's slot: the viewer idle timeout, 60 s. Its
    // own frames take a fraction of a second; the bound leaves a starved CI machine room.
    let took = started.elapsed();
    assert!(
        took < Duration::from_secs(10),
        "the second peer's tracker waited {took:?}"
    );
    // A tracker from the full peer is refused with a line, not left in the backlog.
    let mut refused = crate::loopback::connect(&server.tcp);
    refused
        .write_all(header_with_session(rec, "third").as_bytes())
        .unwrap();
    let reply = read_json_line(&mut BufReader::new(refused));
    assert_eq!(reply["code"], "too_many_connections", "{reply}");
    drop(t);
    drop(held);
    server.stop();
}

#[test]
fn a_viewer_of_a_session_that_never_starts_is_closed_after_the_idle_timeout() {
    let server = Serve::start(&["--rig", "candide3", "--viewer-idle-timeout", "0.5"]);
    let started = Instant::now();
    let mut v = viewer(&server.tcp, "nobody", false);
    match read_message(&mut v) {
        Some(ViewerMessage::Error(e)) => assert_eq!(e["code"], "idle_timeout", "{e}"),
        other => panic!("expected idle_timeout, got {other:?}"),
    }
    assert!(started.elapsed() >= Duration::from_millis(500));
    assert!(read_message(&mut v).is_none());
    server.wait_for("the viewer gone", |s| s["viewers_active"] == 0);
    server.stop();
}

/// The rest of a refusal whose first byte is `first`: asserts its code and returns its message.
fn refusal_reply(first: u8, v: &mut std::net::TcpStream) -> String {
    let reply = if first == b'{' {
        let mut rest = String::new();
        BufReader::new(&mut *v).read_line(&mut rest).unwrap();
        let e: serde_json::Value = serde_json::from_str(&format!("{{{rest}")).unwrap();
        Some(ViewerMessage::Error(e))
    } else {
        read_message(&mut (&[first][..]).chain(&mut *v))
    };
    match reply {
        Some(ViewerMessage::Error(e)) => {
            assert_eq!(e["code"], "too_many_connections", "{e}");
            let m = e["message"].as_str().unwrap_or_default().to_string();
            assert!(
                m.contains("at most 64 connections from 127.0.0.1")
                    || m.contains("no connection slot left but those kept for stats requests"),
                "{e}"
            );
            m
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
}

/// A stats request from 127.0.0.1 (at its share) is answered with the counters, through a slot
/// kept for stats; retried while a refused viewer's task still holds those slots (at most 20 s).
fn stats_through_the_kept_slots(tcp: &str) {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let mut s = crate::loopback::connect(tcp);
        s.write_all(b"{\"type\":\"stats\"}\n").unwrap();
        let mut line = String::new();
        let _ = BufReader::new(s).read_line(&mut line);
        let v: serde_json::Value = serde_json::from_str(&line).unwrap_or_default();
        if v["viewers_active"] == 64 {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "no stats answer from the full peer: {line}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}
