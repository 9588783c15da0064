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
//! * [`refiner`]: the refiner of section 3.1 (network, training data, training, model file
//!   and inference over overlapping windows).
//! * [`solver`]: the motion solver of section 3.2 (heterogeneous graph network, baselines,
//!   training data, training, model file, metrics).
//! * [`harness`]: the one training loop both use: Adam, learning-rate [`harness::Schedule`],
//!   validation, checkpoints through a caller's [`harness::Checkpointer`] and resume.
//! * [`file`]: the model file layout both kinds share.
//! * [`features`]: a take to network inputs (EDM fill, local frame, normalisation) and back.
//! * [`limits`]: the documented ceilings on network, batch and window sizes.
//! * [`refiners`]: refiners as fillers of the clean stage (`locap_clean::Filler`).
//! * [`shipped`]: the trained refiners and solver built into locap.
//! * [`kinematic`]: the solver that needs no network: the labeler's IK with a subject
//!   calibration, for any layout (the baseline the networks must beat).
//! * [`method`]: a take solved by the network, the kinematic solver or both, and the rule of
//!   the default ([`method::solve_take`]).
//!
//! No module reads or writes files: training takes `Take`s and shard readers, checkpoints go
//! to a [`harness::Checkpointer`], and reports give their loss curves as data series
//! ([`harness::LossCurve`]) for the caller to draw.

pub mod features;
pub mod file;
pub mod harness;
pub mod kinematic;
pub mod limits;
pub mod method;
pub mod refiner;
pub mod refiners;
pub mod shipped;
pub mod solver;

pub use burn;
pub use harness::{Checkpointer, Checkpoints, Schedule};
pub use refiner::{ModelMeta, Refiner, TrainConfig, TrainReport, refine_all, refine_all_of};
pub use refiners::{FittingRefiners, RefinerSource, Refiners, filler_for};

/// Errors of the refiner and the solver.
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
    /// A shipped refiner was asked for and none carries the take's markers.
    #[error(
        "no shipped refiner fits this take's markers (shipped: {shipped}); train one with `locap train fill` and give it as a model, or use another fill method"
    )]
    NoShippedRefiner {
        /// The shipped refiners' names.
        shipped: String,
    },
    /// Not a model file (refiner or solver), or a damaged one.
    #[error("not a usable locap model file: {0}")]
    BadModel(String),
    /// The kinematic solver cannot be built or run (layout, skeleton, take).
    #[error("kinematic solver: {0}")]
    Kinematic(String),
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
    /// A setting out of range.
    #[error("{what} {value} must be {expected}")]
    Setting {
        /// The setting.
        what: &'static str,
        /// Its value.
        value: String,
        /// What it must be.
        expected: &'static str,
    },
    /// More graph neighbours than the markers allow.
    #[error("{neighbours} graph neighbours need more than {markers} markers")]
    TooFewMarkers {
        /// Neighbours per marker asked for.
        neighbours: usize,
        /// Markers of the data.
        markers: usize,
    },
    /// Nothing of something needed.
    #[error("no {what}")]
    NoData {
        /// What is missing ("training takes").
        what: &'static str,
    },
    /// No take is as long as a training window.
    #[error("no training take has {window} frames (one window)")]
    TooShortForWindow {
        /// Frames of a window.
        window: usize,
    },
    /// No take is long enough to hold out validation frames.
    #[error(
        "no take is long enough to hold out validation frames ({needed} frames needed; use a validation fraction of 0)"
    )]
    TooShortForValidation {
        /// Frames needed.
        needed: usize,
    },
    /// No training example could be built from the data.
    #[error("no training example could be built (the local frame is never defined?)")]
    NoExamples,
    /// A loss that is not finite (its gradients would spoil the weights).
    #[error("the loss is not finite at step {step}; lower the learning rate")]
    NonFiniteLoss {
        /// The step (0-based).
        step: usize,
    },
    /// Something wrong with one take or shard of the data.
    #[error("{name}: {source}")]
    InTake {
        /// The take (its path).
        name: String,
        /// What is wrong.
        #[source]
        source: Box<NnError>,
    },
    /// Something wrong with one model file.
    #[error("{name}: {source}")]
    InModel {
        /// The model (its path).
        name: String,
        /// What is wrong.
        #[source]
        source: Box<NnError>,
    },
    /// A take that cannot be built from the data.
    #[error("{name}: {source}")]
    Take {
        /// The take (its path).
        name: String,
        /// What is wrong.
        #[source]
        source: locap_core::TakeError,
    },
    /// A solver shard written without a skeleton.
    #[error("{name}: the shard has no skeleton (write it again with this locap's `locap synth`)")]
    NoSkeleton {
        /// The shard.
        name: String,
    },
    /// A solver shard written without joint motion.
    #[error("{name}: the shard has no joint motion")]
    NoMotion {
        /// The shard.
        name: String,
    },
    /// A shard (or model) with another skeleton than the first shard's.
    #[error("{name}: another skeleton than {first}")]
    OtherSkeleton {
        /// The shard.
        name: String,
        /// Whose skeleton it should have.
        first: String,
    },
    /// A skeleton or motion that cannot be built.
    #[error(transparent)]
    Skeleton(#[from] locap_core::SkeletonError),
    /// A take without frames.
    #[error("the take has no frames")]
    EmptyTake,
    /// [`refine_all`] without a refiner.
    #[error("no refiner given")]
    NoRefiner,
    /// A checkpoint that cannot be resumed.
    #[error("{at}: {source}")]
    Checkpoint {
        /// Where it is kept.
        at: String,
        /// What is wrong.
        #[source]
        source: Box<NnError>,
    },
    /// A checkpoint of another run.
    #[error("the checkpoint has other markers or another network size than this run")]
    CheckpointMismatch,
    /// A checkpoint model without the optimizer state saved beside it.
    #[error("{at}: the optimizer state of the checkpoint is missing")]
    MissingCheckpoint {
        /// Where it should be.
        at: String,
    },
    /// A checkpoint that cannot be read or written.
    #[error("{at}: {source}")]
    CheckpointIo {
        /// Where it is kept.
        at: String,
        /// What failed.
        #[source]
        source: std::io::Error,
    },
    /// The fill before solving failed (a refiner that does not fit the take).
    #[error(transparent)]
    Fill(#[from] locap_clean::FillError),
    /// Adam's state cannot be saved or restored.
    #[error("{at}: optimizer state: {source}")]
    OptimizerState {
        /// Where it is kept.
        at: String,
        /// What burn said.
        #[source]
        source: burn::store::RecordError,
    },
    /// A report that cannot be stored in a model file.
    #[error("training report: {0}")]
    Report(#[source] serde_json::Error),
}
