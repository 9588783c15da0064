//! The one training harness of both networks (the refiner of LocalMoCap section 3.1, Eq. 3;
//! the solver of section 3.2, Eq. 5), in the manner of burn's learner: a task says what a
//! network, a step's loss, a validation and a model file are ([`Task`]); [`fit`] does the rest
//! once for both.
//!
//! * Adam with gradient-norm clipping ([`OptimizerConfig`]); the learning rate warmed up
//!   linearly, then cosine-decayed to a tenth ([`Schedule`]).
//! * Every `validate_every` steps (and at the last step) the mean training loss of the
//!   interval and a validation go into the run's [`History`].
//! * A step whose loss is not finite stops the run ([`NnError::NonFiniteLoss`]): its gradients
//!   would spoil the weights for every later step.
//! * Checkpoints (the model file of the run so far and Adam's state) go to a [`Checkpointer`]
//!   the caller provides every `checkpoint_every` steps and at the end; a resumed run continues
//!   from them. Tasks draw every random example from the seed, the step and the example index
//!   ([`rng_for`]), so a resumed run sees the examples a run that never stopped would have seen.

use crate::NnError;
use burn::grad_clipping::GradientClippingConfig;
use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::prelude::*;
use burn::tensor::Bytes;
use rand::SeedableRng;
use rand::rngs::StdRng;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::Mutex;
use std::time::Instant;

/// The learning-rate schedule: linear warm-up over `warmup_steps`, then cosine decay to a
/// tenth of `learning_rate` at `steps`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Schedule {
    /// Optimisation steps of the run.
    pub steps: usize,
    /// Peak learning rate.
    pub learning_rate: f64,
    /// Steps of linear warm-up.
    pub warmup_steps: usize,
}

impl Schedule {
    /// Checks the learning rate.
    ///
    /// # Errors
    /// [`NnError::Setting`] unless it is finite and positive.
    pub fn check(&self) -> Result<(), NnError> {
        let lr = self.learning_rate;
        if lr.is_finite() && lr > 0.0 {
            return Ok(());
        }
        Err(NnError::Setting { what: "learning rate", value: lr.to_string(), expected: "positive" })
    }

    /// Learning rate at `step` (0-based).
    pub fn at(&self, step: usize) -> f64 {
        if step < self.warmup_steps {
            return self.learning_rate * (step + 1) as f64 / self.warmup_steps as f64;
        }
        let span = self.steps.saturating_sub(self.warmup_steps).max(1) as f64;
        let progress = ((step - self.warmup_steps) as f64 / span).min(1.0);
        self.learning_rate * (0.1 + 0.9 * 0.5 * (1.0 + (std::f64::consts::PI * progress).cos()))
    }
}

/// The optimizer: Adam with its gradients clipped to a norm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OptimizerConfig {
    /// Largest gradient norm (larger gradients are scaled down to it).
    pub clip_norm: f32,
}

impl Default for OptimizerConfig {
    /// A norm of 1, which both networks were tuned with.
    fn default() -> OptimizerConfig {
        OptimizerConfig { clip_norm: 1.0 }
    }
}

impl OptimizerConfig {
    fn init(&self) -> ModuleOptimizer {
        AdamConfig::new().with_grad_clipping(Some(GradientClippingConfig::Norm(self.clip_norm))).init()
    }
}

/// What [`fit`] needs to know of a run, besides the task.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitConfig {
    /// The learning rate per step, and the run's length.
    pub schedule: Schedule,
    /// The optimizer.
    pub optimizer: OptimizerConfig,
    /// Steps between validations (and loss-curve points).
    pub validate_every: usize,
    /// Steps between checkpoints (0: only at the end).
    pub checkpoint_every: usize,
    /// Seed of the initial weights.
    pub seed: u64,
}

impl FitConfig {
    /// The default optimizer with `schedule`, validations every `validate_every` steps,
    /// checkpoints every `checkpoint_every`, initial weights from `seed`.
    pub fn new(schedule: Schedule, validate_every: usize, checkpoint_every: usize, seed: u64) -> FitConfig {
        FitConfig { schedule, optimizer: OptimizerConfig::default(), validate_every, checkpoint_every, seed }
    }
}

