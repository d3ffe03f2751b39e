//! GPU tests of the renderer on the real ICT head (lavapipe on CI).
//!
//! With no adapter these fail with the renderer's message, unless MIMIC_SKIP_GPU_TESTS is set.

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use glam::Vec3;
use mimic_render::{Camera, Deform, Image, Shading, View};
use mimic_solve::{Basis, vertex_normals};
use mimic_testkit::Lcg;
use std::path::PathBuf;

mod common;
use common::renderer;

fn ict() -> mimic_types::Rig {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs/rigs/ict-face.toml");
    mimic_assets::load_rig(&root).unwrap()
}

#[test]
fn gpu_morph_and_normals_equal_the_cpu() {
    let Some(r) = renderer(64, 64) else { return };
    let rig = ict();
    let n = rig.mesh.vertex_count();
    let m = 38;
    let mut rng = Lcg(7);
    // A dense random basis (weights in [-1, 1)) and displacements of up to 2 cm per axis.
    let basis = Basis::from_row_major(n, m, (0..n * m).map(|_| rng.next_f32()).collect()).unwrap();
    let d: Vec<Vec3> = (0..m)
        .map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0)
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

/// The triangles `mimic render` draws on the ICT head: all but the lacrimal, eye blend and eye
/// occlusion shells (vertices 24591-25350, configs/meshes/ict-facekit/SOURCE.md).
fn shown(rig: &mimic_types::Rig) -> Vec<[u32; 3]> {
    rig.mesh
        .triangles
        .iter()
        .filter(|t| !t.iter().any(|v| (24591..=25350).contains(v)))
        .copied()
        .collect()
}

#[test]
fn rest_shape_matches_the_neutral_golden_image() {
    let Some(r) = renderer(256, 256) else { return };
    let rig = ict();
    let gpu = r
        .upload_rig(&rig.mesh.positions, &shown(&rig), None)
        .unwrap();
    let (lo, hi) = rig.mesh.bounds().unwrap();
    let img = r
        .render(&gpu, Deform::Rest, &View::lit(Camera::front(lo, hi)))
        .unwrap();
    // The golden image was made by `mimic render --no-materials --hide 24591-25350` from frame 0
    // of a recording (still calibrating, so d = 0): the library's rest render must agree within the integration test's bound (0.25,
    // tests/integration/render.rs says why; the same adapter gives 0).
    let golden_path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/golden_images/ict_neutral_skin_256.png");
    let golden = Image::load_png(&golden_path).unwrap();
    let err = img.mean_abs_error(&golden).unwrap();
    assert!(err <= 0.25, "mean absolute error {err}");
}

#[test]
fn full_positions_path_draws_what_the_morph_draws() {
    let Some(r) = renderer(128, 128) else { return };
    let rig = ict();
    let n = rig.mesh.vertex_count();
    let m = 4;
    let mut rng = Lcg(11);
    // A smooth random basis: each column a bump in y, so the face really moves (up to ~1 cm).
    let centres: Vec<f32> = (0..m).map(|_| rng.next_f32() * 8.0).collect();
    let data: Vec<f32> = (0..n * m)
        .map(|k| {
            let y = rig.mesh.positions[k / m].y;
            (-((y - centres[k % m]) / 3.0).powi(2)).exp()
        })
        .collect();
    let basis = Basis::from_row_major(n, m, data).unwrap();
    let d: Vec<Vec3> = (0..m)
        .map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.5)
        .collect();
    let tris = shown(&rig);
    let gpu = r
        .upload_rig(&rig.mesh.positions, &tris, Some(&basis))
        .unwrap();
    let (lo, hi) = rig.mesh.bounds().unwrap();
    let view = View::lit(Camera::front(lo, hi));
    let morphed = r.render(&gpu, Deform::Controls(&d), &view).unwrap();
    let rest = r.render(&gpu, Deform::Rest, &view).unwrap();

    let mut u = vec![Vec3::ZERO; n];
    basis.apply(&d, &mut u);
    let p: Vec<Vec3> = rig
        .mesh
        .positions
        .iter()
        .zip(&u)
        .map(|(a, b)| *a + *b)
        .collect();
    let from_positions = r
        .render(
            &gpu,
            Deform::Positions {
                positions: &p,
                normals: None,
            },
            &view,
        )
        .unwrap();
    // Same surface up to f32 rounding of P: a handful of bytes may round the other way (mean
    // well under 0.05 per byte), while the deformation itself changes the image visibly.
    let same = morphed.mean_abs_error(&from_positions).unwrap();
    let moved = morphed.mean_abs_error(&rest).unwrap();
    assert!(same < 0.05, "positions path differs by {same}");
    assert!(moved > 0.5, "the morph barely changed the image: {moved}");

    // CPU normals given explicitly: the same picture again.
    let mut nrm = vec![Vec3::ZERO; n];
    vertex_normals(&p, &tris, &mut nrm);
    let with_normals = r
        .render(
            &gpu,
            Deform::Positions {
                positions: &p,
                normals: Some(&nrm),
            },
            &view,
        )
        .unwrap();
    let same_n = morphed.mean_abs_error(&with_normals).unwrap();
    assert!(
        same_n < 0.05,
        "CPU normals give a different image: {same_n}"
    );
}

#[test]
fn heat_maps_colour_by_displacement_and_weight() {
    let Some(r) = renderer(64, 64) else { return };
    let rig = ict();
    let n = rig.mesh.vertex_count();
    // Column 0 weighs every vertex 1 (hot), column 1 weighs none (cold).
    let data: Vec<f32> = (0..n).flat_map(|_| [1.0, 0.0]).collect();
    let basis = Basis::from_row_major(n, 2, data).unwrap();
    let gpu = r
        .upload_rig(&rig.mesh.positions, &shown(&rig), Some(&basis))
        .unwrap();
    let (lo, hi) = rig.mesh.bounds().unwrap();
    let mut view = View::lit(Camera::front(lo, hi));
    view.background = [0.0, 0.0, 0.0, 1.0];
    // Dominant channel of the head's pixels (background is black: skipped).
    let dominant = |img: &Image| {
        let mut votes = [0usize; 3];
        for p in img
            .rgba
            .chunks(4)
            .filter(|p| p[0] as u32 + p[1] as u32 + p[2] as u32 > 30)
        {
            let k = (0..3).max_by_key(|&k| p[k]).unwrap();
            votes[k] += 1;
        }
        (0..3).max_by_key(|&k| votes[k]).unwrap()
    };
    view.shading = Shading::ControlWeight { control: 0 };
    assert_eq!(
        dominant(&r.render(&gpu, Deform::Rest, &view).unwrap()),
        0,
        "weight 1: red"
    );
    view.shading = Shading::ControlWeight { control: 1 };
    assert_eq!(
        dominant(&r.render(&gpu, Deform::Rest, &view).unwrap()),
        2,
        "weight 0: blue"
    );
    // Every vertex moved by 1 cm along x with full scale 1 cm: hot; at rest: cold.
    view.shading = Shading::Displacement { full_scale: 1.0 };
    let d = [Vec3::X, Vec3::ZERO];
    assert_eq!(
        dominant(&r.render(&gpu, Deform::Controls(&d), &view).unwrap()),
        0
    );
    assert_eq!(dominant(&r.render(&gpu, Deform::Rest, &view).unwrap()), 2);
    // A control outside the rig is an error, not a read past the buffer.
    view.shading = Shading::ControlWeight { control: 2 };
    assert!(r.render(&gpu, Deform::Rest, &view).is_err());
}
