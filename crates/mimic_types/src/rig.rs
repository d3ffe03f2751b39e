//! Target rigs: a mesh, its control vertices, regions, frozen vertices and solver settings.

use crate::{ControlName, Mesh, Region, RegionBands};
use serde::{Deserialize, Serialize};

pub use crate::shell::{MAX_SOCKETS, ShellSettings, Socket, SocketMode, Sockets};

/// A target head ready to be deformed.
#[derive(Clone, Debug, PartialEq)]
pub struct Rig {
    /// Short name, e.g. `ict-face`.
    pub name: String,
    /// Length unit of the mesh, e.g. `cm`.
    pub units: String,
    /// Rest mesh.
    pub mesh: Mesh,
    /// Control vertices, one per driven FDP or layout point (any count: 38 FDPs is the
    /// source method's set, dense sets have a layout's own points).
    pub controls: Vec<RigControl>,
    /// How vertices are split into regions.
    pub regions: RegionBands,
    /// Per-vertex flag: true for vertices that never move (back of the head, teeth, ...).
    pub frozen: Vec<bool>,
    /// Default solver settings.
    pub solver: SolverSettings,
    /// Rigid parts (jaw, eyeballs), each four more basis columns after the controls'.
    pub parts: crate::RigParts,
}

/// One control point of a rig.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RigControl {
    /// The control's name: an MPEG-4 FDP (`8.3`) or one point of a layout (`kinect121:23`,
    /// a dense control set). Written `fdp = ...` (or `control = ...`) in rig files; the field
    /// keeps the name it had when every control was an FDP.
    #[serde(alias = "control")]
    pub fdp: ControlName,
    /// Mesh vertex that carries it.
    pub vertex: u32,
    /// Region whose solve it drives.
    pub region: Region,
}

/// A rig that does not hold together.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RigError {
    /// A control vertex index is outside the mesh.
    #[error("control {fdp} uses vertex {vertex}, but the mesh has {vertex_count} vertices")]
    ControlVertexOutOfRange {
        /// Offending control.
        fdp: ControlName,
        /// Offending vertex.
        vertex: u32,
        /// Vertices in the mesh.
        vertex_count: usize,
    },
    /// Two controls share an FDP.
    #[error("control {0} appears twice")]
    DuplicateControl(ControlName),
    /// A control vertex is frozen, so it could never follow its control.
    #[error("control {fdp} uses vertex {vertex}, which is frozen")]
    FrozenControl {
        /// Offending control.
        fdp: ControlName,
        /// Offending vertex.
        vertex: u32,
    },
    /// The frozen mask does not match the mesh.
    #[error("frozen mask has {got} entries for {vertex_count} vertices")]
    FrozenMaskLength {
        /// Entries given.
        got: usize,
        /// Vertices in the mesh.
        vertex_count: usize,
    },
    /// The mesh itself is broken.
    #[error(transparent)]
    Mesh(#[from] crate::MeshError),
}

impl Rig {
    /// Checks controls, mask and mesh.
    pub fn validate(&self) -> Result<(), RigError> {
        self.mesh.validate()?;
        let n = self.mesh.vertex_count();
        if self.frozen.len() != n {
            return Err(RigError::FrozenMaskLength {
                got: self.frozen.len(),
                vertex_count: n,
            });
        }
        let mut seen = std::collections::HashSet::new();
        for c in &self.controls {
            if !seen.insert(c.fdp) {
                return Err(RigError::DuplicateControl(c.fdp));
            }
            if c.vertex as usize >= n {
                return Err(RigError::ControlVertexOutOfRange {
                    fdp: c.fdp,
                    vertex: c.vertex,
                    vertex_count: n,
                });
            }
            if self.frozen[c.vertex as usize] {
                return Err(RigError::FrozenControl {
                    fdp: c.fdp,
                    vertex: c.vertex,
                });
            }
        }
        Ok(())
    }

    /// Range checks of every numeric setting ([`RegionBands::validate`],
    /// [`SolverSettings::validate`]), and a top split band no wider than the mesh is tall.
    pub fn validate_settings(&self) -> Result<(), crate::SettingError> {
        self.regions.validate()?;
        self.solver.validate()?;
        if let (Some(split), Some((lo, hi))) = (self.solver.top_split, self.mesh.bounds()) {
            let height = hi.y - lo.y;
            if split.band > height {
                return Err(crate::SettingError::new(
                    "solver.top_split.band",
                    split.band,
                    format!("must be at most the mesh's height {height}"),
                ));
            }
        }
        Ok(())
    }

