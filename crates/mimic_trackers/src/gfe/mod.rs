//! Importer of the UCI "Grammatical Facial Expressions" Kinect v1 files (`*_datapoints.txt`).
//!
//! Each data row is a timestamp and 100 × (x px, y px, z mm) from the Kinect v1 face tracker's
//! 2D tracked points on the 640×480 colour image. Points are back-projected with the nominal
//! colour intrinsics (f = 531.15 px, centre 320, 240) into the recording convention
//! (x right, y up, z toward the camera, metres). Depth 0 means "no depth": the point is invalid.
//! Timestamps are Unix seconds and a fraction whose digits are a whole number of milliseconds
//! (`1390385015.38` is 15 s + 38 ms).

use glam::{DVec2, Vec3};
use mimic_capture::Imported;
use mimic_capture::{RecordedFrame, RecordingHeader};
use mimic_types::LandmarkFrame;
use std::path::{Path, PathBuf};

mod depth;
pub use depth::{DepthRepair, repair_depth};

/// Layout name of the GFE 100-point files.
pub const LAYOUT: &str = "kinect-gfe100";
/// Points per frame.
pub const POINT_COUNT: usize = 100;
/// Kinect v1 nominal colour focal length (NUI_CAMERA_COLOR_NOMINAL_FOCAL_LENGTH_IN_PIXELS).
pub const FOCAL_PX: f64 = 531.15;
/// Assumed principal point x (image centre of 640×480).
pub const CENTRE_X_PX: f64 = 320.0;
/// Assumed principal point y (image centre of 640×480).
pub const CENTRE_Y_PX: f64 = 240.0;

