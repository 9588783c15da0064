//! Ground-truth marker trajectories from skeleton motion and a layout (LocalMoCap section 4:
//! the synthetic dataset drives a body with CMU motion and reads markers off it).
//!
//! The paper drives a licensed body model (SMPL+H); locap puts the layout's markers on the
//! skeleton itself and adds per-take *subject variation* so that a network never sees the same
//! body twice:
//! - **bone-length scale**: one global factor `U(min, max)` times a small per-bone factor
//!   `N(1, sd)`; the root trajectory scales with the global factor (a taller subject takes
//!   longer strides and carries its pelvis higher) and so do the marker offsets;
//! - **bone tilt** (off by default): each rest offset turned by a small random rotation
//!   (`N(0, sd)` per axis), since subjects differ in rest pose as well as in bone length (CMU's
//!   ASF files give hip, clavicle, neck and foot bones directions that differ by several
//!   degrees between subjects);
//! - **held posture** (off by default): the joints named in
//!   [`Variation::posture_joints`] are turned by one random rotation for the whole take
//!   (`N(0, sd)` per axis, its component about the bone itself removed), on top of the
//!   motion's own rotations. How a subject holds the hands through a take is their own (CMU's
//!   solutions of different subjects turn the hand from the forearm by tens of degrees in
//!   opposite directions), so a network trained on a few subjects learns their habit instead
//!   of reading the hand's marker (docs/benchmarks.md, "The hands' held posture in
//!   training"); the twist about the bone is left out because a hand's one marker cannot show
//!   it;
//! - **offset jitter**: each marker's offset moves by `N(0, sd)` mm per axis, once per take
//!   (markers are never placed twice on exactly the same spot);
//! - **soft-tissue wobble**: a smooth displacement in the joint's frame, per marker and axis a
//!   sum of three sinusoids with random frequency (log-uniform in a band, default 0.5-4 Hz) and
//!   phase, scaled to a given RMS amplitude and by the marker's `soft_tissue` factor;
//! - **resampling** to a target rate: root positions linearly, rotations by slerp;
//! - **mirroring** ([`mirror_motion`]): the motion reflected across the body's sagittal plane,
//!   left and right joints exchanged, a second motion from every motion a data set has.
//!
//! Everything random comes from the caller's RNG, so a seed reproduces a take exactly.

use crate::layout::{BoundLayout, Layout, LayoutError};
use locap_core::{Joint, MarkerName, Motion, Quat, Skeleton, SkeletonError, Take, TakeError, UpAxis, Vec3};
use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};

/// Errors of synthesis.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SynthError {
    /// The layout does not fit the motion's skeleton.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// Building the resampled or scaled motion failed.
    #[error(transparent)]
    Skeleton(#[from] SkeletonError),
    /// Building the take failed (a non-finite position: the motion holds NaN or infinities).
    #[error(transparent)]
    Take(#[from] TakeError),
    /// A motion with no frames.
    #[error("the motion has no frames")]
    NoFrames,
    /// A setting is out of range.
    #[error("{0}")]
    BadSetting(String),
}

/// How marker positions map from the motion's world frame to the lab frame of the take.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LabFrame {
    /// Keep the motion's frame (the take is marked Y-up, as BVH and ASF are).
    Motion,
    /// A Y-up motion in a Z-up lab, as CMU publishes its C3D takes: lab `(X, Y, Z)` = motion
    /// `(z, x, y)`, the convention of [`locap_core::units::y_up_to_z_up`].
    #[default]
    ZUpFromYUp,
}

impl LabFrame {
    /// A motion-frame point in the lab frame.
    pub fn to_lab(self, p: Vec3) -> Vec3 {
        match self {
            LabFrame::Motion => p,
            LabFrame::ZUpFromYUp => locap_core::units::y_up_to_z_up(p),
        }
    }

    /// A lab-frame point in the motion frame (inverse of [`LabFrame::to_lab`]).
    pub fn to_motion(self, p: Vec3) -> Vec3 {
        match self {
            LabFrame::Motion => p,
            LabFrame::ZUpFromYUp => locap_core::units::z_up_to_y_up(p),
        }
    }

    /// The rotation from the motion frame to this lab frame (what [`LabFrame::to_lab`] does to
    /// a point).
    pub fn motion_to_lab_rotation(self) -> locap_core::Quat {
        match self {
            LabFrame::Motion => locap_core::Quat::identity(),
            LabFrame::ZUpFromYUp => locap_core::units::y_up_to_z_up_rotation(),
        }
    }

    /// The up axis of takes in this lab frame.
    pub fn up_axis(self) -> UpAxis {
        match self {
            LabFrame::Motion => UpAxis::Y,
            LabFrame::ZUpFromYUp => UpAxis::Z,
        }
    }

