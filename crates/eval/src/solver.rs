//! The motion-solver metrics of LocalMoCap section 4.2 (Table 1) on held-out shards:
//!
//! * **OMPE**, mm: distance between the cleaned (filled) and the true position of occluded
//!   marker samples only (samples the shard's corrupted markers lack). It measures the cleaning
//!   (EDM, or EDM + refiner), which every solver of one evaluation shares.
//! * **JOE**, degrees: geodesic angle between the solved and the true local rotation of each
//!   rotating joint (the root's global rotation included), averaged over joints and frames.
//!   Joints that never rotate in the model's training data (end sites, CMU's hip joints and
//!   clavicles, which have no degrees of freedom) are left out.
//! * **JPE**, mm: distance between solved and true global joint positions (every joint,
//!   end sites included), averaged over joints and frames.
//!
//! JOE and JPE are also given over the joints the markers constrain (a marker rides on the
//! joint or below it, by the kinematic solver's layout): a 41-marker body set barely sees the
//! fingers and thumbs, whose errors otherwise weigh like any limb's.
//!
//! Methods are the networks ([`Method::Network`]) and the kinematic solver
//! ([`Method::Kinematic`], the "optimization-based" column, `locap_nn::kinematic`), and a
//! network's answer refined by the kinematic solver ([`Method::Refined`]).
//!
//! Each take is solved exactly as `locap solve` solves a real one
//! ([`Solver::solve_cleaned`]): bone offsets averaged over the take, root from the waist
//! frame, so the figures include the skeleton fit. Besides the means, the evaluation keeps the
//! error per joint and by gap length, in the gap-length bins of every locap metric
//! ([`locap_core::gaps::LENGTH_BINS`], the fill benchmark's) after a first bin for frames with
//! no gap open: OMPE by the length of the gap a sample is in, JPE by the longest gap open in
//! the frame.

use locap_core::gaps::{gaps_of, length_bin};
use locap_nn::NnError;
use locap_nn::Refiner;
use locap_nn::kinematic::KinematicSolver;
use locap_nn::solver::Solver;
use locap_nn::solver::data::{Cleaned, SolverShard, clean_for_solving};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Number of gap bins of the per-gap errors: "none", then [`locap_core::gaps::LENGTH_BINS`].
pub const GAP_BIN_COUNT: usize = 1 + locap_core::gaps::LENGTH_BINS.len();

/// Labels of the per-gap errors' bins: `none` (no gap open in the frame), then the labels of
/// [`locap_core::gaps::LENGTH_BINS`].
pub fn gap_bin_labels() -> Vec<String> {
    std::iter::once("none".to_string()).chain(locap_core::gaps::length_bin_labels()).collect()
}

fn gap_bin(len: usize) -> usize {
    length_bin(len).map_or(0, |b| b + 1)
}

/// Why an evaluation could not run.
#[derive(Debug, thiserror::Error)]
pub enum SolverEvalError {
    /// No shards were given.
    #[error("no evaluation shards")]
    NoShards,
    /// A model was trained on another skeleton than the shards'.
    #[error("{model}: the model's skeleton is not the shards' skeleton")]
    OtherSkeleton {
        /// The model's name.
        model: String,
    },
    /// Cleaning or solving a shard failed.
    #[error("{shard}: {source}")]
    Solve {
        /// The shard's name.
        shard: String,
        /// What failed.
        #[source]
        source: NnError,
    },
    /// Two motions compared share no frames or no joint names.
    #[error("the motions share no frames or no joint names")]
    NothingInCommon,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
struct Mean {
    sum: f64,
    n: f64,
}

impl Mean {
    fn add(&mut self, v: f64) {
        self.sum += v;
        self.n += 1.0;
    }
    fn merge(&mut self, o: &Mean) {
        self.sum += o.sum;
        self.n += o.n;
    }
    fn get(&self) -> Option<f64> {
        (self.n > 0.0).then(|| self.sum / self.n)
    }
}

/// The scores of one method.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodScores {
    /// Method name.
    pub name: String,
    /// Joint orientation error, degrees.
    pub joe_deg: f64,
    /// Joint position error, mm.
    pub jpe_mm: f64,
    /// Occluded marker position error of the cleaning it ran on, mm.
    pub ompe_mm: Option<f64>,
    /// JPE per joint, mm.
    pub jpe_per_joint_mm: Vec<f64>,
    /// JOE per joint, degrees (`None` for joints left out).
    pub joe_per_joint_deg: Vec<Option<f64>>,
    /// JPE by the longest gap open in a frame ([`gap_bin_labels`]), mm.
    pub jpe_by_gap_mm: Vec<Option<f64>>,
    /// OMPE by gap length ([`gap_bin_labels`]; the first, "none", is always empty), mm.
    pub ompe_by_gap_mm: Vec<Option<f64>>,
    /// Seconds spent solving (network and skeleton, without cleaning).
    pub solve_seconds: f64,
    /// Frames solved.
    #[serde(default)]
    pub frames: usize,
    /// JOE over the rotating joints the markers constrain, degrees.
    #[serde(default)]
    pub joe_constrained_deg: Option<f64>,
    /// JPE over the joints the markers constrain, mm.
    #[serde(default)]
    pub jpe_constrained_mm: Option<f64>,
}

