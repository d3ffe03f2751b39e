//! A rig's look (`[look]` of its file) and the per-vertex colours it gives the rig's mesh.

use crate::span::toml_error;
use crate::{AssetError, RigFile, load_rig_materials};
use glam::Vec3;
use mimic_types::RigLook;
use std::path::Path;

/// Half-angle of the iris seen from the eyeball's centre (a 12 mm iris on a 24 mm eye: 30 degrees).
pub const IRIS_DEGREES: f32 = 30.0;
/// Half-angle of the pupil seen from the eyeball's centre.
pub const PUPIL_DEGREES: f32 = 11.0;
/// Colour of the pupil.
pub const PUPIL_COLOR: [f32; 3] = [0.02, 0.02, 0.02];

/// The rig file at `rig_path`, parsed (its mesh is not loaded).
pub(crate) fn read_rig_file(rig_path: &Path) -> Result<RigFile, AssetError> {
    let text = crate::read::read_text(rig_path, &mimic_types::limits::RIG_FILE)?;
    toml::from_str(&text).map_err(|e| toml_error(rig_path, &text, e))
}

/// The `[look]` of the rig file at `rig_path` (empty when it has none).
pub fn load_rig_look(rig_path: &Path) -> Result<RigLook, AssetError> {
    Ok(read_rig_file(rig_path)?.look)
}

/// Per-vertex albedo of the rig at `rig_path` from its mesh's MTL materials: each material's
/// `Kd`, except `skin` for the look's skin materials and for vertices of no material, and the
/// look's eyeballs coloured from their front (+z from the centre of their vertices): within
/// [`PUPIL_DEGREES`] the pupil, within [`IRIS_DEGREES`] the eyeball material's `Kd`, the rest the
/// white's. `None` when the mesh names no materials. An avatar's face gives its own colours
/// (`COLOR_0` times the base colour).
pub fn look_colors(
    rig_path: &Path,
    look: &RigLook,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    skin: [f32; 3],
) -> Result<Option<Vec<[f32; 3]>>, AssetError> {
    if let Some(a) = crate::load_rig_avatar(rig_path)?
        && a.face.colors.len() == positions.len()
    {
        // An avatar's face: its vertex colours times its materials' base colours.
        return Ok(Some(
            a.face
                .colors
                .iter()
                .map(|c| c.truncate().to_array())
                .collect(),
        ));
    }
    let materials = load_rig_materials(rig_path)?;
    if materials.materials.is_empty() || materials.triangle_material.len() != triangles.len() {
        return Ok(None);
    }
    let mut colors = materials.vertex_colors(positions.len(), triangles, skin, |m| {
        if look.skin_materials.contains(&m.name) {
            skin
        } else {
            m.diffuse
        }
    });
    for eye in &look.eyeballs {
        let (Some(b), Some(w)) = (materials.find(&eye.iris), materials.find(&eye.white)) else {
            continue;
        };
        let mut vertices: Vec<u32> = triangles
            .iter()
            .zip(&materials.triangle_material)
            .filter(|(_, m)| **m == Some(b))
            .flat_map(|(t, _)| t.iter().copied())
            .collect();
        vertices.sort_unstable();
        vertices.dedup();
        let points: Vec<Vec3> = vertices
            .iter()
            .filter_map(|&v| positions.get(v as usize).copied())
            .collect();
        if points.is_empty() {
            continue;
        }
        let centre = points.iter().copied().sum::<Vec3>() / points.len() as f32;
        let (iris, pupil) = (
            IRIS_DEGREES.to_radians().cos(),
            PUPIL_DEGREES.to_radians().cos(),
        );
        for (&v, p) in vertices.iter().zip(&points) {
            let cos = (*p - centre).normalize_or_zero().dot(Vec3::Z);
            colors[v as usize] = if cos >= pupil {
                PUPIL_COLOR
            } else if cos >= iris {
                materials.materials[b].diffuse
            } else {
                materials.materials[w].diffuse
            };
        }
    }
    Ok(Some(colors))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ConfigDirs, load_obj, rig_mesh_path};

    /// Skin colour used by the tests (any colour no material has).
    const SKIN: [f32; 3] = [0.9, 0.7, 0.6];

    #[test]
    fn the_hidden_ict_ranges_are_its_see_through_eye_parts() {
        let configs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs");
        let path = ConfigDirs::locate(Some(&configs)).rig_path("ict-face");
        let look = load_rig_look(&path).unwrap();
        assert_eq!(
            look.hidden,
            vec![[21451, 22220], [23021, 23790], [24591, 26718]]
        );
        let mats = load_rig_materials(&path).unwrap();
        let mesh = load_obj(&rig_mesh_path(&path).unwrap()).unwrap();
        for (tri, m) in mesh.triangles.iter().zip(&mats.triangle_material) {
            let name = &mats.materials[m.unwrap()].name;
            let shell = [
                "M_ScleraLeft",
                "M_ScleraRight",
                "M_LacrimalFluid",
                "M_EyeBlend",
                "M_EyeOcclusion",
                "M_EyeLashes",
            ]
            .contains(&name.as_str());
            // Their triangles lie wholly in the ranges; no other triangle touches them.
            assert_eq!(tri.iter().all(|v| look.hides(*v)), shell, "{name} {tri:?}");
            assert_eq!(tri.iter().any(|v| look.hides(*v)), shell, "{name} {tri:?}");
        }
        // Colours: gums red, teeth light, the face skin.
        let colors = look_colors(&path, &look, &mesh.positions, &mesh.triangles, SKIN)
            .unwrap()
            .unwrap();
        let of = |name: &str| {
            let k = mats.find(name).unwrap();
            let t = mats
                .triangle_material
                .iter()
                .position(|m| *m == Some(k))
                .unwrap();
            colors[mesh.triangles[t][0] as usize]
        };
        assert_eq!(of("M_GumsTongue"), [0.30, 0.03, 0.06]);
        assert_eq!(of("M_Teeth"), [0.8, 0.8, 0.8]);
        assert_eq!(of("M_Face"), SKIN);
        // Each eyeball: a black pupil, an iris of the iris Kd, the rest the sclera's Kd.
        for ball in ["M_IrisLeft", "M_IrisRight"] {
            let k = mats.find(ball).unwrap();
            let mut seen: Vec<[f32; 3]> = Vec::new();
            for (t, m) in mesh.triangles.iter().zip(&mats.triangle_material) {
                if *m == Some(k) {
                    for &v in t {
                        if !seen.contains(&colors[v as usize]) {
                            seen.push(colors[v as usize]);
                        }
                    }
                }
            }
            seen.sort_by(|a, b| a[0].total_cmp(&b[0]));
            assert_eq!(seen, vec![[0.02; 3], [0.2; 3], [0.6; 3]], "{ball}");
        }
    }

    #[test]
    fn a_rig_without_look_draws_everything_in_material_colours() {
        let configs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs");
        let path = ConfigDirs::locate(Some(&configs)).rig_path("candide3");
        assert_eq!(load_rig_look(&path).unwrap(), RigLook::default());
    }
}
