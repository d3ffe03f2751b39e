//! OBJ frames with normals, texture coordinates and materials (`vn`, `vt`, `mtllib`/`usemtl`),
//! and the MTL file they name.

use crate::{AssetError, Material};
use glam::{Vec2, Vec3};
use mimic_types::Mesh;
use std::io::Write;
use std::path::Path;

/// What an OBJ frame carries besides positions and triangles; each part may be empty.
#[derive(Clone, Copy, Debug, Default)]
pub struct ObjExtras<'a> {
    /// One normal per vertex (`vn`, indexed like the vertices), or empty.
    pub normals: &'a [Vec3],
    /// Texture coordinates (`vt`, OBJ convention), or empty.
    pub uvs: &'a [Vec2],
    /// Per triangle, its corners' indices into `uvs`; empty, or parallel to the triangles.
    pub uv_triangles: &'a [[u32; 3]],
    /// File name for `mtllib` (relative to the OBJ), or `None`.
    pub mtllib: Option<&'a str>,
    /// Material names (`usemtl`).
    pub materials: &'a [String],
    /// Material of each triangle (index into `materials`); empty, or parallel to the triangles.
    pub triangle_material: &'a [Option<usize>],
}

/// Writes an OBJ: `header` as comments, `mtllib`, `v`, `vt`, `vn`, then the faces (`f v/vt/vn`,
/// with `usemtl` wherever the material changes).
pub fn write_obj_with<W: Write>(
    w: &mut W,
    header: &str,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    extras: &ObjExtras<'_>,
) -> std::io::Result<()> {
    for line in header.lines() {
        writeln!(w, "# {line}")?;
    }
    if let Some(lib) = extras.mtllib {
        writeln!(w, "mtllib {lib}")?;
    }
    for p in positions {
        writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
    }
    let uvs = !extras.uvs.is_empty() && extras.uv_triangles.len() == triangles.len();
    if uvs {
        for t in extras.uvs {
            writeln!(w, "vt {} {}", t.x, t.y)?;
        }
    }
    let normals = extras.normals.len() == positions.len() && !positions.is_empty();
    if normals {
        for n in extras.normals {
            writeln!(w, "vn {} {} {}", n.x, n.y, n.z)?;
        }
    }
    let materials = extras.triangle_material.len() == triangles.len();
    let mut current: Option<Option<usize>> = None;
    for (k, t) in triangles.iter().enumerate() {
        if materials {
            let m = extras.triangle_material[k];
            if current != Some(m) {
                let name = m.and_then(|m| extras.materials.get(m));
                writeln!(w, "usemtl {}", name.map_or("default", String::as_str))?;
                current = Some(m);
            }
        }
        write!(w, "f")?;
        for (c, v) in t.iter().enumerate() {
            let v = v + 1;
            match (uvs, normals) {
                (true, true) => write!(w, " {v}/{}/{v}", extras.uv_triangles[k][c] + 1)?,
                (true, false) => write!(w, " {v}/{}", extras.uv_triangles[k][c] + 1)?,
                (false, true) => write!(w, " {v}//{v}")?,
                (false, false) => write!(w, " {v}")?,
            }
        }
        writeln!(w)?;
    }
    Ok(())
}

/// Writes `materials` as an MTL file: `newmtl`, `Kd`, and `d 0.3` for see-through ones.
pub fn write_mtl<W: Write>(w: &mut W, header: &str, materials: &[Material]) -> std::io::Result<()> {
    for line in header.lines() {
        writeln!(w, "# {line}")?;
    }
    for m in materials {
        let [r, g, b] = m.diffuse;
        writeln!(w, "newmtl {}\nKd {r} {g} {b}", m.name)?;
        if m.transparent {
            writeln!(w, "d 0.3")?;
        }
        if let Some(t) = &m.texture {
            writeln!(w, "map_Kd {}", t.display())?;
        }
        writeln!(w)?;
    }
    Ok(())
}

