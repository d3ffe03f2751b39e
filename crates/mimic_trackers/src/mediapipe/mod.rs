//! Importer of MediaPipe Face Mesh dumps (478 landmarks in normalised image coordinates) and
//! their conversion to metres in camera space.
//!
//! The dump is JSON lines, one object per video frame (`tools/mediapipe_track.py` writes it;
//! `docs/recording-format.md`, "Importers", gives the format):
//! `{"frame": i, "t_us": t, "image_size": [w, h], "landmarks": [[x, y, z], ...]}`, with no
//! landmarks (`[]`) where no face was found. x and y are MediaPipe's `NormalizedLandmark` values
//! (divided by the image width and height, origin top-left, y down), z is its relative depth
//! (smaller is nearer, on about the scale of x).
//!
//! **Conversion to metres** ([`to_camera_space`]), per frame, with a pinhole camera of vertical
//! field of view `fov` centred on the image (MediaPipe's own face-geometry pipeline assumes
//! 63 degrees, [`DEFAULT_FOV_DEG`]):
//! 1. Pixel coordinates with y up and z toward the camera: `S = (x w − w/2, −(y h − h/2), −z w)`.
//!    `f = (h/2) / tan(fov/2)` is the focal length in pixels. MediaPipe documents z only as "on
//!    roughly the same scale as x"; it is taken here as exactly that, at the face's centre.
//! 2. Unprojection with the face's centre at depth `f`: point i's depth is `d_i = f − (S_i.z −
//!    S̄.z)` (S̄.z: the weighted mean over the 33 Procrustes landmarks of MediaPipe's
//!    `geometry_pipeline_metadata_landmarks.pbtxt`, [`PROCRUSTES`]), and `M_i = (S_i.x d_i / f,
//!    S_i.y d_i / f, −d_i)`. This is the face in camera space at `1/s` of its real size, for
//!    whatever `s` (a pinhole cannot tell a small near face from a large far one).
//! 3. The face is taken to be the canonical model's size, as MediaPipe's geometry pipeline
//!    assumes: `s` (pixels per cm) is the scale of a weighted similarity (Procrustes) fit of the
//!    canonical model (cm) to `M` over those 33 landmarks, the ratio of the weighted RMS spreads
//!    about the weighted centroids (the least-squares scale of a symmetric Procrustes fit, which
//!    needs no rotation and is exact for a rigid face). Points are `M_i / s` cm, → m; the
//!    face's centre is at `f / s` cm.
//!
//! A wrong `fov` moves the face nearer or farther (its distance is proportional to `f`), keeps its
//! size, and changes its shape only through the perspective term `(S_i.z − S̄.z) / f` (a few per
//! cent of the face's depth relief); mimic removes head motion and fits source to target scale
//! anyway, so the default serves when the camera is unknown.

use glam::{DVec3, Vec3};
use mimic_capture::Imported;
use mimic_capture::{RecordedFrame, RecordingHeader};
use mimic_types::LandmarkFrame;
use mimic_types::limits::FileKind;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Layout name of MediaPipe Face Mesh with iris refinement.
pub const LAYOUT: &str = "mediapipe478";
/// Points per frame of the layout: 468 mesh points and 10 iris points.
pub const POINT_COUNT: usize = 478;
/// Points of a dump made without iris refinement (`refine_landmarks=False`): the mesh only.
pub const MESH_POINTS: usize = 468;
/// MediaPipe's face-geometry default vertical field of view (degrees), used when none is given.
pub const DEFAULT_FOV_DEG: f64 = 63.0;
/// Size cap of a dump (about 12.6 KB a frame: 256 MiB is some 15 minutes at 24 fps).
pub const MEDIAPIPE_FILE: FileKind = FileKind {
    what: "MediaPipe dumps",
    max_bytes: 256 << 20,
};
/// Most pixels a side of `image_size` may have.
pub const MAX_IMAGE_SIDE: u32 = 1 << 16;

