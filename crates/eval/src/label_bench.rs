//! The labeling benchmark (labeling paper section 5.1: identification rate of marker
//! trajectories at 120, 60 and 30 fps, with and without ghosts, against CP and UGM).
//!
//! Every take is unlabeled ([`crate::unlabel`], seeded: every method sees the same points)
//! and cut into segments of `segment_s` seconds. The paper's 665 CMU takes average 10.2 s
//! (816,000 frames at 120 fps), so 10-second segments, each labeled on its own from its
//! first frame's true labels (the paper: "we use the labeled markers at the 1st frame to
//! initialize"), make our trajectories comparable with its.
//!
//! Scores, per sample (frame x marker) and per trajectory (marker x segment):
//! - a sample is *correct* when the marker gets its own point, or no point while it is
//!   missing; *wrong* when it gets another marker's point or a ghost; *missed* when it gets
//!   nothing although its point is there;
//! - the identification rate `zeta` is the fraction of trajectories with every sample correct
//!   (strict: one wrong or missed frame spoils the trajectory);
//! - frames per second: frames labeled per second of one core's time.

use crate::gap_model::GapModel;
use crate::unlabel::{GhostMode, UnlabelConfig, UnlabelError, Unlabeled, unlabel};
use locap_core::Take;
use locap_label::{LabelConfig, LabelError, Labels, Method, Start, Template, label_frames};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// How many ghosts per frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum GhostCount {
    /// A fixed number.
    Fixed(usize),
    /// As many as the take has markers (the paper's `alpha = |M|`).
    PerMarker,
}

impl GhostCount {
    fn count(self, markers: usize) -> usize {
        match self {
            GhostCount::Fixed(n) => n,
            GhostCount::PerMarker => markers,
        }
    }
}

impl std::fmt::Display for GhostCount {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            GhostCount::Fixed(n) => write!(f, "{n}"),
            GhostCount::PerMarker => f.write_str("M"),
        }
    }
}

/// Settings of the benchmark.
#[derive(Debug, Clone)]
pub struct LabelBenchConfig {
    /// Frame rates to test (Hz).
    pub frame_rates_hz: Vec<f64>,
    /// Ghost counts to test.
    pub ghosts: Vec<GhostCount>,
    /// Where ghosts appear.
    pub ghost_mode: GhostMode,
    /// Extra occlusions with real statistics.
    pub drop: Option<GapModel>,
    /// Segment length (s).
    pub segment_s: f64,
    /// Methods, with their settings.
    pub methods: Vec<LabelConfig>,
    /// Seed.
    pub seed: u64,
}

impl Default for LabelBenchConfig {
    fn default() -> LabelBenchConfig {
        LabelBenchConfig {
            frame_rates_hz: vec![120.0, 60.0, 30.0],
            ghosts: vec![GhostCount::Fixed(0), GhostCount::PerMarker],
            ghost_mode: GhostMode::Near,
            drop: Some(GapModel::builtin()),
            segment_s: 10.0,
            methods: Method::ALL.iter().map(|&m| LabelConfig::with_method(m)).collect(),
            seed: 1,
        }
    }
}

impl LabelBenchConfig {
    /// Checks the settings before any take is unlabeled: fixed ghost counts up to
    /// [`crate::unlabel::MAX_GHOSTS_PER_FRAME`] (`M` ghosts are checked per take, against its
    /// marker count), positive frame rates and segment length.
    ///
    /// # Errors
    /// [`LabelBenchError::Config`] naming the setting.
    pub fn validate(&self) -> Result<(), LabelBenchError> {
        let max = crate::unlabel::MAX_GHOSTS_PER_FRAME;
        if let Some(n) = self.ghosts.iter().find_map(|g| matches!(g, GhostCount::Fixed(n) if *n > max).then(|| g)) {
            return Err(LabelBenchError::Config(format!("{n} ghosts per frame (at most {max})")));
        }
        if let Some(r) = self.frame_rates_hz.iter().find(|r| !(r.is_finite() && **r > 0.0)) {
            return Err(LabelBenchError::Config(format!("frame rate {r} Hz is not positive")));
        }
        if !(self.segment_s.is_finite() && self.segment_s > 0.0) {
            return Err(LabelBenchError::Config(format!("segment length {} s is not positive", self.segment_s)));
        }
        Ok(())
    }
}

