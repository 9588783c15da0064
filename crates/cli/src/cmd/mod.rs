//! One module per subcommand.

pub mod bench;
pub mod clean;
pub mod convert;
pub mod hands;
pub mod info;
pub mod layout;
pub mod stats;
pub mod synth;
