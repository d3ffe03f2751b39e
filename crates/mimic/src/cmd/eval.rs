//! `mimic eval`: measure a solver against real expression meshes (the measure is
//! `mimic_retarget::quality`, docs/quality.md).

use crate::cmd::setup::{RigArgs, SolverChoice, SolverTuningArgs, parse_ranges, timed_basis};
use anyhow::{Context, bail};
use glam::Vec3;
use mimic_assets::{load_morph_targets, load_obj};
use mimic_retarget::quality::{
    MorphEval, ShapeError, control_displacements, error_csv, jitter, measure, median, noise_gain,
};
use mimic_types::Region;
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
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// Blendshapes: leave a shape's own morph target out of its fit.
    #[arg(long)]
    pub leave_one_out: bool,
    /// Blendshapes: ridge of the weight fit, relative to each target's squared control deltas.
    #[arg(long, default_value_t = mimic_retarget::BlendshapeSettings::default().ridge)]
    pub ridge: f64,
    /// Measure only these vertices (inclusive ranges such as `0-9408`, comma-separated); frozen
    /// vertices are always left out. Default: every non-frozen vertex.
    #[arg(long, value_parser = parse_vertices)]
    pub vertices: Option<Ranges>,
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

/// Inclusive vertex index ranges.
#[derive(Clone, Debug)]
pub struct Ranges(Vec<(u32, u32)>);

impl Ranges {
    fn contains(&self, i: usize) -> bool {
        self.0
            .iter()
            .any(|&(a, b)| (a as usize..=b as usize).contains(&i))
    }
}

/// Parses `0-9408,11248-14061` (a single index is a range of one; backwards is an error).
fn parse_vertices(text: &str) -> Result<Ranges, String> {
    parse_ranges(text, false).map(Ranges)
}

/// Runs `mimic eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut rig = args.rig.load_rig()?;
    let rig_path = args.rig.rig_path();
    let landmarks_path = args.landmarks.clone().or_else(|| {
        let p = rig_path.with_extension("landmarks.json");
        p.is_file().then_some(p)
    });
    let marks = match (&landmarks_path, args.controls.as_str()) {
        (Some(p), "ibug68") => Some(mimic_rig::load_landmarks(
            p,
            mimic_rig::Numbering::default(),
        )?),
        _ => None,
    };
    let registration = mimic_rig::register::apply_control_set(
        &mut rig,
        &args.controls,
        &args.rig.config_dirs().root,
        marks.as_ref(),
        &mimic_rig::register::RegisterSettings::default(),
    )
    .with_context(|| format!("--controls {}", args.controls))?;
    if let (Some(out), Some(reg)) = (&args.write_rig, &registration) {
        let same_dir = out
            .parent()
            .map(std::path::Path::to_path_buf)
            .unwrap_or_default()
            == rig_path
                .parent()
                .map(std::path::Path::to_path_buf)
                .unwrap_or_default();
        if !same_dir {
            bail!(
                "--write-rig {}: write it beside {} (its mesh path is relative)",
                out.display(),
                rig_path.display()
            );
        }
        let text = mimic_types::limits::read_capped(&rig_path, &mimic_types::limits::RIG_FILE)
            .with_context(|| rig_path.display().to_string())?;
        let written = mimic_rig::register::replace_controls_toml(&text, &rig.controls, reg);
        std::fs::write(out, written).with_context(|| out.display().to_string())?;
        mimic_assets::load_rig(out)
            .with_context(|| format!("{}: the written rig does not load", out.display()))?;
        eprintln!("wrote {} ({} controls)", out.display(), rig.controls.len());
    }
    args.tuning.apply_to_rig(&mut rig);
    let settings = args.tuning.solver_settings(&args.rig, &rig)?;
    let (basis, took) = timed_basis(&rig, &settings)?;
    let setup_ms = took.as_secs_f64() * 1e3;
    let noise_gain = noise_gain(&basis);
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
    let mut weights = serde_json::Map::new();
    let mut shapes: Vec<(PathBuf, ShapeError)> = Vec::new();
    for path in &args.shapes {
        let mesh = load_obj(path)?;
        if mesh.vertex_count() != rig.mesh.vertex_count() || mesh.triangles != rig.mesh.triangles {
            bail!(
                "{}: not the rig mesh's topology ({} vertices, {} triangles; the rig mesh has {} and {})",
                path.display(),
                mesh.vertex_count(),
                mesh.triangles.len(),
                rig.mesh.vertex_count(),
                rig.mesh.triangles.len()
            );
        }
        let measured: Vec<bool> = (0..rig.mesh.vertex_count())
            .map(|i| !rig.frozen[i] && args.vertices.as_ref().is_none_or(|r| r.contains(i)))
            .collect();
        let d = control_displacements(&rig, &mesh.positions);
        let mut u = vec![Vec3::ZERO; rig.mesh.vertex_count()];
        match &blend {
            Some(b) => {
                let mut fitter = b.fitter(&rig, &mesh.positions)?;
                let w = MorphEval::deform(&mut fitter, &d, &mut u);
                weights.insert(path.display().to_string(), json!(w));
            }
            None => basis.apply(&d, &mut u),
        }
        if let Some(dir) = &args.dump {
            let stem = path
                .file_stem()
                .map_or_else(|| "shape".into(), |s| s.to_string_lossy().into_owned());
            let out = dir.join(format!("{stem}.errors.csv"));
            let csv = error_csv(&rig, &u, &mesh.positions, &measured);
            std::fs::write(&out, csv).with_context(|| out.display().to_string())?;
        }
        shapes.push((path.clone(), measure(&rig, &u, &mesh.positions, &measured)));
    }
    let mut ratios: Vec<f64> = shapes.iter().map(|s| s.1.all.ratio).collect();
    let median = median(&mut ratios);
    let report = json!({
        "rig": args.rig.rig,
        "controls": args.controls,
        "control_count": rig.controls.len(),
        "units": rig.units,
        "settings": serde_json::to_value(settings)?,
        "band": rig.regions.band,
        "vertices": args.vertices.as_ref().map(|r| r.0.iter().map(|(a, b)| json!([a, b])).collect::<Vec<_>>()),
        "setup_ms": setup_ms,
        "noise_gain": noise_gain,
        "blendshape_weights": blend.is_some().then_some(&weights),
        "median_ratio": median,
        "max_ratio": ratios.last().copied().unwrap_or(f64::NAN),
        "shapes": shapes.iter().map(|(p, e)| json!({
            "shape": p.display().to_string(),
            "all": e.all,
            "regions": Region::ALL.iter().zip(&e.regions).map(|(r, s)| (r.name().to_string(), json!(s))).collect::<serde_json::Map<_, _>>(),
        })).collect::<Vec<_>>(),
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "rig {} ({}), controls {} ({}), solver {:?}, regions {}, top split {:?}, kernel {:?}, affine {}, distance {:?}, weights {:?}, constraint weight {}, shell {:?}, shell blend {:?}, band {}; setup {:.0} ms",
        args.rig.rig,
        rig.units,
        args.controls,
        rig.controls.len(),
        settings.kind,
        settings.regions,
        settings.top_split,
        settings.kernel,
        settings.affine,
        settings.distance,
        settings.weights,
        settings.constraint_weight,
        settings.shell,
        settings.shell_blend,
        rig.regions.band,
        setup_ms
    );
    println!(
        "{:<28} {:<7} {:>7} {:>9} {:>9} {:>9} {:>9} {:>6}",
        "shape", "region", "verts", "mean_err", "p95_err", "max_err", "mean_disp", "ratio"
    );
    for (path, e) in &shapes {
        let name = path.file_name().map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        let rows = std::iter::once(("all", &e.all))
            .chain(Region::ALL.iter().map(|r| r.name()).zip(e.regions.iter()));
        for (region, s) in rows {
            println!(
                "{:<28} {:<7} {:>7} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>6.3}",
                name,
                region,
                s.vertices,
                s.mean_error,
                s.p95_error,
                s.max_error,
                s.mean_displacement,
                s.ratio
            );
        }
    }
    for (shape, w) in &weights {
        println!("weights for {shape}: {w}");
    }
    println!(
        "median ratio {median:.3}, max ratio {:.3}, noise gain {noise_gain:.2}",
        ratios.last().copied().unwrap_or(f64::NAN)
    );
    Ok(())
}

