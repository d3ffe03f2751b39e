//! `mimic rig check`: warnings about a rig, and a labelled picture of its neutral (logic in
//! `mimic_rig::check` and `mimic_rig::picture`; drawn by `mimic_view::stills::rig_picture`).

use crate::cmd::setup::load_rig_with_targets;
use mimic_assets::ConfigDirs;
use mimic_render::Renderer;
use std::path::PathBuf;

/// Arguments of `mimic rig check`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The rig: a name in configs/rigs/ or a path to a rig .toml.
    pub rig: String,
    /// Print the warnings as JSON.
    #[arg(long)]
    pub json: bool,
    /// Also write a picture of the neutral, regions coloured and every control labelled (PNG,
    /// headless wgpu).
    #[arg(short = 'o', long)]
    pub output: Option<PathBuf>,
    /// Picture size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1024x1024")]
    pub size: String,
}

/// Runs `mimic rig check`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.output.is_some() {
        // SAFETY: no thread has started yet.
        unsafe { mimic_render::headless::quiet_headless_vulkan() };
    }
    let path = ConfigDirs::locate(None).rig_path(&args.rig);
    let (rig, _) = load_rig_with_targets(&args.rig, None)?;
    let warnings = mimic_rig::check_rig(&rig);
    if let Some(out) = &args.output {
        let (width, height) =
            mimic_types::parse::parse_size(&args.size).map_err(anyhow::Error::msg)?;
        let renderer = Renderer::new(width, height)?;
        let image = mimic_view::stills::rig_picture(&renderer, &rig, (width, height))?;
        image.save_png(out)?;
    }
    if args.json {
        let report = serde_json::json!({
            "rig": path.display().to_string(),
            "controls": rig.controls.len(),
            "picture": args.output.as_ref().map(|p| p.display().to_string()),
            "warnings": warnings,
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{}",
        mimic_rig::check::check_line(&path, &rig, warnings.len())
    );
    for w in &warnings {
        println!("warning: {w}");
    }
    mimic_rig::lipcut::mouth_note(&rig)
        .into_iter()
        .for_each(|n| println!("{n}"));
    if let Some(out) = &args.output {
        println!("{}", out.display());
    }
    Ok(())
}
