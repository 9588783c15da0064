//! Training the refiner (LocalMoCap section 3.1, Eq. 3) with the shared harness
//! ([`crate::harness`]) on the takes of [`super::data`].
//!
//! * Loss (Eq. 3): the mean distance, mm, between the truth and EDM + offset over the occluded
//!   samples of each window.
//! * Validation: the last `validation_fraction` of every take (at least one segment) is held
//!   out; a fixed set of validation examples (fixed seed, fixed corruption) is scored every
//!   `validate_every` steps, next to EDM alone on the same samples.
//! * Every random draw comes from the seed, the step and the example index
//!   ([`crate::harness::rng_for`]), so a run resumed from a checkpoint draws the same examples
//!   as one that never stopped.

use super::data::{Batch, Example, Sampler, TrainingData};
use super::file::{ModelMeta, Refiner};
use super::net::{NetConfig, RefinerNet, gather_indices};
use crate::NnError;
use crate::features::{LocalTake, Normalisation, neighbour_graph};
use crate::harness::{
    Checkpoints, FitConfig, History, LossCurve, OptimizerConfig, Progress, Schedule, StepLoss, Task, fit, rng_for,
};
use burn::prelude::*;
use locap_clean::FillMethod;
use locap_clean::local_frame::FrameDefinition;
use locap_synth::augment::AugmentConfig;
use locap_synth::gap_model::GapModel;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Settings of a training run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    /// Frames per window (the paper: 64).
    pub window: usize,
    /// Context frames on each side of a training window for augmentation and EDM.
    pub margin: usize,
    /// Windows per step.
    pub batch: usize,
    /// Steps and learning rate.
    #[serde(flatten)]
    pub schedule: Schedule,
    /// Fraction of every take held out for validation (0: none).
    pub validation_fraction: f64,
    /// Validation examples.
    pub validation_windows: usize,
    /// Steps between validations (and loss-curve points).
    pub validate_every: usize,
    /// Steps between checkpoints (0: only at the end).
    pub checkpoint_every: usize,
    /// Seed of every random draw.
    pub seed: u64,
    /// Corruption of training windows (Eq. 6).
    pub augment: AugmentConfig,
    /// Network size.
    #[serde(flatten)]
    pub net: NetConfig,
    /// `K` of the EDM fill.
    pub edm_neighbours: usize,
    /// Local frame.
    pub frame: FrameDefinition,
    /// Centre every marker's input on its own take's mean (see [`crate::features`]).
    #[serde(default)]
    pub per_take_centre: bool,
    /// The fill the refiner corrects: EDM, or linear for the "w/o EDM" ablation.
    #[serde(default = "edm_init")]
    pub init: FillMethod,
    /// Offsets fade in over this many frames from a gap's borders (see
    /// [`crate::features::offset_taper`]); the loss sees the faded offsets, as inference does.
    #[serde(default)]
    pub taper_frames: usize,
    /// The fade written into the model for inference, if not `taper_frames`: a network trained
    /// with a short fade may serve better with a longer one (chosen on held-out takes).
    #[serde(default)]
    pub inference_taper_frames: Option<usize>,
    /// The optimizer (not stored: every model was trained with the default).
    #[serde(skip)]
    pub optimizer: OptimizerConfig,
}

fn edm_init() -> FillMethod {
    FillMethod::Edm
}

impl Default for TrainConfig {
    /// The default model: 64-frame windows, batch 16, 16 features per marker, LSTM 128 per
    /// direction (about 0.9 M weights, 3.6 MB for 41 markers), 10% occlusion.
    fn default() -> TrainConfig {
        TrainConfig {
            window: 64,
            margin: 32,
            batch: 16,
            schedule: Schedule { steps: 2000, learning_rate: 1e-3, warmup_steps: 50 },
            validation_fraction: 0.1,
            validation_windows: 64,
            validate_every: 50,
            checkpoint_every: 200,
            seed: 1,
            augment: AugmentConfig { missing_fraction: Some(0.1), ..AugmentConfig::default() },
            net: NetConfig { channels: 16, hidden: 128, neighbours: 6 },
            edm_neighbours: 6,
            frame: FrameDefinition::cmu_waist(),
            per_take_centre: true,
            init: FillMethod::Edm,
            taper_frames: 20,
            inference_taper_frames: None,
            optimizer: OptimizerConfig::default(),
        }
    }
}