/// A solving method to score.
#[derive(Debug, Clone, Copy)]
pub enum Method<'a> {
    /// A network solver.
    Network(&'a Solver),
    /// The kinematic solver.
    Kinematic(&'a KinematicSolver),
    /// A network's answer refined by the kinematic solver ([`KinematicSolver::refine`]).
    Refined(&'a Solver, &'a KinematicSolver),
}

impl Method<'_> {
    /// Per joint: the method solves its rotation (JOE is taken over these).
    pub fn rotating(&self) -> Vec<bool> {
        match self {
            Method::Network(s) => s.meta.rotating.clone(),
            Method::Kinematic(k) | Method::Refined(_, k) => k.rotating(),
        }
    }

    fn skeleton(&self) -> &locap_core::Skeleton {
        match self {
            Method::Network(s) => &s.meta.skeleton,
            Method::Kinematic(k) | Method::Refined(_, k) => k.skeleton(),
        }
    }

    /// Solves a cleaned take.
    ///
    /// # Errors
    /// As the method's own `solve_cleaned`.
    pub fn solve_cleaned(&self, cleaned: &Cleaned, rate_hz: f64) -> Result<locap_core::Motion, NnError> {
        match self {
            Method::Network(s) => s.solve_cleaned(cleaned, rate_hz),
            Method::Kinematic(k) => k.solve_cleaned(cleaned, rate_hz).map(|(m, _)| m),
            Method::Refined(s, k) => k.refine(cleaned, rate_hz, &s.solve_cleaned(cleaned, rate_hz)?).map(|(m, _)| m),
        }
    }
}

/// Accumulated errors of one method.
#[derive(Debug, Clone, Default)]
struct Acc {
    joe: Vec<Mean>,
    jpe: Vec<Mean>,
    jpe_by_gap: Vec<Mean>,
    seconds: f64,
    frames: usize,
}

impl Acc {
    fn new(joints: usize) -> Acc {
        Acc {
            joe: vec![Mean::default(); joints],
            jpe: vec![Mean::default(); joints],
            jpe_by_gap: vec![Mean::default(); GAP_BIN_COUNT],
            seconds: 0.0,
            frames: 0,
        }
    }
    fn merge(&mut self, o: &Acc) {
        self.joe.iter_mut().zip(&o.joe).for_each(|(a, b)| a.merge(b));
        self.jpe.iter_mut().zip(&o.jpe).for_each(|(a, b)| a.merge(b));
        self.jpe_by_gap.iter_mut().zip(&o.jpe_by_gap).for_each(|(a, b)| a.merge(b));
        self.seconds += o.seconds;
        self.frames += o.frames;
    }
}