    /// `take` (in this lab frame) moved into the motion frame, e.g. to calibrate a layout.
    pub fn take_to_motion(self, take: &Take) -> Take {
        let mut out = take.clone();
        for f in 0..take.frame_count() {
            for m in 0..take.marker_count() {
                if let Some(p) = take.position_mm(f, m) {
                    // A permutation of a finite point is finite.
                    let _ = out.set_position_mm(f, m, Some(self.to_motion(p)));
                    out.set_quality(f, m, take.quality(f, m));
                }
            }
        }
        out.up_axis = UpAxis::Y;
        out
    }
}

/// Ranges of the per-take subject variation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Variation {
    /// Global bone-length scale, uniform in `[min, max]`.
    pub bone_scale_range: [f64; 2],
    /// Standard deviation of the extra per-bone scale factor (around 1).
    pub bone_scale_sd: f64,
    /// Standard deviation of the per-take marker offset jitter, mm per axis.
    pub offset_jitter_mm: f64,
    /// RMS soft-tissue wobble, mm per axis (times each marker's `soft_tissue`).
    pub wobble_mm: f64,
    /// Frequency band of the wobble, Hz.
    pub wobble_hz: [f64; 2],
    /// Standard deviation of the per-bone tilt of the rest offsets, degrees per axis (0: the
    /// skeleton's own bone directions; files written before the field read as 0).
    #[serde(default)]
    pub bone_tilt_sd_deg: f64,
    /// Standard deviation of the per-take held posture of the joints in `posture_joints`,
    /// degrees per axis (0: the motion's own rotations; files written before the field read
    /// as 0).
    #[serde(default)]
    pub posture_sd_deg: f64,
    /// The joints whose held posture varies per take (by name; every one must be in the
    /// skeleton), e.g. `lhand` and `rhand`.
    #[serde(default)]
    pub posture_joints: Vec<String>,
}

impl Default for Variation {
    /// Adult-like variation: +-8% height, 2% per bone, 4 mm jitter, 2 mm wobble at 0.5-4 Hz.
    fn default() -> Self {
        Variation {
            bone_scale_range: [0.92, 1.08],
            bone_scale_sd: 0.02,
            offset_jitter_mm: 4.0,
            wobble_mm: 2.0,
            wobble_hz: [0.5, 4.0],
            bone_tilt_sd_deg: 0.0,
            posture_sd_deg: 0.0,
            posture_joints: vec![],
        }
    }
}

impl Variation {
    /// No variation: markers exactly where the layout puts them.
    pub fn none() -> Variation {
        Variation {
            bone_scale_range: [1.0, 1.0],
            bone_scale_sd: 0.0,
            offset_jitter_mm: 0.0,
            wobble_mm: 0.0,
            wobble_hz: [1.0, 1.0],
            bone_tilt_sd_deg: 0.0,
            posture_sd_deg: 0.0,
            posture_joints: vec![],
        }
    }

    fn check(&self) -> Result<(), SynthError> {
        let [lo, hi] = self.bone_scale_range;
        let [f0, f1] = self.wobble_hz;
        let ok = lo.is_finite()
            && lo > 0.0
            && hi >= lo
            && hi.is_finite()
            && [self.bone_scale_sd, self.offset_jitter_mm, self.wobble_mm, self.bone_tilt_sd_deg, self.posture_sd_deg]
                .iter()
                .all(|v| v.is_finite() && *v >= 0.0)
            // Beyond a right angle a "tilt" is another skeleton, and a "posture" another
            // motion, not a subject.
            && self.bone_tilt_sd_deg <= 90.0
            && self.posture_sd_deg <= 90.0
            && f0.is_finite()
            && f0 > 0.0
            && f1 >= f0
            && f1.is_finite();
        if ok { Ok(()) } else { Err(SynthError::BadSetting(format!("subject variation out of range: {self:?}"))) }
    }
}

/// Settings of [`synthesize`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct SynthConfig {
    /// Subject variation.
    pub variation: Variation,
    /// Output frame rate; `None` keeps the motion's.
    pub rate_hz: Option<f64>,
    /// Lab frame of the output take.
    pub lab: LabFrame,
}

/// One sinusoid of the wobble: amplitude mm, frequency Hz, phase rad.
type Wave = (f64, f64, f64);

/// The random subject drawn for one take.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Subject {
    /// Global bone-length scale.
    pub global_scale: f64,
    /// Scale of each joint's rest offset (global x per-bone).
    pub bone_scales: Vec<f64>,
    /// Offset jitter of each marker in its joint frame, mm.
    pub jitter_mm: Vec<[f64; 3]>,
    /// Tilt of each joint's rest offset, a rotation vector (axis times angle, radians); empty
    /// without tilt.
    #[serde(default)]
    pub bone_tilt_rad: Vec<[f64; 3]>,
    /// Held posture of each joint, a rotation vector (axis times angle, radians) applied after
    /// the joint's own rotation in every frame; empty without posture variation.
    #[serde(default)]
    pub posture_rad: Vec<[f64; 3]>,
    /// Wobble sinusoids per marker and axis.
    wobble: Vec<[Vec<Wave>; 3]>,
}

