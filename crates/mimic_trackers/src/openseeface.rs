//! OpenSeeFace's UDP datagram and the `.osf` capture container.
//!
//! One face is a 1785-byte little-endian block, packed field by field with no padding by
//! OpenSeeFace's `facetracker.py` (byte table in `docs/trackers.md`); a datagram holds one block
//! per tracked face. A `.osf` capture (ours) is a sequence of records up to EOF: u64 LE receive
//! time in microseconds since the first datagram, u32 LE length N, then the N datagram bytes.

use crate::error::{PacketError, TrackerError};
use mimic_types::limits::{FileKind, read_bytes_capped};
use std::path::Path;

/// Bytes of one face in a datagram.
pub const FACE_BYTES: usize = 1785;
/// 2D landmarks (and confidences) per face: 66 iBUG-like points and 2 pupils.
pub const POINTS_2D: usize = 68;
/// 3D points per face: the 68 landmarks and the 2 eyeball centres.
pub const POINTS_3D: usize = 70;
/// Named features per face.
pub const FEATURES: usize = 14;
/// The features, in datagram order.
pub const FEATURE_NAMES: [&str; FEATURES] = [
    "eye_l",
    "eye_r",
    "eyebrow_steepness_l",
    "eyebrow_updown_l",
    "eyebrow_quirk_l",
    "eyebrow_steepness_r",
    "eyebrow_updown_r",
    "eyebrow_quirk_r",
    "mouth_corner_updown_l",
    "mouth_corner_inout_l",
    "mouth_corner_updown_r",
    "mouth_corner_inout_r",
    "mouth_open",
    "mouth_wide",
];
/// The largest UDP payload (IPv4): a longer datagram cannot have been sent.
pub const MAX_DATAGRAM_BYTES: usize = 65_507;
/// `.osf` capture files (1797 bytes a datagram: 256 MiB is some 4 hours at 10 faces a second).
pub const OSF_FILE: FileKind = FileKind {
    what: "OpenSeeFace captures",
    max_bytes: 256 << 20,
};
/// Bytes of a `.osf` record header (receive time, length).
pub const RECORD_HEADER_BYTES: usize = 12;

/// One face of an OpenSeeFace datagram, every field as sent.
#[derive(Clone, Debug, PartialEq)]
pub struct OsfFace {
    /// `time.time()` when the frame was read (Unix seconds).
    pub timestamp: f64,
    /// Face id (stable while the face stays tracked).
    pub face_id: i32,
    /// Frame width in pixels.
    pub width: f32,
    /// Frame height in pixels.
    pub height: f32,
    /// Eye openness, 1 open, 0 closed: `[right, left]` (the subject's).
    pub eye_open: [f32; 2],
    /// 1 when the 3D fit (solvePnP) succeeded; the 3D points are all zero otherwise.
    pub success: u8,
    /// Reprojection error of the fit in pixels (99999 when it failed).
    pub pnp_error: f32,
    /// Head rotation quaternion `x, y, z, w` (OpenSeeFace's transposed image convention).
    pub quaternion: [f32; 4],
    /// Euler angles in degrees (same convention).
    pub euler: [f32; 3],
    /// Translation (solvePnP `tvec`, reference-model units).
    pub translation: [f32; 3],
    /// Confidence of landmarks 0-67 (about 0-1).
    pub confidence: [f32; POINTS_2D],
    /// 2D landmarks 0-67 in pixels, `(x, y)`: x to the right, y down.
    pub points_2d: [[f32; 2]; POINTS_2D],
    /// Pose-free 3D points 0-69 in reference-model units, as packed: x to the subject's right,
    /// y down, z away from the camera.
    pub points_3d: [[f32; 3]; POINTS_3D],
    /// The 14 features of [`FEATURE_NAMES`].
    pub features: [f32; FEATURES],
}

impl Default for OsfFace {
    fn default() -> Self {
        Self {
            timestamp: 0.0,
            face_id: 0,
            width: 0.0,
            height: 0.0,
            eye_open: [0.0; 2],
            success: 0,
            pnp_error: 0.0,
            quaternion: [0.0; 4],
            euler: [0.0; 3],
            translation: [0.0; 3],
            confidence: [0.0; POINTS_2D],
            points_2d: [[0.0; 2]; POINTS_2D],
            points_3d: [[0.0; 3]; POINTS_3D],
            features: [0.0; FEATURES],
        }
    }
}

