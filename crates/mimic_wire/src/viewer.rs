//! The length-prefixed binary messages a viewer gets: SESSION, RIG, FRAME, END, ERROR.

use crate::bytes::{Cursor, DecodeError, put_vec3};
use glam::{Quat, Vec3};
use mimic_types::{FrameStatus, FrameView, HeadPose, Rig};
use serde_json::{Value, json};

/// Viewer message kind: session description (JSON).
pub const KIND_SESSION: u8 = 1;
/// Viewer message kind: the rig (rest mesh, triangles, basis `B`).
pub const KIND_RIG: u8 = 2;
/// Viewer message kind: one frame (pose, `d`, optionally positions).
pub const KIND_FRAME: u8 = 3;
/// Viewer message kind: the session ended (JSON).
pub const KIND_END: u8 = 4;
/// Viewer message kind: an error (JSON); the server closes the connection after it.
pub const KIND_ERROR: u8 = 5;
/// Bytes of a frame message's fixed part (after length and kind) before `d`.
pub const FRAME_FIXED_BYTES: usize = 8 + 8 + 4 + 4 + 16 + 12 + 4 + 16;

/// A viewer message: `u32` length of what follows, the kind byte, the payload.
fn message(kind: u8, payload_len: usize) -> Vec<u8> {
    let mut m = Vec::with_capacity(5 + payload_len);
    m.extend_from_slice(&((payload_len + 1) as u32).to_le_bytes());
    m.push(kind);
    m
}

/// A JSON viewer message (session, end, error).
pub fn encode_json(kind: u8, value: &Value) -> Vec<u8> {
    let text = value.to_string();
    let mut m = message(kind, text.len());
    m.extend_from_slice(text.as_bytes());
    m
}

/// The rig's basis `B` as the rig message carries it: `n x m` weights, row-major (one row a
/// vertex, one column a control or morph-target axis).
#[derive(Clone, Copy, Debug)]
pub struct BasisRows<'a> {
    /// The `n * m` weights, row-major.
    pub weights: &'a [f32],
    /// Columns `m`.
    pub columns: usize,
}

/// The rig message: a JSON description, then rest positions, triangles and `B` as raw arrays.
pub fn encode_rig(rig: &Rig, basis: BasisRows<'_>) -> Vec<u8> {
    let meta = json!({
        "name": rig.name,
        "units": rig.units,
        "vertices": rig.mesh.vertex_count(),
        "triangles": rig.mesh.triangles.len(),
        "controls": rig.controls.iter().map(|c| json!({
            "fdp": c.fdp.to_string(), "vertex": c.vertex, "region": c.region.name()
        })).collect::<Vec<_>>(),
        "regions": rig.regions,
    });
    encode_rig_parts(&meta, rig, basis)
}

/// The rig message of a weights session: `B` is the morph basis (three columns per target,
/// `mimic_solve::morph_basis`) and the JSON says `"mode":"weights"` and names the `targets` in
/// weight order (its `controls` list is empty: the columns are not control points).
pub fn encode_morph_rig(rig: &Rig, basis: BasisRows<'_>, targets: &[String]) -> Vec<u8> {
    let meta = json!({
        "name": rig.name,
        "units": rig.units,
        "vertices": rig.mesh.vertex_count(),
        "triangles": rig.mesh.triangles.len(),
        "mode": "weights",
        "targets": targets,
        "controls": [],
        "regions": rig.regions,
    });
    encode_rig_parts(&meta, rig, basis)
}

