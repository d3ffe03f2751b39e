//! A rig's `units` as metres, glTF's unit.

use mimic_types::rig::unit_in_metres;

/// Metres per `model` unit: a mesh with no physical unit (CANDIDE-3's, its face about 1.2
/// units wide) is exported as decimetres, so such a face comes out about 12 cm wide.
pub const MODEL_UNIT_METRES: f32 = 0.1;

/// Metres per unit for a rig's `units` name (one of `mimic_types::rig::RIG_UNITS`: `m`, `cm`,
/// `mm`, `in`, and `model`, taken as [`MODEL_UNIT_METRES`]); `None` for a name not in that table.
pub fn metres_per_unit(units: &str) -> Option<f32> {
    match units {
        "model" => Some(MODEL_UNIT_METRES),
        other => unit_in_metres(other).map(|m| m as f32),
    }
}

/// A rig whose units have no length in metres.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("rig `{rig}`: units `{units}` have no length in metres for glTF")]
pub struct UnitsError {
    /// The rig's name.
    pub rig: String,
    /// Its units.
    pub units: String,
}

/// [`metres_per_unit`] of a rig's units, or an error naming the rig.
pub fn rig_metres_per_unit(rig: &mimic_types::Rig) -> Result<f32, UnitsError> {
    metres_per_unit(&rig.units).ok_or_else(|| UnitsError {
        rig: rig.name.clone(),
        units: rig.units.clone(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_rigs_units_are_known() {
        assert_eq!(metres_per_unit("cm"), Some(0.01));
        assert_eq!(metres_per_unit("in"), Some(0.0254));
        assert_eq!(metres_per_unit("model"), Some(MODEL_UNIT_METRES));
        assert_eq!(metres_per_unit("furlong"), None);
    }
}
