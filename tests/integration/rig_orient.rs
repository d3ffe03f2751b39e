//! `mimic rig new` without `--landmarks` on a head in another orientation (issue 41 item 5):
//! the ICT head in mm, upright and as scans come (z up, facing -y). The turned head's rig says
//! its turn, finds the upright run's landmarks and controls, loads the same working mesh, and
//! a replay on it writes the same frames.

use crate::{mimic, repo, text};
use glam::Vec3;
use mimic_assets::{Axis, Orientation};
use std::path::Path;

/// Copies the ICT head scaled to mm and turned into `turn`'s file frame (`v` and `vn` lines;
/// each coordinate written in its shortest round-trip form, so the turn back is exact; no
/// materials).
fn ict_head_mm(to: &Path, turn: Orientation) {
    let from = repo().join("configs/meshes/ict-facekit/generic_neutral_mesh.obj");
    let text = std::fs::read_to_string(from).unwrap();
    let mut out = String::with_capacity(text.len() + text.len() / 4);
    for line in text.lines() {
        let mut it = line.split_whitespace();
        let tag = it.next();
        if matches!(tag, Some("v") | Some("vn")) {
            let c: Vec<f32> = it.take(3).map(|s| s.parse().unwrap()).collect();
            let p = Vec3::new(c[0], c[1], c[2]);
            let q = turn.to_file(if tag == Some("v") { p * 10.0 } else { p });
            out.push_str(&format!("{} {} {} {}\n", tag.unwrap(), q.x, q.y, q.z));
        } else if !matches!(tag, Some("mtllib") | Some("usemtl")) {
            out.push_str(line);
            out.push('\n');
        }
    }
    std::fs::write(to, out).unwrap();
}

/// `rig new MESH -o RIG --units mm --landmarks-out MARKS`: its stderr.
fn rig_new(mesh: &Path, rig: &Path, marks: &Path) -> String {
    let o = mimic(&[
        "rig",
        "new",
        mesh.to_str().unwrap(),
        "-o",
        rig.to_str().unwrap(),
        "--units",
        "mm",
        "--landmarks-out",
        marks.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}\n{stderr}");
    assert!(stderr.contains("68 of 68 landmarks found"), "{stderr}");
    assert!(!stderr.contains("probably failed"), "{stderr}");
    stderr
}

/// The `v` lines of a replay's OBJ frame as points.
fn frame_points(dir: &Path, index: usize) -> Vec<Vec3> {
    let text = std::fs::read_to_string(dir.join(format!("frame_{index:06}.obj"))).unwrap();
    text.lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f32> = l.split_whitespace().map(|s| s.parse().unwrap()).collect();
            Vec3::new(c[0], c[1], c[2])
        })
        .collect()
}

/// `replay a_yn_question.kinect121 --rig RIG`, frames 0, 20, 40 as OBJ into `out`.
fn replay(rig: &Path, out: &Path) {
    let o = mimic(&[
        "replay",
        "recordings/a_yn_question.kinect121.jsonl",
        "--rig",
        rig.to_str().unwrap(),
        "--max-frames",
        "41",
        "--every",
        "20",
        "--format",
        "obj",
        "--out",
        out.to_str().unwrap(),
    ]);
    let (_, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
}

#[test]
fn a_head_lying_z_up_facing_minus_y_gets_the_upright_heads_rig() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scan = Orientation::new(Axis::Z, Axis::new(1, true)).unwrap();
    ict_head_mm(&d.join("upright.obj"), Orientation::default());
    ict_head_mm(&d.join("scan.obj"), scan);
    let said = rig_new(
        &d.join("upright.obj"),
        &d.join("upright.toml"),
        &d.join("upright.json"),
    );
    assert!(!said.contains("turned to y up"), "{said}");
    let said = rig_new(
        &d.join("scan.obj"),
        &d.join("scan.toml"),
        &d.join("scan.json"),
    );
    assert!(
        said.contains("the head faces -y with +z up: turned to y up, +z forward for the rig"),
        "{said}"
    );
    let toml = |p: &str| std::fs::read_to_string(d.join(p)).unwrap();
    assert!(!toml("upright.toml").contains("[orientation]"));
    assert!(
        toml("scan.toml").contains("[orientation]")
            && toml("scan.toml").contains("up = \"+z\"\nforward = \"-y\"\n"),
        "{}",
        toml("scan.toml")
    );
    // The landmarks (vertex numbers) of the two runs.
    let read = |p: &str| -> serde_json::Value { serde_json::from_str(&toml(p)).unwrap() };
    let (a, b) = (read("upright.json"), read("scan.json"));
    let same = (0..68)
        .filter(|k| {
            a[k.to_string().as_str()].is_u64()
                && a[k.to_string().as_str()] == b[k.to_string().as_str()]
        })
        .count();
    assert!(
        same >= 60,
        "{same} of 68 landmarks on the upright run's vertex"
    );
    // The turned rig loads the upright head's working mesh exactly, with its controls.
    let load = |p: &str| mimic_assets::load_rig(&d.join(p)).unwrap();
    let (up, turned) = (load("upright.toml"), load("scan.toml"));
    assert!(
        up.mesh.positions == turned.mesh.positions,
        "the working meshes differ"
    );
    let controls = |r: &mimic_types::Rig| -> Vec<(String, u32)> {
        r.controls
            .iter()
            .map(|c| (c.fdp.to_string(), c.vertex))
            .collect()
    };
    assert_eq!(controls(&up), controls(&turned));
    assert_eq!(up.parts, turned.parts);
    // A replay on each writes the same deformation (in the rig's working frame).
    replay(&d.join("upright.toml"), &d.join("up"));
    replay(&d.join("scan.toml"), &d.join("turned"));
    let rest = &up.mesh.positions;
    for index in [0, 20, 40] {
        let (p, q) = (
            frame_points(&d.join("up"), index),
            frame_points(&d.join("turned"), index),
        );
        assert_eq!((p.len(), q.len()), (rest.len(), rest.len()));
        let apart = p
            .iter()
            .zip(&q)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f32::max);
        let moved = p
            .iter()
            .zip(rest)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f32::max);
        println!(
            "frame {index}: moved up to {moved:.3} mm, the two rigs' frames {apart:.2e} mm apart"
        );
        assert!(apart <= 1e-3, "frame {index}: {apart} mm apart");
        if index > 0 {
            assert!(moved > 0.5, "frame {index} barely moves ({moved} mm)");
        }
    }
}
