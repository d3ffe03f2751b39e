//! Documented limits on what mimic reads: a size cap per kind of file, no reads of anything but
//! regular files, the largest counts a layout, mesh or morph file may hold, and the error for a
//! numeric setting out of its range. The rules are listed in docs/reliability.md ("Config files").
//!
//! [`read_capped`] and [`open_regular`] are the only I/O of this crate: every config and import
//! file goes through them (from `mimic_assets` and `mimic_capture`), so the caps live in one place.

use std::fs::File;
use std::io::Read;
use std::path::Path;

/// Most points a landmark layout may have (`point_count`); the largest shipped has 121.
pub const MAX_LAYOUT_POINTS: usize = 4096;
/// Most vertices a mesh may have; the ICT-FaceKit head has 26 719.
pub const MAX_MESH_VERTICES: usize = 1 << 20;
/// Most triangles a mesh may have (after triangulation); the ICT-FaceKit head has 52 220.
pub const MAX_MESH_TRIANGLES: usize = 1 << 21;
/// Most morph targets a rig or a morph data file may have (ARKit has 52).
pub const MAX_MORPH_TARGETS: usize = 1024;

/// A kind of file and the most bytes mimic reads of it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FileKind {
    /// What the files are, plural, as error messages name them (`OBJ meshes`).
    pub what: &'static str,
    /// Size cap in bytes (a whole number of MiB).
    pub max_bytes: u64,
}

const MIB: u64 = 1 << 20;

/// Landmark layouts (`configs/layouts/*.toml`, largest shipped 21 KB).
pub const LAYOUT_FILE: FileKind = FileKind {
    what: "layout files",
    max_bytes: MIB,
};
/// Rig files (`configs/rigs/*.toml`, largest shipped 10 KB).
pub const RIG_FILE: FileKind = FileKind {
    what: "rig files",
    max_bytes: MIB,
};
/// OBJ meshes: a rig's mesh and its morph targets (the ICT-FaceKit OBJs are 2.6 MB).
pub const OBJ_FILE: FileKind = FileKind {
    what: "OBJ meshes",
    max_bytes: 64 * MIB,
};
/// MTL material files (ICT-FaceKit's is 1.4 KB).
pub const MTL_FILE: FileKind = FileKind {
    what: "MTL files",
    max_bytes: MIB,
};
/// Morph data files (`mimic morph export`; the ICT rig's 8 targets make 11.9 MB).
pub const MORPH_FILE: FileKind = FileKind {
    what: "morph data files",
    max_bytes: 256 * MIB,
};
/// GFE `*_datapoints.txt` and `*_targets.txt` files (the largest of the dataset is 2.9 MB).
pub const GFE_FILE: FileKind = FileKind {
    what: "GFE files",
    max_bytes: 64 * MIB,
};
/// OpenFace CSV files (about 8 KB a frame: 256 MiB is some 18 minutes at 30 fps).
pub const OPENFACE_FILE: FileKind = FileKind {
    what: "OpenFace CSV files",
    max_bytes: 256 * MIB,
};
/// Weights CSV files (`mimic morph apply`, `mimic send --weights`).
pub const WEIGHTS_FILE: FileKind = FileKind {
    what: "weights CSV files",
    max_bytes: 256 * MIB,
};
/// Model files such as CANDIDE-3's `.wfm` (16 KB).
pub const MODEL_FILE: FileKind = FileKind {
    what: "model files",
    max_bytes: 16 * MIB,
};

/// Why a file was not read.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The OS could not stat, open or read it.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// A FIFO, device, socket or directory: refused before reading a byte.
    #[error("not a regular file but {kind}; {what} are read only from regular files")]
    NotRegular {
        /// What the path is, e.g. `a character device`.
        kind: &'static str,
        /// The kind of file expected, plural.
        what: &'static str,
    },
    /// Larger than the cap of its kind.
    #[error("{size} bytes, over the {} cap for {what}", cap_text(*cap))]
    TooLarge {
        /// Its size (or the bytes read before the cap was passed, if it grew while read).
        size: u64,
        /// The cap in bytes.
        cap: u64,
        /// The kind of file, plural.
        what: &'static str,
    },
}