impl Subject {
    /// Draws a subject for `joints` joints and `markers` markers.
    pub fn draw(variation: &Variation, joints: usize, soft_tissue: &[f64], rng: &mut impl Rng) -> Subject {
        let [lo, hi] = variation.bone_scale_range;
        let global_scale = if hi > lo { rng.random_range(lo..hi) } else { lo };
        let bone_scales = (0..joints).map(|_| global_scale * (1.0 + variation.bone_scale_sd * normal(rng))).collect();
        let jitter_mm = soft_tissue.iter().map(|_| [0; 3].map(|_| variation.offset_jitter_mm * normal(rng))).collect();
        const WAVES: usize = 3;
        let amplitude = variation.wobble_mm * (2.0 / WAVES as f64).sqrt();
        let [f0, f1] = variation.wobble_hz;
        let wobble = soft_tissue
            .iter()
            .map(|s| {
                [0; 3].map(|_| {
                    (0..WAVES)
                        .map(|_| {
                            let u: f64 = rng.random();
                            let hz = f0 * (f1 / f0).powf(u);
                            let phase = rng.random::<f64>() * std::f64::consts::TAU;
                            (amplitude * s, hz, phase)
                        })
                        .collect()
                })
            })
            .collect();
        // Drawn last and only when asked for, so that the seeds of tilt-free data sets keep
        // drawing the same subjects.
        let sd = variation.bone_tilt_sd_deg.to_radians();
        let bone_tilt_rad =
            if sd > 0.0 { (0..joints).map(|_| [0; 3].map(|_| sd * normal(rng))).collect() } else { vec![] };
        Subject { global_scale, bone_scales, jitter_mm, bone_tilt_rad, posture_rad: vec![], wobble }
    }

    /// Draws the held posture of [`Variation::posture_joints`] on `skeleton`: per named joint
    /// `N(0, sd)` per axis, less its component along the joint's bone (the mean direction of
    /// its children's rest offsets; a joint without children keeps all three axes). Draws
    /// nothing from `rng` without posture variation, so earlier data sets' seeds keep their
    /// subjects.
    ///
    /// # Errors
    /// [`SynthError::BadSetting`] naming a joint the skeleton does not have.
    pub fn draw_posture(
        &mut self,
        variation: &Variation,
        skeleton: &Skeleton,
        rng: &mut impl Rng,
    ) -> Result<(), SynthError> {
        self.posture_rad.clear();
        if variation.posture_sd_deg == 0.0 || variation.posture_joints.is_empty() {
            return Ok(());
        }
        if let Some(missing) = variation.posture_joints.iter().find(|n| skeleton.index_of(n).is_none()) {
            return Err(SynthError::BadSetting(format!("posture joint `{missing}` is not in the skeleton")));
        }
        let sd = variation.posture_sd_deg.to_radians();
        self.posture_rad = (0..skeleton.len())
            .map(|k| {
                let joint = &skeleton.joints()[k];
                if !variation.posture_joints.contains(&joint.name) {
                    return [0.0; 3];
                }
                let mut r = Vec3::from([0; 3].map(|_| sd * normal(rng)));
                let bone: Vec3 = skeleton.children(k).map(|c| skeleton.joints()[c].offset_mm).sum();
                if let Some(along) = bone.try_normalize(1e-9) {
                    r -= along * r.dot(&along);
                }
                r.into()
            })
            .collect();
        Ok(())
    }

    /// `skeleton`'s rest offsets turned by this subject's bone tilts (unchanged without tilt).
    ///
    /// # Errors
    /// None in practice: the joints keep their names and parents.
    pub fn tilt(&self, skeleton: &Skeleton) -> Result<Skeleton, SkeletonError> {
        if self.bone_tilt_rad.is_empty() {
            return Ok(skeleton.clone());
        }
        let joints = skeleton.joints().iter().zip(self.bone_tilt_rad.iter().chain(std::iter::repeat(&[0.0; 3])));
        Skeleton::new(
            joints
                .map(|(j, r)| Joint { offset_mm: Quat::from_scaled_axis(Vec3::from(*r)) * j.offset_mm, ..j.clone() })
                .collect(),
        )
    }

    /// Wobble displacement of `marker` at time `t_s`, mm in the joint frame.
    pub fn wobble_mm(&self, marker: usize, t_s: f64) -> Vec3 {
        let axis =
            |waves: &Vec<Wave>| waves.iter().map(|(a, hz, ph)| a * (std::f64::consts::TAU * hz * t_s + ph).sin()).sum();
        let w = &self.wobble[marker];
        Vec3::new(axis(&w[0]), axis(&w[1]), axis(&w[2]))
    }
}

