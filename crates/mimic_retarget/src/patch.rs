//! The part of the rig that can move: rows of `B` that are not all zero, and the normals they touch.
//!
//! On a head rig most vertices (back of the head, teeth, eyeballs) are frozen, so their rows of `B`
//! are zero. Applying only the moving rows, and renormalising only the normals those rows can
//! change, keeps a frame's cost proportional to the face, not to the whole head.

use glam::{Vec3, Vec3A};
use mimic_solve::Basis;
use mimic_solve::normals::VertexFans;

/// Moving rows of a basis and the neighbourhood whose normals follow them.
#[derive(Clone, Debug)]
pub(crate) struct MovingPatch {
    /// Vertex index of each moving row.
    rows: Vec<u32>,
    /// `B` restricted to the moving rows.
    compact: Basis,
    /// Scratch for the compact product.
    u: Vec<Vec3>,
    /// Vertices the normal pass reads, by local index: first the moving rows (in `rows` order),
    /// then the other vertices whose normal can change (corners of triangles with a moving
    /// vertex), then the other corners of their triangles.
    local_vertices: Vec<u32>,
    /// Fans around the local vertices whose normal can change (`0..fans.count()`).
    fans: VertexFans,
    /// Positions by local index: the moving rows are rewritten by every [`MovingPatch::deform`],
    /// the others never move and keep their rest position.
    local_positions: Vec<Vec3A>,
}

impl MovingPatch {
    /// Finds the moving rows of `basis` and the triangles around them; `rest` holds the rest
    /// positions of every vertex of the mesh (`basis.vertex_count()` of them).
    pub(crate) fn new(basis: &Basis, triangles: &[[u32; 3]], rest: &[Vec3]) -> Self {
        let n = basis.vertex_count().min(rest.len());
        let m = basis.control_count();
        let rows: Vec<u32> = (0..n)
            .filter(|&i| basis.row(i).iter().any(|w| *w != 0.0))
            .map(|i| i as u32)
            .collect();
        let mut data = Vec::with_capacity(rows.len() * m);
        for &i in &rows {
            data.extend_from_slice(basis.row(i as usize));
        }
        let compact = Basis::from_row_major(rows.len(), m, data)
            .unwrap_or_else(|| unreachable!("rows.len() * m values were copied"));
        let mut moving = vec![false; n];
        rows.iter().for_each(|&i| moving[i as usize] = true);
        let mut in_normal_set = vec![false; n];
        let in_range = |t: &[u32; 3]| t.iter().all(|&v| (v as usize) < n);
        for t in triangles.iter().filter(|t| in_range(t)) {
            if t.iter().any(|&v| moving[v as usize]) {
                t.iter().for_each(|&v| in_normal_set[v as usize] = true);
            }
        }
        let incident: Vec<[u32; 3]> = triangles
            .iter()
            .filter(|t| in_range(t) && t.iter().any(|&v| in_normal_set[v as usize]))
            .copied()
            .collect();
        // Local numbering: the moving rows, the rest of the normal set, then the remaining corners
        // of incident triangles. Every moving vertex is in the normal set or in no triangle at
        // all (its normal is then zero, as `vertex_normals` gives it).
        let mut local_of = vec![u32::MAX; n];
        let mut local_vertices: Vec<u32> = rows.clone();
        local_vertices
            .extend((0..n as u32).filter(|&v| in_normal_set[v as usize] && !moving[v as usize]));
        let normal_count = local_vertices.len();
        for (k, &v) in local_vertices.iter().enumerate() {
            local_of[v as usize] = k as u32;
        }
        for t in &incident {
            for &v in t {
                if local_of[v as usize] == u32::MAX {
                    local_of[v as usize] = local_vertices.len() as u32;
                    local_vertices.push(v);
                }
            }
        }
        let local_triangles: Vec<[u32; 3]> = incident
            .iter()
            .map(|t| t.map(|v| local_of[v as usize]))
            .collect();
        let fans = VertexFans::new(normal_count, local_vertices.len(), &local_triangles);
        Self {
            u: vec![Vec3::ZERO; rows.len()],
            rows,
            compact,
            local_positions: local_vertices
                .iter()
                .map(|&v| Vec3A::from(rest[v as usize]))
                .collect(),
            local_vertices,
            fans,
        }
    }

