//! Non-rigid ICP (Amberg, Romdhani and Vetter, "Optimal Step Nonrigid ICP Algorithms for
//! Surface Registration", CVPR 2007), landmark-free: every template point `v_i` gets its own
//! affine map `X_i` (4 x 3, `[v_i 1] X_i` is where it goes), and each round minimises
//!
//! `sum_i w_i |[v_i 1] X_i - u_i|^2 + alpha^2 sum_(i,j) |G (X_i - X_j)|_F^2`
//!
//! over the edges `(i, j)` of the template's graph, `G = diag(1, 1, 1, gamma)`, `u_i` the
//! point-to-plane match of the current `[v_i 1] X_i` on the surface and `w_i` 1 or 0 (no match,
//! a match on the surface's open border, or one too far away). That is one sparse SPD system
//! `(alpha^2 L (x) G^2 + D' W D) X = D' W U` (`L` the graph Laplacian) per round, solved by a
//! sparse Cholesky factorisation (faer). The stiffness `alpha` steps from high (nearly one
//! affine map) to low, a few rounds each, as in the paper.

use crate::RigNewError;
use crate::nearest::{PointIndex, Surface};
use faer::Side;
use faer::prelude::*;
use faer::sparse::{SparseColMat, Triplet};
use glam::Vec3;

/// Knobs of [`nonrigid_icp`]; lengths in template units (its face units).
#[derive(Clone, Debug, PartialEq)]
pub struct NonRigidSettings {
    /// Stiffness steps, high to low.
    pub stiffness: Vec<f64>,
    /// Rounds per stiffness step at most.
    pub rounds: usize,
    /// Weight of the translation part of the affine differences (`gamma`).
    pub gamma: f64,
    /// Matches farther than this are dropped.
    pub max_distance: f32,
    /// A surface vertex matches a point only if their normals have at least this dot product.
    pub min_dot: f32,
    /// A step ends when the points moved less than this on average in a round.
    pub tolerance: f32,
}

impl Default for NonRigidSettings {
    fn default() -> Self {
        Self {
            stiffness: vec![50.0, 20.0, 10.0, 5.0, 2.0],
            rounds: 3,
            gamma: 1.0,
            max_distance: 0.15,
            min_dot: 0.5,
            tolerance: 1e-3,
        }
    }
}

/// The result of [`nonrigid_icp`].
#[derive(Clone, Debug, PartialEq)]
pub struct NonRigidFit {
    /// Where each template point went.
    pub deformed: Vec<Vec3>,
    /// Points matched in the last round.
    pub matched: usize,
    /// RMS point-to-plane distance of the matched points in the last round.
    pub rms: f32,
    /// Linear solves done.
    pub solves: usize,
}

/// The edges of a k-nearest-neighbour graph of `points` (each point to its `k` nearest, both
/// ways, without repeats), as pairs `(i, j)` with `i < j`.
pub fn knn_graph(points: &[Vec3], k: usize) -> Vec<(u32, u32)> {
    let index = PointIndex::new(points, |_| true);
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(points.len() * k);
    for (i, p) in points.iter().enumerate() {
        for (j, _) in index.nearest_k(*p, k + 1) {
            let i = i as u32;
            if j != i {
                edges.push((i.min(j), i.max(j)));
            }
        }
    }
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// Deforms `points` (unit `normals`, graph `edges`) onto `surface`, which must be in the
/// template's coordinates (the similarity already undone).
pub fn nonrigid_icp(
    points: &[Vec3],
    normals: &[Vec3],
    edges: &[(u32, u32)],
    surface: &Surface,
    s: &NonRigidSettings,
) -> Result<NonRigidFit, RigNewError> {
    let m = points.len();
    let n = 4 * m;
    // X, 4m x 3: start from the identity maps.
    let mut x = Mat::<f64>::zeros(n, 3);
    for i in 0..m {
        for c in 0..3 {
            x[(4 * i + c, c)] = 1.0;
        }
    }
    let hat = |p: Vec3| [f64::from(p.x), f64::from(p.y), f64::from(p.z), 1.0];
    let apply = |x: &Mat<f64>, i: usize| {
        let v = hat(points[i]);
        let mut out = [0f64; 3];
        for (c, o) in out.iter_mut().enumerate() {
            *o = (0..4).map(|a| v[a] * x[(4 * i + a, c)]).sum();
        }
        Vec3::new(out[0] as f32, out[1] as f32, out[2] as f32)
    };
    let g2 = [1.0, 1.0, 1.0, s.gamma * s.gamma];
    // A tiny pull towards the previous maps keeps points with no match and no edge solvable.
    let eps = 1e-6;
    let mut deformed: Vec<Vec3> = points.to_vec();
    let mut matches: Vec<Option<Vec3>> = vec![None; m];
    let mut solves = 0;
    let (mut matched, mut rms) = (0, 0.0);
    let mut triplets: Vec<Triplet<usize, usize, f64>> = Vec::new();
    for &alpha in &s.stiffness {
        for _ in 0..s.rounds {
            let (count, sum) = match_all(&deformed, normals, surface, s, &mut matches);
            (matched, rms) = (count, (sum / count.max(1) as f64).sqrt() as f32);
            triplets.clear();
            let a2 = alpha * alpha;
            for &(i, j) in edges {
                let (i, j) = (i as usize, j as usize);
                for (d, g) in g2.iter().enumerate() {
                    let w = a2 * g;
                    let (r, c) = (4 * j + d, 4 * i + d);
                    triplets.push(Triplet::new(4 * i + d, 4 * i + d, w));
                    triplets.push(Triplet::new(r, c, -w));
                    triplets.push(Triplet::new(r, r, w));
                }
            }
            let mut rhs = Mat::<f64>::zeros(n, 3);
            for i in 0..m {
                for a in 0..4 {
                    triplets.push(Triplet::new(4 * i + a, 4 * i + a, eps));
                    for c in 0..3 {
                        rhs[(4 * i + a, c)] = eps * x[(4 * i + a, c)];
                    }
                }
                let Some(u) = matches[i] else { continue };
                let v = hat(points[i]);
                let u = [f64::from(u.x), f64::from(u.y), f64::from(u.z)];
                for a in 0..4 {
                    for b in 0..=a {
                        triplets.push(Triplet::new(4 * i + a, 4 * i + b, v[a] * v[b]));
                    }
                    for c in 0..3 {
                        rhs[(4 * i + a, c)] += v[a] * u[c];
                    }
                }
            }
            let a = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).map_err(
                |e| RigNewError::Frame(format!("non-rigid ICP: assembly failed: {e:?}")),
            )?;
            let llt = a.sp_cholesky(Side::Lower).map_err(|e| {
                RigNewError::Frame(format!("non-rigid ICP: the system is singular: {e:?}"))
            })?;
            llt.solve_in_place(rhs.as_mut());
            solves += 1;
            x = rhs;
            let next: Vec<Vec3> = (0..m).map(|i| apply(&x, i)).collect();
            let moved = next
                .iter()
                .zip(&deformed)
                .map(|(a, b)| a.distance(*b))
                .sum::<f32>()
                / m.max(1) as f32;
            deformed = next;
            if moved < s.tolerance {
                break;
            }
        }
    }
    let (count, sum) = match_all(&deformed, normals, surface, s, &mut matches);
    if count > 0 {
        (matched, rms) = (count, (sum / count as f64).sqrt() as f32);
    }
    Ok(NonRigidFit {
        deformed,
        matched,
        rms,
        solves,
    })
}

