//! Importer of OpenFace 2.x `FeatureExtraction` CSV files (68 iBUG landmarks in 3D).
//!
//! Columns are found by header name (`timestamp`, `success`, `X_0..X_67`, `Y_0..`, `Z_0..`),
//! never by position. OpenFace's 3D landmarks are camera space in millimetres with y down and
//! z forward; the recording convention is y up, z toward the camera, metres: `(X, −Y, −Z) / 1000`.
//! `success == 0` gives a lost-tracking frame with no points.

use glam::Vec3;
use mimic_capture::Imported;
use mimic_capture::{RecordedFrame, RecordingHeader};
use mimic_types::LandmarkFrame;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Layout name of OpenFace's 68 landmarks.
pub const LAYOUT: &str = "ibug68";
/// Points per frame.
pub const POINT_COUNT: usize = 68;

/// How frame times are chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OpenFaceTiming {
    /// Frame `i` (0-based row) at `i / rate_hz` seconds: for files whose clock is not real.
    Rate(f64),
    /// The file's `timestamp` column (seconds), which must increase.
    FileTimestamps,
}

/// An OpenFace CSV that cannot be imported; every variant names the file (and line).
#[derive(Debug, thiserror::Error)]
pub enum OpenFaceError {
    /// The file cannot be read.
    #[error("{}: cannot read: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A needed column is missing from the header.
    #[error("{}:1: no column `{column}` in the header", path.display())]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The missing column name.
        column: String,
    },
    /// A data row is malformed.
    #[error("{}:{line}: {reason}", path.display())]
    Row {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// The rate is not a positive number.
    #[error("rate {0} Hz is not a positive number")]
    Rate(f64),
}

/// Column positions of the fields the importer reads.
struct Columns {
    timestamp: usize,
    success: usize,
    xyz: Vec<[usize; 3]>,
}

impl Columns {
    fn find(header: &str, path: &Path) -> Result<Self, OpenFaceError> {
        let names: HashMap<&str, usize> = header
            .split(',')
            .map(str::trim)
            .enumerate()
            .map(|(i, n)| (n, i))
            .collect();
        let col = |name: String| {
            names
                .get(name.as_str())
                .copied()
                .ok_or(OpenFaceError::MissingColumn {
                    path: path.to_path_buf(),
                    column: name,
                })
        };
        let mut xyz = Vec::with_capacity(POINT_COUNT);
        for i in 0..POINT_COUNT {
            xyz.push([
                col(format!("X_{i}"))?,
                col(format!("Y_{i}"))?,
                col(format!("Z_{i}"))?,
            ]);
        }
        Ok(Self {
            timestamp: col("timestamp".into())?,
            success: col("success".into())?,
            xyz,
        })
    }
}

