use super::*;

use crate::test_meshes::{grid, lcg, tri_lattice};

/// Area-weighted normals in f64 with, per vertex, the bound on the f32 error of either method:
/// each of the `k` triangle cross products at `v` is off by at most `(6 + k) eps L_t^2` (edge
/// differences, products and the running sum each rounded; `L_t` the longest edge), and
/// normalising a sum `N` perturbed by `delta` moves it by at most `2 |delta| / |N|`, plus the
/// normalisation's own error (a Newton-refined reciprocal square root in the vectorised path,
/// within 4 eps; sqrt and division elsewhere): `tol_v = 2 (6 + k_v) eps sum_t L_t^2 / |N_v| + 8 eps`.
fn reference(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<(glam::DVec3, f64)> {
    let n = positions.len();
    let mut sum = vec![glam::DVec3::ZERO; n];
    let mut scale = vec![0f64; n];
    let mut k = vec![0usize; n];
    for t in triangles
        .iter()
        .filter(|t| t.iter().all(|&v| (v as usize) < n))
    {
        let [a, b, c] = t.map(|v| positions[v as usize].as_dvec3());
        let nt = (b - a).cross(c - a);
        let l2 = (b - a)
            .length_squared()
            .max((c - a).length_squared())
            .max((c - b).length_squared());
        for &v in t {
            sum[v as usize] += nt;
            scale[v as usize] += l2;
            k[v as usize] += 1;
        }
    }
    let eps = f32::EPSILON as f64;
    sum.iter()
        .zip(&scale)
        .zip(&k)
        .map(|((s, l2), &k)| {
            let len = s.length();
            // The fan kernels' difference vectors run from a neighbour, not the centre:
            // up to two edges long, so their products' rounding is bounded with 4 l2.
            let tol = if len > 0.0 {
                2.0 * (6 + k) as f64 * eps * 4.0 * l2 / len + 8.0 * eps
            } else {
                f64::INFINITY
            };
            (
                if len > 0.0 {
                    *s / len
                } else {
                    glam::DVec3::ZERO
                },
                tol,
            )
        })
        .collect()
}

/// Both fan paths (vectorised where the CPU has it, and portable) and `vertex_normals` against
/// the f64 reference, every vertex of `0..count` within its stated tolerance.
fn check_fans(positions: &[Vec3], triangles: &[[u32; 3]], count: usize) {
    let truth = reference(positions, triangles);
    let mut face = vec![Vec3::ZERO; positions.len()];
    vertex_normals(positions, triangles, &mut face);
    let fans = VertexFans::new(count, positions.len(), triangles);
    assert_eq!(fans.count(), count);
    // Packed positions (3 floats a vertex, 1 of padding, NaN here: never used).
    let mut packed: Vec<f32> = positions.iter().flat_map(|p| p.to_array()).collect();
    packed.push(f32::NAN);
    let mut fast = vec![Vec3::NAN; count];
    let mut seen = vec![0; count];
    fans.normals_packed(&packed, |v, n| {
        fast[v] = n;
        seen[v] += 1;
    });
    assert!(seen.iter().all(|&c| c == 1), "each fan vertex written once");
    let mut portable = vec![Vec3::NAN; count];
    fans.normals_packed_portable(&packed, &mut |v, n| portable[v] = n);
    // Renamed (here v -> 2 v + 1): the same normals, each under its new name, each once.
    let names: Vec<u32> = (0..count as u32).map(|v| 2 * v + 1).collect();
    let mut renamed = vec![Vec3::NAN; 2 * count + 1];
    let mut named_seen = vec![0; 2 * count + 1];
    fans.clone()
        .with_names(&names)
        .normals_packed(&packed, |v, n| {
            renamed[v] = n;
            named_seen[v] += 1;
        });
    for v in 0..count {
        assert_eq!(named_seen[2 * v + 1], 1, "renamed vertex {v} written once");
        let (a, b) = (renamed[2 * v + 1], fast[v]);
        assert!(
            a == b || (a.is_nan() && b.is_nan()),
            "renamed vertex {v}: {a} vs {b}"
        );
    }
    assert_eq!(named_seen.iter().sum::<i32>(), count as i32);
    // Each kernel by name (the portable one where the CPU lacks AVX2): every vertex written
    // once, each within the reference's bound below.
    let by_kernel = [VectorKernel::Portable, VectorKernel::Avx2].map(|k| {
        let mut out = vec![Vec3::NAN; count];
        let mut seen = vec![0; count];
        fans.normals_packed_by(k, &packed, |v, n| {
            out[v] = n;
            seen[v] += 1;
        });
        assert!(
            seen.iter().all(|&c| c == 1),
            "{k:?}: each vertex written once"
        );
        out
    });
    let [by_portable, by_avx2] = &by_kernel;
    for v in 0..count {
        for (what, a, b) in [
            ("portable by name", by_portable[v], portable[v]),
            ("avx2 by name", by_avx2[v], fast[v]),
        ] {
            assert!(a == b || (a.is_nan() && b.is_nan()), "{what} v={v}");
        }
    }
    for v in 0..count {
        let (t, tol) = truth[v];
        for (what, got) in [
            ("fans", fast[v]),
            ("portable", portable[v]),
            ("face", face[v]),
            ("avx2", by_avx2[v]),
        ] {
            if tol.is_finite() && tol < 0.1 {
                let err = (got.as_dvec3() - t).length();
                assert!(
                    err <= tol,
                    "{what} v={v}: {got} vs {t}, err {err:e} > tol {tol:e}"
                );
            } else {
                // Sum (nearly) zero: only ask for a finite result of length 0 or 1.
                let l = got.length();
                assert!(l == 0.0 || (l - 1.0).abs() < 1e-5, "{what} v={v}: {got}");
            }
        }
    }
}

#[test]
fn fans_match_reference_on_generated_meshes() {
    // Open sheets (boundary fans), bumps, jitter, and a sheet far from the origin.
    let g = grid(23, 17, 0.4, 0.3, 3);
    check_fans(&g.positions, &g.triangles, g.positions.len());
    let t = tri_lattice(19, 21, 0.25, 5);
    check_fans(&t.positions, &t.triangles, t.positions.len());
    let far: Vec<Vec3> = g
        .positions
        .iter()
        .map(|p| *p * 0.01 + Vec3::new(100.0, -50.0, 30.0))
        .collect();
    check_fans(&far, &g.triangles, far.len());
    // Only some vertices with fans; their neighbours beyond `count` are read, not written.
    check_fans(&g.positions, &g.triangles, 100);
    // Random triangles over random points: non-manifold fans of any shape.
    let mut seed = 11u64;
    let p: Vec<Vec3> = (0..60)
        .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)))
        .collect();
    let tris: Vec<[u32; 3]> = (0..300)
        .map(|_| [0; 3].map(|_| ((lcg(&mut seed) + 1.0) * 30.0) as u32 % 60))
        .collect();
    check_fans(&p, &tris, p.len());
}

