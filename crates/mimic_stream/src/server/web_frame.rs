//! The browser viewer's frame message (docs/protocol.md, "Browser viewer"): encoded once per
//! frame for a session's browser viewers ([`encode_web_frame`]), stamped with its send time as it
//! leaves for each ([`stamped`]).

use axum::body::Bytes;
use mimic_retarget::FrameOutput;
use mimic_wire::KIND_FRAME;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

/// Bytes of a web frame before `d`.
pub(crate) const WEB_FRAME_FIXED_BYTES: usize = 80;

/// Offset of the send time in a web frame (filled when the frame leaves for the browser).
pub(crate) const SENT_AT: usize = 24;

/// The server's wall clock, in microseconds since the Unix epoch.
pub(crate) fn unix_now_us() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_micros()).unwrap_or(i64::MAX))
}

/// The browser's frame message (docs/protocol.md, "Browser viewer"), after the queue's 5-byte
/// header (length, kind FRAME): seq, tracker time, arrival time (server wall clock of the
/// frame's read), send time (0 here; [`stamped`] fills it when the frame leaves), status, `m` and `k`, the session's gated
/// count, head rotation in target axes, pose translation and scale, `d`, and for a weights
/// session (`weights`) the `k = m / 3` weights (`d[3j].x`).
pub(crate) fn encode_web_frame(
    seq: u64,
    out: &FrameOutput,
    arrival: Instant,
    gated: u64,
    weights: bool,
) -> Vec<u8> {
    let m = out.displacements.len();
    let k = if weights { m / 3 } else { 0 };
    let len = WEB_FRAME_FIXED_BYTES + 12 * m + 4 * k;
    let mut b = Vec::with_capacity(5 + len);
    b.extend_from_slice(&u32::try_from(len + 1).unwrap_or(u32::MAX).to_le_bytes());
    b.push(KIND_FRAME);
    let since = i64::try_from(arrival.elapsed().as_micros()).unwrap_or(0);
    b.extend_from_slice(&seq.to_le_bytes());
    b.extend_from_slice(&out.timestamp_us.to_le_bytes());
    b.extend_from_slice(&(unix_now_us() - since).to_le_bytes());
    b.extend_from_slice(&0i64.to_le_bytes());
    b.push(mimic_wire::status_byte(out.status));
    b.push(u8::from(weights));
    b.extend_from_slice(&[0, 0]);
    for x in [m, k] {
        b.extend_from_slice(&u32::try_from(x).unwrap_or(u32::MAX).to_le_bytes());
    }
    b.extend_from_slice(&u32::try_from(gated).unwrap_or(u32::MAX).to_le_bytes());
    let r = out.target_rotation.to_array();
    let t = out.pose.translation.to_array();
    for c in r.iter().chain(&t).chain(&[out.pose.scale]) {
        b.extend_from_slice(&c.to_le_bytes());
    }
    for d in &out.displacements {
        for c in d.to_array() {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for j in 0..k {
        let w = out.displacements.get(3 * j).map_or(0.0, |d| d.x);
        b.extend_from_slice(&w.to_le_bytes());
    }
    b
}

/// A web frame's payload with its send time set to now.
pub(crate) fn stamped(payload: &[u8]) -> Bytes {
    let mut b = payload.to_vec();
    if let Some(at) = b.get_mut(SENT_AT..SENT_AT + 8) {
        at.copy_from_slice(&unix_now_us().to_le_bytes());
    }
    Bytes::from(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};
    use mimic_retarget::FrameStatus;

    #[test]
    fn a_web_frame_has_the_documented_layout() {
        let mut out = FrameOutput {
            timestamp_us: -7,
            status: FrameStatus::Lost,
            positions: Vec::new(),
            normals: Vec::new(),
            displacements: vec![Vec3::new(0.25, 0.0, 0.0), Vec3::Y, Vec3::Z],
            pose: mimic_types::HeadPose::default(),
            target_rotation: Quat::from_rotation_y(0.5),
            filled: 0,
            times: Default::default(),
        };
        out.pose.translation = Vec3::new(1.0, 2.0, 3.0);
        let before = unix_now_us();
        let b = encode_web_frame(42, &out, Instant::now(), 5, true);
        let after = unix_now_us();
        let (m, k) = (3usize, 1usize);
        assert_eq!(b.len(), 5 + WEB_FRAME_FIXED_BYTES + 12 * m + 4 * k);
        assert_eq!(
            u32::from_le_bytes(b[0..4].try_into().unwrap()) as usize,
            b.len() - 4
        );
        assert_eq!(b[4], KIND_FRAME);
        let p = &b[5..];
        let i64_at = |o: usize| i64::from_le_bytes(p[o..o + 8].try_into().unwrap());
        let u32_at = |o: usize| u32::from_le_bytes(p[o..o + 4].try_into().unwrap());
        let f32_at = |o: usize| f32::from_le_bytes(p[o..o + 4].try_into().unwrap());
        assert_eq!(u64::from_le_bytes(p[0..8].try_into().unwrap()), 42);
        assert_eq!(i64_at(8), -7);
        assert!(
            (before..=after).contains(&i64_at(16)),
            "arrival {}",
            i64_at(16)
        );
        assert_eq!(i64_at(24), 0);
        assert_eq!((p[32], p[33]), (2, 1));
        assert_eq!((u32_at(36), u32_at(40), u32_at(44)), (3, 1, 5));
        let r = out.target_rotation.to_array();
        for (a, want) in r.iter().enumerate() {
            assert_eq!(f32_at(48 + 4 * a), *want);
        }
        assert_eq!(
            (f32_at(64), f32_at(68), f32_at(72), f32_at(76)),
            (1.0, 2.0, 3.0, 1.0)
        );
        assert_eq!(f32_at(80 + 12 + 4), 1.0, "d[1].y");
        assert_eq!(f32_at(80 + 36), 0.25, "the weight is d[0].x");
        // The send time is filled when the frame leaves.
        let sent = stamped(&b[5..]);
        assert_eq!(sent[..SENT_AT], p[..SENT_AT]);
        let at = i64::from_le_bytes(sent[24..32].try_into().unwrap());
        assert!(at >= after, "sent {at}");
    }
}
