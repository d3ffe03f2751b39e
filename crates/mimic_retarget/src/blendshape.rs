//! Blendshape mode: control displacements -> morph-target weights -> `P = P0 + sum_k w_k dP_k`.
//!
//! Per frame, [`BlendshapeFitter::apply`] takes the control displacements `d` the
//! [`Retargeter`](crate::Retargeter) produced (38 x 3, target units) and solves
//! `min_w |sum_k w_k D_k - d|^2` plus the ridge, L1, temporal and left/right symmetry terms of
//! the rig's `[blendshape_fit]` ([`BlendshapeFit`]) with `0 <= w_k <= 1` ([`MorphFit`]), where
//! `D_k` are target `k`'s deltas at the rig's control vertices. The weights are then smoothed in time
//! (One Euro per weight) and the mesh is evaluated as the GPU morph-target method does:
//! positions `P0 + sum w_k dP_k`, normals `N0 + sum w_k dN_k` (renormalised). Nothing is allocated
//! per frame.

use crate::{FrameOutput, FrameStatus, OneEuro, OneEuroSettings, OneEuroStep};
use glam::Vec3;
use mimic_solve::morph_fit::{MorphFit, MorphScratch, MorphTerms};
use mimic_solve::{SolveError, vertex_normals};
pub use mimic_types::{BlendshapeFit, WeightMap};
use mimic_types::{MorphTarget, Rig};

/// Knobs of [`BlendshapeFitter`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlendshapeSettings {
    /// Ridge weight relative to each target's own `|D_k|^2`: `lambda_k = ridge |D_k|^2`, so it does
    /// not depend on the rig's units or on how far a target moves the controls; 0.01 shrinks a
    /// lone target's weight by 1 % (`w = 1 / (1 + ridge)`).
    pub ridge: f64,
    /// L1 weight relative to each target's `|D_k|^2` ([`BlendshapeFit::l1`]).
    pub l1: f64,
    /// Weight of the pull towards the previous frame's fitted weights, relative to each target's
    /// `|D_k|^2` ([`BlendshapeFit::temporal`]).
    pub temporal: f64,
    /// Weight of the left/right pairs' likeness ([`BlendshapeFit::symmetry`]).
    pub symmetry: f64,
    /// One Euro filter on each weight (speeds in weight units per second); `None` turns it off.
    pub smoothing: Option<OneEuroSettings>,
}

impl BlendshapeSettings {
    /// The One Euro filter the weights get unless turned off.
    pub const SMOOTHING: OneEuroSettings = OneEuroSettings {
        min_cutoff: 3.0,
        beta: 1.0,
        derivative_cutoff: 1.0,
    };

    /// A rig's `[blendshape_fit]` terms, with the weights smoothed ([`Self::SMOOTHING`]).
    pub fn with_fit(fit: &BlendshapeFit) -> Self {
        Self {
            ridge: fit.ridge,
            l1: fit.l1,
            temporal: fit.temporal,
            symmetry: fit.symmetry,
            smoothing: Some(Self::SMOOTHING),
        }
    }

    /// The terms as a `[blendshape_fit]` table.
    pub fn fit(&self) -> BlendshapeFit {
        BlendshapeFit {
            ridge: self.ridge,
            l1: self.l1,
            temporal: self.temporal,
            symmetry: self.symmetry,
        }
    }
}

impl Default for BlendshapeSettings {
    /// [`BlendshapeFit::DEFAULT`], smoothed.
    fn default() -> Self {
        Self::with_fit(&BlendshapeFit::DEFAULT)
    }
}

