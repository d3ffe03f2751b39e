//! `mimic info`: validate a file and summarise it.

use std::path::PathBuf;

/// Arguments of `mimic info`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A recording (.jsonl), layout (configs/layouts/*.toml) or rig (configs/rigs/*.toml).
    pub file: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `mimic info`.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::bail!("{}: not yet supported", args.file.display())
}
