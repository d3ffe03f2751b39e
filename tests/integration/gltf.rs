//! GLB output checked by the real tools: the Khronos glTF validator and three.js's GLTFLoader
//! (tools/gltf-check, Node), against mimic's own deformed meshes of the same take (its OBJ
//! frames). Skips, saying why, only when `node` is not installed.

use crate::{mimic, repo, text};
use mimic_assets::load_rig;
use serde_json::json;
use std::path::Path;
use std::process::Command;

/// Every `EVERY`-th frame is compared (and written as OBJ).
const EVERY: usize = 173;
/// Every `STRIDE`-th vertex of the rig is a sample vertex.
const STRIDE: usize = 7;

/// Whether `node` runs; prints why the test skips when it does not.
pub(crate) fn node_ready() -> bool {
    match Command::new("node").arg("--version").output() {
        Ok(o) if o.status.success() => {}
        _ => {
            println!("SKIPPED: `node` is not installed (Debian: apt-get install nodejs npm)");
            return false;
        }
    }
    let tools = repo().join("tools/gltf-check");
    if !tools.join("node_modules/gltf-validator").is_dir()
        || !tools.join("node_modules/three").is_dir()
    {
        let o = Command::new("npm")
            .args(["ci", "--no-audit", "--no-fund"])
            .current_dir(&tools)
            .output()
            .expect("run npm ci in tools/gltf-check");
        assert!(
            o.status.success(),
            "npm ci in tools/gltf-check failed: {:?}",
            text(&o)
        );
    }
    true
}

/// `node tools/gltf-check/check.mjs GLB [EXPECT]`; fails the test on any finding.
pub(crate) fn check(glb: &Path, expect: Option<&Path>) {
    let mut c = Command::new("node");
    c.arg(repo().join("tools/gltf-check/check.mjs")).arg(glb);
    if let Some(e) = expect {
        c.arg(e);
    }
    let o = c.output().expect("run node");
    let (out, err) = text(&o);
    println!("{out}{err}");
    assert!(
        o.status.success(),
        "gltf-check failed on {}:\n{out}{err}",
        glb.display()
    );
    assert!(out.contains(" 0 errors, 0 warnings"), "{out}");
}

/// Replays `rec` onto `rig` (extra replay flags in `mode`) as a GLB and as OBJ frames, writes
/// the OBJ frames' sample vertices in metres as the expectation, and runs the check.
fn take_matches_mimic(rec: &str, rig: &str, mode: &[&str]) {
    if !node_ready() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("take.glb");
    let metrics = dir.path().join("m.csv");
    let objs = dir.path().join("obj");
    let every = EVERY.to_string();
    let mut args = vec!["replay", rec, "--rig", rig, "--format", "glb", "--json"];
    args.extend_from_slice(mode);
    let glb_s = glb.to_str().unwrap().to_string();
    let metrics_s = metrics.to_str().unwrap().to_string();
    let o = mimic(&[&args[..], &["--out", &glb_s, "--metrics", &metrics_s]].concat());
    assert!(o.status.success(), "{:?}", text(&o));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(summary["gltf"]["skipped_frames"], 0, "{summary}");
    let objs_s = objs.to_str().unwrap().to_string();
    let mut args = vec![
        "replay", rec, "--rig", rig, "--format", "obj", "--every", &every,
    ];
    args.extend_from_slice(mode);
    let o = mimic(&[&args[..], &["--out", &objs_s]].concat());
    assert!(o.status.success(), "{:?}", text(&o));

    // The recording's frame times, and its duration from the first frame to the last.
    let times: Vec<i64> = std::fs::read_to_string(&metrics)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
        .collect();
    let duration_s = (times[times.len() - 1] - times[0]) as f64 * 1e-6;
    let rig_file = load_rig(&repo().join(format!("configs/rigs/{rig}.toml"))).unwrap();
    let s = f64::from(mimic_gltf::metres_per_unit(&rig_file.units).unwrap());
    let fdps: Vec<_> = rig_file.controls.iter().map(|c| c.fdp).collect();
    let face = mimic_retarget::face_size(&fdps, &rig_file.control_positions()).unwrap();
    let mut frames = Vec::new();
    for k in (0..times.len()).step_by(EVERY) {
        let obj = objs.join(format!("frame_{k:06}.obj"));
        let mesh = mimic_assets::load_obj(&obj).unwrap();
        let vertices: Vec<usize> = (0..mesh.positions.len()).step_by(STRIDE).collect();
        let positions: Vec<[f64; 3]> = vertices
            .iter()
            .map(|&v| mesh.positions[v].to_array().map(|x| f64::from(x) * s))
            .collect();
        // The key time exactly as the GLB stores it: f32 seconds from the first frame.
        let t = ((times[k] - times[0]) as f64 * 1e-6) as f32;
        frames.push(json!({"k": k, "t": t, "vertices": vertices, "positions": positions}));
    }
    assert!(frames.len() >= 3, "{} frames compared", frames.len());
    let expect = json!({
        "duration_s": duration_s,
        "face_size_m": f64::from(face) * s,
        "tolerance_m": 1e-5 * f64::from(face) * s,
        "frames": frames,
    });
    let expect_path = dir.path().join("expect.json");
    std::fs::write(&expect_path, expect.to_string()).unwrap();
    check(&glb, Some(&expect_path));
}

