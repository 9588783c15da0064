//! Helpers shared by the CLI integration tests.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// The `locap` binary under test.
pub fn locap() -> Command {
    Command::new(env!("CARGO_BIN_EXE_locap"))
}

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `../shared/data`, or `None` (with a message saying the tests that need it are skipped)
/// when it is absent; with the environment variable `CI` set, missing data is a failure.
pub fn shared_data() -> Option<PathBuf> {
    locap_testkit::shared_data()
}
