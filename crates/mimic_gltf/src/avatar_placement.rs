//! Which of mimic's morph targets go on which mesh of an avatar written back: a target that moves
//! the face (or nothing) goes on the face mesh, as before; a target that moves only a drawn part
//! (the eyeballs a gaze turns, the lower teeth and tongue the jaw carries: the rigid parts'
//! columns, docs/parts.md) goes on that part's mesh, so the face does not carry dozens of empty
//! targets and the part moves in any glTF viewer.

use crate::Morph;
use mimic_avatar::{Avatar, FaceMesh};

/// The targets one mesh gains.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct MeshTargets {
    /// The glTF mesh.
    pub mesh: usize,
    /// Its vertex arrays in the working mesh, each with its first file vertex (as
    /// [`FaceMesh::arrays`]).
    pub arrays: Vec<(usize, u32)>,
    /// Indices into the morphs of the targets it gains, in order.
    pub morphs: Vec<usize>,
}

/// The face first (every morph that moves a face vertex or none), then each drawn part that some
/// morph moves (the morphs that move it).
pub(crate) fn place(avatar: &Avatar, face: &FaceMesh, morphs: &[Morph]) -> Vec<MeshTargets> {
    let slots = face.meshes.len().max(1);
    let mut arrays: Vec<Vec<(usize, u32)>> = vec![Vec::new(); slots];
    arrays[0] = face.arrays[..face.face_arrays].to_vec();
    for &(array, offset) in &face.arrays[face.face_arrays..] {
        let slot = face.meshes.iter().enumerate().skip(1).find(|(_, m)| {
            avatar
                .meshes
                .get(**m)
                .is_some_and(|mesh| mesh.primitives.iter().any(|p| p.vertices == array))
        });
        if let Some((s, _)) = slot {
            arrays[s].push((array, offset));
        }
    }
    // The slot of each working vertex (seam copies are welded within a mesh only).
    let mut owner = vec![0usize; face.mesh_data.positions.len()];
    for (s, list) in arrays.iter().enumerate() {
        for &(array, offset) in list {
            let count = avatar.vertex_arrays[array].positions.len();
            for f in offset as usize..offset as usize + count {
                if let Some(w) = face.weld.get(f)
                    && let Some(o) = owner.get_mut(*w as usize)
                {
                    *o = s;
                }
            }
        }
    }
    let mut out: Vec<MeshTargets> = arrays
        .into_iter()
        .enumerate()
        .map(|(s, arrays)| MeshTargets {
            mesh: face.meshes.get(s).copied().unwrap_or(face.mesh),
            arrays,
            morphs: Vec::new(),
        })
        .collect();
    let mut touched = vec![false; slots];
    for (k, m) in morphs.iter().enumerate() {
        touched.fill(false);
        for (v, _) in &m.positions {
            if let Some(&s) = owner.get(*v as usize) {
                touched[s] = true;
            }
        }
        let on_parts = touched[1..].iter().any(|t| *t);
        for (s, t) in touched.iter().enumerate() {
            if *t || (s == 0 && !on_parts) {
                out[s].morphs.push(k);
            }
        }
    }
    // The face always comes first; parts no morph moves gain nothing.
    let face_entry = out.remove(0);
    let mut placed = vec![face_entry];
    placed.extend(out.into_iter().filter(|m| !m.morphs.is_empty()));
    placed
}
