//! Helpers shared by the integration tests: where the shared capture data lives.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// `../shared/data` seen from the repository root, or `None` (with a message saying the tests
/// that need it are skipped) when it is absent, as on a user's fresh clone.
pub fn shared_data() -> Option<PathBuf> {
    locap_testkit::shared_data()
}

/// Every file under `dir` whose extension is `ext` (case-insensitive), sorted.
pub fn files_with_extension(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else { continue };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().and_then(|x| x.to_str()).is_some_and(|x| x.eq_ignore_ascii_case(ext)) {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Where `.ci/run` installs the Python reference readers (ezc3d, py-c3d): `.ci/pydeps`, or
/// `$LOCAP_PYDEPS`.
pub fn pydeps() -> PathBuf {
    std::env::var_os("LOCAP_PYDEPS")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.ci/pydeps"))
}

/// True if python3 imports `modules` (e.g. `"ezc3d, numpy"`) from [`pydeps`]; otherwise false
/// after saying the check is skipped, and a failure under CI, which must install them.
pub fn python_has(modules: &str) -> bool {
    let ok = std::process::Command::new("python3")
        .args(["-c", &format!("import {modules}")])
        .env("PYTHONPATH", pydeps())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        assert!(std::env::var_os("CI").is_none(), "CI must install {modules} into .ci/pydeps (see .ci/run)");
        eprintln!("skipping: {modules} not importable from {} (run .ci/run once to install it)", pydeps().display());
    }
    ok
}