/// Why the benchmark cannot run.
#[derive(Debug, thiserror::Error)]
pub enum LabelBenchError {
    /// Settings out of range.
    #[error("{0}")]
    Config(String),
    /// A take could not be unlabeled.
    #[error("{take}: {error}")]
    Unlabel {
        /// Take name.
        take: String,
        /// The cause.
        error: UnlabelError,
    },
    /// A take could not be labeled.
    #[error("{take}: {error}")]
    Label {
        /// Take name.
        take: String,
        /// The cause.
        error: LabelError,
    },
}

/// Counts of one method on some frames.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Score {
    /// Samples scored (frames x markers).
    pub samples: u64,
    /// Correct samples.
    pub correct: u64,
    /// Samples given a wrong point.
    pub wrong: u64,
    /// Samples left unlabeled although their point was there.
    pub missed: u64,
    /// Trajectories scored.
    pub trajectories: u64,
    /// Trajectories with every sample correct.
    pub trajectories_correct: u64,
    /// Frames labeled.
    pub frames: u64,
    /// Seconds spent labeling.
    pub seconds: f64,
}

impl Score {
    fn add(&mut self, other: &Score) {
        self.samples += other.samples;
        self.correct += other.correct;
        self.wrong += other.wrong;
        self.missed += other.missed;
        self.trajectories += other.trajectories;
        self.trajectories_correct += other.trajectories_correct;
        self.frames += other.frames;
        self.seconds += other.seconds;
    }

    /// Identification rate of trajectories `zeta` (%).
    pub fn identification_rate(&self) -> f64 {
        100.0 * self.trajectories_correct as f64 / self.trajectories.max(1) as f64
    }

    /// Correct samples (%).
    pub fn accuracy(&self) -> f64 {
        100.0 * self.correct as f64 / self.samples.max(1) as f64
    }

    /// Frames per second of one core.
    pub fn frames_per_second(&self) -> f64 {
        self.frames as f64 / self.seconds.max(1e-12)
    }
}

/// Scores `labels` of a segment whose per-frame point truth is `truth`.
pub fn score(truth: &[&[i32]], labels: &Labels, markers: usize) -> Score {
    let mut s = Score { frames: truth.len() as u64, trajectories: markers as u64, ..Score::default() };
    let mut spoiled = vec![false; markers];
    for (f, frame_truth) in truth.iter().enumerate() {
        for (m, spoilt) in spoiled.iter_mut().enumerate() {
            let own = frame_truth.iter().position(|&t| t == m as i32);
            let got = labels.get(f, m);
            s.samples += 1;
            match (got, own) {
                (g, o) if g == o => s.correct += 1,
                (None, Some(_)) => {
                    s.missed += 1;
                    *spoilt = true;
                }
                _ => {
                    s.wrong += 1;
                    *spoilt = true;
                }
            }
        }
    }
    s.trajectories_correct = spoiled.iter().filter(|s| !**s).count() as u64;
    s
}

/// One line of the report.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Row {
    /// Frame rate (Hz).
    pub frame_rate_hz: f64,
    /// Ghosts per frame (`M` = as many as markers).
    pub ghosts: String,
    /// Method name.
    pub method: String,
    /// Identification rate of trajectories (%).
    pub identification_rate: f64,
    /// Correct samples (%).
    pub accuracy: f64,
    /// Wrongly labeled samples (%).
    pub wrong_percent: f64,
    /// Missed samples (%).
    pub missed_percent: f64,
    /// Frames per second (one core).
    pub frames_per_second: f64,
    /// Raw counts.
    pub score: Score,
}

/// The benchmark's results.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LabelBenchReport {
    /// Take names.
    pub takes: Vec<String>,
    /// Seed.
    pub seed: u64,
    /// Segment length (s).
    pub segment_s: f64,
    /// Ghost mode.
    pub ghost_mode: GhostMode,
    /// Whether real-statistics occlusions were added.
    pub real_occlusions: bool,
    /// Results.
    pub rows: Vec<Row>,
}

