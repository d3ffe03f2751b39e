#![cfg_attr(
    test,
    allow(
        clippy::unwrap_used,
        reason = "tests: a failed unwrap is the failure report"
    )
)]
//! The avatar as data: a glTF, GLB or VRM file read whole (docs/avatars.md).
//!
//! [`parse_avatar`] checks the document's structure first ([`crate::gltf_check`]), then reads
//! every mesh, node, skin, material, texture and image, keeping the JSON document whole
//! ([`Avatar::document`]) so that a writer can pass through what mimic does not model. Each
//! distinct set of vertex attribute accessors is read once into one [`VertexArray`]; primitives
//! name their array and hold their own index list (a glTF whose 12 primitives share one
//! `POSITION` accessor gives one array, not 12 copies). VRM 0.x and 1.0 extensions give a small
//! typed view, [`Vrm`]. Every error is one line naming the file and the JSON pointer.

mod accessor;
mod animation;
mod container;
mod error;
mod face;
mod files;
pub mod gltf_check;
mod read;
mod vrm;

#[cfg(test)]
mod tests;

pub use animation::{Animation, Channel, ChannelPath};
pub use error::AvatarError;
pub use face::{FaceMesh, find_mesh, is_avatar_path, largest_mesh};
pub use read::{AVATAR_FILE, load_avatar, parse_avatar};
pub use vrm::{Expression, LookAt, LookAtKind, MorphBind, RangeMap, Vrm, VrmVersion};

use glam::{Mat4, Quat, Vec2, Vec3, Vec4};
use std::path::PathBuf;

/// A whole avatar file: the document, its buffers and what mimic reads from it.
#[derive(Clone, Debug)]
pub struct Avatar {
    /// The file it was read from (what errors and reports name).
    pub path: PathBuf,
    /// The glTF JSON document, whole (unknown extensions and extras included).
    pub document: serde_json::Value,
    /// The buffers' bytes, in glTF buffer order (the GLB binary chunk is buffer 0's).
    pub buffers: Vec<Vec<u8>>,
    /// Root nodes of the scene shown (the default scene, else the first; else every parentless node).
    pub scene_roots: Vec<usize>,
    /// Every node, in glTF order.
    pub nodes: Vec<Node>,
    /// Every mesh, in glTF order.
    pub meshes: Vec<Mesh>,
    /// The vertex arrays the primitives share, each read once.
    pub vertex_arrays: Vec<VertexArray>,
    /// The morph targets the primitives share, each read once.
    pub morph_targets: Vec<MorphTarget>,
    /// Every skin, in glTF order.
    pub skins: Vec<Skin>,
    /// Every material, in glTF order.
    pub materials: Vec<Material>,
    /// Every texture, in glTF order.
    pub textures: Vec<Texture>,
    /// Every image with its encoded bytes, in glTF order.
    pub images: Vec<Image>,
    /// The VRM extension's view, for a VRM 0.x or 1.0 file.
    pub vrm: Option<Vrm>,
    /// Every animation, its channels' keys read.
    pub animations: Vec<Animation>,
}

impl Avatar {
    /// Vertices in all vertex arrays (each shared array counted once).
    pub fn vertex_count(&self) -> usize {
        self.vertex_arrays.iter().map(|v| v.positions.len()).sum()
    }

    /// The first mesh named `name`.
    pub fn mesh_named(&self, name: &str) -> Option<usize> {
        self.meshes
            .iter()
            .position(|m| m.name.as_deref() == Some(name))
    }

    /// The first node named `name`.
    pub fn node_named(&self, name: &str) -> Option<usize> {
        self.nodes
            .iter()
            .position(|n| n.name.as_deref() == Some(name))
    }

    /// The first material named `name`.
    pub fn material_named(&self, name: &str) -> Option<usize> {
        self.materials
            .iter()
            .position(|m| m.name.as_deref() == Some(name))
    }

    /// The nodes that show mesh `mesh`.
    pub fn nodes_of_mesh(&self, mesh: usize) -> impl Iterator<Item = usize> + '_ {
        (0..self.nodes.len()).filter(move |&n| self.nodes[n].mesh == Some(mesh))
    }
}

/// A node of the hierarchy.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    /// Its name, if it has one.
    pub name: Option<String>,
    /// Its parent node (None for a root).
    pub parent: Option<usize>,
    /// Its child nodes, in file order.
    pub children: Vec<usize>,
    /// Local translation.
    pub translation: Vec3,
    /// Local rotation.
    pub rotation: Quat,
    /// Local scale.
    pub scale: Vec3,
    /// Local transform (the file's matrix, or translation * rotation * scale).
    pub local: Mat4,
    /// World transform: the parents' local transforms times this one's.
    pub world: Mat4,
    /// The mesh it shows.
    pub mesh: Option<usize>,
    /// The skin its mesh is bound to.
    pub skin: Option<usize>,
}

/// A mesh: named primitives and its morph target names.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    /// Its name, if it has one.
    pub name: Option<String>,
    /// Its primitives, in file order.
    pub primitives: Vec<Primitive>,
    /// Morph target names (`extras.targetNames`), empty when the file names none.
    pub target_names: Vec<String>,
    /// Default morph weights (`weights`), empty when absent.
    pub weights: Vec<f32>,
}

/// How a primitive's indices make shapes (glTF `mode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Points (0).
    Points,
    /// Lines (1).
    Lines,
    /// Line loop (2).
    LineLoop,
    /// Line strip (3).
    LineStrip,
    /// Triangles (4), the default.
    Triangles,
    /// Triangle strip (5).
    TriangleStrip,
    /// Triangle fan (6).
    TriangleFan,
}

