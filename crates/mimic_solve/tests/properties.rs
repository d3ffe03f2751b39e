//! Property tests (proptest) of the deformation bases on random meshes: small grids with random
//! jitter and bump, random control subsets, random frozen vertices, both solvers, regions on/off.
//!
//! Properties: building never panics and a built basis is finite; `u = B d` is finite for any
//! finite `d`; `B` is linear in `d` (`B(a d1 + c d2) = a B d1 + c B d2`); frozen rows are zero;
//! the RBF (regions off) reproduces every control displacement; the Laplacian (nothing frozen,
//! regions off) reproduces a uniform translation everywhere (`L 1 = 0`); and translating the whole
//! mesh leaves the basis unchanged (both solvers depend on positions only through differences).

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use glam::Vec3;
use mimic_solve::{Basis, build_basis};
use mimic_types::{
    Fdp, LaplacianWeights, Mesh, RbfDistance, RbfKernel, RegionBands, Rig, RigControl, SolverKind,
    SolverSettings,
};
use proptest::prelude::*;

/// A random rig: an `nx x ny` grid on the unit square, interior vertices jittered by up to
/// `jitter` of a cell, z a bump; controls at `controls` (distinct), `frozen` vertices frozen
/// unless they hold a control.
#[derive(Clone, Debug)]
struct Case {
    nx: usize,
    ny: usize,
    bump: f32,
    offsets: Vec<(f32, f32)>,
    controls: Vec<usize>,
    frozen: Vec<bool>,
    kind: SolverKind,
    regions: bool,
    radius: f64,
    gaussian: bool,
    weights: LaplacianWeights,
    geodesic: bool,
}

/// The `j`-th FDP of MPEG-4 groups 2..=11 (unique names for up to 89 controls).
fn fdp(j: usize) -> Fdp {
    const SIZES: [u8; 10] = [14, 14, 6, 4, 4, 1, 10, 15, 15, 6];
    let mut j = j;
    for (g, &size) in SIZES.iter().enumerate() {
        if j < size as usize {
            return Fdp::new(g as u8 + 2, j as u8 + 1).unwrap();
        }
        j -= size as usize;
    }
    unreachable!("at most 89 controls")
}

impl Case {
    fn mesh(&self, shift: Vec3) -> Mesh {
        let (nx, ny) = (self.nx, self.ny);
        let mut positions = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                let (mut x, mut y) = (i as f32 / (nx - 1) as f32, j as f32 / (ny - 1) as f32);
                if i > 0 && j > 0 && i + 1 < nx && j + 1 < ny {
                    let (ox, oy) = self.offsets[j * nx + i];
                    x += ox / (nx - 1) as f32;
                    y += oy / (ny - 1) as f32;
                }
                let z = self.bump * (-((x - 0.5).powi(2) + (y - 0.5).powi(2)) / 0.08).exp();
                positions.push(Vec3::new(x, y, z) + shift);
            }
        }
        let mut triangles = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let a = (j * nx + i) as u32;
                let (b, c) = (a + 1, a + nx as u32);
                triangles.push([a, b, c + 1]);
                triangles.push([a, c + 1, c]);
            }
        }
        Mesh {
            positions,
            triangles,
            ..Default::default()
        }
    }

    fn rig(&self, shift: Vec3) -> Rig {
        let mesh = self.mesh(shift);
        // Bands in the shifted frame, so a shifted rig has the same regions.
        let regions = RegionBands {
            top_from: 2.0 / 3.0 + shift.y,
            bottom_below: 1.0 / 3.0 + shift.y,
            band: 0.1,
        };
        let controls = self
            .controls
            .iter()
            .enumerate()
            .map(|(j, &v)| RigControl {
                fdp: fdp(j).into(),
                vertex: v as u32,
                region: regions.region_at(mesh.positions[v].y),
            })
            .collect();
        let mut frozen = self.frozen.clone();
        for &v in &self.controls {
            frozen[v] = false;
        }
        Rig {
            name: "prop".into(),
            units: "m".into(),
            mesh,
            controls,
            regions,
            frozen,
            solver: SolverSettings::default(),
            parts: Default::default(),
        }
    }

    fn settings(&self) -> SolverSettings {
        SolverSettings {
            kind: self.kind,
            kernel: if self.gaussian {
                RbfKernel::Gaussian {
                    radius: self.radius,
                }
            } else {
                RbfKernel::Exponential {
                    radius: self.radius,
                }
            },
            affine: false,
            distance: if self.geodesic {
                RbfDistance::Geodesic
            } else {
                RbfDistance::Euclidean
            },
            weights: self.weights,
            constraint_weight: 10.0,
            regions: self.regions,
            ..SolverSettings::default()
        }
    }
}

