//! Accessor data, bounds-checked: an accessor's elements as floats (normalized integers scaled
//! to 0..1 or -1..1) or as unsigned integers (indices, joints), with sparse substitution.

use super::AvatarError;
use gltf::accessor::{DataType, Dimensions};
use std::path::Path;

/// The most elements one accessor may have (16 Mi; a view-less accessor would allocate them).
pub(crate) const MAX_ACCESSOR_ELEMENTS: usize = 1 << 24;

/// Components per element.
pub(crate) fn dims(d: Dimensions) -> usize {
    match d {
        Dimensions::Scalar => 1,
        Dimensions::Vec2 => 2,
        Dimensions::Vec3 => 3,
        Dimensions::Vec4 | Dimensions::Mat2 => 4,
        Dimensions::Mat3 => 9,
        Dimensions::Mat4 => 16,
    }
}

fn size(t: DataType) -> usize {
    match t {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    }
}

/// One component as a float (normalized integers scaled as glTF says).
fn float(t: DataType, normalized: bool, b: &[u8]) -> f32 {
    match (t, normalized) {
        (DataType::F32, _) => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        (DataType::U8, true) => f32::from(b[0]) / 255.0,
        (DataType::U8, false) => f32::from(b[0]),
        (DataType::I8, true) => (f32::from(b[0] as i8) / 127.0).max(-1.0),
        (DataType::I8, false) => f32::from(b[0] as i8),
        (DataType::U16, n) => {
            let v = f32::from(u16::from_le_bytes([b[0], b[1]]));
            if n { v / 65535.0 } else { v }
        }
        (DataType::I16, n) => {
            let v = f32::from(i16::from_le_bytes([b[0], b[1]]));
            if n { (v / 32767.0).max(-1.0) } else { v }
        }
        (DataType::U32, _) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
    }
}

/// One component as an unsigned integer (None for signed or float components).
fn unsigned(t: DataType, b: &[u8]) -> Option<u32> {
    match t {
        DataType::U8 => Some(u32::from(b[0])),
        DataType::U16 => Some(u32::from(u16::from_le_bytes([b[0], b[1]]))),
        DataType::U32 => Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        _ => None,
    }
}

/// Reads accessor data with `component` per component.
pub(crate) struct Reader<'a> {
    /// The avatar file (for errors).
    pub path: &'a Path,
    /// The buffers' bytes.
    pub buffers: &'a [Vec<u8>],
}

