//! Acclaim skeleton (ASF) and motion (AMC) files, as in the CMU motion capture database.
//!
//! An ASF file describes bones: each has a rest `direction` (a unit vector in the world frame)
//! and `length`, a local frame given by `axis a b c ORDER`, and the rotational degrees of
//! freedom (`dof rx ry rz`) that an AMC file animates. An AMC file lists, per frame number,
//! one line per bone with its dof values in the ASF's dof order (`root` has six: the ASF
//! root `order`, e.g. `TX TY TZ RX RY RZ`).
//!
//! # Conventions (Acclaim)
//! - **Euler angles are applied in the order they are listed**: `axis a b c XYZ` rotates a
//!   vector about X by `a` first, then Y by `b`, then Z by `c`, i.e. the matrix is
//!   `C = Rz(c) * Ry(b) * Rx(a)`; the dof values of a bone build `M` the same way from the
//!   dof order. (This is the reverse of the core [`EulerOrder`] product for the same letters.
//!   It was checked against CMU take 01_01: with it the C3D markers stay rigidly attached to
//!   the bones (marker-to-joint distances vary by 3-15 mm std over the take); with the
//!   reverse product they drift (75-180 mm std).)
//! - A bone's rotation relative to its parent is `L = C * M * C^-1`, its global rotation
//!   `R = R_parent * L`, and its tip is `start + R * direction * length`, where `start` is the
//!   parent bone's tip (the root's position for the root's children).
//! - **Mapping to [`locap_core::Skeleton`]**: joint 0 is `root`; every bone becomes a joint at
//!   its *start*, whose local rotation is `L` and whose offset is the parent bone's
//!   `direction * length` (zero for children of the root); every leaf bone gets an extra end
//!   site joint `<bone>_End` at its tip. Because `L` is the identity at rest, core offsets in
//!   the parent frame are exactly the ASF world-frame rest vectors. The root joint's rotation
//!   is `C_root * M_root * C_root^-1` with `C_root` from the root's `orientation` (in its
//!   `axis` order) and `M_root` from the AMC `RX RY RZ` values (in the root's `order`); its
//!   position is the AMC `TX TY TZ` (the ASF root `position` where the AMC gives none).
//! - **Units.** ASF lengths are in units of `1/length` inches, where `length` is the
//!   `:units length` value (CMU uses 0.45), so one unit is `25.4 / length` mm: see
//!   [`AsfSkeleton::mm_per_unit`]. Angles are in the `:units angle` unit (`deg` or `rad`);
//!   this reader converts each to radians once, as it reads it (an ASF's after the whole
//!   file, so its `:units` section applies wherever it stands), and stores radians. An AMC's
//!   `:DEGREES`/`:RADIANS` header decides its angle unit; without one, the ASF's applies.
//! - **Frame rate.** AMC files do not store one; the caller supplies it (CMU captures are
//!   120 Hz).
//! - **Strictness.** Frame numbers must be consecutive, every bone line must name a bone of
//!   the ASF and have one value per dof, a bone may appear once per frame, and values must be
//!   finite. A bone missing from a frame is read at its rest rotation (all dofs zero), as a
//!   not fully specified AMC intends. Errors name the 1-based line (and column for values).
//! - **Not supported:** translation and length dofs on bones (`tx`, `ty`, `tz`, `l`), which
//!   give an [`Error::Unsupported`] when an AMC is read against such a skeleton.
//! - **Limits.** The `*_with` readers check the bone count and the `:hierarchy` depth against
//!   [`Limits`](crate::limits::Limits), and an AMC's frames × joints against
//!   [`Limits::max_samples`](crate::limits::Limits::max_samples) and against the AMC text's
//!   size (bones left out of a frame are samples no byte backs; see [`crate::limits`]), frame
//!   by frame before the frame is stored.
//!
//! The module holds what both files share: the Acclaim rotation convention, the angle unit
//! (the one place where angles change unit: [`AngleUnit`]'s conversion to radians, applied
//! once to every angle as it is read), the dofs and the line reader; [`asf`] reads skeletons,
//! [`amc`] motions. Everything is re-exported here.

pub mod amc;
pub mod asf;

pub use amc::{read_amc, read_amc_path, read_amc_path_with, read_amc_scaled, read_amc_scaled_with};
pub use asf::{AsfBone, AsfRoot, AsfSkeleton, AsfUnits, read_asf, read_asf_path, read_asf_path_with, read_asf_with};

