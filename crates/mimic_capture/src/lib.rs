//! Frame sources for mimic: the v1 recording format, importers of other trackers' files, paced replay.
//!
//! Entry points: [`read_recording`] (a whole file: header, accepted frames, counts),
//! [`RecordingReader`] / [`RecordingWriter`] / [`summarize`] (the JSON Lines
//! format of `docs/recording-format.md`), [`gfe::import_gfe`], [`openface::import_openface`] and
//! [`mediapipe::import_mediapipe`] (importers), [`Replay`] (frames at their recorded pace on `tokio::time`).
//! Depends on mimic_types, glam, serde and tokio's timer only (for [`Replay`], the default
//! `replay` feature): no networking, no rendering.

pub mod gfe;
mod imported;
pub mod mediapipe;
pub mod named_csv;
pub mod openface;
pub mod recording;
#[cfg(feature = "replay")]
pub mod replay;

pub use imported::{Imported, mean_rate_hz};
pub use recording::{
    FrameError, FrameProblem, ReadStats, RecordedFrame, Recording, RecordingError, RecordingHeader,
    RecordingReader, RecordingSummary, RecordingWriter, RejectCounts, WriteError, parse_frame_line,
    read_recording, summarize, summarize_lenient, summarize_reader,
};
#[cfg(feature = "replay")]
pub use replay::{
    FileSource, FrameSource, MemorySource, Pace, Replay, ReplayError, ReplayFrame, ReplayOptions,
    ReplayStart,
};
