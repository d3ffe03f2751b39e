//! GPU tests of the many-sessions morph (`mimic_bench::BatchMorph`, `mimic bench --gpu`)
//! on the 3k-vertex benchmark face (lavapipe on CI): every session's positions against the CPU's
//! `rest + Basis::apply` (what `MovingDeform` gives bit for bit), its normals against
//! `vertex_normals` of the same positions.
//!
//! With no adapter these fail with the renderer's message, unless MIMIC_SKIP_GPU_TESTS is set.

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use glam::{DVec3, Vec3};
use mimic_bench::{BatchError, BatchMorph};
use mimic_solve::{Basis, deform::MovingDeform, vertex_normals};
use mimic_testkit::Lcg;
use std::path::PathBuf;

fn skip() -> bool {
    let skip = std::env::var_os("MIMIC_SKIP_GPU_TESTS").is_some();
    if skip {
        eprintln!("MIMIC_SKIP_GPU_TESTS is set: skipping a GPU test");
    }
    skip
}

fn batch(basis: &Basis, mesh: &mimic_types::Mesh, sessions: usize) -> BatchMorph {
    match BatchMorph::new(basis, &mesh.positions, &mesh.triangles, sessions) {
        Ok(b) => b,
        Err(e) => panic!("{e} (set MIMIC_SKIP_GPU_TESTS=1 to skip GPU tests)"),
    }
}

fn mesh_3k() -> mimic_types::Mesh {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../configs/meshes/ict-facekit-3k/face_3k.obj");
    mimic_assets::load_obj(&path).unwrap()
}

/// A basis like a face rig's: three regions with their own supports (by height), a frozen part
/// (the lower back, all-zero rows), weights in [0, 1).
fn region_basis(mesh: &mimic_types::Mesh, m: usize, rng: &mut Lcg) -> Basis {
    let (lo, hi) = mesh.bounds().unwrap();
    let mut data = Vec::with_capacity(mesh.positions.len() * m);
    for p in &mesh.positions {
        let h = (p.y - lo.y) / (hi.y - lo.y);
        let frozen = p.z < lo.z + 0.15 * (hi.z - lo.z);
        let region = (h * 3.0).min(2.0) as usize;
        for j in 0..m {
            let inside = match region {
                0 => j < m / 2,
                1 => j >= m / 4 && j < 3 * m / 4,
                _ => j >= m / 2 || j == 0,
            };
            let w = 0.5 + 0.5 * rng.next_f32();
            data.push(if inside && !frozen { w } else { 0.0 });
        }
    }
    Basis::from_row_major(mesh.positions.len(), m, data).unwrap()
}

