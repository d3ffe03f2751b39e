//! `mimic morph`: a rig's morph targets to the morph data file and back (docs/morph-format.md;
//! the checks are `mimic_rig::morph`).

use crate::cmd::setup::load_rig_with_targets;
use anyhow::bail;
use clap::Subcommand;
use mimic_assets::{MORPH_FILE_DECIMALS, load_morph_file, save_morph_file};
use mimic_rig::morph::{MorphCheck, MorphImport, apply_csv};
use std::path::{Path, PathBuf};

/// Export and import of morph data files.
#[derive(Subcommand, Debug)]
pub enum MorphCommand {
    /// Write a rig's morph targets (position and normal deltas) as a morph data file.
    Export {
        /// Rig: a name in configs/rigs/ or a path to a rig .toml.
        #[arg(long, default_value = "ict-face")]
        rig: String,
        /// Output file.
        #[arg(short, long)]
        output: PathBuf,
        /// Config directory (default: ./configs or $MIMIC_CONFIGS).
        #[arg(long)]
        configs: Option<PathBuf>,
    },
    /// Read a morph data file and check it against a rig's own targets (round trip check).
    Import {
        /// The morph data file.
        file: PathBuf,
        /// Rig: a name in configs/rigs/ or a path to a rig .toml.
        #[arg(long, default_value = "ict-face")]
        rig: String,
        /// Config directory (default: ./configs or $MIMIC_CONFIGS).
        #[arg(long)]
        configs: Option<PathBuf>,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Turn named weights per frame (CSV, e.g. an ARKit capture app's export) into meshes.
    Apply {
        /// CSV with a header row of names (ARKit or the rig's target names; case does not
        /// matter) and one row per frame; columns that name no target are ignored.
        weights: PathBuf,
        /// Rig: a name in configs/rigs/ or a path to a rig .toml.
        #[arg(long, default_value = "ict-face")]
        rig: String,
        /// Config directory (default: ./configs or $MIMIC_CONFIGS).
        #[arg(long)]
        configs: Option<PathBuf>,
        /// Directory for one OBJ per frame (frame_000000.obj ...).
        #[arg(long)]
        out: PathBuf,
        /// Write only every N-th frame.
        #[arg(long, default_value_t = 1)]
        every: usize,
    },
}

/// Runs `mimic morph`.
pub fn run(command: MorphCommand) -> anyhow::Result<()> {
    match command {
        MorphCommand::Apply {
            weights,
            rig,
            configs,
            out,
            every,
        } => apply(&weights, &rig, configs.as_deref(), &out, every),
        MorphCommand::Export {
            rig,
            output,
            configs,
        } => export(&rig, configs.as_deref(), &output),
        MorphCommand::Import {
            file,
            rig,
            configs,
            json,
        } => import(&file, &rig, configs.as_deref(), json),
    }
}

/// `mimic morph export`: a rig's targets to a morph data file.
fn export(rig: &str, configs: Option<&Path>, output: &Path) -> anyhow::Result<()> {
    let (rig, targets) = load_rig_with_targets(rig, configs)?;
    if targets.is_empty() {
        bail!("rig `{}` has no morph targets", rig.name);
    }
    let names: Vec<&str> = targets.iter().map(|t| t.name.as_str()).collect();
    let comment = format!(
        "rig {}, units {}, {} targets: {}",
        rig.name,
        rig.units,
        targets.len(),
        names.join(" ")
    );
    save_morph_file(output, &comment, &targets)?;
    println!(
        "wrote {} targets x {} vertices of rig {} to {}",
        targets.len(),
        rig.mesh.vertex_count(),
        rig.name,
        output.display()
    );
    Ok(())
}

/// `mimic morph import`: a morph data file checked against a rig's own targets.
fn import(file: &Path, rig: &str, configs: Option<&Path>, as_json: bool) -> anyhow::Result<()> {
    let read = load_morph_file(file)?;
    let (rig, targets) = load_rig_with_targets(rig, configs)?;
    let n = rig.mesh.vertex_count();
    if let Some(t) = read.iter().find(|t| t.vertex_count() != n) {
        bail!(
            "{}: {} vertices per target, rig `{}` has {n}",
            file.display(),
            t.vertex_count(),
            rig.name
        );
    }
    let report = MorphImport {
        file,
        rig: &rig.name,
        targets_in_file: read.len(),
        targets_in_rig: targets.len(),
        vertices: n,
        check: MorphCheck::compare(&read, &targets),
    };
    if as_json {
        println!("{}", serde_json::to_string_pretty(&report.json()?)?);
    } else {
        print!("{}", report.text());
    }
    if !report.check.round_trip_ok {
        bail!(
            "{}: does not match rig `{}`'s targets to {MORPH_FILE_DECIMALS} decimals",
            file.display(),
            rig.name
        );
    }
    if !as_json {
        println!("round trip ok: every value within the printed precision");
    }
    Ok(())
}

/// `mimic morph apply`: meshes from a CSV of named weights (`mimic_rig::morph::apply_csv`).
fn apply(
    weights: &Path,
    rig: &str,
    configs: Option<&Path>,
    out: &Path,
    every: usize,
) -> anyhow::Result<()> {
    let (rig, targets) = load_rig_with_targets(rig, configs)?;
    let applied = apply_csv(&rig, &targets, weights, out, every)?;
    println!("{}", applied.summary(weights, out));
    Ok(())
}
