//! Training a solver (LocalMoCap section 3.2, Eq. 5) on the shards `locap synth` writes, with
//! the harness the refiner trains with too ([`crate::harness`]: Adam with gradient clipping,
//! warm-up and cosine learning rate, validation on held-out frames, checkpoints and resume).
//!
//! * Data: every shard's corrupted markers are cleaned once as `locap solve` cleans a real take
//!   (outliers, then the EDM fill the shipped model was trained with; [`super::data::clean_for_training`])
//!   and put in the waist frame; each
//!   frame is an example (the solver is per frame). The last `validation_fraction` of every take
//!   is held out.
//! * Loss (Eq. 5): `λ_M |Y - Ŷ| + λ_S |S - Ŝ| + λ_FK |FK(Y, S) - FK(Ŷ, Ŝ)|`: mean absolute
//!   difference of the rotation-matrix entries of the rotating joints, mean absolute offset
//!   difference (mm) of the non-root joints, mean joint-position distance (mm) after forward
//!   kinematics from the predicted root. Weights (defaults): `λ_M = 1`, `λ_S = 0.01 / mm`,
//!   `λ_FK = 0.02 / mm` (a rotation-entry error of 0.1, about 6°, costs as much as 5 mm of joint
//!   position).

use super::data::{LocalInput, SolverShard, clean_for_training, frame_truth, marker_joint_distances};
use super::file::{OutputStats, OutputTensors, Solver, SolverMeta};
use super::net::{
    Gathers, MARKER_JOINT_THRESHOLD_MM, MAX_MARKERS_PER_JOINT, MIN_MARKERS_PER_JOINT, NetConfig, SolverArchitecture,
    SolverGraph, SolverNet, Variant, forward_kinematics,
};
use crate::NnError;
use crate::features::{Normalisation, input_values, neighbour_graph};
use crate::harness::{
    Checkpoints, FitConfig, History, LossCurve, OptimizerConfig, Progress, Schedule, StepLoss, Task, fit, rng_for,
};
use burn::prelude::*;
use locap_clean::local_frame::FrameDefinition;
use rand::RngExt;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Settings of a solver training run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolverTrainConfig {
    /// Which network.
    pub variant: Variant,
    /// Frames per step.
    pub batch: usize,
    /// Steps and learning rate.
    #[serde(flatten)]
    pub schedule: Schedule,
    /// Fraction of every take held out for validation.
    pub validation_fraction: f64,
    /// Validation frames (evenly spread over the held-out frames).
    pub validation_frames: usize,
    /// Steps between validations.
    pub validate_every: usize,
    /// Steps between checkpoints (0: only at the end).
    pub checkpoint_every: usize,
    /// Seed.
    pub seed: u64,
    /// Network size and graph.
    #[serde(flatten)]
    pub net: NetConfig,
    /// `λ_M`: rotation term weight.
    pub rotation_weight: f64,
    /// `λ_S`: offset term weight, per mm.
    pub offset_weight_per_mm: f64,
    /// `λ_FK`: forward-kinematics term weight, per mm.
    pub fk_weight_per_mm: f64,
    /// Local frame.
    pub frame: FrameDefinition,
    /// The optimizer (not stored: every model was trained with the default).
    #[serde(skip)]
    pub optimizer: OptimizerConfig,
}

impl Default for SolverTrainConfig {
    /// 256 frames per step, 32 features per node, a 128-wide global node (the MLP is 4 times as
    /// wide, 512: about as many weights as the graph network).
    fn default() -> SolverTrainConfig {
        SolverTrainConfig {
            variant: Variant::Graph,
            batch: 256,
            schedule: Schedule { steps: 3000, learning_rate: 1e-3, warmup_steps: 100 },
            validation_fraction: 0.1,
            validation_frames: 2048,
            validate_every: 100,
            checkpoint_every: 500,
            seed: 1,
            net: NetConfig { channels: 32, global: 128, neighbours: 3, link_threshold_mm: MARKER_JOINT_THRESHOLD_MM },
            rotation_weight: 1.0,
            offset_weight_per_mm: 0.01,
            fk_weight_per_mm: 0.02,
            frame: FrameDefinition::cmu_waist(),
            optimizer: OptimizerConfig::default(),
        }
    }
}

