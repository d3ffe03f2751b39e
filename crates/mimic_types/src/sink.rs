//! The one seam for a frame loop's outputs ([`FrameSink`]): every output format (OBJ frames,
//! `frames.bin`, a GLB's keys, metrics and weights CSVs, a live viewer) takes each frame as a
//! [`SinkFrame`] and says what it wrote at the end ([`SinkReport`]). Each implementation lives
//! beside its format: a new output format is one implementation in one crate
//! (docs/ARCHITECTURE.md, "Where to change what").

use crate::FrameView;
use glam::Vec3;
use std::path::PathBuf;

/// One frame as a frame loop hands it to every output.
#[derive(Clone, Copy, Debug)]
pub struct SinkFrame<'a> {
    /// The frame's index in the take (0-based, every frame counted).
    pub index: usize,
    /// The recording's label of the frame, if any.
    pub label: Option<i64>,
    /// Time, status, head pose and the control displacements `d`.
    pub view: FrameView<'a>,
    /// Deformed vertex positions, target units (empty where the loop computes none).
    pub positions: &'a [Vec3],
    /// Vertex normals of `positions` (empty where the loop computes none).
    pub normals: &'a [Vec3],
    /// The morph-target weights of the frame (blend-shape mode, a weights take), in the rig's
    /// target order; `None` in free-form mode.
    pub weights: Option<&'a [f32]>,
    /// The head's translation from its neutral, target units, where the loop knows it (a
    /// tracked landmark frame with a source-to-target fit).
    pub head_translation: Option<Vec3>,
}

/// What one output wrote, said when the loop finishes.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SinkReport {
    /// The output's kind, e.g. `obj`, `bin`, `glb`, `metrics`, `weights`.
    pub kind: &'static str,
    /// The file or folder written.
    pub path: PathBuf,
    /// Frames (or keys) written.
    pub frames: usize,
    /// Bytes written.
    pub bytes: u64,
    /// Format-specific figures (a GLB's vertices, targets, keys, ...), JSON.
    pub detail: serde_json::Value,
}

impl SinkReport {
    /// The output of the deformed frames (OBJ, `frames.bin` or GLB) among `outputs`, if any.
    pub fn frames_output(outputs: &[SinkReport]) -> Option<&SinkReport> {
        outputs
            .iter()
            .find(|r| matches!(r.kind, "obj" | "bin" | "glb"))
    }

    /// A GLB output's report as a replay summary's JSON gives it (path, summary, skipped frames,
    /// time).
    pub fn glb_json(&self) -> serde_json::Value {
        serde_json::json!({
            "path": self.path.display().to_string(),
            "summary": self.detail["summary"],
            "skipped_frames": self.detail["skipped_frames"],
            "write_s": self.detail["write_s"],
        })
    }

    /// One line saying what the output wrote.
    pub fn wrote(&self) -> String {
        let mb = self.bytes as f64 / 1e6;
        let path = self.path.display();
        match self.kind {
            "glb" if self.detail["summary"].get("meshes").is_some() => {
                let s = &self.detail["summary"];
                let n = |k: &str| s[k].as_u64().unwrap_or(0);
                format!(
                    "wrote {path}: the avatar ({} meshes, {} vertices) with {} morph targets added ({} in all), {} keys over {:.2} s, head pose on {}, {mb:.1} MB in {:.2} s",
                    n("meshes"),
                    n("vertices"),
                    n("added_targets"),
                    n("targets"),
                    n("keys"),
                    s["duration_s"].as_f64().unwrap_or(0.0),
                    s["head_node"]
                        .as_str()
                        .map_or("no node".into(), |h| format!("`{h}`")),
                    self.detail["write_s"].as_f64().unwrap_or(0.0),
                )
            }
            "glb" => {
                let s = &self.detail["summary"];
                let n = |k: &str| s[k].as_u64().unwrap_or(0);
                let skipped = self.detail["skipped_frames"].as_u64().unwrap_or(0);
                format!(
                    "wrote {path}: {} keys over {:.2} s, {} vertices, {} morph targets ({} sparse), {mb:.1} MB in {:.2} s{}",
                    n("keys"),
                    s["duration_s"].as_f64().unwrap_or(0.0),
                    n("vertices"),
                    n("targets"),
                    n("sparse_targets"),
                    self.detail["write_s"].as_f64().unwrap_or(0.0),
                    if skipped > 0 {
                        format!("; {skipped} frames skipped (time not after the previous key)")
                    } else {
                        String::new()
                    }
                )
            }
            "obj" | "bin" => format!("wrote {} frames ({mb:.1} MB) to {path}", self.frames),
            kind => {
                let lacking = self
                    .detail
                    .get("lacking")
                    .and_then(serde_json::Value::as_array);
                format!(
                    "wrote {path}: {kind}, {} rows{}",
                    self.frames,
                    lacking
                        .filter(|l| !l.is_empty())
                        .map(|l| format!(" ({} ARKit curves the rig lacks, written 0)", l.len()))
                        .unwrap_or_default()
                )
            }
        }
    }
}

/// An output failed: the file it writes and what went wrong.
#[derive(Debug, thiserror::Error)]
#[error("{}: {source}", path.display())]
pub struct SinkError {
    /// The file or folder the output writes.
    pub path: PathBuf,
    /// The cause.
    #[source]
    pub source: Box<dyn std::error::Error + Send + Sync + 'static>,
}

impl SinkError {
    /// An error of the output writing `path`.
    pub fn new(
        path: impl Into<PathBuf>,
        source: impl Into<Box<dyn std::error::Error + Send + Sync + 'static>>,
    ) -> Self {
        Self {
            path: path.into(),
            source: source.into(),
        }
    }
}

/// An output of a frame loop: takes frames one by one, then finishes (flushes, writes what it
/// collected) and reports.
pub trait FrameSink {
    /// Whether the output needs the deformed mesh (`positions`, `normals`); a loop that can skip
    /// the mesh (a weights take) computes it only when some output says yes.
    fn wants_mesh(&self) -> bool {
        false
    }

    /// Takes one frame.
    fn frame(&mut self, frame: &SinkFrame<'_>) -> Result<(), SinkError>;

    /// Flushes and closes the output; says what it wrote.
    fn finish(self: Box<Self>) -> Result<SinkReport, SinkError>;
}