/// A rig's deformed frames as OBJ files in one folder: the rig's materials as one `.mtl` beside
/// them, and per frame `v`, `vt`, `vn` and `usemtl`/`f` ([`write_obj_with`]).
#[derive(Clone, Debug)]
pub struct ObjFrames {
    mtllib: Option<String>,
    names: Vec<String>,
    triangle_material: Vec<Option<usize>>,
    written: usize,
    bytes: u64,
}

impl ObjFrames {
    /// Prepares `dir` for frames of the rig at `rig_path` called `rig_name`, whose mesh has
    /// `triangle_count` triangles: writes `<rig_name>.mtl` there when the mesh names materials.
    pub fn new(
        dir: &Path,
        rig_path: &Path,
        rig_name: &str,
        triangle_count: usize,
    ) -> Result<Self, AssetError> {
        let mut mats = crate::load_rig_materials(rig_path)?;
        // The MTL is written elsewhere: its texture names must not be relative to the old one.
        for m in &mut mats.materials {
            if let Some(t) = &mut m.texture
                && let Ok(abs) = std::path::absolute(&*t)
            {
                *t = abs;
            }
        }
        let mut out = Self {
            mtllib: None,
            names: Vec::new(),
            triangle_material: Vec::new(),
            written: 0,
            bytes: 0,
        };
        if mats.materials.is_empty() || mats.triangle_material.len() != triangle_count {
            return Ok(out);
        }
        let name = format!("{rig_name}.mtl");
        let path = dir.join(&name);
        let mut text = Vec::new();
        write_mtl(
            &mut text,
            &format!("materials of rig {rig_name}"),
            &mats.materials,
        )
        .and_then(|()| std::fs::write(&path, &text))
        .map_err(|cause| AssetError::Io { path, cause })?;
        out.bytes = text.len() as u64;
        out.mtllib = Some(name);
        out.names = mats.materials.iter().map(|m| m.name.clone()).collect();
        out.triangle_material = mats.triangle_material;
        Ok(out)
    }

    /// Writes one frame to `path`: `positions` and `normals` (one per vertex, or empty) of
    /// `mesh`'s vertices, with its triangles and UVs.
    pub fn write(
        &mut self,
        path: &Path,
        header: &str,
        positions: &[Vec3],
        normals: &[Vec3],
        mesh: &Mesh,
    ) -> Result<(), AssetError> {
        let extras = ObjExtras {
            normals,
            uvs: &mesh.uvs,
            uv_triangles: &mesh.uv_triangles,
            mtllib: self.mtllib.as_deref(),
            materials: &self.names,
            triangle_material: &self.triangle_material,
        };
        let io = |cause| AssetError::Io {
            path: path.to_path_buf(),
            cause,
        };
        let file = std::fs::File::create(path).map_err(io)?;
        let mut w = CountingWriter {
            inner: std::io::BufWriter::new(file),
            bytes: 0,
        };
        write_obj_with(&mut w, header, positions, &mesh.triangles, &extras)
            .and_then(|()| w.flush())
            .map_err(io)?;
        self.bytes += w.bytes;
        self.written += 1;
        Ok(())
    }

    /// Frames written.
    pub fn written(&self) -> usize {
        self.written
    }

