//! The learned gap-fill refiner of LocalMoCap section 3.1 (Eq. 3-4): EDM's fill corrected by a
//! graph-convolution + biLSTM network in the waist frame.
//!
//! * [`net`]: the network (graph convolution, biLSTM, offset head).
//! * [`data`]: clean takes, and the training examples cut from them and corrupted afresh.
//! * [`train`]: Eq. 3 training with the shared harness ([`crate::harness`]).
//! * [`file`]: the model file (`LOCAPNN\0`) and inference over overlapping windows.

pub mod data;
pub mod file;
pub mod net;
pub mod train;

pub use data::{TrainingData, shard_take};
pub use file::{ModelMeta, Refiner, refine_all, refine_all_of, window_starts};
pub use net::{Architecture, NetConfig, RefinerNet};
pub use train::{RefinerProgress, TrainConfig, TrainReport, train};
