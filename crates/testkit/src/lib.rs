//! Test helpers shared by every locap crate (a dev-dependency only).
//!
//! Tests on real captures read `../shared/data` beside the repository. A user's fresh clone
//! does not have it, so there such a test says loudly that it skipped; under CI (environment
//! variable `CI` set) a missing folder is a broken setup, and the test fails instead of
//! passing without having run.

use std::path::{Path, PathBuf};

/// `../shared/data` seen from the repository root, or `None` after printing that the test is
/// skipped.
///
/// # Panics
/// When the folder is missing and `CI` is set.
pub fn shared_data() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else if std::env::var_os("CI").is_some() {
        panic!("{} not found, and CI is set: tests on real captures must run", dir.display());
    } else {
        eprintln!("skipping: ../shared/data not found (tests on real captures need it)");
        None
    }
}

/// `../shared/data/RELATIVE`, or `None` as [`shared_data`] says.
///
/// # Panics
/// When the data folder is missing and `CI` is set, or when it exists without `relative`
/// (a test naming a file the shared data does not hold is a broken test, not a skip).
pub fn shared_file(relative: &str) -> Option<PathBuf> {
    let path = shared_data()?.join(relative);
    assert!(path.exists(), "{} is not in the shared data", path.display());
    Some(path)
}
