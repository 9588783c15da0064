//! The kinematic solver: the "optimization-based" column of LocalMoCap's Table 1 (section 4.2,
//! Vicon / MoSh++), for any marker set that has a layout, with no training.
//!
//! A take is solved by the labeler's IK ([`locap_label::ik`], one IK in the code base) through
//! [`locap_label::ik::solve_sequence`]: first a subject calibration on the take itself (an
//! overall scale, then each bone's length and each marker's offset, fitted by linear least
//! squares to poses of frames spread over the take, as a studio's range-of-motion calibration),
//! then every frame's joint angles and root by Levenberg-Marquardt on the robust (Huber) marker
//! distances, warm-started from the previous frame, with joint limits (the layout skeleton's
//! degrees of freedom where it has them) and a temporal smoothness term.
//!
//! Markers are the cleaned take's *captured* samples (`Cleaned::visible`: not gaps, not
//! outliers): the IK needs no gap filling, and filled samples would only add the filler's error.
//! The skeleton comes from the layout ([`locap_synth::layout::LayoutSkeleton`], e.g. built from
//! an OpenSim model) or is given ([`KinematicSolver::cmu41`]: the shipped network's CMU
//! skeleton, whose joints without degrees of freedom stay still). On the CMU skeleton each joint
//! turns about the axes of its ASF bone (the Acclaim ASF's `axis`, `dof` and `limits` lines,
//! see `locap_io::asf_amc`; [`CMU_ASF_DOFS`], the same in every CMU subject): an elbow or knee
//! about one axis, a hand about two, within the ranges CMU's own solutions use
//! ([`CMU_SOLVED_RANGES`]). The wrist joints are calibrated and held near the mean of their
//! two wrist markers ([`CMU_WRIST_CENTRES`]), where gait models put the wrist centre: within a
//! radius of it, as CMU's skeleton has its hand joint further down the hand. The trunk's
//! markers (pelvis, spine, sternum) are held near the layout's offsets in the calibration
//! ([`CMU_TRUNK_LANDMARK_JOINTS`]), as gait models define the pelvis's and thorax's frames
//! from them. Refining a network's answer ([`KinematicSolver::refine`]) runs twice: the first
//! pass shows where the markers persistently disagree with the network, the second pulls
//! towards the network's pose corrected by that bias; the first pass lets the hands' lone
//! markers turn them ([`BODY_HANDS_BIAS_PASS_FACTOR`]), as how a subject holds the hands is
//! theirs, not the training subjects'.
//! It is Y-up; a Z-up take sees it
//! turned into its lab by the convention of [`locap_core::units::y_up_to_z_up`], and the motion
//! comes back in the skeleton's Y-up frame, as the network solver's does.

use crate::NnError;
use locap_clean::{CleanConfig, Cleaned, Filler};
use locap_core::{Joint, Motion, Quat, Skeleton, Take, UpAxis, Vec3};
use locap_label::ik::{
    Attachment, DofAxis, JointCentre, JointCoupling, JointDofs, MarkerModel, SequenceConfig, solve_sequence_with_prior,
};
use locap_synth::Layout;

/// Weight of the rotation directions a layout skeleton's degrees of freedom lock
/// ([`locap_label::ik::IkConfig::locked`]) in [`KinematicSolver::from_layout`].
pub const SOFT_LOCK: f64 = 0.01;

/// One bone of the CMU skeleton's ASF (`:bonedata`): its name, the `axis` angles (degrees,
/// `XYZ` order: X applied first) and its rotational `dof`s, each with the ASF's `limits`
/// (degrees): `(axis 0 = rx, 1 = ry, 2 = rz, min, max)`.
pub type CmuBoneDofs = (&'static str, [f64; 3], &'static [(usize, f64, f64)]);

/// The CMU ASF's degrees of freedom, bone by bone: the same in every CMU subject's ASF (the
/// `axis`, `dof` and `limits` lines of the shared subjects 01-03 agree to 1e-13 degrees; the
/// bones' `direction` and `length` are the subject's own and come from the skeleton instead).
/// Bones not listed (`lhipjoint`, `rhipjoint`) have no `dof` line: they never turn.
pub const CMU_ASF_DOFS: &[CmuBoneDofs] = &[
    ("lfemur", [0.0, 0.0, 20.0], &[(0, -160.0, 20.0), (1, -70.0, 70.0), (2, -60.0, 70.0)]),
    ("ltibia", [0.0, 0.0, 20.0], &[(0, -10.0, 170.0)]),
    ("lfoot", [-90.0, 0.0, 20.0], &[(0, -45.0, 90.0), (2, -70.0, 20.0)]),
    ("ltoes", [-90.0, 0.0, 20.0], &[(0, -90.0, 20.0)]),
    ("rfemur", [0.0, 0.0, -20.0], &[(0, -160.0, 20.0), (1, -70.0, 70.0), (2, -70.0, 60.0)]),
    ("rtibia", [0.0, 0.0, -20.0], &[(0, -10.0, 170.0)]),
    ("rfoot", [-90.0, 0.0, -20.0], &[(0, -45.0, 90.0), (2, -20.0, 70.0)]),
    ("rtoes", [-90.0, 0.0, -20.0], &[(0, -90.0, 20.0)]),
    ("lowerback", [0.0, 0.0, 0.0], &[(0, -20.0, 45.0), (1, -30.0, 30.0), (2, -30.0, 30.0)]),
    ("upperback", [0.0, 0.0, 0.0], &[(0, -20.0, 45.0), (1, -30.0, 30.0), (2, -30.0, 30.0)]),
    ("thorax", [0.0, 0.0, 0.0], &[(0, -20.0, 45.0), (1, -30.0, 30.0), (2, -30.0, 30.0)]),
    ("lowerneck", [0.0, 0.0, 0.0], &[(0, -20.0, 45.0), (1, -30.0, 30.0), (2, -30.0, 30.0)]),
    ("upperneck", [0.0, 0.0, 0.0], &[(0, -20.0, 45.0), (1, -30.0, 30.0), (2, -30.0, 30.0)]),
    ("head", [0.0, 0.0, 0.0], &[(0, -20.0, 45.0), (1, -30.0, 30.0), (2, -30.0, 30.0)]),
    ("lclavicle", [0.0, 0.0, 0.0], &[(1, -20.0, 10.0), (2, 0.0, 20.0)]),
    ("lhumerus", [180.0, -30.0, -90.0], &[(0, -60.0, 90.0), (1, -90.0, 90.0), (2, -90.0, 90.0)]),
    ("lradius", [180.0, -30.0, -90.0], &[(0, -10.0, 170.0)]),
    ("lwrist", [0.0, 90.0, 90.0], &[(1, -180.0, 0.0)]),
    ("lhand", [0.0, 90.0, 90.0], &[(0, -90.0, 90.0), (2, -45.0, 45.0)]),
    ("lfingers", [0.0, 90.0, 90.0], &[(0, 0.0, 90.0)]),
    ("lthumb", [-90.0, 45.0, 0.0], &[(0, -45.0, 45.0), (2, -45.0, 45.0)]),
    ("rclavicle", [0.0, 0.0, 0.0], &[(1, -10.0, 20.0), (2, -20.0, 0.0)]),
    ("rhumerus", [180.0, 30.0, 90.0], &[(0, -90.0, 60.0), (1, -90.0, 90.0), (2, -90.0, 90.0)]),
    ("rradius", [180.0, 30.0, 90.0], &[(0, -10.0, 170.0)]),
    ("rwrist", [0.0, -90.0, -90.0], &[(1, -180.0, 0.0)]),
    ("rhand", [0.0, -90.0, -90.0], &[(0, -90.0, 90.0), (2, -45.0, 45.0)]),
    ("rfingers", [0.0, -90.0, -90.0], &[(0, 0.0, 90.0)]),
    ("rthumb", [-90.0, -45.0, 0.0], &[(0, -45.0, 45.0), (2, -45.0, 45.0)]),
];

