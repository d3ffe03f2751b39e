//! `mimic replay --weights W.csv`: the per-frame weights of the rig's morph targets, as mimic's
//! CSV (`frame,t_us,status,label,<targets>`) or, with `--weights-format livelink`, as a Live
//! Link Face take (`mimic_trackers::take::TakeWriter`: the app's header order and `Timecode`,
//! the rig's weights read back as ARKit curves through the name map's inverse, head yaw, pitch
//! and roll from the head rotation).

use anyhow::Context;
use glam::Quat;
use mimic_retarget::WeightMap;
use mimic_trackers::livelink::{BLENDSHAPES, CURVE_NAMES, CURVES, HEAD_YAW, head_angles};
use mimic_trackers::namemap::{Inverse, NameMap};
use mimic_trackers::take::TakeWriter;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The layout of `--weights`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeightsFormat {
    /// `frame,t_us,status,label` and one column per morph target of the rig.
    Mimic,
    /// A Live Link Face CSV take (`Timecode`, `BlendShapeCount`, the 61 curves).
    Livelink,
}

/// A weights CSV being written.
pub enum WeightsOut {
    /// mimic's own layout.
    Mimic {
        /// The file.
        path: PathBuf,
        /// Its writer.
        w: BufWriter<File>,
    },
    /// A Live Link Face take.
    LiveLink {
        /// The file.
        path: PathBuf,
        /// Its writer.
        w: TakeWriter<BufWriter<File>>,
        /// The name map whose inverse reads the curves back.
        map: NameMap,
        /// The 52 blendshape curves from the rig's weights.
        inverse: Inverse,
        /// This row's curves.
        curves: Box<[f32; CURVES]>,
    },
}

impl WeightsOut {
    /// Creates `path` for the rig's targets `names` (the Live Link layout reads them back as
    /// ARKit curves through the inverse of the name map at `namemap`); says which curves the
    /// rig cannot give (written 0).
    pub fn create(
        path: &Path,
        format: WeightsFormat,
        names: &[String],
        namemap: &Path,
    ) -> anyhow::Result<Self> {
        let file = BufWriter::new(File::create(path).with_context(|| path.display().to_string())?);
        match format {
            WeightsFormat::Mimic => {
                let mut w = file;
                write!(w, "frame,t_us,status,label")?;
                for name in names {
                    write!(w, ",{name}")?;
                }
                writeln!(w)?;
                Ok(Self::Mimic {
                    path: path.to_path_buf(),
                    w,
                })
            }
            WeightsFormat::Livelink => {
                let map = NameMap::load(namemap)?;
                let rig = WeightMap::new(names);
                let mut probe = vec![0.0f32; names.len()];
                let find = |t: &str| {
                    rig.apply([(t, 1.0)], &mut probe);
                    probe.iter().position(|w| *w > 0.0)
                };
                let inverse = map.inverse(&CURVE_NAMES[..BLENDSHAPES], find);
                let lacking: Vec<&str> = (0..BLENDSHAPES)
                    .filter(|&c| !inverse.found(c))
                    .map(|c| CURVE_NAMES[c])
                    .collect();
                if !lacking.is_empty() {
                    println!(
                        "{}: {} of the 52 curves have no morph target in the rig (written 0): {}",
                        path.display(),
                        lacking.len(),
                        lacking.join(", ")
                    );
                }
                let w = TakeWriter::new(file).with_context(|| path.display().to_string())?;
                Ok(Self::LiveLink {
                    path: path.to_path_buf(),
                    w,
                    map,
                    inverse,
                    curves: Box::new([0.0; CURVES]),
                })
            }
        }
    }

    /// Writes frame `index` at `t_us` (status code, label) with the rig's `weights` and the head
    /// `rotation`.
    pub fn row(
        &mut self,
        index: usize,
        t_us: i64,
        status: u32,
        label: Option<i64>,
        weights: &[f32],
        rotation: Quat,
    ) -> anyhow::Result<()> {
        match self {
            Self::Mimic { path, w } => {
                let label = label.map(|l| l.to_string()).unwrap_or_default();
                write!(w, "{index},{t_us},{status},{label}")
                    .with_context(|| path.display().to_string())?;
                for x in weights {
                    write!(w, ",{x:.4}")?;
                }
                writeln!(w)?;
            }
            Self::LiveLink {
                path,
                w,
                map,
                inverse,
                curves,
            } => {
                inverse.apply(map, weights, &mut curves[..BLENDSHAPES]);
                curves[HEAD_YAW..HEAD_YAW + 3].copy_from_slice(&head_angles(rotation));
                w.write_row(t_us, Some(curves))
                    .with_context(|| path.display().to_string())?;
            }
        }
        Ok(())
    }

    /// Flushes the file.
    pub fn finish(self) -> anyhow::Result<()> {
        match self {
            Self::Mimic { path, w } => {
                w.into_inner()
                    .map_err(|e| e.into_error())
                    .with_context(|| path.display().to_string())?;
            }
            Self::LiveLink { path, w, .. } => {
                w.finish()
                    .and_then(|b| b.into_inner().map_err(|e| e.into_error()))
                    .with_context(|| path.display().to_string())?;
            }
        }
        Ok(())
    }
}
