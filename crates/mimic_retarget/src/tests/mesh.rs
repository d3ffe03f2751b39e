//! The mesh the step writes: with positions off, by each vector kernel, with binary16 weights.

use super::*;

#[test]
fn positions_off_gives_the_same_displacements_and_keeps_the_rest_mesh() {
    let (mut on, neutral) = setup(plain());
    let (mut off, _) = setup(RetargetSettings {
        positions: false,
        ..plain()
    });
    let (mut out_on, mut out_off) = (on.new_output(), off.new_output());
    let rest = out_off.positions.clone();
    for k in 0..10i64 {
        let rot = Quat::from_rotation_y(0.02 * k as f32);
        let mut moved: Vec<Vec3> = neutral.iter().map(|p| rot * *p).collect();
        // The chin (last point) drops by k mm.
        if let Some(p) = moved.last_mut() {
            *p += rot * Vec3::new(0.0, -0.001 * k as f32, 0.0);
        }
        let a = on.step(&frame(k * 33_000, moved.clone()), &mut out_on);
        let b = off.step(&frame(k * 33_000, moved), &mut out_off);
        assert_eq!(a, b);
        // Same arithmetic on the same inputs: bit-identical displacements and pose.
        assert_eq!(out_on.displacements, out_off.displacements);
        assert_eq!(out_on.pose, out_off.pose);
        assert_eq!(out_off.positions, rest);
    }
    assert!(out_on.displacements.iter().any(|d| d.length() > 0.01));
    assert_eq!(off.moving_vertex_count(), 0);
}

#[test]
fn each_vector_kernel_gives_the_same_positions_and_normals_within_the_kernels_bound() {
    use mimic_solve::VectorKernel;
    // One retargeter per vector kernel (one the CPU lacks runs the best it has), same frames:
    // the deform kernels sum the same fused chains, so positions are identical, and the fan
    // kernels the same terms, so the normals differ only by their normalisations, at most 9 eps
    // per component (mimic_solve's fan tests).
    let kernels = [
        VectorKernel::Portable,
        VectorKernel::Avx2,
        VectorKernel::Avx512,
    ];
    let mut runs = kernels.map(|k| {
        let (r, neutral) = setup(RetargetSettings {
            deform_kernel: Some(k),
            normals_kernel: Some(k),
            ..plain()
        });
        let out = r.new_output();
        (r, out, neutral)
    });
    for k in 0..10i64 {
        let mut outs = Vec::new();
        for (r, out, neutral) in runs.iter_mut() {
            let rot = Quat::from_rotation_y(0.02 * k as f32);
            let mut moved: Vec<Vec3> = neutral.iter().map(|p| rot * *p).collect();
            if let Some(p) = moved.last_mut() {
                *p += rot * Vec3::new(0.0, -0.001 * k as f32, 0.0);
            }
            r.step(&frame(k * 33_000, moved), out);
            outs.push(out.clone());
        }
        for o in &outs[1..] {
            assert_eq!(o.positions, outs[0].positions);
            for (a, b) in o.normals.iter().zip(&outs[0].normals) {
                assert!(
                    (*a - *b).abs().max_element() <= 9.0 * f32::EPSILON,
                    "frame {k}: {a} vs {b}"
                );
            }
        }
    }
    assert!(runs[0].1.normals.iter().any(|n| n.z.abs() < 0.999));
}

#[test]
fn f16_weights_move_positions_within_their_bound() {
    // The same frames through f32 and binary16 weights: each coordinate of each moving vertex
    // within sum_j (2^-11 |B_ij| + 2^-25) |d_j| (the weights' rounding) plus both sums' f32
    // rounding, (m + 2) eps (sum_j |B_ij| |d_j| + |rest_i|) each.
    let (mut a, neutral) = setup(plain());
    let (mut b, _) = setup(RetargetSettings {
        f16_weights: true,
        ..plain()
    });
    let (mut oa, mut ob) = (a.new_output(), b.new_output());
    let basis = a.basis().clone();
    let m = basis.control_count();
    let eps = f32::EPSILON;
    let mut moved = false;
    for k in 0..6i64 {
        let mut pts = neutral.clone();
        for (i, p) in pts.iter_mut().enumerate() {
            *p += Vec3::new(
                0.0,
                -0.0013 * (k * (i as i64 % 3)) as f32,
                0.0007 * k as f32,
            );
        }
        a.step(&frame(k * 33_000, pts.clone()), &mut oa);
        b.step(&frame(k * 33_000, pts), &mut ob);
        assert_eq!(oa.displacements, ob.displacements, "frame {k}: same d");
        let d = &oa.displacements;
        for (i, (p, q)) in oa.positions.iter().zip(&ob.positions).enumerate() {
            let row = basis.row(i);
            let terms: f32 = (0..m)
                .map(|j| row[j].abs() * d[j].abs().max_element())
                .sum();
            let weights: f32 = (0..m)
                .map(|j| (row[j].abs() / 2048.0 + 2f32.powi(-25)) * d[j].abs().max_element())
                .sum();
            // |rest_i| <= |p_i| + sum_j |B_ij| |d_j|.
            let rest = p.abs().max_element() + terms;
            let tol = weights + 2.0 * (m + 2) as f32 * eps * (terms + rest);
            assert!(
                (*p - *q).abs().max_element() <= tol,
                "frame {k} vertex {i}: {p} vs {q} (tol {tol:e})"
            );
            moved |= p != q;
        }
    }
    assert!(moved, "binary16 weights changed no position");
}
