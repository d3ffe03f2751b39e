//! GPU morph of the ICT rig's morph targets (blendshapes) against the CPU blend (lavapipe on CI).
//!
//! The targets go up as a basis with three columns per target (`mimic_solve::morph_basis`), the
//! weights as control displacements; the GPU's `P0 + B d` must equal `P0 + sum_k w_k dP_k`.
//! With no adapter this fails with the renderer's message, unless MIMIC_SKIP_GPU_TESTS is set.

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
