//! The per-gap automatic fill ([`locap_clean::auto`]) on the shared gap-free takes, with the
//! fixed-length protocol of issue 15 (`protocol/mod.rs`), and its cost on a 10-minute take.
//!
//! The full measurement (every take, single and multi inputs, every method) is
//! `cargo run -p locap-clean --release --example auto_fill`; this test runs three of those
//! inputs, on takes no constant was chosen on, so it stays cheap.

mod protocol;

use locap_clean::auto::{self, AutoConfig};
use locap_clean::{FillConfig, FillMethod, fill_gaps};
use locap_core::{Take, Vec3};
use protocol::Score;
use std::time::Instant;

/// The RMSE (mm) over the hidden samples of `fill` on the protocol's single input (one gap
/// per fill) or multi input (all gaps and the arm gap at once) of `truth`.
fn protocol_rmse(truth: &Take, multi: bool, fill: &dyn Fn(&Take) -> locap_clean::Filled) -> Score {
    let gaps = protocol::gaps(truth, 5, 0);
    let limb = protocol::limb(truth, &gaps, 0);
    assert_eq!((gaps.len(), limb.len()), (20, 3));
    let inputs: Vec<Vec<protocol::Hidden>> = if multi {
        vec![gaps.iter().chain(&limb).cloned().collect()]
    } else {
        gaps.iter().map(|g| vec![g.clone()]).collect()
    };
    let mut score = Score::default();
    for hidden in &inputs {
        let input = protocol::holed(truth, hidden);
        protocol::score(truth, &fill(&input), &protocol::linear(&input), hidden, &mut score);
    }
    score
}

/// On takes no constant of [`AutoConfig`] was chosen on, auto's RMSE over the hidden samples
/// is no worse than 1.05 times the best single method's: CMU 135_02 single and multi inputs,
/// HDM05 single input. (HDM05's multi input, where auto loses on the arm gap, is reported by
/// the example, not asserted.)
#[test]
fn auto_is_no_worse_than_the_best_single_method_on_held_out_takes() {
    for (name, multi) in
        [("cmu-c3d/135_02.c3d", false), ("cmu-c3d/135_02.c3d", true), ("hdm05-c3d/HDM_bd_05-01_01_120.c3d", false)]
    {
        let Some(truth) = protocol::read_take(name) else { return };
        let auto_score = protocol_rmse(&truth, multi, &|t| {
            let out = auto::fill(t, &AutoConfig::default());
            // Every gap is recorded, with the samples it filled.
            assert_eq!(out.choices.iter().map(|c| c.filled).sum::<usize>(), out.filled.filled_count());
            assert!(out.choices.iter().all(|c| c.filled == c.frames.len() && !c.weights.is_empty()));
            out.filled
        });
        assert_eq!(auto_score.missing(), 0, "{name}: auto left hidden samples missing");
        let mut best = f64::INFINITY;
        for method in [FillMethod::Edm, FillMethod::Pca, FillMethod::Rigid, FillMethod::Spline] {
            let s = protocol_rmse(&truth, multi, &|t| fill_gaps(t, &FillConfig { method, ..FillConfig::default() }));
            eprintln!("{name} multi={multi}: {} {:.1} mm", method.name(), s.overall());
            best = best.min(s.overall());
        }
        let got = auto_score.overall();
        eprintln!("{name} multi={multi}: auto {got:.1} mm, best single method {best:.1} mm");
        assert!(got <= 1.05 * best, "{name} multi={multi}: auto {got:.1} mm, best {best:.1} mm");
    }
}

/// A 10-minute, 41-marker take at 120 Hz (HDM05 played forward and backward in turn) with 2%
/// of its samples hidden in seeded gaps of 1 frame to 2 s: the time to fill it.
#[test]
#[ignore = "timing; run with --ignored --nocapture"]
fn ten_minutes_with_two_percent_missing() {
    let Some(hdm) = protocol::read_take("hdm05-c3d/HDM_bd_05-01_01_120.c3d") else { return };
    let (n, m) = (hdm.frame_count(), hdm.marker_count());
    let frames = 72_000;
    let mut samples: Vec<Option<Vec3>> = Vec::with_capacity(frames * m);
    for f in 0..frames {
        let (lap, k) = (f / n, f % n);
        let src = if lap % 2 == 0 { k } else { n - 1 - k };
        samples.extend((0..m).map(|j| hdm.position_mm(src, j)));
    }
    let mut take = Take::from_samples(hdm.markers().to_vec(), &samples, 120.0).unwrap();
    let mut state = 7u64;
    let target = frames * m / 50;
    let mut hidden = 0;
    let mut gaps = 0;
    while hidden < target {
        let marker = (protocol::splitmix(&mut state) % m as u64) as usize;
        let len = 1 + (protocol::splitmix(&mut state) % 240) as usize;
        let start = (protocol::splitmix(&mut state) % (frames - len) as u64) as usize;
        for f in start..start + len {
            if take.is_valid(f, marker) {
                take.set_position_mm(f, marker, None).unwrap();
                hidden += 1;
            }
        }
        gaps += 1;
    }
    for method in [FillMethod::Edm, FillMethod::Auto] {
        let started = Instant::now();
        let out = fill_gaps(&take, &FillConfig { method, ..FillConfig::default() });
        eprintln!(
            "{}: {frames} frames x {m} markers, {hidden} samples hidden in {gaps} gaps, {} filled in {:.2?} on {} threads",
            method.name(),
            out.filled_count(),
            started.elapsed(),
            rayon::current_num_threads()
        );
    }
}
