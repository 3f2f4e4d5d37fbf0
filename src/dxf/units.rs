//! Drawing units: `$INSUNITS` codes and `--units` names, as millimetres per
//! drawing unit.

/// Millimetres per unit for an `$INSUNITS` code; `None` for 0 (unitless)
/// and codes we do not know.
pub fn insunits_mm(code: i64) -> Option<f64> {
    Some(match code {
        1 => 25.4,
        2 => 304.8,
        3 => 1_609_344.0,
        4 => 1.0,
        5 => 10.0,
        6 => 1000.0,
        7 => 1_000_000.0,
        8 => 25.4e-6,
        9 => 0.0254,
        10 => 914.4,
        11 => 1e-7,
        12 => 1e-6,
        13 => 1e-3,
        14 => 100.0,
        15 => 10_000.0,
        16 => 100_000.0,
        _ => return None,
    })
}

/// Millimetres per unit for a unit name given on the command line.
pub fn named_mm(name: &str) -> Option<f64> {
    Some(match name.to_ascii_lowercase().as_str() {
        "mm" | "millimeter" | "millimetre" => 1.0,
        "cm" => 10.0,
        "m" => 1000.0,
        "in" | "inch" | "inches" => 25.4,
        "ft" | "foot" | "feet" => 304.8,
        "um" | "µm" | "micron" | "microns" => 1e-3,
        "nm" => 1e-6,
        "mil" | "thou" => 0.0254,
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_units() {
        assert_eq!(insunits_mm(1), Some(25.4));
        assert_eq!(insunits_mm(0), None);
        assert_eq!(named_mm("Inch"), Some(25.4));
        assert_eq!(named_mm("µm"), Some(1e-3));
        assert_eq!(named_mm("parsec"), None);
    }
}
