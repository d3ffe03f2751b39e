//! Per-frame Levenberg-Marquardt fit of CANDIDE-3 pose, scale and animation units to landmarks.
//!
//! Model: `X = s R (v0 + S sigma + A alpha) + t` in camera space (metres). The shape units `sigma`
//! are estimated once ([`Fitter::estimate_shape`]) and then held fixed; each frame solves the pose
//! (`R`, `t`, `s`) and the 11 animation-unit coefficients `alpha`, warm-started from the previous
//! frame. Residuals are in pixels: a point with depth contributes its 3D offset scaled by
//! `f / depth` (the depth axis down-weighted), a point without depth (or a contour point) its
//! reprojection error. Priors pull `alpha` toward 0 and toward the previous frame's value.

use crate::Camera;
use crate::candide::{AUV_COUNT, Candide3};
use crate::cholesky::solve_spd;
use glam::{DMat3, DQuat, DVec2, DVec3};
use mimic_types::ModelCorrespondence;

mod odd;
pub use odd::OddParts;

/// Pose parameters plus animation units: unknowns per frame.
const POSE_PARAMS: usize = 7;

/// A correspondence list that does not fit the model or the layout.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// A correspondence names neither one vertex nor an edge with `t` in 0..=1.
    #[error(
        "correspondence of point {point} must name `vertex`, or `vertices = [a, b]` with `t` in 0..=1"
    )]
    Malformed {
        /// Layout point of the entry.
        point: usize,
    },
    /// A correspondence names a vertex the model does not have.
    #[error("correspondence of point {point} names vertex {vertex}; the model has {count}")]
    VertexOutOfRange {
        /// Layout point of the entry.
        point: usize,
        /// Offending vertex.
        vertex: usize,
        /// Vertices in the model.
        count: usize,
    },
    /// A correspondence names a point the layout does not have.
    #[error("correspondence names point {point}; the layout has {count}")]
    PointOutOfRange {
        /// Offending point.
        point: usize,
        /// Points in the layout.
        count: usize,
    },
    /// A fitted unit index is not one of the model's AUVs.
    #[error("fitted unit {0} is not an AUV index (0..{AUV_COUNT})")]
    UnitOutOfRange(usize),
    /// Fewer correspondences than a pose and expression fit needs.
    #[error("{0} correspondences; the fitter needs at least 6")]
    TooFew(usize),
}

/// What is known of one tracked point in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PointObservation {
    /// Image position (pixels, y down), if the tracker gave one.
    pub pixel: Option<DVec2>,
    /// Camera-space position (metres), if the point had depth.
    pub position: Option<DVec3>,
}

/// Tuning of the fitter; residual weights are in pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct FitSettings {
    /// Fewer observed correspondences than this: the frame is lost.
    pub min_points: usize,
    /// RMS reprojection residual above this (pixels) after a cold restart: the frame is lost.
    pub max_residual_px: f64,
    /// Ridge prior on each AU coefficient: residual `au_prior_px * alpha`.
    pub au_prior_px: f64,
    /// Temporal prior: residual `au_smooth_px * (alpha - alpha_previous)`.
    pub au_smooth_px: f64,
    /// Ridge prior on each shape-unit coefficient while the shape is estimated.
    pub shape_prior_px: f64,
    /// Bounds of every AU coefficient.
    pub au_bounds: (f64, f64),
    /// Bounds of every shape-unit coefficient.
    pub shape_bounds: (f64, f64),
    /// Weight of the depth axis of a 3D residual (Kinect depth is noisier than the image).
    pub depth_weight: f64,
    /// Residuals (pixels) beyond which the loss grows linearly (Huber), so a stray depth or a
    /// mislabelled point cannot drag the whole fit.
    pub huber_px: f64,
    /// LM iterations of a warm-started frame.
    pub iterations: usize,
    /// LM iterations of a cold start.
    pub cold_iterations: usize,
    /// Metres per model unit assumed when a cold start has no depth at all.
    pub nominal_scale_m: f64,
    /// The AUVs fitted, as indices into [`Candide3::auvs`] (file order); the others stay 0.
    pub units: Vec<usize>,
    /// Whether and how each fitted AUV's left-right odd part is fitted (its displacements times
    /// the sign of the vertex's x; `docs/fitter.md`): the subject's left half then moves by
    /// `alpha + beta` of the unit and the right half by `alpha - beta`, so a one-sided smile
    /// stays one-sided. Default [`OddParts::AfterPose`]: fitted after the symmetric fit, on the
    /// image only, with the pose held, so the odd parts cannot trade off against the head's yaw.
    pub odd: OddParts,
    /// Bounds of every odd-part coefficient `beta` (symmetric: either side may lead).
    pub odd_bound: f64,
    /// Ridge prior on each odd-part coefficient (pixels per unit): stiffer than the AUs', so
    /// tracker noise that differs between the sides does not become expression.
    pub odd_prior_px: f64,
    /// Temporal prior on each odd-part coefficient.
    pub odd_smooth_px: f64,
}

