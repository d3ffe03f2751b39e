//! `mimic eval`: measure a solver against real expression meshes.
//!
//! For each expression shape (same topology as the rig mesh), the rig's controls are driven with
//! the shape's own displacements at the control vertices, the neutral is deformed with `u = B d`,
//! and the result is compared with the true shape at every non-frozen vertex, per region
//! (by `RegionBands::region_at` of the rest height). `ratio = mean_error / mean_displacement`:
//! 0 is perfect, 1 is no better than leaving the neutral unchanged.

use anyhow::{Context, bail};
use glam::Vec3;
use mimic_assets::{load_obj, load_rig};
use mimic_solve::build_basis;
use mimic_types::{
    LaplacianWeights, RbfDistance, RbfKernel, Region, Rig, SolverKind, SolverSettings, TopSplit,
};
use serde_json::{Value, json};
use std::path::PathBuf;
use std::time::Instant;

/// Which solver, on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum SolverArg {
    /// Radial basis functions.
    Rbf,
    /// Laplacian surface editing.
    Laplacian,
    /// Weights of the rig's morph targets fitted to the controls (`P0 + sum w dP`).
    Blendshapes,
}

/// A switch, on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum OnOff {
    /// Enabled.
    On,
    /// Disabled.
    Off,
}

/// RBF kernel family, on the command line (the radius comes from `--radius` or the rig).
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum KernelArg {
    /// `exp(-r / radius)`.
    Exponential,
    /// `exp(-(r / radius)^2)`.
    Gaussian,
    /// Matern 3/2, `(1 + sqrt(3) r / radius) exp(-sqrt(3) r / radius)`.
    Matern32,
    /// `r^2 log r` (turns the affine term on).
    ThinPlate,
}

/// RBF distance, on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum DistanceArg {
    /// Straight-line distance.
    Euclidean,
    /// Shortest path along the mesh edges.
    Geodesic,
}

/// Laplacian edge weights, on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum WeightsArg {
    /// Uniform.
    Uniform,
    /// Mean-value.
    MeanValue,
    /// Cotangent.
    Cotangent,
}

/// Arguments of `mimic eval`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Rig file (configs/rigs/*.toml).
    #[arg(long)]
    pub rig: PathBuf,
    /// Expression meshes (OBJ) with the rig mesh's topology.
    #[arg(long, num_args = 1.., required = true)]
    pub shapes: Vec<PathBuf>,
    /// Solver (default: the rig's).
    #[arg(long, value_enum)]
    pub solver: Option<SolverArg>,
    /// Solve regions separately and blend them (default: the rig's).
    #[arg(long, value_enum)]
    pub regions: Option<OnOff>,
    /// RBF kernel radius in rig units (default: the rig's).
    #[arg(long)]
    pub radius: Option<f64>,
    /// RBF kernel family (default: the rig's).
    #[arg(long, value_enum)]
    pub kernel: Option<KernelArg>,
    /// RBF affine term (default: the rig's).
    #[arg(long, value_enum)]
    pub affine: Option<OnOff>,
    /// RBF distance (default: the rig's).
    #[arg(long, value_enum)]
    pub distance: Option<DistanceArg>,
    /// Laplacian edge weights (default: the rig's).
    #[arg(long, value_enum)]
    pub weights: Option<WeightsArg>,
    /// Laplacian constraint weight (default: the rig's).
    #[arg(long)]
    pub constraint_weight: Option<f64>,
    /// Region blend band width in rig units (default: the rig's).
    #[arg(long)]
    pub band: Option<f32>,
    /// Split the top region into lids and brows at this height (rig units), or `off` (default:
    /// the rig's).
    #[arg(long, value_parser = parse_split)]
    pub top_split: Option<Split>,
    /// Blend band of the top split in rig units (default: the rig's, or 1).
    #[arg(long)]
    pub top_split_band: Option<f32>,
    /// Kernel of the upper (brow) half of the top split as `family:radius` (`exponential`,
    /// `gaussian`, `matern32`; e.g. `matern32:2`), or `off` for the solver's (default: the rig's).
    #[arg(long, value_parser = parse_kernel)]
    pub upper_kernel: Option<KernelChoice>,
    /// Kernel of the lower (lid) half of the top split, as `--upper-kernel` (default: the rig's).
    #[arg(long, value_parser = parse_kernel)]
    pub lower_kernel: Option<KernelChoice>,
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
    #[arg(long, value_parser = parse_ranges)]
    pub vertices: Option<Ranges>,
    /// Also write `<shape>.errors.csv` per shape into this folder (vertex, rest position, error,
    /// true displacement), for plotting where the error is.
    #[arg(long)]
    pub dump: Option<PathBuf>,
}

/// A number, or `off`.
#[derive(Clone, Copy, Debug)]
pub struct Split(Option<f64>);

