//! The one error type of this crate: what went wrong, in which file, on which line.

use std::path::PathBuf;

/// A file that could not be read or does not hold together.
#[derive(Debug, thiserror::Error)]
pub enum AssetError {
    /// An avatar file (glTF, GLB, VRM) that does not read: its one-line error.
    #[error("{0}")]
    Avatar(#[from] mimic_avatar::AvatarError),
    /// The file could not be opened or read.
    #[error("{}: {cause}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        cause: std::io::Error,
    },
    /// A texture image that does not decode, or a texture the rig names wrongly.
    #[error("{}: {message}", path.display())]
    Texture {
        /// The file.
        path: PathBuf,
        /// What was wrong.
        message: String,
    },
    /// A TOML file that does not parse or lacks a field.
    #[error("{}:{line}: {message}", path.display())]
    Toml {
        /// The file.
        path: PathBuf,
        /// 1-based line of the problem.
        line: usize,
        /// What was wrong.
        message: String,
    },
    /// An OBJ file with a bad line.
    #[error("{}:{line}: {message}", path.display())]
    Obj {
        /// The file.
        path: PathBuf,
        /// 1-based line of the problem (0 when tobj reports no line).
        line: usize,
        /// What was wrong.
        message: String,
    },
    /// A layout whose controls or stable points do not fit its points.
    #[error("{}:{line}: {cause}", path.display())]
    Layout {
        /// The file.
        path: PathBuf,
        /// 1-based line of the offending entry.
        line: usize,
        /// What was wrong.
        cause: mimic_types::LayoutError,
    },
    /// A rig whose controls or mask do not fit its mesh.
    #[error("{}:{line}: {cause}", path.display())]
    Rig {
        /// The file.
        path: PathBuf,
        /// 1-based line of the offending entry.
        line: usize,
        /// What was wrong.
        cause: mimic_types::RigError,
    },
    /// A rig's mesh could not be loaded.
    #[error("{}: mesh: {cause}", path.display())]
    RigMesh {
        /// The rig file.
        path: PathBuf,
        /// The mesh's own error.
        cause: Box<AssetError>,
    },
    /// A morph target mesh whose topology is not the neutral's.
    #[error("{}: {message}", path.display())]
    MorphTopology {
        /// The target's OBJ file.
        path: PathBuf,
        /// What differs, e.g. `26718 vertices, the neutral has 26719`.
        message: String,
    },
    /// A rig's morph target could not be loaded.
    #[error("{}:{line}: morph target `{name}`: {cause}", path.display())]
    MorphTarget {
        /// The rig file.
        path: PathBuf,
        /// 1-based line of the target's entry.
        line: usize,
        /// The target's name.
        name: String,
        /// The target's own error.
        cause: Box<AssetError>,
    },
    /// A morph data file with a bad line or wrong counts.
    #[error("{}:{line}: {message}", path.display())]
    MorphFile {
        /// The file.
        path: PathBuf,
        /// 1-based line of the problem.
        line: usize,
        /// What was wrong.
        message: String,
    },
    /// A shape pack (`*.shapes`) that does not hold together.
    #[error("{}: byte {offset}: {message}", path.display())]
    ShapePack {
        /// The file.
        path: PathBuf,
        /// Byte offset of the problem.
        offset: usize,
        /// What was wrong.
        message: String,
    },
    /// A numeric setting of a layout or rig outside its documented range (docs/reliability.md).
    #[error("{}:{line}: {cause}", path.display())]
    Setting {
        /// The file.
        path: PathBuf,
        /// 1-based line of the setting.
        line: usize,
        /// The setting, its value and the rule it breaks.
        cause: mimic_types::SettingError,
    },
    /// A file named by a setting (a rig's `mesh`) refused by its limits: not a regular file, or
    /// over its size cap. Refused before reading a byte of it.
    #[error("{}:{line}: {}: {cause}", path.display(), file.display())]
    Refused {
        /// The config file naming it.
        path: PathBuf,
        /// 1-based line of the setting that names it.
        line: usize,
        /// The refused file.
        file: PathBuf,
        /// Why.
        cause: mimic_types::ReadError,
    },
    /// A named layout was not found in any config directory.
    #[error("no layout named `{name}` (looked for {})", tried.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", "))]
    LayoutNotFound {
        /// Layout name.
        name: String,
        /// Paths looked at.
        tried: Vec<PathBuf>,
    },
}

impl AssetError {
    /// Wraps an I/O error with its path.
    pub(crate) fn io(path: &std::path::Path, cause: std::io::Error) -> Self {
        AssetError::Io {
            path: path.to_path_buf(),
            cause,
        }
    }

    /// Wraps a capped read's error (an OS error, or the file's refusal) with its path.
    pub(crate) fn read(path: &std::path::Path, cause: mimic_types::ReadError) -> Self {
        AssetError::io(path, cause.into())
    }
}
