//! Euler angle orders, as BVH channels and ASF/AMC `axis`/`order` lines use them.
//!
//! An order `ZXY` means the rotation `R = Rz(a1) * Rx(a2) * Ry(a3)` where `a1..a3` are the
//! angles in the order the file lists them: intrinsic rotations applied left to right, the
//! convention of BVH channels (`Zrotation Xrotation Yrotation`). Acclaim ASF/AMC lists its
//! axes the other way round (`axis a b c XYZ` applies X first to a vector, i.e. the matrix
//! `Rz * Ry * Rx`, the `ZYX` order here); `locap_io::asf_amc` converts, as checked against the
//! CMU markers. Only the six Tait-Bryan orders occur in capture files.

use crate::Quat;
use nalgebra::{Matrix3, Unit, Vector3};
use serde::{Deserialize, Serialize};

/// A Tait-Bryan rotation order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum EulerOrder {
    /// `Rx * Ry * Rz`.
    XYZ,
    /// `Rx * Rz * Ry`.
    XZY,
    /// `Ry * Rx * Rz`.
    YXZ,
    /// `Ry * Rz * Rx`.
    YZX,
    /// `Rz * Rx * Ry` (the usual BVH root/joint order).
    ZXY,
    /// `Rz * Ry * Rx`.
    ZYX,
}

impl EulerOrder {
    /// Axis indices (0 = X, 1 = Y, 2 = Z) in product order.
    pub fn axes(self) -> [usize; 3] {
        match self {
            EulerOrder::XYZ => [0, 1, 2],
            EulerOrder::XZY => [0, 2, 1],
            EulerOrder::YXZ => [1, 0, 2],
            EulerOrder::YZX => [1, 2, 0],
            EulerOrder::ZXY => [2, 0, 1],
            EulerOrder::ZYX => [2, 1, 0],
        }
    }

    /// The order whose product uses these axes; `None` if an axis repeats.
    pub fn from_axes(axes: [usize; 3]) -> Option<EulerOrder> {
        [EulerOrder::XYZ, EulerOrder::XZY, EulerOrder::YXZ, EulerOrder::YZX, EulerOrder::ZXY, EulerOrder::ZYX]
            .into_iter()
            .find(|o| o.axes() == axes)
    }

    /// Parses `"XYZ"`, `"zxy"`, ... .
    pub fn parse(text: &str) -> Option<EulerOrder> {
        let letters: Vec<usize> = text
            .trim()
            .chars()
            .map(|c| match c.to_ascii_uppercase() {
                'X' => Some(0),
                'Y' => Some(1),
                'Z' => Some(2),
                _ => None,
            })
            .collect::<Option<_>>()?;
        let axes: [usize; 3] = letters.try_into().ok()?;
        EulerOrder::from_axes(axes)
    }

    /// The three letters, e.g. `"ZXY"`.
    pub fn name(self) -> &'static str {
        match self {
            EulerOrder::XYZ => "XYZ",
            EulerOrder::XZY => "XZY",
            EulerOrder::YXZ => "YXZ",
            EulerOrder::YZX => "YZX",
            EulerOrder::ZXY => "ZXY",
            EulerOrder::ZYX => "ZYX",
        }
    }

    /// The rotation for angles in degrees, listed in this order.
    pub fn to_quat_deg(self, angles_deg: [f64; 3]) -> Quat {
        let axes = self.axes();
        let mut q = Quat::identity();
        for (axis, angle) in axes.iter().zip(angles_deg) {
            q *= axis_rotation(*axis, angle.to_radians());
        }
        q
    }

    /// Angles in degrees (listed in this order) of a rotation; the inverse of
    /// [`EulerOrder::to_quat_deg`]. The middle angle lies in `[-90, 90]`; at gimbal lock the
    /// last angle is set to 0.
    pub fn from_quat_deg(self, q: &Quat) -> [f64; 3] {
        let r: Matrix3<f64> = q.to_rotation_matrix().into_inner();
        let [i, j, k] = self.axes();
        // +1 for cyclic orders (XYZ, YZX, ZXY), -1 for the others.
        let s = if (j + 3 - i) % 3 == 1 { 1.0 } else { -1.0 };
        let sin_b = (s * r[(i, k)]).clamp(-1.0, 1.0);
        let b = sin_b.asin();
        let (a, c);
        if sin_b.abs() < 1.0 - 1e-10 {
            a = (-s * r[(j, k)]).atan2(r[(k, k)]);
            c = (-s * r[(i, j)]).atan2(r[(i, i)]);
        } else {
            a = (s * r[(k, j)]).atan2(r[(j, j)]);
            c = 0.0;
        }
        [a.to_degrees(), b.to_degrees(), c.to_degrees()]
    }
}

impl std::fmt::Display for EulerOrder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Rotation by `angle_rad` about world axis `axis` (0 = X, 1 = Y, 2 = Z).
pub fn axis_rotation(axis: usize, angle_rad: f64) -> Quat {
    let mut v = Vector3::zeros();
    v[axis] = 1.0;
    Quat::from_axis_angle(&Unit::new_unchecked(v), angle_rad)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    const ORDERS: [EulerOrder; 6] =
        [EulerOrder::XYZ, EulerOrder::XZY, EulerOrder::YXZ, EulerOrder::YZX, EulerOrder::ZXY, EulerOrder::ZYX];

    #[test]
    fn hand_computed_rotations() {
        // 90 degrees about Z maps X to Y.
        let q = EulerOrder::ZXY.to_quat_deg([90.0, 0.0, 0.0]);
        assert_relative_eq!(q * Vector3::x(), Vector3::y(), epsilon = 1e-12);
        // Rx(90) * Ry(90): Ry first maps X to -Z, then Rx maps -Z to Y.
        let q = EulerOrder::XYZ.to_quat_deg([90.0, 90.0, 0.0]);
        assert_relative_eq!(q * Vector3::x(), Vector3::y(), epsilon = 1e-12);
        assert_eq!(EulerOrder::parse("zxy"), Some(EulerOrder::ZXY));
        assert_eq!(EulerOrder::parse("XXY"), None);
    }

    #[test]
    fn gimbal_lock_round_trips() {
        for order in ORDERS {
            let q = order.to_quat_deg([30.0, 90.0, 0.0]);
            let back = order.to_quat_deg(order.from_quat_deg(&q));
            assert!(q.angle_to(&back) < 1e-6, "{order}");
        }
    }

    proptest! {
        #[test]
        fn euler_round_trip(a in -180.0f64..180.0, b in -89.0f64..89.0, c in -180.0f64..180.0, o in 0usize..6) {
            let order = ORDERS[o];
            let q = order.to_quat_deg([a, b, c]);
            let angles = order.from_quat_deg(&q);
            let back = order.to_quat_deg(angles);
            prop_assert!(q.angle_to(&back) < 1e-9);
            prop_assert!((angles[1] - b).abs() < 1e-6);
        }
    }
}
