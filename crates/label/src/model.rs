//! A template from a marker model alone: markers on the bones of a skeleton at its rest pose,
//! with no labeled take (issue 16, item 1b: a layout built from an OpenSim model and marker
//! set, `locap layout --from-opensim`).
//!
//! The labeling paper fits "the T-pose model and marker offsets relative to the inboard
//! joints" to the first frame (section 3, last paragraph); this is that model in the form the
//! articulated first fit reads ([`crate::body`]), built from the skeleton instead of learned
//! from a take:
//! - *segments*: the markers of every bone that carries at least three, their shape the rest
//!   pose's (in the rest frame, about their centroid);
//! - *joints*: a segment joins the nearest ancestor bone that is a segment, at the skeleton
//!   joint where the path between them leaves that ancestor (a foot joins its shank at the
//!   ankle, through a talus without markers); where the skeleton's joints on the way turn
//!   about one axis in all (a knee), the joint is a hinge about it
//!   ([`Template::from_model_with_axes`]);
//! - *attached markers*: a marker on a bone with fewer than three markers (a hand's single
//!   marker) rides on the nearest ancestor segment;
//! - *rigid edges*: each marker's neighbours on its own bone first, nearest first, then the
//!   nearest markers elsewhere, as non-rigid edges (tracking estimates with them but does not
//!   match on them).
//!
//! A generic model is not the subject: its bones are longer or shorter, and the technician
//! puts the markers a little elsewhere. Every tolerance therefore grows with the distance it
//! spans ([`SUBJECT_SCALE_SLACK`]) on top of a placement allowance ([`PLACEMENT_MM`]), and an
//! anatomical landmark on a bone that also carries a cluster plate (an ankle marker below a
//! shank plate) is allowed a third of its distance from the plate more, since where the
//! technician straps the plate is this subject's, not the model's (`plate_offsets_mm`). The
//! model only starts labeling: [`crate::subject::label_calibrating`] then labels the take with
//! joints loosened further and makes the subject's own template from the labeled take, which
//! the take is labeled with again.

use crate::LabelError;
use crate::body::{Attached, Body, Hinge, Joint, MIN_TWIST_ARM_MM, NOISE_MM, Segment, Twist};
use crate::template::{Edge, RANKED_NEIGHBOURS, Template};
use locap_core::skeleton::forward_kinematics;
use locap_core::{MarkerName, Quat, Skeleton, Vec3};

/// Relative size difference between the model and a subject that tolerances allow for (a
/// share of the distance a tolerance spans): adults differ from a generic model by about this
/// much in segment lengths.
pub const SUBJECT_SCALE_SLACK: f64 = 0.15;

/// How far a marker may sit from the model's place on its bone, beyond scale (mm): markers
/// are put on by hand, on landmarks a finger's width across.
pub const PLACEMENT_MM: f64 = 15.0;

/// Standard deviation given to an edge between two markers of one bone (mm), at most: under
/// the labeler's rigid limit and the median check's (12 mm), so such edges are matched on.
const MAX_RIGID_STD_MM: f64 = 10.0;

/// Standard deviation given to an edge between markers of different bones (mm): over the
/// labeler's rigid limit (`LabelConfig::max_edge_std_mm`, 25 mm by default), so tracking
/// uses them to estimate but not to match.
const LOOSE_STD_MM: f64 = 40.0;

/// A marker of a model: its label, the skeleton joint (bone) it rides on and where it is at
/// the skeleton's rest pose.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelMarker {
    /// Marker label.
    pub name: MarkerName,
    /// Index of its joint in the skeleton.
    pub joint: usize,
    /// Position at rest (every joint rotation the identity, root at the origin), mm.
    pub rest_mm: Vec3,
}

impl Template {
    /// The template of a marker model (module docs): `markers` on the bones of `skeleton` at
    /// its rest pose. The reference pose is the rest pose; the body and edges come from the
    /// model with tolerances wide enough for another subject. Label a take with it through
    /// [`crate::subject::label_calibrating`] (what [`crate::label_take`] does for a model
    /// template: [`Template::is_model`]).
    ///
    /// # Errors
    /// [`LabelError::Template`] for fewer than three markers, a joint index outside the
    /// skeleton, a position that is not finite, two markers of one name, or no bone with
    /// three markers.
    pub fn from_model(skeleton: &Skeleton, markers: &[ModelMarker]) -> Result<Template, LabelError> {
        Template::from_model_with_axes(skeleton, markers, &[])
    }

