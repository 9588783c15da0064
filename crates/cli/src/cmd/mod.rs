//! One module per subcommand.

pub mod bench;
pub mod clean;
pub mod convert;
pub mod info;
pub mod label;
pub mod unlabel;
