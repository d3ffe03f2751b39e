//! `mimic rig check`: warnings about a rig, and a labelled picture of its neutral (logic in
//! `mimic_rig::check` and `mimic_rig::picture`; drawn by `mimic_render`).

use crate::cmd::setup::{load_rig_with_targets, parse_size};
use anyhow::Context;
use mimic_assets::ConfigDirs;
use mimic_render::{Camera, Deform, Renderer, View};
use mimic_rig::picture::{Canvas, annotate, controlled_triangles, free_bounds, region_colors};
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
        crate::cmd::setup::quiet_headless_vulkan();
    }
    let path = ConfigDirs::locate(None).rig_path(&args.rig);
    let (rig, _) = load_rig_with_targets(&args.rig, None)?;
    let warnings = mimic_rig::check_rig(&rig);
    if let Some(out) = &args.output {
        let (width, height) = parse_size(&args.size)?;
        let renderer = Renderer::new(width, height)?;
        let gpu = renderer.upload_rig(&rig.mesh.positions, &controlled_triangles(&rig), None)?;
        renderer.set_albedo(&gpu, &region_colors(&rig))?;
        let (lo, hi) = free_bounds(&rig).context("the rig's mesh is empty")?;
        let view = View::lit(Camera::framing(lo, hi, 0.0, 0.0));
        let mut image = renderer.render(&gpu, Deform::Rest, &view)?;
        let view_proj = view.camera.view_proj(width as f32 / height as f32);
        annotate(
            &mut Canvas {
                width,
                height,
                rgba: &mut image.rgba,
            },
            &rig,
            view_proj,
        );
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
        "{}: {} controls, {} warning(s)",
        path.display(),
        rig.controls.len(),
        warnings.len()
    );
    for w in &warnings {
        println!("warning: {w}");
    }
    if let Some(out) = &args.output {
        println!("{}", out.display());
    }
    Ok(())
}
