//! Area-weighted vertex normals.

use glam::Vec3;

/// Area-weighted vertex normals: each vertex gets the normalised sum of the un-normalised normals
/// `(b - a) x (c - a)` of its triangles (counter-clockwise seen from outside points outwards).
///
/// Allocates nothing. Vertices in no triangle, or whose summed normal has zero length (e.g. only
/// degenerate triangles), get `Vec3::ZERO`. Triangles naming a vertex outside `positions` are skipped.
///
/// # Panics
/// If `out.len() != positions.len()`.
pub fn vertex_normals(positions: &[Vec3], triangles: &[[u32; 3]], out: &mut [Vec3]) {
    assert_eq!(
        out.len(),
        positions.len(),
        "vertex_normals: output length differs from positions"
    );
    out.fill(Vec3::ZERO);
    for t in triangles {
        let (ia, ib, ic) = (t[0] as usize, t[1] as usize, t[2] as usize);
        let (Some(a), Some(b), Some(c)) = (positions.get(ia), positions.get(ib), positions.get(ic))
        else {
            continue;
        };
        let n = (*b - *a).cross(*c - *a);
        out[ia] += n;
        out[ib] += n;
        out[ic] += n;
    }
    for n in out.iter_mut() {
        *n = n.normalize_or_zero();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_quad_points_up_and_weights_by_area() {
        // Two triangles of a unit square in the xy plane, CCW seen from +z.
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::Y,
            Vec3::new(5.0, 5.0, 5.0),
        ];
        let t = [[0, 1, 2], [0, 2, 3]];
        let mut out = [Vec3::NAN; 5];
        vertex_normals(&p, &t, &mut out);
        for n in &out[..4] {
            assert!((*n - Vec3::Z).length() < 1e-6);
        }
        assert_eq!(out[4], Vec3::ZERO, "isolated vertex gets zero");
    }

    #[test]
    fn area_weighting_on_a_roof() {
        // Vertex 0 is shared by a big triangle in the xy plane (area 2) and a small one in the xz
        // plane (area 0.5): the normal is (2 z + 0.5 (-y)) normalised... computed analytically.
        let p = [
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        // (p1 - p0) x (p2 - p0) = 4 z (twice the area 2); (p3 - p0) x (p1 - p0) = (0,0,1)x(2,0,0) = 2 y.
        let t = [[0, 1, 2], [0, 3, 1]];
        let mut out = [Vec3::ZERO; 4];
        vertex_normals(&p, &t, &mut out);
        let expect = Vec3::new(0.0, 2.0, 4.0).normalize();
        assert!((out[0] - expect).length() < 1e-6, "{}", out[0]);
    }

    #[test]
    fn degenerate_and_bad_triangles_give_zero_not_nan() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)];
        let t = [[0, 1, 2], [0, 1, 7]];
        let mut out = [Vec3::ONE; 3];
        vertex_normals(&p, &t, &mut out);
        assert!(out.iter().all(|n| *n == Vec3::ZERO));
    }
}
