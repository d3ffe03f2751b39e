//! Streaming reader of v1 recordings: one line at a time, bad frames rejected and counted.

use super::RecordedFrame;
use super::error::{FrameError, FrameProblem, RecordingError};
use super::header::RecordingHeader;
use glam::Vec3;
use mimic_types::LandmarkFrame;
use serde::{Deserialize, Serialize};
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

/// Rejected frames, by reason.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct RejectCounts {
    /// Lines that are not a valid frame object.
    pub bad_json: usize,
    /// A cut-off last line.
    pub truncated: usize,
    /// Tracked frames with the wrong number of points.
    pub point_count: usize,
    /// Points with a null or out-of-range coordinate not listed invalid.
    pub bad_coordinate: usize,
    /// `invalid` lists naming points the frame lacks.
    pub bad_invalid_index: usize,
    /// Timestamps not after the previous accepted frame's.
    pub time_not_increasing: usize,
    /// Lines longer than the reader's limit.
    pub too_long: usize,
    /// Lines that could not be read.
    pub io: usize,
}

impl RejectCounts {
    /// All rejected frames.
    pub fn total(&self) -> usize {
        self.bad_json
            + self.truncated
            + self.point_count
            + self.bad_coordinate
            + self.bad_invalid_index
            + self.time_not_increasing
            + self.too_long
            + self.io
    }

    fn count(&mut self, p: &FrameProblem) {
        let slot = match p {
            FrameProblem::Json { .. } => &mut self.bad_json,
            FrameProblem::Truncated { .. } => &mut self.truncated,
            FrameProblem::PointCount { .. } => &mut self.point_count,
            FrameProblem::BadCoordinate { .. } => &mut self.bad_coordinate,
            FrameProblem::InvalidIndexOutOfRange { .. } => &mut self.bad_invalid_index,
            FrameProblem::TimeNotIncreasing { .. } => &mut self.time_not_increasing,
            FrameProblem::TooLong { .. } => &mut self.too_long,
            FrameProblem::Io { .. } => &mut self.io,
        };
        *slot += 1;
    }
}

/// Longest line the reader takes (16 MiB; a 10 000-point frame is about 0.4 MB).
pub const MAX_LINE_BYTES: usize = 1 << 24;

/// Running counts of what a reader has seen so far.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ReadStats {
    /// Frames accepted (lost-tracking frames included).
    pub accepted: usize,
    /// Accepted frames with `tracked: false`.
    pub lost_tracking: usize,
    /// Invalid points summed over accepted frames.
    pub invalid_points: usize,
    /// Rejected frames by reason.
    pub rejected: RejectCounts,
}

/// One frame line as written in the file.
#[derive(Deserialize)]
struct FrameRecord {
    t_us: i64,
    #[serde(default)]
    points: Vec<Option<[Option<f64>; 3]>>,
    #[serde(default)]
    invalid: Vec<usize>,
    #[serde(default = "default_tracked")]
    tracked: bool,
    #[serde(default)]
    label: Option<i64>,
}

fn default_tracked() -> bool {
    true
}

/// Reads a v1 recording line by line from any `BufRead`.
///
/// The expected point count is, in order: the caller's, the header's `point_count`, or the
/// point count of the first accepted tracked frame. Iterating yields each accepted frame or
/// the error of each rejected line; reading goes on after a rejection.
pub struct RecordingReader<R> {
    input: R,
    path: PathBuf,
    header: RecordingHeader,
    expected_points: Option<usize>,
    line: u64,
    last_t_us: Option<i64>,
    stats: ReadStats,
    buf: Vec<u8>,
    max_line_bytes: usize,
    done: bool,
}

impl RecordingReader<BufReader<File>> {
    /// Opens a recording file and reads its header.
    pub fn open(path: &Path, expected_points: Option<usize>) -> Result<Self, RecordingError> {
        let file = mimic_types::limits::open_regular(path, "recordings").map_err(|e| {
            RecordingError::Open {
                path: path.to_path_buf(),
                source: e.into(),
            }
        })?;
        Self::new(BufReader::new(file), path, expected_points)
    }
}

