//! An [`Import`] written to its recording file: as imported ([`Import::write`]), or fitted with
//! CANDIDE-3 as a `kinect121` recording with each frame's `fit` ([`Import::capture_frames`] for
//! the fit, [`Import::write_fitted`]; `mimic import --fit candide3`, docs/fitter.md).

use crate::importer::Import;
use mimic_capture::RecordingWriter;
use mimic_fit::capture::{CaptureFit, CaptureFrame, frame_fields};
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// Why an imported recording could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ImportWriteError {
    /// The file could not be created.
    #[error("{}: cannot create", path.display())]
    Create {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
    /// The recording could not be written.
    #[error("{}: cannot write", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: mimic_capture::WriteError,
    },
}

impl ImportWriteError {
    fn create(path: &Path, source: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> Self {
        Self::Create {
            path: path.to_path_buf(),
            source: source.into(),
        }
    }

    fn write(path: &Path) -> impl FnOnce(mimic_capture::WriteError) -> Self + '_ {
        move |source| Self::Write {
            path: path.to_path_buf(),
            source,
        }
    }
}

impl Import {
    /// Writes the imported recording to `output`.
    pub fn write(&self, output: &Path) -> Result<(), ImportWriteError> {
        let file =
            std::fs::File::create(output).map_err(|e| ImportWriteError::create(output, e))?;
        self.imported
            .write_to(BufWriter::new(file))
            .map_err(ImportWriteError::write(output))?;
        Ok(())
    }

    /// The frames as a face-model fit takes them, each with the tracker's pixels where it gave
    /// them.
    pub fn capture_frames(&self) -> Vec<CaptureFrame<'_>> {
        let pixels = self.pixels.as_deref();
        self.imported
            .frames
            .iter()
            .enumerate()
            .map(|(i, f)| CaptureFrame {
                landmarks: &f.frame,
                label: f.label,
                pixels: pixels.and_then(|p| p.get(i)).map(Vec::as_slice),
            })
            .collect()
    }

    /// Writes `fit` (of [`Import::capture_frames`]) to `output` as a `kinect121` recording with
    /// each frame's `fit` and the source frame's label.
    pub fn write_fitted(&self, fit: &CaptureFit, output: &Path) -> Result<(), ImportWriteError> {
        let labelled = self.imported.frames.iter().any(|f| f.label.is_some());
        let header = fit.recording_header(&self.imported.header, labelled);
        let mut w = RecordingWriter::create(output, &header)
            .map_err(|e| ImportWriteError::create(output, e))?;
        let frames = fit.frames.iter().zip(&fit.results);
        for ((frame, r), source) in frames.zip(&self.imported.frames) {
            w.write_frame_with_fields(frame, source.label, &frame_fields(r))
                .map_err(ImportWriteError::write(output))?;
        }
        w.finish().map_err(ImportWriteError::write(output))?;
        Ok(())
    }
}
