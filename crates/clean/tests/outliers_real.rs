//! Outlier detection on real captures: injected spikes are found and repaired, clean data is
//! left alone.

use locap_clean::outliers::{self, OutlierConfig};
use locap_clean::{FillConfig, fill_gaps, refill_outliers};
use locap_core::{Take, Vec3};

fn read(rel: &str) -> Option<Take> {
    let path = locap_testkit::shared_file(rel)?;
    Some(locap_io::c3d::read_path(&path).unwrap().to_take().unwrap())
}

#[test]
fn injected_spikes_in_a_real_take_are_found_and_repaired() {
    let Some(truth) = read("cmu-c3d/85_02.c3d") else { return };
    let config = OutlierConfig::default();
    assert!(outliers::detect(&truth, &config).is_empty(), "85_02 is clean");
    // 30 spikes of 15-45 mm, single frames and 3-frame jumps, spread over markers and time.
    let mut corrupted = truth.clone();
    let mut injected = Vec::new();
    for k in 0..30usize {
        let marker = (k * 7) % truth.marker_count();
        let frame = 20 + (k * 97) % (truth.frame_count() - 40);
        let len = if k % 3 == 0 { 3 } else { 1 };
        let shift = Vec3::new(15.0 + k as f64, -(k as f64), 10.0);
        for f in frame..frame + len {
            let p = corrupted.position_mm(f, marker).unwrap();
            corrupted.set_position_mm(f, marker, Some(p + shift)).unwrap();
        }
        injected.push((marker, frame..frame + len));
    }
    let found = outliers::detect(&corrupted, &config);
    for (marker, frames) in &injected {
        assert!(
            found.iter().any(|o| o.marker == *marker && o.frames.start <= frames.start && o.frames.end >= frames.end),
            "spike of marker {marker} at {frames:?} not found"
        );
    }
    assert!(found.len() <= injected.len() + 2, "{} found for {} injected", found.len(), injected.len());
    // Repair as `locap clean` does, and compare with the truth.
    let mut holed = corrupted.clone();
    outliers::remove(&mut holed, &found);
    let mut filled = fill_gaps(&holed, &FillConfig::default());
    refill_outliers(&mut filled, &found);
    let mut worst: f64 = 0.0;
    let mut sum = 0.0;
    let mut n = 0;
    for (marker, frames) in &injected {
        for f in frames.clone() {
            let e = (filled.take.position_mm(f, *marker).unwrap() - truth.position_mm(f, *marker).unwrap()).norm();
            worst = worst.max(e);
            sum += e;
            n += 1;
        }
    }
    eprintln!("repaired spikes: mean error {:.2} mm, worst {:.2} mm", sum / n as f64, worst);
    assert!(sum / (n as f64) < 5.0 && worst < 15.0, "mean {} worst {worst}", sum / n as f64);
}

#[test]
fn clean_takes_keep_their_impacts() {
    // HDM05 feet strike the floor hard (accelerations above the threshold) and stand still on
    // an integer-coded file (identical samples): neither is an outlier.
    let Some(take) = read("hdm05-c3d/HDM_bd_05-01_01_120.c3d") else { return };
    let found = outliers::detect(&take, &OutlierConfig::default());
    assert!(found.len() <= 3, "{} outliers in a clean take: {:?}", found.len(), &found[..found.len().min(5)]);
}

#[test]
fn swapped_labels_in_real_takes_are_found_and_undone() {
    use locap_clean::swaps::{self, Swap, SwapConfig};
    let config = SwapConfig::default();
    for rel in ["cmu-c3d/85_02.c3d", "cmu-c3d/135_02.c3d", "hdm05-c3d/HDM_bd_05-01_01_120.c3d"] {
        let Some(take) = read(rel) else { return };
        let found = swaps::detect(&take, &config);
        assert!(found.is_empty(), "{rel}: clean take reported swaps {found:?}");
    }
    let Some(truth) = read("cmu-c3d/85_02.c3d") else { return };
    let (a, b) = (truth.marker_index("LFWT").unwrap(), truth.marker_index("LKNE").unwrap());
    let (a, b) = (a.min(b), a.max(b));
    let mut swapped = truth.clone();
    swaps::unswap(&mut swapped, &[Swap { a, b, frames: 200..320 }]);
    let found = swaps::detect(&swapped, &config);
    assert_eq!(found, vec![Swap { a, b, frames: 200..320 }]);
    swaps::unswap(&mut swapped, &found);
    assert_eq!(swapped, truth);
}

/// splitmix64, so the injected spikes are the same on every run.
fn next(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[test]
fn clean_takes_are_left_alone_and_random_spikes_are_found() {
    // 85_12 (120 Hz, 4499 frames) flagged nothing after the rule of issue 15; HDM05 keeps one
    // stuck-marker window. 40 single-sample spikes of 10-50 mm in random directions, on random
    // markers and frames.
    for (rel, allowed) in [("cmu-c3d/85_12.c3d", 1), ("hdm05-c3d/HDM_bd_05-01_01_120.c3d", 1)] {
        let Some(truth) = read(rel) else { return };
        let config = OutlierConfig::default();
        let found = outliers::detect(&truth, &config);
        assert!(found.len() <= allowed, "{rel}: {} windows on a clean take: {found:?}", found.len());
        let labeled: Vec<usize> = (0..truth.marker_count()).filter(|m| !truth.markers()[*m].is_unlabeled()).collect();
        let mut state = 15;
        let mut unit = || (next(&mut state) >> 11) as f64 / (1u64 << 53) as f64;
        let mut corrupted = truth.clone();
        let mut injected: Vec<(usize, usize)> = Vec::new();
        while injected.len() < 40 {
            let marker = labeled[(unit() * labeled.len() as f64) as usize];
            let frame = 5 + (unit() * (truth.frame_count() - 10) as f64) as usize;
            if injected.iter().any(|(m, f)| *m == marker && f.abs_diff(frame) < 10) {
                continue;
            }
            let v = Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5);
            if v.norm() < 0.05 {
                continue;
            }
            let p = corrupted.position_mm(frame, marker).unwrap();
            corrupted.set_position_mm(frame, marker, Some(p + v.normalize() * (10.0 + 40.0 * unit()))).unwrap();
            injected.push((marker, frame));
        }
        let hits = outliers::detect(&corrupted, &config);
        let recalled = injected.iter().filter(|(m, f)| hits.iter().any(|o| o.marker == *m && o.frames.contains(f)));
        let recall = recalled.count() as f64 / injected.len() as f64;
        assert!(recall >= 0.9, "{rel}: recall {recall}");
        assert!(hits.len() <= injected.len() + allowed, "{rel}: {} windows for {} spikes", hits.len(), injected.len());
    }
}
