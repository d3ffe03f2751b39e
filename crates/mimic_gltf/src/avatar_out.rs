//! The avatar written back: the file's own document with mimic's additions, every other node,
//! skin, material, texture, extension and byte kept (docs/avatars.md).
//!
//! - Buffers are merged into the GLB's one binary chunk (each buffer's views shifted by where it
//!   now starts, 16-byte aligned, so every accessor keeps its alignment); images that were files
//!   or data URIs become buffer views. Nothing else in the document changes.
//! - The face mesh gains the morph targets after its own: each primitive the targets of its
//!   vertex array (primitives sharing an array share the accessors), deltas turned from world
//!   space into the file's space ([`FaceMesh::to_file`]: the bind space of a skinned mesh), and
//!   `extras.targetNames`, `weights` extended to match. Targets that move only a drawn part (the
//!   jaw's and the eyeballs' columns) go on that part's mesh instead, the same way
//!   ([`crate::avatar_placement`]), and the take keys its node's weights too.
//! - A VRM's expressions are bound to the new targets where they carry ARKit names
//!   ([`crate::vrm_out`]).
//! - The take becomes one more animation: the face node's weights (its own targets held at their
//!   defaults), and the head rotation and translation on the head joint (the VRM humanoid head,
//!   else a node named like a head, else the face's node), as local keys under its parent.

use crate::avatar_placement::{MeshTargets, place};
use crate::glb::{Builder, write_container};
use crate::vrm_out::{VrmBinds, bind_expressions};
use crate::{GltfError, Morph, Take};
use glam::{Mat3, Vec3};
use mimic_avatar::{Avatar, FaceMesh};
use serde_json::{Value, json};
use std::io::Write;

/// What [`write_avatar_glb`] wrote.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct AvatarGlbSummary {
    /// Bytes of the file.
    pub bytes: usize,
    /// Vertices of the avatar (each shared vertex array once), unchanged by the writer.
    pub vertices: usize,
    /// Meshes, unchanged.
    pub meshes: usize,
    /// The face mesh's morph targets: the file's own plus mimic's.
    pub targets: usize,
    /// Of them, added by mimic.
    pub added_targets: usize,
    /// Of the added targets, those whose positions are sparse accessors (on every vertex array).
    pub sparse_targets: usize,
    /// Targets added to the drawn parts' meshes (the eyeballs, the lower teeth and tongue: the
    /// rigid parts' columns, which move no face vertex).
    pub part_targets: usize,
    /// Animation keys (0: no animation).
    pub keys: usize,
    /// Seconds from the first key to the last.
    pub duration_s: f32,
    /// The node the head pose keys move (None: no pose keys).
    pub head_node: Option<String>,
    /// A VRM's expressions bound to mimic's targets (None: not a VRM).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vrm_expressions: Option<VrmBinds>,
}

/// The node the head pose goes on: the VRM humanoid head bone; else the node (a skin's joint
/// first) whose name says head best (`head`, then `*_head` / `*:head` / `*.head`, then any name
/// holding `head` but not `end`, `top`, `tip` or `nub`), never a node that shows a mesh (a mesh
/// named `Head` is the face itself); else, for a skinned face, the joint that carries most of its
/// skin weight; else the face's node.
pub fn head_node(avatar: &Avatar, face: &FaceMesh) -> usize {
    if let Some(h) = avatar.vrm.as_ref().and_then(|v| v.head()) {
        return h;
    }
    let score = |k: usize| -> u8 {
        let Some(name) = avatar.nodes[k].name.as_deref() else {
            return 0;
        };
        let l = name.to_ascii_lowercase();
        if avatar.nodes[k].mesh.is_some() {
            0
        } else if l == "head" {
            3
        } else if ["_head", ":head", ".head", " head"]
            .iter()
            .any(|e| l.ends_with(e))
        {
            2
        } else if l.contains("head") && !["end", "top", "tip", "nub"].iter().any(|w| l.contains(w))
        {
            1
        } else {
            0
        }
    };
    let joints: Vec<usize> = avatar
        .skins
        .iter()
        .flat_map(|s| s.joints.iter().copied())
        .collect();
    let candidates = joints.iter().copied().chain(0..avatar.nodes.len());
    let best = candidates.fold((0u8, None), |(bs, bk), k| {
        let s = score(k);
        if s > bs { (s, Some(k)) } else { (bs, bk) }
    });
    if let (_, Some(k)) = best {
        return k;
    }
    heaviest_joint(avatar, face).unwrap_or(face.node)
}

