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
//! skeleton carries no per-joint limits, so by default the constraint term bounds every joint's
//! rotation angle by `limit_deg`; a model given per-joint degrees of freedom
//! ([`MarkerModel::with_dofs`], e.g. an OpenSim model's coordinates and ranges) bounds the
//! rotation vector's component along each axis by its range and pulls the components along no
//! axis to zero.
//!
//! # The same energy as a kinematic solver
//! Every term is a sum of squares, so besides BFGS (the labeler's, as the paper) the pose can be
//! fitted by Levenberg-Marquardt with an analytic Jacobian ([`Optimizer::LevenbergMarquardt`]):
//! a marker's derivative with respect to the rotation vector `v` of a joint `a` above it is
//! `-[p - P_a]x G_a J_r(v)` (`J_r`, the right Jacobian of the exponential map), its derivative
//! with respect to the root translation the identity. A step is kept only when it lowers the
//! energy itself (with the robust Huber loss of [`IkConfig::huber_mm`] when set, linearised by
//! reweighting). [`solve_sequence`] uses it for a whole take: a subject calibration (bone
//! lengths and marker offsets by linear least squares on poses from a subset of frames, as a
//! studio's range-of-motion calibration does: with the rotations fixed, every marker is linear in
//! the bone lengths, the offsets and the root; the priors hold lengths and offsets to the
//! template's at the subject's overall scale), then frame after frame, warm-started, with the
//! smoothness and limit terms. A calibration sample counts as a stray only when it lies far
//! from where the marker's median displacement in its body puts it: a marker the subject wears
//! a few centimetres from the template's place is off by the same amount in every frame, and is
//! recalibrated rather than left out; markers a model names as landmarks (on bone, where every
//! lab puts them: [`MarkerModel::with_landmarks`]) are held harder, since a segment's markers
//! cannot tell a constant turn of the segment from the same turn of all their offsets. A model
//! may name joints that lie at the mean of markers worn around them ([`JointCentre`], a wrist
//! between its two wrist markers): the calibration then fits the bone lengths the markers on
//! the bone leave free to bring the joint within a radius of there, and every frame's fit holds
//! it within that radius.
//! The take is also tracked backwards from its last frame, and the frames before one switch
//! frame come from that pass where it fits the markers clearly better: a limb the first frame
//! leaves in a wrong minimum is otherwise tracked there until a motion snaps it out.

use crate::LabelError;
use argmin::core::{CostFunction, Error, Executor, Gradient, State};
use argmin::solver::linesearch::MoreThuenteLineSearch;
use argmin::solver::quasinewton::BFGS;
use locap_core::skeleton::forward_kinematics;
use locap_core::{Joint, Quat, Skeleton, Vec3};
use nalgebra::{DMatrix, DVector, Matrix3, Rotation3};

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
    /// Per joint: its rotational freedom (all [`JointDofs::Free`] unless given).
    dofs: Vec<JointDofs>,
    /// The root's rotation is `root_base * exp(v_root)`: a tracker re-bases it so the rotation
    /// vector stays far from a full turn, where the exponential map folds.
    root_base: Quat,
    /// Joints that lie at the mean of some markers ([`MarkerModel::with_joint_centres`]).
    centres: Vec<JointCentre>,
    /// Joints whose rotation follows another's ([`MarkerModel::with_couplings`]).
    couplings: Vec<JointCoupling>,
    /// Per joint: how hard a prior pose holds it, times [`IkConfig::prior`]
    /// ([`MarkerModel::with_prior_weights`]; 1 unless given).
    prior_weights: Vec<f64>,
    /// Per marker: worn on a bony landmark whose place the template knows, its offset held
    /// harder in the subject calibration ([`MarkerModel::with_landmarks`]; none unless given).
    landmarks: Vec<bool>,
}

/// A joint that turns as another does, scaled: a finger's distal interphalangeal joint flexes
/// about two thirds as far as its proximal one (one tendon moves both), which no marker set
/// with one marker per finger segment pair can tell apart. A soft pull
/// ([`IkConfig::coupling`]) on the joint's rotation vector towards `ratio` times the leader's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointCoupling {
    /// The following joint.
    pub joint: usize,
    /// The joint it follows.
    pub leader: usize,
    /// Its rotation vector over the leader's.
    pub ratio: f64,
}

/// A joint whose centre lies at the mean of markers worn around it (a wrist between its radial
/// and ulnar markers, as gait models define the wrist centre): the subject calibration fits
/// bone lengths so that it lies within [`IkConfig::centre_radius_mm`] of there
/// ([`SequenceConfig::joint_centre_weight`]), and every frame holds it there
/// ([`IkConfig::centre`]).
#[derive(Debug, Clone, PartialEq)]
pub struct JointCentre {
    /// The joint.
    pub joint: usize,
    /// The markers (model order) around it.
    pub markers: Vec<usize>,
}

/// The rotational freedom of one joint.
#[derive(Debug, Clone, PartialEq)]
pub enum JointDofs {
    /// Any rotation, bounded in angle by [`IkConfig::limit_deg`].
    Free,
    /// Rotation about these axes only, each within its range; an empty list: no rotation.
    Axes(Vec<DofAxis>),
}

impl JointDofs {
    /// The rotation of `angles_rad` about the axes, one angle per axis, applied in the listed
    /// order (the first axis first to a vector: `exp(a_n t_n) ... exp(a_1 t_1)`), as an ASF's
    /// `dof rx rz` values turn a bone; `None` for [`JointDofs::Free`] or another angle count.
    /// Ranges are not applied. The pose fit parametrises a joint by one rotation vector
    /// instead, held to these rotations ([`Locked`]): within the axes' span for one axis and
    /// for three (there the ranges bound the vector's components, not these angles); for two,
    /// on the products themselves, whose rotation vectors leave the plane of the two axes by a
    /// turn about the third direction that grows with the angles (22 degrees at a CMU hand
    /// bent 60 degrees and turned 45).
    pub fn rotation(&self, angles_rad: &[f64]) -> Option<Quat> {
        let JointDofs::Axes(axes) = self else { return None };
        if axes.len() != angles_rad.len() {
            return None;
        }
        let turn = |q: Quat, (a, t): (&DofAxis, &f64)| Quat::from_scaled_axis(a.axis.normalize() * *t) * q;
        Some(axes.iter().zip(angles_rad).fold(Quat::identity(), turn))
    }
}

/// One rotation axis of a joint (joint frame, unit length) and its range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DofAxis {
    /// The axis.
    pub axis: Vec3,
    /// Smallest rotation about it (rad).
    pub min_rad: f64,
    /// Largest rotation about it (rad).
    pub max_rad: f64,
}

/// What a joint's axes forbid of its rotation `exp(v)`: each a residual, zero where the
/// rotation is one the axes make ([`JointDofs::rotation`]), about the angle it is off by.
#[derive(Debug, Clone, PartialEq)]
enum Locked {
    /// Directions of the rotation vector that no axis allows (none for a free joint or three
    /// axes, two for one axis, the whole space for none): the residuals are `v`'s components
    /// along them.
    Directions(Vec<Vec3>),
    /// Two axes, `first` turning a vector first: `R = exp(second t2) exp(first t1)`. Such an
    /// `R` keeps `first`'s angle to `second` (`second . R first = second . first`), and a
    /// rotation that keeps it is one of them: `R first` lies on the cone about `second` that
    /// `first` sweeps, which a turn about `second` reaches, and what remains turns about
    /// `first`. So one residual, `second . R first - second . first` (zero on the products,
    /// about the angle off them near them), holds the fit on them exactly; the rotation
    /// vectors of the products do not lie in the axes' plane.
    Product { first: Vec3, second: Vec3 },
}

impl Locked {
    fn of(dofs: &JointDofs) -> Locked {
        match dofs {
            JointDofs::Free => Locked::Directions(Vec::new()),
            JointDofs::Axes(axes) => match axes.as_slice() {
                [a, b] if a.axis.normalize().cross(&b.axis.normalize()).norm() > 1e-6 => {
                    Locked::Product { first: a.axis.normalize(), second: b.axis.normalize() }
                }
                _ => Locked::Directions(locked_directions(axes)),
            },
        }
    }

    /// The residuals at rotation vector `v` and, per residual, its gradient in `v` (no
    /// allocation: every pose-fit iteration asks each joint).
    fn residuals<'a>(&'a self, v: &'a Vec3) -> impl Iterator<Item = (f64, Vec3)> + 'a {
        let (dirs, product) = match self {
            Locked::Directions(dirs) => (dirs.as_slice(), None),
            Locked::Product { first, second } => {
                let r = Rotation3::from_scaled_axis(*v).into_inner();
                // exp(v + d) = exp(v) exp(J_r d): R first moves by -R [first]x J_r d.
                let gradient = -(second.transpose() * r * skew(first) * right_jacobian(v)).transpose();
                (&[][..], Some((second.dot(&(r * first)) - second.dot(first), gradient)))
            }
        };
        dirs.iter().map(|d| (d.dot(v), *d)).chain(product)
    }
}

