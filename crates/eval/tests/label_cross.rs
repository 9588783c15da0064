//! Labeling a take that does not start in the template's pose (issue 16): the real 62-marker
//! take `KneeltoProne01` (240 Hz) cut in two, each half labeled with the other as template,
//! started by the articulated first fit with defaults (no template frame, no fit distance
//! chosen), points shuffled every frame; and the unlabeled captures of other subjects.

use locap_eval::label_bench::score;
use locap_eval::unlabel::{GhostMode, UnlabelConfig, unlabel};
use locap_label::{FitConfig, LabelConfig, Start, Template, label_frames, label_take};

fn kneel() -> Option<locap_core::Take> {
    let path = locap_testkit::shared_data()?.join("labeling/KneeltoProne01.c3d");
    Some(locap_io::c3d::read_path(&path).unwrap().to_take().unwrap())
}

/// (correct %, wrong %) labeling `target` (unlabeled with `ghosts` near ghosts at `fps`)
/// with `template`.
fn cross(template: &locap_core::Take, target: &locap_core::Take, ghosts: bool, fps: f64) -> (f64, f64) {
    let template = Template::from_take(template, None).unwrap();
    let config = UnlabelConfig {
        frame_rate_hz: Some(fps),
        ghosts: if ghosts { template.marker_count() } else { 0 },
        ghost_mode: GhostMode::Near,
        drop: None,
        seed: 11,
    };
    let u = unlabel(target, &config).unwrap();
    let (labels, fit) = label_frames(
        &u.frames,
        &template,
        &LabelConfig::default(),
        Start::Fit(FitConfig::default(), target.up_axis),
        None,
    )
    .unwrap();
    let fit = fit.unwrap();
    assert!(fit.sure_markers > 40, "{} sure markers", fit.sure_markers);
    let s = score(&u.truth_by_frame(), &labels, template.marker_count());
    (s.accuracy(), 100.0 * s.wrong as f64 / s.samples as f64)
}

/// An excerpt of each half (1.5 s) against the whole other half, both directions: the
/// issue's bars at 240 Hz without ghosts.
#[test]
fn each_half_labels_the_other_at_240_hz() {
    let Some(take) = kneel() else { return };
    let half = take.frame_count() / 2;
    let (first, second) = (take.slice_frames(0..half), take.slice_frames(half..take.frame_count()));
    let excerpt = |t: &locap_core::Take| t.slice_frames(0..360.min(t.frame_count()));
    for (name, template, target) in [("second by first", &first, &second), ("first by second", &second, &first)] {
        let (correct, wrong) = cross(template, &excerpt(target), false, 240.0);
        assert!(correct >= 99.0 && wrong <= 0.5, "{name}: {correct:.3}% correct, {wrong:.3}% wrong");
    }
}

/// With as many near ghosts as markers, and at 30 fps.
#[test]
fn each_half_labels_the_other_with_ghosts_and_at_30_fps() {
    let Some(take) = kneel() else { return };
    let half = take.frame_count() / 2;
    let (first, second) = (take.slice_frames(0..half), take.slice_frames(half..take.frame_count()));
    for (name, template, target) in [("second by first", &first, &second), ("first by second", &second, &first)] {
        let (correct, _) = cross(template, &target.slice_frames(0..480), true, 240.0);
        assert!(correct >= 97.0, "{name}, M ghosts: {correct:.3}% correct");
        let (correct, _) = cross(template, target, false, 30.0);
        assert!(correct >= 95.0, "{name}, 30 fps: {correct:.3}% correct");
    }
}

/// Other subjects, unlabeled captures, template KneeltoProne01 (another subject, whose
/// joint centres in the segments' frames differ by more than the template's tolerances):
/// labeled after calibrating the template on the take (`locap_label::subject`), with
/// defaults, to the 90% labeled and 90% of them within 20 mm of their segment
/// distances' median. Measured (docs/labeling.md): S09 94.8% / 99.1%, S01 97.2% / 97.9%;
/// before the first pass widened the template's plate shapes and refused bones twisted
/// past the template's turns, 88.5% / 96.5% and 71.7% / 88.5%.
#[test]
fn other_subjects_are_labeled_after_calibration() {
    let Some(take) = kneel() else { return };
    let data = locap_testkit::shared_data().unwrap();
    let template = Template::from_take(&take, None).unwrap();
    for (name, labeled_min, consistent_min) in
        [("S09_KneeltoRun02.c3d", 90.0, 90.0), ("S01_Pronetokneel01_mksrem.c3d", 90.0, 90.0)]
    {
        let raw = locap_io::c3d::read_path(&data.join("labeling").join(name)).unwrap().to_take().unwrap();
        let labeled = label_take(&raw, &template, &LabelConfig::default()).unwrap();
        assert!(labeled.calibrated.is_some(), "{name}: the template's own body fitted");
        let samples = labeled.labels.frame_count() * template.marker_count();
        let share = 100.0 * labeled.labeled_samples() as f64 / samples as f64;
        let (consistent, checked) = labeled.labels.median_edge_consistency(&labeled.frames, &template, 20.0);
        let within = 100.0 * consistent as f64 / checked as f64;
        assert!(share >= labeled_min && within >= consistent_min, "{name}: {share:.2}% labeled, {within:.2}% within");
    }
}
