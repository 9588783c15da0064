//! Layout calibration: marker offsets from real markers and the skeleton motion solved from
//! them (issue 5, "layout calibration from real data").
//!
//! Given takes whose labeled markers and skeleton motion describe the same capture frame for
//! frame (CMU 01_01 and 02_01), each marker's offset in its joint's frame is the least-squares
//! solution of `x_f = P_j(f) + R_j(f) o` over all frames `f` where the marker was seen: with
//! `R` orthonormal this is simply `o = mean_f R_j(f)^T (x_f - P_j(f))`. A blended marker
//! (`x = (1-w)(P_j + R_j o_j) + w (P_k + R_k o_k)`) is still linear in `(o_j, o_k)`: the six
//! unknowns come from the 6x6 normal equations (solved by SVD, so a weight of 0 or 1 is fine),
//! and the weight is picked from a small grid by the lowest residual. Several takes (several
//! subjects) are fitted jointly: the offsets then describe an average subject, and the
//! per-take residuals show how much a single offset misses each subject.
//!
//! Takes must be in the *motion's* frame (for CMU: motion = ASF Y-up, the C3D lab is Z-up;
//! see [`crate::synthesize::LabFrame`]).

use crate::layout::{Blend, Layout, LayoutError};
use locap_core::{GlobalPose, Motion, Take, Vec3};
use nalgebra::{Matrix3, Matrix6, Vector6};
use serde::{Deserialize, Serialize};

/// Errors of calibration.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CalibrationError {
    /// A take and its motion have different lengths.
    #[error("take {index} has {take_frames} frames but its motion has {motion_frames}")]
    FrameMismatch {
        /// Which pair.
        index: usize,
        /// Frames of the take.
        take_frames: usize,
        /// Frames of the motion.
        motion_frames: usize,
    },
    /// The layout does not fit the skeleton.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// A marker of the layout is in none of the takes (or never visible).
    #[error("marker {0:?} is never visible in the calibration takes")]
    NeverSeen(String),
}

/// Calibration options.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationOptions {
    /// Try every (non end-site) joint for every marker and keep the one with the lowest
    /// residual, instead of the layout's joint.
    pub search_joints: bool,
    /// Blend weights tried for markers that have a blend.
    pub blend_weights: Vec<f64>,
    /// Use at most this many evenly spaced frames per take.
    pub max_frames: usize,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        CalibrationOptions { search_joints: false, blend_weights: vec![0.0, 0.25, 0.5, 0.75], max_frames: 4000 }
    }
}

/// How well one marker was fitted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MarkerFit {
    /// Marker name.
    pub name: String,
    /// Joint chosen.
    pub joint: String,
    /// Blend joint and weight, if blended.
    pub blend: Option<(String, f64)>,
    /// RMS distance between the real marker and the fitted one, per take, mm (`None` where
    /// the take does not have the marker).
    pub rms_mm_per_take: Vec<Option<f64>>,
    /// RMS over all takes, mm.
    pub rms_mm: f64,
    /// Frames used.
    pub frames: usize,
}

/// The result of [`calibrate`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationReport {
    /// One entry per marker, in layout order.
    pub markers: Vec<MarkerFit>,
}

impl CalibrationReport {
    /// RMS residual over all markers and takes, mm.
    pub fn rms_mm(&self) -> f64 {
        let (mut sum, mut n) = (0.0, 0usize);
        for m in &self.markers {
            sum += m.rms_mm * m.rms_mm * m.frames as f64;
            n += m.frames;
        }
        if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
    }
}

/// Poses and marker samples of one take, thinned to at most `max_frames` frames.
struct Prepared<'a> {
    take: &'a Take,
    motion: &'a Motion,
    frames: Vec<usize>,
    poses: Vec<GlobalPose>,
}

