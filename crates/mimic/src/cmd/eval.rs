//! `mimic eval`: measure a solver against real expression meshes (the measure is
//! `mimic_retarget::quality`, docs/quality.md).

use crate::cmd::setup::{RigArgs, SolverChoice, SolverTuningArgs, timed_basis};
use anyhow::{Context, bail};
use mimic_assets::{load_morph_targets, load_obj};
use mimic_retarget::quality::{
    JitterReport, MorphEval, RigUnder, ShapeError, ShapesReport, check_topology, error_csv,
    evaluate, jitter, jitter_settings, noise_gain,
};
use mimic_rig::register::control_landmarks;
use mimic_solve::Basis;
use mimic_types::Rig;
use mimic_types::parse::{VertexRanges, parse_vertex_ranges};
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `mimic eval`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(flatten)]
    pub tuning: SolverTuningArgs,
    /// Expression meshes (OBJ) with the rig mesh's topology.
    #[arg(long, num_args = 1.., required_unless_present = "jitter")]
    pub shapes: Vec<PathBuf>,
    /// Instead of shapes: replay these recordings through the pipeline (default settings) and
    /// report the frame-to-frame jitter of the deformed non-frozen vertices (docs/quality.md).
    #[arg(long, num_args = 1.., conflicts_with = "shapes")]
    pub jitter: Vec<PathBuf>,
    /// With `--jitter`: the One Euro filter off.
    #[arg(long, requires = "jitter")]
    pub no_filter: bool,
    /// Print the report as JSON (every figure, the solver's settings, per region).
    #[arg(long)]
    pub json: bool,
    /// Also print the solver's settings, each region's errors and morph-target weights.
    #[arg(long)]
    pub detail: bool,
    /// Blendshapes: leave a shape's own morph target out of its fit.
    #[arg(long)]
    pub leave_one_out: bool,
    /// Blendshapes: ridge of the weight fit, relative to each target's squared control deltas.
    #[arg(long, default_value_t = mimic_types::BlendshapeFit::RIDGE_ONLY.ridge)]
    pub ridge: f64,
    /// Measure only these vertices (inclusive ranges such as `0-9408`, comma-separated); frozen
    /// vertices are always left out. Default: every non-frozen vertex.
    #[arg(long, value_parser = parse_vertex_ranges)]
    pub vertices: Option<VertexRanges>,
    /// Also write `<shape>.errors.csv` per shape into this folder (vertex, rest position, error,
    /// true displacement), for plotting where the error is.
    #[arg(long)]
    pub dump: Option<PathBuf>,
    /// Which controls drive the rig: `mpeg4` (the rig's own 38 FDPs) or a layout's own points
    /// registered onto the rig from its template: `kinect121`, `ibug68`, `mediapipe478`
    /// (docs/rigging.md, "Dense control sets").
    #[arg(long, default_value = "mpeg4")]
    pub controls: String,
    /// The rig's iBUG-68 landmark vertices (for `--controls ibug68`); default: the rig file's
    /// `<name>.landmarks.json` beside it, if there is one.
    #[arg(long)]
    pub landmarks: Option<PathBuf>,
    /// Write the rig with the chosen control set to this file (in the rig file's own folder,
    /// so its relative paths hold).
    #[arg(long)]
    pub write_rig: Option<PathBuf>,
}

/// Puts the `--controls` set on the rig (registered from its template), and writes the rig with
/// it under `--write-rig`.
fn apply_controls(args: &Args, rig: &mut Rig) -> anyhow::Result<()> {
    let rig_path = args.rig.rig_path();
    let marks = control_landmarks(&rig_path, &args.controls, args.landmarks.as_deref())?;
    let registration = mimic_rig::register::apply_control_set(
        rig,
        &args.controls,
        &args.rig.config_dirs().root,
        marks.as_ref(),
        &mimic_rig::register::RegisterSettings::default(),
    )
    .with_context(|| format!("--controls {}", args.controls))?;
    if let (Some(out), Some(reg)) = (&args.write_rig, &registration) {
        mimic_rig::write_rig_with_controls(&rig_path, out, rig, reg).context("--write-rig")?;
        eprintln!("wrote {} ({} controls)", out.display(), rig.controls.len());
    }
    Ok(())
}

