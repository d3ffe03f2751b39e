//! The GLB writer: JSON chunk built with serde_json, binary chunk by hand.

use crate::{GltfError, Morph, Take, split_vertices};
use glam::{Vec2, Vec3};
use mimic_types::TextureImage;
use serde_json::{Value, json};
use std::io::Write;

/// One material of the mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfMaterial {
    /// Name.
    pub name: String,
    /// Base colour, linear RGBA.
    pub base_color: [f32; 4],
    /// Drawn blended (see-through) rather than opaque.
    pub blend: bool,
    /// Base colour texture (index into [`GltfMesh::textures`], over `TEXCOORD_0`), or `None`.
    pub texture: Option<usize>,
}

/// The rig's mesh, in rig units and the rig's vertex order.
#[derive(Clone, Copy, Debug)]
pub struct GltfMesh<'a> {
    /// Rest positions.
    pub positions: &'a [Vec3],
    /// Triangles (counter-clockwise seen from outside).
    pub triangles: &'a [[u32; 3]],
    /// Texture coordinates (OBJ convention); empty if none.
    pub uvs: &'a [Vec2],
    /// Per-triangle indices into `uvs`; empty if none.
    pub uv_triangles: &'a [[u32; 3]],
    /// Materials.
    pub materials: &'a [GltfMaterial],
    /// Material of each triangle (index into `materials`); empty or `None`: a default grey.
    pub triangle_material: &'a [Option<usize>],
    /// Linear RGB per rig vertex (glTF `COLOR_0`, which multiplies the base colour); empty if none.
    pub colors: &'a [[f32; 3]],
    /// Texture images the materials name (embedded as they were read: PNG or JPEG).
    pub textures: &'a [TextureImage],
}

/// What to write.
#[derive(Clone, Copy, Debug)]
pub struct Scene<'a> {
    /// Name of the mesh node (the rig's name).
    pub name: &'a str,
    /// The mesh.
    pub mesh: GltfMesh<'a>,
    /// Metres per rig unit ([`crate::metres_per_unit`]).
    pub metres_per_unit: f32,
    /// Morph targets over the rig's vertices.
    pub morphs: &'a [Morph],
    /// The animation, if any.
    pub take: Option<&'a Take>,
    /// Centre of the head's rotation, rig units: the head node's origin.
    pub pivot: Vec3,
}

/// What [`write_glb`] wrote.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct GlbSummary {
    /// Bytes of the file.
    pub bytes: usize,
    /// glTF vertices (the rig's, plus those split at UV seams).
    pub vertices: usize,
    /// Primitives (one per material).
    pub primitives: usize,
    /// Morph targets.
    pub targets: usize,
    /// Of them, stored as sparse accessors.
    pub sparse_targets: usize,
    /// Animation keys (0: no animation).
    pub keys: usize,
    /// Seconds from the first key to the last.
    pub duration_s: f32,
}

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;

/// Binary chunk and the JSON arrays that index it.
#[derive(Default)]
pub(crate) struct Builder {
    pub(crate) bin: Vec<u8>,
    pub(crate) views: Vec<Value>,
    pub(crate) accessors: Vec<Value>,
}

