//! `mimic info` on an avatar file (`.glb`, `.gltf`, `.vrm`): what the file holds, counted from its
//! checked document ([`crate::gltf_check`]), shared vertex lists counted once.

use crate::RigNewError;
use serde::Serialize;
use std::collections::BTreeSet;
use std::path::Path;

/// An avatar file in numbers.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AvatarSummary {
    /// Always `avatar`.
    pub kind: &'static str,
    /// `glb`, `gltf`, `vrm 0.x` or `vrm 1.0`.
    pub format: String,
    /// Nodes in the file.
    pub nodes: usize,
    /// Meshes.
    pub meshes: usize,
    /// Triangle primitives over all meshes.
    pub primitives: usize,
    /// Distinct vertices: each `POSITION` accessor counted once, however many primitives share it.
    pub vertices: u64,
    /// Triangles over all triangle primitives.
    pub triangles: u64,
    /// Materials.
    pub materials: usize,
    /// Textures.
    pub textures: usize,
    /// Skins (skeletons bound to meshes).
    pub skins: usize,
    /// Joints over all skins.
    pub joints: usize,
    /// Morph targets: the most any mesh has.
    pub morph_targets: usize,
    /// Animations.
    pub animations: usize,
}

impl AvatarSummary {
    /// Reads and checks the avatar file at `path` and counts what it holds.
    pub fn of(path: &Path) -> Result<Self, RigNewError> {
        let bytes = mimic_types::limits::read_bytes_capped(path, &crate::gltf_mesh::GLTF_FILE)
            .map_err(|cause| RigNewError::Read {
                path: path.to_path_buf(),
                cause,
            })?;
        let gltf = crate::gltf_mesh::parse_document(path, &bytes)?;
        let used: Vec<&str> = gltf.extensions_used().collect();
        let format = if used.contains(&"VRMC_vrm") {
            "vrm 1.0".to_string()
        } else if used.contains(&"VRM") {
            "vrm 0.x".to_string()
        } else if gltf.blob.is_some() || bytes.starts_with(b"glTF") {
            "glb".to_string()
        } else {
            "gltf".to_string()
        };
        let mut positions = BTreeSet::new();
        let (mut primitives, mut triangles, mut morph_targets) = (0, 0u64, 0);
        for mesh in gltf.meshes() {
            for prim in mesh.primitives() {
                if prim.mode() != gltf::mesh::Mode::Triangles {
                    continue;
                }
                let Some(pos) = prim.get(&gltf::Semantic::Positions) else {
                    continue;
                };
                primitives += 1;
                positions.insert(pos.index());
                let corners = prim.indices().map_or(pos.count(), |i| i.count());
                triangles += corners as u64 / 3;
                morph_targets = morph_targets.max(prim.morph_targets().count());
            }
        }
        let vertices = positions
            .iter()
            .filter_map(|&k| gltf.accessors().nth(k))
            .map(|a| a.count() as u64)
            .sum();
        Ok(Self {
            kind: "avatar",
            format,
            nodes: gltf.nodes().count(),
            meshes: gltf.meshes().count(),
            primitives,
            vertices,
            triangles,
            materials: gltf.materials().count(),
            textures: gltf.textures().count(),
            skins: gltf.skins().count(),
            joints: gltf.skins().map(|s| s.joints().count()).sum(),
            morph_targets,
            animations: gltf.animations().count(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn counts_a_glb_and_names_a_hostile_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("quad.glb");
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.5)];
        let glb = crate::gltf_mesh::write_glb(&p, &[[0, 1, 2], [2, 1, 3]], Vec3::ZERO);
        std::fs::write(&path, &glb).unwrap();
        let s = AvatarSummary::of(&path).unwrap();
        assert_eq!((s.format.as_str(), s.nodes, s.meshes), ("glb", 1, 1));
        assert_eq!((s.primitives, s.vertices, s.triangles), (1, 4, 2));
        // The same GLB with its node its own child: an error naming the pointer.
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        let json = std::str::from_utf8(&glb[20..20 + json_len]).unwrap();
        let hostile = json.replacen("\"mesh\":0,", "\"mesh\":0,\"children\":[0],", 1);
        assert_ne!(hostile, json);
        let mut bad = glb[..12].to_vec();
        let mut text = hostile.into_bytes();
        while !text.len().is_multiple_of(4) {
            text.push(b' ');
        }
        bad.extend_from_slice(&(text.len() as u32).to_le_bytes());
        bad.extend_from_slice(b"JSON");
        bad.extend_from_slice(&text);
        bad.extend_from_slice(&glb[20 + json_len..]);
        let total = bad.len() as u32;
        bad[8..12].copy_from_slice(&total.to_le_bytes());
        std::fs::write(&path, &bad).unwrap();
        let e = AvatarSummary::of(&path).unwrap_err().to_string();
        assert!(e.contains("/nodes/0/children/0"), "{e}");
    }
}
