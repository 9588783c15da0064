//! Labels of the first frame: fit the template's reference pose to the first raw cloud
//! (labeling paper section 3, last paragraph: the subject starts in a known pose "with all
//! markers visible" and the model is fitted "by minimizing the distances between the markers
//! on the model and captured 1st frame").
//!
//! Assumption, documented for users: the first frame of the raw take shows the subject in
//! roughly the template's pose (a T-pose template for a take that starts in a T-pose, or the
//! template take's own first frame). The fit is rigid: the template may stand anywhere in the
//! volume, facing any direction about the vertical axis. It is an iterative closest point
//! fit from twelve headings with trimmed correspondences (robust to a few missing markers and
//! ghosts), finished by an optimal one-to-one assignment (Hungarian) of template markers to
//! points. A first frame whose markers cannot be matched is an error, never a guess.

use crate::LabelError;
use crate::assignment::GatedAssignment;
use crate::template::Template;
use locap_clean::procrustes::{RigidTransform, align};
use locap_core::{UpAxis, Vec3};
use nalgebra::{Rotation3, Unit};
use serde::{Deserialize, Serialize};

/// How labeling finds its first labels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum FitMethod {
    /// Fit the template's articulated body ([`crate::pose_fit`]) to the first frame where the
    /// fit is sure, whatever the pose; templates too short to learn a body fall back to
    /// [`FitMethod::Rigid`].
    #[default]
    Articulated,
    /// Fit the template's reference frame rigidly to the first frame (this module): the take
    /// must start in the template's pose.
    Rigid,
}

/// Settings of the first-frame fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitConfig {
    /// The fit.
    #[serde(default)]
    pub method: FitMethod,
    /// Rigid fit: a template marker is matched to a point only within this distance after
    /// the fit (mm). The articulated fit takes each marker's tolerance from the template.
    pub accept_mm: f64,
    /// Rigid fit: at least this fraction of the template's visible markers must be matched.
    /// Articulated fit: labeling starts at the first frame where the fit is sure of 90% of
    /// the markers it can place, else at the frame where it is sure of the most, if that is
    /// at least this fraction of them ([`crate::start`]).
    pub min_matched_fraction: f64,
}

impl Default for FitConfig {
    fn default() -> FitConfig {
        FitConfig { method: FitMethod::Articulated, accept_mm: 60.0, min_matched_fraction: 0.6 }
    }
}

/// Result of the first-frame fit.
#[derive(Debug, Clone, PartialEq)]
pub struct InitialFit {
    /// For each template marker, the index of its point in the frame, or `None`.
    pub assignment: Vec<Option<usize>>,
    /// Template reference pose -> raw frame.
    pub transform: RigidTransform,
    /// Root mean square distance of the matched markers after the fit (mm).
    pub rms_mm: f64,
    /// The frame fitted (labeling runs forwards and backwards from it).
    pub frame: usize,
    /// Markers whose place the fit is sure of (all the matched ones for the rigid fit);
    /// the others are left to tracking and re-acquisition.
    pub sure_markers: usize,
    /// Where the fit expects each marker it is sure of (mm), also without a point.
    pub expected_mm: Vec<Option<Vec3>>,
}

const HEADINGS: usize = 12;
const ICP_ITERATIONS: usize = 30;