#[test]
fn ict_take_passes_the_validator_and_three_js_morphs_it_like_mimic() {
    take_matches_mimic("recordings/a_yn_question.kinect121.jsonl", "ict-face", &[]);
}

#[test]
fn candide3_take_passes_the_validator_and_three_js_morphs_it_like_mimic() {
    take_matches_mimic(
        "recordings/a_doubt_question.kinect121.jsonl",
        "candide3",
        &[],
    );
}

#[test]
fn blendshape_take_passes_the_validator_and_three_js_morphs_it_like_mimic() {
    take_matches_mimic(
        "recordings/a_affirmative.kinect121.jsonl",
        "ict-face",
        &["--mode", "blendshapes"],
    );
}

#[test]
fn rig_export_writes_a_valid_glb_of_the_rig_alone() {
    if !node_ready() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (rig, mode, targets) in [
        ("candide3", "freeform", 114),
        ("ict-face", "blendshapes", 8),
    ] {
        let glb = dir.path().join(format!("{rig}.glb"));
        let o = mimic(&[
            "rig",
            "export",
            rig,
            "-o",
            glb.to_str().unwrap(),
            "--mode",
            mode,
            "--json",
        ]);
        assert!(o.status.success(), "{:?}", text(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["summary"]["targets"], targets, "{v}");
        assert_eq!(v["summary"]["keys"], 0, "{v}");
        check(&glb, None);
    }
}

/// The JSON chunk of a GLB file.
fn glb_json(path: &Path) -> serde_json::Value {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[0..4], b"glTF");
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&bytes[20..20 + len]).unwrap()
}

#[test]
fn no_pose_and_step_keys_leave_one_step_weights_channel() {
    let dir = tempfile::tempdir().unwrap();
    let rec = "recordings/a_doubt_question.kinect121.jsonl";
    let posed = dir.path().join("posed.glb");
    let flat = dir.path().join("flat.glb");
    for (out, extra) in [
        (&posed, &[][..]),
        (&flat, &["--no-pose", "--step-keys"][..]),
    ] {
        let mut args = vec!["replay", rec, "--rig", "candide3", "--format", "glb"];
        args.extend_from_slice(extra);
        let o = mimic(&[&args[..], &["--out", out.to_str().unwrap()]].concat());
        assert!(o.status.success(), "{:?}", text(&o));
    }
    let paths = |v: &serde_json::Value| -> Vec<String> {
        v["animations"][0]["channels"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c["target"]["path"].as_str().unwrap().to_string())
            .collect()
    };
    let (p, f) = (glb_json(&posed), glb_json(&flat));
    assert_eq!(paths(&p), ["weights", "rotation", "translation"]);
    assert_eq!(paths(&f), ["weights"]);
    assert_eq!(p["animations"][0]["samplers"][0]["interpolation"], "LINEAR");
    assert_eq!(f["animations"][0]["samplers"][0]["interpolation"], "STEP");
    // Same keys and targets either way.
    assert_eq!(p["meshes"][0]["extras"], f["meshes"][0]["extras"]);
    if node_ready() {
        check(&flat, None);
    }
    let o = mimic(&["replay", rec, "--rig", "candide3", "--no-pose"]);
    assert!(!o.status.success());
    assert!(text(&o).1.contains("--format glb"), "{:?}", text(&o));
}
