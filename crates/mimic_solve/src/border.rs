//! The RBF's border with frozen vertices: basis rows faded to zero toward the frozen set.
//!
//! An RBF field does not know about frozen vertices: with the exponential kernel the jaw's field
//! is still a fifth of the chin's motion 3 cm from the chin, and a frozen neighbour then cuts it
//! to zero over one edge, a hard edge where the face meets the neck (issue 14). The Laplacian and
//! the thin shell have the frozen vertices as boundary conditions and need nothing here.
//!
//! The fade: a free vertex at edge-path distance `g` ([`EdgeGraph::distances_from_set`]) from the
//! nearest frozen vertex keeps `smoothstep(g / w)` of its row, with `w` = [`FADE_RADII`] kernel
//! radii, capped at the smallest such distance of a control vertex so that every control keeps
//! its whole row and is still interpolated exactly. `smoothstep` is flat at both ends, so the
//! faded field meets the frozen set and the unfaded field without a kink.

use crate::geodesic::EdgeGraph;
use mimic_types::RbfKernel;

/// The fade runs over this many kernel radii of edge-path distance from the frozen set.
pub const FADE_RADII: f64 = 2.0;

/// `3t^2 - 2t^3` of `t` clamped to [0, 1]: 0 with zero slope at 0, 1 with zero slope at 1.
pub fn smoothstep(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Per-vertex factors of the basis rows near the frozen set.
#[derive(Clone, Debug, PartialEq)]
pub struct BorderFade {
    /// Width `w` of the fade, rig units (edge-path distance from the frozen set).
    pub width: f64,
    /// `smoothstep(g_i / w)` per vertex: 0 on frozen vertices, 1 from `w` on.
    pub factors: Vec<f64>,
}

impl BorderFade {
    /// The fade of a mesh (its edge `graph`) whose vertices in `frozen` stay still, for an RBF
    /// through the control vertices `controls` with `kernel`; `None` when nothing frozen is
    /// reachable from a free vertex (no border to fade) or no positive width is left (thin-plate
    /// has no radius: its width is the cap alone).
    pub fn new(
        graph: &EdgeGraph,
        frozen: &[bool],
        controls: &[usize],
        kernel: RbfKernel,
    ) -> Option<Self> {
        let sources: Vec<usize> = (0..graph.vertex_count())
            .filter(|&i| frozen.get(i).copied().unwrap_or(false))
            .collect();
        if sources.is_empty() {
            return None;
        }
        let dist = graph.distances_from_set(&sources);
        let reaches_free = dist.iter().zip(frozen).any(|(d, &f)| !f && d.is_finite());
        if !reaches_free {
            return None;
        }
        // No control is faded: the width stops at the nearest control's distance.
        let cap = controls
            .iter()
            .filter_map(|&c| dist.get(c).copied())
            .fold(f64::INFINITY, f64::min);
        let wanted = kernel.radius().map_or(f64::INFINITY, |r| FADE_RADII * r);
        let width = wanted.min(cap);
        if !(width.is_finite() && width > 0.0) {
            return None;
        }
        let factors = dist.iter().map(|&g| smoothstep(g / width)).collect();
        Some(Self { width, factors })
    }

    /// Multiplies each row of the row-major `n x m` matrix `b` by its vertex's factor.
    pub fn apply(&self, b: &mut [f64], m: usize) {
        if m == 0 {
            return;
        }
        for (row, &f) in b.chunks_exact_mut(m).zip(&self.factors) {
            if f < 1.0 {
                row.iter_mut().for_each(|v| *v *= f);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::{grid, lcg, random_d, rig};
    use crate::{Basis, build_basis, rbf};
    use glam::Vec3;
    use mimic_types::{LaplacianWeights, RbfDistance, SolverKind, SolverSettings};

    /// Grid spacing of the test mesh: `N x N` vertices on the unit square.
    const N: usize = 41;
    const H: f64 = 1.0 / (N - 1) as f64;
    /// Kernel radius: the wanted fade width is 2 x 0.1 = 0.2, eight rows.
    const RADIUS: f64 = 0.1;

    fn settings(regions: bool) -> SolverSettings {
        SolverSettings {
            kind: SolverKind::Rbf,
            kernel: RbfKernel::Exponential { radius: RADIUS },
            affine: false,
            distance: RbfDistance::Euclidean,
            weights: LaplacianWeights::MeanValue,
            constraint_weight: 10.0,
            regions,
            top_split: None,
            shell: Default::default(),
            rbf_ridge: 0.0,
            shell_blend: [0.0; 3],
        }
    }

    /// A flat grid with its bottom row frozen and controls from row `lowest` up (row j at y = j H).
    fn frozen_bottom_rig(lowest: usize) -> mimic_types::Rig {
        let rows = [lowest, 18, 26, 34, 39];
        let controls: Vec<u32> = rows
            .iter()
            .flat_map(|&j| [5usize, 20, 35].map(move |i| (j * N + i) as u32))
            .collect();
        let mut r = rig(grid(N, N, 0.0, 0.0, 0), &controls, 0.05);
        for (i, f) in r.frozen.iter_mut().enumerate() {
            *f = i < N;
        }
        r
    }

    fn apply(b: &Basis, d: &[Vec3]) -> Vec<Vec3> {
        let mut out = vec![Vec3::NAN; b.vertex_count()];
        b.apply(d, &mut out);
        out
    }

    /// The RBF's basis without the fade, straight from `rbf_columns` (regions off).
    fn unfaded(r: &mimic_types::Rig) -> Vec<f64> {
        let s = settings(false);
        let centres: Vec<Vec3> = r
            .controls
            .iter()
            .map(|c| r.mesh.positions[c.vertex as usize])
            .collect();
        let fdps: Vec<_> = r.controls.iter().map(|c| c.fdp).collect();
        rbf::rbf_columns(&rbf::RbfInputs {
            positions: &r.mesh.positions,
            frozen: &r.frozen,
            centres: &centres,
            fdps: &fdps,
            kernel: s.kernel,
            affine: false,
            metric: rbf::Metric::Euclidean,
            ridge: 0.0,
            system: "test",
        })
        .unwrap()
    }

    #[test]
    fn rows_are_the_unfaded_rows_times_an_independent_smoothstep_of_the_row_height() {
        // Independent truth: on the flat, unjittered grid the edge path from row j to the frozen
        // bottom row is j straight steps, g = j H; the lowest controls sit on row 12 (g = 0.3),
        // beyond the wanted width 2 x 0.1, so w = 0.2 and row j keeps (3t^2 - 2t^3), t = j H / w.
        let r = frozen_bottom_rig(12);
        let m = r.controls.len();
        let b = build_basis(&r, &settings(false)).unwrap();
        let raw = unfaded(&r);
        let w = FADE_RADII * RADIUS;
        let controls: Vec<usize> = r.controls.iter().map(|c| c.vertex as usize).collect();
        let fade = BorderFade::new(
            &EdgeGraph::new(&r.mesh.positions, &r.mesh.triangles),
            &r.frozen,
            &controls,
            settings(false).kernel,
        )
        .unwrap();
        for j in 0..N {
            let t = (j as f64 * H / w).min(1.0);
            let factor = if j == 0 { 0.0 } else { t * t * (3.0 - 2.0 * t) };
            for i in 0..N {
                let v = j * N + i;
                let mut size = 0f64;
                for k in 0..m {
                    let got = f64::from(b.row(v)[k]);
                    // f32 storage of weights <= 1: 1e-6 absolute.
                    assert!(
                        (got - raw[v * m + k] * factor).abs() < 1e-6,
                        "vertex ({i}, {j}) control {k}: {got} vs {} x {factor}",
                        raw[v * m + k]
                    );
                    size += got.abs();
                }
                // The fade's own factors: the independent ones (f32 positions: 1e-6), and a
                // monotone ramp, never decreasing up a column, away from the border.
                assert!((fade.factors[v] - factor).abs() < 1e-6, "({i}, {j})");
                if j > 0 {
                    assert!(fade.factors[v] >= fade.factors[v - N], "({i}, {j})");
                }
                if j == 1 {
                    // The frozen border's neighbours, ~0: t = H / w = 1/8 and the factor
                    // 3t^2 - 2t^3 < 3 (H / w)^2 = 0.047 of the unfaded row (+ f32 rounding).
                    let whole: f64 = raw[v * m..][..m].iter().map(|x| x.abs()).sum();
                    assert!(size <= 3.0 * (H / w).powi(2) * whole + 1e-6 * m as f64);
                }
            }
        }
    }

    #[test]
    fn controls_keep_their_rows_and_exact_interpolation_with_the_width_capped() {
        // The lowest controls on row 3 (g = 0.075 < 0.2): the width is capped to 0.075, the
        // controls' rows are whole and every control displacement is reproduced.
        let r = frozen_bottom_rig(3);
        let fade = BorderFade::new(
            &EdgeGraph::new(&r.mesh.positions, &r.mesh.triangles),
            &r.frozen,
            &r.controls
                .iter()
                .map(|c| c.vertex as usize)
                .collect::<Vec<_>>(),
            settings(false).kernel,
        )
        .unwrap();
        // Three straight steps of H between f32 positions: 1e-6.
        assert!((fade.width - 3.0 * H).abs() < 1e-6, "{}", fade.width);
        let m = r.controls.len();
        for regions in [false, true] {
            let b = build_basis(&r, &settings(regions)).unwrap();
            let mut seed = 7;
            let d = random_d(&mut seed, m, 0.05);
            let u = apply(&b, &d);
            let dmax = d.iter().fold(0f32, |a, v| a.max(v.abs().max_element()));
            for (j, (c, dj)) in r.controls.iter().zip(&d).enumerate() {
                assert_eq!(fade.factors[c.vertex as usize], 1.0, "control {j}");
                if !regions {
                    // f32 basis and f32 sums, as rbf_hits_every_control_exactly: 1e-4 max|d|.
                    assert!(
                        (u[c.vertex as usize] - *dj).abs().max_element() <= 1e-4 * dmax,
                        "control {j}"
                    );
                }
            }
            // Frozen rows stay zero.
            for i in 0..N {
                assert!(b.row(i).iter().all(|&x| x == 0.0));
            }
        }
    }

    #[test]
    fn factors_match_brute_force_distances_on_a_jittered_bumped_mesh() {
        // Independent distances: Bellman-Ford relaxation over every triangle edge until nothing
        // changes, from a frozen patch, against the multi-source Dijkstra of the fade.
        let mesh = grid(12, 10, 0.3, 0.3, 4);
        let n = mesh.vertex_count();
        let mut seed = 9;
        let controls = [5 * 12 + 8, 8 * 12 + 10];
        let frozen: Vec<bool> = (0..n)
            .map(|i| (i % 12 < 2 || lcg(&mut seed) > 0.8) && !controls.contains(&i))
            .collect();
        let kernel = RbfKernel::Gaussian { radius: 0.05 };
        let fade = BorderFade::new(
            &EdgeGraph::new(&mesh.positions, &mesh.triangles),
            &frozen,
            &controls,
            kernel,
        )
        .unwrap();
        let mut dist: Vec<f64> = frozen
            .iter()
            .map(|&f| if f { 0.0 } else { f64::INFINITY })
            .collect();
        loop {
            let mut changed = false;
            for t in &mesh.triangles {
                for e in 0..3 {
                    let (a, b) = (t[e] as usize, t[(e + 1) % 3] as usize);
                    let len =
                        (mesh.positions[a].as_dvec3() - mesh.positions[b].as_dvec3()).length();
                    for (x, y) in [(a, b), (b, a)] {
                        if dist[x] + len < dist[y] - 1e-15 {
                            dist[y] = dist[x] + len;
                            changed = true;
                        }
                    }
                }
            }
            if !changed {
                break;
            }
        }
        let cap = controls
            .iter()
            .map(|&c| dist[c])
            .fold(f64::INFINITY, f64::min);
        let w = (FADE_RADII * 0.05).min(cap);
        // Sums of the same edge lengths in another order: 1e-12.
        assert!((fade.width - w).abs() < 1e-12);
        for (i, (&f, &g)) in fade.factors.iter().zip(&dist).enumerate() {
            assert!((f - smoothstep(g / w)).abs() < 1e-9, "vertex {i}");
        }
        assert!(fade.factors.iter().any(|&f| f > 0.0 && f < 1.0));
    }

    #[test]
    fn nothing_frozen_or_unreachable_means_no_fade() {
        let r = frozen_bottom_rig(12);
        let controls: Vec<usize> = r.controls.iter().map(|c| c.vertex as usize).collect();
        let kernel = settings(false).kernel;
        let none = vec![false; r.mesh.vertex_count()];
        assert!(
            BorderFade::new(
                &EdgeGraph::new(&r.mesh.positions, &r.mesh.triangles),
                &none,
                &controls,
                kernel
            )
            .is_none()
        );
        // A frozen vertex on no triangle: nothing free is reachable from it.
        let mut positions = r.mesh.positions.clone();
        positions.push(Vec3::splat(9.0));
        let mut lone = none.clone();
        lone.push(true);
        assert!(
            BorderFade::new(
                &EdgeGraph::new(&positions, &r.mesh.triangles),
                &lone,
                &controls,
                kernel
            )
            .is_none()
        );
    }

    #[test]
    fn smoothstep_is_flat_at_both_ends_and_monotone() {
        assert_eq!(smoothstep(-1.0), 0.0);
        assert_eq!(smoothstep(0.0), 0.0);
        assert_eq!(smoothstep(0.5), 0.5);
        assert_eq!(smoothstep(1.0), 1.0);
        assert_eq!(smoothstep(3.0), 1.0);
        let mut last = 0.0;
        for k in 1..=100 {
            let s = smoothstep(k as f64 / 100.0);
            assert!(s >= last);
            last = s;
        }
        // Zero slope at the ends: s(e) = 3e^2 - 2e^3 < 3e^2.
        assert!(smoothstep(1e-3) < 3e-6 && 1.0 - smoothstep(1.0 - 1e-3) < 3e-6);
    }
}
