//! What `mimic replay TAKE.csv` says at the end ([`TakeSummary`]): the take's rows, the frames
//! put onto the rig, the names the rig lacks and what each output wrote, plain or as JSON.

use crate::take::{Take, TakeWeights};
use mimic_types::SinkReport;
use serde_json::{Value, json};
use std::path::Path;

/// A take replayed onto a rig's morph targets.
#[derive(Clone, Debug)]
pub struct TakeSummary<'a> {
    /// The take file.
    pub path: &'a Path,
    /// The rig's name.
    pub rig: &'a str,
    /// The take.
    pub take: &'a Take,
    /// Its weights through the name map.
    pub weights: &'a TakeWeights,
    /// The rig's morph targets.
    pub targets: &'a [String],
    /// The take's names the rig lacks.
    pub lacking: &'a [&'a str],
    /// Wall time of the replay.
    pub wall_s: f64,
    /// Frames put onto the rig.
    pub frames: usize,
    /// Each output's report, the frames' output (OBJ, `frames.bin` or GLB) among them.
    pub outputs: &'a [SinkReport],
}

impl TakeSummary<'_> {
    /// Every figure as JSON.
    pub fn json(&self) -> Value {
        let out = match SinkReport::frames_output(self.outputs) {
            None => json!(null),
            Some(r) if r.kind == "glb" => r.glb_json(),
            Some(r) => json!({"frames": r.frames, "bytes": r.bytes}),
        };
        json!({
            "take": self.path.display().to_string(),
            "rig": self.rig,
            "rows": self.take.rows.len(),
            "untracked_rows": self.weights.untracked,
            "frames": self.frames,
            "duration_s": self.take.duration_s(),
            "timecode_rate": self.take.timecode_rate,
            "targets": self.targets,
            "names_lacking": self.lacking,
            "wall_s": self.wall_s,
            "out": out,
            "outputs": self.outputs,
        })
    }

    /// The summary in words, each line ended by a newline.
    pub fn text(&self) -> String {
        let mut out = format!(
            "take {}: {} rows ({} with no face), {:.3} s at {} fps timecode; {} frames onto rig {} ({} morph targets) in {:.3} s\n",
            self.path.display(),
            self.take.rows.len(),
            self.weights.untracked,
            self.take.duration_s(),
            self.take.timecode_rate,
            self.frames,
            self.rig,
            self.targets.len(),
            self.wall_s
        );
        for r in self.outputs {
            out.push_str(&format!("  {}\n", r.wrote()));
        }
        out
    }
}