/// The joint of the face's skin that carries the most weight over the face's own vertices.
fn heaviest_joint(avatar: &Avatar, face: &FaceMesh) -> Option<usize> {
    let skin = &avatar.skins[avatar.nodes[face.node].skin?];
    let mut total = vec![0.0f32; skin.joints.len()];
    for &(array, _) in &face.arrays[..face.face_arrays] {
        let va = &avatar.vertex_arrays[array];
        for (j, w) in va.joints.iter().zip(&va.weights) {
            for (k, weight) in w.to_array().iter().enumerate() {
                if let Some(t) = total.get_mut(j[k] as usize) {
                    *t += weight;
                }
            }
        }
    }
    let (k, _) = total
        .iter()
        .enumerate()
        .filter(|(_, t)| **t > 0.0)
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    skin.joints.get(k).copied()
}

/// Writes `avatar` back as one GLB (module docs) with `morphs` (over `face`'s working vertices,
/// in the file's units per unit of weight) and, if given, `take` (weights per key: one per morph).
pub fn write_avatar_glb(
    avatar: &Avatar,
    face: &FaceMesh,
    morphs: &[Morph],
    take: Option<&Take>,
    w: &mut impl Write,
) -> Result<AvatarGlbSummary, GltfError> {
    let mut doc = avatar.document.clone();
    let mut b = merged_buffers(avatar, &mut doc);
    let placed = place(avatar, face, morphs);
    let own = own_target_count(avatar, face.mesh);
    let (mut added, mut sparse_targets, mut part_targets) = (0, 0, 0);
    let mut owns = Vec::with_capacity(placed.len());
    for (i, mt) in placed.iter().enumerate() {
        let own_here = own_target_count(avatar, mt.mesh);
        let subset: Vec<&Morph> = mt.morphs.iter().map(|&k| &morphs[k]).collect();
        let (a, sparse) = add_targets(avatar, face, mt, &subset, own_here, &mut b, &mut doc);
        pad_weight_keys(avatar, mt.mesh, own_here, a, &mut b, &mut doc);
        if i == 0 {
            (added, sparse_targets) = (a, sparse);
        } else {
            part_targets += a;
        }
        owns.push(own_here);
    }
    let vrm_expressions = avatar.vrm.as_ref().map(|_| {
        let names: Vec<String> = placed[0]
            .morphs
            .iter()
            .map(|&k| morphs[k].name.clone())
            .collect();
        bind_expressions(avatar, face, own, &names, &mut doc)
    });
    let head = head_node(avatar, face);
    let (keys, duration_s) = match take.filter(|t| !t.is_empty()) {
        Some(t) => {
            if t.target_count() != morphs.len() {
                return Err(GltfError::TargetCount {
                    take: t.target_count(),
                    mesh: morphs.len(),
                });
            }
            add_animation(avatar, face, (&placed, &owns), head, t, &mut b, &mut doc);
            (t.len(), t.duration_s())
        }
        None => (0, 0.0),
    };
    while !b.bin.len().is_multiple_of(4) {
        b.bin.push(0);
    }
    if b.bin.len() > u32::MAX as usize - 1024 {
        return Err(GltfError::TooLarge(b.bin.len()));
    }
    doc["buffers"] = json!([{"byteLength": b.bin.len()}]);
    doc["bufferViews"] = Value::Array(std::mem::take(&mut b.views));
    doc["accessors"] = Value::Array(std::mem::take(&mut b.accessors));
    let bytes = write_container(&doc, &b.bin, w)?;
    Ok(AvatarGlbSummary {
        bytes,
        vertices: avatar.vertex_count(),
        meshes: avatar.meshes.len(),
        targets: own + added,
        added_targets: added,
        sparse_targets,
        part_targets,
        keys,
        duration_s,
        head_node: take
            .filter(|t| t.has_pose() && !t.is_empty())
            .map(|_| node_name(avatar, head)),
        vrm_expressions,
    })
}

