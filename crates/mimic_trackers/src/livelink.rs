//! Live Link Face's UDP packet (packet version 6), decoded and encoded.
//!
//! Layout, big-endian after the first byte: u8 version (6); the device id and the subject name,
//! each a u32 length and that many UTF-8 bytes; the frame time as i32 frame number and f32
//! sub-frame; the frame rate as i32 numerator and i32 denominator; u8 curve count (61); then 61
//! f32 curves in ARKit's `FaceBlendShape` enum order ([`CURVE_NAMES`]: 52 blendshapes, head yaw,
//! pitch and roll, left and right eye yaw, pitch and roll). This is the order of the stream, in
//! which `JawLeft` comes before `JawRight` and `MouthLeft` before `MouthRight`; the app's CSV takes
//! order those two pairs the other way round (read them by name: [`crate::take`]).

use crate::error::PacketError;

/// Curves per packet.
pub const CURVES: usize = 61;
/// Blendshape curves (the first 52).
pub const BLENDSHAPES: usize = 52;
/// The packet version this module reads and writes.
pub const PACKET_VERSION: u8 = 6;
/// Longest device id or subject name taken (bytes).
pub const MAX_NAME_BYTES: usize = 1024;
/// Index of `HeadYaw` (then `HeadPitch`, `HeadRoll`).
pub const HEAD_YAW: usize = 52;
/// Index of `LeftEyeYaw` (then pitch, roll, and the right eye's three).
pub const LEFT_EYE_YAW: usize = 55;

/// The 61 curves in stream order (ARKit's `FaceBlendShape` enum).
pub const CURVE_NAMES: [&str; CURVES] = [
    "EyeBlinkLeft",
    "EyeLookDownLeft",
    "EyeLookInLeft",
    "EyeLookOutLeft",
    "EyeLookUpLeft",
    "EyeSquintLeft",
    "EyeWideLeft",
    "EyeBlinkRight",
    "EyeLookDownRight",
    "EyeLookInRight",
    "EyeLookOutRight",
    "EyeLookUpRight",
    "EyeSquintRight",
    "EyeWideRight",
    "JawForward",
    "JawLeft",
    "JawRight",
    "JawOpen",
    "MouthClose",
    "MouthFunnel",
    "MouthPucker",
    "MouthLeft",
    "MouthRight",
    "MouthSmileLeft",
    "MouthSmileRight",
    "MouthFrownLeft",
    "MouthFrownRight",
    "MouthDimpleLeft",
    "MouthDimpleRight",
    "MouthStretchLeft",
    "MouthStretchRight",
    "MouthRollLower",
    "MouthRollUpper",
    "MouthShrugLower",
    "MouthShrugUpper",
    "MouthPressLeft",
    "MouthPressRight",
    "MouthLowerDownLeft",
    "MouthLowerDownRight",
    "MouthUpperUpLeft",
    "MouthUpperUpRight",
    "BrowDownLeft",
    "BrowDownRight",
    "BrowInnerUp",
    "BrowOuterUpLeft",
    "BrowOuterUpRight",
    "CheekPuff",
    "CheekSquintLeft",
    "CheekSquintRight",
    "NoseSneerLeft",
    "NoseSneerRight",
    "TongueOut",
    "HeadYaw",
    "HeadPitch",
    "HeadRoll",
    "LeftEyeYaw",
    "LeftEyePitch",
    "LeftEyeRoll",
    "RightEyeYaw",
    "RightEyePitch",
    "RightEyeRoll",
];

/// The stream index of curve `name` (ASCII case ignored; ICT-FaceKit's spelling of a sided
/// curve too: `eyeBlink_L` is `EyeBlinkLeft`).
pub fn curve_index(name: &str) -> Option<usize> {
    let find = |name: &str| {
        CURVE_NAMES
            .iter()
            .position(|n| n.eq_ignore_ascii_case(name))
    };
    find(name).or_else(|| {
        let (base, side) = match name.strip_suffix("_L") {
            Some(b) => (b, "Left"),
            None => (name.strip_suffix("_R")?, "Right"),
        };
        find(&format!("{base}{side}"))
    })
}

