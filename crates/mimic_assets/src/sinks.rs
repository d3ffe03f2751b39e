//! The frame loop's file outputs ([`FrameSink`]) that are plain files: OBJ frames in a folder
//! ([`ObjSink`]), one `frames.bin` ([`BinSink`], docs/frames-format.md), and the per-frame
//! metrics and control CSVs of `mimic replay --metrics` / `--controls` ([`MetricsCsv`],
//! [`ControlsCsv`]).

use crate::{AssetError, FramesWriter, ObjFrames};
use glam::Vec3;
use mimic_types::frame_metrics::{max_vertex_motion, region_motion};
use mimic_types::{FrameSink, Mesh, Region, Rig, SinkError, SinkFrame, SinkReport};
use serde_json::json;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Path of the OBJ of frame `index` in `dir` (`frame_000000.obj` ...).
pub fn obj_frame_path(dir: &Path, index: usize) -> PathBuf {
    dir.join(format!("frame_{index:06}.obj"))
}

/// Writes frame `index` as an OBJ in `dir` (at [`obj_frame_path`]) with a one-line `header`
/// comment.
pub fn write_obj_frame(
    dir: &Path,
    index: usize,
    header: &str,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
) -> Result<(), AssetError> {
    let path = obj_frame_path(dir, index);
    let io = |cause| AssetError::Io {
        path: path.clone(),
        cause,
    };
    let mut w = File::create(&path).map(BufWriter::new).map_err(io)?;
    crate::write_obj(&mut w, header, positions, None, triangles).map_err(io)?;
    w.flush().map_err(io)
}

/// Creates `path` for writing, buffered; the error names the file.
fn create(path: &Path) -> Result<BufWriter<File>, SinkError> {
    File::create(path)
        .map(BufWriter::new)
        .map_err(|e| SinkError::new(path, e))
}

/// Flushes a buffered file.
fn close(path: &Path, w: BufWriter<File>) -> Result<(), SinkError> {
    w.into_inner()
        .map(drop)
        .map_err(|e| SinkError::new(path, e.into_error()))
}

/// Deformed frames as OBJ files in one folder (`frame_000000.obj` ..., the rig's materials as
/// one `.mtl` beside them): [`ObjFrames`] behind the frame loop's seam.
pub struct ObjSink {
    dir: PathBuf,
    frames: ObjFrames,
    mesh: Mesh,
    /// The first words of each file's header comment, e.g. `mimic replay onto rig ict-face`.
    header: String,
}

impl ObjSink {
    /// OBJ frames of `rig` (read from `rig_path`, for its materials) in `dir`, created if
    /// missing; each file's comment starts with `header`.
    pub fn create(
        dir: &Path,
        rig_path: &Path,
        rig: &Rig,
        header: &str,
    ) -> Result<Self, AssetError> {
        std::fs::create_dir_all(dir).map_err(|cause| AssetError::Io {
            path: dir.to_path_buf(),
            cause,
        })?;
        let frames = ObjFrames::new(dir, rig_path, &rig.name, rig.mesh.triangles.len())?;
        Ok(Self {
            dir: dir.to_path_buf(),
            frames,
            mesh: rig.mesh.clone(),
            header: header.to_string(),
        })
    }
}

impl FrameSink for ObjSink {
    fn wants_mesh(&self) -> bool {
        true
    }

    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<(), SinkError> {
        let header = format!(
            "{}: frame {}, t = {} us",
            self.header, f.index, f.view.timestamp_us
        );
        let path = obj_frame_path(&self.dir, f.index);
        self.frames
            .write(&path, &header, f.positions, f.normals, &self.mesh)
            .map_err(|e| SinkError::new(&path, e))
    }

    fn finish(self: Box<Self>) -> Result<SinkReport, SinkError> {
        Ok(SinkReport {
            kind: "obj",
            path: self.dir,
            frames: self.frames.written(),
            bytes: self.frames.bytes(),
            detail: json!(null),
        })
    }
}

/// Deformed frames in one `frames.bin` (docs/frames-format.md), with normals.
pub struct BinSink {
    path: PathBuf,
    writer: FramesWriter<BufWriter<File>>,
    written: usize,
}

impl BinSink {
    /// `frames.bin` in `dir` (created if missing) for frames of `mesh`.
    pub fn create(dir: &Path, mesh: &Mesh) -> Result<Self, SinkError> {
        std::fs::create_dir_all(dir).map_err(|e| SinkError::new(dir, e))?;
        let path = dir.join("frames.bin");
        let file = create(&path)?;
        let writer = FramesWriter::new(file, mesh.vertex_count(), &mesh.triangles, true)
            .map_err(|e| SinkError::new(&path, e))?;
        Ok(Self {
            path,
            writer,
            written: 0,
        })
    }
}