/// The CMU skeleton's wrists (`lhand`, `rhand`: the joint the hand flexes about) and the wrist
/// markers around each (thumb and little-finger side of the wrist bar), whose mean is the
/// wrist centre as gait models define it ([`KinematicSolver::with_joint_centres`]); the joint
/// is held within [`locap_label::ik::CENTRE_RADIUS_MM`] of it, where CMU's skeleton puts it
/// 45-75 mm away.
pub const CMU_WRIST_CENTRES: &[(&str, &[&str])] = &[("lhand", &["LWRA", "LWRB"]), ("rhand", &["RWRA", "RWRB"])];

/// The CMU trunk's joints whose markers sit on bone (the pelvis's spines on `root`, T10 on
/// `upperback`, the sternum, clavicle notch and back on `thorax`, C7 on `lowerneck`): the
/// subject calibration holds their offsets towards the layout's
/// ([`locap_label::ik::MarkerModel::with_landmarks`]), so the pelvis's and the thorax's frames
/// are the markers' as gait models define them, instead of a turn or shift of the segment the
/// calibration files as marker placement. The head's markers (a band, worn higher or lower) and
/// the limbs' stay free.
pub const CMU_TRUNK_LANDMARK_JOINTS: [&str; 5] = ["root", "lowerback", "upperback", "thorax", "lowerneck"];

/// The ranges CMU's own solutions use (degrees, per bone, in [`CMU_ASF_DOFS`]'s dof order): the
/// ASF's `limits` widened to the 0.1th and 99.9th percentile of the AMC values of training
/// subjects 01 and 03 (every take; angles taken into a half turn either way), rounded out to 5
/// degrees. CMU's solutions turn a wrist about the forearm up to 95 degrees past the ASF's
/// range and bend feet, hands and thumbs beyond theirs; held-out subject 02 is not used.
pub const CMU_SOLVED_RANGES: &[(&str, &[(f64, f64)])] = &[
    ("lfemur", &[(-160.0, 25.0), (-70.0, 70.0), (-60.0, 70.0)]),
    ("ltibia", &[(-10.0, 170.0)]),
    ("lfoot", &[(-180.0, 180.0), (-180.0, 180.0)]),
    ("ltoes", &[(-90.0, 65.0)]),
    ("rfemur", &[(-160.0, 30.0), (-70.0, 70.0), (-70.0, 60.0)]),
    ("rtibia", &[(-10.0, 170.0)]),
    ("rfoot", &[(-50.0, 90.0), (-45.0, 70.0)]),
    ("rtoes", &[(-90.0, 75.0)]),
    ("lowerback", &[(-20.0, 80.0), (-30.0, 30.0), (-30.0, 30.0)]),
    ("upperback", &[(-20.0, 45.0), (-30.0, 30.0), (-30.0, 30.0)]),
    ("thorax", &[(-35.0, 45.0), (-30.0, 30.0), (-30.0, 30.0)]),
    ("lowerneck", &[(-45.0, 45.0), (-30.0, 30.0), (-50.0, 40.0)]),
    ("upperneck", &[(-45.0, 50.0), (-35.0, 35.0), (-30.0, 45.0)]),
    ("head", &[(-20.0, 45.0), (-30.0, 30.0), (-30.0, 30.0)]),
    ("lclavicle", &[(-20.0, 10.0), (-5.0, 20.0)]),
    ("lhumerus", &[(-80.0, 130.0), (-90.0, 90.0), (-90.0, 105.0)]),
    ("lradius", &[(-10.0, 170.0)]),
    ("lwrist", &[(-180.0, 95.0)]),
    ("lhand", &[(-90.0, 90.0), (-70.0, 45.0)]),
    ("lfingers", &[(0.0, 90.0)]),
    ("lthumb", &[(-45.0, 60.0), (-45.0, 70.0)]),
    ("rclavicle", &[(-10.0, 20.0), (-20.0, 5.0)]),
    ("rhumerus", &[(-90.0, 130.0), (-90.0, 90.0), (-165.0, 90.0)]),
    ("rradius", &[(-10.0, 170.0)]),
    ("rwrist", &[(-180.0, 180.0)]),
    ("rhand", &[(-90.0, 90.0), (-130.0, 85.0)]),
    ("rfingers", &[(0.0, 90.0)]),
    ("rthumb", &[(-45.0, 75.0), (-125.0, 115.0)]),
];

/// Which ranges [`cmu_asf_dofs`] gives the CMU axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CmuLimits {
    /// The ASF's `limits`. CMU's own solutions (the AMC files) leave them often (a wrist's
    /// `ry` in about half of the frames), so they are not the ranges CMU solved with.
    Asf,
    /// The ranges CMU's own solutions use ([`CMU_SOLVED_RANGES`]).
    Solved,
    /// Every axis within a half turn either way: the ASF's axes, no range.
    None,
}

/// The bone frame `C` of an ASF `axis a b c XYZ` line (degrees): `Rz(c) Ry(b) Rx(a)`, X
/// applied first (the Acclaim convention, `locap_io::asf_amc`).
pub fn acclaim_axis_frame(angles_deg: [f64; 3]) -> locap_core::Quat {
    let mut q = locap_core::Quat::identity();
    for (axis, angle) in angles_deg.iter().enumerate() {
        q = locap_core::rotation::axis_rotation(axis, angle.to_radians()) * q;
    }
    q
}

/// Each joint's rotational freedom on a CMU skeleton (one built from a CMU ASF, as the shipped
/// solver's: joint frames aligned with the world at rest, so an ASF bone's `L = C M C^-1` is
/// its local rotation): a bone of [`CMU_ASF_DOFS`] turns about `C e_x`, `C e_y`, `C e_z` for
/// its `rx`, `ry`, `rz`, in the ASF's order; the root turns freely; every other joint
/// (hip joints, end sites, a name the table lacks) not at all.
pub fn cmu_asf_dofs(skeleton: &Skeleton, limits: CmuLimits) -> Vec<JointDofs> {
    skeleton
        .joints()
        .iter()
        .enumerate()
        .map(|(j, joint)| {
            if j == 0 {
                return JointDofs::Free;
            }
            let Some((_, axis, dofs)) = CMU_ASF_DOFS.iter().find(|(name, ..)| *name == joint.name) else {
                return JointDofs::Axes(Vec::new());
            };
            let frame = acclaim_axis_frame(*axis);
            let solved = CMU_SOLVED_RANGES.iter().find(|(name, _)| *name == joint.name).map(|(_, r)| *r);
            JointDofs::Axes(
                dofs.iter()
                    .enumerate()
                    .map(|(n, &(k, min_deg, max_deg))| {
                        let (min_deg, max_deg) = match (limits, solved.and_then(|r| r.get(n))) {
                            (CmuLimits::Solved, Some(range)) => *range,
                            (CmuLimits::Asf | CmuLimits::Solved, _) => (min_deg, max_deg),
                            (CmuLimits::None, _) => (-180.0, 180.0),
                        };
                        DofAxis {
                            axis: frame * Vec3::ith(k, 1.0),
                            min_rad: min_deg.to_radians(),
                            max_rad: max_deg.to_radians(),
                        }
                    })
                    .collect(),
            )
        })
        .collect()
}

/// How far (median over the bones, degrees) a subject's skeleton may point from the CMU
/// template's rest pose for [`KinematicSolver::cmu41_on_bones_of`]: CMU subjects' ASF bones
/// differ by a few degrees; a skeleton in another rest pose or frame differs by tens.
pub const MAX_REST_POSE_TURN_DEG: f64 = 30.0;