/// Imports an OpenFace CSV as an `ibug68` recording.
pub fn import_openface(
    path: &Path,
    timing: OpenFaceTiming,
    source: Option<&str>,
) -> Result<Imported, OpenFaceError> {
    if let OpenFaceTiming::Rate(r) = timing
        && !(r.is_finite() && r > 0.0)
    {
        return Err(OpenFaceError::Rate(r));
    }
    let text = mimic_types::limits::read_capped(path, &mimic_types::limits::OPENFACE_FILE)
        .map_err(|e| OpenFaceError::Io {
            path: path.to_path_buf(),
            source: e.into(),
        })?;
    let frames = parse_csv(&text, path, timing)?;
    let rate_hz = match timing {
        OpenFaceTiming::Rate(r) => r,
        OpenFaceTiming::FileTimestamps => mimic_capture::mean_rate_hz(&frames).unwrap_or(30.0),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let default_source = format!("OpenFace 2.x FeatureExtraction 3D landmarks ({name})");
    let mut header = RecordingHeader::new(
        LAYOUT,
        source.unwrap_or(&default_source),
        rate_hz,
        Some(POINT_COUNT),
    );
    header.description = Some(match timing {
        OpenFaceTiming::Rate(r) => format!(
            "iBUG 68 landmarks from OpenFace (X, -Y, -Z) mm -> m; re-timed by frame index at {r} Hz \
             (the file's own timestamps were not used)"
        ),
        OpenFaceTiming::FileTimestamps => {
            "iBUG 68 landmarks from OpenFace (X, -Y, -Z) mm -> m; timestamps from the file"
                .to_string()
        }
    });
    Ok(Imported { header, frames })
}

/// Parses the CSV text into frames.
pub fn parse_csv(
    text: &str,
    path: &Path,
    timing: OpenFaceTiming,
) -> Result<Vec<RecordedFrame>, OpenFaceError> {
    let mut lines = text.lines().enumerate();
    let header = lines.next().map(|(_, l)| l).unwrap_or("");
    let cols = Columns::find(header, path)?;
    let mut frames: Vec<RecordedFrame> = Vec::new();
    for (i, line) in lines {
        let line_no = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let row_error = |reason: String| OpenFaceError::Row {
            path: path.to_path_buf(),
            line: line_no,
            reason,
        };
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let number = |c: usize| -> Result<f64, OpenFaceError> {
            let tok = fields.get(c).ok_or_else(|| {
                row_error(format!(
                    "row has {} fields; column {} is missing",
                    fields.len(),
                    c + 1
                ))
            })?;
            tok.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    row_error(format!("column {}: `{tok}` is not a finite number", c + 1))
                })
        };
        let t_us = match timing {
            OpenFaceTiming::Rate(r) => (frames.len() as f64 * 1e6 / r).round() as i64,
            OpenFaceTiming::FileTimestamps => (number(cols.timestamp)? * 1e6).round() as i64,
        };
        if let Some(prev) = frames.last()
            && t_us <= prev.frame.timestamp_us
        {
            return Err(row_error(format!(
                "timestamp {t_us} us is not after the previous row's {} us",
                prev.frame.timestamp_us
            )));
        }
        let tracked = number(cols.success)? != 0.0;
        let frame = if tracked {
            let mut points = Vec::with_capacity(POINT_COUNT);
            for [cx, cy, cz] in &cols.xyz {
                let (x, y, z) = (number(*cx)?, number(*cy)?, number(*cz)?);
                points.push(Vec3::new(
                    (x * 1e-3) as f32,
                    (-y * 1e-3) as f32,
                    (-z * 1e-3) as f32,
                ));
            }
            LandmarkFrame::new(t_us, points)
        } else {
            LandmarkFrame {
                timestamp_us: t_us,
                points: Vec::new(),
                valid: Vec::new(),
                tracked: false,
            }
        };
        frames.push(RecordedFrame::unlabelled(frame));
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A CSV with columns in a shuffled order, to show lookup is by name.
    fn csv(rows: &[(f64, u8, f64)]) -> String {
        let mut names = vec!["Z_0".to_string(), "success".into(), "frame".into()];
        let mut per_point = Vec::new();
        for i in 0..POINT_COUNT {
            if i > 0 {
                per_point.push(format!("Z_{i}"));
            }
            per_point.push(format!("Y_{i}"));
            per_point.push(format!("X_{i}"));
        }
        names.extend(per_point);
        names.push("timestamp".into());
        let mut out = names.join(", ");
        for (k, &(t, success, base)) in rows.iter().enumerate() {
            let mut vals = vec![
                format!("{}", 600.0 + base),
                format!("{success}"),
                format!("{}", k + 1),
            ];
            for i in 0..POINT_COUNT {
                if i > 0 {
                    vals.push(format!("{}", 600.0 + base + i as f64));
                }
                vals.push(format!("{}", 10.0 * i as f64));
                vals.push(format!("{}", base + i as f64));
            }
            vals.push(format!("{t}"));
            out.push('\n');
            out.push_str(&vals.join(", "));
        }
        out
    }

    #[test]
    fn columns_by_name_and_axes_flipped() {
        let text = csv(&[(0.0, 1, 1.0), (0.001, 0, 2.0), (0.002, 1, 3.0)]);
        let f = parse_csv(&text, Path::new("o.csv"), OpenFaceTiming::Rate(30.0)).unwrap();
        assert_eq!(f.len(), 3);
        // Re-timed: row i at round(i * 1e6 / 30) us.
        assert_eq!(
            f.iter().map(|r| r.frame.timestamp_us).collect::<Vec<_>>(),
            vec![0, 33_333, 66_667]
        );
        assert!(!f[1].frame.tracked && f[1].frame.points.is_empty());
        // Point 5 of row 0: X = 1 + 5 mm, Y = 50 mm, Z = 600 + 1 + 5 mm -> (0.006, -0.05, -0.606) m.
        let p = f[0].frame.points[5];
        assert!(
            (p - Vec3::new(0.006, -0.05, -0.606)).abs().max_element() < 1e-7,
            "{p}"
        );
        let g = parse_csv(&text, Path::new("o.csv"), OpenFaceTiming::FileTimestamps).unwrap();
        assert_eq!(
            g.iter().map(|r| r.frame.timestamp_us).collect::<Vec<_>>(),
            vec![0, 1000, 2000]
        );
    }

    #[test]
    fn missing_column_and_bad_value_are_named() {
        let text = csv(&[(0.0, 1, 1.0)]).replacen("X_17", "Q_17", 1);
        let e = parse_csv(&text, Path::new("o.csv"), OpenFaceTiming::Rate(30.0)).unwrap_err();
        assert_eq!(e.to_string(), "o.csv:1: no column `X_17` in the header");
        let text = format!(
            "{}\n{}",
            csv(&[(0.0, 1, 1.0)]),
            csv(&[(0.5, 1, 1.0)])
                .lines()
                .nth(1)
                .unwrap()
                .replacen("601", "x", 1)
        );
        let e = parse_csv(&text, Path::new("o.csv"), OpenFaceTiming::Rate(30.0)).unwrap_err();
        assert!(e.to_string().starts_with("o.csv:3: column 1: `x`"), "{e}");
    }
}