/// Where checkpoints are kept: named entries of bytes. `locap train` keeps them in a folder,
/// written atomically; tests keep them in memory ([`MemoryCheckpointer`]).
pub trait Checkpointer {
    /// The bytes last saved under `name`, or `None` if nothing was.
    ///
    /// # Errors
    /// The entry exists but cannot be read.
    fn load(&self, name: &str) -> std::io::Result<Option<Vec<u8>>>;

    /// Saves `bytes` under `name`, replacing what was there. A crash while saving must leave
    /// the previous entry whole (a half-written checkpoint cannot be resumed).
    ///
    /// # Errors
    /// The entry cannot be written.
    fn save(&self, name: &str, bytes: &[u8]) -> std::io::Result<()>;

    /// Where `name` is kept, for messages (a path).
    fn location(&self, name: &str) -> String;
}

/// Checkpoints kept in memory.
#[derive(Debug, Default)]
pub struct MemoryCheckpointer {
    entries: Mutex<BTreeMap<String, Vec<u8>>>,
}

impl Checkpointer for MemoryCheckpointer {
    fn load(&self, name: &str) -> std::io::Result<Option<Vec<u8>>> {
        Ok(self.entries.lock().unwrap_or_else(|e| e.into_inner()).get(name).cloned())
    }

    fn save(&self, name: &str, bytes: &[u8]) -> std::io::Result<()> {
        self.entries.lock().unwrap_or_else(|e| e.into_inner()).insert(name.to_string(), bytes.to_vec());
        Ok(())
    }

    fn location(&self, name: &str) -> String {
        format!("memory:{name}")
    }
}

/// The checkpoints of a run.
#[derive(Clone, Copy)]
pub struct Checkpoints<'a> {
    /// Where they are kept.
    pub store: &'a dyn Checkpointer,
    /// Continue from the checkpoint in `store` if there is one.
    pub resume: bool,
}

/// Name of Adam's state in the checkpoint store.
pub const OPTIMIZER_STATE: &str = "optimizer.bin";

/// The loss of one step.
pub struct StepLoss {
    /// The loss, a scalar tensor on the training device.
    pub loss: Tensor<1>,
    /// Whether the step teaches anything (a batch without a scored sample does not: the
    /// optimizer is not stepped, so Adam's state does not move).
    pub learn: bool,
}

/// The history of a run: what [`fit`] records and a checkpoint carries on.
#[derive(Debug, Clone, PartialEq)]
pub struct History<V> {
    /// Steps done in total (including those before a resume).
    pub steps: usize,
    /// `(step, mean training loss)` over each validation interval.
    pub training: Vec<(usize, f64)>,
    /// `(step, validation)`.
    pub validation: Vec<(usize, V)>,
    /// Wall-clock seconds of training steps in this run (without validation).
    pub step_seconds: f64,
    /// Steps done in this run.
    pub steps_this_run: usize,
    /// Weights of the network.
    pub parameters: usize,
}

impl<V> History<V> {
    /// Steps in total, seconds of this run's steps, steps of this run, weights: what a
    /// report keeps of the run besides its curves.
    pub fn counts(&self) -> (usize, f64, usize, usize) {
        (self.steps, self.step_seconds, self.steps_this_run, self.parameters)
    }
}

impl<V> Default for History<V> {
    fn default() -> History<V> {
        History {
            steps: 0,
            training: Vec::new(),
            validation: Vec::new(),
            step_seconds: 0.0,
            steps_this_run: 0,
            parameters: 0,
        }
    }
}

/// Progress of a run, given to the caller's callback after every step.
#[derive(Debug, Clone, PartialEq)]
pub struct Progress<V> {
    /// Steps done.
    pub step: usize,
    /// Steps in the run.
    pub steps: usize,
    /// Training loss of this step.
    pub loss: f64,
    /// Learning rate of this step.
    pub learning_rate: f64,
    /// The validation, if validated at this step.
    pub validation: Option<V>,
}

/// A loss curve as data series, for a caller to draw: each series is a name and its
/// `(step, loss)` points.
#[derive(Debug, Clone, PartialEq)]
pub struct LossCurve {
    /// What the losses are (the y axis).
    pub loss: &'static str,
    /// The series.
    pub series: Vec<(String, Vec<(f64, f64)>)>,
}

