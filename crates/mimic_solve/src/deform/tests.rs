//! Tests of [`MovingDeform`]: against `rest + Basis::apply`, bit for bit where the sums are
//! the same, and the f16 weights against their error bound.

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
        let mut compact = vec![Vec3A::NAN; deform.rows().len()];
        let mut positions = vec![Vec3::NAN; n];
        deform.deform(&d, &mut compact, &mut positions);
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
            assert_eq!(Vec3::from(compact[k]), positions[i]);
        }
        // The packed variant: the same positions and compact rows, bit for bit.
        let mut packed = vec![f32::NAN; 3 * deform.rows().len()];
        let mut positions_p = vec![Vec3::NAN; n];
        deform.deform_packed(&d, &mut packed, &mut positions_p);
        for (k, &i) in deform.rows().iter().enumerate() {
            assert_eq!(
                positions_p[i as usize], positions[i as usize],
                "packed row {i}"
            );
            assert_eq!(&packed[3 * k..3 * k + 3], &positions[i as usize].to_array());
        }
        // Frozen rows are left alone, by both (the packed kernels copy scattered rows as two
        // overlapping 8-byte moves within the row's own vertex).
        for (i, (p, q)) in positions.iter().zip(&positions_p).enumerate() {
            if basis.row(i).iter().all(|w| *w == 0.0) {
                assert!(p.is_nan() && q.is_nan(), "n={n} m={m} frozen row {i}");
            }
        }
    }
}

#[test]
fn portable_path_matches() {
    let (n, m) = (130usize, 38usize);
    let mut seed = 5u64;
    let basis = Basis::from_row_major(n, m, banded(n, m, &mut seed)).unwrap();
    let rest: Vec<Vec3> = (0..n).map(|k| Vec3::splat(k as f32)).collect();
    let d: Vec<Vec3> = (0..m)
        .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)))
        .collect();
    let deform = MovingDeform::new(&basis, &rest);
    let (mut ca, mut pa) = (vec![Vec3A::ZERO; deform.rows().len()], vec![Vec3::ZERO; n]);
    let (mut cb, mut pb) = (ca.clone(), pa.clone());
    deform.deform(&d, &mut ca, &mut pa);
    deform.deform_portable(&d, &mut cb, &mut pb);
    for i in 0..n {
        // Same terms, fused or not: (m + 2) eps (sum |w d| + |rest|).
        let bound: f32 = (0..m)
            .map(|j| basis.row(i)[j].abs() * d[j].abs().max_element())
            .sum::<f32>()
            + rest[i].abs().max_element();
        let tol = 2.0 * (m + 2) as f32 * f32::EPSILON * bound;
        assert!((pa[i] - pb[i]).abs().max_element() <= tol, "row {i}");
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

/// `B` with every weight rounded to binary16 and back: the weights the f16 path reads.
fn rounded_to_f16(basis: &Basis) -> Basis {
    let data = basis
        .as_slice()
        .iter()
        .map(|&w| f32::from(half::f16::from_f32(w)))
        .collect();
    Basis::from_row_major(basis.vertex_count(), basis.control_count(), data).unwrap()
}

#[test]
fn f16_weights_are_the_f32_sums_over_the_rounded_weights_and_within_their_bound() {
    let mut seed = 23u64;
    for &(n, m) in &[(24usize, 38usize), (203, 38), (61, 70), (5, 3)] {
        // Weights over several binades, a few below f16's normal range (6.1e-5).
        let data: Vec<f32> = banded(n, m, &mut seed)
            .into_iter()
            .enumerate()
            .map(|(k, w)| match k % 7 {
                0 => w * 3e-5,
                1 => w * 40.0,
                _ => w,
            })
            .collect();
        let basis = Basis::from_row_major(n, m, data).unwrap();
        let rest: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)) * 10.0)
            .collect();
        let d: Vec<Vec3> = (0..m)
            .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)) * 2.0)
            .collect();
        let f32_deform = MovingDeform::new(&basis, &rest);
        let f16_deform = MovingDeform::new(&basis, &rest).with_f16_weights().unwrap();
        assert!(f16_deform.f16_weights() && !f32_deform.f16_weights());
        assert!(f16_deform.bytes_read() < f32_deform.bytes_read());
        let rounded = MovingDeform::new(&rounded_to_f16(&basis), &rest);
        let k = f32_deform.rows().len();
        let run = |deform: &MovingDeform| {
            let mut packed = vec![f32::NAN; 3 * k];
            let mut positions = vec![Vec3::NAN; n];
            deform.deform_packed(&d, &mut packed, &mut positions);
            let mut compact = vec![Vec3A::NAN; k];
            let mut positions_a = vec![Vec3::NAN; n];
            deform.deform(&d, &mut compact, &mut positions_a);
            for (r, &i) in deform.rows().iter().enumerate() {
                let i = i as usize;
                assert_eq!(positions_a[i], positions[i], "Vec3A and packed, row {i}");
                assert_eq!(Vec3::from(compact[r]), positions[i]);
                assert_eq!(&packed[3 * r..3 * r + 3], &positions[i].to_array());
            }
            positions
        };
        let (p32, p16, pr) = (run(&f32_deform), run(&f16_deform), run(&rounded));
        for &i in f32_deform.rows() {
            let i = i as usize;
            // The f16 kernel converts each weight exactly, so it is the f32 kernel over the
            // rounded weights, the same chains: bit for bit.
            assert_eq!(
                p16[i], pr[i],
                "n={n} m={m} row {i}: f16 vs rounded f32 weights"
            );
            // Against the f32 weights: each weight off by at most 2^-11 |w| (2^-25 below
            // f16's normal range), plus the f32 rounding of both sums.
            let row = basis.row(i);
            let sum_bd: f32 = (0..m)
                .map(|j| row[j].abs() * d[j].abs().max_element())
                .sum();
            let rounding: f32 = (0..m)
                .map(|j| {
                    (row[j].abs() * 2f32.powi(-11) + 2f32.powi(-25)) * d[j].abs().max_element()
                })
                .sum();
            let f32_error =
                2.0 * (m + 2) as f32 * f32::EPSILON * (sum_bd + rest[i].abs().max_element());
            let err = (p16[i] - p32[i]).abs().max_element();
            assert!(
                err <= rounding + f32_error,
                "n={n} m={m} row {i}: {err:e} > {rounding:e} + {f32_error:e}"
            );
        }
    }
}