/// The shapes' errors (by path) and, with morph targets, their fitted weights.
type Scores = (
    Vec<(String, ShapeError)>,
    serde_json::Map<String, serde_json::Value>,
);

/// Evaluates each `--shapes` mesh (writing its `--dump` CSV).
fn score_shapes(
    args: &Args,
    rig: &Rig,
    basis: &Basis,
    blend: Option<&MorphEval>,
) -> anyhow::Result<Scores> {
    let (mut shapes, mut weights) = (Vec::new(), serde_json::Map::new());
    let measured: Vec<bool> = (0..rig.mesh.vertex_count())
        .map(|i| !rig.frozen[i] && args.vertices.as_ref().is_none_or(|r| r.contains(i)))
        .collect();
    for path in &args.shapes {
        let mesh = load_obj(path)?;
        check_topology(path, &mesh, rig)?;
        let e = evaluate(rig, basis, blend, &mesh.positions, &measured)?;
        if let Some(w) = &e.weights {
            weights.insert(path.display().to_string(), json!(w));
        }
        if let Some(dir) = &args.dump {
            let stem = path
                .file_stem()
                .map_or_else(|| "shape".into(), |s| s.to_string_lossy().into_owned());
            let out = dir.join(format!("{stem}.errors.csv"));
            let csv = error_csv(rig, &e.displacements, &mesh.positions, &measured);
            std::fs::write(&out, csv).with_context(|| out.display().to_string())?;
        }
        shapes.push((path.display().to_string(), e.error));
    }
    Ok((shapes, weights))
}

/// Runs `mimic eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut rig = args.rig.load_rig()?;
    apply_controls(&args, &mut rig)?;
    args.tuning.apply_to_rig(&mut rig);
    let settings = args.tuning.solver_settings(&args.rig, &rig)?;
    let (basis, took) = timed_basis(&rig, &settings)?;
    let noise_gain = noise_gain(&basis, rig.controls.len());
    if !args.jitter.is_empty() {
        return run_jitter(&args, &rig, basis, noise_gain);
    }
    let blend = if args.rig.solver == Some(SolverChoice::Blendshapes) {
        let targets = load_morph_targets(&args.rig.rig_path(), &rig)?;
        if targets.is_empty() {
            bail!("rig `{}` has no morph targets", rig.name);
        }
        Some(MorphEval::new(targets, args.leave_one_out, args.ridge))
    } else {
        None
    };
    let (shapes, weights) = score_shapes(&args, &rig, &basis, blend.as_ref())?;
    let report = ShapesReport {
        under: RigUnder {
            name: &args.rig.rig,
            controls: &args.controls,
            rig: &rig,
        },
        settings,
        vertices: args.vertices.as_ref().map(|r| r.0.as_slice()),
        setup_ms: took.as_secs_f64() * 1e3,
        noise_gain,
        blend: blend.is_some(),
        weights: &weights,
        shapes: &shapes,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report.json()?)?);
    } else {
        print!("{}", report.text(args.detail)?);
    }
    Ok(())
}

/// `mimic eval --jitter REC...`: the jitter of each replayed recording on the rig.
fn run_jitter(args: &Args, rig: &Rig, basis: Basis, noise_gain: f64) -> anyhow::Result<()> {
    let basis = std::sync::Arc::new(basis);
    let measured: Vec<bool> = rig.frozen.iter().map(|f| !f).collect();
    let mut rows = Vec::new();
    for path in &args.jitter {
        let rec = mimic_capture::read_recording(path, None)?;
        let layout = args
            .rig
            .config_dirs()
            .load_layout_named(&rec.header.layout)?;
        let settings = jitter_settings(!args.no_filter);
        let mut r = mimic_retarget::Retargeter::new(rig, &layout, basis.clone(), settings)
            .with_context(|| format!("{}: rig `{}`", path.display(), rig.name))?;
        let j = jitter(&mut r, rec.frames.iter().map(|f| &f.frame), &measured);
        rows.push((path.clone(), j, r.stats()));
    }
    let report = JitterReport {
        under: RigUnder {
            name: &args.rig.rig,
            controls: &args.controls,
            rig,
        },
        filter: !args.no_filter,
        noise_gain,
        rows: &rows,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report.json())?);
    } else {
        print!("{}", report.text());
    }
    Ok(())
}