/// `template` with each bone offset moved `share` of the way to that of `target`'s joint that
/// `matching` finds for its name; joints without a match keep the template's.
fn bones_towards(
    template: &Skeleton,
    target: &Skeleton,
    share: f64,
    matching: impl Fn(&str) -> Option<usize>,
) -> Result<Skeleton, NnError> {
    let joints = template
        .joints()
        .iter()
        .map(|j| {
            let to = matching(&j.name).map_or(j.offset_mm, |k| target.joints()[k].offset_mm);
            Joint { offset_mm: (1.0 - share) * j.offset_mm + share * to, ..j.clone() }
        })
        .collect();
    Skeleton::new(joints).map_err(NnError::Skeleton)
}

/// A kinematic solver: a layout's markers attached to a skeleton.
#[derive(Debug, Clone)]
pub struct KinematicSolver {
    model: MarkerModel,
    /// Layout marker names, model order.
    markers: Vec<String>,
    /// Per joint: some marker rides on it or on a joint below it, so the markers constrain its
    /// rotation.
    constrained: Vec<bool>,
    /// Settings of the calibration and the per-frame fit.
    pub config: SequenceConfig,
    /// [`IkConfig::prior`](locap_label::ik::IkConfig::prior) of [`KinematicSolver::refine`]:
    /// how hard the network's pose holds against the markers, times each joint's factor
    /// ([`KinematicSolver::with_refine_prior_factors`]).
    pub refine_prior: f64,
    /// Half-width (seconds) of the window over which [`KinematicSolver::refine`] averages the
    /// network's joint rotations before they pull: a per-frame network flickers from frame to
    /// frame, and its flicker is no evidence of motion ([`PRIOR_HALF_WINDOW_S`]; 0: as given).
    pub prior_half_window_s: f64,
    /// How far [`KinematicSolver::refine`] moves the template's bone offsets towards the
    /// skeleton the network predicted for the take before the subject calibration (0: the
    /// template; 1: the network's). Only the CMU body solver does it (its build is repeated on
    /// the new skeleton): [`BODY_NETWORK_SKELETON`] there, 0 elsewhere.
    pub network_skeleton: f64,
    /// [`KinematicSolver::refine`] in two passes where above 0 (degrees): the first pass's
    /// rotation away from the network's, per joint averaged over
    /// [`KinematicSolver::bias_half_window_s`] each side, is taken as the network's bias, and
    /// its part beyond this angle is added to the network's pose before the second pass pulls
    /// towards it. The markers correct a network persistently wrong about a joint they see;
    /// the pull stays smooth, so they cannot turn a fast hand from frame to frame.
    pub bias_huber_deg: f64,
    /// Half-width (seconds) of the window [`KinematicSolver::bias_huber_deg`] averages over.
    pub bias_half_window_s: f64,
    /// Per joint (empty: 1 for every joint), the share of its pull towards the network's pose
    /// that the first of [`KinematicSolver::refine`]'s two passes keeps
    /// ([`KinematicSolver::with_bias_pass_factors`]): a joint the markers see but the network
    /// holds hard shows the network's bias only where the first pass lets the markers turn it.
    bias_pass_factors: Vec<f64>,
    /// The joints the CMU body solver turns, when this is one ([`KinematicSolver::cmu41`]):
    /// what it needs to be built again on another skeleton.
    cmu_rotating: Option<Vec<bool>>,
}

/// [`KinematicSolver::refine_prior`] of a solver built from a layout's skeleton (the hands),
/// per rad^2: 10 degrees off the network's joint rotation weigh as a marker 3 mm off (the
/// kinematic preset's observed term).
pub const REFINE_PRIOR: f64 = 3.0;

/// [`KinematicSolver::refine_prior`] of the CMU body solver ([`KinematicSolver::cmu41`]): the
/// body networks turn joints the 41 markers barely see (wrists, feet, spine) better than the
/// markers do, so their pose holds harder than a hand's: 10 degrees off weigh as a marker
/// 16 mm off. Of 1, 3, 10, 30 and 100 on a validation take (CMU 01_01's motion synthesized;
/// no network was trained on it, nor is it a test take), 30 was best for both shipped body
/// networks but for one mixed result at 100 (docs/benchmarks.md).
pub const BODY_REFINE_PRIOR: f64 = 30.0;

/// The CMU spine joints the markers split a bend between ambiguously (one marker, T10, between
/// the pelvis and the thorax's cluster).
pub const BODY_SPINE: [&str; 3] = ["lowerback", "upperback", "thorax"];

/// How much harder than [`BODY_REFINE_PRIOR`] the network's pose holds the [`BODY_SPINE`] joints
/// in [`KinematicSolver::refine`]: refined at the body's pull, the spine ends further from the
/// truth than the network alone. Of 1, 3, 10 and 30 on the validation takes (as for
/// [`BODY_REFINE_PRIOR`]), 3 took most of the rotation gain for the least joint position cost;
/// harder pulls traded more position for little more rotation (docs/benchmarks.md, "The
/// network's pull per joint").
pub const BODY_SPINE_REFINE_FACTOR: f64 = 3.0;

/// How much harder than [`BODY_REFINE_PRIOR`] the network's pose holds the CMU `head` joint
/// in [`KinematicSolver::refine`]. The head cap's four markers see the head's orientation in
/// the lab, but the neck between it and the thorax carries no marker, so how a nod is shared
/// between `lowerneck`, `upperneck` and `head` is the network's call more than the markers':
/// refined at the body's pull, the head ended further from the truth than the network alone.
/// Of 3, 10 and 30 on the validation takes (as for [`BODY_SPINE_REFINE_FACTOR`]), 10 turned
/// the joints best at no joint position cost; holding the whole neck was worse
/// (docs/benchmarks.md, "The network's pull per joint").
pub const BODY_HEAD_REFINE_FACTOR: f64 = 10.0;

/// [`KinematicSolver::bias_huber_deg`] of the CMU body solver: its refinement runs twice, and
/// where the first pass turned a joint more than 5 degrees from the network's pose on average
/// (over [`BODY_BIAS_HALF_WINDOW_S`] each side), the network's pose is turned by the excess
/// before the second. A per-frame Huber pull (`IkConfig::prior_huber_deg`) at 5 degrees did
/// as well on held-out joints but let a fast hand snap 20-30 degrees from frame to frame on
/// real takes; the averaged correction keeps the pull smooth. Of 3, 5 and 10 degrees and
/// windows of 0.05 to 1 s on the validation takes (as for [`BODY_SPINE_REFINE_FACTOR`]), 5
/// degrees over 0.05 and 0.1 s were no worse than one pass on any figure and better on joint
/// positions; the wider windows turned joints worse (docs/benchmarks.md, "The network's
/// bias, corrected in a second pass").
pub const BODY_BIAS_HUBER_DEG: f64 = 5.0;

/// [`KinematicSolver::bias_half_window_s`] of the CMU body solver (see [`BODY_BIAS_HUBER_DEG`]).
pub const BODY_BIAS_HALF_WINDOW_S: f64 = 0.1;

/// The CMU joints a single marker each turns: the hands (LFIN, RFIN), flexed and deviated at
/// the wrist.
pub const BODY_HANDS: [&str; 2] = ["lhand", "rhand"];

/// The share of the network's pull that [`BODY_HANDS`] keep in the first pass of the CMU body
/// solver's refinement ([`KinematicSolver::with_bias_pass_factors`]). How a subject holds
/// the hands through a take is the subject's own (CMU's solutions deviate subject 01's hands
/// by about -15 degrees, subject 03's by +20, subject 02's by +17 to +49), so a network that
/// saw a few subjects cannot know it, while the finger marker shows it. At the full pull one
/// marker barely turns the hand, the calibration files the rest as the marker worn elsewhere,
/// and the second pass never sees the bias. At a tenth the first pass follows the marker and
/// the second pass holds the network's hand motion, at the full pull, around the corrected
/// pose, so the choice between the hand's two rotations that place its marker alike stays
/// the network's; with no pull at all the first pass takes the wrong one on the validation
/// takes. Of 0, 0.03, 0.1, 0.3 and 1 there, 0.03 to 0.3 were no worse than 1, and 0.1 is
/// their middle (docs/benchmarks.md, "The hands' bias seen by their markers").
pub const BODY_HANDS_BIAS_PASS_FACTOR: f64 = 0.1;

