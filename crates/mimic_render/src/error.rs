//! Errors of the renderer.

/// What can go wrong creating the renderer, uploading a rig, rendering or writing an image.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No GPU adapter (not even Mesa's software Vulkan, lavapipe) could be created.
    #[error(
        "no GPU adapter found ({0}); install a Vulkan driver, e.g. Mesa's software one: apt-get install mesa-vulkan-drivers libvulkan1"
    )]
    NoAdapter(String),
    /// The adapter refused to create a device.
    #[error("could not create a GPU device: {0}")]
    NoDevice(String),
    /// The rig has more controls than [`crate::MAX_CONTROLS`].
    #[error("the rig has {got} controls; the renderer holds at most {max}")]
    TooManyControls {
        /// Controls of the basis.
        got: usize,
        /// Most the renderer supports.
        max: usize,
    },
    /// Two inputs disagree in size (basis vs mesh, displacements vs controls, positions vs vertices).
    #[error("{what}: got {got}, expected {expected}")]
    SizeMismatch {
        /// What was measured.
        what: &'static str,
        /// Size given.
        got: usize,
        /// Size expected.
        expected: usize,
    },
    /// A triangle names a vertex outside the mesh.
    #[error("triangle {triangle} uses vertex {vertex}, but the mesh has {vertex_count} vertices")]
    BadIndex {
        /// Triangle number.
        triangle: usize,
        /// Offending vertex.
        vertex: u32,
        /// Vertices in the mesh.
        vertex_count: usize,
    },
    /// A textured triangle names a texture the rig does not have.
    #[error("triangle {triangle} uses texture {texture}, but there are {count}")]
    NoSuchTexture {
        /// Triangle number.
        triangle: usize,
        /// Offending texture index.
        texture: u32,
        /// Textures given.
        count: usize,
    },
    /// A control index of the weight heat map is out of range.
    #[error("heat map of control {control}, but the rig has {count} controls")]
    NoSuchControl {
        /// Requested control.
        control: usize,
        /// Controls of the rig.
        count: usize,
    },
    /// The image size is zero or above the device's texture limit.
    #[error("image size {width}x{height} is not supported (1..={max} per side)")]
    BadSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
        /// Largest side the device supports.
        max: u32,
    },
    /// Reading results back from the GPU failed.
    #[error("reading back from the GPU failed: {0}")]
    Readback(String),
    /// Writing a PNG failed.
    #[error("writing {path}: {message}")]
    Png {
        /// File written.
        path: String,
        /// What went wrong.
        message: String,
    },
}
