//! Hand skeletons, hand motion and the hand marker layout (LocalMoCap section 4: the paper
//! takes finger motion from GRAB; no open finger-joint motion exists in locap's data, so it is
//! built here).
//!
//! # The data
//! `hands/ART-Human_hands_real_no6dof.c3d` (c3d.org sample, ART system, 60 Hz, 969 frames) is
//! not a marker capture: ART's hand tracking exports *joint positions* of its hand model, per
//! hand the wrist (`LHAN`) and four points per finger: thumb `TIN` (carpometacarpal), `TMI`
//! (metacarpophalangeal), `TOU` (interphalangeal), `TTI` (tip); other fingers `xFI`, `xFM`,
//! `xFO`, `xFT` (index `I`, middle `M`, ring `R`; pinky `PIN`, `PMI`, `POU`, `PTI`): the
//! knuckle, the two interphalangeal joints and the tip. Bone lengths in it are constant to
//! 0-2 mm, so it is a solved skeleton, which is exactly what a joint-angle fit needs.
//!
//! # Skeleton and fit ([`fit_art_hand`])
//! One skeleton per hand: root `LHand` at the wrist; per finger three joints and an end site
//! (`LIndex1` knuckle, `LIndex2`, `LIndex3`, `LIndex3_End` tip, the name a BVH reader gives the
//! end site). The hand frame is built per frame from the wrist and the knuckles: `x` from the
//! wrist to the middle knuckle, `y` the back of the hand (the side the fingertips curl away
//! from, decided from the data), `z = x cross y`. At rest (identity rotations) the four fingers are straight along `x`, the
//! knuckles where the capture puts them on average, and the thumb in its average pose. Each
//! joint's local rotation is the smallest rotation turning its rest bone onto the captured
//! bone (swing; the twist about a bone is not observable from joint positions and stays 0).
//! The fit is exact up to the capture's own bone-length noise, which the reported residual
//! shows.
//!
//! # Procedural motion ([`procedural_fingers`])
//! New finger motion on a real wrist trajectory: a smooth random grip (0 = open, 1 = fist)
//! shared by the fingers, plus smooth per-finger deviations, mapped into anatomical limits
//! (degrees from straight): knuckle flexion -10..90 and abduction +-15 (less when the hand
//! closes), proximal interphalangeal 0..105, distal 2/3 of it (the tendon coupling of real
//! fingers); the thumb moves +-25 degrees around its captured average pose.
//!
//! # Layout ([`hand_layout`])
//! The paper's hand set: wrist `IWR`/`OWR` (thumb and little-finger side), back of the hand
//! `IHAND`/`OHAND` (behind the index and little-finger knuckles) and two markers per finger,
//! `3` on the proximal and `6` on the distal phalanx (the naming of the paper's released
//! finger statistics, `LTHM3`, `LIDX6`, ...), all on the back of the hand.

use crate::layout::{Dof, Follow, Layout, LayoutJoint, LayoutMarker, LayoutSkeleton, Region};
use locap_core::{EulerOrder, Joint, Motion, Quat, Skeleton, SkeletonError, Take, UpAxis, Vec3};
use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};

/// Which hand.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// Left hand.
    Left,
    /// Right hand.
    Right,
}

impl Side {
    /// `L` or `R`.
    pub fn letter(self) -> &'static str {
        match self {
            Side::Left => "L",
            Side::Right => "R",
        }
    }

    fn region(self) -> Region {
        match self {
            Side::Left => Region::LeftHand,
            Side::Right => Region::RightHand,
        }
    }
}

/// Finger names in skeleton order, with their ART point suffixes (base, middle, outer, tip)
/// and marker prefixes.
const FINGERS: [(&str, [&str; 4], &str); 5] = [
    ("Thumb", ["TIN", "TMI", "TOU", "TTI"], "THM"),
    ("Index", ["IFI", "IFM", "IFO", "IFT"], "IDX"),
    ("Middle", ["MFI", "MFM", "MFO", "MFT"], "MID"),
    ("Ring", ["RFI", "RFM", "RFO", "RFT"], "RNG"),
    ("Pinky", ["PIN", "PMI", "POU", "PTI"], "PNK"),
];

