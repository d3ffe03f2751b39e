//! How a rig is drawn (colours, hidden parts, textures), read from its `[look]`
//! ([`load_look`]), and its upload with that look.

use crate::ViewError;
use glam::Vec3;
use mimic_render::{Renderer, RigGpu};
use mimic_solve::Basis;
use mimic_types::{MeshTextures, Rig};
use std::path::Path;

/// The look of `rig`, read from the rig file `rig_path` as its `[look]` says: its materials'
/// colours and textures unless `materials` is off (skin colour then), and the parts hidden by
/// `hide` (as `--hide` gives them: ranges or `none`) or else by the look.
pub fn load_look(
    rig_path: &Path,
    rig: &Rig,
    hide: Option<&str>,
    materials: bool,
) -> Result<Look, ViewError> {
    let look = mimic_assets::load_rig_look(rig_path)?;
    let (colors, textures) = if materials {
        let (p, t) = (&rig.mesh.positions, &rig.mesh.triangles);
        let skin = mimic_render::SKIN_ALBEDO;
        (
            mimic_assets::look_colors(rig_path, &look, p, t, skin)?,
            mimic_assets::load_rig_textures(rig_path, &rig.mesh)?,
        )
    } else {
        (None, None)
    };
    Ok(Look {
        colors,
        hidden: mimic_types::parse::parse_hidden(hide, &look)
            .map_err(|e| ViewError::Option(format!("--hide {e}")))?,
        textures,
    })
}

/// How a rig is drawn: per-vertex colours, vertex ranges whose triangles are left out, textures.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Look {
    /// One albedo per vertex (linear RGB), or `None` for skin everywhere.
    pub colors: Option<Vec<[f32; 3]>>,
    /// Inclusive vertex ranges not drawn (triangles touching them are dropped).
    pub hidden: Vec<(u32, u32)>,
    /// Textures and where each of the rig's triangles (all of them, in the mesh's order) samples
    /// them, or `None`.
    pub textures: Option<MeshTextures>,
}

/// The look of a live rig, from its name and vertex count (e.g. from the local configs).
pub type LookFor = Box<dyn FnMut(&str, usize) -> Look>;

/// Whether triangle `t` touches no hidden range.
fn shown(t: &[u32; 3], hidden: &[(u32, u32)]) -> bool {
    !t.iter()
        .any(|v| hidden.iter().any(|(a, b)| (*a..=*b).contains(v)))
}

/// The triangles that touch no hidden range, in order.
pub fn visible(triangles: &[[u32; 3]], hidden: &[(u32, u32)]) -> Vec<[u32; 3]> {
    triangles
        .iter()
        .filter(|t| shown(t, hidden))
        .copied()
        .collect()
}

/// Uploads a rig (`triangles`: all of its triangles) with `look`: hidden triangles left out,
/// colours and textures set. Textures are used when they cover exactly these triangles (a live
/// rig's look comes from a local rig of the same name, which may differ).
pub fn upload_with_look(
    renderer: &Renderer,
    rest: &[Vec3],
    triangles: &[[u32; 3]],
    basis: Option<&Basis>,
    look: &Look,
) -> Result<RigGpu, ViewError> {
    let drawn = visible(triangles, &look.hidden);
    let mut gpu = renderer.upload_rig(rest, &drawn, basis)?;
    if let Some(c) = &look.colors {
        renderer.set_albedo(&gpu, c)?;
    }
    if let Some(t) = &look.textures
        && t.triangles.len() == triangles.len()
    {
        let kept = t.kept(|k| triangles.get(k).is_some_and(|tri| shown(tri, &look.hidden)));
        renderer.set_textures(&mut gpu, &kept)?;
    }
    Ok(gpu)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hidden_ranges_drop_the_triangles_that_touch_them() {
        let tris = [[0, 1, 2], [2, 3, 4], [5, 6, 7]];
        assert_eq!(visible(&tris, &[(3, 3)]), vec![[0, 1, 2], [5, 6, 7]]);
        assert_eq!(visible(&tris, &[]), tris.to_vec());
        assert_eq!(visible(&tris, &[(0, 100)]), Vec::<[u32; 3]>::new());
    }
}
