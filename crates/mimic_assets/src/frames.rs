//! The compact binary file of deformed frames that `mimic replay --format bin` writes.
//!
//! Layout (little-endian), specified in `docs/frames-format.md`:
//! header `b"MIMICFRM"`, u32 version (1), u32 vertex count n, u32 triangle count t, u32 flags
//! (bit 0: normals present), then t x 3 u32 vertex indices; then per frame: i64 timestamp (µs),
//! u32 status (0 calibrating, 1 tracked, 2 lost), f32 x 8 head pose (quaternion x y z w,
//! translation x y z, scale), f32 x 3n positions, and if flagged f32 x 3n normals.

use glam::{Quat, Vec3};
use mimic_types::HeadPose;
use std::io::{self, Read, Write};

/// File magic.
pub const FRAMES_MAGIC: &[u8; 8] = b"MIMICFRM";
/// Format version written.
pub const FRAMES_VERSION: u32 = 1;

/// One decoded frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameRecord {
    /// Timestamp (µs).
    pub timestamp_us: i64,
    /// 0 calibrating, 1 tracked, 2 lost.
    pub status: u32,
    /// Head pose of the performer.
    pub pose: HeadPose,
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Vertex normals (empty if the file has none).
    pub normals: Vec<Vec3>,
}

/// Writes a frames file; one `write_frame` per deformed frame.
pub struct FramesWriter<W: Write> {
    out: W,
    vertex_count: usize,
    normals: bool,
}

fn put_f32s(out: &mut impl Write, v: &[Vec3]) -> io::Result<()> {
    for p in v {
        for c in p.to_array() {
            out.write_all(&c.to_le_bytes())?;
        }
    }
    Ok(())
}

impl<W: Write> FramesWriter<W> {
    /// Writes the header and triangles.
    pub fn new(
        mut out: W,
        vertex_count: usize,
        triangles: &[[u32; 3]],
        normals: bool,
    ) -> io::Result<Self> {
        let too_big = |_| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                "mesh too large for the frames format",
            )
        };
        out.write_all(FRAMES_MAGIC)?;
        out.write_all(&FRAMES_VERSION.to_le_bytes())?;
        out.write_all(&u32::try_from(vertex_count).map_err(too_big)?.to_le_bytes())?;
        out.write_all(
            &u32::try_from(triangles.len())
                .map_err(too_big)?
                .to_le_bytes(),
        )?;
        out.write_all(&u32::from(normals).to_le_bytes())?;
        for t in triangles {
            for i in t {
                out.write_all(&i.to_le_bytes())?;
            }
        }
        Ok(Self {
            out,
            vertex_count,
            normals,
        })
    }

    /// Appends one frame; `normals` is ignored unless the header announced normals.
    pub fn write_frame(
        &mut self,
        timestamp_us: i64,
        status: u32,
        pose: &HeadPose,
        positions: &[Vec3],
        normals: &[Vec3],
    ) -> io::Result<()> {
        if positions.len() != self.vertex_count
            || (self.normals && normals.len() != self.vertex_count)
        {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "frame size differs from the header",
            ));
        }
        self.out.write_all(&timestamp_us.to_le_bytes())?;
        self.out.write_all(&status.to_le_bytes())?;
        let q = pose.rotation;
        let t = pose.translation;
        for c in [q.x, q.y, q.z, q.w, t.x, t.y, t.z, pose.scale] {
            self.out.write_all(&c.to_le_bytes())?;
        }
        put_f32s(&mut self.out, positions)?;
        if self.normals {
            put_f32s(&mut self.out, normals)?;
        }
        Ok(())
    }

    /// Flushes and returns the writer.
    pub fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

/// Reads a frames file back (for tests and tools).
pub struct FramesReader<R: Read> {
    input: R,
    /// Vertex count from the header.
    pub vertex_count: usize,
    /// Triangles from the header.
    pub triangles: Vec<[u32; 3]>,
    /// Whether frames carry normals.
    pub normals: bool,
}

fn get<const N: usize>(r: &mut impl Read) -> io::Result<[u8; N]> {
    let mut b = [0u8; N];
    r.read_exact(&mut b)?;
    Ok(b)
}

fn get_u32(r: &mut impl Read) -> io::Result<u32> {
    Ok(u32::from_le_bytes(get::<4>(r)?))
}

