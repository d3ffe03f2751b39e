//! Morph targets from the deformation basis (one per control and axis) or from a rig's own
//! morph targets.

use glam::Vec3;
use mimic_solve::Basis;
use mimic_types::MorphTarget;

/// One glTF morph target over the rig's vertices: the non-zero deltas only.
#[derive(Clone, Debug, PartialEq)]
pub struct Morph {
    /// Target name (`mesh.extras.targetNames`).
    pub name: String,
    /// `(vertex, position delta)` per moved vertex, ascending vertex, glTF units (metres per unit
    /// of weight).
    pub positions: Vec<(u32, Vec3)>,
    /// `(vertex, normal delta)` per vertex whose normal changes, ascending; empty without normals.
    pub normals: Vec<(u32, Vec3)>,
}

const AXES: [(&str, Vec3); 3] = [("x", Vec3::X), ("y", Vec3::Y), ("z", Vec3::Z)];

/// [`basis_morphs`] named by the rig's controls (its FDPs or layout points), then its rigid
/// parts' columns ([`mimic_types::RigParts::column_names`]).
pub fn control_morphs(basis: &Basis, rig: &mimic_types::Rig) -> Vec<Morph> {
    let names: Vec<String> = rig
        .controls
        .iter()
        .map(|c| c.fdp.to_string())
        .chain(rig.parts.column_names())
        .collect();
    basis_morphs(basis, &names)
}

/// The columns of `B` as morph targets: target `3 j + a` (named `"{control}.{x|y|z}"`) moves
/// vertex `i` by `B[i, j]` along axis `a`, so with weight `d_j[a]` (metres, [`basis_weights`])
/// the targets add up to `u = B d` exactly. Positions only: the basis has no normal columns.
pub fn basis_morphs(basis: &Basis, control_names: &[String]) -> Vec<Morph> {
    let m = basis.control_count();
    let mut out: Vec<Morph> = (0..m)
        .flat_map(|j| {
            let name = control_names
                .get(j)
                .cloned()
                .unwrap_or_else(|| format!("control{j}"));
            AXES.iter().map(move |(axis, _)| Morph {
                name: format!("{name}.{axis}"),
                positions: Vec::new(),
                normals: Vec::new(),
            })
        })
        .collect();
    for i in 0..basis.vertex_count() {
        for (j, &b) in basis.row(i).iter().enumerate() {
            if b != 0.0 {
                for (a, (_, unit)) in AXES.iter().enumerate() {
                    out[3 * j + a].positions.push((i as u32, *unit * b));
                }
            }
        }
    }
    out
}

/// The weights of [`basis_morphs`] for control displacements `d` (rig units): `d_j[a]` in metres
/// at `3 j + a`. Allocates nothing.
///
/// # Panics
/// If `out` does not hold three weights per control.
pub fn basis_weights(d: &[Vec3], metres_per_unit: f32, out: &mut [f32]) {
    assert_eq!(out.len(), 3 * d.len(), "three weights per control");
    for (w, d) in out.chunks_exact_mut(3).zip(d) {
        w.copy_from_slice(&(*d * metres_per_unit).to_array());
    }
}

/// A rig's morph targets as glTF targets: position deltas scaled to metres, normal deltas as they
/// are (when the target has them).
pub fn target_morphs(targets: &[MorphTarget], metres_per_unit: f32) -> Vec<Morph> {
    let nonzero = |deltas: &[Vec3], scale: f32| -> Vec<(u32, Vec3)> {
        deltas
            .iter()
            .enumerate()
            .filter(|(_, d)| **d != Vec3::ZERO)
            .map(|(i, d)| (i as u32, *d * scale))
            .collect()
    };
    targets
        .iter()
        .map(|t| Morph {
            name: t.name.clone(),
            positions: nonzero(&t.position_deltas, metres_per_unit),
            normals: nonzero(&t.normal_deltas, 1.0),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_targets_times_weights_are_b_d() {
        // 3 vertices, 2 controls; vertex 2 frozen (zero row).
        let data = vec![1.0, 0.25, -0.5, 0.75, 0.0, 0.0];
        let basis = Basis::from_row_major(3, 2, data).unwrap();
        let names = vec!["2.1".to_string(), "8.3".to_string()];
        let morphs = basis_morphs(&basis, &names);
        assert_eq!(morphs.len(), 6);
        assert_eq!(morphs[4].name, "8.3.y");
        let d = [Vec3::new(1.0, -2.0, 3.0), Vec3::new(-0.5, 4.0, 0.25)];
        let s = 0.01;
        let mut w = vec![0.0; 6];
        basis_weights(&d, s, &mut w);
        let mut sum = [Vec3::ZERO; 3];
        for (m, w) in morphs.iter().zip(&w) {
            for (i, delta) in &m.positions {
                sum[*i as usize] += *delta * *w;
            }
        }
        let mut u = [Vec3::ZERO; 3];
        basis.apply(&d, &mut u);
        for (a, b) in sum.iter().zip(&u) {
            // Same products in another order: a few f32 ulps of the largest term.
            let tol = 4.0 * f32::EPSILON * s * 4.0;
            assert!((*a - *b * s).abs().max_element() <= tol, "{a} vs {b}");
        }
        assert!(
            morphs
                .iter()
                .all(|m| m.positions.iter().all(|(i, _)| *i < 2))
        );
    }
}