/// Occluded marker errors of a cleaning: overall and by gap length.
fn ompe(shard: &SolverShard, cleaned: &Cleaned) -> (Mean, Vec<Mean>) {
    let (t, m) = (shard.observed.frame_count(), shard.observed.marker_count());
    let mut all = Mean::default();
    let mut by = vec![Mean::default(); GAP_BIN_COUNT];
    for k in 0..m {
        for gap in gaps_of((0..t).map(|f| shard.observed.is_valid(f, k))) {
            for f in gap.start..gap.end() {
                if let (Some(a), Some(b)) = (cleaned.filled.take.position_mm(f, k), shard.clean.position_mm(f, k)) {
                    let e = (a - b).norm();
                    all.add(e);
                    by[gap_bin(gap.len)].add(e);
                }
            }
        }
    }
    (all, by)
}

/// The longest gap open in each frame of the shard's corrupted markers.
fn longest_gap_per_frame(shard: &SolverShard) -> Vec<usize> {
    let (t, m) = (shard.observed.frame_count(), shard.observed.marker_count());
    let mut longest = vec![0; t];
    for k in 0..m {
        for gap in gaps_of((0..t).map(|f| shard.observed.is_valid(f, k))) {
            longest[gap.start..gap.end()].iter_mut().for_each(|l| *l = (*l).max(gap.len));
        }
    }
    longest
}

/// Scores `solvers` (name, solver) on `shards`, all on the same cleaning (EDM, or EDM +
/// `refiner`).
///
/// # Errors
/// A solver cannot run on a shard (other markers or skeleton), or the skeletons differ.
pub fn evaluate(
    solvers: &[(String, &Solver)],
    shards: &[SolverShard],
    refiner: Option<&Refiner>,
) -> Result<Vec<MethodScores>, SolverEvalError> {
    let methods: Vec<(String, Method)> = solvers.iter().map(|(n, s)| (n.clone(), Method::Network(s))).collect();
    evaluate_methods(&methods, shards, refiner, None)
}

/// Scores `methods` (name, method) on `shards`, all on the same cleaning (EDM, or EDM +
/// `refiner`); with `constrained` (per joint), also over the joints it marks.
///
/// # Errors
/// A method cannot run on a shard (other markers or skeleton), or the skeletons differ.
pub fn evaluate_methods(
    methods: &[(String, Method)],
    shards: &[SolverShard],
    refiner: Option<&Refiner>,
    constrained: Option<&[bool]>,
) -> Result<Vec<MethodScores>, SolverEvalError> {
    let Some(first) = shards.first() else { return Err(SolverEvalError::NoShards) };
    let j = first.skeleton.len();
    for (name, s) in methods {
        // The same joints in any order: a model trained first on a BVH export lists them
        // depth first, one trained on ASF/AMC shards its end sites last.
        let names = |sk: &locap_core::Skeleton| {
            let mut v = sk.joints().iter().map(|jj| jj.name.clone()).collect::<Vec<_>>();
            v.sort_unstable();
            v
        };
        if shards.iter().any(|sh| names(&sh.skeleton) != names(s.skeleton())) {
            return Err(SolverEvalError::OtherSkeleton { model: name.clone() });
        }
    }
    let cleaned: Vec<Cleaned> = shards
        .par_iter()
        .map(|s| {
            clean_for_solving(&s.observed, refiner)
                .map_err(|source| SolverEvalError::Solve { shard: s.name.clone(), source })
        })
        .collect::<Result<_, _>>()?;
    let mut fill_all = Mean::default();
    let mut fill_by = [Mean::default(); GAP_BIN_COUNT];
    for (s, c) in shards.iter().zip(&cleaned) {
        let (a, b) = ompe(s, c);
        fill_all.merge(&a);
        fill_by.iter_mut().zip(&b).for_each(|(x, y)| x.merge(y));
    }
    let mut out = Vec::new();
    for (name, solver) in methods {
        let mut acc = Acc::new(j);
        for (shard, c) in shards.iter().zip(&cleaned) {
            acc.merge(&score_take(solver, shard, c)?);
        }
        let mean_over = |v: &[Mean]| {
            let mut total = Mean::default();
            v.iter().for_each(|m| total.merge(m));
            total.get().unwrap_or(f64::NAN)
        };
        let mean_where = |v: &[Mean], mask: &[bool]| {
            let mut total = Mean::default();
            v.iter().zip(mask).filter(|(_, m)| **m).for_each(|(x, _)| total.merge(x));
            total.get()
        };
        out.push(MethodScores {
            name: name.clone(),
            joe_deg: mean_over(&acc.joe),
            jpe_mm: mean_over(&acc.jpe),
            ompe_mm: fill_all.get(),
            jpe_per_joint_mm: acc.jpe.iter().map(|m| m.get().unwrap_or(f64::NAN)).collect(),
            joe_per_joint_deg: acc.joe.iter().map(Mean::get).collect(),
            jpe_by_gap_mm: acc.jpe_by_gap.iter().map(Mean::get).collect(),
            ompe_by_gap_mm: fill_by.iter().map(Mean::get).collect(),
            solve_seconds: acc.seconds,
            frames: acc.frames,
            joe_constrained_deg: constrained.and_then(|c| mean_where(&acc.joe, c)),
            jpe_constrained_mm: constrained.and_then(|c| mean_where(&acc.jpe, c)),
        });
    }
    Ok(out)
}

