//! Test helpers shared by every locap crate (a dev-dependency only).
//!
//! Tests on real captures read `../shared/data` beside the repository. A user's fresh clone
//! does not have it, so there such a test says loudly that it skipped; under CI (environment
//! variable `CI` set) a missing folder is a broken setup, and the test fails instead of
//! passing without having run.
//!
//! The fixtures ([`rigid_cluster`]) are the synthetic takes several crates' unit tests share.

use locap_core::{MarkerName, Take, Vec3};
use std::path::{Path, PathBuf};

/// Offsets of the [`rigid_cluster`] markers from the first, mm: spread out of any line or
/// plane, so three of them fix the cluster's pose.
pub const CLUSTER_OFFSETS_MM: [[f64; 3]; 6] = [
    [0.0, 0.0, 0.0],
    [120.0, 10.0, 0.0],
    [0.0, 90.0, 30.0],
    [40.0, 40.0, 110.0],
    [-70.0, 20.0, 50.0],
    [30.0, -80.0, 20.0],
];

/// A take at 120 Hz of `markers` (at most 6) markers on one rigid body that moves 5 mm a frame
/// along x, sways 100 mm in y and turns about all three axes, so every method that uses the
/// segment's rigidity (EDM, rigid, PCA) can fill it exactly and interpolation cannot. Marker
/// `k` is named `name(k)`; `drift_mm(frame, k)` is added to its offset (zero for a rigid body;
/// a marker sliding off the body otherwise).
///
/// # Panics
/// More than 6 markers.
pub fn rigid_cluster(
    frames: usize,
    markers: usize,
    name: impl Fn(usize) -> String,
    drift_mm: impl Fn(usize, usize) -> [f64; 3],
) -> Take {
    assert!(markers <= CLUSTER_OFFSETS_MM.len(), "the cluster has {} markers", CLUSTER_OFFSETS_MM.len());
    let names = (0..markers).map(|k| MarkerName::parse(&name(k))).collect();
    let mut samples = Vec::with_capacity(frames * markers);
    for f in 0..frames {
        let a = f as f64 * 0.03;
        let rot = nalgebra::Rotation3::from_euler_angles(0.3 * a, a, 0.5 * a.sin());
        let base = Vec3::new(5.0 * f as f64, 100.0 * a.cos(), 900.0);
        for (k, o) in CLUSTER_OFFSETS_MM[..markers].iter().enumerate() {
            samples.push(Some(base + rot * (Vec3::from(*o) + Vec3::from(drift_mm(f, k)))));
        }
    }
    Take::from_samples(names, &samples, 120.0).expect("a well-formed take")
}

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

/// An external program the export tests read locap's files with, installed by `.ci/run`
/// under `.ci/`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tool {
    /// Blender as a Python module (`bpy` from PyPI, Python 3.13), in `.ci/bpy-venv`.
    Blender,
    /// OpenSim 4.6 (`opensim` from PyPI, Python 3.11), in `.ci/opensim`.
    OpenSim,
    /// The Khronos glTF validator (`gltf-validator` from npm, run by node), in `.ci/node`.
    GltfValidator,
}

/// A command that runs `tool`'s interpreter (python or node) with the tool importable; give it
/// a script and arguments. `None` after printing that the check is skipped when the tool is
/// not installed.
///
/// # Panics
/// When the tool is missing and `CI` is set: CI installs every tool, so a missing one is a
/// broken setup, not a skip.
pub fn tool(tool: Tool) -> Option<std::process::Command> {
    let ci = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.ci");
    let command = || {
        let mut c = match tool {
            Tool::Blender => std::process::Command::new(ci.join("bpy-venv/bin/python")),
            Tool::OpenSim => {
                let mut c = std::process::Command::new("python3");
                c.env("PYTHONPATH", ci.join("opensim"));
                c
            }
            Tool::GltfValidator => {
                let mut c = std::process::Command::new("node");
                c.env("NODE_PATH", ci.join("node/node_modules"));
                c
            }
        };
        c.stdin(std::process::Stdio::null());
        c
    };
    let probe = match tool {
        Tool::Blender => ["-c", "import bpy"],
        Tool::OpenSim => ["-c", "import opensim"],
        Tool::GltfValidator => ["-e", "require('gltf-validator')"],
    };
    let ok = command()
        .args(probe)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if ok {
        return Some(command());
    }
    assert!(std::env::var_os("CI").is_none(), "CI must install {tool:?} under {} (see .ci/run)", ci.display());
    eprintln!("skipping the {tool:?} check: not installed under {} (run .ci/run once to install it)", ci.display());
    None
}

/// Runs `command` (from [`tool`]) and returns the last line it prints that opens a JSON
/// object (the scripts' report; tools print progress before it), panicking with its output
/// when it fails.
pub fn run_json(mut command: std::process::Command) -> String {
    let out = command.output().expect("the tool starts");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{command:?} failed:\n{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    stdout.lines().rev().find(|l| l.trim_start().starts_with('{')).unwrap_or_default().to_string()
}
