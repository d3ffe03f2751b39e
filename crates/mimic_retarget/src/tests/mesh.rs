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
    let kernels = [VectorKernel::Portable, VectorKernel::Avx2];
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