#[test]
fn every_session_equals_the_cpu_deform_and_normals() {
    if skip() {
        return;
    }
    let mesh = mesh_3k();
    let (n, m, sessions) = (mesh.positions.len(), 38usize, 5usize);
    let mut rng = Lcg(21);
    let basis = region_basis(&mesh, m, &mut rng);
    // Displacements of up to 0.5 cm per axis, different in every session.
    let d: Vec<Vec3> = (0..sessions * m)
        .map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.5)
        .collect();
    let mut gpu = batch(&basis, &mesh, sessions);
    assert!(gpu.moving_count() > n / 2 && gpu.moving_count() < n);
    gpu.run(&d).unwrap();

    let deform = MovingDeform::new(&basis, &mesh.positions);
    let mut compact = vec![0f32; 3 * deform.rows().len()];
    let eps = f32::EPSILON;
    for s in 0..sessions {
        let ds = &d[s * m..(s + 1) * m];
        // The CPU: the retargeter's deform (bit for bit rest + Basis::apply, crates/mimic_solve).
        let mut want = mesh.positions.clone();
        deform.deform_packed(ds, &mut compact, &mut want);
        let got = gpu.read_positions(s).unwrap();
        assert_eq!(got.len(), n);
        for i in 0..n {
            // Each side is an m-term f32 sum plus one addition, in its own order (fused or not):
            // each within (m + 1) eps (sum_j |B_ij| |d_j| + |P0_i|) of the exact value, per axis.
            let bound: f32 = (0..m)
                .map(|j| basis.row(i)[j].abs() * ds[j].abs().max_element())
                .sum::<f32>()
                + mesh.positions[i].abs().max_element();
            let tol = 2.0 * (m + 1) as f32 * eps * bound;
            let err = (got[i] - want[i]).abs().max_element();
            assert!(
                err <= tol,
                "session {s} vertex {i}: gpu {} cpu {} (err {err:e} > tol {tol:e})",
                got[i],
                want[i]
            );
            if basis.row(i).iter().all(|w| *w == 0.0) {
                assert_eq!(
                    got[i], mesh.positions[i],
                    "frozen vertex {i} keeps its rest"
                );
            }
        }

        // Normals of the GPU's own positions, on the CPU face by face: the same k cross products
        // at each triangle's first corner in the same order, each side within (6 + k) eps
        // sum_t L_t^2 of the exact sum (L_t the longest edge), so after normalising they differ by
        // at most 4 (6 + k) eps sum_t L_t^2 / |N| + 16 eps (|N| the exact sum's length, in f64).
        let mut want_n = vec![Vec3::ZERO; n];
        vertex_normals(&got, &mesh.triangles, &mut want_n);
        let got_n = gpu.read_normals(s).unwrap();
        let mut sum = vec![DVec3::ZERO; n];
        let mut scale = vec![0f64; n];
        let mut k = vec![0usize; n];
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|v| got[v as usize].as_dvec3());
            let l2 = (b - a)
                .length_squared()
                .max((c - a).length_squared())
                .max((c - b).length_squared());
            for &v in t {
                sum[v as usize] += (b - a).cross(c - a);
                scale[v as usize] += l2;
                k[v as usize] += 1;
            }
        }
        let mut compared = 0;
        for v in 0..n {
            let len = sum[v].length();
            let tol = 4.0 * (6 + k[v]) as f64 * eps as f64 * scale[v] / len + 16.0 * eps as f64;
            if len > 0.0 && tol < 0.1 {
                let err = (got_n[v].as_dvec3() - want_n[v].as_dvec3()).length();
                assert!(
                    err <= tol,
                    "session {s} normal {v}: gpu {} cpu {} ({err:e} > {tol:e})",
                    got_n[v],
                    want_n[v]
                );
                compared += 1;
            }
        }
        assert!(compared > n * 9 / 10, "{compared} of {n} normals compared");
    }
}

#[test]
fn timing_reports_every_dispatch_and_wrong_weights_are_refused() {
    if skip() {
        return;
    }
    let mesh = mesh_3k();
    let (m, sessions) = (38usize, 3usize);
    let mut rng = Lcg(5);
    let basis = region_basis(&mesh, m, &mut rng);
    let mut gpu = batch(&basis, &mesh, sessions);
    let d = vec![Vec3::new(0.1, -0.2, 0.3); sessions * m];
    let t = gpu.time(&d, 4).unwrap();
    assert_eq!((t.sessions, t.iterations), (sessions, 4));
    assert!(t.wall_us > 0.0 && t.wall_us.is_finite());
    assert_eq!(t.gpu.is_some(), gpu.has_timestamps());
    if let Some(g) = t.gpu {
        assert!(g.morph_us >= 0.0 && g.normals_us >= 0.0 && g.total_us >= g.morph_us);
    }
    // sessions x 16 667 us / per-dispatch time, the time being the GPU's where it has timestamps.
    let per = t.per_dispatch_us();
    assert!((t.sessions_at_60fps() - sessions as f64 * 1e6 / 60.0 / per).abs() < 1e-9 * per);
    let err = gpu.run(&d[..m]).unwrap_err();
    assert!(
        matches!(err, BatchError::Render(_)) && err.to_string().contains("sessions x controls"),
        "{err}"
    );
    assert!(matches!(
        BatchMorph::new(&basis, &mesh.positions, &mesh.triangles, 0),
        Err(BatchError::BadSessions { .. })
    ));
}
