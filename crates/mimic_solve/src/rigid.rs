//! Rigid parts folded into the basis: four columns per part (jaw, left eye, right eye) after the
//! controls', so that `u = B d` moves a part by `w ((R - I)(p - pivot) + t)` when its four
//! entries of `d` are the columns of `R - I` and the slide `t` ([`mimic_types::parts`]), and
//! [`part_coefficients`] writes those four from a rotation and a slide.

use crate::{Basis, SolveError};
use glam::{Mat3, Vec3};
use mimic_types::{PartError, Rig, parts::PART_COLUMNS};

/// `basis` (`n x m`, the controls' columns) with the rig's part columns appended: row `i` of
/// part `k` holds `w_i (p_i - pivot)` in columns `m + 4k .. m + 4k + 3` and `w_i` in `m + 4k + 3`
/// (`p_i` the rest position, `w_i` the vertex's weight in the part). A rig without parts gets
/// `basis` back unchanged.
pub fn with_parts(basis: Basis, rig: &Rig) -> Result<Basis, SolveError> {
    if rig.parts.is_empty() {
        return Ok(basis);
    }
    let n = basis.vertex_count();
    rig.parts
        .validate(n)
        .map_err(|e: PartError| SolveError::InvalidSetting(e.to_string()))?;
    let m = basis.control_count();
    let k = rig.parts.column_count();
    let wide = m + k;
    let mut data = vec![0f32; n * wide];
    for (i, row) in data.chunks_exact_mut(wide).enumerate() {
        row[..m].copy_from_slice(basis.row(i));
    }
    let positions = &rig.mesh.positions;
    for (part, (pivot, vertices)) in rig.parts.bodies(positions).into_iter().enumerate() {
        let col = m + PART_COLUMNS * part;
        for (v, w) in vertices {
            let (v, w) = (v as usize, w);
            let r = (positions[v] - pivot) * w;
            let row = &mut data[v * wide..(v + 1) * wide];
            // A part's vertex follows the part alone (parts are frozen for the solvers).
            row[..m].fill(0.0);
            row[col..col + PART_COLUMNS].copy_from_slice(&[r.x, r.y, r.z, w]);
        }
    }
    Basis::from_row_major(n, wide, data).ok_or(SolveError::NoControls)
}

/// The four entries of `d` that move a part by rotation `rotation` about its pivot and then by
/// `slide`: the columns of `rotation - I`, then `slide`.
pub fn part_coefficients(rotation: Mat3, slide: Vec3) -> [Vec3; PART_COLUMNS] {
    let r = rotation - Mat3::IDENTITY;
    [r.x_axis, r.y_axis, r.z_axis, slide]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes;
    use glam::Quat;
    use mimic_types::{EyePart, JawPart, RigParts};

    /// A grid rig whose last two vertices are a jaw's tooth and an eye's point.
    fn parted_rig() -> Rig {
        let mesh = test_meshes::grid(4, 4, 0.0, 0.0, 1);
        let mut rig = test_meshes::rig(mesh, &[0, 5, 10], 0.5);
        let n = rig.mesh.vertex_count() as u32;
        for f in rig.frozen.iter_mut().skip(n as usize - 2) {
            *f = true;
        }
        rig.parts = RigParts {
            jaw: Some(JawPart {
                vertices: vec![[n - 2, n - 2]],
                ramped: vec![],
                cut: 0.0,
                band: 0.0,
                hinge: Vec3::new(0.0, 2.0, -1.0),
                axis: Vec3::X,
            }),
            eyes: Some([
                EyePart {
                    vertices: vec![[n - 1, n - 1]],
                    centre: Vec3::new(1.0, 1.0, -0.5),
                },
                EyePart {
                    vertices: vec![],
                    centre: Vec3::ZERO,
                },
            ]),
        };
        rig
    }

    #[test]
    fn a_part_moves_rigidly_by_its_columns_and_nothing_else_does() {
        let rig = parted_rig();
        let settings = mimic_types::SolverSettings::default();
        let b = crate::build_basis(&rig, &settings).expect("basis");
        let m = rig.controls.len();
        assert_eq!(b.control_count(), m + 12);
        let n = rig.mesh.vertex_count();
        let jaw_turn = Mat3::from_quat(Quat::from_rotation_x(0.3));
        let eye_turn = Mat3::from_quat(Quat::from_euler(glam::EulerRot::YXZ, 0.2, -0.1, 0.0));
        let slide = Vec3::new(0.0, -0.1, 0.05);
        let mut d = vec![Vec3::ZERO; m + 12];
        d[m..m + 4].copy_from_slice(&part_coefficients(jaw_turn, slide));
        d[m + 4..m + 8].copy_from_slice(&part_coefficients(eye_turn, Vec3::ZERO));
        let mut u = vec![Vec3::ZERO; n];
        b.apply(&d, &mut u);
        let p = &rig.mesh.positions;
        let tooth = n - 2;
        let hinge = Vec3::new(0.0, 2.0, -1.0);
        let want = jaw_turn * (p[tooth] - hinge) + hinge + slide;
        // Independent truth: the rotation applied to the rest point; f32 rounding of a few terms.
        let tol = 8.0 * f32::EPSILON * (p[tooth] - hinge).length().max(1.0);
        assert!((p[tooth] + u[tooth] - want).length() < tol);
        let centre = Vec3::new(1.0, 1.0, -0.5);
        let want = eye_turn * (p[n - 1] - centre) + centre;
        assert!((p[n - 1] + u[n - 1] - want).length() < tol);
        // The face (controls' rows) does not see the part columns.
        for (i, ui) in u.iter().enumerate().take(n - 2) {
            assert_eq!(*ui, Vec3::ZERO, "vertex {i}");
        }
    }

    #[test]
    fn a_rig_without_parts_keeps_its_basis() {
        let mut rig = parted_rig();
        rig.parts = RigParts::default();
        let b = crate::build_basis(&rig, &mimic_types::SolverSettings::default()).expect("basis");
        assert_eq!(b.control_count(), rig.controls.len());
    }
}