/// Directions of a joint's rotation vector that no axis allows: an orthonormal basis of the
/// complement of the axes' span.
fn locked_directions(axes: &[DofAxis]) -> Vec<Vec3> {
    let mut basis: Vec<Vec3> = Vec::new();
    for a in axes.iter().map(|a| a.axis).chain([Vec3::x(), Vec3::y(), Vec3::z()]) {
        let mut v = a;
        for b in &basis {
            v -= b * b.dot(&v);
        }
        if v.norm() > 1e-6 && basis.len() < 3 {
            basis.push(v.normalize());
        }
    }
    // The first `span` vectors span the axes; the rest is locked.
    let span = {
        let mut b: Vec<Vec3> = Vec::new();
        for a in axes {
            let mut v = a.axis;
            for x in &b {
                v -= x * x.dot(&v);
            }
            if v.norm() > 1e-6 {
                b.push(v.normalize());
            }
        }
        b.len()
    };
    basis.split_off(span.min(basis.len()))
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
        let dofs = vec![JointDofs::Free; skeleton.len()];
        let prior_weights = vec![1.0; skeleton.len()];
        let landmarks = vec![false; attachments.len()];
        Ok(MarkerModel {
            prior_weights,
            landmarks,
            skeleton,
            attachments,
            moving,
            lab: Quat::identity(),
            dofs,
            root_base: Quat::identity(),
            centres: Vec::new(),
            couplings: Vec::new(),
        })
    }

    /// Where joint `j`'s rotation vector starts in the pose parameters (`None`: it has none).
    fn block_of(&self, j: usize) -> Option<usize> {
        self.moving.iter().position(|&m| m == j).map(|k| 3 + 3 * k)
    }

    /// The same model with joints whose rotation follows another's (see [`JointCoupling`]).
    ///
    /// # Errors
    /// A joint that does not rotate (an end site, or out of range), a joint following itself,
    /// or a ratio that is not finite.
    pub fn with_couplings(mut self, couplings: Vec<JointCoupling>) -> Result<MarkerModel, LabelError> {
        for c in &couplings {
            let moves = |j: usize| self.moving.contains(&j);
            // The root's rotation vector is relative to a base that moves ([`MarkerModel`]'s
            // `root_base`): it neither leads nor follows.
            if !moves(c.joint)
                || !moves(c.leader)
                || c.joint == c.leader
                || c.joint == 0
                || c.leader == 0
                || !c.ratio.is_finite()
            {
                return Err(LabelError::Config(format!("a joint coupling is not valid: {c:?}")));
            }
        }
        self.couplings = couplings;
        Ok(self)
    }

    /// The same model with joints that lie at the mean of markers around them (see
    /// [`JointCentre`]).
    ///
    /// # Errors
    /// A joint or marker index out of range, or a centre with no markers.
    pub fn with_joint_centres(mut self, centres: Vec<JointCentre>) -> Result<MarkerModel, LabelError> {
        for c in &centres {
            if c.joint >= self.skeleton.len()
                || c.markers.is_empty()
                || c.markers.iter().any(|&m| m >= self.attachments.len() || self.attachments[m].is_none())
            {
                return Err(LabelError::Config(format!("a joint centre refers to what the model lacks: {c:?}")));
            }
        }
        self.centres = centres;
        Ok(self)
    }

    /// The same model with each joint held towards a prior pose ([`IkConfig::prior`]) by its own
    /// weight, times the config's (one entry per skeleton joint; the root's is unused): a
    /// network's answer can be trusted more where the markers split a motion between joints
    /// ambiguously (a spine bending over three joints) than where they see it.
    ///
    /// # Errors
    /// Not one entry per joint, or a weight that is negative or not finite.
    pub fn with_prior_weights(mut self, weights: Vec<f64>) -> Result<MarkerModel, LabelError> {
        if weights.len() != self.skeleton.len() || weights.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
            return Err(LabelError::Config(format!(
                "{} prior weights for a skeleton of {} joints, or one negative or not finite",
                weights.len(),
                self.skeleton.len()
            )));
        }
        self.prior_weights = weights;
        Ok(self)
    }

    /// Per joint: its weight towards a prior pose ([`MarkerModel::with_prior_weights`]).
    pub fn prior_weights(&self) -> &[f64] {
        &self.prior_weights
    }

    /// The same model with the markers `landmarks` marks (one entry per marker) worn on bony
    /// landmarks: the subject calibration holds their offsets towards the template's with
    /// [`SequenceConfig::landmark_offset_prior`] instead of [`SequenceConfig::offset_prior`].
    ///
    /// Why: a segment's markers cannot tell a constant turn or shift of the segment from the
    /// same turn or shift of all their offsets, and with every offset free the calibration
    /// files part of the subject's pose as marker placement. Markers on bone (the pelvis's
    /// spines, the vertebrae, the sternum) sit where a layout says, to within a few
    /// millimetres; holding them fixes the trunk's frame as gait models define it from the
    /// same markers, while markers on soft tissue and wands stay free to sit where this
    /// subject wears them.
    ///
    /// # Errors
    /// Not one entry per marker.
    pub fn with_landmarks(mut self, landmarks: Vec<bool>) -> Result<MarkerModel, LabelError> {
        if landmarks.len() != self.attachments.len() {
            return Err(LabelError::Config(format!(
                "{} landmark flags for a model of {} markers",
                landmarks.len(),
                self.attachments.len()
            )));
        }
        self.landmarks = landmarks;
        Ok(self)
    }

    /// Per marker: worn on a bony landmark ([`MarkerModel::with_landmarks`]).
    pub fn landmarks(&self) -> &[bool] {
        &self.landmarks
    }

    /// The prior's weight on pose parameter `k` (a rotation vector component of a moving joint).
    fn prior_weight_of(&self, k: usize) -> f64 {
        self.prior_weights[self.moving[(k - 3) / 3]]
    }

    /// The same model with each joint's rotational freedom (one entry per skeleton joint; the
    /// root's is ignored: it turns freely).
    ///
    /// # Errors
    /// Not one entry per joint, or an axis that is not a finite non-zero vector or a range
    /// with `min > max`.
    pub fn with_dofs(mut self, dofs: Vec<JointDofs>) -> Result<MarkerModel, LabelError> {
        if dofs.len() != self.skeleton.len() {
            return Err(LabelError::Config(format!(
                "{} joint freedoms for a skeleton of {} joints",
                dofs.len(),
                self.skeleton.len()
            )));
        }
        let mut checked = Vec::with_capacity(dofs.len());
        for d in dofs {
            checked.push(match d {
                JointDofs::Free => JointDofs::Free,
                JointDofs::Axes(axes) => {
                    if axes.len() > 3 {
                        return Err(LabelError::Config(format!(
                            "a joint has {} rotation axes (at most 3)",
                            axes.len()
                        )));
                    }
                    let mut out = Vec::with_capacity(axes.len());
                    for a in axes {
                        let n = a.axis.norm();
                        if !(n.is_finite() && n > 1e-9 && a.min_rad <= a.max_rad) {
                            return Err(LabelError::Config(format!("a joint axis is not valid: {a:?}")));
                        }
                        out.push(DofAxis { axis: a.axis / n, ..a });
                    }
                    JointDofs::Axes(out)
                }
            });
        }
        self.dofs = checked;
        Ok(self)
    }

    /// Per joint: it has rotation parameters and its freedom allows some rotation.
    pub fn rotating(&self) -> Vec<bool> {
        (0..self.skeleton.len())
            .map(|j| {
                self.moving.contains(&j) && !matches!(&self.dofs[j], JointDofs::Axes(axes) if axes.is_empty() && j != 0)
            })
            .collect()
    }

    /// The skeleton.
    pub fn skeleton(&self) -> &Skeleton {
        &self.skeleton
    }

    /// The marker attachments (one per marker).
    pub fn attachments(&self) -> &[Option<Attachment>] {
        &self.attachments
    }

    /// The rotation from the skeleton's frame to the lab's.
    pub fn lab(&self) -> Quat {
        self.lab
    }

    /// Local joint rotations (one per joint) and root position (mm, skeleton frame) of pose
    /// `theta`.
    pub fn pose(&self, theta: &[f64]) -> (Vec<Quat>, Vec3) {
        let mut local = vec![Quat::identity(); self.skeleton.len()];
        for (k, &j) in self.moving.iter().enumerate() {
            let v = Vec3::new(theta[3 + 3 * k], theta[4 + 3 * k], theta[5 + 3 * k]);
            local[j] = Quat::from_scaled_axis(v);
        }
        if self.root_base != Quat::identity() {
            local[0] = self.root_base * local[0];
        }
        (local, Vec3::new(theta[0], theta[1], theta[2]) * DECIMETRE_MM)
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
        let (local, root) = self.pose(theta);
        self.markers_at(&local, root)
    }

    /// The model's markers (lab frame, mm) for local rotations `local` and root `root_mm`.
    pub fn markers_at(&self, local: &[Quat], root_mm: Vec3) -> Vec<Option<Vec3>> {
        let pose = forward_kinematics(&self.skeleton, local, root_mm);
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
/// [`IkConfig::coupling`] of both presets: in the kinematic one, 10 degrees off the coupling
/// weigh as a marker 5 mm off. Soft, since the ratio varies between people and grips.
const COUPLING: f64 = 8.0;
/// Distances in the observed term are measured in this unit (mm).
const DISTANCE_UNIT_MM: f64 = 10.0;

/// How far (mm) a joint centre may lie from its markers' mean before it is pulled in
/// ([`IkConfig::centre_radius_mm`]). The CMU template, like CMU's own solutions, puts its hand
/// joints further than this from the wrist markers' mean; pulled onto the mean, the forearm no
/// longer matches that skeleton, and every joint below the elbow is placed worse. Within this
/// radius the hands still stay within 60 mm of their wrist markers. Chosen on validation takes
/// (docs/benchmarks.md, "A radius for the wrist centres").
pub const CENTRE_RADIUS_MM: f64 = 45.0;

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
    /// Weight of the rotation-vector components along no axis of a joint with
    /// [`JointDofs::Axes`], per rad^2 (the limit term's weight is `limits`).
    pub locked: f64,
    /// Pull of every non-root joint towards its rest orientation, per rad^2: holds joints the
    /// markers do not see (fingers, toes) in place (0: none, the paper's energy).
    pub rest: f64,
    /// Pull of every non-root joint towards the prior pose where one is set
    /// ([`PoseTracker::set_prior`], [`solve_sequence_with_prior`]), per rad^2, times the
    /// joint's own weight ([`MarkerModel::with_prior_weights`]): another solver's answer (a
    /// network's) that the markers refine.
    pub prior: f64,
    /// A joint further than this (degrees, its rotation vector's distance) from the prior pose
    /// is pulled linearly, not squared (Huber): where the markers clearly show the prior
    /// wrong about a joint they see, they win; where they leave it free, it holds. 0: plain
    /// squares.
    pub prior_huber_deg: f64,
    /// Weight of a coupled joint's rotation vector away from its share of its leader's
    /// ([`JointCoupling`]), per rad^2.
    pub coupling: f64,
    /// Observed markers further than this from the model (mm) count linearly, not squared
    /// (Huber): a mislabeled or stray marker cannot drag the pose. 0: plain squares.
    pub huber_mm: f64,
    /// How the energy is minimised.
    pub optimizer: Optimizer,
    /// Re-base the root rotation after every frame (a subject turning round and round).
    pub rebase_root: bool,
    /// The limit term bounds the root's rotation too (the paper's energy; a kinematic solver
    /// lets the subject face any way).
    pub root_limited: bool,
    /// Pull of a model's joint centres ([`JointCentre`]) in every frame where all their markers
    /// are seen, per mm beyond [`IkConfig::centre_radius_mm`] from the markers' mean (a
    /// marker's own is `observed` per mm): the calibration sets the bones, this keeps the joint
    /// there where fast or jittery markers would let the pose drift. 0: none.
    pub centre: f64,
    /// How far (mm) a joint centre may lie from its markers' mean, in the subject calibration
    /// and in every frame, before it is pulled in.
    pub centre_radius_mm: f64,
}

/// The minimiser of the pose energy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Optimizer {
    /// BFGS with central-difference gradients (the paper's choice, the labeler's).
    Bfgs,
    /// Levenberg-Marquardt on the residuals with an analytic Jacobian.
    LevenbergMarquardt,
}

impl IkConfig {
    /// The weights of a kinematic solver, where the markers are the data and the pose is the
    /// answer (not the labeler's estimate of hidden markers): the observed term dominates,
    /// smoothness and rest pull only where the markers leave the pose free, limits are stiff,
    /// outliers are robust (Huber at 20 mm), Levenberg-Marquardt.
    pub fn kinematic() -> IkConfig {
        IkConfig {
            observed: 1.0,
            predicted: 0.0,
            // Joints the markers barely see (a hand with one marker, a foot's roll) are held by
            // smoothness alone: at 10 they turned 20-60 degrees between frames on CMU 135_02.
            smooth: 100.0,
            limits: 1e4,
            limit_deg: 170.0,
            iterations: 12,
            first_iterations: 200,
            velocity_time_constant_s: 0.3,
            locked: 10.0,
            rest: 0.01,
            prior: 0.0,
            prior_huber_deg: 0.0,
            coupling: COUPLING,
            huber_mm: 20.0,
            optimizer: Optimizer::LevenbergMarquardt,
            rebase_root: true,
            root_limited: false,
            // A hard bound: where the joint lies within the radius, it costs nothing.
            centre: 10.0,
            centre_radius_mm: CENTRE_RADIUS_MM,
        }
    }
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
            locked: 10.0,
            rest: 0.0,
            prior: 0.0,
            prior_huber_deg: 0.0,
            coupling: COUPLING,
            huber_mm: 0.0,
            optimizer: Optimizer::Bfgs,
            rebase_root: false,
            root_limited: true,
            centre: 0.0,
            centre_radius_mm: 0.0,
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
    /// Per joint, what its axes do not allow.
    locked: &'a [Locked],
    /// The prior pose's parameters (its root block unused), when set.
    prior: Option<&'a [f64]>,
}