fn case() -> impl Strategy<Value = Case> {
    (3usize..9, 3usize..9)
        .prop_flat_map(|(nx, ny)| {
            let n = nx * ny;
            (
                Just((nx, ny)),
                0.0f32..0.4,
                prop::collection::vec((-0.35f32..0.35, -0.35f32..0.35), n),
                prop::sample::subsequence((0..n).collect::<Vec<_>>(), 1..=n.min(12)),
                prop::collection::vec(prop::bool::weighted(0.2), n),
                (
                    prop_oneof![Just(SolverKind::Rbf), Just(SolverKind::Laplacian)],
                    any::<bool>(),
                    0.15f64..1.0,
                    any::<bool>(),
                    prop_oneof![
                        Just(LaplacianWeights::Uniform),
                        Just(LaplacianWeights::MeanValue),
                        Just(LaplacianWeights::Cotangent)
                    ],
                    any::<bool>(),
                ),
            )
        })
        .prop_map(
            |(
                (nx, ny),
                bump,
                offsets,
                controls,
                frozen,
                (kind, regions, radius, gaussian, weights, geodesic),
            )| Case {
                nx,
                ny,
                bump,
                offsets,
                controls,
                frozen,
                kind,
                regions,
                radius,
                gaussian,
                weights,
                geodesic,
            },
        )
}

fn displacements(m: usize) -> impl Strategy<Value = Vec<Vec3>> {
    prop::collection::vec(
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0).prop_map(|(x, y, z)| Vec3::new(x, y, z) * 0.1),
        m,
    )
}

fn apply(b: &Basis, d: &[Vec3]) -> Vec<Vec3> {
    let mut out = vec![Vec3::NAN; b.vertex_count()];
    b.apply(d, &mut out);
    out
}

/// Sum of |B_ij| over row i: the factor that bounds the rounding of `(B d)_i`.
fn row_abs_sum(b: &Basis, i: usize) -> f32 {
    b.row(i).iter().map(|w| w.abs()).sum()
}