impl ReadError {
    /// Whether mimic refused the file by its limits (as opposed to the OS failing to read it).
    pub fn is_refusal(&self) -> bool {
        !matches!(self, ReadError::Io(_))
    }
}

impl From<ReadError> for std::io::Error {
    fn from(e: ReadError) -> Self {
        match e {
            ReadError::Io(e) => e,
            refused @ ReadError::NotRegular { .. } => {
                std::io::Error::new(std::io::ErrorKind::InvalidInput, refused.to_string())
            }
            refused @ ReadError::TooLarge { .. } => {
                std::io::Error::new(std::io::ErrorKind::FileTooLarge, refused.to_string())
            }
        }
    }
}

/// A cap for messages: whole MiB as `64 MiB`, anything else in bytes.
fn cap_text(cap: u64) -> String {
    if cap >= MIB && cap.is_multiple_of(MIB) {
        format!("{} MiB", cap / MIB)
    } else {
        format!("{cap} bytes")
    }
}

/// What a non-regular file is, for messages.
fn kind_of(t: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_dir() {
        "a directory"
    } else {
        "something else"
    }
}

/// Refuses anything but a regular file (following symlinks), without opening it.
fn check_regular(meta: &std::fs::Metadata, what: &'static str) -> Result<(), ReadError> {
    if meta.is_file() {
        Ok(())
    } else {
        Err(ReadError::NotRegular {
            kind: kind_of(meta.file_type()),
            what,
        })
    }
}

/// Checks `path` against `kind` without opening it: a regular file no larger than the cap.
/// Returns its size.
pub fn check_file(path: &Path, kind: &FileKind) -> Result<u64, ReadError> {
    let meta = std::fs::metadata(path)?;
    check_regular(&meta, kind.what)?;
    if meta.len() > kind.max_bytes {
        return Err(ReadError::TooLarge {
            size: meta.len(),
            cap: kind.max_bytes,
            what: kind.what,
        });
    }
    Ok(meta.len())
}

/// Opens `path` for a streaming reader that bounds its own memory (recordings): refuses FIFOs,
/// devices, sockets and directories before opening them; no size cap.
pub fn open_regular(path: &Path, what: &'static str) -> Result<File, ReadError> {
    check_regular(&std::fs::metadata(path)?, what)?;
    let file = File::open(path)?;
    // The path may have been swapped between the check and the open.
    check_regular(&file.metadata()?, what)?;
    Ok(file)
}

/// Reads a whole file of `kind` as bytes: a regular file within the kind's cap, else an error
/// before reading a byte (or as soon as a file that grows passes the cap).
pub fn read_bytes_capped(path: &Path, kind: &FileKind) -> Result<Vec<u8>, ReadError> {
    let size = check_file(path, kind)?;
    let file = open_regular(path, kind.what)?;
    let mut bytes = Vec::with_capacity(size as usize);
    file.take(kind.max_bytes + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > kind.max_bytes {
        return Err(ReadError::TooLarge {
            size: bytes.len() as u64,
            cap: kind.max_bytes,
            what: kind.what,
        });
    }
    Ok(bytes)
}

/// Reads a whole UTF-8 file of `kind`, like [`std::fs::read_to_string`] but within the kind's cap
/// and only from a regular file.
pub fn read_capped(path: &Path, kind: &FileKind) -> Result<String, ReadError> {
    let bytes = read_bytes_capped(path, kind)?;
    String::from_utf8(bytes).map_err(|_| {
        ReadError::Io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            "stream did not contain valid UTF-8",
        ))
    })
}

/// A numeric setting of a config file outside its documented range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key} = {value}: {rule}")]
pub struct SettingError {
    /// The setting's TOML key path, e.g. `regions.band` or `solver.top_split.lower_kernel.radius`.
    pub key: &'static str,
    /// The value as read.
    pub value: String,
    /// The rule it breaks, e.g. `must be finite and >= 0`.
    pub rule: String,
}

