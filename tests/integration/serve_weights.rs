//! `mimic serve` weights sessions end to end on 127.0.0.1 (docs/protocol.md, "Tracker sending
//! weights"): named ARKit-style weights in, the morph basis's control values and blended
//! positions out, bad frames answered while the session goes on.

use crate::loopback::{Serve, connect, read_json_line, read_message};
use crate::repo;
use glam::Vec3;
use mimic_stream::wire::ViewerMessage;
use serde_json::Value;
use std::io::{BufRead, BufReader, Write};
use std::net::{Shutdown, TcpStream};

/// Viewer messages up to and including END.
fn read_viewer(s: &mut TcpStream) -> Vec<ViewerMessage> {
    let mut out = Vec::new();
    loop {
        let m = read_message(s).expect("viewer message");
        let end = matches!(m, ViewerMessage::End(_));
        out.push(m);
        if end {
            return out;
        }
    }
}

/// The shipped ICT rig's targets in rig order, as `mimic_assets` computes them (independent of
/// the server's copy).
fn ict_targets() -> (Vec<Vec3>, Vec<mimic_types::MorphTarget>) {
    let path = repo().join("configs/rigs/ict-face.toml");
    let rig = mimic_assets::load_rig(&path).unwrap();
    let targets = mimic_assets::load_morph_targets(&path, &rig).unwrap();
    (rig.mesh.positions, targets)
}

/// `P0 + sum_k w_k dP_k`, summed in f64.
fn blend(rest: &[Vec3], targets: &[mimic_types::MorphTarget], w: &[f64]) -> Vec<[f64; 3]> {
    (0..rest.len())
        .map(|i| {
            let mut p = rest[i].to_array().map(f64::from);
            for (t, &wk) in targets.iter().zip(w) {
                let d = t.position_deltas[i].to_array();
                for a in 0..3 {
                    p[a] += wk * f64::from(d[a]);
                }
            }
            p
        })
        .collect()
}