/// [`KinematicSolver::network_skeleton`] of the CMU body solver: halfway from the template to
/// the skeleton the network predicted for the take. The subject calibration fits bone lengths
/// (an overall scale, the wrist centres) but not where each joint centre sits on its bone, and
/// on synthetic takes nearly all of the refined solve's joint position error is that: a
/// constant offset per joint. The network, trained on many subjects, predicts the offsets from
/// the markers; halfway keeps the template as a prior against its errors. Of 0, 0.25, 0.5,
/// 0.75 and 1 on the validation takes (01_01's and 03_01's motion synthesized, as for
/// [`BODY_REFINE_PRIOR`]), 0.5 and 0.75 were best; against CMU's own solutions of the two real
/// takes, on which the layout's marker offsets were fitted, 0 is (docs/benchmarks.md, "The
/// network's skeleton in the refinement").
pub const BODY_NETWORK_SKELETON: f64 = 0.5;

/// [`KinematicSolver::prior_half_window_s`] by default: each joint's prior rotation is the mean
/// over 0.2 s on each side. Of 0.05, 0.1, 0.2 and 0.4 s on the body's validation take (CMU
/// 01_01's motion synthesized) and the left hand's (procedural takes of another seed), 0.2 s
/// was best or within 0.1 degrees of it on both; on the real body takes it removes the few
/// frame pairs where a joint turned over 20 degrees (docs/benchmarks.md, "The network's
/// flicker").
pub const PRIOR_HALF_WINDOW_S: f64 = 0.2;

/// What a solve did besides the motion.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct KinematicReport {
    /// Frames solved.
    pub frames: usize,
    /// Seconds spent (calibration and per-frame fit, not the cleaning).
    pub seconds: f64,
    /// RMS distance of the captured markers from the solved model over the take, mm.
    pub residual_rms_mm: f64,
    /// The same on the calibration frames before and after calibration, mm.
    pub calibration_rms_mm: (f64, f64),
    /// The overall subject scale against the template skeleton.
    pub scale: f64,
}

impl KinematicReport {
    /// Frames solved per second.
    pub fn frames_per_s(&self) -> f64 {
        self.frames as f64 / self.seconds.max(1e-9)
    }
}

fn config_error(e: impl std::fmt::Display) -> NnError {
    NnError::Kinematic(e.to_string())
}

impl KinematicSolver {
    /// `layout`'s markers on `skeleton` (Y-up, as ASF and BVH skeletons are), with each
    /// joint's rotational freedom (`None`: every joint free).
    ///
    /// # Errors
    /// The layout does not bind to the skeleton, or the freedoms are not one per joint.
    pub fn new(layout: &Layout, skeleton: &Skeleton, dofs: Option<Vec<JointDofs>>) -> Result<KinematicSolver, NnError> {
        let bound = layout.bind(skeleton).map_err(config_error)?;
        let attachments: Vec<Option<Attachment>> = bound
            .markers
            .iter()
            .map(|m| {
                Some(Attachment {
                    joint: m.joint,
                    offset_mm: m.offset_mm,
                    blend: m.blend.as_ref().map(|b| (b.joint, b.weight, b.offset_mm)),
                })
            })
            .collect();
        let mut constrained = vec![false; skeleton.len()];
        for m in &bound.markers {
            for start in std::iter::once(m.joint).chain(m.blend.as_ref().map(|b| b.joint)) {
                let mut j = Some(start);
                while let Some(k) = j {
                    constrained[k] = true;
                    j = skeleton.joints()[k].parent;
                }
            }
        }
        let mut model = MarkerModel::new(skeleton.clone(), attachments).map_err(config_error)?;
        if let Some(dofs) = dofs {
            model = model.with_dofs(dofs).map_err(config_error)?;
        }
        Ok(KinematicSolver {
            model,
            markers: bound.names,
            constrained,
            config: SequenceConfig::default(),
            refine_prior: REFINE_PRIOR,
            prior_half_window_s: PRIOR_HALF_WINDOW_S,
            network_skeleton: 0.0,
            bias_huber_deg: 0.0,
            bias_half_window_s: 1.0,
            bias_pass_factors: Vec::new(),
            cmu_rotating: None,
        })
    }

    /// A layout that carries its skeleton (see [`locap_synth::layout::LayoutSkeleton`]), with
    /// that skeleton's joint limits.
    ///
    /// # Errors
    /// The layout has no skeleton section, or it does not make a skeleton.
    pub fn from_layout(layout: &Layout) -> Result<KinematicSolver, NnError> {
        let Some(section) = &layout.skeleton else {
            return Err(NnError::Kinematic(format!(
                "layout {:?} carries no skeleton (a [skeleton] section, e.g. from `locap layout from-opensim`)",
                layout.name
            )));
        };
        if section.up_axis != UpAxis::Y {
            return Err(NnError::Kinematic("only Y-up layout skeletons are solved".into()));
        }
        let skeleton = section.to_skeleton().map_err(config_error)?;
        let dofs = section
            .joints
            .iter()
            .map(|j| match &j.dofs {
                None => JointDofs::Free,
                Some(axes) => JointDofs::Axes(
                    axes.iter()
                        .map(|d| DofAxis {
                            axis: Vec3::from(d.axis),
                            min_rad: d.min_deg.to_radians(),
                            max_rad: d.max_deg.to_radians(),
                        })
                        .collect(),
                ),
            })
            .collect();
        let mut solver = KinematicSolver::new(layout, &skeleton, Some(dofs))?;
        let index = |name: &str| section.joints.iter().position(|j| j.name == name);
        let couplings: Vec<JointCoupling> = section
            .joints
            .iter()
            .enumerate()
            .filter_map(|(k, j)| {
                let f = j.follows.as_ref()?;
                Some(JointCoupling { joint: k, leader: index(&f.joint)?, ratio: f.ratio })
            })
            .collect();
        if !couplings.is_empty() {
            solver.model = solver.model.clone().with_couplings(couplings).map_err(config_error)?;
        }
        // A layout's degrees of freedom are a model's simplification (an OpenSim model welds the
        // head to the torso; the importer drops the knee's spline-coupled rotations), so the
        // directions they lock are a soft pull here, not a weld: a joint leaves its axes by a
        // few degrees where the markers insist (10 degrees off an axis weigh as a marker 17 mm
        // off). The CMU skeleton's locks are the ASF's own and stay stiff.
        solver.config.ik.locked = SOFT_LOCK;
        if let Some(smooth) = section.smoothness {
            solver.config.ik.smooth = smooth;
        }
        Ok(solver)
    }

    /// The CMU 41-marker set ([`Layout::cmu41`]) on the shipped network solver's CMU skeleton
    /// (the mean of the network's training subjects: a refinement then pulls towards rotations
    /// on the rest pose they were predicted for; a new shipped network moves this solver's
    /// figures too, docs/benchmarks.md), each joint with the CMU ASF's degrees of freedom,
    /// within the ranges CMU's own solutions use ([`cmu_asf_dofs`], [`CmuLimits::Solved`]: the
    /// ASF's `limits` keep a 135_02 forearm from reaching its wrist markers;
    /// docs/benchmarks.md), and the wrists calibrated and held near the mean of their markers
    /// ([`CMU_WRIST_CENTRES`]; [`KinematicSolver::without_joint_centres`] for the template's
    /// forearms); the joints that skeleton never rotates (no degrees of freedom in the ASF, and
    /// the clavicles, which CMU's solutions never turn) stay still.
    ///
    /// # Errors
    /// The shipped solver does not load (a damaged build).
    pub fn cmu41() -> Result<KinematicSolver, NnError> {
        // The template's wrist markers lie 45-75 mm from its hand joints (docs/benchmarks.md,
        // "Kinematic solver: ASF degrees of freedom"): the calibration fits the forearms so the
        // wrist centre lies between them.
        let shipped = crate::shipped::solver(&Default::default())?;
        KinematicSolver::cmu41_on(&shipped.meta.skeleton, &shipped.meta.rotating)
    }