impl SolverTrainConfig {
    /// Checks the settings before anything is allocated: sizes within [`crate::limits`],
    /// rates, fractions and thresholds in range. [`train_solver`] calls it; a command line
    /// can call it first.
    ///
    /// # Errors
    /// [`NnError::Limit`] for a size above its ceiling, [`NnError::Setting`] for others.
    pub fn validate(&self) -> Result<(), NnError> {
        use crate::limits::{self, check};
        let net = &self.net;
        check("batch", self.batch, limits::MAX_BATCH_FRAMES)?;
        check("channels", net.channels, limits::MAX_CHANNELS)?;
        check("global", net.global, limits::MAX_GLOBAL)?;
        check("neighbours", net.neighbours, limits::MAX_NEIGHBOURS)?;
        check("validation frames", self.validation_frames, limits::MAX_VALIDATION_FRAMES)?;
        limits::at_least(1, &[("batch", self.batch), ("channels", net.channels), ("global", net.global)])?;
        limits::at_least(1, &[("neighbours", net.neighbours)])?;
        self.schedule.check()?;
        limits::validation_fraction(self.validation_fraction)?;
        let link = net.link_threshold_mm;
        if !(link.is_finite() && link > 0.0) {
            return Err(NnError::Setting {
                what: "link threshold (mm)",
                value: link.to_string(),
                expected: "positive",
            });
        }
        Ok(())
    }

    /// What the harness needs of these settings.
    pub fn fit(&self) -> FitConfig {
        FitConfig {
            optimizer: self.optimizer,
            ..FitConfig::new(self.schedule, self.validate_every, self.checkpoint_every, self.seed)
        }
    }
}

/// `skeleton` with its end sites after every other joint, each group in its own order (an
/// ASF skeleton's order; a BVH file lists each end site after its parent). Training uses
/// this order whichever shard comes first: trained in the depth-first order of a BVH export,
/// the network learned rotations far worse on the same shards, for a reason not found
/// (docs/benchmarks.md, "Neural solver, third model").
fn end_sites_last(skeleton: &locap_core::Skeleton) -> Option<locap_core::Skeleton> {
    let joints = skeleton.joints();
    let (ends, others): (Vec<usize>, Vec<usize>) = (0..joints.len()).partition(|k| joints[*k].is_end_site);
    let order: Vec<usize> = others.into_iter().chain(ends).collect();
    let at = |k: usize| order.iter().position(|o| *o == k);
    let moved: Option<Vec<locap_core::Joint>> = order
        .iter()
        .map(|&k| {
            let parent = match joints[k].parent {
                Some(p) => Some(at(p)?),
                None => None,
            };
            Some(locap_core::Joint { parent, ..joints[k].clone() })
        })
        .collect();
    locap_core::Skeleton::new(moved?).ok()
}

/// Least rotation (radians, half a degree) that makes a joint one that rotates. A solver's
/// locked joint is not exactly still: `locap solve --method ik` holds the CMU hip joints and
/// clavicles with a stiff penalty, and they jitter by a few hundredths of a degree. Counted
/// as rotating, such a joint's unconstrained 3 x 3 output enters the loss's forward
/// kinematics as a free linear map that the network bends to fit positions below it, and
/// rotations came out 180 degrees off (root, hips, thorax) in a model trained on solved
/// motion.
const ROTATING_MIN_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// One take ready for training: per frame inputs and truth.
#[derive(Debug, Clone)]
struct TakeData {
    frames: usize,
    /// `[T][M][4]`.
    input: Vec<f32>,
    /// `[T][J][9]`.
    rotations: Vec<f32>,
    /// `[T][3]`.
    translation: Vec<f32>,
    /// `[T][J][3]`.
    positions: Vec<f32>,
    /// `[J][3]`.
    offsets: Vec<f32>,
}

/// Training data: shards read and prepared.
#[derive(Debug)]
pub struct SolverData {
    /// Marker labels (model order).
    pub markers: Vec<String>,
    /// The first shard's skeleton (every shard must have its joints and parents).
    pub skeleton: locap_core::Skeleton,
    /// The shards.
    pub shards: Vec<SolverShard>,
}

