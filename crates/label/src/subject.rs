//! Labeling a subject the template was not recorded on.
//!
//! The template's body ([`crate::body`]) is the template subject's: its segment shapes,
//! joint centres and tolerances. Marker plates and clusters keep their shapes from subject to
//! subject, but another subject's bones are longer or shorter and the plates sit elsewhere on
//! them, so the joint centres in the segments' frames move by centimetres, more than the
//! joints' tolerances; the first fit then places the upper body and leaves the rest unsure.
//! The labeling paper fits the subject's own model to the first frame ("T-pose model and
//! marker offsets relative to the inboard joints", section 3, last paragraph) and tracks
//! with its distances; here the subject's model is found on the take itself:
//!
//! 1. *First fit with loose joints*: the template's body places the segments it is sure of
//!    as they are; the body with every joint's tolerance widened by [`JOINT_SLACK_MM`] (and,
//!    for a template take, every segment marker's by [`SHAPE_SLACK_MM`]: one lab's plates
//!    differ from subject to subject) then places the others, those held as anchors (so a
//!    loosened joint still has its sure side). Labeling starts from the first frame sure of
//!    [`FIRST_PASS_FRACTION`] of the markers and runs forwards and backwards
//!    ([`crate::start`]). A near-flat plate fits its shape as well turned over on its long
//!    axis; its joints' twists tell the two apart ([`crate::pose_fit`]).
//! 2. *Calibration on the take*: the labeled take, without the samples that break an edge to
//!    a rigid neighbour by more than [`CALIBRATION_TOLERANCE_MM`] from the edge's median,
//!    gives a template of this subject ([`calibrated_template`]: its rigid edges and body),
//!    and the take is labeled again from scratch with it (the loose template body placing
//!    what the calibrated one lacks), so the first fit, tracking's edge costs and
//!    re-acquisition use this subject's distances. Rounds repeat [`CALIBRATION_ROUNDS`]
//!    times, each from the last one's labels, and the labels of the round that keeps the most
//!    samples' segment distances are kept (a round that keeps fewer can lead to one that keeps
//!    more). Before each calibration, two labels of a segment that the template's shape says
//!    are exchanged are exchanged back ([`crate::segment_swaps`]): the calibration would
//!    learn them as they are. A segment the calibrated body leaves out is placed by the loose
//!    body in its mirror partner's calibrated shape where the take showed that one
//!    ([`Body::with_partner_shapes`]: this subject's left foot is its right foot mirrored,
//!    not the template's foot).
//!
//! A take whose subject the template's own body fits is labeled as before: none of this
//! runs.

use crate::body::Body;
use crate::ik::MarkerModel;
use crate::pose_fit::fit_pose;
use crate::segment_swaps::unswap_segments;
use crate::{
    EdgeCheck, FitConfig, FitMethod, InitialFit, LabelConfig, LabelError, Labels, PointFrames, Template, fit_start,
};
use locap_clean::procrustes::{RigidTransform, align};
use locap_core::{UpAxis, Vec3};

impl Body {
    /// The body with `slack_mm` added to every joint's tolerance.
    pub fn with_joint_slack(&self, slack_mm: f64) -> Body {
        let mut body = self.clone();
        for j in &mut body.joints {
            j.tolerance_mm += slack_mm;
        }
        body
    }

    /// The body with `slack_mm` added to every segment marker's tolerance.
    pub fn with_shape_slack(&self, slack_mm: f64) -> Body {
        let mut body = self.clone();
        for seg in &mut body.segments {
            for t in &mut seg.tolerance_mm {
                *t += slack_mm;
            }
        }
        body
    }

