//! One door for every landmark tracker's file: [`Importer`] turns a tracker's file into a v1
//! recording held in memory, and [`IMPORTERS`] is the table `mimic import` dispatches from. A new
//! tracker is one module (its parser, its layout, its `Importer`) and one row here
//! (docs/ARCHITECTURE.md, "Where to change what").

use crate::gfe::{FramePixels, GfeError};
use crate::mediapipe::{DEFAULT_FOV_DEG, MediaPipeError};
use crate::openface::{OpenFaceError, OpenFaceTiming};
use crate::{TrackerError, gfe, import, mediapipe, openface, osf_frames};
use mimic_capture::Imported;
use std::path::Path;

/// What an import may be told; each tracker reads the fields that apply to it.
#[derive(Clone, Copy, Debug)]
pub struct ImportOptions<'a> {
    /// Text for the header's `source` field (default: names the tracker and the file).
    pub source: Option<&'a str>,
    /// GFE: the matching `*_targets.txt` (one 0/1 per frame), stored as each frame's `label`.
    pub targets: Option<&'a Path>,
    /// GFE: keep the sensor's depths as measured (no repair, docs/gate.md).
    pub raw_depth: bool,
    /// The capture is for a face-model fit: the tracker's pixels are kept and depths left raw
    /// (a fit weighs them itself, docs/fitter.md).
    pub for_fit: bool,
    /// OpenFace: re-time the frames by row index at this rate (Hz); `None`: the file's own
    /// `timestamp` column.
    pub rate_hz: Option<f64>,
    /// MediaPipe: the camera's vertical field of view (degrees).
    pub fov_deg: f64,
    /// OpenSeeFace: the face id to import (default: the capture's first).
    pub face: Option<i32>,
    /// OpenSeeFace: a CSV timing each datagram (`packet` and `t_us` or `video_t_us` columns).
    pub frame_times: Option<&'a Path>,
}

impl Default for ImportOptions<'_> {
    fn default() -> Self {
        Self {
            source: None,
            targets: None,
            raw_depth: false,
            for_fit: false,
            rate_hz: None,
            fov_deg: DEFAULT_FOV_DEG,
            face: None,
            frame_times: None,
        }
    }
}

impl<'a> ImportOptions<'a> {
    /// A GFE file's: its `targets` file, the header's `source`, and whether depths stay raw.
    pub fn gfe(targets: Option<&'a Path>, source: Option<&'a str>, raw_depth: bool) -> Self {
        Self {
            targets,
            source,
            raw_depth,
            ..Self::default()
        }
    }

    /// An OpenFace CSV's: re-timed at `rate_hz` (`None`: its own timestamps), the `source`.
    pub fn openface(rate_hz: Option<f64>, source: Option<&'a str>) -> Self {
        Self {
            rate_hz,
            source,
            ..Self::default()
        }
    }

    /// A MediaPipe dump's: the camera's field of view, the `source`.
    pub fn mediapipe(fov_deg: f64, source: Option<&'a str>) -> Self {
        Self {
            fov_deg,
            source,
            ..Self::default()
        }
    }

    /// An OpenSeeFace capture's: the `face`, its `frame_times` CSV, the `source`.
    pub fn openseeface(
        face: Option<i32>,
        frame_times: Option<&'a Path>,
        source: Option<&'a str>,
    ) -> Self {
        Self {
            face,
            frame_times,
            source,
            ..Self::default()
        }
    }
}

/// An imported capture and what a person should be told about it.
#[derive(Clone, Debug, PartialEq)]
pub struct Import {
    /// The recording.
    pub imported: Imported,
    /// Per frame, the tracker's 2D points (GFE), for a fit.
    pub pixels: Option<Vec<FramePixels>>,
    /// Lines for standard output (e.g. what the depth repair did).
    pub notes: Vec<String>,
    /// Lines for standard error (e.g. faces left out).
    pub warnings: Vec<String>,
}

impl Import {
    fn plain(imported: Imported) -> Self {
        Self {
            imported,
            pixels: None,
            notes: Vec::new(),
            warnings: Vec::new(),
        }
    }
}

