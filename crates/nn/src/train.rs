//! Training the refiner (LocalMoCap section 3.1, Eq. 3) on the shards `locap synth` writes.
//!
//! * Data: the clean (ground-truth) markers of every shard are read once, chunk by chunk
//!   ([`ShardReader`]); the corrupted copy in the shard is not used, because every training
//!   window is corrupted afresh ([`locap_synth::augment::augment`], Eq. 6 gaps and shifts), so
//!   the network never sees the same occlusions twice. All shards must carry the same markers
//!   (in any order).
//! * A training example is a random segment of `window + 2 * margin` frames: augmented, filled
//!   by EDM (the margins give EDM the context a real take gives it), turned to the waist frame,
//!   and cut to its central `window` frames. The loss (Eq. 3) is the mean distance, mm, between
//!   the truth and EDM + offset over the occluded samples of the window.
//! * Validation: the last `validation_fraction` of every take (at least one segment) is held
//!   out; a fixed set of validation examples (fixed seed, fixed corruption) is scored every
//!   `validate_every` steps, next to EDM alone on the same samples.
//! * Every random draw comes from the seed, the step and the example index, so a run resumed
//!   from a checkpoint draws the same examples as one that never stopped.
//! * Adam with gradient-norm clipping; learning rate warmed up linearly, then cosine-decayed to
//!   a tenth.

use crate::NnError;
use crate::features::{LocalTake, Normalisation, input_values, marker_order, neighbour_graph, offset_taper, prepare};
use crate::model::{Architecture, RefinerNet, gather_indices};
use crate::refiner::{ModelMeta, Refiner};
use burn::grad_clipping::GradientClippingConfig;
use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams};
use burn::prelude::*;
use burn::tensor::Bytes;
use locap_clean::FillMethod;
use locap_clean::local_frame::FrameDefinition;
use locap_core::{MarkerName, Take, Vec3};
use locap_synth::augment::{AugmentConfig, augment};
use locap_synth::gap_model::GapModel;
use locap_synth::shard::ShardReader;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Settings of a training run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    /// Frames per window (the paper: 64).
    pub window: usize,
    /// Context frames on each side of a training window for augmentation and EDM.
    pub margin: usize,
    /// Windows per step.
    pub batch: usize,
    /// Optimisation steps.
    pub steps: usize,
    /// Peak learning rate.
    pub learning_rate: f64,
    /// Steps of linear warm-up.
    pub warmup_steps: usize,
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
    /// Graph-convolution features per marker.
    pub channels: usize,
    /// LSTM hidden size per direction.
    pub hidden: usize,
    /// Graph neighbours per marker.
    pub neighbours: usize,
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
            steps: 2000,
            learning_rate: 1e-3,
            warmup_steps: 50,
            validation_fraction: 0.1,
            validation_windows: 64,
            validate_every: 50,
            checkpoint_every: 200,
            seed: 1,
            augment: AugmentConfig { missing_fraction: Some(0.1), ..AugmentConfig::default() },
            channels: 16,
            hidden: 128,
            neighbours: 6,
            edm_neighbours: 6,
            frame: FrameDefinition::cmu_waist(),
            per_take_centre: true,
            init: FillMethod::Edm,
            taper_frames: 20,
            inference_taper_frames: None,
        }
    }
}