    /// The body with the shape of every segment none of whose markers `calibrated` (a body
    /// of the same markers) places replaced by its mirror partner's there, where there is one
    /// (`partner[i]`: the marker on the other side of the body, `LHEE` for `RHEE`; a segment
    /// all of whose partners lie on one segment of `calibrated`), mirrored and turned onto the
    /// shape it replaces so that the joints keep their centres: a subject's left foot is the
    /// mirror image of the right one its take showed, where a generic model's foot can miss
    /// it by centimetres.
    pub fn with_partner_shapes(&self, calibrated: &Body, partner: &[Option<usize>]) -> Body {
        let mut body = self.clone();
        let placed = |i: usize| {
            calibrated.member.get(i).is_some_and(Option::is_some) || calibrated.attached.iter().any(|a| a.marker == i)
        };
        for seg in &mut body.segments {
            if seg.markers.iter().any(|&i| placed(i)) {
                continue;
            }
            let Some(mirrored) = mirror_partner(calibrated, seg, partner) else { continue };
            let Some(onto) = align(&mirrored.local_mm, &seg.local_mm) else { continue };
            seg.local_mm = mirrored.local_mm.iter().map(|p| onto.apply(p)).collect();
            seg.tolerance_mm = mirrored.tolerance_mm;
        }
        body
    }
}

/// `seg`'s markers with the shape and tolerances their partners have on one segment of
/// `body`, mirrored (the local frame's z turned over); `None` where a partner is missing or
/// the partners lie on more than one segment.
fn mirror_partner(body: &Body, seg: &crate::body::Segment, partner: &[Option<usize>]) -> Option<crate::body::Segment> {
    let on: Vec<(usize, usize)> = seg
        .markers
        .iter()
        .map(|&i| body.member.get(partner.get(i).copied().flatten()?).copied().flatten())
        .collect::<Option<_>>()?;
    let s = on.first()?.0;
    if on.iter().any(|&(t, _)| t != s) {
        return None;
    }
    let theirs = &body.segments[s];
    let shape: Vec<Vec3> = on.iter().map(|&(_, k)| theirs.local_mm[k]).collect();
    let centroid = shape.iter().sum::<Vec3>() / shape.len() as f64;
    Some(crate::body::Segment {
        markers: seg.markers.clone(),
        local_mm: shape
            .iter()
            .map(|p| {
                let q = p - centroid;
                Vec3::new(q.x, q.y, -q.z)
            })
            .collect(),
        tolerance_mm: on.iter().map(|&(_, k)| theirs.tolerance_mm[k]).collect(),
    })
}

/// For every marker of `names`, the marker of the same name on the other side of the body
/// (a leading `L` and `R` exchanged: `LHEE` and `RHEE`), where there is one.
pub fn mirror_partners(names: &[locap_core::MarkerName]) -> Vec<Option<usize>> {
    names
        .iter()
        .map(|n| {
            let label = n.label.as_str();
            let other = match label.as_bytes().first()? {
                b'L' => format!("R{}", &label[1..]),
                b'R' => format!("L{}", &label[1..]),
                _ => return None,
            };
            names.iter().position(|m| m.label == other)
        })
        .collect()
}

/// Widening of every joint's tolerance for the first fit of another subject (mm): the
/// template's joint centres sit where the template subject's markers put them in their
/// segments' frames, and another subject's markers sit centimetres elsewhere on the bone.
pub const JOINT_SLACK_MM: f64 = 100.0;

/// Widening of every segment marker's tolerance for the first pass over another subject
/// when the template is a take (mm). One lab's plates are not one plate: another subject's
/// plate, labeled as its anatomy says (proximal markers farther from the ankle, anterior ones
/// towards the toes), can differ from the template's by more than the template's tolerances
/// in its distances, while the same points labeled with the plate turned over fit the
/// template's shape closer; the first pass then labels the plate turned over and every
/// calibration round learns it. Widened, the right labels fit too, and the joints' twists
/// refuse the turned ones ([`crate::pose_fit`]). The calibrated body that labels the take has
/// the subject's own shapes back. Measurements: docs/labeling.md ("Another subject's plates").
pub const SHAPE_SLACK_MM: f64 = 15.0;

