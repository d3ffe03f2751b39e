//! Tests of [`MovingDeform`]: against `rest + Basis::apply`, bit for bit where the sums are
//! the same, and its kernels against each other.

use super::*;
use mimic_testkit::lcg;

/// A basis in bands of rows with their own supports (like face regions), frozen rows
/// between, rows of different bands interleaved so the sort has work to do.
fn banded(n: usize, m: usize, seed: &mut u64) -> Vec<f32> {
    (0..n * m)
        .map(|k| {
            let (i, j) = (k / m, k % m);
            let w = lcg(seed);
            match i % 5 {
                0 if j < m / 3 => w,
                1 | 3 if j >= m / 3 && j < 2 * m / 3 + 1 => w,
                4 if j >= m / 2 || j == 1 => w,
                _ => 0.0,
            }
        })
        .collect()
}

/// A basis of `n` rows and `m` controls (every weight drawn when `dense`, else [`banded`]), rest
/// positions within 10 of the origin and control displacements within 1.
fn case(n: usize, m: usize, dense: bool, seed: &mut u64) -> (Basis, Vec<Vec3>, Vec<Vec3>) {
    let data: Vec<f32> = if dense {
        (0..n * m).map(|_| lcg(seed)).collect()
    } else {
        banded(n, m, seed)
    };
    let basis = Basis::from_row_major(n, m, data).unwrap();
    let mut point = || Vec3::new(lcg(seed), lcg(seed), lcg(seed));
    let rest: Vec<Vec3> = (0..n).map(|_| point() * 10.0).collect();
    let d: Vec<Vec3> = (0..m).map(|_| point()).collect();
    (basis, rest, d)
}

#[test]
fn deform_equals_rest_plus_apply_bit_for_bit() {
    let mut seed = 11u64;
    for &(n, m) in &[
        (1usize, 1usize),
        (23, 5),
        (24, 38),
        (70, 38),
        (203, 38),
        (61, 70),
    ] {
        let (basis, rest, d) = case(n, m, m < 5, &mut seed);
        let deform = MovingDeform::new(&basis, &rest);
        let moving = basis.moving_rows(n);
        let mut sorted = deform.rows().to_vec();
        sorted.sort_unstable();
        assert_eq!(sorted, moving.rows, "n={n} m={m}: the same moving rows");
        let mut u = vec![Vec3::ZERO; n];
        basis.apply(&d, &mut u);
        let mut packed = vec![f32::NAN; 3 * deform.rows().len()];
        let mut positions = vec![Vec3::NAN; n];
        deform.deform_packed(&d, &mut packed, &mut positions);
        for (k, &i) in deform.rows().iter().enumerate() {
            let i = i as usize;
            let want = Vec3::from(Vec3A::from(rest[i]) + Vec3A::from(u[i]));
            if m <= 64 {
                // Same fused chains as Basis::apply (its AVX2 path, or both portable).
                #[cfg(target_arch = "x86_64")]
                if crate::basis::avx2_fma() {
                    assert_eq!(positions[i], want, "n={n} m={m} row {i}");
                }
            }
            // Any path: within the f32 error of an m-term sum plus one add, m eps sum |w d|
            // + eps |p|, bounded by (m + 1) eps (sum_j |B_ij| |d_j| + |rest_i|).
            let bound: f32 = (0..m)
                .map(|j| basis.row(i)[j].abs() * d[j].abs().max_element())
                .sum::<f32>()
                + rest[i].abs().max_element();
            let tol = (m + 2) as f32 * f32::EPSILON * bound;
            assert!((positions[i] - want).abs().max_element() <= tol, "row {i}");
            assert_eq!(&packed[3 * k..3 * k + 3], &positions[i].to_array());
        }
        // Frozen rows are left alone (the kernels copy scattered rows as two overlapping 8-byte
        // moves within the row's own vertex).
        for (i, p) in positions.iter().enumerate() {
            if basis.row(i).iter().all(|w| *w == 0.0) {
                assert!(p.is_nan(), "n={n} m={m} frozen row {i}");
            }
        }
    }
}

#[test]
fn support_order_keeps_fewer_columns_than_index_order() {
    // Interleaved bands: blocks in index order keep the union of three supports.
    let (n, m) = (480usize, 38usize);
    let mut seed = 9u64;
    let basis = Basis::from_row_major(n, m, banded(n, m, &mut seed)).unwrap();
    let deform = MovingDeform::new(&basis, &vec![Vec3::ZERO; n]);
    let rows = basis.moving_rows(n).rows;
    let index_order_kept = rows
        .chunks(BLOCK)
        .map(|b| {
            (0..m)
                .filter(|&j| b.iter().any(|&i| basis.row(i as usize)[j] != 0.0))
                .count()
        })
        .sum::<usize>();
    assert!(
        (deform.cols.len() as f64) < 0.7 * index_order_kept as f64,
        "{} vs {index_order_kept}",
        deform.cols.len()
    );
    assert!(deform.kept_fraction() > 0.0 && deform.kept_fraction() < 1.0);
}

#[test]
fn packed_kernels_agree_bit_for_bit() {
    use crate::kernel::VectorKernel;
    let mut seed = 41u64;
    // Banded (scattered blocks), dense (runs of consecutive vertices) and a last partial block.
    for (n, m, dense) in [(203usize, 38usize, false), (24, 38, true), (101, 38, true)] {
        let (basis, rest, d) = case(n, m, dense, &mut seed);
        let deform = MovingDeform::new(&basis, &rest);
        let k = deform.rows().len();
        let run = |kernel: VectorKernel| {
            let mut packed = vec![f32::NAN; 3 * k];
            let mut positions = vec![Vec3::NAN; n];
            deform.deform_packed_by(kernel, &d, &mut packed, &mut positions);
            (packed, positions)
        };
        let (pa, qa) = run(VectorKernel::Avx2);
        // The portable kernel: the same fused chains one row at a time.
        let (pc, qc) = run(VectorKernel::Portable);
        assert_eq!(pa, pc, "n={n}: portable compact rows");
        for (a, c) in qa.iter().zip(&qc) {
            assert!(a == c || (a.is_nan() && c.is_nan()), "n={n}");
        }
    }
}
