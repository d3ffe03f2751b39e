//! The crease measure (`mimic_retarget::quality::crease`, issue 45 item 1) on the shipped ICT
//! rig: ICT's own expression shapes set the bound. With the top split at 4.4 / 0.6 (issue 45;
//! 4.6 / 1.0 before) the fitted Kinect take stays under it (2 of 277 frames were over, frame 115
//! shelved over a brow), and megamind's count and largest figure stay at what was measured
//! (124 of 267, 0.0916; before 130, 0.1168); its crumpled (108) and shelved (240) frames are
//! still over. `cargo test -p mimic_retarget --test crease -- --nocapture` prints the figures
//! docs/quality.md quotes.
#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use glam::Vec3;
use mimic_retarget::quality::crease::CreaseMeasure;
use mimic_retarget::{FrameStatus, RetargetSettings, Retargeter};
use mimic_solve::build_basis;
use mimic_types::{LandmarkFrame, Layout};
use std::path::PathBuf;

/// megamind's frames over ICT's bound and its largest figure, measured with the shipped rig
/// (docs/quality.md, "Creases"); the test allows float drift of a hundredth on each.
const MEGAMIND_MEASURED: (usize, f32) = (124, 0.0916);
/// Slack on the measured megamind figures: a hundredth of each.
const DRIFT: f32 = 0.01;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn recording(name: &str) -> (Layout, Vec<LandmarkFrame>) {
    let reader =
        mimic_capture::RecordingReader::open(&root().join("recordings").join(name), None).unwrap();
    let path = root().join(format!("configs/layouts/{}.toml", reader.header().layout));
    let layout = mimic_assets::load_layout(&path).unwrap();
    let frames = reader
        .read_all()
        .frames
        .into_iter()
        .map(|f| f.frame)
        .collect();
    (layout, frames)
}

#[test]
fn ict_shapes_bound_the_brows_and_the_shelved_and_crumpled_frames_go_over() {
    let rig = mimic_assets::load_rig(&root().join("configs/rigs/ict-face.toml")).unwrap();
    let rest = &rig.mesh.positions;
    // The skin the solvers move, and its brows and forehead: above the lowest brow control (4.x).
    let surface: Vec<bool> = rig.frozen.iter().map(|f| !f).collect();
    let brow = rig
        .controls
        .iter()
        .filter(|c| c.fdp.to_string().starts_with("4."))
        .map(|c| rest[c.vertex as usize].y)
        .fold(f32::MAX, f32::min);
    let forehead: Vec<bool> = rest.iter().map(|p| p.y > brow).collect();
    let m = CreaseMeasure::new(rest, &rig.mesh.triangles, &surface, &forehead);
    assert!(m.region_len() > 500, "{}", m.region_len());

    let pack = mimic_assets::load_shape_pack(
        &root().join("configs/meshes/ict-facekit/expressions.shapes"),
    )
    .unwrap();
    let (mut bound, mut worst) = (0f32, String::new());
    for s in pack.shapes.iter().filter(|s| !s.name.starts_with("Pupil")) {
        let p: Vec<Vec3> = rest.iter().zip(&s.deltas).map(|(a, d)| *a + *d).collect();
        let v = m.measure(&p);
        if v > bound {
            (bound, worst) = (v, s.name.clone());
        }
    }
    println!(
        "ICT's shapes: forehead crease at most {bound:.4} ({worst}); brow line y = {brow:.2} cm"
    );
    assert!(bound > 0.0);

    let basis = build_basis(&rig, &rig.solver).unwrap();
    let mut over: Vec<(&str, usize)> = Vec::new();
    for (name, step) in [
        ("a_yn_question.kinect121.jsonl", 5),
        ("megamind_mediapipe.jsonl", 1),
    ] {
        let (layout, frames) = recording(name);
        let mut rt =
            Retargeter::new(&rig, &layout, basis.clone(), RetargetSettings::default()).unwrap();
        let mut out = rt.new_output();
        let (mut count, mut measured, mut top) = (0, 0, (0f32, 0usize));
        for (k, f) in frames.iter().enumerate() {
            rt.step(f, &mut out);
            if k % step != 0 || out.status != FrameStatus::Tracked {
                continue;
            }
            let v = m.measure(&out.positions);
            measured += 1;
            if v > top.0 {
                top = (v, k);
            }
            if v > bound {
                count += 1;
                over.push((name, k));
            }
        }
        println!(
            "{name}: {count} of {measured} frames over the bound; largest {:.4} at frame {}",
            top.0, top.1
        );
        if name.starts_with("a_yn") {
            // The fitted take's shelf over the brow (frame 115, 0.0500 before) is gone: all under.
            assert_eq!(count, 0, "{name}: {count} of {measured} over");
        } else {
            let (n, v) = MEGAMIND_MEASURED;
            assert!(
                count as f32 <= n as f32 * (1.0 + DRIFT),
                "{name}: {count} over, measured {n}"
            );
            assert!(
                top.0 <= v * (1.0 + DRIFT),
                "{name}: largest {}, measured {v}",
                top.0
            );
            // Not a measure that passes everything: a third or more of the cartoon take is still
            // over (its brows move 1-1.5 cm, ICT's shapes at most 0.45).
            assert!(count * 3 > measured, "{name}: {count} of {measured}");
        }
    }
    // The frames the contact sheets show crumpled (megamind 107-108) and shelved over both brows
    // (megamind 240) are still over: the change lowers them (0.107 -> 0.088, 0.115 -> 0.075) but
    // does not make them ICT-like.
    for k in [
        ("megamind_mediapipe.jsonl", 108),
        ("megamind_mediapipe.jsonl", 240),
    ] {
        assert!(over.contains(&k), "{k:?} not caught; over: {over:?}");
    }
}