impl TrainConfig {
    /// Checks the settings before anything is allocated: sizes within [`crate::limits`],
    /// rates and fractions in range. [`train`] calls it; a command line can call it first.
    ///
    /// # Errors
    /// [`NnError::Limit`] for a size above its ceiling, [`NnError::Data`] for others.
    pub fn validate(&self) -> Result<(), NnError> {
        use crate::limits::{self, check};
        check("window", self.window, limits::MAX_WINDOW)?;
        check("margin", self.margin, limits::MAX_WINDOW)?;
        check("batch", self.batch, limits::MAX_BATCH_WINDOWS)?;
        check("channels", self.channels, limits::MAX_CHANNELS)?;
        check("hidden", self.hidden, limits::MAX_HIDDEN)?;
        check("neighbours", self.neighbours, limits::MAX_NEIGHBOURS)?;
        check("EDM neighbours", self.edm_neighbours, limits::MAX_NEIGHBOURS)?;
        check("validation windows", self.validation_windows, limits::MAX_VALIDATION_WINDOWS)?;
        let bad = |s: String| Err(NnError::Data(s));
        if self.window < 2 || self.batch == 0 || self.channels == 0 || self.hidden == 0 || self.neighbours == 0 {
            return bad(format!(
                "window {} (2 or more), batch {}, channels {}, hidden {}, neighbours {} (1 or more) are out of range",
                self.window, self.batch, self.channels, self.hidden, self.neighbours
            ));
        }
        if !(self.learning_rate.is_finite() && self.learning_rate > 0.0) {
            return bad(format!("learning rate {} must be positive", self.learning_rate));
        }
        if !matches!(self.init, FillMethod::Edm | FillMethod::Linear) {
            return bad(format!("initial fill {} must be edm or linear", self.init.name()));
        }
        if !(0.0..0.9).contains(&self.validation_fraction) {
            return bad(format!("validation fraction {} must be in 0..0.9", self.validation_fraction));
        }
        Ok(())
    }

    /// Frames of one training segment (window and both margins).
    pub fn segment(&self) -> usize {
        self.window + 2 * self.margin
    }

    /// Learning rate at `step` (0-based): linear warm-up, then cosine decay to a tenth.
    pub fn learning_rate_at(&self, step: usize) -> f64 {
        if step < self.warmup_steps {
            return self.learning_rate * (step + 1) as f64 / self.warmup_steps as f64;
        }
        let span = self.steps.saturating_sub(self.warmup_steps).max(1) as f64;
        let progress = ((step - self.warmup_steps) as f64 / span).min(1.0);
        self.learning_rate * (0.1 + 0.9 * 0.5 * (1.0 + (std::f64::consts::PI * progress).cos()))
    }
}

/// Clean takes to train on, all with the same markers in the same order.
#[derive(Debug, Clone)]
pub struct TrainingData {
    /// Marker labels.
    pub markers: Vec<String>,
    /// Clean takes (one per shard), markers in [`TrainingData::markers`] order.
    pub takes: Vec<Take>,
    /// Where each take came from.
    pub names: Vec<String>,
}

/// The clean markers of the shard `reader` reads, as a take (`name` goes into errors). Give
/// it a reader made with [`ShardReader::with_len`] (as [`crate::solver::data::open_shard`]
/// does): its frame count is checked against the data, and the take is sized from it.
///
/// # Errors
/// Cut short, or a sample that is not finite.
pub fn read_shard<R: std::io::Read>(mut reader: ShardReader<R>, name: &str) -> Result<Take, NnError> {
    let header = reader.header().clone();
    let mut samples = crate::solver::data::reserve(header.frames.saturating_mul(header.markers.len()), name)?;
    let at = |source| NnError::ShardFile { path: name.to_string(), source };
    while let Some(chunk) = reader.next_chunk(1024).map_err(at)? {
        for record in chunk.records() {
            samples.extend(record.clean_mm().map(|p| Some(Vec3::new(p[0] as f64, p[1] as f64, p[2] as f64))));
        }
    }
    let names = header.markers.iter().map(|l| MarkerName::parse(l)).collect();
    Take::from_samples(names, &samples, header.frame_rate_hz).map_err(|e| NnError::Data(format!("{name}: {e}")))
}

impl TrainingData {
    /// Every `*.shard` under `dir`, searched recursively (sorted by path), or `dir` itself if it
    /// is a shard file (see [`TrainingData::from_paths`]).
    ///
    /// # Errors
    /// As [`TrainingData::from_paths`].
    pub fn from_path(dir: &Path) -> Result<TrainingData, NnError> {
        TrainingData::from_paths(&[dir.to_path_buf()])
    }

