//! `mimic morph`: a rig's morph targets to the morph data file and back (docs/morph-format.md).

use crate::cmd::setup::{load_rig_with_targets, write_obj_frame};
use anyhow::{Context, bail};
use clap::Subcommand;
use mimic_assets::{MORPH_FILE_DECIMALS, compare_deltas, load_morph_file, save_morph_file};
use mimic_retarget::{BlendshapeFitter, BlendshapeSettings, WeightMap};
use serde_json::json;
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
        } => {
            let (rig, targets) = load_rig_with_targets(&rig, configs.as_deref())?;
            if targets.is_empty() {
                bail!("rig `{}` has no morph targets", rig.name);
            }
            let comment = format!(
                "rig {}, units {}, {} targets: {}",
                rig.name,
                rig.units,
                targets.len(),
                targets
                    .iter()
                    .map(|t| t.name.as_str())
                    .collect::<Vec<_>>()
                    .join(" ")
            );
            save_morph_file(&output, &comment, &targets)?;
            println!(
                "wrote {} targets x {} vertices of rig {} to {}",
                targets.len(),
                rig.mesh.vertex_count(),
                rig.name,
                output.display()
            );
            Ok(())
        }
        MorphCommand::Import {
            file,
            rig,
            configs,
            json,
        } => {
            let read = load_morph_file(&file)?;
            let (rig, targets) = load_rig_with_targets(&rig, configs.as_deref())?;
            let n = rig.mesh.vertex_count();
            if let Some(t) = read.iter().find(|t| t.vertex_count() != n) {
                bail!(
                    "{}: {} vertices per target, rig `{}` has {n}",
                    file.display(),
                    t.vertex_count(),
                    rig.name
                );
            }
            let mut rows = Vec::new();
            let mut all_ok = read.len() == targets.len();
            for t in &read {
                let Some(own) = targets.iter().find(|o| o.name == t.name) else {
                    all_ok = false;
                    rows.push(json!({"target": t.name, "in_rig": false}));
                    continue;
                };
                let (dp, okp) = compare_deltas(&own.position_deltas, &t.position_deltas);
                let (dn, okn) = compare_deltas(&own.normal_deltas, &t.normal_deltas);
                all_ok &= okp && okn;
                rows.push(json!({
                    "target": t.name,
                    "in_rig": true,
                    "max_position_difference": dp,
                    "max_normal_difference": dn,
                    "within_printed_precision": okp && okn,
                }));
            }
            let report = json!({
                "file": file.display().to_string(),
                "rig": rig.name,
                "targets_in_file": read.len(),
                "targets_in_rig": targets.len(),
                "vertices": n,
                "decimals": MORPH_FILE_DECIMALS,
                "targets": rows,
                "round_trip_ok": all_ok,
            });
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                println!(
                    "{}: {} targets x {n} vertices; rig {} has {} targets",
                    file.display(),
                    read.len(),
                    rig.name,
                    targets.len()
                );
                for r in &rows {
                    println!(
                        "  {:<16} max |position diff| {:>10.3e}   max |normal diff| {:>10.3e}",
                        r["target"].as_str().unwrap_or(""),
                        r["max_position_difference"].as_f64().unwrap_or(f64::NAN),
                        r["max_normal_difference"].as_f64().unwrap_or(f64::NAN)
                    );
                }
            }
            if !all_ok {
                bail!(
                    "{}: does not match rig `{}`'s targets to {MORPH_FILE_DECIMALS} decimals",
                    file.display(),
                    rig.name
                );
            }
            if !json {
                println!("round trip ok: every value within the printed precision");
            }
            Ok(())
        }
    }
}

/// `mimic morph apply`: meshes from a CSV of named weights.
fn apply(
    weights: &Path,
    rig: &str,
    configs: Option<&Path>,
    out: &Path,
    every: usize,
) -> anyhow::Result<()> {
    let (rig, targets) = load_rig_with_targets(rig, configs)?;
    let fitter = BlendshapeFitter::new(&rig, &targets, &BlendshapeSettings::default())
        .with_context(|| format!("blendshapes of rig `{}`", rig.name))?;
    let map = WeightMap::new(fitter.names());
    let csv = mimic_capture::named_csv::read_named_csv(weights)?;
    let header: Vec<&str> = csv.header.iter().map(String::as_str).collect();
    // Columns that drive at least one target (checked one by one against the map).
    let mut probe = vec![0f32; fitter.target_count()];
    let used: Vec<usize> = (0..header.len())
        .filter(|&c| map.apply([(header[c], 1.0)], &mut probe) == 0)
        .collect();
    if used.is_empty() {
        bail!(
            "{}: no column names a target of rig `{}` ({})",
            weights.display(),
            rig.name,
            fitter.names().join(", ")
        );
    }
    std::fs::create_dir_all(out).with_context(|| out.display().to_string())?;
    let mut w = vec![0f32; fitter.target_count()];
    let mut pairs: Vec<(&str, f32)> = Vec::with_capacity(used.len());
    let mut positions = rig.mesh.positions.clone();
    let (mut frames, mut written) = (0usize, 0usize);
    for row in &csv.rows {
        pairs.clear();
        for &c in &used {
            let field = row.field(c);
            let v: f32 = field.parse().with_context(|| {
                format!(
                    "{}:{}: column `{}`: `{field}` is not a number",
                    weights.display(),
                    row.line,
                    header[c]
                )
            })?;
            pairs.push((header[c], v));
        }
        map.apply(pairs.iter().copied(), &mut w);
        if frames.is_multiple_of(every.max(1)) {
            fitter.evaluate(&w, &mut positions, &mut []);
            let header = format!("mimic morph apply onto rig {}: frame {frames}", rig.name);
            write_obj_frame(out, frames, &header, &positions, &rig.mesh.triangles)?;
            written += 1;
        }
        frames += 1;
    }
    let ignored: Vec<&str> = (0..header.len())
        .filter(|c| !used.contains(c))
        .map(|c| header[c])
        .collect();
    println!(
        "{}: {frames} frames, {written} written to {}; columns used: {}; ignored: {}",
        weights.display(),
        out.display(),
        used.iter()
            .map(|&c| header[c])
            .collect::<Vec<_>>()
            .join(" "),
        if ignored.is_empty() {
            "none".to_string()
        } else {
            ignored.join(" ")
        }
    );
    Ok(())
}