impl Builder {
    pub(crate) fn view(
        &mut self,
        bytes: impl IntoIterator<Item = u8>,
        target: Option<u32>,
    ) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let start = self.bin.len();
        self.bin.extend(bytes);
        let mut v = json!({"buffer": 0, "byteOffset": start, "byteLength": self.bin.len() - start});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.views.push(v);
        self.views.len() - 1
    }

    pub(crate) fn accessor(&mut self, a: Value) -> usize {
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    /// A float accessor of `n`-component elements (`kind` "SCALAR", "VEC3", ...), with min/max.
    pub(crate) fn floats(
        &mut self,
        values: &[f32],
        n: usize,
        kind: &str,
        target: Option<u32>,
    ) -> usize {
        let (min, max) = min_max(values, n);
        let view = self.view(le(values), target);
        self.accessor(json!({
            "bufferView": view, "componentType": FLOAT, "count": values.len() / n,
            "type": kind, "min": min, "max": max,
        }))
    }

    /// A VEC3 accessor of `count` elements, zero except at `entries` (ascending index): sparse
    /// when that is smaller than dense. Returns the accessor and whether it is sparse.
    pub(crate) fn vec3_sparse(&mut self, count: usize, entries: &[(u32, Vec3)]) -> (usize, bool) {
        let mut min = entries.iter().fold(Vec3::INFINITY, |a, (_, v)| a.min(*v));
        let mut max = entries
            .iter()
            .fold(Vec3::NEG_INFINITY, |a, (_, v)| a.max(*v));
        if entries.len() < count {
            min = min.min(Vec3::ZERO);
            max = max.max(Vec3::ZERO);
        }
        // Sparse: 4 index + 12 value bytes per entry (at least one); dense: 12 per vertex.
        let sparse = 16 * entries.len().max(1) < 12 * count;
        let (min, max) = (min.to_array().to_vec(), max.to_array().to_vec());
        if sparse {
            let mut entries = entries.to_vec();
            if entries.is_empty() {
                entries.push((0, Vec3::ZERO));
            }
            let idx = self.view(entries.iter().flat_map(|(i, _)| i.to_le_bytes()), None);
            let vals: Vec<f32> = entries.iter().flat_map(|(_, v)| v.to_array()).collect();
            let val = self.view(le(&vals), None);
            let a = self.accessor(json!({
                "componentType": FLOAT, "count": count, "type": "VEC3", "min": min, "max": max,
                "sparse": {
                    "count": entries.len(),
                    "indices": {"bufferView": idx, "componentType": UNSIGNED_INT},
                    "values": {"bufferView": val},
                },
            }));
            (a, true)
        } else {
            let mut dense = vec![0.0f32; 3 * count];
            for (i, v) in entries {
                dense[3 * *i as usize..3 * *i as usize + 3].copy_from_slice(&v.to_array());
            }
            let view = self.view(le(&dense), Some(ARRAY_BUFFER));
            let a = self.accessor(json!({
                "bufferView": view, "componentType": FLOAT, "count": count, "type": "VEC3",
                "min": min, "max": max,
            }));
            (a, false)
        }
    }
}

fn le(values: &[f32]) -> impl Iterator<Item = u8> + '_ {
    values.iter().flat_map(|v| v.to_le_bytes())
}

fn min_max(values: &[f32], n: usize) -> (Vec<f32>, Vec<f32>) {
    let mut min = vec![f32::INFINITY; n];
    let mut max = vec![f32::NEG_INFINITY; n];
    for c in values.chunks_exact(n) {
        for k in 0..n {
            min[k] = min[k].min(c[k]);
            max[k] = max[k].max(c[k]);
        }
    }
    (min, max)
}

/// The morph deltas of `morph` (rig vertices) on the glTF vertices `source`, ascending.
fn on_gltf_vertices(
    deltas: &[(u32, Vec3)],
    source: &[u32],
    scratch: &mut [Vec3],
    name: &str,
) -> Result<Vec<(u32, Vec3)>, GltfError> {
    scratch.fill(Vec3::ZERO);
    for (i, d) in deltas {
        let slot = scratch
            .get_mut(*i as usize)
            .ok_or_else(|| GltfError::MorphVertex {
                name: name.to_string(),
                vertex: *i,
                vertex_count: source.len(),
            })?;
        *slot = *d;
    }
    Ok(source
        .iter()
        .enumerate()
        .filter_map(|(g, s)| {
            let d = scratch[*s as usize];
            (d != Vec3::ZERO).then_some((g as u32, d))
        })
        .collect())
}