/// One solver on one cleaned shard.
fn score_take(solver: &Method, shard: &SolverShard, cleaned: &Cleaned) -> Result<Acc, SolverEvalError> {
    let rotating = solver.rotating();
    let started = std::time::Instant::now();
    let motion = solver
        .solve_cleaned(cleaned, shard.clean.frame_rate_hz())
        .map_err(|source| SolverEvalError::Solve { shard: shard.name.clone(), source })?;
    let j = shard.skeleton.len();
    // `from[k]`: the solved motion's joint that is the shard's joint `k`.
    let from: Vec<usize> = shard
        .skeleton
        .joints()
        .iter()
        .map(|joint| motion.skeleton.index_of(&joint.name))
        .collect::<Option<_>>()
        .ok_or_else(|| SolverEvalError::OtherSkeleton { model: shard.name.clone() })?;
    let mut acc = Acc::new(j);
    acc.seconds = started.elapsed().as_secs_f64();
    acc.frames = motion.frame_count();
    let longest = longest_gap_per_frame(shard);
    for (f, longest) in longest.iter().enumerate().take(motion.frame_count()) {
        let pose = motion.forward_kinematics(f);
        let mut frame = Mean::default();
        for (k, &m) in from.iter().enumerate() {
            let e = (shard.lab.to_lab(pose.positions_mm[m]) - shard.joint_positions_mm[f * j + k]).norm();
            acc.jpe[k].add(e);
            frame.add(e);
        }
        acc.jpe_by_gap[gap_bin(*longest)].add(frame.get().unwrap_or(0.0));
        let truth = &shard.rotations[f * j..(f + 1) * j];
        let solved = motion.local_rotations(f);
        for (k, (&m, t)) in from.iter().zip(truth).enumerate() {
            if rotating[m] {
                acc.joe[k].add(solved[m].angle_to(t).to_degrees());
            }
        }
    }
    Ok(acc)
}

/// Table 1 as text: one row per metric, one column per method; `region` heads the first
/// column (body, hand).
pub fn table(region: &str, scores: &[MethodScores]) -> String {
    use std::fmt::Write as _;
    let mut out = format!("{region:<12}");
    for s in scores {
        let _ = write!(out, " {:>16}", s.name);
    }
    out.push('\n');
    let row = |out: &mut String, label: &str, v: &dyn Fn(&MethodScores) -> Option<f64>| {
        let _ = write!(out, "{label:<12}");
        for s in scores {
            let _ = write!(out, " {:>16}", v(s).map_or("-".into(), |x| format!("{x:.2}")));
        }
        out.push('\n');
    };
    row(&mut out, "JOE (deg)", &|s| Some(s.joe_deg));
    row(&mut out, "JPE (mm)", &|s| Some(s.jpe_mm));
    if scores.iter().any(|s| s.joe_constrained_deg.is_some()) {
        row(&mut out, "JOE constr.", &|s| s.joe_constrained_deg);
        row(&mut out, "JPE constr.", &|s| s.jpe_constrained_mm);
    }
    row(&mut out, "OMPE (mm)", &|s| s.ompe_mm);
    if scores.iter().any(|s| s.frames > 0) {
        row(&mut out, "frames/s", &|s| (s.frames > 0).then(|| s.frames as f64 / s.solve_seconds.max(1e-9)));
    }
    out
}

