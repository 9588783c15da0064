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
