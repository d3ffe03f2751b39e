//! `mimic eval`'s solver tuning flags (kernels, the top split, the Laplacian's weights, the thin
//! shell's stiffness, sockets and blend) and their parsers, applied over a rig's own settings.

use super::{RigArgs, Switch, parse_ranges};
use anyhow::bail;
use mimic_types::{
    LaplacianWeights, RbfDistance, RbfKernel, Rig, Socket, SocketMode, Sockets, SolverSettings,
    TopSplit,
};

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

/// Socket vertex ranges from the command line.
#[derive(Clone, Debug)]
pub struct SocketRanges(Vec<[u32; 2]>);

/// Decay lengths from the command line.
#[derive(Clone, Debug)]
pub struct Decays(Vec<f64>);

/// Parses socket vertex ranges (`11248-13293,13294-14061`), or `none`.
fn parse_socket_vertices(text: &str) -> Result<SocketRanges, String> {
    if text == "none" {
        return Ok(SocketRanges(Vec::new()));
    }
    Ok(SocketRanges(
        parse_ranges(text, false)?
            .into_iter()
            .map(|(a, b)| [a, b])
            .collect(),
    ))
}

/// Parses decay lengths, one for every socket or one per socket (`3,0.3`).
fn parse_decays(text: &str) -> Result<Decays, String> {
    text.split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .map_err(|_| format!("`{t}` is not a decay length"))
        })
        .collect::<Result<_, _>>()
        .map(Decays)
}

/// A number, or `off`.
#[derive(Clone, Copy, Debug)]
pub struct Split(pub Option<f64>);

/// Parses a finite number or `off`.
pub fn parse_split(text: &str) -> Result<Split, String> {
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
pub struct KernelChoice(pub Option<RbfKernel>);

/// Parses `family:radius` (`exponential`, `gaussian`, `matern32`) or `off`.
pub fn parse_kernel(text: &str) -> Result<KernelChoice, String> {
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

/// Parses three comma-separated numbers (`top,middle,bottom`).
pub fn parse_shares(text: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = text
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("`{x}`: {e}")))
        .collect::<Result<_, _>>()?;
    <[f64; 3]>::try_from(v.as_slice())
        .map_err(|_| format!("`{text}`: expected three shares, top,middle,bottom (e.g. 0,0,1)"))
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
        let mut s = rig_args.solver_settings(rig);
        if let Some(k) = self.kernel {
            let radius = rig_args.radius.or(s.kernel.radius()).unwrap_or(1.0);
            s.kernel = match k {
                KernelArg::Exponential => RbfKernel::Exponential { radius },
                KernelArg::Gaussian => RbfKernel::Gaussian { radius },
                KernelArg::Matern32 => RbfKernel::Matern32 { radius },
                KernelArg::ThinPlate => {
                    s.affine = true;
                    RbfKernel::ThinPlate
                }
            };
        }
        if let Some(Split(at)) = self.top_split {
            s.top_split = at.map(|at| TopSplit {
                at: at as f32,
                band: s.top_split.map_or(1.0, |t| t.band),
                upper_kernel: s.top_split.and_then(|t| t.upper_kernel),
                lower_kernel: s.top_split.and_then(|t| t.lower_kernel),
            });
        }
        if let Some(split) = s.top_split.as_mut() {
            if let Some(band) = self.top_split_band {
                split.band = band;
            }
            if let Some(KernelChoice(k)) = self.upper_kernel {
                split.upper_kernel = k;
            }
            if let Some(KernelChoice(k)) = self.lower_kernel {
                split.lower_kernel = k;
            }
        }
        if let Some(a) = self.affine {
            s.affine = a == Switch::On;
        }
        if let Some(d) = self.distance {
            s.distance = match d {
                DistanceArg::Euclidean => RbfDistance::Euclidean,
                DistanceArg::Geodesic => RbfDistance::Geodesic,
            };
        }
        if let Some(w) = self.weights {
            s.weights = match w {
                WeightsArg::Uniform => LaplacianWeights::Uniform,
                WeightsArg::MeanValue => LaplacianWeights::MeanValue,
                WeightsArg::Cotangent => LaplacianWeights::Cotangent,
            };
        }
        if let Some(w) = self.constraint_weight {
            s.constraint_weight = w;
        }
        if let Some(ks) = self.shell_stiffness {
            s.shell.stiffness = ks;
        }
        if let Some(shares) = self.shell_blend {
            s.shell_blend = shares;
        }
        if let Some(r) = self.shell_regions {
            s.shell.regions = r == Switch::On;
        }
        if let Some(m) = self.sockets {
            s.shell.socket_mode = match m {
                SocketArg::Free => SocketMode::Free,
                SocketArg::Frozen => SocketMode::Frozen,
                SocketArg::Decay => SocketMode::Decay,
            };
        }
        if let Some(SocketRanges(v)) = &self.socket_vertices {
            let list: Vec<Socket> = v
                .iter()
                .map(|&vertices| Socket {
                    vertices,
                    decay: 1.0,
                })
                .collect();
            s.shell.sockets = Sockets::try_from(list).map_err(anyhow::Error::msg)?;
        }
        if let Some(Decays(l)) = &self.socket_decay {
            let sockets = s.shell.sockets.as_mut_slice();
            if l.len() != 1 && l.len() != sockets.len() {
                bail!(
                    "--socket-decay: {} lengths for {} sockets (give one, or one per socket)",
                    l.len(),
                    sockets.len()
                );
            }
            for (i, sock) in sockets.iter_mut().enumerate() {
                sock.decay = l[i.min(l.len() - 1)];
            }
        }
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn parses_three_shares() {
        assert_eq!(parse_shares("0,0.25,0.75"), Ok([0.0, 0.25, 0.75]));
        assert_eq!(parse_shares(" 0, 1 ,0.5"), Ok([0.0, 1.0, 0.5]));
        assert!(
            parse_shares("0,1")
                .unwrap_err()
                .contains("expected three shares")
        );
        assert!(parse_shares("0,1,1,1").is_err() && parse_shares("0,x,1").is_err());
    }
}
