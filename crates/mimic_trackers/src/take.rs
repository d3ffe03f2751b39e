//! Live Link Face CSV takes: a header of names (`Timecode`, `BlendShapeCount`, then the curves),
//! one row per sample. Columns are read by name, never by position (the CSV orders `JawRight`
//! before `JawLeft` and `MouthRight` before `MouthLeft`, unlike the UDP stream); rows whose
//! `BlendShapeCount` is 0 (no face) are untracked and may be as short as two fields.
//!
//! `Timecode` is `HH:MM:SS:FF.fff`: `FF.fff` is a frame (and its fraction) of the timecode's
//! rate, so the time is `H*3600 + M*60 + S + FF.fff / rate`. The rate is not written in the
//! file: it is the smallest standard rate (24, 25, 30, 48, 50, 60, 120) above every `FF` of the
//! take (Live Link Face writes 60 fps timecode, `FF` 00-59). A time before the previous row's by
//! more than 12 hours is taken as a pass through midnight; any other step back is an error.

use crate::error::TrackerError;
use crate::livelink::{CURVE_NAMES, CURVES, curve_index};
use mimic_types::limits::{FileKind, read_capped};
use std::io::Write;
use std::path::Path;

/// The timecode rate [`TakeWriter`] writes (Live Link Face's own: `FF` 00-59).
pub const WRITTEN_TIMECODE_RATE: u32 = 60;

/// The curve columns of a Live Link Face CSV take in the app's header order (stream indices
/// into [`CURVE_NAMES`]): the stream order, but `JawRight` before `JawLeft` and `MouthRight`
/// before `MouthLeft`.
pub const TAKE_COLUMN_ORDER: [usize; CURVES] = {
    let mut order = [0usize; CURVES];
    let mut i = 0;
    while i < CURVES {
        order[i] = i;
        i += 1;
    }
    // JawLeft 15, JawRight 16; MouthLeft 21, MouthRight 22 in the stream.
    order[15] = 16;
    order[16] = 15;
    order[21] = 22;
    order[22] = 21;
    order
};

/// Live Link CSV takes (about 800 bytes a row: 256 MiB is some 3 hours at 30 rows a second).
pub const TAKE_FILE: FileKind = FileKind {
    what: "Live Link Face takes",
    max_bytes: 256 << 20,
};
/// Timecode rates a take may use, in the order they are tried.
pub const TIMECODE_RATES: [u32; 7] = [24, 25, 30, 48, 50, 60, 120];

/// One row of a take.
#[derive(Clone, Debug, PartialEq)]
pub struct TakeRow {
    /// 1-based line in the file.
    pub line: usize,
    /// Microseconds since the take's first row, from its `Timecode`.
    pub t_us: i64,
    /// False on a `BlendShapeCount` 0 row (no face): its curves are all 0.
    pub tracked: bool,
    /// The 61 curves in stream order ([`CURVE_NAMES`]); 0 for a column the take lacks.
    pub curves: [f32; CURVES],
}

/// A parsed take.
#[derive(Clone, Debug, PartialEq)]
pub struct Take {
    /// Rows in file order.
    pub rows: Vec<TakeRow>,
    /// The timecode rate (frames per second of `FF`).
    pub timecode_rate: u32,
    /// Which of the 61 curves have a column.
    pub present: [bool; CURVES],
}

impl Take {
    /// Seconds from the first row to the last.
    pub fn duration_s(&self) -> f64 {
        self.rows.last().map_or(0.0, |r| r.t_us as f64 * 1e-6)
    }

    /// Rows per second over the take (0 for fewer than two rows).
    pub fn sample_rate_hz(&self) -> f64 {
        let d = self.duration_s();
        if self.rows.len() < 2 || d <= 0.0 {
            return 0.0;
        }
        (self.rows.len() - 1) as f64 / d
    }

    /// Names of the curves the take has, in stream order.
    pub fn curve_names(&self) -> impl Iterator<Item = &'static str> + '_ {
        CURVE_NAMES
            .iter()
            .zip(self.present)
            .filter(|(_, p)| *p)
            .map(|(n, _)| *n)
    }
}

