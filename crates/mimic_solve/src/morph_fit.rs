//! Blendshape weights from control displacements: bounded regularised least squares.
//!
//! `min_w |sum_k w_k D_k - d|^2 + sum_k lambda_k w_k^2 + 2 sum_k mu_k w_k
//! + sum_k tau_k (w_k - p_k)^2 + sum_(a,b) sigma_ab (w_a - w_b)^2` subject to `0 <= w_k <= 1`,
//! where `D_k` are the deltas of morph target `k` at the m controls and `p` the weights of the
//! previous fit on the same scratch ([`MorphTerms`]: ridge, L1 — linear, as `w >= 0` —, temporal
//! and pair terms). Every term is quadratic or linear, so they fold into the Gram matrix
//! `D^T D + diag(lambda) + sum sigma_ab (e_a - e_b)(e_a - e_b)^T`, built once, and the right-hand
//! side `D^T d - mu + diag(tau) p`, built per frame. Each frame runs projected Gauss-Seidel
//! (coordinate descent with clamping), which converges to the unique minimiser when the matrix is
//! positive definite (always when every `lambda_k > 0`).

use crate::SolveError;
use glam::Vec3;

/// Sweeps of projected Gauss-Seidel at most per frame.
const MAX_SWEEPS: usize = 500;
/// Stop when no weight moved more than this in a sweep.
const STEP_TOLERANCE: f64 = 1e-9;

/// A prepared morph-target fit (Gram matrix of the targets at the controls).
#[derive(Clone, Debug)]
pub struct MorphFit {
    targets: usize,
    controls: usize,
    /// Target deltas, target-major: `deltas[k * 3m + 3j + axis]`.
    deltas: Vec<f64>,
    /// `D^T D + diag(lambda) + pair terms`, k x k row-major.
    gram: Vec<f64>,
    /// L1 weight of each target, `mu_k` (subtracted from the right-hand side).
    l1: Vec<f64>,
    /// Temporal weight of each target, `tau_k`.
    temporal: Vec<f64>,
}

/// The terms of [`MorphFit`]'s objective besides the data term, per target (each vector empty,
/// meaning all zero, or one entry per target); all must be finite and `>= 0`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MorphTerms {
    /// `lambda_k`: adds `lambda_k w_k^2`.
    pub ridge: Vec<f64>,
    /// `mu_k`: adds `2 mu_k w_k` (the L1 norm, as `w_k >= 0`; an isolated exact target's weight
    /// drops by `mu_k / |D_k|^2`).
    pub l1: Vec<f64>,
    /// `tau_k`: adds `tau_k (w_k - p_k)^2`, `p` the previous fit's weights on the same scratch
    /// (nothing on a scratch's first fit).
    pub temporal: Vec<f64>,
    /// `(a, b, sigma)`: adds `sigma (w_a - w_b)^2` (a left/right pair kept alike).
    pub pairs: Vec<(usize, usize, f64)>,
}

/// Per-caller scratch for [`MorphFit::fit`]; also keeps the last weights as a warm start.
#[derive(Clone, Debug)]
pub struct MorphScratch {
    rhs: Vec<f64>,
    weights: Vec<f64>,
    /// Whether `weights` holds a previous fit (the temporal term's `p`).
    primed: bool,
}

impl MorphScratch {
    /// Forgets the previous fit: the next starts from all-zero weights with no temporal term,
    /// as on fresh scratch (allocates nothing).
    pub fn reset(&mut self) {
        self.weights.iter_mut().for_each(|w| *w = 0.0);
        self.primed = false;
    }
}

impl MorphFit {
    /// Prepares the fit from `targets[k][j]`, the delta of target `k` at control `j`.
    /// Adds `ridge |w|^2` to the data term.
    pub fn new(target_deltas_at_controls: &[Vec<Vec3>], ridge: f64) -> Result<Self, SolveError> {
        let terms = MorphTerms {
            ridge: vec![ridge; target_deltas_at_controls.len()],
            ..MorphTerms::default()
        };
        Self::with_terms(target_deltas_at_controls, &terms)
    }

