//! `mimic replay --weights W.csv`, behind the frame loop's seam ([`WeightsCsv`]): the per-frame
//! weights of the rig's morph targets, as mimic's CSV (`frame,t_us,status,label,<targets>`) or
//! as a Live Link Face take ([`TakeWriter`]: the app's header order and `Timecode`, the rig's
//! weights read back as ARKit curves through the name map's inverse, head yaw, pitch and roll
//! from the head rotation).

use crate::livelink::{BLENDSHAPES, CURVE_NAMES, CURVES, HEAD_YAW, head_angles};
use crate::namemap::{Inverse, NameMap};
use crate::take::TakeWriter;
use mimic_types::{FrameSink, SinkError, SinkFrame, SinkReport, WeightMap};
use serde_json::json;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The layout of a weights CSV.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeightsLayout {
    /// `frame,t_us,status,label` and one column per morph target of the rig.
    Mimic,
    /// A Live Link Face CSV take (`Timecode`, `BlendShapeCount`, the 61 curves), read back
    /// through the name map.
    LiveLink,
}

enum Writer {
    Mimic(BufWriter<File>),
    LiveLink {
        w: TakeWriter<BufWriter<File>>,
        map: NameMap,
        inverse: Inverse,
        curves: Box<[f32; CURVES]>,
    },
}

/// A weights CSV being written (module docs).
pub struct WeightsCsv {
    path: PathBuf,
    writer: Writer,
    /// The ARKit curves the rig has no morph target for (Live Link layout; written 0).
    lacking: Vec<&'static str>,
    rows: usize,
}

impl WeightsCsv {
    /// Creates `path` for the rig's targets `names` in `layout`; the Live Link layout reads them
    /// back as ARKit curves through the inverse of the name map at `namemap`.
    pub fn create(
        path: &Path,
        layout: WeightsLayout,
        names: &[String],
        namemap: &Path,
    ) -> Result<Self, SinkError> {
        let io = |e| SinkError::new(path, e);
        let mut file = File::create(path).map(BufWriter::new).map_err(io)?;
        let mut lacking = Vec::new();
        let writer = match layout {
            WeightsLayout::Mimic => {
                write!(file, "frame,t_us,status,label").map_err(io)?;
                for name in names {
                    write!(file, ",{name}").map_err(io)?;
                }
                writeln!(file).map_err(io)?;
                Writer::Mimic(file)
            }
            WeightsLayout::LiveLink => {
                let map = NameMap::load(namemap).map_err(|e| SinkError::new(namemap, e))?;
                let rig = WeightMap::new(names);
                let mut probe = vec![0.0f32; names.len()];
                let find = |t: &str| {
                    rig.apply([(t, 1.0)], &mut probe);
                    probe.iter().position(|w| *w > 0.0)
                };
                let inverse = map.inverse(&CURVE_NAMES[..BLENDSHAPES], find);
                lacking = (0..BLENDSHAPES)
                    .filter(|&c| !inverse.found(c))
                    .map(|c| CURVE_NAMES[c])
                    .collect();
                Writer::LiveLink {
                    w: TakeWriter::new(file).map_err(io)?,
                    map,
                    inverse,
                    curves: Box::new([0.0; CURVES]),
                }
            }
        };
        Ok(Self {
            path: path.to_path_buf(),
            writer,
            lacking,
            rows: 0,
        })
    }

    /// The ARKit curves the rig cannot give (Live Link layout), written as 0.
    pub fn lacking(&self) -> &[&'static str] {
        &self.lacking
    }

    /// The line naming the [`WeightsCsv::lacking`] curves of the CSV at `path`, if any.
    pub fn lacking_line(&self, path: &std::path::Path) -> Option<String> {
        (!self.lacking.is_empty()).then(|| {
            format!(
                "{}: {} of the 52 curves have no morph target in the rig (written 0): {}",
                path.display(),
                self.lacking.len(),
                self.lacking.join(", ")
            )
        })
    }

    fn row(&mut self, f: &SinkFrame<'_>, weights: &[f32]) -> std::io::Result<()> {
        match &mut self.writer {
            Writer::Mimic(w) => {
                let label = f.label.map(|l| l.to_string()).unwrap_or_default();
                write!(
                    w,
                    "{},{},{},{label}",
                    f.index,
                    f.view.timestamp_us,
                    f.view.status.code()
                )?;
                for x in weights {
                    write!(w, ",{x:.4}")?;
                }
                writeln!(w)
            }
            Writer::LiveLink {
                w,
                map,
                inverse,
                curves,
            } => {
                inverse.apply(map, weights, &mut curves[..BLENDSHAPES]);
                curves[HEAD_YAW..HEAD_YAW + 3].copy_from_slice(&head_angles(f.view.pose.rotation));
                w.write_row(f.view.timestamp_us, Some(curves))
            }
        }
    }
}

impl FrameSink for WeightsCsv {
    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<(), SinkError> {
        // A frame without weights (free-form mode) has no row: the sink is for morph targets.
        let Some(weights) = f.weights else {
            return Ok(());
        };
        self.row(f, weights)
            .map_err(|e| SinkError::new(&self.path, e))?;
        self.rows += 1;
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<SinkReport, SinkError> {
        let path = self.path;
        let file = match self.writer {
            Writer::Mimic(w) => w,
            Writer::LiveLink { w, .. } => w.finish().map_err(|e| SinkError::new(&path, e))?,
        };
        file.into_inner()
            .map_err(|e| SinkError::new(&path, e.into_error()))?;
        Ok(SinkReport {
            kind: "weights",
            bytes: std::fs::metadata(&path).map_or(0, |m| m.len()),
            path,
            frames: self.rows,
            detail: json!({ "lacking": self.lacking }),
        })
    }
}