/// Errors of the hand tools.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum HandError {
    /// The take lacks a point the fit needs.
    #[error("the take has no point {0:?} (an ART-Human hand export names its wrist xHAN and finger points like xIFI)")]
    MissingPoint(String),
    /// No frame has every point.
    #[error("no frame has every hand point of the {0:?} hand")]
    NoCompleteFrame(Side),
    /// Building the skeleton or motion failed.
    #[error(transparent)]
    Skeleton(#[from] SkeletonError),
    /// More procedural takes asked for than [`MAX_PROCEDURAL_TAKES`].
    #[error("{0} procedural takes per hand asked for (at most {MAX_PROCEDURAL_TAKES})")]
    TooManyTakes(usize),
}

/// Most procedural takes per hand and export (1,000: each is a full-length copy of the
/// captured wrist motion, so 1,000 takes of a one-minute 60 Hz export are 3.6 M frames of
/// training data, more than a hand network needs; a million would run for days).
pub const MAX_PROCEDURAL_TAKES: usize = 1000;

/// Checks a count of procedural takes before any is made.
///
/// # Errors
/// [`HandError::TooManyTakes`] above [`MAX_PROCEDURAL_TAKES`].
pub fn check_procedural_count(takes: usize) -> Result<(), HandError> {
    if takes > MAX_PROCEDURAL_TAKES { Err(HandError::TooManyTakes(takes)) } else { Ok(()) }
}

/// How well [`fit_art_hand`] reproduces the captured points.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HandFitReport {
    /// Which hand.
    pub side: Side,
    /// Frames fitted (frames missing a point repeat the previous pose).
    pub frames: usize,
    /// RMS distance between FK joint positions and the captured points, mm.
    pub rms_mm: f64,
    /// Largest such distance, mm.
    pub max_mm: f64,
    /// Fitted flexion range per finger joint (min, max), degrees from straight, for the four
    /// fingers' knuckle, middle and distal joints (index, middle, ring, pinky).
    pub flexion_range_deg: Vec<(String, f64, f64)>,
}

/// Per frame hand frame (rotation) from wrist and knuckles, with `y` pointing to the back of
/// the hand when `dorsal_sign` is 1.
fn hand_rotation(wrist: Vec3, index: Vec3, middle: Vec3, pinky: Vec3, dorsal_sign: f64) -> Option<Quat> {
    let x = (middle - wrist).try_normalize(1e-9)?;
    let lateral = index - pinky;
    let y = (x.cross(&lateral) * dorsal_sign).try_normalize(1e-9)?;
    let z = x.cross(&y);
    let m = nalgebra::Matrix3::from_columns(&[x, y, z]);
    Some(Quat::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(m)))
}

fn point(take: &Take, side: Side, suffix: &str) -> Result<usize, HandError> {
    let name = format!("{}{suffix}", side.letter());
    take.marker_index(&name).ok_or(HandError::MissingPoint(name))
}

/// The smallest rotation taking direction `from` onto `to` (identity for degenerate input).
fn swing(from: Vec3, to: Vec3) -> Quat {
    Quat::rotation_between(&from, &to).unwrap_or_else(|| {
        // Opposite vectors: half a turn about any perpendicular axis.
        let axis = from.cross(&Vec3::x()).try_normalize(1e-9).unwrap_or_else(Vec3::y);
        Quat::from_axis_angle(&nalgebra::Unit::new_normalize(axis), std::f64::consts::PI)
    })
}