impl Reader<'_> {
    fn err(&self, pointer: String, message: impl Into<String>) -> AvatarError {
        AvatarError::at(self.path, pointer, message)
    }

    /// The bytes of `count` elements of `element` bytes at `offset` of `view`, stride respected:
    /// one slice per element.
    fn elements<'b>(
        &'b self,
        view: &gltf::buffer::View<'_>,
        offset: usize,
        count: usize,
        element: usize,
        pointer: &str,
    ) -> Result<Vec<&'b [u8]>, AvatarError> {
        let data = self
            .buffers
            .get(view.buffer().index())
            .and_then(|b| b.get(view.offset()..view.offset().checked_add(view.length())?))
            .ok_or_else(|| {
                self.err(
                    format!("/bufferViews/{}", view.index()),
                    "lies outside its buffer",
                )
            })?;
        let stride = view.stride().unwrap_or(element);
        if stride < element {
            return Err(self.err(
                format!("/bufferViews/{}/byteStride", view.index()),
                format!("stride {stride} is less than the {element}-byte element"),
            ));
        }
        (0..count)
            .map(|i| {
                i.checked_mul(stride)
                    .and_then(|at| at.checked_add(offset))
                    .and_then(|at| data.get(at..at.checked_add(element)?))
                    .ok_or_else(|| {
                        self.err(
                            pointer.to_string(),
                            format!(
                                "element {i} lies past the end of buffer view {}",
                                view.index()
                            ),
                        )
                    })
            })
            .collect()
    }

    /// Every component of `acc` converted by `f`, `dims` per element, sparse values applied.
    fn read<T: Copy + Default>(
        &self,
        acc: &gltf::Accessor<'_>,
        f: &dyn Fn(&[u8]) -> Option<T>,
    ) -> Result<Vec<T>, AvatarError> {
        let at = format!("/accessors/{}", acc.index());
        let n = dims(acc.dimensions());
        let c = size(acc.data_type());
        if c < 4 && matches!(acc.dimensions(), Dimensions::Mat2 | Dimensions::Mat3) {
            return Err(self.err(
                at,
                "matrices of 1- or 2-byte components (padded columns) are not read",
            ));
        }
        let count = acc.count();
        if count > MAX_ACCESSOR_ELEMENTS {
            return Err(self.err(
                format!("{at}/count"),
                format!("{count} elements, more than the {MAX_ACCESSOR_ELEMENTS} mimic reads"),
            ));
        }
        let bad = |pointer: String| self.err(pointer, "component type not allowed here");
        let mut out = vec![T::default(); count * n];
        if let Some(view) = acc.view() {
            for (i, e) in self
                .elements(&view, acc.offset(), count, n * c, &at)?
                .into_iter()
                .enumerate()
            {
                for k in 0..n {
                    out[i * n + k] = f(&e[k * c..(k + 1) * c])
                        .ok_or_else(|| bad(format!("{at}/componentType")))?;
                }
            }
        }
        if let Some(sparse) = acc.sparse() {
            let sp = format!("{at}/sparse");
            let m = sparse.count();
            if m > count {
                return Err(self.err(
                    format!("{sp}/count"),
                    format!("{m} sparse values for {count} elements"),
                ));
            }
            let idx = sparse.indices();
            let isize_ = match idx.index_type() {
                gltf::accessor::sparse::IndexType::U8 => 1,
                gltf::accessor::sparse::IndexType::U16 => 2,
                gltf::accessor::sparse::IndexType::U32 => 4,
            };
            let index_bytes = self.elements(
                &idx.view(),
                idx.offset(),
                m,
                isize_,
                &format!("{sp}/indices"),
            )?;
            let values = sparse.values();
            let value_bytes = self.elements(
                &values.view(),
                values.offset(),
                m,
                n * c,
                &format!("{sp}/values"),
            )?;
            for (k, (ib, vb)) in index_bytes.iter().zip(&value_bytes).enumerate() {
                let i = match isize_ {
                    1 => u32::from(ib[0]),
                    2 => u32::from(u16::from_le_bytes([ib[0], ib[1]])),
                    _ => u32::from_le_bytes([ib[0], ib[1], ib[2], ib[3]]),
                } as usize;
                if i >= count {
                    return Err(self.err(
                        format!("{sp}/indices"),
                        format!("sparse index {k} is {i}, past the {count} elements"),
                    ));
                }
                for j in 0..n {
                    out[i * n + j] = f(&vb[j * c..(j + 1) * c])
                        .ok_or_else(|| bad(format!("{at}/componentType")))?;
                }
            }
        }
        Ok(out)
    }

    /// The accessor's components as floats; `want` components per element are required.
    pub fn floats(
        &self,
        acc: &gltf::Accessor<'_>,
        want: &[usize],
    ) -> Result<Vec<f32>, AvatarError> {
        self.check_dims(acc, want)?;
        let (t, normalized) = (acc.data_type(), acc.normalized());
        self.read(acc, &|b| Some(float(t, normalized, b)))
    }

    /// The accessor's components as unsigned integers (U8, U16 or U32 only).
    pub fn unsigned(
        &self,
        acc: &gltf::Accessor<'_>,
        want: &[usize],
    ) -> Result<Vec<u32>, AvatarError> {
        self.check_dims(acc, want)?;
        let t = acc.data_type();
        self.read(acc, &|b| unsigned(t, b))
    }

    fn check_dims(&self, acc: &gltf::Accessor<'_>, want: &[usize]) -> Result<(), AvatarError> {
        let n = dims(acc.dimensions());
        if want.contains(&n) {
            Ok(())
        } else {
            Err(self.err(
                format!("/accessors/{}/type", acc.index()),
                format!("{n} components per element, expected {want:?}"),
            ))
        }
    }
}
