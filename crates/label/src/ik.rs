//! Pose reconstruction for missing-marker estimation (labeling paper section 4, Eq. 6-13).
//!
//! When the subject's skeleton and the markers' offsets on it are known, every frame the
//! pose `theta` is fitted by minimising
//! `l1 E_O + l2 E_P + l3 E_S + l4 E_C` (Eq. 6): the observed term (labeled markers against
//! the model's, Eq. 7), the predicted term (the model's missing markers against their Kalman
//! prediction, Mahalanobis, Eq. 10), the smoothness term (second difference of the pose over
//! three frames, Eq. 11, with a decaying velocity) and the constraint term (joint rotations beyond a limit, Eq. 12),
//! with BFGS (the `argmin` crate; gradients by central differences). A missing marker is then
//! placed from its visible rigid neighbours and the pose's relative offsets (Eq. 13), or on
//! the pose itself when its whole limb is gone.
//!
//! Choices where the paper is silent or bound to its own units: the pose is the root
//! translation (in decimetres, so it weighs like radians in the smoothness term) and one
//! rotation vector per joint; terms are dimensionless (distances in units of 10 mm, the
//! prediction by its own variance); the paper's weights 0.05 / 0.15 / 0.8 / 0.1 are kept. The
//! skeleton carries no per-joint limits, so the constraint term bounds every joint's rotation
//! angle by `limit_deg` (biomechanical limits need a per-joint table: not built).

use crate::LabelError;
use argmin::core::{CostFunction, Error, Executor, Gradient, State};
use argmin::solver::linesearch::MoreThuenteLineSearch;
use argmin::solver::quasinewton::BFGS;
use locap_core::skeleton::forward_kinematics;
use locap_core::{Quat, Skeleton, Vec3};

/// Where a marker sits on the skeleton.
#[derive(Debug, Clone, PartialEq)]
pub struct Attachment {
    /// Joint the marker rides on.
    pub joint: usize,
    /// Offset in that joint's frame (mm).
    pub offset_mm: Vec3,
    /// A second joint the marker partly follows: (joint, weight in `[0, 1]`, offset in its
    /// frame, mm), for markers near a joint that slide with the skin.
    pub blend: Option<(usize, f64, Vec3)>,
}

/// A skeleton with the template's markers attached (`None`: a marker the model lacks).
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerModel {
    skeleton: Skeleton,
    attachments: Vec<Option<Attachment>>,
    /// Skeleton world frame -> the take's lab frame (e.g. a Y-up skeleton in a Z-up lab).
    lab: Quat,
    /// Joints with rotation parameters (all but end sites).
    moving: Vec<usize>,
}

impl MarkerModel {
    /// A model for a template whose markers are attached as given (one entry per template
    /// marker).
    pub fn new(skeleton: Skeleton, attachments: Vec<Option<Attachment>>) -> Result<MarkerModel, LabelError> {
        for a in attachments.iter().flatten() {
            let bad = a.joint >= skeleton.len()
                || a.blend.as_ref().is_some_and(|(j, w, _)| *j >= skeleton.len() || !(0.0..=1.0).contains(w));
            if bad {
                return Err(LabelError::Config(format!(
                    "a marker attachment refers to a joint the skeleton lacks: {a:?}"
                )));
            }
        }
        let moving = (0..skeleton.len()).filter(|&j| !skeleton.joints()[j].is_end_site).collect();
        Ok(MarkerModel { skeleton, attachments, moving, lab: Quat::identity() })
    }

    /// The same model in a lab whose axes are the skeleton's turned by `lab` (for a Y-up
    /// skeleton in a Z-up lab as CMU's: lab `(X, Y, Z)` = skeleton `(z, x, y)`, see
    /// [`MarkerModel::y_up_in_z_up_lab`]).
    pub fn in_lab(mut self, lab: Quat) -> MarkerModel {
        self.lab = lab;
        self
    }

    /// The rotation taking a Y-up skeleton's `(x, y, z)` to a Z-up lab's `(z, x, y)`.
    pub fn y_up_in_z_up_lab() -> Quat {
        locap_core::units::y_up_to_z_up_rotation()
    }

    /// Number of markers (attached or not).
    pub fn marker_count(&self) -> usize {
        self.attachments.len()
    }

    /// Number of pose parameters: root translation and one rotation vector per moving joint.
    pub fn parameter_count(&self) -> usize {
        3 + 3 * self.moving.len()
    }