/// A first fit of another subject (before calibration) starts tracking when it is sure of
/// this share of the markers the body places: the calibrated fit that labels the take
/// needs [`crate::FitConfig::min_matched_fraction`] of its own.
pub const FIRST_PASS_FRACTION: f64 = 0.4;

/// Calibrations on the take (fewer when a calibrated template makes no body or no sure start).
pub const CALIBRATION_ROUNDS: usize = 4;

/// A labeled sample is kept for calibration when every edge to its labeled rigid neighbours
/// is within this of the edge's median length over the labeled take (mm).
pub const CALIBRATION_TOLERANCE_MM: f64 = 20.0;

/// Labels of a take, how labeling started, and the template of the take's subject when it
/// was calibrated on the take.
#[derive(Debug, Clone)]
pub struct Adapted {
    /// The labels (template marker order).
    pub labels: Labels,
    /// The first fit the labels start from.
    pub fit: InitialFit,
    /// The template calibrated on the take (same markers, this subject's distances), when the
    /// template's own body was not sure of any frame.
    pub calibrated: Option<Template>,
}

/// Labels `frames` (vertical axis `up`) with `template`: a template built from a marker
/// model ([`Template::is_model`]) always as another subject's; else from the template's own
/// first fit when it is sure of a frame; else, for another subject, from the first fit with loose
/// joints, then again with the template calibrated on the labels (module docs).
///
/// # Errors
/// [`LabelError::FirstFrame`] when neither fit is sure of a frame (the message says how many
/// markers each was sure of), or the calibrated template's fit is not.
pub fn label_adapting(
    frames: &PointFrames,
    template: &Template,
    config: &LabelConfig,
    up: UpAxis,
    pose_model: Option<MarkerModel>,
) -> Result<Adapted, LabelError> {
    if template.is_model() {
        // A generic model's distances are not the subject's: its labels only start the
        // calibration, whatever its own fit is sure of.
        return label_calibrating(frames, template, config, pose_model);
    }
    let own = fit_start(frames, template, up, &config.fit);
    match (own, template.body()) {
        (Err(LabelError::FirstFrame(own)), Some(_)) if config.fit.method == FitMethod::Articulated => {
            label_calibrating(frames, template, config, pose_model)
                .map_err(|e| LabelError::FirstFrame(format!("{own}; for another subject: {}", reason(e))))
        }
        (own, _) => {
            let fit = own?;
            let labels = crate::run(frames, template, config, &fit, pose_model)?;
            Ok(Adapted { labels, fit, calibrated: None })
        }
    }
}