/// The AUVs fitted by default: the six the Kinect v1 face tracker reports (upper lip raiser, jaw drop,
/// lip stretcher, brow lowerer, lip corner depressor, outer brow raiser) and eyes closed. Lid
/// tightener and upper lid raiser move the same lid vertices as eyes closed (nearly collinear), and
/// nose wrinkler and lip presser are barely separable from upper lip raiser on tracked points.
pub const DEFAULT_UNITS: [usize; 7] = [0, 1, 2, 3, 4, 5, 6];

impl Default for FitSettings {
    fn default() -> Self {
        Self {
            min_points: 12,
            max_residual_px: 6.0,
            au_prior_px: 1.0,
            au_smooth_px: 0.5,
            shape_prior_px: 2.0,
            au_bounds: (-1.0, 1.5),
            shape_bounds: (-1.5, 1.5),
            depth_weight: 0.5,
            huber_px: 2.0,
            iterations: 8,
            cold_iterations: 60,
            nominal_scale_m: 0.1,
            units: DEFAULT_UNITS.to_vec(),
            odd: OddParts::AfterPose,
            odd_bound: 1.0,
            odd_prior_px: 3.0,
            odd_smooth_px: 2.0,
        }
    }
}

/// A rigid pose with uniform scale: `X = scale * rotation * m + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Model-to-camera rotation.
    pub rotation: DQuat,
    /// Camera-space translation (metres).
    pub translation: DVec3,
    /// Metres per model unit.
    pub scale: f64,
}

/// The fit of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FitResult {
    /// False when the frame had too few points or no acceptable fit; then nothing else is meaningful.
    pub tracked: bool,
    /// Fitted pose.
    pub pose: Pose,
    /// Fitted coefficients of the 11 AUVs, in model file order.
    pub au: Vec<f64>,
    /// Fitted coefficients of their left-right odd parts (11, same order; empty when the fit is
    /// symmetric, [`FitSettings::odd`] = [`OddParts::Off`]).
    pub au_odd: Vec<f64>,
    /// RMS reprojection error of the observed correspondences (pixels).
    pub residual_px: f64,
    /// Correspondences observed in the frame.
    pub points_used: usize,
    /// LM iterations run.
    pub iterations: usize,
}

/// A correspondence resolved against the model: linear in the coefficients.
#[derive(Clone, Debug)]
struct Target {
    point: usize,
    weight: f64,
    contour: bool,
    base: DVec3,
    au: Vec<DVec3>,
    shape: Vec<DVec3>,
}

#[derive(Clone, Debug)]
struct State {
    rotation: DMat3,
    translation: DVec3,
    log_scale: f64,
    au: Vec<f64>,
}

/// Fits CANDIDE-3 to a stream of frames of one layout.
#[derive(Clone, Debug)]
pub struct Fitter {
    model: Candide3,
    camera: Camera,
    settings: FitSettings,
    point_count: usize,
    targets: Vec<Target>,
    /// Per-vertex displacements of the odd parts, one field per AUV (empty when symmetric).
    odd_dense: Vec<Vec<DVec3>>,
    /// Length of the internal coefficient vector: the AUVs, then (jointly fitted) their odd parts.
    au_len: usize,
    /// The fitted AUVs that have an odd part (a unit moving only the midline has none).
    odd_units: Vec<usize>,
    /// Odd-part coefficients of the last tracked frame, fitted after the pose
    /// ([`OddParts::AfterPose`]; file order, 0 for units without one).
    odd_after: [f64; AUV_COUNT],
    /// Whether `odd_after` belongs to the previous frame (a temporal prior applies).
    odd_warm: bool,
    shape: Vec<f64>,
    state: Option<State>,
    // Scratch (reused across frames, no per-frame allocation in the LM loop).
    jtj: Vec<f64>,
    jtr: Vec<f64>,
    row: Vec<f64>,
}

/// Dense per-vertex displacements of a set of sparse units.
fn dense(units: &[crate::candide::Unit], nv: usize) -> Vec<Vec<DVec3>> {
    units
        .iter()
        .map(|u| {
            let mut d = vec![DVec3::ZERO; nv];
            for &(v, delta) in &u.deltas {
                d[v] += delta;
            }
            d
        })
        .collect()
}