impl<R: BufRead> RecordingReader<R> {
    /// Reads the header from `input`; `path` only names the source in messages.
    pub fn new(
        mut input: R,
        path: impl Into<PathBuf>,
        expected_points: Option<usize>,
    ) -> Result<Self, RecordingError> {
        let path = path.into();
        let header_error = |reason: String| RecordingError::Header {
            path: path.clone(),
            reason,
        };
        let mut buf = Vec::new();
        let n = read_line_capped(&mut input, &mut buf, MAX_LINE_BYTES)
            .map_err(|e| header_error(format!("cannot read the header: {e}")))?;
        match n {
            LineRead::Eof => return Err(header_error("empty file: no header line".to_string())),
            LineRead::TooLong => {
                return Err(header_error(format!(
                    "header line longer than {MAX_LINE_BYTES} bytes"
                )));
            }
            LineRead::Line => {}
        }
        let header: RecordingHeader = serde_json::from_slice(trim_line_end(&buf))
            .map_err(|e| header_error(format!("header is not a valid recording header ({e})")))?;
        header.check().map_err(header_error)?;
        let expected = header.point_count;
        let mut reader = Self {
            input,
            path,
            header,
            expected_points: expected,
            line: 1,
            last_t_us: None,
            stats: ReadStats::default(),
            buf,
            max_line_bytes: MAX_LINE_BYTES,
            done: false,
        };
        if let Some(n) = expected_points {
            reader.expect_points(n)?;
        }
        Ok(reader)
    }

    /// Checks frames against `n` points from now on (call it before the first frame, e.g. once
    /// the layout the header names is loaded); fails when the header says another count.
    pub fn expect_points(&mut self, n: usize) -> Result<(), RecordingError> {
        if let Some(file) = self.header.point_count
            && file != n
        {
            return Err(RecordingError::Header {
                path: self.path.clone(),
                reason: format!(
                    "header says {file} points per frame but layout {} is expected to have {n}",
                    self.header.layout
                ),
            });
        }
        self.expected_points = Some(n);
        Ok(())
    }

    /// Reads every remaining line: the accepted frames are kept, rejected lines only counted.
    pub fn read_all(mut self) -> Recording {
        let mut frames = Vec::new();
        while let Some(item) = self.next_frame() {
            if let Ok(f) = item {
                frames.push(f);
            }
        }
        Recording {
            header: self.header,
            frames,
            stats: self.stats,
        }
    }

    /// Sets the longest frame line taken (default [`MAX_LINE_BYTES`]); longer lines are rejected.
    pub fn with_max_line_bytes(mut self, limit: usize) -> Self {
        self.max_line_bytes = limit;
        self
    }

    /// The recording's header.
    pub fn header(&self) -> &RecordingHeader {
        &self.header
    }

    /// The path named in messages.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Points per tracked frame, once known.
    pub fn expected_points(&self) -> Option<usize> {
        self.expected_points
    }

    /// Counts so far.
    pub fn stats(&self) -> &ReadStats {
        &self.stats
    }

    /// 1-based number of the last line read (1 is the header).
    pub fn line(&self) -> u64 {
        self.line
    }

    /// The next accepted frame or rejected line; `None` at the end of the file.
    pub fn next_frame(&mut self) -> Option<Result<RecordedFrame, FrameError>> {
        loop {
            if self.done {
                return None;
            }
            let read = read_line_capped(&mut self.input, &mut self.buf, self.max_line_bytes);
            let n = match read {
                Ok(n) => n,
                Err(e) => {
                    self.done = true;
                    self.line += 1;
                    return Some(Err(self.reject(FrameProblem::Io {
                        detail: e.to_string(),
                    })));
                }
            };
            if let LineRead::Eof = n {
                self.done = true;
                return None;
            }
            self.line += 1;
            if let LineRead::TooLong = n {
                return Some(Err(self.reject(FrameProblem::TooLong {
                    limit: self.max_line_bytes,
                })));
            }
            let complete = self.buf.ends_with(b"\n");
            let text = trim_line_end(&self.buf);
            if text.iter().all(u8::is_ascii_whitespace) {
                continue;
            }
            let parsed = serde_json::from_slice::<FrameRecord>(text);
            let result = match parsed {
                Ok(rec) => self.check(rec),
                Err(e) => Err(json_problem(&e, complete)),
            };
            return Some(match result {
                Ok(f) => {
                    self.stats.accepted += 1;
                    if !f.frame.tracked {
                        self.stats.lost_tracking += 1;
                    }
                    self.stats.invalid_points += f.frame.valid.iter().filter(|v| !**v).count();
                    self.last_t_us = Some(f.frame.timestamp_us);
                    Ok(f)
                }
                Err(p) => Err(self.reject(p)),
            });
        }
    }

