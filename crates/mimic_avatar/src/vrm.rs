//! VRM's view of an avatar: humanoid bones, expressions with their morph target binds, look-at,
//! from VRM 0.x (`extensions.VRM`) or VRM 1.0 (`extensions.VRMC_vrm`). Every node, mesh and
//! morph target a bind names is checked; the rest of the extension stays in the document.

use super::{AvatarError, Mesh, Node};
use glam::Vec3;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;

/// Which VRM the file is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VrmVersion {
    /// VRM 0.x (`extensions.VRM`).
    V0,
    /// VRM 1.0 (`extensions.VRMC_vrm`).
    V1,
}

/// One morph target weight an expression sets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MorphBind {
    /// The mesh whose target it sets.
    pub mesh: usize,
    /// The node VRM 1.0 names (None for VRM 0.x, which names the mesh).
    pub node: Option<usize>,
    /// Morph target index in the mesh.
    pub index: usize,
    /// Weight at full expression, 0..1 (VRM 0.x's 0..100 scaled).
    pub weight: f32,
}

/// An expression (VRM 1.0) or blend shape group (VRM 0.x).
#[derive(Clone, Debug, PartialEq)]
pub struct Expression {
    /// Its name in the file: the preset key, or the custom or group name.
    pub name: String,
    /// Its VRM 1.0 preset name (`aa`, `blink`, `happy`, ...; VRM 0.x presets mapped), if a preset.
    pub preset: Option<String>,
    /// Morph target weights it sets.
    pub binds: Vec<MorphBind>,
    /// Whether it is on or off only (`isBinary`).
    pub is_binary: bool,
}

/// How the eyes look: by turning bones or by expressions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LookAtKind {
    /// The eye bones turn.
    Bone,
    /// The lookUp/Down/Left/Right expressions are weighted.
    Expression,
}

/// A look-at range map: input angle in degrees to output (degrees for bones, weight for expressions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RangeMap {
    /// `inputMaxValue` (VRM 0.x `xRange`).
    pub input_max: f32,
    /// `outputScale` (VRM 0.x `yRange`).
    pub output_scale: f32,
}

/// Look-at: where the eyes sit relative to the head and how far they turn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LookAt {
    /// Bones or expressions.
    pub kind: LookAtKind,
    /// The eyes' point in the head bone's space.
    pub offset_from_head: Vec3,
    /// Horizontal, towards the nose.
    pub horizontal_inner: Option<RangeMap>,
    /// Horizontal, away from the nose.
    pub horizontal_outer: Option<RangeMap>,
    /// Looking down.
    pub vertical_down: Option<RangeMap>,
    /// Looking up.
    pub vertical_up: Option<RangeMap>,
}

/// The VRM extension of an avatar, typed where mimic uses it.
#[derive(Clone, Debug, PartialEq)]
pub struct Vrm {
    /// 0.x or 1.0.
    pub version: VrmVersion,
    /// Humanoid bone name (`head`, `neck`, `leftEye`, ...) to node.
    pub bones: BTreeMap<String, usize>,
    /// Expressions in file order (presets first for VRM 1.0).
    pub expressions: Vec<Expression>,
    /// Look-at, if the file gives one.
    pub look_at: Option<LookAt>,
}

impl Vrm {
    /// The node of humanoid bone `name`.
    pub fn bone(&self, name: &str) -> Option<usize> {
        self.bones.get(name).copied()
    }

    /// The head bone's node.
    pub fn head(&self) -> Option<usize> {
        self.bone("head")
    }

    /// The neck bone's node.
    pub fn neck(&self) -> Option<usize> {
        self.bone("neck")
    }

    /// The left eye bone's node.
    pub fn left_eye(&self) -> Option<usize> {
        self.bone("leftEye")
    }

    /// The right eye bone's node.
    pub fn right_eye(&self) -> Option<usize> {
        self.bone("rightEye")
    }

    /// The expression with VRM 1.0 preset `name`, else the one named `name`.
    pub fn expression(&self, name: &str) -> Option<&Expression> {
        self.expressions
            .iter()
            .find(|e| e.preset.as_deref() == Some(name))
            .or_else(|| self.expressions.iter().find(|e| e.name == name))
    }
}

/// VRM 0.x preset names to VRM 1.0's.
const V0_PRESETS: &[(&str, &str)] = &[
    ("a", "aa"),
    ("i", "ih"),
    ("u", "ou"),
    ("e", "ee"),
    ("o", "oh"),
    ("blink", "blink"),
    ("blink_l", "blinkLeft"),
    ("blink_r", "blinkRight"),
    ("joy", "happy"),
    ("angry", "angry"),
    ("sorrow", "sad"),
    ("fun", "relaxed"),
    ("lookup", "lookUp"),
    ("lookdown", "lookDown"),
    ("lookleft", "lookLeft"),
    ("lookright", "lookRight"),
    ("neutral", "neutral"),
];

