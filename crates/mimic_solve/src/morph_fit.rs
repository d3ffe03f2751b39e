//! Blendshape weights from control displacements: bounded ridge least squares.
//!
//! `min_w |sum_k w_k D_k - d|^2 + ridge |w|^2` subject to `0 <= w_k <= 1`, where `D_k` are the
//! deltas of morph target `k` at the m controls. The Gram matrix is built once; each frame runs
//! projected Gauss-Seidel (coordinate descent with clamping), which converges to the unique
//! minimiser when the Gram matrix is positive definite (always when `ridge > 0`).

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
    /// `D^T D + ridge I`, k x k row-major.
    gram: Vec<f64>,
}

/// Per-caller scratch for [`MorphFit::fit`]; also keeps the last weights as a warm start.
#[derive(Clone, Debug)]
pub struct MorphScratch {
    rhs: Vec<f64>,
    weights: Vec<f64>,
}

impl MorphFit {
    /// Prepares the fit from `targets[k][j]`, the delta of target `k` at control `j`.
    pub fn new(target_deltas_at_controls: &[Vec<Vec3>], ridge: f64) -> Result<Self, SolveError> {
        if !(ridge.is_finite() && ridge >= 0.0) {
            return Err(SolveError::InvalidSetting(format!(
                "morph fit ridge {ridge} must be finite and >= 0"
            )));
        }
        let targets = target_deltas_at_controls.len();
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
            gram[a * targets + a] += ridge;
        }
        Ok(Self {
            targets,
            controls,
            deltas,
            gram,
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
        }
    }

    /// Fits weights in [0, 1] to control displacements `d`; allocates nothing.
    ///
    /// Starts from the weights of the previous call on the same scratch (converges to the same
    /// minimiser, faster on smooth sequences). Non-finite entries of `d` count as zero.
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
        let w = &mut scratch.weights;
        for _ in 0..MAX_SWEEPS {
            let mut moved = 0f64;
            for t in 0..k {
                let g = &self.gram[t * k..(t + 1) * k];
                let diag = g[t];
                if diag <= 0.0 {
                    // A zero target with no ridge: any weight fits equally; keep 0.
                    w[t] = 0.0;
                    continue;
                }
                let grad: f64 =
                    g.iter().zip(w.iter()).map(|(a, b)| a * b).sum::<f64>() - scratch.rhs[t];
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
    }
}