impl SolverData {
    /// Checks that `shards` share markers, joints and parents, and puts every shard's joints
    /// into one order: the first shard's with its end sites last (`end_sites_last`). A BVH
    /// export of a skeleton lists its end sites among the joints, an ASF after them, and
    /// motion solved from real takes (`locap solve` writes BVH) trains with motion
    /// synthesized from ASF/AMC.
    ///
    /// # Errors
    /// No shards, or shards that differ.
    pub fn new(shards: Vec<SolverShard>) -> Result<SolverData, NnError> {
        let first = shards.first().ok_or(NnError::NoData { what: "training shards" })?;
        let markers: Vec<String> = first.clean.markers().iter().map(|n| n.label.clone()).collect();
        // Cannot fail: end sites are leaves, so every parent still comes first.
        let skeleton = end_sites_last(&first.skeleton).ok_or(NnError::NoData { what: "valid skeleton" })?;
        let first_name = first.name.clone();
        let shards = shards
            .into_iter()
            .map(|s| {
                crate::features::marker_order(&s.clean, &markers)
                    .map_err(|e| NnError::InTake { name: s.name.clone(), source: Box::new(e) })?;
                let name = s.name.clone();
                super::data::in_joint_order(s, &skeleton)
                    .ok_or_else(|| NnError::OtherSkeleton { name, first: first_name.clone() })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(SolverData { markers, skeleton, shards })
    }

    /// Frames of all shards.
    pub fn frames(&self) -> usize {
        self.shards.iter().map(|s| s.clean.frame_count()).sum()
    }
}

/// The history of a run (also stored in the model's metadata).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct SolverReport {
    /// Steps done in total.
    pub steps: usize,
    /// `(step, Eq. 5 training loss)`, averaged over each validation interval.
    pub training_loss: Vec<(usize, f64)>,
    /// `(step, Eq. 5 validation loss)`.
    pub validation_loss: Vec<(usize, f64)>,
    /// `(step, validation joint position error, mm)` (per-frame offsets).
    pub validation_jpe_mm: Vec<(usize, f64)>,
    /// `(step, validation joint rotation error, degrees)`.
    pub validation_joe_deg: Vec<(usize, f64)>,
    /// Weights of the network.
    pub parameters: usize,
    /// Training frames.
    pub training_frames: usize,
    /// Seconds of training steps in this run.
    pub step_seconds: f64,
    /// Steps done in this run.
    pub steps_this_run: usize,
    /// The configuration.
    pub config: Option<SolverTrainConfig>,
}

impl SolverReport {
    /// The loss curve (training and validation Eq. 5 loss).
    pub fn loss_curve(&self) -> LossCurve {
        LossCurve::of("Eq. 5 loss", &[("training", &self.training_loss), ("validation", &self.validation_loss)])
    }
}

/// One validation of a solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverValidation {
    /// Eq. 5 loss.
    pub loss: f64,
    /// Joint position error, mm (per-frame offsets).
    pub jpe_mm: f64,
    /// Joint rotation error, degrees.
    pub joe_deg: f64,
}

/// Progress of a solver run (the loss is Eq. 5's).
pub type SolverProgress = Progress<SolverValidation>;

/// A batch as tensors.
struct Batch {
    x: Tensor<3>,
    rotations: Tensor<4>,
    offsets: Tensor<3>,
    positions: Tensor<3>,
}

impl Batch {
    fn new(takes: &[TakeData], picks: &[(usize, usize)], m: usize, j: usize, device: &Device) -> Batch {
        let n = picks.len();
        let mut x = Vec::with_capacity(n * m * 4);
        let mut rot = Vec::with_capacity(n * j * 9);
        let mut off = Vec::with_capacity(n * j * 3);
        let mut pos = Vec::with_capacity(n * j * 3);
        for &(t, f) in picks {
            let d = &takes[t];
            x.extend_from_slice(&d.input[f * m * 4..(f + 1) * m * 4]);
            rot.extend_from_slice(&d.rotations[f * j * 9..(f + 1) * j * 9]);
            off.extend_from_slice(&d.offsets);
            pos.extend_from_slice(&d.positions[f * j * 3..(f + 1) * j * 3]);
        }
        Batch {
            x: Tensor::from_data(TensorData::new(x, [n, m, 4]), device),
            rotations: Tensor::from_data(TensorData::new(rot, [n, j, 3, 3]), device),
            offsets: Tensor::from_data(TensorData::new(off, [n, j, 3]), device),
            positions: Tensor::from_data(TensorData::new(pos, [n, j, 3]), device),
        }
    }
}