    /// Training takes from `paths`: shard files (`locap synth`: clean synthetic markers) and
    /// labeled C3D takes (real markers; their own gaps are simply not scored), given as files or
    /// folders searched recursively for `*.shard`, or for `*.c3d` when a folder holds no shard
    /// (`locap synth` writes C3D copies beside its shards). Shards come first, each group
    /// sorted by path; the markers are the first take's, and takes that carry more markers
    /// (a split label, unlabeled `*N` points) give up the extra ones.
    ///
    /// # Errors
    /// No takes, unreadable files, or a take lacking some of the first take's markers.
    pub fn from_paths(paths: &[PathBuf]) -> Result<TrainingData, NnError> {
        let is = |p: &Path, ext: &str| p.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext));
        let (mut shards, mut c3ds): (Vec<PathBuf>, Vec<PathBuf>) = (Vec::new(), Vec::new());
        for path in paths {
            if !path.is_dir() {
                if is(path, "c3d") {
                    c3ds.push(path.clone())
                } else {
                    shards.push(path.clone())
                }
                continue;
            }
            let found_shards = files_under(path, "shard")?;
            let found_c3ds = files_under(path, "c3d")?;
            // `locap synth` writes STEM.c3d and STEM.clean.c3d beside STEM.shard: a folder with
            // shards gives its shards only, so no take is read twice.
            if found_shards.is_empty() {
                c3ds.extend(found_c3ds);
            } else {
                shards.extend(found_shards);
            }
        }
        shards.sort();
        c3ds.sort();
        if shards.is_empty() && c3ds.is_empty() {
            let shown: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
            return Err(NnError::Data(format!(
                "{}: no .shard files (write them with `locap synth`) and no .c3d takes",
                shown.join(", ")
            )));
        }
        let read = |p: &PathBuf| -> Result<Take, NnError> {
            let at = |e: String| NnError::Data(format!("{}: {e}", p.display()));
            if is(p, "c3d") {
                let file = locap_io::c3d::read_path(p).map_err(|e| at(e.to_string()))?;
                file.to_take().map_err(|e| at(e.to_string()))
            } else {
                read_shard(crate::solver::data::open_shard(p)?, &p.display().to_string())
            }
        };
        let all: Vec<PathBuf> = shards.into_iter().chain(c3ds).collect();
        let takes = all.par_iter().map(read).collect::<Result<Vec<Take>, NnError>>()?;
        TrainingData::new(takes, all.iter().map(|p| p.display().to_string()).collect())
    }

    /// Training data from takes; the markers are the first take's labelled ones, in its order,
    /// and every take is cut to them.
    ///
    /// # Errors
    /// No takes, or a take lacking some of them.
    pub fn new(takes: Vec<Take>, names: Vec<String>) -> Result<TrainingData, NnError> {
        let first = takes.first().ok_or_else(|| NnError::Data("no training takes".into()))?;
        let markers: Vec<String> =
            first.markers().iter().filter(|n| !n.is_unlabeled()).map(|n| n.label.clone()).collect();
        let mut ordered = Vec::with_capacity(takes.len());
        for (take, name) in takes.iter().zip(&names) {
            let order = marker_order(take, &markers).map_err(|e| NnError::Data(format!("{name}: {e}")))?;
            let samples: Vec<Option<Vec3>> =
                (0..take.frame_count()).flat_map(|f| order.iter().map(move |&k| take.position_mm(f, k))).collect();
            let names = markers.iter().map(|l| MarkerName::parse(l)).collect();
            ordered.push(
                Take::from_samples(names, &samples, take.frame_rate_hz()).map_err(|e| NnError::Data(e.to_string()))?,
            );
        }
        Ok(TrainingData { markers, takes: ordered, names })
    }

    /// Training frames of all takes.
    pub fn frames(&self) -> usize {
        self.takes.iter().map(|t| t.frame_count()).sum()
    }

    /// Steps of `config` in which every frame is seen once on average.
    pub fn steps_per_epoch(&self, config: &TrainConfig) -> usize {
        self.frames().div_ceil(config.window * config.batch).max(1)
    }
}