#[test]
fn f16_weights_out_of_range_are_refused_by_name() {
    let mut data = vec![0.5f32; 30 * 4];
    data[17 * 4 + 2] = -7.0e4;
    let basis = Basis::from_row_major(30, 4, data).unwrap();
    let err = MovingDeform::new(&basis, &vec![Vec3::ZERO; 30])
        .with_f16_weights()
        .unwrap_err();
    assert_eq!(
        err,
        SolveError::F16Range {
            vertex: 17,
            control: 2,
            weight: -7.0e4
        }
    );
}

#[test]
fn f16_portable_path_matches_the_vectorised_one() {
    let (n, m) = (130usize, 38usize);
    let mut seed = 29u64;
    let basis = Basis::from_row_major(n, m, banded(n, m, &mut seed)).unwrap();
    let rest: Vec<Vec3> = (0..n).map(|k| Vec3::splat(k as f32)).collect();
    let d: Vec<Vec3> = (0..m)
        .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)))
        .collect();
    let deform = MovingDeform::new(&basis, &rest).with_f16_weights().unwrap();
    let rounded = rounded_to_f16(&basis);
    let (mut ca, mut pa) = (vec![Vec3A::ZERO; deform.rows().len()], vec![Vec3::ZERO; n]);
    let (mut cb, mut pb) = (ca.clone(), pa.clone());
    deform.deform(&d, &mut ca, &mut pa);
    deform.deform_portable(&d, &mut cb, &mut pb);
    for i in 0..n {
        // Same terms (the rounded weights), fused or not: (m + 2) eps (sum |w d| + |rest|).
        let bound: f32 = (0..m)
            .map(|j| rounded.row(i)[j].abs() * d[j].abs().max_element())
            .sum::<f32>()
            + rest[i].abs().max_element();
        let tol = 2.0 * (m + 2) as f32 * f32::EPSILON * bound;
        assert!((pa[i] - pb[i]).abs().max_element() <= tol, "row {i}");
    }
}

#[test]
fn packed_kernels_agree_bit_for_bit() {
    use crate::kernel::VectorKernel;
    let mut seed = 41u64;
    // Banded (scattered blocks), dense (runs of consecutive vertices) and a last partial block.
    for (n, m, dense) in [(203usize, 38usize, false), (24, 38, true), (101, 38, true)] {
        let (basis, rest, d) = case(n, m, dense, &mut seed);
        for half in [false, true] {
            let mut deform = MovingDeform::new(&basis, &rest);
            if half {
                deform = deform.with_f16_weights().unwrap();
            }
            let k = deform.rows().len();
            let run = |kernel: VectorKernel| {
                let mut packed = vec![f32::NAN; 3 * k];
                let mut positions = vec![Vec3::NAN; n];
                deform.deform_packed_by(kernel, &d, &mut packed, &mut positions);
                (packed, positions)
            };
            let (pa, qa) = run(VectorKernel::Avx2);
            // The AVX-512 kernel (where the CPU has it; else the same kernel twice) sums the
            // same fused chains lane for lane.
            let (pb, qb) = run(VectorKernel::Avx512);
            assert_eq!(pa, pb, "n={n} half={half}: compact rows");
            for (a, b) in qa.iter().zip(&qb) {
                assert!(a == b || (a.is_nan() && b.is_nan()), "n={n} half={half}");
            }
            // The portable kernel: the same fused chains one row at a time.
            let (pc, qc) = run(VectorKernel::Portable);
            assert_eq!(pa, pc, "n={n} half={half}: portable compact rows");
            for (a, c) in qa.iter().zip(&qc) {
                assert!(a == c || (a.is_nan() && c.is_nan()), "n={n} half={half}");
            }
        }
    }
}
