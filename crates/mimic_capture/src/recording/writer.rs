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
    exact: bool,
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
            exact: false,
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

    /// Write each coordinate as the shortest decimal that reads back as the same `f32`
    /// (up to 9 significant digits) instead of 6 digits: the file then holds exactly the frames
    /// given, e.g. what a live server accepted.
    pub fn exact_coordinates(mut self, on: bool) -> Self {
        self.exact = on;
        self
    }

    /// The underlying writer (e.g. to sync a file to disk).
    pub fn get_ref(&self) -> &W {
        &self.out
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
        self.write_frame_with_fields(frame, label, &serde_json::Map::new())
    }

    /// Writes one frame with further top-level fields (e.g. a fitter's `"fit"`), which readers ignore.
    /// Fields named like the format's own (`t_us`, `points`, `invalid`, `tracked`, `label`) are skipped.
    pub fn write_frame_with_fields(
        &mut self,
        frame: &LandmarkFrame,
        label: Option<i64>,
        fields: &serde_json::Map<String, serde_json::Value>,
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
                line.push('[');
                for (k, v) in [p.x, p.y, p.z].into_iter().enumerate() {
                    if k > 0 {
                        line.push(',');
                    }
                    if self.exact {
                        // Rust prints an f32 as the shortest decimal that parses back to it.
                        let _ = write!(line, "{v}");
                    } else {
                        write_coordinate(line, v);
                    }
                }
                line.push(']');
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
        for (key, value) in fields {
            if matches!(
                key.as_str(),
                "t_us" | "points" | "invalid" | "tracked" | "label"
            ) {
                continue;
            }
            let _ = write!(
                line,
                ",{}:{}",
                serde_json::Value::String(key.clone()),
                value
            );
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
    let mut s = String::new();
    write_coordinate(&mut s, v);
    s
}

/// Appends [`format_coordinate`]'s text to `out` (`null` for a non-finite value).
pub fn write_coordinate(out: &mut String, v: f32) {
    if !v.is_finite() {
        out.push_str("null");
        return;
    }
    let v = f64::from(v);
    if v == 0.0 {
        out.push('0');
        return;
    }
    let magnitude = v.abs().log10().floor() as i32;
    let decimals = (SIGNIFICANT_DIGITS - 1 - magnitude).max(0);
    if decimals > 15 || magnitude > 15 {
        // Outside metres' usual range: let the formatter round exactly.
        let mut s = format!("{v:.prec$}", prec = decimals.min(45) as usize);
        if s.contains('.') {
            let kept = s.trim_end_matches('0').trim_end_matches('.').len();
            s.truncate(kept);
        }
        out.push_str(if s == "-0" { "0" } else { &s });
        return;
    }
    // |scaled| < 10^7 and decimals <= 15: an exact integer, printed with the point put in by hand.
    let scaled = (v * 10f64.powi(decimals)).round_ties_even() as i64;
    if scaled == 0 {
        out.push('0');
        return;
    }
    if scaled < 0 {
        out.push('-');
    }
    let digits = scaled.unsigned_abs().to_string();
    let decimals = decimals as usize;
    let (int_part, frac_part) = if digits.len() > decimals {
        digits.split_at(digits.len() - decimals)
    } else {
        ("", digits.as_str())
    };
    if int_part.is_empty() {
        out.push('0');
    } else {
        out.push_str(int_part);
    }
    let frac = frac_part.trim_end_matches('0');
    if !frac.is_empty() {
        out.push('.');
        for _ in frac_part.len()..decimals {
            out.push('0');
        }
        out.push_str(frac);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extra_fields_are_written_and_readers_skip_them() {
        let header = RecordingHeader::new("t", "test", 30.0, Some(1));
        let mut w = RecordingWriter::new(Vec::new(), &header).unwrap();
        let mut fields = serde_json::Map::new();
        fields.insert(
            "fit".into(),
            serde_json::json!({"au": [0.5, -1], "residual_px": 1.25}),
        );
        // A field named like the format's own is not written a second time.
        fields.insert("label".into(), serde_json::json!(9));
        let frame = LandmarkFrame::new(5, vec![glam::Vec3::new(0.1, 0.2, -1.0)]);
        w.write_frame_with_fields(&frame, Some(1), &fields).unwrap();
        let text = String::from_utf8(w.finish().unwrap()).unwrap();
        let line = text.lines().nth(1).unwrap();
        assert_eq!(
            line,
            r#"{"t_us":5,"points":[[0.1,0.2,-1]],"tracked":true,"label":1,"fit":{"au":[0.5,-1],"residual_px":1.25}}"#
        );
        let mut r = super::super::RecordingReader::new(text.as_bytes(), "mem", None).unwrap();
        let f = r.next_frame().unwrap().unwrap();
        assert_eq!(f.frame, frame);
        assert_eq!(f.label, Some(1));
    }

    /// Random f32 bit patterns (finite ones), as the exact writer prints them and the reader
    /// parses them (JSON number -> f64 -> f32), come back bit for bit.
    #[test]
    fn exact_coordinates_read_back_bit_for_bit() {
        let header = RecordingHeader::new("t", "test", 30.0, Some(2));
        let mut w = RecordingWriter::new(Vec::new(), &header)
            .unwrap()
            .exact_coordinates(true);
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut frames = Vec::new();
        let mut t_us = 0;
        while frames.len() < 20_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let v: Vec<f32> = [state as u32, (state >> 32) as u32]
                .iter()
                .map(|b| f32::from_bits(*b))
                .collect();
            if !v.iter().all(|x| x.is_finite()) {
                continue;
            }
            t_us += 1;
            let p = vec![glam::Vec3::new(v[0], v[1], -v[0]), glam::Vec3::splat(v[1])];
            let f = LandmarkFrame::new(t_us, p);
            w.write_frame(&f, None).unwrap();
            frames.push(f);
        }
        let text = w.finish().unwrap();
        let r = super::super::RecordingReader::new(text.as_slice(), "mem", None).unwrap();
        let mut n = 0;
        for (got, want) in r.zip(&frames) {
            let got = got.unwrap().frame;
            let bits = |f: &LandmarkFrame| {
                f.points
                    .iter()
                    .flat_map(|p| p.to_array().map(f32::to_bits))
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&got), bits(want), "t_us {}", want.timestamp_us);
            n += 1;
        }
        assert_eq!(n, frames.len());
    }

    /// A writer flushing per frame, cut off in the middle of its last line (a crash), reads
    /// back as every frame before the cut plus one `truncated` rejection.
    #[test]
    fn a_torn_last_line_loses_only_that_frame() {
        let header = RecordingHeader::new("t", "test", 30.0, Some(1));
        let mut w = RecordingWriter::new(Vec::new(), &header)
            .unwrap()
            .flush_each_frame(true)
            .exact_coordinates(true);
        let frames: Vec<_> = (1..=5)
            .map(|k| LandmarkFrame::new(k * 10, vec![glam::Vec3::new(0.1 * k as f32, 0.2, -1.0)]))
            .collect();
        for f in &frames {
            w.write_frame(f, None).unwrap();
        }
        let text = w.finish().unwrap();
        let last_line_start = text[..text.len() - 1]
            .iter()
            .rposition(|b| *b == b'\n')
            .unwrap()
            + 1;
        for cut in last_line_start + 1..text.len() - 1 {
            let mut r =
                super::super::RecordingReader::new(&text[..cut], "torn.jsonl", None).unwrap();
            let got: Vec<_> = r.by_ref().filter_map(Result::ok).map(|f| f.frame).collect();
            assert_eq!(got, frames[..4], "cut at byte {cut}");
            assert_eq!(r.stats().accepted, 4);
            assert_eq!(r.stats().rejected.truncated, 1, "cut at byte {cut}");
            assert_eq!(r.stats().rejected.total(), 1);
        }
    }

    #[test]
    fn fast_coordinate_text_equals_exact_six_digit_rounding() {
        // Reference: Rust's exact decimal rounding to 6 significant digits ({:.5e}). The two may
        // differ only when v·10^d lies within f64 rounding (1e-9 relative) of a .5 tie.
        let mut rng = mimic_testkit::Lcg::new(0x9E37_79B9_7F4A_7C15);
        let mut ties = 0;
        for _ in 0..20_000 {
            let state = rng.next_u64();
            let mantissa = (state >> 40) as f64 / (1u64 << 24) as f64; // [0, 1)
            let exponent = ((state >> 8) % 24) as i32 - 12; // 1e-12 .. 1e11
            let sign = if state & 1 == 0 { 1.0 } else { -1.0 };
            let v = (sign * (1.0 + 9.0 * mantissa) * 10f64.powi(exponent)) as f32;
            let ours = format_coordinate(v);
            let got: f64 = serde_json::from_str(&ours).unwrap();
            let d = SIGNIFICANT_DIGITS - 1 - f64::from(v).abs().log10().floor() as i32;
            // From 1e6 up, whole numbers are written in full (more digits, never fewer), ties to even.
            let exact: f64 = if d < 0 {
                f64::from(v).round_ties_even()
            } else {
                format!("{:.5e}", f64::from(v)).parse().unwrap()
            };
            let scaled = f64::from(v).abs() * 10f64.powi(d);
            let near_tie = (scaled.fract() - 0.5).abs() < 1e-9 * scaled;
            if near_tie {
                // Either neighbour is a correct rounding: within half a unit of the last digit.
                let unit = 10f64.powi(-d);
                assert!(
                    (got - f64::from(v)).abs() <= 0.5 * unit * (1.0 + 1e-9),
                    "{v}: {ours}"
                );
                ties += 1;
            } else {
                assert_eq!(got, exact, "{v}: {ours}");
            }
        }
        // f32 has about 7.2 decimal digits, so exact .5 ties at the 7th digit are not rare.
        assert!(ties < 1_000, "{ties}");
    }
}
