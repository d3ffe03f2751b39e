//! Criterion benchmarks of mimic_solve: per-frame apply (with the previous row-pair kernel, the
//! blocked kernel on a matrix with no zero to skip, and naive baselines in the same process), basis
//! setup for RBF, Laplacian and the thin shell, vertex normals (face scatter and vertex fans),
//! Kabsch and morph fit.
//!
//! Inputs are generated meshes (a curved sheet, like a face patch) of about 3k, 30k and 100k
//! vertices with 38 controls spread over them; everything is built outside the timed closures.
//! Debug builds (`cargo test --benches`) shrink the sizes so the smoke run is quick.

#![allow(
    clippy::unwrap_used,
    reason = "a bench: a failed unwrap is the failure report"
)]

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use glam::Vec3;
use mimic_solve::kabsch::fit_similarity;
use mimic_solve::morph_fit::MorphFit;
use mimic_solve::normals::VertexFans;
use mimic_solve::{Basis, build_basis, vertex_normals};
use mimic_types::{
    Fdp, LaplacianWeights, Mesh, RbfDistance, RbfKernel, RegionBands, Rig, RigControl, SolverKind,
    SolverSettings,
};
use std::hint::black_box;

/// Grid sides giving about 3k, 30k and 100k vertices (55^2, 174^2, 317^2); tiny in debug builds.
fn sides() -> Vec<usize> {
    if cfg!(debug_assertions) {
        vec![12, 20]
    } else {
        vec![55, 174, 317]
    }
}

use mimic_testkit::lcg;

/// A `side x side` sheet bent like a face (cylinder around y), 20 x 24 units, with 38 controls on a
/// 7 x 6 lattice (four corners dropped), regions by thirds of the height.
fn rig(side: usize) -> Rig {
    let mut positions = Vec::with_capacity(side * side);
    for j in 0..side {
        for i in 0..side {
            let u = i as f32 / (side - 1) as f32 - 0.5;
            let v = j as f32 / (side - 1) as f32 - 0.5;
            let angle = u * 1.6;
            positions.push(Vec3::new(
                10.0 * angle.sin(),
                24.0 * v,
                10.0 * angle.cos() + 0.5 * (6.0 * v).sin(),
            ));
        }
    }
    let mut triangles = Vec::with_capacity(2 * (side - 1) * (side - 1));
    for j in 0..side - 1 {
        for i in 0..side - 1 {
            let a = (j * side + i) as u32;
            let (b, c, d) = (a + 1, a + side as u32, a + side as u32 + 1);
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    let regions = RegionBands {
        top_from: 4.0,
        bottom_below: -4.0,
        band: 2.0,
    };
    let fdps: Vec<Fdp> = (2u8..=9)
        .flat_map(|g| (1u8..=14).filter_map(move |i| Fdp::new(g, i).ok()))
        .take(38)
        .collect();
    let mut controls = Vec::new();
    for b in 0..6 {
        for a in 0..7 {
            if (a == 0 || a == 6) && (b == 0 || b == 5) {
                continue;
            }
            let i = 1 + a * (side - 3) / 6;
            let j = 1 + b * (side - 3) / 5;
            let vertex = (j * side + i) as u32;
            let region = regions.region_at(positions[vertex as usize].y);
            controls.push(RigControl {
                fdp: fdps[controls.len()].into(),
                vertex,
                region,
            });
        }
    }
    let n = positions.len();
    Rig {
        name: format!("sheet{n}"),
        units: "cm".into(),
        mesh: Mesh {
            positions,
            triangles,
            ..Default::default()
        },
        controls,
        regions,
        frozen: vec![false; n],
        solver: SolverSettings::default(),
        parts: Default::default(),
    }
}

fn rbf_settings() -> SolverSettings {
    SolverSettings {
        kind: SolverKind::Rbf,
        kernel: RbfKernel::Exponential { radius: 5.0 },
        affine: false,
        regions: true,
        ..SolverSettings::default()
    }
}

fn laplacian_settings() -> SolverSettings {
    SolverSettings {
        kind: SolverKind::Laplacian,
        weights: LaplacianWeights::MeanValue,
        regions: false,
        ..SolverSettings::default()
    }
}

/// Baseline 1: the first thing one writes: per row, a Vec3 accumulator over the controls.
fn apply_naive_aos(b: &Basis, d: &[Vec3], out: &mut [Vec3]) {
    let m = b.control_count();
    for (i, o) in out.iter_mut().enumerate() {
        let row = &b.as_slice()[i * m..(i + 1) * m];
        let mut acc = Vec3::ZERO;
        for j in 0..m {
            acc += d[j] * row[j];
        }
        *o = acc;
    }
}

/// Baseline 2: a plain f64 triple loop (i, axis, j) over a column-major f64 copy of B.
fn apply_f64_triple(b_col_major: &[f64], n: usize, m: usize, d: &[Vec3], out: &mut [Vec3]) {
    for i in 0..n {
        let mut acc = [0f64; 3];
        for (axis, a) in acc.iter_mut().enumerate() {
            for j in 0..m {
                *a += b_col_major[j * n + i] * d[j][axis] as f64;
            }
        }
        out[i] = Vec3::new(acc[0] as f32, acc[1] as f32, acc[2] as f32);
    }
}

fn bench_apply(c: &mut Criterion) {
    let mut g = c.benchmark_group("apply");
    for side in sides() {
        let r = rig(side);
        let n = r.mesh.vertex_count();
        let b = build_basis(&r, &rbf_settings()).unwrap();
        let m = b.control_count();
        let mut seed = 1;
        let d: Vec<Vec3> = (0..m)
            .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)))
            .collect();
        let mut out = vec![Vec3::ZERO; n];
        g.bench_with_input(BenchmarkId::new("basis", n), &n, |bch, _| {
            bch.iter(|| b.apply(black_box(&d), black_box(&mut out)))
        });
        g.bench_with_input(BenchmarkId::new("row_pairs", n), &n, |bch, _| {
            bch.iter(|| b.apply_row_pairs(black_box(&d), black_box(&mut out)))
        });
        // The same matrix with every weight made non-zero: the blocked kernel with nothing to skip.
        let dense = Basis::from_row_major(
            n,
            m,
            b.as_slice()
                .iter()
                .map(|w| if *w == 0.0 { 1e-30 } else { *w })
                .collect(),
        )
        .unwrap();
        g.bench_with_input(BenchmarkId::new("basis_dense", n), &n, |bch, _| {
            bch.iter(|| dense.apply(black_box(&d), black_box(&mut out)))
        });
        g.bench_with_input(BenchmarkId::new("naive_aos", n), &n, |bch, _| {
            bch.iter(|| apply_naive_aos(black_box(&b), black_box(&d), black_box(&mut out)))
        });
        let col_major: Vec<f64> = (0..m * n)
            .map(|k| b.as_slice()[(k % n) * m + k / n] as f64)
            .collect();
        g.bench_with_input(BenchmarkId::new("f64_triple_loop", n), &n, |bch, _| {
            bch.iter(|| {
                apply_f64_triple(
                    black_box(&col_major),
                    n,
                    m,
                    black_box(&d),
                    black_box(&mut out),
                )
            })
        });
        let mut normals = vec![Vec3::ZERO; n];
        g.bench_with_input(BenchmarkId::new("normals", n), &n, |bch, _| {
            bch.iter(|| {
                vertex_normals(
                    black_box(&r.mesh.positions),
                    black_box(&r.mesh.triangles),
                    &mut normals,
                )
            })
        });
        let fans = VertexFans::new(n, n, &r.mesh.triangles);
        let mut packed: Vec<f32> = r.mesh.positions.iter().flat_map(|p| p.to_array()).collect();
        packed.push(0.0);
        g.bench_with_input(BenchmarkId::new("normals_fans", n), &n, |bch, _| {
            bch.iter(|| fans.normals_packed(black_box(&packed), |v, nv| normals[v] = nv))
        });
    }
    g.finish();
}

