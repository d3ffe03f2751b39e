//! `mimic morph`: a rig's morph targets to the morph data file and back (docs/morph-format.md).

use anyhow::{Context, bail};
use clap::Subcommand;
use mimic_assets::{
    ConfigDirs, MORPH_FILE_DECIMALS, load_morph_file, load_morph_targets, load_rig, save_morph_file,
};
use mimic_retarget::{BlendshapeFitter, BlendshapeSettings, FrameOutput, FrameStatus, WeightMap};
use mimic_types::{MorphTarget, Rig};
use serde_json::json;
use std::fs::File;
use std::io::{BufWriter, Write};
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

/// A rig and its morph targets, loaded from a rig name or path.
pub fn load_rig_with_targets(
    rig: &str,
    configs: Option<&Path>,
) -> anyhow::Result<(Rig, Vec<MorphTarget>)> {
    let path = ConfigDirs::locate(configs).rig_path(rig);
    let rig = load_rig(&path)?;
    let targets = load_morph_targets(&path, &rig)?;
    Ok((rig, targets))
}

/// Largest difference a value may show after printing with [`MORPH_FILE_DECIMALS`] decimals and
/// parsing back to f32: half the last printed digit plus half an f32 ulp of the value.
fn round_trip_tolerance(v: f32) -> f32 {
    0.5 * 10f32.powi(-(MORPH_FILE_DECIMALS as i32)) + v.abs() * f32::EPSILON
}

/// Largest component difference between two delta lists, and whether all are within tolerance.
fn compare(a: &[glam::Vec3], b: &[glam::Vec3]) -> (f32, bool) {
    let mut max = 0f32;
    let mut ok = true;
    for (p, q) in a.iter().zip(b) {
        for (x, y) in p.to_array().into_iter().zip(q.to_array()) {
            let e = (x - y).abs();
            max = max.max(e);
            ok &= e <= round_trip_tolerance(x);
        }
    }
    (max, ok)
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
                let (dp, okp) = compare(&own.position_deltas, &t.position_deltas);
                let (dn, okn) = compare(&own.normal_deltas, &t.normal_deltas);
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

/// Output mode of the retarget pipeline.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Free-form deformation `P0 + B d` by the rig's solver.
    Freeform,
    /// Weights of the rig's morph targets fitted to `d`, mesh `P0 + sum w dP`.
    Blendshapes,
}

/// Command-line options of the blendshape mode (flattened into `mimic replay`).
#[derive(clap::Args, Debug, Clone)]
pub struct BlendshapeArgs {
    /// Free-form deformation, or blendshape weights of the rig's `[[morph_targets]]`.
    #[arg(long, value_enum, default_value = "freeform")]
    pub mode: Mode,
    /// Per-frame blendshape weights as CSV (frame, t_us, status, label, one column per target).
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// Ridge of the weight fit, relative to each target's squared control deltas (0.01: 1 % shrink).
    #[arg(long, default_value_t = BlendshapeSettings::default().ridge)]
    pub ridge: f64,
    /// Turn the One Euro smoothing of the weights off.
    #[arg(long)]
    pub no_weight_filter: bool,
}

/// The blendshape stage of a replay: fitter, weights CSV and running statistics.
pub struct Blend {
    fitter: BlendshapeFitter,
    csv: Option<(PathBuf, BufWriter<File>)>,
    sum: Vec<f64>,
    max: Vec<f32>,
    frames: usize,
    /// Nanoseconds of fit + blend per tracked frame.
    ns: Vec<u32>,
}

impl BlendshapeArgs {
    /// The blendshape stage for `rig` (loaded from `rig_path`), or `None` in free-form mode.
    pub fn blend(&self, rig_path: &Path, rig: &Rig) -> anyhow::Result<Option<Blend>> {
        if self.mode == Mode::Freeform {
            if self.weights.is_some() {
                bail!("--weights needs --mode blendshapes");
            }
            return Ok(None);
        }
        let targets = load_morph_targets(rig_path, rig)?;
        let settings = BlendshapeSettings {
            ridge: self.ridge,
            smoothing: if self.no_weight_filter {
                None
            } else {
                BlendshapeSettings::default().smoothing
            },
        };
        let fitter = BlendshapeFitter::new(rig, &targets, &settings)
            .with_context(|| format!("blendshapes of rig `{}`", rig.name))?;
        let csv = match &self.weights {
            Some(p) => {
                let mut w =
                    BufWriter::new(File::create(p).with_context(|| p.display().to_string())?);
                write!(w, "frame,t_us,status,label")?;
                for name in fitter.names() {
                    write!(w, ",{name}")?;
                }
                writeln!(w)?;
                Some((p.clone(), w))
            }
            None => None,
        };
        let k = fitter.target_count();
        Ok(Some(Blend {
            fitter,
            csv,
            sum: vec![0.0; k],
            max: vec![0.0; k],
            frames: 0,
            ns: Vec::new(),
        }))
    }
}

