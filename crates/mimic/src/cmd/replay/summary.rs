//! What `mimic replay` says at the end: the summary `mimic_retarget::summary` builds from the
//! loop's report, printed plain, with `--detail` or as `--json` (its terms in `--help`).

use super::Args;
use mimic_capture::ReadStats;
use mimic_retarget::LoopReport;
use mimic_retarget::summary::{ReadFigures, ReplaySummary};

/// The reader's counts as the summary gives them.
pub(super) fn read_figures(read: &ReadStats) -> anyhow::Result<ReadFigures> {
    Ok(ReadFigures {
        accepted: read.accepted,
        rejected: read.rejected.total(),
        rejected_by_reason: serde_json::to_value(&read.rejected)?,
        invalid_points: read.invalid_points,
    })
}

/// Prints `summary` with the loop's `report`, as `args` ask (`--json`, `--detail`).
pub(super) fn print(
    args: &Args,
    summary: &ReplaySummary<'_>,
    mut report: LoopReport,
) -> anyhow::Result<()> {
    if args.json {
        let json = summary.json(&mut report)?;
        println!("{}", serde_json::to_string_pretty(&json)?);
    } else {
        print!("{}", summary.text(&mut report, args.detail));
    }
    Ok(())
}
