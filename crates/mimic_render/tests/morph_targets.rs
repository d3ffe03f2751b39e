//! GPU morph of the ICT rig's morph targets (blendshapes) against the CPU blend (lavapipe on CI).
//!
//! The targets go up as a basis with three columns per target (`mimic_solve::morph_basis`), the
//! weights as control displacements; the GPU's `P0 + B d` must equal `P0 + sum_k w_k dP_k`.
//! With no adapter this fails with the renderer's message, unless MIMIC_SKIP_GPU_TESTS is set.

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use glam::Vec3;
use mimic_render::{Deform, Renderer};
use mimic_solve::morph_basis::{morph_basis, morph_controls};
use mimic_solve::vertex_normals;
use std::path::PathBuf;

#[test]
fn gpu_blendshapes_equal_the_cpu_blend() {
    if std::env::var_os("MIMIC_SKIP_GPU_TESTS").is_some() {
        eprintln!("MIMIC_SKIP_GPU_TESTS is set: skipping a GPU test");
        return;
    }
    let r = Renderer::new(64, 64)
        .unwrap_or_else(|e| panic!("{e} (set MIMIC_SKIP_GPU_TESTS=1 to skip GPU tests)"));
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs/rigs/ict-face.toml");
    let rig = mimic_assets::load_rig(&path).unwrap();
    let targets = mimic_assets::load_morph_targets(&path, &rig).unwrap();
    let (n, k) = (rig.mesh.vertex_count(), targets.len());
    assert_eq!(k, 8);
    let basis = morph_basis(&targets, n).unwrap();
    let gpu = r
        .upload_rig(&rig.mesh.positions, &rig.mesh.triangles, Some(&basis))
        .unwrap();
    let mut d = vec![Vec3::ZERO; 3 * k];
    for weights in [
        [0.6, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.1, 0.5, 0.5, 0.2, 0.4, 0.4, 1.0, 0.7],
    ] {
        morph_controls(&weights, &mut d);
        r.deform(&gpu, Deform::Controls(&d)).unwrap();
        let got = r.read_positions(&gpu).unwrap();
        // CPU truth, summed here target by target in f32.
        let mut want = rig.mesh.positions.clone();
        for (t, w) in targets.iter().zip(weights) {
            for (p, dp) in want.iter_mut().zip(&t.position_deltas) {
                *p += w * *dp;
            }
        }
        // 3k = 24 products per axis, each |w dP| <= |dP|: f32 sums in any order differ by at most
        // about 24 eps (|P0| + sum_k |dP_k|) per vertex; doubled for FMA / order slack.
        let mut worst = 0f32;
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            let scale = rig.mesh.positions[i].length()
                + targets
                    .iter()
                    .map(|t| t.position_deltas[i].length())
                    .sum::<f32>();
            let tol = 2.0 * 24.0 * f32::EPSILON * scale;
            let e = (*g - *w).length();
            worst = worst.max(e);
            assert!(e <= tol, "vertex {i}: gpu {g} cpu {w} (tol {tol})");
        }
        eprintln!("weights {weights:?}: worst |gpu - cpu| {worst:e} cm");
        // The GPU recomputes area-weighted normals of the blended surface, as the CPU does.
        let mut want_n = vec![Vec3::ZERO; n];
        vertex_normals(&want, &rig.mesh.triangles, &mut want_n);
        let got_n = r.read_normals(&gpu).unwrap();
        let worst_n = got_n
            .iter()
            .zip(&want_n)
            .map(|(g, w)| (*g - *w).length())
            .fold(0f32, f32::max);
        // Unit vectors from sums of cross products rounded differently: 1e-3 as in gpu.rs.
        assert!(worst_n < 1e-3, "worst normal difference {worst_n}");
    }
}

/// 64 synthetic targets (192 basis columns, beyond the old 64-control uniform) on a 40 x 40 grid:
/// the GPU's `P0 + B d` equals the CPU blend `P0 + sum_k w_k dP_k` summed in f64.
#[test]
fn gpu_blends_64_synthetic_targets_like_the_cpu() {
    if std::env::var_os("MIMIC_SKIP_GPU_TESTS").is_some() {
        eprintln!("MIMIC_SKIP_GPU_TESTS is set: skipping a GPU test");
        return;
    }
    let r = Renderer::new(64, 64)
        .unwrap_or_else(|e| panic!("{e} (set MIMIC_SKIP_GPU_TESTS=1 to skip GPU tests)"));
    let side = 40u32;
    let positions: Vec<Vec3> = (0..side * side)
        .map(|i| Vec3::new((i % side) as f32 * 0.1, (i / side) as f32 * 0.1, 0.0))
        .collect();
    let mut triangles = Vec::new();
    for y in 0..side - 1 {
        for x in 0..side - 1 {
            let a = y * side + x;
            triangles.push([a, a + 1, a + side + 1]);
            triangles.push([a, a + side + 1, a + side]);
        }
    }
    let n = positions.len();
    let k = 64;
    // Target t bends the sheet with its own frequency along each axis (all deltas within 1).
    let targets: Vec<mimic_types::MorphTarget> = (0..k)
        .map(|t| {
            let f = 0.3 + 0.05 * t as f32;
            let position_deltas = positions
                .iter()
                .map(|p| {
                    Vec3::new(
                        0.2 * (f * p.y).sin(),
                        0.2 * (f * p.x).cos(),
                        (f * (p.x + p.y)).sin(),
                    )
                })
                .collect();
            mimic_types::MorphTarget {
                name: format!("t{t}"),
                position_deltas,
                normal_deltas: vec![Vec3::ZERO; n],
            }
        })
        .collect();
    let basis = morph_basis(&targets, n).unwrap();
    assert_eq!(basis.control_count(), 3 * k);
    let gpu = r.upload_rig(&positions, &triangles, Some(&basis)).unwrap();
    let weights: Vec<f32> = (0..k).map(|t| ((t * 37) % 64) as f32 / 63.0).collect();
    let mut d = vec![Vec3::ZERO; 3 * k];
    morph_controls(&weights, &mut d);
    r.deform(&gpu, Deform::Controls(&d)).unwrap();
    let got = r.read_positions(&gpu).unwrap();
    let mut worst = 0f64;
    for (i, g) in got.iter().enumerate() {
        let mut want = positions[i].to_array().map(f64::from);
        let mut scale = f64::from(positions[i].abs().max_element());
        for (t, &w) in targets.iter().zip(&weights) {
            let dp = t.position_deltas[i];
            scale += f64::from(w * dp.abs().max_element());
            for (a, c) in want.iter_mut().zip(dp.to_array()) {
                *a += f64::from(w) * f64::from(c);
            }
        }
        // 3k = 192 f32 products and sums per axis (the zero columns add exactly 0): error at most
        // (3k + 1) eps (|P0| + sum_k w_k |dP_k|).
        let tol = (3 * k + 1) as f64 * f64::from(f32::EPSILON) * scale;
        for (a, (gv, wv)) in g.to_array().iter().zip(want).enumerate() {
            let e = (f64::from(*gv) - wv).abs();
            worst = worst.max(e);
            assert!(
                e <= tol,
                "vertex {i} axis {a}: gpu {gv} cpu {wv} (tol {tol})"
            );
        }
    }
    eprintln!("64 targets: worst |gpu - cpu| {worst:e}");
    // The rest pose really differs from this blend (the comparison is not vacuous).
    let moved = got
        .iter()
        .zip(&positions)
        .map(|(g, p)| (*g - *p).length())
        .fold(0f32, f32::max);
    assert!(moved > 1.0, "the blend moves the sheet by {moved}");
}
