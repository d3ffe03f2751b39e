//! `mimic rig`: tools for target rigs (one module per subcommand, `rig_*.rs`).

use clap::Subcommand;

/// Subcommands of `mimic rig`.
#[derive(Subcommand, Debug)]
pub enum RigCommand {
    /// Write the rig alone (mesh, materials, morph targets) as one GLB, for engines that take
    /// weights live (docs/gltf.md).
    Export(super::rig_export::Args),
}

/// Runs `mimic rig ...`.
pub fn run(command: RigCommand) -> anyhow::Result<()> {
    match command {
        RigCommand::Export(a) => super::rig_export::run(a),
    }
}