/// The head rotation of yaw, pitch and roll (radians, as Live Link sends them):
/// `Quat::from_euler(YXZ, yaw, pitch, roll)`, the identity for a non-finite angle.
pub fn head_quat([yaw, pitch, roll]: [f32; 3]) -> glam::Quat {
    if yaw.is_finite() && pitch.is_finite() && roll.is_finite() {
        glam::Quat::from_euler(glam::EulerRot::YXZ, yaw, pitch, roll)
    } else {
        glam::Quat::IDENTITY
    }
}

/// Yaw, pitch and roll (radians) of a head rotation, the inverse of [`head_quat`].
pub fn head_angles(q: glam::Quat) -> [f32; 3] {
    let (yaw, pitch, roll) = q.normalize().to_euler(glam::EulerRot::YXZ);
    [yaw, pitch, roll]
}

/// One Live Link Face packet.
#[derive(Clone, Debug, PartialEq)]
pub struct LiveLinkPacket {
    /// The device's id (a UUID string in the app).
    pub device_id: String,
    /// The subject name set in the app.
    pub subject: String,
    /// Frame number of the frame time.
    pub frame: i32,
    /// Fraction of a frame.
    pub subframe: f32,
    /// Frame rate numerator (e.g. 60).
    pub rate_numerator: i32,
    /// Frame rate denominator (e.g. 1).
    pub rate_denominator: i32,
    /// The 61 curves in [`CURVE_NAMES`] order.
    pub curves: [f32; CURVES],
}

impl LiveLinkPacket {
    /// Head yaw, pitch and roll (radians).
    pub fn head_rotation(&self) -> [f32; 3] {
        [
            self.curves[HEAD_YAW],
            self.curves[HEAD_YAW + 1],
            self.curves[HEAD_YAW + 2],
        ]
    }

    /// The frame time in microseconds (frame + sub-frame at the packet's rate), or `None` when
    /// the rate is not positive.
    pub fn time_us(&self) -> Option<i64> {
        if self.rate_numerator <= 0 || self.rate_denominator <= 0 {
            return None;
        }
        let frames = f64::from(self.frame) + f64::from(self.subframe);
        let s = frames * f64::from(self.rate_denominator) / f64::from(self.rate_numerator);
        s.is_finite().then(|| (s * 1e6).round() as i64)
    }
}

/// Big-endian reader over a packet that names the byte of each problem.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], PacketError> {
        let s = self.bytes.get(self.at..self.at + n).ok_or_else(|| {
            PacketError::new(
                self.at,
                format!(
                    "{what}: {n} bytes needed, {} left",
                    self.bytes.len() - self.at.min(self.bytes.len())
                ),
            )
        })?;
        self.at += n;
        Ok(s)
    }
    fn four(&mut self, what: &str) -> Result<[u8; 4], PacketError> {
        let mut b = [0u8; 4];
        b.copy_from_slice(self.take(4, what)?);
        Ok(b)
    }
    fn string(&mut self, what: &str) -> Result<String, PacketError> {
        let at = self.at;
        let n = u32::from_be_bytes(self.four(what)?) as usize;
        if n > MAX_NAME_BYTES {
            return Err(PacketError::new(
                at,
                format!("{what} length {n} is over {MAX_NAME_BYTES} bytes"),
            ));
        }
        let at = self.at;
        let b = self.take(n, what)?;
        String::from_utf8(b.to_vec())
            .map_err(|_| PacketError::new(at, format!("{what} is not UTF-8")))
    }
}

/// Decodes one Live Link Face packet; the whole packet must be used.
pub fn decode_packet(packet: &[u8]) -> Result<LiveLinkPacket, PacketError> {
    let mut r = Reader {
        bytes: packet,
        at: 0,
    };
    let version = r.take(1, "version")?[0];
    if version != PACKET_VERSION {
        return Err(PacketError::new(
            0,
            format!("packet version {version}, expected {PACKET_VERSION}"),
        ));
    }
    let device_id = r.string("device id")?;
    let subject = r.string("subject name")?;
    let frame = i32::from_be_bytes(r.four("frame number")?);
    let subframe = f32::from_be_bytes(r.four("sub-frame")?);
    let rate_numerator = i32::from_be_bytes(r.four("frame rate numerator")?);
    let rate_denominator = i32::from_be_bytes(r.four("frame rate denominator")?);
    let count_at = r.at;
    let count = r.take(1, "curve count")?[0] as usize;
    if count != CURVES {
        return Err(PacketError::new(
            count_at,
            format!("{count} curves, expected {CURVES}"),
        ));
    }
    let mut curves = [0.0f32; CURVES];
    for (i, c) in curves.iter_mut().enumerate() {
        *c = f32::from_be_bytes(r.four(CURVE_NAMES[i])?);
    }
    if r.at != packet.len() {
        return Err(PacketError::new(
            r.at,
            format!("{} bytes after the last curve", packet.len() - r.at),
        ));
    }
    Ok(LiveLinkPacket {
        device_id,
        subject,
        frame,
        subframe,
        rate_numerator,
        rate_denominator,
        curves,
    })
}

