//! Rigs for any face mesh (docs/rigging.md): iBUG-68 landmark files, the face frame, the 38
//! MPEG-4 controls placed by rules relative to the landmarks, frozen parts, regions and kernels
//! in face units (`mimic rig new`), landmarks found by registering a template head when none are
//! given, and the checks of `mimic rig check`.

pub mod arkit;
pub mod avatar_parts;
pub mod avatar_summary;
pub mod check;
pub mod eyes;
pub mod frame;
pub mod gltf_mesh;
pub mod head_template;
pub mod icp;
pub mod landmarks;
pub mod lipcut;
pub mod make;
pub mod morph;
pub mod mouth_interior;
pub mod nearest;
pub mod new;
pub mod nonrigid;
pub mod orient;
pub mod overrides;
pub mod parts;
pub mod picture;
pub mod place;
pub mod register;
pub mod rigid_parts;
pub mod speech_mouth;
pub mod summary;
pub mod transfer;
pub mod write;

/// The glTF structure checks, now in `mimic_gltf` (shared with its avatar reader).
pub use mimic_avatar::gltf_check;

pub use check::{Warning, check_rig};
pub use frame::{FaceFrame, FramePoints};
pub use head_template::{
    FindSettings, FoundLandmarks, Registration, TemplateHead, find_landmarks,
    landmarks_of_registration, register_template,
};
pub use landmarks::{
    IBUG_POINTS, LandmarkBase, Landmarks, Numbering, landmarks_json, load_landmarks,
    parse_landmarks,
};
pub use make::{
    MadeRig, NewRig, cut_mesh_path, make_rig_file, prepare_output, write_rig_with_controls,
};
pub use new::{Defaults, GeneratedRig, guess_units, make_rig};
pub use overrides::apply_overrides;
pub use summary::{LayoutSummary, RigSummary};
pub use write::{relative_path, write_rig_toml};

use std::path::{Path, PathBuf};

/// Loads an OBJ face mesh (an avatar's face is `mimic_assets::read_avatar_face`'s).
pub fn load_mesh(path: &Path) -> Result<mimic_types::Mesh, RigNewError> {
    Ok(mimic_assets::load_obj(path)?)
}

/// Why a rig could not be made.
#[derive(Debug, thiserror::Error)]
pub enum RigNewError {
    /// A landmark file could not be read.
    #[error("{}: {cause}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        cause: mimic_types::ReadError,
    },
    /// A landmark file with a bad line.
    #[error("{}:{line}: {message}", path.display())]
    Landmarks {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What was wrong.
        message: String,
    },
    /// The landmarks do not give a usable face frame or region borders.
    #[error("{0}")]
    Frame(String),
    /// A mesh file that could not be read.
    #[error("{}: {message}", path.display())]
    Mesh {
        /// The file.
        path: PathBuf,
        /// What was wrong.
        message: String,
    },
    /// An OBJ or rig file error from `mimic_assets`.
    #[error(transparent)]
    Asset(#[from] mimic_assets::AssetError),
    /// A unit outside `mimic_types::rig::RIG_UNITS`.
    #[error("units `{0}` is not one of m, cm, mm, in, model")]
    Units(String),
    /// An override file (`rig new --overrides`) that is not TOML.
    #[error("{}:{line}: {message}", path.display())]
    OverrideSyntax {
        /// The override file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What was wrong.
        message: String,
    },
    /// An override key that cannot be merged, or with which the rig does not load.
    #[error("{}: key `{key}`: {message}", path.display())]
    Override {
        /// The override file.
        path: PathBuf,
        /// The key path (`solver.kernel`, `controls[5.1].vertex`).
        key: String,
        /// What was wrong.
        message: String,
    },
    /// A file that could not be written.
    #[error("{}: {cause}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        cause: std::io::Error,
    },
    /// An output path that cannot be written (checked before the work).
    #[error("{}: {message}", path.display())]
    Output {
        /// The path asked for.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// An error with what was being done in front of it.
    #[error("{context}: {cause}")]
    Context {
        /// What was being done.
        context: String,
        /// The error (its text is part of this one's, so it is no `source`).
        cause: Box<RigNewError>,
    },
}