use crate::{Error, Result};
use locap_core::rotation::axis_rotation;
use locap_core::{EulerOrder, Quat};

/// Angle unit of an Acclaim file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AngleUnit {
    /// Degrees (`deg`, `:DEGREES`).
    Degree,
    /// Radians (`rad`, `:RADIANS`).
    Radian,
}

impl AngleUnit {
    /// `value`, in this unit, in radians. Every angle of an ASF or AMC file goes through here
    /// once, when it is read; everything after works in radians.
    fn to_radians(self, value: f64) -> f64 {
        match self {
            AngleUnit::Degree => value.to_radians(),
            AngleUnit::Radian => value,
        }
    }
}

/// One degree of freedom of a bone or of the root.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Dof {
    /// Rotation about X (`rx`).
    Rx,
    /// Rotation about Y (`ry`).
    Ry,
    /// Rotation about Z (`rz`).
    Rz,
    /// Translation along X (`tx`).
    Tx,
    /// Translation along Y (`ty`).
    Ty,
    /// Translation along Z (`tz`).
    Tz,
    /// Bone length change (`l`).
    L,
}

impl Dof {
    fn parse(text: &str) -> Option<Dof> {
        match text.to_ascii_lowercase().as_str() {
            "rx" => Some(Dof::Rx),
            "ry" => Some(Dof::Ry),
            "rz" => Some(Dof::Rz),
            "tx" => Some(Dof::Tx),
            "ty" => Some(Dof::Ty),
            "tz" => Some(Dof::Tz),
            "l" => Some(Dof::L),
            _ => None,
        }
    }

    /// The axis of a rotation dof (0 = X, 1 = Y, 2 = Z).
    fn rotation_axis(self) -> Option<usize> {
        match self {
            Dof::Rx => Some(0),
            Dof::Ry => Some(1),
            Dof::Rz => Some(2),
            _ => None,
        }
    }

    fn translation_axis(self) -> Option<usize> {
        match self {
            Dof::Tx => Some(0),
            Dof::Ty => Some(1),
            Dof::Tz => Some(2),
            _ => None,
        }
    }
}

/// Rotation applying `angles_rad` about `axes` in the listed order (the first one first to a
/// vector): the Acclaim convention, `R = R_last * ... * R_first`.
fn acclaim_rotation(axes_angles: impl IntoIterator<Item = (usize, f64)>) -> Quat {
    let mut q = Quat::identity();
    for (axis, angle_rad) in axes_angles {
        q = axis_rotation(axis, angle_rad) * q;
    }
    q
}

/// `C` of an `axis` line.
fn axis_frame(order: EulerOrder, angles_rad: [f64; 3]) -> Quat {
    acclaim_rotation(order.axes().into_iter().zip(angles_rad))
}

/// The core order with the same matrix product as Acclaim letters `order` (reversed letters).
fn reversed(order: EulerOrder) -> EulerOrder {
    let [a, b, c] = order.axes();
    EulerOrder::from_axes([c, b, a]).unwrap_or(order)
}

/// Lines without `\r`, numbered from 1, comments (`#`) and blank lines dropped. Lines keep
/// their indentation so that reported columns match what an editor shows.
fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.split('\n').enumerate().filter_map(|(i, l)| {
        let l = l.strip_suffix('\r').unwrap_or(l);
        let t = l.trim();
        (!t.is_empty() && !t.starts_with('#')).then_some((i + 1, l))
    })
}

/// Words of a line with their 1-based (byte) columns in that line.
fn words<'a>(raw: &'a str) -> impl Iterator<Item = (usize, &'a str)> + 'a {
    let base = raw.as_ptr() as usize;
    raw.split_whitespace().map(move |w| (w.as_ptr() as usize - base + 1, w))
}

fn text_err(format: &'static str, line: usize, column: Option<usize>, message: impl Into<String>) -> Error {
    Error::Text { format, line, column, message: message.into() }
}

/// A finite number (or, where `allow_inf`, an infinite limit).
fn num(format: &'static str, line: usize, col: usize, word: &str, what: &str, allow_inf: bool) -> Result<f64> {
    match word.parse::<f64>() {
        Ok(v) if v.is_finite() || (allow_inf && v.is_infinite()) => Ok(v),
        _ => Err(text_err(format, line, Some(col), format!("expected a number for {what}, found {word:?}"))),
    }
}
