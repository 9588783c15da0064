//! Helpers shared by the integration tests: where the shared capture data lives.

#![allow(dead_code)]

use std::path::PathBuf;

/// `../shared/data` seen from the repository root, or `None` (with a message saying the tests
/// that need it are skipped) when it is absent. With the environment variable `CI` set,
/// missing data is a failure instead.
pub fn shared_data() -> Option<PathBuf> {
    locap_testkit::shared_data()
}
