//! Region blending: per-region bases combined with the partition of unity of [`RegionBands`].
//!
//! `B = sum_r diag(alpha_r) B_r`, where `B_r` has non-zero columns only for region `r`'s controls
//! and `alpha_r(i)` is the weight of region `r` at vertex `i`'s height. Because the weights sum to
//! one and ramp linearly across each band, the blend has no seam.

use glam::Vec3;
use mimic_types::{Region, RegionBands, RigControl};

/// Blend weights `[top, middle, bottom]` of every vertex (by its rest height `y`).
pub fn vertex_region_weights(bands: &RegionBands, positions: &[Vec3]) -> Vec<[f32; 3]> {
    positions.iter().map(|p| bands.weights(p.y)).collect()
}

/// Indices (into `controls`) of the controls of each region, in [`Region::ALL`] order.
pub fn controls_by_region(controls: &[RigControl]) -> [Vec<usize>; 3] {
    let mut out: [Vec<usize>; 3] = Default::default();
    for (j, c) in controls.iter().enumerate() {
        out[c.region.index()].push(j);
    }
    out
}

/// Adds `alpha_r(i) * cols[i, c]` into column `subset[c]` of the row-major `n x m` matrix `basis`.
///
/// `region` `None` means no blending (weight 1 everywhere).
pub fn blend_into(
    basis: &mut [f64],
    m: usize,
    cols: &[f64],
    subset: &[usize],
    region: Option<Region>,
    weights: &[[f32; 3]],
) {
    let k = subset.len();
    if k == 0 {
        return;
    }
    for (i, (row, src)) in basis
        .chunks_exact_mut(m)
        .zip(cols.chunks_exact(k))
        .enumerate()
    {
        let alpha = region.map_or(1.0, |r| weights[i][r.index()] as f64);
        if alpha == 0.0 {
            continue;
        }
        for (&j, v) in subset.iter().zip(src) {
            row[j] += alpha * v;
        }
    }
}
