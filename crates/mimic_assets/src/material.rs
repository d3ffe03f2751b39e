//! Material colours of an OBJ mesh: its `mtllib` file's diffuse colours (`Kd`) and which
//! material each triangle uses (`usemtl`), in the triangle order of [`crate::load_obj`].

use crate::AssetError;
use mimic_types::limits;
use std::path::{Path, PathBuf};

/// One material of an MTL file.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name (`newmtl`).
    pub name: String,
    /// Diffuse colour `Kd` (linear RGB, 0..=1); mid grey if the file gives none.
    pub diffuse: [f32; 3],
    /// Drawn see-through by its renderer: `d` below 1, or a transmission filter `Tf` of zero
    /// (ICT-FaceKit's eye blend, eye occlusion and lacrimal shells, and its alpha-mapped eyelashes).
    pub transparent: bool,
    /// Diffuse texture `map_Kd` (relative names resolved against the MTL file's folder), or
    /// `None`; drawn instead of `Kd` where the mesh has texture coordinates.
    pub texture: Option<PathBuf>,
}

/// The materials of a mesh and the material of each triangle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshMaterials {
    /// Materials, in the MTL file's order.
    pub materials: Vec<Material>,
    /// Per triangle (the order of [`crate::load_obj`]'s triangles): index into `materials`, or
    /// `None` before any `usemtl` or for a name the MTL file does not define.
    pub triangle_material: Vec<Option<usize>>,
}

impl MeshMaterials {
    /// Index of the material called `name`.
    pub fn find(&self, name: &str) -> Option<usize> {
        self.materials.iter().position(|m| m.name == name)
    }

    /// One colour per vertex: the diffuse colour of the material of the last triangle that uses
    /// the vertex (`fallback` for vertices of no triangle or of one without a material), after
    /// `choose` had its say: it gets each material and returns the colour to use for it.
    pub fn vertex_colors(
        &self,
        vertex_count: usize,
        triangles: &[[u32; 3]],
        fallback: [f32; 3],
        choose: impl Fn(&Material) -> [f32; 3],
    ) -> Vec<[f32; 3]> {
        let colors: Vec<[f32; 3]> = self.materials.iter().map(choose).collect();
        let mut out = vec![fallback; vertex_count];
        for (tri, material) in triangles.iter().zip(&self.triangle_material) {
            let Some(c) = material.and_then(|m| colors.get(m)) else {
                continue;
            };
            for &v in tri {
                if let Some(slot) = out.get_mut(v as usize) {
                    *slot = *c;
                }
            }
        }
        out
    }
}

fn mtl_err(path: &Path, line: usize, message: impl Into<String>) -> AssetError {
    AssetError::Obj {
        path: path.to_path_buf(),
        line,
        message: message.into(),
    }
}

/// Parses MTL text (`newmtl`, `Kd`, `d`, `Tf`, `map_Kd`; other statements are ignored); `path`
/// names the file in errors, and `map_Kd` names are relative to its folder. `map_Kd` options
/// (`-s 1 1 1`, `-clamp on`, ...) are skipped: the file name is the last word then.
pub fn parse_mtl(path: &Path, text: &str) -> Result<Vec<Material>, AssetError> {
    let mut out: Vec<Material> = Vec::new();
    for (k, raw) in text.lines().enumerate() {
        let line_no = k + 1;
        let mut tokens = raw.split_whitespace();
        let Some(key) = tokens.next() else { continue };
        let numbers = |tokens: std::str::SplitWhitespace<'_>| -> Result<Vec<f32>, AssetError> {
            tokens
                .map(|t| {
                    t.parse::<f32>()
                        .ok()
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| mtl_err(path, line_no, format!("`{t}` is not a number")))
                })
                .collect()
        };
        match key {
            "newmtl" => out.push(Material {
                name: tokens.collect::<Vec<_>>().join(" "),
                diffuse: [0.5; 3],
                transparent: false,
                texture: None,
            }),
            "map_Kd" => {
                let Some(m) = out.last_mut() else {
                    return Err(mtl_err(path, line_no, "`map_Kd` before any newmtl"));
                };
                let words: Vec<&str> = tokens.collect();
                let name = if words.iter().any(|w| w.starts_with('-')) {
                    words.last().map(|w| (*w).to_string())
                } else {
                    Some(words.join(" "))
                };
                let Some(name) = name.filter(|n| !n.is_empty()) else {
                    return Err(mtl_err(path, line_no, "`map_Kd` names no file"));
                };
                m.texture = Some(path.parent().unwrap_or(Path::new(".")).join(name));
            }
            "Kd" | "d" | "Tf" => {
                let Some(m) = out.last_mut() else {
                    return Err(mtl_err(path, line_no, format!("`{key}` before any newmtl")));
                };
                let v = numbers(tokens)?;
                match (key, v.as_slice()) {
                    ("Kd", [r, g, b, ..]) => m.diffuse = [*r, *g, *b],
                    ("d", [a, ..]) => m.transparent |= *a < 1.0,
                    ("Tf", [r, g, b, ..]) => m.transparent |= r + g + b <= 0.0,
                    _ => {
                        return Err(mtl_err(
                            path,
                            line_no,
                            format!("`{key}` needs {} numbers", if key == "d" { 1 } else { 3 }),
                        ));
                    }
                }
            }
            _ => {}
        }
    }
    Ok(out)
}

