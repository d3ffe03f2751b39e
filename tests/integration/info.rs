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
