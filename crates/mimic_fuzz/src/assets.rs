//! Asset files: OBJ meshes, landmark layouts, rigs and morph data files.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The OBJ mesh parser: every triangle index of an accepted mesh is in range.
pub fn obj(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(mesh) = mimic_assets::parse_obj(Path::new("fuzz.obj"), text) {
        let n = mesh.vertex_count();
        assert!(
            mesh.triangles.iter().flatten().all(|&i| (i as usize) < n),
            "triangle index out of range"
        );
    }
}

/// The avatar file readers (glTF / GLB / VRM bytes): the whole-avatar reader (each primitive's
/// indices lie in its vertex array, every attribute as long as the positions, one-line errors)
/// and, on what it accepts, `mimic rig new`'s working mesh of each mesh (its triangles index
/// its vertices, each triangle has its material, each file vertex its working vertex).
pub fn avatar(data: &[u8]) {
    match mimic_gltf::parse_avatar(Path::new("fuzz.glb"), data, None) {
        Ok(a) => {
            for p in a.meshes.iter().flat_map(|m| &m.primitives) {
                let v = &a.vertex_arrays[p.vertices];
                let n = v.positions.len();
                assert!(
                    p.indices.iter().all(|&i| (i as usize) < n),
                    "index out of range"
                );
                for len in [
                    v.normals.len(),
                    v.colors.len(),
                    v.joints.len(),
                    v.weights.len(),
                ] {
                    assert!(
                        len == 0 || len == n,
                        "attribute length differs from POSITION"
                    );
                }
            }
            for k in 0..a.meshes.len() {
                if let Ok(face) = mimic_gltf::avatar::FaceMesh::of(&a, k) {
                    let mesh = &face.mesh_data;
                    let n = mesh.vertex_count();
                    assert!(
                        mesh.triangles.iter().flatten().all(|&i| (i as usize) < n),
                        "triangle index out of range"
                    );
                    assert_eq!(face.triangle_material.len(), mesh.triangles.len());
                    assert!(face.weld.iter().all(|&w| (w as usize) < n));
                }
            }
        }
        Err(e) => assert!(!e.to_string().contains('\n'), "error over several lines"),
    }
}

/// The landmark layout TOML loader.
pub fn layout(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = mimic_assets::parse_layout(Path::new("fuzz_layout.toml"), text);
}

/// Scratch folder with a 4-vertex mesh `tri.obj` (the corpus rigs name it), made once per
/// process; `None` where the temporary folder cannot be written.
fn rig_path() -> Option<&'static PathBuf> {
    static DIR: OnceLock<Option<PathBuf>> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("mimic-fuzz-rig-{}", std::process::id()));
        std::fs::create_dir_all(&dir).ok()?;
        std::fs::write(
            dir.join("tri.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n",
        )
        .ok()?;
        Some(dir.join("rig.toml"))
    })
    .as_ref()
}

/// The rig TOML loader; the rig's mesh resolves in a scratch folder holding `tri.obj`.
pub fn rig(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    // Only meshes inside the scratch folder: a fuzzed `mesh = "/dev/zero"` would read forever.
    if text.contains('/') || text.contains('\\') || text.contains("..") {
        return;
    }
    if let Some(path) = rig_path() {
        let _ = mimic_assets::parse_rig(path, text);
    }
}

/// The morph data file reader (`docs/morph-format.md`): as many normal deltas as position deltas.
pub fn morph(data: &[u8]) {
    if let Ok(targets) = mimic_assets::read_morph_file(data, Path::new("fuzz.morph.txt")) {
        for t in &targets {
            assert_eq!(
                t.position_deltas.len(),
                t.normal_deltas.len(),
                "position and normal deltas differ in count"
            );
        }
    }
}
