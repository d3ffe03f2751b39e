//! The part of the rig that can move: rows of `B` that are not all zero, and the normals they touch.
//!
//! On a head rig most vertices (back of the head, teeth, eyeballs) are frozen, so their rows of `B`
//! are zero. Applying only the moving rows, and renormalising only the normals those rows can
//! change, keeps a frame's cost proportional to the face, not to the whole head.

use glam::Vec3;
use mimic_solve::Basis;

/// Moving rows of a basis and the neighbourhood whose normals follow them.
#[derive(Clone, Debug)]
pub(crate) struct MovingPatch {
    /// Vertex index of each moving row.
    rows: Vec<u32>,
    /// `B` restricted to the moving rows.
    compact: Basis,
    /// Scratch for the compact product.
    u: Vec<Vec3>,
    /// Vertices whose normal can change (corners of triangles with a moving vertex).
    normal_vertices: Vec<u32>,
    /// Per vertex: is it in `normal_vertices`?
    in_normal_set: Vec<bool>,
    /// Every triangle incident on a vertex of `normal_vertices`.
    normal_triangles: Vec<[u32; 3]>,
}

impl MovingPatch {
    /// Finds the moving rows of `basis` and the triangles around them.
    pub(crate) fn new(basis: &Basis, triangles: &[[u32; 3]]) -> Self {
        let n = basis.vertex_count();
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
        for t in triangles {
            if t.iter()
                .any(|&v| moving.get(v as usize).copied().unwrap_or(false))
            {
                t.iter()
                    .filter(|&&v| (v as usize) < n)
                    .for_each(|&v| in_normal_set[v as usize] = true);
            }
        }
        let normal_vertices: Vec<u32> = (0..n as u32)
            .filter(|&v| in_normal_set[v as usize])
            .collect();
        let normal_triangles: Vec<[u32; 3]> = triangles
            .iter()
            .filter(|t| {
                t.iter().all(|&v| (v as usize) < n) && t.iter().any(|&v| in_normal_set[v as usize])
            })
            .copied()
            .collect();
        Self {
            u: vec![Vec3::ZERO; rows.len()],
            rows,
            compact,
            normal_vertices,
            in_normal_set,
            normal_triangles,
        }
    }

    /// Number of moving vertices.
    pub(crate) fn moving_count(&self) -> usize {
        self.rows.len()
    }

    /// `positions[i] = rest[i] + (B d)_i` for every moving vertex; others are left as they are.
    pub(crate) fn deform(&mut self, d: &[Vec3], rest: &[Vec3], positions: &mut [Vec3]) {
        self.compact.apply(d, &mut self.u);
        for (&i, u) in self.rows.iter().zip(&self.u) {
            positions[i as usize] = rest[i as usize] + *u;
        }
    }

    /// Recomputes the area-weighted normals of the vertices the moving rows can affect.
    pub(crate) fn normals(&self, positions: &[Vec3], normals: &mut [Vec3]) {
        for &v in &self.normal_vertices {
            normals[v as usize] = Vec3::ZERO;
        }
        for t in &self.normal_triangles {
            let (a, b, c) = (
                positions[t[0] as usize],
                positions[t[1] as usize],
                positions[t[2] as usize],
            );
            let n = (b - a).cross(c - a);
            for &v in t {
                if self.in_normal_set[v as usize] {
                    normals[v as usize] += n;
                }
            }
        }
        for &v in &self.normal_vertices {
            normals[v as usize] = normals[v as usize].normalize_or_zero();
        }
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
        let mut patch = MovingPatch::new(&basis, &triangles);
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
        patch.normals(&pos, &mut nrm);
        assert_eq!(pos, full);
        for (a, b) in nrm.iter().zip(&full_n) {
            // Same sums in a different order: f32 rounding, ~1e-6.
            assert!((*a - *b).length() < 1e-5, "{a} vs {b}");
        }
    }
}
