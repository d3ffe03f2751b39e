//! Nearest vertices of a mesh (a `kiddo` k-d tree over a subset of its vertices), and the
//! surface queries registration needs: the nearest vertex facing a given way, and the point of
//! its tangent plane nearest to the query (a point-to-plane correspondence).

use glam::Vec3;
use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use std::num::NonZero;

/// How many nearest vertices a facing-filtered query looks through.
const CANDIDATES: usize = 8;

/// A k-d tree over some vertices of a point set, answering with the original vertex numbers.
pub struct PointIndex {
    tree: ImmutableKdTree<f32, u32, 3, 32>,
    /// Vertex number of each tree item.
    ids: Vec<u32>,
}

impl PointIndex {
    /// An index over the points `points[v]` with `keep(v)`.
    pub fn new(points: &[Vec3], keep: impl Fn(usize) -> bool) -> Self {
        let ids: Vec<u32> = (0..points.len())
            .filter(|&v| keep(v) && points[v].is_finite())
            .map(|v| v as u32)
            .collect();
        let coords: Vec<[f32; 3]> = ids.iter().map(|&v| points[v as usize].to_array()).collect();
        Self {
            tree: ImmutableKdTree::new_from_slice(&coords),
            ids,
        }
    }

    /// How many points the index holds.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// Whether the index holds no point.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// The nearest indexed vertex to `q` and its distance.
    pub fn nearest(&self, q: Vec3) -> Option<(u32, f32)> {
        if self.ids.is_empty() {
            return None;
        }
        let n = self.tree.nearest_one::<SquaredEuclidean>(&q.to_array());
        let v = *self.ids.get(n.item as usize)?;
        Some((v, n.distance.max(0.0).sqrt()))
    }

    /// Up to `k` nearest indexed vertices to `q`, nearest first, with their distances.
    pub fn nearest_k(&self, q: Vec3, k: usize) -> Vec<(u32, f32)> {
        let Some(k) = NonZero::new(k) else {
            return Vec::new();
        };
        if self.ids.is_empty() {
            return Vec::new();
        }
        self.tree
            .nearest_n::<SquaredEuclidean>(&q.to_array(), k)
            .into_iter()
            .filter_map(|n| Some((*self.ids.get(n.item as usize)?, n.distance.max(0.0).sqrt())))
            .collect()
    }
}

/// A surface to register onto: vertex positions and unit normals, which vertices may be
/// matched, and a k-d tree over those.
pub struct Surface {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals (zero where undefined).
    pub normals: Vec<Vec3>,
    /// Vertices on the mesh's open border (an edge of one triangle): a match there means the
    /// query is past the surface's edge.
    pub border: Vec<bool>,
    /// The index over the matchable vertices.
    pub index: PointIndex,
}

/// A correspondence on a [`Surface`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Match {
    /// The matched vertex.
    pub vertex: u32,
    /// The point of the vertex's tangent plane nearest to the query.
    pub on_plane: Vec3,
    /// Distance from the query to that point (point-to-plane distance).
    pub distance: f32,
    /// Whether the vertex is on the open border.
    pub border: bool,
}

impl Surface {
    /// A surface of `positions` (normals from `triangles`) where `keep(v)` vertices match.
    pub fn new(positions: Vec<Vec3>, triangles: &[[u32; 3]], keep: impl Fn(usize) -> bool) -> Self {
        let normals = crate::register::vertex_normals(&positions, triangles);
        let border = border_vertices(positions.len(), triangles);
        let index = PointIndex::new(&positions, |v| keep(v) && normals[v] != Vec3::ZERO);
        Self {
            positions,
            normals,
            border,
            index,
        }
    }

    /// The nearest matchable vertex to `q` (among its 8 nearest) whose normal has
    /// a dot product of at least `min_dot` with `facing`, and the nearest point of its tangent
    /// plane to `q`.
    pub fn closest(&self, q: Vec3, facing: Vec3, min_dot: f32) -> Option<Match> {
        let (v, _) = self
            .index
            .nearest_k(q, CANDIDATES)
            .into_iter()
            .find(|(v, _)| self.normals[*v as usize].dot(facing) >= min_dot)?;
        let (p, n) = (self.positions[v as usize], self.normals[v as usize]);
        let along = n.dot(q - p);
        Some(Match {
            vertex: v,
            on_plane: q - n * along,
            distance: along.abs(),
            border: self.border[v as usize],
        })
    }
}

/// Vertices on an edge that only one triangle uses.
pub fn border_vertices(n: usize, triangles: &[[u32; 3]]) -> Vec<bool> {
    let mut edges: std::collections::HashMap<(u32, u32), u32> = Default::default();
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut border = vec![false; n];
    for ((a, b), count) in edges {
        if count == 1 {
            for v in [a, b] {
                if let Some(x) = border.get_mut(v as usize) {
                    *x = true;
                }
            }
        }
    }
    border
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tree_agrees_with_a_brute_force_search() {
        // A lattice with many equal coordinates (as a mesh's midline has), some left out.
        let points: Vec<Vec3> = (0..1000)
            .map(|i| {
                Vec3::new(
                    (i % 10) as f32,
                    ((i / 10) % 10) as f32 * 0.5,
                    (i / 100) as f32,
                )
            })
            .collect();
        let keep = |v: usize| v % 7 != 3;
        let index = PointIndex::new(&points, keep);
        assert_eq!(index.len(), (0..1000).filter(|v| keep(*v)).count());
        for q in [
            Vec3::new(3.3, 1.2, 4.9),
            Vec3::new(-2.0, 7.0, 0.1),
            Vec3::new(9.6, 4.6, 11.0),
        ] {
            let brute = (0..points.len())
                .filter(|v| keep(*v))
                .map(|v| points[v].distance(q))
                .fold(f32::INFINITY, f32::min);
            let (v, d) = index.nearest(q).unwrap();
            assert!(keep(v as usize));
            assert!((d - brute).abs() <= 1e-5 * (1.0 + brute), "{d} vs {brute}");
            let k = index.nearest_k(q, 5);
            assert_eq!(k.len(), 5);
            assert!((k[0].1 - brute).abs() <= 1e-5 * (1.0 + brute));
            assert!(k.windows(2).all(|w| w[0].1 <= w[1].1));
        }
    }

    #[test]
    fn a_square_has_four_border_vertices_of_five() {
        // Four triangles around a centre vertex 4.
        let tris = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
        assert_eq!(
            border_vertices(5, &tris),
            vec![true, true, true, true, false]
        );
    }
}