/// Fits a hand skeleton and its joint angles to an ART-Human hand export (see the module
/// docs). Positions stay in the take's frame.
pub fn fit_art_hand(take: &Take, side: Side) -> Result<(Motion, HandFitReport), HandError> {
    let wrist = point(take, side, "HAN")?;
    let chains: Vec<[usize; 4]> = FINGERS
        .iter()
        .map(|(_, suffixes, _)| {
            let mut idx = [0; 4];
            for (k, s) in suffixes.iter().enumerate() {
                idx[k] = point(take, side, s)?;
            }
            Ok(idx)
        })
        .collect::<Result<_, HandError>>()?;
    let frames = take.frame_count();
    // Frames with every point.
    let all: Vec<usize> = std::iter::once(wrist).chain(chains.iter().flatten().copied()).collect();
    let complete: Vec<usize> = (0..frames).filter(|f| all.iter().all(|m| take.is_valid(*f, *m))).collect();
    if complete.is_empty() {
        return Err(HandError::NoCompleteFrame(side));
    }
    let p = |f: usize, m: usize| take.position_mm(f, m).unwrap_or_default();
    let frame_of = |f: usize, sign: f64| {
        hand_rotation(p(f, wrist), p(f, chains[1][0]), p(f, chains[2][0]), p(f, chains[4][0]), sign)
    };
    // The back of the hand is where the fingertips do not curl to: with y = x cross lateral,
    // the mean of (tip - knuckle) . y decides the sign.
    let mut curl = 0.0;
    for &f in &complete {
        if let Some(q) = frame_of(f, 1.0) {
            for c in &chains[1..] {
                curl += (q.inverse() * (p(f, c[3]) - p(f, c[0]))).y;
            }
        }
    }
    let dorsal = if curl > 0.0 { -1.0 } else { 1.0 };
    // Rest skeleton: mean knuckle positions and bone lengths in the hand frame; fingers
    // straight along x, the thumb in its mean pose.
    let mut base = [Vec3::zeros(); 5];
    let mut length = [[0.0; 3]; 5];
    let mut thumb_dir = [Vec3::zeros(); 3];
    let mut n: f64 = 0.0;
    for &f in &complete {
        let Some(q) = frame_of(f, dorsal) else { continue };
        n += 1.0;
        for (k, c) in chains.iter().enumerate() {
            base[k] += q.inverse() * (p(f, c[0]) - p(f, wrist));
            for b in 0..3 {
                let v = p(f, c[b + 1]) - p(f, c[b]);
                length[k][b] += v.norm();
                if k == 0 {
                    thumb_dir[b] += (q.inverse() * v).normalize();
                }
            }
        }
    }
    let n = n.max(1.0);
    let prefix = side.letter();
    let mut joints = vec![Joint {
        name: format!("{prefix}Hand"),
        parent: None,
        offset_mm: Vec3::zeros(),
        rotation_order: EulerOrder::ZXY,
        is_end_site: false,
    }];
    // rest_dir[k][b]: rest direction of bone b of finger k (in every rest frame).
    let mut rest_dir = [[Vec3::x(); 3]; 5];
    for b in 0..3 {
        rest_dir[0][b] = thumb_dir[b].try_normalize(1e-9).unwrap_or_else(Vec3::x);
    }
    for (k, (finger, _, _)) in FINGERS.iter().enumerate() {
        let first = joints.len();
        joints.push(Joint {
            name: format!("{prefix}{finger}1"),
            parent: Some(0),
            offset_mm: base[k] / n,
            rotation_order: EulerOrder::ZXY,
            is_end_site: false,
        });
        for b in 0..3 {
            joints.push(Joint {
                name: if b == 2 { format!("{prefix}{finger}3_End") } else { format!("{prefix}{finger}{}", b + 2) },
                parent: Some(first + b),
                offset_mm: rest_dir[k][b] * (length[k][b] / n),
                rotation_order: EulerOrder::ZXY,
                is_end_site: b == 2,
            });
        }
    }
    let skeleton = Skeleton::new(joints)?;
    // Angles per frame; a frame missing a point repeats the previous pose (the first complete
    // pose before it).
    let j = skeleton.len();
    let pose_at = |f: usize| -> Option<(Vec<Quat>, Vec3)> {
        if !all.iter().all(|m| take.is_valid(f, *m)) {
            return None;
        }
        let hand = frame_of(f, dorsal)?;
        let mut local = vec![Quat::identity(); j];
        local[0] = hand;
        for (k, c) in chains.iter().enumerate() {
            let mut parent = hand;
            for b in 0..3 {
                let joint = 1 + 4 * k + b;
                let seen = parent.inverse() * (p(f, c[b + 1]) - p(f, c[b]));
                local[joint] = swing(rest_dir[k][b], seen);
                parent *= local[joint];
            }
        }
        Some((local, p(f, wrist)))
    };
    let mut last = complete.iter().find_map(|&f| pose_at(f)).ok_or(HandError::NoCompleteFrame(side))?;
    let mut rotations = Vec::with_capacity(frames * j);
    let mut root = Vec::with_capacity(frames);
    for f in 0..frames {
        if let Some(pose) = pose_at(f) {
            last = pose;
        }
        rotations.extend_from_slice(&last.0);
        root.push(last.1);
    }
    let motion = Motion::new(skeleton, rotations, root, take.frame_rate_hz())?;
    // Residual and angle ranges.
    let (mut sum, mut count, mut max) = (0.0, 0usize, 0.0f64);
    let mut ranges: Vec<(String, f64, f64)> = Vec::new();
    for (finger, _, _) in FINGERS.iter().skip(1) {
        for b in 0..3 {
            ranges.push((format!("{prefix}{finger}{}", b + 1), f64::INFINITY, f64::NEG_INFINITY));
        }
    }
    for &f in &complete {
        let pose = motion.forward_kinematics(f);
        for (k, c) in chains.iter().enumerate() {
            for (b, point) in c.iter().enumerate() {
                let d = (pose.positions_mm[1 + 4 * k + b] - p(f, *point)).norm();
                sum += d * d;
                count += 1;
                max = max.max(d);
            }
            if k > 0 {
                for b in 0..3 {
                    let angle = flexion_deg(motion.local_rotations(f)[1 + 4 * k + b]);
                    let r = &mut ranges[3 * (k - 1) + b];
                    r.1 = r.1.min(angle);
                    r.2 = r.2.max(angle);
                }
            }
        }
    }
    let report = HandFitReport {
        side,
        frames: complete.len(),
        rms_mm: (sum / count.max(1) as f64).sqrt(),
        max_mm: max,
        flexion_range_deg: ranges,
    };
    Ok((motion, report))
}

