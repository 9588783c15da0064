//! Gap-fill methods on a real take (CMU 85_02 from `../shared/data`): hide 60 frames of a
//! marker where it was captured, fill, and score exactly the hidden samples. Also a timing
//! check of the PCA fill on a long synthetic take (ignored by default; run with `--ignored`).

use locap_clean::{FillConfig, FillMethod, fill_gaps};
use locap_core::{MarkerName, Take, Vec3};
use std::time::Instant;

fn real_take() -> Option<Take> {
    let path = locap_testkit::shared_file("cmu-c3d/85_02.c3d")?;
    Some(locap_io::c3d::read_path(&path).expect("85_02.c3d reads").to_take().expect("85_02.c3d converts"))
}

/// Mean error in mm of each method over 60-frame gaps hidden in several markers, one marker
/// at a time, where the marker is captured just around the gap.
#[test]
fn real_take_sixty_frame_gaps() {
    let Some(take) = real_take() else { return };
    let (frames, markers) = (take.frame_count(), take.marker_count());
    let len = 60;
    let mut totals = vec![(0.0, 0usize, 0usize); FillMethod::ALL.len()];
    let mut cases = 0;
    for (case, marker) in (0..markers).step_by(markers.div_ceil(8).max(1)).enumerate() {
        let start = frames / 5 + case * frames / 12;
        if start + len + 1 >= frames || (start - 1..start + len + 1).any(|f| !take.is_valid(f, marker)) {
            continue;
        }
        cases += 1;
        let mut holed = take.clone();
        for f in start..start + len {
            holed.set_position_mm(f, marker, None).unwrap();
        }
        for (k, method) in FillMethod::ALL.iter().enumerate() {
            let out = fill_gaps(&holed, &FillConfig { method: *method, ..FillConfig::default() });
            for f in start..start + len {
                match out.take.position_mm(f, marker) {
                    Some(p) => {
                        let e = (p - take.position_mm(f, marker).unwrap()).norm();
                        assert!(e.is_finite());
                        totals[k].0 += e;
                        totals[k].1 += 1;
                    }
                    None => totals[k].2 += 1,
                }
            }
        }
    }
    assert!(cases > 0, "no usable marker in 85_02");
    eprintln!("85_02: {frames} frames, {markers} markers, {cases} gaps of {len} frames");
    for (method, (sum, n, unfilled)) in FillMethod::ALL.iter().zip(&totals) {
        let mean = sum / (*n).max(1) as f64;
        eprintln!("{:>7}: mean error {mean:7.2} mm over {n} samples, {unfilled} left missing", method.name());
        // Every method but rigid (which needs 3 donors) fills what it is given.
        if *method != FillMethod::Rigid {
            assert_eq!(*unfilled, 0, "{}", method.name());
        }
    }
}

/// 72,000 frames of 41 markers (10 minutes at 120 Hz), every marker with gaps: PCA must take
/// seconds, not minutes.
#[test]
#[ignore = "timing; run with --ignored --nocapture"]
fn pca_on_a_long_take() {
    let (frames, markers) = (72_000, 41);
    let names = (0..markers).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
    let mut samples = Vec::with_capacity(frames * markers);
    for t in 0..frames {
        let s = t as f64 / 120.0;
        for m in 0..markers {
            let seg = (m / 4) as f64;
            let hidden = (t + 997 * m) % 6000 < 40; // a 40-frame gap every 50 s per marker
            let p = Vec3::new(
                200.0 * seg + 50.0 * (s + seg).sin() + (m % 4) as f64 * 30.0,
                100.0 * (0.7 * s + seg).cos() + 5.0 * (3.0 * s + m as f64).sin(),
                1000.0 + 80.0 * (1.3 * s).sin() + 10.0 * m as f64,
            );
            samples.push((!hidden).then_some(p));
        }
    }
    let take = Take::from_samples(names, &samples, 120.0).unwrap();
    let start = Instant::now();
    let out = locap_clean::baseline::pca::fill(&take, &Default::default());
    let elapsed = start.elapsed();
    eprintln!("pca: {frames} x {markers}, {} samples filled in {elapsed:.2?}", out.filled_count());
    assert_eq!(out.filled_count(), take.missing_count());
    assert!(elapsed.as_secs_f64() < 30.0);
}
