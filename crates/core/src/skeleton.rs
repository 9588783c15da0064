//! Skeletons, skeleton motion and forward kinematics.
//!
//! Conventions (the ones BVH and ASF/AMC share, so readers convert without surprises):
//! - joints are stored parents-first (`parent < index`), the root is joint 0;
//! - a joint's `offset_mm` is its origin in its parent's frame at rest;
//! - a motion frame holds one *local* rotation per joint (relative to the parent, applied
//!   after the rest offset) and the root's *global* position, `root_position_mm`;
//!   the root's own rest offset is not added to it (BVH and AMC store the root position
//!   absolutely);
//! - forward kinematics: `G_j = G_parent * L_j` and `P_j = P_parent + G_parent * offset_j`.

use crate::{EulerOrder, Quat, Vec3};
use serde::{Deserialize, Serialize};

/// Errors from building skeletons and motions.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SkeletonError {
    /// A joint's parent does not come before it.
    #[error("joint {joint} ({name}) has parent {parent}, which does not come before it")]
    BadParent {
        /// Index of the joint.
        joint: usize,
        /// Its name.
        name: String,
        /// The offending parent index.
        parent: usize,
    },
    /// Only joint 0 may be a root.
    #[error("joint {0} ({1}) has no parent, but only joint 0 may be the root")]
    SecondRoot(usize, String),
    /// A skeleton needs at least one joint.
    #[error("a skeleton needs at least one joint")]
    Empty,
    /// Two joints share a name.
    #[error("joint name {0:?} is used twice")]
    DuplicateName(String),
    /// Motion arrays do not match the skeleton.
    #[error("motion has {found} rotations, expected {frames} frames x {joints} joints")]
    ShapeMismatch {
        /// Frames in the motion.
        frames: usize,
        /// Joints in the skeleton.
        joints: usize,
        /// Rotations found.
        found: usize,
    },
    /// The frame rate is not a positive number.
    #[error("frame rate {0} Hz is not a positive number")]
    BadFrameRate(f64),
}

/// One joint of a skeleton.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Joint {
    /// Joint name, unique in its skeleton.
    pub name: String,
    /// Index of the parent joint, `None` for the root.
    pub parent: Option<usize>,
    /// Origin of this joint in its parent's frame at rest, millimetres.
    pub offset_mm: Vec3,
    /// Euler order the source file used for this joint (kept for writing it back).
    pub rotation_order: EulerOrder,
    /// True for a BVH `End Site`: a leaf that marks a bone's tip and never rotates.
    pub is_end_site: bool,
}

impl Joint {
    /// A rotating joint (not an end site) with the ZXY Euler order of CMU's BVH files.
    pub fn new(name: impl Into<String>, parent: Option<usize>, offset_mm: Vec3) -> Joint {
        Joint { name: name.into(), parent, offset_mm, rotation_order: EulerOrder::ZXY, is_end_site: false }
    }
}

/// A joint hierarchy with rest offsets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Skeleton {
    joints: Vec<Joint>,
}

impl Skeleton {
    /// Checks and builds a skeleton: joint 0 is the only root, parents come first, names are
    /// unique.
    pub fn new(joints: Vec<Joint>) -> Result<Skeleton, SkeletonError> {
        if joints.is_empty() {
            return Err(SkeletonError::Empty);
        }
        let mut names = std::collections::HashSet::new();
        for (i, joint) in joints.iter().enumerate() {
            if !names.insert(joint.name.as_str()) {
                return Err(SkeletonError::DuplicateName(joint.name.clone()));
            }
            match joint.parent {
                None if i != 0 => return Err(SkeletonError::SecondRoot(i, joint.name.clone())),
                Some(p) if p >= i => {
                    return Err(SkeletonError::BadParent { joint: i, name: joint.name.clone(), parent: p });
                }
                _ => {}
            }
        }
        if joints[0].parent.is_some() {
            return Err(SkeletonError::BadParent { joint: 0, name: joints[0].name.clone(), parent: 0 });
        }
        Ok(Skeleton { joints })
    }

    /// The joints, parents first.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Number of joints (end sites included).
    pub fn len(&self) -> usize {
        self.joints.len()
    }

    /// Always false: a skeleton has a root.
    pub fn is_empty(&self) -> bool {
        self.joints.is_empty()
    }

    /// Index of the joint called `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// Indices of the children of `joint`.
    pub fn children(&self, joint: usize) -> impl Iterator<Item = usize> + '_ {
        self.joints.iter().enumerate().filter(move |(_, j)| j.parent == Some(joint)).map(|(i, _)| i)
    }

    /// Scales every offset by `factor` (for unit changes or subject size).
    pub fn scaled(&self, factor: f64) -> Skeleton {
        let mut joints = self.joints.clone();
        for j in &mut joints {
            j.offset_mm *= factor;
        }
        Skeleton { joints }
    }
}

