//! The v1 recording format (JSON Lines): a header line, then one frame per line.
//!
//! The normative description is `docs/recording-format.md`. In memory a frame is a
//! [`LandmarkFrame`]; a point with no value has `valid[i] == false` and position `NaN`
//! (never a made-up position such as the origin).

mod error;
use mimic_types::recording as header;
mod reader;
mod summary;
mod writer;

pub use error::{FrameError, FrameProblem, RecordingError, WriteError};
pub use header::{FORMAT_NAME, FORMAT_VERSION, RecordingHeader, UNITS_METRES};
pub use reader::{
    MAX_LINE_BYTES, ReadStats, Recording, RecordingReader, RejectCounts, parse_frame_line,
    read_recording,
};
pub use summary::{RecordingSummary, summarize, summarize_lenient, summarize_reader};
pub use writer::{RecordingWriter, format_coordinate};

use mimic_types::LandmarkFrame;

/// One frame of a recording with its optional per-frame label (e.g. GFE "expression happening" 0/1).
#[derive(Clone, Debug, PartialEq)]
pub struct RecordedFrame {
    /// The landmarks.
    pub frame: LandmarkFrame,
    /// Optional integer label from the recording's `"label"` field.
    pub label: Option<i64>,
}

impl RecordedFrame {
    /// A frame without a label.
    pub fn unlabelled(frame: LandmarkFrame) -> Self {
        Self { frame, label: None }
    }
}
