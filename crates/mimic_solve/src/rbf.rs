//! Radial-basis-function interpolation of control displacements, folded into basis columns.
//!
//! With kernel matrix `Phi_kl = phi(|c_k - c_l|)` and `E_ik = phi(|x_i - c_k|)`, the displacement
//! field is `u = E Phi^-1 d`, so the columns are `E Phi^-1` (n x k). With the affine term the
//! interpolant is `sum_k l_k phi(|x - c_k|) + a . (1, x)` under `P^T l = 0`, solved as the saddle
//! system `[[Phi, P], [P^T, 0]]`. Either way every control displacement is reproduced exactly.

use crate::SolveError;
use faer::prelude::*;
use faer::{Mat, Side};
use glam::{DVec3, Vec3};
use mimic_types::{ControlName, RbfKernel};

/// Relative distance (to the control cloud's extent) under which two controls count as coincident.
const COINCIDENT: f64 = 1e-9;

/// Evaluates the kernel at distance `r` (rig units).
pub fn kernel_value(kernel: RbfKernel, r: f64) -> f64 {
    match kernel {
        RbfKernel::Exponential { radius } => (-r / radius).exp(),
        RbfKernel::Gaussian { radius } => {
            let t = r / radius;
            (-t * t).exp()
        }
        RbfKernel::Matern32 { radius } => {
            let t = 3f64.sqrt() * r / radius;
            (1.0 + t) * (-t).exp()
        }
        RbfKernel::ThinPlate => {
            if r <= 0.0 {
                0.0
            } else {
                r * r * r.ln()
            }
        }
    }
}

/// Checks that the kernel is usable: positive finite radius, and thin-plate only with the affine term.
pub fn check_kernel(kernel: RbfKernel, affine: bool) -> Result<(), SolveError> {
    match kernel {
        RbfKernel::Exponential { radius }
        | RbfKernel::Gaussian { radius }
        | RbfKernel::Matern32 { radius } => {
            if !(radius.is_finite() && radius > 0.0) {
                return Err(SolveError::InvalidSetting(format!(
                    "RBF kernel radius {radius} must be finite and > 0 (rig units)"
                )));
            }
        }
        RbfKernel::ThinPlate => {
            if !affine {
                return Err(SolveError::InvalidSetting(
                    "the thin-plate kernel needs the affine term (solver.affine = true)".into(),
                ));
            }
        }
    }
    Ok(())
}

/// How [`rbf_columns`] measures the distance from a vertex to a centre.
#[derive(Clone, Copy, Debug)]
pub enum Metric<'a> {
    /// Straight-line distance.
    Euclidean,
    /// Precomputed distances: `to_vertex[c][i]` from centre `c` to vertex `i`; centre `c` sits on
    /// vertex `centre_vertices[c]`. Infinite entries (unreachable) give a kernel value of 0, and a
    /// vertex no centre reaches gets a zero row.
    Table {
        /// Distance from each centre to every vertex.
        to_vertex: &'a [Vec<f64>],
        /// Vertex of each centre.
        centre_vertices: &'a [usize],
    },
}

/// What [`rbf_columns`] builds an RBF from.
#[derive(Clone, Copy, Debug)]
pub struct RbfInputs<'a> {
    /// Rest positions of every vertex (the rows of the result).
    pub positions: &'a [Vec3],
    /// Frozen vertices, whose rows are left zero (shorter than `positions`, or empty: the rest
    /// move).
    pub frozen: &'a [bool],
    /// Rest positions of the centres (the controls).
    pub centres: &'a [Vec3],
    /// Name of each centre's control (an FDP or a layout point), for errors and warnings.
    pub fdps: &'a [ControlName],
    /// The radial kernel.
    pub kernel: RbfKernel,
    /// Adds the affine term `(1, x, y, z)`.
    pub affine: bool,
    /// How distances are measured.
    pub metric: Metric<'a>,
    /// Added to the diagonal of the kernel matrix: 0 interpolates the controls, more smooths
    /// ([`mimic_types::SolverSettings::rbf_ridge`]).
    pub ridge: f64,
    /// Names the solve in errors (e.g. `RBF of region top`).
    pub system: &'a str,
}

