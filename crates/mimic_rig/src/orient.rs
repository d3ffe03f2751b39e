//! `mimic rig new` on a head in any orientation (docs/rigging.md, "Orientation"): the turn that
//! stands a head up (y up, +z out of the face), read off its landmarks' face frame and snapped
//! to the nearest of the 24 axis-aligned turns, and the mesh and template registration turned
//! by it. The rig records the turn as `[orientation]`; `mimic_assets::load_rig` turns the mesh
//! as it loads, so every consumer sees the head standing up.

use crate::landmarks::Landmarks;
use crate::new::landmark_frame;
use crate::{Registration, RigNewError};
use glam::Quat;
use mimic_assets::Orientation;
use mimic_types::Mesh;

/// The axis-aligned turn nearest to the face frame of `mesh` by its landmarks (the identity for
/// a head standing y up and facing +z, tilted by less than 45 degrees).
pub fn head_orientation(mesh: &Mesh, marks: &Landmarks) -> Result<Orientation, RigNewError> {
    let frame = landmark_frame(mesh, marks)?;
    Ok(Orientation::nearest(frame.axes[1], frame.axes[2]))
}

/// `mesh`'s positions turned into the rig's frame (exact: coordinates swapped and negated).
pub fn turn_mesh(mesh: &mut Mesh, turn: Orientation) {
    if turn.is_identity() {
        return;
    }
    for p in &mut mesh.positions {
        *p = turn.to_rig(*p);
    }
}

/// A registration onto the unturned mesh re-expressed onto the turned one: its similarity
/// (template face units to target coordinates) followed by the turn. What it holds in the
/// template's face frame is unchanged.
pub fn turn_registration(reg: &mut Registration, turn: Orientation) {
    if turn.is_identity() {
        return;
    }
    let back = Quat::from_mat3(&turn.rig_to_file()).conjugate();
    let pose = &mut reg.rigid.pose;
    pose.rotation = (back * pose.rotation).normalize();
    pose.translation = turn.to_rig(pose.translation);
}

/// What `rig new` says of a turned head.
pub fn turn_note(turn: Orientation) -> String {
    format!(
        "the head {}: turned to y up, +z forward for the rig (its [orientation] turns the mesh as it loads; meshes written from the rig, OBJ frames and GLB, are in that turned frame)",
        turn.describe()
    )
}
