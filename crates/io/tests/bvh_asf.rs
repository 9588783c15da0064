//! BVH and ASF/AMC against the shared CMU data, plus property tests of the BVH writer.

mod common;

use locap_core::{EulerOrder, Joint, LengthUnit, Motion, Quat, Skeleton, Vec3};
use locap_io::Error;
use locap_io::asf_amc::{read_amc, read_amc_path, read_asf, read_asf_path};
use locap_io::bvh::{read_bvh, read_bvh_path, write_bvh, write_bvh_path};
use proptest::prelude::*;
use std::path::PathBuf;

fn data_dir() -> Option<PathBuf> {
    common::shared_data()
}

/// Every joint's distance to its parent equals its rest offset in every frame (rigid bones).
fn assert_rigid(m: &Motion, tolerance_mm: f64) {
    let step = (m.frame_count() / 50).max(1);
    for frame in (0..m.frame_count()).step_by(step) {
        let pose = m.forward_kinematics(frame);
        for (i, j) in m.skeleton.joints().iter().enumerate().skip(1) {
            let p = j.parent.unwrap();
            let len = (pose.positions_mm[i] - pose.positions_mm[p]).norm();
            assert!((len - j.offset_mm.norm()).abs() < tolerance_mm, "{} frame {frame}: {len}", j.name);
        }
    }
}

fn assert_same_motion(a: &Motion, b: &Motion) {
    assert_eq!(a.frame_count(), b.frame_count());
    assert!((a.frame_rate_hz() - b.frame_rate_hz()).abs() <= 1e-6 * a.frame_rate_hz());
    assert_eq!(a.skeleton.len(), b.skeleton.len());
    for (x, y) in a.skeleton.joints().iter().zip(b.skeleton.joints()) {
        assert_eq!(x.parent, y.parent);
        assert_eq!(x.is_end_site, y.is_end_site);
        if !x.is_end_site {
            assert_eq!(x.name, y.name);
            assert_eq!(x.rotation_order, y.rotation_order);
        }
        assert!((x.offset_mm - y.offset_mm).norm() < 1e-6, "{}", x.name);
    }
    for f in 0..a.frame_count() {
        assert!((a.root_position_mm(f) - b.root_position_mm(f)).norm() < 1e-6);
        for (j, (x, y)) in a.local_rotations(f).iter().zip(b.local_rotations(f)).enumerate() {
            if !a.skeleton.joints()[j].is_end_site {
                assert!(x.angle_to(y) < 1e-6, "frame {f} joint {j}");
            }
        }
    }
}

#[test]
fn cmu_bvh_files_read_and_round_trip() {
    let Some(dir) = data_dir() else { return };
    let mut count = 0;
    for entry in std::fs::read_dir(dir.join("cmu-bvh")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "bvh") {
            continue;
        }
        count += 1;
        let text = std::fs::read_to_string(&path).unwrap();
        let declared: usize =
            text.lines().find_map(|l| l.trim().strip_prefix("Frames:")).unwrap().trim().parse().unwrap();
        let m = read_bvh_path(&path, LengthUnit::Inch).unwrap();
        assert_eq!(m.frame_count(), declared, "{}", path.display());
        assert_eq!(m.frame_rate_hz(), 120.0, "CMU .008333 s frames are 120 Hz");
        let real = m.skeleton.joints().iter().filter(|j| !j.is_end_site).count();
        assert_eq!(real, 31, "{}", path.display());
        assert_eq!(m.skeleton.joints()[0].rotation_order, EulerOrder::ZYX);
        assert_rigid(&m, 1e-6);

        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("copy.bvh");
        write_bvh_path(&m, LengthUnit::Centimetre, &out).unwrap();
        let back = read_bvh_path(&out, LengthUnit::Centimetre).unwrap();
        assert_same_motion(&m, &back);
        // Same global joint positions in a few frames.
        for f in [0, m.frame_count() / 2, m.frame_count() - 1] {
            let (p, q) = (m.forward_kinematics(f), back.forward_kinematics(f));
            for (x, y) in p.positions_mm.iter().zip(&q.positions_mm) {
                assert!((x - y).norm() < 1e-6);
            }
        }
    }
    assert_eq!(count, 3);
}

