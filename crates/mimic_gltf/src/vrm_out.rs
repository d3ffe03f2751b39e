//! A VRM written back stays a VRM whose expressions drive mimic's new morph targets
//! (docs/avatars.md, "VRM out"). When the targets mimic adds carry ARKit names (blendshape
//! mode: the rig's named shapes; ICT-FaceKit's `eyeBlink_L` spelling taken too), the VRM
//! presets that bind nothing yet are bound to them through [`PRESETS`], and each ARKit shape
//! present becomes a Perfect Sync expression of its own name. The avatar's own expressions are
//! kept: a preset with any bind is left alone, and its targets keep their indices (mimic's come
//! after them).
//!
//! - VRM 1.0: `expressions.preset.NAME.morphTargetBinds [{node, index, weight 0..1}]` and
//!   `expressions.custom.SHAPE`.
//! - VRM 0.x: `blendShapeMaster.blendShapeGroups [{name, presetName, binds [{mesh, index,
//!   weight 0..100}]}]`; presets 0.x lacks (`surprised`) and the Perfect Sync shapes are groups
//!   with `presetName` `unknown`.

use mimic_avatar::{Avatar, FaceMesh, VrmVersion};
use serde_json::{Value, json};

pub use mimic_types::arkit::ARKIT_NAMES;

/// The VRM 1.0 presets mimic binds and the ARKit shapes each is made of, with their weights
/// (0..1). ARKit's Left is the subject's, as VRM's `blinkLeft` is the avatar's own left.
pub const PRESETS: &[(&str, &[(&str, f32)])] = &[
    ("blink", &[("eyeBlinkLeft", 1.0), ("eyeBlinkRight", 1.0)]),
    ("blinkLeft", &[("eyeBlinkLeft", 1.0)]),
    ("blinkRight", &[("eyeBlinkRight", 1.0)]),
    ("aa", &[("jawOpen", 1.0)]),
    (
        "ih",
        &[
            ("jawOpen", 0.2),
            ("mouthStretchLeft", 0.6),
            ("mouthStretchRight", 0.6),
        ],
    ),
    ("ou", &[("mouthPucker", 1.0), ("mouthFunnel", 0.3)]),
    (
        "ee",
        &[
            ("jawOpen", 0.3),
            ("mouthSmileLeft", 0.4),
            ("mouthSmileRight", 0.4),
            ("mouthStretchLeft", 0.4),
            ("mouthStretchRight", 0.4),
        ],
    ),
    ("oh", &[("jawOpen", 0.5), ("mouthFunnel", 1.0)]),
    (
        "happy",
        &[
            ("mouthSmileLeft", 1.0),
            ("mouthSmileRight", 1.0),
            ("cheekSquintLeft", 0.5),
            ("cheekSquintRight", 0.5),
        ],
    ),
    (
        "angry",
        &[
            ("browDownLeft", 1.0),
            ("browDownRight", 1.0),
            ("noseSneerLeft", 0.5),
            ("noseSneerRight", 0.5),
            ("mouthPressLeft", 0.5),
            ("mouthPressRight", 0.5),
        ],
    ),
    (
        "sad",
        &[
            ("browInnerUp", 1.0),
            ("mouthFrownLeft", 1.0),
            ("mouthFrownRight", 1.0),
        ],
    ),
    (
        "relaxed",
        &[
            ("mouthSmileLeft", 0.5),
            ("mouthSmileRight", 0.5),
            ("eyeSquintLeft", 0.4),
            ("eyeSquintRight", 0.4),
        ],
    ),
    (
        "surprised",
        &[
            ("browInnerUp", 1.0),
            ("browOuterUpLeft", 1.0),
            ("browOuterUpRight", 1.0),
            ("eyeWideLeft", 1.0),
            ("eyeWideRight", 1.0),
            ("jawOpen", 0.3),
        ],
    ),
];

