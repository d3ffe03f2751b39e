//! A whole capture fitted with CANDIDE-3, in memory: shape units from the first neutral frames,
//! then every frame in order (warm start), giving the 121-point `kinect121` frames that
//! `mimic import --fit candide3` writes (points 0-112 the fitted vertices, 113-120 invalid) and
//! each frame's fit ([`fit_capture`]; [`fit_candide3`] with the model read from its file). The
//! caller reads the capture and writes the recording.

use crate::{
    Camera, Candide3, FitError, FitResult, FitSettings, Fitter, OddParts, PointObservation,
};
use glam::{DVec2, DVec3, Vec3};
use mimic_types::{LandmarkFrame, Layout};
use serde_json::{Map, Value, json};
use std::time::Instant;

/// Points in a `kinect121` frame; 0-112 are the CANDIDE-3 vertices.
pub const KINECT121_POINTS: usize = 121;
/// Frames used to estimate the performer's shape units (the first ones not labelled expressive).
pub const SHAPE_FRAMES: usize = 10;

/// One frame of a capture to fit.
#[derive(Clone, Copy, Debug)]
pub struct CaptureFrame<'a> {
    /// The landmarks (camera space, metres).
    pub landmarks: &'a LandmarkFrame,
    /// The frame's label; frames labelled 1 (expressive) are not used for the shape.
    pub label: Option<i64>,
    /// The tracker's 2D pixel per point, where it gave them.
    pub pixels: Option<&'a [Option<DVec2>]>,
}

impl<'a> CaptureFrame<'a> {
    /// A frame of `landmarks` with its `label` and no pixels (a recording keeps none).
    pub fn without_pixels(landmarks: &'a LandmarkFrame, label: Option<i64>) -> Self {
        Self {
            landmarks,
            label,
            pixels: None,
        }
    }
}

/// What a fit run did.
#[derive(Clone, Debug, PartialEq)]
pub struct FitSummary {
    /// Frames fitted (lost ones included).
    pub frames: usize,
    /// Frames flagged lost.
    pub lost: usize,
    /// Median over tracked frames of the per-frame RMS reprojection residual (pixels).
    pub median_residual_px: f64,
    /// Fitting speed on this machine (frames per second, one thread).
    pub frames_per_s: f64,
}

/// A fitted capture: the `kinect121` frames, each frame's fit, and what the fit used.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureFit {
    /// One `kinect121` frame per input frame (lost: no points, `tracked: false`).
    pub frames: Vec<LandmarkFrame>,
    /// Each frame's fit.
    pub results: Vec<FitResult>,
    /// Name of the fitted capture's layout.
    pub from_layout: String,
    /// Neutral frames the shape units were estimated from.
    pub shape_frames: usize,
    /// Counts, residual and speed.
    pub summary: FitSummary,
    /// The header's `fit` object: model, units, shape, camera, median residual.
    pub header_fit: Value,
    /// How the AUs' left-right odd parts were fitted.
    pub odd: OddParts,
}

/// The observations of one frame: positions of its valid points (when tracked), pixels where given.
pub fn observations(frame: &CaptureFrame<'_>) -> Vec<PointObservation> {
    let f = frame.landmarks;
    (0..f.points.len())
        .map(|k| PointObservation {
            pixel: frame.pixels.and_then(|p| p.get(k).copied().flatten()),
            position: (f.tracked && f.is_valid(k)).then(|| f.points[k].as_dvec3()),
        })
        .collect()
}

