//! Writer of v1 recordings to any `Write`.

use super::RecordedFrame;
use super::error::WriteError;
use super::header::RecordingHeader;
use mimic_types::LandmarkFrame;
use std::fmt::Write as _;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Significant digits written per coordinate (1e-5 relative; 10 µm at 1 m).
const SIGNIFICANT_DIGITS: i32 = 6;

/// Writes a header and then frames, one JSON object per line.
///
/// Points that are invalid or non-finite are written as `null` and listed in `invalid`.
/// Tracked frames must all have the same point count and timestamps must increase.
pub struct RecordingWriter<W: Write> {
    out: W,
    flush_each_frame: bool,
    point_count: Option<usize>,
    last_t_us: Option<i64>,
    frames: usize,
    line: String,
}

impl RecordingWriter<BufWriter<File>> {
    /// Creates (truncates) `path` and writes the header.
    pub fn create(path: &Path, header: &RecordingHeader) -> Result<Self, WriteError> {
        Self::new(BufWriter::new(File::create(path)?), header)
    }
}

impl<W: Write> RecordingWriter<W> {
    /// Writes the header line to `out`.
    pub fn new(mut out: W, header: &RecordingHeader) -> Result<Self, WriteError> {
        header.check().map_err(WriteError::Header)?;
        let json = serde_json::to_string(header).map_err(|e| WriteError::Header(e.to_string()))?;
        out.write_all(json.as_bytes())?;
        out.write_all(b"\n")?;
        Ok(Self {
            out,
            flush_each_frame: false,
            point_count: header.point_count,
            last_t_us: None,
            frames: 0,
            line: String::new(),
        })
    }

    /// Flush after every frame, so a crash loses at most the frame being written.
    pub fn flush_each_frame(mut self, on: bool) -> Self {
        self.flush_each_frame = on;
        self
    }

    /// Frames written so far.
    pub fn frames_written(&self) -> usize {
        self.frames
    }

    /// Writes a frame with its label.
    pub fn write(&mut self, f: &RecordedFrame) -> Result<(), WriteError> {
        self.write_frame(&f.frame, f.label)
    }

    /// Writes one frame, with an optional integer label.
    pub fn write_frame(
        &mut self,
        frame: &LandmarkFrame,
        label: Option<i64>,
    ) -> Result<(), WriteError> {
        let t_us = frame.timestamp_us;
        if frame.valid.len() != frame.points.len() {
            return Err(WriteError::ValidityLength {
                t_us,
                points: frame.points.len(),
                valid: frame.valid.len(),
            });
        }
        if let Some(previous_us) = self.last_t_us
            && t_us <= previous_us
        {
            return Err(WriteError::TimeNotIncreasing { t_us, previous_us });
        }
        let count = frame.points.len();
        if frame.tracked || count > 0 {
            match self.point_count {
                Some(expected) if expected != count => {
                    return Err(WriteError::PointCount {
                        t_us,
                        found: count,
                        expected,
                    });
                }
                None if frame.tracked => self.point_count = Some(count),
                _ => {}
            }
        }
        let line = &mut self.line;
        line.clear();
        let _ = write!(line, "{{\"t_us\":{t_us},\"points\":[");
        let mut invalid = Vec::new();
        for i in 0..count {
            if i > 0 {
                line.push(',');
            }
            if frame.is_valid(i) {
                let p = frame.points[i];
                let _ = write!(
                    line,
                    "[{},{},{}]",
                    format_coordinate(p.x),
                    format_coordinate(p.y),
                    format_coordinate(p.z)
                );
            } else {
                line.push_str("null");
                invalid.push(i);
            }
        }
        line.push(']');
        if !invalid.is_empty() {
            line.push_str(",\"invalid\":[");
            for (k, i) in invalid.iter().enumerate() {
                if k > 0 {
                    line.push(',');
                }
                let _ = write!(line, "{i}");
            }
            line.push(']');
        }
        let _ = write!(line, ",\"tracked\":{}", frame.tracked);
        if let Some(l) = label {
            let _ = write!(line, ",\"label\":{l}");
        }
        line.push_str("}\n");
        self.out.write_all(line.as_bytes())?;
        if self.flush_each_frame {
            self.out.flush()?;
        }
        self.last_t_us = Some(t_us);
        self.frames += 1;
        Ok(())
    }

    /// Flushes and returns the underlying writer.
    pub fn finish(mut self) -> Result<W, WriteError> {
        self.out.flush()?;
        Ok(self.out)
    }
}

/// A finite coordinate as compact JSON with six significant digits (`0.0123457`, `-0.836`, `0`).
pub fn format_coordinate(v: f32) -> String {
    if !v.is_finite() {
        return "null".to_string();
    }
    if v == 0.0 {
        return "0".to_string();
    }
    let v = f64::from(v);
    let magnitude = v.abs().log10().floor() as i32;
    let decimals = (SIGNIFICANT_DIGITS - 1 - magnitude).clamp(0, 45) as usize;
    let mut s = format!("{v:.decimals$}");
    if s.contains('.') {
        let trimmed = s.trim_end_matches('0').trim_end_matches('.').len();
        s.truncate(trimmed);
    }
    if s == "-0" { "0".to_string() } else { s }
}