/// Flexion of a finger joint's local rotation, degrees: how far it turns the bone from `x`
/// towards the palm (`-y`).
pub fn flexion_deg(local: Quat) -> f64 {
    let d = local * Vec3::x();
    (-d.y).atan2(d.x).to_degrees()
}

/// Anatomical limits of the procedural finger motion, degrees.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FingerLimits {
    /// Knuckle (MCP) flexion range.
    pub mcp_flexion_deg: [f64; 2],
    /// Knuckle abduction, +-.
    pub mcp_abduction_deg: f64,
    /// Proximal interphalangeal flexion range.
    pub pip_flexion_deg: [f64; 2],
    /// Distal interphalangeal flexion as a fraction of the proximal one.
    pub dip_coupling: f64,
    /// Thumb joints' range around the captured average pose, +-.
    pub thumb_range_deg: f64,
    /// Frequency band of the grip and finger motion, Hz.
    pub band_hz: [f64; 2],
}

impl Default for FingerLimits {
    fn default() -> Self {
        FingerLimits {
            mcp_flexion_deg: [-10.0, 90.0],
            mcp_abduction_deg: 15.0,
            pip_flexion_deg: [0.0, 105.0],
            dip_coupling: 2.0 / 3.0,
            thumb_range_deg: 25.0,
            band_hz: [0.1, 1.5],
        }
    }
}

/// A smooth random signal in `[0, 1]`: a sum of sinusoids in a frequency band, squashed.
struct Smooth {
    waves: Vec<(f64, f64, f64)>,
}

impl Smooth {
    fn new(band: [f64; 2], rng: &mut impl Rng) -> Smooth {
        let waves = (0..4)
            .map(|_| {
                let u: f64 = rng.random();
                let hz = band[0] * (band[1] / band[0]).powf(u);
                (0.5 + 0.5 * rng.random::<f64>(), hz, rng.random::<f64>() * std::f64::consts::TAU)
            })
            .collect();
        Smooth { waves }
    }

    fn at(&self, t_s: f64) -> f64 {
        let total: f64 = self.waves.iter().map(|w| w.0).sum();
        let v: f64 = self.waves.iter().map(|(a, hz, ph)| a * (std::f64::consts::TAU * hz * t_s + ph).sin()).sum();
        0.5 + 0.5 * (v / total * 1.6).tanh() / 1.6f64.tanh()
    }
}