#[test]
fn packed_offsets_are_three_times_the_entries_on_either_side_of_16_bits() {
    // A 147 x 148 grid (21 756 positions: every offset below 65 536) and a 148 x 148 one (21 904:
    // some past it): both kernels read the u32 offsets to the same normals, against the
    // reference within its bound (`check_fans`).
    for nx in [147, 148] {
        let g = grid(nx, 148, 0.3, 0.3, 7);
        let fans = VertexFans::new(g.positions.len(), g.positions.len(), &g.triangles);
        let want: Vec<u32> = fans.entries.iter().map(|&w| 3 * w).collect();
        assert_eq!(
            fans.offsets, want,
            "{nx} x 148: offsets are 3 x the entries"
        );
        check_fans(&g.positions, &g.triangles, g.positions.len());
    }
}

#[test]
fn fans_match_reference_on_a_closed_mesh() {
    // A UV sphere: closed fans everywhere, poles of high valence.
    let (rings, segs) = (12u32, 20u32);
    let mut p = vec![Vec3::Z, -Vec3::Z];
    for r in 1..rings {
        let th = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segs {
            let ph = std::f32::consts::TAU * s as f32 / segs as f32;
            p.push(Vec3::new(
                th.sin() * ph.cos(),
                th.sin() * ph.sin(),
                th.cos(),
            ));
        }
    }
    let at = |r: u32, s: u32| 2 + (r - 1) * segs + s % segs;
    let mut t = Vec::new();
    for s in 0..segs {
        t.push([0, at(1, s), at(1, s + 1)]);
        t.push([1, at(rings - 1, s + 1), at(rings - 1, s)]);
        for r in 1..rings - 1 {
            t.push([at(r, s), at(r + 1, s), at(r + 1, s + 1)]);
            t.push([at(r, s), at(r + 1, s + 1), at(r, s + 1)]);
        }
    }
    check_fans(&p, &t, p.len());
    // Every fan is closed, so it lists its k neighbours once for k triangles (no closing entry
    // back to the first): groups of 16 by length, each padded to its longest.
    let mut valence = vec![0usize; p.len()];
    t.iter().flatten().for_each(|&v| valence[v as usize] += 1);
    valence.sort_unstable();
    let padded: usize = valence.chunks(16).map(|c| 16 * c[c.len() - 1]).sum();
    assert_eq!(VertexFans::new(p.len(), p.len(), &t).entry_count(), padded);
    // Outward: the normal at a vertex of a unit sphere is close to its position.
    let mut packed: Vec<f32> = p.iter().flat_map(|q| q.to_array()).collect();
    packed.push(0.0);
    VertexFans::new(p.len(), p.len(), &t).normals_packed(&packed, |v, n| {
        assert!(n.dot(p[v]) > 0.95, "v={v}: {n} at {}", p[v]);
    });
}