/// One least-squares problem: normal equations of `x = (1-w)(P_j + R_j a) + w(P_k + R_k b)`.
fn solve(preps: &[Prepared], marker: &[Option<usize>], joints: &[(usize, usize)], w: f64) -> Option<(Vec3, Vec3)> {
    let mut ata = Matrix6::<f64>::zeros();
    let mut atb = Vector6::<f64>::zeros();
    let mut n = 0;
    for ((p, m), (j, k)) in preps.iter().zip(marker).zip(joints) {
        let Some(m) = *m else { continue };
        for (pose, &f) in p.poses.iter().zip(&p.frames) {
            let Some(x) = p.take.position_mm(f, m) else { continue };
            let rj: Matrix3<f64> = pose.rotations[*j].to_rotation_matrix().into_inner() * (1.0 - w);
            let rk: Matrix3<f64> = pose.rotations[*k].to_rotation_matrix().into_inner() * w;
            let b = x - pose.positions_mm[*j] * (1.0 - w) - pose.positions_mm[*k] * w;
            let mut a = nalgebra::Matrix3x6::<f64>::zeros();
            a.fixed_view_mut::<3, 3>(0, 0).copy_from(&rj);
            a.fixed_view_mut::<3, 3>(0, 3).copy_from(&rk);
            ata += a.transpose() * a;
            atb += a.transpose() * b;
            n += 1;
        }
    }
    if n == 0 {
        return None;
    }
    let u = ata.svd(true, true).solve(&atb, 1e-9).ok()?;
    Some((Vec3::new(u[0], u[1], u[2]), Vec3::new(u[3], u[4], u[5])))
}

/// Per-take RMS residual of a fitted marker, and the frames used.
fn residuals(
    preps: &[Prepared],
    marker: &[Option<usize>],
    joints: &[(usize, usize)],
    w: f64,
    (a, b): (Vec3, Vec3),
) -> (Vec<Option<f64>>, f64, usize) {
    let mut per_take = Vec::new();
    let (mut total, mut count) = (0.0, 0usize);
    for ((p, m), (j, k)) in preps.iter().zip(marker).zip(joints) {
        let Some(m) = *m else {
            per_take.push(None);
            continue;
        };
        let (mut sum, mut n) = (0.0, 0usize);
        for (pose, &f) in p.poses.iter().zip(&p.frames) {
            let Some(x) = p.take.position_mm(f, m) else { continue };
            let on_j = pose.positions_mm[*j] + pose.rotations[*j] * a;
            let on_k = pose.positions_mm[*k] + pose.rotations[*k] * b;
            sum += (on_j * (1.0 - w) + on_k * w - x).norm_squared();
            n += 1;
        }
        per_take.push((n > 0).then(|| (sum / n as f64).sqrt()));
        total += sum;
        count += n;
    }
    (per_take, if count == 0 { f64::INFINITY } else { (total / count as f64).sqrt() }, count)
}

