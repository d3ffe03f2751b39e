//! One mesh of an avatar as mimic's working mesh (the rig's face): the mesh's vertex arrays,
//! each once, posed at rest in world space, with what a writer needs to put mimic's deltas back
//! into the file's own space.
//!
//! Vertices the file splits at UV or normal seams (one surface point, several vertices at exactly
//! the same place) are welded into one working vertex, so that a solve cannot pull the copies
//! apart (a crack); [`FaceMesh::weld`] maps each file vertex to its working vertex, and the writer
//! gives every copy the same delta.
//!
//! A vertex of a skinned mesh sits at `sum_k w_k (world(joint_k) * inverse_bind_k) p` (glTF's
//! skinning at the bind pose); any other mesh's at `world(node) * p`. A delta `u` in world space is
//! `A^-1 u` in the file's space, `A` the linear part of that transform ([`FaceMesh::to_file`]).

use crate::{Avatar, AvatarError, Mode};
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};

/// A mesh of the avatar as one mimic mesh (module docs).
#[derive(Clone, Debug)]
pub struct FaceMesh {
    /// The glTF mesh.
    pub mesh: usize,
    /// The node that shows it (the first in file order).
    pub node: usize,
    /// Every mesh in the working mesh: the face first, then the parts.
    pub meshes: Vec<usize>,
    /// How many of `arrays` are the face mesh's (the first ones).
    pub face_arrays: usize,
    /// Its vertex arrays in order, each with the index of its first vertex in the file vertex
    /// list (the arrays' vertices one after another).
    pub arrays: Vec<(usize, u32)>,
    /// Per file vertex: its working vertex (seam copies share one).
    pub weld: Vec<u32>,
    /// The working mesh: rest positions in world space, triangles, UVs (OBJ convention, v up;
    /// one per file vertex, so seams keep their two UVs).
    pub mesh_data: mimic_types::Mesh,
    /// Per file vertex: world delta to the file's space (the inverse of the rest transform's
    /// linear part).
    pub to_file: Vec<Mat3>,
    /// Per working vertex `COLOR_0` times its material's base colour (linear RGBA).
    pub colors: Vec<Vec4>,
    /// Per triangle: its material (None: glTF's default).
    pub triangle_material: Vec<Option<usize>>,
}

/// Which mesh of `avatar` the text `face` names: a mesh name, or `#K` for mesh K.
pub fn find_mesh(avatar: &Avatar, face: &str) -> Option<usize> {
    if let Some(k) = face.strip_prefix('#') {
        return k.parse().ok().filter(|&k: &usize| k < avatar.meshes.len());
    }
    avatar.mesh_named(face)
}

impl FaceMesh {
    /// Mesh `mesh` of `avatar` alone (module docs).
    pub fn of(avatar: &Avatar, mesh: usize) -> Result<Self, AvatarError> {
        Self::of_meshes(avatar, &[mesh])
    }