    /// Rest positions of the control vertices, in control order.
    pub fn control_positions(&self) -> Vec<glam::Vec3> {
        self.controls
            .iter()
            .map(|c| self.mesh.positions[c.vertex as usize])
            .collect()
    }

    /// Pairs of controls that sit on one rest position (the same vertex, or vertices within
    /// `1e-9` of the control cloud's extent): an RBF solve can only move such a pair together
    /// (it merges them into one centre driven by their mean), so the rig cannot show them apart.
    pub fn coincident_controls(&self) -> Vec<(ControlName, ControlName)> {
        let at = self.control_positions();
        let (lo, hi) = at.iter().fold(
            (
                glam::Vec3::splat(f32::INFINITY),
                glam::Vec3::splat(f32::NEG_INFINITY),
            ),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let tol = 1e-9 * f64::from((hi - lo).length().max(0.0));
        let mut pairs = Vec::new();
        for (a, ca) in self.controls.iter().enumerate() {
            for (b, cb) in self.controls.iter().enumerate().skip(a + 1) {
                let apart = f64::from(at[a].distance(at[b]));
                if ca.vertex == cb.vertex || apart <= tol {
                    pairs.push((ca.fdp, cb.fdp));
                }
            }
        }
        pairs
    }
}

/// Length units a rig may name in `units`, with their size in metres (`None`: `model`, a mesh
/// with no physical unit, such as CANDIDE-3's).
pub const RIG_UNITS: [(&str, Option<f64>); 5] = [
    ("m", Some(1.0)),
    ("cm", Some(0.01)),
    ("mm", Some(0.001)),
    ("in", Some(0.0254)),
    ("model", None),
];

/// Whether `units` is one of [`RIG_UNITS`].
pub fn is_rig_unit(units: &str) -> bool {
    RIG_UNITS.iter().any(|(name, _)| *name == units)
}

/// One rig unit in metres; `None` for `model` and for names outside [`RIG_UNITS`].
pub fn unit_in_metres(units: &str) -> Option<f64> {
    RIG_UNITS
        .iter()
        .find(|(name, _)| *name == units)
        .and_then(|(_, m)| *m)
}

/// Which deformation solver builds the basis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum SolverKind {
    /// Radial basis functions.
    #[default]
    Rbf,
    /// Laplacian surface editing with soft control constraints.
    Laplacian,
    /// Thin shell: `ks u'Lu + u'L M^-1 L u` (cotangent `L`, lumped mass `M`), controls hard.
    Shell,
}

impl SolverKind {
    /// Every solver, in declaration order.
    pub const ALL: [SolverKind; 3] = [SolverKind::Rbf, SolverKind::Laplacian, SolverKind::Shell];

    /// Lower-case name as written in rig files (`kind = "..."`).
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Rbf => "rbf",
            SolverKind::Laplacian => "laplacian",
            SolverKind::Shell => "shell",
        }
    }
}

/// Radial kernel of the RBF solver; `r` is a distance in rig units.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum RbfKernel {
    /// `exp(-r / radius)`, the source method's kernel (radius 64 there, in millimetres).
    Exponential {
        /// Decay length in rig units.
        radius: f64,
    },
    /// `exp(-(r / radius)^2)`.
    Gaussian {
        /// Width in rig units.
        radius: f64,
    },
    /// Matern 3/2: `(1 + sqrt(3) r / radius) exp(-sqrt(3) r / radius)`; like the exponential
    /// but flat at `r = 0`, so the interpolant has no kink at the controls.
    Matern32 {
        /// Length scale in rig units.
        radius: f64,
    },
    /// `r^2 log r` (needs the affine term to be well posed).
    ThinPlate,
}

impl RbfKernel {
    /// Smallest kernel radius a rig may set (rig units); smaller ones overflow the kernels.
    pub const MIN_RADIUS: f64 = 1e-6;
    /// Largest kernel radius a rig may set (rig units).
    pub const MAX_RADIUS: f64 = 1e6;