/// `mimic eval --jitter REC...`: the jitter of each replayed recording on the rig.
fn run_jitter(
    args: &Args,
    rig: &mimic_types::Rig,
    basis: mimic_solve::Basis,
    noise_gain: f64,
) -> anyhow::Result<()> {
    let basis = std::sync::Arc::new(basis);
    let measured: Vec<bool> = rig.frozen.iter().map(|f| !f).collect();
    let mut rows = Vec::new();
    for path in &args.jitter {
        let rec = mimic_capture::read_recording(path, None)?;
        let layout = args
            .rig
            .config_dirs()
            .load_layout_named(&rec.header.layout)?;
        let settings = mimic_retarget::RetargetSettings {
            filter: if args.no_filter {
                None
            } else {
                mimic_retarget::RetargetSettings::default().filter
            },
            ..Default::default()
        };
        let mut r = mimic_retarget::Retargeter::new(rig, &layout, basis.clone(), settings)
            .with_context(|| format!("{}: rig `{}`", path.display(), rig.name))?;
        let j = jitter(&mut r, rec.frames.iter().map(|f| &f.frame), &measured);
        rows.push((path.clone(), j, r.stats()));
    }
    if args.json {
        let report = json!({
            "rig": args.rig.rig,
            "controls": args.controls,
            "control_count": rig.controls.len(),
            "filter": !args.no_filter,
            "noise_gain": noise_gain,
            "recordings": rows.iter().map(|(p, j, s)| json!({
                "recording": p.display().to_string(), "jitter": j, "stats": s,
            })).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "rig {} ({}), controls {} ({}), filter {}, noise gain {noise_gain:.2}",
        args.rig.rig,
        rig.units,
        args.controls,
        rig.controls.len(),
        if args.no_filter { "off" } else { "on" }
    );
    println!(
        "{:<40} {:>7} {:>12} {:>12} {:>12} {:>6}",
        "recording", "triples", "median_d2", "p95_d2", "median_d1", "gated"
    );
    for (p, j, s) in &rows {
        println!(
            "{:<40} {:>7} {:>12.5} {:>12.5} {:>12.5} {:>6}",
            p.file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
            j.triples,
            j.median_second_difference,
            j.p95_second_difference,
            j.median_first_difference,
            s.gated
        );
    }
    Ok(())
}
