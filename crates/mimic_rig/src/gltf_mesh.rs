//! Face meshes from glTF 2.0 (`.gltf` with its `.bin` files, or `.glb`), for `mimic rig new`.
//!
//! Every triangle primitive of every mesh node of the default scene (else the first scene, else
//! every node) is read with its node's world transform applied; vertices are numbered in that
//! order (nodes in scene order, primitives in mesh order), which is what landmark files for a
//! glTF mesh count. Data URIs are not read.

use crate::RigNewError;
use glam::{Mat4, Vec3};
use mimic_types::{FileKind, Mesh};
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

/// Whether `path` names a glTF or GLB file (by extension).
pub fn is_gltf(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

/// Reads a glTF or GLB file's triangles into one mesh (see the module docs).
pub fn load_gltf(path: &Path) -> Result<Mesh, RigNewError> {
    let read = |p: &Path| {
        mimic_types::limits::read_bytes_capped(p, &GLTF_FILE).map_err(|cause| RigNewError::Read {
            path: p.to_path_buf(),
            cause,
        })
    };
    let bytes = read(path)?;
    let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| err(path, e.to_string()))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let mut buffers: Vec<Vec<u8>> = Vec::new();
    for buffer in gltf.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| err(path, "buffer 0 is the GLB binary chunk, which is missing"))?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                return Err(err(
                    path,
                    format!(
                        "buffer {} is a data URI, which is not read: export as .glb or with a .bin file",
                        buffer.index()
                    ),
                ));
            }
            gltf::buffer::Source::Uri(uri) => read(&base.join(uri))?,
        };
        if data.len() < buffer.length() {
            return Err(err(
                path,
                format!(
                    "buffer {} has {} bytes, the file says {}",
                    buffer.index(),
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        buffers.push(data);
    }
    let mut nodes: Vec<(gltf::Node, Mat4)> = Vec::new();
    fn walk<'a>(node: gltf::Node<'a>, parent: Mat4, out: &mut Vec<(gltf::Node<'a>, Mat4)>) {
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        out.push((node.clone(), world));
        for child in node.children() {
            walk(child, world, out);
        }
    }
    match gltf.default_scene().or_else(|| gltf.scenes().next()) {
        Some(scene) => scene
            .nodes()
            .for_each(|n| walk(n, Mat4::IDENTITY, &mut nodes)),
        None => gltf.nodes().for_each(|n| {
            nodes.push((n.clone(), Mat4::from_cols_array_2d(&n.transform().matrix())))
        }),
    }
    let mut mesh = Mesh::default();
    for (node, world) in &nodes {
        let Some(m) = node.mesh() else { continue };
        for prim in m.primitives() {
            if prim.mode() != gltf::mesh::Mode::Triangles {
                continue;
            }
            let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            let Some(positions) = reader.read_positions() else {
                continue;
            };
            let first = mesh.positions.len() as u32;
            let before = mesh.positions.len();
            mesh.positions
                .extend(positions.map(|p| world.transform_point3(Vec3::from_array(p))));
            let count = (mesh.positions.len() - before) as u32;
            let indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..count).collect(),
            };
            if !indices.len().is_multiple_of(3) {
                return Err(err(
                    path,
                    format!(
                        "mesh {} primitive {}: {} indices, not whole triangles",
                        m.index(),
                        prim.index(),
                        indices.len()
                    ),
                ));
            }
            for t in indices.chunks_exact(3) {
                if t.iter().any(|&i| i >= count) {
                    return Err(err(
                        path,
                        format!(
                            "mesh {} primitive {}: index {} past its {count} vertices",
                            m.index(),
                            prim.index(),
                            t.iter().max().copied().unwrap_or(0)
                        ),
                    ));
                }
                mesh.triangles
                    .push([first + t[0], first + t[1], first + t[2]]);
            }
            if mesh.positions.len() > mimic_types::limits::MAX_MESH_VERTICES {
                return Err(err(path, "more vertices than mimic reads"));
            }
        }
    }
    if mesh.positions.is_empty() {
        return Err(err(path, "no triangle primitive with positions"));
    }
    mesh.validate().map_err(|e| err(path, e.to_string()))?;
    Ok(mesh)
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
    fn reads_a_glb_with_its_node_transform() {
        let dir = tempfile::tempdir().unwrap();
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.5)];
        let tris = [[0, 1, 2], [2, 1, 3]];
        let path = dir.path().join("quad.glb");
        std::fs::write(&path, write_glb(&p, &tris, Vec3::new(0.0, 2.0, 0.0))).unwrap();
        assert!(is_gltf(&path) && !is_gltf(Path::new("a.obj")));
        let mesh = load_gltf(&path).unwrap();
        assert_eq!(mesh.triangles, tris.to_vec());
        let want: Vec<Vec3> = p.iter().map(|v| *v + Vec3::new(0.0, 2.0, 0.0)).collect();
        assert_eq!(mesh.positions, want);
        // A broken file names itself.
        std::fs::write(&path, b"glTF junk").unwrap();
        let e = load_gltf(&path).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}: ", path.display())), "{e}");
    }
}
