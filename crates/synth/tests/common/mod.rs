//! Helpers shared by the integration tests: where the shared capture data lives.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// `../shared/data` seen from the repository root, or `None` (with a message saying the tests
/// that need it are skipped) when it is absent. With the environment variable `CI` set,
/// missing data is a failure instead.
pub fn shared_data() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else if std::env::var_os("CI").is_some() {
        panic!("../shared/data not found, and CI is set: tests on real captures must run");
    } else {
        eprintln!("skipping: ../shared/data not found (tests on real captures need it)");
        None
    }
}
