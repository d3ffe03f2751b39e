//! `mimic rig export R -o head.glb`: a rig as one GLB, without animation (an avatar rig's
//! avatar whole, with the targets on its face).

use crate::cmd::setup::{Mode, RigArgs, SolverChoice};
use anyhow::Context;
use mimic_assets::load_morph_targets;
use mimic_gltf::{control_morphs, export_rig_glb, rig_metres_per_unit, target_morphs};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `mimic rig export`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Rig: a name in configs/rigs/ or a path to a rig .toml.
    pub rig: String,
    /// Output GLB file.
    #[arg(short, long)]
    pub out: PathBuf,
    /// Morph targets: `freeform`, one per control and axis (the columns of the rig's basis; a
    /// weight is that control's displacement in metres), or `blendshapes`, the rig's own
    /// `[[morph_targets]]`.
    #[arg(long, value_enum, default_value = "freeform")]
    pub mode: Mode,
    /// Solver of the basis (default: the rig's).
    #[arg(long, value_enum)]
    pub solver: Option<SolverChoice>,
    /// Config directory (default: ./configs or $MIMIC_CONFIGS).
    #[arg(long)]
    pub configs: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `mimic rig export`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let rig_args = RigArgs {
        rig: args.rig.clone(),
        solver: args.solver,
        regions: None,
        radius: None,
        rbf_ridge: None,
        configs: args.configs.clone(),
    };
    let path = rig_args.rig_path();
    let rig = rig_args.load_rig()?;
    let scale = rig_metres_per_unit(&rig)?;
    let morphs = match args.mode {
        Mode::Freeform => {
            let (basis, _, _) = rig_args.build_basis(&rig)?;
            control_morphs(&basis, &rig)
        }
        Mode::Blendshapes => target_morphs(&load_morph_targets(&path, &rig)?, scale),
    };
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let started = Instant::now();
    let file = File::create(&args.out).with_context(|| args.out.display().to_string())?;
    let mut w = BufWriter::new(file);
    let summary = export_rig_glb(&path, &rig, &morphs, mimic_render::SKIN_ALBEDO, &mut w)
        .with_context(|| args.out.display().to_string())?;
    w.flush().with_context(|| args.out.display().to_string())?;
    let secs = started.elapsed().as_secs_f64();
    if args.json {
        let v = serde_json::json!({
            "rig": rig.name, "out": args.out.display().to_string(), "summary": summary, "write_s": secs,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "wrote {}: rig {} ({} vertices, {} morph targets, {} sparse), {:.1} MB in {secs:.2} s",
            args.out.display(),
            rig.name,
            summary.vertices,
            summary.targets,
            summary.sparse_targets,
            summary.bytes as f64 / 1e6
        );
    }
    Ok(())
}