/// What the loss needs besides a batch.
struct LossParts<'a> {
    gathers: Gathers,
    stats: OutputTensors,
    rotating: Tensor<4>,
    /// The identity on joints that do not rotate, zero elsewhere: `[1, J, 3, 3]`.
    fixed: Tensor<4>,
    rotating_count: f32,
    non_root: Tensor<3>,
    parents: Vec<Option<usize>>,
    config: &'a SolverTrainConfig,
}

impl LossParts<'_> {
    /// Eq. 5 and, for reporting, the predicted rotations and positions.
    fn loss(&self, net: &SolverNet, batch: &Batch) -> (Tensor<1>, Tensor<4>, Tensor<3>) {
        let [n, j, _, _] = batch.rotations.dims();
        let (raw, tr) = net.forward(batch.x.clone(), &self.gathers, j);
        let (rot, off, tr) = self.stats.decode(raw, tr);
        // Joints that never rotate are the identity in FK, as at inference: the network must not
        // use their rotation to move their children.
        let rot_fk = rot.clone() * self.rotating.clone() + self.fixed.clone();
        let positions = forward_kinematics(rot_fk, off.clone(), tr, &self.parents);
        let rot_term = ((rot.clone() - batch.rotations.clone()).abs() * self.rotating.clone()).sum()
            / (n as f32 * self.rotating_count * 9.0).max(1.0);
        let off_term = ((off - batch.offsets.clone()).abs() * self.non_root.clone()).sum()
            / (n as f32 * (j as f32 - 1.0).max(1.0) * 3.0);
        let fk_term = ((positions.clone() - batch.positions.clone()).powf_scalar(2.0).sum_dim(2) + 1e-2).sqrt().mean();
        let c = self.config;
        let loss = rot_term * c.rotation_weight as f32
            + off_term * c.offset_weight_per_mm as f32
            + fk_term * c.fk_weight_per_mm as f32;
        (loss, rot, positions)
    }
}

/// Mean joint distance (mm) and mean rotation angle (degrees, rotating joints) between
/// predicted and true values.
fn errors(pred_rot: &[f32], pred_pos: &[f32], batch_rot: &[f32], batch_pos: &[f32], rotating: &[bool]) -> (f64, f64) {
    let j = rotating.len();
    let (mut pos, mut np) = (0.0, 0.0);
    for (a, b) in pred_pos.chunks_exact(3).zip(batch_pos.chunks_exact(3)) {
        pos += (0..3).map(|i| ((a[i] - b[i]) as f64).powi(2)).sum::<f64>().sqrt();
        np += 1.0;
    }
    let (mut ang, mut na) = (0.0, 0.0);
    for (k, (a, b)) in pred_rot.chunks_exact(9).zip(batch_rot.chunks_exact(9)).enumerate() {
        if rotating[k % j] {
            ang += rotation_angle_deg(a, b);
            na += 1.0;
        }
    }
    (pos / f64::max(np, 1.0), ang / f64::max(na, 1.0))
}

/// Geodesic angle between two row-major rotation matrices, degrees.
pub fn rotation_angle_deg(a: &[f32], b: &[f32]) -> f64 {
    let trace: f64 = (0..9).map(|i| a[i] as f64 * b[i] as f64).sum();
    ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
}

