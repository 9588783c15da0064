//! Marker layouts: which marker rides on which joint, and where (LocalMoCap section 4: the
//! synthetic dataset places markers on a driven body).
//!
//! # File format (TOML)
//! A layout is a human-editable TOML file (JSON with the same fields also works, see
//! [`Layout::from_json`]):
//!
//! ```toml
//! name = "cmu-41"
//! description = "CMU/HDM05 41-marker Vicon set on the CMU ASF skeleton"
//!
//! # Optional: other names of a joint in other skeletons (BVH exports rename joints).
//! [aliases]
//! lfemur = ["LeftHip", "LeftUpLeg"]
//!
//! [[marker]]
//! name = "LKNE"             # marker label, as in the C3D files
//! joint = "lfemur"          # the joint (segment) it rides on
//! offset_mm = [95.0, -380.0, 12.0]   # position in that joint's frame, millimetres
//! region = "body"           # body | left_hand | right_hand
//! soft_tissue = 1.0         # optional: scales the soft-tissue wobble (default 1)
//! # Optional: a marker near a joint slides between two segments, like skin. Its position is
//! # (1 - weight) * (on `joint`) + weight * (on `blend.joint`).
//! blend = { joint = "ltibia", weight = 0.5, offset_mm = [95.0, 20.0, 12.0] }
//! ```
//!
//! Offsets are in the *joint's* frame: `global = P_joint + R_joint * offset_mm` with the
//! joint's global position and rotation from forward kinematics
//! ([`locap_core::skeleton::forward_kinematics`]). In an ASF or CMU BVH skeleton every joint
//! frame is aligned with the world (Y up) at rest, so offsets read as rest-pose displacements.
//! A blend without `offset_mm` takes the marker's rest-pose position and expresses it in the
//! second joint's frame.
//!
//! # The skeleton section (optional)
//! A layout built from a model that brings its own skeleton (an OpenSim model, see
//! [`crate::opensim`]) carries it, so the layout file alone is enough to solve a take:
//!
//! ```toml
//! [skeleton]
//! up_axis = "Y"             # the rest frame's vertical axis
//! smoothness = 10.0         # optional: the kinematic solver's smoothness weight for this
//!                           # skeleton (default: the body's, 100)
//! [[skeleton.joint]]
//! name = "pelvis"           # the root: no parent
//! offset_mm = [0.0, 0.0, 0.0]
//! [[skeleton.joint]]
//! name = "tibia_r"
//! parent = "femur_r"        # parents come before their children
//! offset_mm = [-4.5, -396.0, 0.0]   # joint centre in the parent's frame at rest, mm
//! # Rotational degrees of freedom with their limits; no `dofs`: a free ball joint,
//! # `dofs = []`: no rotation at all.
//! dofs = [{ name = "knee_angle_r", axis = [0.0, 0.0, -1.0], min_deg = 0.0, max_deg = 170.0 }]
//! ```
//!
//! Every joint frame is aligned with the rest frame's axes at rest (as in ASF and CMU BVH), so
//! offsets and axes read in those axes.

use locap_core::skeleton::forward_kinematics;
use locap_core::{GlobalPose, Joint, Quat, Skeleton, UpAxis, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Largest offset of a marker from its joint, per axis, mm: markers sit on the skin or on a
/// wand, centimetres from the bone; 2 m allows any real marker set.
pub const MAX_OFFSET_MM: f64 = 2000.0;

/// Largest soft-tissue factor (1 is the default skin motion; 10 is already a loose cloth marker).
pub const MAX_SOFT_TISSUE: f64 = 100.0;

/// Errors reading or binding a layout.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LayoutError {
    /// The TOML or JSON text does not parse.
    #[error("layout does not parse: {0}")]
    Parse(String),
    /// Two markers share a name.
    #[error("marker {0:?} is listed twice")]
    DuplicateMarker(String),
    /// A layout with no markers.
    #[error("the layout has no markers")]
    Empty,
    /// The skeleton section does not make a skeleton.
    #[error("skeleton section: {0}")]
    Skeleton(String),
    /// A marker's joint (or one of its aliases) is not in the skeleton.
    #[error("marker {marker:?} rides on joint {joint:?}, which the skeleton does not have (nor any alias of it)")]
    UnknownJoint {
        /// Marker name.
        marker: String,
        /// Joint name in the layout.
        joint: String,
    },
    /// A blend weight outside `[0, 1]` or a non-finite number.
    #[error("marker {marker:?}: {what} is not valid ({value})")]
    BadNumber {
        /// Marker name.
        marker: String,
        /// Which field.
        what: &'static str,
        /// The value.
        value: f64,
    },
}