/// Every file with extension `ext` (any case) under the folder `dir`, searched recursively.
///
/// # Errors
/// A folder cannot be listed.
pub(crate) fn files_under(dir: &Path, ext: &str) -> Result<Vec<PathBuf>, NnError> {
    let io = |p: &Path| {
        let p = p.display().to_string();
        move |source| NnError::Io { path: p, source }
    };
    let mut found = Vec::new();
    let mut folders = vec![dir.to_path_buf()];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).map_err(io(&folder))? {
            let path = entry.map_err(io(&folder))?.path();
            if path.is_dir() {
                folders.push(path);
            } else if path.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext)) {
                found.push(path);
            }
        }
    }
    found.sort();
    Ok(found)
}

/// One example: `[window, M]` values of network input, EDM fill, truth and loss mask.
#[derive(Debug, Clone)]
struct Example {
    input: Vec<f32>,
    edm_mm: Vec<f32>,
    truth_mm: Vec<f32>,
    mask: Vec<f32>,
    taper: Vec<f32>,
}

/// Everything an example needs besides the rng.
struct Sampler<'a> {
    config: &'a TrainConfig,
    gap_model: &'a GapModel,
    norm: &'a Normalisation,
    identity: Vec<usize>,
    /// `(take, first frame, frames)` ranges examples are drawn from.
    ranges: Vec<(usize, usize, usize)>,
    takes: &'a [Take],
    /// Per take, what its inputs are centred on ([`Normalisation::centres`]).
    centres: &'a [Vec<[f64; 3]>],
}

impl Sampler<'_> {
    /// An example from a random segment of the ranges; `None` if the segment's local frame
    /// cannot be built.
    fn example(&self, rng: &mut StdRng) -> Option<Example> {
        use rand::RngExt;
        let total: usize = self.ranges.iter().map(|r| r.2 + 1 - self.segment_len(r)).sum();
        let mut pick = rng.random_range(0..total.max(1));
        let &(take, first, len) = self.ranges.iter().find(|r| {
            let n = r.2 + 1 - self.segment_len(r);
            if pick < n {
                true
            } else {
                pick -= n;
                false
            }
        })?;
        let seg_len = self.segment_len(&(take, first, len));
        let start = first + pick;
        let clean = self.takes[take].slice_frames(start..start + seg_len);
        let corrupted = augment(&clean, self.gap_model, &self.config.augment, rng).ok()?;
        let prepared =
            prepare(&corrupted.take, &self.identity, &self.config.frame, self.config.init, self.config.edm_neighbours)
                .ok()?;
        let truth = LocalTake::new(&clean, &self.identity, prepared.local.frames_local.clone());
        let w = self.config.window.min(seg_len);
        let c = (seg_len - w) / 2;
        let m = self.identity.len();
        let mut input = Vec::with_capacity(w * m * 4);
        input_values(&prepared.local, &prepared.visible, self.norm, &self.centres[take], c..c + w, &mut input);
        let mut edm_mm = Vec::with_capacity(w * m * 3);
        let mut truth_mm = Vec::with_capacity(w * m * 3);
        let mut mask = Vec::with_capacity(w * m);
        let taper = offset_taper(&prepared.visible, m, self.config.taper_frames)[c * m..(c + w) * m].to_vec();
        for f in c..c + w {
            for k in 0..m {
                let i = f * m + k;
                let (e, t) = (prepared.local.local_mm[i], truth.local_mm[i]);
                let use_it = !prepared.visible[i] && prepared.filled.filled[i];
                match (e, t) {
                    (Some(e), Some(t)) => {
                        edm_mm.extend(e.iter().map(|v| *v as f32));
                        truth_mm.extend(t.iter().map(|v| *v as f32));
                        mask.push(if use_it { 1.0 } else { 0.0 });
                    }
                    _ => {
                        edm_mm.extend([0.0; 3]);
                        truth_mm.extend([0.0; 3]);
                        mask.push(0.0);
                    }
                }
            }
        }
        Some(Example { input, edm_mm, truth_mm, mask, taper })
    }

    fn segment_len(&self, r: &(usize, usize, usize)) -> usize {
        self.config.segment().min(r.2)
    }
}

