//! The inside of a mouth cut open ([`crate::lipcut`]): ICT-FaceKit's mouth socket, gums with
//! tongue, and teeth, carried onto the head by the template registration and added to the rig's
//! mesh as separate pieces (docs/rigging.md, "Closed lips").
//!
//! The pieces are the template's: the mouth socket is the part of ICT's sockets
//! ([`ICT_SOCKETS`]) below [`SOCKET_BELOW`] in its face frame (the eye sockets lie above; ICT's
//! two groups are 0.15 IOD apart there), the gums and tongue [`ICT_GUMS_TONGUE`] and the teeth
//! [`ICT_TEETH`]. Each vertex is moved as the registration's nodes around it moved (the
//! template's displacement field, [`crate::transfer::deform_template`]'s rule, inverse-distance
//! weighted over its nearest nodes) and taken into the head's coordinates by the registration's
//! similarity. `rig new` then finds them as it finds any mesh's inner parts
//! ([`crate::rigid_parts`]): the lower teeth ride on the jaw, the socket and the gums-and-tongue
//! piece (both spanning the lip line) ride on it below the line.

use crate::head_template::{Registration, TemplateHead};
use crate::nearest::PointIndex;
use glam::{Mat3, Vec3};
use mimic_assets::PackedShape;
use std::ops::Range;

/// ICT's mouth and eye sockets (`configs/rigs/ict-face.toml`).
pub const ICT_SOCKETS: Range<usize> = 11248..14062;

/// ICT's gums and tongue (one piece; material `M_GumsTongue`).
pub const ICT_GUMS_TONGUE: Range<usize> = 14062..17039;

/// ICT's teeth (material `M_Teeth`).
pub const ICT_TEETH: Range<usize> = 17039..21451;

/// The mouth socket is the part of [`ICT_SOCKETS`] below this height in the template's face
/// frame (IOD; ICT's eye sockets reach down to -0.44, its mouth socket up to -0.60).
pub const SOCKET_BELOW: f32 = -0.5;

/// The added pieces' materials, in [`Interior::material`]'s numbering: name and colour (`Kd`).
pub const MATERIALS: [(&str, [f32; 3]); 3] = [
    // The socket is a dark cavity seen from inside.
    ("mouth_socket", [0.06, 0.015, 0.02]),
    // ICT's own `M_GumsTongue` colour.
    ("gums_tongue", [0.30, 0.03, 0.06]),
    ("teeth", [0.85, 0.82, 0.72]),
];

/// The mouth's inside carried onto a head ([`mouth_interior`]).
#[derive(Clone, Debug, Default)]
pub struct Interior {
    /// The template vertex of each added vertex.
    pub template_vertex: Vec<u32>,
    /// Where each added vertex goes, in the head's coordinates.
    pub positions: Vec<Vec3>,
    /// Triangles over the added vertices (numbered from 0 among them).
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle, its material (an index into [`MATERIALS`]).
    pub material: Vec<usize>,
    /// Vertices of the mouth socket, of the gums and tongue, and of the teeth.
    pub counts: [usize; 3],
}

/// ICT's mouth socket, gums, tongue and teeth placed in the head `reg` registered `template`
/// (ICT) onto.
pub fn mouth_interior(template: &TemplateHead, reg: &Registration) -> Interior {
    let mesh = &template.mesh;
    let face = |v: usize| reg.frame.to_face(mesh.positions[v]);
    let group = |v: usize| {
        if ICT_SOCKETS.contains(&v) && face(v).y < SOCKET_BELOW {
            Some(0)
        } else if ICT_GUMS_TONGUE.contains(&v) {
            Some(1)
        } else if ICT_TEETH.contains(&v) {
            Some(2)
        } else {
            None
        }
    };
    let mut out = Interior::default();
    let mut index = vec![u32::MAX; mesh.vertex_count()];
    let nodes = PointIndex::new(&reg.node_at, |_| true);
    let h2 = 0.05f32 * 0.05;
    for (v, slot) in index.iter_mut().enumerate() {
        let Some(g) = group(v) else { continue };
        let f = face(v);
        let (mut sum, mut total) = (Vec3::ZERO, 0.0f32);
        for (k, d) in nodes.nearest_k(f, 8) {
            let w = 1.0 / (d * d + h2);
            let k = k as usize;
            sum += w * (reg.deformed[k] - reg.node_at[k]);
            total += w;
        }
        let moved = if total > 0.0 { f + sum / total } else { f };
        *slot = out.positions.len() as u32;
        out.positions.push(reg.rigid.pose.apply(moved));
        out.template_vertex.push(v as u32);
        out.counts[g] += 1;
    }
    for t in &mesh.triangles {
        let local = t.map(|v| index[v as usize]);
        if local.contains(&u32::MAX) {
            continue;
        }
        if let Some(g) = group(t[0] as usize) {
            out.triangles.push(local);
            out.material.push(g);
        }
    }
    out
}

/// Gives the added inside (vertices `start..` of each shape, ICT's vertex of each in
/// `template_vertex`) the template's own deltas of the shape of the same name in `on_template`,
/// turned and scaled into the head's frame by the registration `reg`.
pub fn carry_shapes(
    shapes: &mut [PackedShape],
    start: usize,
    template_vertex: &[u32],
    on_template: &[PackedShape],
    reg: &Registration,
) {
    let axes = Mat3::from_cols(reg.frame.axes[0], reg.frame.axes[1], reg.frame.axes[2]);
    let turn = Mat3::from_quat(reg.rigid.pose.rotation) * axes.transpose();
    let scale = reg.rigid.pose.scale / reg.frame.iod;
    for s in shapes {
        let Some(t) = on_template.iter().find(|t| t.name == s.name) else {
            continue;
        };
        for (i, v) in template_vertex.iter().enumerate() {
            if let (Some(d), Some(e)) = (s.deltas.get_mut(start + i), t.deltas.get(*v as usize)) {
                *d = turn * *e * scale;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn icts_mouth_pieces_are_split_from_its_eye_sockets_by_height() {
        let configs = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs");
        let t = TemplateHead::ict(&configs).expect("ICT");
        let frame = crate::new::landmark_frame(&t.mesh, &t.landmarks).expect("frame");
        let ys: Vec<f32> = ICT_SOCKETS
            .map(|v| frame.to_face(t.mesh.positions[v]).y)
            .collect();
        // No socket vertex lies within 0.05 IOD of the split: the groups are apart.
        assert!(ys.iter().all(|y| (y - SOCKET_BELOW).abs() > 0.05));
        let mouth = ys.iter().filter(|y| **y < SOCKET_BELOW).count();
        assert!(mouth > 1000 && mouth < ys.len() - 500, "{mouth}");
        // The gums, tongue and teeth lie in the mouth: below the nose base (iBUG 33).
        let nose = frame.to_face(t.mesh.positions[t.landmarks.get(33).expect("33") as usize]);
        for v in ICT_GUMS_TONGUE.start..ICT_TEETH.end {
            assert!(frame.to_face(t.mesh.positions[v]).y < nose.y + 0.1, "{v}");
        }
    }
}
