//! Options and setup shared by the subcommands: rig, layout, solver and pipeline flags, output
//! naming, the CANDIDE-3 model (a rig's look is `mimic_view::load_look`).

use anyhow::{Context, bail};
use mimic_assets::{ConfigDirs, load_morph_targets, load_rig};
use mimic_fit::capture::{CaptureFit, CaptureFrame};
use mimic_retarget::{BlendshapeSettings, Neutral, OneEuroSettings, RetargetSettings, Retargeter};
use mimic_solve::{Basis, build_basis};
use mimic_stream::{Catalog, load_catalog};
use mimic_types::{Layout, MorphTarget, Rig, SolverKind, SolverSettings};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

mod tuning;

/// Which solver, as the command line names it.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverChoice {
    /// Radial basis functions.
    Rbf,
    /// Laplacian surface editing.
    Laplacian,
    /// Thin shell: cotangent membrane + bending energy, controls hard (docs/quality.md).
    Shell,
    /// Weights of the rig's morph targets fitted to the controls (`P0 + sum w dP`); `mimic eval`
    /// only (a replay takes `--mode blendshapes`).
    Blendshapes,
}

/// On or off, as the command line says it.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Switch {
    /// Enabled.
    On,
    /// Disabled.
    Off,
}

/// Command-line options that choose the rig and the solver.
#[derive(clap::Args, Debug, Clone)]
pub struct RigArgs {
    /// Target rig: a name in configs/rigs/ or a path to a rig .toml.
    #[arg(long, default_value = "ict-face")]
    pub rig: String,
    /// Solver (default: the rig's).
    #[arg(long, value_enum)]
    pub solver: Option<SolverChoice>,
    /// Solve top / middle / bottom separately and blend (default: the rig's).
    #[arg(long, value_enum)]
    pub regions: Option<Switch>,
    /// RBF kernel radius in rig units (default: the rig's).
    #[arg(long)]
    pub radius: Option<f64>,
    /// RBF smoothing added to the kernel matrix's diagonal, 0 to 1 (default: the rig's
    /// `rbf_ridge`, 0 unless set: exact at the controls; docs/quality.md, "Dense control sets").
    #[arg(long)]
    pub rbf_ridge: Option<f64>,
    /// Config directory (default: ./configs or $MIMIC_CONFIGS).
    #[arg(long)]
    pub configs: Option<PathBuf>,
}

impl RigArgs {
    /// Config directories these options point at.
    pub fn config_dirs(&self) -> ConfigDirs {
        ConfigDirs::locate(self.configs.as_deref())
    }

    /// The rig file these options name.
    pub fn rig_path(&self) -> PathBuf {
        self.config_dirs().rig_path(&self.rig)
    }

    /// Loads the rig.
    pub fn load_rig(&self) -> anyhow::Result<Rig> {
        Ok(load_rig(&self.rig_path())?)
    }

    /// The rig's solver settings with the command line's overrides applied.
    pub fn solver_settings(&self, rig: &Rig) -> SolverSettings {
        let mut s = rig.solver;
        if let Some(k) = self.solver {
            s.kind = match k {
                SolverChoice::Rbf => SolverKind::Rbf,
                SolverChoice::Laplacian => SolverKind::Laplacian,
                SolverChoice::Shell => SolverKind::Shell,
                SolverChoice::Blendshapes => s.kind,
            };
        }
        if let Some(r) = self.regions {
            s.regions = r == Switch::On;
        }
        if let Some(radius) = self.radius {
            s.kernel = s.kernel.with_radius(radius);
        }
        if let Some(ridge) = self.rbf_ridge {
            s.rbf_ridge = ridge;
        }
        s
    }

