//! Dense Cholesky solve of the small symmetric positive-definite normal equations.

/// Solves `a x = b` for symmetric positive-definite `a` (n x n, row-major) in place:
/// `a` is overwritten by its Cholesky factor, `b` by `x`. False if `a` is not positive definite.
pub fn solve_spd(a: &mut [f64], b: &mut [f64], n: usize) -> bool {
    debug_assert_eq!(a.len(), n * n);
    debug_assert_eq!(b.len(), n);
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= a[i * n + k] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[k * n + i] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_known_system() {
        // a = m^T m + I for a fixed m; b = a x_true, so the solve must return x_true to rounding.
        let n = 4;
        let m = [
            1.0, 2.0, 0.5, -1.0, 0.0, 1.0, 3.0, 2.0, -2.0, 0.5, 1.0, 0.0, 1.0, 1.0, 1.0, 1.0,
        ];
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                a[i * n + j] = (0..n).map(|k| m[k * n + i] * m[k * n + j]).sum::<f64>()
                    + if i == j { 1.0 } else { 0.0 };
            }
        }
        let x_true = [0.3, -1.2, 2.0, 0.7];
        let mut b: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| a[i * n + j] * x_true[j]).sum())
            .collect();
        assert!(solve_spd(&mut a, &mut b, n));
        for (x, t) in b.iter().zip(x_true) {
            assert!((x - t).abs() < 1e-12, "{x} vs {t}");
        }
        let mut singular = vec![1.0, 1.0, 1.0, 1.0];
        assert!(!solve_spd(&mut singular, &mut [1.0, 2.0], 2));
    }
}
