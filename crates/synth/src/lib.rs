//! # locap-synth: training data from skeleton motion (LocalMoCap sections 3.3 and 4)
//!
//! The networks of LocalMoCap learn from pairs *(corrupted markers -> clean markers, skeleton
//! motion)*. The paper drives a licensed body model with CMU motion; locap builds its own
//! synthetic capture from open skeleton motion. The pipeline, one module per step:
//!
//! 1. [`layout`]: a marker layout file (TOML) says which marker rides on which joint and
//!    where, optionally sliding between two segments like skin.
//! 2. [`calibrate`]: the layout's offsets are fitted by least squares to real labeled takes
//!    for which the solved skeleton motion exists (CMU 01_01 and 02_01), with per-marker
//!    residuals.
//! 3. [`synthesize`]: motion + layout -> clean marker take, with a random subject per take
//!    (bone-length scale, offset jitter, smooth soft-tissue wobble) and resampling.
//! 4. [`gap_model`] and [`augment`]: occlusion gaps with the per-marker occlusion
//!    probabilities and heavy-tailed gap lengths of real captures, placed longest first
//!    without overlap (Eq. 6), plus shift outliers; or the per-frame random corruption of
//!    Holden (2018) for comparison.
//! 5. [`shard`]: a compact, chunk-streamable binary file per take (clean and corrupted
//!    markers, visibility, joint positions and rotations) for training.
//!
//! Two more ways to get a layout or motion: [`fit`] fits a layout's offsets to a real take's
//! marker distances when no skeleton motion exists, and [`hand`] builds hand skeleton motion
//! from an ART hand export (fitted joint angles, plus procedural finger motion within joint
//! limits) and the paper's hand marker layout. [`opensim`] builds a layout and its skeleton (with
//! joint limits) from an OpenSim model and marker set.
//!
//! This crate never touches files: it takes and returns `locap_core` types (and writes
//! training shards to any `std::io::Write`). `locap synth`, `locap stats` and
//! `locap layout` are where files meet it.

pub mod augment;
pub mod calibrate;
pub mod fit;
pub mod gap_model;
pub mod hand;
pub mod layout;
pub mod opensim;
pub mod shard;
pub mod synthesize;
#[cfg(test)]
mod test_util;

pub use layout::{Layout, Region};
