//! Pose matching on a real cyclic take (the Hamner subject's treadmill run from OpenSim's
//! example pipelines, `../shared/data/trc`, 41 markers at 60 Hz): one-second gaps hidden where
//! the marker was captured are filled from the other strides, where an interpolation across a
//! running stride is far off.

use locap_clean::{FillConfig, FillMethod, fill_gaps};
use locap_core::Take;

fn run_take() -> Option<Take> {
    let path = locap_testkit::shared_file("trc/Pipelines_Hamner_subject02_running.trc")?;
    Some(locap_io::trc::read_trc_path(&path).expect("the Hamner run reads"))
}

/// Mean error (mm) of `method` over the hidden samples of one 60-frame gap in each of eight
/// markers (one at a time).
fn mean_error(take: &Take, method: FillMethod) -> f64 {
    let (frames, markers) = (take.frame_count(), take.marker_count());
    let (mut sum, mut n) = (0.0, 0usize);
    for (case, marker) in (0..markers).step_by(markers.div_ceil(8)).enumerate() {
        let start = 100 + case * 50;
        assert!(start + 61 < frames && (start - 1..start + 61).all(|f| take.is_valid(f, marker)));
        let mut holed = take.clone();
        for f in start..start + 60 {
            holed.set_position_mm(f, marker, None).unwrap();
        }
        let out = fill_gaps(&holed, &FillConfig { method, ..FillConfig::default() });
        for f in start..start + 60 {
            let filled = out.take.position_mm(f, marker).expect("every hidden sample is filled");
            sum += (filled - take.position_mm(f, marker).unwrap()).norm();
            n += 1;
        }
    }
    sum / n as f64
}

#[test]
fn a_running_stride_is_filled_from_the_other_strides() {
    let Some(take) = run_take() else { return };
    let pose = mean_error(&take, FillMethod::PoseMatch);
    let spline = mean_error(&take, FillMethod::Spline);
    eprintln!("Hamner run, 1 s gaps: pose matching {pose:.1} mm, spline {spline:.1} mm");
    assert!(pose < 15.0 && pose < 0.1 * spline, "pose matching {pose:.1} mm, spline {spline:.1} mm");
}