impl PoseProblem<'_> {
    fn energy(&self, theta: &[f64]) -> f64 {
        let markers = self.model.markers_mm(theta);
        let (mut observed, mut predicted) = (0.0, 0.0);
        let huber = self.config.huber_mm / DISTANCE_UNIT_MM;
        for (i, m) in markers.iter().enumerate() {
            let Some(m) = m else { continue };
            if let Some(o) = self.observed[i] {
                let d2 = (m - o).norm_squared() / (DISTANCE_UNIT_MM * DISTANCE_UNIT_MM);
                observed +=
                    if huber > 0.0 && d2 > huber * huber { 2.0 * huber * d2.sqrt() - huber * huber } else { d2 };
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
        let (mut locked, mut rest) = (0.0, 0.0);
        let limits: f64 = theta[3..]
            .chunks(3)
            .zip(&self.model.moving)
            .map(|(v, &j)| match &self.model.dofs[j] {
                JointDofs::Axes(axes) if j != 0 => {
                    let v = Vec3::new(v[0], v[1], v[2]);
                    locked += self.locked[j].residuals(&v).map(|(r, _)| r * r).sum::<f64>();
                    rest += v.norm_squared();
                    axes.iter().map(|a| axis_excess(a, &v).powi(2)).sum::<f64>()
                }
                _ if j == 0 && !self.config.root_limited => 0.0,
                _ => {
                    if j != 0 {
                        rest += v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
                    }
                    ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - limit).max(0.0).powi(2)
                }
            })
            .sum();
        let mut energy = self.config.observed * observed
            + self.config.predicted * predicted
            + self.config.smooth * smooth
            + self.config.limits * limits;
        // Only where set, so the paper's energy is computed exactly as before.
        if locked > 0.0 {
            energy += self.config.limits * self.config.locked * locked;
        }
        if self.config.rest > 0.0 {
            energy += self.config.rest * rest;
        }
        for c in &self.model.couplings {
            if let (Some(a), Some(b)) = (self.model.block_of(c.joint), self.model.block_of(c.leader)) {
                let off: f64 = (0..3).map(|d| (theta[a + d] - c.ratio * theta[b + d]).powi(2)).sum();
                energy += self.config.coupling * off;
            }
        }
        if self.config.centre > 0.0 {
            let (local, root) = self.model.pose(theta);
            let pose = forward_kinematics(&self.model.skeleton, &local, root);
            for c in &self.model.centres {
                if let Some((joint, target)) = self.centre_target(c, &pose) {
                    energy +=
                        self.config.centre * (joint - target).norm_squared() / (DISTANCE_UNIT_MM * DISTANCE_UNIT_MM);
                }
            }
        }
        if let Some(prior) = self.prior {
            // Every block but the root's (the first), each joint's robustly.
            let huber = self.config.prior_huber_deg.to_radians();
            let off: f64 = (6..theta.len())
                .step_by(3)
                .map(|k| {
                    let d2: f64 = (k..k + 3).map(|c| (theta[c] - prior[c]).powi(2)).sum();
                    let rho =
                        if huber > 0.0 && d2 > huber * huber { 2.0 * huber * d2.sqrt() - huber * huber } else { d2 };
                    self.model.prior_weight_of(k) * rho
                })
                .sum();
            energy += self.config.prior * off;
        }
        energy
    }

    /// Where `centre`'s joint lies (lab frame, mm) in `pose` and where it is pulled to: the
    /// nearest point within [`IkConfig::centre_radius_mm`] of its markers' observed mean.
    /// `None` where it lies within that, or a marker is not seen.
    fn centre_target(&self, centre: &JointCentre, pose: &locap_core::skeleton::GlobalPose) -> Option<(Vec3, Vec3)> {
        let seen: Vec<Vec3> = centre.markers.iter().map(|&m| self.observed[m]).collect::<Option<_>>()?;
        let mean = seen.iter().sum::<Vec3>() / seen.len() as f64;
        let joint = self.model.lab * pose.positions_mm[centre.joint];
        let away = joint - mean;
        let radius = self.config.centre_radius_mm;
        (away.norm() > radius).then(|| (joint, mean + away * (radius / away.norm())))
    }

    /// The energy as residuals `r` (`energy = |r|^2` without the Huber loss; with it, the
    /// observed residuals are reweighted at `theta`) and their Jacobian.
    fn linearize(&self, theta: &[f64]) -> (DVector<f64>, DMatrix<f64>) {
        let model = self.model;
        let n = theta.len();
        let (local, root) = model.pose(theta);
        let pose = forward_kinematics(&model.skeleton, &local, root);
        let lab = model.lab.to_rotation_matrix().into_inner();
        // Parameter block of each joint's rotation vector, and the lab-frame derivative of a
        // point's motion by that rotation: `lab * -[p - P_a]x * G_a * J_r(v_a)`.
        let mut block = vec![None; model.skeleton.len()];
        let mut g_jr = vec![Matrix3::zeros(); model.skeleton.len()];
        for (k, &j) in model.moving.iter().enumerate() {
            block[j] = Some(3 + 3 * k);
            let v = Vec3::new(theta[3 + 3 * k], theta[4 + 3 * k], theta[5 + 3 * k]);
            g_jr[j] = pose.rotations[j].to_rotation_matrix().into_inner() * right_jacobian(&v);
        }
        let rows_markers = 3 * model.attachments.len();
        // Rows: 3 per marker, 1 per parameter (smoothness), 9 per moving joint (3 limit rows,
        // 3 locked directions, 3 rest).
        let rows_joints = rows_markers + n + 9 * model.moving.len();
        // And 3 per coupling, and with a prior pose 3 per moving joint but the root.
        let rows_prior = rows_joints + 3 * model.couplings.len();
        let rows_centres = rows_prior + self.prior.map_or(0, |_| n - 6);
        // And 3 per joint centre, where it is pulled.
        let rows = rows_centres + if self.config.centre > 0.0 { 3 * model.centres.len() } else { 0 };
        let mut r = DVector::zeros(rows);
        let mut jac = DMatrix::zeros(rows, n);
        let on = |j: usize, o: &Vec3| pose.positions_mm[j] + pose.rotations[j] * o;
        // d(lab p)/d(theta) for a point p riding on joint j, scaled by `w`, into `jac`'s rows.
        let chain = |jac: &mut DMatrix<f64>, row: usize, j: usize, p: &Vec3, w: f64| {
            for c in 0..3 {
                for d in 0..3 {
                    jac[(row + c, d)] += w * lab[(c, d)] * DECIMETRE_MM;
                }
            }
            let mut a = Some(j);
            while let Some(joint) = a {
                if let Some(b) = block[joint] {
                    let arm = p - pose.positions_mm[joint];
                    let m = lab * -skew(&arm) * g_jr[joint] * w;
                    let mut view = jac.view_mut((row, b), (3, 3));
                    view += m;
                }
                a = model.skeleton.joints()[joint].parent;
            }
        };
        let huber = self.config.huber_mm;
        for (i, att) in model.attachments.iter().enumerate() {
            let Some(att) = att else { continue };
            let (target, scale) = if let Some(o) = self.observed[i] {
                (o, self.config.observed.sqrt() / DISTANCE_UNIT_MM)
            } else if let Some((v, variance)) = self.predicted[i] {
                (v, self.config.predicted.sqrt() / variance.max(PREDICTION_FLOOR_MM * PREDICTION_FLOOR_MM).sqrt())
            } else {
                continue;
            };
            let p = on(att.joint, &att.offset_mm);
            let (m, blend) = match &att.blend {
                Some((j, w, o)) => {
                    let q = on(*j, o);
                    (p * (1.0 - w) + q * *w, Some((*j, *w, q)))
                }
                None => (p, None),
            };
            let m_lab = model.lab * m;
            let mut w = scale;
            if self.observed[i].is_some() && huber > 0.0 {
                let d = (m_lab - target).norm();
                if d > huber {
                    // IRLS weight of the Huber loss: rho(d) = 2 h d - h^2 has rho'(d)/(2d) = h/d.
                    w *= (huber / d).sqrt();
                }
            }
            let e = (m_lab - target) * w;
            r.rows_mut(3 * i, 3).copy_from(&e);
            match blend {
                Some((j, bw, q)) => {
                    chain(&mut jac, 3 * i, att.joint, &p, w * (1.0 - bw));
                    chain(&mut jac, 3 * i, j, &q, w * bw);
                }
                None => chain(&mut jac, 3 * i, att.joint, &p, w),
            }
        }
        if let Some((a, b)) = self.history {
            let s = self.config.smooth.sqrt();
            for k in 0..n {
                r[rows_markers + k] = s * (theta[k] - a[k] - self.damping * (a[k] - b[k]));
                jac[(rows_markers + k, k)] = s;
            }
        }
        let limit = self.config.limit_deg.to_radians();
        let l = self.config.limits.sqrt();
        let (lk, rs) = ((self.config.limits * self.config.locked).sqrt(), self.config.rest.sqrt());
        for (k, &j) in model.moving.iter().enumerate() {
            let b = 3 + 3 * k;
            let row = rows_markers + n + 9 * k;
            let v = Vec3::new(theta[b], theta[b + 1], theta[b + 2]);
            if j != 0 {
                for c in 0..3 {
                    r[row + 6 + c] = rs * v[c];
                    jac[(row + 6 + c, b + c)] = rs;
                }
            }
            match &model.dofs[j] {
                JointDofs::Axes(axes) if j != 0 => {
                    for (c, a) in axes.iter().enumerate() {
                        let excess = axis_excess(a, &v);
                        r[row + c] = l * excess;
                        if excess != 0.0 {
                            for d in 0..3 {
                                jac[(row + c, b + d)] = l * a.axis[d];
                            }
                        }
                    }
                    for (c, (residual, gradient)) in self.locked[j].residuals(&v).enumerate() {
                        r[row + 3 + c] = lk * residual;
                        for d in 0..3 {
                            jac[(row + 3 + c, b + d)] = lk * gradient[d];
                        }
                    }
                }
                _ if j == 0 && !self.config.root_limited => {}
                _ => {
                    let norm = v.norm();
                    if norm > limit {
                        r[row] = l * (norm - limit);
                        for d in 0..3 {
                            jac[(row, b + d)] = l * v[d] / norm;
                        }
                    }
                }
            }
        }
        let w = self.config.coupling.sqrt();
        for (k, c) in model.couplings.iter().enumerate() {
            let (Some(a), Some(b)) = (model.block_of(c.joint), model.block_of(c.leader)) else { continue };
            let row = rows_joints + 3 * k;
            for d in 0..3 {
                r[row + d] = w * (theta[a + d] - c.ratio * theta[b + d]);
                jac[(row + d, a + d)] = w;
                jac[(row + d, b + d)] = -w * c.ratio;
            }
        }
        if let Some(prior) = self.prior {
            let huber = self.config.prior_huber_deg.to_radians();
            for k in (6..n).step_by(3) {
                let mut w = (self.config.prior * model.prior_weight_of(k)).sqrt();
                let d: f64 = (k..k + 3).map(|c| (theta[c] - prior[c]).powi(2)).sum::<f64>().sqrt();
                if huber > 0.0 && d > huber {
                    // IRLS weight of the Huber loss, as for the markers.
                    w *= (huber / d).sqrt();
                }
                for c in k..k + 3 {
                    r[rows_prior + c - 6] = w * (theta[c] - prior[c]);
                    jac[(rows_prior + c - 6, c)] = w;
                }
            }
        }
        if self.config.centre > 0.0 {
            let w = self.config.centre.sqrt() / DISTANCE_UNIT_MM;
            for (k, c) in model.centres.iter().enumerate() {
                let Some((joint, target)) = self.centre_target(c, &pose) else { continue };
                let row = rows_centres + 3 * k;
                r.rows_mut(row, 3).copy_from(&((joint - target) * w));
                chain(&mut jac, row, c.joint, &pose.positions_mm[c.joint], w);
            }
        }
        (r, jac)
    }
}

/// How far the rotation vector `v`'s component along `a` lies outside its range (signed, rad).
fn axis_excess(a: &DofAxis, v: &Vec3) -> f64 {
    let x = a.axis.dot(v);
    (x - a.max_rad).max(0.0) + (x - a.min_rad).min(0.0)
}

/// `[v]x`: the cross-product matrix.
fn skew(v: &Vec3) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// The right Jacobian of the exponential map at `v`: `exp(v + d) = exp(v) exp(J_r(v) d)` to
/// first order.
fn right_jacobian(v: &Vec3) -> Matrix3<f64> {
    let t2 = v.norm_squared();
    let k = skew(v);
    if t2 < 1e-12 {
        return Matrix3::identity() - k * 0.5;
    }
    let t = t2.sqrt();
    Matrix3::identity() - k * ((1.0 - t.cos()) / t2) + k * k * ((t - t.sin()) / (t2 * t))
}

/// `J^T J` and `J^T r`, row by row over each row's non-zero entries: a marker's row touches
/// only the root and the joints above it, a smoothness or limit row one joint, so this is many
/// times cheaper than the dense product on a skeleton of a few dozen joints.
fn normal_equations(r: &DVector<f64>, jac: &DMatrix<f64>) -> (DMatrix<f64>, DVector<f64>) {
    let n = jac.ncols();
    let mut h = DMatrix::zeros(n, n);
    let mut g = DVector::zeros(n);
    let mut nz: Vec<(usize, f64)> = Vec::with_capacity(n);
    for i in 0..jac.nrows() {
        nz.clear();
        nz.extend((0..n).filter_map(|k| {
            let x = jac[(i, k)];
            (x != 0.0).then_some((k, x))
        }));
        for &(a, x) in &nz {
            g[a] += x * r[i];
            for &(b, y) in &nz {
                h[(a, b)] += x * y;
            }
        }
    }
    (h, g)
}

