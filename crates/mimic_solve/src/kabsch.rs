//! Least-squares similarity between point sets (Kabsch / Umeyama), via Horn's quaternion method.

#![allow(
    clippy::needless_range_loop,
    reason = "the Jacobi sweeps index rows and columns of a 4x4 matrix as in the textbook formulas"
)]

use glam::{DQuat, DVec3, Quat, Vec3};
use mimic_types::HeadPose;

/// Best `pose` with `dst ≈ pose.apply(src)` in the least-squares sense: proper rotation (det +1),
/// translation, and (when `allow_scale`) a uniform scale (Umeyama); otherwise scale is 1.
///
/// Computed in f64 with Horn's quaternion method (largest eigenvector of a 4x4 symmetric matrix
/// by Jacobi sweeps), which gives a proper rotation by construction and allocates nothing.
/// `None` when the lengths differ, there are fewer than 3 points, a point is not finite, or the
/// rotation is not determined (all source points coincide or lie on one line).
pub fn fit_similarity(src: &[Vec3], dst: &[Vec3], allow_scale: bool) -> Option<HeadPose> {
    if src.len() != dst.len() || src.len() < 3 {
        return None;
    }
    if !src.iter().chain(dst).all(|p| p.is_finite()) {
        return None;
    }
    let inv_n = 1.0 / src.len() as f64;
    let mu_s = src.iter().fold(DVec3::ZERO, |a, p| a + p.as_dvec3()) * inv_n;
    let mu_d = dst.iter().fold(DVec3::ZERO, |a, p| a + p.as_dvec3()) * inv_n;
    // Cross-covariance S[a][b] = sum src'_a dst'_b, and the source's spread.
    let mut s = [[0f64; 3]; 3];
    let mut src_sq = 0.0;
    for (p, q) in src.iter().zip(dst) {
        let a = p.as_dvec3() - mu_s;
        let b = q.as_dvec3() - mu_d;
        src_sq += a.length_squared();
        for (r, ar) in s.iter_mut().zip(a.to_array()) {
            for (c, bc) in r.iter_mut().zip(b.to_array()) {
                *c += ar * bc;
            }
        }
    }
    if src_sq <= 0.0 {
        return None;
    }
    // Horn (1987): the unit quaternion (w, x, y, z) maximising sum dst' . R src' is the top
    // eigenvector of N; the maximum is its eigenvalue.
    let mut nm = horn_matrix(s);
    let (top, v) = match top_eigen_newton(&nm) {
        Some(found) => found,
        None => top_eigen_jacobi(&mut nm)?,
    };
    // The quaternion's sign is free; w >= 0 keeps it continuous from frame to frame.
    let sign = if v[0] < 0.0 { -1.0 } else { 1.0 };
    let q = DQuat::from_xyzw(sign * v[1], sign * v[2], sign * v[3], sign * v[0]).normalize();
    let scale = if allow_scale { top / src_sq } else { 1.0 };
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    let translation = mu_d - q * (mu_s * scale);
    Some(HeadPose {
        rotation: Quat::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32).normalize(),
        translation: translation.as_vec3(),
        scale: scale as f32,
    })
}

/// Horn's symmetric, traceless 4x4 matrix of the cross-covariance `s` (`s[a][b] = sum src'_a dst'_b`).
fn horn_matrix(s: [[f64; 3]; 3]) -> [[f64; 4]; 4] {
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = s;
    [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ]
}

