//! Morph targets as a deformation basis, so anything that evaluates `P0 + B d` (the CPU
//! [`Basis::apply`], the GPU morph of `mimic_render`) also evaluates blendshapes.
//!
//! Target `k` becomes three columns `3k + a` (a = x, y, z) with `B[i, 3k + a] = dP_k[i].a`, and a
//! weight `w_k` becomes the three control displacements `d[3k + a] = w_k e_a`, so
//! `sum_j B[i, j] d_j = sum_k sum_a dP_k[i].a w_k e_a = sum_k w_k dP_k[i]`.

use crate::Basis;
use glam::Vec3;
use mimic_types::MorphTarget;

/// The n x 3k basis of `targets`; `None` if a target does not have `vertex_count` position deltas.
pub fn morph_basis(targets: &[MorphTarget], vertex_count: usize) -> Option<Basis> {
    if targets
        .iter()
        .any(|t| t.position_deltas.len() != vertex_count)
    {
        return None;
    }
    let m = 3 * targets.len();
    let mut data = vec![0f32; vertex_count * m];
    for (k, t) in targets.iter().enumerate() {
        for (i, d) in t.position_deltas.iter().enumerate() {
            data[i * m + 3 * k..i * m + 3 * k + 3].copy_from_slice(&d.to_array());
        }
    }
    Basis::from_row_major(vertex_count, m, data)
}

/// The control displacements that make [`morph_basis`]'s basis evaluate `weights`; allocates nothing.
///
/// # Panics
/// If `out.len() != 3 * weights.len()`.
pub fn morph_controls(weights: &[f32], out: &mut [Vec3]) {
    assert_eq!(out.len(), 3 * weights.len(), "three controls per target");
    for (w, d) in weights.iter().zip(out.chunks_exact_mut(3)) {
        d[0] = Vec3::X * *w;
        d[1] = Vec3::Y * *w;
        d[2] = Vec3::Z * *w;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_of_targets_evaluates_the_weighted_sum() {
        let t = |name: &str, f: fn(f32) -> Vec3| MorphTarget {
            name: name.into(),
            position_deltas: (0..4).map(|i| f(i as f32)).collect(),
            normal_deltas: vec![Vec3::ZERO; 4],
        };
        let targets = [
            t("a", |i| Vec3::new(i, 0.0, 1.0)),
            t("b", |i| Vec3::new(0.0, -2.0 * i, 0.5)),
        ];
        let basis = morph_basis(&targets, 4).unwrap();
        assert_eq!(basis.control_count(), 6);
        let mut d = [Vec3::NAN; 6];
        morph_controls(&[0.5, 0.25], &mut d);
        let mut u = [Vec3::ZERO; 4];
        basis.apply(&d, &mut u);
        for (i, u) in u.iter().enumerate() {
            let i = i as f32;
            // 0.5 (i, 0, 1) + 0.25 (0, -2i, 0.5), exact in binary fractions.
            assert_eq!(*u, Vec3::new(0.5 * i, -0.5 * i, 0.625));
        }
        assert!(morph_basis(&targets, 5).is_none());
    }
}