    /// Bytes written, the `.mtl` included.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

/// A writer that counts the bytes through it.
struct CountingWriter<W> {
    inner: W,
    bytes: u64,
}

impl<W: Write> Write for CountingWriter<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.bytes += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn a_written_frame_reads_back_with_its_uvs_and_materials() {
        let dir = tempfile::tempdir().unwrap();
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE];
        let triangles = [[0, 1, 2], [2, 1, 3]];
        let uvs = [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE, Vec2::splat(0.5)];
        let uv_triangles = [[0, 1, 2], [4, 1, 3]];
        let normals = [Vec3::Z; 4];
        let mats = vec![
            Material {
                name: "A".into(),
                diffuse: [1.0, 0.0, 0.0],
                transparent: false,
                texture: None,
            },
            Material {
                name: "B".into(),
                diffuse: [0.0, 0.0, 1.0],
                transparent: true,
                texture: None,
            },
        ];
        let names: Vec<String> = mats.iter().map(|m| m.name.clone()).collect();
        let mut mtl = Vec::new();
        write_mtl(&mut mtl, "test", &mats).unwrap();
        std::fs::write(dir.path().join("m.mtl"), &mtl).unwrap();
        let extras = ObjExtras {
            normals: &normals,
            uvs: &uvs,
            uv_triangles: &uv_triangles,
            mtllib: Some("m.mtl"),
            materials: &names,
            triangle_material: &[Some(1), Some(0)],
        };
        let mut obj = Vec::new();
        write_obj_with(&mut obj, "frame 0", &positions, &triangles, &extras).unwrap();
        let text = String::from_utf8(obj).unwrap();
        assert!(text.contains("f 3/5/3 2/2/2 4/4/4"), "{text}");
        let path = dir.path().join("f.obj");
        let mesh = crate::parse_obj(&path, &text).unwrap();
        assert_eq!(mesh.positions, positions);
        assert_eq!(mesh.triangles, triangles);
        // The reader may renumber the UVs: each corner's UV is what was written.
        for (got, want) in mesh.uv_triangles.iter().zip(&uv_triangles) {
            for c in 0..3 {
                assert_eq!(mesh.uvs[got[c] as usize], uvs[want[c] as usize]);
            }
        }
        let m = crate::parse_obj_materials(&path, &text).unwrap();
        assert_eq!(m.triangle_material, vec![Some(1), Some(0)]);
        assert_eq!(m.materials, mats);
        assert!(Path::new(&dir.path().join("m.mtl")).exists());
    }

    #[test]
    fn ict_frames_name_the_rigs_materials_and_candide3_frames_none() {
        let rigs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/rigs");
        let dir = tempfile::tempdir().unwrap();
        let ict = rigs.join("ict-face.toml");
        let mesh = crate::load_obj(&crate::rig_mesh_path(&ict).unwrap()).unwrap();
        let mut frames = ObjFrames::new(dir.path(), &ict, "ict", mesh.triangles.len()).unwrap();
        let frame = dir.path().join("f.obj");
        frames
            .write(&frame, "rest", &mesh.positions, &[], &mesh)
            .unwrap();
        assert_eq!(frames.written(), 1);
        let mtl = std::fs::metadata(dir.path().join("ict.mtl")).unwrap().len();
        let obj = std::fs::metadata(&frame).unwrap().len();
        assert_eq!(frames.bytes(), mtl + obj);
        // The frame reads back as the rig's mesh with the rig's materials per triangle.
        let text = std::fs::read_to_string(&frame).unwrap();
        let back = crate::parse_obj(&frame, &text).unwrap();
        assert_eq!(back.positions, mesh.positions);
        assert_eq!(back.triangles, mesh.triangles);
        let want = crate::load_rig_materials(&ict).unwrap();
        let got = crate::parse_obj_materials(&frame, &text).unwrap();
        assert_eq!(got.triangle_material, want.triangle_material);
        assert_eq!(got.materials.len(), want.materials.len());
        for (g, w) in got.materials.iter().zip(&want.materials) {
            assert_eq!(
                (&g.name, g.diffuse, g.transparent),
                (&w.name, w.diffuse, w.transparent)
            );
        }
        let candide = rigs.join("candide3.toml");
        let mesh = crate::load_obj(&crate::rig_mesh_path(&candide).unwrap()).unwrap();
        let mut frames = ObjFrames::new(dir.path(), &candide, "c3", mesh.triangles.len()).unwrap();
        frames
            .write(&frame, "rest", &mesh.positions, &[], &mesh)
            .unwrap();
        assert!(!std::fs::read_to_string(&frame).unwrap().contains("mtllib"));
        assert!(!dir.path().join("c3.mtl").exists());
    }
}
