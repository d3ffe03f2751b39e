//! What a replay says at the end, built from the frame loop's [`LoopReport`]: a plain summary
//! (what came in, what happened to it, what was written), the per-stage timings with `detail`,
//! everything as JSON. The terms are explained in [`TERMS`] (`mimic replay --help`) and
//! docs/replay.md.

use crate::{LoopReport, SourceToTarget, Stats};
use mimic_types::{SinkReport, SolverSettings};
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

/// The summary's terms, for `--help` (docs/replay.md says the same).
pub const TERMS: &str = "\
The summary's terms:
  frames in     frames read from the recording (lost-tracking frames included)
  rejected      lines that were not a valid frame (bad JSON, wrong point count, time not
                after the previous frame): skipped and counted, never fatal
  calibrating   the first tracked frames, averaged into the performer's neutral face; the
                rig shows its rest face meanwhile
  provisional   those frames when the layout ships a canonical neutral face (MediaPipe's):
                retargeted against it instead (tracked; its identity is part of the
                expression), then eased into the calibrated output (docs/replay.md)
  lost          frames the tracker marked lost (or with too few stable points): the last head
                pose is held and the expression eases back to neutral
  gated         tracked frames no face can make (e.g. a fit failure's sudden head turn), held
                like lost frames (docs/gate.md)
  clamped       tracked frames in which some control moved faster than a face can; that
                control's speed was limited
  jumps         tracked frames where some control moved more than the jump limit since the
                previous frame (reported only)
  controls filled  controls with no valid tracked point in a frame, held at their last value
                (summed over frames)
  moving vertices  vertices the rig's controls can move (the rest are frozen)";

/// What the recording's reader accepted and rejected, as the summary gives it.
#[derive(Clone, Debug)]
pub struct ReadFigures {
    /// Frames accepted (lost-tracking frames included).
    pub accepted: usize,
    /// Lines rejected.
    pub rejected: usize,
    /// Rejected lines by reason, JSON.
    pub rejected_by_reason: Value,
    /// Invalid points summed over accepted frames.
    pub invalid_points: usize,
}

/// Everything a landmark replay's summary says besides the loop's report.
#[derive(Clone, Debug)]
pub struct ReplaySummary<'a> {
    /// The recording replayed.
    pub recording: &'a Path,
    /// The recording's layout.
    pub layout: String,
    /// The rig's name.
    pub rig: String,
    /// The solver.
    pub solver: SolverSettings,
    /// Time to build the basis.
    pub basis_time: Duration,
    /// Vertices the rig's controls move.
    pub moving_vertices: usize,
    /// What the reader accepted and rejected.
    pub read: ReadFigures,
    /// The retargeter's counters.
    pub stats: Stats,
    /// The source-to-target fit, once calibrated.
    pub source_to_target: Option<SourceToTarget>,
    /// Wall time of the loop.
    pub wall_s: f64,
    /// The `--out` path, if one was given.
    pub out: Option<&'a Path>,
}

impl ReplaySummary<'_> {
    /// Every figure as JSON (sorts the report's step samples).
    pub fn json(&self, report: &mut LoopReport) -> Result<Value, serde_json::Error> {
        let (stages, step) = report.samples.summary();
        let frames_out = report.frames_output();
        let (stats, map) = (&self.stats, self.source_to_target);
        Ok(json!({
            "recording": self.recording.display().to_string(),
            "layout": self.layout,
            "rig": self.rig,
            "solver": serde_json::to_value(self.solver)?,
            "basis_setup_ms": self.basis_time.as_secs_f64() * 1e3,
            "moving_vertices": self.moving_vertices,
            "frames_in": self.read.accepted,
            "rejected": self.read.rejected,
            "rejected_by_reason": self.read.rejected_by_reason,
            "invalid_points": self.read.invalid_points,
            "calibrating": stats.calibrating,
            "provisional": stats.provisional,
            "tracked": stats.tracked,
            "lost": stats.lost,
            "gated": stats.gated,
            "clamped": stats.clamped,
            "jumps": stats.jumps,
            "repaired": stats.repaired,
            "filled_controls": stats.filled_controls,
            "frames_with_non_finite_vertices": report.non_finite_frames,
            "source_to_target": map.map(|m| json!({"scale": m.scale, "mirrored": m.mirrored, "rms_residual": m.rms_residual})),
            "stages": stages,
            "step": step,
            "processing_frames_per_second": step.per_second(),
            "wall_s": self.wall_s,
            "frames_written": frames_out.map_or(0, |r| r.frames),
            "bytes_written": frames_out.map_or(0, |r| r.bytes),
            "out": self.out.map(|p| p.display().to_string()),
            "blendshapes": report.weights,
            "gltf": frames_out.filter(|r| r.kind == "glb").map(SinkReport::glb_json),
            "outputs": report.outputs,
        }))
    }

    /// The plain summary, each line ended by a newline; `detail` adds each stage's timings
    /// (sorts the report's step samples).
    pub fn text(&self, report: &mut LoopReport, detail: bool) -> String {
        let (stages, step) = report.samples.summary();
        let stats = &self.stats;
        let mut out = format!(
            "{}: {} frames in ({} rejected, {} lost, {} gated, {} clamped, {} jumps, {} calibrating{}), {} controls filled; rig {} ({} moving vertices), basis {:.0} ms\n",
            self.recording.display(),
            self.read.accepted,
            self.read.rejected,
            stats.lost,
            stats.gated,
            stats.clamped,
            stats.jumps,
            stats.calibrating,
            match stats.provisional {
                0 => String::new(),
                n => format!(", {n} provisional"),
            },
            stats.filled_controls,
            self.rig,
            self.moving_vertices,
            self.basis_time.as_secs_f64() * 1e3
        );
        // Writing to a String cannot fail.
        let _ = if detail {
            write!(out, "{stages}").and_then(|()| {
                writeln!(
                    out,
                    "  {:<10} median {:>8.1} us   p99 {:>8.1} us   ({:.0} frames/s of processing)",
                    "step",
                    step.median_us,
                    step.p99_us,
                    step.per_second()
                )
            })
        } else {
            writeln!(
                out,
                "  {:.0} frames/s of processing (median step {:.1} us; --detail for each stage)",
                step.per_second(),
                step.median_us
            )
        };
        if report.non_finite_frames > 0 {
            let _ = writeln!(
                out,
                "  {} frames had a vertex that is not a finite number",
                report.non_finite_frames
            );
        }
        for r in &report.outputs {
            let _ = writeln!(out, "  {}", r.wrote());
        }
        out
    }
}