/// Reads the material of every face of OBJ text: `mtllib` (relative to `obj_path`'s folder; the
/// first one is read) and `usemtl`; a face of k corners is k - 2 triangles, as [`crate::load_obj`]
/// triangulates it. An OBJ without `mtllib` has no materials.
pub fn parse_obj_materials(obj_path: &Path, text: &str) -> Result<MeshMaterials, AssetError> {
    let mut out = MeshMaterials::default();
    let mut current: Option<usize> = None;
    for raw in text.lines() {
        let mut tokens = raw.split_whitespace();
        match tokens.next() {
            Some("mtllib") if out.materials.is_empty() => {
                let name = tokens.collect::<Vec<_>>().join(" ");
                let path = obj_path.parent().unwrap_or(Path::new(".")).join(name);
                let mtl = crate::read::read_text(&path, &limits::MTL_FILE)?;
                out.materials = parse_mtl(&path, &mtl)?;
            }
            Some("usemtl") => {
                let name = tokens.collect::<Vec<_>>().join(" ");
                current = out.find(&name);
            }
            Some("f") => {
                let corners = tokens.count();
                for _ in 2..corners {
                    out.triangle_material.push(current);
                }
            }
            _ => {}
        }
    }
    Ok(out)
}

/// The OBJ mesh file a rig file names (relative to the rig file).
pub fn rig_mesh_path(rig_path: &Path) -> Result<PathBuf, AssetError> {
    let file = crate::look::read_rig_file(rig_path)?;
    Ok(rig_path
        .parent()
        .unwrap_or(Path::new("."))
        .join(file.mesh.get_ref()))
}

/// The materials of a rig's mesh (see [`parse_obj_materials`]; for an avatar, its face mesh's
/// glTF materials: `avatar_rig::avatar_materials`).
pub fn load_rig_materials(rig_path: &Path) -> Result<MeshMaterials, AssetError> {
    if let Some(a) = crate::load_rig_avatar(rig_path)? {
        return Ok(crate::avatar_rig::avatar_materials(&a));
    }
    let obj = rig_mesh_path(rig_path)?;
    let text = crate::read::read_text(&obj, &limits::OBJ_FILE)?;
    parse_obj_materials(&obj, &text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mtl_colours_and_transparency() {
        let m = parse_mtl(
            Path::new("x.mtl"),
            "newmtl Skin\nKd 0.6 0.5 0.4\nTf 1 1 1\n\nnewmtl Shell\nKd 0.5 0.5 0.5\nTf 0 0 0\nnewmtl Glass\nd 0.3\n",
        )
        .unwrap();
        assert_eq!(m.len(), 3);
        assert_eq!(m[0].diffuse, [0.6, 0.5, 0.4]);
        assert!(!m[0].transparent && m[1].transparent && m[2].transparent);
        let e = parse_mtl(Path::new("x.mtl"), "Kd 1 1 1\n").unwrap_err();
        assert!(e.to_string().contains("x.mtl:1"), "{e}");
        let e = parse_mtl(Path::new("x.mtl"), "newmtl a\nKd 1 x 1\n").unwrap_err();
        assert!(e.to_string().contains("x.mtl:2"), "{e}");
        assert_eq!(m[0].texture, None);
    }

    #[test]
    fn map_kd_is_relative_to_the_mtl() {
        let m = parse_mtl(
            Path::new("dir/x.mtl"),
            "newmtl A\nmap_Kd tex/skin map.png\nnewmtl B\nmap_Kd -s 1 1 1 -clamp on b.jpg\n",
        )
        .unwrap();
        assert_eq!(m[0].texture, Some(PathBuf::from("dir/tex/skin map.png")));
        assert_eq!(m[1].texture, Some(PathBuf::from("dir/b.jpg")));
        let e = parse_mtl(Path::new("x.mtl"), "newmtl A\nmap_Kd\n").unwrap_err();
        assert_eq!(e.to_string(), "x.mtl:2: `map_Kd` names no file");
    }

    #[test]
    fn faces_get_their_material_in_triangle_order() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("m.mtl"),
            "newmtl A\nKd 1 0 0\nnewmtl B\nKd 0 0 1\n",
        )
        .unwrap();
        let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nusemtl B\nf 1 2 3 4\nusemtl A\nf 2 5 3\n";
        let path = dir.path().join("m.obj");
        let mats = parse_obj_materials(&path, obj).unwrap();
        assert_eq!(
            mats.triangle_material,
            vec![None, Some(1), Some(1), Some(0)]
        );
        let mesh = crate::parse_obj(&path, obj).unwrap();
        assert_eq!(mesh.triangles.len(), mats.triangle_material.len());
        let colors = mats.vertex_colors(6, &mesh.triangles, [0.5; 3], |m| m.diffuse);
        // Vertex 4 (B's quad only) is blue; vertices 2 and 3 were last used by A (red); 6 is unused.
        assert_eq!(colors[3], [0.0, 0.0, 1.0]);
        assert_eq!(colors[1], [1.0, 0.0, 0.0]);
        assert_eq!(colors[4], [1.0, 0.0, 0.0]);
        assert_eq!(colors[5], [0.5; 3]);
    }

    #[test]
    fn ict_materials_cover_every_triangle() {
        let rig = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/rigs/ict-face.toml");
        let mats = load_rig_materials(&rig).unwrap();
        let mesh = crate::load_obj(&rig_mesh_path(&rig).unwrap()).unwrap();
        assert_eq!(mats.triangle_material.len(), mesh.triangles.len());
        assert!(mats.triangle_material.iter().all(Option::is_some));
        let gums = mats.find("M_GumsTongue").unwrap();
        assert_eq!(mats.materials[gums].diffuse, [0.30, 0.03, 0.06]);
        for shell in ["M_EyeBlend", "M_EyeOcclusion", "M_LacrimalFluid"] {
            let k = mats.find(shell).unwrap();
            assert!(mats.materials[k].transparent, "{shell}");
        }
    }
}
