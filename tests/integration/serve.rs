//! `mimic serve` and `mimic send` end to end on 127.0.0.1, speaking raw bytes (docs/protocol.md).
//!
//! Every socket has a read timeout and every server is stopped with SIGINT (then killed if it
//! has not exited), so the tests stop by themselves.

use crate::loopback::{
    Serve, assert_closed, connect, frame_lines, header_with_session, read_json_line, read_message,
    read_session, viewer,
};
use crate::{mimic, repo, text};
use glam::Vec3;
use mimic_stream::wire::ViewerMessage;
use serde_json::Value;
use std::io::{BufReader, Read, Write};
use std::net::{Shutdown, UdpSocket};
use std::time::Duration;

/// Parses `replay --controls` CSV: (t_us, status, d) per frame.
fn controls_csv(path: &std::path::Path) -> Vec<(i64, u8, Vec<Vec3>)> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let v: Vec<f32> = f[3..].iter().map(|x| x.parse().unwrap()).collect();
            let d = v.chunks(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
            (f[1].parse().unwrap(), f[2].parse().unwrap(), d)
        })
        .collect()
}

#[test]
fn a_sent_recording_reaches_two_viewers_as_replay_computes_it() {
    let rec = "recordings/openface_test.jsonl";
    let server = Serve::start(&["--rig", "candide3", "--viewer-queue", "100000"]);
    let mut a = viewer(&server.tcp, "eq", false);
    let mut b = viewer(&server.tcp, "eq", true);
    server.wait_for("two viewers", |s| s["viewers_active"] == 2);
    let ta = mimic_testkit::spawn("viewer a", move || read_session(&mut a));
    let tb = mimic_testkit::spawn("viewer b", move || read_session(&mut b));
    let sent = mimic(&[
        "send",
        rec,
        "--to",
        &server.tcp,
        "--session",
        "eq",
        "--speed",
        "10",
    ]);
    let (stdout, stderr) = text(&sent);
    assert!(sent.status.success(), "{stderr}");
    assert!(stdout.contains("100 frames retargeted"), "{stdout}");
    let (a, b) = (ta.join().unwrap(), tb.join().unwrap());

    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("controls.csv");
    let bin = dir.path().join("bin");
    let out = mimic(&[
        "replay",
        rec,
        "--rig",
        "candide3",
        "--controls",
        csv.to_str().unwrap(),
        "--format",
        "bin",
        "--out",
        bin.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out).1);
    let expected = controls_csv(&csv);
    assert_eq!(expected.len(), 100);
    let file = std::fs::File::open(bin.join("frames.bin")).unwrap();
    let mut frames_bin = mimic_assets::FramesReader::new(BufReader::new(file)).unwrap();

    let rig = mimic_assets::load_rig(&repo().join("configs/rigs/candide3.toml")).unwrap();
    for seen in [&a, &b] {
        assert_eq!(seen.session.as_ref().unwrap()["rig"], "candide3");
        assert_eq!(seen.end.as_ref().unwrap()["frames"], 100);
        // The rig arrives once, as raw f32 copies of the rig's rest mesh.
        let r = seen.rig.as_ref().unwrap();
        assert_eq!(r.rest, rig.mesh.positions);
        assert_eq!(r.triangles, rig.mesh.triangles);
        assert_eq!(r.basis.len(), rig.mesh.positions.len() * r.controls);
        assert_eq!(seen.frames.len(), expected.len());
        for (k, (f, (t_us, status, d))) in seen.frames.iter().zip(&expected).enumerate() {
            assert_eq!(f.seq, k as u64);
            assert_eq!(f.timestamp_us, *t_us);
            assert_eq!(f.status, *status);
            // The CSV prints 5 decimals: |error| <= 0.5e-5 plus f32 rounding of |d| (< 2^-23 |d|).
            for (x, y) in f.displacements.iter().zip(d) {
                let tol = 0.5e-5 + 1.2e-7 * y.abs().max_element() + 1e-7;
                assert!(
                    (*x - *y).abs().max_element() <= tol,
                    "frame {k}: {x} vs {y}"
                );
            }
        }
    }
    // Both viewers got the same frames; B also the positions, equal to replay's binary frames.
    let rig_msg = b.rig.as_ref().unwrap();
    let m = rig_msg.controls;
    for (fa, fb) in a.frames.iter().zip(&b.frames) {
        assert_eq!(fa.displacements, fb.displacements);
        assert_eq!(fa.pose, fb.pose);
        let p = fb.positions.as_ref().unwrap();
        let replayed = frames_bin.next_frame().unwrap().unwrap();
        assert_eq!(replayed.timestamp_us, fb.timestamp_us);
        // Same moving-rows product on the same d: bit-identical.
        assert_eq!(p, &replayed.positions, "frame {}", fb.seq);
        // A GPU-style viewer evaluating rest + B d from the rig message gets the same mesh;
        // the sum order differs, so allow 38 terms of f32 rounding: 1e-5 of the largest |B d|.
        for (v, got) in p.iter().enumerate() {
            let mut u = Vec3::ZERO;
            for (j, d) in fb.displacements.iter().enumerate() {
                u += *d * rig_msg.basis[v * m + j];
            }
            let want = rig_msg.rest[v] + u;
            assert!((want - *got).abs().max_element() <= 1e-5 * (1.0 + u.abs().max_element()));
        }
    }
    let stats = server.stats();
    let s = &stats["sessions"][0];
    assert_eq!(s["name"], "eq");
    assert_eq!(s["frames"], 100);
    assert_eq!(s["late"], 0);
    assert_eq!(s["malformed"], 0);
    assert_eq!(stats["viewer_frames_dropped"], 0);
    let rest = server.stop();
    assert!(rest.contains("1 sessions"), "{rest}");
}

