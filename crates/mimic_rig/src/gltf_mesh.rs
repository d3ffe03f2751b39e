//! Face meshes from glTF 2.0 (`.gltf` with its `.bin` files, or `.glb`), for `mimic rig new`.
//!
//! Every triangle primitive of every mesh node of the default scene (else the first scene, else
//! every node) is read with its node's world transform applied; vertices are numbered in that
//! order (nodes in scene order, primitives in mesh order), which is what landmark files for a
//! glTF mesh count. Data URIs are not read.
//!
//! [`load_gltf_look`] also reads what the look needs: `TEXCOORD_0` (as the mesh's UVs, OBJ
//! convention), each primitive's material (`baseColorFactor`) and its `baseColorTexture` image
//! (from a buffer view or a file beside the glTF), which [`write_obj_copy`] writes out as an OBJ
//! with `vt`, an MTL with `Kd` and `map_Kd`, and the image files: the rig's mesh.

use crate::RigNewError;
use glam::{Mat4, Vec2, Vec3};
use mimic_types::{FileKind, Mesh};
use std::path::{Path, PathBuf};

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

/// Whether `path` names a glTF, GLB or VRM file (by extension; a VRM is a GLB).
pub fn is_gltf(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| {
        ["gltf", "glb", "vrm"]
            .iter()
            .any(|x| e.eq_ignore_ascii_case(x))
    })
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

/// One material of a glTF mesh, as the rig's MTL will hold it.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfLookMaterial {
    /// Name: `material_K` for glTF material K, `default` for primitives without one.
    pub name: String,
    /// `baseColorFactor`'s RGB (linear).
    pub diffuse: [f32; 3],
    /// Index into [`GltfLook::images`] of its `baseColorTexture`, if any.
    pub image: Option<usize>,
}

/// The look of a glTF mesh: materials, the material of each triangle, the texture images.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GltfLook {
    /// Materials used by the mesh's primitives.
    pub materials: Vec<GltfLookMaterial>,
    /// Per triangle of the mesh, its material (index into `materials`).
    pub triangle_material: Vec<usize>,
    /// Texture images: a file name (`.png` / `.jpg`) and the encoded bytes.
    pub images: Vec<(String, Vec<u8>)>,
}

/// Reads a glTF or GLB file's triangles into one mesh (see the module docs).
pub fn load_gltf(path: &Path) -> Result<Mesh, RigNewError> {
    load_gltf_look(path).map(|(mesh, _)| mesh)
}

fn read(p: &Path) -> Result<Vec<u8>, RigNewError> {
    mimic_types::limits::read_bytes_capped(p, &GLTF_FILE).map_err(|cause| RigNewError::Read {
        path: p.to_path_buf(),
        cause,
    })
}

/// Reads a glTF or GLB file's triangles into one mesh with its texture coordinates, and its look.
pub fn load_gltf_look(path: &Path) -> Result<(Mesh, GltfLook), RigNewError> {
    let bytes = read(path)?;
    parse_gltf_look(path, &bytes, Some(path.parent().unwrap_or(Path::new("."))))
}

/// [`load_gltf_look`] on a file's bytes; files it names (buffers, images) are read from `files`'
/// folder, or refused when `files` is `None`. Errors name `path`.
pub fn parse_gltf_look(
    path: &Path,
    bytes: &[u8],
    files: Option<&Path>,
) -> Result<(Mesh, GltfLook), RigNewError> {
    let gltf = parse_document(path, bytes)?;
    let base = files.unwrap_or(Path::new("."));
    let external = |uri: &str| match files {
        Some(dir) => read(&dir.join(uri)),
        None => Err(err(
            path,
            format!("`{uri}` is a separate file, not read here"),
        )),
    };
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
            gltf::buffer::Source::Uri(uri) => external(uri)?,
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
    let nodes = world_nodes(&gltf);
    let mut mesh = Mesh::default();
    let mut look = GltfLook::default();
    // glTF material index (None: no material) to look material; glTF image index to look image.
    let mut material_of: Vec<(Option<usize>, usize)> = Vec::new();
    let mut image_of: Vec<(usize, usize)> = Vec::new();
    let mut uvs: Vec<Vec2> = Vec::new();
    let mut any_uv = false;
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
            // UVs per vertex (glTF's v runs down: OBJ's is 1 - v); none: zeros.
            let mut prim_uvs: Vec<Vec2> = reader
                .read_tex_coords(0)
                .map(|t| t.into_f32().map(|[u, v]| Vec2::new(u, 1.0 - v)).collect())
                .unwrap_or_default();
            any_uv |= !prim_uvs.is_empty();
            prim_uvs.resize(count as usize, Vec2::ZERO);
            uvs.extend(prim_uvs);
            let material = prim.material();
            let key = material.index();
            let look_material = match material_of.iter().find(|(k, _)| *k == key) {
                Some((_, m)) => *m,
                None => {
                    let image = match material
                        .pbr_metallic_roughness()
                        .base_color_texture()
                        .map(|info| info.texture().source())
                    {
                        Some(img) => match image_of.iter().find(|(k, _)| *k == img.index()) {
                            Some((_, i)) => Some(*i),
                            None => {
                                let (ext, bytes) =
                                    image_bytes(path, files.map(|_| base), &img, &buffers)?;
                                look.images
                                    .push((format!("texture{}.{ext}", look.images.len()), bytes));
                                image_of.push((img.index(), look.images.len() - 1));
                                Some(look.images.len() - 1)
                            }
                        },
                        None => None,
                    };
                    let [r, g, b, _] = material.pbr_metallic_roughness().base_color_factor();
                    // The gltf crate reads names only with its `names` feature: by index.
                    let name =
                        key.map_or_else(|| "default".to_string(), |k| format!("material_{k}"));
                    look.materials.push(GltfLookMaterial {
                        name,
                        diffuse: [r, g, b],
                        image,
                    });
                    material_of.push((key, look.materials.len() - 1));
                    look.materials.len() - 1
                }
            };
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
                look.triangle_material.push(look_material);
            }
            if mesh.positions.len() > mimic_types::limits::MAX_MESH_VERTICES {
                return Err(err(path, "more vertices than mimic reads"));
            }
        }
    }
    if mesh.positions.is_empty() {
        return Err(err(path, "no triangle primitive with positions"));
    }
    if any_uv {
        mesh.uvs = uvs;
        mesh.uv_triangles = mesh.triangles.clone();
    }
    mesh.validate().map_err(|e| err(path, e.to_string()))?;
    Ok((mesh, look))
}