/// Little-endian reader over one face block (its length checked by the caller).
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Cursor<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        if let Some(src) = self.bytes.get(self.at..self.at + N) {
            out.copy_from_slice(src);
        }
        self.at += N;
        out
    }
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
    fn floats<const N: usize>(&mut self) -> [f32; N] {
        std::array::from_fn(|_| self.f32())
    }
}

/// Decodes one 1785-byte face block into `out` (allocation-free).
pub fn decode_face(block: &[u8], out: &mut OsfFace) -> Result<(), PacketError> {
    if block.len() != FACE_BYTES {
        return Err(PacketError::new(
            block.len().min(FACE_BYTES),
            format!(
                "a face block is {FACE_BYTES} bytes, this one {}",
                block.len()
            ),
        ));
    }
    let mut c = Cursor {
        bytes: block,
        at: 0,
    };
    out.timestamp = f64::from_le_bytes(c.take());
    out.face_id = i32::from_le_bytes(c.take());
    out.width = c.f32();
    out.height = c.f32();
    out.eye_open = c.floats();
    out.success = c.take::<1>()[0];
    out.pnp_error = c.f32();
    out.quaternion = c.floats();
    out.euler = c.floats();
    out.translation = c.floats();
    out.confidence = c.floats();
    for p in &mut out.points_2d {
        *p = c.floats();
    }
    for p in &mut out.points_3d {
        *p = c.floats();
    }
    out.features = c.floats();
    debug_assert_eq!(c.at, FACE_BYTES);
    Ok(())
}

/// Decodes a datagram: one face per 1785-byte block (at least one).
pub fn decode_packet(packet: &[u8]) -> Result<Vec<OsfFace>, PacketError> {
    if packet.is_empty() || !packet.len().is_multiple_of(FACE_BYTES) {
        return Err(PacketError::new(
            packet.len() - packet.len() % FACE_BYTES,
            format!(
                "{} bytes is not a whole number of {FACE_BYTES}-byte faces",
                packet.len()
            ),
        ));
    }
    packet
        .chunks_exact(FACE_BYTES)
        .enumerate()
        .map(|(i, block)| {
            let mut f = OsfFace::default();
            decode_face(block, &mut f)
                .map_err(|e| PacketError::new(i * FACE_BYTES + e.offset, e.reason))?;
            Ok(f)
        })
        .collect()
}

/// Appends one face's 1785-byte block to `out`, field by field as OpenSeeFace packs it.
pub fn encode_face(face: &OsfFace, out: &mut Vec<u8>) {
    let floats = |out: &mut Vec<u8>, v: &[f32]| {
        for x in v {
            out.extend_from_slice(&x.to_le_bytes());
        }
    };
    out.extend_from_slice(&face.timestamp.to_le_bytes());
    out.extend_from_slice(&face.face_id.to_le_bytes());
    floats(out, &[face.width, face.height]);
    floats(out, &face.eye_open);
    out.push(face.success);
    floats(out, &[face.pnp_error]);
    floats(out, &face.quaternion);
    floats(out, &face.euler);
    floats(out, &face.translation);
    floats(out, &face.confidence);
    for p in &face.points_2d {
        floats(out, p);
    }
    for p in &face.points_3d {
        floats(out, p);
    }
    floats(out, &face.features);
}

/// A datagram holding `faces`, one block each.
pub fn encode_packet(faces: &[OsfFace]) -> Vec<u8> {
    let mut out = Vec::with_capacity(faces.len() * FACE_BYTES);
    for f in faces {
        encode_face(f, &mut out);
    }
    out
}

/// One record of a `.osf` capture.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OsfRecord {
    /// Receive time in microseconds since the first datagram.
    pub receive_us: u64,
    /// Byte offset of the record in the file.
    pub file_offset: u64,
    /// The datagram, byte for byte.
    pub datagram: Vec<u8>,
}

/// Why a `.osf` capture's bytes are not a capture: the record, its file offset and the reason.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CaptureProblem {
    /// 0-based record number.
    pub record: usize,
    /// Byte offset of the record in the file.
    pub file_offset: u64,
    /// What is wrong.
    pub reason: String,
}