    /// Meshes `meshes` of `avatar` as one working mesh, the face (`meshes[0]`) first, then the
    /// parts in the order given (their vertices after the face's, so the face's numbering does
    /// not depend on the parts); an error when a mesh is shown by no node or has no triangles.
    pub fn of_meshes(avatar: &Avatar, meshes: &[usize]) -> Result<Self, AvatarError> {
        let mut arrays: Vec<(usize, u32)> = Vec::new();
        let mut array_mesh: Vec<usize> = Vec::new();
        let mut nodes = Vec::with_capacity(meshes.len());
        let mut next = 0u32;
        for &mesh in meshes {
            let pointer = format!("/meshes/{mesh}");
            let bad = |m: String| AvatarError::at(&avatar.path, &pointer, m);
            let m = avatar
                .meshes
                .get(mesh)
                .ok_or_else(|| bad(format!("the file has {} meshes", avatar.meshes.len())))?;
            let node = avatar
                .nodes_of_mesh(mesh)
                .next()
                .ok_or_else(|| bad("no node shows this mesh".into()))?;
            nodes.push(node);
            let before = arrays.len();
            for p in m.primitives.iter().filter(|p| p.mode == Mode::Triangles) {
                if !arrays.iter().any(|(a, _)| *a == p.vertices) {
                    arrays.push((p.vertices, next));
                    array_mesh.push(mesh);
                    next += avatar.vertex_arrays[p.vertices].positions.len() as u32;
                }
            }
            if arrays.len() == before && !m.primitives.iter().any(|p| p.mode == Mode::Triangles) {
                return Err(bad("the mesh has no triangle primitives".into()));
            }
        }
        let face_arrays = array_mesh.iter().take_while(|m| **m == meshes[0]).count();
        let n = next as usize;
        let mut positions = Vec::with_capacity(n);
        let mut to_file = Vec::with_capacity(n);
        let mut weld_keys = Vec::with_capacity(n);
        let any_uv = arrays
            .iter()
            .any(|(a, _)| !avatar.vertex_arrays[*a].tex_coords.is_empty());
        let mut uvs = Vec::new();
        for (k, &(a, _)) in arrays.iter().enumerate() {
            let mesh_k = meshes.iter().position(|m| *m == array_mesh[k]).unwrap_or(0);
            let node = &avatar.nodes[nodes[mesh_k]];
            let joint_mats: Vec<Mat4> = node.skin.map_or_else(Vec::new, |s| {
                let s = &avatar.skins[s];
                s.joints
                    .iter()
                    .zip(&s.inverse_bind_matrices)
                    .map(|(&j, ibm)| avatar.nodes[j].world * *ibm)
                    .collect()
            });
            let va = &avatar.vertex_arrays[a];
            for (i, p) in va.positions.iter().enumerate() {
                let rest = rest_transform(va, i, &joint_mats).unwrap_or(node.world);
                positions.push(rest.transform_point3(*p));
                weld_keys.push(mesh_k as u32);
                let linear = Mat3::from_mat4(rest);
                let inv = if linear.determinant().abs() > f32::MIN_POSITIVE {
                    linear.inverse()
                } else {
                    Mat3::IDENTITY
                };
                to_file.push(inv);
                if any_uv {
                    let t = va.tex_coords.get(i).copied().unwrap_or_default();
                    uvs.push(Vec2::new(t.x, 1.0 - t.y));
                }
            }
        }
        let (weld, welded) = weld_exact(&positions, &weld_keys);
        let mut file_triangles = Vec::new();
        let mut triangle_material = Vec::new();
        let mut vertex_material: Vec<Option<usize>> = vec![None; n];
        for &mesh in meshes {
            for p in avatar.meshes[mesh]
                .primitives
                .iter()
                .filter(|p| p.mode == Mode::Triangles)
            {
                let offset = arrays
                    .iter()
                    .find(|(a, _)| *a == p.vertices)
                    .map_or(0, |(_, o)| *o);
                for t in p.triangles() {
                    let t = t.map(|v| v + offset);
                    t.iter()
                        .for_each(|&v| vertex_material[v as usize] = p.material);
                    file_triangles.push(t);
                    triangle_material.push(p.material);
                }
            }
        }
        let mut colors = vec![Vec4::ONE; welded.len()];
        for &(a, offset) in arrays.iter().rev() {
            let va = &avatar.vertex_arrays[a];
            for i in (0..va.positions.len()).rev() {
                let f = offset as usize + i;
                let base = vertex_material[f]
                    .and_then(|k| avatar.materials.get(k))
                    .map_or(Vec4::ONE, |mat| mat.base_color);
                // The first copy of a welded vertex gives its colour (written last).
                colors[weld[f] as usize] = va.colors.get(i).copied().unwrap_or(Vec4::ONE) * base;
            }
        }
        let triangles = file_triangles
            .iter()
            .map(|t| t.map(|v| weld[v as usize]))
            .collect();
        let uv_triangles = if any_uv { file_triangles } else { Vec::new() };
        Ok(Self {
            mesh: meshes[0],
            node: nodes[0],
            meshes: meshes.to_vec(),
            arrays,
            face_arrays,
            weld,
            mesh_data: mimic_types::Mesh {
                positions: welded,
                triangles,
                uvs,
                uv_triangles,
            },
            to_file,
            colors,
            triangle_material,
        })
    }

