//! Laplacian surface editing with soft control constraints, folded into basis columns.
//!
//! With `L = I - D^-1 W` (rows normalised edge weights), displacement `u` (so `V = V0 + u` and
//! `L V - L V0 = L u`), the solve minimises `|L u|^2 + w^2 sum_j |u_kj - d_j|^2` with the frozen
//! vertices held at `u = 0` (eliminated). Normal equations: `A = L_F^T L_F + w^2 C^T C` over the
//! free vertices, `u = A^-1 w^2 C^T d`, so the columns are `A^-1 w^2 C^T`: one sparse Cholesky
//! factorisation (faer, supernodal) and one solve with k right-hand sides. Nothing dense is n x n.
//!
//! Degenerate input, handled without NaN:
//! - a triangle whose doubled area is below `1e-12` of its longest squared edge, or that repeats a
//!   vertex, makes its vertices' rows fall back to uniform weights (mean-value and cotangent
//!   weights blow up there);
//! - negative cotangent weights (obtuse angles) are clamped to zero; a row whose weights sum to
//!   zero or less falls back to uniform;
//! - an isolated vertex has an all-zero Laplacian row;
//! - a connected component that holds no control and no frozen vertex is undetermined (its
//!   Laplacian energy does not see translations): it is held at zero displacement, as if frozen,
//!   with a `tracing::warn`.

#![allow(
    clippy::needless_range_loop,
    reason = "index loops mirror the matrix formulas (rows i, columns j) and touch several arrays at once"
)]

use crate::SolveError;
use faer::Side;
use faer::prelude::*;
use faer::sparse::{SparseColMat, Triplet};
use glam::{DVec3, Vec3};
use mimic_types::LaplacianWeights;

/// Doubled triangle area, relative to its longest squared edge, below which it counts as degenerate.
const DEGENERATE_AREA: f64 = 1e-12;

/// Sparse Laplacian rows: for each vertex, its neighbours and `-w_ij / sum_j w_ij` (diagonal 1 implied
/// when the list is not empty).
#[derive(Clone, Debug)]
pub struct LaplacianRows {
    /// `offsets[i]..offsets[i + 1]` index `cols` / `vals` for row `i`.
    pub offsets: Vec<usize>,
    /// Neighbour vertex of each entry.
    pub cols: Vec<u32>,
    /// Off-diagonal value `-w_ij / sum_j w_ij` of each entry.
    pub vals: Vec<f64>,
}

impl LaplacianRows {
    /// Off-diagonal entries `(neighbour, value)` of row `i`.
    pub fn row(&self, i: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let r = self.offsets[i]..self.offsets[i + 1];
        self.cols[r.clone()]
            .iter()
            .map(|c| *c as usize)
            .zip(self.vals[r].iter().copied())
    }

    /// Diagonal entry of row `i`: 1 when the vertex has neighbours, 0 when isolated.
    pub fn diagonal(&self, i: usize) -> f64 {
        if self.offsets[i + 1] > self.offsets[i] {
            1.0
        } else {
            0.0
        }
    }
}