/// A standard normal draw (Box-Muller; rand 0.10 has no distributions without rand_distr).
pub(crate) fn normal(rng: &mut impl Rng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(f64::MIN_POSITIVE);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// What [`synthesize`] returns.
#[derive(Debug, Clone, PartialEq)]
pub struct Synthesized {
    /// Clean marker take (ground truth) in the lab frame.
    pub take: Take,
    /// The motion the markers come from: resampled and scaled to the subject, in the
    /// motion's own frame.
    pub motion: Motion,
    /// The subject drawn.
    pub subject: Subject,
}

/// Highest output frame rate, Hz: the fastest optical systems film at a few kHz (Vicon
/// Vantage 2 kHz, Qualisys Arqus about 1.4 kHz at full resolution, more windowed); 10 kHz is
/// generous. Checked by [`SynthConfig::validate`] and [`resample`].
pub const MAX_RATE_HZ: f64 = 10_000.0;
/// Most frames a resample may produce (2 million: 4.6 hours at 120 Hz, 14 minutes at
/// 2.4 kHz; about 1 KB of rotations a frame for a CMU skeleton, 2 GB), checked before any
/// frame is allocated.
pub const MAX_RESAMPLED_FRAMES: usize = 2_000_000;

impl SynthConfig {
    /// Checks the settings: the subject variation's ranges, and a rate in `(0, MAX_RATE_HZ]`.
    ///
    /// # Errors
    /// [`SynthError::BadSetting`] naming the setting.
    pub fn validate(&self) -> Result<(), SynthError> {
        self.variation.check()?;
        self.rate_hz.map_or(Ok(()), check_rate)
    }
}

fn check_rate(rate_hz: f64) -> Result<(), SynthError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0 && rate_hz <= MAX_RATE_HZ) {
        return Err(SynthError::BadSetting(format!("frame rate {rate_hz} Hz is not in (0, {MAX_RATE_HZ}] Hz")));
    }
    Ok(())
}

/// `motion` resampled to `rate_hz`: root positions interpolated linearly, rotations by slerp.
///
/// # Errors
/// A rate out of `(0, MAX_RATE_HZ]`, no frames, or more than [`MAX_RESAMPLED_FRAMES`] out.
/// The last output frame is the last one at or before the input's last frame.
pub fn resample(motion: &Motion, rate_hz: f64) -> Result<Motion, SynthError> {
    check_rate(rate_hz)?;
    let n = motion.frame_count();
    if n == 0 {
        return Err(SynthError::NoFrames);
    }
    let src = motion.frame_rate_hz();
    if (rate_hz - src).abs() < 1e-9 {
        return Ok(motion.clone());
    }
    // In f64 first: a lying source rate or a huge ratio must not wrap before the check.
    let out = ((n - 1) as f64 * rate_hz / src + 1e-9).floor() + 1.0;
    if !(out <= MAX_RESAMPLED_FRAMES as f64) {
        return Err(SynthError::BadSetting(format!(
            "resampling {n} frames from {src} Hz to {rate_hz} Hz gives {out} frames (at most {MAX_RESAMPLED_FRAMES})"
        )));
    }
    let out_frames = out as usize;
    let mut rotations = Vec::with_capacity(out_frames * motion.skeleton.len());
    let mut root = Vec::with_capacity(out_frames);
    for i in 0..out_frames {
        let u = i as f64 * src / rate_hz;
        let f0 = (u.floor() as usize).min(n - 1);
        let f1 = (f0 + 1).min(n - 1);
        let t = u - f0 as f64;
        root.push(motion.root_position_mm(f0).lerp(&motion.root_position_mm(f1), t));
        for (a, b) in motion.local_rotations(f0).iter().zip(motion.local_rotations(f1)) {
            rotations.push(a.try_slerp(b, t, 1e-12).unwrap_or(*a));
        }
    }
    Ok(Motion::new(motion.skeleton.clone(), rotations, root, rate_hz)?)
}

/// `motion` on a skeleton whose rest offsets are scaled per joint by `scales`, with the root
/// trajectory scaled by `root_scale`.
pub fn scale_motion(motion: &Motion, scales: &[f64], root_scale: f64) -> Result<Motion, SynthError> {
    let joints: Vec<Joint> = motion
        .skeleton
        .joints()
        .iter()
        .zip(scales.iter().chain(std::iter::repeat(&1.0)))
        .map(|(j, s)| Joint { offset_mm: j.offset_mm * *s, ..j.clone() })
        .collect();
    let skeleton = Skeleton::new(joints)?;
    let n = motion.frame_count();
    let rotations: Vec<Quat> = (0..n).flat_map(|f| motion.local_rotations(f).iter().copied()).collect();
    let root = (0..n).map(|f| motion.root_position_mm(f) * root_scale).collect();
    Ok(Motion::new(skeleton, rotations, root, motion.frame_rate_hz())?)
}

