//! AMC motions: per frame, each bone's dof values, read against an ASF skeleton into a core
//! [`Motion`] (see the parent module for the conventions).

use super::asf::AsfSkeleton;
use super::{AngleUnit, Dof, acclaim_rotation, axis_frame, content_lines, num, text_err, words};
use crate::limits::{self, Limits};
use crate::{Error, Result};
use locap_core::{Motion, Quat, Vec3};
use std::collections::HashMap;
use std::path::Path;

const AMC: &str = "AMC";

/// Reads an AMC file's text against its skeleton, at `frame_rate_hz` (AMC files do not say;
/// CMU captures are 120 Hz). Root translations are scaled by [`AsfSkeleton::mm_per_unit`].
pub fn read_amc(text: &str, asf: &AsfSkeleton, frame_rate_hz: f64) -> Result<Motion> {
    read_amc_scaled(text, asf, frame_rate_hz, asf.mm_per_unit())
}

/// [`read_amc`] with an explicit length scale, to match [`AsfSkeleton::to_skeleton`].
pub fn read_amc_scaled(text: &str, asf: &AsfSkeleton, frame_rate_hz: f64, mm_per_length_unit: f64) -> Result<Motion> {
    read_amc_scaled_with(text, asf, frame_rate_hz, mm_per_length_unit, &Limits::default())
}