impl Fitter {
    /// A fitter of `model` to a layout of `point_count` points with these correspondences.
    pub fn new(
        model: Candide3,
        correspondences: &[ModelCorrespondence],
        point_count: usize,
        camera: Camera,
        settings: FitSettings,
    ) -> Result<Fitter, FitError> {
        let nv = model.vertices.len();
        let mut au_dense = dense(model.auvs(), nv);
        let mut settings = settings;
        let odd_dense: Vec<Vec<DVec3>> = if settings.odd != OddParts::Off {
            au_dense
                .iter()
                .map(|d| {
                    d.iter()
                        .zip(&model.vertices)
                        .map(|(dv, v)| {
                            if v.x.abs() < 1e-9 {
                                DVec3::ZERO
                            } else {
                                *dv * v.x.signum()
                            }
                        })
                        .collect()
                })
                .collect()
        } else {
            Vec::new()
        };
        au_dense.extend(odd_dense.iter().cloned());
        // Jointly fitted odd parts are coefficients of the LM state; after-pose ones are kept apart
        // (the targets still carry their fields, after the AUVs').
        let au_len = if settings.odd == OddParts::Joint {
            au_dense.len()
        } else {
            AUV_COUNT
        };
        let shape_dense = dense(&model.shape_units, nv);
        let mut targets = Vec::with_capacity(correspondences.len());
        for c in correspondences {
            if c.point >= point_count {
                return Err(FitError::PointOutOfRange {
                    point: c.point,
                    count: point_count,
                });
            }
            let blend = c.blend().ok_or(FitError::Malformed { point: c.point })?;
            if let Some(&(v, _)) = blend.iter().find(|(v, _)| *v >= nv) {
                return Err(FitError::VertexOutOfRange {
                    point: c.point,
                    vertex: v,
                    count: nv,
                });
            }
            let mix = |field: &dyn Fn(usize) -> DVec3| -> DVec3 {
                blend.iter().map(|&(v, w)| field(v) * f64::from(w)).sum()
            };
            targets.push(Target {
                point: c.point,
                weight: f64::from(c.weight),
                contour: c.contour,
                base: mix(&|v| model.vertices[v]),
                au: au_dense.iter().map(|d| mix(&|v| d[v])).collect(),
                shape: shape_dense.iter().map(|d| mix(&|v| d[v])).collect(),
            });
        }
        if targets.len() < 6 {
            return Err(FitError::TooFew(targets.len()));
        }
        if let Some(&k) = settings.units.iter().find(|&&k| k >= AUV_COUNT) {
            return Err(FitError::UnitOutOfRange(k));
        }
        // The fitted units that have an odd part (a unit moving only the midline, x = 0, has
        // none). Jointly fitted, they are the LM's units AUV_COUNT + k.
        let odd_units: Vec<usize> = if settings.odd == OddParts::Off {
            Vec::new()
        } else {
            settings
                .units
                .iter()
                .copied()
                .filter(|&k| odd_dense[k].iter().any(|d| *d != DVec3::ZERO))
                .collect()
        };
        if settings.odd == OddParts::Joint {
            settings
                .units
                .extend(odd_units.iter().map(|&k| AUV_COUNT + k));
        }
        let n = POSE_PARAMS + settings.units.len() + model.shape_units.len();
        let shape = vec![0.0; model.shape_units.len()];
        Ok(Fitter {
            model,
            camera,
            settings,
            point_count,
            targets,
            odd_dense,
            au_len,
            odd_units,
            odd_after: [0.0; AUV_COUNT],
            odd_warm: false,
            shape,
            state: None,
            jtj: vec![0.0; n * n],
            jtr: vec![0.0; n],
            row: vec![0.0; n],
        })
    }

    /// The model being fitted.
    pub fn model(&self) -> &Candide3 {
        &self.model
    }

    /// The settings in use.
    pub fn settings(&self) -> &FitSettings {
        &self.settings
    }

    /// Current shape-unit coefficients (zeros until [`Fitter::estimate_shape`] or [`Fitter::set_shape`]).
    pub fn shape(&self) -> &[f64] {
        &self.shape
    }

    /// Sets the shape-unit coefficients (one per model shape unit; extra values are ignored).
    pub fn set_shape(&mut self, shape: &[f64]) {
        for (s, v) in self.shape.iter_mut().zip(shape) {
            *s = *v;
        }
    }

