//! `mimic eval`'s solver tuning flags (kernels, the top split, the Laplacian's weights, the thin
//! shell's stiffness, sockets and blend), applied over a rig's own settings by
//! `mimic_types::overrides::SolverOverrides` (where their value parsers live).

use super::{RigArgs, Switch};
use mimic_types::overrides::{
    Decays, KernelChoice, KernelFamily, SocketRanges, SolverOverrides, Split, parse_decays,
    parse_kernel, parse_shares, parse_socket_vertices, parse_split,
};
use mimic_types::{LaplacianWeights, RbfDistance, Rig, SocketMode, SolverSettings};

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

/// Socket handling of the thin-shell solver, on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum SocketArg {
    /// In the one shell solve.
    Free,
    /// Held still.
    Frozen,
    /// Their own screened solve from the rim (`--socket-decay`).
    Decay,
}

/// Command-line options that tune a solver beyond [`RigArgs`] (`mimic eval`).
#[derive(clap::Args, Debug, Clone)]
pub struct SolverTuningArgs {
    /// RBF kernel family (default: the rig's).
    #[arg(long, value_enum)]
    pub kernel: Option<KernelArg>,
    /// RBF affine term (default: the rig's).
    #[arg(long, value_enum)]
    pub affine: Option<Switch>,
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
    /// Thin shell: membrane weight `ks` in rig units^-2 (default: the rig's).
    #[arg(long)]
    pub shell_stiffness: Option<f64>,
    /// Thin shell: cut its columns by region (default: the rig's `solver.shell.regions`).
    #[arg(long, value_enum)]
    pub shell_regions: Option<Switch>,
    /// Thin shell: how the socket vertices move (default: the rig's).
    #[arg(long, value_enum)]
    pub sockets: Option<SocketArg>,
    /// Thin shell: decay length of `--sockets decay` in rig units, one for all sockets or one per
    /// socket (`3,0.3`) (default: the rig's).
    #[arg(long, value_parser = parse_decays)]
    pub socket_decay: Option<Decays>,
    /// Thin shell: the sockets as vertex ranges (`11248-13293,13294-14061`), or `none`; decay 1
    /// unless `--socket-decay` says (default: the rig's).
    #[arg(long, value_parser = parse_socket_vertices)]
    pub socket_vertices: Option<SocketRanges>,
    /// RBF: the thin shell's share in the top, middle and bottom regions
    /// (`0,0,1`: the mouth and jaw from the shell) (default: the rig's `solver.shell_blend`).
    #[arg(long, value_parser = parse_shares)]
    pub shell_blend: Option<[f64; 3]>,
}

impl SolverTuningArgs {
    /// Applies the region band to `rig`.
    pub fn apply_to_rig(&self, rig: &mut Rig) {
        if let Some(band) = self.band {
            rig.regions.band = band;
        }
    }

    /// `rig_args`' settings for `rig` with these options applied on top.
    pub fn solver_settings(&self, rig_args: &RigArgs, rig: &Rig) -> anyhow::Result<SolverSettings> {
        let on = |s: Option<Switch>| s.map(|s| s == Switch::On);
        let overrides = SolverOverrides {
            radius: rig_args.radius,
            kernel: self.kernel.map(|k| match k {
                KernelArg::Exponential => KernelFamily::Exponential,
                KernelArg::Gaussian => KernelFamily::Gaussian,
                KernelArg::Matern32 => KernelFamily::Matern32,
                KernelArg::ThinPlate => KernelFamily::ThinPlate,
            }),
            affine: on(self.affine),
            distance: self.distance.map(|d| match d {
                DistanceArg::Euclidean => RbfDistance::Euclidean,
                DistanceArg::Geodesic => RbfDistance::Geodesic,
            }),
            weights: self.weights.map(|w| match w {
                WeightsArg::Uniform => LaplacianWeights::Uniform,
                WeightsArg::MeanValue => LaplacianWeights::MeanValue,
                WeightsArg::Cotangent => LaplacianWeights::Cotangent,
            }),
            constraint_weight: self.constraint_weight,
            top_split: self.top_split,
            top_split_band: self.top_split_band,
            upper_kernel: self.upper_kernel,
            lower_kernel: self.lower_kernel,
            shell_stiffness: self.shell_stiffness,
            shell_regions: on(self.shell_regions),
            socket_mode: self.sockets.map(|m| match m {
                SocketArg::Free => SocketMode::Free,
                SocketArg::Frozen => SocketMode::Frozen,
                SocketArg::Decay => SocketMode::Decay,
            }),
            socket_decay: self.socket_decay.clone(),
            socket_vertices: self.socket_vertices.clone(),
            shell_blend: self.shell_blend,
            ..SolverOverrides::default()
        };
        Ok(overrides.apply(rig_args.solver_settings(rig))?)
    }
}
