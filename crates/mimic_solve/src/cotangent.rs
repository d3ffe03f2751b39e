//! The cotangent Laplacian (stiffness matrix) and the lumped (barycentric) mass of a triangle mesh.
//!
//! `L` is the symmetric positive semi-definite stiffness matrix of piecewise-linear finite
//! elements: `L_ij = -w_ij` for an edge, `L_ii = sum_j w_ij`, `w_ij = (cot a + cot b) / 2` over
//! the one or two angles opposite the edge, so `u'Lu = sum_edges w_ij |u_i - u_j|^2` is the
//! Dirichlet (membrane) energy of `u`. `M` is diagonal: a third of each incident triangle's area.
//!
//! Robustness (what the solve needs is a PSD `L` and a positive `M`):
//! - a triangle that repeats a vertex, or whose doubled area is below `1e-12` of its longest
//!   squared edge (or is not finite), contributes nothing to `L` (its cotangents are unbounded);
//!   its area (about 0) still goes to the mass;
//! - each angle's cotangent is capped at [`COT_MAX`] (an angle of about 0.06 degrees), so sliver
//!   triangles cannot dominate;
//! - an edge whose summed weight is negative (the two opposite angles add up to more than 180
//!   degrees: a non-Delaunay edge next to obtuse triangles) is clamped to 0. With every `w_ij >= 0`
//!   the matrix is a weighted graph Laplacian, PSD with non-positive off-diagonals (no overshoot
//!   from negative weights); clamping a whole edge's sum, not each angle, keeps the exact weights
//!   (and the linear precision) wherever an obtuse angle is balanced by its neighbour;
//! - a vertex with no area (isolated, or only in degenerate triangles) gets the mass floor
//!   [`MASS_FLOOR`] times the mean vertex mass, so `M^-1` stays finite (its `L` row is then empty
//!   or small).

use glam::{DVec3, Vec3};

/// Doubled triangle area, relative to its longest squared edge, below which it counts as degenerate.
const DEGENERATE_AREA: f64 = 1e-12;
/// Largest cotangent one angle may contribute (about `cot(0.057 degrees)`).
pub const COT_MAX: f64 = 1e3;
/// Smallest vertex mass, as a fraction of the mean mass of the vertices that have one.
pub const MASS_FLOOR: f64 = 1e-8;

/// A symmetric sparse matrix in compressed rows: the diagonal apart, off-diagonals sorted by column.
#[derive(Clone, Debug)]
pub struct SymRows {
    /// `offsets[i]..offsets[i + 1]` index `cols` / `vals` for row `i`.
    pub offsets: Vec<usize>,
    /// Column of each off-diagonal entry.
    pub cols: Vec<u32>,
    /// Value of each off-diagonal entry.
    pub vals: Vec<f64>,
    /// Diagonal entry of each row.
    pub diag: Vec<f64>,
}

impl SymRows {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.diag.len()
    }

    /// Whether the matrix has no rows.
    pub fn is_empty(&self) -> bool {
        self.diag.is_empty()
    }

    /// Off-diagonal entries `(column, value)` of row `i`.
    pub fn row(&self, i: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let r = self.offsets[i]..self.offsets[i + 1];
        self.cols[r.clone()]
            .iter()
            .map(|c| *c as usize)
            .zip(self.vals[r].iter().copied())
    }

    /// `y = A x` for one scalar field.
    pub fn mul(&self, x: &[f64]) -> Vec<f64> {
        (0..self.len())
            .map(|i| self.diag[i] * x[i] + self.row(i).map(|(j, v)| v * x[j]).sum::<f64>())
            .collect()
    }
}

/// Whether triangle `p` (corner positions) is too thin to carry cotangent weights.
fn degenerate(idx: [usize; 3], p: &[DVec3; 3]) -> bool {
    let area2 = (p[1] - p[0]).cross(p[2] - p[0]).length();
    let longest = (0..3)
        .map(|e| (p[(e + 1) % 3] - p[e]).length_squared())
        .fold(0f64, f64::max);
    idx[0] == idx[1]
        || idx[1] == idx[2]
        || idx[0] == idx[2]
        || !(area2.is_finite() && longest.is_finite())
        || area2 <= DEGENERATE_AREA * longest
}