/// Runs the benchmark; jobs (take x rate x ghosts x segment) run on all cores, each method
/// timed on its own.
pub fn run(takes: &[(String, Take)], config: &LabelBenchConfig) -> Result<LabelBenchReport, LabelBenchError> {
    config.validate()?;
    let mut cases = Vec::new();
    for (t, (name, take)) in takes.iter().enumerate() {
        let template =
            Template::from_take(take, None).map_err(|error| LabelBenchError::Label { take: name.clone(), error })?;
        for (r, &rate) in config.frame_rates_hz.iter().enumerate() {
            for (g, &ghosts) in config.ghosts.iter().enumerate() {
                let unlabel_config = UnlabelConfig {
                    frame_rate_hz: Some(rate.min(take.frame_rate_hz())),
                    ghosts: ghosts.count(template.marker_count()),
                    ghost_mode: config.ghost_mode,
                    drop: config.drop.clone(),
                    // From the take, rate and ghost count themselves (not their places in the
                    // lists), so a setting gets the same points whatever else is run with it.
                    seed: config.seed
                        ^ ((t as u64) << 40)
                        ^ (((rate * 1000.0).round() as u64) << 12)
                        ^ ghosts.count(template.marker_count()) as u64,
                };
                let unlabeled = unlabel(take, &unlabel_config)
                    .map_err(|error| LabelBenchError::Unlabel { take: name.clone(), error })?;
                cases.push((name, template.clone(), r, g, unlabeled));
            }
        }
    }
    let jobs: Vec<(usize, std::ops::Range<usize>)> = cases
        .iter()
        .enumerate()
        .flat_map(|(c, case)| {
            let frames = case.4.frames.frame_count();
            let length = ((config.segment_s * case.4.frames.frame_rate_hz()).round() as usize).max(2);
            (0..frames).step_by(length).map(move |start| (c, start..(start + length).min(frames)))
        })
        .filter(|(_, range)| range.len() >= 2)
        .collect();
    let results: Vec<Result<Vec<Score>, LabelBenchError>> = jobs
        .par_iter()
        .map(|(c, range)| {
            let (name, template, _, _, unlabeled) = &cases[*c];
            label_segment(template, unlabeled, range.clone(), &config.methods)
                .map_err(|error| LabelBenchError::Label { take: (*name).clone(), error })
        })
        .collect();
    let mut totals = vec![Score::default(); config.frame_rates_hz.len() * config.ghosts.len() * config.methods.len()];
    for ((c, _), result) in jobs.iter().zip(results) {
        let (_, _, r, g, _) = &cases[*c];
        for (k, s) in result?.iter().enumerate() {
            totals[(r * config.ghosts.len() + g) * config.methods.len() + k].add(s);
        }
    }
    let mut rows = Vec::new();
    for (r, &rate) in config.frame_rates_hz.iter().enumerate() {
        for (g, ghosts) in config.ghosts.iter().enumerate() {
            for (k, method) in config.methods.iter().enumerate() {
                let s = totals[(r * config.ghosts.len() + g) * config.methods.len() + k];
                let percent = |n: u64| 100.0 * n as f64 / s.samples.max(1) as f64;
                rows.push(Row {
                    frame_rate_hz: rate,
                    ghosts: ghosts.to_string(),
                    method: method.method.name().to_string(),
                    identification_rate: s.identification_rate(),
                    accuracy: s.accuracy(),
                    wrong_percent: percent(s.wrong),
                    missed_percent: percent(s.missed),
                    frames_per_second: s.frames_per_second(),
                    score: s,
                });
            }
        }
    }
    Ok(LabelBenchReport {
        takes: takes.iter().map(|(n, _)| n.clone()).collect(),
        seed: config.seed,
        segment_s: config.segment_s,
        ghost_mode: config.ghost_mode,
        real_occlusions: config.drop.is_some(),
        rows,
    })
}

/// Labels one segment with every method, from the true labels of its first frame.
fn label_segment(
    template: &Template,
    unlabeled: &Unlabeled,
    range: std::ops::Range<usize>,
    methods: &[LabelConfig],
) -> Result<Vec<Score>, LabelError> {
    let frames = unlabeled.frames.slice_frames(range.clone());
    let by_frame = unlabeled.truth_by_frame();
    let truth = &by_frame[range];
    let initial: Vec<Option<usize>> =
        (0..template.marker_count()).map(|m| truth[0].iter().position(|&t| t == m as i32)).collect();
    methods
        .iter()
        .map(|config| {
            let started = Instant::now();
            let (labels, _) = label_frames(&frames, template, config, Start::Known(&initial), None)?;
            let seconds = started.elapsed().as_secs_f64();
            Ok(Score { seconds, ..score(truth, &labels, template.marker_count()) })
        })
        .collect()
}

