//! `mimic import … --fit candide3`: fits CANDIDE-3 to an imported capture and writes a `kinect121`
//! recording (points 0-112 the fitted vertices, 113-120 invalid) with the fit kept per frame.

use anyhow::Context;
use glam::{DVec2, DVec3, Vec3};
use mimic_assets::ConfigDirs;
use mimic_capture::Imported;
use mimic_capture::recording::{RecordedFrame, RecordingHeader, RecordingWriter};
use mimic_fit::{Camera, Candide3, FitResult, FitSettings, Fitter, PointObservation};
use mimic_types::LandmarkFrame;
use serde_json::{Value, json};
use std::path::Path;
use std::time::Instant;

/// Model a capture can be fitted with.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitModel {
    /// CANDIDE-3 (configs/models/candide3/candide3.wfm) -> a `kinect121` recording.
    Candide3,
}

/// Points in a `kinect121` frame; 0-112 are the CANDIDE-3 vertices.
pub const KINECT121_POINTS: usize = 121;
/// Frames used to estimate the performer's shape units (the first ones not labelled expressive).
pub const SHAPE_FRAMES: usize = 10;

/// What a fit run did, for the summary line.
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

/// Raw GFE pixels by frame: the `*_datapoints.txt` rows' (x, y) per point, (0, 0) read as missing.
pub fn gfe_pixels(datapoints: &Path) -> anyhow::Result<Vec<Vec<Option<DVec2>>>> {
    let text = std::fs::read_to_string(datapoints)
        .with_context(|| format!("{}: cannot read", datapoints.display()))?;
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        if line.trim().is_empty() {
            continue;
        }
        let tokens: Vec<&str> = line.split_whitespace().collect();
        let values: Vec<f64> = tokens
            .iter()
            .skip(1)
            .map(|t| t.parse::<f64>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("{}:{}: not a number", datapoints.display(), i + 1))?;
        rows.push(
            values
                .chunks_exact(3)
                .map(|p| {
                    let px = DVec2::new(p[0], p[1]);
                    (px.is_finite() && px != DVec2::ZERO).then_some(px)
                })
                .collect(),
        );
    }
    Ok(rows)
}

/// Observations of an imported capture: positions from its valid points, pixels where given.
pub fn observations(
    imported: &Imported,
    pixels: Option<&[Vec<Option<DVec2>>]>,
) -> anyhow::Result<Vec<Vec<PointObservation>>> {
    if let Some(p) = pixels
        && p.len() != imported.frames.len()
    {
        anyhow::bail!(
            "{} pixel rows for {} imported frames",
            p.len(),
            imported.frames.len()
        );
    }
    Ok(imported
        .frames
        .iter()
        .enumerate()
        .map(|(i, f)| {
            (0..f.frame.points.len())
                .map(|k| PointObservation {
                    pixel: pixels.and_then(|p| p[i].get(k).copied().flatten()),
                    position: (f.frame.tracked && f.frame.is_valid(k))
                        .then(|| f.frame.points[k].as_dvec3()),
                })
                .collect()
        })
        .collect())
}

/// Fits `model` to an imported capture and returns the `kinect121` recording and a summary.
pub fn fit_capture(
    imported: &Imported,
    pixels: Option<&[Vec<Option<DVec2>>]>,
    model: FitModel,
) -> anyhow::Result<(FittedRecording, FitSummary)> {
    let FitModel::Candide3 = model;
    let configs = ConfigDirs::locate(None);
    let layout = configs.load_layout_named(&imported.header.layout)?;
    if layout.candide_correspondences.is_empty() {
        anyhow::bail!(
            "layout `{}` lists no candide_correspondences: it cannot be fitted",
            layout.name
        );
    }
    let wfm = configs.root.join("models/candide3/candide3.wfm");
    let bytes = std::fs::read(&wfm).with_context(|| format!("{}: cannot read", wfm.display()))?;
    let candide = Candide3::parse(&String::from_utf8_lossy(&bytes))
        .with_context(|| format!("{}: not a CANDIDE-3 model", wfm.display()))?;
    let camera = Camera::KINECT_V1_COLOUR;
    let mut fitter = Fitter::new(
        candide,
        &layout.candide_correspondences,
        layout.point_count,
        camera,
        FitSettings::default(),
    )?;
    let obs = observations(imported, pixels)?;
    let started = Instant::now();
    let neutral: Vec<&[PointObservation]> = obs
        .iter()
        .zip(&imported.frames)
        .filter(|(_, f)| f.frame.tracked && f.label != Some(1))
        .map(|(o, _)| o.as_slice())
        .take(SHAPE_FRAMES)
        .collect();
    let shape_used = fitter.estimate_shape(&neutral);
    let mut frames = Vec::with_capacity(obs.len());
    let mut fields = Vec::with_capacity(obs.len());
    let mut residuals = Vec::new();
    let mut verts = Vec::new();
    for (o, f) in obs.iter().zip(&imported.frames) {
        let r = if f.frame.tracked {
            fitter.fit(o)
        } else {
            fitter.reset();
            fitter.fit(&[])
        };
        let frame = if r.tracked {
            residuals.push(r.residual_px);
            fitter.vertices(&r.pose, &r.au, &mut verts);
            let mut points: Vec<Vec3> = verts.iter().map(|v| v.as_vec3()).collect();
            let mut valid = vec![true; points.len()];
            points.resize(KINECT121_POINTS, Vec3::NAN);
            valid.resize(KINECT121_POINTS, false);
            LandmarkFrame {
                timestamp_us: f.frame.timestamp_us,
                points,
                valid,
                tracked: true,
            }
        } else {
            LandmarkFrame {
                timestamp_us: f.frame.timestamp_us,
                points: Vec::new(),
                valid: Vec::new(),
                tracked: false,
            }
        };
        frames.push(RecordedFrame {
            frame,
            label: f.label,
        });
        fields.push(fit_field(&r));
    }
    let elapsed = started.elapsed().as_secs_f64();
    residuals.sort_by(f64::total_cmp);
    let median_residual_px = residuals
        .get(residuals.len() / 2)
        .copied()
        .unwrap_or(f64::NAN);
    let summary = FitSummary {
        frames: frames.len(),
        lost: frames.iter().filter(|f| !f.frame.tracked).count(),
        median_residual_px,
        frames_per_s: frames.len() as f64 / elapsed.max(1e-9),
    };
    let mut header = RecordingHeader::new(
        "kinect121",
        &format!(
            "{} -> CANDIDE-3 fit (mimic import --fit candide3)",
            imported.header.source
        ),
        imported.header.rate_hz,
        Some(KINECT121_POINTS),
    );
    header.description = Some(format!(
        "Kinect-style 121-point shape: points 0-112 are CANDIDE-3 v3.1.6 vertices fitted per frame to the `{}` \
         points (pose, scale, animation units; shape units from {shape_used} neutral frames), camera space, metres; \
         points 113-120 are not modelled and always invalid. Per frame `fit` holds the pose, the 11 AUV \
         coefficients and the RMS reprojection residual (docs/fitter.md).{}",
        imported.header.layout,
        if frames.iter().any(|f| f.label.is_some()) {
            " label = the source's per-frame label."
        } else {
            ""
        }
    ));
    let m = fitter.model();
    header.extra.insert(
        "fit".to_string(),
        json!({
            "model": "candide3",
            "from_layout": imported.header.layout,
            "au_names": m.auvs().iter().map(|u| u.name.clone()).collect::<Vec<_>>(),
            "au_fitted": fitter.settings().units,
            "shape_units": m.shape_units.iter().map(|u| u.name.clone()).collect::<Vec<_>>(),
            "shape": fitter.shape().iter().map(|v| round(*v, 4)).collect::<Vec<_>>(),
            "camera": {"focal_px": camera.focal_px, "cx": camera.cx, "cy": camera.cy},
            "median_residual_px": round(median_residual_px, 3),
        }),
    );
    let imported = Imported { header, frames };
    Ok((FittedRecording { imported, fields }, summary))
}