/// A GFE file that cannot be imported; every variant names the file and 1-based line.
#[derive(Debug, thiserror::Error)]
pub enum GfeError {
    /// The file cannot be read.
    #[error("{}: cannot read: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The header line is not the 300 (or 301) point labels.
    #[error("{}:1: {reason}", path.display())]
    Header {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
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
    /// The targets file does not match the data rows.
    #[error("{}: {reason}", path.display())]
    Targets {
        /// The targets file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

/// The tracker's 2D pixel (x, y) of each point of one frame; `None` where the file has (0, 0).
pub type FramePixels = Vec<Option<DVec2>>;

/// Imports a GFE `*_datapoints.txt`, optionally labelling frames from its `*_targets.txt`.
pub fn import_gfe(
    datapoints: &Path,
    targets: Option<&Path>,
    source: Option<&str>,
) -> Result<Imported, GfeError> {
    import_gfe_with_pixels(datapoints, targets, source).map(|(imported, _)| imported)
}

/// [`import_gfe`], also returning each frame's raw pixels (for a model fit, `docs/fitter.md`).
pub fn import_gfe_with_pixels(
    datapoints: &Path,
    targets: Option<&Path>,
    source: Option<&str>,
) -> Result<(Imported, Vec<FramePixels>), GfeError> {
    let text = mimic_types::limits::read_capped(datapoints, &mimic_types::limits::GFE_FILE)
        .map_err(|e| GfeError::Io {
            path: datapoints.to_path_buf(),
            source: e.into(),
        })?;
    let (mut frames, pixels) = parse_rows(&text, datapoints)?;
    if let Some(tp) = targets {
        let t =
            mimic_types::limits::read_capped(tp, &mimic_types::limits::GFE_FILE).map_err(|e| {
                GfeError::Io {
                    path: tp.to_path_buf(),
                    source: e.into(),
                }
            })?;
        let labels = parse_targets(&t, tp)?;
        if labels.len() != frames.len() {
            return Err(GfeError::Targets {
                path: tp.to_path_buf(),
                reason: format!("{} labels for {} data rows", labels.len(), frames.len()),
            });
        }
        for (f, l) in frames.iter_mut().zip(labels) {
            f.label = Some(l);
        }
    }
    let name = datapoints
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let default_source =
        format!("kinect-v1 face tracking (UCI Grammatical Facial Expressions, {name})");
    // Rounded to 0.1 Hz.
    let rate = mimic_capture::mean_rate_hz(&frames).map_or(16.0, |r| (r * 10.0).round() / 10.0);
    let mut header = RecordingHeader::new(
        LAYOUT,
        source.unwrap_or(&default_source),
        rate,
        Some(POINT_COUNT),
    );
    header.description = Some(format!(
        "Kinect v1 Face Tracking SDK 2D tracked points (100), back-projected with f = {FOCAL_PX} px, \
         centre ({CENTRE_X_PX}, {CENTRE_Y_PX}) px; depth 0 -> invalid point{}",
        if targets.is_some() {
            "; label = GFE target (1: grammatical expression happening)"
        } else {
            ""
        }
    ));
    Ok((Imported { header, frames }, pixels))
}

/// Checks the header: 300 labels `0x 0y 0z … 99x 99y 99z`, optionally after one extra token.
pub fn check_header(line: &str, path: &Path) -> Result<(), GfeError> {
    let tokens: Vec<&str> = line.split_whitespace().collect();
    let labels = match tokens.len() {
        300 => &tokens[..],
        301 => &tokens[1..],
        n => {
            return Err(GfeError::Header {
                path: path.to_path_buf(),
                reason: format!(
                    "header has {n} tokens; expected 300 point labels (0x … 99z), optionally after one extra token"
                ),
            });
        }
    };
    for (k, label) in labels.iter().enumerate() {
        let want = format!("{}{}", k / 3, ["x", "y", "z"][k % 3]);
        if *label != want {
            return Err(GfeError::Header {
                path: path.to_path_buf(),
                reason: format!("header label {} is `{label}`, expected `{want}`", k + 1),
            });
        }
    }
    Ok(())
}

/// Parses a GFE timestamp: seconds, then the fraction digits as whole milliseconds, in µs.
pub fn parse_timestamp_us(token: &str) -> Option<i64> {
    let (secs, ms) = token.split_once('.').unwrap_or((token, "0"));
    if secs.is_empty() || !secs.bytes().all(|b| b.is_ascii_digit()) || ms.is_empty() || ms.len() > 3
    {
        return None;
    }
    if !ms.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let secs: i64 = secs.parse().ok()?;
    let ms: i64 = ms.parse().ok()?;
    secs.checked_mul(1_000_000)?.checked_add(ms * 1000)
}

/// Back-projects a pixel and depth (mm) to camera space in metres; `None` when depth is 0.
pub fn back_project(x_px: f64, y_px: f64, depth_mm: f64) -> Option<Vec3> {
    if depth_mm == 0.0 {
        return None;
    }
    let x = (x_px - CENTRE_X_PX) * depth_mm / FOCAL_PX;
    let y = -(y_px - CENTRE_Y_PX) * depth_mm / FOCAL_PX;
    let z = -depth_mm;
    Some(Vec3::new(
        (x * 1e-3) as f32,
        (y * 1e-3) as f32,
        (z * 1e-3) as f32,
    ))
}

/// Parses the text of a datapoints file (header line, then data rows).
pub fn parse_datapoints(text: &str, path: &Path) -> Result<Vec<RecordedFrame>, GfeError> {
    parse_rows(text, path).map(|(frames, _)| frames)
}

/// [`parse_datapoints`], with each row's pixels.
fn parse_rows(text: &str, path: &Path) -> Result<(Vec<RecordedFrame>, Vec<FramePixels>), GfeError> {
    let mut lines = text.lines().enumerate();
    let header = lines
        .next()
        .map(|(_, l)| l)
        .ok_or_else(|| GfeError::Header {
            path: path.to_path_buf(),
            reason: "empty file".to_string(),
        })?;
    check_header(header, path)?;
    let mut frames: Vec<RecordedFrame> = Vec::new();
    let mut pixels: Vec<FramePixels> = Vec::new();
    for (i, line) in lines {
        let line_no = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let row_error = |reason: String| GfeError::Row {
            path: path.to_path_buf(),
            line: line_no,
            reason,
        };
        let tokens: Vec<&str> = line.split_whitespace().collect();
        if tokens.len() != 1 + 3 * POINT_COUNT {
            return Err(row_error(format!(
                "row has {} values; expected 301 (timestamp + 100 × x y z)",
                tokens.len()
            )));
        }
        let t_us = parse_timestamp_us(tokens[0]).ok_or_else(|| {
            row_error(format!(
                "timestamp `{}` is not seconds.milliseconds",
                tokens[0]
            ))
        })?;
        if let Some(prev) = frames.last()
            && t_us <= prev.frame.timestamp_us
        {
            return Err(row_error(format!(
                "timestamp `{}` ({t_us} us) is not after the previous row's ({} us)",
                tokens[0], prev.frame.timestamp_us
            )));
        }
        let mut points = Vec::with_capacity(POINT_COUNT);
        let mut valid = Vec::with_capacity(POINT_COUNT);
        let mut row_pixels = Vec::with_capacity(POINT_COUNT);
        for (p, xyz) in tokens[1..].chunks_exact(3).enumerate() {
            let mut v = [0.0f64; 3];
            for (slot, tok) in v.iter_mut().zip(xyz) {
                *slot = tok
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| {
                        row_error(format!("point {p}: `{tok}` is not a finite number"))
                    })?;
            }
            if v[2] < 0.0 {
                return Err(row_error(format!("point {p}: negative depth {} mm", v[2])));
            }
            let px = DVec2::new(v[0], v[1]);
            row_pixels.push((px != DVec2::ZERO).then_some(px));
            match back_project(v[0], v[1], v[2]) {
                Some(q) => {
                    points.push(q);
                    valid.push(true);
                }
                None => {
                    points.push(Vec3::NAN);
                    valid.push(false);
                }
            }
        }
        let frame = LandmarkFrame {
            timestamp_us: t_us,
            points,
            valid,
            tracked: true,
        };
        frames.push(RecordedFrame::unlabelled(frame));
        pixels.push(row_pixels);
    }
    Ok((frames, pixels))
}

/// Parses a targets file: one 0 or 1 per line.
pub fn parse_targets(text: &str, path: &Path) -> Result<Vec<i64>, GfeError> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| match l.trim() {
            "0" => Ok(0),
            "1" => Ok(1),
            other => Err(GfeError::Targets {
                path: path.to_path_buf(),
                reason: format!("line {}: `{other}` is not 0 or 1", i + 1),
            }),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels() -> Vec<String> {
        (0..300)
            .map(|k| format!("{}{}", k / 3, ["x", "y", "z"][k % 3]))
            .collect()
    }

    fn row(t: &str, z0: &str) -> String {
        let mut r = vec![t.to_string()];
        for p in 0..100 {
            r.push(format!("{}", 320 + p));
            r.push("240".to_string());
            r.push(if p == 0 {
                z0.to_string()
            } else {
                "1000".to_string()
            });
        }
        r.join(" ")
    }

    #[test]
    fn header_with_300_or_301_tokens_both_parse() {
        let p = Path::new("h.txt");
        let h300 = labels().join(" ");
        let h301 = format!("0.0 {h300}");
        for h in [&h300, &h301] {
            let text = format!("{h}\r\n{}\r\n{}", row("10.5", "0"), row("10.38", "800"));
            let frames = parse_datapoints(&text, p).unwrap();
            assert_eq!(frames.len(), 2);
        }
        let h299 = labels()[1..].join(" ");
        let e = parse_datapoints(&format!("{h299}\r\n"), p).unwrap_err();
        assert!(
            e.to_string().starts_with("h.txt:1: header has 299 tokens"),
            "{e}"
        );
        let mut wrong = labels();
        wrong[4] = "1q".into();
        let e = check_header(&wrong.join(" "), p).unwrap_err();
        assert!(
            e.to_string().contains("label 5 is `1q`, expected `1y`"),
            "{e}"
        );
    }

    #[test]
    fn fraction_digits_are_whole_milliseconds() {
        assert_eq!(
            parse_timestamp_us("1390385015.38"),
            Some(1_390_385_015_038_000)
        );
        assert_eq!(
            parse_timestamp_us("1390385015.5"),
            Some(1_390_385_015_005_000)
        );
        assert_eq!(
            parse_timestamp_us("1390385015.756"),
            Some(1_390_385_015_756_000)
        );
        assert_eq!(
            parse_timestamp_us("1390385015"),
            Some(1_390_385_015_000_000)
        );
        assert_eq!(parse_timestamp_us("15.1234"), None);
        assert_eq!(parse_timestamp_us("-1.5"), None);
        assert_eq!(parse_timestamp_us("1e9.5"), None);
    }

    #[test]
    fn depth_zero_is_invalid_and_back_projection_is_pinhole() {
        let text = format!(
            "{}\n{}\n{}\n",
            labels().join(" "),
            row("10.5", "0"),
            row("10.38", "800")
        );
        let frames = parse_datapoints(&text, Path::new("t")).unwrap();
        // "10.5" is 10 s + 5 ms, "10.38" is 10 s + 38 ms: increasing.
        assert_eq!(frames[0].frame.timestamp_us, 10_005_000);
        assert_eq!(frames[1].frame.timestamp_us, 10_038_000);
        let f0 = &frames[0].frame;
        assert!(!f0.valid[0] && !f0.is_valid(0));
        assert_eq!(f0.valid_count(), 99);
        // Point 1 at (321, 240) px, 1000 mm: X = 1 * 1000 / 531.15 mm, Y = 0, Z = -1 m.
        let p = f0.points[1];
        assert!((p.x - (1.0 / 531.15) as f32).abs() < 1e-7, "{p}");
        assert_eq!(p.y, 0.0);
        assert_eq!(p.z, -1.0);
        let q = frames[1].frame.points[0];
        assert_eq!(q, Vec3::new(0.0, 0.0, -0.8));
    }

    #[test]
    fn pixels_are_the_rows_x_y_and_zero_zero_is_missing() {
        // Frame 0's point 0 at (0, 0) px: no pixel; frame 1's point 0 keeps (320, 240) without depth.
        let zero = row("10.5", "0").replacen(" 320 240 ", " 0 0 ", 1);
        let text = format!("{}\n{zero}\n{}\n", labels().join(" "), row("10.6", "0"));
        let (frames, pixels) = parse_rows(&text, Path::new("t")).unwrap();
        assert_eq!((frames.len(), pixels.len()), (2, 2));
        assert_eq!(pixels[0].len(), POINT_COUNT);
        assert_eq!(pixels[0][0], None);
        assert_eq!(pixels[1][0], Some(DVec2::new(320.0, 240.0)));
        assert_eq!(pixels[0][1], Some(DVec2::new(321.0, 240.0)));
        // Depth 0 leaves the point invalid but keeps its pixel.
        assert!(!frames[1].frame.is_valid(0));
    }

    #[test]
    fn malformed_rows_name_file_and_line() {
        let bad = row("10.5", "0").replace(" 240 ", " abc ");
        let text = format!("{}\n{}\n{}\n", labels().join(" "), row("10.1", "0"), bad);
        let e = parse_datapoints(&text, Path::new("d.txt")).unwrap_err();
        assert!(e.to_string().starts_with("d.txt:3: point 0: `abc`"), "{e}");
        let text = format!(
            "{}\n{}\n{}\n",
            labels().join(" "),
            row("10.50", "0"),
            row("10.49", "0")
        );
        let e = parse_datapoints(&text, Path::new("d.txt")).unwrap_err();
        assert!(
            e.to_string().starts_with("d.txt:3: timestamp `10.49`"),
            "{e}"
        );
        let text = format!("{}\n1.5 2 3\n", labels().join(" "));
        let e = parse_datapoints(&text, Path::new("d.txt")).unwrap_err();
        assert!(
            e.to_string().starts_with("d.txt:2: row has 3 values"),
            "{e}"
        );
    }
}