impl LabelBenchReport {
    /// The report as a text table.
    pub fn table(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "{} takes, {} s segments, ghosts {:?}, real occlusions {}, seed {}",
            self.takes.len(),
            self.segment_s,
            self.ghost_mode,
            if self.real_occlusions { "added" } else { "no" },
            self.seed
        );
        let _ = writeln!(
            s,
            "{:>6} {:>6} {:<6} {:>8} {:>9} {:>8} {:>8} {:>12} {:>8}",
            "fps", "ghosts", "method", "zeta %", "samples %", "wrong %", "missed %", "frames/s", "trajs"
        );
        for r in &self.rows {
            let _ = writeln!(
                s,
                "{:>6} {:>6} {:<6} {:>8.2} {:>9.3} {:>8.3} {:>8.3} {:>12.0} {:>8}",
                r.frame_rate_hz,
                r.ghosts,
                r.method,
                r.identification_rate,
                r.accuracy,
                r.wrong_percent,
                r.missed_percent,
                r.frames_per_second,
                r.score.trajectories
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{MarkerName, Vec3};

    #[test]
    fn scores_wrong_missed_and_correct_samples() {
        // Three markers over three frames; the truth lists each point's marker (-1: ghost).
        let truth: Vec<&[i32]> = vec![&[0, 1, -1, 2], &[1, -1, 0], &[2, 0, 1]];
        let labels = Labels::from_frames(
            3,
            &[
                vec![Some(0), Some(1), Some(3)], // all correct
                vec![Some(2), Some(0), None],    // 0, 1 correct; 2 correctly missing
                vec![Some(0), None, Some(2)],    // 0 took marker 2's point (wrong), 1 missed, 2 wrong
            ],
        );
        let s = score(&truth, &labels, 3);
        assert_eq!((s.samples, s.correct, s.wrong, s.missed), (9, 6, 2, 1));
        assert_eq!((s.trajectories, s.trajectories_correct), (3, 0));
        let clean = Labels::from_frames(3, &[vec![Some(0), Some(1), Some(3)], vec![Some(2), Some(0), None]]);
        let s = score(&truth[..2], &clean, 3);
        assert_eq!((s.correct, s.trajectories_correct), (6, 3));
        assert!((s.identification_rate() - 100.0).abs() < 1e-12);
    }

    #[test]
    fn ours_labels_a_rigid_body_among_ghosts() {
        // A rigid 6-marker body tumbling across the room, 2 s at 120 Hz, labeled at 30 fps
        // with 6 near ghosts: scores are complete and ours labels nearly everything.
        let body = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(150.0, 0.0, 0.0),
            Vec3::new(0.0, 120.0, 0.0),
            Vec3::new(0.0, 0.0, 200.0),
            Vec3::new(80.0, 90.0, 40.0),
            Vec3::new(-60.0, 50.0, 120.0),
        ];
        let names: Vec<MarkerName> = (0..6).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let samples: Vec<Option<Vec3>> = (0..240)
            .flat_map(|f| {
                let t = f as f64 / 120.0;
                let r = nalgebra::Rotation3::from_euler_angles(0.8 * t, 0.3 * t, 1.1 * t);
                let origin = Vec3::new(600.0 * t, 200.0 * (2.0 * t).sin(), 1000.0);
                body.iter().map(move |p| Some(origin + r * p)).collect::<Vec<_>>()
            })
            .collect();
        let take = Take::from_samples(names, &samples, 120.0).unwrap();
        let config = LabelBenchConfig {
            frame_rates_hz: vec![30.0],
            ghosts: vec![GhostCount::PerMarker],
            drop: None,
            ..LabelBenchConfig::default()
        };
        let report = run(&[("body".into(), take)], &config).unwrap();
        assert_eq!(report.rows.len(), 3);
        let ours = &report.rows[0];
        assert_eq!(ours.method, "ours");
        assert_eq!(ours.score.samples, 60 * 6);
        assert!(ours.accuracy > 99.0, "{}", report.table());
        assert!(report.table().contains("ugm"));
    }

    /// `bench label --ghosts 100000` ran without bound: refused before any take is touched.
    #[test]
    fn ghost_counts_are_bounded() {
        let config = LabelBenchConfig { ghosts: vec![GhostCount::Fixed(100_000)], ..LabelBenchConfig::default() };
        let e = run(&[], &config).unwrap_err().to_string();
        assert_eq!(e, "100000 ghosts per frame (at most 1000)");
        let ok = LabelBenchConfig { ghosts: vec![GhostCount::Fixed(1000), GhostCount::PerMarker], ..config };
        assert!(ok.validate().is_ok());
        assert!(LabelBenchConfig { segment_s: 0.0, ..ok }.validate().is_err());
    }
}