/// [`read_amc_scaled`] with explicit [`Limits`] on frames and samples (frames × joints).
pub fn read_amc_scaled_with(
    text: &str,
    asf: &AsfSkeleton,
    frame_rate_hz: f64,
    mm_per_length_unit: f64,
    limits: &Limits,
) -> Result<Motion> {
    // Checked first: a rate the caller got wrong should not cost a pass over the file.
    if !(frame_rate_hz.is_finite() && frame_rate_hz > 0.0) {
        return Err(locap_core::SkeletonError::BadFrameRate(frame_rate_hz).into());
    }
    let skeleton = asf.to_skeleton(mm_per_length_unit)?;
    for bone in &asf.bones {
        if bone.dof.iter().any(|d| d.rotation_axis().is_none()) {
            return Err(Error::Unsupported(format!(
                "bone {:?} has translation or length dofs, which locap does not read",
                bone.name
            )));
        }
    }
    if asf.root.order.contains(&Dof::L) {
        return Err(Error::Unsupported("root dof \"l\"".into()));
    }
    let s = mm_per_length_unit;
    let joints = skeleton.len();
    let bone_count = asf.bones.len();
    // Slot 0 is the root; slot i + 1 is bone i. Value vectors are reused frame to frame.
    let mut slots: HashMap<&str, usize> = HashMap::with_capacity(bone_count + 1);
    slots.insert("root", 0);
    for (i, b) in asf.bones.iter().enumerate() {
        slots.insert(b.name.as_str(), i + 1);
    }
    let dofs: Vec<&[Dof]> =
        std::iter::once(asf.root.order.as_slice()).chain(asf.bones.iter().map(|b| b.dof.as_slice())).collect();
    // The constant frames C and C^-1 of every bone (and the root).
    let frames: Vec<(Quat, Quat)> = std::iter::once(axis_frame(asf.root.axis, asf.root.orientation_rad))
        .chain(asf.bones.iter().map(|b| axis_frame(b.axis_order, b.axis_rad)))
        .map(|c| (c, c.inverse()))
        .collect();

    let mut angle_unit = asf.units.angle;
    let mut values: Vec<Vec<f64>> = vec![Vec::new(); bone_count + 1];
    let mut seen = vec![false; bone_count + 1];
    let mut frame_number: Option<i64> = None;
    let mut frames_started = 0usize;
    let mut rotations: Vec<Quat> = Vec::new();
    let mut root_positions: Vec<Vec3> = Vec::new();

    let mut finish = |values: &mut Vec<Vec<f64>>, seen: &mut Vec<bool>, unit: AngleUnit| {
        let mut p = asf.root.position * s;
        for (slot, (vals, ((c, c_inv), dof))) in values.iter().zip(frames.iter().zip(&dofs)).enumerate() {
            let m = acclaim_rotation(
                dof.iter().zip(vals).filter_map(|(d, v)| d.rotation_axis().map(|a| (a, unit.to_radians(*v)))),
            );
            rotations.push(c * m * c_inv);
            if slot == 0 {
                for (d, v) in dof.iter().zip(vals) {
                    if let Some(a) = d.translation_axis() {
                        p[a] = v * s;
                    }
                }
            }
        }
        root_positions.push(p);
        // End sites never rotate.
        rotations.extend(std::iter::repeat_n(Quat::identity(), joints.saturating_sub(bone_count + 1)));
        for v in values.iter_mut() {
            v.clear();
        }
        seen.fill(false);
    };

    for (line, raw) in content_lines(text) {
        let ws: Vec<(usize, &str)> = words(raw).collect();
        let Some(&(col, key)) = ws.first() else {
            continue;
        };
        if let Some(keyword) = key.strip_prefix(':') {
            if frame_number.is_some() {
                return Err(text_err(AMC, line, Some(col), "header keyword after the first frame"));
            }
            match keyword.to_ascii_uppercase().as_str() {
                "DEGREES" => angle_unit = AngleUnit::Degree,
                "RADIANS" => angle_unit = AngleUnit::Radian,
                _ => {} // :FULLY-SPECIFIED and others: nothing to change
            }
            continue;
        }
        if ws.len() == 1
            && let Ok(n) = key.parse::<i64>()
        {
            if let Some(prev) = frame_number {
                if prev.checked_add(1) != Some(n) {
                    return Err(text_err(AMC, line, Some(col), format!("frame {n} follows frame {prev}")));
                }
                finish(&mut values, &mut seen, angle_unit);
            }
            // The frame starting here will be stored: count it before it is.
            frames_started += 1;
            limits.check_text_samples(AMC, frames_started, joints, "joints", text.len())?;
            frame_number = Some(n);
            continue;
        }
        if frame_number.is_none() {
            return Err(text_err(AMC, line, Some(col), format!("expected a frame number, found {key:?}")));
        }
        let slot = *slots
            .get(key)
            .ok_or_else(|| text_err(AMC, line, Some(col), format!("unknown bone {key:?} (not in the ASF)")))?;
        let (Some(vals), Some(dof), Some(flag)) = (values.get_mut(slot), dofs.get(slot), seen.get_mut(slot)) else {
            continue;
        };
        if *flag {
            return Err(text_err(AMC, line, Some(col), format!("bone {key:?} appears twice in one frame")));
        }
        *flag = true;
        let given = ws.get(1..).unwrap_or(&[]);
        if given.len() != dof.len() {
            return Err(text_err(
                AMC,
                line,
                None,
                format!("bone {key:?} has {} dofs, the line gives {} values", dof.len(), given.len()),
            ));
        }
        for &(c, w) in given {
            vals.push(num(AMC, line, c, w, "a dof value", false)?);
        }
    }
    if frame_number.is_some() {
        finish(&mut values, &mut seen, angle_unit);
    }
    Ok(Motion::new(skeleton, rotations, root_positions, frame_rate_hz)?)
}

/// Reads an AMC file (see [`read_amc`]); errors name the file.
pub fn read_amc_path(path: &Path, asf: &AsfSkeleton, frame_rate_hz: f64) -> Result<Motion> {
    read_amc_path_with(path, asf, frame_rate_hz, &Limits::default())
}

/// [`read_amc_path`] with explicit [`Limits`]. A path that is not a regular file (a named
/// pipe, a device, a directory) is refused before it is opened.
pub fn read_amc_path_with(path: &Path, asf: &AsfSkeleton, frame_rate_hz: f64, limits: &Limits) -> Result<Motion> {
    let text = limits::read_utf8(path, limits)?;
    read_amc_scaled_with(&text, asf, frame_rate_hz, asf.mm_per_unit(), limits).map_err(|e| e.in_file(path))
}

#[cfg(test)]
mod tests {
    use super::super::asf::tests::ASF_TEXT;
    use super::super::read_asf;
    use super::*;