    fn reject(&mut self, problem: FrameProblem) -> FrameError {
        self.stats.rejected.count(&problem);
        FrameError {
            path: self.path.clone(),
            line: self.line,
            problem,
        }
    }

    fn check(&mut self, rec: FrameRecord) -> Result<RecordedFrame, FrameProblem> {
        let t_us = rec.t_us;
        let f = check_frame(rec, self.expected_points, &self.header.layout)?;
        if let Some(previous_us) = self.last_t_us
            && t_us <= previous_us
        {
            return Err(FrameProblem::TimeNotIncreasing { t_us, previous_us });
        }
        if f.frame.tracked && !f.frame.points.is_empty() && self.expected_points.is_none() {
            self.expected_points = Some(f.frame.points.len());
        }
        Ok(f)
    }
}

/// Parses one frame line (without its newline) as the reader does, except for the timestamp
/// order, which is the caller's to check: `expected_points` is the layout's point count (if
/// known) and `layout` only names it in messages. `complete` says whether the line ended with a
/// newline (a line that does not parse without one is [`FrameProblem::Truncated`]).
pub fn parse_frame_line(
    line: &[u8],
    complete: bool,
    expected_points: Option<usize>,
    layout: &str,
) -> Result<RecordedFrame, FrameProblem> {
    let rec = serde_json::from_slice::<FrameRecord>(trim_line_end(line))
        .map_err(|e| json_problem(&e, complete))?;
    check_frame(rec, expected_points, layout)
}

/// Point count, `invalid` indices and coordinates of a parsed frame line.
fn check_frame(
    rec: FrameRecord,
    expected_points: Option<usize>,
    layout: &str,
) -> Result<RecordedFrame, FrameProblem> {
    let count = rec.points.len();
    if rec.tracked || count > 0 {
        match expected_points {
            Some(expected) if expected != count => {
                return Err(FrameProblem::PointCount {
                    found: count,
                    expected,
                    layout: layout.to_string(),
                });
            }
            _ => {}
        }
    }
    let mut valid = vec![true; count];
    for &i in &rec.invalid {
        match valid.get_mut(i) {
            Some(v) => *v = false,
            None => return Err(FrameProblem::InvalidIndexOutOfRange { index: i, count }),
        }
    }
    let mut points = Vec::with_capacity(count);
    for (i, (p, ok)) in rec.points.iter().zip(&valid).enumerate() {
        if !ok {
            points.push(Vec3::NAN);
            continue;
        }
        let coords = p.and_then(|[x, y, z]| Some([x?, y?, z?]));
        let v = coords.map(|[x, y, z]| Vec3::new(x as f32, y as f32, z as f32));
        match v {
            Some(v) if v.is_finite() => points.push(v),
            _ => return Err(FrameProblem::BadCoordinate { point: i }),
        }
    }
    let frame = LandmarkFrame {
        timestamp_us: rec.t_us,
        points,
        valid,
        tracked: rec.tracked,
    };
    Ok(RecordedFrame {
        frame,
        label: rec.label,
    })
}

/// A whole recording in memory: its header, the accepted frames and the reader's counts.
#[derive(Clone, Debug, PartialEq)]
pub struct Recording {
    /// The header line.
    pub header: RecordingHeader,
    /// Accepted frames in file order (lost-tracking frames included).
    pub frames: Vec<RecordedFrame>,
    /// What was accepted and rejected.
    pub stats: ReadStats,
}

