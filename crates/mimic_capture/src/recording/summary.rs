//! Whole-file summaries of recordings, for `mimic info`.

use super::error::RecordingError;
use super::header::RecordingHeader;
use super::reader::{RecordingReader, RejectCounts};
use serde::Serialize;
use std::path::Path;

/// What a recording holds and how healthy it is.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RecordingSummary {
    /// The file, as given.
    pub path: String,
    /// The header line.
    pub header: RecordingHeader,
    /// Points per tracked frame (given, from the header, or from the first frame).
    pub point_count: Option<usize>,
    /// Accepted frames, lost-tracking frames included.
    pub frames: usize,
    /// Accepted frames with `tracked: false`.
    pub lost_tracking_frames: usize,
    /// Invalid points summed over accepted frames.
    pub invalid_points: usize,
    /// Accepted frames with a label.
    pub labelled_frames: usize,
    /// Accepted frames whose label is non-zero.
    pub positive_labels: usize,
    /// Timestamp of the first accepted frame (µs).
    pub first_t_us: Option<i64>,
    /// Timestamp of the last accepted frame (µs).
    pub last_t_us: Option<i64>,
    /// Last minus first timestamp, in seconds.
    pub duration_s: f64,
    /// (frames − 1) / duration, in Hz; `None` for fewer than two frames.
    pub mean_rate_hz: Option<f64>,
    /// Largest gap between consecutive accepted frames, in seconds.
    pub max_gap_s: f64,
    /// Rejected frames by reason.
    pub rejected: RejectCounts,
    /// The first rejection, as `file:line: reason`.
    pub first_problem: Option<String>,
}

/// Reads the whole file strictly: the first rejected frame is returned as the error.
pub fn summarize(
    path: &Path,
    expected_points: Option<usize>,
) -> Result<RecordingSummary, RecordingError> {
    summarize_with(path, expected_points, true)
}

/// Reads the whole file, counting rejected frames instead of failing on them.
pub fn summarize_lenient(
    path: &Path,
    expected_points: Option<usize>,
) -> Result<RecordingSummary, RecordingError> {
    summarize_with(path, expected_points, false)
}

fn summarize_with(
    path: &Path,
    expected_points: Option<usize>,
    strict: bool,
) -> Result<RecordingSummary, RecordingError> {
    summarize_reader(RecordingReader::open(path, expected_points)?, strict)
}

/// [`summarize`] (or, not `strict`, [`summarize_lenient`]) of an open reader, from its next frame
/// (e.g. after its header was looked at and [`RecordingReader::expect_points`] set).
pub fn summarize_reader<R: std::io::BufRead>(
    mut reader: RecordingReader<R>,
    strict: bool,
) -> Result<RecordingSummary, RecordingError> {
    let mut first_problem = None;
    let (mut first, mut last) = (None::<i64>, None::<i64>);
    let mut max_gap_us = 0i64;
    let (mut labelled, mut positive) = (0usize, 0usize);
    for item in reader.by_ref() {
        match item {
            Ok(f) => {
                let t = f.frame.timestamp_us;
                first.get_or_insert(t);
                if let Some(prev) = last {
                    max_gap_us = max_gap_us.max(t - prev);
                }
                last = Some(t);
                if let Some(l) = f.label {
                    labelled += 1;
                    if l != 0 {
                        positive += 1;
                    }
                }
            }
            Err(e) if strict => return Err(e.into()),
            Err(e) => {
                if first_problem.is_none() {
                    first_problem = Some(e.to_string());
                }
            }
        }
    }
    let stats = reader.stats().clone();
    let duration_s = match (first, last) {
        (Some(a), Some(b)) => (b - a) as f64 * 1e-6,
        _ => 0.0,
    };
    let mean_rate_hz =
        (stats.accepted >= 2 && duration_s > 0.0).then(|| (stats.accepted - 1) as f64 / duration_s);
    Ok(RecordingSummary {
        path: reader.path().display().to_string(),
        header: reader.header().clone(),
        point_count: reader.expected_points(),
        frames: stats.accepted,
        lost_tracking_frames: stats.lost_tracking,
        invalid_points: stats.invalid_points,
        labelled_frames: labelled,
        positive_labels: positive,
        first_t_us: first,
        last_t_us: last,
        duration_s,
        mean_rate_hz,
        max_gap_s: max_gap_us as f64 * 1e-6,
        rejected: stats.rejected,
        first_problem,
    })
}