/// Basis columns of an RBF through `centres` (rest positions of the controls, named by `fdps` for
/// errors): returns `n x k` values, row-major, for the `positions` (frozen rows are left zero).
/// `system` names the solve in errors (e.g. `RBF of region top`).
///
/// Centres that coincide under the metric (e.g. the inner-lip midpoints 2.2 and 2.3 of a closed
/// mouth on two vertices at one position, with Euclidean distances) cannot be interpolated
/// separately: they are merged into one centre driven by the **mean** of their displacements (the
/// least-squares compromise), each keeping `1 / count` of the merged column. Every other control
/// is still reproduced exactly. (With geodesic distances such vertices are usually far apart.)
pub fn rbf_columns(inputs: &RbfInputs<'_>) -> Result<Vec<f64>, SolveError> {
    let RbfInputs {
        positions,
        centres,
        fdps,
        metric,
        system,
        ..
    } = *inputs;
    let k = centres.len();
    let n = positions.len();
    if fdps.len() != k {
        return Err(SolveError::InvalidSetting(format!(
            "{system}: {} FDP names for {k} centres",
            fdps.len()
        )));
    }
    if let Metric::Table {
        to_vertex,
        centre_vertices,
    } = metric
    {
        let bad_table = to_vertex.len() != k || to_vertex.iter().any(|t| t.len() != n);
        let bad_vertices = centre_vertices.len() != k || centre_vertices.iter().any(|&v| v >= n);
        if bad_table || bad_vertices {
            return Err(SolveError::InvalidSetting(format!(
                "{system}: distance table does not match {k} centres on {n} vertices"
            )));
        }
    }
    let c: Vec<DVec3> = centres.iter().map(|p| p.as_dvec3()).collect();
    let between = |a: usize, b: usize| match metric {
        Metric::Euclidean => (c[a] - c[b]).length(),
        Metric::Table {
            to_vertex,
            centre_vertices,
        } => 0.5 * (to_vertex[a][centre_vertices[b]] + to_vertex[b][centre_vertices[a]]),
    };
    let extent = c
        .iter()
        .fold(0f64, |a, p| a.max((*p - c[0]).length()))
        .max(f64::MIN_POSITIVE);
    // cluster[a]: index (into `unique`) of the merged centre that centre a belongs to.
    let mut unique: Vec<usize> = Vec::new();
    let mut cluster = vec![0usize; k];
    for a in 0..k {
        match unique
            .iter()
            .position(|&u| between(u, a) <= COINCIDENT * extent)
        {
            Some(u) => {
                tracing::warn!(system, first = %fdps[unique[u]], second = %fdps[a], "controls coincide; merged into one RBF centre driven by their mean");
                cluster[a] = u;
            }
            None => {
                cluster[a] = unique.len();
                unique.push(a);
            }
        }
    }
    if unique.len() == k {
        return rbf_columns_distinct(inputs);
    }
    let u_centres: Vec<Vec3> = unique.iter().map(|&a| centres[a]).collect();
    let (u_table, u_vertices): (Vec<Vec<f64>>, Vec<usize>) = match metric {
        Metric::Euclidean => (Vec::new(), Vec::new()),
        Metric::Table {
            to_vertex,
            centre_vertices,
        } => (
            unique.iter().map(|&a| to_vertex[a].clone()).collect(),
            unique.iter().map(|&a| centre_vertices[a]).collect(),
        ),
    };
    let u_metric = match metric {
        Metric::Euclidean => Metric::Euclidean,
        Metric::Table { .. } => Metric::Table {
            to_vertex: &u_table,
            centre_vertices: &u_vertices,
        },
    };
    let merged = rbf_columns_distinct(&RbfInputs {
        centres: &u_centres,
        metric: u_metric,
        ..*inputs
    })?;
    let ku = unique.len();
    let mut sizes = vec![0f64; ku];
    for &u in &cluster {
        sizes[u] += 1.0;
    }
    let mut cols = vec![0.0; n * k];
    for (row, src) in cols.chunks_exact_mut(k).zip(merged.chunks_exact(ku)) {
        for (a, out) in row.iter_mut().enumerate() {
            *out = src[cluster[a]] / sizes[cluster[a]];
        }
    }
    Ok(cols)
}