    /// Range check: a radius in [[`Self::MIN_RADIUS`], [`Self::MAX_RADIUS`]], and thin-plate
    /// only with the affine term; `key` names the kernel's setting in the error.
    pub fn validate(self, key: &'static str, affine: bool) -> Result<(), crate::SettingError> {
        match self.radius() {
            Some(r) if !(Self::MIN_RADIUS..=Self::MAX_RADIUS).contains(&r) => {
                Err(crate::SettingError::new(
                    key,
                    format!("{{ radius = {r} }}"),
                    format!(
                        "the radius must be finite, >= {:e} and <= {:e} (rig units)",
                        Self::MIN_RADIUS,
                        Self::MAX_RADIUS
                    ),
                ))
            }
            None if !affine => Err(crate::SettingError::new(
                key,
                "thin_plate",
                "needs affine = true (the thin-plate system is not well posed without it)",
            )),
            _ => Ok(()),
        }
    }

    /// The kernel's length scale in rig units (`None` for thin-plate, which has none).
    pub fn radius(self) -> Option<f64> {
        match self {
            RbfKernel::Exponential { radius }
            | RbfKernel::Gaussian { radius }
            | RbfKernel::Matern32 { radius } => Some(radius),
            RbfKernel::ThinPlate => None,
        }
    }

    /// The same family with length scale `radius` (thin-plate becomes exponential).
    pub fn with_radius(self, radius: f64) -> Self {
        match self {
            RbfKernel::Gaussian { .. } => RbfKernel::Gaussian { radius },
            RbfKernel::Matern32 { .. } => RbfKernel::Matern32 { radius },
            RbfKernel::Exponential { .. } | RbfKernel::ThinPlate => {
                RbfKernel::Exponential { radius }
            }
        }
    }
}

impl Default for RbfKernel {
    fn default() -> Self {
        RbfKernel::Exponential { radius: 64.0 }
    }
}

/// Edge weights of the Laplacian solver.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LaplacianWeights {
    /// Every neighbour weighs the same.
    Uniform,
    /// Mean-value (convex) weights `(tan(a/2) + tan(b/2)) / |vi - vj|`.
    #[default]
    MeanValue,
    /// Cotangent weights.
    Cotangent,
}

/// How the RBF solver measures the distance `r` between a vertex and a control.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum RbfDistance {
    /// Straight-line distance in space.
    #[default]
    Euclidean,
    /// Shortest path along the mesh edges (approximates the geodesic; keeps the lips and the
    /// eyelids apart, which are close in space but far apart along the skin).
    Geodesic,
}

/// Solver settings a rig ships with; the command line may override them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SolverSettings {
    /// Which solver.
    pub kind: SolverKind,
    /// RBF kernel.
    pub kernel: RbfKernel,
    /// Whether the RBF adds an affine term.
    pub affine: bool,
    /// How the RBF measures distances.
    pub distance: RbfDistance,
    /// Laplacian edge weights.
    pub weights: LaplacianWeights,
    /// Weight of the soft control constraints of the Laplacian solve.
    pub constraint_weight: f64,
    /// Solve top / middle / bottom separately and blend them (RBF, Laplacian; the thin shell has
    /// its own [`ShellSettings::regions`]).
    pub regions: bool,
    /// RBF with regions: split the top region into lids (below) and brows (above); `None` keeps
    /// one top solve. The Laplacian ignores it.
    pub top_split: Option<TopSplit>,
    /// Settings of the thin-shell solver (the others ignore them).
    pub shell: ShellSettings,
    /// RBF smoothing: `ridge` added to the diagonal of the kernel matrix (whose entries are at
    /// most 1), so the field no longer passes exactly through the controls and passes less of
    /// their noise (docs/quality.md, "Dense control sets"); 0 interpolates. At most 1.
    pub rbf_ridge: f64,
    /// RBF only: the share of the thin-shell basis (with [`SolverSettings::shell`])
    /// blended into each region, `[top, middle, bottom]` in `[0, 1]`: a vertex's row is
    /// `(1 - s) B + s B_shell` with `s` the regions' shares weighted by the vertex's region
    /// weights. Both bases reproduce the controls, so the blend does too. `[0, 0, 0]` (the
    /// default) builds no shell.
    pub shell_blend: [f64; 3],
}