/// Parses a finite number or `off`.
fn parse_split(text: &str) -> Result<Split, String> {
    if text == "off" {
        return Ok(Split(None));
    }
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(Split(Some(v))),
        _ => Err(format!("`{text}`: expected a number or `off`")),
    }
}

/// A kernel with its radius, or `off`.
#[derive(Clone, Copy, Debug)]
pub struct KernelChoice(Option<RbfKernel>);

/// Parses `family:radius` (`exponential`, `gaussian`, `matern32`) or `off`.
fn parse_kernel(text: &str) -> Result<KernelChoice, String> {
    if text == "off" {
        return Ok(KernelChoice(None));
    }
    let (family, radius) = text
        .split_once(':')
        .ok_or_else(|| format!("`{text}`: expected family:radius (e.g. matern32:2) or `off`"))?;
    let radius: f64 = radius
        .parse()
        .map_err(|e| format!("`{text}`: radius: {e}"))?;
    let kernel = match family {
        "exponential" => RbfKernel::Exponential { radius },
        "gaussian" => RbfKernel::Gaussian { radius },
        "matern32" => RbfKernel::Matern32 { radius },
        _ => return Err(format!("`{text}`: unknown kernel family `{family}`")),
    };
    Ok(KernelChoice(Some(kernel)))
}

/// Inclusive vertex index ranges.
#[derive(Clone, Debug)]
pub struct Ranges(Vec<(usize, usize)>);

impl Ranges {
    fn contains(&self, i: usize) -> bool {
        self.0.iter().any(|&(a, b)| (a..=b).contains(&i))
    }
}

