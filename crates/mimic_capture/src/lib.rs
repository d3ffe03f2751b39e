//! Frame sources for mimic: the v1 recording format and paced replay.
//!
//! Entry points: [`read_recording`] (a whole file: header, accepted frames, counts),
//! [`RecordingReader`] / [`RecordingWriter`] / [`summarize`] (the JSON Lines
//! format of `docs/recording-format.md`), [`Imported`] (a converted recording held in memory,
//! what every tracker's importer in `mimic_trackers` returns), [`named_csv`] (CSV read by its
//! column names), [`Replay`] (frames at their recorded pace on `tokio::time`). The trackers'
//! own formats (GFE, OpenFace, MediaPipe, OpenSeeFace, Live Link) live in `mimic_trackers`,
//! one module each.
//! Depends on mimic_types, glam, serde and tokio's timer only (for [`Replay`], the default
//! `replay` feature): no networking, no rendering.

mod imported;
pub mod named_csv;
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