/// Splits the top region's RBF in two at a height: the top controls at or above `at` (brows)
/// drive the vertices above it, those below (lids, eye corners) the vertices below, blended
/// linearly over `band` within the top region's own weight. Keeps a blink from lifting into
/// the brows and a brow raise from pulling the lids. Each half may have its own kernel.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TopSplit {
    /// Height (rig units) of the split, between the highest lid and the lowest brow control.
    pub at: f32,
    /// Full width (rig units) of the linear blend across the split; 0 gives a hard border.
    #[serde(default)]
    pub band: f32,
    /// Kernel of the upper (brow) half; `None` uses the solver's kernel.
    #[serde(default)]
    pub upper_kernel: Option<RbfKernel>,
    /// Kernel of the lower (lid) half; `None` uses the solver's kernel.
    #[serde(default)]
    pub lower_kernel: Option<RbfKernel>,
}

impl SolverSettings {
    /// Largest Laplacian constraint weight a rig may set (its square enters the normal equations).
    pub const MAX_CONSTRAINT_WEIGHT: f64 = 1e6;

    /// Whether `ridge` is a usable [`SolverSettings::rbf_ridge`]: finite, from 0 to 1.
    pub fn valid_rbf_ridge(ridge: f64) -> bool {
        ridge.is_finite() && (0.0..=1.0).contains(&ridge)
    }

    /// Range check of [`SolverSettings::shell_blend`]: each share finite, in `[0, 1]`.
    pub fn validate_shell_blend(&self) -> Result<(), crate::SettingError> {
        for share in self.shell_blend {
            if !(share.is_finite() && (0.0..=1.0).contains(&share)) {
                return Err(crate::SettingError::new(
                    "solver.shell_blend",
                    share,
                    "each share must be finite, >= 0 and <= 1",
                ));
            }
        }
        Ok(())
    }

    /// Range checks of every numeric solver setting, whichever solver the rig picks (the command
    /// line may switch it): kernel radii, the constraint weight in (0, 1e6], a finite top split.
    pub fn validate(&self) -> Result<(), crate::SettingError> {
        use crate::SettingError;
        self.kernel.validate("solver.kernel", self.affine)?;
        let w = self.constraint_weight;
        if !(w.is_finite() && w > 0.0 && w <= Self::MAX_CONSTRAINT_WEIGHT) {
            return Err(SettingError::new(
                "solver.constraint_weight",
                w,
                format!(
                    "must be finite, > 0 and <= {:e}",
                    Self::MAX_CONSTRAINT_WEIGHT
                ),
            ));
        }
        self.shell.validate()?;
        if !Self::valid_rbf_ridge(self.rbf_ridge) {
            return Err(SettingError::new(
                "solver.rbf_ridge",
                self.rbf_ridge,
                "must be finite, >= 0 and <= 1",
            ));
        }
        self.validate_shell_blend()?;
        if let Some(split) = &self.top_split {
            if !split.at.is_finite() {
                return Err(SettingError::new(
                    "solver.top_split.at",
                    split.at,
                    "must be a finite number",
                ));
            }
            if !(split.band.is_finite() && split.band >= 0.0) {
                return Err(SettingError::new(
                    "solver.top_split.band",
                    split.band,
                    "must be finite and >= 0",
                ));
            }
            if let Some(k) = split.upper_kernel {
                k.validate("solver.top_split.upper_kernel", self.affine)?;
            }
            if let Some(k) = split.lower_kernel {
                k.validate("solver.top_split.lower_kernel", self.affine)?;
            }
        }
        Ok(())
    }
}

impl TopSplit {
    /// Share of the upper (brow) part at height `y`, in `[0, 1]`.
    pub fn upper_share(&self, y: f32) -> f32 {
        if self.band <= 0.0 {
            if y >= self.at { 1.0 } else { 0.0 }
        } else {
            ((y - self.at) / self.band + 0.5).clamp(0.0, 1.0)
        }
    }
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            kind: SolverKind::Rbf,
            kernel: RbfKernel::default(),
            affine: false,
            distance: RbfDistance::Euclidean,
            weights: LaplacianWeights::MeanValue,
            constraint_weight: 10.0,
            regions: true,
            top_split: None,
            shell: ShellSettings::default(),
            rbf_ridge: 0.0,
            shell_blend: [0.0; 3],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn top_split_share_ramps_across_the_band() {
        let s = TopSplit {
            at: 4.0,
            band: 1.0,
            upper_kernel: None,
            lower_kernel: None,
        };
        assert_eq!(s.upper_share(3.0), 0.0);
        assert_eq!(s.upper_share(3.5), 0.0);
        assert_eq!(s.upper_share(4.0), 0.5);
        assert_eq!(s.upper_share(4.25), 0.75);
        assert_eq!(s.upper_share(5.0), 1.0);
        let hard = TopSplit { band: 0.0, ..s };
        assert_eq!((hard.upper_share(3.99), hard.upper_share(4.0)), (0.0, 1.0));
    }

