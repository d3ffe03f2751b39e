//! Per-frame motion metrics of a retargeter's output, as `mimic replay --metrics` writes them.

use crate::Region;
use glam::Vec3;

/// Mean length of the control displacements of each region (top, middle, bottom), 0 for a region
/// without controls; `regions` gives each control's region.
pub fn region_motion(displacements: &[Vec3], regions: &[Region]) -> [f32; 3] {
    let mut sum = [0f32; 3];
    let mut count = [0u32; 3];
    for (d, r) in displacements.iter().zip(regions) {
        sum[r.index()] += d.length();
        count[r.index()] += 1;
    }
    std::array::from_fn(|k| {
        if count[k] > 0 {
            sum[k] / count[k] as f32
        } else {
            0.0
        }
    })
}

/// Largest distance of a vertex from its rest position.
pub fn max_vertex_motion(positions: &[Vec3], rest: &[Vec3]) -> f32 {
    positions
        .iter()
        .zip(rest)
        .map(|(p, r)| p.distance(*r))
        .fold(0f32, f32::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn motion_per_region_and_largest_vertex_motion() {
        let d = [Vec3::new(3.0, 4.0, 0.0), Vec3::X, Vec3::new(0.0, 0.0, 2.0)];
        let r = [Region::Top, Region::Top, Region::Bottom];
        // Top: (5 + 1) / 2; no middle control; bottom: 2.
        assert_eq!(region_motion(&d, &r), [3.0, 0.0, 2.0]);
        let rest = [Vec3::ZERO, Vec3::ONE];
        assert_eq!(
            max_vertex_motion(&[Vec3::X, Vec3::new(1.0, 1.0, 3.0)], &rest),
            2.0
        );
        assert_eq!(max_vertex_motion(&[], &[]), 0.0);
    }
}