#[test]
fn a_weights_stream_reaches_viewers_as_the_blend_and_bad_frames_are_answered() {
    let serve = Serve::start(&["--no-udp", "--also-rig", "candide3"]);
    let (rest, targets) = ict_targets();
    let names: Vec<String> = targets.iter().map(|t| t.name.clone()).collect();
    let k = names.len();

    let viewer = |positions: bool| {
        let mut s = connect(&serve.tcp);
        let hello =
            format!("{{\"type\":\"viewer\",\"session\":\"w\",\"positions\":{positions}}}\n");
        s.write_all(hello.as_bytes()).unwrap();
        s
    };
    let (vp, vd) = (viewer(true), viewer(false));
    serve.wait_for("two viewers", |s| s["viewers_active"] == 2);

    let mut tracker = connect(&serve.tcp);
    let mut replies = BufReader::new(tracker.try_clone().unwrap());
    tracker
        .write_all(
            b"{\"mode\":\"weights\",\"session\":\"w\",\"source\":\"arkit\",\"rate_hz\":60}\n",
        )
        .unwrap();
    let welcome = read_json_line(&mut replies);
    assert_eq!(welcome["type"], "welcome", "{welcome}");
    assert_eq!(welcome["mode"], "weights");
    assert_eq!(welcome["targets"], Value::from(names.clone()));
    let frames = [
        // line 2: good; `browInnerUp` drives both ICT halves; `tongueOut` is no target.
        r#"{"t_us":1000,"weights":{"jawOpen":0.4,"mouthSmileLeft":0.2,"browInnerUp":0.5,"tongueOut":0.3}}"#,
        // line 3: a weight that is not a number.
        r#"{"t_us":2000,"weights":{"jawOpen":"wide"}}"#,
        // line 4: JSON has no NaN.
        r#"{"t_us":3000,"weights":{"jawOpen":NaN}}"#,
        // line 5: late (not after 1000): dropped and counted, no reply.
        r#"{"t_us":900,"weights":{"jawOpen":0.9}}"#,
        // line 6: good; values clamped to [0, 1], names in any case; `tongueOut` not reported again.
        r#"{"t_us":4000,"weights":{"JawOpen":1.7,"eyeBlinkLeft":-0.5,"mouthFunnel":0.25,"tongueOut":1}}"#,
    ];
    for f in frames {
        tracker.write_all(f.as_bytes()).unwrap();
        tracker.write_all(b"\n").unwrap();
    }
    tracker.shutdown(Shutdown::Write).unwrap();
    // Both viewers read as real ones do, at once and concurrently: a viewer left unread for
    // `--viewer-write-timeout` (10 s) is dropped as stalled, which a slow machine could reach
    // while the checks below run on the other viewer.
    let readers = [vp, vd].map(|mut v| mimic_testkit::spawn("viewer", move || read_viewer(&mut v)));
    let lines: Vec<Value> = (0..4).map(|_| read_json_line(&mut replies)).collect();
    let brief: Vec<(String, String, u64)> = lines
        .iter()
        .map(|l| {
            (
                l["type"].as_str().unwrap().to_string(),
                l["code"].as_str().unwrap_or("").to_string(),
                l["line"].as_u64().unwrap_or(0),
            )
        })
        .collect();
    let want = |t: &str, c: &str, n: u64| (t.to_string(), c.to_string(), n);
    assert_eq!(
        brief,
        vec![
            want("warning", "unknown_weight", 2),
            want("error", "bad_weight", 3),
            want("error", "bad_json", 4),
            want("bye", "", 0),
        ],
        "{lines:?}"
    );
    let bye = &lines[3];
    assert_eq!(
        (
            &bye["frames"],
            &bye["late"],
            &bye["malformed"],
            &bye["unknown_weights"]
        ),
        (
            &Value::from(2),
            &Value::from(1),
            &Value::from(2),
            &Value::from(2)
        ),
        "{bye}"
    );

    // The weights the two good frames stand for, in target order.
    let weight = |pairs: &[(&str, f64)]| {
        let mut w = vec![0f64; k];
        for (n, v) in pairs {
            w[names.iter().position(|x| x == n).unwrap()] = *v;
        }
        w
    };
    let expected = [
        weight(&[
            ("jawOpen", 0.4),
            ("mouthSmileLeft", 0.2),
            ("browInnerUp_L", 0.5),
            ("browInnerUp_R", 0.5),
        ]),
        weight(&[("jawOpen", 1.0), ("mouthFunnel", 0.25)]),
    ];

    // f32 terms summed, each rounding once: error <= (2 + 3k) eps (|P0| + sum |w dP|), bounded
    // with the largest coordinate of the mesh plus k times the largest delta.
    let scale = rest
        .iter()
        .map(|p| p.abs().max_element())
        .fold(0f32, f32::max)
        + targets
            .iter()
            .flat_map(|t| t.position_deltas.iter())
            .map(|d| d.abs().max_element())
            .fold(0f32, f32::max)
            * k as f32;
    let tol = f64::from((2 + 3 * k) as f32 * f32::EPSILON * scale);

    for (reader, positions) in readers.into_iter().zip([true, false]) {
        let msgs = reader.join().expect("viewer reader");
        let ViewerMessage::Rig(rig) = &msgs[1] else {
            panic!("second message is not the rig");
        };
        assert_eq!(rig.meta["mode"], "weights");
        assert_eq!(rig.meta["targets"], Value::from(names.clone()));
        assert_eq!((rig.rest.len(), rig.controls), (rest.len(), 3 * k));
        let frames: Vec<_> = msgs
            .iter()
            .filter_map(|m| match m {
                ViewerMessage::Frame(f) => Some(f),
                _ => None,
            })
            .collect();
        assert_eq!(frames.len(), 2);
        for (seq, (f, w)) in frames.iter().zip(&expected).enumerate() {
            assert_eq!(f.seq, seq as u64);
            // d[3k + a] = w_k e_a, exactly (one f64 -> f32 rounding of w).
            for (j, d) in f.displacements.iter().enumerate() {
                let mut e = [0f32; 3];
                e[j % 3] = w[j / 3] as f32;
                assert_eq!(d.to_array(), e, "frame {seq} control {j}");
            }
            let truth = blend(&rest, &targets, w);
            // Evaluating the rig message as a GPU would (rest + B d) gives the same mesh.
            let m = rig.controls;
            for (i, t) in truth.iter().enumerate() {
                let mut p = rig.rest[i].to_array().map(f64::from);
                for (j, d) in f.displacements.iter().enumerate() {
                    let b = f64::from(rig.basis[i * m + j]);
                    for (pa, da) in p.iter_mut().zip(d.to_array()) {
                        *pa += b * f64::from(da);
                    }
                }
                for (pa, ta) in p.iter().zip(t) {
                    assert!((pa - ta).abs() <= tol, "rig message vertex {i}");
                }
            }
            assert_eq!(f.positions.is_some(), positions);
            if let Some(ps) = &f.positions {
                assert_eq!(ps.len(), rest.len());
                for (i, (p, t)) in ps.iter().zip(&truth).enumerate() {
                    for (a, (pa, ta)) in p.to_array().iter().zip(t).enumerate() {
                        let err = (f64::from(*pa) - ta).abs();
                        assert!(err <= tol, "frame {seq} vertex {i} axis {a}: {err} > {tol}");
                    }
                }
            }
        }
        // Weights 1 on a few targets really move the mesh (the comparison above is not vacuous).
        let moved = blend(&rest, &targets, &expected[1])
            .iter()
            .zip(&rest)
            .map(|(t, r)| (t[1] - f64::from(r.y)).abs())
            .fold(0f64, f64::max);
        assert!(moved > 1e3 * tol, "jawOpen moves the chin: {moved}");
        let ViewerMessage::End(end) = msgs.last().unwrap() else {
            unreachable!()
        };
        assert_eq!(end["unknown_weights"], 2);
    }
    let stats = serve.stats();
    let s = &stats["sessions"][0];
    assert_eq!(
        (&s["layout"], &s["tracked"], &s["unknown_weights"]),
        (&Value::from("weights"), &Value::from(2), &Value::from(2))
    );

    // A rig without morph targets refuses a weights session at its hello.
    let mut t = connect(&serve.tcp);
    t.write_all(b"{\"mode\":\"weights\",\"rig\":\"candide3\"}\n")
        .unwrap();
    let mut r = BufReader::new(t);
    let refused = read_json_line(&mut r);
    assert_eq!(refused["code"], "no_morph_targets", "{refused}");
    assert!(refused["message"].as_str().unwrap().contains("candide3"));
    let mut rest_of = String::new();
    assert_eq!(
        r.read_line(&mut rest_of).unwrap_or(0),
        0,
        "closed after refusing"
    );
}

