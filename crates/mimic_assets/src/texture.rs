//! Texture images (PNG through `png`, JPEG through `jpeg-decoder`) and the textures of a rig's
//! mesh: each material's `map_Kd` (or the rig's `[look.textures]`) over the mesh's UVs.

use crate::{AssetError, load_rig_look, load_rig_materials};
use mimic_types::{
    MAX_TEXTURE_SIDE, Mesh, MeshTextures, TEXTURE_FILE, TextureImage, TriangleTexture,
};
use std::io::Cursor;
use std::path::Path;

fn tex_err(path: &Path, message: impl Into<String>) -> AssetError {
    AssetError::Texture {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Reads and decodes a PNG or JPEG texture (told apart by their first bytes, not the name) into
/// sRGB RGBA8; grey and RGB images get an opaque alpha, 16-bit PNGs are cut to 8 bits. Files over
/// [`TEXTURE_FILE`]'s cap and images with a side over [`MAX_TEXTURE_SIDE`] are refused.
pub fn load_texture(path: &Path) -> Result<TextureImage, AssetError> {
    let bytes = mimic_types::limits::read_bytes_capped(path, &TEXTURE_FILE)
        .map_err(|e| AssetError::read(path, e))?;
    decode_texture(path, bytes)
}

/// Decodes the bytes of a PNG or JPEG texture (see [`load_texture`]); `path` names it in errors
/// and gives the image its name.
pub fn decode_texture(path: &Path, bytes: Vec<u8>) -> Result<TextureImage, AssetError> {
    let name = path
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let check = |w: u32, h: u32| {
        if w == 0 || h == 0 || w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE {
            Err(tex_err(
                path,
                format!("{w} x {h} pixels: each side must be 1 to {MAX_TEXTURE_SIDE}"),
            ))
        } else {
            Ok(())
        }
    };
    let (width, height, rgba, mime) = if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        let mut decoder = png::Decoder::new(Cursor::new(&bytes[..]));
        decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
        let mut reader = decoder
            .read_info()
            .map_err(|e| tex_err(path, format!("PNG: {e}")))?;
        let (w, h) = (reader.info().width, reader.info().height);
        check(w, h)?;
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| tex_err(path, "PNG: image too large"))?;
        let mut buf = vec![0u8; size];
        let out = reader
            .next_frame(&mut buf)
            .map_err(|e| tex_err(path, format!("PNG: {e}")))?;
        let px = w as usize * h as usize;
        let data = &buf[..out.buffer_size()];
        let rgba: Vec<u8> = match out.color_type {
            png::ColorType::Rgba => data[..px * 4].to_vec(),
            png::ColorType::Rgb => data[..px * 3]
                .chunks_exact(3)
                .flat_map(|c| [c[0], c[1], c[2], 255])
                .collect(),
            png::ColorType::GrayscaleAlpha => data[..px * 2]
                .chunks_exact(2)
                .flat_map(|c| [c[0], c[0], c[0], c[1]])
                .collect(),
            png::ColorType::Grayscale => data[..px].iter().flat_map(|&g| [g, g, g, 255]).collect(),
            png::ColorType::Indexed => {
                return Err(tex_err(path, "PNG: palette not expanded"));
            }
        };
        (w, h, rgba, "image/png")
    } else if bytes.starts_with(&[0xFF, 0xD8]) {
        let mut decoder = jpeg_decoder::Decoder::new(Cursor::new(&bytes[..]));
        decoder
            .read_info()
            .map_err(|e| tex_err(path, format!("JPEG: {e}")))?;
        let info = decoder
            .info()
            .ok_or_else(|| tex_err(path, "JPEG: no image header"))?;
        let (w, h) = (u32::from(info.width), u32::from(info.height));
        check(w, h)?;
        let pixels = decoder
            .decode()
            .map_err(|e| tex_err(path, format!("JPEG: {e}")))?;
        let px = w as usize * h as usize;
        let rgba: Vec<u8> = match info.pixel_format {
            jpeg_decoder::PixelFormat::RGB24 if pixels.len() >= px * 3 => pixels[..px * 3]
                .chunks_exact(3)
                .flat_map(|c| [c[0], c[1], c[2], 255])
                .collect(),
            jpeg_decoder::PixelFormat::L8 if pixels.len() >= px => {
                pixels[..px].iter().flat_map(|&g| [g, g, g, 255]).collect()
            }
            other => {
                return Err(tex_err(
                    path,
                    format!("JPEG: {other:?} pixels are not read (RGB or grey only)"),
                ));
            }
        };
        (w, h, rgba, "image/jpeg")
    } else {
        return Err(tex_err(path, "neither a PNG nor a JPEG file"));
    };
    Ok(TextureImage {
        name,
        width,
        height,
        rgba,
        encoded: bytes,
        mime,
    })
}

