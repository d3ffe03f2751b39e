//! The weights CSV a weights or Live Link session is recorded as (`docs/recording-format.md`,
//! "Weights recordings"): a header `t_us,<name>,...` with the session rig's morph-target names in
//! the rig's order, then one row per accepted frame: its time (µs, the session's clock) and its
//! weights, each the shortest decimal that reads back as the same f32. `mimic send --weights`
//! and `mimic morph apply` read it back (named columns, a `t_us` column for the times).

use std::fs::File;
use std::io::{BufWriter, Write};

/// The time column of a weights recording.
pub const WEIGHTS_TIME_COLUMN: &str = "t_us";

/// A weight as the recording writes it: the shortest decimal that parses back to the same f32
/// (Rust's `Display`, never an exponent); a non-finite weight (never produced: name maps clamp)
/// is written as 0.
pub fn format_weight(out: &mut String, w: f32) {
    use std::fmt::Write as _;
    let w = if w.is_finite() { w } else { 0.0 };
    let _ = write!(out, "{w}");
}

/// A weights recording being written, flushed row by row.
#[derive(Debug)]
pub struct WeightsCsv {
    out: BufWriter<File>,
    columns: usize,
    line: String,
}

impl WeightsCsv {
    /// Writes the header (`t_us` and `names`) to `file`; a name that is empty, holds a comma,
    /// quote or line break, or is `t_us` itself is refused.
    pub fn new(file: File, names: &[String]) -> Result<Self, mimic_capture::WriteError> {
        for n in names {
            if n.is_empty()
                || n.contains([',', '"', '\n', '\r'])
                || n.trim() != n
                || n.eq_ignore_ascii_case(WEIGHTS_TIME_COLUMN)
            {
                return Err(mimic_capture::WriteError::Header(format!(
                    "morph-target name `{n}` cannot be a column of a weights CSV"
                )));
            }
        }
        let mut out = BufWriter::new(file);
        let mut header = String::from(WEIGHTS_TIME_COLUMN);
        for n in names {
            header.push(',');
            header.push_str(n);
        }
        header.push('\n');
        out.write_all(header.as_bytes())?;
        out.flush()?;
        Ok(Self {
            out,
            columns: names.len(),
            line: String::new(),
        })
    }

    /// Writes and flushes one row; `weights` must have one value per column.
    pub fn write(&mut self, t_us: i64, weights: &[f32]) -> std::io::Result<()> {
        if weights.len() != self.columns {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!(
                    "{} weights for a recording of {} columns",
                    weights.len(),
                    self.columns
                ),
            ));
        }
        use std::fmt::Write as _;
        self.line.clear();
        let _ = write!(self.line, "{t_us}");
        for &w in weights {
            self.line.push(',');
            format_weight(&mut self.line, w);
        }
        self.line.push('\n');
        self.out.write_all(self.line.as_bytes())?;
        self.out.flush()
    }

    /// The file under the buffer.
    pub fn file(&self) -> &File {
        self.out.get_ref()
    }

    /// Flushes and hands back the file.
    pub fn finish(self) -> std::io::Result<File> {
        self.out.into_inner().map_err(|e| e.into_error())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_read_back_as_the_same_f32() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("w.weights.csv");
        let names = vec!["jawOpen".to_string(), "eyeBlink_L".to_string()];
        let mut w = WeightsCsv::new(File::create(&path).unwrap(), &names).unwrap();
        let rows = [
            (0i64, [0.1f32, 1.0]),
            (16_667, [1.0 / 3.0, 0.0]),
            (33_333, [f32::MIN_POSITIVE, 0.999_999_9]),
        ];
        for (t, v) in &rows {
            w.write(*t, v).unwrap();
        }
        assert!(w.write(1, &[0.5]).is_err(), "a row of the wrong width");
        w.finish().unwrap();
        let table = mimic_capture::named_csv::read_named_csv(&path).unwrap();
        assert_eq!(table.header, ["t_us", "jawOpen", "eyeBlink_L"]);
        assert_eq!(table.rows.len(), rows.len());
        for (row, (t, v)) in table.rows.iter().zip(&rows) {
            assert_eq!(row.field(0).parse::<i64>().unwrap(), *t);
            for (k, x) in v.iter().enumerate() {
                assert_eq!(row.field(k + 1).parse::<f32>().unwrap(), *x);
            }
        }
        for bad in ["a,b", "t_us", "", " x"] {
            let f = File::create(tmp.path().join("bad.csv")).unwrap();
            assert!(WeightsCsv::new(f, &[bad.to_string()]).is_err(), "{bad:?}");
        }
    }
}