/// Everything derived from the training shards: model metadata (without training summary) and
/// the per-take data.
fn prepare(data: &SolverData, config: &SolverTrainConfig) -> Result<(SolverMeta, Vec<TakeData>), NnError> {
    let (m, j) = (data.markers.len(), data.skeleton.len());
    if config.net.neighbours >= m {
        return Err(NnError::TooFewMarkers { neighbours: config.net.neighbours, markers: m });
    }
    let prepared = data
        .shards
        .par_iter()
        .map(|s| -> Result<_, NnError> {
            let cleaned = clean_for_training(&s.observed);
            let input = LocalInput::new(&cleaned, &data.markers, &config.frame)
                .map_err(|e| NnError::InTake { name: s.name.clone(), source: Box::new(e) })?;
            Ok(input)
        })
        .collect::<Result<Vec<LocalInput>, NnError>>()?;
    // Pooled, not per-take centring: the solver needs where the markers are, not only how
    // they move (bone lengths and joint positions come from it).
    let normalisation = Normalisation::of_local_takes(prepared.iter().map(|p| &p.local), m, false);
    // Joints that rotate anywhere in the data.
    let mut rotating = vec![false; j];
    for s in &data.shards {
        for (i, q) in s.rotations.iter().enumerate() {
            if q.angle() > ROTATING_MIN_RAD {
                rotating[i % j] = true;
            }
        }
    }
    for (k, joint) in data.skeleton.joints().iter().enumerate() {
        rotating[k] &= !joint.is_end_site;
    }
    rotating[0] = true;
    let takes: Vec<TakeData> = data
        .shards
        .par_iter()
        .zip(&prepared)
        .map(|(s, p)| {
            let t = p.local.frames;
            let mut d = TakeData {
                frames: t,
                input: Vec::with_capacity(t * m * 4),
                rotations: Vec::with_capacity(t * j * 9),
                translation: Vec::with_capacity(t * 3),
                positions: Vec::with_capacity(t * j * 3),
                offsets: s.skeleton.joints().iter().flat_map(|jj| jj.offset_mm.iter().map(|v| *v as f32)).collect(),
            };
            input_values(&p.local, &p.visible, &normalisation, &normalisation.mean_mm, 0..t, &mut d.input);
            for f in 0..t {
                let truth = frame_truth(s, f, &p.local.frames_local[f]);
                d.rotations.extend(truth.rotations);
                d.translation.extend(truth.translation_mm);
                d.positions.extend(truth.positions_mm);
            }
            d
        })
        .collect();
    drop(prepared);
    // Output statistics.
    let mean_std = |rows: &mut dyn Iterator<Item = [f64; 3]>, floor: f64| {
        let (mut n, mut s, mut sq) = (0.0, [0.0; 3], [0.0; 3]);
        for r in rows {
            n += 1.0;
            for a in 0..3 {
                s[a] += r[a];
                sq[a] += r[a] * r[a];
            }
        }
        let mean = s.map(|v| v / f64::max(n, 1.0));
        let std = [0, 1, 2].map(|a| (sq[a] / f64::max(n, 1.0) - mean[a] * mean[a]).max(0.0).sqrt().max(floor));
        (mean, std)
    };
    let mut offset_mean_mm = Vec::with_capacity(j);
    let mut offset_std_mm = Vec::with_capacity(j);
    for k in 0..j {
        let (mean, std) = mean_std(&mut data.shards.iter().map(|s| s.skeleton.joints()[k].offset_mm.into()), 5.0);
        offset_mean_mm.push(mean);
        offset_std_mm.push(std);
    }
    let (translation_mean_mm, translation_std_mm) = mean_std(
        &mut takes.iter().flat_map(|d| d.translation.chunks_exact(3).map(|t| [t[0], t[1], t[2]].map(|v| v as f64))),
        5.0,
    );
    // The graph.
    let longest = data.shards.iter().max_by_key(|s| s.clean.frame_count()).map(|s| &s.clean);
    let identity: Vec<usize> = (0..m).collect();
    let marker_neighbours = match longest {
        Some(take) => neighbour_graph(take, &identity, config.net.neighbours),
        None => return Err(NnError::NoData { what: "training shards" }),
    };
    let distances = marker_joint_distances(&data.shards, &data.markers, 10);
    let joint_markers = distances
        .iter()
        .map(|row| {
            let mut order: Vec<usize> = (0..m).collect();
            order.sort_by(|a, b| row[*a].total_cmp(&row[*b]));
            order
                .into_iter()
                .enumerate()
                .take_while(|(rank, k)| *rank < MIN_MARKERS_PER_JOINT || row[*k] < config.net.link_threshold_mm)
                .take(MAX_MARKERS_PER_JOINT)
                .map(|(_, k)| k)
                .collect()
        })
        .collect();
    let graph = SolverGraph {
        marker_neighbours,
        joint_markers,
        parents: data.skeleton.joints().iter().map(|jj| jj.parent).collect(),
    };
    let mut skeleton_joints = data.skeleton.joints().to_vec();
    for (joint, mean) in skeleton_joints.iter_mut().zip(&offset_mean_mm) {
        joint.offset_mm = locap_core::Vec3::from(*mean);
    }
    let meta = SolverMeta {
        markers: data.markers.clone(),
        skeleton: locap_core::Skeleton::new(skeleton_joints)?,
        graph,
        frame: config.frame.clone(),
        lab: data.shards[0].lab,
        normalisation,
        outputs: OutputStats { offset_mean_mm, offset_std_mm, translation_mean_mm, translation_std_mm },
        rotating,
        architecture: SolverArchitecture {
            variant: config.variant,
            markers: m,
            joints: j,
            channels: config.net.channels,
            global: if config.variant == Variant::Mlp { 4 * config.net.global } else { config.net.global },
        },
        training: serde_json::Value::Null,
    };
    Ok((meta, takes))
}

