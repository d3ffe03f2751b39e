//! Lost tracking in a live session, in the documented UDP form (P = 0, `tracked` clear;
//! docs/recording-format.md, docs/protocol.md): counted lost (never malformed), held, then eased
//! to the neutral, as a viewer sees it.

use crate::loopback::{
    Serve, connect, frame_lines, header_with_session, read_json_line, read_session, viewer,
};
use mimic_types::LandmarkFrame;
use std::io::{BufReader, Write};
use std::net::{Shutdown, UdpSocket};

#[test]
fn udp_frames_with_no_points_are_lost_then_held_and_eased() {
    let rec = "recordings/openface_test.jsonl";
    let tcp_frames = 40;
    let lost_frames = 30;
    let server = Serve::start(&["--rig", "candide3", "--viewer-queue", "100000"]);
    let mut v = viewer(&server.tcp, "lost", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let tv = mimic_testkit::spawn("viewer lost", move || read_session(&mut v));
    let mut t = connect(&server.tcp);
    t.write_all(header_with_session(rec, "lost").as_bytes())
        .unwrap();
    let lines = frame_lines(rec);
    for l in lines.iter().take(tcp_frames) {
        t.write_all(l.as_bytes()).unwrap();
    }
    let mut r = BufReader::new(t.try_clone().unwrap());
    let welcome = read_json_line(&mut r);
    let id = welcome["session_id"].as_u64().unwrap() as u32;
    let key = welcome["udp_key"].as_u64().unwrap() as u32;
    server.wait_for("the TCP frames", |s| {
        s["sessions"][0]["frames"] == tcp_frames
    });
    let last: serde_json::Value = serde_json::from_str(lines[tcp_frames - 1].trim()).unwrap();
    let last_t = last["t_us"].as_i64().unwrap();
    let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
    for k in 0..lost_frames {
        // 30 frames/s of lost tracking: 1 s, past the 0.25 s hold and the 0.5 s ease.
        let frame = LandmarkFrame {
            timestamp_us: last_t + (k as i64 + 1) * 33_333,
            points: Vec::new(),
            valid: Vec::new(),
            tracked: false,
        };
        let packet = mimic_stream::wire::encode_udp_frame(id, key, &frame);
        assert_eq!(packet.len(), mimic_stream::wire::UDP_HEADER_BYTES);
        udp.send_to(&packet, &server.udp).unwrap();
        // One at a time, so the session's small UDP queue never drops one.
        server.wait_for("the lost frame", |s| {
            s["sessions"][0]["frames"] == tcp_frames + k + 1
        });
    }
    let s = server.stats();
    let x = &s["sessions"][0];
    assert_eq!(x["lost"], lost_frames, "{x}");
    assert_eq!(x["malformed"], 0, "{x}");
    assert_eq!(x["udp_frames"], lost_frames, "{x}");
    assert_eq!(x["udp_queue_dropped"], 0, "{x}");
    t.shutdown(Shutdown::Write).unwrap();
    let seen = tv.join().unwrap();
    assert_eq!(seen.frames.len(), tcp_frames + lost_frames);
    let (before, lost) = seen.frames.split_at(tcp_frames);
    assert!(
        lost.iter().all(|f| f.status == 2),
        "every UDP frame with no points is lost"
    );
    let held = &before[tcp_frames - 1].displacements;
    let size = |d: &[glam::Vec3]| d.iter().map(|v| v.length()).fold(0.0f32, f32::max);
    assert!(
        size(held) > 0.0,
        "the last tracked frame moves some control"
    );
    // Held: the first lost frame shows the last expression; eased: the last one the neutral, and
    // the expression never grows on the way.
    let tol = 1e-6 * (1.0 + size(held));
    let first = &lost[0].displacements;
    assert!(
        first
            .iter()
            .zip(held)
            .all(|(a, b)| (*a - *b).length() <= tol)
    );
    assert!(size(&lost[lost_frames - 1].displacements) <= tol);
    for w in lost.windows(2) {
        assert!(size(&w[1].displacements) <= size(&w[0].displacements) + tol);
    }
}
