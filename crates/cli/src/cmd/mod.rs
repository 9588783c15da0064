//! One module per subcommand.

pub mod bench;
pub mod clean;
pub mod convert;
pub mod eval;
pub mod hands;
pub mod info;
pub mod label;
pub mod layout;
pub mod plot;
pub mod solve;
pub mod stats;
pub mod synth;
pub mod train;
pub mod train_solve;
pub mod unlabel;
pub mod view;