impl LossCurve {
    /// The curve of `series` (name, `(step, loss)` points); series without points are left
    /// out.
    pub fn of(loss: &'static str, series: &[(&str, &[(usize, f64)])]) -> LossCurve {
        let series = series
            .iter()
            .filter(|(_, points)| !points.is_empty())
            .map(|(name, points)| (name.to_string(), points.iter().map(|(s, l)| (*s as f64, *l)).collect()))
            .collect();
        LossCurve { loss, series }
    }
}

/// A trained model as [`fit`] saves and resumes it: a network and its metadata, whose
/// `training` entry holds the run's report.
pub trait Model: Sized {
    /// The network.
    type Net: Module;

    /// The model file.
    ///
    /// # Errors
    /// The weights cannot be serialised.
    fn to_bytes(&self) -> Result<Vec<u8>, NnError>;

    /// Reads a model file onto `device`.
    ///
    /// # Errors
    /// Not a model file of this kind, or a damaged one.
    fn from_bytes(bytes: &[u8], device: &Device) -> Result<Self, NnError>;

    /// The network and the metadata's `training` entry.
    fn into_parts(self) -> (Self::Net, serde_json::Value);
}

/// What one network's training is, for [`fit`].
pub trait Task {
    /// The network.
    type Net: Module;
    /// What one validation measures.
    type Validation: Clone;
    /// The report stored in the model file.
    type Report: Serialize + DeserializeOwned;
    /// The trained model.
    type Model: Model<Net = Self::Net>;
    /// Name of the model file in the checkpoint store.
    const CHECKPOINT: &'static str;

    /// A freshly initialised network on `device` (seeded by [`fit`]).
    fn init(&self, device: &Device) -> Self::Net;

    /// The loss of step `step` (0-based) of `net` on `device` (autodiff).
    ///
    /// # Errors
    /// No example can be built.
    fn loss(&self, net: &Self::Net, step: usize, device: &Device) -> Result<StepLoss, NnError>;

    /// Scores `net` (without autodiff, on `device`) on the held-out data; `None` without any.
    fn validate(&self, net: &Self::Net, device: &Device) -> Option<Self::Validation>;

    /// The report of the run so far.
    fn report(&self, history: &History<Self::Validation>) -> Self::Report;

    /// The curves of a report, to continue them (the inverse of [`Task::report`] on them).
    fn history(report: Self::Report) -> History<Self::Validation>;

    /// `net` as a model of this run whose metadata's `training` entry is `training`.
    fn model(&self, net: Self::Net, training: serde_json::Value, device: &Device) -> Self::Model;

    /// Whether a checkpoint's model is of this run (same markers and network size).
    fn fits(&self, saved: &Self::Model) -> bool;
}