/// Builds the normalised Laplacian rows of a mesh (triangles must index inside `positions`).
pub fn laplacian_rows(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    weights: LaplacianWeights,
) -> LaplacianRows {
    let n = positions.len();
    let mut fallback = vec![false; n];
    // Directed (row, col, weight) contributions; summed per pair below.
    let mut entries: Vec<(u32, u32, f64)> = Vec::with_capacity(triangles.len() * 6);
    for t in triangles {
        let idx = [t[0] as usize, t[1] as usize, t[2] as usize];
        if idx.iter().any(|&v| v >= n) {
            continue;
        }
        let p = idx.map(|v| positions[v].as_dvec3());
        let area2 = (p[1] - p[0]).cross(p[2] - p[0]).length();
        let longest = (0..3)
            .map(|e| (p[(e + 1) % 3] - p[e]).length_squared())
            .fold(0f64, f64::max);
        let degenerate = idx[0] == idx[1]
            || idx[1] == idx[2]
            || idx[0] == idx[2]
            || area2 <= DEGENERATE_AREA * longest
            || !area2.is_finite()
            || !longest.is_finite();
        for corner in 0..3 {
            let (i, j, k) = (idx[corner], idx[(corner + 1) % 3], idx[(corner + 2) % 3]);
            if i != j {
                entries.push((i as u32, j as u32, 0.0));
            }
            if i != k {
                entries.push((i as u32, k as u32, 0.0));
            }
            if degenerate {
                fallback[i] = true;
                continue;
            }
            let (pi, pj, pk) = (p[corner], p[(corner + 1) % 3], p[(corner + 2) % 3]);
            let len = entries.len();
            match weights {
                LaplacianWeights::Uniform => {}
                LaplacianWeights::MeanValue => {
                    let (e1, e2) = (pj - pi, pk - pi);
                    let half_tan = tan_half_angle(e1, e2);
                    entries[len - 2].2 = half_tan / e1.length();
                    entries[len - 1].2 = half_tan / e2.length();
                }
                LaplacianWeights::Cotangent => {
                    // The angle at i is opposite edge (j, k): cot/2 goes to w_jk and w_kj.
                    let (e1, e2) = (pj - pi, pk - pi);
                    let cot = e1.dot(e2) / e1.cross(e2).length();
                    entries.push((j as u32, k as u32, 0.5 * cot));
                    entries.push((k as u32, j as u32, 0.5 * cot));
                }
            }
        }
    }
    entries.sort_unstable_by_key(|e| (e.0, e.1));
    let mut offsets = Vec::with_capacity(n + 1);
    let mut cols = Vec::new();
    let mut vals = Vec::new();
    let mut e = 0;
    offsets.push(0);
    for i in 0..n {
        let start = cols.len();
        while e < entries.len() && entries[e].0 as usize == i {
            let j = entries[e].1;
            let mut w = 0.0;
            while e < entries.len() && entries[e].0 as usize == i && entries[e].1 == j {
                w += entries[e].2;
                e += 1;
            }
            cols.push(j);
            vals.push(match weights {
                LaplacianWeights::Cotangent => w.max(0.0),
                _ => w,
            });
        }
        let row = &mut vals[start..];
        let sum: f64 = row.iter().sum();
        let uniform =
            weights == LaplacianWeights::Uniform || fallback[i] || !(sum.is_finite() && sum > 0.0);
        let count = row.len() as f64;
        for v in row.iter_mut() {
            *v = if uniform { -1.0 / count } else { -*v / sum };
        }
        offsets.push(cols.len());
    }
    LaplacianRows {
        offsets,
        cols,
        vals,
    }
}

/// `tan(theta / 2)` of the angle between `a` and `b`, as `|a x b| / (|a||b| + a.b)`.
fn tan_half_angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length() / (a.length() * b.length() + a.dot(b))
}