/// True when `header` (a CSV's first line) is a Live Link Face take's: `Timecode` and
/// `BlendShapeCount` columns.
pub fn is_take_header(header: &str) -> bool {
    let has = |n: &str| header.split(',').any(|c| c.trim().eq_ignore_ascii_case(n));
    has("Timecode") && has("BlendShapeCount")
}

/// A timecode `HH:MM:SS:FF.fff` split into seconds of the day (without the frames) and the
/// frame count `FF.fff`.
pub fn split_timecode(text: &str) -> Result<(u32, f64), String> {
    let bad = || format!("Timecode `{text}` is not HH:MM:SS:FF.fff");
    let mut parts = text.trim().split(':');
    let mut field = |max: u32| -> Result<u32, String> {
        let p = parts.next().ok_or_else(bad)?;
        if p.is_empty() || p.len() > 2 || !p.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad());
        }
        let v: u32 = p.parse().map_err(|_| bad())?;
        if v > max {
            return Err(bad());
        }
        Ok(v)
    };
    let (h, m, s) = (field(23)?, field(59)?, field(59)?);
    let ff = parts.next().ok_or_else(bad)?;
    if parts.next().is_some()
        || ff.is_empty()
        || !ff.bytes().all(|b| b.is_ascii_digit() || b == b'.')
    {
        return Err(bad());
    }
    let frames: f64 = ff.parse().map_err(|_| bad())?;
    if !(0.0..1000.0).contains(&frames) {
        return Err(bad());
    }
    Ok((h * 3600 + m * 60 + s, frames))
}

/// The smallest rate of [`TIMECODE_RATES`] above frame number `max_frame`.
pub fn timecode_rate(max_frame: f64) -> Option<u32> {
    TIMECODE_RATES
        .iter()
        .copied()
        .find(|r| max_frame.floor() < f64::from(*r))
}

/// Where each Live Link curve is among a header's `names` (any case), or why not: a curve
/// named twice.
pub(crate) fn curve_columns(names: &[&str]) -> Result<[Option<usize>; CURVES], String> {
    let mut columns = [None; CURVES];
    for (c, name) in names.iter().enumerate() {
        if let Some(i) = curve_index(name) {
            if columns[i].is_some() {
                return Err(format!("column `{name}` appears twice"));
            }
            columns[i] = Some(c);
        }
    }
    Ok(columns)
}

/// A curve's value `v` in column `column`: a finite number, or why not.
pub(crate) fn curve_value(v: &str, column: &str) -> Result<f32, String> {
    v.parse::<f32>()
        .ok()
        .filter(|x| x.is_finite())
        .ok_or_else(|| format!("column `{column}`: `{v}` is not a number"))
}