/// [`rbf_columns`] for centres that are pairwise distinct under the metric (`fdps` unread).
fn rbf_columns_distinct(inputs: &RbfInputs<'_>) -> Result<Vec<f64>, SolveError> {
    let RbfInputs {
        positions,
        frozen,
        centres,
        kernel,
        affine,
        metric,
        ridge,
        system,
        ..
    } = *inputs;
    check_kernel(kernel, affine)?;
    let k = centres.len();
    let n = positions.len();
    if k == 0 {
        return Ok(vec![0.0; n * k]);
    }
    let c: Vec<DVec3> = centres.iter().map(|p| p.as_dvec3()).collect();
    let phi = |r: f64| {
        if r.is_finite() {
            kernel_value(kernel, r)
        } else {
            0.0
        }
    };
    // Distance from centre l to vertex i (at position p), and between centres a and b.
    let to_vertex = |l: usize, i: usize, p: DVec3| match metric {
        Metric::Euclidean => (p - c[l]).length(),
        Metric::Table { to_vertex, .. } => to_vertex[l][i],
    };
    let between = |a: usize, b: usize| match metric {
        Metric::Euclidean => (c[a] - c[b]).length(),
        Metric::Table {
            to_vertex,
            centre_vertices,
        } => 0.5 * (to_vertex[a][centre_vertices[b]] + to_vertex[b][centre_vertices[a]]),
    };
    // Kernel matrix entry between centres a and b, the ridge on its diagonal.
    let entry = |a: usize, b: usize| phi(between(a, b)) + if a == b { ridge } else { 0.0 };
    let table = matches!(metric, Metric::Table { .. });
    let extra = if affine { 4 } else { 0 };
    let size = k + extra;
    // Weights X (size x k): coefficient vector of the interpolant of each unit control displacement.
    // Kernels of graph distances need not be positive definite: those go through LU too.
    let x = if affine || table {
        let m = Mat::<f64>::from_fn(size, size, |i, j| match (i < k, j < k) {
            (true, true) => entry(i, j),
            (true, false) => affine_entry(c[i], j - k),
            (false, true) => affine_entry(c[j], i - k),
            (false, false) => 0.0,
        });
        let rhs = Mat::<f64>::from_fn(size, k, |i, j| if i == j { 1.0 } else { 0.0 });
        let lu = m.partial_piv_lu();
        let x = lu.solve(&rhs);
        // Singular saddle systems (controls on a plane) show up as a large residual or NaN.
        let residual = (&m * &x - &rhs).norm_max();
        if !residual.is_finite() || residual > 1e-6 {
            return Err(SolveError::Singular {
                system: system.to_string(),
                detail: format!(
                    "RBF system residual {residual:e} (with the affine term: are the controls coplanar or fewer than 4?)"
                ),
            });
        }
        x
    } else {
        let m = Mat::<f64>::from_fn(k, k, entry);
        let llt = m.llt(Side::Lower).map_err(|e| SolveError::Singular {
            system: system.to_string(),
            detail: format!("{e:?}"),
        })?;
        let mut x = Mat::<f64>::identity(k, k);
        llt.solve_in_place(x.as_mut());
        x
    };
    // X transposed, so that each basis entry is one contiguous dot product.
    let xt: Vec<f64> = (0..k)
        .flat_map(|col| (0..size).map(move |l| (col, l)))
        .map(|(col, l)| x[(l, col)])
        .collect();
    let mut cols = vec![0.0; n * k];
    let mut e = vec![0.0; size];
    for (i, (p, row)) in positions.iter().zip(cols.chunks_exact_mut(k)).enumerate() {
        if frozen.get(i).copied().unwrap_or(false) {
            continue;
        }
        let p = p.as_dvec3();
        if table && (0..k).all(|l| !to_vertex(l, i, p).is_finite()) {
            continue;
        }
        for (l, el) in e.iter_mut().enumerate() {
            *el = if l < k {
                phi(to_vertex(l, i, p))
            } else {
                affine_entry(p, l - k)
            };
        }
        for (out, xc) in row.iter_mut().zip(xt.chunks_exact(size)) {
            *out = e.iter().zip(xc).map(|(a, b)| a * b).sum();
        }
    }
    if cols.iter().any(|v| !v.is_finite()) {
        return Err(SolveError::Singular {
            system: system.to_string(),
            detail: "non-finite basis".into(),
        });
    }
    Ok(cols)
}

