//! `mimic import`: other trackers' files to v1 recordings; with `--fit candide3`, the capture
//! fitted with CANDIDE-3 as a `kinect121` recording (points 0-112 the fitted vertices, 113-120
//! invalid) with the fit kept per frame and one-sided motion kept by the AUs' odd parts, fitted
//! after the pose (`--symmetric`: without them; docs/fitter.md, "One-sided motion").

use crate::cmd::setup::fit_candide3;
use anyhow::Context;
use clap::Subcommand;
use mimic_assets::ConfigDirs;
use mimic_fit::OddParts;
use mimic_trackers::importer::{ImportOptions, importer};
use std::path::PathBuf;

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
        #[arg(long, default_value_t = mimic_trackers::mediapipe::DEFAULT_FOV_DEG)]
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
    /// Speech (WAV) to ARKit mouth weights at 60 fps, a weights CSV (docs/audio.md).
    Audio {
        /// The WAV (PCM or float, any common rate, mono or stereo).
        wav: PathBuf,
        /// What is said (text, or a file holding it): its phones are laid along the speech.
        #[arg(long)]
        transcript: Option<String>,
        /// Output weights CSV.
        #[arg(short, long)]
        output: PathBuf,
    },
}

/// Runs an import subcommand: the tracker's row of `mimic_trackers::importer::IMPORTERS` reads
/// the file; then the recording is written, or fitted first with `--fit`.
pub fn run(c: ImportCommand) -> anyhow::Result<()> {
    let (name, mut o, input, output, fit, symmetric) = match &c {
        ImportCommand::Gfe {
            datapoints,
            targets,
            output,
            source,
            fit,
            symmetric,
            raw_depth,
        } => {
            let o = ImportOptions::gfe(targets.as_deref(), source.as_deref(), *raw_depth);
            ("gfe", o, datapoints, output, *fit, *symmetric)
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
            let rate = (!keep_timestamps).then_some(*rate);
            let o = ImportOptions::openface(rate, source.as_deref());
            ("openface", o, csv, output, *fit, *symmetric)
        }
        ImportCommand::Mediapipe {
            dump,
            output,
            fov_deg,
            source,
        } => {
            let o = ImportOptions::mediapipe(*fov_deg, source.as_deref());
            ("mediapipe", o, dump, output, None, false)
        }
        ImportCommand::Openseeface {
            capture,
            output,
            face,
            frame_times,
            source,
        } => {
            let o = ImportOptions::openseeface(*face, frame_times.as_deref(), source.as_deref());
            ("openseeface", o, capture, output, None, false)
        }
        ImportCommand::Audio {
            wav,
            transcript,
            output,
        } => {
            let said = mimic_audio::import_audio(wav, transcript.as_deref(), output)?;
            println!("{said}");
            return Ok(());
        }
    };
    o.for_fit = fit.is_some();
    let tracker = importer(name).with_context(|| format!("no importer named `{name}`"))?;
    let import = tracker.import(input, &o)?;
    for line in &import.notes {
        println!("{line}");
    }
    for line in &import.warnings {
        eprintln!("{line}");
    }
    if let Some(FitModel::Candide3) = fit {
        let odd = OddParts::of_import(symmetric);
        let configs = ConfigDirs::locate(None);
        let layout = &import.imported.header.layout;
        let fit = fit_candide3(&configs, layout, &import.capture_frames(), odd)?;
        import.write_fitted(&fit, output)?;
        println!("{}", fit.summary.said(output));
        return Ok(());
    }
    import.write(output)?;
    println!("{}", import.imported.summary(output));
    Ok(())
}