/// Synthesizes a clean marker take from `motion` and `layout` with a random subject.
pub fn synthesize(
    motion: &Motion,
    layout: &Layout,
    config: &SynthConfig,
    rng: &mut impl Rng,
) -> Result<Synthesized, SynthError> {
    config.validate()?;
    if motion.frame_count() == 0 {
        return Err(SynthError::NoFrames);
    }
    let bound = layout.bind(&motion.skeleton)?;
    let soft: Vec<f64> = bound.markers.iter().map(|m| m.soft_tissue).collect();
    let mut subject = Subject::draw(&config.variation, motion.skeleton.len(), &soft, rng);
    subject.draw_posture(&config.variation, &motion.skeleton, rng)?;
    let resampled = match config.rate_hz {
        Some(hz) => resample(motion, hz)?,
        None => motion.clone(),
    };
    let mut scaled = scale_motion(&resampled, &subject.bone_scales, subject.global_scale)?;
    // The subject's bone tilts and held posture, in one rebuild of the motion (each leaves it
    // as it is when not drawn).
    if !subject.bone_tilt_rad.is_empty() || !subject.posture_rad.is_empty() {
        let held: Vec<Quat> = subject.posture_rad.iter().map(|r| Quat::from_scaled_axis(Vec3::from(*r))).collect();
        let n = scaled.frame_count();
        let rotations = (0..n)
            .flat_map(|f| scaled.local_rotations(f).iter().enumerate().map(|(k, q)| held.get(k).map_or(*q, |h| q * h)))
            .collect();
        let root = (0..n).map(|f| scaled.root_position_mm(f)).collect();
        scaled = Motion::new(subject.tilt(&scaled.skeleton)?, rotations, root, scaled.frame_rate_hz())?;
    }
    let take = markers_of(&scaled, &bound, &subject, config.lab)?;
    Ok(Synthesized { take, motion: scaled, subject })
}

/// The joint a joint mirrors onto: the one named with its side exchanged (a leading `l`/`r`,
/// `L`/`R` or `Left`/`Right`), itself when no such joint exists (`lowerback`, `Hips`).
fn mirror_partner(skeleton: &Skeleton, k: usize) -> usize {
    let name = &skeleton.joints()[k].name;
    let swapped = [("Left", "Right"), ("Right", "Left"), ("l", "r"), ("r", "l"), ("L", "R"), ("R", "L")]
        .iter()
        .filter_map(|(a, b)| name.strip_prefix(a).map(|rest| format!("{b}{rest}")));
    for other in swapped {
        if let Some(p) = skeleton.joints().iter().position(|j| j.name == other) {
            return p;
        }
    }
    k
}

/// `motion` reflected across the plane normal to its `lateral` axis (0, 1, 2 for x, y, z of the
/// motion frame; CMU's ASF and BVH skeletons have their left side at +x, so 0): every joint
/// takes its partner's rest offset and local rotation, reflected ([`mirror_partner`]: `lfemur`
/// and `rfemur`, `LeftHip` and `RightHip`), and the root moves on the reflected path. A
/// rotation `R` reflects as `M R M` with `M` the reflection, again a rotation; in the
/// world-aligned rest frames of [`forward_kinematics`](locap_core::skeleton::forward_kinematics)
/// that gives exactly the mirrored pose, so markers synthesized from it are those of a subject
/// doing the motion with the other hand.
///
/// # Errors
/// `lateral` is not 0, 1 or 2, or the left and right joints do not pair up (a joint and its
/// partner with parents that are not partners too).
pub fn mirror_motion(motion: &Motion, lateral: usize) -> Result<Motion, SynthError> {
    if lateral > 2 {
        return Err(SynthError::BadSetting(format!("mirror axis {lateral} is not 0, 1 or 2 (x, y, z)")));
    }
    let sk = &motion.skeleton;
    let partner: Vec<usize> = (0..sk.len()).map(|k| mirror_partner(sk, k)).collect();
    let reflect = |mut v: Vec3| {
        v[lateral] = -v[lateral];
        v
    };
    for (k, j) in sk.joints().iter().enumerate() {
        let p = &sk.joints()[partner[k]];
        if partner[partner[k]] != k || j.parent.map(|q| partner[q]) != p.parent {
            return Err(SynthError::BadSetting(format!(
                "joints {} and {} do not mirror: their parents are not left/right partners",
                j.name, p.name
            )));
        }
    }
    let joints = sk
        .joints()
        .iter()
        .zip(&partner)
        .map(|(j, &p)| Joint { offset_mm: reflect(sk.joints()[p].offset_mm), ..j.clone() });
    let skeleton = Skeleton::new(joints.collect())?;
    // The quaternion of M R M: the vector part reflected and negated (a reflection turns the
    // sense of rotation), i.e. every component but the lateral one negated.
    let reflect_rotation = |q: &Quat| {
        let mut v = -q.imag();
        v[lateral] = -v[lateral];
        Quat::new_normalize(nalgebra::Quaternion::from_parts(q.w, v))
    };
    let n = motion.frame_count();
    let mut rotations = Vec::with_capacity(n * sk.len());
    for f in 0..n {
        let local = motion.local_rotations(f);
        rotations.extend(partner.iter().map(|&p| reflect_rotation(&local[p])));
    }
    let root = (0..n).map(|f| reflect(motion.root_position_mm(f))).collect();
    Ok(Motion::new(skeleton, rotations, root, motion.frame_rate_hz())?)
}