#[test]
fn truncated_or_garbled_bvh_gives_line_errors() {
    let Some(dir) = data_dir() else { return };
    let text = std::fs::read_to_string(dir.join("cmu-bvh/131_01.bvh")).unwrap();
    let total_lines = text.split('\n').count();
    // Cut anywhere: inside the hierarchy, the header, a motion line.
    // (The last cut drops the final value of the last motion line.)
    for cut in (0..text.len()).step_by(text.len() / 40 + 1).chain(text.rfind(' ')) {
        if !text.is_char_boundary(cut) {
            continue;
        }
        match read_bvh(&text[..cut], LengthUnit::Inch) {
            Err(Error::Text { format: "BVH", line, .. }) => assert!((1..=total_lines).contains(&line)),
            Err(other) => panic!("cut at {cut}: {other:?}"),
            Ok(_) => panic!("cut at {cut} was read as a valid file"),
        }
    }
    // A value replaced by garbage in motion line 200 (file line 187 + 200).
    let mut lines: Vec<&str> = text.split('\n').collect();
    let garbled = lines[387].replacen(' ', " 1.2.3 ", 1);
    lines[387] = &garbled;
    match read_bvh(&lines.join("\n"), LengthUnit::Inch) {
        Err(Error::Text { line: 388, column: Some(_), .. }) => {}
        other => panic!("{other:?}"),
    }
    // Arbitrary bytes never panic.
    for seed in 0..200u64 {
        let garbage: String = (0..200u64)
            .map(|i: u64| {
                let x = seed.wrapping_mul(6364136223846793005).wrapping_add(i.wrapping_mul(1442695040888963407)) >> 58;
                b"HIERARCHY ROOT JOINT End Site { } OFFSET CHANNELS 3 6 Xrotation Yposition MOTION Frames: Frame Time: 1 .5 -2\n"
                    [x as usize % 64] as char
            })
            .collect();
        let _ = read_bvh(&garbage, LengthUnit::Millimetre);
    }
}

#[test]
fn cmu_asf_and_amc_files_read() {
    let Some(dir) = data_dir() else { return };
    for subject in ["01", "02", "03"] {
        let asf = read_asf_path(&dir.join(format!("cmu-asfamc/{subject}/{subject}.asf"))).unwrap();
        assert_eq!(asf.bones.len(), 30, "{subject}");
        assert!((asf.units.length - 0.45).abs() < 1e-12);
        let sk = asf.to_skeleton(asf.mm_per_unit()).unwrap();
        // root + 30 bones + an end site for each of the 7 leaves.
        assert_eq!(sk.len(), 38);
        let amc_path = dir.join(format!("cmu-asfamc/{subject}/{subject}_01.amc"));
        let text = std::fs::read_to_string(&amc_path).unwrap();
        let frames = text.lines().filter(|l| l.trim().parse::<u64>().is_ok()).count();
        let m = read_amc_path(&amc_path, &asf, 120.0).unwrap();
        assert_eq!(m.frame_count(), frames, "{subject}");
        assert_eq!(m.frame_rate_hz(), 120.0);
        assert_rigid(&m, 1e-6);
        // A standing adult: femur 35-55 cm, and the head above the root by 40-80 cm.
        let femur = sk.joints()[sk.index_of("ltibia").unwrap()].offset_mm.norm();
        assert!((350.0..550.0).contains(&femur), "{femur}");
        let pose = m.forward_kinematics(0);
        let up = pose.positions_mm[sk.index_of("head").unwrap()].y - pose.positions_mm[0].y;
        assert!((400.0..800.0).contains(&up), "{up}");
    }
}

