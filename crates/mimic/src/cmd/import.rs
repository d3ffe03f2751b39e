//! `mimic import`: other trackers' files to v1 recordings; with `--fit candide3`, the capture
//! fitted with CANDIDE-3 as a `kinect121` recording (points 0-112 the fitted vertices, 113-120
//! invalid) with the fit kept per frame and one-sided motion kept by the AUs' odd parts, fitted
//! after the pose (`--symmetric`: without them; docs/fitter.md, "One-sided motion").

use crate::cmd::setup::fit_candide3;
use anyhow::Context;
use clap::Subcommand;
use mimic_assets::ConfigDirs;
use mimic_capture::gfe::FramePixels;
use mimic_capture::openface::OpenFaceTiming;
use mimic_capture::{Imported, RecordingHeader, RecordingWriter};
use mimic_fit::OddParts;
use mimic_fit::capture::{CaptureFrame, KINECT121_POINTS, frame_fields};
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// Model a capture can be fitted with.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitModel {
    /// CANDIDE-3 (configs/models/candide3/candide3.wfm) -> a `kinect121` recording.
    Candide3,
}

/// Importers of other trackers' files.
#[derive(Subcommand, Debug)]
pub enum ImportCommand {
    /// UCI Grammatical Facial Expressions Kinect file (`*_datapoints.txt`) to a `kinect-gfe100` recording.
    Gfe {
        /// The `*_datapoints.txt` file.
        datapoints: PathBuf,
        /// The matching `*_targets.txt` (one 0/1 per frame), stored as each frame's `label`.
        #[arg(long)]
        targets: Option<PathBuf>,
        /// Output recording (.jsonl).
        #[arg(short, long)]
        output: PathBuf,
        /// Text for the header's `source` field (default: names the dataset and file).
        #[arg(long)]
        source: Option<String>,
        /// Fit a face model and write its `kinect121` recording instead (docs/fitter.md).
        #[arg(long, value_enum)]
        fit: Option<FitModel>,
        /// With --fit: a left-right symmetric fit, no odd parts (the fit before one-sided motion
        /// was kept, docs/fitter.md).
        #[arg(long, requires = "fit")]
        symmetric: bool,
        /// Keep the sensor's depths: holes stay invalid, off-face samples stay (default: repaired
        /// from the head's depth plane and the neighbouring frames, docs/gate.md).
        #[arg(long)]
        raw_depth: bool,
    },
    /// OpenFace 2.x CSV (3D landmarks X_i, Y_i, Z_i) to an `ibug68` recording.
    Openface {
        /// The CSV written by OpenFace FeatureExtraction.
        csv: PathBuf,
        /// Output recording (.jsonl).
        #[arg(short, long)]
        output: PathBuf,
        /// Re-time frames by row index at this rate (Hz).
        #[arg(long, default_value_t = 30.0, conflicts_with = "keep_timestamps")]
        rate: f64,
        /// Keep the file's `timestamp` column instead of re-timing.
        #[arg(long)]
        keep_timestamps: bool,
        /// Text for the header's `source` field (default: names the tool and file).
        #[arg(long)]
        source: Option<String>,
        /// Fit a face model and write its `kinect121` recording instead (docs/fitter.md).
        #[arg(long, value_enum)]
        fit: Option<FitModel>,
        /// With --fit: a left-right symmetric fit, no odd parts (the fit before one-sided motion
        /// was kept, docs/fitter.md).
        #[arg(long, requires = "fit")]
        symmetric: bool,
    },
    /// MediaPipe Face Mesh dump (JSON lines of normalised landmarks, `tools/mediapipe_track.py`)
    /// to a `mediapipe478` recording in camera-space metres.
    Mediapipe {
        /// The dump (.jsonl).
        dump: PathBuf,
        /// Output recording (.jsonl).
        #[arg(short, long)]
        output: PathBuf,
        /// The camera's vertical field of view in degrees (MediaPipe's own default: 63).
        #[arg(long, default_value_t = mimic_capture::mediapipe::DEFAULT_FOV_DEG)]
        fov_deg: f64,
        /// Text for the header's `source` field (default: names the tracker and file).
        #[arg(long)]
        source: Option<String>,
    },
    /// OpenSeeFace UDP capture (`.osf`: per datagram its receive time, length and bytes) to an
    /// `openseeface68` recording (docs/trackers.md).
    Openseeface {
        /// The `.osf` capture.
        capture: PathBuf,
        /// Output recording (.jsonl).
        #[arg(short, long)]
        output: PathBuf,
        /// Face id to import (default: the capture's first).
        #[arg(long)]
        face: Option<i32>,
        /// Time each datagram by this CSV (`packet`, `t_us` or `video_t_us` columns), e.g. the
        /// video time behind each datagram of a capture of a video file (default: the
        /// datagrams' own timestamps).
        #[arg(long, value_name = "CSV")]
        frame_times: Option<PathBuf>,
        /// Text for the header's `source` field (default: names the tracker and file).
        #[arg(long)]
        source: Option<String>,
    },
}

