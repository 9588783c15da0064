//! The CMU degrees of freedom the kinematic solver carries ([`locap_nn::kinematic::CMU_ASF_DOFS`])
//! against every shared CMU ASF, and posed with CMU's own solutions: through the table's axes,
//! an AMC frame's values give the joint positions the AMC reader's forward kinematics gives.

use locap_core::skeleton::forward_kinematics;
use locap_core::{Quat, Vec3};
use locap_io::asf_amc::{Dof, read_amc_path, read_asf_path};
use locap_label::ik::JointDofs;
use locap_nn::kinematic::{
    CMU_ASF_DOFS, CMU_SOLVED_RANGES, CmuLimits, KinematicSolver, acclaim_axis_frame, cmu_asf_dofs,
};
use locap_testkit::shared_data;
use std::collections::HashMap;

fn rotation_axis(d: Dof) -> usize {
    match d {
        Dof::Rx => 0,
        Dof::Ry => 1,
        Dof::Rz => 2,
        other => panic!("a CMU bone with a {other:?} dof"),
    }
}

#[test]
fn the_table_is_every_shared_cmu_asf() {
    let Some(data) = shared_data() else { return };
    let mut asfs: Vec<_> = std::fs::read_dir(data.join("cmu-asfamc"))
        .unwrap()
        .flat_map(|d| std::fs::read_dir(d.unwrap().path()).unwrap())
        .map(|f| f.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "asf"))
        .collect();
    asfs.sort();
    assert!(asfs.len() >= 3, "{asfs:?}");
    for path in &asfs {
        let asf = read_asf_path(path).unwrap();
        let mut listed = 0;
        for bone in &asf.bones {
            let entry = CMU_ASF_DOFS.iter().find(|(name, ..)| *name == bone.name);
            let Some((_, axis_deg, dofs)) = entry else {
                assert!(bone.dof.is_empty(), "{}: {} has dofs the table lacks", path.display(), bone.name);
                continue;
            };
            listed += 1;
            // The ASF's own C, in its own axis order (X applied first for `XYZ`).
            let mut c = Quat::identity();
            for (a, t) in bone.axis_order.axes().into_iter().zip(bone.axis_rad) {
                c = locap_core::rotation::axis_rotation(a, t) * c;
            }
            let angle = c.angle_to(&acclaim_axis_frame(*axis_deg));
            assert!(angle < 1e-9, "{}: {} axis off by {angle} rad", path.display(), bone.name);
            let axes: Vec<usize> = bone.dof.iter().map(|d| rotation_axis(*d)).collect();
            assert_eq!(axes, dofs.iter().map(|d| d.0).collect::<Vec<_>>(), "{}: {}", path.display(), bone.name);
            assert_eq!(bone.limits.len(), dofs.len(), "{}: {}", path.display(), bone.name);
            for ((min, max), (_, lo, hi)) in bone.limits.iter().zip(dofs.iter()) {
                assert!((min - lo.to_radians()).abs() < 1e-9 && (max - hi.to_radians()).abs() < 1e-9, "{}", bone.name);
            }
        }
        assert_eq!(listed, CMU_ASF_DOFS.len(), "{}", path.display());
    }
}

/// Per frame, each bone's AMC values (radians; the shared AMCs say `:DEGREES`).
fn amc_values(text: &str) -> Vec<HashMap<String, Vec<f64>>> {
    assert!(text.contains(":DEGREES"));
    let mut frames: Vec<HashMap<String, Vec<f64>>> = Vec::new();
    for line in text.lines().map(str::trim) {
        if line.is_empty() || line.starts_with('#') || line.starts_with(':') {
            continue;
        }
        let mut words = line.split_whitespace();
        let first = words.next().unwrap();
        if first.parse::<usize>().is_ok() {
            frames.push(HashMap::new());
            continue;
        }
        let values = words.map(|w| w.parse::<f64>().unwrap().to_radians()).collect();
        frames.last_mut().unwrap().insert(first.to_string(), values);
    }
    frames
}