    /// File vertices (the arrays' vertices one after another).
    pub fn file_vertex_count(&self) -> usize {
        self.weld.len()
    }
}

/// Each point's first exact copy with the same key (its mesh: parts are never welded to the
/// face): per point the index of its welded point, and the welded points in first-seen order.
fn weld_exact(points: &[Vec3], keys: &[u32]) -> (Vec<u32>, Vec<Vec3>) {
    let mut seen: std::collections::HashMap<[u32; 4], u32> =
        std::collections::HashMap::with_capacity(points.len());
    let mut welded = Vec::with_capacity(points.len());
    let weld = points
        .iter()
        .zip(keys)
        .map(|(p, k)| {
            // +0.0 and -0.0 are one place.
            let [x, y, z] = (*p + Vec3::ZERO).to_array().map(f32::to_bits);
            let key = [x, y, z, *k];
            *seen.entry(key).or_insert_with(|| {
                welded.push(*p);
                (welded.len() - 1) as u32
            })
        })
        .collect();
    (weld, welded)
}

/// The bind-pose transform of vertex `i` of a skinned array (None when it is not skinned).
fn rest_transform(va: &crate::VertexArray, i: usize, joints: &[Mat4]) -> Option<Mat4> {
    if joints.is_empty() {
        return None;
    }
    let (j, w) = (va.joints.get(i)?, va.weights.get(i)?);
    let total = w.x + w.y + w.z + w.w;
    if total <= 0.0 {
        return None;
    }
    let mut m = Mat4::ZERO;
    for (k, &weight) in w.to_array().iter().enumerate() {
        if weight > 0.0 {
            m += *joints.get(j[k] as usize)? * (weight / total);
        }
    }
    Some(m)
}

/// The mesh of `avatar` most likely the face when the caller has no registration to go by: the
/// triangle mesh with the most vertices whose name says face or head, else the one with the most
/// vertices; a mesh drawn only by see-through (BLEND) materials never.
pub fn largest_mesh(avatar: &Avatar) -> Option<usize> {
    let count = |m: &crate::Mesh| -> usize {
        let mut arrays: Vec<usize> = m
            .primitives
            .iter()
            .filter(|p| p.mode == Mode::Triangles)
            .map(|p| p.vertices)
            .collect();
        arrays.sort_unstable();
        arrays.dedup();
        arrays
            .iter()
            .map(|&a| avatar.vertex_arrays[a].positions.len())
            .sum()
    };
    let shown = |k: usize| avatar.nodes_of_mesh(k).next().is_some();
    // A see-through shell (every primitive alpha BLEND: an eye occlusion, a glasses lens) is
    // never the face.
    let solid = |m: &crate::Mesh| {
        m.primitives.iter().any(|p| {
            p.material
                .and_then(|k| avatar.materials.get(k))
                .is_none_or(|mat| mat.alpha_mode != crate::AlphaMode::Blend)
        })
    };
    let named = |m: &crate::Mesh| {
        m.name.as_deref().is_some_and(|n| {
            let n = n.to_ascii_lowercase();
            n.contains("face") || n.contains("head")
        })
    };
    let best = |want_name: bool| {
        avatar
            .meshes
            .iter()
            .enumerate()
            .filter(|(k, m)| shown(*k) && solid(m) && (!want_name || named(m)) && count(m) > 0)
            .max_by_key(|(_, m)| count(m))
            .map(|(k, _)| k)
    };
    best(true).or_else(|| best(false))
}

/// Whether `path` names a glTF, GLB or VRM file (by extension; a VRM is a GLB).
pub fn is_avatar_path(path: &std::path::Path) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| {
        ["gltf", "glb", "vrm"]
            .iter()
            .any(|x| e.eq_ignore_ascii_case(x))
    })
}