/// Opens a recording once and reads it whole (see [`RecordingReader::read_all`]).
pub fn read_recording(
    path: &Path,
    expected_points: Option<usize>,
) -> Result<Recording, RecordingError> {
    Ok(RecordingReader::open(path, expected_points)?.read_all())
}

impl<R: BufRead> Iterator for RecordingReader<R> {
    type Item = Result<RecordedFrame, FrameError>;
    fn next(&mut self) -> Option<Self::Item> {
        self.next_frame()
    }
}

/// What [`read_line_capped`] found.
enum LineRead {
    /// A line (possibly without a final newline) is in the buffer.
    Line,
    /// The line was longer than the limit; it was skipped up to its newline.
    TooLong,
    /// End of input.
    Eof,
}

/// Reads one line into `buf` (cleared first), never buffering more than `limit` + 1 bytes.
fn read_line_capped<R: BufRead>(
    input: &mut R,
    buf: &mut Vec<u8>,
    limit: usize,
) -> std::io::Result<LineRead> {
    buf.clear();
    let n = input
        .by_ref()
        .take(limit as u64 + 1)
        .read_until(b'\n', buf)?;
    if n == 0 {
        return Ok(LineRead::Eof);
    }
    if buf.len() > limit && !buf.ends_with(b"\n") {
        input.skip_until(b'\n')?;
        buf.clear();
        return Ok(LineRead::TooLong);
    }
    Ok(LineRead::Line)
}

/// The line without its trailing `\n` or `\r\n`.
fn trim_line_end(buf: &[u8]) -> &[u8] {
    let buf = buf.strip_suffix(b"\n").unwrap_or(buf);
    buf.strip_suffix(b"\r").unwrap_or(buf)
}

/// A parse error as a problem; a last line without newline that fails to parse is truncated.
fn json_problem(e: &serde_json::Error, complete: bool) -> FrameProblem {
    let full = e.to_string();
    // serde_json appends " at line L column C"; the line is always 1 here, so keep the message only.
    let detail = match full.rfind(" at line ") {
        Some(i) => full[..i].to_string(),
        None => full,
    };
    if complete {
        FrameProblem::Json {
            column: e.column(),
            detail,
        }
    } else {
        FrameProblem::Truncated { detail }
    }
}

#[cfg(test)]
mod parse_line_tests {
    use super::*;

    #[test]
    fn parse_frame_line_agrees_with_the_reader() {
        let frames = [
            "{\"t_us\":10,\"points\":[[0.1,0.2,-0.9],null],\"invalid\":[1],\"label\":1}\n",
            "{\"t_us\":20,\"points\":[],\"tracked\":false}\n",
            "{\"t_us\":30,\"points\":[[0,0,0]]}\n",
            "{\"t_us\":40,\"points\":[[0,0,0],[1,1]]}\n",
            "{\"t_us\":50,\"points\":[[0,0,0],null]}\n",
            "{\"t_us\":60,\"points\":[[0,0,0],[1,1,1]],\"invalid\":[2]}\n",
            "not json\n",
            "{\"t_us\":70,\"points\":[[0,0,0],[1,",
        ];
        let header = "{\"format\":\"mimic-recording\",\"version\":1,\"layout\":\"x\",\"units\":\"m\",\"source\":\"t\",\"rate_hz\":30,\"point_count\":2}\n";
        let text = format!("{header}{}", frames.concat());
        let reader = RecordingReader::new(text.as_bytes(), "t.jsonl", None).unwrap();
        let from_reader: Vec<_> = reader.map(|r| r.map_err(|e| e.problem)).collect();
        let from_lines: Vec<_> = frames
            .iter()
            .map(|l| parse_frame_line(l.as_bytes(), l.ends_with('\n'), Some(2), "x"))
            .collect();
        // Timestamps increase here, so the reader's only extra check never fires. (Compared as
        // text: invalid points are NaN, which is not equal to itself.)
        assert_eq!(format!("{from_reader:?}"), format!("{from_lines:?}"));
        assert_eq!(from_lines.iter().filter(|r| r.is_ok()).count(), 2);
        assert!(matches!(from_lines[7], Err(FrameProblem::Truncated { .. })));
    }
}