/// Node `k`'s name, `#K` when it has none.
fn node_name(avatar: &Avatar, k: usize) -> String {
    avatar.nodes[k]
        .name
        .clone()
        .unwrap_or_else(|| format!("#{k}"))
}

/// Every buffer in one binary chunk, the document's views pointing into it, images from files
/// or data URIs moved into buffer views; the builder holds the document's views and accessors.
fn merged_buffers(avatar: &Avatar, doc: &mut Value) -> Builder {
    let mut b = Builder::default();
    let mut starts = Vec::with_capacity(avatar.buffers.len());
    for buffer in &avatar.buffers {
        while !b.bin.len().is_multiple_of(16) {
            b.bin.push(0);
        }
        starts.push(b.bin.len());
        b.bin.extend_from_slice(buffer);
    }
    let views = doc
        .get_mut("bufferViews")
        .and_then(Value::as_array_mut)
        .map(std::mem::take)
        .unwrap_or_default();
    for mut v in views {
        let buffer = v["buffer"].as_u64().unwrap_or(0) as usize;
        let offset = v["byteOffset"].as_u64().unwrap_or(0) as usize;
        v["buffer"] = json!(0);
        v["byteOffset"] = json!(starts.get(buffer).copied().unwrap_or(0) + offset);
        b.views.push(v);
    }
    b.accessors = doc
        .get_mut("accessors")
        .and_then(Value::as_array_mut)
        .map(std::mem::take)
        .unwrap_or_default();
    if let Some(images) = doc.get_mut("images").and_then(Value::as_array_mut) {
        for (k, image) in images.iter_mut().enumerate() {
            let Some(obj) = image.as_object_mut() else {
                continue;
            };
            if obj.remove("uri").is_none() {
                continue;
            }
            let Some(read) = avatar.images.get(k) else {
                continue;
            };
            let view = b.view(read.bytes.iter().copied(), None);
            obj.insert("bufferView".into(), json!(view));
            let mime = read.mime_type.clone().unwrap_or_else(|| "image/png".into());
            obj.insert("mimeType".into(), json!(mime));
        }
    }
    b
}

/// The face mesh's own morph target count (every primitive has the same, glTF's rule).
fn own_target_count(avatar: &Avatar, mesh: usize) -> usize {
    avatar.meshes[mesh]
        .primitives
        .first()
        .map_or(0, |p| p.targets.len())
}