/// MediaPipe's 33 Procrustes landmarks: (landmark, weight, canonical position in cm), from
/// `geometry_pipeline_metadata_landmarks.pbtxt` and `canonical_face_model.obj` of MediaPipe
/// v0.10.21 (Apache-2.0, `configs/models/mediapipe/`). A unit test checks the positions against
/// the shipped OBJ.
pub const PROCRUSTES: [(usize, f64, [f64; 3]); 33] = [
    (4, 0.070909939706326, [0.0, -0.46317, 7.58658]),
    (6, 0.032100144773722, [0.0, 2.473255, 5.788627]),
    (10, 0.008446550928056, [0.0, 8.261778, 4.481535]),
    (33, 0.058724168688059, [-4.445859, 2.663991, 3.173422]),
    (54, 0.007667080033571, [-6.279331, 6.615427, 1.42585]),
    (67, 0.009078059345484, [-3.523964, 8.005976, 3.729163]),
    (117, 0.009791937656701, [-5.258659, 0.945811, 2.974312]),
    (119, 0.014565368182957, [-3.300681, 0.861641, 3.872784]),
    (121, 0.018591361120343, [-1.820731, 1.467954, 4.224124]),
    (127, 0.005197994410992, [-7.743095, 2.364999, -2.005167]),
    (129, 0.120625205338001, [-1.785794, -0.978284, 4.85047]),
    (132, 0.005560018587857, [-7.270895, -2.890917, -2.252455]),
    (133, 0.05328618362546, [-1.856432, 2.585245, 3.757904]),
    (136, 0.066890455782413, [-5.085276, -7.17859, 0.714711]),
    (143, 0.014816547743976, [-6.407571, 2.236021, 1.560843]),
    (147, 0.014262833632529, [-6.234883, -1.94443, 1.663542]),
    (198, 0.025462191551924, [-1.246815, 0.230297, 5.681036]),
    (205, 0.047252278774977, [-3.832928, -1.537326, 4.137731]),
    (263, 0.058724168688059, [4.445859, 2.663991, 3.173422]),
    (284, 0.007667080033571, [6.279331, 6.615427, 1.42585]),
    (297, 0.009078059345484, [3.523964, 8.005976, 3.729163]),
    (346, 0.009791937656701, [5.258659, 0.945811, 2.974312]),
    (348, 0.014565368182957, [3.300681, 0.861641, 3.872784]),
    (350, 0.018591361120343, [1.820731, 1.467954, 4.224124]),
    (356, 0.005197994410992, [7.743095, 2.364999, -2.005167]),
    (358, 0.120625205338001, [1.785794, -0.978284, 4.85047]),
    (361, 0.005560018587857, [7.270895, -2.890917, -2.252455]),
    (362, 0.05328618362546, [1.856432, 2.585245, 3.757904]),
    (365, 0.066890455782413, [5.085276, -7.17859, 0.714711]),
    (372, 0.014816547743976, [6.407571, 2.236021, 1.560843]),
    (376, 0.014262833632529, [6.234883, -1.94443, 1.663542]),
    (420, 0.025462191551924, [1.246815, 0.230297, 5.681036]),
    (425, 0.047252278774977, [3.832928, -1.537326, 4.137731]),
];

/// A dump that cannot be imported; every variant names the file (and line).
#[derive(Debug, thiserror::Error)]
pub enum MediaPipeError {
    /// The file cannot be read.
    #[error("{}: cannot read: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A line is malformed.
    #[error("{}:{line}: {reason}", path.display())]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// The dump has no frame at all.
    #[error("{}: no frames (an empty MediaPipe dump)", path.display())]
    Empty {
        /// The file.
        path: PathBuf,
    },
    /// The field of view is not in (0, 180) degrees.
    #[error("field of view {0} degrees is not in (0, 180)")]
    Fov(f64),
}

/// One line of a dump, as written.
#[derive(Debug, Deserialize)]
struct RawLine {
    /// Video frame index (informative; order is by line).
    #[serde(default)]
    #[allow(dead_code, reason = "read to reject a malformed field, not used")]
    frame: Option<u64>,
    t_us: i64,
    #[serde(default)]
    image_size: Option<[u32; 2]>,
    landmarks: Vec<[f64; 3]>,
}

/// One frame of a dump: time, image size and MediaPipe's normalised landmarks (none: no face).
#[derive(Clone, Debug, PartialEq)]
pub struct DumpFrame {
    /// Frame time in µs.
    pub t_us: i64,
    /// Image width and height in pixels (present whenever there are landmarks).
    pub image_size: Option<[u32; 2]>,
    /// `[x, y, z]` per landmark: 0, 468 or 478 of them.
    pub landmarks: Vec<[f64; 3]>,
}

