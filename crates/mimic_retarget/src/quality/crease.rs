//! A measure of shelves and crumples (issue 45): how unevenly the surface bends at a scale of a
//! few rings. Per vertex, the normal (averaged over [`SMOOTH_RINGS`] rings, so single-triangle
//! noise does not count) turns from rest by the rotation vector `r = n0 x n`; a smooth
//! deformation turns neighbouring normals alike, a shelf or a crumple turns them differently, so
//! the measure is `|r - avg(r)|` with the average over [`VARY_RINGS`] rings, and a frame's figure
//! the 99.5th percentile of that over the measured region (the forehead: a fine-scale
//! Laplacian misses these broad faults). ICT-FaceKit's own expression shapes give the bound a
//! real face stays under (docs/quality.md, "Creases").

use glam::Vec3;

/// Rings the normals are averaged over before they are compared.
pub const SMOOTH_RINGS: usize = 2;
/// Rings the normals' turn is compared with its average over.
pub const VARY_RINGS: usize = 4;

/// The crease measure of one surface (module docs).
#[derive(Clone, Debug)]
pub struct CreaseMeasure {
    /// Triangles whose corners are all on the surface.
    triangles: Vec<[u32; 3]>,
    /// Its edges, each once.
    edges: Vec<(u32, u32)>,
    /// One over (1 + vertex degree) per vertex (0 off the surface).
    inv_degree: Vec<f32>,
    /// Smoothed rest normals.
    rest_normals: Vec<Vec3>,
    /// The vertices measured.
    region: Vec<u32>,
}

impl CreaseMeasure {
    /// The measure of the surface made by the triangles of `triangles` whose corners are all in
    /// `surface`, over the vertices of `region`, from `rest`.
    pub fn new(rest: &[Vec3], triangles: &[[u32; 3]], surface: &[bool], region: &[bool]) -> Self {
        let on = |v: u32| surface.get(v as usize).copied().unwrap_or(false);
        let triangles: Vec<[u32; 3]> = triangles
            .iter()
            .copied()
            .filter(|t| t.iter().all(|v| on(*v)))
            .collect();
        let mut edges: Vec<(u32, u32)> = triangles
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(a, b)| (a.min(b), a.max(b)))
            .collect();
        edges.sort_unstable();
        edges.dedup();
        let mut degree = vec![0u32; rest.len()];
        for &(a, b) in &edges {
            degree[a as usize] += 1;
            degree[b as usize] += 1;
        }
        let inv_degree = degree
            .iter()
            .enumerate()
            .map(|(i, d)| {
                if surface.get(i).copied().unwrap_or(false) {
                    1.0 / (1.0 + *d as f32)
                } else {
                    0.0
                }
            })
            .collect();
        let region = (0..rest.len() as u32)
            .filter(|&v| on(v) && region.get(v as usize).copied().unwrap_or(false))
            .collect();
        let mut m = Self {
            triangles,
            edges,
            inv_degree,
            rest_normals: Vec::new(),
            region,
        };
        m.rest_normals = m.smoothed_normals(rest);
        m
    }

    /// Vertices measured.
    pub fn region_len(&self) -> usize {
        self.region.len()
    }

    /// The frame's figure: the 99.5th percentile over the region of `|r - avg(r)|` (module docs),
    /// for `positions` (one per rest vertex).
    pub fn measure(&self, positions: &[Vec3]) -> f32 {
        let n = self.smoothed_normals(positions);
        let turn: Vec<Vec3> = self
            .rest_normals
            .iter()
            .zip(&n)
            .map(|(a, b)| a.cross(*b))
            .collect();
        let mut avg = turn.clone();
        for _ in 0..VARY_RINGS {
            avg = self.ring_average(&avg);
        }
        let mut dev: Vec<f32> = self
            .region
            .iter()
            .map(|&v| (turn[v as usize] - avg[v as usize]).length())
            .collect();
        if dev.is_empty() {
            return 0.0;
        }
        dev.sort_unstable_by(f32::total_cmp);
        let k = ((dev.len() - 1) as f32 * 0.995).round() as usize;
        dev[k.min(dev.len() - 1)]
    }

    /// Area-weighted vertex normals averaged over [`SMOOTH_RINGS`] rings, unit length.
    fn smoothed_normals(&self, p: &[Vec3]) -> Vec<Vec3> {
        let mut n = vec![Vec3::ZERO; p.len()];
        for t in &self.triangles {
            let [a, b, c] = t.map(|v| p[v as usize]);
            let face = (b - a).cross(c - a);
            for v in t {
                n[*v as usize] += face;
            }
        }
        for _ in 0..SMOOTH_RINGS {
            n = self.ring_average(&n);
        }
        n.iter().map(|v| v.normalize_or_zero()).collect()
    }

    /// Each surface vertex's value averaged with its neighbours' (one ring).
    fn ring_average(&self, x: &[Vec3]) -> Vec<Vec3> {
        let mut s = x.to_vec();
        for &(a, b) in &self.edges {
            s[a as usize] += x[b as usize];
            s[b as usize] += x[a as usize];
        }
        s.iter()
            .zip(&self.inv_degree)
            .map(|(v, w)| *v * *w)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat `k x k` grid (spacing 1), with its triangles.
    fn grid(k: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = (0..k * k)
            .map(|i| Vec3::new((i % k) as f32, (i / k) as f32, 0.0))
            .collect();
        let mut t = Vec::new();
        for y in 0..k - 1 {
            for x in 0..k - 1 {
                let a = (y * k + x) as u32;
                let k = k as u32;
                t.push([a, a + 1, a + k + 1]);
                t.push([a, a + k + 1, a + k]);
            }
        }
        (p, t)
    }

    #[test]
    fn a_smooth_bend_measures_less_than_a_shelf() {
        let k = 30;
        let (rest, tris) = grid(k);
        let all = vec![true; rest.len()];
        // The middle, away from the border (whose one-sided averages bend too).
        let region: Vec<bool> = rest
            .iter()
            .map(|p| p.x > 8.0 && p.x < 21.0 && p.y > 8.0 && p.y < 21.0)
            .collect();
        let m = CreaseMeasure::new(&rest, &tris, &all, &region);
        assert!(m.measure(&rest) < 1e-6);
        // The same height change, once as a wide smooth slope and once as a step one cell wide.
        let smooth: Vec<Vec3> = rest
            .iter()
            .map(|p| *p + Vec3::Z * 3.0 * (1.0 - (-((p.x - 14.5) / 6.0).powi(2)).exp()))
            .collect();
        let shelf: Vec<Vec3> = rest
            .iter()
            .map(|p| *p + Vec3::Z * if p.x > 14.5 { 3.0 } else { 0.0 })
            .collect();
        let (a, b) = (m.measure(&smooth), m.measure(&shelf));
        assert!(b > 2.0 * a, "smooth {a}, shelf {b}");
        // A rigid tilt turns every normal alike: nothing to measure.
        let q = glam::Quat::from_rotation_x(0.3);
        let tilted: Vec<Vec3> = rest.iter().map(|p| q * *p).collect();
        assert!(m.measure(&tilted) < 1e-4, "{}", m.measure(&tilted));
    }
}
