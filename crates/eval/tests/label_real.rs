//! Labeling on real takes: a labeled take, unlabeled (points shuffled every frame) and labeled
//! again from its template, must get its own labels back on every sample whose point is there.

use locap_eval::unlabel::{GhostMode, UnlabelConfig, unlabel};
use locap_label::{FitConfig, LabelConfig, Start, Template, label_frames};
use std::path::Path;

fn data() -> Option<std::path::PathBuf> {
    locap_testkit::shared_data()
}

/// Per marker: (label, wrong, missed) over the whole take.
fn roundtrip(path: &Path) -> Vec<(String, usize, usize)> {
    let take = locap_io::c3d::read_path(path).unwrap().to_take().unwrap();
    let template = Template::from_take(&take, None).unwrap();
    let config = UnlabelConfig { frame_rate_hz: None, ghosts: 0, ghost_mode: GhostMode::Near, drop: None, seed: 5 };
    let u = unlabel(&take, &config).unwrap();
    let (labels, _) = label_frames(
        &u.frames,
        &template,
        &LabelConfig::default(),
        Start::Fit(FitConfig::default(), take.up_axis),
        None,
    )
    .unwrap();
    // A marker named `X-1` whose `X` exists is a fragment of X's trajectory under another
    // name (CMU 01_01 has `RBAC-1` for 8 frames while RBAC is missing): the same physical
    // marker, so labeling its point X is right.
    let names: Vec<String> = template.names().iter().map(|n| n.label.clone()).collect();
    let same_as: Vec<i32> = (0..names.len())
        .map(|m| {
            let base = names[m].rsplit_once('-').map(|(base, _)| base);
            base.and_then(|b| names.iter().position(|n| n == b)).unwrap_or(m) as i32
        })
        .collect();
    let canonical: Vec<Vec<i32>> = u
        .truth_by_frame()
        .iter()
        .map(|t| t.iter().map(|&k| if k >= 0 { same_as[k as usize] } else { k }).collect())
        .collect();
    let truth: Vec<&[i32]> = canonical.iter().map(|t| t.as_slice()).collect();
    let mut out: Vec<(String, usize, usize)> = template.names().iter().map(|n| (n.full(), 0, 0)).collect();
    for (f, frame_truth) in truth.iter().enumerate() {
        for (m, counts) in out.iter_mut().enumerate() {
            let present = frame_truth.contains(&(m as i32));
            match labels.get(f, m) {
                Some(p) if frame_truth[p] == m as i32 => {}
                None if !present => {}
                None => counts.2 += 1,
                Some(_) => counts.1 += 1,
            }
        }
    }
    out
}

#[test]
fn unlabel_then_label_gives_the_labels_back() {
    let Some(data) = data() else { return };
    // Not 135_02: its martial-arts strikes move the wrists up to 130 mm per frame at 120 Hz
    // with frame-to-frame jumps of the same size; labeling gets 93% of its samples (see the
    // issue notes), not all.
    for take in ["cmu-c3d/85_02.c3d", "cmu-c3d/85_12.c3d", "cmu-c3d/02_01.c3d", "cmu-c3d/01_01.c3d", "hdm05-c3d"] {
        let path = data.join(take);
        let path = if path.is_dir() {
            std::fs::read_dir(&path)
                .unwrap()
                .map(|e| e.unwrap().path())
                .find(|p| p.extension().is_some_and(|e| e == "c3d"))
                .unwrap()
        } else {
            path
        };
        let result = roundtrip(&path);
        // CMU 01_01 has `RBAC-1`, a fragment of RBAC's trajectory under its own name for 8
        // frames: the same physical marker, which can only be labeled RBAC.
        let bad: Vec<_> = result.iter().filter(|(name, w, m)| w + m > 0 && name != "RBAC-1").collect();
        assert!(bad.is_empty(), "{take}: markers with wrong or missed samples (label, wrong, missed): {bad:?}");
    }
}

/// The bar at the hardest frame rate: at 30 fps, with the built-in heavy occlusions
/// and with and without near ghosts, ours identifies more trajectories and labels more
/// samples right than UGM and CP on the real CMU + HDM05 takes (seeded: same points for all).
#[test]
fn ours_beats_the_baselines_at_30_fps_under_heavy_occlusion() {
    use locap_eval::label_bench::{LabelBenchConfig, run};
    let Some(data) = data() else { return };
    let mut paths: Vec<std::path::PathBuf> = Vec::new();
    for folder in ["cmu-c3d", "hdm05-c3d"] {
        let mut found: Vec<_> = std::fs::read_dir(data.join(folder))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "c3d"))
            .collect();
        found.sort();
        paths.extend(found);
    }
    let takes: Vec<(String, locap_core::Take)> = paths
        .iter()
        .map(|p| (p.display().to_string(), locap_io::c3d::read_path(p).unwrap().to_take().unwrap()))
        .collect();
    let config = LabelBenchConfig { frame_rates_hz: vec![30.0], ..LabelBenchConfig::default() };
    let report = run(&takes, &config).unwrap();
    let table = report.table();
    for ghosts in ["0", "M"] {
        let row = |method: &str| report.rows.iter().find(|r| r.ghosts == ghosts && r.method == method).unwrap();
        let ours = row("ours");
        for baseline in ["ugm", "cp"] {
            let other = row(baseline);
            assert!(
                ours.identification_rate > other.identification_rate && ours.accuracy > other.accuracy,
                "30 fps, {ghosts} ghosts: ours must beat {baseline}\n{table}"
            );
        }
    }
}
