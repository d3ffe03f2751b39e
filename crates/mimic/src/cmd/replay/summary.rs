//! What `mimic replay` says at the end: a plain summary (what came in, what happened to it, what
//! was written), the per-stage timings with `--detail`, everything as JSON with `--json`. The
//! terms are explained in `mimic replay --help` ([`TERMS`]) and docs/replay.md.

use super::Args;
use mimic_capture::ReadStats;
use mimic_retarget::{LoopReport, SourceToTarget, Stats};
use mimic_types::{Rig, SinkReport, SolverSettings};
use serde_json::{Value, json};
use std::time::Duration;

/// The summary's terms, for `--help` (docs/replay.md says the same).
pub const TERMS: &str = "\
The summary's terms:
  frames in     frames read from the recording (lost-tracking frames included)
  rejected      lines that were not a valid frame (bad JSON, wrong point count, time not
                after the previous frame): skipped and counted, never fatal
  calibrating   the first tracked frames, averaged into the performer's neutral face; the
                rig shows its rest face meanwhile
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

/// What the replay measured besides the loop's report.
pub(super) struct Run {
    /// The retargeter's counters.
    pub stats: Stats,
    /// Vertices the rig's controls move.
    pub moving_vertices: usize,
    /// The source-to-target fit, once calibrated.
    pub source_to_target: Option<SourceToTarget>,
    /// What the reader accepted and rejected.
    pub read: ReadStats,
    /// The recording's layout.
    pub layout: String,
    /// The solver.
    pub solver: SolverSettings,
    /// Time to build the basis.
    pub basis_time: Duration,
    /// Wall time of the loop.
    pub wall_s: f64,
}

/// Prints the summary of a replay of `args.recording` onto `rig`.
pub(super) fn print(
    args: &Args,
    rig: &Rig,
    run: &Run,
    mut report: LoopReport,
) -> anyhow::Result<()> {
    let (stages, step) = report.samples.summary();
    let frames_out = frames_output(&report);
    let stats = &run.stats;
    let map = run.source_to_target;
    let gltf = frames_out.filter(|r| r.kind == "glb").map(glb_json);
    if args.json {
        let summary = json!({
            "recording": args.recording.display().to_string(),
            "layout": run.layout,
            "rig": rig.name,
            "solver": serde_json::to_value(run.solver)?,
            "basis_setup_ms": run.basis_time.as_secs_f64() * 1e3,
            "moving_vertices": run.moving_vertices,
            "frames_in": run.read.accepted,
            "rejected": run.read.rejected.total(),
            "rejected_by_reason": serde_json::to_value(&run.read.rejected)?,
            "invalid_points": run.read.invalid_points,
            "calibrating": stats.calibrating,
            "tracked": stats.tracked,
            "lost": stats.lost,
            "gated": stats.gated,
            "clamped": stats.clamped,
            "jumps": stats.jumps,
            "filled_controls": stats.filled_controls,
            "frames_with_non_finite_vertices": report.non_finite_frames,
            "source_to_target": map.map(|m| json!({"scale": m.scale, "mirrored": m.mirrored, "rms_residual": m.rms_residual})),
            "stages": stages,
            "step": step,
            "processing_frames_per_second": step.per_second(),
            "wall_s": run.wall_s,
            "frames_written": frames_out.map_or(0, |r| r.frames),
            "bytes_written": frames_out.map_or(0, |r| r.bytes),
            "out": args.out.as_ref().map(|p| p.display().to_string()),
            "blendshapes": report.weights,
            "gltf": gltf,
            "outputs": report.outputs,
        });
        println!("{}", serde_json::to_string_pretty(&summary)?);
        return Ok(());
    }
    println!(
        "{}: {} frames in ({} rejected, {} lost, {} gated, {} clamped, {} jumps, {} calibrating), {} controls filled; rig {} ({} moving vertices), basis {:.0} ms",
        args.recording.display(),
        run.read.accepted,
        run.read.rejected.total(),
        stats.lost,
        stats.gated,
        stats.clamped,
        stats.jumps,
        stats.calibrating,
        stats.filled_controls,
        rig.name,
        run.moving_vertices,
        run.basis_time.as_secs_f64() * 1e3
    );
    if args.detail {
        print!("{stages}");
        println!(
            "  {:<10} median {:>8.1} us   p99 {:>8.1} us   ({:.0} frames/s of processing)",
            "step",
            step.median_us,
            step.p99_us,
            step.per_second()
        );
    } else {
        println!(
            "  {:.0} frames/s of processing (median step {:.1} us; --detail for each stage)",
            step.per_second(),
            step.median_us
        );
    }
    if report.non_finite_frames > 0 {
        println!(
            "  {} frames had a vertex that is not a finite number",
            report.non_finite_frames
        );
    }
    for r in &report.outputs {
        println!("  {}", wrote(r));
    }
    Ok(())
}

/// The output of the deformed frames (OBJ, `frames.bin` or GLB), if one was asked for.
pub(super) fn frames_output(report: &LoopReport) -> Option<&SinkReport> {
    report
        .outputs
        .iter()
        .find(|r| matches!(r.kind, "obj" | "bin" | "glb"))
}

/// A GLB output's report as the summary's JSON gives it (path, summary, skipped frames, time).
pub(super) fn glb_json(r: &SinkReport) -> Value {
    json!({
        "path": r.path.display().to_string(),
        "summary": r.detail["summary"],
        "skipped_frames": r.detail["skipped_frames"],
        "write_s": r.detail["write_s"],
    })
}

/// One line saying what an output wrote.
pub(super) fn wrote(r: &SinkReport) -> String {
    let mb = r.bytes as f64 / 1e6;
    let path = r.path.display();
    match r.kind {
        "glb" => {
            let s = &r.detail["summary"];
            let n = |k: &str| s[k].as_u64().unwrap_or(0);
            let skipped = r.detail["skipped_frames"].as_u64().unwrap_or(0);
            format!(
                "wrote {path}: {} keys over {:.2} s, {} vertices, {} morph targets ({} sparse), {mb:.1} MB in {:.2} s{}",
                n("keys"),
                s["duration_s"].as_f64().unwrap_or(0.0),
                n("vertices"),
                n("targets"),
                n("sparse_targets"),
                r.detail["write_s"].as_f64().unwrap_or(0.0),
                if skipped > 0 {
                    format!("; {skipped} frames skipped (time not after the previous key)")
                } else {
                    String::new()
                }
            )
        }
        "obj" | "bin" => format!("wrote {} frames ({mb:.1} MB) to {path}", r.frames),
        kind => {
            let lacking = r.detail.get("lacking").and_then(Value::as_array);
            format!(
                "wrote {path}: {kind}, {} rows{}",
                r.frames,
                lacking
                    .filter(|l| !l.is_empty())
                    .map(|l| format!(" ({} ARKit curves the rig lacks, written 0)", l.len()))
                    .unwrap_or_default()
            )
        }
    }
}
