//! A converted recording held in memory, as the importers return it.

use crate::recording::{RecordedFrame, RecordingHeader, RecordingWriter, WriteError};

/// Mean frame rate of frames in time order, from the first to the last timestamp; `None` for
/// fewer than two frames or no time between them.
pub fn mean_rate_hz(frames: &[RecordedFrame]) -> Option<f64> {
    let (first, last) = (frames.first()?, frames.last()?);
    let span = (last.frame.timestamp_us - first.frame.timestamp_us) as f64 * 1e-6;
    (span > 0.0).then(|| (frames.len() - 1) as f64 / span)
}

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

    /// The line `mimic import` prints for the recording written to `output`: frames, lost
    /// frames, invalid points, duration and layout.
    pub fn summary(&self, output: &std::path::Path) -> String {
        let frames = &self.frames;
        let duration_s = match (frames.first(), frames.last()) {
            (Some(a), Some(b)) => (b.frame.timestamp_us - a.frame.timestamp_us) as f64 * 1e-6,
            _ => 0.0,
        };
        format!(
            "{}: {} frames ({} lost tracking), {} invalid points, {:.1} s, layout {}",
            output.display(),
            frames.len(),
            self.lost_frames(),
            self.invalid_points(),
            duration_s,
            self.header.layout
        )
    }

    /// Invalid points summed over all frames.
    pub fn invalid_points(&self) -> usize {
        self.frames
            .iter()
            .map(|f| f.frame.valid.iter().filter(|v| !**v).count())
            .sum()
    }
}