impl TrainConfig {
    /// Checks the settings before anything is allocated: sizes within [`crate::limits`],
    /// rates and fractions in range. [`train`] calls it; a command line can call it first.
    ///
    /// # Errors
    /// [`NnError::Limit`] for a size above its ceiling, [`NnError::Setting`] for others.
    pub fn validate(&self) -> Result<(), NnError> {
        use crate::limits::{self, check};
        let net = &self.net;
        check("window", self.window, limits::MAX_WINDOW)?;
        check("margin", self.margin, limits::MAX_WINDOW)?;
        check("batch", self.batch, limits::MAX_BATCH_WINDOWS)?;
        check("channels", net.channels, limits::MAX_CHANNELS)?;
        check("hidden", net.hidden, limits::MAX_HIDDEN)?;
        check("neighbours", net.neighbours, limits::MAX_NEIGHBOURS)?;
        check("EDM neighbours", self.edm_neighbours, limits::MAX_NEIGHBOURS)?;
        check("validation windows", self.validation_windows, limits::MAX_VALIDATION_WINDOWS)?;
        if self.window < 2 {
            return Err(NnError::Setting { what: "window", value: self.window.to_string(), expected: "2 or more" });
        }
        limits::at_least(1, &[("batch", self.batch), ("channels", net.channels), ("hidden", net.hidden)])?;
        limits::at_least(1, &[("neighbours", net.neighbours)])?;
        self.schedule.check()?;
        if !matches!(self.init, FillMethod::Edm | FillMethod::Linear) {
            let init = self.init.name().to_string();
            return Err(NnError::Setting { what: "initial fill", value: init, expected: "edm or linear" });
        }
        limits::validation_fraction(self.validation_fraction)?;
        Ok(())
    }

    /// Frames of one training segment (window and both margins).
    pub fn segment(&self) -> usize {
        self.window + 2 * self.margin
    }

    /// What the harness needs of these settings.
    pub fn fit(&self) -> FitConfig {
        FitConfig {
            optimizer: self.optimizer,
            ..FitConfig::new(self.schedule, self.validate_every, self.checkpoint_every, self.seed)
        }
    }
}

/// The history and figures of a run (also stored in the model's metadata).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct TrainReport {
    /// Steps done in total (including those before a resume).
    pub steps: usize,
    /// `(step, training loss mm)`, averaged over each validation interval.
    pub training_mm: Vec<(usize, f64)>,
    /// `(step, validation loss mm)`.
    pub validation_mm: Vec<(usize, f64)>,
    /// EDM alone on the validation samples, mm.
    pub edm_validation_mm: Option<f64>,
    /// Occluded samples in the validation set.
    pub validation_samples: usize,
    /// Weights of the network.
    pub parameters: usize,
    /// Training frames.
    pub training_frames: usize,
    /// Wall-clock seconds of training steps in this run (without validation).
    pub step_seconds: f64,
    /// Steps done in this run.
    pub steps_this_run: usize,
    /// The configuration.
    pub config: Option<TrainConfig>,
}

impl TrainReport {
    /// The loss curve: training, validation and EDM alone.
    pub fn loss_curve(&self) -> LossCurve {
        let edm = match (self.edm_validation_mm, self.training_mm.first(), self.training_mm.last()) {
            (Some(edm), Some(first), Some(last)) => vec![(first.0, edm), (last.0, edm)],
            _ => Vec::new(),
        };
        let series = [
            ("training", &self.training_mm[..]),
            ("validation", &self.validation_mm),
            ("EDM alone (validation)", &edm),
        ];
        LossCurve::of("mean error of occluded samples, mm (Eq. 3)", &series)
    }
}

/// Progress of a refiner run: the loss and validation are in mm.
pub type RefinerProgress = Progress<f64>;

/// The refiner's training, for the harness.
struct RefinerTask<'a> {
    config: &'a TrainConfig,
    meta: ModelMeta,
    sampler: Sampler<'a>,
    valid_examples: Vec<Example>,
    /// Frames of a batch's windows.
    window: usize,
    markers: usize,
    std_values: Vec<f32>,
    gather: Tensor<1, Int>,
    std_mm: Tensor<4>,
    /// The report's fixed parts.
    fixed: TrainReport,
}

