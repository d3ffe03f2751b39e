//! The VRM binding: the table, ARKit names, and both VRM versions written and read back.

use super::*;
use crate::{Morph, write_avatar_glb};
use glam::Vec3;
use mimic_avatar::{Expression, MorphBind, load_avatar, parse_avatar};
use std::path::Path;

fn repo(rel: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

/// One small morph per name, each moving working vertex 0.
fn morphs(names: &[&str]) -> Vec<Morph> {
    names
        .iter()
        .enumerate()
        .map(|(k, n)| Morph {
            name: (*n).into(),
            positions: vec![(0, Vec3::new(0.001 * (k + 1) as f32, 0.0, 0.0))],
            normals: Vec::new(),
        })
        .collect()
}

/// Writes the fixture at `rel` back with `names` as added targets; the summary and the file read back.
fn round_trip(rel: &str, names: &[&str]) -> (Option<VrmBinds>, mimic_avatar::Avatar) {
    let a = load_avatar(&repo(rel)).unwrap();
    let face = FaceMesh::of(&a, 0).unwrap();
    let mut out = Vec::new();
    let s = write_avatar_glb(&a, &face, &morphs(names), None, &mut out).unwrap();
    let b = parse_avatar(Path::new("out.vrm"), &out, None).unwrap();
    (s.vrm_expressions, b)
}

const SHAPES: &[&str] = &[
    "jawOpen",
    "eyeBlinkLeft",
    "eyeBlinkRight",
    "mouthSmileLeft",
    "mouthSmileRight",
    "4.1.x",
];

/// The binds of expression `name` as (index, weight).
fn binds(e: Option<&Expression>) -> Vec<(usize, f32)> {
    e.unwrap()
        .binds
        .iter()
        .map(|b| (b.index, b.weight))
        .collect()
}

#[test]
fn arkit_names_in_arkit_and_ict_spellings() {
    assert_eq!(arkit_name("jawOpen"), Some("jawOpen"));
    assert_eq!(arkit_name("JawOpen"), Some("jawOpen"));
    assert_eq!(arkit_name("eyeBlink_L"), Some("eyeBlinkLeft"));
    assert_eq!(arkit_name("mouthSmile_R"), Some("mouthSmileRight"));
    assert_eq!(arkit_name("browInnerUp_L"), Some("browInnerUp"));
    assert_eq!(arkit_name("4.1.x"), None);
    assert_eq!(arkit_name("blink"), None);
    assert_eq!(arkit_name("_L"), None);
}

#[test]
fn the_table_binds_vrm_presets_to_arkit_shapes() {
    let presets = [
        "blink",
        "blinkLeft",
        "blinkRight",
        "aa",
        "ih",
        "ou",
        "ee",
        "oh",
        "happy",
        "angry",
        "sad",
        "relaxed",
        "surprised",
    ];
    let names: Vec<&str> = PRESETS.iter().map(|(p, _)| *p).collect();
    assert_eq!(names, presets);
    for (preset, row) in PRESETS {
        assert!(!row.is_empty(), "{preset}");
        for (shape, w) in *row {
            assert!(ARKIT_NAMES.contains(shape), "{preset}: {shape}");
            assert!(*w > 0.0 && *w <= 1.0, "{preset}: {shape} {w}");
        }
    }
    let row = |p: &str| PRESETS.iter().find(|(n, _)| *n == p).unwrap().1;
    assert_eq!(row("aa"), &[("jawOpen", 1.0)]);
    assert_eq!(row("blinkLeft"), &[("eyeBlinkLeft", 1.0)]);
    assert!(row("ou").contains(&("mouthPucker", 1.0)));
    // Every VRM 1.0 preset but surprised has a 0.x preset name.
    for p in presets {
        assert_eq!(
            V0_NAMES.iter().any(|(v1, _, _)| *v1 == p),
            p != "surprised",
            "{p}"
        );
    }
}

#[test]
fn vrm_1_presets_without_binds_and_perfect_sync_bind_mimics_targets() {
    let (s, b) = round_trip("tests/data/vrm/mimic_vrm1.vrm", SHAPES);
    let s = s.unwrap();
    // blink and aa were the avatar's: left alone. happy was there without binds: filled.
    assert_eq!(
        s.presets,
        [
            "blinkLeft",
            "blinkRight",
            "ih",
            "ee",
            "oh",
            "happy",
            "relaxed",
            "surprised"
        ]
    );
    // mouthSmileLeft was the avatar's own custom expression: kept, not replaced.
    assert_eq!(
        s.custom,
        [
            "jawOpen",
            "eyeBlinkLeft",
            "eyeBlinkRight",
            "mouthSmileRight"
        ]
    );
    let vrm = b.vrm.as_ref().unwrap();
    assert_eq!(binds(vrm.expression("blink")), [(0, 1.0)]);
    assert_eq!(binds(vrm.expression("aa")), [(1, 0.8)]);
    assert_eq!(binds(vrm.expression("mouthSmileLeft")), [(1, 0.25)]);
    // The added targets follow the avatar's two: jawOpen is 2, eyeBlinkLeft 3, ...
    assert_eq!(binds(vrm.expression("blinkLeft")), [(3, 1.0)]);
    assert_eq!(binds(vrm.expression("happy")), [(5, 1.0), (6, 1.0)]);
    assert_eq!(binds(vrm.expression("oh")), [(2, 0.5)]);
    assert_eq!(binds(vrm.expression("jawOpen")), [(2, 1.0)]);
    let happy = vrm.expression("happy").unwrap();
    assert_eq!(happy.preset.as_deref(), Some("happy"));
    assert_eq!(
        happy.binds[0],
        MorphBind {
            mesh: 0,
            node: Some(6),
            index: 5,
            weight: 1.0
        }
    );
    // No preset lacking its shapes is made up.
    assert!(vrm.expression("ou").is_none());
    assert!(vrm.expression("angry").is_none());
    let custom = b
        .document
        .pointer("/extensions/VRMC_vrm/expressions/custom")
        .unwrap();
    assert_eq!(custom.as_object().unwrap().len(), 5);
    // The rest of the extension is the avatar's.
    assert_eq!(b.document["extensions"]["MIMIC_unknown_test"]["kept"], true);
    assert_eq!(vrm.bones.len(), 5);
}

#[test]
fn vrm_0_groups_without_binds_and_perfect_sync_bind_mimics_targets() {
    let (s, b) = round_trip("tests/data/vrm/mimic_vrm0.vrm", SHAPES);
    let s = s.unwrap();
    assert_eq!(
        s.presets,
        [
            "blinkLeft",
            "blinkRight",
            "ih",
            "ee",
            "oh",
            "happy",
            "relaxed",
            "surprised"
        ]
    );
    assert_eq!(
        s.custom,
        [
            "jawOpen",
            "eyeBlinkLeft",
            "eyeBlinkRight",
            "mouthSmileLeft",
            "mouthSmileRight"
        ]
    );
    let vrm = b.vrm.as_ref().unwrap();
    assert_eq!(binds(vrm.expression("blink")), [(0, 1.0)]);
    assert_eq!(binds(vrm.expression("aa")), [(1, 0.8)]);
    // Joy, there without binds, is filled in place (weights 0..100 in the file).
    let happy = vrm.expression("happy").unwrap();
    assert_eq!(happy.name, "Joy");
    assert_eq!(binds(Some(happy)), [(5, 1.0), (6, 1.0)]);
    assert_eq!(binds(vrm.expression("blinkLeft")), [(3, 1.0)]);
    let groups = b
        .document
        .pointer("/extensions/VRM/blendShapeMaster/blendShapeGroups")
        .unwrap()
        .as_array()
        .unwrap();
    let group = |name: &str| groups.iter().find(|g| g["name"] == name).unwrap();
    assert_eq!(group("Blink_L")["presetName"], "blink_l");
    assert_eq!(group("Blink_L")["binds"][0]["weight"], 100.0);
    assert_eq!(group("Joy")["binds"][1]["weight"], 100.0);
    // 0.x has no surprised preset, and Perfect Sync shapes are groups of their own.
    assert_eq!(group("Surprised")["presetName"], "unknown");
    assert_eq!(group("jawOpen")["presetName"], "unknown");
    assert_eq!(binds(vrm.expression("jawOpen")), [(2, 1.0)]);
    // Three groups were there, eight presets and five shapes were added (Joy filled in place).
    assert_eq!(groups.len(), 3 + 7 + 5);
}

#[test]
fn targets_without_arkit_names_leave_the_vrm_as_it_was() {
    let a = load_avatar(&repo("tests/data/vrm/mimic_vrm1.vrm")).unwrap();
    let (s, b) = round_trip("tests/data/vrm/mimic_vrm1.vrm", &["4.1.x", "4.1.y"]);
    assert_eq!(s, Some(VrmBinds::default()));
    assert_eq!(
        a.document["extensions"]["VRMC_vrm"],
        b.document["extensions"]["VRMC_vrm"]
    );
    assert_eq!(a.vrm, b.vrm);
}
