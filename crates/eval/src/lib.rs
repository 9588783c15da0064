//! # locap-eval: measuring locap against baselines on real data
//!
//! # Gap-fill benchmark
//! The protocol of the LocalMoCap paper's Table 1 (OMPE: mean position error over occluded
//! samples only), on real takes: [`gap_model`] hides samples of gap-free (or mostly gap-free)
//! takes with gaps drawn from real occlusion statistics (Eq. 6 of section 3.3: per-marker
//! occlusion probability, heavy-tailed gap lengths, segments placed longest first without
//! overlap), and [`fill_bench`] fills them with every method on *the same* gaps, then scores
//! exactly the hidden samples.
//!
//! [`fill_candidates`] chooses the methods under test and the statistics the gaps are drawn
//! from, the same way for every front end.
//!
//! [`fill_lengths`] is the fixed-length protocol of the published gap fillers: gaps of set
//! lengths (0.1 / 0.5 / 1 / 2 s), one per input and all at once with a whole limb hidden
//! together, RMSE over the hidden samples per length.
//!
//! # Solver metrics
//! [`solver`] scores motion solvers on held-out synthetic shards as section 4.2 of the paper
//! does (JOE, JPE and the cleaning's OMPE, Table 1), and compares solved motions with a
//! reference solution of real takes.
//!
//! # Labeling benchmark
//! [`unlabel`] turns labeled takes into what a capture system delivers, and [`label_bench`]
//! scores labelers on them (identification rate, labeling paper section 5.1).
//!
//! Every error by gap length here is in the bins of [`locap_core::gaps::LENGTH_BINS`], so the
//! fill benchmark, the solver evaluation and the gap-length charts of `locap_view` compare.
//! Like the stages, this crate reads no files: the `locap` binary finds the takes and shards,
//! and draws the charts from the data series the reports give.

pub mod fill_bench;
pub mod fill_candidates;
pub mod fill_lengths;
/// Moved to `locap-synth` (the training-data augmentation and the benchmark share one gap
/// model); re-exported so `locap_eval::gap_model` keeps working.
pub use locap_synth::gap_model;
pub mod label_bench;
pub mod label_layout;
pub mod solver;
pub mod unlabel;
