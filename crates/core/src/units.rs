//! Length units and axis conventions.
//!
//! Capture files store lengths in millimetres (most C3D), metres (some TRC, OpenSim), or
//! centimetres and inches (BVH exporters). locap converts everything to millimetres on read;
//! [`LengthUnit`] records what a file used so it can be written back the same way.

use serde::{Deserialize, Serialize};

/// A unit of length as found in capture files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum LengthUnit {
    /// Millimetres (the C3D default and locap's internal unit).
    Millimetre,
    /// Centimetres.
    Centimetre,
    /// Metres.
    Metre,
    /// Inches.
    Inch,
}

impl LengthUnit {
    /// How many millimetres one unit is.
    pub fn mm_per_unit(self) -> f64 {
        match self {
            LengthUnit::Millimetre => 1.0,
            LengthUnit::Centimetre => 10.0,
            LengthUnit::Metre => 1000.0,
            LengthUnit::Inch => 25.4,
        }
    }

    /// Parses the unit strings used by C3D `POINT:UNITS` and TRC `Units` (case-insensitive,
    /// surrounding blanks ignored). Returns `None` for anything else.
    pub fn parse(text: &str) -> Option<LengthUnit> {
        match text.trim().to_ascii_lowercase().as_str() {
            "mm" | "millimeter" | "millimeters" | "millimetre" | "millimetres" => Some(LengthUnit::Millimetre),
            "cm" | "centimeter" | "centimeters" | "centimetre" | "centimetres" => Some(LengthUnit::Centimetre),
            "m" | "meter" | "meters" | "metre" | "metres" => Some(LengthUnit::Metre),
            "in" | "inch" | "inches" => Some(LengthUnit::Inch),
            _ => None,
        }
    }

    /// The short symbol written to files (`mm`, `cm`, `m`, `in`).
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Millimetre => "mm",
            LengthUnit::Centimetre => "cm",
            LengthUnit::Metre => "m",
            LengthUnit::Inch => "in",
        }
    }
}

impl std::fmt::Display for LengthUnit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.symbol())
    }
}

/// Which world axis points up. Vicon and most C3D files are Z-up; BVH and many game tools are
/// Y-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
pub enum UpAxis {
    /// +Y is up.
    Y,
    /// +Z is up (the C3D convention).
    #[default]
    Z,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_units_case_insensitively() {
        assert_eq!(LengthUnit::parse(" MM "), Some(LengthUnit::Millimetre));
        assert_eq!(LengthUnit::parse("m"), Some(LengthUnit::Metre));
        assert_eq!(LengthUnit::parse("cm"), Some(LengthUnit::Centimetre));
        assert_eq!(LengthUnit::parse("furlong"), None);
        assert_eq!(LengthUnit::Metre.mm_per_unit(), 1000.0);
    }
}
