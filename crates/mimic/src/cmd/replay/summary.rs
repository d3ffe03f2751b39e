//! What `mimic replay` says at the end: the summary `mimic_retarget::summary` builds from the
//! loop's report, printed plain, with `--detail` or as `--json` (its terms in `--help`).

use super::Args;
use mimic_capture::ReadStats;
use mimic_retarget::summary::{ReadFigures, ReplaySummary};
use mimic_retarget::{LoopReport, SourceToTarget, Stats};
use mimic_types::{Rig, SolverSettings};
use std::time::Duration;

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
    run: Run,
    mut report: LoopReport,
) -> anyhow::Result<()> {
    let summary = ReplaySummary {
        recording: &args.recording,
        layout: run.layout,
        rig: rig.name.clone(),
        solver: run.solver,
        basis_time: run.basis_time,
        moving_vertices: run.moving_vertices,
        read: ReadFigures {
            accepted: run.read.accepted,
            rejected: run.read.rejected.total(),
            rejected_by_reason: serde_json::to_value(&run.read.rejected)?,
            invalid_points: run.read.invalid_points,
        },
        stats: run.stats,
        source_to_target: run.source_to_target,
        wall_s: run.wall_s,
        out: args.out.as_deref(),
    };
    if args.json {
        let json = summary.json(&mut report)?;
        println!("{}", serde_json::to_string_pretty(&json)?);
    } else {
        print!("{}", summary.text(&mut report, args.detail));
    }
    Ok(())
}