/// A stream of independent generators: example `index` of step `step`.
pub(crate) fn rng_for(seed: u64, step: u64, index: u64) -> StdRng {
    // SplitMix64 finaliser over the three numbers.
    let mut z = seed ^ step.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    StdRng::seed_from_u64(z ^ (z >> 31))
}

/// Examples as tensors.
struct Batch {
    x: Tensor<4>,
    edm: Tensor<4>,
    truth: Tensor<4>,
    mask: Tensor<4>,
    taper: Tensor<4>,
    samples: f32,
}

impl Batch {
    fn new(examples: &[Example], window: usize, markers: usize, device: &Device) -> Batch {
        let b = examples.len();
        let cat =
            |f: fn(&Example) -> &Vec<f32>| examples.iter().flat_map(|e| f(e).iter().copied()).collect::<Vec<f32>>();
        let t = |v: Vec<f32>, c: usize| Tensor::<4>::from_data(TensorData::new(v, [b, window, markers, c]), device);
        let mask = cat(|e| &e.mask);
        let samples = mask.iter().sum();
        Batch {
            x: t(cat(|e| &e.input), 4),
            edm: t(cat(|e| &e.edm_mm), 3),
            truth: t(cat(|e| &e.truth_mm), 3),
            mask: t(mask, 1),
            taper: t(cat(|e| &e.taper), 1),
            samples,
        }
    }

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

/// Progress of a run, given to the caller's callback after every step.
#[derive(Debug, Clone, PartialEq)]
pub struct Progress {
    /// Steps done.
    pub step: usize,
    /// Steps in the run.
    pub steps: usize,
    /// Training loss of this step, mm.
    pub loss_mm: f64,
    /// Learning rate of this step.
    pub learning_rate: f64,
    /// Validation loss, mm, if validated at this step.
    pub validation_mm: Option<f64>,
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
    ///
    /// # Errors
    /// No points yet.
    pub fn loss_curve(&self, title: &str) -> Result<locap_view::plot::Chart, locap_view::ViewError> {
        let pts = |v: &[(usize, f64)]| v.iter().map(|(s, l)| (*s as f64, *l)).collect::<Vec<_>>();
        let mut series = vec![("training".to_string(), pts(&self.training_mm))];
        if !self.validation_mm.is_empty() {
            series.push(("validation".to_string(), pts(&self.validation_mm)));
        }
        if let (Some(edm), Some(first), Some(last)) =
            (self.edm_validation_mm, self.training_mm.first(), self.training_mm.last())
        {
            series.push(("EDM alone (validation)".to_string(), vec![(first.0 as f64, edm), (last.0 as f64, edm)]));
        }
        locap_view::plot::Chart::loss_curve(series, "mean error of occluded samples, mm (Eq. 3)", title)
    }
}

/// Where checkpoints go: `DIR/checkpoint.locapnn` (a model file whose metadata holds the run's
/// report) and `DIR/optimizer.bin` (Adam's state).
#[derive(Debug, Clone)]
pub struct Checkpoints {
    /// The folder.
    pub dir: PathBuf,
    /// Continue from the checkpoint in `dir` if there is one.
    pub resume: bool,
}

impl Checkpoints {
    fn model_path(&self) -> PathBuf {
        self.dir.join("checkpoint.locapnn")
    }
    fn optimizer_path(&self) -> PathBuf {
        self.dir.join("optimizer.bin")
    }
}

pub(crate) fn write_file(path: &Path, bytes: &[u8]) -> Result<(), NnError> {
    locap_io::atomic::write_atomically(path, |w| Ok(w.write_all(bytes)?))
        .map_err(|e| NnError::Data(format!("{}: {e}", path.display())))
}

pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, NnError> {
    std::fs::read(path).map_err(|source| NnError::Io { path: path.display().to_string(), source })
}

/// Trains a refiner on `data`; `progress` is called after every step. Returns the trained
/// refiner (its metadata carries the report) and the report.
///
/// # Errors
/// Unusable settings or data (takes shorter than a window, no frame where the local frame is
/// defined), or checkpoints that cannot be written or read.
pub fn train(
    data: &TrainingData,
    config: &TrainConfig,
    gap_model: &GapModel,
    checkpoints: Option<&Checkpoints>,
    progress: &mut dyn FnMut(&Progress),
) -> Result<(Refiner, TrainReport), NnError> {
    config.validate()?;
    let m = data.markers.len();
    if config.neighbours >= m {
        return Err(NnError::Data(format!("{} graph neighbours need more than {m} markers", config.neighbours)));
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
        return Err(NnError::Data(format!("no training take has {} frames (one window)", config.window)));
    }
    if config.validation_fraction > 0.0 && valid_ranges.is_empty() {
        return Err(NnError::Data(format!(
            "no take is long enough to hold out validation frames ({} frames needed; use a validation fraction of 0)",
            3 * seg
        )));
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
    let longest = data.takes.iter().max_by_key(|t| t.frame_count()).ok_or_else(|| NnError::Data("no takes".into()))?;
    let graph = neighbour_graph(longest, &identity, config.neighbours);
    let architecture =
        Architecture { markers: m, neighbours: config.neighbours, channels: config.channels, hidden: config.hidden };
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

    let device = Device::default().autodiff();
    device.seed(config.seed);
    let mut net = RefinerNet::new(&architecture, &device);
    let mut optimizer = AdamConfig::new().with_grad_clipping(Some(GradientClippingConfig::Norm(1.0))).init();
    let mut report = TrainReport {
        parameters: net.num_params(),
        training_frames: train_ranges.iter().map(|r| r.2).sum(),
        config: Some(config.clone()),
        ..TrainReport::default()
    };
    if let Some(cp) = checkpoints {
        std::fs::create_dir_all(&cp.dir)
            .map_err(|source| NnError::Io { path: cp.dir.display().to_string(), source })?;
        if cp.resume && cp.model_path().exists() {
            let saved = Refiner::from_bytes(&read_file(&cp.model_path())?, &device)?;
            if saved.meta.markers != meta.markers || saved.meta.architecture != architecture {
                return Err(NnError::Data(format!(
                    "{}: the checkpoint has other markers or another network size than this run",
                    cp.model_path().display()
                )));
            }
            let previous: TrainReport = serde_json::from_value(saved.meta.training.clone())
                .map_err(|e| NnError::BadModel(format!("checkpoint report: {e}")))?;
            net = saved.net;
            optimizer = optimizer
                .from_bytes(Bytes::from_bytes_vec(read_file(&cp.optimizer_path())?))
                .map_err(|e| NnError::BadModel(format!("{}: {e:?}", cp.optimizer_path().display())))?;
            report.steps = previous.steps;
            report.training_mm = previous.training_mm;
            report.validation_mm = previous.validation_mm;
        }
    }

    let train_sampler = Sampler {
        config,
        gap_model,
        norm: &norm,
        identity: identity.clone(),
        ranges: train_ranges,
        takes: &data.takes,
        centres: &centres,
    };
    let valid_sampler = Sampler {
        config,
        gap_model,
        norm: &norm,
        identity: identity.clone(),
        ranges: valid_ranges,
        takes: &data.takes,
        centres: &centres,
    };
    let valid_examples: Vec<Example> =
        (0..if config.validation_fraction > 0.0 { config.validation_windows } else { 0 })
            .into_par_iter()
            .filter_map(|i| valid_sampler.example(&mut rng_for(config.seed ^ 0x5EED, u64::MAX, i as u64)))
            .collect();
    if !valid_examples.is_empty() {
        let (sum, n) = Batch::edm_loss(&valid_examples);
        report.edm_validation_mm = (n > 0.0).then(|| sum / n);
        report.validation_samples = n as usize;
    }
    let window = config.window.min(config.segment().min(data.takes.iter().map(|t| t.frame_count()).max().unwrap_or(0)));
    let gather = gather_indices(&graph, &device);
    let std_values: Vec<f32> = norm.std_mm.iter().flatten().map(|v| *v as f32).collect();
    let std_mm = Tensor::<4>::from_data(TensorData::new(std_values.clone(), [1, 1, m, 3]), &device);

    let validate = |net: &RefinerNet| -> Option<f64> {
        if valid_examples.is_empty() {
            return None;
        }
        let inner = device.clone().without_autodiff();
        let valid_net = net.valid();
        let gather = gather_indices(&graph, &inner);
        let std_mm = Tensor::<4>::from_data(TensorData::new(std_values.clone(), [1, 1, m, 3]), &inner);
        let (mut sum, mut n) = (0.0, 0.0);
        for chunk in valid_examples.chunks(config.batch.max(16)) {
            let b = Batch::new(chunk, window, m, &inner);
            let loss: f32 = b.loss(&valid_net, gather.clone(), std_mm.clone()).into_scalar();
            sum += loss as f64 * b.samples as f64;
            n += b.samples as f64;
        }
        (n > 0.0).then(|| sum / n)
    };

    let first = report.steps;
    let mut interval = (0.0, 0usize);
    for step in first..config.steps {
        let started = Instant::now();
        let examples: Vec<Example> = (0..config.batch)
            .into_par_iter()
            .filter_map(|i| train_sampler.example(&mut rng_for(config.seed, step as u64, i as u64)))
            .collect();
        if examples.is_empty() {
            return Err(NnError::Data("no training example could be built (the local frame is never defined?)".into()));
        }
        let batch = Batch::new(&examples, window, m, &device);
        let lr = config.learning_rate_at(step);
        let loss = batch.loss(&net, gather.clone(), std_mm.clone());
        let loss_mm: f32 = loss.clone().into_scalar();
        if batch.samples > 0.0 {
            let grads = GradientsParams::from_grads(loss.backward(), &net);
            net = optimizer.step(lr, net, grads);
        }
        report.step_seconds += started.elapsed().as_secs_f64();
        report.steps_this_run += 1;
        report.steps = step + 1;
        interval.0 += loss_mm as f64;
        interval.1 += 1;
        let done = step + 1 == config.steps;
        let mut validation_mm = None;
        if (step + 1) % config.validate_every.max(1) == 0 || done {
            report.training_mm.push((step + 1, interval.0 / interval.1 as f64));
            interval = (0.0, 0);
            validation_mm = validate(&net);
            if let Some(v) = validation_mm {
                report.validation_mm.push((step + 1, v));
            }
        }
        progress(&Progress {
            step: step + 1,
            steps: config.steps,
            loss_mm: loss_mm as f64,
            learning_rate: lr,
            validation_mm,
        });
        if let Some(cp) = checkpoints
            && ((config.checkpoint_every > 0 && (step + 1) % config.checkpoint_every == 0) || done)
        {
            let mut meta = meta.clone();
            meta.training = serde_json::to_value(&report).map_err(|e| NnError::Data(e.to_string()))?;
            write_file(&cp.model_path(), &Refiner::from_parts(meta, net.clone(), &device).to_bytes()?)?;
            let state = optimizer.into_bytes().map_err(|e| NnError::Data(format!("optimizer state: {e:?}")))?;
            write_file(&cp.optimizer_path(), &state)?;
        }
    }
    let mut meta = meta;
    meta.training = serde_json::to_value(&report).map_err(|e| NnError::Data(e.to_string()))?;
    let inner = device.without_autodiff();
    Ok((Refiner::from_parts(meta, net.valid(), &inner), report))
}
