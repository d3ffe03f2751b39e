//! The AUs' left-right odd parts fitted after the pose ([`OddParts::AfterPose`], docs/fitter.md
//! "One-sided motion"): once the symmetric fit of a frame has converged, only the odd
//! coefficients are solved, with pose, scale, shape and the AUs held, on the image residual alone
//! (no depth term). The pose is then exactly the symmetric fit's, so the odd parts cannot trade off
//! against the head's yaw, and depth noise cannot drive them.

use super::{Fitter, PointObservation, State, huber_loss, pixel_rows};
use crate::candide::AUV_COUNT;
use crate::cholesky::solve_spd;

/// Whether and how the fitter fits the AUs' left-right odd parts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum OddParts {
    /// No odd parts: the fit is left-right symmetric (`mimic import --symmetric`).
    Off,
    /// Odd parts fitted jointly with pose and AUs; they trade off against the head's yaw and the
    /// fit fails more often on the shipped captures (docs/fitter.md).
    Joint,
    /// Odd parts fitted after the symmetric fit converged, on the image only, everything else held.
    #[default]
    AfterPose,
}

impl OddParts {
    /// `mimic import --fit`'s choice: [`OddParts::Off`] with `--symmetric`, else
    /// [`OddParts::AfterPose`].
    pub fn of_import(symmetric: bool) -> Self {
        if symmetric {
            Self::Off
        } else {
            Self::AfterPose
        }
    }
}

/// Gauss-Newton iterations of the odd-part solve: the image is nearly linear in the odd
/// coefficients once the pose is held, so it converges in two or three.
const ITERATIONS: usize = 6;
/// A step this small (coefficient units) ends the iterations.
const STEP_TOL: f64 = 1e-7;

impl Fitter {
    /// Fits the odd parts of the converged frame `state` into `self.odd_after` (`warm`: the
    /// previous frame's odd parts start the solve and form the temporal prior); returns the RMS
    /// reprojection residual (pixels) of the fit with them.
    pub(super) fn fit_odd_after_pose(
        &mut self,
        state: &State,
        obs: &[PointObservation],
        warm: bool,
    ) -> f64 {
        let n = self.odd_units.len().min(AUV_COUNT);
        let mut prev = [0.0; AUV_COUNT];
        for (p, &k) in prev.iter_mut().zip(&self.odd_units) {
            *p = if warm { self.odd_after[k] } else { 0.0 };
        }
        let mut beta = prev;
        let mut jtj = [0.0; AUV_COUNT * AUV_COUNT];
        let mut jtr = [0.0; AUV_COUNT];
        let prior = warm.then_some(&prev);
        let mut cost = self.odd_cost(state, obs, &beta[..n], prior, None);
        let bound = self.settings.odd_bound;
        for _ in 0..ITERATIONS {
            if n == 0 {
                break;
            }
            self.odd_cost(
                state,
                obs,
                &beta[..n],
                prior,
                Some((&mut jtj[..n * n], &mut jtr[..n])),
            );
            let mut delta = [0.0; AUV_COUNT];
            for (d, r) in delta.iter_mut().zip(&jtr[..n]) {
                *d = -r;
            }
            if !solve_spd(&mut jtj[..n * n], &mut delta[..n], n) {
                break;
            }
            // Backtrack on the step until the cost does not grow.
            let mut scale = 1.0;
            let mut moved = 0.0f64;
            for _ in 0..4 {
                let mut trial = beta;
                for (t, d) in trial[..n].iter_mut().zip(&delta) {
                    *t = (*t + scale * d).clamp(-bound, bound);
                }
                let c = self.odd_cost(state, obs, &trial[..n], prior, None);
                if c.is_finite() && c <= cost {
                    moved = trial[..n]
                        .iter()
                        .zip(&beta[..n])
                        .map(|(a, b)| (a - b).abs())
                        .fold(0.0, f64::max);
                    beta = trial;
                    cost = c;
                    break;
                }
                scale *= 0.5;
            }
            if moved < STEP_TOL {
                break;
            }
        }
        self.odd_after = [0.0; AUV_COUNT];
        for (&k, b) in self.odd_units.iter().zip(&beta) {
            self.odd_after[k] = *b;
        }
        self.reprojection_rms(state, obs, &beta[..n])
    }

    /// Huber cost of the weighted image residuals plus the odd priors; with `normal`, also the
    /// Gauss-Newton normal equations (IRLS weights) into it.
    fn odd_cost(
        &self,
        state: &State,
        obs: &[PointObservation],
        beta: &[f64],
        prev: Option<&[f64; AUV_COUNT]>,
        mut normal: Option<(&mut [f64], &mut [f64])>,
    ) -> f64 {
        let n = beta.len();
        if let Some((jtj, jtr)) = normal.as_mut() {
            jtj.iter_mut().for_each(|v| *v = 0.0);
            jtr.iter_mut().for_each(|v| *v = 0.0);
        }
        let s = state.log_scale.exp();
        let huber = self.settings.huber_px;
        let mut cost = 0.0;
        for t in &self.targets {
            let Some(o) = obs.get(t.point) else { continue };
            let Some((x, seen)) = self.image_point(state, t, o, beta) else {
                continue;
            };
            let rows = pixel_rows(&self.camera, x, seen, t.weight);
            for (res, coef) in rows {
                let (c, hw) = huber_loss(res, huber);
                cost += c;
                if let Some((jtj, jtr)) = normal.as_mut() {
                    let mut row = [0.0; AUV_COUNT];
                    for (r, &k) in row.iter_mut().zip(&self.odd_units).take(n) {
                        if let Some(d) = t.au.get(AUV_COUNT + k) {
                            *r = coef.dot(s * (state.rotation * *d));
                        }
                    }
                    for (i, &ri) in row[..n].iter().enumerate() {
                        if ri == 0.0 {
                            continue;
                        }
                        jtr[i] += hw * ri * res;
                        for (j, &rj) in row[..n].iter().enumerate() {
                            jtj[i * n + j] += hw * ri * rj;
                        }
                    }
                }
            }
        }
        let ridge = self.settings.odd_prior_px;
        let smooth = self.settings.odd_smooth_px;
        for (i, b) in beta.iter().enumerate() {
            let p = prev.map(|p| p[i]);
            cost += (ridge * b) * (ridge * b);
            if let Some(p) = p {
                cost += (smooth * (b - p)) * (smooth * (b - p));
            }
            if let Some((jtj, jtr)) = normal.as_mut() {
                jtj[i * n + i] += ridge * ridge;
                jtr[i] += ridge * ridge * b;
                if let Some(p) = p {
                    jtj[i * n + i] += smooth * smooth;
                    jtr[i] += smooth * smooth * (b - p);
                }
            }
        }
        cost
    }
}
