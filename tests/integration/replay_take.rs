//! `mimic replay` of a Live Link Face take (its weights onto the ICT rig's morph targets through
//! `configs/namemaps/arkit.toml`, at its `Timecode` times, as a blendshape-mode GLB) and
//! `--weights-format livelink`: a CSV that `mimic_trackers`' take parser (as Live Link
//! importers) reads back with the names, values and times written, from a take and from the
//! blendshape fit of a landmark recording.

use crate::{mimic, repo, text};
use mimic_trackers::livelink::{BLENDSHAPES, CURVE_NAMES, HEAD_YAW, curve_index};
use mimic_trackers::take::{Take, read_take};
use serde_json::Value;
use std::path::Path;

/// A timecode is within half a thousandth of a 60 fps frame of its time; both ends of a
/// difference may be off by that (µs).
const TIMECODE_TOL_US: f64 = 2.0 * (1e6 / 60.0 / 1000.0 / 2.0) + 1.0;

/// The JSON chunk of a GLB file.
fn glb_json(path: &Path) -> Value {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[..4], b"glTF");
    let len = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
    assert_eq!(&b[16..20], b"JSON");
    serde_json::from_slice(&b[20..20 + len]).unwrap()
}

/// The ICT rig target a curve drives (`browInnerUp` drives both halves: read from `_L`).
fn ict_target(curve: &str) -> Option<&'static str> {
    [
        "jawOpen",
        "mouthSmileLeft",
        "mouthSmileRight",
        "mouthFunnel",
        "browInnerUp",
        "eyeBlinkLeft",
        "eyeBlinkRight",
    ]
    .into_iter()
    .find(|t| t.eq_ignore_ascii_case(curve))
}

#[test]
fn a_live_link_take_replays_as_a_glb_and_its_weights_as_a_live_link_csv() {
    let take_path = repo().join("tests/data/livelinkface/S07-001.csv");
    let take = read_take(&take_path).unwrap();
    let tracked: Vec<_> = take.rows.iter().filter(|r| r.tracked).collect();
    let tmp = tempfile::tempdir().unwrap();
    let glb = tmp.path().join("take.glb");
    let csv = tmp.path().join("w.csv");
    let o = mimic(&[
        "replay",
        take_path.to_str().unwrap(),
        "--rig",
        "ict-face",
        "--format",
        "glb",
        "--out",
        glb.to_str().unwrap(),
        "--weights",
        csv.to_str().unwrap(),
        "--weights-format",
        "livelink",
        "--json",
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    let json_at = stdout.find('{').unwrap();
    let summary: Value = serde_json::from_str(&stdout[json_at..]).unwrap();
    assert_eq!(summary["frames"].as_u64().unwrap() as usize, tracked.len());
    // The GLB: the rig's 8 morph targets, one animation over the take's tracked rows' times.
    let j = glb_json(&glb);
    let names = &j["meshes"][0]["extras"]["targetNames"];
    assert_eq!(names.as_array().unwrap().len(), 8, "{names}");
    let input = j["animations"][0]["samplers"][0]["input"].as_u64().unwrap() as usize;
    let acc = &j["accessors"][input];
    assert_eq!(acc["count"].as_u64().unwrap() as usize, tracked.len());
    let span = (tracked[tracked.len() - 1].t_us - tracked[0].t_us) as f64 * 1e-6;
    let max = acc["max"][0].as_f64().unwrap() - acc["min"][0].as_f64().unwrap();
    assert!(
        (max - span).abs() <= 1e-4,
        "keys over {max} s, take {span} s"
    );
    // The CSV read back: every tracked row, its time, the curves the rig has, the head.
    let back: Take = read_take(&csv).unwrap();
    assert_eq!(back.rows.len(), tracked.len());
    assert!(back.present.iter().all(|p| *p));
    for (r, (b, t)) in back.rows.iter().zip(&tracked).enumerate() {
        let want_us = (t.t_us - tracked[0].t_us) as f64;
        assert!(
            (b.t_us as f64 - want_us).abs() <= TIMECODE_TOL_US,
            "row {r}"
        );
        for (k, name) in CURVE_NAMES.iter().enumerate().take(BLENDSHAPES) {
            let want = if ict_target(name).is_some() {
                t.curves[k].clamp(0.0, 1.0)
            } else {
                0.0
            };
            assert_eq!(b.curves[k], want, "row {r}, {name}");
        }
        for a in 0..3 {
            let (got, want) = (b.curves[HEAD_YAW + a], t.curves[HEAD_YAW + a]);
            assert!(
                (got - want).abs() <= 1e-5,
                "row {r}, head {a}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn blendshape_mode_weights_of_a_landmark_recording_as_a_live_link_csv() {
    let tmp = tempfile::tempdir().unwrap();
    let (ours, theirs) = (tmp.path().join("w.csv"), tmp.path().join("ll.csv"));
    let run = |path: &Path, format: &str| {
        let o = mimic(&[
            "replay",
            "recordings/a_yn_question.jsonl",
            "--rig",
            "ict-face",
            "--mode",
            "blendshapes",
            "--max-frames",
            "300",
            "--weights",
            path.to_str().unwrap(),
            "--weights-format",
            format,
        ]);
        let (stdout, stderr) = text(&o);
        assert!(o.status.success(), "{stdout}{stderr}");
    };
    run(&ours, "mimic");
    run(&theirs, "livelink");
    let table = mimic_capture::named_csv::read_named_csv(&ours).unwrap();
    let col = |n: &str| table.header.iter().position(|h| h == n).unwrap();
    let back = read_take(&theirs).unwrap();
    assert_eq!(back.rows.len(), table.rows.len());
    let t0: i64 = table.rows[0].field(col("t_us")).parse().unwrap();
    // mimic's CSV has 4 decimals; the Live Link one the exact f32.
    let tol = 0.5e-4 + f32::EPSILON;
    let mut moved = 0.0f32;
    for (r, (b, row)) in back.rows.iter().zip(&table.rows).enumerate() {
        let t: i64 = row.field(col("t_us")).parse().unwrap();
        assert!(
            ((b.t_us - (t - t0)) as f64).abs() <= TIMECODE_TOL_US,
            "row {r}"
        );
        for (curve, target) in [
            ("JawOpen", "jawOpen"),
            ("MouthSmileLeft", "mouthSmileLeft"),
            ("BrowInnerUp", "browInnerUp_L"),
            ("EyeBlinkRight", "eyeBlinkRight"),
        ] {
            let want: f32 = row.field(col(target)).parse().unwrap();
            let got = b.curves[curve_index(curve).unwrap()];
            assert!(
                (got - want).abs() <= tol,
                "row {r}, {curve}: {got} vs {want}"
            );
        }
        assert_eq!(b.curves[curve_index("TongueOut").unwrap()], 0.0);
        moved = moved.max(b.curves[curve_index("JawOpen").unwrap()]);
    }
    assert!(moved > 0.1, "the jaw opens in this recording: max {moved}");
}
