//! Several networks' answers for one take, averaged: an ensemble of solvers trained alike on
//! differently drawn subjects and seeds (LocalMoCap section 3.2's network; built by
//! [`Solver::with_members`](super::Solver::with_members)). A per-frame network's errors on an unseen subject are
//! partly its training draw's; networks trained on other draws err differently, and their mean
//! errs less than either.
//!
//! Per frame and joint, the members' rotations are averaged as quaternions (each turned to the
//! first member's hemisphere, the sum normalised: for two members, the midpoint of the arc
//! between them), the root positions and each bone's offset arithmetically.

use crate::NnError;
use crate::solver::Solver;
use burn::prelude::Device;
use locap_core::skeleton::Joint;
use locap_core::{Motion, Quat, Skeleton, Vec3};

/// The mean of `motions`: one skeleton (joint names, parents and order the same in each),
/// frame count and rate.
///
/// # Errors
/// No motions, or motions of other skeletons, lengths or rates.
pub fn average_motions(motions: &[Motion]) -> Result<Motion, NnError> {
    let Some(first) = motions.first() else {
        return Err(NnError::BadModel("an ensemble of no solvers".into()));
    };
    let (sk, t) = (&first.skeleton, first.frame_count());
    for m in &motions[1..] {
        if !same_joints(&m.skeleton, sk) || m.frame_count() != t || m.frame_rate_hz() != first.frame_rate_hz() {
            return Err(NnError::BadModel("the ensemble's solvers answer on different skeletons".into()));
        }
    }
    let n = motions.len() as f64;
    let joints: Vec<Joint> = sk
        .joints()
        .iter()
        .enumerate()
        .map(|(k, j)| {
            let offset_mm = motions.iter().map(|m| m.skeleton.joints()[k].offset_mm).sum::<Vec3>() / n;
            Joint { offset_mm, ..j.clone() }
        })
        .collect();
    let skeleton = Skeleton::new(joints).map_err(NnError::Skeleton)?;
    let mut rotations = Vec::with_capacity(t * sk.len());
    let mut root = Vec::with_capacity(t);
    for f in 0..t {
        for k in 0..sk.len() {
            let q0 = first.local_rotations(f)[k].into_inner();
            let sum = motions.iter().fold(nalgebra::Quaternion::new(0.0, 0.0, 0.0, 0.0), |acc, m| {
                let q = m.local_rotations(f)[k].into_inner();
                if q.dot(&q0) < 0.0 { acc - q } else { acc + q }
            });
            rotations.push(Quat::new_normalize(sum));
        }
        root.push(motions.iter().map(|m| m.root_position_mm(f)).sum::<Vec3>() / n);
    }
    Motion::new(skeleton, rotations, root, first.frame_rate_hz()).map_err(NnError::Skeleton)
}

/// Whether `a` and `b` have the same joints in the same order: names and parents (the bones'
/// offsets may differ, as each network predicts its own).
pub(crate) fn same_joints(a: &Skeleton, b: &Skeleton) -> bool {
    a.len() == b.len() && a.joints().iter().zip(b.joints()).all(|(x, y)| x.name == y.name && x.parent == y.parent)
}