fn get_vec3s(r: &mut impl Read, n: usize) -> io::Result<Vec<Vec3>> {
    (0..n)
        .map(|_| {
            let b = get::<12>(r)?;
            let f = |k: usize| f32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]);
            Ok(Vec3::new(f(0), f(4), f(8)))
        })
        .collect()
}

impl<R: Read> FramesReader<R> {
    /// Reads and checks the header.
    pub fn new(mut input: R) -> io::Result<Self> {
        let bad = |m: &str| io::Error::new(io::ErrorKind::InvalidData, m.to_string());
        if &get::<8>(&mut input)? != FRAMES_MAGIC {
            return Err(bad("not a mimic frames file (bad magic)"));
        }
        let version = get_u32(&mut input)?;
        if version != FRAMES_VERSION {
            return Err(bad(&format!(
                "frames format version {version}, expected {FRAMES_VERSION}"
            )));
        }
        let vertex_count = get_u32(&mut input)? as usize;
        let tri_count = get_u32(&mut input)? as usize;
        let normals = get_u32(&mut input)? & 1 == 1;
        let mut triangles = Vec::with_capacity(tri_count.min(1 << 24));
        for _ in 0..tri_count {
            triangles.push([
                get_u32(&mut input)?,
                get_u32(&mut input)?,
                get_u32(&mut input)?,
            ]);
        }
        Ok(Self {
            input,
            vertex_count,
            triangles,
            normals,
        })
    }

    /// The next frame; `None` at a clean end of file.
    pub fn next_frame(&mut self) -> io::Result<Option<FrameRecord>> {
        let mut t = [0u8; 8];
        match self.input.read_exact(&mut t) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => return Ok(None),
            Err(e) => return Err(e),
        }
        let status = get_u32(&mut self.input)?;
        let mut pose = [0f32; 8];
        for p in &mut pose {
            *p = f32::from_le_bytes(get::<4>(&mut self.input)?);
        }
        let positions = get_vec3s(&mut self.input, self.vertex_count)?;
        let normals = if self.normals {
            get_vec3s(&mut self.input, self.vertex_count)?
        } else {
            Vec::new()
        };
        Ok(Some(FrameRecord {
            timestamp_us: i64::from_le_bytes(t),
            status,
            pose: HeadPose {
                rotation: Quat::from_xyzw(pose[0], pose[1], pose[2], pose[3]),
                translation: Vec3::new(pose[4], pose[5], pose[6]),
                scale: pose[7],
            },
            positions,
            normals,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_exactly() {
        let tris = [[0u32, 1, 2]];
        let pos = [
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(-1.5, 0.25, 1e-7),
            Vec3::Z,
        ];
        let nrm = [Vec3::Z, Vec3::Y, Vec3::X];
        let pose = HeadPose {
            rotation: Quat::from_rotation_y(0.3),
            translation: Vec3::X,
            scale: 1.0,
        };
        let mut w = FramesWriter::new(Vec::new(), 3, &tris, true).unwrap();
        w.write_frame(42, 1, &pose, &pos, &nrm).unwrap();
        w.write_frame(84, 2, &pose, &pos, &nrm).unwrap();
        let bytes = w.finish().unwrap();
        // 24-byte header + 12 bytes of triangle + 2 frames of (8 + 4 + 32 + 2 * 36).
        assert_eq!(bytes.len(), 24 + 12 + 2 * (8 + 4 + 32 + 72));
        let mut r = FramesReader::new(bytes.as_slice()).unwrap();
        assert_eq!(r.triangles, tris.to_vec());
        let f = r.next_frame().unwrap().unwrap();
        assert_eq!((f.timestamp_us, f.status), (42, 1));
        assert_eq!(f.positions, pos.to_vec());
        assert_eq!(f.normals, nrm.to_vec());
        assert_eq!(f.pose, pose);
        assert_eq!(r.next_frame().unwrap().unwrap().timestamp_us, 84);
        assert!(r.next_frame().unwrap().is_none());
    }

    #[test]
    fn rejects_other_files() {
        assert!(FramesReader::new(&b"NOTMIMIC\x01\0\0\0"[..]).is_err());
        let mut w = FramesWriter::new(Vec::new(), 3, &[], false).unwrap();
        let e = w
            .write_frame(0, 1, &HeadPose::IDENTITY, &[Vec3::ZERO], &[])
            .unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
    }
}