/// Marker positions of `bound` on every frame of `motion` for `subject`, in `lab`.
pub fn markers_of(motion: &Motion, bound: &BoundLayout, subject: &Subject, lab: LabFrame) -> Result<Take, SynthError> {
    let names: Vec<MarkerName> = bound.names.iter().map(|n| MarkerName::parse(n)).collect();
    let mut take = Take::empty(names, motion.frame_count(), motion.frame_rate_hz())?;
    take.up_axis = lab.up_axis();
    let rate = motion.frame_rate_hz();
    for f in 0..motion.frame_count() {
        let pose = motion.forward_kinematics(f);
        let t_s = f as f64 / rate;
        for (m, marker) in bound.markers.iter().enumerate() {
            let scaled = crate::layout::BoundMarker {
                offset_mm: marker.offset_mm * subject.global_scale,
                blend: marker.blend.clone().map(|mut b| {
                    b.offset_mm *= subject.global_scale;
                    b
                }),
                ..marker.clone()
            };
            let extra = Vec3::from(subject.jitter_mm.get(m).copied().unwrap_or_default()) + subject.wobble_mm(m, t_s);
            take.set_position_mm(f, m, Some(lab.to_lab(scaled.position_mm(&pose, extra))))?;
        }
    }
    Ok(take)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::{joint, marker};
    use locap_core::EulerOrder;
    use rand::SeedableRng;

    fn motion(frames: usize) -> Motion {
        let sk = Skeleton::new(vec![
            joint("root", None, [0.0; 3]),
            joint("thigh", Some(0), [100.0, 0.0, 0.0]),
            joint("shin", Some(1), [0.0, -400.0, 0.0]),
        ])
        .unwrap();
        let mut rotations = Vec::new();
        let mut root = Vec::new();
        for f in 0..frames {
            let t = f as f64 / 120.0;
            rotations.push(EulerOrder::ZXY.to_quat_deg([0.0, 0.0, 30.0 * t]));
            rotations.push(EulerOrder::ZXY.to_quat_deg([20.0 * (3.0 * t).sin(), 40.0 * t, 0.0]));
            rotations.push(EulerOrder::ZXY.to_quat_deg([0.0, 60.0 * (2.0 * t).sin().abs(), 0.0]));
            root.push(Vec3::new(500.0 * t, 900.0, 0.0));
        }
        Motion::new(sk, rotations, root, 120.0).unwrap()
    }

    fn layout() -> Layout {
        crate::test_util::layout(vec![
            marker("THI", "thigh", [60.0, -200.0, 10.0]),
            marker("SHN", "shin", [40.0, -150.0, 30.0]),
        ])
    }

    /// Without jitter or wobble, a marker's offset in its joint frame is the layout's offset
    /// in every frame: the markers are forward-kinematics consistent.
    #[test]
    fn markers_are_fk_consistent() {
        let m = motion(200);
        let config = SynthConfig { variation: Variation::none(), rate_hz: None, lab: LabFrame::ZUpFromYUp };
        let out = synthesize(&m, &layout(), &config, &mut rand::rngs::StdRng::seed_from_u64(3)).unwrap();
        assert_eq!(out.take.frame_count(), 200);
        assert_eq!(out.take.up_axis, UpAxis::Z);
        for f in 0..200 {
            let pose = out.motion.forward_kinematics(f);
            for (k, (j, o)) in [(1, [60.0, -200.0, 10.0]), (2, [40.0, -150.0, 30.0])].into_iter().enumerate() {
                let x = LabFrame::ZUpFromYUp.to_motion(out.take.position_mm(f, k).unwrap());
                let local = pose.rotations[j].inverse() * (x - pose.positions_mm[j]);
                assert!((local - Vec3::from(o)).norm() < 1e-9, "frame {f}: {local} vs {o:?}");
            }
        }
    }

    /// Same seed, same take; another seed, another subject. Variation stays within its
    /// ranges and wobble is smooth (tiny frame-to-frame steps).
    #[test]
    fn deterministic_under_a_seed_and_varied_across_seeds() {
        let m = motion(240);
        let config = SynthConfig::default();
        let run = |seed| synthesize(&m, &layout(), &config, &mut rand::rngs::StdRng::seed_from_u64(seed)).unwrap();
        let (a, b, c) = (run(7), run(7), run(8));
        assert_eq!(a.take, b.take);
        assert_ne!(a.take, c.take);
        assert!((0.92..1.08).contains(&a.subject.global_scale));
        // Wobble: the difference to the variation-free marker is a few mm and changes slowly.
        let mut prev: Option<f64> = None;
        for f in 0..240 {
            let w = a.subject.wobble_mm(0, f as f64 / 120.0).norm();
            assert!(w < 15.0);
            if let Some(p) = prev {
                assert!((w - p).abs() < 0.5, "wobble jumps at frame {f}");
            }
            prev = Some(w);
        }
    }

    #[test]
    fn resampling_keeps_time_and_endpoints() {
        let m = motion(121);
        let r = resample(&m, 60.0).unwrap();
        assert_eq!(r.frame_count(), 61);
        assert_eq!(r.root_position_mm(60), m.root_position_mm(120));
        let up = resample(&m, 240.0).unwrap();
        assert_eq!(up.frame_count(), 241);
        // Halfway between two source frames: root halfway, rotation halfway.
        let mid = up.root_position_mm(1);
        assert!((mid - (m.root_position_mm(0) + m.root_position_mm(1)) / 2.0).norm() < 1e-9);
        let q = up.local_rotations(1)[1];
        let (a, b) = (m.local_rotations(0)[1], m.local_rotations(1)[1]);
        assert!((q.angle_to(&a) - q.angle_to(&b)).abs() < 1e-9);
        assert!(matches!(resample(&m, 0.0), Err(SynthError::BadSetting(_))));
        // `synth --rate 1e9` allocated frames x rate: now refused before allocating.
        assert!(matches!(resample(&m, 1e9), Err(SynthError::BadSetting(_))));
        let e = resample(&m, MAX_RATE_HZ).map(|r| r.frame_count());
        assert!(e.is_ok(), "{e:?}");
        let config = SynthConfig { rate_hz: Some(1e9), ..SynthConfig::default() };
        assert!(matches!(config.validate(), Err(SynthError::BadSetting(_))));
    }

    /// A left/right skeleton: root, two legs, a spine that starts with an `l` but has no `r`
    /// partner.
    fn two_legs(frames: usize) -> Motion {
        let sk = Skeleton::new(vec![
            joint("root", None, [0.0; 3]),
            joint("lfemur", Some(0), [90.0, -20.0, 5.0]),
            joint("ltibia", Some(1), [0.0, -400.0, 10.0]),
            joint("rfemur", Some(0), [-95.0, -20.0, 0.0]),
            joint("rtibia", Some(3), [0.0, -410.0, 0.0]),
            joint("lowerback", Some(0), [0.0, 150.0, -10.0]),
        ])
        .unwrap();
        let mut rotations = Vec::new();
        let mut root = Vec::new();
        for f in 0..frames {
            let t = f as f64 / 120.0;
            rotations.push(EulerOrder::ZXY.to_quat_deg([10.0 * t, 5.0, 30.0 * t]));
            rotations.push(EulerOrder::ZXY.to_quat_deg([20.0 * (3.0 * t).sin(), 40.0 * t, 7.0]));
            rotations.push(EulerOrder::ZXY.to_quat_deg([0.0, 60.0 * (2.0 * t).sin().abs(), 0.0]));
            rotations.push(EulerOrder::ZXY.to_quat_deg([-15.0, 10.0 * t, 3.0]));
            rotations.push(EulerOrder::ZXY.to_quat_deg([5.0, 20.0, -30.0 * t]));
            rotations.push(EulerOrder::ZXY.to_quat_deg([12.0, -8.0 * t, 4.0]));
            root.push(Vec3::new(500.0 * t, 900.0, 80.0 * t));
        }
        Motion::new(sk, rotations, root, 120.0).unwrap()
    }

    /// The mirrored motion's joints sit where the original's partners sit, reflected; the
    /// mirror of the mirror is the motion again.
    #[test]
    fn mirroring_reflects_every_joint_onto_its_partner() {
        let m = two_legs(50);
        let partners = [0, 3, 4, 1, 2, 5];
        for lateral in 0..3 {
            let mirrored = mirror_motion(&m, lateral).unwrap();
            for f in [0, 17, 49] {
                let (a, b) = (m.forward_kinematics(f), mirrored.forward_kinematics(f));
                for (k, &p) in partners.iter().enumerate() {
                    let mut x = a.positions_mm[p];
                    x[lateral] = -x[lateral];
                    assert!((b.positions_mm[k] - x).norm() < 1e-9, "axis {lateral} frame {f} joint {k}");
                }
            }
            let back = mirror_motion(&mirrored, lateral).unwrap();
            for f in 0..50 {
                assert!((back.root_position_mm(f) - m.root_position_mm(f)).norm() < 1e-9);
                for (q, r) in back.local_rotations(f).iter().zip(m.local_rotations(f)) {
                    assert!(q.angle_to(r) < 1e-9);
                }
            }
        }
        assert!(matches!(mirror_motion(&m, 3), Err(SynthError::BadSetting(_))));
    }

    /// A left joint whose partner hangs off another parent cannot be mirrored.
    #[test]
    fn unpaired_sides_are_an_error() {
        let sk = Skeleton::new(vec![
            joint("root", None, [0.0; 3]),
            joint("lfemur", Some(0), [90.0, -20.0, 0.0]),
            joint("rfemur", Some(1), [-90.0, -20.0, 0.0]),
        ])
        .unwrap();
        let m = Motion::new(sk, vec![Quat::identity(); 3], vec![Vec3::zeros()], 120.0).unwrap();
        assert!(matches!(mirror_motion(&m, 0), Err(SynthError::BadSetting(_))));
    }

    /// Tilt turns bones without changing their length, and without it the subjects are the
    /// ones the same seed drew before the setting existed (no extra draws).
    #[test]
    fn bone_tilt_keeps_lengths_and_old_seeds() {
        let m = two_legs(20);
        let soft = [1.0; 2];
        let plain = Variation::default();
        let tilted = Variation { bone_tilt_sd_deg: 5.0, ..Variation::default() };
        let a = Subject::draw(&plain, 6, &soft, &mut rand::rngs::StdRng::seed_from_u64(4));
        let b = Subject::draw(&tilted, 6, &soft, &mut rand::rngs::StdRng::seed_from_u64(4));
        assert!(a.bone_tilt_rad.is_empty());
        assert_eq!((a.global_scale, &a.bone_scales, &a.jitter_mm), (b.global_scale, &b.bone_scales, &b.jitter_mm));
        let sk = b.tilt(&m.skeleton).unwrap();
        let mut turned = 0;
        for (x, y) in m.skeleton.joints().iter().zip(sk.joints()) {
            assert!((x.offset_mm.norm() - y.offset_mm.norm()).abs() < 1e-9);
            if x.offset_mm.norm() > 0.0 && x.offset_mm.angle(&y.offset_mm) > 1e-3 {
                turned += 1;
            }
        }
        assert_eq!(turned, 5, "every bone of non-zero length turns");
        let config = SynthConfig { variation: tilted, ..SynthConfig::default() };
        let out = synthesize(&m, &layout_two_legs(), &config, &mut rand::rngs::StdRng::seed_from_u64(4)).unwrap();
        assert_eq!(
            out.motion.skeleton.joints()[2].offset_mm,
            b.tilt(&scale_motion(&m, &b.bone_scales, b.global_scale).unwrap().skeleton).unwrap().joints()[2].offset_mm
        );
        let bad = Variation { bone_tilt_sd_deg: -1.0, ..Variation::default() };
        assert!(matches!(
            SynthConfig { variation: bad, ..SynthConfig::default() }.validate(),
            Err(SynthError::BadSetting(_))
        ));
    }

    /// A held posture turns the named joint by one rotation in every frame, never about its
    /// own bone; the other joints, and without the setting the whole take, are the ones the
    /// same seed drew before it existed.
    #[test]
    fn held_posture_turns_the_named_joints_alike_in_every_frame() {
        let m = two_legs(30);
        let layout = layout_two_legs();
        let draw = |variation: Variation| {
            let config = SynthConfig { variation, ..SynthConfig::default() };
            synthesize(&m, &layout, &config, &mut rand::rngs::StdRng::seed_from_u64(9)).unwrap()
        };
        let plain = draw(Variation::default());
        let held =
            draw(Variation { posture_sd_deg: 20.0, posture_joints: vec!["lfemur".into()], ..Variation::default() });
        assert!(plain.subject.posture_rad.is_empty());
        assert_eq!(plain.subject.bone_scales, held.subject.bone_scales);
        let turn = Vec3::from(held.subject.posture_rad[1]);
        assert!(turn.norm() > 1e-3, "the named joint turns");
        let bone = m.skeleton.joints()[2].offset_mm.normalize();
        assert!(turn.dot(&bone).abs() < 1e-9, "not about its own bone");
        for (k, r) in held.subject.posture_rad.iter().enumerate() {
            assert!(k == 1 || *r == [0.0; 3], "joint {k} is not named");
        }
        let h = Quat::from_scaled_axis(turn);
        for f in 0..m.frame_count() {
            let (a, b) = (plain.motion.local_rotations(f), held.motion.local_rotations(f));
            assert!((a[1] * h).angle_to(&b[1]) < 1e-9);
            for k in [0, 2, 3, 4, 5] {
                assert!(a[k].angle_to(&b[k]) < 1e-12);
            }
        }
        // The knee marker rides the turned thigh.
        assert!((plain.take.position_mm(0, 0).unwrap() - held.take.position_mm(0, 0).unwrap()).norm() > 1.0);
        let unknown = Variation { posture_sd_deg: 5.0, posture_joints: vec!["lhand".into()], ..Variation::default() };
        let config = SynthConfig { variation: unknown, ..SynthConfig::default() };
        let err = synthesize(&m, &layout, &config, &mut rand::rngs::StdRng::seed_from_u64(9)).unwrap_err();
        assert!(err.to_string().contains("lhand"), "{err}");
        let bad = Variation { posture_sd_deg: f64::NAN, ..Variation::default() };
        assert!(SynthConfig { variation: bad, ..SynthConfig::default() }.validate().is_err());
    }

    fn layout_two_legs() -> Layout {
        crate::test_util::layout(vec![
            marker("LKNE", "ltibia", [40.0, 0.0, 0.0]),
            marker("RKNE", "rtibia", [-40.0, 0.0, 0.0]),
        ])
    }

    #[test]
    fn bad_settings_are_errors() {
        let m = motion(10);
        let mut config = SynthConfig::default();
        config.variation.bone_scale_range = [1.2, 0.8];
        let err = synthesize(&m, &layout(), &config, &mut rand::rngs::StdRng::seed_from_u64(1));
        assert!(matches!(err, Err(SynthError::BadSetting(_))));
    }
}