/// Each turn of a joint `rotating` marks between consecutive frames: `(f, joint index,
/// degrees)` for the pair `(f, f + 1)`, in frame order. Local rotations: a parent's turn is not
/// counted again in its children.
fn local_turns<'a>(
    motion: &'a locap_core::Motion,
    rotating: &'a [bool],
) -> impl Iterator<Item = (usize, usize, f64)> + 'a {
    (1..motion.frame_count()).flat_map(move |f| {
        let (a, b) = (motion.local_rotations(f - 1), motion.local_rotations(f));
        a.iter()
            .zip(b)
            .enumerate()
            .filter(|(k, _)| rotating.get(*k).copied().unwrap_or(false))
            .map(|(k, (qa, qb))| (f - 1, k, qa.angle_to(qb).to_degrees()))
            .collect::<Vec<_>>()
    })
}

/// The largest rotation of any joint `rotating` marks between consecutive frames (degrees),
/// the joint's name, and how many frame pairs turn some joint by more than `over_deg`.
pub fn rotation_jumps(motion: &locap_core::Motion, rotating: &[bool], over_deg: f64) -> (f64, String, usize) {
    let (mut max, mut joint, mut over, mut counted) = (0.0, String::new(), 0, None);
    for (f, k, deg) in local_turns(motion, rotating) {
        if deg > max {
            max = deg;
            joint = motion.skeleton.joints()[k].name.clone();
        }
        if deg > over_deg && counted != Some(f) {
            over += 1;
            counted = Some(f);
        }
    }
    (max, joint, over)
}

/// Every frame pair `(f, f + 1)` in which a joint `rotating` marks turns by more than
/// `over_deg` (as [`rotation_jumps`] counts them): `(f, joint index)`, in frame order.
pub fn rotation_jumps_over(motion: &locap_core::Motion, rotating: &[bool], over_deg: f64) -> Vec<(usize, usize)> {
    local_turns(motion, rotating).filter(|&(.., deg)| deg > over_deg).map(|(f, k, _)| (f, k)).collect()
}

/// The wrist joints of the known skeletons and the markers beside them: (joint, markers).
pub const WRISTS: &[(&str, &[&str])] = &[
    ("lhand", &["LWRA", "LWRB"]),
    ("rhand", &["RWRA", "RWRB"]),
    ("hand_l", &["LRAD", "LULN"]),
    ("hand_r", &["RRAD", "RULN"]),
];

/// How well the solved wrists follow their markers: per frame where a wrist's markers are seen,
/// the distance of the wrist joint (of [`WRISTS`]) from the markers' mean; returns the share of
/// such samples within `within_mm` and the largest distance (mm). `None`: no wrist of
/// [`WRISTS`] is in both the motion and the take. The motion is in its Y-up frame; a Z-up take
/// is compared through the lab convention.
pub fn wrists_within(motion: &locap_core::Motion, take: &locap_core::Take, within_mm: f64) -> Option<(f64, f64)> {
    let pairs: Vec<(usize, Vec<usize>)> = WRISTS
        .iter()
        .filter_map(|(joint, markers)| {
            let j = motion.skeleton.index_of(joint)?;
            let m: Vec<usize> = markers.iter().filter_map(|m| take.marker_index(m)).collect();
            (!m.is_empty()).then_some((j, m))
        })
        .collect();
    let (mut near, mut n, mut worst) = (0usize, 0usize, 0.0f64);
    for f in 0..motion.frame_count().min(take.frame_count()) {
        let pose = motion.forward_kinematics(f);
        for (j, markers) in &pairs {
            let seen: Vec<locap_core::Vec3> = markers.iter().filter_map(|&m| take.position_mm(f, m)).collect();
            if seen.is_empty() {
                continue;
            }
            let mean = seen.iter().sum::<locap_core::Vec3>() / seen.len() as f64;
            let p = pose.positions_mm[*j];
            let lab = match take.up_axis {
                locap_core::UpAxis::Z => locap_core::units::y_up_to_z_up(p),
                locap_core::UpAxis::Y => p,
            };
            let d = (lab - mean).norm();
            worst = worst.max(d);
            n += 1;
            if d <= within_mm {
                near += 1;
            }
        }
    }
    (n > 0).then(|| (near as f64 / n as f64, worst))
}