#[test]
fn fans_give_zero_for_degenerate_isolated_and_bad() {
    let p = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0), Vec3::ONE];
    let t = [[0, 1, 2], [0, 1, 7], [1, 1, 2]];
    let fans = VertexFans::new(4, 4, &t);
    assert_eq!(fans.position_count(), 4);
    let mut packed: Vec<f32> = p.iter().flat_map(|q| q.to_array()).collect();
    packed.push(0.0);
    let mut out = [Vec3::ONE; 4];
    fans.normals_packed(&packed, |v, n| out[v] = n);
    assert!(out.iter().all(|n| *n == Vec3::ZERO), "{out:?}");
    let mut out = [Vec3::ONE; 4];
    fans.normals_packed_portable(&packed, &mut |v, n| out[v] = n);
    assert!(out.iter().all(|n| *n == Vec3::ZERO), "{out:?}");
    for k in [VectorKernel::Portable, VectorKernel::Avx2] {
        let mut out = [Vec3::ONE; 4];
        fans.normals_packed_by(k, &packed, |v, n| out[v] = n);
        assert!(out.iter().all(|n| *n == Vec3::ZERO), "{k:?}: {out:?}");
    }
    let none = VertexFans::new(0, 0, &[]);
    none.normals_packed(&[0.0], |_, _| unreachable!("no fans"));
}

#[test]
fn flat_quad_points_up_and_weights_by_area() {
    // Two triangles of a unit square in the xy plane, CCW seen from +z.
    let p = [
        Vec3::ZERO,
        Vec3::X,
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::Y,
        Vec3::new(5.0, 5.0, 5.0),
    ];
    let t = [[0, 1, 2], [0, 2, 3]];
    let mut out = [Vec3::NAN; 5];
    vertex_normals(&p, &t, &mut out);
    for n in &out[..4] {
        assert!((*n - Vec3::Z).length() < 1e-6);
    }
    assert_eq!(out[4], Vec3::ZERO, "isolated vertex gets zero");
}

#[test]
fn area_weighting_on_a_roof() {
    // Vertex 0 is shared by a big triangle in the xy plane (area 2) and a small one in the xz
    // plane (area 0.5): the normal is (2 z + 0.5 (-y)) normalised... computed analytically.
    let p = [
        Vec3::ZERO,
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
    ];
    // (p1 - p0) x (p2 - p0) = 4 z (twice the area 2); (p3 - p0) x (p1 - p0) = (0,0,1)x(2,0,0) = 2 y.
    let t = [[0, 1, 2], [0, 3, 1]];
    let mut out = [Vec3::ZERO; 4];
    vertex_normals(&p, &t, &mut out);
    let expect = Vec3::new(0.0, 2.0, 4.0).normalize();
    assert!((out[0] - expect).length() < 1e-6, "{}", out[0]);
}

#[test]
fn degenerate_and_bad_triangles_give_zero_not_nan() {
    let p = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)];
    let t = [[0, 1, 2], [0, 1, 7]];
    let mut out = [Vec3::ONE; 3];
    vertex_normals(&p, &t, &mut out);
    assert!(out.iter().all(|n| *n == Vec3::ZERO));
}