/// The solver's training, for the harness.
struct SolverTask<'a> {
    config: &'a SolverTrainConfig,
    meta: SolverMeta,
    takes: Vec<TakeData>,
    train_frames: Vec<(usize, usize)>,
    valid_frames: Vec<(usize, usize)>,
    /// The loss's parts on the training device.
    train_parts: LossParts<'a>,
    /// The report's fixed parts.
    fixed: SolverReport,
}

impl<'a> SolverTask<'a> {
    /// What the loss needs besides a batch, on `device`.
    fn parts(meta: &SolverMeta, config: &'a SolverTrainConfig, device: &Device) -> LossParts<'a> {
        let j = meta.skeleton.len();
        let mask_r: Vec<f32> = meta.rotating.iter().map(|r| if *r { 1.0 } else { 0.0 }).collect();
        let mask_o: Vec<f32> = (0..j).map(|k| if k == 0 { 0.0 } else { 1.0 }).collect();
        let fixed: Vec<f32> =
            mask_r.iter().flat_map(|r| (0..9).map(move |i| if i % 4 == 0 { 1.0 - r } else { 0.0 })).collect();
        LossParts {
            fixed: Tensor::from_data(TensorData::new(fixed, [1, j, 3, 3]), device),
            gathers: Gathers::new(&meta.graph, meta.architecture.variant, device),
            stats: OutputTensors::new(&meta.outputs, device),
            rotating_count: mask_r.iter().sum(),
            rotating: Tensor::from_data(TensorData::new(mask_r, [1, j, 1, 1]), device),
            non_root: Tensor::from_data(TensorData::new(mask_o, [1, j, 1]), device),
            parents: meta.graph.parents.clone(),
            config,
        }
    }
}

impl Task for SolverTask<'_> {
    type Net = SolverNet;
    type Validation = SolverValidation;
    type Report = SolverReport;
    type Model = Solver;
    const CHECKPOINT: &'static str = "checkpoint.locapsv";

    fn init(&self, device: &Device) -> SolverNet {
        SolverNet::new(&self.meta.architecture, &self.meta.graph, device)
    }

    fn loss(&self, net: &SolverNet, step: usize, device: &Device) -> Result<StepLoss, NnError> {
        let (m, j) = (self.meta.markers.len(), self.meta.skeleton.len());
        let mut rng = rng_for(self.config.seed, step as u64, 0);
        let picks: Vec<(usize, usize)> =
            (0..self.config.batch).map(|_| self.train_frames[rng.random_range(0..self.train_frames.len())]).collect();
        let batch = Batch::new(&self.takes, &picks, m, j, device);
        let (loss, _, _) = self.train_parts.loss(net, &batch);
        Ok(StepLoss { loss, learn: true })
    }

