//! GPU tests of the renderer on the real ICT head (lavapipe on CI).
//!
//! With no adapter these fail with the renderer's message, unless MIMIC_SKIP_GPU_TESTS is set.

use glam::Vec3;
use mimic_render::{Camera, Deform, Image, Renderer, Shading, View};
use mimic_solve::{Basis, vertex_normals};
use std::path::PathBuf;

fn renderer(w: u32, h: u32) -> Option<Renderer> {
    if std::env::var_os("MIMIC_SKIP_GPU_TESTS").is_some() {
        eprintln!("MIMIC_SKIP_GPU_TESTS is set: skipping a GPU test");
        return None;
    }
    match Renderer::new(w, h) {
        Ok(r) => Some(r),
        Err(e) => panic!("{e} (set MIMIC_SKIP_GPU_TESTS=1 to skip GPU tests)"),
    }
}

fn ict() -> mimic_types::Rig {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs/rigs/ict-face.toml");
    mimic_assets::load_rig(&root).unwrap()
}

/// Deterministic pseudo-random numbers in [-1, 1) (a 64-bit LCG), independent of the code under test.
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }
}

#[test]
fn gpu_morph_and_normals_equal_the_cpu() {
    let Some(r) = renderer(64, 64) else { return };
    let rig = ict();
    let n = rig.mesh.vertex_count();
    let m = 38;
    let mut rng = Lcg(7);
    // A dense random basis (weights in [-1, 1)) and displacements of up to 2 cm per axis.
    let basis = Basis::from_row_major(n, m, (0..n * m).map(|_| rng.next()).collect()).unwrap();
    let d: Vec<Vec3> = (0..m)
        .map(|_| Vec3::new(rng.next(), rng.next(), rng.next()) * 2.0)
        .collect();
    let gpu = r
        .upload_rig(&rig.mesh.positions, &rig.mesh.triangles, Some(&basis))
        .unwrap();
    r.deform(&gpu, Deform::Controls(&d)).unwrap();
    let got = r.read_positions(&gpu).unwrap();

    let mut u = vec![Vec3::ZERO; n];
    basis.apply(&d, &mut u);
    let want: Vec<Vec3> = rig
        .mesh
        .positions
        .iter()
        .zip(&u)
        .map(|(p, u)| *p + *u)
        .collect();
    // Both sides sum m = 38 products |B d| <= 2 in f32 in possibly different orders / with FMA:
    // the error is bounded by about m * eps * (|P0| + sum_j |B_ij| |d_j|) <= 38 * 1.2e-7 * (|P0| + 38 * 2 * sqrt 3).
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        let scale = rig.mesh.positions[i].length() + 38.0 * 2.0 * 3f32.sqrt();
        let tol = 38.0 * f32::EPSILON * scale * 2.0;
        assert!(
            (*g - *w).length() <= tol,
            "vertex {i}: gpu {g} cpu {w} (tol {tol})"
        );
    }

    // Normals: the CPU's area-weighted normals of the same morphed positions.
    let mut want_n = vec![Vec3::ZERO; n];
    vertex_normals(&want, &rig.mesh.triangles, &mut want_n);
    let got_n = r.read_normals(&gpu).unwrap();
    let mut worst = 0f32;
    for (g, w) in got_n.iter().zip(&want_n) {
        worst = worst.max((*g - *w).length());
    }
    // Unit vectors from sums of cross products whose f32 rounding (FMA or not) differs: 1e-3 allows
    // cancellation where a vertex's triangles nearly oppose each other on the random shape.
    assert!(worst < 1e-3, "worst normal difference {worst}");
}

#[test]
fn scratch_render() {
    let Some(r) = renderer(512, 512) else { return };
    let rig = ict();
    let gpu = r
        .upload_rig(&rig.mesh.positions, &rig.mesh.triangles, None)
        .unwrap();
    let (lo, hi) = rig.mesh.bounds().unwrap();
    let view = View::lit(Camera::front(lo, hi));
    let img = r.render(&gpu, Deform::Rest, &view).unwrap();
    img.save_png(std::path::Path::new("/tmp/ict_rest.png"))
        .unwrap();
    let _ = (Image::filled(1, 1, [0; 4]), Shading::Lit);
    eprintln!("{}", r.adapter());
}
