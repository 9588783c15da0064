//! Measures the default outlier detection ([`locap_clean::outliers`]) on the shared gap-free
//! takes (issue 15, item 3): windows and samples flagged on clean data (false positives), how
//! far the spline refill moves the flagged samples, and recall / precision on seeded injected
//! single-sample spikes of 10-50 mm in random directions.
//!
//! ```text
//! cargo run -p locap-clean --release --example outlier_eval -- [--spikes 20] [--seed 0]
//!     [--floor BODY_MM,HAND_MM] [--neighbours N]
//! ```
//!
//! `--floor 0,0 --neighbours 0` is the rule before issue 15. With `OUTLIER_EVAL_LIST=1` every
//! window flagged on the clean takes is listed on stderr with its marker, kind, peak and the
//! deviation from the local fit ([`outliers::deviation_mm`]) of each sample in it.

use locap_clean::outliers::{self, OutlierConfig};
use locap_clean::{Filled, refill_outliers};
use locap_core::{Take, Vec3};

const TAKES: [&str; 5] = [
    "cmu-c3d/85_02.c3d",
    "cmu-c3d/85_12.c3d",
    "cmu-c3d/135_02.c3d",
    "hdm05-c3d/HDM_bd_05-01_01_120.c3d",
    "labeling/KneeltoProne01.c3d",
];

