//! `mimic rig`: tools for target rigs, one module per subcommand (`rig_*.rs`): make a rig for
//! one's own head (`new`, docs/rigging.md), check one (`check`), export one as a GLB (`export`,
//! docs/gltf.md).

use crate::cmd::{rig_check, rig_export, rig_new};

/// Subcommands of `mimic rig`.
#[derive(clap::Subcommand, Debug)]
pub enum RigCommand {
    /// Make a rig from a face mesh and its iBUG-68 landmark vertices.
    New(rig_new::Args),
    /// Report what looks wrong in a rig (missing or shared FDPs, asymmetry, units).
    Check(rig_check::Args),
    /// Write the rig alone (mesh, materials, morph targets) as one GLB, for engines that take
    /// weights live (docs/gltf.md).
    Export(rig_export::Args),
}

/// Runs `mimic rig ...`.
pub fn run(command: RigCommand) -> anyhow::Result<()> {
    match command {
        RigCommand::New(a) => rig_new::run(a),
        RigCommand::Check(a) => rig_check::run(a),
        RigCommand::Export(a) => rig_export::run(a),
    }
}
