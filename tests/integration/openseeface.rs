//! OpenSeeFace end to end on its real capture (`tests/data/openseeface/megamind.osf`, a copy of
//! the shared data's): `mimic import openseeface` to an `openseeface68` recording that replays onto
//! ict-face, and the capture sent over loopback UDP at its recorded pace (`mimic send
//! --openseeface`) into `mimic serve --openseeface`, where every packet is counted (accepted, bad
//! or late), a viewer receives the frames and `--record` keeps them.

use crate::loopback::{Serve, read_session, viewer};
use crate::{mimic, repo, text};
use std::net::UdpSocket;
use std::path::PathBuf;

/// `tests/data/openseeface` (a copy of the project's shared data, with its SOURCE.md and licence).
fn osf_data() -> Option<PathBuf> {
    let found = ["tests/data/openseeface"]
        .iter()
        .map(|p| repo().join(p))
        .find(|d| d.join("megamind.osf").is_file());
    if found.is_none() {
        panic!("tests/data/openseeface/megamind.osf missing: the repository ships it");
    }
    found
}

/// Imports the capture (with `extra` flags) into `dir/name`.
fn import(data: &std::path::Path, dir: &std::path::Path, name: &str, extra: &[&str]) -> String {
    let out = dir.join(name).display().to_string();
    let osf = data.join("megamind.osf").display().to_string();
    let mut args = vec!["import", "openseeface", osf.as_str(), "-o", out.as_str()];
    args.extend_from_slice(extra);
    let o = mimic(&args);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    assert!(stdout.contains("231 frames (0 lost tracking)"), "{stdout}");
    out
}