/// New finger motion on the wrist trajectory of `base` (a motion of a skeleton from
/// [`fit_art_hand`]): the root and the thumb's average pose come from `base`, the fingers
/// from a smooth random grip within `limits` (see the module docs).
pub fn procedural_fingers(base: &Motion, limits: &FingerLimits, rng: &mut impl Rng) -> Result<Motion, HandError> {
    let skeleton = base.skeleton.clone();
    let j = skeleton.len();
    let frames = base.frame_count();
    let rate = base.frame_rate_hz();
    let grip = Smooth::new(limits.band_hz, rng);
    let fingers: Vec<[Smooth; 3]> = (0..4).map(|_| [0; 3].map(|_| Smooth::new(limits.band_hz, rng))).collect();
    let thumb: Vec<[Smooth; 2]> = (0..3).map(|_| [0; 2].map(|_| Smooth::new(limits.band_hz, rng))).collect();
    // The thumb's average local rotations in the base motion (its rest is the average pose,
    // so these are near identity; procedural motion varies around them).
    let lerp = |r: [f64; 2], u: f64| r[0] + (r[1] - r[0]) * u.clamp(0.0, 1.0);
    let mut rotations = Vec::with_capacity(frames * j);
    for f in 0..frames {
        let t = f as f64 / rate;
        let mut local = vec![Quat::identity(); j];
        local[0] = base.local_rotations(f)[0];
        let g = grip.at(t);
        for (k, s) in fingers.iter().enumerate() {
            let joint = 1 + 4 * (k + 1);
            let own = |i: usize| s[i].at(t) - 0.5;
            let mcp = lerp(limits.mcp_flexion_deg, g + 0.5 * own(0));
            let pip = lerp(limits.pip_flexion_deg, g + 0.5 * own(1));
            let abd = limits.mcp_abduction_deg * (1.0 - g) * 2.0 * own(2);
            let flex = |deg: f64| Quat::from_axis_angle(&Vec3::z_axis(), -deg.to_radians());
            // Flexion after abduction, so the flexion angle reads back exactly ([`flexion_deg`]).
            local[joint] = flex(mcp) * Quat::from_axis_angle(&Vec3::y_axis(), abd.to_radians());
            local[joint + 1] = flex(pip);
            local[joint + 2] = flex(limits.dip_coupling * pip);
        }
        for (b, s) in thumb.iter().enumerate() {
            let r = limits.thumb_range_deg.to_radians();
            let a = (2.0 * s[0].at(t) - 1.0) * r;
            let c = (2.0 * s[1].at(t) - 1.0) * r * (0.5 + 0.5 * g);
            local[1 + b] = Quat::from_axis_angle(&Vec3::y_axis(), a) * Quat::from_axis_angle(&Vec3::z_axis(), -c.abs());
        }
        rotations.extend_from_slice(&local);
    }
    let root = (0..frames).map(|f| base.root_position_mm(f)).collect();
    Ok(Motion::new(skeleton, rotations, root, rate)?)
}