/// The cotangent stiffness matrix `L` of a mesh (triangles indexing outside `positions` are skipped).
pub fn cotangent_laplacian(positions: &[Vec3], triangles: &[[u32; 3]]) -> SymRows {
    let n = positions.len();
    let mut entries: Vec<(u32, u32, f64)> = Vec::with_capacity(triangles.len() * 6);
    for t in triangles {
        let idx = [t[0] as usize, t[1] as usize, t[2] as usize];
        if idx.iter().any(|&v| v >= n) {
            continue;
        }
        let p = idx.map(|v| positions[v].as_dvec3());
        let skip = degenerate(idx, &p);
        for corner in 0..3 {
            let (j, k) = (idx[(corner + 1) % 3], idx[(corner + 2) % 3]);
            if j == k {
                continue;
            }
            // Keep the edge in the pattern even when the triangle is skipped (weight 0).
            let half_cot = if skip {
                0.0
            } else {
                let e1 = p[(corner + 1) % 3] - p[corner];
                let e2 = p[(corner + 2) % 3] - p[corner];
                0.5 * (e1.dot(e2) / e1.cross(e2).length()).min(COT_MAX)
            };
            entries.push((j as u32, k as u32, half_cot));
            entries.push((k as u32, j as u32, half_cot));
        }
    }
    entries.sort_unstable_by_key(|e| (e.0, e.1));
    let mut offsets = Vec::with_capacity(n + 1);
    let mut cols = Vec::new();
    let mut vals = Vec::new();
    let mut diag = vec![0f64; n];
    offsets.push(0);
    let mut e = 0;
    for (i, d) in diag.iter_mut().enumerate() {
        while e < entries.len() && entries[e].0 as usize == i {
            let j = entries[e].1;
            let mut w = 0.0;
            while e < entries.len() && entries[e].0 as usize == i && entries[e].1 == j {
                w += entries[e].2;
                e += 1;
            }
            let w = w.max(0.0);
            cols.push(j);
            vals.push(-w);
            *d += w;
        }
        offsets.push(cols.len());
    }
    SymRows {
        offsets,
        cols,
        vals,
        diag,
    }
}