/// Top eigenpair of Horn's matrix `n` (symmetric, traceless) by Newton's method on its
/// characteristic polynomial and the adjugate of `n - top I` (the idea of Theobald's QCP,
/// Acta Cryst. A61, 2005); `None` unless the top eigenvalue is well separated from the next, when
/// the caller falls back to Jacobi sweeps.
///
/// With `tr n = 0`, `det(n - l I) = l^4 - (p2 / 2) l^2 - (p3 / 3) l + det n` (`pk = tr n^k`,
/// Newton's identities). Started at `sqrt(p2)`, which bounds every `|eigenvalue|`, Newton's
/// iterates fall monotonically onto the top eigenvalue (the polynomial is increasing and convex
/// right of it). There the adjugate is `-P'(top) v v^T`; its largest diagonal entry picks the
/// column that is `v` up to scale. Accepted only when `P'(top) >= 1e-3 sqrt(p2)^3`: then the gap
/// to the next eigenvalue is at least `P'(top) / (2 sqrt(p2))^2 >= 2.5e-4 sqrt(p2)`, far above
/// the `1e-9` of the scale at which the rotation counts as undetermined, and the column's
/// relative rounding error is about `4e3` f64 epsilons.
fn top_eigen_newton(n: &[[f64; 4]; 4]) -> Option<(f64, [f64; 4])> {
    let mut p2 = 0.0;
    let mut p3 = 0.0;
    for i in 0..4 {
        for j in 0..4 {
            p2 += n[i][j] * n[i][j];
            let n2_ji: f64 = (0..4).map(|k| n[j][k] * n[k][i]).sum();
            p3 += n[i][j] * n2_ji;
        }
    }
    let bound = p2.sqrt();
    if !(bound.is_finite() && bound > 0.0) {
        return None;
    }
    let (c2, c1, c0) = (-0.5 * p2, -p3 / 3.0, det4(n));
    let mut l = bound;
    let mut slope = 0.0;
    for _ in 0..100 {
        let value = ((l * l + c2) * l + c1) * l + c0;
        slope = (4.0 * l * l + 2.0 * c2) * l + c1;
        if slope.is_nan() || slope <= 0.0 {
            break;
        }
        let next = l - value / slope;
        // Monotone in exact arithmetic: a step that does not go down is rounding at the root.
        if next.is_nan() || next >= l {
            break;
        }
        l = next;
    }
    if slope.is_nan() || slope < 1e-3 * bound * bound * bound {
        return None;
    }
    let mut m = *n;
    for (i, row) in m.iter_mut().enumerate() {
        row[i] -= l;
    }
    let cofactor = |r: usize, c: usize| -> f64 {
        let rows: [usize; 3] = others(r);
        let cols: [usize; 3] = others(c);
        let a = |i: usize, j: usize| m[rows[i]][cols[j]];
        let minor = a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1))
            - a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0))
            + a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
        if (r + c).is_multiple_of(2) {
            minor
        } else {
            -minor
        }
    };
    let mut best = 0;
    let mut best_abs = -1.0;
    for j in 0..4 {
        let d = cofactor(j, j).abs();
        if d > best_abs {
            best = j;
            best_abs = d;
        }
    }
    let v = [
        cofactor(best, 0),
        cofactor(best, 1),
        cofactor(best, 2),
        cofactor(best, 3),
    ];
    let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !(norm.is_finite() && norm > 0.0) {
        return None;
    }
    Some((l, v.map(|x| x / norm)))
}

/// The three indices of 0..4 other than `i`, ascending.
fn others(i: usize) -> [usize; 3] {
    match i {
        0 => [1, 2, 3],
        1 => [0, 2, 3],
        2 => [0, 1, 3],
        _ => [0, 1, 2],
    }
}

/// Determinant of a 4x4 matrix by 2x2 minors of its first two and last two rows (Laplace).
fn det4(a: &[[f64; 4]; 4]) -> f64 {
    let lo = |c0: usize, c1: usize| a[0][c0] * a[1][c1] - a[0][c1] * a[1][c0];
    let hi = |c0: usize, c1: usize| a[2][c0] * a[3][c1] - a[2][c1] * a[3][c0];
    lo(0, 1) * hi(2, 3) - lo(0, 2) * hi(1, 3) + lo(0, 3) * hi(1, 2) + lo(1, 2) * hi(0, 3)
        - lo(1, 3) * hi(0, 2)
        + lo(2, 3) * hi(0, 1)
}

/// Top eigenpair of Horn's matrix by Jacobi sweeps (any gap); `None` when the top eigenvalue is
/// double up to `1e-9` of the largest `|eigenvalue|` (collinear sources leave the rotation about
/// their line free).
fn top_eigen_jacobi(nm: &mut [[f64; 4]; 4]) -> Option<(f64, [f64; 4])> {
    let (vals, vecs) = jacobi_eigen4(nm);
    let mut order = [0usize, 1, 2, 3];
    order.sort_by(|&a, &b| vals[b].total_cmp(&vals[a]));
    let (top, second) = (vals[order[0]], vals[order[1]]);
    let scale_of_n = vals.iter().fold(0f64, |a, v| a.max(v.abs()));
    if scale_of_n <= 0.0 || top - second <= 1e-9 * scale_of_n {
        return None;
    }
    let k = order[0];
    Some((top, [vecs[0][k], vecs[1][k], vecs[2][k], vecs[3][k]]))
}