    #[test]
    fn solver_settings_range_checks() {
        let ok = SolverSettings::default();
        ok.validate().unwrap();
        let err = |s: SolverSettings| s.validate().unwrap_err();
        for r in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e-9, 1e7] {
            let e = err(SolverSettings {
                kernel: RbfKernel::Gaussian { radius: r },
                ..ok
            });
            assert_eq!(e.key, "solver.kernel", "{r}");
        }
        let e = err(SolverSettings {
            kernel: RbfKernel::ThinPlate,
            ..ok
        });
        assert!(e.to_string().contains("needs affine = true"), "{e}");
        SolverSettings {
            kernel: RbfKernel::ThinPlate,
            affine: true,
            ..ok
        }
        .validate()
        .unwrap();
        for w in [0.0, -2.0, f64::NAN, 1e7] {
            let e = err(SolverSettings {
                constraint_weight: w,
                ..ok
            });
            assert_eq!(e.key, "solver.constraint_weight", "{w}");
        }
        for r in [-0.1, 1.5, f64::NAN, f64::INFINITY] {
            let e = err(SolverSettings { rbf_ridge: r, ..ok });
            assert_eq!(e.key, "solver.rbf_ridge", "{r}");
        }
        SolverSettings {
            rbf_ridge: 0.25,
            ..ok
        }
        .validate()
        .unwrap();
        for b in [-0.1, 1.5, f64::NAN] {
            let e = err(SolverSettings {
                shell_blend: [0.0, 0.0, b],
                ..ok
            });
            assert_eq!(e.key, "solver.shell_blend", "{b}");
        }
        SolverSettings {
            shell_blend: [0.0, 0.5, 1.0],
            ..ok
        }
        .validate()
        .unwrap();
        let split = TopSplit {
            at: 4.0,
            band: 1.0,
            upper_kernel: None,
            lower_kernel: Some(RbfKernel::Matern32 { radius: 1.0 }),
        };
        let with = |t: TopSplit| SolverSettings {
            top_split: Some(t),
            ..ok
        };
        with(split).validate().unwrap();
        assert_eq!(
            err(with(TopSplit {
                at: f32::NAN,
                ..split
            }))
            .key,
            "solver.top_split.at"
        );
        assert_eq!(
            err(with(TopSplit {
                band: -1.0,
                ..split
            }))
            .to_string(),
            "solver.top_split.band = -1: must be finite and >= 0"
        );
        assert_eq!(
            err(with(TopSplit {
                lower_kernel: Some(RbfKernel::Matern32 { radius: 0.0 }),
                ..split
            }))
            .key,
            "solver.top_split.lower_kernel"
        );
    }

    #[test]
    fn rig_units_are_a_closed_list() {
        assert_eq!(unit_in_metres("mm"), Some(0.001));
        assert_eq!(unit_in_metres("in"), Some(0.0254));
        assert_eq!(unit_in_metres("model"), None);
        assert!(is_rig_unit("model") && is_rig_unit("cm"));
        assert!(!is_rig_unit("furlongs") && !is_rig_unit("CM") && !is_rig_unit(""));
    }

    #[test]
    fn kernel_radius_round_trips() {
        for k in [
            RbfKernel::Exponential { radius: 2.0 },
            RbfKernel::Gaussian { radius: 2.0 },
            RbfKernel::Matern32 { radius: 2.0 },
        ] {
            assert_eq!(k.radius(), Some(2.0));
            assert_eq!(k.with_radius(3.0).radius(), Some(3.0));
            assert_eq!(
                std::mem::discriminant(&k.with_radius(3.0)),
                std::mem::discriminant(&k)
            );
        }
        assert_eq!(RbfKernel::ThinPlate.radius(), None);
    }
}