    /// The fitted units as the recording header's `au_fitted` lists them: the AUVs (file order
    /// indices), then their odd parts as `AUV_COUNT + k`.
    pub fn fitted_units(&self) -> Vec<usize> {
        let mut units = self.settings.units.clone();
        if self.settings.odd == OddParts::AfterPose {
            units.extend(self.odd_units.iter().map(|&k| AUV_COUNT + k));
        }
        units
    }

    /// Forgets the previous frame: the next fit starts cold.
    pub fn reset(&mut self) {
        self.state = None;
        self.odd_warm = false;
    }

    /// Estimates the shape units from `frames` (the performer's first, ideally neutral, frames):
    /// each frame with enough points is fitted cold with shape free and AUs held at 0 (the frames are
    /// taken as neutral), and the shapes are averaged.
    /// Returns the number of frames used; the fitter is reset afterwards.
    pub fn estimate_shape(&mut self, frames: &[&[PointObservation]]) -> usize {
        let ns = self.shape.len();
        let mut sum = vec![0.0; ns];
        let mut used = 0;
        // The frames are taken as neutral: AUs stay 0 so they cannot absorb the shape.
        let units = std::mem::take(&mut self.settings.units);
        for obs in frames {
            self.shape.iter_mut().for_each(|s| *s = 0.0);
            self.state = None;
            if self.observed(obs) < self.settings.min_points {
                continue;
            }
            let mut state = self.initial_state(obs);
            let iterations = self.settings.cold_iterations;
            let (_, residual) = self.solve(&mut state, obs, true, None, iterations);
            if residual.is_finite() && residual <= self.settings.max_residual_px {
                sum.iter_mut().zip(&self.shape).for_each(|(a, s)| *a += s);
                used += 1;
            }
        }
        self.settings.units = units;
        self.shape = if used > 0 {
            sum.iter().map(|a| a / used as f64).collect()
        } else {
            vec![0.0; ns]
        };
        self.reset();
        used
    }

    fn observed(&self, obs: &[PointObservation]) -> usize {
        self.targets
            .iter()
            .filter(|t| obs.get(t.point).is_some_and(|o| self.usable(t, o)))
            .count()
    }

    fn usable(&self, t: &Target, o: &PointObservation) -> bool {
        o.pixel.is_some_and(|p| p.is_finite())
            || (!t.contour && o.position.is_some_and(|p| p.is_finite() && p.z < 0.0))
    }

    /// Fits one frame (`obs[i]` is layout point `i`), warm-started from the previous tracked frame.
    pub fn fit(&mut self, obs: &[PointObservation]) -> FitResult {
        let used = if obs.len() == self.point_count {
            self.observed(obs)
        } else {
            0
        };
        if used < self.settings.min_points {
            self.reset();
            return self.lost(used);
        }
        let prev_au = self.state.as_ref().map(|s| s.au.clone());
        let mut iterations_total = 0;
        if let Some(mut state) = self.state.take() {
            let iterations = self.settings.iterations;
            let (it, residual) = self.solve(&mut state, obs, false, prev_au.as_deref(), iterations);
            iterations_total += it;
            if residual <= self.settings.max_residual_px {
                return self.accept(state, obs, residual, used, iterations_total, true);
            }
        }
        let mut state = self.initial_state(obs);
        let iterations = self.settings.cold_iterations;
        let (it, residual) = self.solve(&mut state, obs, false, None, iterations);
        iterations_total += it;
        if residual <= self.settings.max_residual_px {
            self.accept(state, obs, residual, used, iterations_total, false)
        } else {
            self.odd_warm = false;
            let mut r = self.lost(used);
            r.residual_px = residual;
            r.iterations = iterations_total;
            r
        }
    }

    /// A converged frame: with [`OddParts::AfterPose`], its odd parts fitted now (`warm`: the
    /// frame was warm-started from the previous one, whose odd parts then form a temporal prior).
    fn accept(
        &mut self,
        state: State,
        obs: &[PointObservation],
        residual_px: f64,
        used: usize,
        iterations: usize,
        warm: bool,
    ) -> FitResult {
        let (au_odd, residual_px) = if self.settings.odd == OddParts::AfterPose {
            let residual = self.fit_odd_after_pose(&state, obs, warm && self.odd_warm);
            self.odd_warm = true;
            (self.odd_after.to_vec(), residual)
        } else {
            (state.au[AUV_COUNT..].to_vec(), residual_px)
        };
        let r = FitResult {
            tracked: true,
            pose: pose_of(&state),
            au: state.au[..AUV_COUNT].to_vec(),
            au_odd,
            residual_px,
            points_used: used,
            iterations,
        };
        self.state = Some(state);
        r
    }

