//! Length units and axis conventions.
//!
//! Capture files store lengths in millimetres (most C3D), metres (some TRC, OpenSim), or
//! centimetres and inches (BVH exporters). locap converts everything to millimetres on read;
//! [`LengthUnit`] records what a file used so it can be written back the same way.
//!
//! Vertical axes differ too: C3D labs are Z-up, BVH, ASF/AMC and three.js Y-up. [`UpAxis`]
//! says which a take uses, and [`y_up_to_z_up`] / [`z_up_to_y_up`] are the one convention
//! every crate converts between them with.

use crate::{Quat, Vec3};
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

/// The lab convention between Y-up and Z-up frames, defined once for every stage: a Y-up
/// point `(x, y, z)` (BVH, ASF/AMC, three.js) is the Z-up point `(z, x, y)` (C3D, Vicon).
///
/// Any rotation taking Y to Z would do for markers alone; this one (a cyclic swap of the
/// axes, a rotation with no mirroring) is the one under which CMU's AMC motions land on the
/// markers of their C3D takes (measured on CMU 01_01, see `locap_io`'s `amc_matches_c3d`
/// test), so motions, synthetic takes and the viewer agree with CMU's data.
pub fn y_up_to_z_up(p: Vec3) -> Vec3 {
    Vec3::new(p.z, p.x, p.y)
}

/// The inverse of [`y_up_to_z_up`]: a Z-up point `(x, y, z)` is the Y-up point `(y, z, x)`.
pub fn z_up_to_y_up(p: Vec3) -> Vec3 {
    Vec3::new(p.y, p.z, p.x)
}

/// [`y_up_to_z_up`] as a rotation (for poses and orientations).
pub fn y_up_to_z_up_rotation() -> Quat {
    let m = nalgebra::Matrix3::new(0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0);
    Quat::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(m))
}

/// The Y-up frame of animation and biomechanics tools (Blender's and MotionBuilder's BVH
/// import, glTF 2.0 section 3.4 "Coordinate System and Units", FBX with `UpAxis` 1, OpenSim):
/// a Z-up lab point `(x, y, z)` is the Y-up point `(x, z, -y)`, a rotation of -90 degrees
/// about X.
///
/// It differs from the lab convention of [`z_up_to_y_up`] on purpose: that cyclic swap is how
/// CMU's skeletons sit in their labs; this one is what the tools undo when they import Y-up
/// data into a Z-up scene (Blender maps Y-up `(x, y, z)` to its `(x, -z, y)`), so a motion
/// written in it lands in the tool exactly where its markers were in the lab, upright and
/// facing the way the markers face.
pub fn z_up_to_tools_y_up(p: Vec3) -> Vec3 {
    Vec3::new(p.x, p.z, -p.y)
}

/// The inverse of [`z_up_to_tools_y_up`]: a tools' Y-up point `(x, y, z)` is the Z-up lab
/// point `(x, -z, y)`.
pub fn tools_y_up_to_z_up(p: Vec3) -> Vec3 {
    Vec3::new(p.x, -p.z, p.y)
}

/// [`z_up_to_tools_y_up`] as a rotation (for poses and orientations).
pub fn z_up_to_tools_y_up_rotation() -> Quat {
    Quat::from_axis_angle(&Vec3::x_axis(), -std::f64::consts::FRAC_PI_2)
}

impl UpAxis {
    /// A point of a frame whose vertical axis is `self` in Y-up axes ([`z_up_to_y_up`] for
    /// Z-up, unchanged for Y-up).
    pub fn to_y_up(self, p: Vec3) -> Vec3 {
        match self {
            UpAxis::Y => p,
            UpAxis::Z => z_up_to_y_up(p),
        }
    }
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

    #[test]
    fn the_lab_convention_is_one_rotation_and_its_inverse() {
        let p = Vec3::new(1.0, 2.0, 3.0);
        // Y-up "up" (0, 1, 0) is Z-up "up" (0, 0, 1).
        assert_eq!(y_up_to_z_up(Vec3::y()), Vec3::z());
        assert_eq!(y_up_to_z_up(p), Vec3::new(3.0, 1.0, 2.0));
        assert_eq!(z_up_to_y_up(y_up_to_z_up(p)), p);
        assert!((y_up_to_z_up_rotation() * p - y_up_to_z_up(p)).norm() < 1e-12);
        assert_eq!(UpAxis::Z.to_y_up(Vec3::z()), Vec3::y());
        assert_eq!(UpAxis::Y.to_y_up(p), p);
    }

    #[test]
    fn the_tools_convention_keeps_x_and_turns_z_up_into_y_up() {
        let p = Vec3::new(1.0, 2.0, 3.0);
        assert_eq!(z_up_to_tools_y_up(Vec3::z()), Vec3::y());
        assert_eq!(z_up_to_tools_y_up(Vec3::x()), Vec3::x());
        // The lab's +Y (often "forward" in a Z-up lab) becomes -Z, Blender's forward on import.
        assert_eq!(z_up_to_tools_y_up(Vec3::y()), -Vec3::z());
        assert_eq!(tools_y_up_to_z_up(z_up_to_tools_y_up(p)), p);
        assert!((z_up_to_tools_y_up_rotation() * p - z_up_to_tools_y_up(p)).norm() < 1e-12);
    }
}