    /// Number of moving vertices.
    pub(crate) fn moving_count(&self) -> usize {
        self.rows.len()
    }

    /// `positions[i] = rest[i] + (B d)_i` for every moving vertex; others are left as they are.
    /// The new positions are also kept for [`MovingPatch::normals`].
    pub(crate) fn deform(&mut self, d: &[Vec3], rest: &[Vec3], positions: &mut [Vec3]) {
        self.compact.apply(d, &mut self.u);
        for ((&i, u), local) in self.rows.iter().zip(&self.u).zip(&mut self.local_positions) {
            let p = rest[i as usize] + *u;
            positions[i as usize] = p;
            *local = Vec3A::from(p);
        }
    }

    /// Recomputes the area-weighted normals of the vertices the moving rows can affect, from the
    /// positions of the last [`MovingPatch::deform`] (rest positions before the first).
    ///
    /// Gathers vertex by vertex over precomputed fans ([`VertexFans`]) on the compact copy of the
    /// neighbourhood in 16-byte SIMD vectors: each normal is summed in registers, normalised and
    /// written once.
    pub(crate) fn normals(&mut self, normals: &mut [Vec3]) {
        let targets = &self.local_vertices;
        self.fans.normals(&self.local_positions, |k, n| {
            normals[targets[k] as usize] = n;
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patch_equals_full_apply_and_full_normals() {
        // A 6 x 6 grid, 2 controls, rows of the left half zero (frozen).
        let g = 6usize;
        let positions: Vec<Vec3> = (0..g * g)
            .map(|k| Vec3::new((k % g) as f32, (k / g) as f32, 0.0))
            .collect();
        let mut triangles = Vec::new();
        for y in 0..g - 1 {
            for x in 0..g - 1 {
                let i = (y * g + x) as u32;
                triangles.push([i, i + 1, i + g as u32 + 1]);
                triangles.push([i, i + g as u32 + 1, i + g as u32]);
            }
        }
        let data: Vec<f32> = (0..g * g)
            .flat_map(|k| {
                if k % g < 3 {
                    [0.0, 0.0]
                } else {
                    [0.1 * (k % g) as f32, 0.05 * (k / g) as f32]
                }
            })
            .collect();
        let basis = Basis::from_row_major(g * g, 2, data).unwrap();
        let mut patch = MovingPatch::new(&basis, &triangles, &positions);
        assert_eq!(patch.moving_count(), g * 3);
        let d = [Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.3, -0.2, 0.5)];
        // Reference: full apply and full normals.
        let mut u = vec![Vec3::ZERO; g * g];
        basis.apply(&d, &mut u);
        let full: Vec<Vec3> = positions.iter().zip(&u).map(|(p, u)| *p + *u).collect();
        let mut full_n = vec![Vec3::ZERO; g * g];
        mimic_solve::vertex_normals(&full, &triangles, &mut full_n);
        // Patch: start from rest positions and rest normals, update only what moves.
        let mut pos = positions.clone();
        let mut nrm = vec![Vec3::ZERO; g * g];
        mimic_solve::vertex_normals(&pos, &triangles, &mut nrm);
        patch.deform(&d, &positions, &mut pos);
        patch.normals(&mut nrm);
        assert_eq!(pos, full);
        for (a, b) in nrm.iter().zip(&full_n) {
            // Same sums in a different order: f32 rounding, ~1e-6.
            assert!((*a - *b).length() < 1e-5, "{a} vs {b}");
        }
    }
}