/// Eigen-decomposition of a symmetric 4x4 matrix by cyclic Jacobi rotations: returns the eigenvalues
/// and the eigenvectors as columns (`vecs[row][k]` is component `row` of eigenvector `k`).
fn jacobi_eigen4(a: &mut [[f64; 4]; 4]) -> ([f64; 4], [[f64; 4]; 4]) {
    let mut v = [[0f64; 4]; 4];
    for (i, r) in v.iter_mut().enumerate() {
        r[i] = 1.0;
    }
    for _sweep in 0..50 {
        let off: f64 = (0..4)
            .flat_map(|p| (p + 1..4).map(move |q| (p, q)))
            .map(|(p, q)| a[p][q] * a[p][q])
            .sum();
        let total: f64 = a.iter().flatten().map(|x| x * x).sum();
        if off <= 1e-30 * total.max(f64::MIN_POSITIVE) {
            break;
        }
        for p in 0..4 {
            for q in p + 1..4 {
                if a[p][q] == 0.0 {
                    continue;
                }
                // Rotation that zeroes a[p][q] (Golub & Van Loan, sym.schur2).
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..4 {
                    let (akp, akq) = (a[k][p], a[k][q]);
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for k in 0..4 {
                    let (apk, aqk) = (a[p][k], a[q][k]);
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for row in v.iter_mut() {
                    let (vp, vq) = (row[p], row[q]);
                    row[p] = c * vp - s * vq;
                    row[q] = s * vp + c * vq;
                }
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2], a[3][3]], v)
}

#[cfg(test)]
mod tests {
    use super::*;

    use mimic_testkit::lcg;

    /// Distance between rotations as quaternions up to sign (f32 `angle_between` goes through
    /// `acos` near 1, which only resolves ~1e-3 rad).
    fn quat_distance(a: Quat, b: Quat) -> f32 {
        (a - b).length().min((a + b).length())
    }

    fn cloud(seed: &mut u64, n: usize) -> Vec<Vec3> {
        (0..n)
            .map(|_| Vec3::new(lcg(seed), lcg(seed), lcg(seed)) * 0.1)
            .collect()
    }

    #[test]
    fn recovers_known_similarity() {
        let mut seed = 42;
        for case in 0..20 {
            let src = cloud(&mut seed, 12);
            let axis = Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)).normalize();
            // Include angles near pi, where naive SVD sign handling tends to fail.
            let angle = if case == 0 {
                std::f32::consts::PI - 1e-3
            } else {
                lcg(&mut seed) * 3.0
            };
            let truth = HeadPose {
                rotation: Quat::from_axis_angle(axis, angle),
                translation: Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)),
                scale: 1.0 + 0.5 * lcg(&mut seed),
            };
            let dst: Vec<Vec3> = src.iter().map(|p| truth.apply(*p)).collect();
            let fit = fit_similarity(&src, &dst, true).unwrap();
            // Exact data: f32 input rounding dominates, ~1e-7 relative; allow 1e-4 (points ~0.1, t ~1).
            assert!(
                quat_distance(fit.rotation, truth.rotation) < 1e-5,
                "case {case}"
            );
            assert!(
                (fit.translation - truth.translation).length() < 1e-4,
                "case {case}"
            );
            assert!((fit.scale - truth.scale).abs() < 1e-4, "case {case}");
            for (p, q) in src.iter().zip(&dst) {
                assert!((fit.apply(*p) - *q).length() < 1e-4);
            }
        }
    }

    #[test]
    fn rigid_fit_keeps_unit_scale_and_proper_rotation() {
        let mut seed = 3;
        let src = cloud(&mut seed, 8);
        let truth = HeadPose {
            rotation: Quat::from_euler(glam::EulerRot::XYZ, 0.3, -0.2, 0.9),
            translation: Vec3::new(0.1, 0.2, -0.5),
            scale: 1.0,
        };
        // A mirrored target: the best proper rotation must not become a reflection.
        let dst: Vec<Vec3> = src
            .iter()
            .map(|p| truth.apply(*p * Vec3::new(-1.0, 1.0, 1.0)))
            .collect();
        let fit = fit_similarity(&src, &dst, false).unwrap();
        assert_eq!(fit.scale, 1.0);
        let m = glam::Mat3::from_quat(fit.rotation);
        assert!((m.determinant() - 1.0).abs() < 1e-5);
        let exact = fit_similarity(
            &src,
            &src.iter().map(|p| truth.apply(*p)).collect::<Vec<_>>(),
            false,
        )
        .unwrap();
        assert!(quat_distance(exact.rotation, truth.rotation) < 1e-5);
    }

    /// `|n v - l v|` (max over rows) for a unit `v`.
    fn eigen_residual(n: &[[f64; 4]; 4], l: f64, v: &[f64; 4]) -> f64 {
        (0..4)
            .map(|i| ((0..4).map(|k| n[i][k] * v[k]).sum::<f64>() - l * v[i]).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn newton_eigenpair_matches_jacobi_and_is_an_eigenpair() {
        let mut seed = 11;
        let mut newton_used = 0;
        for case in 0..300 {
            // Random cross-covariances: full rank, rank 2 (planar points, as on a face) and near
            // rotations by pi (two top eigenvalues close).
            let mut s = [[0f64; 3]; 3];
            for row in s.iter_mut() {
                for c in row.iter_mut() {
                    *c = f64::from(lcg(&mut seed));
                }
            }
            if case % 3 == 1 {
                for row in s.iter_mut() {
                    row[2] *= 1e-6;
                }
            }
            let n = horn_matrix(s);
            let bound = n.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
            let mut copy = n;
            let (l_j, v_j) = top_eigen_jacobi(&mut copy).unwrap();
            let Some((l, v)) = top_eigen_newton(&n) else {
                continue;
            };
            newton_used += 1;
            // Independent truth: Jacobi's pair and the eigen-equation itself, to a few hundred
            // f64 epsilons of the matrix's scale (the documented ~4e3 eps bounds the vector).
            assert!(
                (l - l_j).abs() <= 64.0 * f64::EPSILON * bound,
                "case {case}"
            );
            assert!(
                eigen_residual(&n, l, &v) <= 1e4 * f64::EPSILON * bound,
                "case {case}"
            );
            let dot: f64 = v.iter().zip(&v_j).map(|(a, b)| a * b).sum();
            assert!(1.0 - dot.abs() <= 1e4 * f64::EPSILON, "case {case}: {dot}");
        }
        // The gap test lets most random matrices through; the rest went to Jacobi.
        assert!(newton_used > 200, "{newton_used}");
    }

    #[test]
    fn nearly_collinear_points_fall_back_to_jacobi() {
        // Points 1e-4 off a line: the top eigenvalue is nearly double, the Newton path declines,
        // and the fit is still the Jacobi one (determined, if barely).
        let src: Vec<Vec3> = (0..6)
            .map(|i| Vec3::new(i as f32 * 0.02, 0.0, if i % 2 == 0 { 1e-4 } else { -1e-4 }))
            .collect();
        let truth = Quat::from_euler(glam::EulerRot::XYZ, 0.1, 0.2, 0.3);
        let dst: Vec<Vec3> = src.iter().map(|p| truth * *p).collect();
        let mean = |ps: &[Vec3]| ps.iter().fold(DVec3::ZERO, |a, p| a + p.as_dvec3()) / 6.0;
        let (ms, md) = (mean(&src), mean(&dst));
        let mut s = [[0f64; 3]; 3];
        for (p, q) in src.iter().zip(&dst) {
            let (a, b) = (p.as_dvec3() - ms, q.as_dvec3() - md);
            for (r, ar) in s.iter_mut().zip(a.to_array()) {
                for (c, bc) in r.iter_mut().zip(b.to_array()) {
                    *c += ar * bc;
                }
            }
        }
        assert!(top_eigen_newton(&horn_matrix(s)).is_none());
        let fit = fit_similarity(&src, &dst, false).unwrap();
        assert!(quat_distance(fit.rotation, truth) < 1e-2);
        assert!(fit.rotation.w >= 0.0);
    }

    #[test]
    fn degenerate_inputs_give_none() {
        let line: Vec<Vec3> = (0..5).map(|i| Vec3::X * i as f32).collect();
        assert!(fit_similarity(&line, &line, true).is_none());
        let same = vec![Vec3::ONE; 4];
        assert!(fit_similarity(&same, &same, false).is_none());
        assert!(fit_similarity(&line[..2], &line[..2], false).is_none());
        let mut seed = 1;
        let a = cloud(&mut seed, 4);
        assert!(fit_similarity(&a, &a[..3], false).is_none());
        let mut b = a.clone();
        b[1].x = f32::NAN;
        assert!(fit_similarity(&a, &b, false).is_none());
    }
}
