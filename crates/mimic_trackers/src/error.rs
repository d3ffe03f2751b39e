//! Errors of the tracker formats: a packet's (by byte offset) and a file's (by path and record
//! or line).

use std::path::PathBuf;

/// A packet that cannot be decoded: what is wrong and at which byte.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("byte {offset}: {reason}")]
pub struct PacketError {
    /// Byte offset in the packet where the problem is.
    pub offset: usize,
    /// What is wrong.
    pub reason: String,
}

impl PacketError {
    /// A problem at byte `offset`.
    pub fn new(offset: usize, reason: impl Into<String>) -> Self {
        Self {
            offset,
            reason: reason.into(),
        }
    }
}

/// A tracker file that cannot be read; every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum TrackerError {
    /// The file cannot be read (missing, too large, not a regular file).
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: mimic_types::limits::ReadError,
    },
    /// A record of a capture file is bad.
    #[error("{}: record {record} (file offset {file_offset}): {reason}", path.display())]
    Record {
        /// The file.
        path: PathBuf,
        /// 0-based record (datagram) number.
        record: usize,
        /// Byte offset of the record in the file.
        file_offset: u64,
        /// What is wrong.
        reason: String,
    },
    /// A line of a text file is bad.
    #[error("{}:{line}: {reason}", path.display())]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        reason: String,
    },
}