    /// [`KinematicSolver::cmu41`] on the subject's own bones, as a studio solves onto the
    /// skeleton it calibrated for the subject: each bone of the shipped CMU skeleton takes the
    /// offset of `subject`'s joint of the same name (or of an alias the CMU layout gives it, a
    /// CMU BVH's `LeftHip` for `lfemur`); bones `subject` lacks keep the template's. The subject
    /// calibration still fits lengths and offsets, held towards these bones, and the refinement
    /// leaves them where they are ([`KinematicSolver::network_skeleton`] 0).
    ///
    /// # Errors
    /// The shipped solver does not load; `subject` names no CMU joint a marker rides on; or its
    /// bones are not in the template's units and rest pose: together more than twice or less
    /// than half as long, or their median direction over [`MAX_REST_POSE_TURN_DEG`] off.
    pub fn cmu41_on_bones_of(subject: &Skeleton) -> Result<KinematicSolver, NnError> {
        let shipped = crate::shipped::solver(&Default::default())?;
        let template = &shipped.meta.skeleton;
        let layout = Layout::cmu41();
        let skeleton = bones_towards(template, subject, 1.0, |name| layout.resolve_joint(subject, name))?;
        if !layout.markers.iter().any(|m| layout.resolve_joint(subject, &m.joint).is_some()) {
            return Err(NnError::Kinematic(
                "the skeleton names none of the CMU joints the markers ride on (lfemur, rhumerus, ... or LeftHip, ...)"
                    .into(),
            ));
        }
        let (mut template_mm, mut subject_mm, mut turns) = (0.0, 0.0, Vec::new());
        for (t, s) in template.joints().iter().zip(skeleton.joints()) {
            if t.offset_mm.norm() > 1.0 && s.offset_mm.norm() > 1.0 && t.offset_mm != s.offset_mm {
                template_mm += t.offset_mm.norm();
                subject_mm += s.offset_mm.norm();
                turns.push(t.offset_mm.angle(&s.offset_mm).to_degrees());
            }
        }
        let ratio = subject_mm / template_mm.max(f64::MIN_POSITIVE);
        if !turns.is_empty() && !(0.5..=2.0).contains(&ratio) {
            return Err(NnError::Kinematic(format!(
                "the skeleton's bones are {ratio:.2} times the CMU template's: another length unit?"
            )));
        }
        turns.sort_by(f64::total_cmp);
        if let Some(&median) = turns.get(turns.len() / 2).filter(|&&m| m > MAX_REST_POSE_TURN_DEG) {
            return Err(NnError::Kinematic(format!(
                "the skeleton's bones point {median:.0} degrees from the CMU template's (median): another rest pose or up axis?"
            )));
        }
        let mut solver = KinematicSolver::cmu41_on(&skeleton, &shipped.meta.rotating)?;
        solver.network_skeleton = 0.0;
        // The layout's trunk offsets are measured from the template's pelvis and thorax joints;
        // a studio's skeleton puts those joints elsewhere in the body, so no marker is held
        // there (held, 02_01 on subject 02's bones came 2.4 mm further from CMU's solution).
        let markers = solver.model.marker_count();
        solver.model = solver.model.with_landmarks(vec![false; markers]).map_err(config_error)?;
        Ok(solver)
    }

    /// [`KinematicSolver::cmu41`] with each joint's freedom from `dofs` (given the shipped
    /// skeleton; one entry per joint), where the shipped skeleton rotates the joint at all:
    /// e.g. `|s| vec![JointDofs::Free; s.len()]`, every rotating joint free in three axes (the
    /// solver before the ASF's degrees of freedom), or [`cmu_asf_dofs`] with other limits.
    ///
    /// # Errors
    /// The shipped solver does not load, or `dofs` gives not one entry per joint.
    pub fn cmu41_with(dofs: impl FnOnce(&Skeleton) -> Vec<JointDofs>) -> Result<KinematicSolver, NnError> {
        let device = Default::default();
        let shipped = crate::shipped::solver(&device)?;
        KinematicSolver::cmu41_on_with(&shipped.meta.skeleton, &shipped.meta.rotating, dofs)
    }

    /// [`KinematicSolver::cmu41`] on another CMU skeleton (the same joints; e.g. the one a
    /// network solve predicted for the take), turning the joints `rotating` marks.
    ///
    /// # Errors
    /// The layout does not bind to `skeleton`, or `rotating` is not one per joint.
    pub fn cmu41_on(skeleton: &Skeleton, rotating: &[bool]) -> Result<KinematicSolver, NnError> {
        let mut solver =
            KinematicSolver::cmu41_on_with(skeleton, rotating, |skeleton| cmu_asf_dofs(skeleton, CmuLimits::Solved))?
                .with_joint_centres(CMU_WRIST_CENTRES)?;
        solver.cmu_rotating = Some(rotating.to_vec());
        solver.network_skeleton = BODY_NETWORK_SKELETON;
        Ok(solver)
    }

    fn cmu41_on_with(
        skeleton: &Skeleton,
        rotating: &[bool],
        dofs: impl FnOnce(&Skeleton) -> Vec<JointDofs>,
    ) -> Result<KinematicSolver, NnError> {
        if rotating.len() != skeleton.len() {
            return Err(NnError::Kinematic(format!("{} rotating flags for {} joints", rotating.len(), skeleton.len())));
        }
        let given = dofs(skeleton);
        if given.len() != skeleton.len() {
            return Err(NnError::Kinematic(format!(
                "{} joint freedoms for the shipped skeleton of {} joints",
                given.len(),
                skeleton.len()
            )));
        }
        let dofs = given
            .into_iter()
            .zip(rotating)
            .enumerate()
            .map(|(j, (d, r))| if *r || j == 0 { d } else { JointDofs::Axes(Vec::new()) })
            .collect();
        let layout = Layout::cmu41();
        let mut solver = KinematicSolver::new(&layout, skeleton, Some(dofs))?;
        let landmarks = solver
            .markers
            .iter()
            .map(|name| {
                layout.markers.iter().any(|m| m.name == *name && CMU_TRUNK_LANDMARK_JOINTS.contains(&m.joint.as_str()))
            })
            .collect();
        solver.model = solver.model.with_landmarks(landmarks).map_err(config_error)?;
        solver.refine_prior = BODY_REFINE_PRIOR;
        solver.bias_huber_deg = BODY_BIAS_HUBER_DEG;
        solver.bias_half_window_s = BODY_BIAS_HALF_WINDOW_S;
        let mut factors: Vec<(&str, f64)> = BODY_SPINE.iter().map(|j| (*j, BODY_SPINE_REFINE_FACTOR)).collect();
        factors.push(("head", BODY_HEAD_REFINE_FACTOR));
        let hands: Vec<(&str, f64)> = BODY_HANDS.iter().map(|j| (*j, BODY_HANDS_BIAS_PASS_FACTOR)).collect();
        solver.with_refine_prior_factors(&factors)?.with_bias_pass_factors(&hands)
    }

    /// The same solver with the first of [`KinematicSolver::refine`]'s two passes (where
    /// [`KinematicSolver::bias_huber_deg`] is above 0) pulling each named joint towards the
    /// network's pose `factor` times as hard as the second pass does (the others: as hard; on
    /// the CMU body solver the hands [`BODY_HANDS_BIAS_PASS_FACTOR`]).
    ///
    /// # Errors
    /// A joint the skeleton lacks, or a factor that is negative or not finite.
    pub fn with_bias_pass_factors(mut self, factors: &[(&str, f64)]) -> Result<KinematicSolver, NnError> {
        let mut start = std::mem::take(&mut self.bias_pass_factors);
        if start.is_empty() {
            start = vec![1.0; self.model.skeleton().len()];
        }
        self.bias_pass_factors = self.named_factors(start, factors, "bias pass")?;
        Ok(self)
    }