/// First-order bound on how far translating the mesh by `shift` moves an RBF basis entry.
///
/// Positions (coordinates up to `|shift| + 1.4`) are stored in f32, so every distance the RBF uses
/// changes by up to `e = 2 sqrt(3) eps (|shift| + 1.4)`, a relative change of at most
/// `delta = e / d_min` (`d_min`: the closest two vertices; a geodesic path is no shorter than
/// that). With `x phi'(x) <= L` (2/e Gaussian, 1/e exponential) each kernel entry changes by at
/// most `L delta`. For one solve `B_r = K X`, `X = A^-1` of the centres' kernel matrix `A`:
/// `dB_r = dK X - B_r dA X`, so `|dB_ij| <= L delta (1 + S) C`, with `C` the largest column sum of
/// `|X|` and `S` the sum of all of them (which bounds every row sum of `|B_r|`, since `|K| <= 1`).
/// The region blend is convex; its weights ramp over the band, moving by `e / band`, on columns
/// bounded by `S`. The border fade's factors move by at most `3 delta` (smoothstep' <= 1.5 on a
/// ratio of two distances) on rows bounded by `S`. Twice the sum (second-order terms), plus the
/// f32 rounding of both bases (`2 eps max|B|`).
fn rbf_translation_bound(c: &Case, shift: Vec3, bmax: f32) -> f32 {
    use faer::linalg::solvers::DenseSolveCore;
    use mimic_solve::geodesic::EdgeGraph;
    let rig = c.rig(Vec3::ZERO);
    let p = &rig.mesh.positions;
    let e = 2.0 * 3f64.sqrt() * f32::EPSILON as f64 * (shift.length() as f64 + 1.4);
    let mut d_min = f64::INFINITY;
    for (i, a) in p.iter().enumerate() {
        for b in &p[i + 1..] {
            d_min = d_min.min((*a - *b).as_dvec3().length());
        }
    }
    let delta = e / d_min;
    let kernel = c.settings().kernel;
    let phi = |d: f64| mimic_solve::rbf::kernel_value(kernel, d);
    let lip = if c.gaussian { 2.0 } else { 1.0 } / std::f64::consts::E;
    let vertices: Vec<usize> = rig.controls.iter().map(|k| k.vertex as usize).collect();
    let between: Vec<Vec<f64>> = if c.geodesic {
        let graph = EdgeGraph::new(p, &rig.mesh.triangles);
        let to: Vec<Vec<f64>> = vertices.iter().map(|&v| graph.distances_from(v)).collect();
        (0..vertices.len())
            .map(|a| {
                (0..vertices.len())
                    .map(|b| 0.5 * (to[a][vertices[b]] + to[b][vertices[a]]))
                    .collect()
            })
            .collect()
    } else {
        vertices
            .iter()
            .map(|&a| {
                vertices
                    .iter()
                    .map(|&b| (p[a] - p[b]).as_dvec3().length())
                    .collect()
            })
            .collect()
    };
    let subsets: Vec<Vec<usize>> = if c.regions {
        mimic_solve::regions::controls_by_region(&rig.controls).to_vec()
    } else {
        vec![(0..vertices.len()).collect()]
    };
    let (mut col_max, mut col_sum) = (0f64, 0f64);
    for subset in subsets.iter().filter(|s| !s.is_empty()) {
        let k = subset.len();
        let a = faer::Mat::<f64>::from_fn(k, k, |i, j| phi(between[subset[i]][subset[j]]));
        let x = a.partial_piv_lu().inverse();
        let sums: Vec<f64> = (0..k)
            .map(|j| (0..k).map(|i| x[(i, j)].abs()).sum())
            .collect();
        col_max = col_max.max(sums.iter().copied().fold(0.0, f64::max));
        col_sum = col_sum.max(sums.iter().sum());
    }
    let solve = lip * delta * (1.0 + col_sum) * col_max;
    let blend = if c.regions {
        e / rig.regions.band as f64 * col_sum
    } else {
        0.0
    };
    let fade = 3.0 * delta * col_sum;
    (2.0 * (solve + blend + fade)) as f32 + 2.0 * f32::EPSILON * bmax
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// Finite, linear, frozen rows zero, controls hit (RBF) / translation kept (Laplacian).
    #[test]
    fn bases_are_finite_linear_and_keep_their_invariants(
        c in case(),
        seed in prop::collection::vec(-1.0f32..1.0, 12 * 3 * 2 + 5),
    ) {
        let rig = c.rig(Vec3::ZERO);
        let s = c.settings();
        // Every random rig here is valid (distinct, unfrozen controls on a connected grid whose
        // vertices stay over 0.3 cells apart), so the build must succeed.
        let b = build_basis(&rig, &s);
        prop_assert!(b.is_ok(), "build failed: {:?}", b.err());
        let b = b.unwrap();
        let m = rig.controls.len();
        prop_assert_eq!(b.control_count(), m);
        prop_assert!(b.as_slice().iter().all(|w| w.is_finite()), "non-finite basis weight");

        let v = |k: usize| Vec3::new(seed[3 * k], seed[3 * k + 1], seed[3 * k + 2]) * 0.1;
        let d1: Vec<Vec3> = (0..m).map(v).collect();
        let d2: Vec<Vec3> = (0..m).map(|k| v(k + 12)).collect();
        let (a, cc) = (seed[72] * 2.0, seed[73] * 2.0);
        let mix: Vec<Vec3> = d1.iter().zip(&d2).map(|(x, y)| *x * a + *y * cc).collect();
        let (u1, u2, um) = (apply(&b, &d1), apply(&b, &d2), apply(&b, &mix));
        let dmax = 0.1 * 3f32.sqrt();
        let eps = f32::EPSILON;
        for i in 0..b.vertex_count() {
            prop_assert!(u1[i].is_finite() && um[i].is_finite());
            // Each computed (B d)_i is within (m + 2) eps S_i max|d| of exact per component (S_i =
            // sum_j |B_ij|); three such results combine with factors |a|, |c|, 1 on |d| <= max|d| (|a| + |c|),
            // and a vector length adds sqrt(3): bound 4 sqrt(3) (m + 2) eps S_i (|a| + |c|) max|d| + 1e-12.
            let bound = 4.0 * 3f32.sqrt() * (m as f32 + 2.0) * eps * row_abs_sum(&b, i)
                * (a.abs() + cc.abs()) * dmax + 1e-12;
            let err = (um[i] - (u1[i] * a + u2[i] * cc)).length();
            prop_assert!(err <= bound, "linearity at {}: {} > {}", i, err, bound);
            if rig.frozen[i] {
                prop_assert!(b.row(i).iter().all(|w| *w == 0.0), "frozen row {} not zero", i);
            }
        }
        if c.kind == SolverKind::Rbf && !c.regions {
            // RBF interpolates: u at each control's vertex equals its d. The f64 solve is exact to
            // ~cond * 1e-16; the basis is rounded to f32 (relative eps per weight) and summed in f32:
            // |u - d| <= (m + 2) eps S_i max|d| sqrt(3), plus the f64 residual, well under 1e-3 * max|d|
            // for the radii drawn here. Take the larger of the two as the bound.
            for (j, ctl) in rig.controls.iter().enumerate() {
                let i = ctl.vertex as usize;
                let bound = (3f32.sqrt() * (m as f32 + 2.0) * eps * row_abs_sum(&b, i) * dmax)
                    .max(1e-3 * dmax);
                let err = (u1[i] - d1[j]).length();
                prop_assert!(err <= bound, "control {} off by {} > {}", j, err, bound);
            }
        }
        if c.kind == SolverKind::Laplacian && !c.regions && !rig.frozen.iter().any(|f| *f) {
            // L 1 = 0, so for d = t at every control the exact minimiser is u = t everywhere. The
            // sparse f64 solve leaves a relative residual ~1e-10; f32 rounding of B and an m-term
            // sum add (m + 2) eps S_i |t|: bound 1e-5 |t| + (m + 2) eps S_i |t|.
            let t = Vec3::new(seed[74], seed[75], seed[76]) * 0.1;
            for (i, u) in apply(&b, &vec![t; m]).iter().enumerate() {
                let bound = (1e-5 + (m as f32 + 2.0) * eps * row_abs_sum(&b, i)) * t.length();
                prop_assert!((*u - t).length() <= bound, "vertex {}: {} vs {}", i, u, t);
            }
        }
    }

    /// Translating the whole mesh (and its region bands) leaves the basis unchanged.
    #[test]
    fn basis_is_invariant_under_mesh_translation(
        c in case(),
        (sx, sy, sz) in (-5.0f32..5.0, -5.0f32..5.0, -5.0f32..5.0),
    ) {
        let shift = Vec3::new(sx, sy, sz);
        let s = c.settings();
        let b0 = build_basis(&c.rig(Vec3::ZERO), &s).unwrap();
        let b1 = build_basis(&c.rig(shift), &s).unwrap();
        let bmax = b0.as_slice().iter().fold(0f32, |a, w| a.max(w.abs()));
        let worst = b0.as_slice().iter().zip(b1.as_slice()).fold(0f32, |a, (x, y)| a.max((x - y).abs()));
        let bound = match c.kind {
            SolverKind::Rbf => rbf_translation_bound(&c, shift, bmax),
            // The Laplacian's weights come from edge vectors and angles of one-ring neighbours
            // (relative change <= ~5e-5, as below) and its solve is well conditioned (constraint
            // weight 10 on a connected mesh): 1e-4 max|B| (measured worst over 300 cases 1.2e-5 max|B|).
            _ => 1e-4 * bmax.max(1.0),
        };
        prop_assert!(worst <= bound, "basis moved by {} > {} (max |B| {})", worst, bound, bmax);
    }

    /// Random finite displacements of any size give finite vertex displacements.
    #[test]
    fn random_displacements_never_give_nan(
        c in case(),
        d in displacements(12),
        scale in prop_oneof![Just(1.0f32), Just(1e3), Just(1e-6)],
    ) {
        let rig = c.rig(Vec3::ZERO);
        let b = build_basis(&rig, &c.settings()).unwrap();
        let d: Vec<Vec3> = d[..rig.controls.len()].iter().map(|v| *v * scale).collect();
        prop_assert!(apply(&b, &d).iter().all(|u| u.is_finite()));
    }
}