    fn lost(&self, used: usize) -> FitResult {
        FitResult {
            tracked: false,
            pose: Pose {
                rotation: DQuat::IDENTITY,
                translation: DVec3::ZERO,
                scale: 0.0,
            },
            au: vec![0.0; AUV_COUNT],
            au_odd: if self.settings.odd == OddParts::Off {
                Vec::new()
            } else {
                vec![0.0; AUV_COUNT]
            },
            residual_px: f64::NAN,
            points_used: used,
            iterations: 0,
        }
    }

    /// All model vertices posed and animated as `result` says (camera space, metres); `au_odd`
    /// are the odd parts' coefficients ([`FitResult::au_odd`], may be empty).
    pub fn vertices(&self, pose: &Pose, au: &[f64], au_odd: &[f64], out: &mut Vec<DVec3>) {
        out.clear();
        out.extend_from_slice(&self.model.vertices);
        for (unit, &c) in self.model.shape_units.iter().zip(&self.shape) {
            for &(v, d) in &unit.deltas {
                out[v] += d * c;
            }
        }
        for (unit, &c) in self.model.auvs().iter().zip(au) {
            for &(v, d) in &unit.deltas {
                out[v] += d * c;
            }
        }
        for (field, &c) in self.odd_dense.iter().zip(au_odd) {
            if c != 0.0 {
                for (p, d) in out.iter_mut().zip(field) {
                    *p += *d * c;
                }
            }
        }
        for p in out.iter_mut() {
            *p = pose.scale * (pose.rotation * *p) + pose.translation;
        }
    }

    /// Model position of a target under the current shape and `au`.
    fn model_point(&self, t: &Target, au: &[f64]) -> DVec3 {
        let mut m = t.base;
        for (d, c) in t.au.iter().zip(au) {
            m += *d * *c;
        }
        for (d, c) in t.shape.iter().zip(&self.shape) {
            m += *d * *c;
        }
        m
    }

    /// Cold start: identity rotation, scale and translation from centroids and spreads.
    fn initial_state(&self, obs: &[PointObservation]) -> State {
        let au = vec![0.0; self.au_len];
        let mut pos = Vec::new();
        let mut pix = Vec::new();
        for t in &self.targets {
            let Some(o) = obs.get(t.point) else { continue };
            let m = self.model_point(t, &au);
            if let Some(p) = o
                .position
                .filter(|p| p.is_finite() && p.z < 0.0 && !t.contour)
            {
                pos.push((m, p));
            }
            if let Some(p) = o.pixel.filter(|p| p.is_finite()) {
                pix.push((m, p));
            }
        }
        let (scale, translation) = if pos.len() >= 4 {
            let n = pos.len() as f64;
            let cm = pos.iter().map(|(m, _)| *m).sum::<DVec3>() / n;
            let co = pos.iter().map(|(_, p)| *p).sum::<DVec3>() / n;
            let sm: f64 = pos.iter().map(|(m, _)| (*m - cm).length_squared()).sum();
            let so: f64 = pos.iter().map(|(_, p)| (*p - co).length_squared()).sum();
            let s = if sm > 0.0 {
                (so / sm).sqrt()
            } else {
                self.settings.nominal_scale_m
            };
            (s, co - s * cm)
        } else {
            let n = pix.len().max(1) as f64;
            let cm = pix.iter().map(|(m, _)| *m).sum::<DVec3>() / n;
            let cp = pix.iter().map(|(_, p)| *p).sum::<DVec2>() / n;
            let sm: f64 = pix
                .iter()
                .map(|(m, _)| (*m - cm).truncate().length_squared())
                .sum();
            let sp: f64 = pix.iter().map(|(_, p)| (*p - cp).length_squared()).sum();
            let s = self.settings.nominal_scale_m;
            let depth = if sp > 0.0 {
                self.camera.focal_px * s * (sm / sp).sqrt()
            } else {
                1.0
            };
            (s, self.camera.back_project(cp, depth) - s * cm)
        };
        State {
            rotation: DMat3::IDENTITY,
            translation,
            log_scale: scale.max(1e-9).ln(),
            au,
        }
    }