/// Which part of the body a marker belongs to (the paper solves body and hands apart).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Region {
    /// Body (trunk, head, limbs).
    #[default]
    Body,
    /// Left hand and fingers.
    LeftHand,
    /// Right hand and fingers.
    RightHand,
}

/// A second segment a marker partly follows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Blend {
    /// The second joint.
    pub joint: String,
    /// How much the marker follows the second joint, in `[0, 1]`.
    pub weight: f64,
    /// Offset in the second joint's frame, mm; `None`: the rest-pose position of the marker.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset_mm: Option<[f64; 3]>,
}

/// One marker of a layout.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayoutMarker {
    /// Marker label.
    pub name: String,
    /// Joint the marker rides on.
    pub joint: String,
    /// Position in the joint's frame, millimetres.
    pub offset_mm: [f64; 3],
    /// Body region.
    #[serde(default)]
    pub region: Region,
    /// Optional second segment.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blend: Option<Blend>,
    /// Scale of the soft-tissue wobble for this marker (1 = the take's amplitude).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub soft_tissue: f64,
}

fn one() -> f64 {
    1.0
}

fn is_one(v: &f64) -> bool {
    *v == 1.0
}

/// A marker layout (see the module docs for the file format).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Layout {
    /// Short name.
    pub name: String,
    /// What the layout is and where its offsets come from.
    #[serde(default)]
    pub description: String,
    /// Other names of joints in other skeletons (layout joint name -> alternatives, tried in
    /// order when the skeleton has no joint of the layout's name).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub aliases: BTreeMap<String, Vec<String>>,
    /// The markers, in output order.
    #[serde(rename = "marker")]
    pub markers: Vec<LayoutMarker>,
    /// The skeleton the layout was built for, when the layout brings one (see the module docs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skeleton: Option<LayoutSkeleton>,
}

/// A skeleton carried in a layout file: joints by name, offsets and rotational degrees of
/// freedom with their limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayoutSkeleton {
    /// Vertical axis of the rest frame (joint frames are aligned with it at rest).
    pub up_axis: UpAxis,
    /// Weight of the kinematic solver's temporal smoothness term for this skeleton
    /// (`locap_label::ik::IkConfig::smooth`); `None`: the solver's default, set for a body
    /// at 120 Hz. A hand's fingers move further per frame, and their markers weigh less
    /// against a rotation, than a body's limbs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub smoothness: Option<f64>,
    /// The joints, parents first; the first is the root.
    #[serde(rename = "joint")]
    pub joints: Vec<LayoutJoint>,
}

/// One joint of a [`LayoutSkeleton`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayoutJoint {
    /// Joint name (the name markers ride on).
    pub name: String,
    /// Parent joint name; `None` for the root.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parent: Option<String>,
    /// Joint centre in the parent's frame at rest, mm.
    pub offset_mm: [f64; 3],
    /// Rotational degrees of freedom; `None`: a free ball joint without limits.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dofs: Option<Vec<Dof>>,
    /// Another joint this one turns with, scaled (a finger's distal joint with its middle
    /// one); a solver pulls it softly there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub follows: Option<Follow>,
}

/// How a [`LayoutJoint`] turns with another.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Follow {
    /// The joint it follows.
    pub joint: String,
    /// Its rotation over that joint's (about the same axes).
    pub ratio: f64,
}

/// A rotation axis of a joint and its range.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dof {
    /// Name of the degree of freedom (an OpenSim coordinate).
    pub name: String,
    /// Rotation axis in the joint's frame (aligned with the rest frame's axes), unit length.
    pub axis: [f64; 3],
    /// Smallest rotation about `axis`, degrees.
    pub min_deg: f64,
    /// Largest rotation about `axis`, degrees.
    pub max_deg: f64,
}