/// Parses a take's text; errors name `path` and the line.
pub fn parse_take(text: &str, path: &Path) -> Result<Take, TrackerError> {
    let err = |line: usize, reason: String| TrackerError::Line {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut lines = text.lines().enumerate();
    let header = lines
        .next()
        .map(|(_, l)| l)
        .ok_or_else(|| err(1, "empty file".into()))?;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let find = |n: &str| names.iter().position(|c| c.eq_ignore_ascii_case(n));
    let timecode = find("Timecode").ok_or_else(|| err(1, "no `Timecode` column".into()))?;
    let count =
        find("BlendShapeCount").ok_or_else(|| err(1, "no `BlendShapeCount` column".into()))?;
    let columns = curve_columns(&names).map_err(|r| err(1, r))?;
    if columns.iter().all(Option::is_none) {
        return Err(err(1, "no Live Link curve column (e.g. `JawOpen`)".into()));
    }
    // First pass: times as (seconds of the day, frames), to find the timecode rate.
    let mut raw = Vec::new();
    for (i, l) in lines {
        if l.trim().is_empty() {
            continue;
        }
        let line = i + 1;
        let fields: Vec<&str> = l.split(',').map(str::trim).collect();
        let tc = fields.get(timecode).copied().unwrap_or("");
        let (secs, frames) = split_timecode(tc).map_err(|r| err(line, r))?;
        let n = fields.get(count).copied().unwrap_or("");
        let n: usize = n
            .parse()
            .map_err(|_| err(line, format!("BlendShapeCount `{n}` is not a count")))?;
        let mut curves = [0.0f32; CURVES];
        if n > 0 {
            for (k, col) in columns.iter().enumerate() {
                let Some(c) = *col else { continue };
                let v = fields.get(c).copied().ok_or_else(|| {
                    err(
                        line,
                        format!(
                            "{} fields; column `{}` (field {}) is missing",
                            fields.len(),
                            CURVE_NAMES[k],
                            c + 1
                        ),
                    )
                })?;
                curves[k] = curve_value(v, CURVE_NAMES[k]).map_err(|r| err(line, r))?;
            }
        }
        raw.push((line, secs, frames, n > 0, curves));
    }
    let max_frame = raw.iter().map(|r| r.2).fold(0.0f64, f64::max);
    let rate = timecode_rate(max_frame).ok_or_else(|| {
        err(
            1,
            format!("timecode frame {max_frame} is over every standard rate (at most 119)"),
        )
    })?;
    let mut rows = Vec::with_capacity(raw.len());
    let mut day_offset = 0.0f64;
    let mut first = None;
    let mut prev = f64::NEG_INFINITY;
    for (line, secs, frames, tracked, curves) in raw {
        let mut t = f64::from(secs) + frames / f64::from(rate) + day_offset;
        if t < prev - 12.0 * 3600.0 {
            day_offset += 86_400.0;
            t += 86_400.0;
        }
        if t < prev {
            return Err(err(
                line,
                format!("Timecode goes back {:.3} s from the previous row", prev - t),
            ));
        }
        prev = t;
        let t0 = *first.get_or_insert(t);
        rows.push(TakeRow {
            line,
            t_us: ((t - t0) * 1e6).round() as i64,
            tracked,
            curves,
        });
    }
    Ok(Take {
        rows,
        timecode_rate: rate,
        present: columns.map(|c| c.is_some()),
    })
}

/// Whether the file at `path` starts with a Live Link Face take's header (its first line, up
/// to 64 KiB, has `Timecode` and `BlendShapeCount` columns).
pub fn is_take_file(path: &Path) -> Result<bool, TrackerError> {
    Ok(first_line(path)?.is_some_and(|l| is_take_header(&l)))
}

/// The first line of the file at `path` (up to 64 KiB); `None` when it is not text.
pub(crate) fn first_line(path: &Path) -> Result<Option<String>, TrackerError> {
    use std::io::{BufRead, Read};
    let io = |e: std::io::Error| TrackerError::Io {
        path: path.to_path_buf(),
        source: e.into(),
    };
    let f = std::fs::File::open(path).map_err(io)?;
    let mut first = String::new();
    match std::io::BufReader::new(f)
        .take(64 * 1024)
        .read_line(&mut first)
    {
        Ok(_) => Ok(Some(first)),
        // Not text: not a take.
        Err(e) if e.kind() == std::io::ErrorKind::InvalidData => Ok(None),
        Err(e) => Err(io(e)),
    }
}

/// `HH:MM:SS:FF.fff` at [`WRITTEN_TIMECODE_RATE`] of `t_us` (µs; its time of day: a day is
/// taken off as often as it fits), the frame rounded to a thousandth: within 1/120000 s of
/// `t_us`.
pub fn format_timecode(t_us: i64) -> String {
    let day_us = 86_400_000_000i64;
    let t = t_us.rem_euclid(day_us);
    let rate = i64::from(WRITTEN_TIMECODE_RATE);
    // Thousandths of a frame since midnight: t_us * rate * 1000 / 1e6, rounded.
    let milli = (i128::from(t) * i128::from(rate) + 500) / 1000;
    let milli = i64::try_from(milli).unwrap_or(0) % (86_400 * rate * 1000);
    let frames = milli / 1000;
    let secs = frames / rate;
    format!(
        "{:02}:{:02}:{:02}:{:02}.{:03}",
        secs / 3600,
        secs / 60 % 60,
        secs % 60,
        frames % rate,
        milli % 1000
    )
}

/// Writes a Live Link Face CSV take: the app's header (`Timecode`, `BlendShapeCount`, the 61
/// curves in [`TAKE_COLUMN_ORDER`]), then one row per frame (all 61 curves, `BlendShapeCount`
/// 61; a frame with no face as `Timecode,0`). Curves are written as the shortest decimal that
/// reads back as the same f32. [`parse_take`] reads it back.
#[derive(Debug)]
pub struct TakeWriter<W: Write> {
    out: W,
    line: String,
    rows: usize,
}

impl<W: Write> TakeWriter<W> {
    /// Writes the header to `out`.
    pub fn new(mut out: W) -> std::io::Result<Self> {
        let mut header = String::from("Timecode,BlendShapeCount");
        for &k in &TAKE_COLUMN_ORDER {
            header.push(',');
            header.push_str(CURVE_NAMES[k]);
        }
        header.push('\n');
        out.write_all(header.as_bytes())?;
        Ok(Self {
            out,
            line: String::new(),
            rows: 0,
        })
    }

    /// Writes one row at `t_us` (its timecode, [`format_timecode`]): the curves in stream order
    /// ([`CURVE_NAMES`]; a non-finite one as 0), or `None` for a frame with no face.
    pub fn write_row(&mut self, t_us: i64, curves: Option<&[f32; CURVES]>) -> std::io::Result<()> {
        use std::fmt::Write as _;
        self.line.clear();
        self.line.push_str(&format_timecode(t_us));
        match curves {
            None => self.line.push_str(",0"),
            Some(c) => {
                let _ = write!(self.line, ",{CURVES}");
                for &k in &TAKE_COLUMN_ORDER {
                    let v = if c[k].is_finite() { c[k] } else { 0.0 };
                    let _ = write!(self.line, ",{v}");
                }
            }
        }
        self.line.push('\n');
        self.rows += 1;
        self.out.write_all(self.line.as_bytes())
    }

    /// Rows written.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Flushes and hands back the writer.
    pub fn finish(mut self) -> std::io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

/// Reads a take file (capped at [`TAKE_FILE`]); a weights CSV of ARKit curves too
/// ([`crate::weights_take`]).
pub fn read_take(path: &Path) -> Result<Take, TrackerError> {
    let text = read_capped(path, &TAKE_FILE).map_err(|source| TrackerError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    match text.lines().next() {
        Some(h) if !is_take_header(h) && crate::weights_take::is_weights_take_header(h) => {
            crate::weights_take::parse_weights_take(&text, path)
        }
        _ => parse_take(&text, path),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_by_name_and_timecode() {
        let text = "Timecode,BlendShapeCount,JawRight,JawLeft,MouthRight,MouthLeft\n\
                    23:59:59:58.000,4,0.1,0.2,0.3,0.4\n\
                    23:59:59:59.500,0\n\
                    00:00:00:01.000,4,0.5,0.6,0.7,0.8\n";
        let t = parse_take(text, Path::new("t.csv")).unwrap();
        assert_eq!(t.timecode_rate, 60);
        assert_eq!(t.rows.len(), 3);
        let jl = curve_index("JawLeft").unwrap();
        let jr = curve_index("JawRight").unwrap();
        assert!(jl < jr, "the stream puts Left first");
        assert_eq!(t.rows[0].curves[jr], 0.1);
        assert_eq!(t.rows[0].curves[jl], 0.2);
        assert_eq!(t.rows[0].curves[curve_index("MouthLeft").unwrap()], 0.4);
        assert!(!t.rows[1].tracked);
        assert_eq!(t.rows[1].t_us, 25_000);
        // Through midnight: 23:59:59 + 58/60 -> 00:00:00 + 1/60 is 3/60 s.
        assert_eq!(t.rows[2].t_us, 50_000);
        assert_eq!(t.curve_names().count(), 4);
    }

    #[test]
    fn a_written_take_parses_back_with_its_names_values_and_times() {
        let mut w = TakeWriter::new(Vec::new()).unwrap();
        let mut rng = mimic_testkit::Lcg::new(19);
        // 90 frames at 60 Hz from 23:59:59.5 (through midnight), the 40th without a face.
        let start = 86_400_000_000i64 - 500_000;
        let mut rows = Vec::new();
        for i in 0..90i64 {
            let t = start + i * 16_667;
            let mut c = [0.0f32; CURVES];
            c.iter_mut().for_each(|x| *x = rng.next_f32());
            let tracked = i != 40;
            w.write_row(t, tracked.then_some(&c)).unwrap();
            rows.push((t, tracked, c));
        }
        assert_eq!(w.rows(), 90);
        let bytes = w.finish().unwrap();
        let text = String::from_utf8(bytes).unwrap();
        let header = text.lines().next().unwrap();
        assert!(
            header.contains("JawForward,JawRight,JawLeft,JawOpen"),
            "{header}"
        );
        assert!(header.contains("MouthPucker,MouthRight,MouthLeft,MouthSmileLeft"));
        assert!(text.starts_with("Timecode,BlendShapeCount,EyeBlinkLeft,"));
        assert!(
            text.lines()
                .nth(1)
                .unwrap()
                .starts_with("23:59:59:30.000,61,")
        );
        let t = parse_take(&text, Path::new("w.csv")).unwrap();
        assert_eq!(t.timecode_rate, WRITTEN_TIMECODE_RATE);
        assert!(t.present.iter().all(|p| *p));
        assert_eq!(t.rows.len(), rows.len());
        // A timecode is within half a thousandth of a 60 fps frame of its time.
        let tol_us = 1e6 / (60.0 * 1000.0) / 2.0 + 1.0;
        for (r, (t_us, tracked, c)) in t.rows.iter().zip(&rows) {
            let want = (t_us - start) as f64;
            assert!(
                (r.t_us as f64 - want).abs() <= 2.0 * tol_us,
                "{} vs {want}",
                r.t_us
            );
            assert_eq!(r.tracked, *tracked);
            if *tracked {
                assert_eq!(&r.curves, c);
            }
        }
        assert_eq!(format_timecode(0), "00:00:00:00.000");
        assert_eq!(format_timecode(3_723_500_000), "01:02:03:30.000");
        assert_eq!(format_timecode(-1_000_000), "23:59:59:00.000");
    }

    #[test]
    fn bad_rows_name_the_line() {
        let e = parse_take(
            "Timecode,BlendShapeCount,JawOpen\n00:00:00:00.0,1,0.5\n00:00:00:01.0,1,x\n",
            Path::new("t.csv"),
        )
        .unwrap_err();
        assert!(
            e.to_string().starts_with("t.csv:3: column `JawOpen`"),
            "{e}"
        );
        let e = parse_take(
            "Timecode,BlendShapeCount,JawOpen\n00:00:01:00.0,1,0.5\n00:00:00:01.0,1,0.1\n",
            Path::new("t.csv"),
        )
        .unwrap_err();
        assert!(e.to_string().contains("t.csv:3: Timecode goes back"), "{e}");
        assert!(split_timecode("12:27:47").is_err());
        assert!(split_timecode("12:61:47:00.0").is_err());
        assert_eq!(split_timecode("12:27:47:47.169").unwrap(), (44867, 47.169));
        assert!(is_take_header("Timecode,BlendShapeCount,EyeBlinkLeft"));
        assert!(!is_take_header("t_us,jawOpen"));
    }
}

/// A take's tracked rows as morph-target weights through a name map.
#[derive(Clone, Debug, PartialEq)]
pub struct TakeWeights {
    /// Target names, one per weight of each frame.
    pub targets: Vec<String>,
    /// `(line, t_us, weights)` of each tracked row.
    pub frames: Vec<(usize, i64, Vec<f32>)>,
    /// Rows with no face (`BlendShapeCount` 0), not in `frames`.
    pub untracked: usize,
    /// Blendshape columns the map does not list (sent under their own names).
    pub unmapped: Vec<String>,
}

/// The take's blendshape curves (the first 52; head and eye angles are not weights) through
/// `map`, for its tracked rows.
pub fn take_weights(take: &Take, map: &crate::namemap::NameMap) -> TakeWeights {
    let columns: Vec<usize> = (0..crate::livelink::BLENDSHAPES)
        .filter(|&k| take.present[k])
        .collect();
    let names: Vec<&str> = columns.iter().map(|&k| CURVE_NAMES[k]).collect();
    let mapping = map.resolve(&names);
    let mut values = vec![0.0f32; columns.len()];
    let mut frames = Vec::with_capacity(take.rows.len());
    for r in take.rows.iter().filter(|r| r.tracked) {
        for (v, &k) in values.iter_mut().zip(&columns) {
            *v = r.curves[k];
        }
        let mut w = vec![0.0f32; mapping.targets.len()];
        mapping.apply(map, &values, &mut w);
        frames.push((r.line, r.t_us, w));
    }
    TakeWeights {
        untracked: take.rows.len() - frames.len(),
        targets: mapping.targets,
        frames,
        unmapped: mapping.unmapped,
    }
}