    /// Runs LM on `state`; returns (iterations, RMS reprojection residual in pixels).
    fn solve(
        &mut self,
        state: &mut State,
        obs: &[PointObservation],
        fit_shape: bool,
        prev_au: Option<&[f64]>,
        iterations: usize,
    ) -> (usize, f64) {
        let nu = self.settings.units.len();
        let n = POSE_PARAMS + nu + if fit_shape { self.shape.len() } else { 0 };
        let mut cost = self.accumulate(state, obs, fit_shape, prev_au, n, false);
        let mut mu = 1e-3;
        let mut it = 0;
        let mut a = vec![0.0; n * n];
        let mut delta = vec![0.0; n];
        while it < iterations {
            it += 1;
            self.accumulate(state, obs, fit_shape, prev_au, n, true);
            let mut improved = false;
            for _ in 0..8 {
                a.copy_from_slice(&self.jtj[..n * n]);
                for i in 0..n {
                    a[i * n + i] += mu * a[i * n + i].max(1e-9) + 1e-12;
                    delta[i] = -self.jtr[i];
                }
                if !solve_spd(&mut a, &mut delta, n) {
                    mu *= 10.0;
                    continue;
                }
                let saved = (state.clone(), self.shape.clone());
                self.apply(state, &delta, fit_shape);
                let trial = self.accumulate(state, obs, fit_shape, prev_au, n, false);
                if trial.is_finite() && trial <= cost {
                    let gain = cost - trial;
                    cost = trial;
                    mu = (mu / 3.0).max(1e-9);
                    improved = gain > 1e-9 * cost.max(1e-12);
                    break;
                }
                *state = saved.0;
                self.shape = saved.1;
                mu *= 4.0;
            }
            if !improved {
                break;
            }
        }
        (it, self.reprojection_rms(state, obs, &[]))
    }

    fn apply(&mut self, state: &mut State, delta: &[f64], fit_shape: bool) {
        let w = DVec3::new(delta[0], delta[1], delta[2]);
        let r = DMat3::from_quat(DQuat::from_scaled_axis(w)) * state.rotation;
        // Re-orthonormalise through the quaternion so rounding never accumulates.
        state.rotation = DMat3::from_quat(DQuat::from_mat3(&r).normalize());
        state.translation += DVec3::new(delta[3], delta[4], delta[5]);
        state.log_scale += delta[6];
        let (lo, hi) = self.settings.au_bounds;
        let odd = self.settings.odd_bound;
        let nu = self.settings.units.len();
        for (col, &k) in self.settings.units.iter().enumerate() {
            let (lo, hi) = if k < AUV_COUNT { (lo, hi) } else { (-odd, odd) };
            state.au[k] = (state.au[k] + delta[POSE_PARAMS + col]).clamp(lo, hi);
        }
        if fit_shape {
            let (lo, hi) = self.settings.shape_bounds;
            for (j, s) in self.shape.iter_mut().enumerate() {
                *s = (*s + delta[POSE_PARAMS + nu + j]).clamp(lo, hi);
            }
        }
    }