fn encode_rig_parts(meta: &Value, rig: &Rig, basis: BasisRows<'_>) -> Vec<u8> {
    let meta = meta.to_string();
    let n = rig.mesh.vertex_count();
    let t = rig.mesh.triangles.len();
    let m = basis.columns;
    let len = 4 + meta.len() + 12 + n * 12 + t * 12 + n * m * 4;
    let mut out = message(KIND_RIG, len);
    out.extend_from_slice(&(meta.len() as u32).to_le_bytes());
    out.extend_from_slice(meta.as_bytes());
    for v in [n, t, m] {
        out.extend_from_slice(&(v as u32).to_le_bytes());
    }
    for p in &rig.mesh.positions {
        put_vec3(&mut out, *p);
    }
    for tri in &rig.mesh.triangles {
        for i in tri {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    for w in basis.weights {
        out.extend_from_slice(&w.to_le_bytes());
    }
    out
}

/// Status byte of a frame message ([`FrameStatus::code`]).
pub fn status_byte(s: FrameStatus) -> u8 {
    s.code()
}

/// A frame message: sequence number, time, status, pose, target rotation, `d`, and the
/// positions when given.
pub fn encode_frame(seq: u64, out: &FrameView<'_>, positions: Option<&[Vec3]>) -> Vec<u8> {
    let m = out.displacements.len();
    let n = positions.map_or(0, <[Vec3]>::len);
    let len = FRAME_FIXED_BYTES + m * 12 + positions.map_or(0, |_| 4 + n * 12);
    let mut b = message(KIND_FRAME, len);
    b.extend_from_slice(&seq.to_le_bytes());
    b.extend_from_slice(&out.timestamp_us.to_le_bytes());
    b.push(status_byte(out.status));
    b.push(u8::from(positions.is_some()));
    b.extend_from_slice(&[0, 0]);
    b.extend_from_slice(&(m as u32).to_le_bytes());
    for c in out.pose.rotation.to_array() {
        b.extend_from_slice(&c.to_le_bytes());
    }
    put_vec3(&mut b, out.pose.translation);
    b.extend_from_slice(&out.pose.scale.to_le_bytes());
    for c in out.target_rotation.to_array() {
        b.extend_from_slice(&c.to_le_bytes());
    }
    for d in out.displacements {
        put_vec3(&mut b, *d);
    }
    if let Some(p) = positions {
        b.extend_from_slice(&(n as u32).to_le_bytes());
        for v in p {
            put_vec3(&mut b, *v);
        }
    }
    b
}

/// A decoded viewer message.
#[derive(Clone, Debug, PartialEq)]
pub enum ViewerMessage {
    /// Session description.
    Session(Value),
    /// The rig.
    Rig(RigMessage),
    /// One frame.
    Frame(FrameMessage),
    /// The session ended.
    End(Value),
    /// An error; the connection closes after it.
    Error(Value),
}

/// The rig as a viewer receives it.
#[derive(Clone, Debug, PartialEq)]
pub struct RigMessage {
    /// JSON description (name, units, controls with regions, region bands).
    pub meta: Value,
    /// Rest positions.
    pub rest: Vec<Vec3>,
    /// Triangles.
    pub triangles: Vec<[u32; 3]>,
    /// Controls (columns of `B`).
    pub controls: usize,
    /// `B`, n x m row-major.
    pub basis: Vec<f32>,
}

/// One frame as a viewer receives it.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameMessage {
    /// Index of the frame in the session (accepted frames, from 0).
    pub seq: u64,
    /// Frame time (µs, the tracker's clock).
    pub timestamp_us: i64,
    /// 0 calibrating, 1 tracked, 2 lost, 3 rejected.
    pub status: u8,
    /// Head pose (source space).
    pub pose: HeadPose,
    /// Head rotation in target axes.
    pub target_rotation: Quat,
    /// Control displacements `d`, target units.
    pub displacements: Vec<Vec3>,
    /// Deformed positions, when the viewer asked for them.
    pub positions: Option<Vec<Vec3>>,
}

fn json_of(b: &[u8], packet: &'static str) -> Result<Value, DecodeError> {
    serde_json::from_slice(b).map_err(|e| DecodeError::Json {
        packet,
        message: e.to_string(),
    })
}

/// Decodes a viewer message from its kind byte and payload (what follows the kind).
pub fn decode_viewer_message(kind: u8, payload: &[u8]) -> Result<ViewerMessage, DecodeError> {
    match kind {
        KIND_SESSION => Ok(ViewerMessage::Session(json_of(payload, "SESSION message")?)),
        KIND_END => Ok(ViewerMessage::End(json_of(payload, "END message")?)),
        KIND_ERROR => Ok(ViewerMessage::Error(json_of(payload, "ERROR message")?)),
        KIND_RIG => decode_rig(payload).map(ViewerMessage::Rig),
        KIND_FRAME => decode_frame(payload).map(ViewerMessage::Frame),
        k => Err(DecodeError::Kind(k)),
    }
}

/// The payload of a RIG message.
fn decode_rig(payload: &[u8]) -> Result<RigMessage, DecodeError> {
    const PACKET: &str = "RIG message";
    let mut c = Cursor::new(payload, PACKET);
    let meta_len = c.count("json_len")?;
    let meta = json_of(c.take(meta_len, "json")?, PACKET)?;
    let n = c.count("n")?;
    let t = c.count("t")?;
    let m = c.count("m")?;
    let rest = c.vec3s(n, "rest")?;
    let triangles = c.triangles(t, "triangles")?;
    let cells = n.checked_mul(m).ok_or_else(|| c.short("B"))?;
    let basis = c.f32s(cells, "B")?;
    Ok(RigMessage {
        meta,
        rest,
        triangles,
        controls: m,
        basis,
    })
}

/// The payload of a FRAME message.
fn decode_frame(payload: &[u8]) -> Result<FrameMessage, DecodeError> {
    let mut c = Cursor::new(payload, "FRAME message");
    let seq = c.u64("seq")?;
    let timestamp_us = c.i64("t_us")?;
    let status = c.u8("status")?;
    let has_positions = c.u8("has_positions")? != 0;
    c.take(2, "reserved")?;
    let m = c.count("m")?;
    let rotation = c.quat("rotation")?;
    let translation = c.vec3("translation")?;
    let scale = c.f32("scale")?;
    let target_rotation = c.quat("target_rotation")?;
    let displacements = c.vec3s(m, "d")?;
    let positions = if has_positions {
        let n = c.count("n")?;
        Some(c.vec3s(n, "positions")?)
    } else {
        None
    };
    Ok(FrameMessage {
        seq,
        timestamp_us,
        status,
        pose: HeadPose {
            rotation,
            translation,
            scale,
        },
        target_rotation,
        displacements,
        positions,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_message_round_trips() {
        let d = [Vec3::new(1.0, -2.0, 3.5), Vec3::splat(0.25)];
        let out = FrameView {
            timestamp_us: -5,
            status: FrameStatus::Lost,
            displacements: &d,
            pose: HeadPose {
                rotation: Quat::from_rotation_y(0.3),
                translation: Vec3::new(0.1, 0.2, -0.7),
                scale: 1.5,
            },
            target_rotation: Quat::from_rotation_x(-0.2),
        };
        let pos = [Vec3::X, Vec3::new(7.0, 8.0, 9.0)];
        for positions in [None, Some(&pos[..])] {
            let bytes = encode_frame(42, &out, positions);
            let len = u32::from_le_bytes(bytes[..4].try_into().unwrap()) as usize;
            assert_eq!(len + 4, bytes.len());
            let ViewerMessage::Frame(f) = decode_viewer_message(bytes[4], &bytes[5..]).unwrap()
            else {
                panic!("not a frame")
            };
            // Raw f32 copies: exact.
            assert_eq!(f.seq, 42);
            assert_eq!(f.timestamp_us, -5);
            assert_eq!(f.status, 2);
            assert_eq!(f.pose, out.pose);
            assert_eq!(f.target_rotation, out.target_rotation);
            assert_eq!(f.displacements, out.displacements.to_vec());
            assert_eq!(f.positions.as_deref(), positions);
            // Any cut-off payload is an error, never a panic.
            for cut in 0..bytes.len() - 5 {
                assert!(decode_viewer_message(bytes[4], &bytes[5..5 + cut]).is_err());
            }
        }
    }
}