    /// `start` (one value per joint) with each named joint's value replaced by its factor.
    ///
    /// # Errors
    /// A joint the skeleton lacks, or a factor that is negative or not finite (`what` names
    /// the setting in the message).
    fn named_factors(&self, mut start: Vec<f64>, factors: &[(&str, f64)], what: &str) -> Result<Vec<f64>, NnError> {
        let skeleton = self.model.skeleton();
        for (name, factor) in factors {
            let j = skeleton
                .index_of(name)
                .ok_or_else(|| NnError::Kinematic(format!("{what}: the skeleton has no joint {name:?}")))?;
            if !(factor.is_finite() && *factor >= 0.0) {
                return Err(NnError::Kinematic(format!("{what}: factor {factor} for {name:?}")));
            }
            start[j] = *factor;
        }
        Ok(start)
    }

    /// The solver of [`KinematicSolver::refine`]'s first pass: each joint's pull scaled by its
    /// [`KinematicSolver::bias_pass_factors`] (a copy of this one where there are none).
    fn for_bias_pass(&self) -> Result<KinematicSolver, NnError> {
        let weights: Vec<f64> = self
            .model
            .prior_weights()
            .iter()
            .zip(self.bias_pass_factors.iter().chain(std::iter::repeat(&1.0)))
            .map(|(w, f)| w * f)
            .collect();
        let mut solver = self.clone();
        solver.model = solver.model.with_prior_weights(weights).map_err(config_error)?;
        Ok(solver)
    }

    /// The same solver with the network's pose in [`KinematicSolver::refine`] holding each named
    /// joint `factor` times [`KinematicSolver::refine_prior`] (the others keep their factor: 1,
    /// or on the CMU body solver the spine's [`BODY_SPINE_REFINE_FACTOR`] and the head's
    /// [`BODY_HEAD_REFINE_FACTOR`]).
    ///
    /// # Errors
    /// A joint the skeleton lacks, or a factor that is negative or not finite.
    pub fn with_refine_prior_factors(mut self, factors: &[(&str, f64)]) -> Result<KinematicSolver, NnError> {
        let weights = self.named_factors(self.model.prior_weights().to_vec(), factors, "refine prior")?;
        self.model = self.model.with_prior_weights(weights).map_err(config_error)?;
        Ok(self)
    }

    /// The same solver with its joint centres left to the markers alone: the template's bone
    /// lengths scaled, no pull towards the markers' mean, in the calibration or in any frame.
    pub fn without_joint_centres(mut self) -> KinematicSolver {
        self.config.joint_centre_weight = 0.0;
        self.config.ik.centre = 0.0;
        self
    }

    /// The same solver with joints that lie at the mean of markers around them, by name: the
    /// subject calibration fits the bone lengths to put them there ([`JointCentre`]).
    ///
    /// # Errors
    /// A joint the skeleton lacks or a marker the layout lacks.
    pub fn with_joint_centres(mut self, centres: &[(&str, &[&str])]) -> Result<KinematicSolver, NnError> {
        let mut found = Vec::with_capacity(centres.len());
        for (joint, markers) in centres {
            let j = self
                .model
                .skeleton()
                .index_of(joint)
                .ok_or_else(|| NnError::Kinematic(format!("joint centre {joint:?}: no such joint")))?;
            let markers = markers
                .iter()
                .map(|m| {
                    self.markers
                        .iter()
                        .position(|n| n == m)
                        .ok_or_else(|| NnError::Kinematic(format!("joint centre {joint:?}: no marker {m:?}")))
                })
                .collect::<Result<Vec<usize>, NnError>>()?;
            found.push(JointCentre { joint: j, markers });
        }
        self.model = self.model.with_joint_centres(found).map_err(config_error)?;
        Ok(self)
    }

    /// The layout's marker names, model order.
    pub fn markers(&self) -> &[String] {
        &self.markers
    }

    /// The template skeleton (before a take's calibration).
    pub fn skeleton(&self) -> &Skeleton {
        self.model.skeleton()
    }

    /// Per joint: the solver turns it (not welded by its degrees of freedom).
    pub fn rotating(&self) -> Vec<bool> {
        self.model.rotating()
    }

    /// Per joint: the markers constrain its rotation (a marker rides on it or below it).
    pub fn constrained(&self) -> &[bool] {
        &self.constrained
    }

    /// True when `take` carries at least half of the layout's markers (by label): enough to
    /// pose every limb the others leave free only through the joint limits and rest prior.
    pub fn fits(&self, take: &Take) -> bool {
        let found = self.markers.iter().filter(|m| take.marker_index(m).is_some()).count();
        found * 2 >= self.markers.len() && found >= 3
    }

    /// True when this solver can refine `network`'s answers ([`KinematicSolver::refine`]):
    /// every joint of its skeleton is one of the network's, by name. (A joint the network
    /// lacks would be held at its rest orientation.)
    pub fn refines(&self, network: &crate::solver::Solver) -> bool {
        self.model.skeleton().joints().iter().all(|j| network.meta.skeleton.index_of(&j.name).is_some())
    }

    /// The whole pipeline on a raw take: cleaned as `locap clean` does (swaps and outliers;
    /// gaps filled by `filler`, for the cleaned markers only), then solved
    /// ([`KinematicSolver::solve_cleaned`]).
    ///
    /// # Errors
    /// As [`KinematicSolver::solve_cleaned`], or the filler cannot run on the take.
    pub fn solve(&self, take: &Take, filler: &dyn Filler) -> Result<(Motion, Cleaned, KinematicReport), NnError> {
        if !self.fits(take) {
            return Err(self.marker_set_error(take));
        }
        let cleaned = locap_clean::clean_with(take, &CleanConfig::default(), filler)?;
        let (motion, report) = self.solve_cleaned(&cleaned, take.frame_rate_hz())?;
        Ok((motion, cleaned, report))
    }

    fn marker_set_error(&self, take: &Take) -> NnError {
        let missing: Vec<&str> =
            self.markers.iter().filter(|m| take.marker_index(m).is_none()).map(String::as_str).collect();
        NnError::MarkerSet {
            missing: missing.len(),
            total: self.markers.len(),
            first: missing.iter().take(5).copied().collect::<Vec<_>>().join(", "),
        }
    }

    /// Per frame, each layout marker's captured sample in `cleaned` (lab frame, mm; `None`:
    /// not in the take, missing or an outlier): what [`KinematicSolver::solve_cleaned`] fits.
    pub fn observed_frames(&self, cleaned: &Cleaned) -> Vec<Vec<Option<Vec3>>> {
        let take = cleaned.take();
        let order: Vec<Option<usize>> = self.markers.iter().map(|m| take.marker_index(m)).collect();
        let m = take.marker_count();
        (0..take.frame_count())
            .map(|f| {
                order
                    .iter()
                    .map(|k| {
                        let k = (*k)?;
                        if cleaned.visible.get(f * m + k).copied().unwrap_or(false) {
                            take.position_mm(f, k)
                        } else {
                            None
                        }
                    })
                    .collect()
            })
            .collect()
    }

    /// The template marker model in a lab with `up` axis (a Z-up lab sees the Y-up skeleton
    /// turned by the lab convention).
    pub fn lab_model(&self, up: UpAxis) -> MarkerModel {
        match up {
            UpAxis::Z => self.model.clone().in_lab(MarkerModel::y_up_in_z_up_lab()),
            UpAxis::Y => self.model.clone(),
        }
    }

