//! Errors of the audio path ([`AudioError`]): each names the file or the tool it is about.

use std::path::PathBuf;

/// What can go wrong turning speech into weights.
#[derive(Debug, thiserror::Error)]
pub enum AudioError {
    /// The file is not a WAV mimic can read (not RIFF/WAVE, compressed, empty, unreadable).
    #[error("{}: {reason}", path.display())]
    Wav {
        /// The WAV file.
        path: PathBuf,
        /// Why, in words.
        reason: String,
    },
    /// The recogniser could not be run or said something unreadable.
    #[error("phoneme recogniser ({python}): {reason}")]
    Recogniser {
        /// The Python interpreter that was run.
        python: String,
        /// Why, in words.
        reason: String,
    },
    /// The viseme table is malformed.
    #[error("viseme table {what}: {reason}")]
    Table {
        /// Which table (a path or `shipped`).
        what: String,
        /// Why, in words.
        reason: String,
    },
    /// A live stream's settings are unusable (e.g. its sample rate).
    #[error("audio stream: {0}")]
    Stream(String),
    /// Reading the transcript or writing the output failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
}