impl LayoutSkeleton {
    /// Checks names, parents and numbers; builds the [`Skeleton`] (ZXY rotation order, as CMU
    /// BVH files write it).
    pub fn to_skeleton(&self) -> Result<Skeleton, LayoutError> {
        let bad = |what: String| Err(LayoutError::Skeleton(what));
        let mut joints: Vec<Joint> = Vec::with_capacity(self.joints.len());
        for (i, j) in self.joints.iter().enumerate() {
            let parent = match &j.parent {
                None => None,
                Some(p) => match joints.iter().position(|k| k.name == *p) {
                    Some(k) => Some(k),
                    None => return bad(format!("joint {:?}: parent {p:?} does not come before it", j.name)),
                },
            };
            if (parent.is_none()) != (i == 0) {
                return bad(format!("joint {:?}: only the first joint is the root (has no parent)", j.name));
            }
            if let Some(v) = j.offset_mm.iter().find(|v| !(v.is_finite() && v.abs() <= MAX_OFFSET_MM)) {
                return bad(format!("joint {:?}: offset_mm {v} is not a length within {MAX_OFFSET_MM} mm", j.name));
            }
            for d in j.dofs.iter().flatten() {
                let norm = Vec3::from(d.axis).norm();
                let finite = d.axis.iter().chain([&d.min_deg, &d.max_deg]).all(|v| v.is_finite());
                if !finite || !(0.5..2.0).contains(&norm) || !(d.min_deg <= d.max_deg) {
                    return bad(format!("joint {:?}: degree of freedom {:?} is not valid: {d:?}", j.name, d.name));
                }
            }
            joints.push(Joint::new(j.name.clone(), parent, Vec3::from(j.offset_mm)));
        }
        if let Some(w) = self.smoothness.filter(|w| !(w.is_finite() && *w >= 0.0)) {
            return bad(format!("smoothness {w} is not a weight (finite, at least 0)"));
        }
        for j in &self.joints {
            let Some(f) = &j.follows else { continue };
            if f.joint == j.name || !self.joints.iter().any(|k| k.name == f.joint) || !f.ratio.is_finite() {
                return bad(format!("joint {:?}: it cannot follow {:?} by {}", j.name, f.joint, f.ratio));
            }
        }
        Skeleton::new(joints).map_err(|e| LayoutError::Skeleton(e.to_string()))
    }
}

impl Layout {
    /// Parses a TOML layout and checks it.
    pub fn from_toml(text: &str) -> Result<Layout, LayoutError> {
        let layout: Layout = toml::from_str(text).map_err(|e| LayoutError::Parse(e.to_string()))?;
        layout.check()?;
        Ok(layout)
    }

    /// Parses a JSON layout (same fields as TOML) and checks it.
    pub fn from_json(text: &str) -> Result<Layout, LayoutError> {
        let layout: Layout = serde_json::from_str(text).map_err(|e| LayoutError::Parse(e.to_string()))?;
        layout.check()?;
        Ok(layout)
    }

    /// The layout as TOML text.
    pub fn to_toml(&self) -> String {
        // Every field is a string, number, array or table: serialisation cannot fail.
        toml::to_string(self).unwrap_or_default()
    }

    /// The CMU/HDM05 41-marker Vicon set on the CMU ASF skeleton, calibrated on CMU takes
    /// 01_01 and 02_01 (`layouts/cmu41.toml`; see `layouts/README.md`).
    pub fn cmu41() -> Layout {
        const TOML: &str = include_str!("../layouts/cmu41.toml");
        // Shipped with the crate and parsed by a test.
        Layout::from_toml(TOML).unwrap_or_else(|e| panic!("built-in layout cmu41.toml: {e}"))
    }

    /// Checks names, numbers and weights. Offsets and the soft-tissue factor must be finite
    /// and at most [`MAX_OFFSET_MM`] / [`MAX_SOFT_TISSUE`]: a marker metres from its joint is a
    /// typo, and a value like 1e308 overflows to infinity in the first rotation, which the
    /// labeler's pose search would chase forever.
    pub fn check(&self) -> Result<(), LayoutError> {
        if self.markers.is_empty() {
            return Err(LayoutError::Empty);
        }
        if let Some(skeleton) = &self.skeleton {
            skeleton.to_skeleton()?;
        }
        let mut seen = std::collections::HashSet::new();
        for m in &self.markers {
            if !seen.insert(m.name.as_str()) {
                return Err(LayoutError::DuplicateMarker(m.name.clone()));
            }
            let bad = |what, value| LayoutError::BadNumber { marker: m.name.clone(), what, value };
            let out_of_range = |v: &&f64| !(v.is_finite() && v.abs() <= MAX_OFFSET_MM);
            if let Some(v) = m.offset_mm.iter().find(out_of_range) {
                return Err(bad("offset_mm", *v));
            }
            if !(m.soft_tissue.is_finite() && (0.0..=MAX_SOFT_TISSUE).contains(&m.soft_tissue)) {
                return Err(bad("soft_tissue", m.soft_tissue));
            }
            if let Some(b) = &m.blend {
                if !(0.0..=1.0).contains(&b.weight) {
                    return Err(bad("blend.weight", b.weight));
                }
                if let Some(v) = b.offset_mm.iter().flatten().find(out_of_range) {
                    return Err(bad("blend.offset_mm", *v));
                }
            }
        }
        Ok(())
    }

