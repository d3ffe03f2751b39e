//! Live Link Face takes end to end (the real takes in `tests/data/livelinkface`, copied
//! from the shared data): `mimic send --weights TAKE.csv` paces the take by its `Timecode` (duration
//! within 1 % of the take's), drives the ICT rig's morph targets through the name map
//! (`configs/namemaps/arkit.toml`) and reports the names the rig lacks once, in one line.

use crate::loopback::{Serve, read_session, viewer};
use crate::{mimic, repo, text};
use std::path::PathBuf;

/// `tests/data/livelinkface` (a copy of the project's shared data, with its SOURCE.md and licence).
fn takes() -> Option<PathBuf> {
    let found = ["tests/data/livelinkface"]
        .iter()
        .map(|p| repo().join(p))
        .find(|d| d.join("S07-001.csv").is_file());
    if found.is_none() {
        panic!("tests/data/livelinkface/S07-001.csv missing: the repository ships it");
    }
    found
}

/// The take's duration by its first and last Timecode, `HH:MM:SS:FF.fff` at 60 fps timecode.
fn take_duration(csv: &str) -> (f64, Vec<Vec<String>>) {
    let rows: Vec<Vec<String>> = csv
        .lines()
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    let secs = |tc: &str| {
        let p: Vec<f64> = tc.split(':').map(|x| x.parse().unwrap()).collect();
        p[0] * 3600.0 + p[1] * 60.0 + p[2] + p[3] / 60.0
    };
    let d = secs(&rows[rows.len() - 1][0]) - secs(&rows[1][0]);
    (d, rows)
}

