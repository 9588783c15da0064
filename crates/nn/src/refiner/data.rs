//! Training data of the refiner (LocalMoCap section 3.1): clean takes, and examples cut from
//! them and corrupted afresh every time.
//!
//! * The clean (ground-truth) markers of every shard are decoded once by synth's one shard
//!   decoder ([`ShardReader::read_clean`]); the corrupted copy in the shard is not used, because
//!   every training window is corrupted afresh ([`locap_synth::augment::augment`], Eq. 6 gaps
//!   and shifts), so the network never sees the same occlusions twice. Real labeled takes
//!   (C3D, read by the caller) train beside them. All takes must carry the first one's markers
//!   (in any order).
//! * A training example is a random segment of `window + 2 * margin` frames: augmented, filled
//!   by EDM (the margins give EDM the context a real take gives it), turned to the waist frame,
//!   and cut to its central `window` frames.

use super::train::TrainConfig;
use crate::NnError;
use crate::features::{LocalTake, Normalisation, input_values, marker_order, offset_taper, prepare};
use burn::prelude::*;
use locap_core::{MarkerName, Take, Vec3};
use locap_synth::augment::augment;
use locap_synth::gap_model::GapModel;
use locap_synth::shard::ShardReader;
use rand::rngs::StdRng;

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

/// The clean markers of the shard `reader` reads, as a take (`name`, the shard's path, goes
/// into errors). Give it a reader made with [`ShardReader::with_len`]: its frame count is
/// checked against the file's length, and the take is sized from it.
///
/// # Errors
/// [`NnError::ShardFile`]: cut short, or a sample that is not finite.
pub fn shard_take<R: std::io::Read>(reader: ShardReader<R>, name: &str) -> Result<Take, NnError> {
    reader.read_clean().map_err(|source| NnError::ShardFile { path: name.to_string(), source })
}

impl TrainingData {
    /// Training data from takes; the markers are the first take's labelled ones, in its order,
    /// and every take is cut to them.
    ///
    /// # Errors
    /// No takes, or a take lacking some of them.
    pub fn new(takes: Vec<Take>, names: Vec<String>) -> Result<TrainingData, NnError> {
        let first = takes.first().ok_or(NnError::NoData { what: "training takes" })?;
        let markers: Vec<String> =
            first.markers().iter().filter(|n| !n.is_unlabeled()).map(|n| n.label.clone()).collect();
        let mut ordered = Vec::with_capacity(takes.len());
        for (take, name) in takes.iter().zip(&names) {
            let order = marker_order(take, &markers)
                .map_err(|e| NnError::InTake { name: name.clone(), source: Box::new(e) })?;
            let samples: Vec<Option<Vec3>> =
                (0..take.frame_count()).flat_map(|f| order.iter().map(move |&k| take.position_mm(f, k))).collect();
            let names = markers.iter().map(|l| MarkerName::parse(l)).collect();
            let cut = Take::from_samples(names, &samples, take.frame_rate_hz())
                .map_err(|source| NnError::Take { name: name.clone(), source })?;
            ordered.push(cut);
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

/// One example: `[window, M]` values of network input, EDM fill, truth and loss mask.
#[derive(Debug, Clone)]
pub(super) struct Example {
    pub(super) input: Vec<f32>,
    pub(super) edm_mm: Vec<f32>,
    pub(super) truth_mm: Vec<f32>,
    pub(super) mask: Vec<f32>,
    pub(super) taper: Vec<f32>,
}

/// Everything an example needs besides the rng.
pub(super) struct Sampler<'a> {
    pub(super) config: &'a TrainConfig,
    pub(super) gap_model: &'a GapModel,
    pub(super) norm: &'a Normalisation,
    pub(super) identity: Vec<usize>,
    /// `(take, first frame, frames)` ranges examples are drawn from.
    pub(super) ranges: Vec<(usize, usize, usize)>,
    pub(super) takes: &'a [Take],
    /// Per take, what its inputs are centred on ([`Normalisation::centres`]).
    pub(super) centres: &'a [Vec<[f64; 3]>],
}

impl Sampler<'_> {
    /// An example from a random segment of the ranges; `None` if the segment's local frame
    /// cannot be built.
    pub(super) fn example(&self, rng: &mut StdRng) -> Option<Example> {
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

/// Examples as tensors.
pub(super) struct Batch {
    pub(super) x: Tensor<4>,
    pub(super) edm: Tensor<4>,
    pub(super) truth: Tensor<4>,
    pub(super) mask: Tensor<4>,
    pub(super) taper: Tensor<4>,
    pub(super) samples: f32,
}

impl Batch {
    pub(super) fn new(examples: &[Example], window: usize, markers: usize, device: &Device) -> Batch {
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
}