/// Basis columns of the Laplacian solve constrained at `controls` (vertex indices): `n x k` values,
/// row-major. Rows of frozen vertices, and of components no control or frozen vertex reaches, are zero.
pub fn laplacian_columns(
    rows: &LaplacianRows,
    frozen: &[bool],
    controls: &[usize],
    constraint_weight: f64,
    system: &str,
) -> Result<Vec<f64>, SolveError> {
    if !(constraint_weight.is_finite() && constraint_weight > 0.0) {
        return Err(SolveError::InvalidSetting(format!(
            "Laplacian constraint weight {constraint_weight} must be finite and > 0"
        )));
    }
    let n = rows.offsets.len() - 1;
    let k = controls.len();
    if let Some(&c) = controls.iter().find(|&&c| c >= n) {
        return Err(SolveError::InvalidSetting(format!(
            "{system}: control vertex {c} outside the {n} vertices"
        )));
    }
    let mut fixed: Vec<bool> = (0..n)
        .map(|i| frozen.get(i).copied().unwrap_or(false))
        .collect();
    // Components reached by neither a control nor a frozen vertex are singular: hold them still.
    let mut parent: Vec<usize> = (0..n).collect();
    for i in 0..n {
        for (j, _) in rows.row(i) {
            union(&mut parent, i, j);
        }
    }
    let mut anchored = vec![false; n];
    for i in 0..n {
        if fixed[i] {
            let r = find(&mut parent, i);
            anchored[r] = true;
        }
    }
    for &c in controls {
        let r = find(&mut parent, c);
        anchored[r] = true;
    }
    let mut floating = 0usize;
    for i in 0..n {
        let r = find(&mut parent, i);
        if !anchored[r] && !fixed[i] {
            fixed[i] = true;
            floating += 1;
        }
    }
    if floating > 0 {
        tracing::warn!(
            system,
            vertices = floating,
            "mesh parts reached by no control and no frozen vertex are held still"
        );
    }
    let mut free_index = vec![usize::MAX; n];
    let mut nf = 0;
    for i in 0..n {
        if !fixed[i] {
            free_index[i] = nf;
            nf += 1;
        }
    }
    let mut cols = vec![0.0; n * k];
    if nf == 0 || k == 0 {
        return Ok(cols);
    }
    let w2 = constraint_weight * constraint_weight;
    // A = L_F^T L_F + w^2 C^T C, lower triangle only, duplicates summed by faer.
    let mut triplets: Vec<Triplet<usize, usize, f64>> = Vec::new();
    let mut row_buf: Vec<(usize, f64)> = Vec::new();
    for i in 0..n {
        row_buf.clear();
        if !fixed[i] {
            row_buf.push((free_index[i], rows.diagonal(i)));
        }
        row_buf.extend(
            rows.row(i)
                .filter(|(j, _)| !fixed[*j])
                .map(|(j, v)| (free_index[j], v)),
        );
        for &(p, vp) in &row_buf {
            for &(q, vq) in &row_buf {
                if p >= q {
                    triplets.push(Triplet::new(p, q, vp * vq));
                }
            }
        }
    }
    for &c in controls {
        if !fixed[c] {
            triplets.push(Triplet::new(free_index[c], free_index[c], w2));
        }
    }
    let singular = |detail: String| SolveError::Singular {
        system: system.to_string(),
        detail,
    };
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(nf, nf, &triplets)
        .map_err(|e| singular(format!("assembly failed: {e:?}")))?;
    drop(triplets);
    let llt = a
        .sp_cholesky(Side::Lower)
        .map_err(|e| singular(format!("{e:?}")))?;
    let mut rhs = Mat::<f64>::zeros(nf, k);
    for (col, &c) in controls.iter().enumerate() {
        if !fixed[c] {
            rhs[(free_index[c], col)] += w2;
        }
    }
    llt.solve_in_place(rhs.as_mut());
    for i in 0..n {
        if fixed[i] {
            continue;
        }
        let f = free_index[i];
        for (col, out) in cols[i * k..(i + 1) * k].iter_mut().enumerate() {
            *out = rhs[(f, col)];
        }
    }
    if cols.iter().any(|v| !v.is_finite()) {
        return Err(singular("non-finite solution".into()));
    }
    Ok(cols)
}