/// Encodes a packet as the app sends it.
pub fn encode_packet(p: &LiveLinkPacket) -> Vec<u8> {
    let mut out = Vec::with_capacity(1 + 8 + p.device_id.len() + p.subject.len() + 17 + 4 * CURVES);
    out.push(PACKET_VERSION);
    for s in [&p.device_id, &p.subject] {
        out.extend_from_slice(&(s.len() as u32).to_be_bytes());
        out.extend_from_slice(s.as_bytes());
    }
    out.extend_from_slice(&p.frame.to_be_bytes());
    out.extend_from_slice(&p.subframe.to_be_bytes());
    out.extend_from_slice(&p.rate_numerator.to_be_bytes());
    out.extend_from_slice(&p.rate_denominator.to_be_bytes());
    out.push(CURVES as u8);
    for c in &p.curves {
        out.extend_from_slice(&c.to_be_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn packet() -> LiveLinkPacket {
        let mut curves = [0.0; CURVES];
        curves[17] = 0.25;
        curves[HEAD_YAW] = 0.1;
        LiveLinkPacket {
            device_id: "9A1B7D4E-0000-4000-8000-000000000001".into(),
            subject: "iPhone".into(),
            frame: 1234,
            subframe: 0.5,
            rate_numerator: 60,
            rate_denominator: 1,
            curves,
        }
    }

    #[test]
    fn ict_spellings_name_sided_curves() {
        let at = |n: &str| curve_index(n).map(|k| CURVE_NAMES[k]);
        assert_eq!(at("eyeBlink_L"), Some("EyeBlinkLeft"));
        assert_eq!(at("mouthSmile_R"), Some("MouthSmileRight"));
        assert_eq!(at("jawLeft"), Some("JawLeft"));
        // ARKit's one browInnerUp has no sided curve; a half is no curve.
        assert_eq!(at("browInnerUp_L"), None);
        assert_eq!(at("_L"), None);
    }

    #[test]
    fn round_trip_and_layout() {
        let p = packet();
        let bytes = encode_packet(&p);
        assert_eq!(bytes.len(), 1 + 4 + 36 + 4 + 6 + 16 + 1 + 4 * CURVES);
        assert_eq!(bytes[0], 6);
        // The device id's big-endian length: the `$` (36) PyLiveLinkFace takes as part of its id.
        assert_eq!(&bytes[1..5], &[0, 0, 0, 36]);
        assert_eq!(decode_packet(&bytes).unwrap(), p);
        assert_eq!(curve_index("jawopen"), Some(17));
        assert_eq!(p.time_us(), Some((1234.5f64 / 60.0 * 1e6).round() as i64));
        assert_eq!(p.head_rotation(), [0.1, 0.0, 0.0]);
    }

    #[test]
    fn head_angles_invert_head_quat() {
        for a in [[0.3f32, -0.2, 0.1], [0.0, 0.0, 0.0], [-1.2, 0.7, -0.4]] {
            let back = head_angles(head_quat(a));
            for (x, y) in a.iter().zip(back) {
                assert!((x - y).abs() <= 1e-5, "{a:?} -> {back:?}");
            }
        }
        assert_eq!(head_quat([f32::NAN, 0.0, 0.0]), glam::Quat::IDENTITY);
    }

    #[test]
    fn errors_name_the_byte() {
        let bytes = encode_packet(&packet());
        let e = decode_packet(&bytes[..bytes.len() - 2]).unwrap_err();
        assert_eq!(e.offset, bytes.len() - 4);
        let mut long = bytes.clone();
        long.push(0);
        assert_eq!(decode_packet(&long).unwrap_err().offset, bytes.len());
        let mut v5 = bytes;
        v5[0] = 5;
        assert_eq!(decode_packet(&v5).unwrap_err().offset, 0);
    }
}
