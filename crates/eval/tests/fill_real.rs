//! The fill benchmark on real takes: EDM must beat linear and spline interpolation on gaps
//! longer than half a second, as the paper claims. Accuracy, not speed: no timing asserted.

use locap_clean::FillMethod;
use locap_clean::neighbours::Selection;
use locap_eval::fill_bench::{self, Variant};
use locap_eval::gap_model::GapModel;

#[test]
fn edm_beats_interpolation_on_long_real_gaps() {
    let Some(data) = locap_testkit::shared_data() else { return };
    let read = |rel: &str| locap_io::c3d::read_path(&data.join(rel)).unwrap().to_take().unwrap();
    let takes =
        vec![("85_02".to_string(), read("cmu-c3d/85_02.c3d")), ("135_02".to_string(), read("cmu-c3d/135_02.c3d"))];
    let real = locap_core::GapStatistics::of_take(&read("numediart-c3d/03_rolling.c3d"));
    let mut model = GapModel::from_statistics([&real]).unwrap();
    model.max_gap_frames = 240;
    let v = |method| Variant { method, selection: Selection::Variance };
    let variants = [v(FillMethod::Edm), v(FillMethod::Linear), v(FillMethod::Spline)];
    let report = fill_bench::run(&takes, &model, &variants, 6, 7);
    eprintln!("{}", report.table());
    // Buckets from 61 frames (0.5 s at 120 Hz) up.
    let long = |m: &fill_bench::MethodResult| -> f64 {
        let b: Vec<_> = m.by_gap_length.iter().filter(|b| b.min_frames > 60 && b.samples > 0).collect();
        b.iter().map(|b| b.mean_mm.unwrap() * b.samples as f64).sum::<f64>()
            / b.iter().map(|b| b.samples).sum::<usize>() as f64
    };
    let (edm, linear, spline) = (long(&report.methods[0]), long(&report.methods[1]), long(&report.methods[2]));
    assert!(edm < linear && edm < spline, "long gaps: edm {edm:.1} mm, linear {linear:.1}, spline {spline:.1}");
    assert_eq!(report.methods[0].unfilled_samples, 0);
}