/// Levenberg-Marquardt from `start`: at most `iterations` accepted steps, each kept only if it
/// lowers the energy.
fn levenberg_marquardt(problem: &PoseProblem, start: Vec<f64>, iterations: u64) -> Vec<f64> {
    let mut theta = start;
    let mut energy = problem.energy(&theta);
    let mut damping = 1e-3;
    for _ in 0..iterations {
        let (r, jac) = problem.linearize(&theta);
        let (h, g) = normal_equations(&r, &jac);
        let mut accepted = false;
        for _ in 0..8 {
            let mut a = h.clone();
            for k in 0..a.nrows() {
                a[(k, k)] += damping * (h[(k, k)] + 1e-6);
            }
            let Some(step) = a.cholesky().map(|c| c.solve(&(-&g))) else {
                damping *= 10.0;
                continue;
            };
            let next: Vec<f64> = theta.iter().zip(step.iter()).map(|(t, s)| t + s).collect();
            let e = problem.energy(&next);
            if e.is_finite() && e < energy {
                let small = step.norm() < 1e-7;
                theta = next;
                energy = e;
                damping = (damping / 3.0).max(1e-9);
                accepted = !small;
                break;
            }
            damping *= 4.0;
        }
        if !accepted {
            break;
        }
    }
    theta
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
    /// Per joint, what its axes do not allow.
    locked: Vec<Locked>,
    /// The prior pose of the next fit ([`PoseTracker::set_prior`]).
    prior: Option<Vec<f64>>,
}

impl PoseTracker {
    /// A tracker for `model` on a take recorded at `frame_rate_hz`.
    pub fn new(model: MarkerModel, config: IkConfig, frame_rate_hz: f64) -> PoseTracker {
        let damping = (-1.0 / (frame_rate_hz * config.velocity_time_constant_s)).exp();
        let locked = model.dofs.iter().map(Locked::of).collect();
        PoseTracker { model, config, history: Vec::new(), damping, locked, prior: None }
    }

    /// The marker model.
    pub fn model(&self) -> &MarkerModel {
        &self.model
    }

    /// Fits this frame's pose to the `observed` markers (mm) and the Kalman `predicted`
    /// positions with variances of the others; returns the model's marker positions.
    pub fn fit(&mut self, observed: &[Option<Vec3>], predicted: &[Option<(Vec3, f64)>]) -> Vec<Option<Vec3>> {
        let theta = self.fit_theta(observed, predicted);
        let markers = self.model.markers_mm(&theta);
        self.push(theta);
        markers
    }

    /// As [`PoseTracker::fit`], returning the fitted pose: local rotations (one per joint) and
    /// root position (mm), in the skeleton's frame.
    pub fn fit_pose(&mut self, observed: &[Option<Vec3>], predicted: &[Option<(Vec3, f64)>]) -> (Vec<Quat>, Vec3) {
        let theta = self.fit_theta(observed, predicted);
        let pose = self.model.pose(&theta);
        self.push(theta);
        pose
    }

    fn fit_theta(&self, observed: &[Option<Vec3>], predicted: &[Option<(Vec3, f64)>]) -> Vec<f64> {
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
            locked: &self.locked,
            prior: self.prior.as_deref(),
        };
        let iterations = if first { self.config.first_iterations } else { self.config.iterations };
        if self.config.optimizer == Optimizer::LevenbergMarquardt {
            return levenberg_marquardt(&problem, start, iterations);
        }
        let identity: Vec<Vec<f64>> =
            (0..n).map(|i| (0..n).map(|j| if i == j { 1e-3 } else { 0.0 }).collect()).collect();
        let solver = BFGS::new(MoreThuenteLineSearch::new());
        Executor::new(problem, solver)
            .configure(|state| state.param(start.clone()).inv_hessian(identity).max_iters(iterations))
            .run()
            .ok()
            .and_then(|result| result.state().get_best_param().cloned())
            .unwrap_or(start)
    }

    /// Records the pose of the frame just fitted; re-bases the root rotation when asked.
    fn push(&mut self, theta: Vec<f64>) {
        self.history.insert(0, theta);
        self.history.truncate(2);
        if !(self.config.rebase_root && self.model.moving.first() == Some(&0)) {
            return;
        }
        let v = Vec3::new(self.history[0][3], self.history[0][4], self.history[0][5]);
        if v.norm() < 1.0 {
            return;
        }
        // The same rotations, expressed from a new base: the newest root vector becomes 0.
        let old = self.model.root_base;
        let base = old * Quat::from_scaled_axis(v);
        for h in &mut self.history {
            let r = base.inverse() * old * Quat::from_scaled_axis(Vec3::new(h[3], h[4], h[5]));
            let w = r.scaled_axis();
            h[3..6].copy_from_slice(&[w.x, w.y, w.z]);
        }
        self.model.root_base = base;
    }

    /// Starts the next frame from the pose `local`, `root_mm` (as [`PoseTracker::fit_pose`]
    /// returns it), without a motion history: a fit of a lone frame near a known pose.
    pub fn start_from(&mut self, local: &[Quat], root_mm: Vec3) {
        self.model.root_base = Quat::identity();
        self.history = vec![self.parameters_of(local, root_mm)];
    }

    /// The parameters of a pose with the root's rotation taken as is (no base).
    fn parameters_of(&self, local: &[Quat], root_mm: Vec3) -> Vec<f64> {
        let mut theta = vec![0.0; self.model.parameter_count()];
        for (k, &j) in self.model.moving.iter().enumerate() {
            let v = local[j].scaled_axis();
            theta[3 + 3 * k..6 + 3 * k].copy_from_slice(&[v.x, v.y, v.z]);
        }
        for c in 0..3 {
            theta[c] = root_mm[c] / DECIMETRE_MM;
        }
        theta
    }

    /// The pose the next fits are pulled towards, joint by joint but the root
    /// ([`IkConfig::prior`]): local rotations, one per skeleton joint; `None`: no pull.
    pub fn set_prior(&mut self, local: Option<&[Quat]>) {
        self.prior = local.map(|l| self.parameters_of(l, Vec3::zeros()));
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
        self.model.root_base = Quat::identity();
    }
}

/// Settings of [`solve_sequence`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SequenceConfig {
    /// The per-frame fit ([`IkConfig::kinematic`] by default).
    pub ik: IkConfig,
    /// Frames the subject calibration fits lengths and offsets on, spread over the take
    /// (0: no calibration, the model as given).
    pub calibration_frames: usize,
    /// Rounds of calibration (poses, then lengths and offsets); the first fits one overall
    /// scale, the others each bone's length and each marker's offset.
    pub calibration_rounds: usize,
    /// Pull of a bone's length scale towards the template's (at the overall scale): mm of residual per
    /// unit of scale, per calibration frame (10% costs as much as `0.1 x` this on one marker
    /// in every frame).
    pub bone_prior_mm: f64,
    /// Pull of a marker's offset towards the template's (at the overall scale): residual per mm
    /// of offset change, per calibration frame.
    pub offset_prior: f64,
    /// The same pull for the markers a model marks as landmarks ([`MarkerModel::with_landmarks`]).
    /// At 1 a landmark's offset lands halfway between the template's and where the markers alone
    /// would put it (its pull weighs as much as the marker seen in every calibration frame).
    pub landmark_offset_prior: f64,
    /// Calibration samples further than this (mm) from where the posed model and the marker's
    /// median displacement put it are left out (stray or swapped markers; in the first round,
    /// which fits no offsets, from the posed model itself).
    pub calibration_outlier_mm: f64,
    /// Frame rate (Hz) of the first, calibration-pose pass over the take (every k-th frame).
    pub first_pass_hz: f64,
    /// Pull of a model's joint centres ([`MarkerModel::with_joint_centres`]) towards the mean
    /// of their markers: residual per mm, per calibration frame (a marker's own is 1).
    pub joint_centre_weight: f64,
}

impl Default for SequenceConfig {
    fn default() -> SequenceConfig {
        SequenceConfig {
            ik: IkConfig::kinematic(),
            calibration_frames: 40,
            // Poses and offsets are fitted in turn, which converges slowly where a whole
            // cluster sits elsewhere than the template's (docs/benchmarks.md, "Kinematic solver").
            calibration_rounds: 10,
            bone_prior_mm: 200.0,
            offset_prior: 0.05,
            // Chosen on the validation takes (docs/benchmarks.md, "The trunk's markers held").
            landmark_offset_prior: 1.0,
            calibration_outlier_mm: 60.0,
            first_pass_hz: 30.0,
            // A bone 10% off its template length costs as much as a centre 20 mm off.
            joint_centre_weight: 1.0,
        }
    }
}

/// A take solved by [`solve_sequence`].
#[derive(Debug, Clone)]
pub struct SequenceFit {
    /// The calibrated model (bone lengths and marker offsets of this subject).
    pub model: MarkerModel,
    /// Per frame: local rotations (one per joint) and root position (mm, skeleton frame).
    pub poses: Vec<(Vec<Quat>, Vec3)>,
    /// The overall scale the calibration found (1: the template's size).
    pub scale: f64,
    /// Per joint: its offset's scale relative to the template (overall scale included).
    pub bone_scales: Vec<f64>,
    /// RMS distance (mm) of the observed markers from the model on the calibration frames,
    /// before and after calibration.
    pub calibration_rms_mm: (f64, f64),
    /// Per frame, RMS distance (mm) of the observed markers from the solved model (`None`:
    /// no marker observed).
    pub residual_rms_mm: Vec<Option<f64>>,
}

impl SequenceFit {
    /// RMS distance (mm) of every observed marker sample from the solved model.
    pub fn rms_mm(&self, frames: &[Vec<Option<Vec3>>]) -> f64 {
        let (mut sum, mut n) = (0.0, 0usize);
        for (f, (local, root)) in self.poses.iter().enumerate() {
            for (m, o) in self.model.markers_at(local, *root).iter().zip(&frames[f]) {
                if let (Some(m), Some(o)) = (m, o) {
                    sum += (m - o).norm_squared();
                    n += 1;
                }
            }
        }
        if n == 0 { f64::NAN } else { (sum / n as f64).sqrt() }
    }
}

impl MarkerModel {
    /// The model with joint offsets scaled per joint and the markers' offsets replaced.
    fn resized(&self, scales: &[f64], offsets: &NewOffsets) -> MarkerModel {
        let joints: Vec<Joint> = self
            .skeleton
            .joints()
            .iter()
            .zip(scales)
            .map(|(j, s)| Joint { offset_mm: j.offset_mm * *s, ..j.clone() })
            .collect();
        let mut out = self.clone();
        // Same names and parents: still a valid skeleton.
        out.skeleton = Skeleton::new(joints).unwrap_or_else(|_| self.skeleton.clone());
        for (a, o) in out.attachments.iter_mut().zip(offsets) {
            if let (Some(a), Some((primary, blend))) = (a, o) {
                a.offset_mm = *primary;
                if let (Some(b), Some(o)) = (&mut a.blend, blend) {
                    b.2 = *o;
                }
            }
        }
        out
    }
}

/// Fits `model` to a whole take: a subject calibration on the take itself, then every frame,
/// warm-started from the previous one (see the module docs). `frames` holds, per frame, each
/// model marker's observed position (lab frame, mm; `None`: not seen).
///
/// # Errors
/// No frames, frames of another marker count, or a frame rate that is not positive.
pub fn solve_sequence(
    model: MarkerModel,
    frames: &[Vec<Option<Vec3>>],
    frame_rate_hz: f64,
    config: &SequenceConfig,
) -> Result<SequenceFit, LabelError> {
    solve_sequence_with_prior(model, frames, frame_rate_hz, config, None)
}

