//! Face regions (top / middle / bottom) and the blend bands between them.

use serde::{Deserialize, Serialize};
use std::fmt;

/// One of the three face regions solved separately: brows and eyes, nose and cheeks, mouth and jaw.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Region {
    /// Forehead, brows and eyes.
    Top,
    /// Nose and cheeks.
    Middle,
    /// Lips, chin and jaw.
    Bottom,
}

impl Region {
    /// All regions, top to bottom.
    pub const ALL: [Region; 3] = [Region::Top, Region::Middle, Region::Bottom];

    /// Position of this region in [`Region::ALL`].
    pub fn index(self) -> usize {
        match self {
            Region::Top => 0,
            Region::Middle => 1,
            Region::Bottom => 2,
        }
    }

    /// Lower-case name as written in config files.
    pub fn name(self) -> &'static str {
        match self {
            Region::Top => "top",
            Region::Middle => "middle",
            Region::Bottom => "bottom",
        }
    }
}

impl fmt::Display for Region {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Where the regions of a rig meet along its up axis (y), and how wide the blend band is.
///
/// Above `top_from` a vertex is in the top region, below `bottom_below` in the bottom region,
/// in between in the middle. Within `band / 2` of a border the two regions' weights ramp
/// linearly, so the weights of every vertex sum to one (a partition of unity) and no seam shows.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RegionBands {
    /// Height (rig units) above which a vertex belongs to the top region.
    pub top_from: f32,
    /// Height (rig units) below which a vertex belongs to the bottom region.
    pub bottom_below: f32,
    /// Full width (rig units) of the linear blend across each border; 0 gives hard borders.
    pub band: f32,
}

impl RegionBands {
    /// Range checks of a rig's `[regions]`: finite borders with `top_from > bottom_below`, and a
    /// band in `[0, top_from - bottom_below]` (the two blends may meet but not overlap).
    pub fn validate(&self) -> Result<(), crate::SettingError> {
        use crate::SettingError;
        for (key, v) in [
            ("regions.top_from", self.top_from),
            ("regions.bottom_below", self.bottom_below),
        ] {
            if !v.is_finite() {
                return Err(SettingError::new(key, v, "must be a finite number"));
            }
        }
        let middle = self.top_from - self.bottom_below;
        if middle <= 0.0 {
            return Err(SettingError::new(
                "regions.top_from",
                self.top_from,
                format!("must be above bottom_below = {}", self.bottom_below),
            ));
        }
        if !(self.band.is_finite() && self.band >= 0.0) {
            return Err(SettingError::new(
                "regions.band",
                self.band,
                "must be finite and >= 0",
            ));
        }
        if self.band > middle {
            return Err(SettingError::new(
                "regions.band",
                self.band,
                format!(
                    "must be at most top_from - bottom_below = {middle} (the blends would overlap)"
                ),
            ));
        }
        Ok(())
    }

    /// Blend weights `[top, middle, bottom]` of a vertex at height `y`; they sum to one.
    pub fn weights(&self, y: f32) -> [f32; 3] {
        let ramp = |border: f32| -> f32 {
            // 0 well below the border, 1 well above it.
            if self.band <= 0.0 {
                if y >= border { 1.0 } else { 0.0 }
            } else {
                ((y - border) / self.band + 0.5).clamp(0.0, 1.0)
            }
        };
        let above_top = ramp(self.top_from);
        let above_bottom = ramp(self.bottom_below);
        let top = above_top;
        let bottom = 1.0 - above_bottom;
        let middle = (1.0 - top - bottom).max(0.0);
        let sum = top + middle + bottom;
        [top / sum, middle / sum, bottom / sum]
    }

    /// The region with the largest weight at height `y`.
    pub fn region_at(&self, y: f32) -> Region {
        let w = self.weights(y);
        let mut best = 0;
        for r in 1..3 {
            if w[r] > w[best] {
                best = r;
            }
        }
        Region::ALL[best]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_partition_unity_and_ramp() {
        let b = RegionBands {
            top_from: 2.0,
            bottom_below: -2.0,
            band: 1.0,
        };
        for i in -100..100 {
            let y = i as f32 * 0.05;
            let w = b.weights(y);
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
            assert!(w.iter().all(|x| (0.0..=1.0).contains(x)));
        }
        assert_eq!(b.weights(5.0), [1.0, 0.0, 0.0]);
        assert_eq!(b.weights(0.0), [0.0, 1.0, 0.0]);
        assert_eq!(b.weights(-5.0), [0.0, 0.0, 1.0]);
        let w = b.weights(2.0);
        assert!((w[0] - 0.5).abs() < 1e-6 && (w[1] - 0.5).abs() < 1e-6);
        assert_eq!(b.region_at(3.0), Region::Top);
        assert_eq!(b.region_at(-3.0), Region::Bottom);
    }

    #[test]
    fn validate_refuses_nan_negative_and_overlapping_bands() {
        let ok = RegionBands {
            top_from: 1.0,
            bottom_below: 0.0,
            band: 0.5,
        };
        ok.validate().unwrap();
        RegionBands { band: 1.0, ..ok }.validate().unwrap();
        let err = |b: RegionBands| b.validate().unwrap_err().to_string();
        assert_eq!(
            err(RegionBands {
                band: f32::NAN,
                ..ok
            }),
            "regions.band = NaN: must be finite and >= 0"
        );
        assert_eq!(
            err(RegionBands { band: -0.1, ..ok }),
            "regions.band = -0.1: must be finite and >= 0"
        );
        assert!(
            err(RegionBands { band: 1.5, ..ok }).starts_with("regions.band = 1.5: must be at most")
        );
        assert_eq!(
            err(RegionBands {
                bottom_below: f32::INFINITY,
                ..ok
            }),
            "regions.bottom_below = inf: must be a finite number"
        );
        assert!(
            err(RegionBands {
                top_from: -1.0,
                ..ok
            })
            .starts_with("regions.top_from = -1: must be above")
        );
    }

    #[test]
    fn hard_borders_with_zero_band() {
        let b = RegionBands {
            top_from: 1.0,
            bottom_below: 0.0,
            band: 0.0,
        };
        assert_eq!(b.weights(1.0), [1.0, 0.0, 0.0]);
        assert_eq!(b.weights(0.5), [0.0, 1.0, 0.0]);
        assert_eq!(b.weights(-0.1), [0.0, 0.0, 1.0]);
    }
}