/// The hand marker layout of the paper (see the module docs) on a hand skeleton from
/// [`fit_art_hand`]; offsets are on the back of the hand, `dorsal_mm` above the bones.
pub fn hand_layout(skeleton: &Skeleton, side: Side, dorsal_mm: f64) -> Result<Layout, HandError> {
    let s = side.letter();
    let joint = |name: String| skeleton.index_of(&name).ok_or(HandError::MissingPoint(name));
    let offset = |j: usize| skeleton.joints()[j].offset_mm;
    let index1 = offset(joint(format!("{s}Index1"))?);
    let pinky1 = offset(joint(format!("{s}Pinky1"))?);
    let lateral = (index1 - pinky1).try_normalize(1e-9).unwrap_or_else(Vec3::z);
    let up = Vec3::y() * dorsal_mm;
    let marker = |name: String, joint: String, o: Vec3| LayoutMarker {
        name,
        joint,
        offset_mm: [o.x, o.y, o.z].map(|c| (c * 10.0).round() / 10.0),
        region: side.region(),
        blend: None,
        soft_tissue: 0.5,
    };
    let hand = format!("{s}Hand");
    let mut markers = vec![
        marker(format!("{s}IWR"), hand.clone(), lateral * 25.0 + up - Vec3::x() * 10.0),
        marker(format!("{s}OWR"), hand.clone(), -lateral * 25.0 + up - Vec3::x() * 10.0),
        marker(format!("{s}IHAND"), hand.clone(), index1 + up - Vec3::x() * 15.0),
        marker(format!("{s}OHAND"), hand.clone(), pinky1 + up - Vec3::x() * 15.0),
    ];
    for (finger, _, short) in FINGERS {
        // Proximal phalanx: the bone from joint 2 for the thumb (joint 1 is its metacarpal),
        // from joint 1 for the others; distal phalanx: the bone from joint 3.
        let proximal = if finger == "Thumb" { 2 } else { 1 };
        for (bone, number, at) in [(proximal, 3, 0.5), (3, 6, 0.5)] {
            let j = joint(format!("{s}{finger}{bone}"))?;
            let child =
                joint(if bone == 3 { format!("{s}{finger}3_End") } else { format!("{s}{finger}{}", bone + 1) })?;
            markers.push(marker(
                format!("{s}{short}{number}"),
                skeleton.joints()[j].name.clone(),
                offset(child) * at + up * 0.7,
            ));
        }
    }
    Ok(Layout {
        name: format!("hand-{}", if side == Side::Left { "left" } else { "right" }),
        description: format!(
            "LocalMoCap hand set ({s}IWR/{s}OWR/{s}IHAND/{s}OHAND + 2 markers per finger) on a hand skeleton fitted to the ART-Human hand capture"
        ),
        aliases: Default::default(),
        markers,
        skeleton: Some(hand_skeleton(skeleton, &FingerLimits::default())),
    })
}

/// How far the joint ranges of [`hand_skeleton`] reach beyond [`FingerLimits`], degrees: a
/// real hand (the fitted ART capture) goes a little beyond the procedural motion's ranges.
pub const RANGE_MARGIN_DEG: f64 = 10.0;

/// The kinematic solver's smoothness weight for a hand ([`LayoutSkeleton::smoothness`]): the
/// body's 100 holds fingers that move further per frame (60 Hz) and whose markers weigh less
/// against a rotation. Of 1, 3, 10 and 100 on a validation set of procedural hand takes apart
/// from the test takes, 10 placed the joints best and turned them within 0.03 degrees of 3
/// (docs/benchmarks.md, "Kinematic hand solver").
pub const HAND_SMOOTHNESS: f64 = 10.0;

