//! OpenSim motion (`.mot`): joint angles of a solved motion as an OpenSim Storage table.
//!
//! # Layout
//! The Storage format of OpenSim (documented in the OpenSim user's guide, "Storage (.sto)
//! and Motion (.mot) Files"; read by `Storage` and, through `STOFileAdapter`, by
//! `TimeSeriesTable`): a header of `key=value` lines and free text ended by `endheader`, then a
//! tab-separated table whose first column is `time` in seconds.
//! ```text
//! 02_01.mot
//! version=1
//! nRows=343
//! nColumns=97
//! inDegrees=yes
//! ...description lines...
//! endheader
//! time  root_tx  root_ty  root_tz  root_rz  root_ry  root_rx  lfemur_rz ...
//! ```
//!
//! # Columns
//! - `time`: `frame / rate`, seconds from the first frame.
//! - `<root>_tx`, `_ty`, `_tz`: the root's position in metres, in the motion's axes (what the
//!   caller says `up` is, written in the header; `locap solve` writes Y-up, see
//!   [`crate::axes`]).
//! - `<joint>_r<axis>` for every joint that rotates (end sites do not): its local rotation as
//!   the three Euler angles of the joint's own order, in degrees, in that order
//!   (`R = R_a1 * R_a2 * R_a3`, the BVH convention of [`locap_core::EulerOrder`]).
//!
//! Euler angles jump by 360 degrees where they wrap; OpenSim filters and plots coordinates
//! as curves, so every angle is unwrapped to the value nearest the previous frame's (the
//! same rotation).
//!
//! This is not an OpenSim model's coordinate set: locap's skeletons are not OpenSim models,
//! so the columns are named after locap's joints. Loading them onto a model needs the model's
//! coordinate names.

use crate::atomic::write_atomically;
use crate::{Error, Result};
use locap_core::{Motion, UpAxis};
use std::io::Write;
use std::path::Path;

/// The column names of [`write_mot`] for `motion`, `time` first.
pub fn column_names(motion: &Motion) -> Vec<String> {
    let joints = motion.skeleton.joints();
    let mut names = vec!["time".to_string()];
    if let Some(root) = joints.first() {
        names.extend(["tx", "ty", "tz"].map(|c| format!("{}_{c}", root.name)));
    }
    for j in joints.iter().filter(|j| !j.is_end_site) {
        for axis in j.rotation_order.name().chars() {
            names.push(format!("{}_r{}", j.name, axis.to_ascii_lowercase()));
        }
    }
    names
}

/// `angle` plus the multiple of 360 degrees that brings it nearest `previous`.
fn unwrap_deg(angle: f64, previous: f64) -> f64 {
    angle - 360.0 * ((angle - previous) / 360.0).round()
}

/// Writes `motion` as an OpenSim `.mot` table called `name` (its first header line), stating
/// that `up` is the vertical axis of the root positions.
pub fn write_mot(motion: &Motion, name: &str, up: UpAxis, w: &mut dyn Write) -> Result<()> {
    let names = column_names(motion);
    for n in &names {
        if n.chars().any(|c| c.is_whitespace() || c.is_control()) {
            return Err(Error::Unwritable(format!("MOT: column {n:?} has a blank; joint names must not")));
        }
    }
    let name: String = name.chars().map(|c| if c.is_control() { '_' } else { c }).collect();
    let frames = motion.frame_count();
    writeln!(w, "{name}")?;
    writeln!(w, "version=1")?;
    writeln!(w, "nRows={frames}")?;
    writeln!(w, "nColumns={}", names.len())?;
    writeln!(w, "inDegrees=yes")?;
    writeln!(w, "Units are S.I. units (second, meters, Newtons, ...)")?;
    writeln!(w, "Written by locap: joint angles in degrees, local Euler angles in each joint's order;")?;
    let up = match up {
        UpAxis::Y => "Y",
        UpAxis::Z => "Z",
    };
    writeln!(w, "root translations in meters, {up}-up, at {} Hz.", motion.frame_rate_hz())?;
    writeln!(w, "endheader")?;
    writeln!(w, "{}", names.join("\t"))?;
    let joints = motion.skeleton.joints();
    let mut previous: Vec<f64> = Vec::new();
    let mut row: Vec<f64> = Vec::with_capacity(names.len());
    let mut line = String::new();
    for frame in 0..frames {
        row.clear();
        row.push(frame as f64 / motion.frame_rate_hz());
        let p = motion.root_position_mm(frame) / 1000.0;
        row.extend([p.x, p.y, p.z]);
        let local = motion.local_rotations(frame);
        for (j, q) in joints.iter().zip(local).filter(|(j, _)| !j.is_end_site) {
            row.extend(j.rotation_order.from_quat_deg(q));
        }
        if previous.len() == row.len() {
            // Angles only: time and the root translation (columns 0..4) are not periodic.
            for (v, prev) in row.iter_mut().zip(&previous).skip(4) {
                *v = unwrap_deg(*v, *prev);
            }
        }
        line.clear();
        for (i, v) in row.iter().enumerate() {
            if !v.is_finite() {
                return Err(Error::Unwritable(format!("MOT: frame {frame}, column {} is {v}", names[i])));
            }
            if i > 0 {
                line.push('\t');
            }
            // Shortest round-trip text: nothing is lost to a fixed number of decimals.
            line.push_str(&v.to_string());
        }
        line.push('\n');
        w.write_all(line.as_bytes())?;
        previous.clone_from(&row);
    }
    Ok(())
}

