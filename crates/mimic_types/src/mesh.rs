//! Triangle meshes.

use glam::{Vec2, Vec3};

/// An indexed triangle mesh: positions per vertex, triangles as vertex index triples.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions, in the mesh's units.
    pub positions: Vec<Vec3>,
    /// Triangles, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Texture coordinates per triangle corner (`uv_triangles[t][k]` indexes `uvs`); empty if none.
    pub uvs: Vec<Vec2>,
    /// Per-triangle indices into `uvs`, parallel to `triangles`; empty if the mesh has no UVs.
    pub uv_triangles: Vec<[u32; 3]>,
}

/// A mesh whose indices or values are unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// A triangle names a vertex that does not exist.
    #[error("triangle {triangle} uses vertex {vertex}, but the mesh has {vertex_count} vertices")]
    IndexOutOfRange {
        /// Triangle number.
        triangle: usize,
        /// Offending vertex index.
        vertex: u32,
        /// Vertices in the mesh.
        vertex_count: usize,
    },
    /// A vertex position is NaN or infinite.
    #[error("vertex {0} has a non-finite position")]
    NonFinite(usize),
    /// The mesh has no vertices.
    #[error("the mesh has no vertices")]
    Empty,
}

impl Mesh {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Checks that every index is in range and every position finite.
    pub fn validate(&self) -> Result<(), MeshError> {
        if self.positions.is_empty() {
            return Err(MeshError::Empty);
        }
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshError::NonFinite(i));
        }
        let n = self.positions.len();
        for (t, tri) in self.triangles.iter().enumerate() {
            for &v in tri {
                if v as usize >= n {
                    return Err(MeshError::IndexOutOfRange {
                        triangle: t,
                        vertex: v,
                        vertex_count: n,
                    });
                }
            }
        }
        Ok(())
    }

    /// Axis-aligned bounding box `(min, max)`; `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))),
        )
    }

    /// Undirected edges `(a, b)` with `a < b`, each once, sorted.
    pub fn edges(&self) -> Vec<(u32, u32)> {
        let mut e: Vec<(u32, u32)> = self
            .triangles
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(a, b)| if a < b { (a, b) } else { (b, a) })
            .collect();
        e.sort_unstable();
        e.dedup();
        e
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> Mesh {
        Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        }
    }

    #[test]
    fn validates_and_lists_edges() {
        let m = quad();
        m.validate().unwrap();
        assert_eq!(m.edges(), vec![(0, 1), (0, 2), (0, 3), (1, 2), (2, 3)]);
        assert_eq!(m.bounds(), Some((Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0))));
    }

    #[test]
    fn rejects_out_of_range_and_nan() {
        let mut m = quad();
        m.triangles.push([0, 1, 9]);
        assert_eq!(
            m.validate(),
            Err(MeshError::IndexOutOfRange {
                triangle: 2,
                vertex: 9,
                vertex_count: 4
            })
        );
        let mut m = quad();
        m.positions[2].x = f32::NAN;
        assert_eq!(m.validate(), Err(MeshError::NonFinite(2)));
    }
}