/// Adds `morphs` to every primitive of `mt`'s mesh (the face or a part); returns how many were
/// added and how many of them are sparse.
fn add_targets(
    avatar: &Avatar,
    face: &FaceMesh,
    mt: &MeshTargets,
    morphs: &[&Morph],
    own: usize,
    b: &mut Builder,
    doc: &mut Value,
) -> (usize, usize) {
    if morphs.is_empty() {
        return (0, 0);
    }
    let mut sparse = vec![true; morphs.len()];
    let with_normals = morphs.iter().any(|m| !m.normals.is_empty());
    // Per vertex array of the face: one accessor pair per morph; every file copy of a welded
    // working vertex gets its delta.
    let working = face.mesh_data.positions.len();
    let mut scratch = vec![Vec3::ZERO; working];
    let mut on_array = |entries: &[(u32, Vec3)], offset: u32, count: usize| -> Vec<(u32, Vec3)> {
        for (v, d) in entries {
            if let Some(slot) = scratch.get_mut(*v as usize) {
                *slot = *d;
            }
        }
        let out = (0..count)
            .filter_map(|i| {
                let f = offset as usize + i;
                let d = scratch[face.weld[f] as usize];
                (d != Vec3::ZERO).then(|| (i as u32, face.to_file[f] * d))
            })
            .collect();
        for (v, _) in entries {
            if let Some(slot) = scratch.get_mut(*v as usize) {
                *slot = Vec3::ZERO;
            }
        }
        out
    };
    let mut per_array: Vec<(usize, Vec<Value>)> = Vec::new();
    for &(array, offset) in &mt.arrays {
        let count = avatar.vertex_arrays[array].positions.len();
        let targets = morphs
            .iter()
            .zip(sparse.iter_mut())
            .map(|(m, all_sparse)| {
                let p = on_array(&m.positions, offset, count);
                let (position, is_sparse) = b.vec3_sparse(count, &p);
                *all_sparse &= is_sparse;
                let mut t = json!({"POSITION": position});
                if with_normals {
                    let q = on_array(&m.normals, offset, count);
                    t["NORMAL"] = json!(b.vec3_sparse(count, &q).0);
                }
                t
            })
            .collect();
        per_array.push((array, targets));
    }
    let mesh = &avatar.meshes[mt.mesh];
    for (k, p) in mesh.primitives.iter().enumerate() {
        let ours = match per_array.iter().find(|(a, _)| *a == p.vertices) {
            Some((_, t)) => t.clone(),
            None => {
                // A primitive on another vertex array: zero targets (no buffer view).
                let count = avatar.vertex_arrays[p.vertices].positions.len();
                let zero = b.accessor(json!({
                    "componentType": 5126, "count": count, "type": "VEC3",
                    "min": [0.0, 0.0, 0.0], "max": [0.0, 0.0, 0.0],
                }));
                vec![json!({"POSITION": zero}); morphs.len()]
            }
        };
        let prim = &mut doc["meshes"][mt.mesh]["primitives"][k];
        let mut targets = prim
            .get("targets")
            .and_then(Value::as_array)
            .cloned()
            .unwrap_or_default();
        targets.extend(ours);
        prim["targets"] = Value::Array(targets);
    }
    let gl_mesh = &mut doc["meshes"][mt.mesh];
    let mut names: Vec<Value> = (0..own)
        .map(|k| {
            json!(
                mesh.target_names
                    .get(k)
                    .cloned()
                    .unwrap_or_else(|| format!("target_{k}"))
            )
        })
        .collect();
    names.extend(morphs.iter().map(|m| json!(m.name)));
    let mut weights: Vec<Value> = (0..own)
        .map(|k| json!(mesh.weights.get(k).copied().unwrap_or(0.0)))
        .collect();
    weights.extend(std::iter::repeat_n(json!(0.0), morphs.len()));
    gl_mesh["weights"] = Value::Array(weights);
    if !gl_mesh.get("extras").is_some_and(Value::is_object) {
        gl_mesh["extras"] = json!({});
    }
    gl_mesh["extras"]["targetNames"] = Value::Array(names);
    // Nodes that override the mesh's weights keep theirs and get zeros for the new targets.
    for n in avatar.nodes_of_mesh(mt.mesh) {
        // `get_mut`, not indexing: an index would insert a null `weights`.
        if let Some(ws) = doc["nodes"][n]
            .get_mut("weights")
            .and_then(Value::as_array_mut)
        {
            ws.extend(std::iter::repeat_n(json!(0.0), morphs.len()));
        }
    }
    (morphs.len(), sparse.iter().filter(|s| **s).count())
}

/// The avatar's own animations that key `mesh`'s weights get a zero for each added target in
/// every key (and tangent), so that their keys keep the width of the mesh's targets.
fn pad_weight_keys(
    avatar: &Avatar,
    mesh: usize,
    own: usize,
    added: usize,
    b: &mut Builder,
    doc: &mut Value,
) {
    if added == 0 || own == 0 {
        return;
    }
    let face_nodes: Vec<usize> = avatar.nodes_of_mesh(mesh).collect();
    for (ai, a) in avatar.animations.iter().enumerate() {
        for (ci, c) in a.channels.iter().enumerate() {
            if c.path != mimic_avatar::ChannelPath::Weights || !face_nodes.contains(&c.node) {
                continue;
            }
            let mut padded = Vec::with_capacity(c.values.len() / own * (own + added));
            for block in c.values.chunks(own) {
                padded.extend_from_slice(block);
                padded.extend(std::iter::repeat_n(0.0, added));
            }
            let out = b.floats(&padded, 1, "SCALAR", None);
            let sampler = &doc["animations"][ai]["channels"][ci]["sampler"];
            if let Some(si) = sampler.as_u64() {
                doc["animations"][ai]["samplers"][si as usize]["output"] = json!(out);
            }
        }
    }
}

