//! A rig's `[blendshape_fit]` table: the terms of the fit of its morph targets' weights to the
//! control displacements (landmarks to ARKit weights; docs/quality.md, "Landmarks to ARKit weights").

use serde::{Deserialize, Serialize};

/// The weights of the fit's terms besides the data term, each relative to the target's own
/// squared deltas at the controls `|D_k|^2`, so that none depends on the rig's units or on how
/// far a target moves the controls. Absent keys take the defaults, chosen by leave-one-out on
/// two Live Link Face takes (docs/quality.md, "Landmarks to ARKit weights").
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BlendshapeFit {
    /// Ridge: adds `ridge |D_k|^2 w_k^2` (a lone target's weight shrinks to `w / (1 + ridge)`).
    pub ridge: f64,
    /// L1: adds `2 l1 |D_k|^2 w_k` (a lone target's weight drops by `l1`, to 0 at most).
    pub l1: f64,
    /// Temporal: adds `temporal |D_k|^2 (w_k - p_k)^2`, `p` the previous frame's fitted weights
    /// (a lone target's weight is `(w + temporal p) / (1 + temporal)`).
    pub temporal: f64,
    /// Symmetry: adds `symmetry |D_L| |D_R| (w_L - w_R)^2` over each left/right pair of ARKit
    /// shapes ([`crate::arkit::mirror_pairs`]).
    pub symmetry: f64,
}

impl BlendshapeFit {
    /// The fit before the `[blendshape_fit]` table existed: a ridge of 0.01 and nothing else.
    pub const RIDGE_ONLY: Self = Self {
        ridge: 0.01,
        l1: 0.0,
        temporal: 0.0,
        symmetry: 0.0,
    };

    /// The defaults: picked on both Live Link Face takes of tests/data/livelinkface; their
    /// leave-one-out figures are in docs/quality.md, "Landmarks to ARKit weights" (no L1: no
    /// setting of it helped on either take).
    pub const DEFAULT: Self = Self {
        ridge: 0.03,
        l1: 0.0,
        temporal: 0.3,
        symmetry: 1.0,
    };

    /// Range check: every weight finite and `>= 0`.
    pub fn validate(&self) -> Result<(), crate::SettingError> {
        for (key, v) in [
            ("blendshape_fit.ridge", self.ridge),
            ("blendshape_fit.l1", self.l1),
            ("blendshape_fit.temporal", self.temporal),
            ("blendshape_fit.symmetry", self.symmetry),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(crate::SettingError::new(key, v, "must be finite and >= 0"));
            }
        }
        Ok(())
    }
}

impl Default for BlendshapeFit {
    fn default() -> Self {
        Self::DEFAULT
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absent_keys_take_the_defaults_and_bad_values_are_refused() {
        let f: BlendshapeFit = serde_json::from_str(r#"{"l1": 0.5}"#).unwrap();
        assert_eq!(
            f,
            BlendshapeFit {
                l1: 0.5,
                ..BlendshapeFit::DEFAULT
            }
        );
        assert!(f.validate().is_ok());
        assert!(serde_json::from_str::<BlendshapeFit>(r#"{"lasso": 1.0}"#).is_err());
        let bad = BlendshapeFit {
            symmetry: -1.0,
            ..BlendshapeFit::DEFAULT
        };
        assert_eq!(bad.validate().unwrap_err().key, "blendshape_fit.symmetry");
    }
}