/// One solver from model files' bytes, each with the name an error gives it (its path): the
/// first, with the rest beside it as an ensemble ([`Solver::with_members`]). Each member joins
/// on its own, so a file that does not load, or a model that cannot join the first, is the one
/// named.
///
/// # Errors
/// No files, a file that is not a solver model, or one of another marker set or skeleton.
pub fn from_named_files(files: &[(String, Vec<u8>)], device: &Device) -> Result<Solver, NnError> {
    let in_model = |name: &str, e: NnError| NnError::InModel { name: name.to_string(), source: Box::new(e) };
    let load = |(name, bytes): &(String, Vec<u8>)| Solver::from_bytes(bytes, device).map_err(|e| in_model(name, e));
    let Some((first, rest)) = files.split_first() else {
        return Err(NnError::BadModel("an ensemble of no solvers".into()));
    };
    rest.iter()
        .try_fold(load(first)?, |solver, file| solver.with_members(vec![load(file)?]).map_err(|e| in_model(&file.0, e)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motion(angle: f64, root_x: f64, bone_mm: f64) -> Motion {
        let skeleton = Skeleton::new(vec![
            Joint::new("root", None, Vec3::zeros()),
            Joint::new("a", Some(0), Vec3::new(bone_mm, 0.0, 0.0)),
        ])
        .unwrap();
        let q = Quat::from_axis_angle(&Vec3::z_axis(), angle);
        Motion::new(skeleton, vec![Quat::identity(), q], vec![Vec3::new(root_x, 0.0, 0.0)], 120.0).unwrap()
    }

    /// Two answers average to the rotation halfway between them, whichever sign their
    /// quaternions carry, the mean root and the mean bone.
    #[test]
    fn two_answers_meet_halfway() {
        let a = motion(0.2, 10.0, 100.0);
        let b = motion(0.6, 30.0, 110.0);
        let mean = average_motions(&[a.clone(), b.clone()]).unwrap();
        let angle = mean.local_rotations(0)[1].angle();
        assert!((angle - 0.4).abs() < 1e-12, "{angle}");
        assert!((mean.root_position_mm(0).x - 20.0).abs() < 1e-12);
        assert!((mean.skeleton.joints()[1].offset_mm.x - 105.0).abs() < 1e-12);
        // The same rotation written with the other sign.
        let flipped = {
            let q = b.local_rotations(0)[1].into_inner();
            Motion::new(
                b.skeleton.clone(),
                vec![Quat::identity(), Quat::new_unchecked(-q)],
                vec![b.root_position_mm(0)],
                120.0,
            )
            .unwrap()
        };
        let again = average_motions(&[a.clone(), flipped]).unwrap();
        assert!((again.local_rotations(0)[1].angle() - 0.4).abs() < 1e-12);
        // One member is itself.
        let one = average_motions(std::slice::from_ref(&a)).unwrap();
        assert_eq!(one.local_rotations(0), a.local_rotations(0));
        assert!(average_motions(&[]).is_err());
    }

    /// Answers on other skeletons or lengths are refused, not mixed.
    #[test]
    fn answers_on_other_skeletons_are_refused() {
        let a = motion(0.2, 10.0, 100.0);
        let other = Motion::new(
            Skeleton::new(vec![Joint::new("root", None, Vec3::zeros()), Joint::new("b", Some(0), Vec3::x())]).unwrap(),
            vec![Quat::identity(); 2],
            vec![Vec3::zeros()],
            120.0,
        )
        .unwrap();
        assert!(average_motions(&[a, other]).is_err());
    }

    /// The shipped solver is the three body networks as one, and a hand network cannot join
    /// them: its markers and skeleton are another's.
    #[test]
    fn the_shipped_ensemble_takes_only_networks_of_its_own_markers_and_skeleton() {
        let device = Default::default();
        let shipped = crate::shipped::solver(&device).unwrap();
        assert_eq!(shipped.networks(), 3);
        let file = |name: &str| {
            let path = format!("{}/../../models/{name}", env!("CARGO_MANIFEST_DIR"));
            (name.to_string(), std::fs::read(path).unwrap())
        };
        let hand = file("solver-hand-left.locapsv");
        let error = shipped.with_members(vec![Solver::from_bytes(&hand.1, &device).unwrap()]).unwrap_err();
        assert!(error.to_string().contains("marker set, skeleton"), "{error}");
        // From files: the one that cannot join is named, and the three join.
        let error = from_named_files(&[file("solver-cmu41-v3.locapsv"), hand], &device).unwrap_err();
        assert!(error.to_string().starts_with("solver-hand-left.locapsv: "), "{error}");
        let three = ["solver-cmu41-v3.locapsv", "solver-cmu41-v2.locapsv", "solver-cmu41.locapsv"].map(file);
        assert_eq!(from_named_files(&three, &device).unwrap().networks(), 3);
        assert!(from_named_files(&[], &device).is_err());
    }
}