/// Adds the take as an animation (module docs).
fn add_animation(
    avatar: &Avatar,
    face: &FaceMesh,
    (placed, owns): (&[MeshTargets], &[usize]),
    head: usize,
    take: &Take,
    b: &mut Builder,
    doc: &mut Value,
) {
    let interpolation = take.interpolation.gltf_name();
    let input = b.floats(take.times(), 1, "SCALAR", None);
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    let mut channel = |b: &mut Builder, values: &[f32], n: usize, kind: &str, node, path| {
        let out = b.floats(values, n, kind, None);
        samplers.push(json!({"input": input, "output": out, "interpolation": interpolation}));
        channels
            .push(json!({"sampler": samplers.len() - 1, "target": {"node": node, "path": path}}));
    };
    let added = take.target_count();
    // Each mesh that gained targets: its node's weights, its own targets at their defaults.
    for (i, (mt, &own)) in placed.iter().zip(owns).enumerate() {
        let node = if i == 0 {
            Some(face.node)
        } else {
            avatar.nodes_of_mesh(mt.mesh).next()
        };
        let Some(node) = node.filter(|_| added > 0 && !mt.morphs.is_empty()) else {
            continue;
        };
        let defaults = &avatar.meshes[mt.mesh].weights;
        let mut out = Vec::with_capacity(take.len() * (own + mt.morphs.len()));
        for key in take.weights().chunks_exact(added) {
            out.extend((0..own).map(|k| defaults.get(k).copied().unwrap_or(0.0)));
            out.extend(mt.morphs.iter().map(|&k| key[k]));
        }
        channel(b, &out, 1, "SCALAR", node, "weights");
    }
    if take.has_pose() {
        let node = &avatar.nodes[head];
        let parent = node
            .parent
            .map_or(glam::Mat4::IDENTITY, |p| avatar.nodes[p].world);
        let (_, parent_rot, _) = parent.to_scale_rotation_translation();
        let to_parent = {
            let m = Mat3::from_mat4(parent);
            if m.determinant().abs() > f32::MIN_POSITIVE {
                m.inverse()
            } else {
                Mat3::IDENTITY
            }
        };
        let (scale, rest_rot, rest_t) = node.local.to_scale_rotation_translation();
        let rot: Vec<f32> = take
            .rotations()
            .iter()
            .flat_map(|r| {
                (parent_rot.inverse() * *r * parent_rot * rest_rot)
                    .normalize()
                    .to_array()
            })
            .collect();
        let tr: Vec<f32> = take
            .translations()
            .iter()
            .flat_map(|t| (rest_t + to_parent * *t).to_array())
            .collect();
        channel(b, &rot, 4, "VEC4", head, "rotation");
        channel(b, &tr, 3, "VEC3", head, "translation");
        // An animated node must use TRS, not a matrix.
        let n = &mut doc["nodes"][head];
        if let Some(obj) = n.as_object_mut()
            && obj.remove("matrix").is_some()
        {
            obj.insert("translation".into(), json!(rest_t.to_array()));
            obj.insert("rotation".into(), json!(rest_rot.to_array()));
            obj.insert("scale".into(), json!(scale.to_array()));
        }
    }
    let mut animations = doc
        .get("animations")
        .and_then(Value::as_array)
        .cloned()
        .unwrap_or_default();
    animations.push(json!({"name": "mimic take", "samplers": samplers, "channels": channels}));
    doc["animations"] = Value::Array(animations);
}
