//! One module per subcommand.

pub mod bench;
pub mod clean;
pub mod convert;
pub mod info;
pub mod plot;
pub mod view;
