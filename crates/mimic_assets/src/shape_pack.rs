//! Shape packs (`*.shapes`): many blend shapes of one mesh as sparse, quantized position
//! deltas in one small binary file (the ICT expression set, 57 shapes of 26 719 vertices, in
//! about 2.5 MB where the morph data file would take 80 MB).
//!
//! Layout (little-endian, unsigned LEB128 varints, signed values zigzag-coded):
//! the magic [`SHAPE_PACK_MAGIC`]; varint vertex count; varint shape count; `f32` quantum `q`;
//! then per shape: varint name length, the UTF-8 name, varint count of moved vertices, and per
//! moved vertex (ascending) a varint gap to the previous one (`index - previous - 1`, the first
//! counts from -1) and three zigzag varints `round(delta / q)`. A vertex every component of which
//! rounds to 0 is left out, so every component comes back within `q / 2` ([`pack_tolerance`]).

use crate::AssetError;
use glam::Vec3;
use mimic_types::limits;
use std::io::{Read, Write};
use std::path::Path;

/// The first bytes of a shape pack.
pub const SHAPE_PACK_MAGIC: &[u8] = b"mimic shapes 1\n";

/// One shape of a pack: its name and a position delta per vertex of the mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct PackedShape {
    /// The shape's name (no whitespace).
    pub name: String,
    /// Position delta of every vertex against the neutral.
    pub deltas: Vec<Vec3>,
}

/// Blend shapes of one mesh, with the quantum their deltas are stored in.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapePack {
    /// Vertices of the mesh (the length of every shape's deltas).
    pub vertex_count: usize,
    /// Step the deltas are rounded to, mesh units.
    pub quantum: f32,
    /// The shapes, in file order.
    pub shapes: Vec<PackedShape>,
}

impl ShapePack {
    /// The shape named `name`.
    pub fn get(&self, name: &str) -> Option<&PackedShape> {
        self.shapes.iter().find(|s| s.name == name)
    }
}

/// Largest component difference a delta `v` may show after a round trip through a pack of
/// quantum `q`: half the quantum plus two f32 ulps of the value.
pub fn pack_tolerance(q: f32, v: f32) -> f32 {
    0.5 * q + 2.0 * (v.abs() + q) * f32::EPSILON
}

fn put_varint(w: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        w.push((v as u8 & 0x7f) | 0x80);
        v >>= 7;
    }
    w.push(v as u8);
}

/// Writes `pack` (deltas rounded to its quantum).
///
/// # Panics
/// If a shape's delta count differs from the vertex count, or the quantum is not positive.
pub fn write_shape_pack<W: Write>(mut w: W, pack: &ShapePack) -> std::io::Result<()> {
    let q = f64::from(pack.quantum);
    assert!(q > 0.0, "write_shape_pack: quantum {q}");
    let mut out = SHAPE_PACK_MAGIC.to_vec();
    put_varint(&mut out, pack.vertex_count as u64);
    put_varint(&mut out, pack.shapes.len() as u64);
    out.extend_from_slice(&pack.quantum.to_le_bytes());
    for s in &pack.shapes {
        assert_eq!(
            s.deltas.len(),
            pack.vertex_count,
            "write_shape_pack: {}",
            s.name
        );
        put_varint(&mut out, s.name.len() as u64);
        out.extend_from_slice(s.name.as_bytes());
        let rounded: Vec<(usize, [i64; 3])> = s
            .deltas
            .iter()
            .map(|d| d.to_array().map(|x| (f64::from(x) / q).round() as i64))
            .enumerate()
            .filter(|(_, r)| r.iter().any(|x| *x != 0))
            .collect();
        put_varint(&mut out, rounded.len() as u64);
        let mut next = 0usize;
        for (v, r) in rounded {
            put_varint(&mut out, (v - next) as u64);
            next = v + 1;
            for x in r {
                put_varint(&mut out, ((x << 1) ^ (x >> 63)) as u64);
            }
        }
    }
    w.write_all(&out)?;
    w.flush()
}

/// Reads a shape pack from its bytes; `path` names it in errors.
pub fn read_shape_pack(bytes: &[u8], path: &Path) -> Result<ShapePack, AssetError> {
    let mut r = Cursor { bytes, at: 0, path };
    if !bytes.starts_with(SHAPE_PACK_MAGIC) {
        return Err(r.error("not a shape pack (no `mimic shapes 1` header)"));
    }
    r.at = SHAPE_PACK_MAGIC.len();
    let n = r.count(limits::MAX_MESH_VERTICES, "vertices")?;
    let k = r.count(limits::MAX_MORPH_TARGETS, "shapes")?;
    let quantum = f32::from_le_bytes(r.take(4)?.try_into().unwrap_or_default());
    if !(quantum.is_finite() && quantum > 0.0) {
        return Err(r.error(&format!("quantum {quantum} is not a positive number")));
    }
    let mut shapes: Vec<PackedShape> = Vec::with_capacity(k);
    for _ in 0..k {
        let len = r.count(256, "name bytes")?;
        let name = std::str::from_utf8(r.take(len)?)
            .ok()
            .filter(|s| !s.is_empty() && !s.contains(char::is_whitespace))
            .map(str::to_string);
        let name =
            name.ok_or_else(|| r.error("a shape name is empty, has spaces or is not UTF-8"))?;
        if shapes.iter().any(|s| s.name == name) {
            return Err(r.error(&format!("shape `{name}` appears twice")));
        }
        let moved = r.count(n, "moved vertices")?;
        let mut deltas = vec![Vec3::ZERO; n];
        let mut next = 0usize;
        for _ in 0..moved {
            let v = next.saturating_add(r.count(n, "vertex gap")?);
            let slot = deltas
                .get_mut(v)
                .ok_or_else(|| r.error(&format!("shape `{name}`: vertex {v} of {n}")))?;
            let mut c = [0f32; 3];
            for x in &mut c {
                let z = r.varint()?;
                let i = (z >> 1) as i64 ^ -((z & 1) as i64);
                *x = (i as f64 * f64::from(quantum)) as f32;
            }
            *slot = Vec3::from_array(c);
            next = v + 1;
        }
        shapes.push(PackedShape { name, deltas });
    }
    if r.at != bytes.len() {
        return Err(r.error("bytes after the last shape"));
    }
    Ok(ShapePack {
        vertex_count: n,
        quantum,
        shapes,
    })
}