    /// Prepares the fit from `targets[k][j]`, the delta of target `k` at control `j`, with the
    /// objective's other `terms`.
    pub fn with_terms(
        target_deltas_at_controls: &[Vec<Vec3>],
        terms: &MorphTerms,
    ) -> Result<Self, SolveError> {
        let targets = target_deltas_at_controls.len();
        let per_target = |what: &str, v: &[f64]| -> Result<Vec<f64>, SolveError> {
            if v.is_empty() {
                return Ok(vec![0.0; targets]);
            }
            if v.len() != targets {
                return Err(SolveError::InvalidSetting(format!(
                    "morph fit {what}: {} values for {targets} targets",
                    v.len()
                )));
            }
            match v.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
                Some(x) => Err(SolveError::InvalidSetting(format!(
                    "morph fit {what} {x} must be finite and >= 0"
                ))),
                None => Ok(v.to_vec()),
            }
        };
        let ridge = per_target("ridge", &terms.ridge)?;
        let l1 = per_target("l1", &terms.l1)?;
        let temporal = per_target("temporal", &terms.temporal)?;
        for &(a, b, sigma) in &terms.pairs {
            if a >= targets || b >= targets || a == b || !(sigma.is_finite() && sigma >= 0.0) {
                return Err(SolveError::InvalidSetting(format!(
                    "morph fit pair ({a}, {b}, {sigma}): two distinct targets of {targets}, weight finite and >= 0"
                )));
            }
        }
        let controls = target_deltas_at_controls.first().map_or(0, Vec::len);
        let mut deltas = Vec::with_capacity(targets * 3 * controls);
        for (k, t) in target_deltas_at_controls.iter().enumerate() {
            if t.len() != controls {
                return Err(SolveError::MorphTargetLength {
                    target: k,
                    got: t.len(),
                    expected: controls,
                });
            }
            if let Some(j) = t.iter().position(|v| !v.is_finite()) {
                return Err(SolveError::MorphTargetNonFinite {
                    target: k,
                    control: j,
                });
            }
            deltas.extend(t.iter().flat_map(|v| v.as_dvec3().to_array()));
        }
        let len = 3 * controls;
        let mut gram = vec![0.0; targets * targets];
        for a in 0..targets {
            for b in 0..=a {
                let da = &deltas[a * len..(a + 1) * len];
                let db = &deltas[b * len..(b + 1) * len];
                let g: f64 = da.iter().zip(db).map(|(x, y)| x * y).sum();
                gram[a * targets + b] = g;
                gram[b * targets + a] = g;
            }
            gram[a * targets + a] += ridge[a];
        }
        for &(a, b, sigma) in &terms.pairs {
            gram[a * targets + a] += sigma;
            gram[b * targets + b] += sigma;
            gram[a * targets + b] -= sigma;
            gram[b * targets + a] -= sigma;
        }
        Ok(Self {
            targets,
            controls,
            deltas,
            gram,
            l1,
            temporal,
        })
    }

    /// Number of morph targets (length of the weights).
    pub fn target_count(&self) -> usize {
        self.targets
    }

    /// Number of controls (length of `d`).
    pub fn control_count(&self) -> usize {
        self.controls
    }

    /// Fresh scratch for [`MorphFit::fit`], starting from all-zero weights.
    pub fn scratch(&self) -> MorphScratch {
        MorphScratch {
            rhs: vec![0.0; self.targets],
            weights: vec![0.0; self.targets],
            primed: false,
        }
    }

    /// Fits weights in [0, 1] to control displacements `d`; allocates nothing.
    ///
    /// Starts from the weights of the previous call on the same scratch (converges to the same
    /// minimiser, faster on smooth sequences), which are also the temporal term's `p` (no
    /// temporal term on a fresh scratch). Non-finite entries of `d` count as zero.
    ///
    /// # Panics
    /// If `d.len() != control_count()`, `weights_out.len() != target_count()`, or the scratch was made
    /// by a fit with another target count.
    pub fn fit(&self, d: &[Vec3], scratch: &mut MorphScratch, weights_out: &mut [f32]) {
        let k = self.targets;
        assert_eq!(
            d.len(),
            self.controls,
            "MorphFit::fit: wrong number of control displacements"
        );
        assert_eq!(
            weights_out.len(),
            k,
            "MorphFit::fit: wrong number of weights"
        );
        assert!(
            scratch.rhs.len() == k && scratch.weights.len() == k,
            "MorphFit::fit: foreign scratch"
        );
        let len = 3 * self.controls;
        for (t, r) in scratch.rhs.iter_mut().enumerate() {
            let dt = &self.deltas[t * len..(t + 1) * len];
            *r = dt
                .chunks_exact(3)
                .zip(d)
                .map(|(c, v)| {
                    let v = if v.is_finite() {
                        v.as_dvec3()
                    } else {
                        glam::DVec3::ZERO
                    };
                    c[0] * v.x + c[1] * v.y + c[2] * v.z
                })
                .sum();
        }
        // The L1 term's gradient and the temporal term's pull towards the previous fit.
        let primed = scratch.primed;
        for ((r, (mu, tau)), p) in scratch
            .rhs
            .iter_mut()
            .zip(self.l1.iter().zip(&self.temporal))
            .zip(&scratch.weights)
        {
            *r -= mu;
            if primed {
                *r += tau * p;
            }
        }
        scratch.primed = true;
        let w = &mut scratch.weights;
        for _ in 0..MAX_SWEEPS {
            let mut moved = 0f64;
            for t in 0..k {
                let g = &self.gram[t * k..(t + 1) * k];
                let tau = if primed { self.temporal[t] } else { 0.0 };
                let diag = g[t] + tau;
                if diag <= 0.0 {
                    // A zero target with no ridge: any weight fits equally; keep 0.
                    w[t] = 0.0;
                    continue;
                }
                let grad: f64 = g.iter().zip(w.iter()).map(|(a, b)| a * b).sum::<f64>()
                    + tau * w[t]
                    - scratch.rhs[t];
                let new = (w[t] - grad / diag).clamp(0.0, 1.0);
                moved = moved.max((new - w[t]).abs());
                w[t] = new;
            }
            if moved <= STEP_TOLERANCE {
                break;
            }
        }
        for (o, v) in weights_out.iter_mut().zip(w.iter()) {
            *o = *v as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use mimic_testkit::lcg;

    fn targets(seed: &mut u64, k: usize, m: usize) -> Vec<Vec<Vec3>> {
        (0..k)
            .map(|_| {
                (0..m)
                    .map(|_| Vec3::new(lcg(seed), lcg(seed), lcg(seed)))
                    .collect()
            })
            .collect()
    }

    fn combine(t: &[Vec<Vec3>], w: &[f32]) -> Vec<Vec3> {
        let m = t[0].len();
        (0..m)
            .map(|j| t.iter().zip(w).map(|(tk, wk)| tk[j] * *wk).sum())
            .collect()
    }

    #[test]
    fn recovers_known_weights_inside_the_box() {
        let mut seed = 11;
        let t = targets(&mut seed, 6, 38);
        let truth = [0.0, 0.25, 0.5, 1.0, 0.8, 0.1];
        let d = combine(&t, &truth);
        let fit = MorphFit::new(&t, 0.0).unwrap();
        let mut s = fit.scratch();
        let mut w = [0f32; 6];
        fit.fit(&d, &mut s, &mut w);
        // Exact, well-conditioned data (random 114 x 6): error ~ f32 rounding of d, 1e-5 is generous.
        for (a, b) in w.iter().zip(&truth) {
            assert!((a - b).abs() < 1e-5, "{w:?}");
        }
    }

    #[test]
    fn clamps_weights_outside_the_box() {
        let mut seed = 5;
        // Orthogonal targets: the bounded solution is the clamped unbounded one.
        let m = 4;
        let mut t = vec![vec![Vec3::ZERO; m]; 3];
        t[0][0] = Vec3::X;
        t[1][1] = Vec3::Y;
        t[2][2] = Vec3::Z;
        let _ = lcg(&mut seed);
        let d = combine(&t, &[1.7, -0.4, 0.3]);
        let fit = MorphFit::new(&t, 0.0).unwrap();
        let mut s = fit.scratch();
        let mut w = [0.5f32; 3];
        fit.fit(&d, &mut s, &mut w);
        assert!(
            (w[0] - 1.0).abs() < 1e-6 && w[1].abs() < 1e-6 && (w[2] - 0.3).abs() < 1e-6,
            "{w:?}"
        );
    }

    #[test]
    fn ridge_shrinks_as_predicted() {
        // One target t, d = t: unbounded minimiser w = |t|^2 / (|t|^2 + ridge).
        let t = vec![vec![Vec3::new(1.0, 2.0, 2.0)]];
        let fit = MorphFit::new(&t, 9.0).unwrap();
        let mut s = fit.scratch();
        let mut w = [0f32];
        fit.fit(&t[0], &mut s, &mut w);
        assert!((w[0] - 0.5).abs() < 1e-6, "{w:?}");
    }

    /// The objective of [`MorphFit::with_terms`] written out term by term, and its gradient,
    /// from the deltas themselves (no Gram matrix): the reference the fit is checked against.
    struct Objective<'a> {
        t: &'a [Vec<Vec3>],
        d: &'a [Vec3],
        terms: &'a MorphTerms,
        prev: Option<&'a [f64]>,
    }

    impl Objective<'_> {
        fn residual(&self, w: &[f64]) -> Vec<glam::DVec3> {
            (0..self.d.len())
                .map(|j| {
                    self.t
                        .iter()
                        .zip(w)
                        .map(|(tk, wk)| tk[j].as_dvec3() * *wk)
                        .sum::<glam::DVec3>()
                        - self.d[j].as_dvec3()
                })
                .collect()
        }

        fn gradient(&self, w: &[f64]) -> Vec<f64> {
            let r = self.residual(w);
            let k = w.len();
            let mut g: Vec<f64> = (0..k)
                .map(|a| {
                    let data: f64 = self.t[a]
                        .iter()
                        .zip(&r)
                        .map(|(x, y)| 2.0 * x.as_dvec3().dot(*y))
                        .sum();
                    let mut v = data + 2.0 * self.terms.ridge[a] * w[a] + 2.0 * self.terms.l1[a];
                    if let Some(p) = self.prev {
                        v += 2.0 * self.terms.temporal[a] * (w[a] - p[a]);
                    }
                    v
                })
                .collect();
            for &(a, b, s) in &self.terms.pairs {
                g[a] += 2.0 * s * (w[a] - w[b]);
                g[b] -= 2.0 * s * (w[a] - w[b]);
            }
            g
        }

        /// Projected gradient descent from 0 with step `1 / L`, `L` the trace of the Hessian
        /// (at least its largest eigenvalue), until the contraction `(1 - mu / L)^n` (`mu` a
        /// lower bound of the smallest eigenvalue) is below 1e-13.
        fn minimise(&self, mu: f64) -> Vec<f64> {
            let k = self.t.len();
            let mut trace: f64 = (0..k)
                .map(|a| {
                    let dd: f64 = self.t[a]
                        .iter()
                        .map(|v| v.as_dvec3().length_squared())
                        .sum();
                    2.0 * (dd + self.terms.ridge[a])
                        + if self.prev.is_some() {
                            2.0 * self.terms.temporal[a]
                        } else {
                            0.0
                        }
                })
                .sum();
            trace += self.terms.pairs.iter().map(|p| 4.0 * p.2).sum::<f64>();
            let n = ((1e-13f64).ln() / (1.0 - 2.0 * mu / trace).ln()).ceil() as usize;
            assert!(n < 5_000_000, "reference too slow: {n} steps");
            let mut w = vec![0.0; k];
            for _ in 0..n {
                let g = self.gradient(&w);
                for (x, gx) in w.iter_mut().zip(g) {
                    *x = (*x - gx / trace).clamp(0.0, 1.0);
                }
            }
            w
        }
    }

    #[test]
    fn every_term_matches_a_projected_gradient_reference() {
        let mut seed = 41;
        let mut bounded = 0;
        for case in 0..6 {
            // Few controls (one or two: 3 or 6 coordinates for 5 targets), so the terms decide.
            let (k, m) = (5, 1 + case % 2);
            let t = targets(&mut seed, k, m);
            let mut per = |scale: f32| -> Vec<f64> {
                (0..k)
                    .map(|_| f64::from(scale * (lcg(&mut seed) + 1.0)))
                    .collect()
            };
            let terms = MorphTerms {
                ridge: per(0.3),
                l1: per(0.2),
                temporal: per(0.5),
                pairs: vec![(0, 1, 0.4), (2, 3, 0.8 * case as f64)],
            };
            let fit = MorphFit::with_terms(&t, &terms).unwrap();
            let mut s = fit.scratch();
            let mut w = [0f32; 5];
            let mut prev: Option<Vec<f64>> = None;
            for frame in 0..2 {
                // Displacements of weights partly outside the box, so bounds are active.
                let truth: Vec<f32> = (0..k).map(|_| 0.3 + 0.9 * lcg(&mut seed)).collect();
                let d = combine(&t, &truth);
                fit.fit(&d, &mut s, &mut w);
                let objective = Objective {
                    t: &t,
                    d: &d,
                    terms: &terms,
                    prev: prev.as_deref(),
                };
                // The data and pair terms are positive semi-definite: the ridge (and the
                // temporal term from the second fit on) bound the smallest eigenvalue below.
                let mu = (0..k)
                    .map(|a| terms.ridge[a] + if frame > 0 { terms.temporal[a] } else { 0.0 })
                    .fold(f64::INFINITY, f64::min);
                let want = objective.minimise(mu);
                // Gauss-Seidel stops after a sweep that moved no weight more than 1e-9: then each
                // coordinate's projected gradient (half the objective's) is at most 1e-9 times its
                // row of the half-Hessian H (absolute sum, bounded by `row`), so the distance to the
                // minimiser is at most sqrt(k) 1e-9 row / mu; the reference stops at 1e-13 of its
                // start, and the output is rounded to f32.
                let row: f64 = (0..k)
                    .map(|a| {
                        let dots: f64 = (0..k)
                            .map(|b| {
                                t[a].iter()
                                    .zip(&t[b])
                                    .map(|(x, y)| x.dot(*y).abs() as f64)
                                    .sum::<f64>()
                            })
                            .sum();
                        dots + terms.ridge[a] + terms.temporal[a] + 2.0 * 0.8 * case as f64 + 0.8
                    })
                    .fold(0.0, f64::max);
                let tol = (k as f64).sqrt() * 1e-9 * row / mu + 1e-12 + f64::from(f32::EPSILON);
                for (a, b) in w.iter().zip(&want) {
                    assert!(
                        (f64::from(*a) - b).abs() <= tol,
                        "case {case} frame {frame}: {w:?} vs {want:?} (tol {tol})"
                    );
                }
                bounded += want.iter().filter(|x| **x == 0.0 || **x == 1.0).count();
                prev = Some(want);
            }
        }
        // Weights at a bound: the box is checked too, not only the interior.
        assert!(bounded >= 6, "{bounded} weights at a bound");
    }

    #[test]
    fn terms_shift_a_lone_target_as_their_formulas_say() {
        // One target t with |t|^2 = 9, d = a t: the unbounded minimiser of
        // 9 (w - a)^2 + lambda w^2 + 2 mu w + tau (w - p)^2 is (9 a - mu + tau p) / (9 + lambda + tau).
        let t = vec![vec![Vec3::new(1.0, 2.0, 2.0)]];
        let (lambda, mu, tau) = (0.9, 1.8, 4.5);
        let terms = MorphTerms {
            ridge: vec![lambda],
            l1: vec![mu],
            temporal: vec![tau],
            pairs: Vec::new(),
        };
        let fit = MorphFit::with_terms(&t, &terms).unwrap();
        let mut s = fit.scratch();
        let mut w = [0f32];
        let a = 0.8;
        fit.fit(&[t[0][0] * a], &mut s, &mut w);
        // First fit: no previous weights, so no temporal term.
        let first = (9.0 * f64::from(a) - mu) / (9.0 + lambda);
        assert!((f64::from(w[0]) - first).abs() < 1e-6, "{w:?} vs {first}");
        fit.fit(&[t[0][0] * 0.3], &mut s, &mut w);
        let second = (9.0 * 0.3 - mu + tau * first) / (9.0 + lambda + tau);
        assert!((f64::from(w[0]) - second).abs() < 1e-6, "{w:?} vs {second}");
        // The L1 term holds a small weight at exactly 0 (soft threshold): 9 a < mu.
        let mut s = fit.scratch();
        fit.fit(&[t[0][0] * 0.15], &mut s, &mut w);
        assert_eq!(w[0], 0.0);
    }

    #[test]
    fn a_pair_term_pulls_two_orthogonal_targets_together() {
        // Orthogonal unit targets, d = (a, b): minimise (x - a)^2 + (y - b)^2 + s (x - y)^2;
        // x + y = a + b and x - y = (a - b) / (1 + 2 s).
        let t = vec![vec![Vec3::X], vec![Vec3::Y]];
        let s = 1.5;
        let terms = MorphTerms {
            pairs: vec![(0, 1, s)],
            ..MorphTerms::default()
        };
        let fit = MorphFit::with_terms(&t, &terms).unwrap();
        let mut scratch = fit.scratch();
        let mut w = [0f32; 2];
        let (a, b) = (0.9, 0.3);
        fit.fit(&[Vec3::new(a, b, 0.0)], &mut scratch, &mut w);
        let diff = (a - b) / (1.0 + 2.0 * s as f32);
        let want = [(a + b + diff) / 2.0, (a + b - diff) / 2.0];
        for (x, y) in w.iter().zip(want) {
            assert!((x - y).abs() < 1e-6, "{w:?} vs {want:?}");
        }
    }

    #[test]
    fn rejects_bad_targets() {
        assert!(matches!(
            MorphFit::new(&[vec![Vec3::X], vec![]], 0.1),
            Err(SolveError::MorphTargetLength { .. })
        ));
        assert!(matches!(
            MorphFit::new(&[vec![Vec3::NAN]], 0.1),
            Err(SolveError::MorphTargetNonFinite { .. })
        ));
        assert!(matches!(
            MorphFit::new(&[vec![Vec3::X]], -1.0),
            Err(SolveError::InvalidSetting(_))
        ));
        let bad = |terms: MorphTerms| {
            matches!(
                MorphFit::with_terms(&[vec![Vec3::X], vec![Vec3::Y]], &terms),
                Err(SolveError::InvalidSetting(_))
            )
        };
        assert!(bad(MorphTerms {
            l1: vec![0.1],
            ..MorphTerms::default()
        }));
        assert!(bad(MorphTerms {
            temporal: vec![0.1, f64::NAN],
            ..MorphTerms::default()
        }));
        assert!(bad(MorphTerms {
            pairs: vec![(0, 2, 1.0)],
            ..MorphTerms::default()
        }));
        assert!(bad(MorphTerms {
            pairs: vec![(1, 1, 1.0)],
            ..MorphTerms::default()
        }));
    }
}
