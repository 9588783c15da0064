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