/// Fits `template` to the cloud `points` (mm) whose vertical axis is `up`.
pub fn fit_first_frame(
    template: &Template,
    points: &[Vec3],
    up: UpAxis,
    config: &FitConfig,
) -> Result<InitialFit, LabelError> {
    let source: Vec<(usize, Vec3)> =
        template.reference_mm().iter().enumerate().filter_map(|(m, p)| p.map(|p| (m, p))).collect();
    if points.len() < 3 {
        return Err(LabelError::FirstFrame(format!(
            "the first frame has {} points; at least 3 are needed",
            points.len()
        )));
    }
    let axis = match up {
        UpAxis::Y => Vec3::y_axis(),
        UpAxis::Z => Vec3::z_axis(),
    };
    let source_centroid = source.iter().map(|(_, p)| p).sum::<Vec3>() / source.len() as f64;
    let target_centroid = points.iter().sum::<Vec3>() / points.len() as f64;
    let mut best: Option<(f64, RigidTransform)> = None;
    for h in 0..HEADINGS {
        let angle = std::f64::consts::TAU * h as f64 / HEADINGS as f64;
        let rotation = Rotation3::from_axis_angle(&Unit::new_normalize(axis.into_inner()), angle);
        let start = RigidTransform { rotation, translation: target_centroid - rotation * source_centroid };
        let fitted = icp(&source, points, start);
        let score = truncated_score(&source, points, &fitted, config.accept_mm);
        if best.as_ref().is_none_or(|(s, _)| score < *s) {
            best = Some((score, fitted));
        }
    }
    let (_, transform) = best.ok_or_else(|| LabelError::FirstFrame("the template has no visible markers".into()))?;

    let placed = refine_segments(template, points, &transform);

    // One-to-one matching within the acceptance distance.
    let mut assignment = GatedAssignment::default();
    assignment.begin(points.len());
    let limit2 = config.accept_mm * config.accept_mm;
    for p in &placed {
        assignment.push_marker(limit2);
        if let Some(moved) = p {
            let moved = *moved;
            for (j, q) in points.iter().enumerate() {
                let d2 = (moved - q).norm_squared();
                if d2 < limit2 {
                    assignment.push_candidate(j, d2);
                }
            }
        }
    }
    let matched: Vec<Option<usize>> = assignment.solve().iter().map(|a| a.map(|p| p as usize)).collect();
    let pairs: Vec<(Vec3, Vec3)> =
        matched.iter().zip(&placed).filter_map(|(a, p)| Some(((*p)?, points[(*a)?]))).collect();
    let needed = ((source.len() as f64 * config.min_matched_fraction).ceil() as usize).max(3);
    if pairs.len() < needed {
        return Err(LabelError::FirstFrame(format!(
            "only {} of the template's {} markers lie within {} mm of a point after the best rigid fit \
             (at least {needed} needed): the take's first frame does not show the template's pose",
            pairs.len(),
            source.len(),
            config.accept_mm
        )));
    }
    let rms_mm = (pairs.iter().map(|(a, b)| (a - b).norm_squared()).sum::<f64>() / pairs.len() as f64).sqrt();
    let sure_markers = pairs.len();
    let expected_mm = matched.iter().map(|_| None).collect();
    Ok(InitialFit { assignment: matched, transform, rms_mm, frame: 0, sure_markers, expected_mm })
}

/// Neighbours whose distance spread over the template is at most this (mm) move with a
/// marker as one segment during refinement.
const SEGMENT_STD_MM: f64 = 25.0;

/// Articulated refinement: the subject's limbs need not be posed exactly as in the template.
/// Starting from the whole-body fit, every marker's segment (the marker and its rigid
/// neighbours) is fitted again on its own, by trimmed ICP with a shrinking search radius,
/// and the marker is placed where its segment's fit puts it.
fn refine_segments(template: &Template, points: &[Vec3], body: &RigidTransform) -> Vec<Option<Vec3>> {
    let reference = template.reference_mm();
    let (mut from, mut to) = (Vec::new(), Vec::new());
    (0..template.marker_count())
        .map(|i| {
            let r = reference[i]?;
            let group: Vec<Vec3> = std::iter::once(r)
                .chain(
                    template.edges()[i]
                        .iter()
                        .filter(|e| e.std_mm <= SEGMENT_STD_MM)
                        .filter_map(|e| reference[e.neighbour]),
                )
                .collect();
            let mut transform = *body;
            if group.len() >= 3 {
                for radius in [200.0, 150.0, 100.0, 80.0, 60.0, 60.0, 60.0] {
                    from.clear();
                    to.clear();
                    for p in &group {
                        let moved = transform.apply(p);
                        let nearest = points
                            .iter()
                            .map(|q| ((moved - q).norm_squared(), q))
                            .min_by(|a, b| a.0.total_cmp(&b.0))
                            .expect("at least 3 points");
                        if nearest.0 < radius * radius {
                            from.push(*p);
                            to.push(*nearest.1);
                        }
                    }
                    match align(&from, &to) {
                        Some(next) => transform = next,
                        None => break,
                    }
                }
            }
            Some(transform.apply(&r))
        })
        .collect()
}