    /// Builds the basis for the rig with these settings, and how long it took.
    pub fn build_basis(&self, rig: &Rig) -> anyhow::Result<(Basis, SolverSettings, Duration)> {
        if self.solver == Some(SolverChoice::Blendshapes) {
            bail!("--solver blendshapes is for `mimic eval`; replay with --mode blendshapes");
        }
        let settings = self.solver_settings(rig);
        let (basis, took) = timed_basis(rig, &settings)?;
        Ok((basis, settings, took))
    }
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

/// Builds the basis of `rig` with `settings`, and how long it took.
pub fn timed_basis(rig: &Rig, settings: &SolverSettings) -> anyhow::Result<(Basis, Duration)> {
    let t = Instant::now();
    let basis = build_basis(rig, settings)
        .with_context(|| format!("building the basis of rig `{}`", rig.name))?;
    Ok((basis, t.elapsed()))
}

pub use mimic_types::parse::{parse_seconds, parse_seconds_f32};

pub use tuning::SolverTuningArgs;

/// The warning `--f16-weights` prints (once): the f16 weights are gone from the deform.
const F16_REMOVED: &str = "warning: --f16-weights is ignored: f16 weights were removed, as they were no faster than f32 on the CI machine class (the step took 0.94-0.98x as long, under the 10 % a kernel variant must buy; `mimic bench`, 2026-12-07); f32 weights are used";

/// Command-line options of the per-frame pipeline.
#[derive(clap::Args, Debug, Clone)]
pub struct PipelineArgs {
    /// Number of first usable frames averaged into the neutral face.
    #[arg(long, default_value_t = 5)]
    pub neutral_frames: usize,
    /// Turn the One Euro jitter filter off.
    #[arg(long)]
    pub no_filter: bool,
    /// Turn the plausibility gate off: implausible frames pass through (for before/after comparisons; docs/gate.md).
    #[arg(long)]
    pub no_gate: bool,
    /// One Euro cutoff at rest (Hz).
    #[arg(long, default_value_t = OneEuroSettings::default().min_cutoff)]
    pub filter_cutoff: f32,
    /// One Euro speed coefficient (per target unit).
    #[arg(long, default_value_t = OneEuroSettings::default().beta)]
    pub filter_beta: f32,
    /// Also scale per axis by the ratio of face extents.
    #[arg(long)]
    pub per_axis_scale: bool,
    /// Seconds to hold the last expression after tracking is lost, before easing to neutral.
    #[arg(long, default_value_t = 0.25, value_parser = parse_seconds_f32)]
    pub lost_hold: f32,
    /// Seconds over which a lost face eases to neutral.
    #[arg(long, default_value_t = 0.5, value_parser = parse_seconds_f32)]
    pub lost_ease: f32,
    /// Removed (f32 weights are used): accepted, hidden, and warned about (`F16_REMOVED`).
    #[arg(long, hide = true)]
    pub f16_weights: bool,
}

impl PipelineArgs {
    /// The pipeline settings these options describe.
    pub fn settings(&self) -> RetargetSettings {
        static WARNED: std::sync::Once = std::sync::Once::new();
        if self.f16_weights {
            WARNED.call_once(|| eprintln!("{F16_REMOVED}"));
        }
        let mut gate = RetargetSettings::default().gate;
        gate.enabled = !self.no_gate;
        RetargetSettings {
            gate,
            neutral: Neutral::FirstFrames(self.neutral_frames.max(1)),
            filter: (!self.no_filter).then_some(OneEuroSettings {
                min_cutoff: self.filter_cutoff,
                beta: self.filter_beta,
                ..OneEuroSettings::default()
            }),
            per_axis_scale: self.per_axis_scale,
            lost_hold_secs: self.lost_hold,
            lost_ease_secs: self.lost_ease,
            ..RetargetSettings::default()
        }
    }
}

/// A ready pipeline: rig, layout, retargeter and how it was set up.
pub struct Prepared {
    /// The rig.
    pub rig: Rig,
    /// The layout of the source.
    pub layout: Layout,
    /// The retargeter.
    pub retargeter: Retargeter,
    /// Solver settings used.
    pub solver: SolverSettings,
    /// Time spent building the basis.
    pub basis_time: Duration,
}

/// Loads the rig and the named layout, builds the basis and the retargeter.
pub fn prepare(
    rig_args: &RigArgs,
    pipeline: &PipelineArgs,
    layout_name: &str,
) -> anyhow::Result<Prepared> {
    prepare_with(rig_args, pipeline.settings(), layout_name)
}

/// [`prepare`] with pipeline settings given directly.
pub fn prepare_with(
    rig_args: &RigArgs,
    settings: RetargetSettings,
    layout_name: &str,
) -> anyhow::Result<Prepared> {
    let layout = rig_args.config_dirs().load_layout_named(layout_name)?;
    let rig = rig_args.load_rig()?;
    let (basis, solver, basis_time) = rig_args.build_basis(&rig)?;
    let retargeter = Retargeter::new(&rig, &layout, basis, settings)
        .with_context(|| format!("rig `{}` with layout `{}`", rig.name, layout.name))?;
    Ok(Prepared {
        rig,
        layout,
        retargeter,
        solver,
        basis_time,
    })
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
    /// Ridge of the weight fit, relative to each target's squared control deltas (0.01: 1 % shrink);
    /// default: the rig's `[blendshape_fit]` (docs/quality.md, "Landmarks to ARKit weights").
    #[arg(long)]
    pub ridge: Option<f64>,
    /// Turn the One Euro smoothing of the weights off.
    #[arg(long)]
    pub no_weight_filter: bool,
}

impl BlendshapeArgs {
    /// The weight fit's settings: the `[blendshape_fit]` of the rig file at `rig_path`, as
    /// these options change them.
    pub fn settings(&self, rig_path: &std::path::Path) -> anyhow::Result<BlendshapeSettings> {
        let mut s = BlendshapeSettings::with_fit(&mimic_assets::load_blendshape_fit(rig_path)?);
        s.ridge = self.ridge.unwrap_or(s.ridge);
        s.smoothing = s.smoothing.filter(|_| !self.no_weight_filter);
        Ok(s)
    }
}

/// Fits CANDIDE-3 (`configs/models/candide3/candide3.wfm`) to a capture in the layout named
/// `layout_name` (which must list `candide_correspondences`), its AUs' odd parts as `odd` says.
pub fn fit_candide3(
    configs: &ConfigDirs,
    layout_name: &str,
    frames: &[CaptureFrame<'_>],
    odd: mimic_fit::OddParts,
) -> anyhow::Result<CaptureFit> {
    let layout = configs.load_layout_named(layout_name)?;
    let wfm = configs.root.join("models/candide3/candide3.wfm");
    Ok(mimic_fit::capture::fit_candide3(
        &wfm, &layout, frames, odd,
    )?)
}

/// The rigs (`--rig` first, then `--also-rig`, each with its basis and morph targets) and every
/// layout of the config folder, as a server (or a `mimic worker`) offers them; and each rig's
/// file by rig name (for the browser viewer's GLBs).
pub(crate) fn build_catalog(
    args_rig: &RigArgs,
    also_rig: &[String],
) -> anyhow::Result<(Catalog, BTreeMap<String, PathBuf>)> {
    if args_rig.solver == Some(SolverChoice::Blendshapes) {
        bail!("--solver blendshapes is for `mimic eval`; replay with --mode blendshapes");
    }
    let rigs = std::iter::once(&args_rig.rig)
        .chain(also_rig)
        .map(String::as_str);
    let settings = |rig: &Rig| args_rig.solver_settings(rig);
    Ok(load_catalog(&args_rig.config_dirs(), rigs, settings)?)
}