/// Why a blendshape fitter cannot be set up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BlendshapeError {
    /// The rig lists no morph targets.
    #[error("rig `{0}` has no morph targets (add [[morph_targets]] to its file)")]
    NoTargets(String),
    /// A target does not cover the rig's vertices.
    #[error(
        "morph target `{name}` has {got} position and {normals} normal deltas, the rig mesh has {expected} vertices"
    )]
    VertexCount {
        /// Target name.
        name: String,
        /// Position deltas given.
        got: usize,
        /// Normal deltas given.
        normals: usize,
        /// Vertices of the rig mesh.
        expected: usize,
    },
    /// A target has a NaN or infinite delta.
    #[error("morph target `{name}` has a non-finite delta at vertex {vertex}")]
    NonFinite {
        /// Target name.
        name: String,
        /// First offending vertex.
        vertex: usize,
    },
    /// A term's weight is negative or not finite.
    #[error(transparent)]
    Setting(#[from] mimic_types::SettingError),
    /// The bounded least-squares fit could not be prepared.
    #[error(transparent)]
    Fit(#[from] SolveError),
}

/// Fits morph-target weights to control displacements and evaluates the blended mesh.
#[derive(Debug)]
pub struct BlendshapeFitter {
    names: Vec<String>,
    fit: MorphFit,
    scratch: MorphScratch,
    smoothing: Option<OneEuroSettings>,
    filters: Vec<OneEuro>,
    last_time_us: Option<i64>,
    raw: Vec<f32>,
    weights: Vec<f32>,
    rest: Vec<Vec3>,
    rest_normals: Vec<Vec3>,
    /// Target-major: `position_deltas[k * n + i]`.
    position_deltas: Vec<Vec3>,
    /// Target-major: `normal_deltas[k * n + i]`.
    normal_deltas: Vec<Vec3>,
    /// Ridge weight of each target, `lambda_k` (rig units squared).
    ridges: Vec<f64>,
    /// The left/right pairs the symmetry term holds alike.
    pairs: Vec<(usize, usize)>,
    /// The settings it was made with.
    settings: BlendshapeSettings,
    /// The target of each of ARKit's eight `eyeLook*` shapes ([`crate::gaze::EYE_LOOK_NAMES`]),
    /// by ARKit or ICT name, if the rig has it.
    eye_look_targets: [Option<usize>; 8],
    /// The gaze's `eyeLook*` weights for the next [`BlendshapeFitter::apply`], if any.
    eye_look: Option<[f32; 8]>,
    /// Each target's ARKit name, if it has one (by ARKit or ICT spelling).
    arkit: Vec<Option<&'static str>>,
    /// Per target, a weight from another source (speech) that replaces the fit's at the next
    /// [`BlendshapeFitter::apply`] ([`BlendshapeFitter::set_mouth`]).
    mouth: Vec<Option<f32>>,
}

impl BlendshapeFitter {
    /// Prepares the fit of `targets` (on `rig`'s mesh) against `rig`'s control displacements.
    pub fn new(
        rig: &Rig,
        targets: &[MorphTarget],
        settings: &BlendshapeSettings,
    ) -> Result<Self, BlendshapeError> {
        if targets.is_empty() {
            return Err(BlendshapeError::NoTargets(rig.name.clone()));
        }
        settings.fit().validate()?;
        let n = rig.mesh.vertex_count();
        let k = targets.len();
        let mut position_deltas = Vec::with_capacity(k * n);
        let mut normal_deltas = Vec::with_capacity(k * n);
        let mut at_controls: Vec<Vec<Vec3>> = Vec::with_capacity(k);
        for t in targets {
            if t.position_deltas.len() != n || t.normal_deltas.len() != n {
                return Err(BlendshapeError::VertexCount {
                    name: t.name.clone(),
                    got: t.position_deltas.len(),
                    normals: t.normal_deltas.len(),
                    expected: n,
                });
            }
            if let Some(vertex) = (0..n)
                .find(|&i| !(t.position_deltas[i].is_finite() && t.normal_deltas[i].is_finite()))
            {
                return Err(BlendshapeError::NonFinite {
                    name: t.name.clone(),
                    vertex,
                });
            }
            position_deltas.extend_from_slice(&t.position_deltas);
            normal_deltas.extend_from_slice(&t.normal_deltas);
            // Rig::validate guarantees control vertices are inside the mesh.
            at_controls.push(
                rig.controls
                    .iter()
                    .map(|c| t.position_deltas[c.vertex as usize])
                    .collect::<Vec<Vec3>>(),
            );
        }
        // Every term relative to the target's own |D_k|^2, so none depends on the rig's units.
        let scale: Vec<f64> = at_controls
            .iter()
            .map(|t| t.iter().map(|v| v.as_dvec3().length_squared()).sum::<f64>())
            .collect();
        let names: Vec<String> = targets.iter().map(|t| t.name.clone()).collect();
        let pairs = mimic_types::arkit::mirror_pairs(&names);
        let times = |x: f64| scale.iter().map(|s| x * s).collect::<Vec<f64>>();
        let terms = MorphTerms {
            ridge: times(settings.ridge),
            l1: times(settings.l1),
            temporal: times(settings.temporal),
            pairs: pairs
                .iter()
                .map(|&(l, r)| (l, r, settings.symmetry * (scale[l] * scale[r]).sqrt()))
                .collect(),
        };
        let fit = MorphFit::with_terms(&at_controls, &terms)?;
        let ridges = terms.ridge;
        let mut rest_normals = vec![Vec3::ZERO; n];
        vertex_normals(&rig.mesh.positions, &rig.mesh.triangles, &mut rest_normals);
        Ok(Self {
            names,
            scratch: fit.scratch(),
            fit,
            smoothing: settings.smoothing,
            filters: vec![OneEuro::default(); k],
            last_time_us: None,
            raw: vec![0.0; k],
            weights: vec![0.0; k],
            rest: rig.mesh.positions.clone(),
            rest_normals,
            position_deltas,
            normal_deltas,
            ridges,
            pairs,
            settings: *settings,
            eye_look_targets: crate::gaze::EYE_LOOK_NAMES.map(|look| {
                targets
                    .iter()
                    .position(|t| mimic_types::arkit::arkit_name(&t.name) == Some(look))
            }),
            eye_look: None,
            arkit: targets
                .iter()
                .map(|t| mimic_types::arkit::arkit_name(&t.name))
                .collect(),
            mouth: vec![None; k],
        })
    }

    /// The gaze's ARKit `eyeLook*` weights ([`crate::gaze::eye_look_weights`]) that the next
    /// [`BlendshapeFitter::apply`] puts on the rig's `eyeLook*` targets in place of the fit's
    /// (the controls barely see where the eyes look); `None` leaves the fit's.
    pub fn set_eye_look(&mut self, weights: Option<[f32; 8]>) {
        self.eye_look = weights;
    }

    /// ARKit weights by name (`names[i]` weighs `weights[i]`; the mouth's, from speech) that
    /// replace the fit's on the targets of those names at the next [`BlendshapeFitter::apply`];
    /// `None` leaves the fit's. Allocates nothing.
    pub fn set_mouth(&mut self, named: Option<(&[&str], &[f32])>) {
        for (slot, arkit) in self.mouth.iter_mut().zip(&self.arkit) {
            *slot = named.and_then(|(names, weights)| {
                let i = names.iter().position(|n| Some(*n) == *arkit)?;
                weights.get(i).copied()
            });
        }
    }

    /// How many of ARKit's eight `eyeLook*` shapes the rig has as targets.
    pub fn eye_look_target_count(&self) -> usize {
        self.eye_look_targets.iter().flatten().count()
    }

    /// Target names, in weight order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Number of targets.
    pub fn target_count(&self) -> usize {
        self.names.len()
    }

    /// The ridge weight `lambda_k` of each target (rig units squared).
    pub fn ridges(&self) -> &[f64] {
        &self.ridges
    }

    /// The left/right pairs of targets the symmetry term holds alike
    /// ([`mimic_types::arkit::mirror_pairs`]).
    pub fn mirror_pairs(&self) -> &[(usize, usize)] {
        &self.pairs
    }

    /// The settings the fitter was made with.
    pub fn settings(&self) -> &BlendshapeSettings {
        &self.settings
    }

    /// Weights of the last frame, after smoothing.
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }

    /// Weights of the last frame as fitted, before smoothing.
    pub fn raw_weights(&self) -> &[f32] {
        &self.raw
    }

    /// Forgets the smoothing history and the warm start; weights return to 0.
    pub fn reset(&mut self) {
        self.filters.iter_mut().for_each(OneEuro::reset);
        self.last_time_us = None;
        self.scratch = self.fit.scratch();
        self.raw.fill(0.0);
        self.weights.fill(0.0);
    }

    /// Fits weights to control displacements `d` (target units) taken at `timestamp_us`, smooths
    /// them, and returns them; allocates nothing.
    ///
    /// # Panics
    /// If `d` has fewer entries than the rig has controls (entries after the controls', the
    /// rigid parts' columns, are not read).
    pub fn fit(&mut self, d: &[Vec3], timestamp_us: i64) -> &[f32] {
        let m = self.fit.control_count();
        assert!(
            d.len() >= m,
            "BlendshapeFitter::fit: one displacement per control"
        );
        self.fit.fit(&d[..m], &mut self.scratch, &mut self.raw);
        let dt = self
            .last_time_us
            .map_or(0.0, |t| (timestamp_us - t) as f32 * 1e-6);
        self.last_time_us = Some(timestamp_us);
        match &self.smoothing {
            Some(s) => {
                let step = OneEuroStep::new(s, dt);
                for ((w, f), x) in self
                    .weights
                    .iter_mut()
                    .zip(&mut self.filters)
                    .zip(&self.raw)
                {
                    *w = f.filter_step(s, &step, *x).clamp(0.0, 1.0);
                }
            }
            None => self.weights.copy_from_slice(&self.raw),
        }
        &self.weights
    }

    /// Evaluates `P0 + sum w_k dP_k` into `positions` and, unless `normals` is empty, the
    /// renormalised `N0 + sum w_k dN_k` into `normals`; allocates nothing.
    ///
    /// # Panics
    /// If `weights` is not one per target, `positions` not one per vertex, or `normals` neither
    /// empty nor one per vertex.
    pub fn evaluate(&self, weights: &[f32], positions: &mut [Vec3], normals: &mut [Vec3]) {
        let n = self.rest.len();
        assert_eq!(weights.len(), self.names.len(), "one weight per target");
        assert_eq!(positions.len(), n, "one position per vertex");
        assert!(
            normals.is_empty() || normals.len() == n,
            "normals: empty or one per vertex"
        );
        positions.copy_from_slice(&self.rest);
        self.add_weighted_deltas(weights, positions);
        if normals.is_empty() {
            return;
        }
        normals.copy_from_slice(&self.rest_normals);
        for (k, &w) in weights.iter().enumerate() {
            if w != 0.0 {
                let dn = &self.normal_deltas[k * n..(k + 1) * n];
                for (m, d) in normals.iter_mut().zip(dn) {
                    *m += w * *d;
                }
            }
        }
        for m in normals.iter_mut() {
            *m = m.normalize_or_zero();
        }
    }

    /// Evaluates the displacement `sum w_k dP_k` (the blended mesh minus the rest mesh) into `u`;
    /// allocates nothing.
    ///
    /// # Panics
    /// If `weights` is not one per target or `u` not one per vertex.
    pub fn displacements(&self, weights: &[f32], u: &mut [Vec3]) {
        assert_eq!(weights.len(), self.names.len(), "one weight per target");
        assert_eq!(u.len(), self.rest.len(), "one displacement per vertex");
        u.fill(Vec3::ZERO);
        self.add_weighted_deltas(weights, u);
    }

    /// Adds `sum w_k dP_k` to `out` (one entry per vertex).
    fn add_weighted_deltas(&self, weights: &[f32], out: &mut [Vec3]) {
        let n = self.rest.len();
        for (k, &w) in weights.iter().enumerate() {
            if w != 0.0 {
                let dp = &self.position_deltas[k * n..(k + 1) * n];
                for (p, d) in out.iter_mut().zip(dp) {
                    *p += w * *d;
                }
            }
        }
    }

    /// Turns a retargeter's output into the blendshape output, in place: fits and smooths the
    /// weights from `out.displacements`, then overwrites `out.positions` (and `out.normals` when
    /// the retargeter computes them) with the blended mesh. Calibrating frames give zero weights;
    /// rejected frames leave `out` and the weights as they were. Returns the weights.
    pub fn apply(&mut self, out: &mut FrameOutput) -> &[f32] {
        match out.status {
            FrameStatus::Rejected => return &self.weights,
            FrameStatus::Calibrating => self.reset(),
            FrameStatus::Tracked | FrameStatus::Lost => {
                self.fit(&out.displacements, out.timestamp_us);
                if let Some(look) = self.eye_look {
                    for (target, w) in self.eye_look_targets.iter().zip(look) {
                        if let Some(slot) = target.and_then(|k| self.weights.get_mut(k)) {
                            *slot = w;
                        }
                    }
                }
                for (w, m) in self.weights.iter_mut().zip(&self.mouth) {
                    if let Some(m) = m {
                        *w = m.clamp(0.0, 1.0);
                    }
                }
            }
        }
        let weights = std::mem::take(&mut self.weights);
        self.evaluate(&weights, &mut out.positions, &mut out.normals);
        self.weights = weights;
        &self.weights
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mimic_types::{Mesh, Region, RegionBands, RigControl, SolverSettings};

    /// A 4 x 4 grid in the xy plane with a control on every vertex of the middle 2 x 2.
    fn grid_rig() -> Rig {
        let mut positions = Vec::new();
        for y in 0..4 {
            for x in 0..4 {
                positions.push(Vec3::new(x as f32, y as f32, 0.0));
            }
        }
        let mut triangles = Vec::new();
        for y in 0..3u32 {
            for x in 0..3u32 {
                let a = y * 4 + x;
                triangles.push([a, a + 1, a + 5]);
                triangles.push([a, a + 5, a + 4]);
            }
        }
        let fdps = ["8.1", "8.2", "8.3", "8.4"];
        let controls = [5u32, 6, 9, 10]
            .iter()
            .zip(fdps)
            .map(|(&v, f)| RigControl {
                fdp: f.parse().unwrap(),
                vertex: v,
                region: Region::Bottom,
            })
            .collect();
        Rig {
            name: "grid".into(),
            units: "cm".into(),
            mesh: Mesh {
                positions,
                triangles,
                ..Mesh::default()
            },
            controls,
            regions: RegionBands {
                top_from: 10.0,
                bottom_below: 5.0,
                band: 0.1,
            },
            frozen: vec![false; 16],
            solver: SolverSettings::default(),
            parts: Default::default(),
        }
    }

    /// Target `k` lifts vertices by a pattern that differs per target (linearly independent at the controls).
    fn targets(rig: &Rig) -> Vec<MorphTarget> {
        let n = rig.mesh.vertex_count();
        (0..3)
            .map(|k| {
                let deltas: Vec<Vec3> = (0..n)
                    .map(|i| {
                        let p = rig.mesh.positions[i];
                        match k {
                            0 => Vec3::new(0.0, 0.0, 0.5 * p.x),
                            1 => Vec3::new(0.0, 0.3 * p.y, 0.0),
                            _ => Vec3::new(0.2, 0.0, 0.1 * p.x * p.y),
                        }
                    })
                    .collect();
                let moved: Vec<Vec3> = rig
                    .mesh
                    .positions
                    .iter()
                    .zip(&deltas)
                    .map(|(a, b)| *a + *b)
                    .collect();
                let mut n0 = vec![Vec3::ZERO; n];
                let mut n1 = vec![Vec3::ZERO; n];
                vertex_normals(&rig.mesh.positions, &rig.mesh.triangles, &mut n0);
                vertex_normals(&moved, &rig.mesh.triangles, &mut n1);
                MorphTarget {
                    name: format!("t{k}"),
                    position_deltas: deltas,
                    normal_deltas: n1.iter().zip(&n0).map(|(a, b)| *a - *b).collect(),
                }
            })
            .collect()
    }

    fn control_d(rig: &Rig, t: &[MorphTarget], w: &[f32]) -> Vec<Vec3> {
        rig.controls
            .iter()
            .map(|c| {
                t.iter()
                    .zip(w)
                    .map(|(t, w)| t.position_deltas[c.vertex as usize] * *w)
                    .sum()
            })
            .collect()
    }

    /// A tracked frame of `rig` at rest with control displacements `d`.
    fn tracked(rig: &Rig, d: Vec<Vec3>) -> FrameOutput {
        FrameOutput {
            timestamp_us: 0,
            status: FrameStatus::Tracked,
            positions: rig.mesh.positions.clone(),
            normals: Vec::new(),
            displacements: d,
            pose: mimic_types::HeadPose::IDENTITY,
            target_rotation: glam::Quat::IDENTITY,
            filled: 0,
            times: Default::default(),
        }
    }

    #[test]
    fn the_gaze_sets_the_eye_look_targets_and_the_fit_the_rest() {
        let rig = grid_rig();
        let mut t = targets(&rig);
        // Targets 1 and 2 named as two of ARKit's eyeLook shapes (one in ICT's spelling).
        t[1].name = "eyeLookOutLeft".into();
        t[2].name = "eyeLookUp_R".into();
        let settings = BlendshapeSettings {
            ridge: 0.0,
            smoothing: None,
            l1: 0.0,
            temporal: 0.0,
            symmetry: 0.0,
        };
        let mut f = BlendshapeFitter::new(&rig, &t, &settings).unwrap();
        assert_eq!(f.eye_look_target_count(), 2);
        let mut out = tracked(&rig, control_d(&rig, &t, &[0.6, 0.3, 0.2]));
        let look = [0.0, 0.0, 0.7, 0.0, 0.0, 0.0, 0.0, 0.4];
        f.set_eye_look(Some(look));
        let w = f.apply(&mut out).to_vec();
        // The fit's weight for target 0 (exact data), the gaze's for the eyeLook targets:
        // eyeLookOutLeft is EYE_LOOK_NAMES[2], eyeLookUpRight [7].
        assert!((w[0] - 0.6).abs() < 1e-5, "{w:?}");
        assert_eq!((w[1], w[2]), (0.7, 0.4));
        f.set_eye_look(None);
        let w = f.apply(&mut out).to_vec();
        assert!(
            (w[1] - 0.3).abs() < 1e-5 && (w[2] - 0.2).abs() < 1e-5,
            "{w:?}"
        );
    }

    #[test]
    fn speech_sets_the_mouth_targets_it_names_and_the_fit_the_rest() {
        let rig = grid_rig();
        let mut t = targets(&rig);
        // Target 1 is ARKit's jawOpen, target 2 mouthClose in ICT's (= ARKit's) spelling.
        t[1].name = "jawOpen".into();
        t[2].name = "mouthClose".into();
        let settings = BlendshapeSettings {
            ridge: 0.0,
            smoothing: None,
            l1: 0.0,
            temporal: 0.0,
            symmetry: 0.0,
        };
        let mut f = BlendshapeFitter::new(&rig, &t, &settings).unwrap();
        let mut out = tracked(&rig, control_d(&rig, &t, &[0.6, 0.3, 0.2]));
        // The speech names jawOpen (1.5 is clamped to 1) and a shape the rig lacks.
        f.set_mouth(Some((&["tongueOut", "jawOpen"], &[0.9, 1.5])));
        let w = f.apply(&mut out).to_vec();
        assert!(
            (w[0] - 0.6).abs() < 1e-5 && (w[2] - 0.2).abs() < 1e-5,
            "{w:?}"
        );
        assert_eq!(w[1], 1.0);
        // The blend follows the weights in use.
        let mut want = rig.mesh.positions.clone();
        for (k, wk) in w.iter().enumerate() {
            for (p, d) in want.iter_mut().zip(&t[k].position_deltas) {
                *p += *d * *wk;
            }
        }
        for (a, b) in out.positions.iter().zip(&want) {
            assert!(a.distance(*b) <= 1e-5 * (1.0 + b.length()), "{a} vs {b}");
        }
        f.set_mouth(None);
        let w = f.apply(&mut out).to_vec();
        assert!((w[1] - 0.3).abs() < 1e-5, "{w:?}");
    }

    #[test]
    fn recovers_weights_and_evaluates_the_blend() {
        let rig = grid_rig();
        let t = targets(&rig);
        let settings = BlendshapeSettings {
            ridge: 0.0,
            smoothing: None,
            l1: 0.0,
            temporal: 0.0,
            symmetry: 0.0,
        };
        let mut f = BlendshapeFitter::new(&rig, &t, &settings).unwrap();
        let truth = [0.6, 0.3, 0.0];
        let d = control_d(&rig, &t, &truth);
        let w = f.fit(&d, 0).to_vec();
        // Exact data, no ridge, 12 x 3 full-rank system: error ~ f32 rounding, 1e-5 is generous.
        for (a, b) in w.iter().zip(&truth) {
            assert!((a - b).abs() < 1e-5, "{w:?}");
        }
        let mut p = vec![Vec3::ZERO; 16];
        let mut nrm = vec![Vec3::ZERO; 16];
        f.evaluate(&truth, &mut p, &mut nrm);
        for i in 0..16 {
            let q = rig.mesh.positions[i];
            // Analytic blend: z = 0.6 * 0.5 x, y scaled by 1 + 0.3 * 0.3.
            let want = Vec3::new(q.x, q.y * (1.0 + 0.09), 0.3 * q.x);
            assert!((p[i] - want).length() < 1e-5, "{i}: {} vs {want}", p[i]);
            // N0 = +z; the blend of normal deltas is renormalised to unit length.
            assert!((nrm[i].length() - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn ridge_matches_the_dense_unbounded_solution() {
        // With the ridge, the minimiser is (G + lambda I)^-1 D^T d; when it lies inside the box it
        // is also the bounded one. Solve the 3 x 3 system independently (Cramer's rule, f64).
        let rig = grid_rig();
        let t = targets(&rig);
        let settings = BlendshapeSettings {
            ridge: 0.05,
            smoothing: None,
            l1: 0.0,
            temporal: 0.0,
            symmetry: 0.0,
        };
        let mut f = BlendshapeFitter::new(&rig, &t, &settings).unwrap();
        let truth = [0.5, 0.4, 0.7];
        let d = control_d(&rig, &t, &truth);
        let cols: Vec<Vec<f64>> = t
            .iter()
            .map(|t| {
                rig.controls
                    .iter()
                    .flat_map(|c| t.position_deltas[c.vertex as usize].as_dvec3().to_array())
                    .collect()
            })
            .collect();
        let dd: Vec<f64> = d.iter().flat_map(|v| v.as_dvec3().to_array()).collect();
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let lambda: Vec<f64> = cols.iter().map(|c| settings.ridge * dot(c, c)).collect();
        for (a, b) in f.ridges().iter().zip(&lambda) {
            assert!((a - b).abs() <= 1e-6 * b, "{a} vs {b}");
        }
        let g = glam::DMat3::from_cols_array_2d(&[0, 1, 2].map(|a| {
            [0, 1, 2].map(|b| dot(&cols[a], &cols[b]) + if a == b { lambda[a] } else { 0.0 })
        }));
        let rhs = glam::DVec3::new(dot(&cols[0], &dd), dot(&cols[1], &dd), dot(&cols[2], &dd));
        let want = g.inverse() * rhs;
        let w = f.fit(&d, 0);
        for (a, b) in w.iter().zip(want.to_array()) {
            // Gauss-Seidel stops at a step of 1e-9; f32 output rounding ~ 1e-7.
            assert!((*a as f64 - b).abs() < 1e-5, "{w:?} vs {want}");
            assert!((0.0..=1.0).contains(a));
        }
        // The ridge shrinks the norm: |w_lambda| < |w_0| = |truth| for exact data.
        let norm = |v: &[f32]| v.iter().map(|x| x * x).sum::<f32>().sqrt();
        assert!(norm(w) < norm(&truth));
    }

    #[test]
    fn smoothing_converges_to_a_held_expression_and_calibration_zeroes() {
        let rig = grid_rig();
        let t = targets(&rig);
        let mut f = BlendshapeFitter::new(
            &rig,
            &t,
            &BlendshapeSettings {
                ridge: 0.0,
                ..BlendshapeSettings::with_fit(&BlendshapeFit::RIDGE_ONLY)
            },
        )
        .unwrap();
        let d = control_d(&rig, &t, &[1.0, 0.0, 0.0]);
        let zero = vec![Vec3::ZERO; 4];
        f.fit(&zero, 0);
        let first = f.fit(&d, 33_333)[0];
        // One Euro at >= 3 Hz with dt = 1/30 s: alpha = 1 / (1 + tau/dt) >= 0.386, and < 1.
        assert!(first > 0.38 && first < 1.0, "{first}");
        for i in 2..60 {
            f.fit(&d, i * 33_333);
        }
        // After 2 s held the filtered weight is at the target (error decays like (1 - 0.386)^58).
        assert!((f.weights()[0] - 1.0).abs() < 1e-4, "{:?}", f.weights());
        let mut out = FrameOutput {
            timestamp_us: 0,
            status: FrameStatus::Calibrating,
            positions: vec![Vec3::ONE; 16],
            normals: Vec::new(),
            displacements: d.clone(),
            pose: mimic_types::HeadPose::IDENTITY,
            target_rotation: glam::Quat::IDENTITY,
            filled: 0,
            times: Default::default(),
        };
        assert!(f.apply(&mut out).iter().all(|w| *w == 0.0));
        assert_eq!(out.positions, rig.mesh.positions);
        out.status = FrameStatus::Tracked;
        f.apply(&mut out);
        assert!((out.positions[3] - Vec3::new(3.0, 0.0, 1.5)).length() < 1e-4);
    }

    #[test]
    fn rejects_mismatched_targets() {
        let rig = grid_rig();
        let mut t = targets(&rig);
        let s = BlendshapeSettings::default();
        assert!(matches!(
            BlendshapeFitter::new(&rig, &[], &s),
            Err(BlendshapeError::NoTargets(_))
        ));
        t[1].normal_deltas.pop();
        assert!(matches!(
            BlendshapeFitter::new(&rig, &t, &s),
            Err(BlendshapeError::VertexCount { .. })
        ));
        let mut t = targets(&rig);
        t[2].position_deltas[7] = Vec3::NAN;
        assert!(matches!(
            BlendshapeFitter::new(&rig, &t, &s),
            Err(BlendshapeError::NonFinite { vertex: 7, .. })
        ));
    }

    #[test]
    fn weight_map_takes_arkit_and_ict_names() {
        let names: Vec<String> = [
            "jawOpen",
            "mouthSmileLeft",
            "browInnerUp_L",
            "browInnerUp_R",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let map = WeightMap::new(&names);
        let mut w = [9.0f32; 4];
        let unknown = map.apply(
            [
                ("jawOpen", 0.5),
                ("MouthSmile_L", 1.5),
                ("browInnerUp", 0.25),
                ("cheekPuff", 0.7),
            ],
            &mut w,
        );
        assert_eq!(w, [0.5, 1.0, 0.25, 0.25]);
        assert_eq!(unknown, 1);
        // An exact name wins over the shared base; NaN counts as 0; unnamed targets are 0.
        let unknown = map.apply([("browInnerUp_R", 0.75), ("jawOpen", f32::NAN)], &mut w);
        assert_eq!((w, unknown), ([0.0, 0.0, 0.0, 0.75], 0));
    }

    #[test]
    fn a_shape_that_is_a_target_is_matched_unless_left_out() {
        use crate::quality::{MorphEval, control_displacements, measure};
        let rig = grid_rig();
        let t = targets(&rig);
        // The measured shape is target 0 at full weight.
        let shape: Vec<Vec3> = rig
            .mesh
            .positions
            .iter()
            .zip(&t[0].position_deltas)
            .map(|(p, d)| *p + *d)
            .collect();
        let d = control_displacements(&rig, &shape);
        assert_eq!(d, control_d(&rig, &t, &[1.0, 0.0, 0.0]));
        let everything = vec![true; 16];
        let mut u = vec![Vec3::NAN; 16];
        let with_it = MorphEval::new(t.clone(), false, 0.0);
        let mut f = with_it.fitter(&rig, &shape).unwrap();
        let w = MorphEval::deform(&mut f, &d, &mut u);
        assert_eq!(w.len(), 3);
        assert!((w[0].1 - 1.0).abs() < 1e-4, "{w:?}");
        let e = measure(&rig, &u, &shape, &everything);
        assert_eq!(e.all.vertices, 16);
        assert!(e.all.ratio < 1e-4, "{:?}", e.all);
        // Left out, the other two targets cannot make it: a clearly worse match.
        let without = MorphEval::new(t, true, 0.0);
        let mut f = without.fitter(&rig, &shape).unwrap();
        assert_eq!(MorphEval::deform(&mut f, &d, &mut u).len(), 2);
        assert!(measure(&rig, &u, &shape, &everything).all.ratio > 0.1);
    }

    #[test]
    fn displacements_are_the_blend_minus_the_rest() {
        let rig = grid_rig();
        let f =
            BlendshapeFitter::new(&rig, &targets(&rig), &BlendshapeSettings::default()).unwrap();
        let w = [0.25, 0.5, 1.0];
        let (mut p, mut u) = (vec![Vec3::ZERO; 16], vec![Vec3::NAN; 16]);
        f.evaluate(&w, &mut p, &mut []);
        f.displacements(&w, &mut u);
        for i in 0..16 {
            assert!((rig.mesh.positions[i] + u[i] - p[i]).length() < 1e-6, "{i}");
        }
    }
}