/// Union-find root of `i`, with path halving.
fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// Joins the sets of `a` and `b`.
fn union(parent: &mut [usize], a: usize, b: usize) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra] = rb;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::{control_lattice, grid, lcg, tri_lattice};

    /// Dense reference: builds L densely from the rows, then A and the right-hand side, and solves
    /// with a dense LU (faer), with the same frozen set.
    fn dense_reference(
        rows: &LaplacianRows,
        frozen: &[bool],
        controls: &[usize],
        w: f64,
    ) -> Vec<f64> {
        let n = frozen.len();
        let k = controls.len();
        let mut l = Mat::<f64>::zeros(n, n);
        for i in 0..n {
            l[(i, i)] = rows.diagonal(i);
            for (j, v) in rows.row(i) {
                l[(i, j)] += v;
            }
        }
        let free: Vec<usize> = (0..n).filter(|&i| !frozen[i]).collect();
        let lf = Mat::<f64>::from_fn(n, free.len(), |i, c| l[(i, free[c])]);
        let mut a = lf.transpose() * &lf;
        let mut rhs = Mat::<f64>::zeros(free.len(), k);
        for (col, &c) in controls.iter().enumerate() {
            let f = free.iter().position(|&v| v == c).unwrap();
            a[(f, f)] += w * w;
            rhs[(f, col)] = w * w;
        }
        let x = a.partial_piv_lu().solve(&rhs);
        let mut out = vec![0.0; n * k];
        for (c, &i) in free.iter().enumerate() {
            for col in 0..k {
                out[i * k + col] = x[(c, col)];
            }
        }
        out
    }

    #[test]
    fn sparse_solve_matches_dense_reference() {
        let mesh = grid(10, 10, 0.3, 0.3, 1);
        let n = mesh.vertex_count();
        let controls: Vec<usize> = control_lattice(10, 10, 3, 3)
            .into_iter()
            .map(|v| v as usize)
            .collect();
        // Freeze the bottom row of the grid.
        let frozen: Vec<bool> = (0..n).map(|i| i < 10).collect();
        for weights in [
            LaplacianWeights::Uniform,
            LaplacianWeights::MeanValue,
            LaplacianWeights::Cotangent,
        ] {
            let rows = laplacian_rows(&mesh.positions, &mesh.triangles, weights);
            let sparse = laplacian_columns(&rows, &frozen, &controls, 3.0, "test").unwrap();
            let dense = dense_reference(&rows, &frozen, &controls, 3.0);
            let scale = dense.iter().fold(0f64, |a, v| a.max(v.abs()));
            // Both are backward-stable solves of a system with condition ~1e4 here: 1e-9 * max|B|.
            for (s, d) in sparse.iter().zip(&dense) {
                assert!((s - d).abs() <= 1e-9 * scale, "{weights:?}: {s} vs {d}");
            }
            for i in 0..10 {
                assert!(
                    sparse[i * 9..(i + 1) * 9].iter().all(|v| *v == 0.0),
                    "frozen row {i} moved"
                );
            }
        }
    }

    #[test]
    fn mean_value_and_cotangent_have_linear_precision_on_a_plane() {
        // Mean-value and cotangent weights reproduce linear functions at interior vertices of a
        // planar mesh: sum_j w_ij v_j / sum_j w_ij = v_i, i.e. L V = 0 (uniform weights do not
        // on a jittered mesh). The jittered triangular lattice keeps every angle below 90 degrees,
        // so no cotangent is clamped.
        let mesh = tri_lattice(8, 8, 0.1, 9);
        for weights in [
            LaplacianWeights::MeanValue,
            LaplacianWeights::Cotangent,
            LaplacianWeights::Uniform,
        ] {
            let rows = laplacian_rows(&mesh.positions, &mesh.triangles, weights);
            let mut worst = 0f64;
            for j in 1..7 {
                for i in 1..7 {
                    let v = j * 8 + i;
                    let lv = rows.row(v).fold(mesh.positions[v].as_dvec3(), |a, (c, w)| {
                        a + mesh.positions[c].as_dvec3() * w
                    });
                    worst = worst.max(lv.length());
                }
            }
            // f32 positions of size 1, weights of size 1/6: a few ulps, 1e-6 is generous.
            if weights == LaplacianWeights::Uniform {
                assert!(
                    worst > 1e-3,
                    "uniform weights should not be linear-precise on a jittered grid"
                );
            } else {
                assert!(worst < 1e-6, "{weights:?}: |L V| = {worst}");
            }
        }
    }

    #[test]
    fn mean_value_weights_match_hand_computation() {
        // Regular fan of 6 equilateral triangles around the origin: every angle is 60 degrees and
        // every spoke has length 1, so all weights are equal and each normalised entry is -1/6.
        let mut positions = vec![Vec3::ZERO];
        for a in 0..6 {
            let t = a as f32 * std::f32::consts::PI / 3.0;
            positions.push(Vec3::new(t.cos(), t.sin(), 0.0));
        }
        let triangles: Vec<[u32; 3]> = (0..6).map(|a| [0, 1 + a, 1 + (a + 1) % 6]).collect();
        let rows = laplacian_rows(&positions, &triangles, LaplacianWeights::MeanValue);
        let entries: Vec<_> = rows.row(0).collect();
        assert_eq!(entries.len(), 6);
        for (_, v) in entries {
            assert!((v + 1.0 / 6.0).abs() < 1e-7);
        }
        // Boundary vertex 1: neighbours 0 (two triangles, angles 60 each) and 2, 6 (one each, angle
        // 60): raw weights 2 tan30 / 1 for 0 and tan30 / 1 for 2 and 6 -> 1/2, 1/4, 1/4.
        let row1: Vec<_> = rows.row(1).collect();
        let get = |c: usize| row1.iter().find(|e| e.0 == c).unwrap().1;
        assert!(
            (get(0) + 0.5).abs() < 1e-7
                && (get(2) + 0.25).abs() < 1e-7
                && (get(6) + 0.25).abs() < 1e-7
        );
    }

    #[test]
    fn translation_moves_every_vertex_exactly_when_nothing_is_frozen() {
        // L 1 = 0, so u = t everywhere has zero energy and meets every constraint: it is the
        // unique minimiser. Columns therefore sum to 1 in every row (up to solver round-off ~1e-12).
        let mesh = grid(12, 9, 0.2, 0.2, 4);
        let n = mesh.vertex_count();
        let controls: Vec<usize> = control_lattice(12, 9, 4, 3)
            .into_iter()
            .map(|v| v as usize)
            .collect();
        for weights in [
            LaplacianWeights::Uniform,
            LaplacianWeights::MeanValue,
            LaplacianWeights::Cotangent,
        ] {
            let rows = laplacian_rows(&mesh.positions, &mesh.triangles, weights);
            let cols = laplacian_columns(&rows, &vec![false; n], &controls, 2.0, "t").unwrap();
            for row in cols.chunks_exact(controls.len()) {
                assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-9, "{weights:?}");
            }
        }
    }

    #[test]
    fn degenerate_meshes_give_documented_zeros_not_nan() {
        // Part 1: a strip with a zero-area triangle (collinear 0, 1, 2) and a repeated vertex index.
        // Part 2: an isolated vertex 6. Part 3: a floating triangle 7, 8, 9 with no control.
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(2.0, 1.0, 0.0),
            Vec3::new(5.0, 5.0, 5.0),
            Vec3::new(9.0, 0.0, 0.0),
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(9.0, 1.0, 0.0),
        ];
        let triangles = vec![
            [0, 1, 2],
            [0, 1, 4],
            [0, 4, 3],
            [1, 2, 5],
            [1, 5, 4],
            [2, 2, 5],
            [7, 8, 9],
        ];
        let mut seed = 3;
        for weights in [
            LaplacianWeights::Uniform,
            LaplacianWeights::MeanValue,
            LaplacianWeights::Cotangent,
        ] {
            let rows = laplacian_rows(&positions, &triangles, weights);
            assert!(rows.vals.iter().all(|v| v.is_finite()), "{weights:?}");
            assert_eq!(rows.diagonal(6), 0.0, "isolated vertex has an empty row");
            let controls = [0usize, 5];
            let cols = laplacian_columns(&rows, &[false; 10], &controls, 5.0, "t").unwrap();
            assert!(cols.iter().all(|v| v.is_finite()));
            // Isolated and floating vertices are held still.
            for i in 6..10 {
                assert_eq!(&cols[i * 2..i * 2 + 2], &[0.0, 0.0]);
            }
            // The strip itself still reproduces a translation (its rows sum to 1).
            let _ = lcg(&mut seed);
            for i in 0..6 {
                assert!(
                    (cols[i * 2] + cols[i * 2 + 1] - 1.0).abs() < 1e-9,
                    "{weights:?} row {i}"
                );
            }
        }
        // An isolated control vertex follows its control (weight w^2 / w^2).
        let rows = laplacian_rows(&positions, &triangles, LaplacianWeights::MeanValue);
        let cols = laplacian_columns(&rows, &[false; 10], &[0, 6], 5.0, "t").unwrap();
        assert!((cols[6 * 2 + 1] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_constraint_weight() {
        let mesh = grid(3, 3, 0.0, 0.0, 0);
        let rows = laplacian_rows(&mesh.positions, &mesh.triangles, LaplacianWeights::Uniform);
        for w in [0.0, -1.0, f64::NAN] {
            assert!(matches!(
                laplacian_columns(&rows, &[false; 9], &[4], w, "t"),
                Err(SolveError::InvalidSetting(_))
            ));
        }
    }
}
