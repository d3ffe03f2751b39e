//! A converted recording held in memory, as the importers return it.

use crate::recording::{RecordedFrame, RecordingHeader, RecordingWriter, WriteError};

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