/// Iterative closest point with trimmed correspondences: each iteration pairs every source
/// marker with its nearest point, keeps the pairs within three times the median distance
/// (at least 30 mm), and re-aligns.
fn icp(source: &[(usize, Vec3)], points: &[Vec3], mut transform: RigidTransform) -> RigidTransform {
    let mut pairs: Vec<(f64, Vec3, Vec3)> = Vec::with_capacity(source.len());
    let (mut from, mut to) = (Vec::with_capacity(source.len()), Vec::with_capacity(source.len()));
    for _ in 0..ICP_ITERATIONS {
        pairs.clear();
        for (_, p) in source {
            let moved = transform.apply(p);
            let nearest = points
                .iter()
                .map(|q| ((moved - q).norm_squared(), *q))
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .expect("at least 3 points");
            pairs.push((nearest.0.sqrt(), *p, nearest.1));
        }
        let mut distances: Vec<f64> = pairs.iter().map(|p| p.0).collect();
        distances.sort_unstable_by(f64::total_cmp);
        let keep_below = (3.0 * distances[distances.len() / 2]).max(30.0);
        from.clear();
        to.clear();
        for (d, p, q) in &pairs {
            if *d <= keep_below {
                from.push(*p);
                to.push(*q);
            }
        }
        match align(&from, &to) {
            Some(next) => {
                let moved = (next.translation - transform.translation).norm();
                transform = next;
                if moved < 1e-3 {
                    break;
                }
            }
            None => break,
        }
    }
    transform
}

/// Sum over source markers of the squared distance to the nearest point, each capped at
/// `cap_mm`: markers without a point (occluded, or a different pose) cost the cap.
fn truncated_score(source: &[(usize, Vec3)], points: &[Vec3], transform: &RigidTransform, cap_mm: f64) -> f64 {
    source
        .iter()
        .map(|(_, p)| {
            let moved = transform.apply(p);
            points.iter().map(|q| (moved - q).norm_squared()).fold(cap_mm * cap_mm, f64::min)
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{MarkerName, Take};

    /// A small asymmetric "body" of 8 markers.
    fn body() -> Vec<Vec3> {
        vec![
            Vec3::new(0.0, 0.0, 1000.0),
            Vec3::new(150.0, 0.0, 1000.0),
            Vec3::new(0.0, 100.0, 1050.0),
            Vec3::new(-200.0, 0.0, 1400.0),
            Vec3::new(300.0, 20.0, 1400.0),
            Vec3::new(50.0, -80.0, 1600.0),
            Vec3::new(-100.0, 30.0, 500.0),
            Vec3::new(120.0, 30.0, 100.0),
        ]
    }

    fn template() -> Template {
        let names = (0..8).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let samples: Vec<Option<Vec3>> = body().into_iter().map(Some).collect();
        Template::from_take(&Take::from_samples(names, &samples, 100.0).unwrap(), None).unwrap()
    }

    #[test]
    fn finds_a_turned_and_moved_subject_among_ghosts() {
        let rotation = Rotation3::from_axis_angle(&Vec3::z_axis(), 2.0);
        let shift = Vec3::new(1500.0, -700.0, 0.0);
        // Shuffled order, marker 3 missing, two ghosts.
        let order = [5usize, 0, 7, 2, 6, 1, 4];
        let mut points: Vec<Vec3> = order.iter().map(|&m| rotation * body()[m] + shift).collect();
        points.insert(2, Vec3::new(0.0, 0.0, 0.0));
        points.push(rotation * body()[4] + shift + Vec3::new(200.0, 0.0, 0.0));
        let fit = fit_first_frame(&template(), &points, UpAxis::Z, &FitConfig::default()).unwrap();
        for (m, a) in fit.assignment.iter().enumerate() {
            match a {
                Some(p) => assert!((points[*p] - (rotation * body()[m] + shift)).norm() < 1e-6, "marker {m}"),
                None => assert_eq!(m, 3),
            }
        }
        assert!(fit.rms_mm < 1e-6);
    }

    #[test]
    fn refuses_a_frame_that_does_not_show_the_pose() {
        let points: Vec<Vec3> = (0..8).map(|i| Vec3::new(i as f64 * 700.0, (i * i) as f64 * 90.0, 0.0)).collect();
        let err = fit_first_frame(&template(), &points, UpAxis::Z, &FitConfig::default()).unwrap_err();
        assert!(err.to_string().contains("does not show the template's pose"), "{err}");
        assert!(fit_first_frame(&template(), &points[..2], UpAxis::Z, &FitConfig::default()).is_err());
    }
}
