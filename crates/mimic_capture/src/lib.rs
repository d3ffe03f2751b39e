//! Frame sources for mimic: the v1 recording format, importers of other trackers' files, paced replay.
//!
//! Entry points: [`RecordingReader`] / [`RecordingWriter`] / [`summarize`] (the JSON Lines
//! format of `docs/recording-format.md`), [`gfe::import_gfe`] and [`openface::import_openface`]
//! (importers), [`Replay`] (frames at their recorded pace on `tokio::time`).
//! Depends on mimic_types, glam, serde and tokio's timer only: no networking, no rendering.

pub mod gfe;
pub mod openface;
pub mod recording;
pub mod replay;

pub use recording::{
    FrameError, FrameProblem, ReadStats, RecordedFrame, RecordingError, RecordingHeader,
    RecordingReader, RecordingSummary, RecordingWriter, RejectCounts, WriteError, summarize,
    summarize_lenient,
};
pub use replay::{
    FileSource, FrameSource, MemorySource, Pace, Replay, ReplayError, ReplayFrame, ReplayOptions,
    ReplayStart,
};

/// A converted recording held in memory: header and frames, ready for [`RecordingWriter`].
#[derive(Clone, Debug, PartialEq)]
pub struct Imported {
    /// Header to write.
    pub header: RecordingHeader,
    /// Frames in time order.
    pub frames: Vec<RecordedFrame>,
}

impl Imported {
    /// Writes header and frames to `out`.
    pub fn write_to<W: std::io::Write>(&self, out: W) -> Result<W, WriteError> {
        let mut w = RecordingWriter::new(out, &self.header)?;
        for f in &self.frames {
            w.write(f)?;
        }
        w.finish()
    }

    /// Accepted frames with `tracked: false`.
    pub fn lost_frames(&self) -> usize {
        self.frames.iter().filter(|f| !f.frame.tracked).count()
    }

    /// Invalid points summed over all frames.
    pub fn invalid_points(&self) -> usize {
        self.frames
            .iter()
            .map(|f| f.frame.valid.iter().filter(|v| !**v).count())
            .sum()
    }
}