/// Trains `task`'s network on `device` (an autodiff device) as `config` says, with
/// `checkpoints` if given; `progress` is called after every step. Returns the model (its
/// network on `device` without autodiff) and the report.
///
/// # Errors
/// The task's errors, a loss that is not finite, checkpoints that cannot be read, written or
/// resumed.
pub fn fit<T: Task>(
    task: &T,
    config: &FitConfig,
    device: &Device,
    checkpoints: Option<Checkpoints<'_>>,
    progress: &mut dyn FnMut(&Progress<T::Validation>),
) -> Result<(T::Model, T::Report), NnError> {
    device.seed(config.seed);
    let mut net = task.init(device);
    let mut optimizer = config.optimizer.init();
    let mut history = History { parameters: net.num_params(), ..History::default() };
    if let Some(cp) = checkpoints
        && cp.resume
        && let Some(bytes) = load(cp.store, T::CHECKPOINT)?
    {
        let at = cp.store.location(T::CHECKPOINT);
        let (saved, previous) =
            resume(task, &bytes, device).map_err(|e| NnError::Checkpoint { at, source: Box::new(e) })?;
        let at = cp.store.location(OPTIMIZER_STATE);
        let state = load(cp.store, OPTIMIZER_STATE)?.ok_or_else(|| NnError::MissingCheckpoint { at: at.clone() })?;
        optimizer = optimizer
            .from_bytes(Bytes::from_bytes_vec(state))
            .map_err(|source| NnError::OptimizerState { at, source })?;
        net = saved;
        // Only the curves carry on: this run's timing starts afresh.
        history =
            History { steps: previous.steps, training: previous.training, validation: previous.validation, ..history };
    }
    let inner = device.clone().without_autodiff();
    let steps = config.schedule.steps;
    let mut interval = (0.0, 0usize);
    for step in history.steps..steps {
        let started = Instant::now();
        let StepLoss { loss, learn } = task.loss(&net, step, device)?;
        let learning_rate = config.schedule.at(step);
        let value: f32 = loss.clone().into_scalar();
        if !value.is_finite() {
            return Err(NnError::NonFiniteLoss { step });
        }
        if learn {
            let grads = GradientsParams::from_grads(loss.backward(), &net);
            net = optimizer.step(learning_rate, net, grads);
        }
        history.step_seconds += started.elapsed().as_secs_f64();
        history.steps_this_run += 1;
        history.steps = step + 1;
        interval.0 += value as f64;
        interval.1 += 1;
        let done = step + 1 == steps;
        let mut validation = None;
        if (step + 1) % config.validate_every.max(1) == 0 || done {
            history.training.push((step + 1, interval.0 / interval.1 as f64));
            interval = (0.0, 0);
            validation = task.validate(&net.valid(), &inner);
            if let Some(v) = &validation {
                history.validation.push((step + 1, v.clone()));
            }
        }
        progress(&Progress { step: step + 1, steps, loss: value as f64, learning_rate, validation });
        if let Some(cp) = checkpoints
            && ((config.checkpoint_every > 0 && (step + 1) % config.checkpoint_every == 0) || done)
        {
            let model = task.model(net.clone(), report_value(&task.report(&history))?, device);
            save(cp.store, T::CHECKPOINT, &model.to_bytes()?)?;
            let at = cp.store.location(OPTIMIZER_STATE);
            let state = optimizer.into_bytes().map_err(|source| NnError::OptimizerState { at, source })?;
            save(cp.store, OPTIMIZER_STATE, &state)?;
        }
    }
    let report = task.report(&history);
    let model = task.model(net.valid(), report_value(&report)?, &inner);
    Ok((model, report))
}

/// The network and history of the checkpoint model `bytes`, onto `device`.
fn resume<T: Task>(task: &T, bytes: &[u8], device: &Device) -> Result<(T::Net, History<T::Validation>), NnError> {
    let saved = T::Model::from_bytes(bytes, device)?;
    if !task.fits(&saved) {
        return Err(NnError::CheckpointMismatch);
    }
    let (net, training) = saved.into_parts();
    let previous =
        serde_json::from_value(training).map_err(|e| NnError::BadModel(format!("checkpoint report: {e}")))?;
    Ok((net, T::history(previous)))
}

fn load(store: &dyn Checkpointer, name: &str) -> Result<Option<Vec<u8>>, NnError> {
    store.load(name).map_err(|source| NnError::CheckpointIo { at: store.location(name), source })
}

fn save(store: &dyn Checkpointer, name: &str, bytes: &[u8]) -> Result<(), NnError> {
    store.save(name, bytes).map_err(|source| NnError::CheckpointIo { at: store.location(name), source })
}

/// A stream of independent generators: example `index` of step `step`.
pub fn rng_for(seed: u64, step: u64, index: u64) -> StdRng {
    // SplitMix64 finaliser over the three numbers.
    let mut z = seed ^ step.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    StdRng::seed_from_u64(z ^ (z >> 31))
}

/// A report as a model's metadata `training` entry.
fn report_value(report: &impl Serialize) -> Result<serde_json::Value, NnError> {
    serde_json::to_value(report).map_err(NnError::Report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_schedule_warms_up_then_decays_to_a_tenth() {
        let s = Schedule { steps: 100, learning_rate: 1.0, warmup_steps: 10 };
        assert_eq!(s.at(0), 0.1);
        assert_eq!(s.at(9), 1.0);
        assert_eq!(s.at(10), 1.0);
        assert!((s.at(55) - 0.55).abs() < 1e-12);
        assert!((s.at(100) - 0.1).abs() < 1e-12);
        assert!((s.at(1000) - 0.1).abs() < 1e-12);
    }

    #[test]
    fn memory_checkpoints_keep_the_last_save() {
        let store = MemoryCheckpointer::default();
        assert_eq!(store.load("a").unwrap(), None);
        store.save("a", b"1").unwrap();
        store.save("a", b"22").unwrap();
        assert_eq!(store.load("a").unwrap().as_deref(), Some(&b"22"[..]));
    }
}
