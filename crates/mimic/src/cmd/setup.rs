//! Rig, layout and solver setup shared by the subcommands that retarget.

use anyhow::Context;
use mimic_assets::{ConfigDirs, load_rig};
use mimic_retarget::{Neutral, OneEuroSettings, RetargetSettings, Retargeter};
use mimic_solve::{Basis, build_basis};
use mimic_types::{Layout, Rig, SolverKind, SolverSettings};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Which solver, as the command line names it.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverChoice {
    /// Radial basis functions.
    Rbf,
    /// Laplacian surface editing.
    Laplacian,
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
    /// Config directory (default: ./configs or $MIMIC_CONFIGS).
    #[arg(long)]
    pub configs: Option<PathBuf>,
}

impl RigArgs {
    /// Config directories these options point at.
    pub fn config_dirs(&self) -> ConfigDirs {
        ConfigDirs::locate(self.configs.as_deref())
    }

    /// Loads the rig.
    pub fn load_rig(&self) -> anyhow::Result<Rig> {
        let path = self.config_dirs().rig_path(&self.rig);
        Ok(load_rig(&path)?)
    }

    /// The rig's solver settings with the command line's overrides applied.
    pub fn solver_settings(&self, rig: &Rig) -> SolverSettings {
        let mut s = rig.solver;
        if let Some(k) = self.solver {
            s.kind = match k {
                SolverChoice::Rbf => SolverKind::Rbf,
                SolverChoice::Laplacian => SolverKind::Laplacian,
            };
        }
        if let Some(r) = self.regions {
            s.regions = r == Switch::On;
        }
        if let Some(radius) = self.radius {
            s.kernel = s.kernel.with_radius(radius);
        }
        s
    }

    /// Builds the basis for the rig with these settings, and how long it took.
    pub fn build_basis(&self, rig: &Rig) -> anyhow::Result<(Basis, SolverSettings, Duration)> {
        let settings = self.solver_settings(rig);
        let t = Instant::now();
        let basis = build_basis(rig, &settings)
            .with_context(|| format!("building the basis of rig `{}`", rig.name))?;
        Ok((basis, settings, t.elapsed()))
    }
}

/// Command-line options of the per-frame pipeline.
#[derive(clap::Args, Debug, Clone)]
pub struct PipelineArgs {
    /// Number of first usable frames averaged into the neutral face.
    #[arg(long, default_value_t = 5)]
    pub neutral_frames: usize,
    /// Turn the One Euro jitter filter off.
    #[arg(long)]
    pub no_filter: bool,
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
    #[arg(long, default_value_t = 0.25)]
    pub lost_hold: f32,
    /// Seconds over which a lost face eases to neutral.
    #[arg(long, default_value_t = 0.5)]
    pub lost_ease: f32,
}

impl PipelineArgs {
    /// The pipeline settings these options describe.
    pub fn settings(&self) -> RetargetSettings {
        RetargetSettings {
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
    settings: mimic_retarget::RetargetSettings,
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
