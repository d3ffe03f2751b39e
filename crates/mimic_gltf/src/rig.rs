//! A rig file as a glTF scene: its mesh, its look's materials and colours, its units.

use crate::{
    GlbSummary, GltfError, GltfMaterial, GltfMesh, Morph, Scene, Take, metres_per_unit, write_glb,
};
use glam::Vec3;
use mimic_types::Rig;
use std::io::Write;
use std::path::Path;

/// Alpha of a see-through material (MTL `d` < 1 or `Tf 0`) that the look does not hide.
const SEE_THROUGH_ALPHA: f32 = 0.3;

/// What a rig's file adds to its mesh for glTF: materials and colours from its look.
#[derive(Clone, Debug, PartialEq)]
pub struct RigLookParts {
    /// Materials: white base colour times the vertex colours; alpha 0 (blended) for the parts the
    /// look hides, 0.3 for other see-through ones.
    pub materials: Vec<GltfMaterial>,
    /// Material of each triangle.
    pub triangle_material: Vec<Option<usize>>,
    /// Per-vertex colours ([`mimic_assets::look_colors`], `skin` for the skin materials); empty
    /// when the mesh names no materials; white where a triangle is textured.
    pub colors: Vec<[f32; 3]>,
    /// Texture images ([`mimic_assets::load_rig_textures`]) the materials name.
    pub textures: Vec<mimic_types::TextureImage>,
}

/// The materials and colours of the rig at `rig_path` (loaded as `rig`), `skin` for its skin.
pub fn rig_look_parts(
    rig_path: &Path,
    rig: &Rig,
    skin: [f32; 3],
) -> Result<RigLookParts, GltfError> {
    let look = mimic_assets::load_rig_look(rig_path)?;
    let mats = mimic_assets::load_rig_materials(rig_path)?;
    let (p, t) = (&rig.mesh.positions, &rig.mesh.triangles);
    let mut colors = mimic_assets::look_colors(rig_path, &look, p, t, skin)?.unwrap_or_default();
    if colors.is_empty() || mats.triangle_material.len() != t.len() {
        return Ok(RigLookParts {
            materials: Vec::new(),
            triangle_material: Vec::new(),
            colors: Vec::new(),
            textures: Vec::new(),
        });
    }
    let textures = mimic_assets::load_rig_textures(rig_path, &rig.mesh)?.unwrap_or_default();
    let mut texture_of = vec![None; mats.materials.len()];
    for (k, ms) in textures.materials.iter().enumerate() {
        for &m in ms {
            if let Some(slot) = texture_of.get_mut(m) {
                *slot = Some(k);
            }
        }
    }
    // A textured triangle's vertices are white: COLOR_0 multiplies the texture (as mimic_render
    // draws it: the texture alone, times the light).
    for (tri, x) in t.iter().zip(&textures.triangles) {
        if x.is_some() {
            for &v in tri {
                if let Some(c) = colors.get_mut(v as usize) {
                    *c = [1.0; 3];
                }
            }
        }
    }
    let mut hidden = vec![false; mats.materials.len()];
    for (tri, m) in t.iter().zip(&mats.triangle_material) {
        if let Some(m) = m
            && tri.iter().any(|v| look.hides(*v))
        {
            hidden[*m] = true;
        }
    }
    let materials = mats
        .materials
        .iter()
        .zip(&hidden)
        .enumerate()
        .map(|(k, (m, hidden))| {
            let alpha = if *hidden {
                0.0
            } else if m.transparent {
                SEE_THROUGH_ALPHA
            } else {
                1.0
            };
            GltfMaterial {
                name: m.name.clone(),
                base_color: [1.0, 1.0, 1.0, alpha],
                blend: alpha < 1.0,
                texture: texture_of[k],
            }
        })
        .collect();
    Ok(RigLookParts {
        materials,
        triangle_material: mats.triangle_material,
        colors,
        textures: textures.textures,
    })
}

/// Writes `rig` (from `rig_path`) with `morphs` and an optional `take` as one GLB to `w`: rig
/// units scaled to metres ([`metres_per_unit`]; an unknown `units` is an error), axes as they
/// are (mimic's rigs are y up, z out of the face, as glTF's +Y up and +Z front), the head node's
/// origin at the centroid of the rig's controls.
pub fn write_rig_glb(
    rig_path: &Path,
    rig: &Rig,
    morphs: &[Morph],
    take: Option<&Take>,
    skin: [f32; 3],
    w: &mut impl Write,
) -> Result<GlbSummary, GltfError> {
    let s = metres_per_unit(&rig.units).ok_or_else(|| GltfError::Units(rig.units.clone()))?;
    let parts = rig_look_parts(rig_path, rig, skin)?;
    let controls = rig.control_positions();
    let pivot = controls.iter().copied().sum::<Vec3>() / controls.len().max(1) as f32;
    let scene = Scene {
        name: &rig.name,
        mesh: GltfMesh {
            positions: &rig.mesh.positions,
            triangles: &rig.mesh.triangles,
            uvs: &rig.mesh.uvs,
            uv_triangles: &rig.mesh.uv_triangles,
            materials: &parts.materials,
            triangle_material: &parts.triangle_material,
            colors: &parts.colors,
            textures: &parts.textures,
        },
        metres_per_unit: s,
        morphs,
        take,
        pivot,
    };
    write_glb(&scene, w)
}

/// `mimic rig export`: an avatar rig's avatar written back whole with `morphs` on its face
/// ([`crate::write_avatar_glb`], no animation), any other rig as [`write_rig_glb`] writes it.
pub fn export_rig_glb(
    rig_path: &Path,
    rig: &Rig,
    morphs: &[Morph],
    skin: [f32; 3],
    w: &mut impl Write,
) -> Result<GlbSummary, GltfError> {
    let Some(a) = mimic_assets::load_rig_avatar(rig_path)? else {
        return write_rig_glb(rig_path, rig, morphs, None, skin, w);
    };
    let s = crate::write_avatar_glb(&a.avatar, &a.face, morphs, None, w)?;
    let primitives = a.avatar.meshes.iter().map(|m| m.primitives.len()).sum();
    Ok(GlbSummary {
        bytes: s.bytes,
        vertices: s.vertices,
        primitives,
        targets: s.targets,
        sparse_targets: s.sparse_targets,
        keys: 0,
        duration_s: 0.0,
    })
}