/// Why an import failed: the tracker's own error, naming the file and line or record.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// A GFE file.
    #[error(transparent)]
    Gfe(#[from] GfeError),
    /// An OpenFace CSV.
    #[error(transparent)]
    OpenFace(#[from] OpenFaceError),
    /// A MediaPipe dump.
    #[error(transparent)]
    MediaPipe(#[from] MediaPipeError),
    /// An OpenSeeFace capture or frame-times CSV.
    #[error(transparent)]
    Tracker(#[from] TrackerError),
}

/// A landmark tracker's file format (module docs).
pub trait Importer: Sync {
    /// The name `mimic import` knows it by.
    fn name(&self) -> &'static str;
    /// The landmark layout of its recordings (`configs/layouts/`).
    fn layout(&self) -> &'static str;
    /// Reads the file at `path` into a recording.
    fn import(&self, path: &Path, options: &ImportOptions<'_>) -> Result<Import, ImportError>;
}

/// Every landmark tracker file mimic imports.
pub static IMPORTERS: &[&dyn Importer] = &[&Gfe, &OpenFace, &MediaPipe, &OpenSeeFace];

/// The importer called `name`.
pub fn importer(name: &str) -> Option<&'static dyn Importer> {
    IMPORTERS.iter().copied().find(|i| i.name() == name)
}

/// UCI "Grammatical Facial Expressions" Kinect files (`*_datapoints.txt`).
pub struct Gfe;

impl Importer for Gfe {
    fn name(&self) -> &'static str {
        "gfe"
    }

    fn layout(&self) -> &'static str {
        gfe::LAYOUT
    }

    fn import(&self, path: &Path, o: &ImportOptions<'_>) -> Result<Import, ImportError> {
        let (mut imported, pixels) = gfe::import_gfe_with_pixels(path, o.targets, o.source)?;
        let mut notes = Vec::new();
        if !o.for_fit && !o.raw_depth {
            let r = gfe::repair_depth(&mut imported, &pixels);
            notes.push(format!(
                "depth repaired: {} holes filled, {} off-face depths replaced, {} frames kept as measured",
                r.holes_filled, r.outliers_replaced, r.frames_kept
            ));
        }
        Ok(Import {
            imported,
            pixels: Some(pixels),
            notes,
            warnings: Vec::new(),
        })
    }
}

/// OpenFace 2.x CSVs (68 3D landmarks).
pub struct OpenFace;

impl Importer for OpenFace {
    fn name(&self) -> &'static str {
        "openface"
    }

    fn layout(&self) -> &'static str {
        openface::LAYOUT
    }

    fn import(&self, path: &Path, o: &ImportOptions<'_>) -> Result<Import, ImportError> {
        let timing = match o.rate_hz {
            Some(rate) => OpenFaceTiming::Rate(rate),
            None => OpenFaceTiming::FileTimestamps,
        };
        Ok(Import::plain(openface::import_openface(
            path, timing, o.source,
        )?))
    }
}

/// MediaPipe Face Mesh dumps (`tools/mediapipe_track.py -o`).
pub struct MediaPipe;

impl Importer for MediaPipe {
    fn name(&self) -> &'static str {
        "mediapipe"
    }

    fn layout(&self) -> &'static str {
        mediapipe::LAYOUT
    }

    fn import(&self, path: &Path, o: &ImportOptions<'_>) -> Result<Import, ImportError> {
        Ok(Import::plain(mediapipe::import_mediapipe(
            path, o.fov_deg, o.source,
        )?))
    }
}

/// OpenSeeFace UDP captures (`.osf`).
pub struct OpenSeeFace;

impl Importer for OpenSeeFace {
    fn name(&self) -> &'static str {
        "openseeface"
    }

    fn layout(&self) -> &'static str {
        osf_frames::LAYOUT
    }

    fn import(&self, path: &Path, o: &ImportOptions<'_>) -> Result<Import, ImportError> {
        let times = o.frame_times.map(import::read_frame_times).transpose()?;
        let osf = import::import_osf(path, o.face, o.source, times.as_ref())?;
        let mut warnings = Vec::new();
        if osf.other_faces > 0 {
            warnings.push(format!(
                "{}: {} faces of other ids left out (imported face {}; --face picks one)",
                path.display(),
                osf.other_faces,
                osf.face_id
            ));
        }
        Ok(Import {
            imported: osf.imported,
            pixels: None,
            notes: Vec::new(),
            warnings,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_names_each_tracker_once_with_its_layout() {
        let names: Vec<&str> = IMPORTERS.iter().map(|i| i.name()).collect();
        assert_eq!(names, ["gfe", "openface", "mediapipe", "openseeface"]);
        assert_eq!(importer("gfe").map(|i| i.layout()), Some("kinect-gfe100"));
        assert_eq!(importer("openface").map(|i| i.layout()), Some("ibug68"));
        assert_eq!(
            importer("mediapipe").map(|i| i.layout()),
            Some("mediapipe478")
        );
        assert_eq!(
            importer("openseeface").map(|i| i.layout()),
            Some("openseeface68")
        );
        assert!(importer("kinect").is_none());
    }

    #[test]
    fn a_missing_file_is_an_error_naming_it_for_every_tracker() {
        let dir = std::env::temp_dir().join("mimic-importer-test-missing");
        for i in IMPORTERS {
            let path = dir.join(format!("no-such-{}.file", i.name()));
            let e = i
                .import(&path, &ImportOptions::default())
                .expect_err("a missing file");
            assert!(
                e.to_string().contains(&path.display().to_string()),
                "{}: {e}",
                i.name()
            );
        }
    }
}