#[test]
fn garbage_oversized_and_half_sent_messages_get_errors_while_another_session_streams() {
    let rec = "recordings/openface_test.jsonl";
    let server = Serve::start(&[
        "--rig",
        "candide3",
        "--max-message-bytes",
        "65536",
        "--max-errors",
        "4",
        "--viewer-queue",
        "100000",
    ]);
    let mut g = viewer(&server.tcp, "good", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let tg = mimic_testkit::spawn("viewer g", move || read_session(&mut g));
    let tcp = server.tcp.clone();
    let good = mimic_testkit::spawn("good sender", move || {
        mimic(&[
            "send",
            rec,
            "--to",
            &tcp,
            "--session",
            "good",
            "--speed",
            "3",
        ])
    });

    // A bad hello is refused with an error, then the connection closes.
    let mut s = connect(&server.tcp);
    s.write_all(b"nonsense\n").unwrap();
    let mut r = BufReader::new(s.try_clone().unwrap());
    assert_eq!(read_json_line(&mut r)["code"], "bad_hello");
    assert_closed(&mut r);

    // A tracker that sends garbage, an oversized line, a good frame, a short frame, and then
    // half a frame before closing its side.
    let lines = frame_lines(rec);
    let mut bad = connect(&server.tcp);
    bad.write_all(header_with_session(rec, "bad").as_bytes())
        .unwrap();
    let mut r = BufReader::new(bad.try_clone().unwrap());
    let welcome = read_json_line(&mut r);
    assert_eq!(welcome["type"], "welcome");
    assert_eq!(welcome["session"], "bad");
    bad.write_all(b"this is not json\n").unwrap();
    let e = read_json_line(&mut r);
    assert_eq!(
        (e["code"].as_str(), e["line"].as_u64()),
        (Some("bad_json"), Some(2))
    );
    let mut huge = vec![b'x'; 70_000];
    huge.push(b'\n');
    bad.write_all(&huge).unwrap();
    let e = read_json_line(&mut r);
    assert_eq!(
        (e["code"].as_str(), e["line"].as_u64()),
        (Some("too_long"), Some(3))
    );
    bad.write_all(lines[0].as_bytes()).unwrap();
    bad.write_all(b"{\"t_us\":99999999999,\"points\":[[0,0,-1]]}\n")
        .unwrap();
    let e = read_json_line(&mut r);
    assert_eq!(
        (e["code"].as_str(), e["line"].as_u64()),
        (Some("point_count"), Some(5))
    );
    let half = &lines[1].as_bytes()[..lines[1].len() / 2];
    bad.write_all(half).unwrap();
    bad.shutdown(Shutdown::Write).unwrap();
    let e = read_json_line(&mut r);
    assert_eq!(
        (e["code"].as_str(), e["line"].as_u64()),
        (Some("truncated"), Some(6))
    );
    let bye = read_json_line(&mut r);
    assert_eq!(bye["type"], "bye");
    assert_eq!(bye["frames"], 1);
    assert_eq!(bye["malformed"], 4);

    // A tracker that only sends garbage is closed after 4 in a row, though it never closes.
    let mut spam = connect(&server.tcp);
    spam.write_all(header_with_session(rec, "spam").as_bytes())
        .unwrap();
    spam.write_all(b"a\nb\nc\nd\ne\nf\n").unwrap();
    let mut r = BufReader::new(spam.try_clone().unwrap());
    assert_eq!(read_json_line(&mut r)["type"], "welcome");
    for _ in 0..4 {
        assert_eq!(read_json_line(&mut r)["code"], "bad_json");
    }
    assert_eq!(read_json_line(&mut r)["code"], "too_many_errors");
    assert_eq!(read_json_line(&mut r)["reason"], "too_many_errors");
    assert_closed(&mut r);

    // Garbage over UDP is counted, not answered.
    let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
    udp.send_to(b"garbage", &server.udp).unwrap();

    // The good session saw none of it.
    let sent = good.join().unwrap();
    assert!(sent.status.success(), "{}", text(&sent).1);
    let seen = tg.join().unwrap();
    assert_eq!(seen.frames.len(), 100);
    assert!(
        seen.frames
            .iter()
            .enumerate()
            .all(|(k, f)| f.seq == k as u64)
    );
    let end = seen.end.unwrap();
    assert_eq!(
        (end["frames"].as_u64(), end["malformed"].as_u64()),
        (Some(100), Some(0))
    );
    server.wait_for("the UDP packet", |s| s["udp_bad_packets"] == 1);
    assert!(server.stats()["refused"].as_u64().unwrap() >= 1);
    server.stop();
}

#[test]
fn a_stalled_viewer_does_not_delay_the_other_viewer() {
    // ICT positions frames are 26 719 x 12 bytes = 320 kB each: a viewer that reads nothing fills
    // its socket buffers within a few frames and its queue then drops the oldest. The write
    // timeout is long so that on a slow machine the stalled viewer is not dropped as stalled
    // before it reads (here it is only slow).
    let rec = "recordings/openface_test.jsonl";
    let server = Serve::start(&[
        "--rig",
        "ict-face",
        "--viewer-queue",
        "32",
        "--viewer-write-timeout",
        "600",
    ]);
    let mut stalled = viewer(&server.tcp, "st", true);
    let mut live = viewer(&server.tcp, "st", false);
    server.wait_for("two viewers", |s| s["viewers_active"] == 2);
    let tl = mimic_testkit::spawn("live viewer", move || read_session(&mut live));
    let sent = mimic(&["send", rec, "--to", &server.tcp, "--session", "st"]);
    assert!(sent.status.success(), "{}", text(&sent).1);
    // The live viewer got every frame and the end while the stalled one had read nothing.
    let seen = tl.join().unwrap();
    assert_eq!(seen.frames.len(), 100);
    assert!(
        seen.frames
            .iter()
            .enumerate()
            .all(|(k, f)| f.seq == k as u64)
    );
    assert!(seen.end.is_some());
    let stats = server.stats();
    let viewers = stats["sessions"][0]["viewers"].as_array().unwrap().clone();
    let by_positions = |p: bool| {
        viewers
            .iter()
            .find(|v| v["positions"] == p)
            .unwrap()
            .clone()
    };
    assert_eq!(by_positions(false)["frames_dropped"], 0);
    let dropped = by_positions(true)["frames_dropped"].as_u64().unwrap();
    assert!(dropped > 0, "the stalled viewer dropped nothing: {stats}");
    // Now the stalled viewer reads: what it gets is in order, ends with the last frame, and
    // with what was dropped accounts for every frame.
    let seen = read_session(&mut stalled);
    let seqs: Vec<u64> = seen.frames.iter().map(|f| f.seq).collect();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "{seqs:?}");
    assert_eq!(seqs.last(), Some(&99));
    assert_eq!(seqs.len() as u64 + dropped, 100);
    server.stop();
}