/// Parses one dump line: `Ok(None)` for a blank line, else the frame or why it is malformed.
pub fn parse_dump_line(line: &str) -> Result<Option<DumpFrame>, String> {
    let line = line.trim();
    if line.is_empty() {
        return Ok(None);
    }
    let raw: RawLine = serde_json::from_str(line).map_err(|e| format!("invalid JSON: {e}"))?;
    let n = raw.landmarks.len();
    if n != 0 && n != MESH_POINTS && n != POINT_COUNT {
        return Err(format!(
            "{n} landmarks; MediaPipe Face Mesh gives {POINT_COUNT} (or {MESH_POINTS} without iris refinement, or none)"
        ));
    }
    if n > 0 {
        let Some([w, h]) = raw.image_size else {
            return Err("landmarks without `image_size` (needed to convert them to pixels)".into());
        };
        if w == 0 || h == 0 || w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
            return Err(format!(
                "image_size [{w}, {h}] is not a size from 1 to {MAX_IMAGE_SIDE} pixels a side"
            ));
        }
        if let Some(i) = raw
            .landmarks
            .iter()
            .position(|p| p.iter().any(|v| !v.is_finite() || v.abs() > 1e3))
        {
            return Err(format!(
                "landmark {i} is {:?}: not a normalised coordinate (finite, |v| <= 1000)",
                raw.landmarks[i]
            ));
        }
    }
    Ok(Some(DumpFrame {
        t_us: raw.t_us,
        image_size: raw.image_size,
        landmarks: raw.landmarks,
    }))
}

/// Parses a whole dump: every non-blank line a frame, times strictly increasing.
pub fn parse_dump(text: &str, path: &Path) -> Result<Vec<DumpFrame>, MediaPipeError> {
    let mut frames: Vec<DumpFrame> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let bad = |reason: String| MediaPipeError::Line {
            path: path.to_path_buf(),
            line: i + 1,
            reason,
        };
        let Some(frame) = parse_dump_line(line).map_err(bad)? else {
            continue;
        };
        if let Some(prev) = frames.last()
            && frame.t_us <= prev.t_us
        {
            return Err(bad(format!(
                "t_us {} is not after the previous frame's {}",
                frame.t_us, prev.t_us
            )));
        }
        frames.push(frame);
    }
    Ok(frames)
}

/// The pinhole focal length in pixels for an image `height` pixels high seen with a vertical
/// field of view of `fov_deg` degrees.
pub fn focal_px(height: f64, fov_deg: f64) -> f64 {
    height * 0.5 / (fov_deg.to_radians() * 0.5).tan()
}

/// Converts one frame's normalised landmarks to camera-space metres (the method of the module
/// docs), writing `out` (cleared first; one point per landmark). Returns the fitted distance of
/// the face (its Procrustes points' weighted centroid) in metres, or `None` (and `out` empty)
/// for a frame without landmarks or whose Procrustes points are all in one spot.
pub fn to_camera_space(frame: &DumpFrame, fov_deg: f64, out: &mut Vec<Vec3>) -> Option<f64> {
    out.clear();
    let [w, h] = frame.image_size?;
    if frame.landmarks.len() < MESH_POINTS {
        return None;
    }
    let (w, h) = (f64::from(w), f64::from(h));
    let f = focal_px(h, fov_deg);
    let pixels = |p: &[f64; 3]| DVec3::new(p[0] * w - 0.5 * w, -(p[1] * h - 0.5 * h), -p[2] * w);
    // Mean depth offset of the Procrustes points, in pixels (MediaPipe's z has its own origin).
    let mut sw = 0.0;
    let mut z0 = 0.0;
    for &(i, wt, _) in &PROCRUSTES {
        sw += wt;
        z0 += wt * pixels(&frame.landmarks[i]).z;
    }
    let z0 = z0 / sw;
    // Unprojected with the centroid at depth f: the face in camera space at 1/s of its size.
    let unproject = |p: &[f64; 3]| {
        let q = pixels(p);
        let depth = f - (q.z - z0);
        DVec3::new(q.x * depth / f, q.y * depth / f, -depth)
    };
    let (mut mc, mut cc) = (DVec3::ZERO, DVec3::ZERO);
    for &(i, wt, c) in &PROCRUSTES {
        mc += wt * unproject(&frame.landmarks[i]);
        cc += wt * DVec3::from_array(c);
    }
    let (mc, cc) = (mc / sw, cc / sw);
    let (mut ms, mut cs) = (0.0, 0.0);
    for &(i, wt, c) in &PROCRUSTES {
        ms += wt * (unproject(&frame.landmarks[i]) - mc).length_squared();
        cs += wt * (DVec3::from_array(c) - cc).length_squared();
    }
    // Pixels per cm: the similarity scale that gives the face the canonical model's size.
    let s = (ms / cs).sqrt();
    if !(s.is_finite() && s > 1e-9) {
        return None;
    }
    out.extend(
        frame
            .landmarks
            .iter()
            .map(|p| (unproject(p) * (0.01 / s)).as_vec3()),
    );
    Some(f / s * 0.01)
}