impl Blend {
    /// Replaces `out`'s mesh with the blend fitted to its displacements and writes the CSV row.
    pub fn frame(
        &mut self,
        index: usize,
        status_code: u32,
        label: Option<i64>,
        out: &mut FrameOutput,
    ) -> anyhow::Result<()> {
        let tracked = out.status == FrameStatus::Tracked;
        let started = std::time::Instant::now();
        let w = self.fitter.apply(out);
        if tracked {
            self.ns
                .push(u32::try_from(started.elapsed().as_nanos()).unwrap_or(u32::MAX));
            self.frames += 1;
            for ((s, m), x) in self.sum.iter_mut().zip(&mut self.max).zip(w) {
                *s += f64::from(*x);
                *m = m.max(*x);
            }
        }
        if let Some((path, csv)) = self.csv.as_mut() {
            let label = label.map(|l| l.to_string()).unwrap_or_default();
            write!(csv, "{index},{},{status_code},{label}", out.timestamp_us)
                .with_context(|| path.display().to_string())?;
            for x in w {
                write!(csv, ",{x:.4}")?;
            }
            writeln!(csv)?;
        }
        Ok(())
    }

    /// Flushes the CSV; returns a summary (per target: mean and max weight over tracked frames).
    pub fn finish(mut self) -> anyhow::Result<serde_json::Value> {
        if let Some((path, csv)) = self.csv {
            csv.into_inner()
                .map_err(|e| e.into_error())
                .with_context(|| path.display().to_string())?;
        }
        let n = self.frames.max(1) as f64;
        let (median_us, p99_us) = crate::cmd::replay::median_p99_us(&mut self.ns);
        Ok(json!({
            "fit_and_blend": {"median_us": median_us, "p99_us": p99_us},
            "ridge_per_target": self.fitter.ridges(),
            "targets": self.fitter.names().iter().zip(&self.sum).zip(&self.max).map(|((name, s), m)| {
                json!({"target": name, "mean_weight": s / n, "max_weight": m})
            }).collect::<Vec<_>>(),
        }))
    }
}

/// Blendshape "solver" for `mimic eval`: fits weights to a shape's control displacements (no
/// smoothing) and deforms the neutral with the rig's morph targets.
pub struct EvalBlend {
    targets: Vec<MorphTarget>,
    leave_one_out: bool,
    ridge: f64,
}

impl EvalBlend {
    /// Loads the rig's morph targets; with `leave_one_out`, a target identical to the measured
    /// shape is left out of that shape's fit (so a shape cannot be matched by itself).
    pub fn load(
        rig_path: &Path,
        rig: &Rig,
        leave_one_out: bool,
        ridge: f64,
    ) -> anyhow::Result<Self> {
        let targets = load_morph_targets(rig_path, rig)?;
        if targets.is_empty() {
            bail!("rig `{}` has no morph targets", rig.name);
        }
        Ok(Self {
            targets,
            leave_one_out,
            ridge,
        })
    }

    /// The fitter for `shape` (positions on the rig's topology).
    pub fn fitter(&self, rig: &Rig, shape: &[glam::Vec3]) -> anyhow::Result<BlendshapeFitter> {
        let is_shape = |t: &MorphTarget| {
            t.position_deltas
                .iter()
                .zip(shape.iter().zip(&rig.mesh.positions))
                .all(|(d, (s, p))| (*s - *p - *d).abs().max_element() <= 1e-6)
        };
        let used: Vec<MorphTarget> = self
            .targets
            .iter()
            .filter(|t| !(self.leave_one_out && is_shape(t)))
            .cloned()
            .collect();
        let settings = BlendshapeSettings {
            ridge: self.ridge,
            smoothing: None,
        };
        Ok(BlendshapeFitter::new(rig, &used, &settings)?)
    }

    /// `u = P(w) - P0` for the weights `fitter` fits to `d`; returns the weights by name.
    pub fn deform(
        fitter: &mut BlendshapeFitter,
        rest: &[glam::Vec3],
        d: &[glam::Vec3],
        u: &mut [glam::Vec3],
    ) -> Vec<(String, f32)> {
        let w = fitter.fit(d, 0).to_vec();
        fitter.evaluate(&w, u, &mut []);
        for (u, p) in u.iter_mut().zip(rest) {
            *u -= *p;
        }
        fitter.names().iter().cloned().zip(w).collect()
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
    let text = std::fs::read_to_string(weights).with_context(|| weights.display().to_string())?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .with_context(|| format!("{}: empty file", weights.display()))?
        .split(',')
        .map(str::trim)
        .collect();
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
    for (i, line) in lines.enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        pairs.clear();
        for &c in &used {
            let field = fields.get(c).copied().unwrap_or("");
            let v: f32 = field.parse().with_context(|| {
                format!(
                    "{}:{}: column `{}`: `{field}` is not a number",
                    weights.display(),
                    i + 2,
                    header[c]
                )
            })?;
            pairs.push((header[c], v));
        }
        map.apply(pairs.iter().copied(), &mut w);
        if frames.is_multiple_of(every.max(1)) {
            fitter.evaluate(&w, &mut positions, &mut []);
            let path = crate::cmd::replay::obj_frame_path(out, frames);
            let file = File::create(&path).with_context(|| path.display().to_string())?;
            let mut f = BufWriter::new(file);
            mimic_assets::write_obj(
                &mut f,
                &format!("mimic morph apply onto rig {}: frame {frames}", rig.name),
                &positions,
                None,
                &rig.mesh.triangles,
            )?;
            f.flush().with_context(|| path.display().to_string())?;
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