#[test]
fn udp_frames_are_retargeted_and_late_ones_dropped() {
    let rec = "recordings/openface_test.jsonl";
    let server = Serve::start(&["--rig", "candide3", "--viewer-queue", "100000"]);
    let mut v = viewer(&server.tcp, "u", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let tv = mimic_testkit::spawn("viewer v", move || read_session(&mut v));
    // The session opens over TCP, which also carries the first 10 frames (the neutral).
    let mut t = connect(&server.tcp);
    t.write_all(header_with_session(rec, "u").as_bytes())
        .unwrap();
    for l in frame_lines(rec).iter().take(10) {
        t.write_all(l.as_bytes()).unwrap();
    }
    let mut r = BufReader::new(t.try_clone().unwrap());
    let welcome = read_json_line(&mut r);
    let id = welcome["session_id"].as_u64().unwrap() as u32;
    let key = welcome["udp_key"].as_u64().unwrap() as u32;
    server.wait_for("10 TCP frames", |s| s["sessions"][0]["frames"] == 10);
    let frames: Vec<_> = mimic_capture::RecordingReader::open(&repo().join(rec), None)
        .unwrap()
        .map(|f| f.unwrap().frame)
        .collect();
    let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
    let packet = |k: usize, key: u32| mimic_stream::wire::encode_udp_frame(id, key, &frames[k]);
    for k in 10..40 {
        udp.send_to(&packet(k, key), &server.udp).unwrap();
        // Paced so the session's 8-packet UDP queue rarely fills; a full queue is counted.
        std::thread::sleep(Duration::from_millis(2));
    }
    let counted =
        |x: &Value| x["frames"].as_u64().unwrap() + x["udp_queue_dropped"].as_u64().unwrap();
    server.wait_for("30 UDP frames", |s| counted(&s["sessions"][0]) == 40);
    // An old frame again (late: dropped) and a packet with the wrong key (not this session's).
    udp.send_to(&packet(3, key), &server.udp).unwrap();
    udp.send_to(&packet(50, key ^ 1), &server.udp).unwrap();
    let s = server.wait_for("the late and the bad packet", |s| {
        s["sessions"][0]["late"] == 1 && s["udp_bad_packets"] == 1
    });
    let x = &s["sessions"][0];
    assert_eq!(
        x["udp_frames"].as_u64().unwrap() + 10,
        x["frames"].as_u64().unwrap()
    );
    t.shutdown(Shutdown::Write).unwrap();
    let seen = tv.join().unwrap();
    assert_eq!(seen.frames.len() as u64, x["frames"].as_u64().unwrap());
    assert!(
        seen.frames
            .windows(2)
            .all(|w| w[0].timestamp_us < w[1].timestamp_us)
    );
    server.stop();
}

#[test]
fn ctrl_c_ends_live_sessions_and_flushes_them_to_viewers() {
    let rec = "recordings/openface_test.jsonl";
    let server = Serve::start(&["--rig", "candide3", "--viewer-queue", "100000"]);
    let mut v = viewer(&server.tcp, "c", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let mut t = connect(&server.tcp);
    t.write_all(header_with_session(rec, "c").as_bytes())
        .unwrap();
    for l in frame_lines(rec).iter().take(30) {
        t.write_all(l.as_bytes()).unwrap();
    }
    server.wait_for("30 frames", |s| s["sessions"][0]["frames"] == 30);
    let rest = server.stop();
    assert!(rest.contains("1 sessions"), "{rest}");
    let seen = read_session(&mut v);
    assert_eq!(seen.frames.len(), 30);
    assert_eq!(seen.end.unwrap()["reason"], "shutdown");
    let mut r = BufReader::new(t);
    assert_eq!(read_json_line(&mut r)["type"], "welcome");
    let bye = read_json_line(&mut r);
    assert_eq!(
        (bye["reason"].as_str(), bye["frames"].as_u64()),
        (Some("shutdown"), Some(30))
    );
}

#[test]
fn limits_idle_timeout_and_http_stats() {
    let rec = "recordings/openface_test.jsonl";
    let server = Serve::start(&[
        "--rig",
        "candide3",
        "--max-sessions",
        "1",
        "--max-viewers",
        "1",
        "--idle-timeout",
        "0.5",
    ]);
    // The one allowed session; a second tracker is refused, as is a second viewer.
    let mut first = connect(&server.tcp);
    first
        .write_all(header_with_session(rec, "one").as_bytes())
        .unwrap();
    let mut r1 = BufReader::new(first.try_clone().unwrap());
    assert_eq!(read_json_line(&mut r1)["type"], "welcome");
    let mut second = connect(&server.tcp);
    second
        .write_all(header_with_session(rec, "two").as_bytes())
        .unwrap();
    let mut r2 = BufReader::new(second);
    assert_eq!(read_json_line(&mut r2)["code"], "too_many_sessions");
    assert_closed(&mut r2);
    let _v1 = viewer(&server.tcp, "one", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let mut v2 = viewer(&server.tcp, "one", false);
    match read_message(&mut v2) {
        Some(ViewerMessage::Error(e)) => assert_eq!(e["code"], "too_many_viewers"),
        other => panic!("{other:?}"),
    }
    // The silent tracker is closed after the idle timeout.
    assert_eq!(read_json_line(&mut r1)["code"], "idle_timeout");
    assert_eq!(read_json_line(&mut r1)["reason"], "idle_timeout");
    // HTTP GET /stats.
    let mut h = connect(&server.tcp);
    h.write_all(b"GET /stats HTTP/1.0\r\n\r\n").unwrap();
    let mut reply = String::new();
    h.read_to_string(&mut reply).unwrap();
    assert!(reply.starts_with("HTTP/1.0 200 OK\r\n"), "{reply}");
    let body = reply.split("\r\n\r\n").nth(1).unwrap();
    let stats: Value = serde_json::from_str(body).unwrap();
    assert_eq!(stats["sessions"][0]["end_reason"], "idle_timeout");
    assert!(stats["refused"].as_u64().unwrap() >= 2);
    server.stop();
}