/// Entry `a` of the affine polynomial basis `(1, x, y, z)` at `p`.
fn affine_entry(p: DVec3, a: usize) -> f64 {
    match a {
        0 => 1.0,
        1 => p.x,
        2 => p.y,
        _ => p.z,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::{control_lattice, fdp, grid, lcg};

    fn setup() -> (Vec<Vec3>, Vec<Vec3>, Vec<ControlName>) {
        let mesh = grid(15, 15, 0.3, 0.3, 2);
        let centres: Vec<Vec3> = control_lattice(15, 15, 4, 4)
            .iter()
            .map(|&v| mesh.positions[v as usize])
            .collect();
        let fdps = (0..centres.len()).map(fdp).collect();
        (mesh.positions, centres, fdps)
    }

    const KERNELS: [(RbfKernel, bool); 7] = [
        (RbfKernel::Exponential { radius: 0.3 }, false),
        (RbfKernel::Exponential { radius: 0.3 }, true),
        (RbfKernel::Matern32 { radius: 0.3 }, false),
        (RbfKernel::Matern32 { radius: 0.3 }, true),
        (RbfKernel::Gaussian { radius: 0.4 }, false),
        (RbfKernel::Gaussian { radius: 0.4 }, true),
        (RbfKernel::ThinPlate, true),
    ];

    #[test]
    fn kernel_values_match_closed_forms() {
        // Matern 3/2 at r = 0 is 1 with zero slope; at r = s / sqrt(3) it is 2 / e; the exponential
        // at r = s is 1 / e; every kernel with a radius decays with r.
        let s = 0.7;
        let m = RbfKernel::Matern32 { radius: s };
        assert_eq!(kernel_value(m, 0.0), 1.0);
        let at = kernel_value(m, s / 3f64.sqrt());
        assert!((at - 2.0 / std::f64::consts::E).abs() < 1e-15, "{at}");
        // Flat top: phi(h) = 1 - 3 h^2 / (2 s^2) + O(h^3), so the slope at 0 vanishes.
        let h = 1e-4;
        assert!((1.0 - kernel_value(m, h)) / h < 1e-3);
        let e = kernel_value(RbfKernel::Exponential { radius: s }, s);
        assert!((e - 1.0 / std::f64::consts::E).abs() < 1e-15);
        for k in [
            m,
            RbfKernel::Exponential { radius: s },
            RbfKernel::Gaussian { radius: s },
        ] {
            assert!(
                (1..50).all(
                    |i| kernel_value(k, i as f64 * 0.1) > kernel_value(k, i as f64 * 0.1 + 0.1)
                )
            );
        }
    }

    #[test]
    fn columns_are_the_identity_at_the_controls() {
        // Interpolation: the column of control c is 1 at c and 0 at every other control.
        let (_, centres, fdps) = setup();
        for (kernel, affine) in KERNELS {
            let cols = rbf_columns(&RbfInputs {
                positions: &centres,
                frozen: &[],
                centres: &centres,
                fdps: &fdps,
                kernel,
                affine,
                metric: Metric::Euclidean,
                ridge: 0.0,
                system: "t",
            })
            .unwrap();
            let k = centres.len();
            for a in 0..k {
                for b in 0..k {
                    let want = if a == b { 1.0 } else { 0.0 };
                    // Conditioning of Phi ~1e6 at most here: 1e-8 leaves room for f64 round-off.
                    assert!((cols[a * k + b] - want).abs() < 1e-8, "{kernel:?} {affine}");
                }
            }
        }
    }

    #[test]
    fn affine_term_reproduces_affine_fields_everywhere() {
        // With the affine term, displacements d_j = M c_j + t are interpolated by exactly u(x) = M x + t
        // (the kernel part vanishes), at every vertex, not just the controls.
        let (positions, centres, fdps) = setup();
        let mut s = 17;
        let m = glam::DMat3::from_cols_array(&std::array::from_fn(|_| lcg(&mut s) as f64));
        let t = glam::DVec3::new(0.1, -0.2, 0.3);
        let k = centres.len();
        for (kernel, _) in KERNELS.into_iter().filter(|(_, a)| *a) {
            let cols = rbf_columns(&RbfInputs {
                positions: &positions,
                frozen: &[],
                centres: &centres,
                fdps: &fdps,
                kernel,
                affine: true,
                metric: Metric::Euclidean,
                ridge: 0.0,
                system: "t",
            })
            .unwrap();
            for (p, row) in positions.iter().zip(cols.chunks_exact(k)) {
                let u = row
                    .iter()
                    .zip(&centres)
                    .fold(glam::DVec3::ZERO, |a, (w, c)| {
                        a + (m * c.as_dvec3() + t) * *w
                    });
                let want = m * p.as_dvec3() + t;
                // Exact in exact arithmetic; f64 solve of a system with condition <= 1e8: 1e-7.
                assert!((u - want).length() < 1e-7, "{kernel:?}: {u} vs {want}");
            }
        }
    }

    #[test]
    fn a_ridge_smooths_the_controls_by_the_ridge_regression_formula() {
        // At the centres themselves, the columns are Phi (Phi + lambda I)^-1 (ridge regression's
        // smoother matrix): the identity at lambda = 0, shrunk towards 0 as lambda grows. The
        // truth here: Phi from the kernel's closed form, the inverse by Gauss-Jordan in f64.
        let (_, centres, fdps) = setup();
        let k = centres.len();
        let radius = 0.3;
        let phi =
            |a: usize, b: usize| (-(centres[a] - centres[b]).as_dvec3().length() / radius).exp();
        for lambda in [0.0, 0.05, 0.25, 1.0] {
            let cols = rbf_columns(&RbfInputs {
                positions: &centres,
                frozen: &[],
                centres: &centres,
                fdps: &fdps,
                kernel: RbfKernel::Exponential { radius },
                affine: false,
                metric: Metric::Euclidean,
                ridge: lambda,
                system: "t",
            })
            .unwrap();
            // [Phi + lambda I | I] reduced to [I | (Phi + lambda I)^-1].
            let mut a: Vec<Vec<f64>> = (0..k)
                .map(|i| {
                    (0..2 * k)
                        .map(|j| match j < k {
                            true => phi(i, j) + if i == j { lambda } else { 0.0 },
                            false => f64::from(u8::from(j - k == i)),
                        })
                        .collect()
                })
                .collect();
            for c in 0..k {
                let p = (c..k)
                    .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
                    .unwrap();
                a.swap(c, p);
                let d = a[c][c];
                a[c].iter_mut().for_each(|v| *v /= d);
                for r in (0..k).filter(|&r| r != c) {
                    let f = a[r][c];
                    let row_c = a[c].clone();
                    a[r].iter_mut().zip(&row_c).for_each(|(v, w)| *v -= f * w);
                }
            }
            for i in 0..k {
                for j in 0..k {
                    let want: f64 = (0..k).map(|l| phi(i, l) * a[l][k + j]).sum();
                    // Two f64 solves of Phi + lambda I, whose condition is at most Phi's (~1e6
                    // here, as in the test above; the ridge only lowers it): 1e-8.
                    assert!(
                        (cols[i * k + j] - want).abs() < 1e-8,
                        "lambda {lambda}: ({i}, {j}) {} vs {want}",
                        cols[i * k + j]
                    );
                }
            }
            if lambda > 0.0 {
                // Shrinks: every control's own weight below 1.
                assert!((0..k).all(|i| cols[i * k + i] < 1.0));
            }
        }
    }

    #[test]
    fn without_affine_term_the_field_decays_away_from_controls() {
        // exp(-r/s) columns far from every control (r >> s) vanish: a far point's row is ~0.
        let (_, centres, fdps) = setup();
        let far = [Vec3::new(100.0, 0.0, 0.0)];
        let cols = rbf_columns(&RbfInputs {
            positions: &far,
            frozen: &[],
            centres: &centres,
            fdps: &fdps,
            kernel: RbfKernel::Exponential { radius: 0.3 },
            affine: false,
            metric: Metric::Euclidean,
            ridge: 0.0,
            system: "t",
        })
        .unwrap();
        assert!(cols.iter().all(|v| v.abs() < 1e-100));
    }

    #[test]
    fn frozen_rows_stay_zero() {
        let (positions, centres, fdps) = setup();
        let frozen: Vec<bool> = (0..positions.len()).map(|i| i % 3 == 0).collect();
        let cols = rbf_columns(&RbfInputs {
            positions: &positions,
            frozen: &frozen,
            centres: &centres,
            fdps: &fdps,
            kernel: RbfKernel::default(),
            affine: false,
            metric: Metric::Euclidean,
            ridge: 0.0,
            system: "t",
        })
        .unwrap();
        let k = centres.len();
        for (i, row) in cols.chunks_exact(k).enumerate() {
            assert_eq!(frozen[i], row.iter().all(|v| *v == 0.0), "row {i}");
        }
    }

    #[test]
    fn degenerate_setups_are_errors() {
        let (_, mut centres, fdps) = setup();
        let thin = rbf_columns(&RbfInputs {
            positions: &centres,
            frozen: &[],
            centres: &centres,
            fdps: &fdps,
            kernel: RbfKernel::ThinPlate,
            affine: false,
            metric: Metric::Euclidean,
            ridge: 0.0,
            system: "t",
        });
        assert!(matches!(thin, Err(SolveError::InvalidSetting(_))));
        let zero = rbf_columns(&RbfInputs {
            positions: &centres,
            frozen: &[],
            centres: &centres,
            fdps: &fdps,
            kernel: RbfKernel::Gaussian { radius: 0.0 },
            affine: false,
            metric: Metric::Euclidean,
            ridge: 0.0,
            system: "t",
        });
        assert!(matches!(zero, Err(SolveError::InvalidSetting(_))));
        // All controls on the plane z = 0 make the affine system singular.
        let flat: Vec<Vec3> = centres.iter().map(|c| Vec3::new(c.x, c.y, 0.0)).collect();
        let r = rbf_columns(&RbfInputs {
            positions: &flat,
            frozen: &[],
            centres: &flat,
            fdps: &fdps,
            kernel: RbfKernel::ThinPlate,
            affine: true,
            metric: Metric::Euclidean,
            ridge: 0.0,
            system: "t",
        });
        assert!(matches!(r, Err(SolveError::Singular { .. })), "{r:?}");
        // Coincident centres merge: both columns are half the merged one, so each of the pair
        // follows the mean of the two displacements while every other control stays exact.
        centres[3] = centres[5];
        let cols = rbf_columns(&RbfInputs {
            positions: &centres,
            frozen: &[],
            centres: &centres,
            fdps: &fdps,
            kernel: RbfKernel::default(),
            affine: false,
            metric: Metric::Euclidean,
            ridge: 0.0,
            system: "t",
        })
        .unwrap();
        let k = centres.len();
        for a in 0..k {
            for b in 0..k {
                let want = match (a, b) {
                    (3 | 5, 3 | 5) => 0.5,
                    _ if a == b => 1.0,
                    _ => 0.0,
                };
                // Well-conditioned 15 x 15 solve: 1e-8.
                assert!(
                    (cols[a * k + b] - want).abs() < 1e-8,
                    "({a}, {b}) = {}",
                    cols[a * k + b]
                );
            }
        }
    }
}