    /// Solves a cleaned take: its captured samples of the layout's markers (lab frame; a
    /// Z-up take is the Y-up skeleton turned by the lab convention), at `rate_hz`. Returns the
    /// motion on the subject's calibrated skeleton, in the skeleton's Y-up frame.
    ///
    /// # Errors
    /// The take carries fewer than half of the layout's markers, or no frames.
    pub fn solve_cleaned(&self, cleaned: &Cleaned, rate_hz: f64) -> Result<(Motion, KinematicReport), NnError> {
        let take = cleaned.take();
        if !self.fits(take) {
            return Err(self.marker_set_error(take));
        }
        if take.frame_count() == 0 {
            return Err(NnError::EmptyTake);
        }
        self.solve_frames(cleaned, rate_hz, None)
    }

    /// [`KinematicSolver::solve_cleaned`] with every frame pulled towards `prior`'s joint
    /// rotations (joints matched by name; [`KinematicSolver::refine_prior`] the pull; each averaged
    /// over [`KinematicSolver::prior_half_window_s`] on each side): another
    /// solver's answer (a network's) refined by the markers. The network knows how people
    /// move where the markers say little (twists, fingers); the fit puts the joints where the
    /// markers are. A joint `prior` lacks is pulled towards its rest orientation as hard. The
    /// CMU body solver first moves its template skeleton towards `prior`'s
    /// ([`KinematicSolver::network_skeleton`]).
    ///
    /// # Errors
    /// As [`KinematicSolver::solve_cleaned`], or `prior` has another frame count.
    pub fn refine(
        &self,
        cleaned: &Cleaned,
        rate_hz: f64,
        prior: &Motion,
    ) -> Result<(Motion, KinematicReport), NnError> {
        let frames = cleaned.take().frame_count();
        if prior.frame_count() != frames {
            return Err(NnError::Kinematic(format!(
                "the motion to refine has {} frames, the take {frames}",
                prior.frame_count()
            )));
        }
        if let (true, Some(rotating)) = (self.network_skeleton > 0.0, &self.cmu_rotating) {
            return self.on_skeleton_towards(&prior.skeleton, rotating)?.refine(cleaned, rate_hz, prior);
        }
        let joints = self.model.skeleton().joints();
        let from: Vec<Option<usize>> = joints.iter().map(|j| prior.skeleton.index_of(&j.name)).collect();
        let poses: Vec<Vec<Quat>> = (0..frames)
            .map(|f| {
                let local = prior.local_rotations(f);
                from.iter().map(|k| k.map_or_else(Quat::identity, |k| local[k])).collect()
            })
            .collect();
        let half = (self.prior_half_window_s * rate_hz).round();
        let poses = if half >= 1.0 { mean_rotations(&poses, half as usize) } else { poses };
        if !(self.bias_huber_deg > 0.0) {
            return self.solve_frames(cleaned, rate_hz, Some(&poses));
        }
        let (first, first_report) = self.for_bias_pass()?.solve_frames(cleaned, rate_hz, Some(&poses))?;
        let fitted: Vec<&[Quat]> = (0..frames).map(|f| first.local_rotations(f)).collect();
        let half = (self.bias_half_window_s * rate_hz).round().max(0.0) as usize;
        let corrected = without_bias(&poses, &fitted, half, self.bias_huber_deg.to_radians());
        let (motion, mut report) = self.solve_frames(cleaned, rate_hz, Some(&corrected))?;
        report.seconds += first_report.seconds;
        Ok((motion, report))
    }

    /// The CMU body solver built again on its template with each bone offset moved
    /// [`KinematicSolver::network_skeleton`] of the way to `target`'s (joints matched by name;
    /// one `target` lacks keeps the template's), with this solver's settings.
    fn on_skeleton_towards(&self, target: &Skeleton, rotating: &[bool]) -> Result<KinematicSolver, NnError> {
        let w = self.network_skeleton.clamp(0.0, 1.0);
        let skeleton = bones_towards(self.model.skeleton(), target, w, |name| target.index_of(name))?;
        let mut solver = KinematicSolver::cmu41_on(&skeleton, rotating)?;
        solver.config = self.config;
        solver.refine_prior = self.refine_prior;
        solver.prior_half_window_s = self.prior_half_window_s;
        solver.network_skeleton = 0.0;
        solver.bias_huber_deg = self.bias_huber_deg;
        solver.bias_half_window_s = self.bias_half_window_s;
        solver.bias_pass_factors = self.bias_pass_factors.clone();
        solver.model = solver
            .model
            .with_prior_weights(self.model.prior_weights().to_vec())
            .and_then(|m| m.with_landmarks(self.model.landmarks().to_vec()))
            .map_err(config_error)?;
        Ok(solver)
    }

    fn solve_frames(
        &self,
        cleaned: &Cleaned,
        rate_hz: f64,
        prior: Option<&[Vec<Quat>]>,
    ) -> Result<(Motion, KinematicReport), NnError> {
        let take = cleaned.take();
        if !self.fits(take) {
            return Err(self.marker_set_error(take));
        }
        if take.frame_count() == 0 {
            return Err(NnError::EmptyTake);
        }
        let started = std::time::Instant::now();
        let frames = self.observed_frames(cleaned);
        let model = self.lab_model(take.up_axis);
        let mut config = self.config;
        if prior.is_some() {
            config.ik.prior = self.refine_prior;
        }
        let fit = solve_sequence_with_prior(model, &frames, rate_hz, &config, prior).map_err(config_error)?;
        let rms = fit.rms_mm(&frames);
        let skeleton = fit.model.skeleton().clone();
        let rotations = fit.poses.iter().flat_map(|(local, _)| local.iter().copied()).collect();
        let roots = fit.poses.iter().map(|(_, root)| *root).collect();
        let motion = Motion::new(skeleton, rotations, roots, rate_hz).map_err(NnError::Skeleton)?;
        let report = KinematicReport {
            frames: take.frame_count(),
            seconds: started.elapsed().as_secs_f64(),
            residual_rms_mm: rms,
            calibration_rms_mm: fit.calibration_rms_mm,
            scale: fit.scale,
        };
        Ok((motion, report))
    }
}

/// `prior` turned, per joint and frame, by the part beyond `limit_rad` of its average rotation
/// (over `half` frames each side) to `fitted`: the bias of the prior that the markers showed,
/// less what may be the markers' own noise ([`KinematicSolver::bias_huber_deg`]).
fn without_bias(prior: &[Vec<Quat>], fitted: &[&[Quat]], half: usize, limit_rad: f64) -> Vec<Vec<Quat>> {
    let away: Vec<Vec<Quat>> =
        prior.iter().zip(fitted).map(|(p, r)| p.iter().zip(r.iter()).map(|(p, r)| p.inverse() * r).collect()).collect();
    let bias = mean_rotations(&away, half);
    prior
        .iter()
        .zip(&bias)
        .map(|(pose, bias)| {
            pose.iter()
                .zip(bias)
                .map(|(p, b)| {
                    let v = b.scaled_axis();
                    let angle = v.norm();
                    if angle > limit_rad { p * Quat::from_scaled_axis(v * ((angle - limit_rad) / angle)) } else { *p }
                })
                .collect()
        })
        .collect()
}

