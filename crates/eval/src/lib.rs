//! # locap-eval: measuring locap against baselines on real data
//!
//! # Gap-fill benchmark
//! The protocol of the LocalMoCap paper's Table 1 (OMPE: mean position error over occluded
//! samples only), on real takes: [`gap_model`] hides samples of gap-free (or mostly gap-free)
//! takes with gaps drawn from real occlusion statistics (Eq. 6 of section 3.3: per-marker
//! occlusion probability, heavy-tailed gap lengths, segments placed longest first without
//! overlap), and [`fill_bench`] fills them with every method on *the same* gaps, then scores
//! exactly the hidden samples.

pub mod fill_bench;
/// Moved to `locap-synth` (the training-data augmentation and the benchmark share one gap
/// model); re-exported so `locap_eval::gap_model` keeps working.
pub use locap_synth::gap_model;
pub mod label_bench;
pub mod unlabel;
