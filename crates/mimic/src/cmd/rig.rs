//! `mimic rig`: make a rig for one's own head (`new`) and check one (`check`), docs/rigging.md.

use crate::cmd::{rig_check, rig_new};

/// Subcommands of `mimic rig`.
#[derive(clap::Subcommand, Debug)]
pub enum RigCommand {
    /// Make a rig from a face mesh and its iBUG-68 landmark vertices.
    New(rig_new::Args),
    /// Report what looks wrong in a rig (missing or shared FDPs, asymmetry, units).
    Check(rig_check::Args),
}

/// Runs `mimic rig`.
pub fn run(command: RigCommand) -> anyhow::Result<()> {
    match command {
        RigCommand::New(a) => rig_new::run(a),
        RigCommand::Check(a) => rig_check::run(a),
    }
}
