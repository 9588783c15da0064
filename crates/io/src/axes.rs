//! The axes and units each writer uses, and the conversions into them.
//!
//! locap keeps lengths in millimetres and a take in its lab's own axes (C3D labs are Z-up,
//! [`Take::up_axis`] says which). Animation and biomechanics tools want Y-up: Blender,
//! MotionBuilder and Maya import BVH and FBX as Y-up, glTF 2.0 is Y-up by definition
//! (specification section 3.4, "Coordinate System and Units": "glTF uses a right-handed
//! coordinate system ... +Y is up ... the units for all linear distances are meters"), and
//! OpenSim models are Y-up. The one Y-up frame every writer here uses for a Z-up lab is
//! [`locap_core::units::z_up_to_tools_y_up`]: lab `(x, y, z)` is written `(x, z, -y)`, so the
//! tools' own Y-up to Z-up import puts the data back where it was in the lab.
//!
//! | output | axes | lengths | angles |
//! | --- | --- | --- | --- |
//! | C3D, TRC, CSV | the take's (`--up` converts) | mm (TRC: `--trc-unit`) | - |
//! | BVH | Y-up | `--bvh-unit`, cm by default | degrees |
//! | glTF / GLB | Y-up, +Z forward of the asset | metres | quaternions |
//! | FBX | Y-up (`GlobalSettings`) | centimetres (`UnitScaleFactor` 1) | degrees |
//! | OpenSim `.mot` | Y-up | metres | degrees (`inDegrees=yes`) |

use crate::c3d::C3dFile;
use crate::{Error, Result};
use locap_core::units::{tools_y_up_to_z_up, z_up_to_tools_y_up, z_up_to_tools_y_up_rotation};
use locap_core::{Motion, Quat, Take, UpAxis, Vec3};

/// `p`, a point of a frame whose vertical axis is `from`, in a frame whose vertical axis is
/// `to` (the tools' convention between Z-up and Y-up, see the module doc).
pub fn convert_point(p: Vec3, from: UpAxis, to: UpAxis) -> Vec3 {
    match (from, to) {
        (UpAxis::Z, UpAxis::Y) => z_up_to_tools_y_up(p),
        (UpAxis::Y, UpAxis::Z) => tools_y_up_to_z_up(p),
        _ => p,
    }
}

/// The rotation [`convert_point`] applies.
pub fn conversion_rotation(from: UpAxis, to: UpAxis) -> Quat {
    match (from, to) {
        (UpAxis::Z, UpAxis::Y) => z_up_to_tools_y_up_rotation(),
        (UpAxis::Y, UpAxis::Z) => z_up_to_tools_y_up_rotation().inverse(),
        _ => Quat::identity(),
    }
}

/// `take` with its markers turned so that `up` is its vertical axis (a copy of `take` if it
/// already is); missing samples stay missing, qualities are kept.
pub fn take_with_up_axis(take: &Take, up: UpAxis) -> Take {
    let mut out = take.clone();
    if take.up_axis == up {
        return out;
    }
    for f in 0..take.frame_count() {
        for m in 0..take.marker_count() {
            if let Some(p) = take.position_mm(f, m) {
                // A rotation of a finite point is finite, so this cannot fail.
                let _ = out.set_position_mm(f, m, Some(convert_point(p, take.up_axis, up)));
                out.set_quality(f, m, take.quality(f, m));
            }
        }
    }
    out.up_axis = up;
    out
}

/// Turns a whole C3D file's markers so that `up` is its vertical axis, and says so in
/// `POINT:X_SCREEN` / `POINT:Y_SCREEN` (C3D User Guide, "The POINT group"), keeping every
/// other parameter and the analog data.
///
/// A file with force plates is refused: their corners and origins are lab coordinates too,
/// and turning the markers without them would misplace every force.
pub fn set_c3d_up_axis(file: &mut C3dFile, up: UpAxis) -> Result<()> {
    let plates = file.parameters.get("FORCE_PLATFORM", "USED").and_then(|p| p.as_i64()).unwrap_or(0);
    if plates > 0 && file.up_axis() != up {
        return Err(Error::Unsupported(format!(
            "turning a C3D file with {plates} force plates to another up axis (their corners would stay in lab axes)"
        )));
    }
    let take = file.to_take()?;
    file.set_take(&take_with_up_axis(&take, up))?;
    file.parameters.set_strings("POINT", "X_SCREEN", &["+X".to_string()]);
    let screen = match up {
        UpAxis::Y => "+Y",
        UpAxis::Z => "+Z",
    };
    file.parameters.set_strings("POINT", "Y_SCREEN", &[screen.to_string()]);
    Ok(())
}

/// A solved motion moved into the tools' Y-up frame: `to_lab` takes the motion's own frame to
/// the lab's (whose vertical axis is `lab_up`), then the lab goes to Y-up as
/// [`take_with_up_axis`] moves its markers, so the character stands where its markers stood.
pub fn motion_to_tools_y_up(motion: &Motion, to_lab: Quat, lab_up: UpAxis) -> Motion {
    motion.rotated(conversion_rotation(lab_up, UpAxis::Y) * to_lab)
}

/// The inverse of [`motion_to_tools_y_up`]: a motion read from the tools' Y-up frame (a BVH
/// `locap solve` wrote) back in its own frame, for comparing with a reference solution or
/// drawing over the lab's markers.
pub fn motion_from_tools_y_up(motion: &Motion, to_lab: Quat, lab_up: UpAxis) -> Motion {
    motion.rotated((conversion_rotation(lab_up, UpAxis::Y) * to_lab).inverse())
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{Joint, MarkerName, Skeleton};

    #[test]
    fn markers_and_motion_move_together() {
        let take = Take::from_samples(
            vec![MarkerName::parse("A"), MarkerName::parse("B")],
            &[Some(Vec3::new(1.0, 2.0, 3.0)), None],
            100.0,
        )
        .unwrap();
        let y = take_with_up_axis(&take, UpAxis::Y);
        assert_eq!(y.up_axis, UpAxis::Y);
        assert_eq!(y.position_mm(0, 0), Some(Vec3::new(1.0, 3.0, -2.0)));
        assert_eq!(y.position_mm(0, 1), None);
        assert_eq!(take_with_up_axis(&y, UpAxis::Z).position_mm(0, 0), take.position_mm(0, 0));

        // A motion whose frame is CMU's Y-up (lab = (z, x, y)) lands on the Y-up markers.
        let sk = Skeleton::new(vec![Joint::new("root", None, Vec3::zeros())]).unwrap();
        let motion = Motion::new(sk, vec![Quat::identity()], vec![Vec3::new(2.0, 3.0, 1.0)], 100.0).unwrap();
        let to_lab = locap_core::units::y_up_to_z_up_rotation();
        let moved = motion_to_tools_y_up(&motion, to_lab, UpAxis::Z);
        assert!((moved.root_position_mm(0) - Vec3::new(1.0, 3.0, -2.0)).norm() < 1e-12);
        let back = motion_from_tools_y_up(&moved, to_lab, UpAxis::Z);
        assert!((back.root_position_mm(0) - motion.root_position_mm(0)).norm() < 1e-12);
        assert!(back.local_rotations(0)[0].angle_to(&Quat::identity()) < 1e-12);
    }
}
