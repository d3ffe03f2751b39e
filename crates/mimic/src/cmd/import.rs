//! `mimic import`: other trackers' files to v1 recordings.

use clap::Subcommand;

/// Importers of other trackers' files.
#[derive(Subcommand, Debug)]
pub enum ImportCommand {}

/// Runs an import subcommand.
pub fn run(c: ImportCommand) -> anyhow::Result<()> {
    match c {}
}