/// Labels `frames` with `template` calibrated on them (module docs, steps 1 and 2), whether
/// or not the template's own body fits the subject.
///
/// # Errors
/// [`LabelError::Template`] for a template without a body; [`LabelError::FirstFrame`] when
/// the first fit with loose joints is sure of no frame.
pub fn label_calibrating(
    frames: &PointFrames,
    template: &Template,
    config: &LabelConfig,
    pose_model: Option<MarkerModel>,
) -> Result<Adapted, LabelError> {
    let body = template
        .body()
        .ok_or_else(|| LabelError::Template("the template shows no rigid segment of three markers".into()))?;
    // A model's segment tolerances already allow for where a technician puts the markers
    // (`crate::model`); a template take's are its own subject's plates.
    let shape_slack = if template.is_model() { 0.0 } else { SHAPE_SLACK_MM };
    let loose = template.with_body(body.with_joint_slack(JOINT_SLACK_MM).with_shape_slack(shape_slack));
    let loose_body = loose.body().unwrap_or(body);
    let first_pass = FitConfig { min_matched_fraction: FIRST_PASS_FRACTION, ..config.fit };
    let fit = two_stage_start(frames, &loose, body, loose_body, &first_pass)?;
    let mut labels = crate::run(frames, &loose, config, &fit, None)?;
    // The calibration would learn two exchanged labels as this subject's shape.
    unswap_segments(&mut labels, frames, body);
    let partners = mirror_partners(template.names());
    let mut best: Option<(usize, Adapted)> = None;
    let mut last = fit;
    // Round 0 scores the first pass; each later one labels the take again with the template
    // calibrated on the last labels; the labels that keep the most samples' segment distances
    // are returned.
    for round in 0..=CALIBRATION_ROUNDS {
        let calibrated = calibrated_template(&labels, frames, template)?;
        let (kept, _) = labels.median_edge_consistency(frames, template, CALIBRATION_TOLERANCE_MM);
        // A round that keeps fewer can still be followed by one that keeps more (a segment
        // learned in one round is placed in the next): every round runs, the best is kept.
        if best.as_ref().is_none_or(|(k, _)| kept > *k) {
            best = Some((
                kept,
                Adapted { labels: labels.clone(), fit: last.clone(), calibrated: Some(calibrated.clone()) },
            ));
        }
        if round == CALIBRATION_ROUNDS {
            break;
        }
        // The calibrated body places what the last labels showed; segments they missed are
        // placed by the template's loose body, anchored on the calibrated ones, in the shape
        // of their calibrated mirror partner where there is one.
        let Some(own_body) = calibrated.body() else { break };
        let loose_round = loose_body.with_partner_shapes(own_body, &partners);
        let Ok(fit) = two_stage_start(frames, &calibrated, own_body, &loose_round, &config.fit) else { break };
        labels = crate::run(frames, &calibrated, config, &fit, pose_model.clone())?;
        unswap_segments(&mut labels, frames, body);
        last = fit;
    }
    // Cannot be none: round 0 sets it.
    best.map(|(_, a)| a).ok_or_else(|| LabelError::FirstFrame("no calibration round".into()))
}

/// The start ([`crate::start::find_start`]) with two bodies of the same markers: `tight`
/// places the segments whose shapes and joints fit as they are (plates and clusters the
/// technician placed alike), `loose` then places the others with those held as anchors, so a
/// joint loosened for this subject still has its sure neighbour's side of it.
fn two_stage_start(
    frames: &PointFrames,
    template: &Template,
    tight: &Body,
    loose: &Body,
    config: &FitConfig,
) -> Result<InitialFit, LabelError> {
    let m = template.marker_count();
    let fit_frame = |points: &[Vec3]| {
        let first = fit_pose(tight, m, points, &[], &[]);
        let mut taken = vec![false; points.len()];
        for p in first.assignment.iter().flatten() {
            taken[*p] = true;
        }
        // The loose body's segments are not the tight one's (a calibrated body groups
        // markers its own way): anchor each loose segment all of whose markers the first
        // fit placed.
        let anchors: Vec<Option<RigidTransform>> = loose
            .segments
            .iter()
            .map(|seg| {
                let (from, to): (Vec<Vec3>, Vec<Vec3>) = seg
                    .markers
                    .iter()
                    .zip(&seg.local_mm)
                    .map(|(&i, l)| Some((*l, first.expected_mm[i]?)))
                    .collect::<Option<Vec<_>>>()?
                    .into_iter()
                    .unzip();
                align(&from, &to)
            })
            .collect();
        let rest = fit_pose(loose, m, points, &taken, &anchors);
        let mut merged = first;
        for i in 0..m {
            if merged.expected_mm[i].is_none() {
                merged.assignment[i] = rest.assignment[i];
                merged.expected_mm[i] = rest.expected_mm[i];
            }
        }
        merged.sure_markers = merged.expected_mm.iter().flatten().count();
        merged
    };
    crate::start::find_start_with(frames, template, loose.placeable(), config, fit_frame)
}

fn reason(e: LabelError) -> String {
    match e {
        LabelError::FirstFrame(reason) => reason,
        other => other.to_string(),
    }
}