/// [`solve_sequence`] with every frame's fit pulled towards a prior pose (`prior[f]`: local
/// rotations of the model's joints, [`IkConfig::prior`] its weight), such as a network's
/// answer: the markers refine it where they see, the prior holds what they do not.
///
/// # Errors
/// As [`solve_sequence`], or a prior that is not one pose of the model's joints per frame.
pub fn solve_sequence_with_prior(
    model: MarkerModel,
    frames: &[Vec<Option<Vec3>>],
    frame_rate_hz: f64,
    config: &SequenceConfig,
    prior: Option<&[Vec<Quat>]>,
) -> Result<SequenceFit, LabelError> {
    if let Some(p) = prior
        && (p.len() != frames.len() || p.iter().any(|pose| pose.len() != model.skeleton.len()))
    {
        return Err(LabelError::Config(format!(
            "the prior has {} poses for {} frames, or not one rotation per joint",
            p.len(),
            frames.len()
        )));
    }
    let prior_at = |f: usize| prior.map(|p| p[f].as_slice());
    if frames.is_empty() {
        return Err(LabelError::Config("the take has no frames".into()));
    }
    if let Some(f) = frames.iter().position(|f| f.len() != model.marker_count()) {
        return Err(LabelError::Config(format!(
            "frame {f} has {} markers, the model {}",
            frames[f].len(),
            model.marker_count()
        )));
    }
    if !(frame_rate_hz.is_finite() && frame_rate_hz > 0.0) {
        return Err(LabelError::Config(format!("frame rate {frame_rate_hz} Hz is not positive")));
    }
    let mut model = model;
    let joints = model.skeleton.len();
    let mut bone_scales = vec![1.0; joints];
    let mut scale = 1.0;
    let mut calibration_rms_mm = (f64::NAN, f64::NAN);
    let chosen = calibration_frames(frames, config.calibration_frames);
    // The first pass's pose of the first frame (on the template): a second start for it below.
    let mut first_pass_start: Option<(Vec<Quat>, Vec3)> = None;
    if !chosen.is_empty() && config.calibration_rounds > 0 {
        // Poses of the chosen frames from a pass over the take at a lower rate.
        let stride = ((frame_rate_hz / config.first_pass_hz).round() as usize).max(1);
        let mut tracker = PoseTracker::new(model.clone(), config.ik, frame_rate_hz / stride as f64);
        let mut poses = Vec::with_capacity(chosen.len());
        let mut next = 0;
        for f in (0..frames.len()).step_by(stride) {
            tracker.set_prior(prior_at(f));
            let pose = tracker.fit_pose(&frames[f], &vec![None; frames[f].len()]);
            if f == 0 {
                first_pass_start = Some(pose.clone());
            }
            while next < chosen.len() && chosen[next] < f + stride {
                poses.push(pose.clone());
                next += 1;
            }
        }
        let mut refit = IkConfig { iterations: 30, ..config.ik };
        let chosen_frames: Vec<&[Option<Vec3>]> = chosen.iter().map(|&f| frames[f].as_slice()).collect();
        poses = refit_poses(&model, refit, &chosen_frames, &poses);
        calibration_rms_mm.0 = rms_of(&model, &poses, &chosen_frames);
        let mut anchor: Option<MarkerModel> = None;
        for _ in 0..config.calibration_rounds {
            let (s, offsets) = calibrate_linear(&model, &poses, &chosen_frames, anchor.as_ref(), config);
            model = model.resized(&s, &offsets);
            for (b, x) in bone_scales.iter_mut().zip(&s) {
                *b *= x;
            }
            if anchor.is_none() {
                scale = s.get(1).copied().unwrap_or(1.0);
                anchor = Some(model.clone());
            }
            refit.iterations = 20;
            poses = refit_poses(&model, refit, &chosen_frames, &poses);
        }
        calibration_rms_mm.1 = rms_of(&model, &poses, &chosen_frames);
    }
    let mut tracker = PoseTracker::new(model.clone(), config.ik, frame_rate_hz);
    let mut poses = Vec::with_capacity(frames.len());
    let mut residual_rms_mm = Vec::with_capacity(frames.len());
    for (f, frame) in frames.iter().enumerate() {
        tracker.set_prior(prior_at(f));
        let (mut local, mut root) = tracker.fit_pose(frame, &vec![None; frame.len()]);
        // The first frame also from the first pass's pose: from the rest pose, a limb the
        // markers barely turn (a hand on one marker, its twist wide open) can land on the
        // mirror solution and be tracked there for the whole take.
        if let (0, Some((start, start_root))) = (f, &first_pass_start) {
            let mut other =
                PoseTracker::new(model.clone(), IkConfig { iterations: config.ik.first_iterations, ..config.ik }, 1.0);
            other.start_from(start, *start_root);
            other.set_prior(prior_at(0));
            let (l, r) = other.fit_pose(frame, &vec![None; frame.len()]);
            let better = |a: Option<f64>, b: Option<f64>| matches!((a, b), (Some(a), Some(b)) if a < b - 1e-9);
            if better(frame_rms(&model, &l, r, frame), frame_rms(&model, &local, root, frame)) {
                tracker.start_from(&l, r);
                (local, root) = (l, r);
            }
        }
        residual_rms_mm.push(frame_rms(&model, &local, root, frame));
        poses.push((local, root));
    }
    track_back_from_the_end(&model, frames, frame_rate_hz, config, prior, &mut poses, &mut residual_rms_mm);
    Ok(SequenceFit { model, poses, scale, bone_scales, calibration_rms_mm, residual_rms_mm })
}

/// Least mean improvement (mm^2 of squared frame RMS) over the frames before the switch for
/// [`track_back_from_the_end`] to take the backward pass there: noise and the way a redundant
/// chain (the neck) shares a turn do not switch (HDM05: 4 mm^2 per frame), a limb in a wrong
/// minimum does (S01's right arm: 640).
const BACKWARD_GAIN_MM2: f64 = 25.0;

/// Largest difference (radians) of a joint's rotation between the two passes at the switch
/// frame: a wider seam would be a jump in the motion.
const MAX_SEAM_RAD: f64 = 10.0 * std::f64::consts::PI / 180.0;

/// Share of the best gain a switch frame may give up to meet the forward pass where the two
/// agree best.
const SWITCH_SLACK: f64 = 0.05;

/// A limb the first frame leaves in a wrong minimum (a twisted arm that fits its markers
/// worse, but locally best) is tracked there until a motion snaps it out, which can be half
/// the take. So the take is also tracked backwards from its last frame, and the frames before
/// one switch frame are taken from the backward pass where that fits the markers better on
/// the whole. One switch only, placed where the two passes agree best among the switches
/// that keep nearly all of the gain: a switch between two solutions would be a jump.
fn track_back_from_the_end(
    model: &MarkerModel,
    frames: &[Vec<Option<Vec3>>],
    frame_rate_hz: f64,
    config: &SequenceConfig,
    prior: Option<&[Vec<Quat>]>,
    poses: &mut [(Vec<Quat>, Vec3)],
    residual_rms_mm: &mut [Option<f64>],
) {
    let n = frames.len();
    // From the rest pose, as the forward pass starts.
    let mut tracker = PoseTracker::new(model.clone(), config.ik, frame_rate_hz);
    let mut back: Vec<(Vec<Quat>, Vec3)> = Vec::with_capacity(n);
    let mut back_rms: Vec<Option<f64>> = Vec::with_capacity(n);
    for f in (0..n).rev() {
        tracker.set_prior(prior.map(|p| p[f].as_slice()));
        let (local, root) = tracker.fit_pose(&frames[f], &vec![None; frames[f].len()]);
        back_rms.push(frame_rms(model, &local, root, &frames[f]));
        back.push((local, root));
    }
    back.reverse();
    back_rms.reverse();
    // gains[k]: frames [0, k) backward, [k, n) forward, against all forward: the sum over the
    // first k frames of the forward pass's squared RMS less the backward pass's.
    let sq = |r: Option<f64>| r.map_or(0.0, |r| r * r);
    let mut gains = vec![0.0; n + 1];
    for k in 1..=n {
        gains[k] = gains[k - 1] + sq(residual_rms_mm[k - 1]) - sq(back_rms[k - 1]);
    }
    let worth = |k: usize| gains[k] > BACKWARD_GAIN_MM2 * k as f64;
    let Some(best) = (1..=n).filter(|&k| worth(k)).map(|k| gains[k]).max_by(f64::total_cmp) else { return };
    // Where the backward pose of frame k-1 meets the forward pose of frame k most closely.
    let seam = |k: usize| -> f64 {
        if k == n {
            return 0.0;
        }
        back[k].0.iter().zip(&poses[k].0).map(|(a, b)| a.angle_to(b)).fold(0.0, f64::max)
    };
    let Some(best_k) = (1..=n)
        .filter(|&k| worth(k) && gains[k] >= best - SWITCH_SLACK * best)
        .min_by(|&a, &b| seam(a).total_cmp(&seam(b)))
        .filter(|&k| seam(k) <= MAX_SEAM_RAD)
    else {
        return;
    };
    poses[..best_k].clone_from_slice(&back[..best_k]);
    residual_rms_mm[..best_k].copy_from_slice(&back_rms[..best_k]);
}

/// Up to `count` frames spread evenly over those that see at least 70% of the markers (or,
/// if none does, over the frames that see the most).
fn calibration_frames(frames: &[Vec<Option<Vec3>>], count: usize) -> Vec<usize> {
    if count == 0 {
        return Vec::new();
    }
    let seen: Vec<usize> = frames.iter().map(|f| f.iter().flatten().count()).collect();
    let most = seen.iter().copied().max().unwrap_or(0);
    let m = frames[0].len();
    let need = if most * 10 >= m * 7 { (m * 7).div_ceil(10) } else { most };
    if need < 3 {
        return Vec::new();
    }
    let good: Vec<usize> = (0..frames.len()).filter(|&f| seen[f] >= need).collect();
    let k = count.min(good.len());
    (0..k).map(|i| good[i * good.len() / k]).collect()
}

fn frame_rms(model: &MarkerModel, local: &[Quat], root: Vec3, observed: &[Option<Vec3>]) -> Option<f64> {
    let (mut sum, mut n) = (0.0, 0usize);
    for (m, o) in model.markers_at(local, root).iter().zip(observed) {
        if let (Some(m), Some(o)) = (m, o) {
            sum += (m - o).norm_squared();
            n += 1;
        }
    }
    (n > 0).then(|| (sum / n as f64).sqrt())
}

fn rms_of(model: &MarkerModel, poses: &[(Vec<Quat>, Vec3)], frames: &[&[Option<Vec3>]]) -> f64 {
    let (mut sum, mut n) = (0.0, 0.0);
    for ((local, root), frame) in poses.iter().zip(frames) {
        if let Some(r) = frame_rms(model, local, *root, frame) {
            let k = frame.iter().flatten().count() as f64;
            sum += r * r * k;
            n += k;
        }
    }
    if n > 0.0 { (sum / n).sqrt() } else { f64::NAN }
}

/// Each frame's pose refitted alone from its previous pose (no smoothness).
fn refit_poses(
    model: &MarkerModel,
    config: IkConfig,
    frames: &[&[Option<Vec3>]],
    poses: &[(Vec<Quat>, Vec3)],
) -> Vec<(Vec<Quat>, Vec3)> {
    let mut tracker = PoseTracker::new(model.clone(), config, 1.0);
    frames
        .iter()
        .zip(poses)
        .map(|(frame, (local, root))| {
            tracker.start_from(local, *root);
            tracker.fit_pose(frame, &vec![None; frame.len()])
        })
        .collect()
}

/// Per marker, its offset on its joint and, for a blended marker, on the second joint (mm).
type NewOffsets = Vec<Option<(Vec3, Option<Vec3>)>>;

/// Per marker, the component-wise median over the frames of where its sample lies from the
/// posed model's marker, in the frame of the body it rides on (mm, scaled by the share of the
/// marker that body carries): the robust estimate of how far the subject wears it from the
/// template's place.
fn offset_shifts(model: &MarkerModel, poses: &[(Vec<Quat>, Vec3)], frames: &[&[Option<Vec3>]]) -> Vec<Vec3> {
    let lab_inv = model.lab.inverse();
    let mut seen: Vec<[Vec<f64>; 3]> = vec![Default::default(); model.marker_count()];
    for ((local, root), frame) in poses.iter().zip(frames) {
        let pose = forward_kinematics(&model.skeleton, local, *root);
        for (i, (now, o)) in model.markers_at(local, *root).iter().zip(frame.iter()).enumerate() {
            let (Some(att), Some(now), Some(o)) = (&model.attachments[i], now, o) else { continue };
            let share = 1.0 - att.blend.map_or(0.0, |b| b.1);
            if share < 1e-3 {
                continue;
            }
            let d = pose.rotations[att.joint].inverse() * (lab_inv * (o - now)) / share;
            for c in 0..3 {
                seen[i][c].push(d[c]);
            }
        }
    }
    seen.into_iter()
        .map(|mut axes| {
            let mut out = Vec3::zeros();
            for (c, v) in axes.iter_mut().enumerate() {
                if !v.is_empty() {
                    v.sort_by(f64::total_cmp);
                    out[c] = v[v.len() / 2];
                }
            }
            out
        })
        .collect()
}