/// Writes `scene` as one GLB to `w`: a head node (origin at the pivot; the pose channels move
/// it) holding the mesh node, one primitive per material sharing the vertex attributes and the
/// morph targets, the target names in `mesh.extras.targetNames`, and the take as one animation.
pub fn write_glb(scene: &Scene<'_>, w: &mut impl Write) -> Result<GlbSummary, GltfError> {
    let mesh = &scene.mesh;
    let s = scene.metres_per_unit;
    let n = mesh.positions.len();
    let split = split_vertices(n, mesh.triangles, mesh.uvs, mesh.uv_triangles)?;
    let count = split.source.len();
    let mut b = Builder::default();

    // Vertex attributes: metres; smooth normals of the rig's vertices (+z where undefined).
    let mut rig_normals = vec![Vec3::ZERO; n];
    mimic_solve::normals::vertex_normals(mesh.positions, mesh.triangles, &mut rig_normals);
    let positions: Vec<f32> = split
        .source
        .iter()
        .flat_map(|i| (mesh.positions[*i as usize] * s).to_array())
        .collect();
    let normals: Vec<f32> = split
        .source
        .iter()
        .flat_map(|i| {
            let v = rig_normals[*i as usize];
            if v == Vec3::ZERO { Vec3::Z } else { v }.to_array()
        })
        .collect();
    let mut attributes = json!({
        "POSITION": b.floats(&positions, 3, "VEC3", Some(ARRAY_BUFFER)),
        "NORMAL": b.floats(&normals, 3, "VEC3", Some(ARRAY_BUFFER)),
    });
    if mesh.colors.len() == n {
        let colors: Vec<f32> = split
            .source
            .iter()
            .flat_map(|i| mesh.colors[*i as usize].map(|c| c.clamp(0.0, 1.0)))
            .collect();
        attributes["COLOR_0"] = json!(b.floats(&colors, 3, "VEC3", Some(ARRAY_BUFFER)));
    }
    if !split.uvs.is_empty() {
        let uvs: Vec<f32> = split.uvs.iter().flat_map(|v| v.to_array()).collect();
        attributes["TEXCOORD_0"] = json!(b.floats(&uvs, 2, "VEC2", Some(ARRAY_BUFFER)));
    }

    // Morph targets.
    let with_normals = scene.morphs.iter().any(|m| !m.normals.is_empty());
    let mut scratch = vec![Vec3::ZERO; n];
    let mut targets = Vec::with_capacity(scene.morphs.len());
    let mut sparse_targets = 0;
    for m in scene.morphs {
        let p = on_gltf_vertices(&m.positions, &split.source, &mut scratch, &m.name)?;
        let (pa, sparse) = b.vec3_sparse(count, &p);
        sparse_targets += usize::from(sparse);
        let mut t = json!({"POSITION": pa});
        if with_normals {
            let q = on_gltf_vertices(&m.normals, &split.source, &mut scratch, &m.name)?;
            t["NORMAL"] = json!(b.vec3_sparse(count, &q).0);
        }
        targets.push(t);
    }

    // Materials and one primitive per material used (triangles of no material: a default).
    let mut materials: Vec<Value> = mesh
        .materials
        .iter()
        .map(|m| {
            let mut v = json!({
                "name": m.name,
                "pbrMetallicRoughness": {
                    "baseColorFactor": m.base_color, "metallicFactor": 0.0, "roughnessFactor": 0.6,
                },
            });
            if m.blend {
                v["alphaMode"] = json!("BLEND");
            }
            // A texture needs texture coordinates: without them the material keeps its colour.
            if let Some(t) = m
                .texture
                .filter(|t| *t < mesh.textures.len() && !split.uvs.is_empty())
            {
                v["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": t, "texCoord": 0});
            }
            v
        })
        .collect();
    // Each texture image as it was read, in the binary chunk, with one shared sampler
    // (trilinear, repeating: as mimic_render samples it).
    let images: Vec<Value> = mesh
        .textures
        .iter()
        .map(|t| {
            let view = b.view(t.encoded.iter().copied(), None);
            json!({"name": t.name, "bufferView": view, "mimeType": t.mime})
        })
        .collect();
    let default_material = materials.len();
    let mut groups: Vec<Vec<u32>> = vec![Vec::new(); default_material + 1];
    for (t, tri) in split.triangles.iter().enumerate() {
        let k = mesh
            .triangle_material
            .get(t)
            .copied()
            .flatten()
            .filter(|k| *k < default_material)
            .unwrap_or(default_material);
        groups[k].extend_from_slice(tri);
    }
    if !groups[default_material].is_empty() {
        materials.push(json!({
            "name": "default",
            "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.66, 0.58, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.6},
        }));
    }
    let mut primitives = Vec::new();
    for (k, indices) in groups.iter().enumerate() {
        if indices.is_empty() {
            continue;
        }
        let view = b.view(
            indices.iter().flat_map(|i| i.to_le_bytes()),
            Some(ELEMENT_ARRAY_BUFFER),
        );
        let acc = b.accessor(json!({
            "bufferView": view, "componentType": UNSIGNED_INT, "count": indices.len(), "type": "SCALAR",
        }));
        let mut p = json!({"attributes": attributes, "indices": acc, "material": k, "mode": 4});
        if !targets.is_empty() {
            p["targets"] = json!(targets);
        }
        primitives.push(p);
    }
    let names: Vec<&str> = scene.morphs.iter().map(|m| m.name.as_str()).collect();
    let mut gl_mesh = json!({"name": scene.name, "primitives": primitives});
    if !targets.is_empty() {
        gl_mesh["weights"] = json!(vec![0.0; targets.len()]);
        gl_mesh["extras"] = json!({ "targetNames": names });
    }

    let pivot = (scene.pivot * s).to_array();
    let mut root = json!({
        "asset": {
            "version": "2.0",
            "generator": concat!("mimic ", env!("CARGO_PKG_VERSION")),
            "extras": {"metresPerRigUnit": s},
        },
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"name": "head", "translation": pivot, "children": [1]},
            {"name": scene.name, "mesh": 0, "translation": (-scene.pivot * s).to_array()},
        ],
        "meshes": [gl_mesh],
        "materials": materials,
    });
    if !images.is_empty() {
        let textures: Vec<Value> = (0..images.len())
            .map(|k| json!({"sampler": 0, "source": k}))
            .collect();
        root["images"] = Value::Array(images);
        root["textures"] = Value::Array(textures);
        root["samplers"] = json!([{
            "magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497,
        }]);
    }

    // The animation.
    let mut keys = 0;
    let mut duration_s = 0.0;
    if let Some(take) = scene.take.filter(|t| !t.is_empty()) {
        if take.target_count() != targets.len() {
            return Err(GltfError::TargetCount {
                take: take.target_count(),
                mesh: targets.len(),
            });
        }
        keys = take.len();
        duration_s = take.duration_s();
        let interpolation = take.interpolation.gltf_name();
        let input = b.floats(take.times(), 1, "SCALAR", None);
        let mut samplers = Vec::new();
        let mut channels = Vec::new();
        if !targets.is_empty() {
            let out = b.floats(take.weights(), 1, "SCALAR", None);
            samplers.push(json!({"input": input, "output": out, "interpolation": interpolation}));
            channels.push(
                json!({"sampler": samplers.len() - 1, "target": {"node": 1, "path": "weights"}}),
            );
        }
        if take.has_pose() {
            let r: Vec<f32> = take.rotations().iter().flat_map(|q| q.to_array()).collect();
            let out = b.floats(&r, 4, "VEC4", None);
            samplers.push(json!({"input": input, "output": out, "interpolation": interpolation}));
            channels.push(
                json!({"sampler": samplers.len() - 1, "target": {"node": 0, "path": "rotation"}}),
            );
            let p: Vec<f32> = take
                .translations()
                .iter()
                .flat_map(|t| (*t + scene.pivot * s).to_array())
                .collect();
            let out = b.floats(&p, 3, "VEC3", None);
            samplers.push(json!({"input": input, "output": out, "interpolation": interpolation}));
            channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": 0, "path": "translation"}}));
        }
        if !channels.is_empty() {
            root["animations"] =
                json!([{"name": "take", "samplers": samplers, "channels": channels}]);
        }
    }

    while !b.bin.len().is_multiple_of(4) {
        b.bin.push(0);
    }
    if b.bin.len() > u32::MAX as usize - 1024 {
        return Err(GltfError::TooLarge(b.bin.len()));
    }
    root["buffers"] = json!([{"byteLength": b.bin.len()}]);
    root["bufferViews"] = Value::Array(b.views);
    root["accessors"] = Value::Array(b.accessors);
    let total = write_container(&root, &b.bin, w)?;
    Ok(GlbSummary {
        bytes: total,
        vertices: count,
        primitives: groups.iter().filter(|g| !g.is_empty()).count(),
        targets: targets.len(),
        sparse_targets,
        keys,
        duration_s,
    })
}

/// Writes the GLB container (header, JSON chunk, binary chunk) of `root` and `bin` to `w`;
/// returns the file's length.
pub(crate) fn write_container(
    root: &Value,
    bin: &[u8],
    w: &mut impl Write,
) -> Result<usize, GltfError> {
    let mut text = serde_json::to_vec(root)?;
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let pad = (4 - bin.len() % 4) % 4;
    let bin_len = bin.len() + pad;
    let total = 12 + 8 + text.len() + 8 + bin_len;
    if total > u32::MAX as usize {
        return Err(GltfError::TooLarge(total));
    }
    let u = |x: usize| (x as u32).to_le_bytes();
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&u(total))?;
    w.write_all(&u(text.len()))?;
    w.write_all(b"JSON")?;
    w.write_all(&text)?;
    w.write_all(&u(bin_len))?;
    w.write_all(b"BIN\0")?;
    w.write_all(bin)?;
    w.write_all(&[0u8; 3][..pad])?;
    Ok(total)
}