#[test]
fn amc_frames_posed_through_the_table_match_the_amc_readers_kinematics() {
    let Some(data) = shared_data() else { return };
    for (asf, amc) in [("01/01.asf", "01/01_01.amc"), ("02/02.asf", "02/02_01.amc"), ("03/03.asf", "03/03_01.amc")] {
        let asf = read_asf_path(&data.join("cmu-asfamc").join(asf)).unwrap();
        let amc_path = data.join("cmu-asfamc").join(amc);
        let reference = read_amc_path(&amc_path, &asf, 120.0).unwrap();
        let values = amc_values(&std::fs::read_to_string(&amc_path).unwrap());
        assert_eq!(values.len(), reference.frame_count(), "{amc}");
        let skeleton = &reference.skeleton;
        let dofs = cmu_asf_dofs(skeleton, CmuLimits::Asf);
        let (mut worst_mm, mut worst_rad) = (0.0f64, 0.0f64);
        // How far two-axis rotations lie from the plane of their axes (the solver's rotation
        // vectors stay in it): reported, not asserted.
        let mut off_plane: HashMap<&str, f64> = HashMap::new();
        for (f, frame) in values.iter().enumerate() {
            let reference_local = reference.local_rotations(f);
            let mut local = vec![Quat::identity(); skeleton.len()];
            local[0] = reference_local[0];
            for (j, joint) in skeleton.joints().iter().enumerate().skip(1) {
                let given = frame.get(&joint.name).map_or(&[][..], Vec::as_slice);
                let JointDofs::Axes(axes) = &dofs[j] else { panic!("{} free", joint.name) };
                // A bone without dofs (hip joints, end sites) has no AMC line.
                local[j] = dofs[j].rotation(given).unwrap_or_else(|| panic!("{amc} {}: {given:?}", joint.name));
                worst_rad = worst_rad.max(local[j].angle_to(&reference_local[j]));
                if axes.len() == 2 {
                    let v = local[j].scaled_axis();
                    let normal = axes[0].axis.cross(&axes[1].axis).normalize();
                    let e = off_plane.entry(skeleton.joints()[j].name.as_str()).or_default();
                    *e = e.max(normal.dot(&v).abs().to_degrees());
                }
            }
            let ours = forward_kinematics(skeleton, &local, reference.root_position_mm(f));
            let theirs = reference.forward_kinematics(f);
            for (a, b) in ours.positions_mm.iter().zip(&theirs.positions_mm) {
                worst_mm = worst_mm.max((a - b).norm());
            }
        }
        eprintln!("{amc}: worst joint {worst_mm:.2e} mm, worst local rotation {worst_rad:.2e} rad");
        let mut planes: Vec<_> = off_plane.into_iter().collect();
        planes.sort_by(|a, b| a.0.cmp(b.0));
        eprintln!("{amc}: two-axis joints, largest turn off their axes' plane (deg): {planes:?}");
        assert!(worst_mm < 1e-6, "{amc}: {worst_mm} mm");
        assert!(worst_rad < 1e-9, "{amc}: {worst_rad} rad");
    }
}

#[test]
fn the_solved_ranges_widen_the_asf_limits() {
    assert_eq!(CMU_SOLVED_RANGES.len(), CMU_ASF_DOFS.len());
    for (name, _, dofs) in CMU_ASF_DOFS {
        let (_, ranges) = CMU_SOLVED_RANGES.iter().find(|(n, _)| n == name).unwrap_or_else(|| panic!("{name}"));
        assert_eq!(ranges.len(), dofs.len(), "{name}");
        for ((lo, hi), (_, min, max)) in ranges.iter().zip(dofs.iter()) {
            assert!(lo <= min && hi >= max && *lo >= -180.0 && *hi <= 180.0, "{name}");
        }
    }
}

#[test]
fn the_cmu_solver_turns_the_shipped_joints_about_the_asf_axes() {
    let solver = KinematicSolver::cmu41().unwrap();
    let free = KinematicSolver::cmu41_with(|s| vec![JointDofs::Free; s.len()]).unwrap();
    // The same joints turn as before; only about fewer axes.
    assert_eq!(solver.rotating(), free.rotating());
    let names: Vec<&str> = solver.skeleton().joints().iter().map(|j| j.name.as_str()).collect();
    let rotating: Vec<&str> = names.iter().zip(solver.rotating()).filter(|(_, r)| *r).map(|(n, _)| *n).collect();
    eprintln!("rotating joints: {rotating:?}");
    for elbow in ["lradius", "rradius", "ltibia", "rtibia"] {
        assert!(rotating.contains(&elbow), "{elbow}");
    }
    let dofs = cmu_asf_dofs(solver.skeleton(), CmuLimits::None);
    let knee = names.iter().position(|n| *n == "ltibia").unwrap();
    let JointDofs::Axes(axes) = &dofs[knee] else { panic!("knee free") };
    assert_eq!(axes.len(), 1);
    // The knee bends about the thigh frame's x axis, turned 20 degrees about z.
    let expected = Vec3::new(20f64.to_radians().cos(), 20f64.to_radians().sin(), 0.0);
    assert!((axes[0].axis - expected).norm() < 1e-12, "{:?}", axes[0].axis);
    assert!(KinematicSolver::cmu41_with(|_| Vec::new()).is_err());
}