    /// Cost (sum of squared weighted residuals); with `jacobian`, also fills `jtj` and `jtr`.
    fn accumulate(
        &mut self,
        state: &State,
        obs: &[PointObservation],
        fit_shape: bool,
        prev_au: Option<&[f64]>,
        n: usize,
        jacobian: bool,
    ) -> f64 {
        let mut jtj = std::mem::take(&mut self.jtj);
        let mut jtr = std::mem::take(&mut self.jtr);
        let mut row = std::mem::take(&mut self.row);
        if jacobian {
            jtj[..n * n].iter_mut().for_each(|x| *x = 0.0);
            jtr[..n].iter_mut().for_each(|x| *x = 0.0);
        }
        let s = state.log_scale.exp();
        let r = state.rotation;
        let f = self.camera.focal_px;
        let wz = self.settings.depth_weight;
        let huber = self.settings.huber_px;
        let mut cost = 0.0;
        let units = std::mem::take(&mut self.settings.units);
        let nu = units.len();
        // Jacobian of X (3 x n), column-major: jx[c] is dX/dp_c.
        let mut jx = [DVec3::ZERO; 64];
        for t in &self.targets {
            let Some(o) = obs.get(t.point) else { continue };
            let position = o
                .position
                .filter(|p| !t.contour && p.is_finite() && p.z < 0.0);
            let pixel = o.pixel.filter(|p| p.is_finite());
            if position.is_none() && pixel.is_none() {
                continue;
            }
            let m = self.model_point(t, &state.au);
            let y = s * (r * m);
            let x = y + state.translation;
            if jacobian {
                jx[0] = DVec3::X.cross(y);
                jx[1] = DVec3::Y.cross(y);
                jx[2] = DVec3::Z.cross(y);
                jx[3] = DVec3::X;
                jx[4] = DVec3::Y;
                jx[5] = DVec3::Z;
                jx[6] = y;
                for (col, &k) in units.iter().enumerate() {
                    jx[POSE_PARAMS + col] = s * (r * t.au[k]);
                }
                if fit_shape {
                    for (j, d) in t.shape.iter().enumerate() {
                        jx[POSE_PARAMS + nu + j] = s * (r * *d);
                    }
                }
            }
            let mut add = |res: f64, coef: DVec3, cost: &mut f64| {
                // Huber loss, by iteratively reweighted least squares.
                let (c, w) = huber_loss(res, huber);
                *cost += c;
                let res = res * w;
                if jacobian {
                    for c in 0..n {
                        row[c] = coef.dot(jx[c]);
                    }
                    for i in 0..n {
                        let ri = row[i];
                        if ri == 0.0 {
                            continue;
                        }
                        jtr[i] += ri * res;
                        for j in 0..=i {
                            jtj[i * n + j] += w * ri * row[j];
                        }
                    }
                }
            };
            if let Some(p) = position {
                let g = t.weight * f / (-p.z);
                let d = x - p;
                add(g * d.x, DVec3::new(g, 0.0, 0.0), &mut cost);
                add(g * d.y, DVec3::new(0.0, g, 0.0), &mut cost);
                add(g * wz * d.z, DVec3::new(0.0, 0.0, g * wz), &mut cost);
            } else if let Some(p) = pixel {
                for (res, coef) in pixel_rows(&self.camera, x, p, t.weight) {
                    add(res, coef, &mut cost);
                }
            }
        }
        // Priors: diagonal, so added straight to the normal equations.
        let mut prior = |i: usize, w: f64, res: f64, cost: &mut f64| {
            *cost += (w * res) * (w * res);
            if jacobian {
                jtj[i * n + i] += w * w;
                jtr[i] += w * w * res;
            }
        };
        for (col, &k) in units.iter().enumerate() {
            let a = state.au[k];
            let (ridge, smooth) = if k < AUV_COUNT {
                (self.settings.au_prior_px, self.settings.au_smooth_px)
            } else {
                (self.settings.odd_prior_px, self.settings.odd_smooth_px)
            };
            prior(POSE_PARAMS + col, ridge, a, &mut cost);
            if let Some(p) = prev_au.and_then(|p| p.get(k)) {
                prior(POSE_PARAMS + col, smooth, a - p, &mut cost);
            }
        }
        if fit_shape {
            for (j, sj) in self.shape.iter().enumerate() {
                prior(
                    POSE_PARAMS + nu + j,
                    self.settings.shape_prior_px,
                    *sj,
                    &mut cost,
                );
            }
        }
        self.settings.units = units;
        if jacobian {
            for i in 0..n {
                for j in 0..i {
                    jtj[j * n + i] = jtj[i * n + j];
                }
            }
        }
        self.jtj = jtj;
        self.jtr = jtr;
        self.row = row;
        cost
    }

    /// The pixel target `t` is fitted to in the image: the tracker's pixel, or a 3D point's
    /// projection (contour points have no usable depth).
    fn seen_pixel(&self, t: &Target, o: &PointObservation) -> Option<DVec2> {
        o.pixel.filter(|p| p.is_finite()).or_else(|| {
            o.position
                .filter(|p| !t.contour && p.is_finite() && p.z < 0.0)
                .map(|p| self.camera.project(p))
        })
    }

    /// Camera-space point of target `t` for the frame's pose and AUs plus the odd coefficients
    /// `odd` (one per `odd_units`; empty: none), with the pixel it is fitted to.
    fn image_point(
        &self,
        state: &State,
        t: &Target,
        o: &PointObservation,
        odd: &[f64],
    ) -> Option<(DVec3, DVec2)> {
        let seen = self.seen_pixel(t, o)?;
        let mut m = self.model_point(t, &state.au);
        for (&k, b) in self.odd_units.iter().zip(odd) {
            if let Some(d) = t.au.get(AUV_COUNT + k) {
                m += *d * *b;
            }
        }
        let x = state.log_scale.exp() * (state.rotation * m) + state.translation;
        Some((x, seen))
    }

    /// RMS image distance between the fitted targets (with the odd coefficients `odd`, see
    /// [`Fitter::image_point`]) and their observed pixels (or projected positions).
    fn reprojection_rms(&self, state: &State, obs: &[PointObservation], odd: &[f64]) -> f64 {
        let (mut sum, mut count) = (0.0, 0usize);
        for t in &self.targets {
            let Some(o) = obs.get(t.point) else { continue };
            if let Some((x, seen)) = self.image_point(state, t, o, odd) {
                sum += (self.camera.project(x) - seen).length_squared();
                count += 1;
            }
        }
        if count == 0 {
            f64::NAN
        } else {
            (sum / count as f64).sqrt()
        }
    }
}

