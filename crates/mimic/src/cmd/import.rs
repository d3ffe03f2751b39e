//! `mimic import`: other trackers' files to v1 recordings.

use anyhow::Context;
use clap::Subcommand;
use mimic_capture::Imported;
use mimic_capture::openface::OpenFaceTiming;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

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
        fit: Option<crate::cmd::import_fit::FitModel>,
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
        fit: Option<crate::cmd::import_fit::FitModel>,
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
        } => {
            let imported =
                mimic_capture::gfe::import_gfe(&datapoints, targets.as_deref(), source.as_deref())?;
            let fit = match fit {
                Some(m) => Some((m, Some(crate::cmd::import_fit::gfe_pixels(&datapoints)?))),
                None => None,
            };
            (imported, output, fit)
        }
        ImportCommand::Openface {
            csv,
            output,
            rate,
            keep_timestamps,
            source,
            fit,
        } => {
            let timing = if keep_timestamps {
                OpenFaceTiming::FileTimestamps
            } else {
                OpenFaceTiming::Rate(rate)
            };
            (
                mimic_capture::openface::import_openface(&csv, timing, source.as_deref())?,
                output,
                fit.map(|m| (m, None)),
            )
        }
    };
    if let Some((model, pixels)) = fit {
        return crate::cmd::import_fit::run_fit(&imported, pixels.as_deref(), model, &output);
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