    fn amc(frames: &[&str]) -> String {
        let mut s = String::from("#!OML:ASF x\r\n:FULLY-SPECIFIED\r\n:DEGREES\r\n");
        for (i, f) in frames.iter().enumerate() {
            s.push_str(&format!("{}\r\n{f}", i + 1));
        }
        s
    }

    /// Hand-computed Acclaim convention: the first listed axis is applied first.
    #[test]
    fn acclaim_axis_and_dof_order() {
        let asf = read_asf(ASF_TEXT).unwrap();
        // Bone a: C = Rz(90) Rx(90) maps X to Y, so `rx 90` turns about world Y, and the tip
        // of a (2, 0, 0) goes to (0, 0, -2). (The reverse product would turn about Z.)
        // Bone b: M = Rz(90) Rx(90) takes its direction Y to Z (Rx first), not to -X.
        let m = read_amc(
            &amc(&["root 0 0 0 0 0 0\r\na 90\r\nb 0 0\r\n", "root 1 2 3 0 0 0\r\na 0\r\nb 90 90\r\n"]),
            &asf,
            120.0,
        )
        .unwrap();
        assert_eq!(m.frame_count(), 2);
        let s = asf.mm_per_unit();
        let p = m.forward_kinematics(0).positions_mm;
        assert!((p[2] - Vec3::new(0.0, 0.0, -2.0 * s)).norm() < 1e-9, "{:?}", p[2]);
        let p = m.forward_kinematics(1).positions_mm;
        assert!((p[0] - Vec3::new(1.0, 2.0, 3.0) * s).norm() < 1e-9);
        assert!((p[3] - Vec3::new(3.0, 2.0, 4.0) * s).norm() < 1e-9, "{:?}", p[3]);
    }

    #[test]
    fn radians_header_is_honoured() {
        let asf = read_asf(ASF_TEXT).unwrap();
        let text = amc(&["root 0 0 0 0 0 0\r\na 1.5707963267948966\r\n"]).replace(":DEGREES", ":RADIANS");
        let m = read_amc(&text, &asf, 120.0).unwrap();
        let p = m.forward_kinematics(0).positions_mm;
        assert!((p[2] - Vec3::new(0.0, 0.0, -2.0 * asf.mm_per_unit())).norm() < 1e-9);
    }

    #[test]
    fn amc_errors_name_the_line() {
        let asf = read_asf(ASF_TEXT).unwrap();
        let check = |text: String, want_line: usize| match read_amc(&text, &asf, 120.0) {
            Err(Error::Text { format: "AMC", line, .. }) => assert_eq!(line, want_line, "{text}"),
            other => panic!("{other:?}"),
        };
        check(amc(&["root 0 0 0 0 0 0\r\nzzz 1\r\n"]), 6);
        check(amc(&["root 0 0 0 0 0 0\r\na x\r\n"]), 6);
        check(amc(&["root 0 0 0 0 0\r\n"]), 5);
        check(amc(&["a 1\r\na 2\r\n"]), 6);
        check(amc(&["a 1\r\n"]).replace("\r\n2\r\n", "\r\n3\r\n") + "3\r\n", 6);
        check("a 1\r\n".into(), 1);
        // Skipped frame number.
        check(amc(&["a 1\r\n", "a 1\r\n"]).replace("\r\n2\r\n", "\r\n4\r\n"), 6);
    }

    #[test]
    fn every_truncation_is_an_error_or_ok_never_a_panic() {
        let asf = read_asf(ASF_TEXT).unwrap();
        for (i, _) in ASF_TEXT.char_indices() {
            if let Err(e) = read_asf(&ASF_TEXT[..i]) {
                assert!(matches!(e, Error::Text { .. }), "cut at {i}: {e:?}");
            }
        }
        let text = amc(&["root 0 0 0 0 0 0\r\na 90\r\nb 0 0\r\n", "root 1 2 3 0 0 0\r\na 0\r\nb 90 90\r\n"]);
        for (i, _) in text.char_indices() {
            if let Err(e) = read_amc(&text[..i], &asf, 120.0) {
                assert!(matches!(e, Error::Text { .. }), "cut at {i}: {e:?}");
            }
        }
    }
}