    fn validate(&self, net: &SolverNet, device: &Device) -> Option<SolverValidation> {
        if self.valid_frames.is_empty() {
            return None;
        }
        let (m, j) = (self.meta.markers.len(), self.meta.skeleton.len());
        let vp = SolverTask::parts(&self.meta, self.config, device);
        let (mut loss, mut jpe, mut joe, mut n) = (0.0, 0.0, 0.0, 0.0);
        for chunk in self.valid_frames.chunks(512) {
            let batch = Batch::new(&self.takes, chunk, m, j, device);
            let (l, rot, pos) = vp.loss(net, &batch);
            let v = |t: TensorData| t.try_to_vec::<f32>().unwrap_or_default();
            let (p, r) = (v(pos.into_data()), v(rot.into_data()));
            let (bp, br) = (v(batch.positions.into_data()), v(batch.rotations.into_data()));
            let (e_pos, e_rot) = errors(&r, &p, &br, &bp, &self.meta.rotating);
            let w = chunk.len() as f64;
            loss += l.into_scalar::<f32>() as f64 * w;
            jpe += e_pos * w;
            joe += e_rot * w;
            n += w;
        }
        Some(SolverValidation { loss: loss / n, jpe_mm: jpe / n, joe_deg: joe / n })
    }

    fn report(&self, history: &History<SolverValidation>) -> SolverReport {
        let series = |f: fn(&SolverValidation) -> f64| history.validation.iter().map(|(s, v)| (*s, f(v))).collect();
        let mut report = SolverReport {
            training_loss: history.training.clone(),
            validation_loss: series(|v| v.loss),
            validation_jpe_mm: series(|v| v.jpe_mm),
            validation_joe_deg: series(|v| v.joe_deg),
            ..self.fixed.clone()
        };
        (report.steps, report.step_seconds, report.steps_this_run, report.parameters) = history.counts();
        report
    }

    fn history(report: SolverReport) -> History<SolverValidation> {
        let validation = report
            .validation_loss
            .iter()
            .zip(&report.validation_jpe_mm)
            .zip(&report.validation_joe_deg)
            .map(|((&(step, loss), &(_, jpe_mm)), &(_, joe_deg))| (step, SolverValidation { loss, jpe_mm, joe_deg }))
            .collect();
        History { steps: report.steps, training: report.training_loss, validation, ..History::default() }
    }

    fn model(&self, net: SolverNet, training: serde_json::Value, device: &Device) -> Solver {
        Solver::from_parts(SolverMeta { training, ..self.meta.clone() }, net, device)
    }

    fn fits(&self, saved: &Solver) -> bool {
        saved.meta.markers == self.meta.markers && saved.meta.architecture == self.meta.architecture
    }
}

/// Trains a solver on `data`; `progress` is called after every step.
///
/// # Errors
/// Unusable settings or data, a loss that is not finite, or checkpoints that cannot be
/// written or read.
pub fn train_solver(
    data: &SolverData,
    config: &SolverTrainConfig,
    checkpoints: Option<Checkpoints<'_>>,
    progress: &mut dyn FnMut(&SolverProgress),
) -> Result<(Solver, SolverReport), NnError> {
    config.validate()?;
    let (meta, takes) = prepare(data, config)?;
    crate::limits::check_weights(meta.architecture.weights(&meta.graph))?;
    // Frames: the tail of every take is validation.
    let mut train_frames: Vec<(usize, usize)> = Vec::new();
    let mut valid_frames: Vec<(usize, usize)> = Vec::new();
    for (i, d) in takes.iter().enumerate() {
        let held = (d.frames as f64 * config.validation_fraction).ceil() as usize;
        train_frames.extend((0..d.frames - held.min(d.frames)).map(|f| (i, f)));
        valid_frames.extend((d.frames - held.min(d.frames)..d.frames).map(|f| (i, f)));
    }
    if train_frames.is_empty() {
        return Err(NnError::NoData { what: "training frames" });
    }
    let stride = valid_frames.len().div_ceil(config.validation_frames.max(1)).max(1);
    let valid_frames: Vec<(usize, usize)> = valid_frames.into_iter().step_by(stride).collect();
    let device = Device::default().autodiff();
    let task = SolverTask {
        config,
        train_parts: SolverTask::parts(&meta, config, &device),
        fixed: SolverReport {
            training_frames: train_frames.len(),
            config: Some(config.clone()),
            ..SolverReport::default()
        },
        meta,
        takes,
        train_frames,
        valid_frames,
    };
    fit(&task, &config.fit(), &device, checkpoints, progress)
}