/// Global position and rotation of every joint in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct GlobalPose {
    /// Global joint positions, millimetres.
    pub positions_mm: Vec<Vec3>,
    /// Global joint rotations.
    pub rotations: Vec<Quat>,
}

/// Skeleton motion: per frame, a local rotation per joint and the root's global position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Motion {
    /// The skeleton this motion drives.
    pub skeleton: Skeleton,
    /// Local joint rotations, frame-major (`frame * joints + joint`).
    rotations: Vec<Quat>,
    /// Root global position per frame, millimetres.
    root_position_mm: Vec<Vec3>,
    frame_rate_hz: f64,
}

impl Motion {
    /// Builds a motion; `rotations` is frame-major with one entry per joint.
    pub fn new(
        skeleton: Skeleton,
        rotations: Vec<Quat>,
        root_position_mm: Vec<Vec3>,
        frame_rate_hz: f64,
    ) -> Result<Motion, SkeletonError> {
        if !(frame_rate_hz.is_finite() && frame_rate_hz > 0.0) {
            return Err(SkeletonError::BadFrameRate(frame_rate_hz));
        }
        let (frames, joints) = (root_position_mm.len(), skeleton.len());
        if rotations.len() != frames * joints {
            return Err(SkeletonError::ShapeMismatch { frames, joints, found: rotations.len() });
        }
        Ok(Motion { skeleton, rotations, root_position_mm, frame_rate_hz })
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.root_position_mm.len()
    }

    /// Frame rate in Hz.
    pub fn frame_rate_hz(&self) -> f64 {
        self.frame_rate_hz
    }

    /// Local rotations of all joints at `frame`.
    pub fn local_rotations(&self, frame: usize) -> &[Quat] {
        let j = self.skeleton.len();
        &self.rotations[frame * j..(frame + 1) * j]
    }

    /// Root global position at `frame`, millimetres.
    pub fn root_position_mm(&self, frame: usize) -> Vec3 {
        self.root_position_mm[frame]
    }

    /// The same motion seen in a world turned by `world` (e.g. from one axis convention to
    /// another): the root's rotation and position are turned, every other joint keeps its
    /// local rotation, so every global joint position `p` becomes `world * p`.
    pub fn rotated(&self, world: Quat) -> Motion {
        let joints = self.skeleton.len();
        let mut rotations = self.rotations.clone();
        for frame in rotations.chunks_mut(joints.max(1)) {
            if let Some(root) = frame.first_mut() {
                *root = world * *root;
            }
        }
        let root_position_mm = self.root_position_mm.iter().map(|p| world * p).collect();
        Motion { skeleton: self.skeleton.clone(), rotations, root_position_mm, frame_rate_hz: self.frame_rate_hz }
    }

    /// Global joint positions and rotations at `frame`.
    pub fn forward_kinematics(&self, frame: usize) -> GlobalPose {
        forward_kinematics(&self.skeleton, self.local_rotations(frame), self.root_position_mm[frame])
    }
}