/// VRM 1.0's preset names.
const V1_PRESETS: &[&str] = &[
    "happy",
    "angry",
    "sad",
    "relaxed",
    "surprised",
    "aa",
    "ih",
    "ou",
    "ee",
    "oh",
    "blink",
    "blinkLeft",
    "blinkRight",
    "lookUp",
    "lookDown",
    "lookLeft",
    "lookRight",
    "neutral",
];

struct Ctx<'a> {
    path: &'a Path,
    nodes: &'a [Node],
    meshes: &'a [Mesh],
}

impl Ctx<'_> {
    fn err(&self, pointer: &str, message: impl Into<String>) -> AvatarError {
        AvatarError::at(self.path, pointer, message)
    }

    fn index(&self, v: &Value, pointer: &str) -> Result<usize, AvatarError> {
        v.as_u64()
            .and_then(|i| usize::try_from(i).ok())
            .ok_or_else(|| self.err(pointer, "not an index"))
    }

    fn node(&self, v: &Value, pointer: &str) -> Result<usize, AvatarError> {
        let n = self.index(v, pointer)?;
        if n < self.nodes.len() {
            Ok(n)
        } else {
            Err(self.err(
                pointer,
                format!("node {n} does not exist ({} nodes)", self.nodes.len()),
            ))
        }
    }

    /// Checks that `mesh` exists and has morph target `index`.
    fn target(&self, mesh: usize, index: usize, pointer: &str) -> Result<(), AvatarError> {
        let m = self
            .meshes
            .get(mesh)
            .ok_or_else(|| self.err(pointer, format!("mesh {mesh} does not exist")))?;
        let n = m.primitives.first().map_or(0, |p| p.targets.len());
        if index < n {
            Ok(())
        } else {
            Err(self.err(
                pointer,
                format!("morph target {index} of mesh {mesh}, which has {n}"),
            ))
        }
    }
}

fn f32_of(v: Option<&Value>) -> Option<f32> {
    v.and_then(Value::as_f64).map(|x| x as f32)
}

/// The VRM view of `document`, if it has a VRM extension.
pub(crate) fn read(
    path: &Path,
    document: &Value,
    nodes: &[Node],
    meshes: &[Mesh],
) -> Result<Option<Vrm>, AvatarError> {
    let cx = Ctx {
        path,
        nodes,
        meshes,
    };
    if let Some(v1) = document.pointer("/extensions/VRMC_vrm") {
        return read_v1(&cx, v1).map(Some);
    }
    if let Some(v0) = document.pointer("/extensions/VRM") {
        return read_v0(&cx, v0).map(Some);
    }
    Ok(None)
}

fn read_v1(cx: &Ctx<'_>, vrm: &Value) -> Result<Vrm, AvatarError> {
    const AT: &str = "/extensions/VRMC_vrm";
    let mut bones = BTreeMap::new();
    if let Some(map) = vrm
        .pointer("/humanoid/humanBones")
        .and_then(Value::as_object)
    {
        for (name, bone) in map {
            let at = format!("{AT}/humanoid/humanBones/{name}/node");
            let node = bone.get("node").ok_or_else(|| cx.err(&at, "missing"))?;
            bones.insert(name.clone(), cx.node(node, &at)?);
        }
    }
    let mut expressions = Vec::new();
    for group in ["preset", "custom"] {
        let Some(map) = vrm
            .pointer(&format!("/expressions/{group}"))
            .and_then(Value::as_object)
        else {
            continue;
        };
        for (name, e) in map {
            let at = format!("{AT}/expressions/{group}/{name}");
            let mut binds = Vec::new();
            for (k, b) in e
                .get("morphTargetBinds")
                .and_then(Value::as_array)
                .into_iter()
                .flatten()
                .enumerate()
            {
                let bat = format!("{at}/morphTargetBinds/{k}");
                let node = cx.node(
                    b.get("node").unwrap_or(&Value::Null),
                    &format!("{bat}/node"),
                )?;
                let mesh = cx.nodes[node].mesh.ok_or_else(|| {
                    cx.err(&format!("{bat}/node"), format!("node {node} has no mesh"))
                })?;
                let index = cx.index(
                    b.get("index").unwrap_or(&Value::Null),
                    &format!("{bat}/index"),
                )?;
                cx.target(mesh, index, &format!("{bat}/index"))?;
                binds.push(MorphBind {
                    mesh,
                    node: Some(node),
                    index,
                    weight: f32_of(b.get("weight")).unwrap_or(0.0),
                });
            }
            let preset =
                (group == "preset" && V1_PRESETS.contains(&name.as_str())).then(|| name.clone());
            expressions.push(Expression {
                name: name.clone(),
                preset,
                binds,
                is_binary: e.get("isBinary").and_then(Value::as_bool).unwrap_or(false),
            });
        }
    }
    let look_at = vrm.get("lookAt").map(|l| {
        let range = |key: &str| {
            l.get(key).map(|r| RangeMap {
                input_max: f32_of(r.get("inputMaxValue")).unwrap_or(90.0),
                output_scale: f32_of(r.get("outputScale")).unwrap_or(10.0),
            })
        };
        let offset: Vec<f32> = l
            .get("offsetFromHeadBone")
            .and_then(Value::as_array)
            .map(|a| a.iter().filter_map(|x| f32_of(Some(x))).collect())
            .unwrap_or_default();
        LookAt {
            kind: match l.get("type").and_then(Value::as_str) {
                Some("expression") => LookAtKind::Expression,
                _ => LookAtKind::Bone,
            },
            offset_from_head: match offset[..] {
                [x, y, z] => Vec3::new(x, y, z),
                _ => Vec3::ZERO,
            },
            horizontal_inner: range("rangeMapHorizontalInner"),
            horizontal_outer: range("rangeMapHorizontalOuter"),
            vertical_down: range("rangeMapVerticalDown"),
            vertical_up: range("rangeMapVerticalUp"),
        }
    });
    Ok(Vrm {
        version: VrmVersion::V1,
        bones,
        expressions,
        look_at,
    })
}