/// Huber loss of a residual and its IRLS weight: quadratic up to `huber`, then linear.
fn huber_loss(res: f64, huber: f64) -> (f64, f64) {
    let a = res.abs();
    if a <= huber {
        (res * res, 1.0)
    } else {
        (huber * (2.0 * a - huber), huber / a)
    }
}

/// The two image residuals (x, y) of camera-space point `x` against pixel `seen`, weighted by
/// `w`, each with its gradient with respect to `x`.
fn pixel_rows(camera: &Camera, x: DVec3, seen: DVec2, w: f64) -> [(f64, DVec3); 2] {
    let f = camera.focal_px;
    let depth = (-x.z).max(1e-6);
    let q = camera.project(x);
    [
        (
            w * (q.x - seen.x),
            w * DVec3::new(f / depth, 0.0, f * x.x / (depth * depth)),
        ),
        (
            w * (q.y - seen.y),
            w * DVec3::new(0.0, -f / depth, -f * x.y / (depth * depth)),
        ),
    ]
}

fn pose_of(state: &State) -> Pose {
    Pose {
        rotation: DQuat::from_mat3(&state.rotation).normalize(),
        translation: state.translation,
        scale: state.log_scale.exp(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::candide::tests::model;

    fn vertex(point: usize, v: usize) -> ModelCorrespondence {
        ModelCorrespondence {
            point,
            vertex: Some(v),
            vertices: vec![],
            t: None,
            weight: 1.0,
            contour: false,
        }
    }

    fn eight() -> Vec<ModelCorrespondence> {
        [5, 7, 8, 20, 23, 53, 56, 31, 64, 10]
            .iter()
            .enumerate()
            .map(|(i, &v)| vertex(i, v))
            .collect()
    }

    fn fitter(c: &[ModelCorrespondence], settings: FitSettings) -> Result<Fitter, FitError> {
        Fitter::new(model(), c, 10, Camera::KINECT_V1_COLOUR, settings)
    }

    #[test]
    fn bad_correspondences_and_units_are_refused() {
        let mut c = eight();
        c[2] = vertex(12, 8);
        assert_eq!(
            fitter(&c, FitSettings::default()).unwrap_err(),
            FitError::PointOutOfRange {
                point: 12,
                count: 10
            }
        );
        let mut c = eight();
        c[2] = vertex(2, 113);
        assert_eq!(
            fitter(&c, FitSettings::default()).unwrap_err(),
            FitError::VertexOutOfRange {
                point: 2,
                vertex: 113,
                count: 113
            }
        );
        let mut c = eight();
        c[3].vertices = vec![1, 2];
        assert_eq!(
            fitter(&c, FitSettings::default()).unwrap_err(),
            FitError::Malformed { point: 3 }
        );
        assert_eq!(
            fitter(&eight()[..5], FitSettings::default()).unwrap_err(),
            FitError::TooFew(5)
        );
        let settings = FitSettings {
            units: vec![0, 11],
            ..FitSettings::default()
        };
        assert_eq!(
            fitter(&eight(), settings).unwrap_err(),
            FitError::UnitOutOfRange(11)
        );
    }

    #[test]
    fn vertices_follow_the_model_equation() {
        // X = s R (v0 + A alpha) + t, checked on vertex 8 (neutral (0, -0.526, 0.15), moved by AUV11 jaw
        // drop by (0, -0.26, -0.05) per unit, both from the file) for a 90 deg yaw.
        let f = fitter(&eight(), FitSettings::default()).unwrap();
        let pose = Pose {
            rotation: DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2),
            translation: DVec3::new(0.0, 0.0, -1.0),
            scale: 0.1,
        };
        let mut au = vec![0.0; AUV_COUNT];
        au[1] = 0.5;
        let mut out = Vec::new();
        f.vertices(&pose, &au, &[], &mut out);
        assert_eq!(out.len(), 113);
        let m = DVec3::new(0.0, -0.526, 0.15) + 0.5 * DVec3::new(0.0, -0.26, -0.05);
        // Yaw by +90 deg maps (x, y, z) to (z, y, -x).
        let expected = 0.1 * DVec3::new(m.z, m.y, -m.x) + DVec3::new(0.0, 0.0, -1.0);
        assert!(
            (out[8] - expected).length() < 1e-12,
            "{} vs {expected}",
            out[8]
        );
    }
}