/// Fits `model` with `settings` to every frame of a capture in `layout` (through its
/// `candide_correspondences`).
pub fn fit_capture(
    model: Candide3,
    layout: &Layout,
    camera: Camera,
    settings: FitSettings,
    frames: &[CaptureFrame<'_>],
) -> Result<CaptureFit, FitError> {
    let odd = settings.odd;
    let mut fitter = Fitter::new(
        model,
        &layout.candide_correspondences,
        layout.point_count,
        camera,
        settings,
    )?;
    let obs: Vec<Vec<PointObservation>> = frames.iter().map(observations).collect();
    let started = Instant::now();
    let neutral: Vec<&[PointObservation]> = obs
        .iter()
        .zip(frames)
        .filter(|(_, f)| f.landmarks.tracked && f.label != Some(1))
        .map(|(o, _)| o.as_slice())
        .take(SHAPE_FRAMES)
        .collect();
    let shape_frames = fitter.estimate_shape(&neutral);
    let mut out = Vec::with_capacity(obs.len());
    let mut results = Vec::with_capacity(obs.len());
    let mut residuals = Vec::new();
    let mut verts = Vec::new();
    for (o, f) in obs.iter().zip(frames) {
        let t = f.landmarks.timestamp_us;
        let r = if f.landmarks.tracked {
            fitter.fit(o)
        } else {
            fitter.reset();
            fitter.fit(&[])
        };
        out.push(if r.tracked {
            residuals.push(r.residual_px);
            fitter.vertices(&r.pose, &r.au, &r.au_odd, &mut verts);
            let mut points: Vec<Vec3> = verts.iter().map(|v| v.as_vec3()).collect();
            let mut valid = vec![true; points.len()];
            points.resize(KINECT121_POINTS, Vec3::NAN);
            valid.resize(KINECT121_POINTS, false);
            LandmarkFrame {
                timestamp_us: t,
                points,
                valid,
                tracked: true,
            }
        } else {
            LandmarkFrame {
                timestamp_us: t,
                points: Vec::new(),
                valid: Vec::new(),
                tracked: false,
            }
        });
        results.push(r);
    }
    let elapsed = started.elapsed().as_secs_f64();
    residuals.sort_by(f64::total_cmp);
    let median_residual_px = residuals
        .get(residuals.len() / 2)
        .copied()
        .unwrap_or(f64::NAN);
    let summary = FitSummary {
        frames: out.len(),
        lost: out.iter().filter(|f| !f.tracked).count(),
        median_residual_px,
        frames_per_s: out.len() as f64 / elapsed.max(1e-9),
    };
    let m = fitter.model();
    let mut header_fit = json!({
        "model": "candide3",
        "from_layout": layout.name,
        "au_names": m.auvs().iter().map(|u| u.name.clone()).collect::<Vec<_>>(),
        "au_fitted": fitter.fitted_units(),
        "shape_units": m.shape_units.iter().map(|u| u.name.clone()).collect::<Vec<_>>(),
        "shape": fitter.shape().iter().map(|v| round(*v, 4)).collect::<Vec<_>>(),
        "camera": {"focal_px": camera.focal_px, "cx": camera.cx, "cy": camera.cy},
        "median_residual_px": round(median_residual_px, 3),
    });
    // A symmetric fit's header stays as it was before odd parts existed.
    let odd_name = match odd {
        OddParts::Off => None,
        OddParts::Joint => Some("joint"),
        OddParts::AfterPose => Some("after_pose"),
    };
    if let (Some(name), Some(h)) = (odd_name, header_fit.as_object_mut()) {
        h.insert("odd".into(), json!(name));
    }
    Ok(CaptureFit {
        frames: out,
        results,
        from_layout: layout.name.clone(),
        shape_frames,
        summary,
        header_fit,
        odd,
    })
}

/// Why a capture cannot be fitted with the CANDIDE-3 model file.
#[derive(Debug, thiserror::Error)]
pub enum Candide3FitError {
    /// The layout names no CANDIDE-3 vertex for its points.
    #[error("layout `{0}` lists no candide_correspondences: it cannot be fitted")]
    NoCorrespondences(String),
    /// The model file could not be read.
    #[error("{}: cannot read", path.display())]
    Read {
        /// The model file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: mimic_types::ReadError,
    },
    /// The model file is not a CANDIDE-3 model.
    #[error("{}: not a CANDIDE-3 model", path.display())]
    Model {
        /// The model file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: crate::ModelError,
    },
    /// The fit failed.
    #[error(transparent)]
    Fit(#[from] FitError),
}

/// Fits the CANDIDE-3 model in `wfm` to a capture in `layout` (which must list
/// `candide_correspondences`), seen by a Kinect v1's colour camera, its AUs' odd parts as `odd`
/// says.
pub fn fit_candide3(
    wfm: &std::path::Path,
    layout: &Layout,
    frames: &[CaptureFrame<'_>],
    odd: OddParts,
) -> Result<CaptureFit, Candide3FitError> {
    if layout.candide_correspondences.is_empty() {
        return Err(Candide3FitError::NoCorrespondences(layout.name.clone()));
    }
    let limit = &mimic_types::limits::MODEL_FILE;
    let bytes = mimic_types::limits::read_bytes_capped(wfm, limit).map_err(|source| {
        Candide3FitError::Read {
            path: wfm.to_path_buf(),
            source,
        }
    })?;
    let candide = Candide3::parse(&String::from_utf8_lossy(&bytes)).map_err(|source| {
        Candide3FitError::Model {
            path: wfm.to_path_buf(),
            source,
        }
    })?;
    let settings = FitSettings {
        odd,
        ..FitSettings::default()
    };
    let camera = Camera::KINECT_V1_COLOUR;
    Ok(fit_capture(candide, layout, camera, settings, frames)?)
}

impl FitSummary {
    /// The figures as `mimic bench --json` gives them.
    pub fn json(&self) -> Value {
        json!({
            "model": "candide3",
            "frames": self.frames,
            "lost": self.lost,
            "frames_per_second": self.frames_per_s,
            "median_residual_px": self.median_residual_px,
        })
    }

    /// The fitting speed as `mimic bench` prints it.
    pub fn speed_line(&self) -> String {
        format!(
            "fit CANDIDE-3 to the recording: {:.0} frames/s ({} frames, median residual {:.2} px)",
            self.frames_per_s, self.frames, self.median_residual_px
        )
    }

    /// The line `mimic import --fit candide3` prints for the recording written to `output`.
    pub fn said(&self, output: &std::path::Path) -> String {
        format!(
            "{}: {} frames fitted with CANDIDE-3 ({} lost), median residual {:.2} px, {:.0} frames/s, layout kinect121",
            output.display(),
            self.frames,
            self.lost,
            self.median_residual_px,
            self.frames_per_s
        )
    }
}

impl CaptureFit {
    /// The `kinect121` recording's header of this fit of a capture with header `source`
    /// (`labelled` when its frames carry labels): its description and the header's `fit`.
    pub fn recording_header(
        &self,
        source: &mimic_types::RecordingHeader,
        labelled: bool,
    ) -> mimic_types::RecordingHeader {
        let mut header = mimic_types::RecordingHeader::new(
            "kinect121",
            &format!(
                "{} -> CANDIDE-3 fit (mimic import --fit candide3)",
                source.source
            ),
            source.rate_hz,
            Some(KINECT121_POINTS),
        );
        header.description = Some(self.description(labelled));
        header
            .extra
            .insert("fit".to_string(), self.header_fit.clone());
        header
    }

    /// The recording header's description of this fit; `labelled` when the frames carry labels.
    pub fn description(&self, labelled: bool) -> String {
        format!(
            "Kinect-style 121-point shape: points 0-112 are CANDIDE-3 v3.1.6 vertices fitted per frame to the `{}` \
             points (pose, scale, animation units; shape units from {} neutral frames), camera space, metres; \
             points 113-120 are not modelled and always invalid. Per frame `fit` holds the pose, the 11 AUV \
             coefficients{} and the RMS reprojection residual (docs/fitter.md).{}",
            self.from_layout,
            self.shape_frames,
            if self.odd == OddParts::Off {
                ""
            } else {
                ", their left-right odd parts (`au_odd`)"
            },
            if labelled {
                " label = the source's per-frame label."
            } else {
                ""
            }
        )
    }
}

/// A frame's extra recording fields: `{"fit": {rotation, translation, scale, au, au_odd,
/// residual_px, points_used}}` (`au_odd` only when odd parts were fitted; pose and residual only
/// when tracked), rounded as written.
pub fn frame_fields(r: &FitResult) -> Map<String, Value> {
    let mut fit = Map::new();
    if r.tracked {
        let q = r.pose.rotation;
        let t: DVec3 = r.pose.translation;
        fit.insert(
            "rotation".into(),
            json!([round(q.x, 6), round(q.y, 6), round(q.z, 6), round(q.w, 6)]),
        );
        fit.insert(
            "translation".into(),
            json!([round(t.x, 5), round(t.y, 5), round(t.z, 5)]),
        );
        fit.insert("scale".into(), json!(round(r.pose.scale, 6)));
        fit.insert(
            "au".into(),
            json!(r.au.iter().map(|a| round(*a, 4)).collect::<Vec<_>>()),
        );
        if !r.au_odd.is_empty() {
            fit.insert(
                "au_odd".into(),
                json!(r.au_odd.iter().map(|a| round(*a, 4)).collect::<Vec<_>>()),
            );
        }
        fit.insert("residual_px".into(), json!(round(r.residual_px, 3)));
    }
    fit.insert("points_used".into(), json!(r.points_used));
    let mut fields = Map::new();
    fields.insert("fit".into(), Value::Object(fit));
    fields
}

/// `v` rounded to `digits` decimals.
fn round(v: f64, digits: i32) -> f64 {
    let k = 10f64.powi(digits);
    (v * k).round() / k
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn observations_take_valid_tracked_points_and_given_pixels() {
        let frame = LandmarkFrame {
            timestamp_us: 0,
            points: vec![Vec3::new(1.0, 2.0, 3.0), Vec3::NAN],
            valid: vec![true, false],
            tracked: true,
        };
        let pixels = [None, Some(DVec2::new(5.0, 6.0))];
        let o = observations(&CaptureFrame {
            landmarks: &frame,
            label: None,
            pixels: Some(&pixels),
        });
        assert_eq!(o.len(), 2);
        assert_eq!(o[0].position, Some(DVec3::new(1.0, 2.0, 3.0)));
        assert_eq!((o[0].pixel, o[1].position), (None, None));
        assert_eq!(o[1].pixel, Some(DVec2::new(5.0, 6.0)));
        // A lost frame gives no positions.
        let lost = LandmarkFrame {
            tracked: false,
            ..frame
        };
        let o = observations(&CaptureFrame {
            landmarks: &lost,
            label: None,
            pixels: None,
        });
        assert!(o.iter().all(|p| p.position.is_none() && p.pixel.is_none()));
    }

    #[test]
    fn frame_fields_round_and_leave_lost_frames_bare() {
        let lost = FitResult {
            tracked: false,
            pose: crate::Pose {
                rotation: glam::DQuat::IDENTITY,
                translation: DVec3::ZERO,
                scale: 1.0,
            },
            au: vec![],
            au_odd: vec![],
            residual_px: f64::NAN,
            points_used: 3,
            iterations: 0,
        };
        assert_eq!(
            Value::Object(frame_fields(&lost)),
            json!({"fit": {"points_used": 3}})
        );
        let tracked = FitResult {
            tracked: true,
            au: vec![0.123_456],
            au_odd: vec![-0.054_321],
            residual_px: 1.234_56,
            ..lost
        };
        let f = Value::Object(frame_fields(&tracked));
        assert_eq!(f["fit"]["au"], json!([0.1235]));
        assert_eq!(f["fit"]["au_odd"], json!([-0.0543]));
        assert_eq!(f["fit"]["residual_px"], json!(1.235));
        assert_eq!(f["fit"]["rotation"], json!([0.0, 0.0, 0.0, 1.0]));
    }
}