impl Batch {
    /// Eq. 3: mean over the occluded samples of `|truth - (EDM + offset)|`, mm.
    fn loss(&self, net: &RefinerNet, gather: Tensor<1, Int>, std_mm: Tensor<4>) -> Tensor<1> {
        let offset = net.forward(self.x.clone(), gather) * std_mm * self.taper.clone();
        let diff = self.truth.clone() - self.edm.clone() - offset;
        let dist = (diff.powf_scalar(2.0).sum_dim(3) + 1e-2).sqrt();
        (dist * self.mask.clone()).sum() / self.samples.max(1.0)
    }

    /// The loss with zero offsets (EDM alone), mm.
    fn edm_loss(examples: &[Example]) -> (f64, f64) {
        let mut sum = 0.0;
        let mut n = 0.0;
        for e in examples {
            for (k, &m) in e.mask.iter().enumerate() {
                if m > 0.0 {
                    let d: f64 =
                        (0..3).map(|a| (e.truth_mm[3 * k + a] - e.edm_mm[3 * k + a]) as f64).map(|v| v * v).sum();
                    sum += d.sqrt();
                    n += 1.0;
                }
            }
        }
        (sum, n)
    }
}

impl Task for RefinerTask<'_> {
    type Net = RefinerNet;
    type Validation = f64;
    type Report = TrainReport;
    type Model = Refiner;
    const CHECKPOINT: &'static str = "checkpoint.locapnn";

    fn init(&self, device: &Device) -> RefinerNet {
        RefinerNet::new(&self.meta.architecture, device)
    }

    fn loss(&self, net: &RefinerNet, step: usize, device: &Device) -> Result<StepLoss, NnError> {
        let config = self.config;
        let examples: Vec<Example> = (0..config.batch)
            .into_par_iter()
            .filter_map(|i| self.sampler.example(&mut rng_for(config.seed, step as u64, i as u64)))
            .collect();
        if examples.is_empty() {
            return Err(NnError::NoExamples);
        }
        let batch = Batch::new(&examples, self.window, self.markers, device);
        let loss = batch.loss(net, self.gather.clone(), self.std_mm.clone());
        Ok(StepLoss { loss, learn: batch.samples > 0.0 })
    }

    fn validate(&self, net: &RefinerNet, device: &Device) -> Option<f64> {
        if self.valid_examples.is_empty() {
            return None;
        }
        let m = self.markers;
        let gather = gather_indices(&self.meta.neighbours, device);
        let std_mm = Tensor::<4>::from_data(TensorData::new(self.std_values.clone(), [1, 1, m, 3]), device);
        let (mut sum, mut n) = (0.0, 0.0);
        for chunk in self.valid_examples.chunks(self.config.batch.max(16)) {
            let b = Batch::new(chunk, self.window, m, device);
            let loss: f32 = b.loss(net, gather.clone(), std_mm.clone()).into_scalar();
            sum += loss as f64 * b.samples as f64;
            n += b.samples as f64;
        }
        (n > 0.0).then(|| sum / n)
    }

    fn report(&self, history: &History<f64>) -> TrainReport {
        let (training_mm, validation_mm) = (history.training.clone(), history.validation.clone());
        let mut report = TrainReport { training_mm, validation_mm, ..self.fixed.clone() };
        (report.steps, report.step_seconds, report.steps_this_run, report.parameters) = history.counts();
        report
    }

    fn history(report: TrainReport) -> History<f64> {
        History {
            steps: report.steps,
            training: report.training_mm,
            validation: report.validation_mm,
            ..History::default()
        }
    }

    fn model(&self, net: RefinerNet, training: serde_json::Value, device: &Device) -> Refiner {
        Refiner::from_parts(ModelMeta { training, ..self.meta.clone() }, net, device)
    }

    fn fits(&self, saved: &Refiner) -> bool {
        saved.meta.markers == self.meta.markers && saved.meta.architecture == self.meta.architecture
    }
}