/// Matches every point (`None`: none, on the border, or too far); the count and the sum of
/// squared distances of the matched ones.
fn match_all(
    at: &[Vec3],
    normals: &[Vec3],
    surface: &Surface,
    s: &NonRigidSettings,
    out: &mut [Option<Vec3>],
) -> (usize, f64) {
    let (mut count, mut sum) = (0usize, 0f64);
    for ((p, nrm), o) in at.iter().zip(normals).zip(out.iter_mut()) {
        *o = surface
            .closest(*p, *nrm, s.min_dot)
            .filter(|m| !m.border && m.distance <= s.max_distance)
            .map(|m| {
                count += 1;
                sum += f64::from(m.distance * m.distance);
                m.on_plane
            });
    }
    (count, sum)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `side` x `side` sheet over [-1, 1]^2 with height `h(x, y)`.
    fn sheet(side: u32, h: impl Fn(f32, f32) -> f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        for j in 0..side {
            for i in 0..side {
                let (x, y) = (
                    -1.0 + 2.0 * i as f32 / (side - 1) as f32,
                    -1.0 + 2.0 * j as f32 / (side - 1) as f32,
                );
                p.push(Vec3::new(x, y, h(x, y)));
            }
        }
        let mut t = Vec::new();
        for j in 0..side - 1 {
            for i in 0..side - 1 {
                let a = j * side + i;
                t.push([a, a + 1, a + side + 1]);
                t.push([a, a + side + 1, a + side]);
            }
        }
        (p, t)
    }

    #[test]
    fn a_flat_template_takes_the_shape_of_a_bumpy_surface() {
        // Target: a sheet with a bump of height 0.1 (finer, and larger, so no template point
        // falls past its border); template: a flat 21 x 21 sheet over the middle.
        let bump = |x: f32, y: f32| 0.1 * (-(x * x + y * y) / 0.3).exp();
        let (tp, tt) = sheet(81, |x, y| bump(1.5 * x, 1.5 * y));
        let target: Vec<Vec3> = tp
            .iter()
            .map(|p| Vec3::new(p.x * 1.5, p.y * 1.5, p.z))
            .collect();
        let surface = Surface::new(target, &tt, |_| true);
        let (points, tris) = sheet(21, |_, _| 0.0);
        let normals = crate::register::vertex_normals(&points, &tris);
        let edges = knn_graph(&points, 6);
        // Down to a lower stiffness than the default: the bump spans only a few nodes.
        let settings = NonRigidSettings {
            max_distance: 0.3,
            stiffness: vec![20.0, 10.0, 5.0, 2.0, 1.0, 0.5],
            rounds: 5,
            ..NonRigidSettings::default()
        };
        let fit = nonrigid_icp(&points, &normals, &edges, &surface, &settings).unwrap();
        assert_eq!(fit.matched, points.len());
        // The points end near the bumpy surface: their height error (against the bump's true
        // height at each point's x, y) is a quarter of the flat template's at most on average,
        // and below 70% of the bump's height (0.1) everywhere.
        let error = |p: &Vec3| (p.z - bump(p.x, p.y)).abs();
        let mean = |v: &[Vec3]| v.iter().map(error).sum::<f32>() / v.len() as f32;
        let worst = fit.deformed.iter().map(error).fold(0.0, f32::max);
        let (before, after) = (mean(&points), mean(&fit.deformed));
        println!("mean height error {before} flat, {after} fitted; worst {worst}");
        assert!(after <= 0.25 * before, "{after} vs {before}");
        assert!(worst <= 0.7 * 0.1, "worst height error {worst}");
    }
}