/// A solved motion against a reference solution of the same take (e.g. CMU's own AMC).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotionComparison {
    /// Frames compared (the shorter of the two).
    pub frames: usize,
    /// Joints compared (same name in both skeletons).
    pub joints: usize,
    /// JPE: global joint positions, mm.
    pub jpe_mm: f64,
    /// JPE after moving each frame's solved root onto the reference root (pose error only), mm.
    pub jpe_root_aligned_mm: f64,
    /// Root position error, mm.
    pub root_mm: f64,
    /// JOE over the solver's rotating joints (the root's global rotation included), degrees.
    pub joe_deg: f64,
    /// Per compared joint: name, JPE mm, JOE degrees (`None` where not compared).
    pub per_joint: Vec<(String, f64, Option<f64>)>,
}

/// Compares `solved` with `reference` joint by joint (matched by name; both in the same motion
/// frame and units). JOE is taken over the joints `rotating` marks (by `solved`'s index).
///
/// # Errors
/// No frames or no joint names in common.
pub fn compare_motions(
    solved: &locap_core::Motion,
    reference: &locap_core::Motion,
    rotating: &[bool],
) -> Result<MotionComparison, SolverEvalError> {
    let frames = solved.frame_count().min(reference.frame_count());
    let pairs: Vec<(usize, usize)> = solved
        .skeleton
        .joints()
        .iter()
        .enumerate()
        .filter_map(|(i, j)| reference.skeleton.index_of(&j.name).map(|r| (i, r)))
        .collect();
    if frames == 0 || pairs.is_empty() {
        return Err(SolverEvalError::NothingInCommon);
    }
    let mut jpe = vec![Mean::default(); pairs.len()];
    let mut joe = vec![Mean::default(); pairs.len()];
    let (mut aligned, mut root) = (Mean::default(), Mean::default());
    for f in 0..frames {
        let (a, b) = (solved.forward_kinematics(f), reference.forward_kinematics(f));
        let shift = b.positions_mm[0] - a.positions_mm[0];
        root.add(shift.norm());
        let (la, lb) = (solved.local_rotations(f), reference.local_rotations(f));
        for (k, &(i, r)) in pairs.iter().enumerate() {
            jpe[k].add((a.positions_mm[i] - b.positions_mm[r]).norm());
            aligned.add((a.positions_mm[i] + shift - b.positions_mm[r]).norm());
            if rotating.get(i).copied().unwrap_or(false) {
                joe[k].add(la[i].angle_to(&lb[r]).to_degrees());
            }
        }
    }
    let pooled = |v: &[Mean]| {
        let mut t = Mean::default();
        v.iter().for_each(|m| t.merge(m));
        t.get().unwrap_or(f64::NAN)
    };
    Ok(MotionComparison {
        frames,
        joints: pairs.len(),
        jpe_mm: pooled(&jpe),
        jpe_root_aligned_mm: aligned.get().unwrap_or(f64::NAN),
        root_mm: root.get().unwrap_or(f64::NAN),
        joe_deg: pooled(&joe),
        per_joint: pairs
            .iter()
            .enumerate()
            .map(|(k, &(i, _))| {
                (solved.skeleton.joints()[i].name.clone(), jpe[k].get().unwrap_or(f64::NAN), joe[k].get())
            })
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{EulerOrder, Joint, Motion, Quat, Skeleton, Vec3};

    fn motion(knee_deg: f64, root_x_mm: f64, extra_joint: bool) -> Motion {
        let joint = |name: &str, parent: Option<usize>, y: f64| Joint {
            name: name.into(),
            parent,
            offset_mm: Vec3::new(0.0, y, 0.0),
            rotation_order: EulerOrder::ZXY,
            is_end_site: false,
        };
        let mut joints =
            vec![joint("root", None, 0.0), joint("knee", Some(0), -400.0), joint("ankle", Some(1), -400.0)];
        if extra_joint {
            joints.push(joint("other", Some(0), 100.0));
        }
        let n = joints.len();
        let sk = Skeleton::new(joints).unwrap();
        let mut rot = vec![Quat::identity(); 2 * n];
        rot[1] = EulerOrder::ZXY.to_quat_deg([0.0, knee_deg, 0.0]);
        rot[n + 1] = rot[1];
        Motion::new(sk, rot, vec![Vec3::new(root_x_mm, 900.0, 0.0); 2], 120.0).unwrap()
    }

    #[test]
    fn jumps_are_frame_pairs_of_rotating_joints_over_the_limit() {
        let sk = motion(0.0, 0.0, false).skeleton;
        // The knee at 0, 30, 35 and 5 degrees: jumps of 30, 5 and 30.
        let knee = [0.0, 30.0, 35.0, 5.0];
        let mut rot = vec![Quat::identity(); 3 * knee.len()];
        for (f, deg) in knee.iter().enumerate() {
            rot[3 * f + 1] = EulerOrder::ZXY.to_quat_deg([0.0, *deg, 0.0]);
        }
        let m = Motion::new(sk, rot, vec![Vec3::zeros(); knee.len()], 120.0).unwrap();
        assert_eq!(rotation_jumps_over(&m, &[true, true, true], 20.0), [(0, 1), (2, 1)]);
        assert!(rotation_jumps_over(&m, &[true, false, true], 20.0).is_empty(), "the knee not rotating");
        let (max, joint, over) = rotation_jumps(&m, &[true, true, true], 20.0);
        assert!((max - 30.0).abs() < 1e-9 && joint == "knee" && over == 2, "{max} {joint} {over}");
    }

    #[test]
    fn gap_bins_are_none_then_the_shared_bins() {
        assert_eq!(gap_bin_labels(), ["none", "1-10", "11-30", "31-60", "61-120", "121-240", "241+"]);
        assert_eq!(gap_bin_labels().len(), GAP_BIN_COUNT);
        assert_eq!([gap_bin(0), gap_bin(1), gap_bin(10), gap_bin(11), gap_bin(241), gap_bin(5000)], [0, 1, 1, 2, 6, 6]);
    }

    #[test]
    fn motions_compare_by_joint_name() {
        let truth = motion(0.0, 0.0, true);
        let same = compare_motions(&motion(0.0, 0.0, false), &truth, &[true, true, true]).unwrap();
        assert_eq!((same.frames, same.joints), (2, 3));
        assert!(same.jpe_mm < 1e-9 && same.joe_deg < 1e-6);
        // A root 30 mm off and the knee bent by 90 degrees: the ankle moves 400 * sqrt(2) mm
        // more.
        let off = compare_motions(&motion(90.0, 30.0, false), &truth, &[false, true, false]).unwrap();
        assert!((off.root_mm - 30.0).abs() < 1e-9);
        assert!((off.joe_deg - 90.0).abs() < 1e-6, "only the knee is compared: {off:?}");
        let ankle = off.per_joint.iter().find(|j| j.0 == "ankle").unwrap();
        assert!((ankle.1 - Vec3::new(30.0, 400.0, 400.0).norm()).abs() < 1e-6, "{ankle:?}");
        assert!((off.jpe_root_aligned_mm - 400.0 * 2f64.sqrt() / 3.0).abs() < 1e-6, "{off:?}");
        let other = Skeleton::new(vec![Joint {
            name: "elsewhere".into(),
            parent: None,
            offset_mm: Vec3::zeros(),
            rotation_order: EulerOrder::ZXY,
            is_end_site: false,
        }])
        .unwrap();
        let other = Motion::new(other, vec![Quat::identity(); 2], vec![Vec3::zeros(); 2], 120.0).unwrap();
        assert!(matches!(compare_motions(&other, &truth, &[true]), Err(SolverEvalError::NothingInCommon)));
    }
}