/// Splits a `.osf` capture into its records (the datagrams are not decoded).
pub fn parse_capture(bytes: &[u8]) -> Result<Vec<OsfRecord>, CaptureProblem> {
    let mut records = Vec::new();
    let mut at = 0usize;
    while at < bytes.len() {
        let problem = |reason: String| CaptureProblem {
            record: records.len(),
            file_offset: at as u64,
            reason,
        };
        let Some(head) = bytes.get(at..at + RECORD_HEADER_BYTES) else {
            return Err(problem(format!(
                "{} bytes left, a record header is {RECORD_HEADER_BYTES}",
                bytes.len() - at
            )));
        };
        let (t, n) = head.split_at(8);
        let mut t8 = [0u8; 8];
        t8.copy_from_slice(t);
        let mut n4 = [0u8; 4];
        n4.copy_from_slice(n);
        let receive_us = u64::from_le_bytes(t8);
        let len = u32::from_le_bytes(n4) as usize;
        if len > MAX_DATAGRAM_BYTES {
            return Err(problem(format!(
                "datagram length {len} is over the UDP maximum of {MAX_DATAGRAM_BYTES}"
            )));
        }
        let start = at + RECORD_HEADER_BYTES;
        let Some(datagram) = bytes.get(start..start + len) else {
            return Err(problem(format!(
                "datagram length {len}, but only {} bytes are left",
                bytes.len() - start
            )));
        };
        if let Some(prev) = records.last().map(|r: &OsfRecord| r.receive_us)
            && receive_us < prev
        {
            return Err(problem(format!(
                "receive time {receive_us} us is before the previous record's {prev} us"
            )));
        }
        records.push(OsfRecord {
            receive_us,
            file_offset: at as u64,
            datagram: datagram.to_vec(),
        });
        at = start + len;
    }
    Ok(records)
}

/// Appends one `.osf` record (receive time, length, datagram) to `out`.
pub fn encode_record(receive_us: u64, datagram: &[u8], out: &mut Vec<u8>) {
    out.extend_from_slice(&receive_us.to_le_bytes());
    out.extend_from_slice(&(datagram.len() as u32).to_le_bytes());
    out.extend_from_slice(datagram);
}

/// Reads a `.osf` capture file (capped at [`OSF_FILE`]) into its records.
pub fn read_capture(path: &Path) -> Result<Vec<OsfRecord>, TrackerError> {
    let bytes = read_bytes_capped(path, &OSF_FILE).map_err(|source| TrackerError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_capture(&bytes).map_err(|p| TrackerError::Record {
        path: path.to_path_buf(),
        record: p.record,
        file_offset: p.file_offset,
        reason: p.reason,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_face_round_trips_byte_for_byte() {
        let mut rng = mimic_testkit::Lcg::new(7);
        let mut face = OsfFace {
            timestamp: 1796149943.4854996,
            face_id: 3,
            success: 1,
            ..OsfFace::default()
        };
        for c in &mut face.confidence {
            *c = rng.next_f32();
        }
        for p in &mut face.points_3d {
            *p = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
        }
        face.features[13] = 0.5;
        let bytes = encode_packet(&[face.clone(), face.clone()]);
        assert_eq!(bytes.len(), 2 * FACE_BYTES);
        let back = decode_packet(&bytes).unwrap();
        assert_eq!(back, vec![face.clone(), face]);
        assert_eq!(encode_packet(&back), bytes);
    }

    #[test]
    fn bad_lengths_name_the_byte() {
        let e = decode_packet(&[0u8; FACE_BYTES + 10]).unwrap_err();
        assert_eq!(e.offset, FACE_BYTES);
        assert!(decode_packet(&[]).is_err());
        let mut cap = Vec::new();
        encode_record(0, &[1, 2, 3], &mut cap);
        encode_record(5, &[4], &mut cap);
        let recs = parse_capture(&cap).unwrap();
        assert_eq!(recs.len(), 2);
        assert_eq!(recs[1].file_offset, 15);
        assert_eq!(recs[1].datagram, vec![4]);
        cap.pop();
        let p = parse_capture(&cap).unwrap_err();
        assert_eq!((p.record, p.file_offset), (1, 15));
    }
}