/// The template of the subject `labels` show: the labeled take of `frames` with every sample
/// that breaks an edge to a labeled rigid neighbour (rigid in `template`) by more than
/// [`CALIBRATION_TOLERANCE_MM`] from the edge's median over the take left out, as a
/// template (its edges, body and reference frame from these frames; same markers and order
/// as `template`).
///
/// # Errors
/// [`LabelError::Template`] when too little is left to make a template.
pub fn calibrated_template(labels: &Labels, frames: &PointFrames, template: &Template) -> Result<Template, LabelError> {
    let checks = labels.median_edge_checks(frames, template, CALIBRATION_TOLERANCE_MM);
    let mut take = labels.to_take(frames, template.names(), None, false);
    let m = template.marker_count();
    for f in 0..labels.frame_count() {
        for i in 0..m {
            if checks[f * m + i] == Some(EdgeCheck::Broken) {
                // Cannot fail: frame and column are inside the take made above.
                let _ = take.set_position_mm(f, i, None);
            }
        }
    }
    Template::from_take(&take, None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::tests::hinge_take;
    use nalgebra::Rotation3;

    /// Another subject on the hinge take's body: the same plates, the lower one strapped
    /// 120 mm further down its bone (its joint centre moves by that in the plate's frame),
    /// swinging the other way and turned; points in a new order every frame.
    fn other_subject(frames: usize) -> (PointFrames, Vec<Vec<usize>>) {
        let upper = [[0.0, 0.0, 60.0], [80.0, 0.0, 200.0], [-50.0, 40.0, 320.0], [0.0, -60.0, 150.0]];
        let lower = [[0.0, 30.0, -80.0], [70.0, 0.0, -220.0], [-40.0, -50.0, -300.0], [20.0, 60.0, -150.0]];
        let mut out = PointFrames::with_rate(100.0);
        let mut truth = Vec::new();
        for f in 0..frames {
            let s = f as f64 / frames as f64;
            let body = Rotation3::from_euler_angles(0.0, 0.0, 2.5 - s);
            let knee = Rotation3::from_euler_angles(1.0 + 0.8 * s, 0.0, 0.0);
            let origin = Vec3::new(-300.0 * s, 200.0, 1000.0);
            let mut points: Vec<Vec3> = upper.iter().map(|p| origin + body * Vec3::from(*p)).collect();
            points.extend(lower.iter().map(|p| origin + body * knee * (Vec3::from(*p) + Vec3::new(0.0, 0.0, -120.0))));
            points.push(origin + body * Vec3::new(100.0, 100.0, 100.0));
            // Marker k is at point order[k].
            let order: Vec<usize> = (0..9).map(|k| (k * 4 + f) % 9).collect();
            let mut cloud = vec![Vec3::zeros(); 9];
            for (k, &p) in order.iter().enumerate() {
                cloud[p] = points[k];
            }
            out.push_frame(cloud.into_iter().enumerate().map(|(c, p)| (c as u32, p)));
            truth.push(order);
        }
        (out, truth)
    }

    #[test]
    fn another_subject_is_labeled_after_calibration() {
        let template = Template::from_take(&hinge_take(200), None).unwrap();
        let (frames, truth) = other_subject(200);
        let config = LabelConfig::default();
        let adapted = label_calibrating(&frames, &template, &config, None).unwrap();
        assert!(adapted.calibrated.is_some());
        let mut right = 0;
        for (f, order) in truth.iter().enumerate() {
            for (m, &point) in order.iter().enumerate().take(8) {
                let got = adapted.labels.get(f, m);
                assert!(got.is_none() || got == Some(point), "frame {f} marker {m}: {got:?}");
                right += usize::from(got == Some(point));
            }
        }
        // The segment markers: every one labeled in nearly every frame.
        assert!(right >= 8 * 195, "{right} of {}", 8 * 200);
        let (kept, checked) = adapted.labels.median_edge_consistency(&frames, &template, 20.0);
        assert_eq!(kept, checked);
    }

    #[test]
    fn left_and_right_markers_are_partners() {
        let names: Vec<locap_core::MarkerName> =
            ["LHEE", "RHEE", "RFTB", "BHD", "LFTB", "LONE"].iter().map(|n| locap_core::MarkerName::parse(n)).collect();
        assert_eq!(mirror_partners(&names), vec![Some(1), Some(0), Some(4), None, Some(2), None]);
    }

    /// A segment the calibration never showed takes its partner's shape, mirrored, placed on
    /// the generic shape it replaces (so that its joints keep their centres); one with a
    /// marker calibrated, or without partners on one segment, keeps its own.
    #[test]
    fn a_missing_segment_takes_its_partners_shape_mirrored() {
        use crate::body::Segment;
        let right = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(200.0, 0.0, 30.0),
            Vec3::new(230.0, 40.0, 0.0),
            Vec3::new(215.0, -35.0, 5.0),
        ];
        // Markers 0-3 the right foot, 4-7 the left foot.
        let segment = |markers: Vec<usize>, local_mm: Vec<Vec3>| Segment {
            tolerance_mm: vec![10.0; markers.len()],
            markers,
            local_mm,
        };
        let member: Vec<Option<(usize, usize)>> = (0..8).map(|i| (i < 4).then_some((0, i))).collect();
        let calibrated = Body {
            segments: vec![segment((0..4).collect(), right.to_vec())],
            joints: vec![],
            attached: vec![],
            member,
        };
        // The generic left foot: a smaller foot, somewhere else in its own frame.
        let generic: Vec<Vec3> =
            right.iter().map(|p| Vec3::new(0.8 * p.x + 5.0, -0.8 * p.y, 0.8 * p.z - 20.0)).collect();
        let model_member: Vec<Option<(usize, usize)>> = (0..8).map(|i| Some((i / 4, i % 4))).collect();
        let model = Body {
            segments: vec![segment((0..4).collect(), generic.clone()), segment((4..8).collect(), generic.clone())],
            joints: vec![],
            attached: vec![],
            member: model_member,
        };
        let partner: Vec<Option<usize>> = (0..8).map(|i| Some((i + 4) % 8)).collect();
        let out = model.with_partner_shapes(&calibrated, &partner);
        // The right foot is calibrated: its generic shape stays.
        assert_eq!(out.segments[0], model.segments[0]);
        // The left one is the right one mirrored: every distance the right one's, and no
        // rotation turns it onto the right one.
        let left = &out.segments[1].local_mm;
        for a in 0..4 {
            for b in 0..4 {
                assert!(((left[a] - left[b]).norm() - (right[a] - right[b]).norm()).abs() < 1e-9);
            }
        }
        let volume = |p: &[Vec3]| (p[1] - p[0]).cross(&(p[2] - p[0])).dot(&(p[3] - p[0]));
        assert!((volume(left) + volume(&right)).abs() < 1e-6 && volume(&right).abs() > 1.0);
        // Placed on the generic shape it replaces: closer to it than the bare mirror image.
        let rms = |p: &[Vec3]| (p.iter().zip(&generic).map(|(a, b)| (a - b).norm_squared()).sum::<f64>() / 4.0).sqrt();
        let bare: Vec<Vec3> = right.iter().map(|p| Vec3::new(p.x, p.y, -p.z)).collect();
        assert!(rms(left) < rms(&bare), "{} against {}", rms(left), rms(&bare));
        // Without partners nothing changes.
        assert_eq!(model.with_partner_shapes(&calibrated, &[None; 8]), model);
    }

    #[test]
    fn joint_slack_widens_joints_only() {
        let template = Template::from_take(&hinge_take(200), None).unwrap();
        let body = template.body().unwrap();
        let loose = body.with_joint_slack(50.0);
        assert_eq!(loose.segments, body.segments);
        for (a, b) in loose.joints.iter().zip(&body.joints) {
            assert!((a.tolerance_mm - b.tolerance_mm - 50.0).abs() < 1e-9);
        }
    }
}
