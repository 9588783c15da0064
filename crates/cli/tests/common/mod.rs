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

/// A BVH that `locap solve` wrote (the animation tools' Y-up frame) against CMU's own
/// solution of the same take, `cmu-asfamc/SUBJECT/TAKE.amc` of `data` at 120 Hz (the
/// skeleton's motion frame; lab = `y_up_to_z_up(motion)`): both turns undone before comparing,
/// every joint counted.
pub fn bvh_against_cmu(bvh: &Path, data: &Path, subject: &str, take: &str) -> locap_eval::solver::MotionComparison {
    let solved = locap_io::bvh::read_bvh_path(bvh, locap_core::LengthUnit::Centimetre).unwrap();
    let to_lab = locap_core::units::y_up_to_z_up_rotation();
    let solved = locap_io::axes::motion_from_tools_y_up(&solved, to_lab, locap_core::UpAxis::Z);
    let asf = locap_io::asf_amc::read_asf_path(&data.join(format!("cmu-asfamc/{subject}/{subject}.asf"))).unwrap();
    let amc = data.join(format!("cmu-asfamc/{subject}/{take}.amc"));
    let reference = locap_io::asf_amc::read_amc_path(&amc, &asf, 120.0).unwrap();
    let rotating = vec![true; solved.skeleton.len()];
    locap_eval::solver::compare_motions(&solved, &reference, &rotating).unwrap()
}

/// The frame pairs with a joint turning over 20 degrees and the wrists' share within 60 mm of
/// their markers (%), as `locap solve` prints them.
pub fn tracking(stdout: &str) -> (usize, Option<f64>) {
    let at = stdout.find(" frame pairs over 20 deg").unwrap_or_else(|| panic!("no jumps in {stdout}"));
    let over = stdout[..at].rsplit(' ').next().unwrap().parse().unwrap();
    let wrists = stdout.find("of their markers ").map(|at| {
        let rest = &stdout[at + "of their markers ".len()..];
        rest[..rest.find('%').unwrap()].parse().unwrap()
    });
    (over, wrists)
}
