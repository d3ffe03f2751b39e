//! Overrides of a rig's solver settings ([`SolverOverrides`], what `mimic eval`'s and the rig
//! options' tuning flags ask for), applied over the rig's own [`SolverSettings`], and the parsers
//! of their values.

use crate::parse::parse_ranges;
use crate::{
    LaplacianWeights, RbfDistance, RbfKernel, Socket, SocketMode, Sockets, SolverKind,
    SolverSettings, TopSplit,
};

/// An RBF kernel family, its radius given apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelFamily {
    /// `exp(-r / radius)`.
    Exponential,
    /// `exp(-(r / radius)^2)`.
    Gaussian,
    /// Matern 3/2.
    Matern32,
    /// `r^2 log r` (turns the affine term on).
    ThinPlate,
}

/// A number, or `off`.
#[derive(Clone, Copy, Debug)]
pub struct Split(pub Option<f64>);

/// A kernel with its radius, or `off`.
#[derive(Clone, Copy, Debug)]
pub struct KernelChoice(pub Option<RbfKernel>);

/// Socket vertex ranges.
#[derive(Clone, Debug)]
pub struct SocketRanges(pub Vec<[u32; 2]>);

/// Decay lengths: one for every socket or one per socket.
#[derive(Clone, Debug)]
pub struct Decays(pub Vec<f64>);

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

/// Parses socket vertex ranges (`11248-13293,13294-14061`), or `none`.
pub fn parse_socket_vertices(text: &str) -> Result<SocketRanges, String> {
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
pub fn parse_decays(text: &str) -> Result<Decays, String> {
    text.split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .map_err(|_| format!("`{t}` is not a decay length"))
        })
        .collect::<Result<_, _>>()
        .map(Decays)
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

/// Overrides that cannot be applied.
#[derive(Debug, thiserror::Error)]
pub enum OverrideError {
    /// The socket list is not valid.
    #[error("{0}")]
    Sockets(String),
    /// The decay lengths fit neither every socket nor each.
    #[error(
        "--socket-decay: {lengths} lengths for {sockets} sockets (give one, or one per socket)"
    )]
    Decays {
        /// Lengths given.
        lengths: usize,
        /// Sockets set.
        sockets: usize,
    },
}

/// Settings to put over a rig's solver settings; `None` keeps the rig's.
#[derive(Clone, Debug, Default)]
pub struct SolverOverrides {
    /// The solver.
    pub kind: Option<SolverKind>,
    /// Whether the regions are solved apart and blended.
    pub regions: Option<bool>,
    /// The RBF kernel's radius, rig units.
    pub radius: Option<f64>,
    /// The RBF's smoothing on the kernel matrix's diagonal.
    pub rbf_ridge: Option<f64>,
    /// The RBF kernel family (radius from `radius`, the rig's, or 1).
    pub kernel: Option<KernelFamily>,
    /// The RBF affine term.
    pub affine: Option<bool>,
    /// The RBF distance.
    pub distance: Option<RbfDistance>,
    /// The Laplacian's edge weights.
    pub weights: Option<LaplacianWeights>,
    /// The Laplacian's constraint weight.
    pub constraint_weight: Option<f64>,
    /// The top split's height, or off.
    pub top_split: Option<Split>,
    /// The top split's blend band.
    pub top_split_band: Option<f32>,
    /// The kernel of the top split's upper half.
    pub upper_kernel: Option<KernelChoice>,
    /// The kernel of the top split's lower half.
    pub lower_kernel: Option<KernelChoice>,
    /// The thin shell's membrane weight.
    pub shell_stiffness: Option<f64>,
    /// Whether the thin shell's columns are cut by region.
    pub shell_regions: Option<bool>,
    /// How the socket vertices move.
    pub socket_mode: Option<SocketMode>,
    /// The sockets' decay lengths.
    pub socket_decay: Option<Decays>,
    /// The sockets as vertex ranges (decay 1 unless `socket_decay` says).
    pub socket_vertices: Option<SocketRanges>,
    /// The thin shell's share per region in an RBF rig.
    pub shell_blend: Option<[f64; 3]>,
}

impl SolverOverrides {
    /// `settings` with these overrides put over them.
    pub fn apply(&self, mut s: SolverSettings) -> Result<SolverSettings, OverrideError> {
        if let Some(kind) = self.kind {
            s.kind = kind;
        }
        if let Some(r) = self.regions {
            s.regions = r;
        }
        if let Some(radius) = self.radius {
            s.kernel = s.kernel.with_radius(radius);
        }
        if let Some(ridge) = self.rbf_ridge {
            s.rbf_ridge = ridge;
        }
        if let Some(k) = self.kernel {
            let radius = self.radius.or(s.kernel.radius()).unwrap_or(1.0);
            s.kernel = match k {
                KernelFamily::Exponential => RbfKernel::Exponential { radius },
                KernelFamily::Gaussian => RbfKernel::Gaussian { radius },
                KernelFamily::Matern32 => RbfKernel::Matern32 { radius },
                KernelFamily::ThinPlate => {
                    s.affine = true;
                    RbfKernel::ThinPlate
                }
            };
        }
        self.apply_top_split(&mut s);
        s.affine = self.affine.unwrap_or(s.affine);
        s.distance = self.distance.unwrap_or(s.distance);
        s.weights = self.weights.unwrap_or(s.weights);
        s.constraint_weight = self.constraint_weight.unwrap_or(s.constraint_weight);
        s.shell.stiffness = self.shell_stiffness.unwrap_or(s.shell.stiffness);
        s.shell_blend = self.shell_blend.unwrap_or(s.shell_blend);
        s.shell.regions = self.shell_regions.unwrap_or(s.shell.regions);
        s.shell.socket_mode = self.socket_mode.unwrap_or(s.shell.socket_mode);
        if let Some(SocketRanges(v)) = &self.socket_vertices {
            let list: Vec<Socket> = v
                .iter()
                .map(|&vertices| Socket {
                    vertices,
                    decay: 1.0,
                })
                .collect();
            s.shell.sockets = Sockets::try_from(list).map_err(OverrideError::Sockets)?;
        }
        if let Some(Decays(l)) = &self.socket_decay {
            let sockets = s.shell.sockets.as_mut_slice();
            if l.len() != 1 && l.len() != sockets.len() {
                return Err(OverrideError::Decays {
                    lengths: l.len(),
                    sockets: sockets.len(),
                });
            }
            for (i, sock) in sockets.iter_mut().enumerate() {
                sock.decay = l[i.min(l.len() - 1)];
            }
        }
        Ok(s)
    }

    /// The top split's height, band and kernels.
    fn apply_top_split(&self, s: &mut SolverSettings) {
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

    #[test]
    fn overrides_keep_the_rest_and_check_the_decays() {
        let rig = SolverSettings::default();
        assert_eq!(SolverOverrides::default().apply(rig).unwrap(), rig);
        let thin = SolverOverrides {
            kernel: Some(KernelFamily::ThinPlate),
            ..Default::default()
        };
        let s = thin.apply(rig).unwrap();
        assert!(s.affine && s.kernel == RbfKernel::ThinPlate);
        let decays = SolverOverrides {
            socket_vertices: Some(SocketRanges(vec![[0, 1], [2, 3]])),
            socket_decay: Some(Decays(vec![1.0, 2.0, 3.0])),
            ..Default::default()
        };
        assert!(matches!(
            decays.apply(rig),
            Err(OverrideError::Decays {
                lengths: 3,
                sockets: 2
            })
        ));
    }
}