impl SettingError {
    /// An error for `key` holding `value`.
    pub fn new(key: &'static str, value: impl std::fmt::Display, rule: impl Into<String>) -> Self {
        SettingError {
            key,
            value: value.to_string(),
            rule: rule.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TINY: FileKind = FileKind {
        what: "tiny files",
        max_bytes: 8,
    };

    #[test]
    fn reads_within_the_cap_and_refuses_past_it() {
        let dir = tempfile_dir();
        let ok = dir.join("ok.txt");
        std::fs::write(&ok, "12345678").unwrap();
        assert_eq!(read_capped(&ok, &TINY).unwrap(), "12345678");
        let big = dir.join("big.txt");
        std::fs::write(&big, "123456789").unwrap();
        let e = read_capped(&big, &TINY).unwrap_err();
        assert!(e.is_refusal());
        assert_eq!(
            e.to_string(),
            "9 bytes, over the 8 bytes cap for tiny files"
        );
        let e = read_capped(&big, &OBJ_FILE).unwrap();
        assert_eq!(e.len(), 9);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn refuses_devices_and_directories_before_reading() {
        let e = read_capped(Path::new("/dev/zero"), &OBJ_FILE).unwrap_err();
        assert_eq!(
            e.to_string(),
            "not a regular file but a character device; OBJ meshes are read only from regular files"
        );
        let e = open_regular(Path::new("/dev/null"), "recordings").unwrap_err();
        assert!(e.to_string().contains("a character device"), "{e}");
        let e = read_capped(Path::new("/"), &LAYOUT_FILE).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("not a regular file but a directory")
        );
        let io: std::io::Error = e.into();
        assert_eq!(io.kind(), std::io::ErrorKind::InvalidInput);
    }

    #[test]
    fn missing_file_is_the_os_error() {
        let e = read_capped(Path::new("/no/such/file.toml"), &LAYOUT_FILE).unwrap_err();
        assert!(!e.is_refusal());
        let io: std::io::Error = e.into();
        assert_eq!(io.kind(), std::io::ErrorKind::NotFound);
    }

    #[test]
    fn caps_are_whole_mib() {
        for k in [
            LAYOUT_FILE,
            RIG_FILE,
            OBJ_FILE,
            MTL_FILE,
            MORPH_FILE,
            GFE_FILE,
            OPENFACE_FILE,
            WEIGHTS_FILE,
            MODEL_FILE,
        ] {
            assert!(k.max_bytes.is_multiple_of(MIB), "{}", k.what);
            assert!(k.max_bytes >= MIB, "{}", k.what);
        }
    }

    #[test]
    fn shipped_configs_are_far_below_their_caps() {
        let configs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs");
        let mut checked = 0;
        for (dir, ext, kind) in [
            ("layouts", "toml", LAYOUT_FILE),
            ("rigs", "toml", RIG_FILE),
            ("meshes/ict-facekit", "obj", OBJ_FILE),
            ("meshes/candide3", "obj", OBJ_FILE),
            ("meshes/ict-facekit", "mtl", MTL_FILE),
        ] {
            let Ok(entries) = std::fs::read_dir(configs.join(dir)) else {
                continue;
            };
            for e in entries.flatten() {
                let p = e.path();
                if p.extension().is_some_and(|x| x == ext) {
                    let size = check_file(&p, &kind).unwrap();
                    // At least 20x headroom over every real file of the kind.
                    assert!(20 * size < kind.max_bytes, "{}", p.display());
                    checked += 1;
                }
            }
        }
        assert!(checked > 0 || !configs.exists());
    }

    /// A fresh scratch directory (this crate has no tempfile dev-dependency).
    fn tempfile_dir() -> std::path::PathBuf {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static N: AtomicUsize = AtomicUsize::new(0);
        let d = std::env::temp_dir().join(format!(
            "mimic-types-limits-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&d).unwrap();
        d
    }
}
