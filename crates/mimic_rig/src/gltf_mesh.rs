//! glTF documents for `mimic info`'s avatar summary ([`parse_document`], structure checked first)
//! and a minimal GLB writer for tests and docs ([`write_glb`]). A rig's avatar mesh is read by
//! `mimic_avatar` (`FaceMesh`), not here.

use crate::RigNewError;
use glam::Vec3;
use mimic_types::FileKind;
use std::path::Path;

/// Size cap of glTF and GLB files and of the buffers they name.
pub const GLTF_FILE: FileKind = FileKind {
    what: "glTF files",
    max_bytes: 256 << 20,
};

fn err(path: &Path, message: impl Into<String>) -> RigNewError {
    RigNewError::Mesh {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Parses a glTF or GLB file's bytes into a document, its structure checked
/// ([`crate::gltf_check`]) before the `gltf` crate's own validation; errors name `path`.
pub fn parse_document(path: &Path, bytes: &[u8]) -> Result<gltf::Gltf, RigNewError> {
    let raw =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| err(path, e.to_string()))?;
    crate::gltf_check::check(raw.document.as_json()).map_err(|f| err(path, f.to_string()))?;
    let document = gltf::Document::from_json(raw.document.into_json())
        .map_err(|e| err(path, e.to_string()))?;
    Ok(gltf::Gltf {
        document,
        blob: raw.blob,
    })
}

/// A minimal GLB of `positions` and `triangles` under one node translated by `t` (what the
/// tests and `docs/rigging.md`'s round trip use; no normals, UVs or materials).
pub fn write_glb(positions: &[Vec3], triangles: &[[u32; 3]], t: Vec3) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    for p in positions {
        for c in p.to_array() {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let pos_len = bin.len();
    for tri in triangles {
        for i in tri {
            bin.extend_from_slice(&i.to_le_bytes());
        }
    }
    let idx_len = bin.len() - pos_len;
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let (lo, hi) = positions.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(a, b), p| (a.min(*p), b.max(*p)),
    );
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
"nodes":[{{"mesh":0,"translation":[{},{},{}]}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
"buffers":[{{"byteLength":{}}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{pos_len}}},{{"buffer":0,"byteOffset":{pos_len},"byteLength":{idx_len}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3","min":[{},{},{}],"max":[{},{},{}]}},
{{"bufferView":1,"componentType":5125,"count":{},"type":"SCALAR"}}]}}"#,
        t.x,
        t.y,
        t.z,
        bin.len(),
        positions.len(),
        lo.x,
        lo.y,
        lo.z,
        hi.x,
        hi.y,
        hi.z,
        triangles.len() * 3
    );
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_glb_reads_as_an_avatar_face_with_its_node_transform() {
        let dir = tempfile::tempdir().unwrap();
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.5)];
        let tris = [[0, 1, 2], [2, 1, 3]];
        let path = dir.path().join("quad.glb");
        std::fs::write(&path, write_glb(&p, &tris, Vec3::new(0.0, 2.0, 0.0))).unwrap();
        assert!(
            mimic_avatar::is_avatar_path(&path)
                && !mimic_avatar::is_avatar_path(Path::new("a.obj"))
        );
        let avatar = mimic_avatar::load_avatar(&path).unwrap();
        let mesh = mimic_avatar::FaceMesh::of(&avatar, 0).unwrap().mesh_data;
        assert_eq!(mesh.triangles, tris.to_vec());
        let want: Vec<Vec3> = p.iter().map(|v| *v + Vec3::new(0.0, 2.0, 0.0)).collect();
        assert_eq!(mesh.positions, want);
        // A broken file names itself.
        std::fs::write(&path, b"glTF junk").unwrap();
        let e = mimic_avatar::load_avatar(&path).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}: ", path.display())), "{e}");
    }
}