/// Fits the offsets of `layout` to `pairs` of (real take in the motion's frame, motion) and
/// returns the calibrated layout with a residual report. Markers are matched by label
/// (subject prefixes ignored); a take without some marker simply does not contribute to it.
pub fn calibrate(
    layout: &Layout,
    pairs: &[(&Take, &Motion)],
    options: &CalibrationOptions,
) -> Result<(Layout, CalibrationReport), CalibrationError> {
    layout.check()?;
    let mut preps = Vec::new();
    for (index, (take, motion)) in pairs.iter().enumerate() {
        if take.frame_count() != motion.frame_count() {
            return Err(CalibrationError::FrameMismatch {
                index,
                take_frames: take.frame_count(),
                motion_frames: motion.frame_count(),
            });
        }
        let stride = take.frame_count().div_ceil(options.max_frames.max(1)).max(1);
        let frames: Vec<usize> = (0..take.frame_count()).step_by(stride).collect();
        let poses = frames.iter().map(|&f| motion.forward_kinematics(f)).collect();
        preps.push(Prepared { take, motion, frames, poses });
    }
    let mut out = layout.clone();
    let mut fits = Vec::new();
    for lm in out.markers.iter_mut() {
        let marker: Vec<Option<usize>> = preps.iter().map(|p| p.take.marker_index(&lm.name)).collect();
        // Candidate (joint name, blend joint name, weight) triples.
        let mut candidates: Vec<(String, Option<String>, f64)> = Vec::new();
        match &lm.blend {
            Some(b) => {
                for &w in &options.blend_weights {
                    candidates.push((lm.joint.clone(), Some(b.joint.clone()), w));
                }
            }
            None if options.search_joints => {
                if let Some(p) = preps.first() {
                    for j in p.motion.skeleton.joints().iter().filter(|j| !j.is_end_site) {
                        candidates.push((j.name.clone(), None, 0.0));
                    }
                }
            }
            None => candidates.push((lm.joint.clone(), None, 0.0)),
        }
        let mut best: Option<(f64, MarkerFit, (Vec3, Vec3), f64)> = None;
        for (joint, blend_joint, w) in candidates {
            let mut joints = Vec::new();
            for p in &preps {
                let sk = &p.motion.skeleton;
                let unknown = |name: &str| LayoutError::UnknownJoint { marker: lm.name.clone(), joint: name.into() };
                let j = layout.resolve_joint(sk, &joint).ok_or_else(|| unknown(&joint))?;
                let k = match &blend_joint {
                    Some(name) => layout.resolve_joint(sk, name).ok_or_else(|| unknown(name))?,
                    None => j,
                };
                joints.push((j, k));
            }
            let Some(offsets) = solve(&preps, &marker, &joints, w) else { continue };
            let (per_take, rms, frames) = residuals(&preps, &marker, &joints, w, offsets);
            if best.as_ref().is_none_or(|b| rms < b.0) {
                let fit = MarkerFit {
                    name: lm.name.clone(),
                    joint: joint.clone(),
                    blend: blend_joint.clone().map(|b| (b, w)),
                    rms_mm_per_take: per_take,
                    rms_mm: rms,
                    frames,
                };
                best = Some((rms, fit, offsets, w));
            }
        }
        let (_, fit, (a, b), w) = best.ok_or_else(|| CalibrationError::NeverSeen(lm.name.clone()))?;
        let round = |v: Vec3| [v.x, v.y, v.z].map(|c| (c * 10.0).round() / 10.0);
        lm.joint = fit.joint.clone();
        lm.offset_mm = round(a);
        if let Some(blend) = &mut lm.blend {
            *blend = Blend { joint: blend.joint.clone(), weight: w, offset_mm: Some(round(b)) };
        }
        fits.push(fit);
    }
    Ok((out, CalibrationReport { markers: fits }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::{joint, layout, marker};
    use locap_core::{EulerOrder, MarkerName, Skeleton};

    fn chain() -> Skeleton {
        Skeleton::new(vec![
            joint("root", None, [0.0; 3]),
            joint("a", Some(0), [0.0, 100.0, 0.0]),
            joint("b", Some(1), [0.0, 300.0, 0.0]),
        ])
        .unwrap()
    }

    /// Markers generated from known offsets are recovered exactly, and the joint search finds
    /// the joint they were put on.
    #[test]
    fn recovers_known_offsets_and_joints() {
        let sk = chain();
        let frames = 50;
        let mut rotations = Vec::new();
        let mut root = Vec::new();
        for f in 0..frames {
            let t = f as f64 * 0.1;
            rotations.push(EulerOrder::XYZ.to_quat_deg([10.0 * t, 20.0 * t.sin(), 5.0]));
            rotations.push(EulerOrder::XYZ.to_quat_deg([30.0 * t.cos(), 0.0, 40.0 * t]));
            rotations.push(EulerOrder::XYZ.to_quat_deg([0.0, 50.0 * t.sin(), 0.0]));
            root.push(Vec3::new(t * 10.0, 900.0, 0.0));
        }
        let motion = Motion::new(sk, rotations, root, 120.0).unwrap();
        let truth = [(1, Vec3::new(40.0, 150.0, 20.0)), (2, Vec3::new(-30.0, 100.0, 25.0))];
        let mut samples = Vec::new();
        for f in 0..frames {
            let pose = motion.forward_kinematics(f);
            for (j, o) in truth {
                samples.push(Some(pose.positions_mm[j] + pose.rotations[j] * o));
            }
        }
        let take = Take::from_samples(vec![MarkerName::parse("M1"), MarkerName::parse("M2")], &samples, 120.0).unwrap();
        let layout = layout(vec![marker("M1", "root", [0.0; 3]), marker("M2", "b", [0.0; 3])]);
        let options = CalibrationOptions { search_joints: true, ..Default::default() };
        let (fitted, report) = calibrate(&layout, &[(&take, &motion)], &options).unwrap();
        assert_eq!(fitted.markers[0].joint, "a");
        assert_eq!(fitted.markers[1].joint, "b");
        for (m, (_, o)) in fitted.markers.iter().zip(truth) {
            assert!((Vec3::from(m.offset_mm) - o).norm() < 0.1, "{:?} vs {o}", m.offset_mm);
        }
        assert!(report.rms_mm() < 0.1);
        // A mismatched motion is refused, not mis-fitted.
        let short = take.slice_frames(0..10);
        assert!(matches!(
            calibrate(&layout, &[(&short, &motion)], &options),
            Err(CalibrationError::FrameMismatch { .. })
        ));
    }
}
