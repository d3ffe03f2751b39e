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
            || !(area2 > DEGENERATE_AREA * longest)
            || !area2.is_finite();
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