/// The textures of the rig at `rig_path` over its loaded `mesh`: for each material, the rig's
/// `[look.textures]` entry (relative to the rig file) or else the MTL's `map_Kd` (relative to the
/// MTL); each texture file is decoded once. `None` when no material has a texture, or when the
/// mesh has no texture coordinates (then the material colours are drawn; a warning says so).
pub fn load_rig_textures(rig_path: &Path, mesh: &Mesh) -> Result<Option<MeshTextures>, AssetError> {
    let look = load_rig_look(rig_path)?;
    let mats = load_rig_materials(rig_path)?;
    let rig_dir = rig_path.parent().unwrap_or(Path::new("."));
    let mut files: Vec<std::path::PathBuf> = Vec::new();
    let mut of_material: Vec<Option<u32>> = Vec::with_capacity(mats.materials.len());
    for m in &mats.materials {
        let file = match look.textures.get(&m.name) {
            Some(p) => Some(rig_dir.join(p)),
            None => m.texture.clone(),
        };
        of_material.push(file.map(|f| match files.iter().position(|g| *g == f) {
            Some(k) => k as u32,
            None => {
                files.push(f);
                (files.len() - 1) as u32
            }
        }));
    }
    for name in look.textures.keys() {
        if mats.find(name).is_none() {
            return Err(AssetError::Texture {
                path: rig_path.to_path_buf(),
                message: format!("[look.textures]: the mesh has no material `{name}`"),
            });
        }
    }
    if files.is_empty() || mats.triangle_material.len() != mesh.triangles.len() {
        return Ok(None);
    }
    if mesh.uv_triangles.len() != mesh.triangles.len() {
        tracing::warn!(
            rig = %rig_path.display(),
            "the mesh has textured materials but no texture coordinates: drawn in material colours"
        );
        return Ok(None);
    }
    let textures = files
        .iter()
        .map(|f| load_texture(f))
        .collect::<Result<Vec<_>, _>>()?;
    let mut materials: Vec<Vec<usize>> = vec![Vec::new(); textures.len()];
    for (m, t) in of_material.iter().enumerate() {
        if let Some(t) = t {
            materials[*t as usize].push(m);
        }
    }
    let mut triangles = Vec::with_capacity(mesh.triangles.len());
    for (t, (m, uvt)) in mats
        .triangle_material
        .iter()
        .zip(&mesh.uv_triangles)
        .enumerate()
    {
        let Some(texture) = m.and_then(|m| of_material.get(m).copied().flatten()) else {
            triangles.push(None);
            continue;
        };
        let mut uv = [[0f32; 2]; 3];
        for (k, &i) in uvt.iter().enumerate() {
            let Some(p) = mesh.uvs.get(i as usize) else {
                return Err(AssetError::Texture {
                    path: rig_path.to_path_buf(),
                    message: format!(
                        "triangle {t} uses texture coordinate {i}, the mesh has {}",
                        mesh.uvs.len()
                    ),
                });
            };
            uv[k] = [p.x, 1.0 - p.y];
        }
        triangles.push(Some(TriangleTexture { texture, uv }));
    }
    Ok(Some(MeshTextures {
        textures,
        triangles,
        materials,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w x h` RGB PNG whose pixel (x, y) is (x, y, 7).
    fn png_bytes(w: u32, h: u32) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().unwrap();
        let data: Vec<u8> = (0..h)
            .flat_map(|y| (0..w).flat_map(move |x| [x as u8, y as u8, 7]))
            .collect();
        writer.write_image_data(&data).unwrap();
        writer.finish().unwrap();
        out
    }

    #[test]
    fn png_pixels_come_out_as_rgba_rows_from_the_top() {
        let t = decode_texture(Path::new("a.png"), png_bytes(3, 2)).unwrap();
        assert_eq!((t.width, t.height, t.mime), (3, 2, "image/png"));
        assert_eq!(&t.rgba[..4], &[0, 0, 7, 255]);
        // Pixel (2, 1): row 1, column 2.
        assert_eq!(&t.rgba[(3 + 2) * 4..(3 + 2) * 4 + 4], &[2, 1, 7, 255]);
        let e = decode_texture(Path::new("b.png"), b"GIF89a".to_vec()).unwrap_err();
        assert_eq!(e.to_string(), "b.png: neither a PNG nor a JPEG file");
        let mut cut = png_bytes(3, 2);
        cut.truncate(40);
        let e = decode_texture(Path::new("c.png"), cut).unwrap_err();
        assert!(e.to_string().starts_with("c.png: PNG: "), "{e}");
    }

    #[test]
    fn a_jpeg_decodes_near_its_colour() {
        // A 16 x 8 baseline JPEG of one colour (made by PIL, quality 95): RGB (200, 120, 80).
        let jpeg = include_bytes!("../tests/data/flat_200_120_80.jpg").to_vec();
        let t = decode_texture(Path::new("f.jpg"), jpeg).unwrap();
        assert_eq!((t.width, t.height, t.mime), (16, 8, "image/jpeg"));
        for p in t.rgba.chunks_exact(4) {
            for (got, want) in p[..3].iter().zip([200u8, 120, 80]) {
                // Baseline JPEG of a flat colour: within a few levels (chroma rounding).
                assert!(got.abs_diff(want) <= 3, "{p:?}");
            }
            assert_eq!(p[3], 255);
        }
    }

    /// A rig file's required part, naming `m.obj`.
    const HEAD: &str = "name = \"t\"\nunits = \"m\"\nmesh = \"m.obj\"\ncontrols = []\n\
                        [regions]\ntop_from = 0.7\nbottom_below = 0.3\nband = 0.1\n";

    #[test]
    fn map_kd_gives_textured_triangles_with_flipped_v() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("tex")).unwrap();
        std::fs::write(d.join("tex/skin.png"), png_bytes(4, 4)).unwrap();
        std::fs::write(
            d.join("m.mtl"),
            "newmtl Skin\nKd 1 1 1\nmap_Kd tex/skin.png\nnewmtl Plain\nKd 0 0 1\n",
        )
        .unwrap();
        std::fs::write(
            d.join("m.obj"),
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\n\
             usemtl Skin\nf 1/1 2/2 3/3\nusemtl Plain\nf 2/2 4/4 3/3\n",
        )
        .unwrap();
        let rig = d.join("r.toml");
        std::fs::write(&rig, HEAD).unwrap();
        let mesh = crate::load_obj(&d.join("m.obj")).unwrap();
        let tex = load_rig_textures(&rig, &mesh).unwrap().unwrap();
        assert_eq!(tex.textures.len(), 1);
        assert_eq!(tex.textures[0].name, "skin.png");
        assert_eq!(tex.materials, vec![vec![0]]);
        assert_eq!(tex.triangles[1], None);
        let t0 = tex.triangles[0].unwrap();
        assert_eq!(t0.texture, 0);
        assert_eq!(t0.uv, [[0.0, 1.0], [1.0, 1.0], [0.0, 0.0]]);
        // The look's entry replaces map_Kd; one naming no material is an error.
        std::fs::write(d.join("other.png"), png_bytes(2, 2)).unwrap();
        std::fs::write(
            &rig,
            format!("{HEAD}[look.textures]\nPlain = \"other.png\"\n"),
        )
        .unwrap();
        let tex = load_rig_textures(&rig, &mesh).unwrap().unwrap();
        assert_eq!(tex.textures.len(), 2);
        assert_eq!(tex.triangles[1].unwrap().texture, 1);
        assert_eq!(tex.textures[1].width, 2);
        std::fs::write(
            &rig,
            format!("{HEAD}[look.textures]\nNope = \"other.png\"\n"),
        )
        .unwrap();
        let e = load_rig_textures(&rig, &mesh).unwrap_err().to_string();
        assert!(e.contains("the mesh has no material `Nope`"), "{e}");
        // A missing texture file names itself.
        std::fs::remove_file(d.join("tex/skin.png")).unwrap();
        std::fs::write(&rig, HEAD).unwrap();
        let e = load_rig_textures(&rig, &mesh).unwrap_err().to_string();
        assert!(e.contains("skin.png"), "{e}");
    }
}