#[test]
fn a_take_paced_by_its_timecode_drives_the_ict_morph_targets() {
    let Some(dir) = takes() else { return };
    let csv = dir.join("S07-001.csv");
    let (duration, rows) = take_duration(&std::fs::read_to_string(&csv).unwrap());
    let speed = 8.0;
    let server = Serve::start(&["--rig", "ict-face", "--no-udp", "--viewer-queue", "100000"]);
    let mut v = viewer(&server.tcp, "take", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let tv = mimic_testkit::spawn("viewer", move || read_session(&mut v));
    let o = mimic(&[
        "send",
        "--weights",
        csv.to_str().unwrap(),
        "--to",
        &server.tcp,
        "--session",
        "take",
        "--speed",
        "8",
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    // Names the rig lacks: one line, and no per-name warning from the server.
    let lacking: Vec<&str> = stdout
        .lines()
        .filter(|l| l.contains("has no morph target"))
        .collect();
    assert_eq!(lacking.len(), 1, "{stdout}");
    assert!(lacking[0].contains("45 of the take's 52 names"), "{stdout}");
    assert!(!stderr.contains("unknown_weight"), "{stderr}");
    // "sent N weight frames in X s": paced by the Timecode, within 1 % of the take's duration.
    let words: Vec<&str> = stdout.split_whitespace().collect();
    let at = words.iter().position(|w| *w == "weight").unwrap();
    assert_eq!(words[at - 1], "2028");
    let paced: f64 = words[at + 3].parse().unwrap();
    let want = duration / speed;
    assert!(
        (paced - want).abs() <= 0.01 * want,
        "paced {paced} s, take {duration} s / {speed}"
    );
    assert!(stdout.contains("server: 2028 frames, 0 late, 0 malformed, 0 unknown weight names"));
    // The viewer's controls are the weights (`d[3k]` = (w_k, 0, 0)); jawOpen is the rig's first
    // target: it follows the take's JawOpen column, found here by its header name.
    let seen = tv.join().unwrap();
    assert_eq!(seen.frames.len(), 2028);
    let jaw = rows[0].iter().position(|h| h == "JawOpen").unwrap();
    let smile = rows[0].iter().position(|h| h == "MouthSmileLeft").unwrap();
    let mut moved = 0.0f32;
    for (f, row) in seen.frames.iter().zip(&rows[1..]) {
        let w_jaw: f32 = row[jaw].parse::<f32>().unwrap().clamp(0.0, 1.0);
        let w_smile: f32 = row[smile].parse::<f32>().unwrap().clamp(0.0, 1.0);
        assert!((f.displacements[0].x - w_jaw).abs() <= 1e-6, "{}", f.seq);
        assert!((f.displacements[3].x - w_smile).abs() <= 1e-6, "{}", f.seq);
        moved = moved.max(w_jaw);
    }
    assert!(moved > 0.2, "the jaw opens in the take: max {moved}");
    server.stop();
}

#[test]
fn a_take_with_dropouts_sends_only_its_tracked_rows() {
    let Some(dir) = takes() else { return };
    let csv = dir.join("S88-001.csv");
    let server = Serve::start(&["--rig", "ict-face", "--no-udp"]);
    let o = mimic(&[
        "send",
        "--weights",
        csv.to_str().unwrap(),
        "--to",
        &server.tcp,
        "--fast",
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    assert!(
        stdout.contains("1939 rows (277 with no face, not sent)"),
        "{stdout}"
    );
    assert!(stdout.contains("server: 1662 frames, 0 late"), "{stdout}");
    // `--loop`: the take again with later times, none late.
    let o = mimic(&[
        "send",
        "--weights",
        csv.to_str().unwrap(),
        "--to",
        &server.tcp,
        "--fast",
        "--loop",
        "--max-frames",
        "2000",
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    assert!(stdout.contains("server: 2000 frames, 0 late"), "{stdout}");
    server.stop();
}

#[test]
fn live_link_udp_packets_drive_a_weights_session_with_the_head_pose() {
    use mimic_trackers::livelink::{CURVES, HEAD_YAW, LiveLinkPacket, curve_index, encode_packet};
    let Some(dir) = takes() else { return };
    let take = mimic_trackers::take::read_take(&dir.join("S07-001.csv")).unwrap();
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let addr = format!("127.0.0.1:{port}");
    let server = Serve::start(&[
        "--rig",
        "ict-face",
        "--no-udp",
        "--livelink",
        &addr,
        "--viewer-queue",
        "100000",
        "--idle-timeout",
        "1",
    ]);
    let mut v = viewer(&server.tcp, "livelink-iPhone", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let tv = mimic_testkit::spawn("viewer", move || read_session(&mut v));
    let udp = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let n = 120;
    let yaw = |i: usize| 0.4 * (i as f32 / 15.0).sin();
    let packet = |i: usize| {
        let mut curves = [0.0f32; CURVES];
        curves.copy_from_slice(&take.rows[i].curves);
        curves[HEAD_YAW] = yaw(i);
        encode_packet(&LiveLinkPacket {
            device_id: "9A1B7D4E-0000-4000-8000-000000000001".into(),
            subject: "iPhone".into(),
            frame: 1000 + 2 * i as i32,
            subframe: 0.0,
            rate_numerator: 60,
            rate_denominator: 1,
            curves,
        })
    };
    udp.send_to(b"not a packet", &addr).unwrap();
    for i in 0..n {
        udp.send_to(&packet(i), &addr).unwrap();
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    // An old packet again: late.
    udp.send_to(&packet(3), &addr).unwrap();
    let x = server.wait_for_session("livelink-iPhone", "the idle end", |x| x["active"] == false);
    let s = server.stats();
    let frames = x["frames"].as_u64().unwrap();
    assert_eq!(frames, n as u64, "{x}");
    assert_eq!(x["late"], 1);
    assert_eq!(s["udp_bad_packets"], 1);
    assert_eq!(frames + 1 + 1, n as u64 + 2, "accepted + late + bad = sent");
    let seen = tv.join().unwrap();
    assert_eq!(seen.frames.len(), n);
    let jaw = curve_index("JawOpen").unwrap();
    for (i, f) in seen.frames.iter().enumerate() {
        // Frame 1000 + 2i at 60 fps, from the first packet's (each rounded to 1 us).
        let want_us = (2 * i) as f64 / 60.0 * 1e6;
        assert!((f.timestamp_us as f64 - want_us).abs() <= 1.0, "frame {i}");
        let w = take.rows[i].curves[jaw].clamp(0.0, 1.0);
        assert!((f.displacements[0].x - w).abs() <= 1e-6, "frame {i}");
        // A pure yaw psi about y takes x to (cos psi, 0, -sin psi).
        let ex = f.pose.rotation * glam::Vec3::X;
        let want = glam::Vec3::new(yaw(i).cos(), 0.0, -yaw(i).sin());
        assert!((ex - want).length() <= 1e-5, "frame {i}: {ex} vs {want}");
    }
    server.stop();
}

#[test]
fn a_take_sent_as_live_link_packets_is_counted_in_a_livelink_session() {
    let Some(dir) = takes() else { return };
    let csv = dir.join("S88-001.csv");
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let addr = format!("127.0.0.1:{port}");
    let server = Serve::start(&[
        "--rig",
        "ict-face",
        "--no-udp",
        "--livelink",
        &addr,
        "--idle-timeout",
        "1",
    ]);
    let o = mimic(&[
        "send",
        "--weights",
        csv.to_str().unwrap(),
        "--livelink",
        &addr,
        "--session",
        "phone",
        "--speed",
        "16",
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    assert!(stdout.contains("sent 1662 Live Link packets"), "{stdout}");
    let x = server.wait_for_session("livelink-phone", "the idle end", |x| x["active"] == false);
    let n = |k: &str| x[k].as_u64().unwrap();
    // Every packet counted: accepted + late + future (+ undecodable, none here) = sent.
    assert_eq!(n("frames") + n("late") + n("future"), 1662, "{x}");
    assert_eq!(server.stats()["udp_bad_packets"], 0);
    assert_eq!(n("udp_frames"), n("frames"));
    server.stop();
}
