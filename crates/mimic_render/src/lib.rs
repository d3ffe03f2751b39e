//! `mimic_render`: a headless wgpu renderer for mimic rigs.
//!
//! A rig is uploaded once ([`Renderer::upload_rig`]): rest positions, triangles and the basis `B`
//! (n x m, row-major) in storage buffers. Per frame a uniform (the camera, the head transform) and
//! the m control displacements `d` (a storage buffer sized for the rig, so m is not bounded by a
//! uniform: 64 morph targets are 192 columns) go up. A compute pass computes the morph
//! `P_i = P0_i + sum_j B[i, j] d_j` and a second one the area-weighted vertex normals of the
//! morphed surface; the vertex shader fetches vertex `i` by index and applies the head transform
//! and the camera; the fragment shader lights it (diffuse + ambient) or colours it as a heat map of
//! `|P_i - P0_i|` or of one column `B[i, j]`. An [`Overlay`] (bitmap text, panels, the heat map's
//! colour legend, bars) can be composited over the image ([`Renderer::render_with`]).
//! [`Deform::Positions`] takes full vertex positions instead. Images come back as RGBA8 ([`Image`]) and can be written as PNG.
//!
//! Runs on any Vulkan adapter, including Mesa's software lavapipe. No tokio.

mod camera;
mod error;
pub mod headless;
mod image;
pub mod overlay;
mod renderer;
mod texture;

pub use camera::Camera;
pub use error::RenderError;
pub use image::Image;
pub use overlay::{Anchor, Overlay, Rect};
pub use renderer::{
    COLOR_FORMAT, Deform, MAX_CONTROLS, Renderer, RigGpu, SKIN_ALBEDO, Shading, View,
};