    /// Index of the joint called `name` (or one of its aliases) in `skeleton`.
    pub fn resolve_joint(&self, skeleton: &Skeleton, name: &str) -> Option<usize> {
        skeleton.index_of(name).or_else(|| self.aliases.get(name)?.iter().find_map(|alt| skeleton.index_of(alt)))
    }

    /// Resolves joint names against `skeleton` and fills in blend offsets from its rest pose.
    pub fn bind(&self, skeleton: &Skeleton) -> Result<BoundLayout, LayoutError> {
        self.check()?;
        let rest = forward_kinematics(skeleton, &vec![Quat::identity(); skeleton.len()], Vec3::zeros());
        let joint = |m: &LayoutMarker, name: &str| {
            self.resolve_joint(skeleton, name)
                .ok_or_else(|| LayoutError::UnknownJoint { marker: m.name.clone(), joint: name.to_string() })
        };
        let mut markers = Vec::with_capacity(self.markers.len());
        for m in &self.markers {
            let j = joint(m, &m.joint)?;
            let offset = Vec3::from(m.offset_mm);
            let blend = match &m.blend {
                Some(b) if b.weight > 0.0 => {
                    let k = joint(m, &b.joint)?;
                    let offset_k = match b.offset_mm {
                        Some(o) => Vec3::from(o),
                        None => {
                            let at_rest = rest.positions_mm[j] + rest.rotations[j] * offset;
                            rest.rotations[k].inverse() * (at_rest - rest.positions_mm[k])
                        }
                    };
                    Some(BoundBlend { joint: k, weight: b.weight, offset_mm: offset_k })
                }
                _ => None,
            };
            markers.push(BoundMarker { joint: j, offset_mm: offset, blend, soft_tissue: m.soft_tissue });
        }
        Ok(BoundLayout { names: self.markers.iter().map(|m| m.name.clone()).collect(), markers })
    }
}

/// A blend resolved to a joint index.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundBlend {
    /// Second joint index.
    pub joint: usize,
    /// Weight of the second joint.
    pub weight: f64,
    /// Offset in the second joint's frame, mm.
    pub offset_mm: Vec3,
}

/// A marker resolved against a skeleton.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundMarker {
    /// Joint index.
    pub joint: usize,
    /// Offset in the joint's frame, mm.
    pub offset_mm: Vec3,
    /// Second segment, if any.
    pub blend: Option<BoundBlend>,
    /// Soft-tissue scale.
    pub soft_tissue: f64,
}

impl BoundMarker {
    /// Global position in `pose` with the offsets displaced by `extra_mm` (in the joint frames;
    /// soft tissue and jitter), millimetres.
    pub fn position_mm(&self, pose: &GlobalPose, extra_mm: Vec3) -> Vec3 {
        let on = |joint: usize, offset: Vec3| pose.positions_mm[joint] + pose.rotations[joint] * (offset + extra_mm);
        let a = on(self.joint, self.offset_mm);
        match &self.blend {
            Some(b) => a * (1.0 - b.weight) + on(b.joint, b.offset_mm) * b.weight,
            None => a,
        }
    }
}

/// A layout bound to one skeleton: joint indices instead of names.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundLayout {
    /// Marker names, in layout order.
    pub names: Vec<String>,
    /// The markers, in layout order.
    pub markers: Vec<BoundMarker>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::joint;

    fn arm() -> Skeleton {
        Skeleton::new(vec![
            joint("root", None, [0.0; 3]),
            joint("upper", Some(0), [0.0, 0.0, 0.0]),
            joint("lower", Some(1), [300.0, 0.0, 0.0]),
        ])
        .unwrap()
    }

    const TEXT: &str = r#"