/// `skeleton` (from [`fit_art_hand`]) with each joint's rotational freedom, so a layout
/// carrying it solves with no training (`locap solve --method ik`): the root free; each
/// finger's knuckle flexion (about `z`, towards the palm is negative) and abduction (about
/// `y`), its two interphalangeal joints flexion only, within [`FingerLimits`] widened by
/// [`RANGE_MARGIN_DEG`]; the thumb's three joints about `y` and `z` within its range around
/// the rest pose; end sites without rotation; each finger's distal joint following its
/// proximal interphalangeal one by [`FingerLimits::dip_coupling`]. Twist about a bone is not a
/// freedom of any finger joint, as in the fit (swing only); the smoothness weight
/// [`HAND_SMOOTHNESS`].
pub fn hand_skeleton(skeleton: &Skeleton, limits: &FingerLimits) -> LayoutSkeleton {
    let m = RANGE_MARGIN_DEG;
    let dof = |name: &str, axis: [f64; 3], min_deg: f64, max_deg: f64| Dof {
        name: name.to_string(),
        axis,
        min_deg: min_deg - m,
        max_deg: max_deg + m,
    };
    let (y, z) = ([0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
    // Flexion of `deg` is a turn of `-deg` about `z` ([`procedural_fingers`]).
    let flexion = |range: [f64; 2]| dof("flexion", z, -range[1], -range[0]);
    let joints = skeleton.joints();
    let layout_joints = joints
        .iter()
        .map(|j| {
            // Names are `LHand`, `LIndex1`, ..., `LIndex3_End`: side letter, finger, bone.
            let bone = j.name.chars().last().and_then(|c| c.to_digit(10));
            let thumb = j.name.get(1..).is_some_and(|n| n.starts_with("Thumb"));
            let dofs = match (j.parent, bone) {
                (None, _) => None,
                (Some(_), None) => Some(Vec::new()),
                (Some(_), Some(_)) if thumb => {
                    let r = limits.thumb_range_deg;
                    Some(vec![dof("abduction", y, -r, r), dof("flexion", z, -r, 0.0)])
                }
                (Some(_), Some(1)) => Some(vec![
                    dof("abduction", y, -limits.mcp_abduction_deg, limits.mcp_abduction_deg),
                    flexion(limits.mcp_flexion_deg),
                ]),
                (Some(_), Some(2)) => Some(vec![flexion(limits.pip_flexion_deg)]),
                (Some(_), Some(_)) => Some(vec![flexion(limits.pip_flexion_deg.map(|d| d * limits.dip_coupling))]),
            };
            // The distal interphalangeal joint flexes with the proximal one (one tendon).
            let follows = match (bone, j.parent) {
                (Some(3), Some(p)) if !thumb => {
                    Some(Follow { joint: joints[p].name.clone(), ratio: limits.dip_coupling })
                }
                _ => None,
            };
            let o = j.offset_mm;
            LayoutJoint {
                name: j.name.clone(),
                parent: j.parent.map(|p| joints[p].name.clone()),
                offset_mm: [o.x, o.y, o.z],
                dofs,
                follows,
            }
        })
        .collect();
    LayoutSkeleton { up_axis: UpAxis::Y, smoothness: Some(HAND_SMOOTHNESS), joints: layout_joints }
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::MarkerName;
    use rand::SeedableRng;

    /// A synthetic ART-like export: the fitted skeleton's own FK points for a known motion
    /// are fitted back exactly.
    fn art_like(frames: usize) -> Take {
        let mut names = vec!["LHAN".to_string()];
        for (_, s, _) in FINGERS {
            names.extend(s.iter().map(|x| format!("L{x}")));
        }
        let mut samples = Vec::new();
        for f in 0..frames {
            let t = f as f64 / 60.0;
            let hand = EulerOrder::XYZ.to_quat_deg([20.0 * t, 30.0 * t.sin(), 10.0]);
            let wrist = Vec3::new(100.0 * t, 1000.0, 50.0);
            samples.push(Some(wrist));
            for (k, _) in FINGERS.iter().enumerate() {
                let lateral = (k as f64 - 2.0) * 20.0;
                let mut pos = wrist + hand * Vec3::new(if k == 0 { 20.0 } else { 80.0 }, 0.0, lateral);
                let mut rot = hand;
                samples.push(Some(pos));
                for (b, len) in [45.0, 27.0, 18.0].into_iter().enumerate() {
                    let flex = 30.0 * (1.0 + (2.0 * t + k as f64 + b as f64).sin());
                    rot *= Quat::from_axis_angle(&Vec3::z_axis(), -flex.to_radians());
                    pos += rot * Vec3::new(len, 0.0, 0.0);
                    samples.push(Some(pos));
                }
            }
        }
        Take::from_samples(names.iter().map(|n| MarkerName::parse(n)).collect(), &samples, 60.0).unwrap()
    }

    #[test]
    fn fits_joint_angles_to_hand_points() {
        let take = art_like(120);
        let (motion, report) = fit_art_hand(&take, Side::Left).unwrap();
        assert_eq!(motion.frame_count(), 120);
        assert_eq!(motion.skeleton.len(), 21);
        // Positions come back (the synthetic hand is rigid, so exactly up to the knuckle
        // frame's definition).
        assert!(report.rms_mm < 1.0, "{report:?}");
        // Fingers curl towards the palm: positive flexion.
        let (_, lo, hi) = &report.flexion_range_deg[1];
        assert!(*lo > -5.0 && *hi > 30.0, "{:?}", report.flexion_range_deg);
        assert!(matches!(fit_art_hand(&take, Side::Right), Err(HandError::MissingPoint(_))));
    }

    /// The layout carries the skeleton it was made on, with ranges that hold the procedural
    /// motion: every joint's rotation vector (what the kinematic solver fits) has its component
    /// along each axis within that axis's range, and the root is free.
    #[test]
    fn layout_skeleton_holds_the_procedural_motion() {
        let (base, _) = fit_art_hand(&art_like(300), Side::Left).unwrap();
        let motion =
            procedural_fingers(&base, &FingerLimits::default(), &mut rand::rngs::StdRng::seed_from_u64(5)).unwrap();
        let layout = hand_layout(&motion.skeleton, Side::Left, 8.0).unwrap();
        let section = layout.skeleton.as_ref().expect("the hand layout carries its skeleton");
        layout.check().unwrap();
        let rebuilt = section.to_skeleton().unwrap();
        assert_eq!(rebuilt.len(), motion.skeleton.len());
        for (a, b) in rebuilt.joints().iter().zip(motion.skeleton.joints()) {
            assert_eq!((&a.name, a.parent), (&b.name, b.parent));
            assert!((a.offset_mm - b.offset_mm).norm() < 1e-9, "{}", a.name);
        }
        assert_eq!(section.joints[0].dofs, None);
        // End sites never turn; every finger joint turns about one or two axes.
        for j in &section.joints[1..] {
            let dofs = j.dofs.as_ref().unwrap();
            assert_eq!(dofs.is_empty(), j.name.ends_with("_End"), "{}", j.name);
        }
        let mut worst: f64 = 0.0;
        for f in 0..motion.frame_count() {
            for (j, rot) in section.joints.iter().zip(motion.local_rotations(f)).skip(1) {
                let v = rot.scaled_axis();
                for d in j.dofs.iter().flatten() {
                    let along = v.dot(&Vec3::from(d.axis)).to_degrees();
                    worst = worst.max(d.min_deg - along).max(along - d.max_deg);
                }
            }
        }
        assert!(worst <= 0.0, "the procedural motion leaves the layout's ranges by {worst} degrees");
    }

    /// `hands --procedural 1000000` ran for days: refused up front.
    #[test]
    fn procedural_count_is_bounded() {
        assert_eq!(check_procedural_count(MAX_PROCEDURAL_TAKES), Ok(()));
        assert_eq!(check_procedural_count(1_000_000), Err(HandError::TooManyTakes(1_000_000)));
    }

    /// Procedural fingers stay within their limits and are smooth; the layout binds.
    #[test]
    fn procedural_fingers_respect_limits() {
        let (base, _) = fit_art_hand(&art_like(300), Side::Left).unwrap();
        let limits = FingerLimits::default();
        let motion = procedural_fingers(&base, &limits, &mut rand::rngs::StdRng::seed_from_u64(3)).unwrap();
        let mut max_step: f64 = 0.0;
        let mut seen = [f64::INFINITY, f64::NEG_INFINITY];
        for f in 0..motion.frame_count() {
            for k in 1..5 {
                let j = 1 + 4 * k;
                let rot = motion.local_rotations(f);
                let mcp = flexion_deg(rot[j]);
                let pip = flexion_deg(rot[j + 1]);
                assert!(mcp >= limits.mcp_flexion_deg[0] - 1e-6 && mcp <= limits.mcp_flexion_deg[1] + 1e-6, "{mcp}");
                assert!(pip >= -1e-6 && pip <= limits.pip_flexion_deg[1] + 1e-6, "{pip}");
                let dip = flexion_deg(rot[j + 2]);
                assert!((dip - pip * limits.dip_coupling).abs() < 1e-6);
                seen = [seen[0].min(pip), seen[1].max(pip)];
                if f > 0 {
                    max_step = max_step.max((pip - flexion_deg(motion.local_rotations(f - 1)[j + 1])).abs());
                }
            }
        }
        assert!(seen[1] - seen[0] > 30.0, "fingers barely move: {seen:?}");
        // Fast real finger motion peaks near 600-1000 degrees/s; 10 degrees per frame at 60 Hz
        // is 600.
        assert!(max_step < 10.0, "jerky at 60 Hz: {max_step} degrees per frame");
        let layout = hand_layout(&motion.skeleton, Side::Left, 8.0).unwrap();
        assert_eq!(layout.markers.len(), 14);
        assert!(layout.bind(&motion.skeleton).is_ok());
        assert!(layout.markers.iter().all(|m| m.region == Region::LeftHand));
    }
}