/// The scene's nodes with their world transforms, parents before children (the default scene,
/// else the first, else every node as a root). The graph is a checked set of trees
/// ([`crate::gltf_check`]), walked with a stack, not recursion.
fn world_nodes(gltf: &gltf::Gltf) -> Vec<(gltf::Node<'_>, Mat4)> {
    let mut stack: Vec<(gltf::Node, Mat4)> =
        match gltf.default_scene().or_else(|| gltf.scenes().next()) {
            Some(scene) => scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect(),
            // No scene: each node alone with its own transform (no children followed).
            None => {
                return gltf
                    .nodes()
                    .map(|n| {
                        let m = Mat4::from_cols_array_2d(&n.transform().matrix());
                        (n, m)
                    })
                    .collect();
            }
        };
    stack.reverse();
    let mut out = Vec::new();
    while let Some((node, parent)) = stack.pop() {
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        let first = stack.len();
        stack.extend(node.children().map(|c| (c, world)));
        stack[first..].reverse();
        out.push((node, world));
    }
    out
}

/// The encoded bytes of a glTF image and the file extension of its type (PNG or JPEG only);
/// image files are read from `base` (refused when `None`).
fn image_bytes(
    path: &Path,
    base: Option<&Path>,
    image: &gltf::Image<'_>,
    buffers: &[Vec<u8>],
) -> Result<(&'static str, Vec<u8>), RigNewError> {
    let bytes = match image.source() {
        gltf::image::Source::View { view, .. } => {
            let data = buffers
                .get(view.buffer().index())
                .and_then(|b| b.get(view.offset()..view.offset() + view.length()))
                .ok_or_else(|| {
                    err(
                        path,
                        format!("image {}: its buffer view is out of range", image.index()),
                    )
                })?;
            data.to_vec()
        }
        gltf::image::Source::Uri { uri, .. } if uri.starts_with("data:") => {
            return Err(err(
                path,
                format!(
                    "image {} is a data URI, which is not read: export as .glb or with image files",
                    image.index()
                ),
            ));
        }
        gltf::image::Source::Uri { uri, .. } => {
            let Some(base) = base else {
                return Err(err(
                    path,
                    format!(
                        "image {}: `{uri}` is a separate file, not read here",
                        image.index()
                    ),
                ));
            };
            let p = base.join(uri);
            mimic_types::limits::read_bytes_capped(&p, &mimic_types::TEXTURE_FILE)
                .map_err(|cause| RigNewError::Read { path: p, cause })?
        }
    };
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Ok(("png", bytes))
    } else if bytes.starts_with(&[0xFF, 0xD8]) {
        Ok(("jpg", bytes))
    } else {
        Err(err(
            path,
            format!("image {}: neither PNG nor JPEG", image.index()),
        ))
    }
}