/// A fitted `kinect121` recording and each frame's extra fields (its `fit` object), ready to write.
#[derive(Clone, Debug, PartialEq)]
pub struct FittedRecording {
    /// Header and frames.
    pub imported: Imported,
    /// Per-frame extra fields, one map per frame.
    pub fields: Vec<serde_json::Map<String, Value>>,
}

fn round(v: f64, digits: i32) -> f64 {
    let k = 10f64.powi(digits);
    (v * k).round() / k
}

fn fit_field(r: &FitResult) -> serde_json::Map<String, Value> {
    let mut fit = serde_json::Map::new();
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
        fit.insert("residual_px".into(), json!(round(r.residual_px, 3)));
    }
    fit.insert("points_used".into(), json!(r.points_used));
    let mut fields = serde_json::Map::new();
    fields.insert("fit".into(), Value::Object(fit));
    fields
}

/// Writes a fitted recording, each frame with its `fit` field.
pub fn write_fitted(fitted: &FittedRecording, output: &Path) -> anyhow::Result<()> {
    let mut w = RecordingWriter::create(output, &fitted.imported.header)
        .with_context(|| format!("{}: cannot create", output.display()))?;
    let empty = serde_json::Map::new();
    for (i, f) in fitted.imported.frames.iter().enumerate() {
        w.write_frame_with_fields(&f.frame, f.label, fitted.fields.get(i).unwrap_or(&empty))
            .with_context(|| format!("{}: cannot write", output.display()))?;
    }
    w.finish()
        .with_context(|| format!("{}: cannot write", output.display()))?;
    Ok(())
}

/// Fits, writes `output` and prints the summary line.
pub fn run_fit(
    imported: &Imported,
    pixels: Option<&[Vec<Option<DVec2>>]>,
    model: FitModel,
    output: &Path,
) -> anyhow::Result<()> {
    let (fitted, s) = fit_capture(imported, pixels, model)?;
    write_fitted(&fitted, output)?;
    println!(
        "{}: {} frames fitted with CANDIDE-3 ({} lost), median residual {:.2} px, {:.0} frames/s, layout kinect121",
        output.display(),
        s.frames,
        s.lost,
        s.median_residual_px,
        s.frames_per_s
    );
    Ok(())
}

/// CANDIDE-3 fitting speed on a recording whose layout lists correspondences (`None` otherwise), for
/// `mimic bench`: its valid 3D points only (a recording keeps no pixels of depth-less points).
pub fn fit_throughput(recording: &Path) -> anyhow::Result<Option<FitSummary>> {
    let mut reader = mimic_capture::RecordingReader::open(recording, None)?;
    let header = reader.header().clone();
    let configs = ConfigDirs::locate(None);
    let has_correspondences = configs
        .load_layout_named(&header.layout)
        .is_ok_and(|l| !l.candide_correspondences.is_empty());
    if !has_correspondences {
        return Ok(None);
    }
    let mut frames = Vec::new();
    while let Some(item) = reader.next_frame() {
        if let Ok(f) = item {
            frames.push(f);
        }
    }
    let imported = Imported { header, frames };
    let (_, summary) = fit_capture(&imported, None, FitModel::Candide3)?;
    Ok(Some(summary))
}