/// Trains a refiner on `data`; `progress` is called after every step. Returns the trained
/// refiner (its metadata carries the report) and the report.
///
/// # Errors
/// Unusable settings or data (takes shorter than a window, no frame where the local frame is
/// defined), a loss that is not finite, or checkpoints that cannot be written or read.
pub fn train(
    data: &TrainingData,
    config: &TrainConfig,
    gap_model: &GapModel,
    checkpoints: Option<Checkpoints<'_>>,
    progress: &mut dyn FnMut(&RefinerProgress),
) -> Result<(Refiner, TrainReport), NnError> {
    config.validate()?;
    let m = data.markers.len();
    if config.net.neighbours >= m {
        return Err(NnError::TooFewMarkers { neighbours: config.net.neighbours, markers: m });
    }
    // Split every take: the tail is validation.
    let seg = config.segment();
    let mut train_ranges = Vec::new();
    let mut valid_ranges = Vec::new();
    for (i, take) in data.takes.iter().enumerate() {
        let t = take.frame_count();
        let held = if config.validation_fraction > 0.0 && t >= 3 * seg {
            ((t as f64 * config.validation_fraction).ceil() as usize).max(seg)
        } else {
            0
        };
        if t - held >= config.window {
            train_ranges.push((i, 0, t - held));
        }
        if held > 0 {
            valid_ranges.push((i, t - held, held));
        }
    }
    if train_ranges.is_empty() {
        return Err(NnError::TooShortForWindow { window: config.window });
    }
    if config.validation_fraction > 0.0 && valid_ranges.is_empty() {
        return Err(NnError::TooShortForValidation { needed: 3 * seg });
    }
    // Graph and normalisation from the clean training frames.
    let identity: Vec<usize> = (0..m).collect();
    let locals = data
        .takes
        .par_iter()
        .map(|take| LocalTake::of_take(take, &identity, &config.frame))
        .collect::<Result<Vec<_>, _>>()?;
    let norm = Normalisation::of_local_takes(&locals, m, config.per_take_centre);
    let centres: Vec<Vec<[f64; 3]>> = locals.iter().map(|l| norm.centres(l, None)).collect();
    let longest =
        data.takes.iter().max_by_key(|t| t.frame_count()).ok_or(NnError::NoData { what: "training takes" })?;
    let graph = neighbour_graph(longest, &identity, config.net.neighbours);
    let architecture = config.net.architecture(m);
    crate::limits::check_weights(architecture.weights())?;
    let meta = ModelMeta {
        markers: data.markers.clone(),
        neighbours: graph.clone(),
        frame: config.frame.clone(),
        normalisation: norm.clone(),
        window: config.window,
        edm_neighbours: config.edm_neighbours,
        init: config.init,
        taper_frames: config.inference_taper_frames.unwrap_or(config.taper_frames),
        architecture,
        training: serde_json::Value::Null,
    };

    let sampler = |ranges| Sampler {
        config,
        gap_model,
        norm: &norm,
        identity: identity.clone(),
        ranges,
        takes: &data.takes,
        centres: &centres,
    };
    let valid_sampler = sampler(valid_ranges);
    let valid_examples: Vec<Example> =
        (0..if config.validation_fraction > 0.0 { config.validation_windows } else { 0 })
            .into_par_iter()
            .filter_map(|i| valid_sampler.example(&mut rng_for(config.seed ^ 0x5EED, u64::MAX, i as u64)))
            .collect();
    let mut fixed = TrainReport {
        training_frames: train_ranges.iter().map(|r| r.2).sum(),
        config: Some(config.clone()),
        ..TrainReport::default()
    };
    if !valid_examples.is_empty() {
        let (sum, n) = Batch::edm_loss(&valid_examples);
        fixed.edm_validation_mm = (n > 0.0).then(|| sum / n);
        fixed.validation_samples = n as usize;
    }
    let window = config.window.min(config.segment().min(data.takes.iter().map(|t| t.frame_count()).max().unwrap_or(0)));
    let device = Device::default().autodiff();
    let std_values: Vec<f32> = norm.std_mm.iter().flatten().map(|v| *v as f32).collect();
    let task = RefinerTask {
        config,
        sampler: sampler(train_ranges),
        valid_examples,
        window,
        markers: m,
        gather: gather_indices(&graph, &device),
        std_mm: Tensor::<4>::from_data(TensorData::new(std_values.clone(), [1, 1, m, 3]), &device),
        std_values,
        fixed,
        meta,
    };
    fit(&task, &config.fit(), &device, checkpoints, progress)
}
