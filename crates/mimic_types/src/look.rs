//! How a rig is drawn: the `[look]` table of a rig file (hidden parts, skin materials, eyeballs,
//! textures), and the decoded textures of a mesh with the texture coordinates of its triangles.

use crate::FileKind;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Texture images (PNG, JPEG) named by an MTL's `map_Kd`, a rig's `[look.textures]` or a glTF
/// material (a 4096 x 4096 RGBA PNG of noise is 64 MiB; photos and painted maps are far smaller).
pub const TEXTURE_FILE: FileKind = FileKind {
    what: "texture images",
    max_bytes: 32 << 20,
};
/// Longest side of a texture image that is decoded (a larger one is refused before decoding).
pub const MAX_TEXTURE_SIDE: u32 = 8192;

/// How a rig is drawn by `mimic render` and `mimic view`; empty (everything drawn, material
/// colours as the mesh's MTL gives them) when the rig file has no `[look]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigLook {
    /// Inclusive vertex index ranges whose triangles are not drawn by default (e.g. see-through
    /// shells that opaque would cover the eyes).
    #[serde(default)]
    pub hidden: Vec<[u32; 2]>,
    /// Materials drawn in the renderer's skin colour instead of their MTL colour (e.g. a flat
    /// `Kd` meant to multiply a skin texture that is not shipped).
    #[serde(default)]
    pub skin_materials: Vec<String>,
    /// Eyeballs coloured by angle from their front: pupil, iris, white.
    #[serde(default)]
    pub eyeballs: Vec<Eyeball>,
    /// Textures by material name (paths relative to the rig file, PNG or JPEG): drawn instead of
    /// the material's colour, over the mesh's texture coordinates; they replace the MTL's
    /// `map_Kd` for that material.
    #[serde(default)]
    pub textures: BTreeMap<String, PathBuf>,
}

/// One eyeball of a rig's look, by material names.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Eyeball {
    /// Material of the whole eyeball mesh; its `Kd` colours the iris.
    pub iris: String,
    /// Material whose `Kd` colours the rest of the eyeball (the white).
    pub white: String,
}

impl RigLook {
    /// Whether vertex `v` lies in a hidden range.
    pub fn hides(&self, v: u32) -> bool {
        self.hidden.iter().any(|[a, b]| (*a..=*b).contains(&v))
    }
}

/// One decoded texture image: sRGB-encoded RGBA8 rows from the top, and the file's bytes.
#[derive(Clone, PartialEq, Eq)]
pub struct TextureImage {
    /// File name (e.g. `skin.png`), for messages and the glTF image's name.
    pub name: String,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` RGBA8 pixels, sRGB-encoded colour, top row first.
    pub rgba: Vec<u8>,
    /// The file as read (PNG or JPEG), for writers that embed it unchanged (glTF).
    pub encoded: Vec<u8>,
    /// MIME type of `encoded`: `image/png` or `image/jpeg`.
    pub mime: &'static str,
}

impl std::fmt::Debug for TextureImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TextureImage")
            .field("name", &self.name)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("mime", &self.mime)
            .field("encoded_bytes", &self.encoded.len())
            .finish_non_exhaustive()
    }
}

/// Where one triangle samples its material's texture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleTexture {
    /// Index into [`MeshTextures::textures`].
    pub texture: u32,
    /// Texture coordinates of the triangle's three corners in image convention (u right, v down
    /// from the top-left corner, as glTF: `1 - v` of an OBJ's `vt`).
    pub uv: [[f32; 2]; 3],
}

/// A mesh's textures and, per triangle (in the mesh's triangle order), the texture it shows.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshTextures {
    /// The decoded images.
    pub textures: Vec<TextureImage>,
    /// One entry per triangle: `None` for a triangle of an untextured material.
    pub triangles: Vec<Option<TriangleTexture>>,
    /// Per texture, the materials (by index into the mesh's materials) that show it.
    pub materials: Vec<Vec<usize>>,
}

impl MeshTextures {
    /// The textures of the triangles for which `keep(t)` holds, in order (what a renderer that
    /// leaves hidden triangles out uploads).
    pub fn kept(&self, keep: impl Fn(usize) -> bool) -> MeshTextures {
        MeshTextures {
            textures: self.textures.clone(),
            triangles: self
                .triangles
                .iter()
                .enumerate()
                .filter(|(t, _)| keep(*t))
                .map(|(_, x)| *x)
                .collect(),
            materials: self.materials.clone(),
        }
    }
}