#[test]
fn send_weights_csv_drives_a_weights_session() {
    let serve = Serve::start(&["--no-udp"]);
    let dir = std::env::temp_dir().join(format!("mimic-send-weights-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("w.csv");
    // An ARKit-style export: a timecode column (not sent), two known names and one unknown.
    std::fs::write(
        &csv,
        "Timecode,jawOpen,mouthSmileLeft,tongueOut\n00:00:00:01,0.1,0.2,0.3\n00:00:00:02,0.4,0.5,0.6\n00:00:00:03,0.7,0.8,0.9\n",
    )
    .unwrap();
    let out = crate::mimic(&[
        "send",
        "--weights",
        csv.to_str().unwrap(),
        "--to",
        &serve.tcp,
        "--session",
        "csv",
        "--fast",
    ]);
    let (stdout, stderr) = crate::text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stdout.contains("sent 3 weight frames")
            && stdout.contains("server: 3 frames, 0 late, 0 malformed, 3 unknown weight names"),
        "{stdout}"
    );
    // The unknown name is reported once, though it came in every frame.
    assert_eq!(stderr.matches("unknown_weight").count(), 1, "{stderr}");
    let s = serve.wait_for("the csv session", |s| s["sessions"][0]["active"] == false);
    assert_eq!(s["sessions"][0]["name"], "csv");
    assert_eq!(s["sessions"][0]["tracked"], 3);
    // `--loop` sends the CSV again with later times: 7 frames of 3 rows, none late.
    let out = crate::mimic(&[
        "send",
        "--weights",
        csv.to_str().unwrap(),
        "--to",
        &serve.tcp,
        "--session",
        "looped",
        "--fast",
        "--loop",
        "--max-frames",
        "7",
    ]);
    let (stdout, stderr) = crate::text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stdout.contains("sent 7 weight frames")
            && stdout.contains("server: 7 frames, 0 late, 0 malformed"),
        "{stdout}"
    );
    // A bad cell is an error naming the line and column.
    std::fs::write(&csv, "jawOpen\n0.5\nwide\n").unwrap();
    let out = crate::mimic(&[
        "send",
        "--weights",
        csv.to_str().unwrap(),
        "--to",
        &serve.tcp,
    ]);
    let (_, stderr) = crate::text(&out);
    assert!(!out.status.success());
    assert!(
        stderr.contains("w.csv:3: column `jawOpen`: `wide` is not a number"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