    /// The model's marker positions (mm) in pose `theta`.
    pub fn markers_mm(&self, theta: &[f64]) -> Vec<Option<Vec3>> {
        let mut local = vec![Quat::identity(); self.skeleton.len()];
        for (k, &j) in self.moving.iter().enumerate() {
            let v = Vec3::new(theta[3 + 3 * k], theta[4 + 3 * k], theta[5 + 3 * k]);
            local[j] = Quat::from_scaled_axis(v);
        }
        let root = Vec3::new(theta[0], theta[1], theta[2]) * DECIMETRE_MM;
        let pose = forward_kinematics(&self.skeleton, &local, root);
        let on = |j: usize, o: &Vec3| self.lab * (pose.positions_mm[j] + pose.rotations[j] * o);
        self.attachments
            .iter()
            .map(|a| {
                let a = a.as_ref()?;
                let p = on(a.joint, &a.offset_mm);
                Some(match &a.blend {
                    Some((j, w, o)) => p * (1.0 - w) + on(*j, o) * *w,
                    None => p,
                })
            })
            .collect()
    }
}

const DECIMETRE_MM: f64 = 100.0;
/// Smallest standard deviation granted to a Kalman prediction in the predicted term (mm).
/// While a marker is hidden its track is fed with the pose's own estimates, so a tight
/// variance would let the track's stale velocity steer the hidden limb.
const PREDICTION_FLOOR_MM: f64 = 50.0;
/// Distances in the observed term are measured in this unit (mm).
const DISTANCE_UNIT_MM: f64 = 10.0;

/// Weights and limits of the pose fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkConfig {
    /// `l1`, observed term (paper: 0.05).
    pub observed: f64,
    /// `l2`, predicted term (paper: 0.15).
    pub predicted: f64,
    /// `l3`, smoothness term (paper: 0.8).
    pub smooth: f64,
    /// `l4`, joint-limit term (paper: 0.1).
    pub limits: f64,
    /// Largest rotation of a joint from its rest orientation before the limit term acts (deg).
    pub limit_deg: f64,
    /// BFGS iterations per frame (paper: 3-5 suffice, warm-started from the last pose).
    pub iterations: u64,
    /// BFGS iterations for the first frame (from the rest pose).
    pub first_iterations: u64,
    /// Time constant (s) with which the smoothness term lets the pose velocity decay. The
    /// paper's Eq. 11 (second difference, `infinity` here) keeps a hidden limb turning at the
    /// speed it had when it vanished, for as long as it stays hidden; decaying, it comes to
    /// rest like the Kalman tracks of unseen markers.
    pub velocity_time_constant_s: f64,
}

impl Default for IkConfig {
    fn default() -> IkConfig {
        IkConfig {
            observed: 0.05,
            predicted: 0.15,
            smooth: 0.8,
            limits: 0.1,
            limit_deg: 160.0,
            iterations: 5,
            first_iterations: 200,
            velocity_time_constant_s: 0.3,
        }
    }
}

/// One frame's fitting problem.
struct PoseProblem<'a> {
    model: &'a MarkerModel,
    config: &'a IkConfig,
    observed: &'a [Option<Vec3>],
    /// Predicted position and its variance (mm^2) of the markers not observed.
    predicted: &'a [Option<(Vec3, f64)>],
    /// The two previous poses (t-1, t-2), when known.
    history: Option<(&'a [f64], &'a [f64])>,
    /// Per-frame decay of the pose velocity the smoothness term expects.
    damping: f64,
}

impl PoseProblem<'_> {
    fn energy(&self, theta: &[f64]) -> f64 {
        let markers = self.model.markers_mm(theta);
        let (mut observed, mut predicted) = (0.0, 0.0);
        for (i, m) in markers.iter().enumerate() {
            let Some(m) = m else { continue };
            if let Some(o) = self.observed[i] {
                observed += (m - o).norm_squared() / (DISTANCE_UNIT_MM * DISTANCE_UNIT_MM);
            } else if let Some((v, variance)) = self.predicted[i] {
                predicted += (m - v).norm_squared() / variance.max(PREDICTION_FLOOR_MM * PREDICTION_FLOOR_MM);
            }
        }
        let smooth = match self.history {
            Some((a, b)) => {
                theta.iter().zip(a).zip(b).map(|((t, a), b)| (t - a - self.damping * (a - b)).powi(2)).sum()
            }
            None => 0.0,
        };
        let limit = self.config.limit_deg.to_radians();
        let limits: f64 = theta[3..]
            .chunks(3)
            .map(|v| ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - limit).max(0.0).powi(2))
            .sum();
        self.config.observed * observed
            + self.config.predicted * predicted
            + self.config.smooth * smooth
            + self.config.limits * limits
    }
}