/// Imports a MediaPipe dump as a `mediapipe478` recording: converted frames, `tracked: false`
/// with no points where no face was found; a 468-point frame (no iris refinement) has its 10
/// iris points invalid. `fov_deg` is the camera's vertical field of view.
pub fn import_mediapipe(
    path: &Path,
    fov_deg: f64,
    source: Option<&str>,
) -> Result<Imported, MediaPipeError> {
    let text = mimic_types::limits::read_capped(path, &MEDIAPIPE_FILE).map_err(|e| {
        MediaPipeError::Io {
            path: path.to_path_buf(),
            source: e.into(),
        }
    })?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let default_source = format!("MediaPipe Face Mesh 478 landmarks ({name})");
    convert_dump(&text, path, fov_deg, source.unwrap_or(&default_source))
}

/// [`import_mediapipe`] on a dump already in memory (`path` only names it in errors).
pub fn convert_dump(
    text: &str,
    path: &Path,
    fov_deg: f64,
    source: &str,
) -> Result<Imported, MediaPipeError> {
    if !(fov_deg.is_finite() && fov_deg > 0.0 && fov_deg < 180.0) {
        return Err(MediaPipeError::Fov(fov_deg));
    }
    let dump = parse_dump(text, path)?;
    let (Some(first), Some(last)) = (dump.first(), dump.last()) else {
        return Err(MediaPipeError::Empty {
            path: path.to_path_buf(),
        });
    };
    let span_s = (last.t_us - first.t_us) as f64 * 1e-6;
    let rate_hz = if dump.len() > 1 && span_s > 0.0 {
        (dump.len() - 1) as f64 / span_s
    } else {
        30.0
    };
    let mut frames = Vec::with_capacity(dump.len());
    let mut points = Vec::with_capacity(POINT_COUNT);
    let mut lost_fits = 0usize;
    for d in &dump {
        let fitted = to_camera_space(d, fov_deg, &mut points).is_some();
        let frame = if fitted {
            let mut pts = points.clone();
            let mut valid = vec![true; POINT_COUNT];
            if pts.len() == MESH_POINTS {
                pts.resize(POINT_COUNT, Vec3::NAN);
                valid[MESH_POINTS..].fill(false);
            }
            LandmarkFrame {
                timestamp_us: d.t_us,
                points: pts,
                valid,
                tracked: true,
            }
        } else {
            lost_fits += usize::from(!d.landmarks.is_empty());
            LandmarkFrame {
                timestamp_us: d.t_us,
                points: Vec::new(),
                valid: Vec::new(),
                tracked: false,
            }
        };
        frames.push(RecordedFrame::unlabelled(frame));
    }
    let mut header = RecordingHeader::new(LAYOUT, source, rate_hz, Some(POINT_COUNT));
    header.description = Some(format!(
        "MediaPipe normalised landmarks -> metres in camera space (mimic_capture::mediapipe): pinhole \
         camera with a {fov_deg} degree vertical field of view centred on the image; per frame, the \
         scale of a weighted similarity fit of MediaPipe's canonical face (cm) over its 33 Procrustes \
         landmarks gives the face's distance, each point unprojected at its own depth; the face is \
         taken to be the canonical face's size{}",
        if lost_fits > 0 {
            format!("; {lost_fits} frames with degenerate landmarks written as lost")
        } else {
            String::new()
        }
    ));
    Ok(Imported { header, frames })
}

#[cfg(test)]
mod tests;
