//! Little-endian reading and writing of binary packets, and why a packet does not decode.

use glam::{Quat, Vec3};

/// Why a viewer message or a UDP packet cannot be decoded; names the packet (and field).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// The payload ends before one of its fields does.
    #[error("{packet} is {len} bytes, too short for its field `{field}`")]
    Short {
        /// The packet, e.g. `FRAME message`.
        packet: &'static str,
        /// The field it ends in (or whose count it cannot hold).
        field: &'static str,
        /// Payload bytes.
        len: usize,
    },
    /// Unknown kind byte.
    #[error("unknown message kind {0}")]
    Kind(u8),
    /// A JSON part that does not parse.
    #[error("bad JSON in {packet}: {message}")]
    Json {
        /// The packet, e.g. `SESSION message`.
        packet: &'static str,
        /// What the JSON parser said.
        message: String,
    },
    /// Wrong magic in a UDP packet.
    #[error("not a mimic frame packet (magic)")]
    Magic,
    /// A UDP packet whose size does not match its point count.
    #[error("UDP frame packet is {len} bytes; {points} points need {expected}")]
    Size {
        /// Packet bytes.
        len: usize,
        /// Points the packet says it has.
        points: usize,
        /// Bytes that needs.
        expected: usize,
    },
    /// A UDP point with an infinite coordinate.
    #[error("UDP frame packet: point {0} has an infinite coordinate")]
    Infinite(usize),
}

/// Little-endian cursor over the payload of one packet.
pub(crate) struct Cursor<'a> {
    b: &'a [u8],
    at: usize,
    packet: &'static str,
}

impl<'a> Cursor<'a> {
    /// A cursor at the start of `b`, a `packet` (named in errors).
    pub(crate) fn new(b: &'a [u8], packet: &'static str) -> Self {
        Self { b, at: 0, packet }
    }

    /// The error of a payload too short for `field`.
    pub(crate) fn short(&self, field: &'static str) -> DecodeError {
        DecodeError::Short {
            packet: self.packet,
            field,
            len: self.b.len(),
        }
    }

    /// The next `k` bytes, field `field`.
    pub(crate) fn take(&mut self, k: usize, field: &'static str) -> Result<&'a [u8], DecodeError> {
        let s = self
            .b
            .get(self.at..self.at.saturating_add(k))
            .ok_or_else(|| self.short(field))?;
        self.at += k;
        Ok(s)
    }

    /// The next `K` bytes as an array.
    pub(crate) fn arr<const K: usize>(
        &mut self,
        field: &'static str,
    ) -> Result<[u8; K], DecodeError> {
        let mut a = [0u8; K];
        a.copy_from_slice(self.take(K, field)?);
        Ok(a)
    }

    /// A byte.
    pub(crate) fn u8(&mut self, field: &'static str) -> Result<u8, DecodeError> {
        Ok(self.arr::<1>(field)?[0])
    }

    /// A `u32`.
    pub(crate) fn u32(&mut self, field: &'static str) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.arr(field)?))
    }

    /// A `u32` count of items that follow; refused when the payload cannot hold that many.
    pub(crate) fn count(&mut self, field: &'static str) -> Result<usize, DecodeError> {
        let k = self.u32(field)? as usize;
        // Every counted item takes at least 4 bytes: refuse counts the payload cannot hold.
        if k > self.b.len() {
            return Err(self.short(field));
        }
        Ok(k)
    }

    /// A `u64`.
    pub(crate) fn u64(&mut self, field: &'static str) -> Result<u64, DecodeError> {
        Ok(u64::from_le_bytes(self.arr(field)?))
    }

    /// An `i64`.
    pub(crate) fn i64(&mut self, field: &'static str) -> Result<i64, DecodeError> {
        Ok(i64::from_le_bytes(self.arr(field)?))
    }

    /// An `f32`.
    pub(crate) fn f32(&mut self, field: &'static str) -> Result<f32, DecodeError> {
        Ok(f32::from_le_bytes(self.arr(field)?))
    }

    /// Three `f32`.
    pub(crate) fn vec3(&mut self, field: &'static str) -> Result<Vec3, DecodeError> {
        Ok(Vec3::new(
            self.f32(field)?,
            self.f32(field)?,
            self.f32(field)?,
        ))
    }

    /// Four `f32`, `x y z w`.
    pub(crate) fn quat(&mut self, field: &'static str) -> Result<Quat, DecodeError> {
        Ok(Quat::from_xyzw(
            self.f32(field)?,
            self.f32(field)?,
            self.f32(field)?,
            self.f32(field)?,
        ))
    }

    /// `k` `f32`.
    pub(crate) fn f32s(&mut self, k: usize, field: &'static str) -> Result<Vec<f32>, DecodeError> {
        let bytes = k.checked_mul(4).ok_or_else(|| self.short(field))?;
        Ok(self
            .take(bytes, field)?
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect())
    }

    /// `k` points of three `f32`.
    pub(crate) fn vec3s(
        &mut self,
        k: usize,
        field: &'static str,
    ) -> Result<Vec<Vec3>, DecodeError> {
        let floats = k.checked_mul(3).ok_or_else(|| self.short(field))?;
        Ok(self
            .f32s(floats, field)?
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect())
    }

    /// `k` triangles of three `u32`.
    pub(crate) fn triangles(
        &mut self,
        k: usize,
        field: &'static str,
    ) -> Result<Vec<[u32; 3]>, DecodeError> {
        let bytes = k.checked_mul(12).ok_or_else(|| self.short(field))?;
        Ok(self
            .take(bytes, field)?
            .chunks_exact(12)
            .map(|b| {
                let u = |k: usize| u32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]);
                [u(0), u(4), u(8)]
            })
            .collect())
    }
}

/// Appends a point as three little-endian `f32`.
pub(crate) fn put_vec3(out: &mut Vec<u8>, v: Vec3) {
    for c in v.to_array() {
        out.extend_from_slice(&c.to_le_bytes());
    }
}