/// Parses `0-9408,11248-14061` (a single index is a range of one).
fn parse_ranges(text: &str) -> Result<Ranges, String> {
    text.split(',')
        .map(|part| {
            let (a, b) = part.split_once('-').unwrap_or((part, part));
            let parse = |s: &str| {
                s.trim()
                    .parse::<usize>()
                    .map_err(|e| format!("`{part}`: {e}"))
            };
            let (a, b) = (parse(a)?, parse(b)?);
            if a > b {
                return Err(format!("`{part}`: range runs backwards"));
            }
            Ok((a, b))
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Ranges)
}

/// Error statistics over a set of vertices.
#[derive(Clone, Copy, Debug, Default)]
struct Stats {
    vertices: usize,
    mean_error: f64,
    p95_error: f64,
    max_error: f64,
    mean_displacement: f64,
    ratio: f64,
}

impl Stats {
    fn of(errors: &mut [f64], displacements: &[f64]) -> Stats {
        let n = errors.len();
        if n == 0 {
            return Stats::default();
        }
        let mean_error = errors.iter().sum::<f64>() / n as f64;
        let mean_displacement = displacements.iter().sum::<f64>() / n as f64;
        errors.sort_by(f64::total_cmp);
        let p95_error = errors[((n as f64 * 0.95).ceil() as usize).clamp(1, n) - 1];
        Stats {
            vertices: n,
            mean_error,
            p95_error,
            max_error: errors[n - 1],
            mean_displacement,
            ratio: if mean_displacement > 0.0 {
                mean_error / mean_displacement
            } else {
                f64::NAN
            },
        }
    }

    fn json(&self) -> Value {
        json!({
            "vertices": self.vertices,
            "mean_error": self.mean_error,
            "p95_error": self.p95_error,
            "max_error": self.max_error,
            "mean_displacement": self.mean_displacement,
            "ratio": self.ratio,
        })
    }
}

/// The rig's settings with the command line's overrides.
fn settings(rig: &Rig, args: &Args) -> SolverSettings {
    let mut s = rig.solver;
    if let Some(k) = args.solver {
        s.kind = match k {
            SolverArg::Rbf => SolverKind::Rbf,
            SolverArg::Laplacian => SolverKind::Laplacian,
            SolverArg::Blendshapes => s.kind,
        };
    }
    if let Some(r) = args.regions {
        s.regions = matches!(r, OnOff::On);
    }
    let radius = args.radius.or(s.kernel.radius());
    if let Some(k) = args.kernel {
        let radius = radius.unwrap_or(1.0);
        s.kernel = match k {
            KernelArg::Exponential => RbfKernel::Exponential { radius },
            KernelArg::Gaussian => RbfKernel::Gaussian { radius },
            KernelArg::Matern32 => RbfKernel::Matern32 { radius },
            KernelArg::ThinPlate => {
                s.affine = true;
                RbfKernel::ThinPlate
            }
        };
    } else if let Some(r) = args.radius {
        s.kernel = s.kernel.with_radius(r);
    }
    if let Some(Split(at)) = args.top_split {
        s.top_split = at.map(|at| TopSplit {
            at: at as f32,
            band: s.top_split.map_or(1.0, |t| t.band),
            upper_kernel: s.top_split.and_then(|t| t.upper_kernel),
            lower_kernel: s.top_split.and_then(|t| t.lower_kernel),
        });
    }
    if let Some(split) = s.top_split.as_mut() {
        if let Some(band) = args.top_split_band {
            split.band = band;
        }
        if let Some(KernelChoice(k)) = args.upper_kernel {
            split.upper_kernel = k;
        }
        if let Some(KernelChoice(k)) = args.lower_kernel {
            split.lower_kernel = k;
        }
    }
    if let Some(a) = args.affine {
        s.affine = matches!(a, OnOff::On);
    }
    if let Some(d) = args.distance {
        s.distance = match d {
            DistanceArg::Euclidean => RbfDistance::Euclidean,
            DistanceArg::Geodesic => RbfDistance::Geodesic,
        };
    }
    if let Some(w) = args.weights {
        s.weights = match w {
            WeightsArg::Uniform => LaplacianWeights::Uniform,
            WeightsArg::MeanValue => LaplacianWeights::MeanValue,
            WeightsArg::Cotangent => LaplacianWeights::Cotangent,
        };
    }
    if let Some(w) = args.constraint_weight {
        s.constraint_weight = w;
    }
    s
}

/// Runs `mimic eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut rig = load_rig(&args.rig)?;
    if let Some(band) = args.band {
        rig.regions.band = band;
    }
    let settings = settings(&rig, &args);
    let started = Instant::now();
    let basis = build_basis(&rig, &settings)
        .with_context(|| format!("building the basis of {}", args.rig.display()))?;
    let setup_ms = started.elapsed().as_secs_f64() * 1e3;
    // Noise gain: the largest row sum of |B|, i.e. how much a per-control error (tracking noise,
    // inconsistent neighbouring controls) can be amplified at one vertex (1 for a partition of unity).
    let noise_gain = (0..basis.vertex_count())
        .map(|i| basis.row(i).iter().map(|w| w.abs() as f64).sum::<f64>())
        .fold(0f64, f64::max);
    let blend = matches!(args.solver, Some(SolverArg::Blendshapes))
        .then(|| {
            crate::cmd::morph::EvalBlend::load(&args.rig, &rig, args.leave_one_out, args.ridge)
        })
        .transpose()?;
    let mut weights = serde_json::Map::new();
    let mut shapes = Vec::new();
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
        let mut fitter = blend
            .as_ref()
            .map(|b| b.fitter(&rig, &mesh.positions))
            .transpose()?;
        let mut deform = |d: &[Vec3], u: &mut [Vec3]| match fitter.as_mut() {
            Some(f) => {
                let w = crate::cmd::morph::EvalBlend::deform(f, &rig.mesh.positions, d, u);
                weights.insert(path.display().to_string(), json!(w));
            }
            None => basis.apply(d, u),
        };
        let (all, regions) = evaluate(
            &rig,
            &mut deform,
            &mesh.positions,
            &measured,
            args.dump.as_deref(),
            path,
        )?;
        shapes.push((path.clone(), all, regions));
    }
    let mut ratios: Vec<f64> = shapes.iter().map(|s| s.1.ratio).collect();
    ratios.sort_by(f64::total_cmp);
    let median = if ratios.is_empty() {
        f64::NAN
    } else if ratios.len() % 2 == 1 {
        ratios[ratios.len() / 2]
    } else {
        0.5 * (ratios[ratios.len() / 2 - 1] + ratios[ratios.len() / 2])
    };
    let report = json!({
        "rig": args.rig.display().to_string(),
        "units": rig.units,
        "settings": serde_json::to_value(settings)?,
        "band": rig.regions.band,
        "vertices": args.vertices.as_ref().map(|r| r.0.iter().map(|(a, b)| json!([a, b])).collect::<Vec<_>>()),
        "setup_ms": setup_ms,
        "noise_gain": noise_gain,
        "blendshape_weights": blend.is_some().then_some(&weights),
        "median_ratio": median,
        "max_ratio": ratios.last().copied().unwrap_or(f64::NAN),
        "shapes": shapes.iter().map(|(p, all, regions)| json!({
            "shape": p.display().to_string(),
            "all": all.json(),
            "regions": Region::ALL.iter().zip(regions).map(|(r, s)| (r.name().to_string(), s.json())).collect::<serde_json::Map<_, _>>(),
        })).collect::<Vec<_>>(),
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "rig {} ({}), solver {:?}, regions {}, top split {:?}, kernel {:?}, affine {}, distance {:?}, weights {:?}, constraint weight {}, band {}; setup {:.0} ms",
        args.rig.display(),
        rig.units,
        settings.kind,
        settings.regions,
        settings.top_split,
        settings.kernel,
        settings.affine,
        settings.distance,
        settings.weights,
        settings.constraint_weight,
        rig.regions.band,
        setup_ms
    );
    println!(
        "{:<28} {:<7} {:>7} {:>9} {:>9} {:>9} {:>9} {:>6}",
        "shape", "region", "verts", "mean_err", "p95_err", "max_err", "mean_disp", "ratio"
    );
    for (path, all, regions) in &shapes {
        let name = path.file_name().map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        let rows = std::iter::once(("all", all))
            .chain(Region::ALL.iter().map(|r| r.name()).zip(regions.iter()));
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

/// Drives the rig with the shape's control displacements and measures the result at the `measured`
/// vertices, overall and per region; with `dump`, writes the per-vertex errors of `path` there as CSV.
fn evaluate(
    rig: &Rig,
    deform: &mut dyn FnMut(&[Vec3], &mut [Vec3]),
    shape: &[Vec3],
    measured: &[bool],
    dump: Option<&std::path::Path>,
    path: &std::path::Path,
) -> anyhow::Result<(Stats, [Stats; 3])> {
    let neutral = &rig.mesh.positions;
    let d: Vec<Vec3> = rig
        .controls
        .iter()
        .map(|c| shape[c.vertex as usize] - neutral[c.vertex as usize])
        .collect();
    let mut u = vec![Vec3::ZERO; neutral.len()];
    deform(&d, &mut u);
    if let Some(dir) = dump {
        use std::fmt::Write as _;
        let mut csv = String::from("vertex,x,y,z,error,displacement\n");
        for (i, p) in neutral.iter().enumerate().filter(|(i, _)| measured[*i]) {
            let truth = shape[i] - *p;
            let _ = writeln!(
                csv,
                "{i},{},{},{},{},{}",
                p.x,
                p.y,
                p.z,
                (u[i] - truth).length(),
                truth.length()
            );
        }
        let stem = path
            .file_stem()
            .map_or_else(|| "shape".into(), |s| s.to_string_lossy().into_owned());
        let out = dir.join(format!("{stem}.errors.csv"));
        std::fs::write(&out, csv).with_context(|| out.display().to_string())?;
    }
    let mut errors: [Vec<f64>; 4] = Default::default();
    let mut moves: [Vec<f64>; 4] = Default::default();
    for i in 0..neutral.len() {
        if !measured[i] {
            continue;
        }
        let truth = shape[i] - neutral[i];
        let e = (u[i] - truth).length() as f64;
        let t = truth.length() as f64;
        let r = 1 + rig.regions.region_at(neutral[i].y).index();
        for slot in [0, r] {
            errors[slot].push(e);
            moves[slot].push(t);
        }
    }
    let [mut e0, mut e1, mut e2, mut e3] = errors;
    let all = Stats::of(&mut e0, &moves[0]);
    let regions = [
        Stats::of(&mut e1, &moves[1]),
        Stats::of(&mut e2, &moves[2]),
        Stats::of(&mut e3, &moves[3]),
    ];
    Ok((all, regions))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_vertex_ranges() {
        let r = parse_ranges("0-9408,11248-14061,20000").unwrap();
        assert!(r.contains(0) && r.contains(9408) && !r.contains(9409) && r.contains(12000));
        assert!(r.contains(20000) && !r.contains(20001));
        assert!(parse_ranges("5-1").is_err() && parse_ranges("a-3").is_err());
    }

    #[test]
    fn parses_kernels_and_splits() {
        assert!(matches!(
            parse_kernel("matern32:2"),
            Ok(KernelChoice(Some(RbfKernel::Matern32 { radius }))) if radius == 2.0
        ));
        assert!(matches!(parse_kernel("off"), Ok(KernelChoice(None))));
        assert!(parse_kernel("matern32").is_err() && parse_kernel("cubic:1").is_err());
        assert!(matches!(parse_split("4.6"), Ok(Split(Some(v))) if v == 4.6));
        assert!(matches!(parse_split("off"), Ok(Split(None))));
        assert!(parse_split("inf").is_err() && parse_split("x").is_err());
    }

    #[test]
    fn stats_of_known_errors() {
        // Errors 1..=100 (shuffled order does not matter): mean 50.5, nearest-rank p95 = 95, max 100;
        // displacements all 101: ratio 0.5.
        let mut errors: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        let s = Stats::of(&mut errors, &[101.0; 100]);
        assert_eq!(s.vertices, 100);
        assert!((s.mean_error - 50.5).abs() < 1e-12);
        assert_eq!(s.p95_error, 95.0);
        assert_eq!(s.max_error, 100.0);
        assert!((s.ratio - 0.5).abs() < 1e-12);
        let empty = Stats::of(&mut [], &[]);
        assert_eq!(empty.vertices, 0);
    }
}