impl FrameSink for BinSink {
    fn wants_mesh(&self) -> bool {
        true
    }

    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<(), SinkError> {
        self.writer
            .write_frame(
                f.view.timestamp_us,
                u32::from(f.view.status.code()),
                &f.view.pose,
                f.positions,
                f.normals,
            )
            .map_err(|e| SinkError::new(&self.path, e))?;
        self.written += 1;
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<SinkReport, SinkError> {
        let file = self
            .writer
            .finish()
            .map_err(|e| SinkError::new(&self.path, e))?;
        close(&self.path, file)?;
        let bytes = std::fs::metadata(&self.path).map_or(0, |m| m.len());
        Ok(SinkReport {
            kind: "bin",
            path: self.path,
            frames: self.written,
            bytes,
            detail: json!(null),
        })
    }
}

/// `mimic replay --metrics`: per frame the time, status, label, the mean control motion per
/// region (top, middle, bottom) and the largest vertex motion from rest.
pub struct MetricsCsv {
    path: PathBuf,
    w: BufWriter<File>,
    regions: Vec<Region>,
    rest: Vec<Vec3>,
    rows: usize,
}

impl MetricsCsv {
    /// The CSV at `path` for frames of `rig`.
    pub fn create(path: &Path, rig: &Rig) -> Result<Self, SinkError> {
        let mut w = create(path)?;
        writeln!(w, "frame,t_us,status,label,top,middle,bottom,max_vertex")
            .map_err(|e| SinkError::new(path, e))?;
        Ok(Self {
            path: path.to_path_buf(),
            w,
            regions: rig.controls.iter().map(|c| c.region).collect(),
            rest: rig.mesh.positions.clone(),
            rows: 0,
        })
    }
}

impl FrameSink for MetricsCsv {
    fn wants_mesh(&self) -> bool {
        true
    }

    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<(), SinkError> {
        let [top, middle, bottom] = region_motion(f.view.displacements, &self.regions);
        let max_vertex = max_vertex_motion(f.positions, &self.rest);
        let label = f.label.map(|l| l.to_string()).unwrap_or_default();
        writeln!(
            self.w,
            "{},{},{},{label},{top:.6},{middle:.6},{bottom:.6},{max_vertex:.6}",
            f.index,
            f.view.timestamp_us,
            f.view.status.code(),
        )
        .map_err(|e| SinkError::new(&self.path, e))?;
        self.rows += 1;
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<SinkReport, SinkError> {
        close(&self.path, self.w)?;
        Ok(SinkReport {
            kind: "metrics",
            bytes: std::fs::metadata(&self.path).map_or(0, |m| m.len()),
            path: self.path,
            frames: self.rows,
            detail: json!(null),
        })
    }
}

/// `mimic replay --controls`: per frame the time, status and each control's displacement
/// (target units), one `x, y, z` column triple per control.
pub struct ControlsCsv {
    path: PathBuf,
    w: BufWriter<File>,
    rows: usize,
    /// The rig's control count: the entries of `d` after them (rigid parts) are not controls.
    controls: usize,
}

impl ControlsCsv {
    /// The CSV at `path` for frames of `rig`'s controls.
    pub fn create(path: &Path, rig: &Rig) -> Result<Self, SinkError> {
        let mut w = create(path)?;
        let io = |e| SinkError::new(path, e);
        write!(w, "frame,t_us,status").map_err(io)?;
        for c in &rig.controls {
            write!(w, ",{0}_x,{0}_y,{0}_z", c.fdp).map_err(io)?;
        }
        writeln!(w).map_err(io)?;
        Ok(Self {
            path: path.to_path_buf(),
            w,
            rows: 0,
            controls: rig.controls.len(),
        })
    }

    fn row(&mut self, f: &SinkFrame<'_>) -> std::io::Result<()> {
        write!(
            self.w,
            "{},{},{}",
            f.index,
            f.view.timestamp_us,
            f.view.status.code()
        )?;
        for d in f.view.displacements.iter().take(self.controls) {
            write!(self.w, ",{:.5},{:.5},{:.5}", d.x, d.y, d.z)?;
        }
        writeln!(self.w)
    }
}

impl FrameSink for ControlsCsv {
    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<(), SinkError> {
        self.row(f).map_err(|e| SinkError::new(&self.path, e))?;
        self.rows += 1;
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<SinkReport, SinkError> {
        close(&self.path, self.w)?;
        Ok(SinkReport {
            kind: "controls",
            bytes: std::fs::metadata(&self.path).map_or(0, |m| m.len()),
            path: self.path,
            frames: self.rows,
            detail: json!(null),
        })
    }
}
