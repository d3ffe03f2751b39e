//! Region blending: per-region bases combined with the partition of unity of [`RegionBands`].
//!
//! `B = sum_r diag(alpha_r) B_r`, where `B_r` has non-zero columns only for region `r`'s controls
//! and `alpha_r(i)` is the weight of region `r` at vertex `i`'s height. Because the weights sum to
//! one and ramp linearly across each band, the blend has no seam.

use glam::Vec3;
use mimic_types::{Region, RegionBands, RigControl, TopSplit};

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

/// One solve of a region blend: which controls, and the share of the blend at each vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Part {
    /// No regions: every control, weight 1 everywhere.
    All,
    /// A whole region, weighted by its band weight.
    Region(Region),
    /// The top region's lower (lid) or upper (brow) half of a [`TopSplit`]: the top weight times
    /// `1 - s(y)` or `s(y)`, `s` = [`TopSplit::upper_share`].
    TopHalf {
        /// The split.
        split: TopSplit,
        /// The upper (brow) half if true, the lower (lid) half if false.
        upper: bool,
    },
}

impl Part {
    /// Blend weight of this part at a vertex of rest height `y` with region weights `w`.
    pub fn weight(&self, y: f32, w: &[f32; 3]) -> f64 {
        match *self {
            Part::All => 1.0,
            Part::Region(r) => w[r.index()] as f64,
            Part::TopHalf { split, upper } => {
                let s = split.upper_share(y);
                let share = if upper { s } else { 1.0 - s };
                (w[Region::Top.index()] * share) as f64
            }
        }
    }

    /// Whether control `c` (rest height `y`) belongs to this part.
    pub fn owns(&self, c: &RigControl, y: f32) -> bool {
        match *self {
            Part::All => true,
            Part::Region(r) => c.region == r,
            Part::TopHalf { split, upper } => c.region == Region::Top && (y >= split.at) == upper,
        }
    }

    /// The parts of a blend: one without regions; three regions, or four with the top split.
    pub fn all(regions: bool, top_split: Option<TopSplit>) -> Vec<Part> {
        match (regions, top_split) {
            (false, _) => vec![Part::All],
            (true, None) => Region::ALL.into_iter().map(Part::Region).collect(),
            (true, Some(split)) => vec![
                Part::TopHalf { split, upper: true },
                Part::TopHalf {
                    split,
                    upper: false,
                },
                Part::Region(Region::Middle),
                Part::Region(Region::Bottom),
            ],
        }
    }
}

/// Adds `part(i) * cols[i, c]` into column `subset[c]` of the row-major `n x m` matrix `basis`,
/// where `part(i)` is the part's [`Part::weight`] at vertex `i`.
pub fn blend_into(
    basis: &mut [f64],
    m: usize,
    cols: &[f64],
    subset: &[usize],
    part: Part,
    positions: &[Vec3],
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
        let alpha = part.weight(positions[i].y, &weights[i]);
        if alpha == 0.0 {
            continue;
        }
        for (&j, v) in subset.iter().zip(src) {
            row[j] += alpha * v;
        }
    }
}
