//! A rig's `units` as metres, glTF's unit.

/// Metres per unit for a rig's `units` name (`m`, `cm`, `mm`, `in`, and `candide`: the
/// CANDIDE-3 model's units, about 10 cm each, from its face about 1.2 units wide); `None` for a
/// name not in this table.
pub fn metres_per_unit(units: &str) -> Option<f32> {
    match units.trim().to_ascii_lowercase().as_str() {
        "m" | "metre" | "metres" | "meter" | "meters" => Some(1.0),
        "cm" | "centimetre" | "centimetres" | "centimeter" | "centimeters" => Some(0.01),
        "mm" | "millimetre" | "millimetres" | "millimeter" | "millimeters" => Some(0.001),
        "in" | "inch" | "inches" => Some(0.0254),
        "candide" => Some(0.1),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_rigs_units_are_known() {
        assert_eq!(metres_per_unit("cm"), Some(0.01));
        assert_eq!(metres_per_unit(" M "), Some(1.0));
        assert_eq!(metres_per_unit("candide"), Some(0.1));
        assert_eq!(metres_per_unit("furlong"), None);
    }
}
