//! VMC (Virtual Motion Capture protocol: OSC over UDP) frames: one OSC bundle per frame holding
//! `/VMC/Ext/Blend/Val <name> <value>` per weight, then `/VMC/Ext/Blend/Apply`, then
//! `/VMC/Ext/Bone/Pos "Head" px py pz qx qy qz qw`.
//!
//! Axes: mimic (and ARKit) are right-handed, x right, y up, z toward the viewer; Unity, whose
//! axes VMC uses, is left-handed with z away from the viewer. So a point maps as (x, y, -z) and a
//! rotation quaternion (x, y, z, w) as (-x, -y, z, w) (the mirror through the xy plane). The
//! head's position is sent as 0 (the weights paths have no head translation).

use glam::Quat;
use rosc::{OscBundle, OscMessage, OscPacket, OscTime, OscType};

/// The address of a blendshape value.
pub const BLEND_VAL: &str = "/VMC/Ext/Blend/Val";
/// The address that applies the values sent since the last one.
pub const BLEND_APPLY: &str = "/VMC/Ext/Blend/Apply";
/// The address of a bone's local position and rotation.
pub const BONE_POS: &str = "/VMC/Ext/Bone/Pos";
/// The bone the head rotation is sent as.
pub const HEAD_BONE: &str = "Head";

/// A right-handed rotation (mimic, ARKit) in Unity's left-handed axes: `(-x, -y, z, w)`.
pub fn to_unity(q: Quat) -> [f32; 4] {
    [-q.x, -q.y, q.z, q.w]
}

/// Encodes one frame's bundle into `out` (cleared first): `names[i]` with `values[i]` (pairs
/// past the shorter end are left out), the apply, then the head rotation.
pub fn encode_frame(names: &[String], values: &[f32], head: Quat, out: &mut Vec<u8>) {
    let mut content: Vec<OscPacket> = names
        .iter()
        .zip(values)
        .map(|(n, &v)| {
            OscPacket::Message(OscMessage {
                addr: BLEND_VAL.to_string(),
                args: vec![OscType::String(n.clone()), OscType::Float(v)],
            })
        })
        .collect();
    content.push(OscPacket::Message(OscMessage {
        addr: BLEND_APPLY.to_string(),
        args: Vec::new(),
    }));
    let [qx, qy, qz, qw] = to_unity(head);
    let mut bone = vec![OscType::String(HEAD_BONE.to_string())];
    bone.extend([0.0, 0.0, 0.0, qx, qy, qz, qw].map(OscType::Float));
    content.push(OscPacket::Message(OscMessage {
        addr: BONE_POS.to_string(),
        args: bone,
    }));
    // Time tag 1: "immediately" (OSC 1.0).
    let bundle = OscPacket::Bundle(OscBundle {
        timetag: OscTime {
            seconds: 0,
            fractional: 1,
        },
        content,
    });
    out.clear();
    let _ = rosc::encoder::encode_into(&bundle, out);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_decodes_as_values_apply_and_head() {
        let names = vec!["jawOpen".to_string(), "A".to_string()];
        let head = Quat::from_rotation_y(0.3);
        let mut buf = Vec::new();
        encode_frame(&names, &[0.25, 1.0], head, &mut buf);
        let (rest, p) = rosc::decoder::decode_udp(&buf).unwrap();
        assert!(rest.is_empty());
        let OscPacket::Bundle(b) = p else {
            panic!("not a bundle")
        };
        let m: Vec<OscMessage> = b
            .content
            .into_iter()
            .map(|p| match p {
                OscPacket::Message(m) => m,
                OscPacket::Bundle(_) => panic!("nested bundle"),
            })
            .collect();
        assert_eq!(m.len(), 4);
        assert_eq!(m[0].addr, BLEND_VAL);
        assert_eq!(
            m[0].args,
            [OscType::String("jawOpen".into()), OscType::Float(0.25)]
        );
        assert_eq!(m[2].addr, BLEND_APPLY);
        assert_eq!(m[3].addr, BONE_POS);
        assert_eq!(m[3].args.len(), 8);
        // A yaw about +y in right-handed axes is the opposite yaw in left-handed ones.
        let q: Vec<f32> = m[3].args[4..]
            .iter()
            .map(|a| a.clone().float().unwrap())
            .collect();
        let back = Quat::from_xyzw(q[0], q[1], q[2], q[3]);
        assert!(
            back.abs_diff_eq(Quat::from_rotation_y(-0.3), 1e-6),
            "{back}"
        );
    }
}