fn read_v0(cx: &Ctx<'_>, vrm: &Value) -> Result<Vrm, AvatarError> {
    const AT: &str = "/extensions/VRM";
    let mut bones = BTreeMap::new();
    for (k, b) in vrm
        .pointer("/humanoid/humanBones")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .enumerate()
    {
        let at = format!("{AT}/humanoid/humanBones/{k}");
        let name = b
            .get("bone")
            .and_then(Value::as_str)
            .ok_or_else(|| cx.err(&format!("{at}/bone"), "not a bone name"))?;
        let node = cx.node(b.get("node").unwrap_or(&Value::Null), &format!("{at}/node"))?;
        bones.insert(name.to_string(), node);
    }
    let mut expressions = Vec::new();
    for (g, group) in vrm
        .pointer("/blendShapeMaster/blendShapeGroups")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .enumerate()
    {
        let at = format!("{AT}/blendShapeMaster/blendShapeGroups/{g}");
        let name = group
            .get("name")
            .and_then(Value::as_str)
            .unwrap_or_default();
        let preset_name = group
            .get("presetName")
            .and_then(Value::as_str)
            .unwrap_or("unknown")
            .to_ascii_lowercase();
        let preset = V0_PRESETS
            .iter()
            .find(|(v0, _)| *v0 == preset_name)
            .map(|(_, v1)| v1.to_string());
        let mut binds = Vec::new();
        for (k, b) in group
            .get("binds")
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
            .enumerate()
        {
            let bat = format!("{at}/binds/{k}");
            let mesh = cx.index(
                b.get("mesh").unwrap_or(&Value::Null),
                &format!("{bat}/mesh"),
            )?;
            let index = cx.index(
                b.get("index").unwrap_or(&Value::Null),
                &format!("{bat}/index"),
            )?;
            cx.target(mesh, index, &bat)?;
            binds.push(MorphBind {
                mesh,
                node: None,
                index,
                weight: f32_of(b.get("weight")).unwrap_or(0.0) / 100.0,
            });
        }
        expressions.push(Expression {
            name: if name.is_empty() {
                preset_name.clone()
            } else {
                name.to_string()
            },
            preset,
            binds,
            is_binary: group
                .get("isBinary")
                .and_then(Value::as_bool)
                .unwrap_or(false),
        });
    }
    let look_at = vrm.get("firstPerson").map(look_at_v0);
    Ok(Vrm {
        version: VrmVersion::V0,
        bones,
        expressions,
        look_at,
    })
}

/// VRM 0.x `firstPerson` as look-at (`xRange` the input, `yRange` the output of each curve).
fn look_at_v0(fp: &Value) -> LookAt {
    let range = |key: &str| {
        fp.get(key).map(|r| RangeMap {
            input_max: f32_of(r.get("xRange")).unwrap_or(90.0),
            output_scale: f32_of(r.get("yRange")).unwrap_or(10.0),
        })
    };
    let o = fp.get("firstPersonBoneOffset");
    let c = |k: &str| f32_of(o.and_then(|o| o.get(k))).unwrap_or(0.0);
    LookAt {
        kind: match fp.get("lookAtTypeName").and_then(Value::as_str) {
            Some("BlendShape") => LookAtKind::Expression,
            _ => LookAtKind::Bone,
        },
        offset_from_head: Vec3::new(c("x"), c("y"), c("z")),
        horizontal_inner: range("lookAtHorizontalInner"),
        horizontal_outer: range("lookAtHorizontalOuter"),
        vertical_down: range("lookAtVerticalDown"),
        vertical_up: range("lookAtVerticalUp"),
    }
}