    /// [`Template::from_model`] for a skeleton whose joints' rotation axes are known:
    /// `axes[j]` the axes joint `j` turns about (in its frame at rest; empty for a fixed
    /// joint, `None` or missing where not known). A joint between two segments that turns
    /// about one axis in all (a knee, an elbow) is a hinge ([`crate::body::Joint::hinge`]),
    /// which tells a marker plate from the same plate turned over.
    ///
    /// # Errors
    /// As [`Template::from_model`].
    pub fn from_model_with_axes(
        skeleton: &Skeleton,
        markers: &[ModelMarker],
        axes: &[Option<Vec<Vec3>>],
    ) -> Result<Template, LabelError> {
        let bad = |what: String| Err(LabelError::Template(what));
        if markers.len() < 3 {
            return bad(format!("the model has {} markers; at least 3 are needed", markers.len()));
        }
        let mut seen = std::collections::HashSet::new();
        for m in markers {
            if m.joint >= skeleton.len() {
                return bad(format!("marker {}: joint {} outside the skeleton's {}", m.name, m.joint, skeleton.len()));
            }
            if !m.rest_mm.iter().all(|v| v.is_finite()) {
                return bad(format!("marker {}: rest position {:?} is not finite", m.name, m.rest_mm));
            }
            if !seen.insert(m.name.to_string()) {
                return bad(format!("marker {} appears twice in the model", m.name));
            }
        }
        let body = model_body(skeleton, markers, axes)
            .ok_or_else(|| LabelError::Template("no bone of the model carries three markers".into()))?;
        let edges = model_edges(markers, &body);
        let names = markers.iter().map(|m| m.name.clone()).collect();
        let reference_mm = markers.iter().map(|m| Some(m.rest_mm)).collect();
        Ok(Template::from_parts(names, reference_mm, edges, Some(body), true))
    }
}

/// Tolerance of a placement spanning `distance_mm` (scale and placement, module docs).
fn tolerance(distance_mm: f64) -> f64 {
    NOISE_MM + PLACEMENT_MM + SUBJECT_SCALE_SLACK * distance_mm
}

/// Most distant two markers of a plate may be (mm): cluster plates are a hand's width across.
pub const PLATE_SPAN_MM: f64 = 150.0;

/// Smallest number of markers that make a plate: four fix a rigid shape with one to spare.
const PLATE_MARKERS: usize = 4;

/// For each of one bone's markers at `rest_mm`, how far it sits from the bone's plate (mm):
/// 0 for the plate's own markers and for every marker of a bone without one. A plate is the
/// largest group of [`PLATE_MARKERS`] or more markers within [`PLATE_SPAN_MM`] of each other
/// (a cluster strapped to the segment); the bone's other markers are anatomical landmarks (an
/// ankle, an acromion), and where the landmark sits from the plate depends on where the
/// technician strapped the plate on this subject's bone, not on the model: a third of that
/// distance on top of the scale allowance, as for a marker across a joint. Without it the
/// plate's true placement leaves its landmark out of tolerance, and a placement slid along
/// the bone that matches the landmark costs as little (`docs/labeling.md`).
fn plate_offsets_mm(rest_mm: &[Vec3]) -> Vec<f64> {
    let n = rest_mm.len();
    let near = |a: usize, b: usize| (rest_mm[a] - rest_mm[b]).norm() <= PLATE_SPAN_MM;
    // Grow a group from each marker, nearest first, keeping every pair within the span; the
    // largest group (the first found on ties) is the plate.
    let mut plate: Vec<usize> = Vec::new();
    for seed in 0..n {
        let mut order: Vec<usize> = (0..n).filter(|&j| j != seed).collect();
        order.sort_by(|&a, &b| (rest_mm[a] - rest_mm[seed]).norm().total_cmp(&(rest_mm[b] - rest_mm[seed]).norm()));
        let mut group = vec![seed];
        for j in order {
            if group.iter().all(|&g| near(g, j)) {
                group.push(j);
            }
        }
        if group.len() > plate.len() {
            plate = group;
        }
    }
    if plate.len() < PLATE_MARKERS || plate.len() == n {
        return vec![0.0; n];
    }
    let centre = plate.iter().map(|&j| rest_mm[j]).sum::<Vec3>() / plate.len() as f64;
    (0..n).map(|i| if plate.contains(&i) { 0.0 } else { (rest_mm[i] - centre).norm() }).collect()
}