/// Writes `mesh` with `look` as the rig's OBJ copy `dir/STEM.mesh.obj`: `vt` and `usemtl` when
/// the mesh has them, an MTL `STEM.mesh.mtl` (`Kd`, `map_Kd`) and the images as
/// `STEM.TEXTURE` beside it; `header` goes in the OBJ's comment. Returns the OBJ's path.
pub fn write_obj_copy(
    dir: &Path,
    stem: &str,
    mesh: &Mesh,
    look: &GltfLook,
    header: &str,
) -> std::io::Result<PathBuf> {
    let obj = dir.join(format!("{stem}.mesh.obj"));
    let mtl_name = format!("{stem}.mesh.mtl");
    let with_materials =
        !look.materials.is_empty() && look.triangle_material.len() == mesh.triangles.len();
    if with_materials {
        let mut images = Vec::with_capacity(look.images.len());
        for (name, bytes) in &look.images {
            let file = format!("{stem}.{name}");
            std::fs::write(dir.join(&file), bytes)?;
            images.push(file);
        }
        let materials: Vec<mimic_assets::Material> = look
            .materials
            .iter()
            .map(|m| mimic_assets::Material {
                name: m.name.clone(),
                diffuse: m.diffuse,
                transparent: false,
                texture: m.image.and_then(|i| images.get(i)).map(PathBuf::from),
            })
            .collect();
        let mut text = Vec::new();
        mimic_assets::write_mtl(&mut text, header, &materials)?;
        std::fs::write(dir.join(&mtl_name), text)?;
    }
    let names: Vec<String> = look.materials.iter().map(|m| m.name.clone()).collect();
    let triangle_material: Vec<Option<usize>> =
        look.triangle_material.iter().map(|m| Some(*m)).collect();
    let extras = mimic_assets::ObjExtras {
        uvs: &mesh.uvs,
        uv_triangles: &mesh.uv_triangles,
        mtllib: with_materials.then_some(mtl_name.as_str()),
        materials: if with_materials { &names } else { &[] },
        triangle_material: if with_materials {
            &triangle_material
        } else {
            &[]
        },
        ..Default::default()
    };
    let mut w = std::io::BufWriter::new(std::fs::File::create(&obj)?);
    mimic_assets::write_obj_with(&mut w, header, &mesh.positions, &mesh.triangles, &extras)?;
    std::io::Write::flush(&mut w)?;
    Ok(obj)
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
    fn a_textured_glb_becomes_an_obj_with_its_mtl_and_image() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let png = include_bytes!("../../../configs/meshes/ict-facekit-textured/skin.png").to_vec();
        let image = mimic_assets::decode_texture(Path::new("skin.png"), png.clone()).unwrap();
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
        let triangles = [[0, 1, 2], [2, 1, 3]];
        // OBJ-convention UVs; vertex 2 is on a seam (another UV in the second triangle).
        let uvs = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.25, 0.75),
        ];
        let uv_triangles = [[0, 1, 2], [4, 1, 3]];
        let materials = [mimic_gltf::GltfMaterial {
            name: "Skin Mat".into(),
            base_color: [1.0, 0.5, 0.25, 1.0],
            blend: false,
            texture: Some(0),
        }];
        let scene = mimic_gltf::Scene {
            name: "quad",
            mesh: mimic_gltf::GltfMesh {
                positions: &positions,
                triangles: &triangles,
                uvs: &uvs,
                uv_triangles: &uv_triangles,
                materials: &materials,
                triangle_material: &[Some(0), Some(0)],
                colors: &[],
                textures: std::slice::from_ref(&image),
            },
            metres_per_unit: 1.0,
            morphs: &[],
            take: None,
            pivot: Vec3::ZERO,
        };
        let glb = d.join("quad.glb");
        let mut bytes = Vec::new();
        mimic_gltf::write_glb(&scene, &mut bytes).unwrap();
        std::fs::write(&glb, bytes).unwrap();
        let (mesh, look) = load_gltf_look(&glb).unwrap();
        assert_eq!(look.materials.len(), 1);
        assert_eq!(look.materials[0].name, "material_0");
        assert_eq!(look.materials[0].diffuse, [1.0, 0.5, 0.25]);
        assert_eq!(look.images, vec![("texture0.png".to_string(), png.clone())]);
        let obj = write_obj_copy(d, "quad", &mesh, &look, "test").unwrap();
        assert_eq!(obj, d.join("quad.mesh.obj"));
        assert_eq!(std::fs::read(d.join("quad.texture0.png")).unwrap(), png);
        // Loaded back as a rig's mesh: the corners keep their UVs (image convention: 1 - v).
        let rig = d.join("quad.toml");
        std::fs::write(
            &rig,
            "name = \"q\"\nunits = \"m\"\nmesh = \"quad.mesh.obj\"\ncontrols = []\n\
             [regions]\ntop_from = 0.7\nbottom_below = 0.3\nband = 0.1\n",
        )
        .unwrap();
        let back = mimic_assets::load_obj(&obj).unwrap();
        let tex = mimic_assets::load_rig_textures(&rig, &back)
            .unwrap()
            .unwrap();
        assert_eq!(tex.textures[0].encoded, png);
        for (t, uvt) in uv_triangles.iter().enumerate() {
            let got = tex.triangles[t].unwrap().uv;
            for k in 0..3 {
                let want = uvs[uvt[k] as usize];
                assert!(
                    (got[k][0] - want.x).abs() < 1e-6 && (got[k][1] - (1.0 - want.y)).abs() < 1e-6
                );
            }
        }
    }

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
