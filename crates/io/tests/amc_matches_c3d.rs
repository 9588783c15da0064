//! The ASF/AMC conventions checked on real data: CMU take 01_01 was captured once and published
//! both as C3D markers (`cmu-c3d/01_01.c3d`) and as a skeleton animation solved from them
//! (`cmu-asfamc/01/01_01.amc`), 2751 frames each, frame for frame. If locap reads the ASF/AMC
//! conventions right (Euler order, `axis` frames, units), markers must stay rigidly attached
//! to the joints they sit on: the ankle markers at a near-constant distance from the ankle
//! joints, the head markers around the head's tip, the pelvis markers around the root.
//!
//! Frames: C3D (X, Y, Z) in mm = ASF (z, x, y) in mm (`read_amc` already scales ASF units,
//! `25.4 / 0.45` mm each, so only the axes are permuted). This mapping was measured once on
//! this take; the test checks it still holds with the reader as it is.

mod common;

use locap_core::{Take, Vec3};
use locap_io::asf_amc::{read_amc_path, read_asf_path};
use locap_io::c3d;

/// ASF world frame (Y up) to the C3D lab frame (Z up): C3D (X, Y, Z) = ASF (z, x, y).
fn asf_to_c3d(p: Vec3) -> Vec3 {
    Vec3::new(p.z, p.x, p.y)
}

/// Mean of the markers `labels` at `frame`, if every one of them is present.
fn marker_mean(take: &Take, frame: usize, labels: &[&str]) -> Option<Vec3> {
    let mut sum = Vec3::zeros();
    for label in labels {
        let m = take.marker_index(label).unwrap_or_else(|| panic!("marker {label} not in 01_01.c3d"));
        sum += take.position_mm(frame, m)?;
    }
    Some(sum / labels.len() as f64)
}

/// Markers whose mean must follow a joint: its distance to the joint must have a standard
/// deviation below `max_std` (rigid attachment) or a mean below `max_mean` (close by).
struct Check {
    what: &'static str,
    markers: &'static [&'static str],
    joint: usize,
    max_std: Option<f64>,
    max_mean: Option<f64>,
}

/// Mean and standard deviation.
fn mean_std(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
    (mean, var.sqrt())
}

#[test]
fn cmu_01_01_markers_follow_the_amc_skeleton() {
    let Some(data) = common::shared_data() else { return };
    let take = c3d::read_path(&data.join("cmu-c3d/01_01.c3d")).unwrap().to_take().unwrap();
    let asf = read_asf_path(&data.join("cmu-asfamc/01/01.asf")).unwrap();
    let motion = read_amc_path(&data.join("cmu-asfamc/01/01_01.amc"), &asf, 120.0).unwrap();
    assert_eq!(take.frame_count(), 2751);
    assert_eq!(motion.frame_count(), 2751);

    let skeleton = &motion.skeleton;
    let joint = |name: &str| skeleton.index_of(name).unwrap_or_else(|| panic!("joint {name} not in 01.asf"));
    let checks = [
        Check { what: "LANK - lfoot", markers: &["LANK"], joint: joint("lfoot"), max_std: Some(10.0), max_mean: None },
        Check { what: "RANK - rfoot", markers: &["RANK"], joint: joint("rfoot"), max_std: Some(10.0), max_mean: None },
        Check {
            what: "head markers - head_End",
            markers: &["LFHD", "RFHD", "LBHD", "RBHD"],
            joint: joint("head_End"),
            max_std: None,
            max_mean: Some(80.0),
        },
        Check {
            what: "pelvis markers - root",
            markers: &["LFWT", "RFWT", "LBWT", "RBWT"],
            joint: joint("root"),
            max_std: None,
            max_mean: Some(60.0),
        },
    ];
    let mut distances: Vec<Vec<f64>> = vec![Vec::new(); checks.len()];
    for frame in 0..take.frame_count() {
        let pose = motion.forward_kinematics(frame);
        for (k, check) in checks.iter().enumerate() {
            if let Some(marker) = marker_mean(&take, frame, check.markers) {
                distances[k].push((marker - asf_to_c3d(pose.positions_mm[check.joint])).norm());
            }
        }
    }
    let mut failures = Vec::new();
    for (Check { what, max_std, max_mean, .. }, d) in checks.iter().zip(&distances) {
        assert!(d.len() > 2000, "{what}: markers present in only {} frames", d.len());
        let (mean, std) = mean_std(d);
        eprintln!("01_01 {what}: mean {mean:.1} mm, std {std:.1} mm over {} frames", d.len());
        if max_std.is_some_and(|m| std >= m) || max_mean.is_some_and(|m| mean >= m) {
            failures.push(format!("{what}: mean {mean:.1} mm, std {std:.1} mm"));
        }
    }
    assert!(failures.is_empty(), "markers do not follow the AMC skeleton: {failures:?}");
}