/// Reads the shape pack at `path` (capped as morph data files are).
pub fn load_shape_pack(path: &Path) -> Result<ShapePack, AssetError> {
    let mut bytes = Vec::new();
    crate::read::open_capped(path, &limits::MORPH_FILE)?
        .read_to_end(&mut bytes)
        .map_err(|e| AssetError::io(path, e))?;
    read_shape_pack(&bytes, path)
}

/// Writes `pack` to `path`.
pub fn save_shape_pack(path: &Path, pack: &ShapePack) -> Result<(), AssetError> {
    let file = std::fs::File::create(path).map_err(|e| AssetError::io(path, e))?;
    write_shape_pack(std::io::BufWriter::new(file), pack).map_err(|e| AssetError::io(path, e))
}

/// A reader over a pack's bytes that names the file and offset in its errors.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
    path: &'a Path,
}

impl Cursor<'_> {
    fn error(&self, message: &str) -> AssetError {
        AssetError::ShapePack {
            path: self.path.to_path_buf(),
            offset: self.at,
            message: message.to_string(),
        }
    }

    fn take(&mut self, len: usize) -> Result<&[u8], AssetError> {
        let end = self.at.saturating_add(len);
        let slice = self
            .bytes
            .get(self.at..end)
            .ok_or_else(|| self.error("the file ends early"))?;
        self.at = end;
        Ok(slice)
    }

    fn varint(&mut self) -> Result<u64, AssetError> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let b = self.take(1)?[0];
            v |= u64::from(b & 0x7f) << shift;
            if b < 0x80 {
                return Ok(v);
            }
        }
        Err(self.error("a number runs over 64 bits"))
    }

    fn count(&mut self, max: usize, what: &str) -> Result<usize, AssetError> {
        let v = self.varint()?;
        usize::try_from(v)
            .ok()
            .filter(|v| *v <= max)
            .ok_or_else(|| self.error(&format!("{v} {what}, over the maximum of {max}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pack() -> ShapePack {
        // Deltas over many magnitudes, both signs, some vertices still.
        let n = 500;
        let shape = |s: f32| PackedShape {
            name: format!("s{s}"),
            deltas: (0..n)
                .map(|i| {
                    let t = i as f32;
                    if i % 7 == 0 {
                        Vec3::ZERO
                    } else {
                        Vec3::new(s * (t * 0.37).sin(), 1e-5 * t, -s * t * t * 1e-4)
                    }
                })
                .collect(),
        };
        ShapePack {
            vertex_count: n,
            quantum: 1e-4,
            shapes: vec![shape(0.5), shape(3.0), shape(-20.0)],
        }
    }

    #[test]
    fn a_round_trip_keeps_every_component_within_half_the_quantum() {
        let p = pack();
        let mut bytes = Vec::new();
        write_shape_pack(&mut bytes, &p).unwrap();
        let back = read_shape_pack(&bytes, Path::new("t.shapes")).unwrap();
        assert_eq!(
            (back.vertex_count, back.quantum),
            (p.vertex_count, p.quantum)
        );
        let mut worst = 0f32;
        for (a, b) in p.shapes.iter().zip(&back.shapes) {
            assert_eq!(a.name, b.name);
            for (x, y) in a.deltas.iter().zip(&b.deltas) {
                for (x, y) in x.to_array().into_iter().zip(y.to_array()) {
                    assert!((x - y).abs() <= pack_tolerance(p.quantum, x), "{x} vs {y}");
                    worst = worst.max((x - y).abs());
                }
            }
        }
        assert!(worst > 0.0 && worst <= 0.5 * p.quantum + 1e-6, "{worst}");
        // Writing what was read gives the same bytes.
        let mut again = Vec::new();
        write_shape_pack(&mut again, &back).unwrap();
        assert_eq!(again, bytes);
    }

    #[test]
    fn cut_or_broken_packs_are_refused_with_the_offset() {
        let mut bytes = Vec::new();
        write_shape_pack(&mut bytes, &pack()).unwrap();
        let path = Path::new("t.shapes");
        for cut in [
            3,
            SHAPE_PACK_MAGIC.len() + 2,
            bytes.len() / 2,
            bytes.len() - 1,
        ] {
            let e = read_shape_pack(&bytes[..cut], path)
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("t.shapes: byte "), "{e}");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        let e = read_shape_pack(&longer, path).unwrap_err().to_string();
        assert!(e.ends_with("bytes after the last shape"), "{e}");
    }
}
