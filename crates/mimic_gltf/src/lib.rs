#![cfg_attr(
    test,
    allow(
        clippy::unwrap_used,
        reason = "tests: a failed unwrap is the failure report"
    )
)]
//! glTF 2.0 out: a rig and a performance as one binary glTF (GLB) file.
//!
//! mimic's deformation is linear, `u = B d`, so it maps onto glTF morph targets exactly: one
//! target per control and axis (the columns of [`mimic_solve::Basis`] times the axis unit
//! vector, [`basis_morphs`]) whose weights per frame are the control displacements `d` in metres
//! ([`basis_weights`]). In blendshape mode the rig's own morph targets are written instead
//! ([`target_morphs`]) with the fitted weights. [`Take`] collects the keys of a performance
//! (weights and head pose per frame); [`write_glb`] writes mesh, materials, targets and the
//! animation. Units and axes: [`metres_per_unit`] and docs/gltf.md.
//!
//! glTF in: `mimic_avatar` reads a glTF, GLB or VRM avatar whole ([`load_avatar`],
//! docs/avatars.md), after the structure checks of [`gltf_check`] (both re-exported here).

mod avatar_out;
mod avatar_placement;
mod glb;
mod morphs;
mod rig;
mod sink;
mod take;
mod units;
mod vertices;
mod vrm_out;

pub use avatar_out::{AvatarGlbSummary, head_node, write_avatar_glb};
pub use glb::{GlbSummary, GltfMaterial, GltfMesh, Scene, write_glb};
pub use mimic_avatar as avatar;
pub use mimic_avatar::{Avatar, AvatarError, gltf_check, load_avatar, parse_avatar};
pub use morphs::{Morph, basis_morphs, basis_weights, control_morphs, target_morphs};
pub use rig::{RigLookParts, export_rig_glb, rig_look_parts, write_rig_glb};
pub use sink::{GlbKeys, GlbSink, take_path};
pub use take::{Interpolation, Take, head_translation};
pub use units::{MODEL_UNIT_METRES, UnitsError, metres_per_unit, rig_metres_per_unit};
pub use vertices::{SplitVertices, split_vertices};
pub use vrm_out::{ARKIT_NAMES, PRESETS, VrmBinds, arkit_name};

/// Why a GLB could not be written.
#[derive(Debug, thiserror::Error)]
pub enum GltfError {
    /// Writing the file failed.
    #[error("writing the GLB: {0}")]
    Io(#[from] std::io::Error),
    /// Encoding the JSON chunk failed.
    #[error("encoding the glTF JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// A triangle's texture coordinate index points past the mesh's UVs.
    #[error("triangle {triangle} uses texture coordinate {uv}, but the mesh has {uv_count}")]
    UvIndex {
        /// Triangle number.
        triangle: usize,
        /// Offending UV index.
        uv: u32,
        /// UVs in the mesh.
        uv_count: usize,
    },
    /// A triangle names a vertex past the mesh's positions.
    #[error("triangle {triangle} uses vertex {vertex}, but the mesh has {vertex_count}")]
    VertexIndex {
        /// Triangle number.
        triangle: usize,
        /// Offending vertex.
        vertex: u32,
        /// Vertices in the mesh.
        vertex_count: usize,
    },
    /// A morph target names a vertex past the mesh's positions.
    #[error("morph target `{name}` moves vertex {vertex}, but the mesh has {vertex_count}")]
    MorphVertex {
        /// Target name.
        name: String,
        /// Offending vertex.
        vertex: u32,
        /// Vertices in the mesh.
        vertex_count: usize,
    },
    /// The take's keys have another target count than the mesh.
    #[error("the take has {take} weights per key, the mesh {mesh} morph targets")]
    TargetCount {
        /// Weights per key.
        take: usize,
        /// Morph targets.
        mesh: usize,
    },
    /// Reading the rig's files failed.
    #[error(transparent)]
    Asset(#[from] mimic_assets::AssetError),
    /// The rig's `units` has no known length in metres.
    #[error("rig units `{0}`: not one of m, cm, mm, in, model (glTF needs metres)")]
    Units(String),
    /// The binary chunk would pass glTF's 4 GiB limit.
    #[error("the binary chunk would be {0} bytes, over glTF's 4 GiB limit")]
    TooLarge(usize),
}

#[cfg(test)]
mod tests;
