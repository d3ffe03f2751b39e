//! `mimic info` on every shipped layout and rig, and its one-line errors.

use crate::{mimic, repo, text};

fn shipped(dir: &str) -> Vec<String> {
    let mut files: Vec<String> = std::fs::read_dir(repo().join(dir))
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "toml"))
                .map(|p| p.strip_prefix(repo()).unwrap().display().to_string())
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

#[test]
fn accepts_every_shipped_layout_and_rig() {
    let files: Vec<String> = shipped("configs/layouts")
        .into_iter()
        .chain(shipped("configs/rigs"))
        .collect();
    for f in &files {
        let out = mimic(&["info", f, "--json"]);
        let (stdout, stderr) = text(&out);
        assert!(out.status.success(), "{f}: {stderr}");
        let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        // Dense rigs (`<rig>.<layout>.toml`, docs/rigging.md) have their layout's points instead.
        let dense = ["kinect121", "ibug68", "mediapipe478"]
            .iter()
            .any(|set| f.ends_with(&format!(".{set}.toml")) && f.contains("configs/rigs"));
        if dense {
            assert!(v["controls"].as_u64().unwrap() > 38, "{f}: {v}");
        } else {
            assert_eq!(v["controls"], 38, "{f} should map the 38 controls");
        }
    }
}

#[test]
fn missing_obj_is_a_one_line_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let rig = dir.path().join("r.toml");
    std::fs::write(
        &rig,
        "name = \"r\"\nunits = \"cm\"\nmesh = \"nope.obj\"\n[regions]\ntop_from = 1.0\nbottom_below = 0.0\nband = 0.5\n\n[[controls]]\nfdp = \"8.3\"\nvertex = 0\nregion = \"bottom\"\n",
    )
    .unwrap();
    let out = mimic(&["info", rig.to_str().unwrap()]);
    let (_, stderr) = text(&out);
    assert!(!out.status.success());
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("r.toml: mesh: ") && stderr.contains("nope.obj: No such file"),
        "{stderr}"
    );
}

#[test]
fn control_vertex_out_of_range_names_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("t.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let rig = dir.path().join("r.toml");
    std::fs::write(
        &rig,
        "name = \"r\"\nunits = \"cm\"\nmesh = \"t.obj\"\n[regions]\ntop_from = 1.0\nbottom_below = 0.0\nband = 0.5\n\n[[controls]]\nfdp = \"8.3\"\nvertex = 3\nregion = \"bottom\"\n",
    )
    .unwrap();
    let out = mimic(&["info", rig.to_str().unwrap()]);
    let (_, stderr) = text(&out);
    assert!(!out.status.success());
    assert!(
        stderr
            .trim_end()
            .ends_with("r.toml:9: control 8.3 uses vertex 3, but the mesh has 3 vertices"),
        "{stderr}"
    );
}

#[test]
fn info_warns_about_controls_that_share_a_rest_position() {
    // CANDIDE-3's inner-lip middles (FDPs 2.2 and 2.3, vertices 87 and 40) coincide at rest.
    let out = mimic(&["info", "configs/rigs/candide3.toml", "--json"]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let warnings = v["warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    let w = warnings[0].as_str().unwrap();
    assert!(w.contains("controls 2.2 and 2.3"), "{w}");
    assert!(stderr.contains(&format!("warning: {w}")), "{stderr}");
    // The ICT head's controls are all apart.
    let out = mimic(&["info", "configs/rigs/ict-face.toml", "--json"]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["warnings"], serde_json::json!([]));
    assert!(!stderr.contains("warning:"), "{stderr}");
}

/// The shipped recording of the layout a rig file's name declares (`<rig>.<layout>.toml`).
fn recording_for(rig: &str) -> &'static str {
    if rig.ends_with(".kinect121.toml") {
        "recordings/a_yn_question.kinect121.jsonl"
    } else if rig.ends_with(".ibug68.toml") {
        "recordings/openface_test.jsonl"
    } else if rig.ends_with(".mediapipe478.toml") {
        "recordings/megamind_mediapipe.jsonl"
    } else {
        "recordings/a_yn_question.jsonl"
    }
}

#[test]
fn every_shipped_rig_with_morph_targets_lists_them_and_replays_in_blendshapes_mode() {
    let mut with_targets = 0;
    for rig in shipped("configs/rigs") {
        let declared = std::fs::read_to_string(repo().join(&rig))
            .unwrap()
            .matches("[[morph_targets]]")
            .count();
        let out = mimic(&["info", &rig, "--json"]);
        let (stdout, stderr) = text(&out);
        assert!(out.status.success(), "{rig}: {stderr}");
        let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        let listed = v["morph_targets"].as_array().map_or(0, Vec::len);
        assert_eq!(listed, declared, "{rig}: {v}");
        if declared == 0 {
            continue;
        }
        with_targets += 1;
        let summary = crate::replay::replay_json(&[
            recording_for(&rig),
            "--rig",
            &rig,
            "--mode",
            "blendshapes",
        ]);
        assert!(
            summary["frames_in"].as_u64().unwrap() > 0,
            "{rig}: {summary}"
        );
        assert_eq!(summary["frames_with_non_finite_vertices"], 0, "{rig}");
    }
    assert!(
        with_targets >= 2,
        "expected shipped rigs with morph targets"
    );
}

#[test]
fn info_refuses_a_rig_whose_morph_target_does_not_match_its_mesh() {
    // The 3 000-vertex rig pointed at a full ICT expression mesh (26 719 vertices).
    let dir = tempfile::tempdir().unwrap();
    let rigs = repo().join("configs/rigs");
    let text_3k = std::fs::read_to_string(rigs.join("ict-face-3k.toml")).unwrap();
    let mesh = rigs.join("../meshes/ict-facekit-3k/face_3k.obj");
    let wrong = rigs.join("../meshes/ict-facekit/jawOpen.obj");
    let head = &text_3k[..text_3k.find("[[morph_targets]]").unwrap()];
    let tail = &text_3k[text_3k.find("[regions]").unwrap()..];
    let broken = format!(
        "{}[[morph_targets]]\nname = \"jawOpen\"\nobj = {:?}\n\n{tail}",
        head.replace(
            "\"../meshes/ict-facekit-3k/face_3k.obj\"",
            &format!("{:?}", mesh.to_str().unwrap())
        ),
        wrong.to_str().unwrap()
    );
    let rig = dir.path().join("r.toml");
    std::fs::write(&rig, broken).unwrap();
    let out = mimic(&["info", rig.to_str().unwrap()]);
    let (_, stderr) = text(&out);
    assert!(!out.status.success(), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("r.toml") && stderr.contains("jawOpen"),
        "{stderr}"
    );
}