/// splitmix64: a seeded generator without a dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// The longest run of frames in which every labeled marker is present (KneeltoProne01 has real
/// gaps; the others are whole).
fn gap_free(take: &Take) -> std::ops::Range<usize> {
    let labeled: Vec<usize> = (0..take.marker_count()).filter(|m| !take.markers()[*m].is_unlabeled()).collect();
    let (mut best, mut start) = (0..0, 0);
    for f in 0..=take.frame_count() {
        let whole = f < take.frame_count() && labeled.iter().all(|m| take.is_valid(f, *m));
        if !whole {
            if f - start > best.len() {
                best = start..f;
            }
            start = f + 1;
        }
    }
    best
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |flag: &str| args.iter().position(|a| a == flag).and_then(|k| args.get(k + 1)).cloned();
    let spikes: usize = get("--spikes").map_or(20, |s| s.parse().expect("--spikes"));
    let seed: u64 = get("--seed").map_or(0, |s| s.parse().expect("--seed"));
    let mut config = OutlierConfig::default();
    if let Some(v) = get("--floor") {
        let (b, h) = v.split_once(',').expect("--floor BODY,HAND");
        config.body_floor_mm = b.parse().expect("--floor");
        config.hand_floor_mm = h.parse().expect("--floor");
    }
    if let Some(v) = get("--neighbours") {
        config.segment_neighbours = v.parse().expect("--neighbours");
    }
    println!(
        "| take | Hz | frames | clean: windows | clean: samples | refill moves (median / max mm) | noise (mm) | recall \
         | precision |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for rel in TAKES {
        let Some(path) = locap_testkit::shared_file(rel) else { continue };
        let full = locap_io::c3d::read_path(&path).expect("read").to_take().expect("take");
        let range = gap_free(&full);
        let truth = full.slice_frames(range);
        let found = outliers::detect(&truth, &config);
        if std::env::var_os("OUTLIER_EVAL_LIST").is_some() {
            for o in &found {
                let devs: Vec<String> = o
                    .frames
                    .clone()
                    .map(|t| outliers::deviation_mm(&truth, o.marker, t).map_or("-".into(), |d| format!("{d:.1}")))
                    .collect();
                eprintln!(
                    "{rel} {} {:?} {:?} peak {:.0} dev {}",
                    truth.markers()[o.marker].label,
                    o.frames,
                    o.kind,
                    o.peak_m_s2,
                    devs.join(" ")
                );
            }
        }
        let samples: usize = found.iter().map(|o| o.frames.len()).sum();
        // How far the refill moves what was flagged (spline through the window, as `clean`).
        let mut holed = truth.clone();
        outliers::remove(&mut holed, &found);
        let mut filled = Filled::unchanged(&holed);
        refill_outliers(&mut filled, &found);
        let mut moves: Vec<f64> = Vec::new();
        for o in &found {
            for f in o.frames.clone() {
                if let (Some(a), Some(b)) = (filled.take.position_mm(f, o.marker), truth.position_mm(f, o.marker)) {
                    moves.push((a - b).norm());
                }
            }
        }
        moves.sort_by(f64::total_cmp);
        // The marker noise to compare the moves with: the median distance of a sample from the
        // local cubic through its neighbours, over every sample of the take.
        let t = &truth;
        let mut noise: Vec<f64> = (0..t.marker_count())
            .filter(|m| !t.markers()[*m].is_unlabeled())
            .flat_map(|m| (0..t.frame_count()).filter_map(move |f| outliers::deviation_mm(t, m, f)))
            .collect();
        noise.sort_by(f64::total_cmp);
        let noise = noise.get(noise.len() / 2).copied().unwrap_or(0.0);
        let moved = if moves.is_empty() {
            "-".to_string()
        } else {
            format!("{:.1} / {:.1}", moves[moves.len() / 2], moves[moves.len() - 1])
        };
        // Injected single-sample spikes, 10-50 mm in a random direction.
        let mut rng = Rng(seed ^ (rel.len() as u64 * 0x1234_5678));
        let labeled: Vec<usize> = (0..truth.marker_count()).filter(|m| !truth.markers()[*m].is_unlabeled()).collect();
        let mut corrupted = truth.clone();
        let mut injected: Vec<(usize, usize)> = Vec::new();
        let mut sizes: Vec<f64> = Vec::new();
        while injected.len() < spikes {
            let marker = labeled[rng.below(labeled.len())];
            let frame = 5 + rng.below(truth.frame_count() - 10);
            if injected.iter().any(|(m, f)| *m == marker && f.abs_diff(frame) < 10) {
                continue;
            }
            let dir = loop {
                let v = Vec3::new(rng.unit() * 2.0 - 1.0, rng.unit() * 2.0 - 1.0, rng.unit() * 2.0 - 1.0);
                if v.norm() > 0.1 && v.norm() <= 1.0 {
                    break v.normalize();
                }
            };
            let d = 10.0 + 40.0 * rng.unit();
            let p = corrupted.position_mm(frame, marker).expect("gap-free");
            corrupted.set_position_mm(frame, marker, Some(p + dir * d)).expect("set");
            injected.push((marker, frame));
            sizes.push(d);
        }
        let hits = outliers::detect(&corrupted, &config);
        let recalled =
            injected.iter().filter(|(m, f)| hits.iter().any(|o| o.marker == *m && o.frames.contains(f))).count();
        if std::env::var_os("OUTLIER_EVAL_LIST").is_some() {
            for ((m, f), d) in injected.iter().zip(&sizes) {
                if !hits.iter().any(|o| o.marker == *m && o.frames.contains(f)) {
                    eprintln!("{rel}: missed {d:.1} mm spike of {} at {f}", truth.markers()[*m].label);
                }
            }
        }
        let true_windows =
            hits.iter().filter(|o| injected.iter().any(|(m, f)| o.marker == *m && o.frames.contains(f))).count();
        println!(
            "| {rel} | {} | {} | {} | {} | {moved} | {noise:.2} | {:.2} | {:.2} |",
            truth.frame_rate_hz(),
            truth.frame_count(),
            found.len(),
            samples,
            recalled as f64 / spikes as f64,
            if hits.is_empty() { 1.0 } else { true_windows as f64 / hits.len() as f64 },
        );
    }
    // The shipped example (real gaps): windows `locap clean` removes with the default stage.
    let shipped = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/cmu_01_01_last10s.c3d");
    if let Ok(file) = locap_io::c3d::read_path(&shipped) {
        let take = file.to_take().expect("take");
        let clean_config = locap_clean::CleanConfig { outliers: Some(config.clone()), ..Default::default() };
        let cleaned = locap_clean::clean(&take, &clean_config);
        println!(
            "examples/cmu_01_01_last10s.c3d: {} windows, {} samples",
            cleaned.outliers.len(),
            cleaned.outlier_samples
        );
    }
}