#[test]
fn bad_amc_gives_line_errors() {
    let Some(dir) = data_dir() else { return };
    let asf = read_asf_path(&dir.join("cmu-asfamc/01/01.asf")).unwrap();
    let text = std::fs::read_to_string(dir.join("cmu-asfamc/01/01_02.amc")).unwrap();
    let expect_line = |t: &str, want: usize| match read_amc(t, &asf, 120.0) {
        Err(Error::Text { format: "AMC", line, .. }) => assert_eq!(line, want),
        other => panic!("{other:?}"),
    };
    let mut lines: Vec<String> = text.split('\n').map(str::to_string).collect();
    let original = lines.clone();
    lines[40] = "nosuchbone 1 2 3\r".into();
    expect_line(&lines.join("\n"), 41);
    lines = original.clone();
    lines[41] = lines[41].replacen(' ', " abc ", 1);
    expect_line(&lines.join("\n"), 42);
    // Truncating inside a bone line leaves too few values.
    let cut = text.find("\nlfemur").unwrap() + 10;
    let line = text[..cut].split('\n').count();
    expect_line(&text[..cut], line);
    // The ASF cut short, and with a bad number.
    let asf_text = std::fs::read_to_string(dir.join("cmu-asfamc/01/01.asf")).unwrap();
    assert!(matches!(read_asf(&asf_text[..asf_text.len() / 2]), Err(Error::Text { .. })));
    let bad = asf_text.replacen("length 7.1578", "length 7.1.578", 1);
    let line = asf_text[..asf_text.find("length 7.1578").unwrap()].split('\n').count();
    match read_asf(&bad) {
        Err(Error::Text { format: "ASF", line: l, .. }) => assert_eq!(l, line),
        other => panic!("{other:?}"),
    }
}

/// A random skeleton whose index order is a depth-first walk (as BVH stores it), with random
/// rotation orders, and random leaves turned into end sites.
fn skeleton_strategy() -> impl Strategy<Value = Skeleton> {
    (1usize..8)
        .prop_flat_map(|n| {
            (
                proptest::collection::vec(0usize..8, n),
                proptest::collection::vec(0usize..6, n),
                proptest::collection::vec(proptest::array::uniform3(-500.0f64..500.0), n),
                proptest::collection::vec(any::<bool>(), n),
            )
        })
        .prop_map(|(depths, orders, offsets, end)| {
            const ORDERS: [EulerOrder; 6] =
                [EulerOrder::XYZ, EulerOrder::XZY, EulerOrder::YXZ, EulerOrder::YZX, EulerOrder::ZXY, EulerOrder::ZYX];
            let n = depths.len();
            let mut path: Vec<usize> = Vec::new();
            let mut parents = Vec::with_capacity(n);
            for (i, d) in depths.iter().enumerate() {
                let parent = if i == 0 {
                    None
                } else {
                    let k = d % path.len();
                    path.truncate(k + 1);
                    Some(path[k])
                };
                path.push(i);
                parents.push(parent);
            }
            let has_child: Vec<bool> = (0..n).map(|i| parents.contains(&Some(i))).collect();
            let joints: Vec<Joint> = (0..n)
                .map(|i| {
                    let is_end_site = i > 0 && !has_child[i] && end[i];
                    Joint {
                        // BVH does not store end-site names; they are compared by position.
                        name: if is_end_site { format!("e{i}") } else { format!("j{i}") },
                        parent: parents[i],
                        offset_mm: Vec3::from(offsets[i]),
                        rotation_order: ORDERS[orders[i]],
                        is_end_site,
                    }
                })
                .collect();
            Skeleton::new(joints).unwrap()
        })
}

fn motion_strategy() -> impl Strategy<Value = Motion> {
    (skeleton_strategy(), 0usize..4, 1.0f64..1000.0).prop_flat_map(|(sk, frames, rate)| {
        let n = sk.len();
        (
            Just(sk),
            proptest::collection::vec((-179.0f64..179.0, -89.0f64..89.0, -179.0f64..179.0), n * frames),
            proptest::collection::vec(proptest::array::uniform3(-5000.0f64..5000.0), frames),
            Just(rate),
        )
            .prop_map(|(sk, angles, roots, rate)| {
                let rotations: Vec<Quat> = angles
                    .iter()
                    .enumerate()
                    .map(|(k, &(a, b, c))| {
                        let j = &sk.joints()[k % sk.len()];
                        if j.is_end_site { Quat::identity() } else { j.rotation_order.to_quat_deg([a, b, c]) }
                    })
                    .collect();
                Motion::new(sk, rotations, roots.into_iter().map(Vec3::from).collect(), rate).unwrap()
            })
    })
}

proptest! {
    #[test]
    fn bvh_write_read_round_trip(m in motion_strategy(), unit in 0usize..4) {
        let unit = [LengthUnit::Millimetre, LengthUnit::Centimetre, LengthUnit::Metre, LengthUnit::Inch][unit];
        let mut out = Vec::new();
        write_bvh(&m, unit, &mut out).unwrap();
        let back = read_bvh(std::str::from_utf8(&out).unwrap(), unit).unwrap();
        assert_same_motion(&m, &back);
    }
}
