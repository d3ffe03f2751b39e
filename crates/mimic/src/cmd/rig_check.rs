//! `mimic rig check`: warnings about a rig (logic in `mimic_rig::check`).

use crate::cmd::setup::load_rig_with_targets;
use mimic_assets::ConfigDirs;

/// Arguments of `mimic rig check`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The rig: a name in configs/rigs/ or a path to a rig .toml.
    pub rig: String,
    /// Print the warnings as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `mimic rig check`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let path = ConfigDirs::locate(None).rig_path(&args.rig);
    let (rig, _) = load_rig_with_targets(&args.rig, None)?;
    let warnings = mimic_rig::check_rig(&rig);
    if args.json {
        let report = serde_json::json!({
            "rig": path.display().to_string(),
            "controls": rig.controls.len(),
            "warnings": warnings,
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{}: {} controls, {} warning(s)",
        path.display(),
        rig.controls.len(),
        warnings.len()
    );
    for w in &warnings {
        println!("warning: {w}");
    }
    Ok(())
}