fn bench_setup(c: &mut Criterion) {
    let mut g = c.benchmark_group("setup");
    g.sample_size(10);
    for side in sides() {
        let r = rig(side);
        let n = r.mesh.vertex_count();
        g.bench_with_input(BenchmarkId::new("rbf_regions", n), &n, |bch, _| {
            bch.iter(|| build_basis(black_box(&r), &rbf_settings()).unwrap())
        });
        let geodesic = SolverSettings {
            distance: RbfDistance::Geodesic,
            ..rbf_settings()
        };
        g.bench_with_input(BenchmarkId::new("rbf_regions_geodesic", n), &n, |bch, _| {
            bch.iter(|| build_basis(black_box(&r), &geodesic).unwrap())
        });
        g.bench_with_input(BenchmarkId::new("laplacian_mean_value", n), &n, |bch, _| {
            bch.iter(|| build_basis(black_box(&r), &laplacian_settings()).unwrap())
        });
        let shell = SolverSettings {
            kind: SolverKind::Shell,
            regions: false,
            ..SolverSettings::default()
        };
        g.bench_with_input(BenchmarkId::new("shell", n), &n, |bch, _| {
            bch.iter(|| build_basis(black_box(&r), &shell).unwrap())
        });
    }
    g.finish();
}

fn bench_small(c: &mut Criterion) {
    let mut seed = 9;
    let src: Vec<Vec3> = (0..38)
        .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)))
        .collect();
    let pose = mimic_types::HeadPose {
        rotation: glam::Quat::from_euler(glam::EulerRot::XYZ, 0.1, 0.2, 0.3),
        translation: Vec3::new(0.1, 0.0, -0.4),
        scale: 1.0,
    };
    let dst: Vec<Vec3> = src.iter().map(|p| pose.apply(*p)).collect();
    c.bench_function("kabsch_38", |b| {
        b.iter(|| fit_similarity(black_box(&src), black_box(&dst), true))
    });
    let targets: Vec<Vec<Vec3>> = (0..50)
        .map(|_| {
            (0..38)
                .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)))
                .collect()
        })
        .collect();
    let fit = MorphFit::new(&targets, 0.01).unwrap();
    let truth: Vec<f32> = (0..50).map(|k| (k % 5) as f32 / 4.0).collect();
    let d: Vec<Vec3> = (0..38)
        .map(|j| targets.iter().zip(&truth).map(|(t, w)| t[j] * *w).sum())
        .collect();
    let mut weights = vec![0f32; 50];
    let mut warm = fit.scratch();
    fit.fit(&d, &mut warm, &mut weights);
    c.bench_function("morph_fit_50x38_warm", |b| {
        b.iter(|| fit.fit(black_box(&d), &mut warm, &mut weights))
    });
    c.bench_function("morph_fit_50x38_cold", |b| {
        b.iter(|| {
            let mut scratch = fit.scratch();
            fit.fit(black_box(&d), &mut scratch, &mut weights)
        })
    });
}

criterion_group!(benches, bench_apply, bench_setup, bench_small);
criterion_main!(benches);