name = "test"
[aliases]
upper = ["UpperArm"]
[[marker]]
name = "A"
joint = "upper"
offset_mm = [150.0, 40.0, 0.0]
[[marker]]
name = "ELB"
joint = "upper"
offset_mm = [300.0, 30.0, 0.0]
region = "left_hand"
blend = { joint = "lower", weight = 0.5 }
"#;

    #[test]
    fn parses_binds_and_round_trips() {
        let layout = Layout::from_toml(TEXT).unwrap();
        assert_eq!(layout.markers[1].region, Region::LeftHand);
        let bound = layout.bind(&arm()).unwrap();
        // The blend offset is the rest position in the lower joint's frame.
        assert_eq!(bound.markers[1].blend.as_ref().unwrap().offset_mm, Vec3::new(0.0, 30.0, 0.0));
        let again = Layout::from_toml(&layout.to_toml()).unwrap();
        assert_eq!(again, layout);
        let json = serde_json::to_string(&layout).unwrap();
        assert_eq!(Layout::from_json(&json).unwrap(), layout);
    }

    #[test]
    fn rejects_bad_layouts_with_reasons() {
        let dup = TEXT.replace("name = \"ELB\"", "name = \"A\"");
        assert_eq!(Layout::from_toml(&dup), Err(LayoutError::DuplicateMarker("A".into())));
        let weight = TEXT.replace("weight = 0.5", "weight = 1.5");
        assert!(matches!(Layout::from_toml(&weight), Err(LayoutError::BadNumber { what: "blend.weight", .. })));
        assert!(matches!(Layout::from_toml("name = 3"), Err(LayoutError::Parse(_))));
        // An offset of 1e308 (it made `label --layout` hang in the pose search) is refused.
        let huge = TEXT.replace("[150.0, 40.0, 0.0]", "[1e308, 40.0, 0.0]");
        assert!(matches!(Layout::from_toml(&huge), Err(LayoutError::BadNumber { what: "offset_mm", .. })));
        let unknown = Layout::from_toml(&TEXT.replace("joint = \"lower\"", "joint = \"shin\"")).unwrap();
        assert!(matches!(unknown.bind(&arm()), Err(LayoutError::UnknownJoint { .. })));
    }

    /// A skeleton's smoothness weight is read, written back and checked.
    #[test]
    fn a_skeletons_smoothness_round_trips_and_must_be_a_weight() {
        let with = |w: &str| {
            format!(
                "{TEXT}[skeleton]\nup_axis = \"Y\"\nsmoothness = {w}\n[[skeleton.joint]]\nname = \"upper\"\noffset_mm = [0.0, 0.0, 0.0]\n"
            )
        };
        let layout = Layout::from_toml(&with("10.0")).unwrap();
        let section = layout.skeleton.as_ref().unwrap();
        assert_eq!(section.smoothness, Some(10.0));
        assert!(section.to_skeleton().is_ok());
        assert_eq!(Layout::from_toml(&layout.to_toml()).unwrap(), layout);
        for bad in ["-1.0", "nan", "inf"] {
            let err = Layout::from_toml(&with(bad)).unwrap_err();
            assert!(err.to_string().contains("smoothness"), "{bad}: {err}");
        }
    }

    #[test]
    fn aliases_resolve() {
        let layout = Layout::from_toml(TEXT).unwrap();
        let mut joints = arm().joints().to_vec();
        joints[1].name = "UpperArm".into();
        let sk = Skeleton::new(joints).unwrap();
        assert_eq!(layout.bind(&sk).unwrap().markers[0].joint, 1);
    }

    proptest::proptest! {
        /// Any valid layout survives TOML and JSON round trips exactly. (This test found
        /// serde_json's default float parsing one ulp off; the workspace enables its
        /// `float_roundtrip` feature.)
        #[test]
        fn round_trips(
            offsets in proptest::collection::vec(proptest::array::uniform3(-500.0f64..500.0), 1..8),
            weight in 0.0f64..=1.0,
            soft in 0.0f64..3.0,
        ) {
            let markers = offsets
                .iter()
                .enumerate()
                .map(|(i, o)| LayoutMarker {
                    name: format!("M{i}"),
                    joint: "upper".into(),
                    offset_mm: *o,
                    region: if i % 2 == 0 { Region::Body } else { Region::RightHand },
                    blend: (i % 3 == 0).then(|| Blend { joint: "lower".into(), weight, offset_mm: Some(*o) }),
                    soft_tissue: soft,
                })
                .collect();
            let layout = crate::test_util::layout(markers);
            proptest::prop_assert_eq!(Layout::from_toml(&layout.to_toml()).unwrap(), layout.clone());
            proptest::prop_assert_eq!(Layout::from_json(&serde_json::to_string(&layout).unwrap()).unwrap(), layout);
        }
    }

    #[test]
    fn builtin_cmu_layout_has_41_markers() {
        let layout = Layout::cmu41();
        assert_eq!(layout.markers.len(), 41);
    }
}