/// Lumped barycentric mass: a third of each incident triangle's area per vertex, floored at
/// [`MASS_FLOOR`] times the mean (so every entry is positive).
pub fn lumped_mass(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<f64> {
    let n = positions.len();
    let mut mass = vec![0f64; n];
    for t in triangles {
        let idx = [t[0] as usize, t[1] as usize, t[2] as usize];
        if idx.iter().any(|&v| v >= n) {
            continue;
        }
        let p = idx.map(|v| positions[v].as_dvec3());
        let area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        if !area.is_finite() {
            continue;
        }
        for &v in &idx {
            mass[v] += area / 3.0;
        }
    }
    let (sum, count) = mass
        .iter()
        .filter(|m| **m > 0.0)
        .fold((0f64, 0usize), |(s, c), m| (s + m, c + 1));
    let floor = if count > 0 {
        MASS_FLOOR * sum / count as f64
    } else {
        1.0
    };
    for m in &mut mass {
        *m = m.max(floor);
    }
    mass
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::{grid, tri_lattice};

    /// Interior vertices of an `nx x ny` lattice (one ring in from the border).
    fn interior(nx: usize, ny: usize) -> impl Iterator<Item = usize> {
        (1..ny - 1).flat_map(move |j| (1..nx - 1).map(move |i| j * nx + i))
    }

    #[test]
    fn linear_functions_are_harmonic_in_the_interior() {
        // Piecewise-linear FE: (L f)_i = 0 at interior vertices for f linear on a planar mesh
        // (any triangulation, obtuse or not, as long as no edge weight is clamped). The jittered
        // triangular lattice keeps every angle acute, so nothing is clamped.
        let mesh = tri_lattice(9, 9, 0.15, 7);
        let l = cotangent_laplacian(&mesh.positions, &mesh.triangles);
        let f: Vec<f64> = mesh
            .positions
            .iter()
            .map(|p| 0.3 + 1.7 * f64::from(p.x) - 0.4 * f64::from(p.y))
            .collect();
        let lf = l.mul(&f);
        // Entries of L are O(1) (cotangents of angles near 60 degrees) and |f| <= 15: f32
        // positions give ~1e-7 relative error per weight, so 1e-5 bounds the sum.
        for i in interior(9, 9) {
            assert!(lf[i].abs() < 1e-5, "vertex {i}: (L f) = {}", lf[i]);
        }
        // Constants are in the kernel everywhere (rows sum to zero), border included.
        let ones = vec![1.0; f.len()];
        assert!(l.mul(&ones).iter().all(|v| v.abs() < 1e-12));
    }

    #[test]
    fn equilateral_weights_are_cot_60() {
        // Interior edge of an exact equilateral lattice: two opposite 60 degree angles, so
        // w = (cot 60 + cot 60) / 2 = 1/sqrt(3); diagonal = 6 w.
        let mesh = tri_lattice(5, 5, 0.0, 0);
        let l = cotangent_laplacian(&mesh.positions, &mesh.triangles);
        let v = 2 * 5 + 2;
        let w = 1.0 / 3f64.sqrt();
        assert_eq!(l.row(v).count(), 6);
        for (_, x) in l.row(v) {
            assert!((x + w).abs() < 1e-6, "{x}");
        }
        assert!((l.diag[v] - 6.0 * w).abs() < 1e-6);
    }

    #[test]
    fn dirichlet_energy_of_a_linear_field_is_gradient_squared_times_area() {
        // For f = a.x on a planar mesh, u'Lu = |a|^2 * area exactly (FE energy of a linear field),
        // when no edge is clamped: the jittered triangular lattice keeps every angle acute.
        let mesh = tri_lattice(7, 6, 0.15, 3);
        let area: f64 = mesh
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(|v| mesh.positions[v as usize].as_dvec3());
                0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()
            })
            .sum();
        let l = cotangent_laplacian(&mesh.positions, &mesh.triangles);
        let f: Vec<f64> = mesh
            .positions
            .iter()
            .map(|p| 2.0 * f64::from(p.x) + 0.5 * f64::from(p.y))
            .collect();
        let energy: f64 = f.iter().zip(l.mul(&f)).map(|(a, b)| a * b).sum();
        // |a|^2 = 4.25; tolerance: f32 positions, relative 1e-5.
        assert!(
            (energy - 4.25 * area).abs() < 1e-5 * 4.25 * area,
            "{energy} vs {area}"
        );
    }

    #[test]
    fn mass_sums_to_the_area() {
        // A flat jittered unit square (no triangle flipped at this jitter): total mass = 1.
        let mesh = grid(11, 9, 0.0, 0.2, 5);
        let m = lumped_mass(&mesh.positions, &mesh.triangles);
        let total: f64 = m.iter().sum();
        assert!((total - 1.0).abs() < 1e-6, "{total}");
        // A curved one: the sum equals the summed triangle areas.
        let bump = grid(11, 9, 0.4, 0.2, 5);
        let m = lumped_mass(&bump.positions, &bump.triangles);
        let area: f64 = bump
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(|v| bump.positions[v as usize].as_dvec3());
                0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()
            })
            .sum();
        assert!((m.iter().sum::<f64>() - area).abs() < 1e-9 * area);
        assert!(area > 1.05, "the bump is curved: {area}");
    }

    #[test]
    fn obtuse_and_degenerate_triangles_stay_psd_and_finite() {
        // A fan with a sliver (angle ~1e-7 rad), a zero-area triangle and an obtuse pair whose
        // shared edge is non-Delaunay; plus an isolated vertex 6.
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.5, 0.05, 0.0),
            Vec3::new(0.5, -0.05, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(1.0, 1e-7, 0.0),
            Vec3::new(5.0, 5.0, 5.0),
        ];
        let triangles = vec![[0, 1, 2], [1, 0, 3], [0, 1, 5], [1, 4, 4], [1, 4, 2]];
        let l = cotangent_laplacian(&positions, &triangles);
        assert!(l.vals.iter().all(|v| v.is_finite() && *v <= 0.0));
        assert!(l.diag.iter().all(|v| v.is_finite() && *v >= 0.0));
        // Edge (0, 1) is opposite two 168.6 degree angles: its summed weight is negative, clamped.
        let w01 = l.row(0).find(|e| e.0 == 1).map(|e| e.1);
        assert_eq!(w01, Some(-0.0));
        // PSD: x'Lx >= 0 for random x (graph Laplacian with non-negative weights).
        let mut s = 11;
        for _ in 0..20 {
            let x: Vec<f64> = (0..7)
                .map(|_| f64::from(crate::test_meshes::lcg(&mut s)))
                .collect();
            let e: f64 = x.iter().zip(l.mul(&x)).map(|(a, b)| a * b).sum();
            assert!(e >= -1e-12, "{e}");
        }
        let m = lumped_mass(&positions, &triangles);
        assert!(m.iter().all(|v| v.is_finite() && *v > 0.0));
        assert_eq!(l.row(6).count(), 0);
    }
}