/// One draw of a mesh: a vertex array, the indices into it, a material.
#[derive(Clone, Debug, PartialEq)]
pub struct Primitive {
    /// Index into [`Avatar::vertex_arrays`].
    pub vertices: usize,
    /// Indices into the vertex array (`0..n` when the file has none), each checked in range.
    pub indices: Vec<u32>,
    /// The glTF accessor of the indices, if any.
    pub indices_accessor: Option<usize>,
    /// Index into [`Avatar::materials`] (None: glTF's default material).
    pub material: Option<usize>,
    /// How the indices make shapes.
    pub mode: Mode,
    /// Its morph targets, indices into [`Avatar::morph_targets`], in target order.
    pub targets: Vec<usize>,
}

impl Primitive {
    /// The triangles of a [`Mode::Triangles`] primitive (empty for other modes).
    pub fn triangles(&self) -> impl Iterator<Item = [u32; 3]> + '_ {
        let chunks = match self.mode {
            Mode::Triangles => self.indices.chunks_exact(3),
            _ => [].chunks_exact(3),
        };
        chunks.map(|t| [t[0], t[1], t[2]])
    }
}

/// The glTF accessors of a vertex array's attributes (its identity: primitives naming the same
/// accessors share one array).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct AttributeAccessors {
    /// `POSITION`.
    pub position: usize,
    /// `NORMAL`.
    pub normal: Option<usize>,
    /// `TEXCOORD_0`.
    pub tex_coord: Option<usize>,
    /// `COLOR_0`.
    pub color: Option<usize>,
    /// `JOINTS_0`.
    pub joints: Option<usize>,
    /// `WEIGHTS_0`.
    pub weights: Option<usize>,
}

/// One vertex list, read once: positions and the optional attributes, all of one length.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexArray {
    /// The accessors it was read from.
    pub accessors: AttributeAccessors,
    /// Positions (in the mesh's node space).
    pub positions: Vec<Vec3>,
    /// Normals (empty when absent).
    pub normals: Vec<Vec3>,
    /// `TEXCOORD_0`, glTF convention (v down; empty when absent).
    pub tex_coords: Vec<Vec2>,
    /// `COLOR_0` as linear RGBA (RGB files get alpha 1; empty when absent).
    pub colors: Vec<Vec4>,
    /// `JOINTS_0`: indices into the skin's joints (empty when absent).
    pub joints: Vec<[u16; 4]>,
    /// `WEIGHTS_0` (empty when absent).
    pub weights: Vec<Vec4>,
}

/// A morph target: per-vertex deltas, read once.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MorphTarget {
    /// Its `POSITION` accessor, if any.
    pub position_accessor: Option<usize>,
    /// Its `NORMAL` accessor, if any.
    pub normal_accessor: Option<usize>,
    /// Position deltas (empty when absent).
    pub positions: Vec<Vec3>,
    /// Normal deltas (empty when absent).
    pub normals: Vec<Vec3>,
}

/// A skin: joints and their inverse bind matrices.
#[derive(Clone, Debug, PartialEq)]
pub struct Skin {
    /// Its name, if it has one.
    pub name: Option<String>,
    /// Joint nodes, in the order `JOINTS_0` counts them.
    pub joints: Vec<usize>,
    /// One inverse bind matrix per joint (identity when the file has none).
    pub inverse_bind_matrices: Vec<Mat4>,
    /// The skeleton's root node, if named.
    pub skeleton: Option<usize>,
}

/// How a material's alpha is used.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    /// Alpha ignored.
    Opaque,
    /// Drawn where alpha is at least the cutoff, else not at all.
    Mask {
        /// `alphaCutoff` (0.5 by default).
        cutoff: f32,
    },
    /// Blended: see-through.
    Blend,
}

/// A texture reference of a material.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextureRef {
    /// Index into [`Avatar::textures`].
    pub texture: usize,
    /// Which `TEXCOORD_n` it reads.
    pub tex_coord: u32,
}

/// A material: PBR base colour, alpha, sides.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Its name, if it has one.
    pub name: Option<String>,
    /// `baseColorFactor` (linear RGBA).
    pub base_color: Vec4,
    /// `baseColorTexture`.
    pub base_color_texture: Option<TextureRef>,
    /// `metallicFactor`.
    pub metallic: f32,
    /// `roughnessFactor`.
    pub roughness: f32,
    /// `normalTexture`.
    pub normal_texture: Option<TextureRef>,
    /// `emissiveFactor`.
    pub emissive: Vec3,
    /// `alphaMode` with its cutoff.
    pub alpha_mode: AlphaMode,
    /// `doubleSided`.
    pub double_sided: bool,
}

/// A texture sampler, as glTF's GL enums (None: the viewer's choice).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sampler {
    /// `magFilter` (9728 nearest, 9729 linear).
    pub mag_filter: Option<u32>,
    /// `minFilter` (9728..9987).
    pub min_filter: Option<u32>,
    /// `wrapS` (10497 repeat by default).
    pub wrap_s: u32,
    /// `wrapT` (10497 repeat by default).
    pub wrap_t: u32,
}

/// A texture: an image and how it is sampled.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Its name, if it has one.
    pub name: Option<String>,
    /// Index into [`Avatar::images`].
    pub image: usize,
    /// Its sampler (glTF's defaults when the file gives none).
    pub sampler: Sampler,
}

/// An image with its encoded bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Its name, if it has one.
    pub name: Option<String>,
    /// `mimeType`, else guessed from the bytes (`image/png`, `image/jpeg`), else None.
    pub mime_type: Option<String>,
    /// The file it came from, for an image beside a `.gltf` (None: a buffer view or data URI).
    pub uri: Option<String>,
    /// The encoded bytes (PNG, JPEG, ...), unchanged.
    pub bytes: Vec<u8>,
}