/// VRM 1.0 preset names to VRM 0.x's `presetName` and group name (`surprised` has none in 0.x).
const V0_NAMES: &[(&str, &str, &str)] = &[
    ("blink", "blink", "Blink"),
    ("blinkLeft", "blink_l", "Blink_L"),
    ("blinkRight", "blink_r", "Blink_R"),
    ("aa", "a", "A"),
    ("ih", "i", "I"),
    ("ou", "u", "U"),
    ("ee", "e", "E"),
    ("oh", "o", "O"),
    ("happy", "joy", "Joy"),
    ("angry", "angry", "Angry"),
    ("sad", "sorrow", "Sorrow"),
    ("relaxed", "fun", "Fun"),
];

/// The VRM expressions [`crate::write_avatar_glb`] bound to mimic's targets.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct VrmBinds {
    /// VRM 1.0 preset names bound to mimic's targets (presets the avatar had bound are not).
    pub presets: Vec<String>,
    /// Perfect Sync expressions added, one per ARKit shape present.
    pub custom: Vec<String>,
}

pub use mimic_types::arkit::arkit_name;

/// The ARKit shapes among `names` (mimic's added targets, from index `own` on), in first-seen
/// order, each with the target indices that carry it.
fn arkit_targets(names: &[String], own: usize) -> Vec<(&'static str, Vec<usize>)> {
    let mut out: Vec<(&'static str, Vec<usize>)> = Vec::new();
    for (k, name) in names.iter().enumerate() {
        let Some(a) = arkit_name(name) else {
            continue;
        };
        match out.iter_mut().find(|(n, _)| *n == a) {
            Some((_, ks)) => ks.push(own + k),
            None => out.push((a, vec![own + k])),
        }
    }
    out
}

/// The (target index, weight) pairs of preset `row` over the shapes present.
fn preset_binds(row: &[(&str, f32)], shapes: &[(&'static str, Vec<usize>)]) -> Vec<(usize, f32)> {
    row.iter()
        .flat_map(|(shape, w)| {
            shapes
                .iter()
                .filter(move |(n, _)| n == shape)
                .flat_map(move |(_, ks)| ks.iter().map(move |k| (*k, *w)))
        })
        .collect()
}

/// Whether a VRM 1.0 expression (or 0.x group) sets anything: morph, material or texture binds.
fn has_binds(e: &Value) -> bool {
    [
        "morphTargetBinds",
        "materialColorBinds",
        "textureTransformBinds",
        "binds",
        "materialValues",
    ]
    .iter()
    .any(|k| {
        e.get(k)
            .and_then(Value::as_array)
            .is_some_and(|a| !a.is_empty())
    })
}

/// The object at `keys` under `v` (an object), each level made an object if it is missing or
/// is not one; what is there is kept.
fn object_at<'a>(mut v: &'a mut Value, keys: &[&str]) -> &'a mut Value {
    for k in keys {
        if !v.get(*k).is_some_and(Value::is_object) {
            v[*k] = json!({});
        }
        v = &mut v[*k];
    }
    v
}

/// Binds `doc`'s VRM expressions (module docs) to the face's added targets `names` (their
/// indices from `own` on); does nothing for an avatar that is not a VRM or targets without
/// ARKit names.
pub fn bind_expressions(
    avatar: &Avatar,
    face: &FaceMesh,
    own: usize,
    names: &[String],
    doc: &mut Value,
) -> VrmBinds {
    let Some(vrm) = &avatar.vrm else {
        return VrmBinds::default();
    };
    let shapes = arkit_targets(names, own);
    if shapes.is_empty() || !doc.is_object() {
        return VrmBinds::default();
    }
    match vrm.version {
        VrmVersion::V1 => bind_v1(face.node, &shapes, doc),
        VrmVersion::V0 => bind_v0(face.mesh, &shapes, doc),
    }
}

/// VRM 1.0: presets and `custom` under `extensions.VRMC_vrm.expressions`.
fn bind_v1(node: usize, shapes: &[(&'static str, Vec<usize>)], doc: &mut Value) -> VrmBinds {
    let mut done = VrmBinds::default();
    let binds = |list: &[(usize, f32)]| -> Value {
        list.iter()
            .map(|(k, w)| json!({"node": node, "index": k, "weight": w}))
            .collect()
    };
    let expressions = object_at(doc, &["extensions", "VRMC_vrm", "expressions"]);
    let preset = object_at(expressions, &["preset"]);
    for (name, row) in PRESETS {
        if preset.get(*name).is_some_and(has_binds) {
            continue;
        }
        let list = preset_binds(row, shapes);
        if list.is_empty() {
            continue;
        }
        // An expression there without binds keeps its other fields (isBinary, overrides).
        object_at(preset, &[name])["morphTargetBinds"] = binds(&list);
        done.presets.push((*name).into());
    }
    let custom = object_at(expressions, &["custom"]);
    for (shape, ks) in shapes {
        if custom.get(*shape).is_some() {
            continue;
        }
        let list: Vec<(usize, f32)> = ks.iter().map(|k| (*k, 1.0)).collect();
        custom[*shape] = json!({"morphTargetBinds": binds(&list)});
        done.custom.push((*shape).into());
    }
    done
}

/// VRM 0.x: groups in `extensions.VRM.blendShapeMaster.blendShapeGroups`.
fn bind_v0(mesh: usize, shapes: &[(&'static str, Vec<usize>)], doc: &mut Value) -> VrmBinds {
    let mut done = VrmBinds::default();
    let binds = |list: &[(usize, f32)]| -> Value {
        list.iter()
            .map(|(k, w)| json!({"mesh": mesh, "index": k, "weight": w * 100.0}))
            .collect()
    };
    let group = |name: &str, preset: &str, list: &[(usize, f32)]| {
        json!({
            "name": name, "presetName": preset, "binds": binds(list),
            "materialValues": [], "isBinary": false,
        })
    };
    let master = object_at(doc, &["extensions", "VRM", "blendShapeMaster"]);
    if !master.get("blendShapeGroups").is_some_and(Value::is_array) {
        master["blendShapeGroups"] = json!([]);
    }
    let Some(groups) = master
        .get_mut("blendShapeGroups")
        .and_then(Value::as_array_mut)
    else {
        return done;
    };
    let named = |g: &Value, name: &str| {
        g.get("name")
            .and_then(Value::as_str)
            .is_some_and(|n| n.eq_ignore_ascii_case(name))
    };
    for (name, row) in PRESETS {
        let (preset, group_name) = V0_NAMES
            .iter()
            .find(|(v1, _, _)| v1 == name)
            .map_or(("unknown", "Surprised"), |(_, p, g)| (*p, *g));
        let existing = groups.iter().position(|g| {
            if preset == "unknown" {
                named(g, group_name)
            } else {
                g.get("presetName")
                    .and_then(Value::as_str)
                    .is_some_and(|p| p.eq_ignore_ascii_case(preset))
            }
        });
        if existing.is_some_and(|i| has_binds(&groups[i])) {
            continue;
        }
        let list = preset_binds(row, shapes);
        if list.is_empty() {
            continue;
        }
        match existing
            .and_then(|i| groups.get_mut(i))
            .and_then(Value::as_object_mut)
        {
            Some(g) => {
                g.insert("binds".into(), binds(&list));
            }
            None => groups.push(group(group_name, preset, &list)),
        }
        done.presets.push((*name).into());
    }
    for (shape, ks) in shapes {
        if groups.iter().any(|g| named(g, shape)) {
            continue;
        }
        let list: Vec<(usize, f32)> = ks.iter().map(|k| (*k, 1.0)).collect();
        groups.push(group(shape, "unknown", &list));
        done.custom.push((*shape).into());
    }
    done
}

#[cfg(test)]
mod tests;
