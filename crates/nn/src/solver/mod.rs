//! The motion solver of LocalMoCap section 3.2 (Eq. 4-5) and its comparisons of section 4
//! (Table 1): cleaned markers in the waist frame -> per-frame joint rotations, bone offsets and
//! root translation, solved by a heterogeneous marker/joint graph network.
//!
//! * [`net`]: the networks (heterogeneous graph, no-marker-convolution ablation, Holden 2018
//!   MLP), Gram-Schmidt and forward kinematics in burn.
//! * [`data`]: training shards with their skeleton, the cleaning before solving, per-frame
//!   truth in the waist frame.
//! * [`train`]: Eq. 5 training with the shared harness ([`crate::harness`]).
//! * [`file`]: the model file (`LOCAPSV\0`) and inference on a take.
//! * [`ensemble`]: several networks' answers for a take, averaged.
//!
//! The paper's metrics (JOE, JPE, OMPE) on held-out shards are in `locap_eval::solver`.
//!
//! Body and hands are solved by separate networks, as in the paper: a body network in the
//! waist frame, a hand network per hand in its wrist frame (same code, `frame` and link
//! threshold set for the hand). The body+hands-in-one-network ablation needs takes with both
//! body and finger motion, which the data (CMU bodies, ART hands) does not have.

pub mod data;
pub mod ensemble;
pub mod file;
pub mod net;
pub mod train;

pub use data::{SolverShard, solver_shard};
pub use file::{Solver, SolverMeta};
pub use net::{NetConfig, Variant};
pub use train::{SolverData, SolverProgress, SolverReport, SolverTrainConfig, SolverValidation, train_solver};
