//! UDP frame packets: a tracker's frames, after the welcome line gave it an id and key.

use crate::bytes::{Cursor, DecodeError, put_vec3};
use glam::Vec3;
use mimic_types::LandmarkFrame;

/// First four bytes of a UDP frame packet.
pub const UDP_MAGIC: [u8; 4] = *b"MMF1";
/// Bytes of a UDP frame packet before the points.
pub const UDP_HEADER_BYTES: usize = 28;

/// A frame packet as sent over UDP.
#[derive(Clone, Debug, PartialEq)]
pub struct UdpFrame {
    /// Session id from the tracker's welcome line.
    pub session_id: u32,
    /// Session key from the welcome line.
    pub key: u32,
    /// The frame (NaN coordinates mark invalid points).
    pub frame: LandmarkFrame,
}

/// Encodes a UDP frame packet (invalid points are sent as NaN).
pub fn encode_udp_frame(session_id: u32, key: u32, frame: &LandmarkFrame) -> Vec<u8> {
    let mut b = Vec::with_capacity(UDP_HEADER_BYTES + frame.points.len() * 12);
    b.extend_from_slice(&UDP_MAGIC);
    b.extend_from_slice(&session_id.to_le_bytes());
    b.extend_from_slice(&key.to_le_bytes());
    b.extend_from_slice(&frame.timestamp_us.to_le_bytes());
    b.push(u8::from(frame.tracked));
    b.extend_from_slice(&[0, 0, 0]);
    b.extend_from_slice(&(frame.points.len() as u32).to_le_bytes());
    for (i, p) in frame.points.iter().enumerate() {
        put_vec3(&mut b, if frame.is_valid(i) { *p } else { Vec3::NAN });
    }
    b
}

/// Decodes a UDP frame packet; the point count is checked against the layout by the session.
pub fn decode_udp_frame(packet: &[u8]) -> Result<UdpFrame, DecodeError> {
    let mut c = Cursor::new(packet, "UDP frame packet");
    if c.arr::<4>("magic")? != UDP_MAGIC {
        return Err(DecodeError::Magic);
    }
    let session_id = c.u32("session_id")?;
    let key = c.u32("key")?;
    let timestamp_us = c.i64("t_us")?;
    let flags = c.u8("flags")?;
    c.take(3, "reserved")?;
    let points = c.u32("points")? as usize;
    let expected = points
        .checked_mul(12)
        .and_then(|b| b.checked_add(UDP_HEADER_BYTES));
    if expected != Some(packet.len()) {
        return Err(DecodeError::Size {
            len: packet.len(),
            points,
            expected: expected.unwrap_or(usize::MAX),
        });
    }
    let pts = c.vec3s(points, "points")?;
    let mut valid = Vec::with_capacity(points);
    for (i, p) in pts.iter().enumerate() {
        if p.is_nan() {
            valid.push(false);
        } else if !p.is_finite() {
            return Err(DecodeError::Infinite(i));
        } else {
            valid.push(true);
        }
    }
    Ok(UdpFrame {
        session_id,
        key,
        frame: LandmarkFrame {
            timestamp_us,
            points: pts,
            valid,
            tracked: flags & 1 != 0,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn udp_packet_round_trips_and_checks_its_size() {
        let frame = LandmarkFrame {
            timestamp_us: 123_456,
            points: vec![Vec3::new(0.1, 0.2, -0.9), Vec3::NAN, Vec3::ONE],
            valid: vec![true, false, true],
            tracked: true,
        };
        let b = encode_udp_frame(7, 99, &frame);
        assert_eq!(b.len(), UDP_HEADER_BYTES + 3 * 12);
        let u = decode_udp_frame(&b).unwrap();
        assert_eq!((u.session_id, u.key), (7, 99));
        assert_eq!(u.frame.valid, frame.valid);
        assert_eq!(u.frame.points[0], frame.points[0]);
        assert_eq!(u.frame.timestamp_us, 123_456);
        assert!(matches!(
            decode_udp_frame(&b[..b.len() - 1]),
            Err(DecodeError::Size { .. })
        ));
        let mut bad = b.clone();
        bad[0] = b'X';
        assert_eq!(decode_udp_frame(&bad), Err(DecodeError::Magic));
        let mut inf = b;
        inf[UDP_HEADER_BYTES..UDP_HEADER_BYTES + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
        assert_eq!(decode_udp_frame(&inf), Err(DecodeError::Infinite(0)));
    }
}
