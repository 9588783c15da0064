//! locap's learned gap-fill refiner (LocalMoCap section 3.1, Eq. 3-4), trained and run on the
//! CPU with [burn](https://burn.dev)'s `flex` backend, in the same binary as the rest of locap.
//!
//! EDM (locality gap fill, `locap_clean::edm`) gives a first estimate of every occluded sample
//! from the distances to its most stable neighbours. Distances do not capture every motion
//! pattern, so the paper refines EDM's estimate with a network that sees the markers in the
//! waist's local frame (no global position or heading to learn), their visibility, their
//! stable-neighbour graph (per-edge filters, Eq. 4) and 64 frames of context (biLSTM), and
//! predicts a residual offset for the occluded samples only, trained with Eq. 3.
//!
//! * [`model`]: the network (graph convolution, biLSTM, offset head).
//! * [`limits`]: the documented ceilings on network, batch and window sizes.
//! * [`features`]: a take to network inputs (EDM fill, local frame, normalisation) and back.
//! * [`refiner`]: the versioned model file and inference over overlapping windows.
//! * [`refiners`]: refiners as fillers of the clean stage (`locap_clean::Filler`).
//! * [`shipped`]: the trained refiners and solver built into locap.
//! * [`solver`]: the motion solver of section 3.2 (heterogeneous graph network, baselines,
//!   training, metrics).
//! * [`train`]: shard data loading with on-the-fly Eq. 6 augmentation, Adam, learning-rate
//!   schedule, validation, checkpoints and resume, loss curve.

pub mod features;
pub mod limits;
pub mod model;
pub mod refiner;
pub mod refiners;
pub mod shipped;
pub mod solver;
pub mod train;

pub use burn;
pub use refiner::{ModelMeta, Refiner, refine_all, refine_all_of};
pub use refiners::Refiners;
pub use train::{TrainConfig, TrainReport};

/// Errors of the refiner.
#[derive(Debug, thiserror::Error)]
pub enum NnError {
    /// The model's markers are not all in the take.
    #[error(
        "the model was trained on another marker set: {missing} of its {total} markers are not in the take (first: {first})"
    )]
    MarkerSet {
        /// How many model markers the take lacks.
        missing: usize,
        /// Markers of the model.
        total: usize,
        /// The first few missing labels.
        first: String,
    },
    /// Not a model file (refiner or solver), or a damaged one.
    #[error("not a usable locap model file: {0}")]
    BadModel(String),
    /// The local frame cannot be built on the take.
    #[error(transparent)]
    LocalFrame(#[from] locap_clean::local_frame::LocalFrameError),
    /// Reading training data failed.
    #[error(transparent)]
    Shard(#[from] locap_synth::shard::ShardError),
    /// A shard file that cannot be read.
    #[error("{path}: {source}")]
    ShardFile {
        /// The file.
        path: String,
        /// What is wrong with it.
        source: locap_synth::shard::ShardError,
    },
    /// A size above its ceiling (see [`limits`]).
    #[error("{what} {value} is above its ceiling {max}")]
    Limit {
        /// The setting.
        what: &'static str,
        /// Its value.
        value: u64,
        /// The ceiling.
        max: u64,
    },
    /// Augmentation settings out of range.
    #[error(transparent)]
    Augment(#[from] locap_synth::augment::AugmentError),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// What failed.
        source: std::io::Error,
    },
    /// The fill before solving failed (a refiner that does not fit the take).
    #[error(transparent)]
    Fill(#[from] locap_clean::FillError),
    /// Training data or settings that cannot be used.
    #[error("{0}")]
    Data(String),
}