impl CostFunction for PoseProblem<'_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, theta: &Vec<f64>) -> Result<f64, Error> {
        Ok(self.energy(theta))
    }
}

impl Gradient for PoseProblem<'_> {
    type Param = Vec<f64>;
    type Gradient = Vec<f64>;
    fn gradient(&self, theta: &Vec<f64>) -> Result<Vec<f64>, Error> {
        // Central differences: the energy is cheap (one forward kinematics) and smooth.
        const H: f64 = 1e-5;
        let mut x = theta.clone();
        Ok((0..theta.len())
            .map(|k| {
                x[k] = theta[k] + H;
                let up = self.energy(&x);
                x[k] = theta[k] - H;
                let down = self.energy(&x);
                x[k] = theta[k];
                (up - down) / (2.0 * H)
            })
            .collect())
    }
}

/// Fits poses frame after frame, warm-started from the previous one.
#[derive(Debug, Clone)]
pub struct PoseTracker {
    model: MarkerModel,
    config: IkConfig,
    /// Poses of the last two frames, newest first.
    history: Vec<Vec<f64>>,
    damping: f64,
}

impl PoseTracker {
    /// A tracker for `model` on a take recorded at `frame_rate_hz`.
    pub fn new(model: MarkerModel, config: IkConfig, frame_rate_hz: f64) -> PoseTracker {
        let damping = (-1.0 / (frame_rate_hz * config.velocity_time_constant_s)).exp();
        PoseTracker { model, config, history: Vec::new(), damping }
    }

    /// The marker model.
    pub fn model(&self) -> &MarkerModel {
        &self.model
    }

    /// Fits this frame's pose to the `observed` markers (mm) and the Kalman `predicted`
    /// positions with variances of the others; returns the model's marker positions.
    pub fn fit(&mut self, observed: &[Option<Vec3>], predicted: &[Option<(Vec3, f64)>]) -> Vec<Option<Vec3>> {
        let n = self.model.parameter_count();
        let first = self.history.is_empty();
        let start = match self.history.len() {
            0 => self.rest_pose_on(observed),
            1 => self.history[0].clone(),
            // The pose moving on at its (decaying) velocity.
            _ => self.history[0].iter().zip(&self.history[1]).map(|(a, b)| a + self.damping * (a - b)).collect(),
        };
        let history = (self.history.len() >= 2).then(|| (self.history[0].as_slice(), self.history[1].as_slice()));
        let problem = PoseProblem {
            model: &self.model,
            config: &self.config,
            observed,
            predicted,
            history,
            damping: self.damping,
        };
        let iterations = if first { self.config.first_iterations } else { self.config.iterations };
        let identity: Vec<Vec<f64>> =
            (0..n).map(|i| (0..n).map(|j| if i == j { 1e-3 } else { 0.0 }).collect()).collect();
        let solver = BFGS::new(MoreThuenteLineSearch::new());
        let theta = Executor::new(problem, solver)
            .configure(|state| state.param(start.clone()).inv_hessian(identity).max_iters(iterations))
            .run()
            .ok()
            .and_then(|result| result.state().get_best_param().cloned())
            .unwrap_or(start);
        let markers = self.model.markers_mm(&theta);
        self.history.insert(0, theta);
        self.history.truncate(2);
        markers
    }

    /// The rest pose turned and moved onto the observed markers (rigid fit of the rest pose's
    /// markers, Kabsch): the first frame's fit then only has to bend the limbs, whichever way
    /// the subject faces.
    fn rest_pose_on(&self, observed: &[Option<Vec3>]) -> Vec<f64> {
        let mut theta = vec![0.0; self.model.parameter_count()];
        let rest = self.model.markers_mm(&theta);
        let (from, to): (Vec<Vec3>, Vec<Vec3>) =
            rest.iter().zip(observed).filter_map(|(r, o)| Some(((*r)?, (*o)?))).unzip();
        let lab = self.model.lab;
        let root_position = match locap_clean::procrustes::align(&from, &to) {
            Some(fit) => {
                // lab * (root + R_root p) = R_fit (lab p) + t  =>  R_root = lab^-1 R_fit lab.
                let r_fit = Quat::from_rotation_matrix(&fit.rotation);
                let r_root = lab.inverse() * r_fit * lab;
                // The root comes first among the moving joints (parents precede children).
                let v = r_root.scaled_axis();
                theta[3..6].copy_from_slice(&[v.x, v.y, v.z]);
                lab.inverse() * fit.translation
            }
            None if !to.is_empty() => {
                lab.inverse() * (to.iter().sum::<Vec3>() - from.iter().sum::<Vec3>()) / to.len() as f64
            }
            None => Vec3::zeros(),
        };
        for k in 0..3 {
            theta[k] = root_position[k] / DECIMETRE_MM;
        }
        theta
    }