/// A model joint's twists: none at the rest pose, where every segment's frame is the
/// model's (each bone from the joint's centre, `child_mm` / `parent_mm` in its segment's
/// frame, to its segment's centroid, the frame's origin). The first fit's quarter turn of
/// allowance past them covers a hip's, knee's or neck's turn about its bone and most of a
/// shoulder's or forearm's; a plate turned over is half a turn off.
fn rest_twist(parent_mm: Vec3, child_mm: Vec3) -> Option<[Twist; 2]> {
    let bone = |axis: Vec3| Twist { axis, mean_rad: 0.0, half_width_rad: 0.0 };
    Some([bone((-child_mm).try_normalize(MIN_TWIST_ARM_MM)?), bone((-parent_mm).try_normalize(MIN_TWIST_ARM_MM)?)])
}

fn model_body(skeleton: &Skeleton, markers: &[ModelMarker], axes: &[Option<Vec<Vec3>>]) -> Option<Body> {
    let rest = forward_kinematics(skeleton, &vec![Quat::identity(); skeleton.len()], Vec3::zeros());
    let joints = skeleton.joints();
    // Bones with three markers or more are segments.
    let mut segment_of_joint = vec![None; skeleton.len()];
    let mut segments: Vec<Segment> = Vec::new();
    for (j, slot) in segment_of_joint.iter_mut().enumerate() {
        let on: Vec<usize> = (0..markers.len()).filter(|&i| markers[i].joint == j).collect();
        if on.len() < 3 {
            continue;
        }
        let centroid = on.iter().map(|&i| markers[i].rest_mm).sum::<Vec3>() / on.len() as f64;
        let local_mm: Vec<Vec3> = on.iter().map(|&i| markers[i].rest_mm - centroid).collect();
        let rest: Vec<Vec3> = on.iter().map(|&i| markers[i].rest_mm).collect();
        let beside = plate_offsets_mm(&rest);
        let tolerance_mm = local_mm.iter().zip(&beside).map(|(l, b)| tolerance(l.norm()) + b / 3.0).collect();
        *slot = Some(segments.len());
        segments.push(Segment { markers: on, local_mm, tolerance_mm });
    }
    if segments.is_empty() {
        return None;
    }
    let centroid = |s: &Segment, k: usize| markers[s.markers[k]].rest_mm - s.local_mm[k];
    // The nearest ancestor of `j` that is a segment, and the joint just below it on the way.
    let ancestor = |j: usize| {
        let (mut below, mut at) = (j, joints[j].parent?);
        loop {
            if let Some(s) = segment_of_joint[at] {
                return Some((s, below));
            }
            (below, at) = (at, joints[at].parent?);
        }
    };
    let mut body_joints = Vec::new();
    // Skeleton order puts parents first, so joints come parents before children.
    for (j, own) in segment_of_joint.iter().enumerate() {
        let Some(child) = *own else { continue };
        let Some((parent, below)) = ancestor(j) else { continue };
        let centre = rest.positions_mm[below];
        let (pc, cc) = (centroid(&segments[parent], 0), centroid(&segments[child], 0));
        // Both ends may be off by the subject's scale: the centre from the parent's side and
        // from the child's.
        let tolerance_mm = tolerance((centre - pc).norm() + (centre - cc).norm());
        // The rotations between the two bones: those of every joint from the child's bone up
        // to the one just below the parent's. One axis in all makes a hinge.
        let mut turns: Option<Vec<Vec3>> = Some(Vec::new());
        let mut at = j;
        loop {
            match (turns.as_mut(), axes.get(at).cloned().flatten()) {
                (Some(t), Some(a)) => t.extend(a),
                _ => turns = None,
            }
            if at == below {
                break;
            }
            // Cannot fail: `below` is an ancestor of `j`.
            let Some(up) = joints[at].parent else { break };
            at = up;
        }
        let hinge = match turns.as_deref() {
            Some([axis]) if axis.norm() > 0.0 => Some(Hinge::shared(axis.normalize())),
            _ => None,
        };
        body_joints.push(Joint {
            parent,
            child,
            parent_mm: centre - pc,
            child_mm: centre - cc,
            tolerance_mm,
            hinge,
            twist: rest_twist(centre - pc, centre - cc),
        });
    }
    let mut member = vec![None; markers.len()];
    for (s, seg) in segments.iter().enumerate() {
        for (k, &i) in seg.markers.iter().enumerate() {
            member[i] = Some((s, k));
        }
    }
    let attached = (0..markers.len())
        .filter(|&i| member[i].is_none())
        .filter_map(|i| {
            let j = markers[i].joint;
            let (segment, _) = segment_of_joint[j].map(|s| (s, j)).or_else(|| ancestor(j))?;
            let local_mm = markers[i].rest_mm - centroid(&segments[segment], 0);
            // Across a joint (a wrist, an ankle) the marker swings with the joint's rotation:
            // a third of its distance on top of the scale allowance.
            let tolerance_mm = tolerance(local_mm.norm()) + local_mm.norm() / 3.0;
            Some(Attached { marker: i, segment, local_mm, tolerance_mm })
        })
        .collect();
    Some(Body { segments, joints: body_joints, attached, member })
}

