//! Errors of the viewer.

/// What can stop `mimic view`.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// The renderer failed (no adapter, a size, a buffer).
    #[error(transparent)]
    Render(#[from] mimic_render::RenderError),
    /// A rig's look (materials, textures) could not be read.
    #[error(transparent)]
    Asset(#[from] mimic_assets::AssetError),
    /// Opening the window or its event loop failed.
    #[error("window: {0}")]
    Window(String),
    /// The GPU surface of the window could not be made.
    #[error("window surface: {0}")]
    Surface(String),
    /// Connecting to `mimic serve` failed.
    #[error("connecting to {addr}: {cause}")]
    Connect {
        /// Address given.
        addr: String,
        /// What the OS said.
        cause: std::io::Error,
    },
    /// The live rig does not hold together (basis size vs vertices).
    #[error("live rig `{0}`: the basis does not match its vertices")]
    BadRig(String),
    /// Building a basis or a retargeter for the other solver failed.
    #[error("{0}")]
    Solver(String),
    /// An option that names nothing the rig has (`--heat control:FDP`).
    #[error("{0}")]
    Option(String),
    /// An output folder could not be created.
    #[error("creating {}", path.display())]
    Folder {
        /// The folder.
        path: std::path::PathBuf,
        /// What the OS said.
        #[source]
        cause: std::io::Error,
    },
    /// The rig's mesh has no vertices to frame.
    #[error("the rig's mesh is empty")]
    EmptyMesh,
    /// The recording has no frames to play.
    #[error("the recording has no accepted frames")]
    NoFrames,
}