/// Forward kinematics of one pose: local rotations (one per joint) and the root's global
/// position to global joint positions and rotations.
///
/// # Panics
/// If `local` does not have one rotation per joint.
pub fn forward_kinematics(skeleton: &Skeleton, local: &[Quat], root_position_mm: Vec3) -> GlobalPose {
    assert_eq!(local.len(), skeleton.len(), "one local rotation per joint");
    let mut positions_mm = Vec::with_capacity(local.len());
    let mut rotations: Vec<Quat> = Vec::with_capacity(local.len());
    for (joint, rot) in skeleton.joints().iter().zip(local) {
        match joint.parent {
            None => {
                positions_mm.push(root_position_mm);
                rotations.push(*rot);
            }
            Some(p) => {
                positions_mm.push(positions_mm[p] + rotations[p] * joint.offset_mm);
                rotations.push(rotations[p] * rot);
            }
        }
    }
    GlobalPose { positions_mm, rotations }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    fn joint(name: &str, parent: Option<usize>, offset: [f64; 3]) -> Joint {
        Joint::new(name, parent, Vec3::from(offset))
    }

    fn arm() -> Skeleton {
        Skeleton::new(vec![
            joint("root", None, [0.0, 0.0, 0.0]),
            joint("shoulder", Some(0), [100.0, 0.0, 0.0]),
            joint("elbow", Some(1), [300.0, 0.0, 0.0]),
            joint("hand", Some(2), [250.0, 0.0, 0.0]),
        ])
        .unwrap()
    }

    #[test]
    fn rejects_malformed_hierarchies() {
        assert_eq!(Skeleton::new(vec![]), Err(SkeletonError::Empty));
        assert!(matches!(
            Skeleton::new(vec![joint("a", None, [0.0; 3]), joint("b", Some(1), [0.0; 3])]),
            Err(SkeletonError::BadParent { .. })
        ));
        assert!(matches!(
            Skeleton::new(vec![joint("a", None, [0.0; 3]), joint("b", None, [0.0; 3])]),
            Err(SkeletonError::SecondRoot(1, _))
        ));
        assert!(matches!(
            Skeleton::new(vec![joint("a", None, [0.0; 3]), joint("a", Some(0), [0.0; 3])]),
            Err(SkeletonError::DuplicateName(_))
        ));
    }

    #[test]
    fn hand_computed_arm() {
        let sk = arm();
        let root = Vec3::new(10.0, 20.0, 30.0);
        // Rest pose: offsets add up along X.
        let pose = forward_kinematics(&sk, &[Quat::identity(); 4], root);
        assert_relative_eq!(pose.positions_mm[3], Vec3::new(660.0, 20.0, 30.0), epsilon = 1e-9);
        // Shoulder bent 90 degrees about Z: the elbow lies along +Y of the shoulder, and the
        // elbow bent another 90 degrees points the hand along -X.
        let z90 = EulerOrder::ZXY.to_quat_deg([90.0, 0.0, 0.0]);
        let pose = forward_kinematics(&sk, &[Quat::identity(), z90, z90, Quat::identity()], root);
        assert_relative_eq!(pose.positions_mm[1], Vec3::new(110.0, 20.0, 30.0), epsilon = 1e-9);
        assert_relative_eq!(pose.positions_mm[2], Vec3::new(110.0, 320.0, 30.0), epsilon = 1e-9);
        assert_relative_eq!(pose.positions_mm[3], Vec3::new(-140.0, 320.0, 30.0), epsilon = 1e-9);
        assert!(pose.rotations[3].angle_to(&(z90 * z90)) < 1e-12);
    }

    #[test]
    fn motion_shape_is_checked() {
        let sk = arm();
        assert!(Motion::new(sk.clone(), vec![Quat::identity(); 7], vec![Vec3::zeros(); 2], 120.0).is_err());
        let m = Motion::new(sk, vec![Quat::identity(); 8], vec![Vec3::zeros(); 2], 120.0).unwrap();
        assert_eq!(m.frame_count(), 2);
        assert_eq!(m.forward_kinematics(1).positions_mm.len(), 4);
    }

    #[test]
    fn a_rotated_motion_turns_every_joint() {
        let sk = arm();
        let z90 = EulerOrder::ZXY.to_quat_deg([90.0, 0.0, 0.0]);
        let local = vec![z90, Quat::identity(), z90, Quat::identity()];
        let m = Motion::new(sk, local, vec![Vec3::new(10.0, 20.0, 30.0)], 100.0).unwrap();
        let world = EulerOrder::XYZ.to_quat_deg([-90.0, 0.0, 0.0]);
        let (a, b) = (m.forward_kinematics(0), m.rotated(world).forward_kinematics(0));
        for (p, q) in a.positions_mm.iter().zip(&b.positions_mm) {
            assert_relative_eq!(world * p, *q, epsilon = 1e-9);
        }
    }

    proptest! {
        /// Rigid motion: bone lengths never change, whatever the rotations.
        #[test]
        fn fk_preserves_bone_lengths(angles in proptest::collection::vec(-180.0f64..180.0, 12), t in proptest::array::uniform3(-1e3f64..1e3)) {
            let sk = arm();
            let local: Vec<Quat> = angles.chunks(3).map(|a| EulerOrder::XYZ.to_quat_deg([a[0], a[1], a[2]])).collect();
            let pose = forward_kinematics(&sk, &local, Vec3::from(t));
            for (i, j) in sk.joints().iter().enumerate().skip(1) {
                let p = j.parent.unwrap();
                let len = (pose.positions_mm[i] - pose.positions_mm[p]).norm();
                prop_assert!((len - j.offset_mm.norm()).abs() < 1e-6);
            }
            // A global rotation of the root rotates every joint about the root.
            let extra = EulerOrder::ZYX.to_quat_deg([angles[0], angles[1] / 2.0, angles[2]]);
            let mut turned = local.clone();
            turned[0] = extra * turned[0];
            let pose2 = forward_kinematics(&sk, &turned, Vec3::from(t));
            for i in 0..4 {
                let expect = Vec3::from(t) + extra * (pose.positions_mm[i] - Vec3::from(t));
                prop_assert!((pose2.positions_mm[i] - expect).norm() < 1e-6);
            }
        }
    }
}