/// Each joint's rotation averaged over `half` frames on each side, fewer at the take's ends
/// (the quaternions turned to the centre frame's hemisphere, summed and normalised: the
/// chordal mean, close to the rotation mean for rotations this close together).
fn mean_rotations(poses: &[Vec<Quat>], half: usize) -> Vec<Vec<Quat>> {
    let n = poses.len();
    (0..n)
        .map(|f| {
            let (lo, hi) = (f.saturating_sub(half), (f + half + 1).min(n));
            (0..poses[f].len())
                .map(|j| {
                    let centre = poses[f][j].coords;
                    let mut sum = nalgebra::Vector4::zeros();
                    for pose in &poses[lo..hi] {
                        let q = pose[j].coords;
                        sum += if q.dot(&centre) < 0.0 { -q } else { q };
                    }
                    Quat::from_quaternion(nalgebra::Quaternion::from(sum))
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The prior's window averages a frame-to-frame flicker away, follows a steady turn, and
    /// keeps a rotation whose quaternion changes sign from frame to frame (the same rotation).
    #[test]
    fn the_prior_window_averages_a_flicker_and_follows_a_turn() {
        let axis = Vec3::y_axis();
        let flicker: Vec<Vec<Quat>> = (0..40)
            .map(|f| {
                let q = Quat::from_axis_angle(&axis, 0.5 + if f % 2 == 0 { 0.2 } else { -0.2 });
                // Every third frame the same rotation as its negated quaternion.
                vec![if f % 3 == 0 { Quat::new_unchecked(-q.into_inner()) } else { q }]
            })
            .collect();
        let mean = mean_rotations(&flicker, 5);
        for pose in &mean[5..35] {
            assert!(pose[0].angle_to(&Quat::from_axis_angle(&axis, 0.5)) < 0.03, "{pose:?}");
        }
        let turn: Vec<Vec<Quat>> = (0..40).map(|f| vec![Quat::from_axis_angle(&axis, 0.01 * f as f64)]).collect();
        let mean = mean_rotations(&turn, 5);
        for (f, pose) in mean.iter().enumerate().take(35).skip(5) {
            assert!(pose[0].angle_to(&turn[f][0]) < 1e-6, "frame {f}");
        }
        // At the ends the window is cut: the first frame is the mean of the first six.
        assert!(mean[0][0].angle_to(&Quat::from_axis_angle(&axis, 0.025)) < 1e-4);
    }

    /// A prior persistently turned away from the fit is corrected by the excess over the limit;
    /// one within the limit, or off in a single frame only, is left alone.
    #[test]
    fn the_second_pass_removes_the_priors_persistent_bias_beyond_the_limit() {
        let axis = Vec3::z_axis();
        let frames = 41;
        let prior: Vec<Vec<Quat>> = (0..frames)
            .map(|f| vec![Quat::from_axis_angle(&axis, 0.01 * f as f64), Quat::identity(), Quat::identity()])
            .collect();
        // Joint 0 fitted 20 degrees further throughout; joint 1 3 degrees; joint 2 30 degrees in
        // frame 20 alone.
        let fitted: Vec<Vec<Quat>> = prior
            .iter()
            .enumerate()
            .map(|(f, p)| {
                let spike = if f == 20 { 30f64.to_radians() } else { 0.0 };
                vec![
                    p[0] * Quat::from_axis_angle(&axis, 20f64.to_radians()),
                    p[1] * Quat::from_axis_angle(&axis, 3f64.to_radians()),
                    p[2] * Quat::from_axis_angle(&axis, spike),
                ]
            })
            .collect();
        let fitted: Vec<&[Quat]> = fitted.iter().map(Vec::as_slice).collect();
        let corrected = without_bias(&prior, &fitted, 12, 5f64.to_radians());
        for f in 0..frames {
            let turned = |j: usize| (prior[f][j].inverse() * corrected[f][j]).angle().to_degrees();
            assert!((turned(0) - 15.0).abs() < 1e-9, "frame {f}: {}", turned(0));
            assert!(turned(1) < 1e-9);
            // The spike averages to 30 / 25 = 1.2 degrees at most: within the limit.
            assert!(turned(2) < 1e-9, "frame {f}: {}", turned(2));
        }
    }

    /// The refinement's skeleton moves the asked share of the way from the template to the
    /// network's, joint by joint; a joint the network lacks keeps the template's offset, and
    /// the solver keeps its settings.
    #[test]
    fn the_network_skeleton_moves_each_bone_its_share_of_the_way() {
        // A factor of the user's besides the spine's, to be carried over too.
        let mut solver = KinematicSolver::cmu41().unwrap().with_refine_prior_factors(&[("lhand", 0.1)]).unwrap();
        solver.refine_prior = 7.0;
        solver.network_skeleton = 0.25;
        solver.config.ik.prior_huber_deg = 5.0;
        let template = solver.skeleton().clone();
        let femur = template.index_of("lfemur").unwrap();
        let tibia = template.index_of("ltibia").unwrap();
        // The network's skeleton: the left femur 40 mm longer along x; no left tibia.
        let mut joints = template.joints().to_vec();
        joints[femur].offset_mm += Vec3::new(40.0, 0.0, 0.0);
        joints[tibia].name = "other".into();
        let network = Skeleton::new(joints).unwrap();
        let rotating = solver.cmu_rotating.clone().unwrap();
        let moved = solver.on_skeleton_towards(&network, &rotating).unwrap();
        let offset = |s: &KinematicSolver, j: usize| s.skeleton().joints()[j].offset_mm;
        assert!((offset(&moved, femur) - offset(&solver, femur) - Vec3::new(10.0, 0.0, 0.0)).norm() < 1e-9);
        assert_eq!(offset(&moved, tibia), offset(&solver, tibia));
        let other = template.index_of("rfemur").unwrap();
        assert!((offset(&moved, other) - offset(&solver, other)).norm() < 1e-9);
        assert_eq!((moved.refine_prior, moved.network_skeleton), (7.0, 0.0));
        assert_eq!(moved.config.ik.prior_huber_deg, 5.0);
        assert_eq!((moved.bias_huber_deg, moved.bias_half_window_s), (BODY_BIAS_HUBER_DEG, BODY_BIAS_HALF_WINDOW_S));
        assert_eq!(moved.rotating(), solver.rotating());
        // The spine's harder pull moves with it.
        let weights = moved.model.prior_weights();
        assert_eq!(weights, solver.model.prior_weights());
        for (j, joint) in template.joints().iter().enumerate() {
            let expected = match joint.name.as_str() {
                "lhand" => 0.1,
                name if BODY_SPINE.contains(&name) => BODY_SPINE_REFINE_FACTOR,
                "head" => BODY_HEAD_REFINE_FACTOR,
                _ => 1.0,
            };
            assert_eq!(weights[j], expected, "{}", joint.name);
        }
        assert!(solver.clone().with_refine_prior_factors(&[("nowhere", 2.0)]).is_err());
        assert!(solver.clone().with_refine_prior_factors(&[("lhand", -2.0)]).is_err());
        // So does the hands' lighter pull in the first pass, scaling the second pass's weights.
        assert_eq!(moved.bias_pass_factors, solver.bias_pass_factors);
        let first = moved.for_bias_pass().unwrap();
        for (j, joint) in template.joints().iter().enumerate() {
            let factor = if BODY_HANDS.contains(&joint.name.as_str()) { BODY_HANDS_BIAS_PASS_FACTOR } else { 1.0 };
            assert_eq!(first.model.prior_weights()[j], weights[j] * factor, "{}", joint.name);
        }
        assert!(solver.clone().with_bias_pass_factors(&[("nowhere", 0.5)]).is_err());
        assert!(solver.clone().with_bias_pass_factors(&[("rhand", f64::NAN)]).is_err());
        // Solvers not built as the CMU body solver have nothing to rebuild: not moved.
        let layout = Layout::from_toml(include_str!("../../synth/layouts/hand-left.toml")).unwrap();
        assert!(KinematicSolver::from_layout(&layout).unwrap().cmu_rotating.is_none());
    }

    /// A layout's skeleton sets the solver's smoothness weight; without one the default holds.
    #[test]
    fn a_layouts_smoothness_weight_is_the_solvers() {
        let shipped = include_str!("../../synth/layouts/hand-left.toml");
        let layout = Layout::from_toml(shipped).unwrap();
        let solver = KinematicSolver::from_layout(&layout).unwrap();
        assert_eq!(solver.config.ik.smooth, locap_synth::hand::HAND_SMOOTHNESS);
        let mut plain = layout.clone();
        plain.skeleton.as_mut().unwrap().smoothness = None;
        let solver = KinematicSolver::from_layout(&plain).unwrap();
        assert_eq!(solver.config.ik.smooth, SequenceConfig::default().ik.smooth);
        assert_ne!(solver.config.ik.smooth, locap_synth::hand::HAND_SMOOTHNESS);
    }
}