/// Each marker's [`RANKED_NEIGHBOURS`] neighbours: those on its own bone, nearest first, as
/// rigid edges, then the nearest others as loose ones (module docs).
fn model_edges(markers: &[ModelMarker], body: &Body) -> Vec<Vec<Edge>> {
    let bone = |i: usize| markers[i].joint;
    (0..markers.len())
        .map(|i| {
            let mut others: Vec<(bool, f64, usize)> = (0..markers.len())
                .filter(|&j| j != i)
                .map(|j| {
                    // Attached markers are on no rigid shape the model knows.
                    let rigid = bone(i) == bone(j) && body.member[i].is_some() && body.member[j].is_some();
                    (!rigid, (markers[i].rest_mm - markers[j].rest_mm).norm(), j)
                })
                .collect();
            others.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
            others
                .into_iter()
                .take(RANKED_NEIGHBOURS)
                .map(|(loose, length_mm, neighbour)| {
                    let std_mm = if loose {
                        LOOSE_STD_MM
                    } else {
                        (SUBJECT_SCALE_SLACK / 3.0 * length_mm + NOISE_MM).min(MAX_RIGID_STD_MM)
                    };
                    Edge { neighbour, length_mm, std_mm }
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::Joint as SkeletonJoint;

    /// A leg: pelvis, thigh, a marker-less talus-like link, a foot with three markers and a
    /// toe with one.
    fn leg() -> (Skeleton, Vec<ModelMarker>) {
        let skeleton = Skeleton::new(vec![
            SkeletonJoint::new("pelvis", None, Vec3::zeros()),
            SkeletonJoint::new("thigh", Some(0), Vec3::new(100.0, -50.0, 0.0)),
            SkeletonJoint::new("link", Some(1), Vec3::new(0.0, -400.0, 0.0)),
            SkeletonJoint::new("foot", Some(2), Vec3::new(0.0, -40.0, 0.0)),
        ])
        .unwrap();
        let m = |name: &str, joint: usize, p: [f64; 3]| ModelMarker {
            name: MarkerName::parse(name),
            joint,
            rest_mm: Vec3::from(p),
        };
        let markers = vec![
            m("P1", 0, [0.0, 0.0, 100.0]),
            m("P2", 0, [100.0, 0.0, 100.0]),
            m("P3", 0, [50.0, 50.0, -100.0]),
            m("T1", 1, [150.0, -200.0, 0.0]),
            m("T2", 1, [100.0, -250.0, 60.0]),
            m("T3", 1, [60.0, -300.0, 0.0]),
            m("F1", 3, [100.0, -500.0, -50.0]),
            m("F2", 3, [100.0, -500.0, 150.0]),
            m("F3", 3, [60.0, -490.0, 100.0]),
            m("X", 2, [120.0, -460.0, 0.0]),
        ];
        (skeleton, markers)
    }

    #[test]
    fn bones_become_segments_joined_through_bare_links() {
        let (skeleton, markers) = leg();
        let template = Template::from_model(&skeleton, &markers).unwrap();
        assert!(template.is_model());
        let body = template.body().unwrap();
        let groups: Vec<Vec<usize>> = body.segments.iter().map(|s| s.markers.clone()).collect();
        assert_eq!(groups, vec![vec![0, 1, 2], vec![3, 4, 5], vec![6, 7, 8]]);
        assert_eq!(body.joints.len(), 2);
        // The foot joins the thigh at the link's joint (the knee), not at its own (the ankle).
        let foot = body.joints.iter().find(|j| j.child == 2).unwrap();
        assert_eq!(foot.parent, 1);
        let thigh_centroid = Vec3::new(310.0, -750.0, 60.0) / 3.0;
        assert!((foot.parent_mm + thigh_centroid - Vec3::new(100.0, -450.0, 0.0)).norm() < 1e-9);
        // The link's marker rides on the thigh.
        assert_eq!(body.attached.len(), 1);
        assert_eq!((body.attached[0].marker, body.attached[0].segment), (9, 1));
        // Own-bone edges first and rigid, the rest loose.
        let e = &template.edges()[0];
        assert_eq!(e.len(), RANKED_NEIGHBOURS);
        assert!(e[..2].iter().all(|e| e.neighbour <= 2 && e.std_mm <= MAX_RIGID_STD_MM));
        assert!(e[2..].iter().all(|e| e.std_mm == LOOSE_STD_MM));
        // Every joint twists neither bone at the rest pose, each bone from the joint's centre
        // to its segment's centroid (the frame's origin), and allows nothing beyond.
        for j in &body.joints {
            let [child, parent] = j.twist.expect("both segments off the joint's centre");
            assert!((child.axis + j.child_mm.normalize()).norm() < 1e-9);
            assert!((parent.axis + j.parent_mm.normalize()).norm() < 1e-9);
            assert_eq!((child.mean_rad, child.half_width_rad, parent.half_width_rad), (0.0, 0.0, 0.0));
        }
    }

    #[test]
    fn one_axis_between_two_segments_makes_a_hinge() {
        let (skeleton, markers) = leg();
        let z = Vec3::new(0.0, 0.0, 2.0);
        let hinges = |axes: &[Option<Vec<Vec3>>]| -> Vec<Option<Vec3>> {
            let t = Template::from_model_with_axes(&skeleton, &markers, axes).unwrap();
            t.body().unwrap().joints.iter().map(|j| j.hinge.map(|h| h.child_axis)).collect()
        };
        // Hip: three axes. Knee (the link's joint) one, the ankle fixed: the foot hinges on the
        // thigh about the knee's axis, made a unit vector.
        let axes = vec![None, Some(vec![Vec3::x(), Vec3::y(), Vec3::z()]), Some(vec![z]), Some(vec![])];
        assert_eq!(hinges(&axes), vec![None, Some(Vec3::z())]);
        // An ankle that turns too: two axes between thigh and foot, no hinge.
        let two = vec![None, None, Some(vec![z]), Some(vec![Vec3::x()])];
        assert_eq!(hinges(&two), vec![None, None]);
        // Nothing known: no hinge, as from_model.
        assert_eq!(hinges(&[]), vec![None, None]);
        assert_eq!(Template::from_model(&skeleton, &markers).unwrap().body().unwrap().joints[1].hinge, None);
    }

    #[test]
    fn a_landmark_beside_a_plate_is_allowed_the_plate_strapped_elsewhere() {
        // A shank: a 70 x 65 mm plate and an ankle landmark 220 mm below its centre.
        let plate = [[35.0, -110.0, 50.0], [-40.0, -110.0, 50.0], [-40.0, -175.0, 50.0], [35.0, -175.0, 50.0]];
        let mut shank: Vec<Vec3> = plate.iter().map(|p| Vec3::from(*p)).collect();
        shank.push(Vec3::new(-2.5, -362.5, 50.0));
        let beside = plate_offsets_mm(&shank);
        assert_eq!(&beside[..4], &[0.0; 4]);
        assert!((beside[4] - 220.0).abs() < 1e-9);
        // A foot's four landmarks (heel and three forefoot markers): no plate of four, no
        // allowance; nor for a plate alone.
        let foot = [[-20.0, 20.0, 0.0], [120.0, 35.0, 40.0], [150.0, 45.0, 20.0], [160.0, 24.0, 50.0]];
        assert_eq!(plate_offsets_mm(&foot.map(Vec3::from)), vec![0.0; 4]);
        assert_eq!(plate_offsets_mm(&shank[..4]), vec![0.0; 4]);
    }

    #[test]
    fn bad_models_are_refused_with_reasons() {
        let (skeleton, mut markers) = leg();
        let mut far = markers.clone();
        far[0].joint = 9;
        assert!(matches!(Template::from_model(&skeleton, &far), Err(LabelError::Template(m)) if m.contains("joint 9")));
        let mut nan = markers.clone();
        nan[1].rest_mm.x = f64::NAN;
        assert!(Template::from_model(&skeleton, &nan).is_err());
        let mut twice = markers.clone();
        twice[1].name = MarkerName::parse("P1");
        assert!(Template::from_model(&skeleton, &twice).is_err());
        for m in &mut markers {
            m.joint = (m.joint + 1) % 4;
        }
        markers.truncate(2);
        assert!(Template::from_model(&skeleton, &markers).is_err());
    }
}