    /// Forgets the motion so far (a new take).
    pub fn reset(&mut self) {
        self.history.clear();
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use locap_core::{EulerOrder, Joint};

    /// Root, upper arm (300 mm), forearm (250 mm), hand end site.
    pub(crate) fn arm() -> Skeleton {
        let joint = |name: &str, parent: Option<usize>, offset: [f64; 3], end: bool| Joint {
            name: name.into(),
            parent,
            offset_mm: Vec3::from(offset),
            rotation_order: EulerOrder::XYZ,
            is_end_site: end,
        };
        Skeleton::new(vec![
            joint("root", None, [0.0; 3], false),
            joint("upper", Some(0), [0.0, 0.0, 0.0], false),
            joint("fore", Some(1), [300.0, 0.0, 0.0], false),
            joint("hand", Some(2), [250.0, 0.0, 0.0], true),
        ])
        .unwrap()
    }

    pub(crate) fn arm_model() -> MarkerModel {
        let at = |joint: usize, o: [f64; 3]| Some(Attachment { joint, offset_mm: Vec3::from(o), blend: None });
        MarkerModel::new(
            arm(),
            vec![
                at(0, [0.0, 50.0, 0.0]),
                at(0, [0.0, -50.0, 30.0]),
                at(0, [-40.0, 0.0, 60.0]),
                at(1, [150.0, 40.0, 0.0]),
                at(1, [100.0, -40.0, 20.0]),
                at(1, [280.0, 0.0, 40.0]),
                at(2, [120.0, 30.0, 0.0]),
                at(2, [200.0, -30.0, 10.0]),
                at(2, [240.0, 0.0, -30.0]),
            ],
        )
        .unwrap()
    }

    /// A pose: root at `x`, shoulder and elbow bent.
    pub(crate) fn arm_pose(model: &MarkerModel, t: f64) -> Vec<f64> {
        let mut theta = vec![0.0; model.parameter_count()];
        theta[0] = 10.0 + t;
        theta[2] = 10.0;
        theta[3 + 5] = 0.3 + 0.5 * t; // joint 1 (upper), z rotation
        theta[3 + 8] = 0.8 * t; // joint 2 (forearm), z rotation
        theta
    }

    #[test]
    fn fits_observed_markers_and_places_the_hidden_ones() {
        let model = arm_model();
        let mut tracker = PoseTracker::new(model.clone(), IkConfig::default(), 40.0);
        for f in 0..40 {
            let t = f as f64 / 40.0;
            let truth = model.markers_mm(&arm_pose(&model, t));
            // The whole forearm (markers 6-8) is hidden after frame 10.
            let observed: Vec<Option<Vec3>> =
                truth.iter().enumerate().map(|(i, p)| if f > 10 && i >= 6 { None } else { *p }).collect();
            let predicted = vec![None; truth.len()];
            let fitted = tracker.fit(&observed, &predicted);
            if f > 10 {
                for i in 0..6 {
                    let e = (fitted[i].unwrap() - truth[i].unwrap()).norm();
                    assert!(e < 5.0, "frame {f} observed marker {i} off by {e} mm");
                }
            }
        }
    }

    #[test]
    fn the_first_frame_finds_a_turned_subject_in_a_z_up_lab() {
        let model = arm_model().in_lab(MarkerModel::y_up_in_z_up_lab());
        let mut theta = arm_pose(&model, 0.3);
        theta[3..6].copy_from_slice(&[0.0, 2.5, 0.0]); // root turned 143 degrees about y (up)
        let truth = model.markers_mm(&theta);
        let mut tracker = PoseTracker::new(model.clone(), IkConfig::default(), 60.0);
        let fitted = tracker.fit(&truth, &vec![None; truth.len()]);
        for (f, t) in fitted.iter().zip(&truth) {
            let e = (f.unwrap() - t.unwrap()).norm();
            assert!(e < 5.0, "off by {e} mm");
        }
    }

    #[test]
    fn bad_attachments_are_errors() {
        let bad = vec![Some(Attachment { joint: 9, offset_mm: Vec3::zeros(), blend: None })];
        assert!(MarkerModel::new(arm(), bad).is_err());
    }
}