/// Writes `motion` as a `.mot` file at `path`, atomically (see [`write_mot`]); the table is
/// named after the file.
pub fn write_mot_path(motion: &Motion, up: UpAxis, path: &Path) -> Result<()> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    write_atomically(path, |w| write_mot(motion, &name, up, w))
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{EulerOrder, Joint, Quat, Skeleton, Vec3};

    fn motion() -> Motion {
        let mut end = Joint::new("tip", Some(1), Vec3::new(0.0, 100.0, 0.0));
        end.is_end_site = true;
        let sk = Skeleton::new(vec![
            Joint::new("hips", None, Vec3::zeros()),
            Joint::new("spine", Some(0), Vec3::new(0.0, 100.0, 0.0)),
            end,
        ])
        .unwrap();
        let frames: Vec<[f64; 3]> = vec![[170.0, 10.0, 0.0], [-170.0, 10.0, 5.0]];
        let mut rotations = Vec::new();
        for a in &frames {
            rotations.extend([EulerOrder::ZXY.to_quat_deg(*a), Quat::identity(), Quat::identity()]);
        }
        Motion::new(sk, rotations, vec![Vec3::new(1000.0, 900.0, -5.0); 2], 50.0).unwrap()
    }

    #[test]
    fn header_columns_and_unwrapped_angles() {
        let mut out = Vec::new();
        write_mot(&motion(), "t.mot", UpAxis::Y, &mut out).unwrap();
        let text = String::from_utf8(out).unwrap();
        let (header, table) = text.split_once("endheader\n").unwrap();
        assert!(header.starts_with("t.mot\nversion=1\nnRows=2\nnColumns=10\ninDegrees=yes\n"), "{header}");
        let rows: Vec<Vec<&str>> = table.lines().map(|l| l.split('\t').collect()).collect();
        assert_eq!(
            rows[0],
            [
                "time", "hips_tx", "hips_ty", "hips_tz", "hips_rz", "hips_rx", "hips_ry", "spine_rz", "spine_rx",
                "spine_ry"
            ]
        );
        let second: Vec<f64> = rows[2].iter().map(|v| v.parse().unwrap()).collect();
        assert_eq!(second[0], 0.02);
        assert_eq!(&second[1..4], &[1.0, 0.9, -0.005]);
        // -170 degrees right after 170 is written as 190: the same rotation, no jump.
        assert!((second[4] - 190.0).abs() < 1e-9, "{second:?}");
        assert!((second[6] - 5.0).abs() < 1e-9);
    }

    #[test]
    fn unwrap_keeps_the_nearest_turn() {
        assert_eq!(unwrap_deg(-170.0, 170.0), 190.0);
        assert_eq!(unwrap_deg(10.0, 5.0), 10.0);
        assert_eq!(unwrap_deg(350.0, -5.0), -10.0);
    }
}