#[test]
fn the_capture_imports_with_sides_kept_and_replays_onto_ict_face() {
    let Some(data) = osf_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let times = data.join("megamind_frames.csv").display().to_string();
    let rec = import(&data, dir.path(), "mm.jsonl", &["--frame-times", &times]);
    let r = mimic_capture::read_recording(std::path::Path::new(&rec), Some(68)).unwrap();
    assert_eq!(r.header.layout, "openseeface68");
    assert_eq!(r.frames.len(), 231);
    // The clip's times: frame 6 to frame 269 at 23.976 fps (megamind_frames.csv).
    let last = r.frames.last().unwrap().frame.timestamp_us;
    let want = ((269.0 - 6.0) * 1e6 / 23.976f64).round() as i64;
    assert!((last - want).abs() <= 1, "{last} vs {want}");
    // The subject's left points (jaw top 16, outer eye corner 45, mouth corner 62) lie at image
    // right (+x) of their right twins (0, 36, 58) in every frame.
    for f in &r.frames {
        let p = &f.frame.points;
        for (left, right) in [(16, 0), (45, 36), (62, 58), (26, 17)] {
            assert!(p[left].x > p[right].x, "t {}", f.frame.timestamp_us);
        }
    }
    let o = mimic(&["replay", &rec, "--rig", "ict-face"]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    assert!(
        stdout.contains("231 frames in (0 rejected, 0 lost"),
        "{stdout}"
    );
    head_turns_reach_the_target(&data, dir.path(), &rec);
}

/// The replay's head rotation (the Live Link take's `HeadYaw`, `HeadPitch`, `HeadRoll`, from the
/// retargeter's pose) moves with the capture: each angle spans over 10 degrees and follows its
/// estimate from the 2D landmarks alone (`angles_2d`) with r > 0.5 (measured 0.96 / 0.68 / 0.97:
/// the retargeter's rigid fit uses the stable points only, which pin pitch least; a replay
/// that ignored OpenSeeFace's pose would span about 0 degrees).
fn head_turns_reach_the_target(data: &std::path::Path, dir: &std::path::Path, rec: &str) {
    let take = dir.join("mm_take.csv").display().to_string();
    let args = [
        "replay",
        rec,
        "--rig",
        "ict-face",
        "--mode",
        "blendshapes",
        "--weights",
        take.as_str(),
        "--weights-format",
        "livelink",
    ];
    let o = mimic(&args);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    let rows = mimic_trackers::take::read_take(std::path::Path::new(&take)).unwrap();
    let records = mimic_trackers::openseeface::read_capture(&data.join("megamind.osf")).unwrap();
    assert_eq!(rows.rows.len(), records.len());
    let head = mimic_trackers::livelink::curve_index("HeadYaw").unwrap();
    for k in 0..3 {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for (row, r) in rows.rows.iter().zip(&records) {
            let f = &mimic_trackers::openseeface::decode_packet(&r.datagram).unwrap()[0];
            a.push(f64::from(row.curves[head + k]));
            b.push(angles_2d(f)[k]);
        }
        let span =
            a.iter().copied().fold(f64::MIN, f64::max) - a.iter().copied().fold(f64::MAX, f64::min);
        let r = pearson(&a, &b);
        assert!(span.to_degrees() > 10.0, "angle {k}: spans {span} rad");
        assert!(r > 0.5, "angle {k}: r = {r} against the 2D estimate");
    }
}

/// Yaw, pitch and roll from 2D landmarks alone (x right, y down): the nose tip's (30) offset from
/// the eye corners' (36, 39, 42, 45) midpoint along the eye line and across it (down), over the
/// inter-ocular distance, and the eye line's angle (the image-right eye higher: > 0).
fn angles_2d(f: &mimic_trackers::openseeface::OsfFace) -> [f64; 3] {
    let p = |i: usize| [f64::from(f.points_2d[i][0]), f64::from(f.points_2d[i][1])];
    let mean = |r: std::ops::Range<usize>| {
        let n = r.len() as f64;
        r.map(p)
            .fold([0.0, 0.0], |s, q| [s[0] + q[0] / n, s[1] + q[1] / n])
    };
    let (er, el) = (mean(36..42), mean(42..48));
    let (ux, uy) = (el[0] - er[0], el[1] - er[1]);
    let iod = ux.hypot(uy);
    let (ux, uy) = (ux / iod, uy / iod);
    let mid = [36, 39, 42, 45]
        .map(p)
        .iter()
        .fold([0.0, 0.0], |s, q| [s[0] + q[0] / 4.0, s[1] + q[1] / 4.0]);
    let nose = p(30);
    let (dx, dy) = (nose[0] - mid[0], nose[1] - mid[1]);
    [
        (dx * ux + dy * uy) / iod,
        (-dx * uy + dy * ux) / iod,
        (-uy).atan2(ux),
    ]
}

fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

#[test]
fn the_capture_sent_over_udp_at_its_pace_is_counted_retargeted_viewed_and_recorded() {
    let Some(data) = osf_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let rec = import(&data, dir.path(), "mm.jsonl", &[]);
    let record_dir = dir.path().join("rec");
    // A free loopback port for the OpenSeeFace intake.
    let port = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let osf_addr = format!("127.0.0.1:{port}");
    let server = Serve::start(&[
        "--rig",
        "ict-face",
        "--openseeface",
        &osf_addr,
        "--viewer-queue",
        "100000",
        "--idle-timeout",
        "1.5",
        "--record",
        record_dir.to_str().unwrap(),
    ]);
    let mut v = viewer(&server.tcp, "openseeface-0", false);
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let tv = mimic_testkit::spawn("viewer", move || read_session(&mut v));
    // Three bad datagrams (not a whole number of faces) before the capture.
    let bad = UdpSocket::bind("127.0.0.1:0").unwrap();
    for n in [1usize, 100, 1786] {
        bad.send_to(&vec![7u8; n], &osf_addr).unwrap();
    }
    let started = std::time::Instant::now();
    let o = mimic(&["send", &rec, "--openseeface", &osf_addr]);
    let took = started.elapsed().as_secs_f64();
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    assert!(
        stdout.contains("sent 231 OpenSeeFace datagrams"),
        "{stdout}"
    );
    // At its recorded pace: the capture spans 3.52 s of tracker time.
    assert!(took >= 3.5, "sent in {took} s");
    let sent = 231 + 3;
    let counted = |s: &serde_json::Value| {
        let x = Serve::session(s, "openseeface-0", 0);
        let n = |k: &str| x[k].as_u64().unwrap_or(0);
        n("frames")
            + n("late")
            + n("future")
            + n("malformed")
            + s["udp_bad_packets"].as_u64().unwrap()
    };
    let s = server.wait_for("every packet counted", |s| counted(s) == sent);
    assert_eq!(s["udp_bad_packets"], 3);
    let x = server.wait_for_session("openseeface-0", "the idle end", |x| x["active"] == false);
    assert_eq!(x["layout"], "openseeface68");
    assert_eq!(x["end_reason"], "idle_timeout");
    let frames = x["frames"].as_u64().unwrap();
    assert!(frames >= 225, "{x}");
    assert_eq!(
        x["tracked"].as_u64().unwrap()
            + x["calibrating"].as_u64().unwrap()
            + x["lost"].as_u64().unwrap(),
        frames
    );
    let seen = tv.join().unwrap();
    assert_eq!(seen.frames.len() as u64, frames);
    assert!(seen.rig.is_some() && seen.end.is_some());
    assert_eq!(seen.session.as_ref().unwrap()["layout"], "openseeface68");
    assert!(
        seen.frames
            .windows(2)
            .all(|w| w[0].timestamp_us < w[1].timestamp_us)
    );
    assert_eq!(x["recorded"].as_u64().unwrap(), frames);
    let recorded: Vec<_> = std::fs::read_dir(&record_dir).unwrap().collect();
    assert_eq!(recorded.len(), 1);
    let path = recorded[0].as_ref().unwrap().path();
    let r = mimic_capture::read_recording(&path, Some(68)).unwrap();
    assert_eq!(r.frames.len() as u64, frames);
    server.stop();
}

#[test]
fn two_captures_sent_one_after_the_other_into_one_port_are_both_retargeted() {
    let Some(data) = osf_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let rec = import(&data, dir.path(), "mm.jsonl", &[]);
    let osf_addr = {
        let port = UdpSocket::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        format!("127.0.0.1:{port}")
    };
    let server = Serve::start(&[
        "--rig",
        "ict-face",
        "--no-udp",
        "--openseeface",
        &osf_addr,
        "--idle-timeout",
        "10",
    ]);
    // OpenSeeFace run twice: each `mimic send` is a new process (a new source port) whose
    // clock starts again; a restarted tracker takes a second or more to send again.
    for run in 0..2 {
        if run == 1 {
            std::thread::sleep(std::time::Duration::from_secs(1));
        }
        let o = mimic(&["send", &rec, "--openseeface", &osf_addr]);
        let (stdout, stderr) = text(&o);
        assert!(o.status.success(), "{stdout}{stderr}");
    }
    let x = server.wait_for_session("openseeface-0", "both runs counted", |x| {
        let n = |k: &str| x[k].as_u64().unwrap_or(0);
        n("frames") + n("late") + n("future") + n("malformed") == 2 * 231
    });
    // One session, both runs retargeted: none refused as late, the restart counted.
    assert_eq!(x["late"], 0, "{x}");
    assert_eq!(x["future"], 0, "{x}");
    assert_eq!(x["restarts"], 1, "{x}");
    assert!(x["frames"].as_u64().unwrap() >= 2 * 225, "{x}");
    let s = server.stats();
    assert_eq!(s["udp_wrong_source"], 0, "{s}");
    assert_eq!(s["udp_refused"], 0, "{s}");
    let ids: Vec<_> = s["sessions"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|x| x["name"] == "openseeface-0")
        .collect();
    assert_eq!(ids.len(), 1, "{s}");
    server.stop();
}