/// The calibration's linear least squares: with every frame's rotations fixed, each marker is
/// `root + sum_b s_b G_parent(b) offset_b + G_j o` (skeleton frame), linear in the roots, the
/// bone scales `s_b` and the offsets `o`. `anchor` given: one scale per bone and the offsets,
/// with priors towards the anchor's lengths and offsets (the template at the subject's overall
/// scale: anchored to it, not to the previous round, the lengths and offsets the markers leave
/// free cannot drift from round to round); else one overall scale of bones and offsets
/// together. Returns the per-joint scales and the new offsets (primary, blend) per marker.
fn calibrate_linear(
    model: &MarkerModel,
    poses: &[(Vec<Quat>, Vec3)],
    frames: &[&[Option<Vec3>]],
    anchor: Option<&MarkerModel>,
    config: &SequenceConfig,
) -> (Vec<f64>, NewOffsets) {
    let per_bone = anchor.is_some();
    let sk = &model.skeleton;
    let joints = sk.len();
    let k = poses.len();
    let k_frames = k;
    let unchanged: NewOffsets =
        model.attachments.iter().map(|a| a.as_ref().map(|a| (a.offset_mm, a.blend.map(|b| b.2)))).collect();
    // Unknowns: roots (3 per frame), then scales, then offsets (3 per attached marker).
    let scaled: Vec<Option<usize>> = {
        let mut next = 3 * k;
        (0..joints)
            .map(|j| {
                let bone = j > 0 && sk.joints()[j].offset_mm.norm() > 1.0;
                match (bone, per_bone) {
                    (true, true) => {
                        next += 1;
                        Some(next - 1)
                    }
                    (true, false) => Some(3 * k),
                    _ => None,
                }
            })
            .collect()
    };
    let first_offset = 3 * k + if per_bone { scaled.iter().flatten().count() } else { 1 };
    let offset_of: Vec<Option<usize>> = {
        let mut next = first_offset;
        model
            .attachments
            .iter()
            .map(|a| {
                (per_bone && a.is_some()).then(|| {
                    next += 3;
                    next - 3
                })
            })
            .collect()
    };
    let n = first_offset + 3 * offset_of.iter().flatten().count();
    let mut a = DMatrix::<f64>::zeros(n, n);
    let mut b = DVector::<f64>::zeros(n);
    let add_row = |coeffs: &[(usize, f64)], rhs: f64, a: &mut DMatrix<f64>, b: &mut DVector<f64>| {
        for &(i, x) in coeffs {
            b[i] += x * rhs;
            for &(j, y) in coeffs {
                a[(i, j)] += x * y;
            }
        }
    };
    let lab_inv = model.lab.inverse();
    let cutoff = config.calibration_outlier_mm;
    let shifts = if per_bone { offset_shifts(model, poses, frames) } else { vec![Vec3::zeros(); model.marker_count()] };
    // Component `c` of joint `j`'s position in a frame posed as `pose`, linear in the unknowns:
    // (column, coefficient) pairs, each times `w`, and the constant part (not times `w`). The
    // root's column is frame `f`'s.
    let chain_terms = |j: usize, pose: &(usize, locap_core::skeleton::GlobalPose), c: usize, w: f64| {
        let (f, pose) = pose;
        let mut coeffs: Vec<(usize, f64)> = vec![(3 * f + c, w)];
        let mut constant = 0.0;
        let mut joint = j;
        while let Some(parent) = sk.joints()[joint].parent {
            let x = (pose.rotations[parent] * sk.joints()[joint].offset_mm)[c];
            match scaled[joint] {
                Some(col) => coeffs.push((col, w * x)),
                None => constant += x,
            }
            joint = parent;
        }
        (coeffs, constant)
    };
    // The same for marker `i` (its attachment, blend included).
    let marker_terms = |i: usize, pose: &(usize, locap_core::skeleton::GlobalPose), c: usize| {
        let Some(att) = &model.attachments[i] else { return (Vec::new(), 0.0) };
        // Each part of the marker: (weight, joint, offset in its frame, offset unknown?).
        let mut parts = vec![(1.0, att.joint, att.offset_mm, true)];
        if let Some((j, w, off)) = att.blend {
            parts[0].0 = 1.0 - w;
            parts.push((w, j, off, false));
        }
        let mut coeffs: Vec<(usize, f64)> = vec![(3 * pose.0 + c, 1.0)];
        let mut constant = 0.0;
        for &(w, j, off, primary) in &parts {
            // The chain of bones from the root to j (the root's column is counted once above).
            let (chain, k) = chain_terms(j, pose, c, w);
            coeffs.extend(chain.into_iter().skip(1));
            constant += w * k;
            let g = pose.1.rotations[j].to_rotation_matrix().into_inner();
            match (primary, offset_of[i]) {
                (true, Some(col)) => {
                    for d in 0..3 {
                        coeffs.push((col + d, w * g[(c, d)]));
                    }
                }
                // The overall scale scales the offsets too.
                _ if !per_bone => coeffs.push((3 * k_frames, w * (g * off)[c])),
                _ => constant += w * (g * off)[c],
            }
        }
        (coeffs, constant)
    };
    for (f, ((local, root), frame)) in poses.iter().zip(frames).enumerate() {
        let posed = (f, forward_kinematics(sk, local, *root));
        let pose = &posed.1;
        let current = model.markers_at(local, *root);
        for (i, att) in model.attachments.iter().enumerate() {
            let (Some(att), Some(o), Some(now)) = (att, frame[i], current[i]) else { continue };
            // A marker the subject wears elsewhere than the template is off by the same
            // displacement (in its body's frame) in every frame: that is what the offsets are
            // fitted for, so only samples off from the marker's own typical place are strays.
            let expected = now + model.lab * (pose.rotations[att.joint] * shifts[i]);
            if (expected - o).norm() > cutoff {
                continue;
            }
            let target = lab_inv * o;
            for c in 0..3 {
                let (coeffs, constant) = marker_terms(i, &posed, c);
                add_row(&coeffs, target[c] - constant, &mut a, &mut b);
            }
        }
        // Joint centres at the mean of their markers, where all of them are seen: fitted with
        // the bone lengths (from the second round, which fits them).
        if !per_bone || config.joint_centre_weight <= 0.0 {
            continue;
        }
        for centre in &model.centres {
            if centre.markers.iter().any(|&m| frame[m].is_none()) {
                continue;
            }
            let share = 1.0 / centre.markers.len() as f64;
            let w = config.joint_centre_weight;
            // A joint further than the radius from its markers' mean is pulled in to the
            // radius, along the direction it lies in now; one within it stays where it is.
            let radius = config.ik.centre_radius_mm;
            let Some(placed) = centre.markers.iter().map(|&m| current[m]).collect::<Option<Vec<Vec3>>>() else {
                continue;
            };
            let mean = placed.iter().map(|p| lab_inv * p).sum::<Vec3>() * share;
            let away = pose.positions_mm[centre.joint] - mean;
            let kept = if away.norm() > radius { away * (radius / away.norm()) } else { away };
            for c in 0..3 {
                // w (mean of the markers - the joint) = 0, the roots cancelling.
                let (mut coeffs, mut constant) = chain_terms(centre.joint, &posed, c, -w);
                constant *= -w;
                for &m in &centre.markers {
                    let (more, k) = marker_terms(m, &posed, c);
                    coeffs.extend(more.into_iter().map(|(col, x)| (col, x * w * share)));
                    constant += k * w * share;
                }
                add_row(&coeffs, -constant - w * kept[c], &mut a, &mut b);
            }
        }
    }
    let root_k = (k as f64).sqrt();
    if let Some(anchor) = anchor {
        let w = config.bone_prior_mm * root_k;
        for (j, col) in scaled.iter().enumerate() {
            let Some(col) = col else { continue };
            let target = anchor.skeleton.joints()[j].offset_mm.norm() / sk.joints()[j].offset_mm.norm();
            add_row(&[(*col, w)], w * target, &mut a, &mut b);
        }
        for (i, col) in offset_of.iter().enumerate() {
            let (Some(col), Some(att)) = (col, &anchor.attachments[i]) else { continue };
            // A model whose markers were changed after the flags were given counts none as a landmark.
            let landmark = model.landmarks.get(i).copied().unwrap_or(false);
            let prior = if landmark { config.landmark_offset_prior } else { config.offset_prior };
            let w = prior * root_k;
            for d in 0..3 {
                add_row(&[(col + d, w)], w * att.offset_mm[d], &mut a, &mut b);
            }
        }
    }
    // A tiny ridge keeps roots of frames without markers (and unseen bones) determined.
    for i in 0..n {
        a[(i, i)] += 1e-9;
    }
    let Some(x) = a.cholesky().map(|c| c.solve(&b)) else {
        return (vec![1.0; joints], unchanged);
    };
    let sane = |s: f64| s.is_finite() && (0.5..2.0).contains(&s);
    let scales: Vec<f64> = scaled.iter().map(|c| c.map_or(1.0, |c| if sane(x[c]) { x[c] } else { 1.0 })).collect();
    if per_bone {
        let offsets = model
            .attachments
            .iter()
            .zip(&offset_of)
            .map(|(att, col)| {
                let att = att.as_ref()?;
                let o = col.map_or(att.offset_mm, |c| Vec3::new(x[c], x[c + 1], x[c + 2]));
                let ok = o.iter().all(|v| v.is_finite()) && (o - att.offset_mm).norm() < 200.0;
                Some((if ok { o } else { att.offset_mm }, att.blend.map(|b| b.2)))
            })
            .collect();
        (scales, offsets)
    } else {
        let s = if sane(x[3 * k]) { x[3 * k] } else { 1.0 };
        let mut all = vec![s; joints];
        all[0] = 1.0;
        let offsets = unchanged.iter().map(|o| o.map(|(p, bl)| (p * s, bl.map(|v| v * s)))).collect();
        (all, offsets)
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

    /// The arm with the forearm hinged about z within [0, 2] rad and the upper arm free.
    fn hinged_arm() -> MarkerModel {
        let hinge = JointDofs::Axes(vec![DofAxis { axis: Vec3::z(), min_rad: 0.0, max_rad: 2.0 }]);
        arm_model().with_dofs(vec![JointDofs::Free, JointDofs::Free, hinge, JointDofs::Free]).unwrap()
    }

    fn problem<'a>(
        model: &'a MarkerModel,
        config: &'a IkConfig,
        observed: &'a [Option<Vec3>],
        predicted: &'a [Option<(Vec3, f64)>],
        history: Option<(&'a [f64], &'a [f64])>,
        locked: &'a [Locked],
    ) -> PoseProblem<'a> {
        PoseProblem { model, config, observed, predicted, history, damping: 0.9, locked, prior: None }
    }

    /// [`hinged_arm`] with a shoulder that turns about two axes only, as a CMU hand does.
    fn two_axis_shoulder() -> MarkerModel {
        let hinge = JointDofs::Axes(vec![DofAxis { axis: Vec3::z(), min_rad: 0.0, max_rad: 2.0 }]);
        let two = JointDofs::Axes(vec![
            DofAxis { axis: Vec3::x(), min_rad: -1.5, max_rad: 1.5 },
            DofAxis { axis: Vec3::new(0.0, 0.3, 1.0).normalize(), min_rad: -1.0, max_rad: 1.0 },
        ]);
        arm_model().with_dofs(vec![JointDofs::Free, two, hinge, JointDofs::Free]).unwrap()
    }

    #[test]
    fn residuals_are_the_energy_and_the_jacobian_its_derivative() {
        for arm in [hinged_arm(), two_axis_shoulder()] {
            residuals_are_the_energy_and_the_jacobian_its_derivative_on(arm);
        }
    }

    fn residuals_are_the_energy_and_the_jacobian_its_derivative_on(arm: MarkerModel) {
        // The forearm follows the upper arm (a coupling's rows are checked too).
        // The prior holds each joint by its own weight (rows checked too).
        let model = arm
            .with_couplings(vec![JointCoupling { joint: 2, leader: 1, ratio: 0.6 }])
            .unwrap()
            .with_prior_weights(vec![1.0, 4.0, 0.5, 1.0])
            .unwrap()
            .in_lab(MarkerModel::y_up_in_z_up_lab());
        let tracker = PoseTracker::new(model.clone(), IkConfig::default(), 60.0);
        let config = IkConfig { rest: 0.3, limit_deg: 20.0, predicted: 0.2, ..IkConfig::kinematic() };
        let config = IkConfig { huber_mm: 0.0, prior: 2.0, ..config };
        let mut theta = arm_pose(&model, 0.7);
        theta[3..6].copy_from_slice(&[0.3, -0.2, 0.5]);
        theta[9..12].copy_from_slice(&[0.2, 0.1, -0.4]); // forearm: off its axis and below its range
        let truth = model.markers_mm(&arm_pose(&model, 0.2));
        let observed: Vec<Option<Vec3>> =
            truth.iter().enumerate().map(|(i, p)| if i == 4 { None } else { *p }).collect();
        let mut predicted = vec![None; truth.len()];
        predicted[4] = Some((truth[4].unwrap() + Vec3::new(3.0, 0.0, 0.0), 900.0));
        let (a, b) = (arm_pose(&model, 0.6), arm_pose(&model, 0.5));
        // A prior pose to be pulled towards (its rows are checked too).
        let prior = arm_pose(&model, 0.9);
        let p = PoseProblem {
            prior: Some(&prior),
            ..problem(&model, &config, &observed, &predicted, Some((&a, &b)), &tracker.locked)
        };
        let (r, jac) = p.linearize(&theta);
        let energy = p.energy(&theta);
        assert!((r.norm_squared() - energy).abs() < 1e-9 * energy.max(1.0), "{} vs {energy}", r.norm_squared());
        for k in 0..theta.len() {
            let h = 1e-6;
            let (mut up, mut down) = (theta.clone(), theta.clone());
            up[k] += h;
            down[k] -= h;
            let numeric = (p.linearize(&up).0 - p.linearize(&down).0) / (2.0 * h);
            let analytic = jac.column(k);
            let err = (numeric - analytic).norm();
            assert!(err < 1e-4 * analytic.norm().max(1.0), "parameter {k}: {err}");
        }
    }

    #[test]
    fn a_joint_far_from_the_prior_is_pulled_linearly_and_the_step_descends() {
        let model = hinged_arm().with_prior_weights(vec![1.0, 4.0, 0.5, 1.0]).unwrap();
        let tracker = PoseTracker::new(model.clone(), IkConfig::default(), 60.0);
        // The prior's term alone.
        let config = IkConfig {
            observed: 0.0,
            predicted: 0.0,
            smooth: 0.0,
            limits: 0.0,
            locked: 0.0,
            rest: 0.0,
            coupling: 0.0,
            centre: 0.0,
            prior: 2.0,
            prior_huber_deg: 5.0,
            ..IkConfig::kinematic()
        };
        let plain = IkConfig { prior_huber_deg: 0.0, ..config };
        let prior = arm_pose(&model, 0.9);
        let observed = vec![None; model.markers_mm(&prior).len()];
        let predicted = vec![None; observed.len()];
        let h = 5f64.to_radians();
        // The upper arm's block (weight 4) moved by `d` radians.
        let moved = |d: f64| {
            let mut theta = prior.clone();
            let v = Vec3::new(1.0, 2.0, -2.0).normalize() * d;
            for c in 0..3 {
                theta[6 + c] += v[c];
            }
            theta
        };
        let energy = |config: &IkConfig, theta: &[f64]| {
            let p = PoseProblem {
                prior: Some(&prior),
                ..problem(&model, config, &observed, &predicted, None, &tracker.locked)
            };
            p.energy(theta)
        };
        // Within the threshold the squares; beyond it linear, below the squares.
        let near = moved(0.5 * h);
        assert!((energy(&config, &near) - energy(&plain, &near)).abs() < 1e-12);
        assert!((energy(&config, &near) - 2.0 * 4.0 * (0.5 * h).powi(2)).abs() < 1e-12);
        let far = moved(4.0 * h);
        assert!((energy(&config, &far) - 2.0 * 4.0 * (2.0 * h * 4.0 * h - h * h)).abs() < 1e-12);
        assert!(energy(&config, &far) < 0.5 * energy(&plain, &far));
        // The linearisation's gradient (J^T r) is half the energy's: its steps go downhill.
        let p = PoseProblem {
            prior: Some(&prior),
            ..problem(&model, &config, &observed, &predicted, None, &tracker.locked)
        };
        let (r, jac) = p.linearize(&far);
        let gradient = jac.transpose() * r;
        for k in 0..far.len() {
            let step = 1e-6;
            let (mut up, mut down) = (far.clone(), far.clone());
            up[k] += step;
            down[k] -= step;
            let numeric = (p.energy(&up) - p.energy(&down)) / (2.0 * step);
            assert!((0.5 * numeric - gradient[k]).abs() < 1e-5 * gradient.norm().max(1.0), "parameter {k}");
        }
    }

    #[test]
    fn couplings_join_two_turning_joints_other_than_the_root() {
        let coupled = |joint, leader, ratio| hinged_arm().with_couplings(vec![JointCoupling { joint, leader, ratio }]);
        assert!(coupled(2, 1, 0.5).is_ok());
        assert!(coupled(3, 2, 0.5).is_err(), "an end site");
        assert!(coupled(2, 2, 0.5).is_err(), "itself");
        assert!(coupled(2, 0, 0.5).is_err(), "the root leads");
        assert!(coupled(0, 2, 0.5).is_err(), "the root follows");
        assert!(coupled(9, 2, 0.5).is_err(), "no such joint");
        assert!(coupled(2, 1, f64::NAN).is_err(), "no ratio");
    }

    #[test]
    fn levenberg_marquardt_recovers_a_known_pose_in_a_turned_lab() {
        let model = hinged_arm().in_lab(MarkerModel::y_up_in_z_up_lab());
        let mut theta = arm_pose(&model, 0.8);
        theta[3..6].copy_from_slice(&[0.4, 2.0, -0.3]);
        let truth = model.markers_mm(&theta);
        let mut tracker = PoseTracker::new(model.clone(), IkConfig::kinematic(), 60.0);
        let (local, root) = tracker.fit_pose(&truth, &vec![None; truth.len()]);
        let (want, want_root) = model.pose(&theta);
        assert!((root - want_root).norm() < 0.1, "root {root} vs {want_root}");
        for (j, (q, t)) in local.iter().zip(&want).enumerate().take(3) {
            assert!(q.angle_to(t).to_degrees() < 0.1, "joint {j}: {} deg", q.angle_to(t).to_degrees());
        }
    }

    #[test]
    fn joint_limits_hold_against_the_markers() {
        let model = hinged_arm();
        // Markers of an elbow bent the wrong way (-0.6 rad) and twisted off the hinge.
        let mut theta = arm_pose(&model, 0.0);
        theta[9..12].copy_from_slice(&[0.3, 0.0, -0.6]);
        let free = arm_model();
        let truth = free.markers_mm(&theta);
        let mut tracker = PoseTracker::new(model.clone(), IkConfig::kinematic(), 60.0);
        let (local, _) = tracker.fit_pose(&truth, &vec![None; truth.len()]);
        let v = local[2].scaled_axis();
        assert!(v.z > -0.02 && v.x.abs() < 0.02 && v.y.abs() < 0.02, "forearm {v}");
    }

    /// A synthetic take of the arm: the subject 10% larger than the template, markers placed
    /// 8 mm off the template's, the root turning round three times.
    /// Per frame, each marker's position.
    type Frames = Vec<Vec<Option<Vec3>>>;

    fn subject_take(model: &MarkerModel, frames: usize) -> (MarkerModel, Frames, Vec<Vec<f64>>) {
        let joints: Vec<Joint> =
            model.skeleton.joints().iter().map(|j| Joint { offset_mm: j.offset_mm * 1.1, ..j.clone() }).collect();
        let mut subject = model.clone();
        subject.skeleton = Skeleton::new(joints).unwrap();
        for (i, a) in subject.attachments.iter_mut().flatten().enumerate() {
            a.offset_mm = a.offset_mm * 1.1 + Vec3::new(8.0 * (i as f64).sin(), 8.0 * (i as f64).cos(), 3.0);
        }
        let mut poses = Vec::new();
        let takes = (0..frames)
            .map(|f| {
                let t = f as f64 / frames as f64;
                let mut theta = arm_pose(&subject, 0.5 + 0.5 * (6.0 * t).sin());
                let turn = 3.0 * std::f64::consts::TAU * t;
                let q = Quat::from_scaled_axis(Vec3::new(0.0, turn, 0.0))
                    * Quat::from_scaled_axis(Vec3::new(0.3, 0.0, 0.0));
                // The root's vector folded into [0, pi]: the tracker must follow it across.
                let v = q.scaled_axis();
                theta[3..6].copy_from_slice(&[v.x, v.y, v.z]);
                // The forearm on its hinge (z), inside its range.
                theta[9..12].copy_from_slice(&[0.0, 0.0, 0.8 + 0.5 * (5.0 * t).sin()]);
                poses.push(theta.clone());
                subject.markers_mm(&theta)
            })
            .collect();
        (subject, takes, poses)
    }

    #[test]
    fn a_sequence_is_calibrated_to_its_subject_and_tracked_round_and_round() {
        let model = hinged_arm();
        let (subject, frames, truth) = subject_take(&model, 240);
        let fit = solve_sequence(model.clone(), &frames, 60.0, &SequenceConfig::default()).unwrap();
        assert!((fit.scale - 1.1).abs() < 0.05, "overall scale {}", fit.scale);
        let (before, after) = fit.calibration_rms_mm;
        assert!(after < before && after < 2.0, "calibration {before:.1} -> {after:.2} mm");
        let rms = fit.rms_mm(&frames);
        let mut worst: f64 = 0.0;
        for (f, theta) in truth.iter().enumerate() {
            let (want, _) = subject.pose(theta);
            let e = fit.poses[f].0[2].angle_to(&want[2]).to_degrees();
            worst = worst.max(e);
        }
        assert!(rms < 2.0, "residual {rms:.2} mm");
        // Three markers per segment fix the segment, not exactly where its joint centre is:
        // bone length and offsets trade a little, a few degrees at the elbow.
        assert!(worst < 5.0, "elbow off by {worst:.2} deg");
        // Without calibration the template's size shows in the residual.
        let plain =
            solve_sequence(model, &frames, 60.0, &SequenceConfig { calibration_frames: 0, ..Default::default() })
                .unwrap();
        assert!(plain.rms_mm(&frames) > 2.0 * rms, "{} vs {rms}", plain.rms_mm(&frames));
    }

    #[test]
    fn a_marker_worn_far_from_the_templates_place_is_recalibrated_not_dropped() {
        let model = hinged_arm();
        let (mut subject, _, truth) = subject_take(&model, 240);
        // The subject wears the forearm's markers 120 mm from where the template has them: beyond
        // the calibration's stray cutoff in every frame.
        let moved = Vec3::new(50.0, 100.0, -40.0);
        for i in 6..9 {
            subject.attachments[i].as_mut().unwrap().offset_mm += moved;
        }
        let frames: Frames = truth.iter().map(|theta| subject.markers_mm(theta)).collect();
        // A tight cutoff, so the poses' compromise cannot bring the moved markers inside it.
        let config = SequenceConfig { calibration_outlier_mm: 15.0, ..Default::default() };
        let fit = solve_sequence(model, &frames, 60.0, &config).unwrap();
        let rms = fit.rms_mm(&frames);
        assert!(rms < 5.0, "residual {rms:.2} mm");
        let (mut sum, mut n) = (0.0, 0.0);
        for (f, (local, root)) in fit.poses.iter().enumerate() {
            let e = (fit.model.markers_at(local, *root)[7].unwrap() - frames[f][7].unwrap()).norm();
            sum += e * e;
            n += 1.0;
        }
        let marker = (sum / n).sqrt();
        assert!(marker < 5.0, "the moved marker stays {marker:.1} mm off");
    }

    #[test]
    fn a_landmark_markers_offset_is_held_towards_the_template() {
        // The subject wears one of the root's three markers 30 mm from the template's place (a
        // marker on soft tissue, or a template that is off for it): free, the calibration moves
        // its offset most of the way there; as a landmark (with its two partners), it stays
        // near the template's place (measured: 18.4 mm against 5.5).
        let model = hinged_arm();
        let (mut subject, _, truth) = subject_take(&model, 240);
        let moved = Vec3::new(0.0, 0.0, 30.0);
        subject.attachments[1].as_mut().unwrap().offset_mm += moved;
        let frames: Frames = truth.iter().map(|theta| subject.markers_mm(theta)).collect();
        let config = SequenceConfig::default();
        // Where marker 1 ends up in its joint's frame, against the template's offset at the
        // subject's overall scale.
        let shift = |model: MarkerModel| {
            let fit = solve_sequence(model, &frames, 60.0, &config).unwrap();
            let template = hinged_arm().attachments[1].as_ref().unwrap().offset_mm * fit.scale;
            (fit.model.attachments[1].as_ref().unwrap().offset_mm - template).norm()
        };
        let free = shift(model.clone());
        let landmarks = (0..model.marker_count()).map(|i| i < 3).collect();
        let held = shift(model.with_landmarks(landmarks).unwrap());
        assert!(free > 15.0, "the free marker's offset moved {free:.1} mm");
        assert!(held < 0.5 * free, "the landmark's offset moved {held:.1} mm, the free one's {free:.1}");
        assert!(hinged_arm().with_landmarks(vec![true; 2]).is_err());
    }

    #[test]
    fn a_joint_centre_between_two_markers_sets_the_bone_length_the_markers_leave_free() {
        // The subject's forearm is 300 mm (the template's 250, the rest 1.1 times the
        // template's): nothing rides below the hand joint, so only its two wrist markers,
        // around it, say where it is.
        let mut model = hinged_arm();
        let wrist = |o: [f64; 3]| Some(Attachment { joint: 2, offset_mm: Vec3::from(o), blend: None });
        // The template's wrist markers 40 mm short of its hand joint.
        model.attachments.extend([wrist([210.0, 30.0, 0.0]), wrist([210.0, -30.0, 0.0])]);
        let (mut subject, _, truth) = subject_take(&model, 240);
        let mut joints = subject.skeleton.joints().to_vec();
        joints[3].offset_mm = Vec3::new(300.0, 0.0, 0.0);
        subject.skeleton = Skeleton::new(joints).unwrap();
        subject.attachments[9].as_mut().unwrap().offset_mm = Vec3::new(300.0, 30.0, 0.0);
        subject.attachments[10].as_mut().unwrap().offset_mm = Vec3::new(300.0, -30.0, 0.0);
        let frames: Frames = truth.iter().map(|theta| subject.markers_mm(theta)).collect();
        let model = model.with_joint_centres(vec![JointCentre { joint: 3, markers: vec![9, 10] }]).unwrap();
        // Hand joint from the wrist markers' mean, worst frame (mm).
        let off = |config: &SequenceConfig| {
            let fit = solve_sequence(model.clone(), &frames, 60.0, config).unwrap();
            let mut worst: f64 = 0.0;
            for (f, (local, root)) in fit.poses.iter().enumerate() {
                let hand = fit.model.lab * forward_kinematics(&fit.model.skeleton, local, *root).positions_mm[3];
                let mean = (frames[f][9].unwrap() + frames[f][10].unwrap()) / 2.0;
                worst = worst.max((hand - mean).norm());
            }
            worst
        };
        let within = |radius: f64| SequenceConfig {
            ik: IkConfig { centre_radius_mm: radius, ..IkConfig::kinematic() },
            ..Default::default()
        };
        let centred = off(&within(0.0));
        let near = off(&within(20.0));
        let template = off(&SequenceConfig {
            joint_centre_weight: 0.0,
            ik: IkConfig { centre: 0.0, ..IkConfig::kinematic() },
            ..Default::default()
        });
        // The bone prior keeps part of the template's length: the centre pulls, not welds.
        eprintln!(
            "hand from its markers' mean: {centred:.1} mm, within 20 mm {near:.1}, {template:.1} without the centre"
        );
        assert!(centred < 10.0 && template > 2.0 * centred, "{centred:.1} vs {template:.1} mm");
        // Within a radius, the joint is pulled only as far as that.
        assert!(near < 22.0 && near > centred + 5.0, "{near:.1} mm within 20");
        assert!(model.clone().with_joint_centres(vec![JointCentre { joint: 3, markers: vec![] }]).is_err());
        assert!(model.with_joint_centres(vec![JointCentre { joint: 9, markers: vec![0] }]).is_err());
    }

    /// A two-axis joint is held on the products of its two turns, not on the rotation vectors
    /// in their plane: a large bend and turn (a CMU hand's 60 and -45 degrees) costs nothing,
    /// and a turn off them costs.
    #[test]
    fn a_two_axis_joint_is_held_on_the_products_of_its_turns() {
        let axes = vec![
            DofAxis { axis: Vec3::x(), min_rad: -2.0, max_rad: 2.0 },
            DofAxis { axis: Vec3::z(), min_rad: -2.0, max_rad: 2.0 },
        ];
        let dofs = JointDofs::Axes(axes.clone());
        let locked = Locked::of(&dofs);
        assert!(matches!(locked, Locked::Product { .. }));
        let off = |q: Quat| -> f64 { locked.residuals(&q.scaled_axis()).map(|(r, _)| r * r).sum::<f64>().sqrt() };
        let product = dofs.rotation(&[-45f64.to_radians(), 60f64.to_radians()]).unwrap();
        assert!(off(product) < 1e-12, "{}", off(product));
        // Its rotation vector leaves the plane of the two axes far: the plane alone could not
        // reach it.
        assert!(product.scaled_axis().y.abs() > 0.2, "{:?}", product.scaled_axis());
        let twisted = product * Quat::from_axis_angle(&Vec3::y_axis(), 0.1);
        // Here the residual is sin(0.1) cos(45 degrees): the turn seen through the second axis.
        assert!((off(twisted) - 0.1f64.sin() * 45f64.to_radians().cos()).abs() < 1e-9, "{}", off(twisted));
        // The gradient is the residual's derivative.
        let v = twisted.scaled_axis();
        let (_, gradient) = locked.residuals(&v).next().unwrap();
        for d in 0..3 {
            let mut step = Vec3::zeros();
            step[d] = 1e-6;
            let (up, down) = (v + step, v - step);
            let numeric = (locked.residuals(&up).next().unwrap().0 - locked.residuals(&down).next().unwrap().0) / 2e-6;
            assert!((numeric - gradient[d]).abs() < 1e-6, "{d}: {numeric} vs {}", gradient[d]);
        }
        // One axis and three keep the span's directions.
        assert!(matches!(Locked::of(&JointDofs::Axes(axes[..1].to_vec())), Locked::Directions(d) if d.len() == 2));
        assert!(matches!(Locked::of(&JointDofs::Free), Locked::Directions(d) if d.is_empty()));
    }

    #[test]
    fn dof_angles_turn_about_their_axes_in_order() {
        let axis = |v: Vec3| DofAxis { axis: v, min_rad: -1.0, max_rad: 1.0 };
        let two = JointDofs::Axes(vec![axis(Vec3::x()), axis(Vec3::z() * 2.0)]);
        let q = two.rotation(&[0.3, -0.5]).unwrap();
        // x first, then z (a vector turned about x, then about z), the axis length ignored.
        let want = Quat::from_scaled_axis(Vec3::z() * -0.5) * Quat::from_scaled_axis(Vec3::x() * 0.3);
        assert!(q.angle_to(&want) < 1e-12);
        assert!(two.rotation(&[0.3]).is_none());
        assert!(JointDofs::Free.rotation(&[0.0, 0.0, 0.0]).is_none());
        assert_eq!(JointDofs::Axes(Vec::new()).rotation(&[]), Some(Quat::identity()));
    }

    #[test]
    fn sparse_normal_equations_are_the_dense_products() {
        let mut jac = DMatrix::from_fn(7, 5, |i, k| ((i * 5 + k) as f64).sin());
        jac[(2, 3)] = 0.0;
        jac.row_mut(4).fill(0.0);
        let r = DVector::from_fn(7, |i, _| (i as f64).cos());
        let (h, g) = normal_equations(&r, &jac);
        assert!((h - jac.transpose() * &jac).norm() < 1e-12);
        assert!((g - jac.transpose() * &r).norm() < 1e-12);
    }

    /// A joint no marker rides on is held near where the prior puts it (within a few degrees:
    /// the smoothness term lags a moving prior), away from the rest pose the fit without a
    /// prior leaves it in; the markers still place the rest.
    #[test]
    fn a_prior_holds_what_the_markers_do_not_see() {
        let model = hinged_arm();
        let config = SequenceConfig {
            ik: IkConfig { prior: 3.0, ..IkConfig::kinematic() },
            calibration_frames: 0,
            ..SequenceConfig::default()
        };
        let mut frames = Vec::new();
        let mut prior = Vec::new();
        for f in 0..30 {
            let theta = arm_pose(&model, f as f64 / 30.0);
            // The forearm's markers (6-8) are never captured.
            let mut markers = model.markers_mm(&theta);
            markers[6..].iter_mut().for_each(|m| *m = None);
            frames.push(markers);
            prior.push(model.pose(&theta).0);
        }
        let with = solve_sequence_with_prior(model.clone(), &frames, 60.0, &config, Some(&prior)).unwrap();
        let without = solve_sequence(model.clone(), &frames, 60.0, &config).unwrap();
        for f in [10, 29] {
            let forearm = |fit: &SequenceFit| fit.poses[f].0[2].angle_to(&prior[f][2]).to_degrees();
            assert!(forearm(&with) < 5.0, "frame {f}: forearm {} deg from the prior", forearm(&with));
            assert!(forearm(&without) > 10.0, "frame {f}: without a prior {} deg", forearm(&without));
            assert!(with.poses[f].0[1].angle_to(&prior[f][1]).to_degrees() < 1.0, "frame {f}: upper arm");
        }
        assert!(solve_sequence_with_prior(model, &frames, 60.0, &config, Some(&prior[1..])).is_err());
    }

    #[test]
    fn prior_weights_are_one_per_joint_and_not_negative() {
        let model = arm_model();
        assert_eq!(model.prior_weights(), [1.0; 4]);
        assert!(model.clone().with_prior_weights(vec![1.0; 3]).is_err());
        assert!(model.clone().with_prior_weights(vec![1.0, -1.0, 1.0, 1.0]).is_err());
        assert!(model.clone().with_prior_weights(vec![1.0, f64::NAN, 1.0, 1.0]).is_err());
        assert_eq!(model.with_prior_weights(vec![1.0, 0.0, 3.0, 1.0]).unwrap().prior_weights(), [1.0, 0.0, 3.0, 1.0]);
    }

    #[test]
    fn bad_sequences_are_errors() {
        let model = arm_model();
        assert!(solve_sequence(model.clone(), &[], 60.0, &SequenceConfig::default()).is_err());
        assert!(solve_sequence(model.clone(), &[vec![None; 2]], 60.0, &SequenceConfig::default()).is_err());
        let ok = vec![vec![None; model.marker_count()]];
        assert!(solve_sequence(model.clone(), &ok, 0.0, &SequenceConfig::default()).is_err());
        // A frame with no marker at all still gives a pose (the rest pose).
        assert_eq!(solve_sequence(model, &ok, 60.0, &SequenceConfig::default()).unwrap().poses.len(), 1);
        let two = vec![JointDofs::Free; 2];
        assert!(arm_model().with_dofs(two).is_err());
    }

    #[test]
    fn bad_attachments_are_errors() {
        let bad = vec![Some(Attachment { joint: 9, offset_mm: Vec3::zeros(), blend: None })];
        assert!(MarkerModel::new(arm(), bad).is_err());
    }
}