/// Runs an import subcommand.
pub fn run(c: ImportCommand) -> anyhow::Result<()> {
    let (imported, output, fit) = match c {
        ImportCommand::Gfe {
            datapoints,
            targets,
            output,
            source,
            fit,
            symmetric,
            raw_depth,
        } => {
            let (mut imported, pixels) = mimic_capture::gfe::import_gfe_with_pixels(
                &datapoints,
                targets.as_deref(),
                source.as_deref(),
            )?;
            // A fit reads the pixels and weighs depths itself (docs/fitter.md): it gets them raw.
            if fit.is_none() && !raw_depth {
                let r = mimic_capture::gfe::repair_depth(&mut imported, &pixels);
                println!(
                    "depth repaired: {} holes filled, {} off-face depths replaced, {} frames kept as measured",
                    r.holes_filled, r.outliers_replaced, r.frames_kept
                );
            }
            (imported, output, fit.map(|m| (m, symmetric, Some(pixels))))
        }
        ImportCommand::Openface {
            csv,
            output,
            rate,
            keep_timestamps,
            source,
            fit,
            symmetric,
        } => {
            let timing = if keep_timestamps {
                OpenFaceTiming::FileTimestamps
            } else {
                OpenFaceTiming::Rate(rate)
            };
            (
                mimic_capture::openface::import_openface(&csv, timing, source.as_deref())?,
                output,
                fit.map(|m| (m, symmetric, None)),
            )
        }
        ImportCommand::Mediapipe {
            dump,
            output,
            fov_deg,
            source,
        } => (
            mimic_capture::mediapipe::import_mediapipe(&dump, fov_deg, source.as_deref())?,
            output,
            None,
        ),
        ImportCommand::Openseeface {
            capture,
            output,
            face,
            frame_times,
            source,
        } => {
            let times = frame_times
                .as_deref()
                .map(mimic_trackers::import::read_frame_times)
                .transpose()?;
            let osf = mimic_trackers::import::import_osf(
                &capture,
                face,
                source.as_deref(),
                times.as_ref(),
            )?;
            if osf.other_faces > 0 {
                eprintln!(
                    "{}: {} faces of other ids left out (imported face {}; --face picks one)",
                    capture.display(),
                    osf.other_faces,
                    osf.face_id
                );
            }
            (osf.imported, output, None)
        }
    };
    if let Some((FitModel::Candide3, symmetric, pixels)) = fit {
        let odd = if symmetric {
            OddParts::Off
        } else {
            OddParts::AfterPose
        };
        return write_fitted(&imported, pixels.as_deref(), odd, &output);
    }
    write(&imported, &output)?;
    println!("{}", summary_line(&imported, &output));
    Ok(())
}

fn write(imported: &Imported, output: &Path) -> anyhow::Result<()> {
    let file = std::fs::File::create(output)
        .with_context(|| format!("{}: cannot create", output.display()))?;
    imported
        .write_to(BufWriter::new(file))
        .with_context(|| format!("{}: cannot write", output.display()))?;
    Ok(())
}

/// Fits CANDIDE-3 to an imported capture (with the tracker's pixels where it gave them), writes
/// the `kinect121` recording with each frame's `fit` and prints the summary line.
fn write_fitted(
    imported: &Imported,
    pixels: Option<&[FramePixels]>,
    odd: OddParts,
    output: &Path,
) -> anyhow::Result<()> {
    let frames: Vec<CaptureFrame> = imported
        .frames
        .iter()
        .enumerate()
        .map(|(i, f)| CaptureFrame {
            landmarks: &f.frame,
            label: f.label,
            pixels: pixels.and_then(|p| p.get(i)).map(Vec::as_slice),
        })
        .collect();
    let fit = fit_candide3(
        &ConfigDirs::locate(None),
        &imported.header.layout,
        &frames,
        odd,
    )?;
    let mut header = RecordingHeader::new(
        "kinect121",
        &format!(
            "{} -> CANDIDE-3 fit (mimic import --fit candide3)",
            imported.header.source
        ),
        imported.header.rate_hz,
        Some(KINECT121_POINTS),
    );
    header.description = Some(fit.description(imported.frames.iter().any(|f| f.label.is_some())));
    header
        .extra
        .insert("fit".to_string(), fit.header_fit.clone());
    let cannot_write = || format!("{}: cannot write", output.display());
    let mut w = RecordingWriter::create(output, &header)
        .with_context(|| format!("{}: cannot create", output.display()))?;
    for ((frame, r), source) in fit.frames.iter().zip(&fit.results).zip(&imported.frames) {
        w.write_frame_with_fields(frame, source.label, &frame_fields(r))
            .with_context(cannot_write)?;
    }
    w.finish().with_context(cannot_write)?;
    let s = &fit.summary;
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

fn summary_line(imported: &Imported, output: &Path) -> String {
    let frames = &imported.frames;
    let duration_s = match (frames.first(), frames.last()) {
        (Some(a), Some(b)) => (b.frame.timestamp_us - a.frame.timestamp_us) as f64 * 1e-6,
        _ => 0.0,
    };
    format!(
        "{}: {} frames ({} lost tracking), {} invalid points, {:.1} s, layout {}",
        output.display(),
        frames.len(),
        imported.lost_frames(),
        imported.invalid_points(),
        duration_s,
        imported.header.layout
    )
}
