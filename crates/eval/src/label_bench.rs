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
//! - frames per second: frames labeled per second of one core's time, once tracking (the
//!   first fit of the cross-trial case is timed on its own).
//!
//! # The cross-trial case
//! A user's template is another take of the subject, not the take's own first frame. With
//! [`LabelBenchConfig::cross_trial`], every take is also cut in two halves, and each half is
//! labeled with the other half as template: every segment of it starts from the articulated
//! first fit ([`locap_label::start`]: the first frame the fit is sure of, labeled forwards and
//! backwards from there), not from true labels. These rows read `other half` in the template
//! column; segments whose fit found no frame it was sure of are counted (`failed fits`) and
//! score their samples as missed.
//!
//! # The layout case
//! With [`LabelBenchConfig::layout`] (a template from a marker layout alone, no labeled take:
//! [`crate::label_layout`]), every take that has at least half of the layout's markers is also
//! labeled with it, segment by segment, as `locap label --layout` labels a take: the model's
//! first fit, then the template calibrated on the segment and the segment labeled again
//! ([`locap_label::subject`]). These rows read `layout`; their frames/s and fit time count the
//! fit, the calibration rounds and tracking together.

use crate::gap_model::GapModel;
use crate::unlabel::{GhostMode, UnlabelConfig, UnlabelError, Unlabeled, unlabel};
use locap_core::{Take, UpAxis};
use locap_label::{LabelConfig, LabelError, Labels, Method, Start, Template, fit_start, label_frames};
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
    /// Also label each half of every take with the other half as template (our method
    /// only, started by the articulated fit).
    pub cross_trial: bool,
    /// A template from a marker layout alone ([`crate::label_layout`]): every take that has
    /// at least half of its markers (matched by label) is also labeled with it, our method
    /// only (rows `layout`).
    pub layout: Option<Template>,
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
            cross_trial: true,
            layout: None,
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
    /// Seconds spent labeling, once started.
    pub seconds: f64,
    /// First fits made (cross-trial case).
    #[serde(default)]
    pub fits: u64,
    /// First fits that found no frame they were sure of.
    #[serde(default)]
    pub failed_fits: u64,
    /// Seconds spent on first fits.
    #[serde(default)]
    pub fit_seconds: f64,
}

impl Score {
    /// The counts of `self` and `other` together.
    fn plus(mut self, other: Score) -> Score {
        self.add(&other);
        self
    }

    fn add(&mut self, other: &Score) {
        self.samples += other.samples;
        self.correct += other.correct;
        self.wrong += other.wrong;
        self.missed += other.missed;
        self.trajectories += other.trajectories;
        self.trajectories_correct += other.trajectories_correct;
        self.frames += other.frames;
        self.seconds += other.seconds;
        self.fits += other.fits;
        self.failed_fits += other.failed_fits;
        self.fit_seconds += other.fit_seconds;
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

/// Per marker of `labels`, its (wrong, missed) samples against the per-frame point truth
/// `truth` (as [`score`] counts them).
pub fn marker_errors(truth: &[&[i32]], labels: &Labels, markers: usize) -> Vec<(usize, usize)> {
    (0..markers)
        .map(|m| {
            let (mut wrong, mut missed) = (0, 0);
            for (f, t) in truth.iter().enumerate() {
                match (labels.get(f, m), t.iter().position(|&k| k == m as i32)) {
                    (g, o) if g == o => {}
                    (None, Some(_)) => missed += 1,
                    _ => wrong += 1,
                }
            }
            (wrong, missed)
        })
        .collect()
}

/// The point truth of an unlabeled take (per frame, each point's take column) in the marker
/// order of `template`, whose markers are matched to `take`'s columns by label (-1 for a
/// column the template lacks: its points count as ghosts).
pub fn truth_in_template_order(truth: &[&[i32]], template: &Template, take: &Take) -> Vec<Vec<i32>> {
    let columns = layout_columns(template, take);
    remap(truth, &columns)
}

fn remap(truth: &[&[i32]], columns: &[i32]) -> Vec<Vec<i32>> {
    truth.iter().map(|t| t.iter().map(|&k| if k >= 0 { columns[k as usize] } else { -1 }).collect()).collect()
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
    /// Where the template came from: `own first frame` (true labels of each segment's first
    /// frame), `other half` (the cross-trial case) or `layout` (a marker layout alone).
    #[serde(default)]
    pub template: String,
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
    /// Mean time of one first fit (ms; cross-trial rows).
    #[serde(default)]
    pub fit_ms: f64,
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

/// Where a case's template came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Source {
    /// The take itself, started from each segment's true first labels.
    Own,
    /// The other half of the take (cross-trial).
    OtherHalf,
    /// A layout ([`LabelBenchConfig::layout`]); the truth's take columns map to template
    /// markers through `columns`.
    Layout,
}

/// One take (or half of one) unlabeled at one rate and ghost count, with its template.
struct Case<'a> {
    name: &'a String,
    template: Template,
    source: Source,
    /// For [`Source::Layout`]: per take column, its template marker (-1: none).
    columns: Vec<i32>,
    up: UpAxis,
    rate: usize,
    ghosts: usize,
    unlabeled: Unlabeled,
}

/// Runs the benchmark; jobs (take x rate x ghosts x segment) run on all cores, each method
/// timed on its own.
pub fn run(takes: &[(String, Take)], config: &LabelBenchConfig) -> Result<LabelBenchReport, LabelBenchError> {
    config.validate()?;
    let ours = config.methods.iter().position(|m| m.method == Method::SoftGraph);
    let mut cases = Vec::new();
    for (t, (name, take)) in takes.iter().enumerate() {
        let template_of = |take: &Take| {
            Template::from_take(take, None).map_err(|error| LabelBenchError::Label { take: name.clone(), error })
        };
        let template = template_of(take)?;
        // (template, labeled source, seed tag): the take itself, then its halves the other
        // way round.
        let mut sources = vec![(template, take.clone(), 0u64, Source::Own)];
        let half = take.frame_count() / 2;
        if config.cross_trial && ours.is_some() && half >= 2 {
            let (first, second) = (take.slice_frames(0..half), take.slice_frames(half..take.frame_count()));
            sources.push((template_of(&second)?, first.clone(), 1, Source::OtherHalf));
            sources.push((template_of(&first)?, second, 2, Source::OtherHalf));
        }
        let columns = config.layout.as_ref().map(|layout| layout_columns(layout, take)).unwrap_or_default();
        if let Some(layout) = &config.layout
            && ours.is_some()
            && 2 * columns.iter().filter(|&&c| c >= 0).count() >= layout.marker_count()
        {
            sources.push((layout.clone(), take.clone(), 3, Source::Layout));
        }
        for (template, source, tag, kind) in sources {
            for (r, &rate) in config.frame_rates_hz.iter().enumerate() {
                for (g, &ghosts) in config.ghosts.iter().enumerate() {
                    let unlabel_config = UnlabelConfig {
                        frame_rate_hz: Some(rate.min(source.frame_rate_hz())),
                        ghosts: ghosts.count(template.marker_count()),
                        ghost_mode: config.ghost_mode,
                        drop: config.drop.clone(),
                        // From the take, rate and ghost count themselves (not their places in
                        // the lists), so a setting gets the same points whatever else is run
                        // with it.
                        seed: config.seed
                            ^ ((t as u64) << 40)
                            ^ (((rate * 1000.0).round() as u64) << 12)
                            ^ ghosts.count(template.marker_count()) as u64
                            ^ (tag << 56),
                    };
                    let unlabeled = unlabel(&source, &unlabel_config)
                        .map_err(|error| LabelBenchError::Unlabel { take: name.clone(), error })?;
                    cases.push(Case {
                        name,
                        template: template.clone(),
                        source: kind,
                        columns: if kind == Source::Layout { columns.clone() } else { Vec::new() },
                        up: take.up_axis,
                        rate: r,
                        ghosts: g,
                        unlabeled,
                    });
                }
            }
        }
    }
    let jobs: Vec<(usize, std::ops::Range<usize>)> = cases
        .iter()
        .enumerate()
        .flat_map(|(c, case)| {
            let frames = case.unlabeled.frames.frame_count();
            let length = ((config.segment_s * case.unlabeled.frames.frame_rate_hz()).round() as usize).max(2);
            (0..frames).step_by(length).map(move |start| (c, start..(start + length).min(frames)))
        })
        .filter(|(_, range)| range.len() >= 2)
        .collect();
    let results: Vec<Result<Vec<Score>, LabelBenchError>> = jobs
        .par_iter()
        .map(|(c, range)| {
            let case = &cases[*c];
            let scores = match (case.source, ours) {
                (Source::OtherHalf, Some(k)) => {
                    label_segment_fitted(&case.template, &case.unlabeled, range.clone(), &config.methods[k], case.up)
                        .map(|s| vec![s])
                }
                (Source::Layout, Some(k)) => {
                    label_segment_layout(case, range.clone(), &config.methods[k]).map(|s| vec![s])
                }
                _ => label_segment(&case.template, &case.unlabeled, range.clone(), &config.methods),
            };
            scores.map_err(|error| LabelBenchError::Label { take: case.name.clone(), error })
        })
        .collect();
    let per_setting = config.frame_rates_hz.len() * config.ghosts.len();
    let mut totals = vec![Score::default(); per_setting * config.methods.len()];
    let mut cross = vec![Score::default(); per_setting];
    let mut layout = vec![Score::default(); per_setting];
    for ((c, _), result) in jobs.iter().zip(results) {
        let case = &cases[*c];
        let setting = case.rate * config.ghosts.len() + case.ghosts;
        for (k, s) in result?.iter().enumerate() {
            match case.source {
                Source::OtherHalf => cross[setting].add(s),
                Source::Layout => layout[setting].add(s),
                Source::Own => totals[setting * config.methods.len() + k].add(s),
            }
        }
    }
    let row = |rate: f64, ghosts: &GhostCount, method: &str, template: &str, s: Score| {
        let percent = |n: u64| 100.0 * n as f64 / s.samples.max(1) as f64;
        Row {
            frame_rate_hz: rate,
            ghosts: ghosts.to_string(),
            method: method.to_string(),
            template: template.to_string(),
            identification_rate: s.identification_rate(),
            accuracy: s.accuracy(),
            wrong_percent: percent(s.wrong),
            missed_percent: percent(s.missed),
            frames_per_second: s.frames_per_second(),
            fit_ms: 1000.0 * s.fit_seconds / s.fits.max(1) as f64,
            score: s,
        }
    };
    let mut rows = Vec::new();
    for (r, &rate) in config.frame_rates_hz.iter().enumerate() {
        for (g, ghosts) in config.ghosts.iter().enumerate() {
            let setting = r * config.ghosts.len() + g;
            for (k, method) in config.methods.iter().enumerate() {
                rows.push(row(
                    rate,
                    ghosts,
                    method.method.name(),
                    OWN_FIRST_FRAME,
                    totals[setting * config.methods.len() + k],
                ));
            }
        }
    }
    for (scores, template) in [(&cross, OTHER_HALF), (&layout, LAYOUT)] {
        if scores.iter().any(|s| s.samples > 0) {
            for (r, &rate) in config.frame_rates_hz.iter().enumerate() {
                for (g, ghosts) in config.ghosts.iter().enumerate() {
                    rows.push(row(
                        rate,
                        ghosts,
                        Method::SoftGraph.name(),
                        template,
                        scores[r * config.ghosts.len() + g],
                    ));
                }
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

/// [`Row::template`] of segments started from their first frame's true labels.
pub const OWN_FIRST_FRAME: &str = "own first frame";
/// [`Row::template`] of the cross-trial case.
pub const OTHER_HALF: &str = "other half";
/// [`Row::template`] of the layout case ([`LabelBenchConfig::layout`]).
pub const LAYOUT: &str = "layout";

/// Per column of `take`, the marker of `template` of the same label (-1: none).
fn layout_columns(template: &Template, take: &Take) -> Vec<i32> {
    take.markers()
        .iter()
        .map(|n| template.names().iter().position(|t| t.label == n.label).map_or(-1, |k| k as i32))
        .collect()
}

/// Labels one segment of a layout case the way `locap label --layout` labels a take (the
/// model's first fit, then the template calibrated on the segment: [`label_frames`] with a
/// fit start); the fit and calibration are timed with tracking, as one. A segment the fit is
/// sure of no frame of leaves every sample missed.
fn label_segment_layout(
    case: &Case<'_>,
    range: std::ops::Range<usize>,
    config: &LabelConfig,
) -> Result<Score, LabelError> {
    let frames = case.unlabeled.frames.slice_frames(range.clone());
    let by_frame = case.unlabeled.truth_by_frame();
    let truth = remap(&by_frame[range], &case.columns);
    let truth: Vec<&[i32]> = truth.iter().map(Vec::as_slice).collect();
    let m = case.template.marker_count();
    let started = Instant::now();
    let labeled = label_frames(&frames, &case.template, config, Start::Fit(config.fit, case.up), None);
    let seconds = started.elapsed().as_secs_f64();
    let timed = Score { fits: 1, fit_seconds: seconds, seconds, ..Score::default() };
    match labeled {
        Ok((labels, _)) => Ok(timed.plus(score(&truth, &labels, m))),
        Err(LabelError::FirstFrame(_)) => {
            let nothing = Labels::from_frames(m, &vec![Vec::new(); truth.len()]);
            Ok(Score { failed_fits: 1, ..timed.plus(score(&truth, &nothing, m)) })
        }
        Err(e) => Err(e),
    }
}

/// Labels one segment with `config`, started by the articulated first fit (timed on its
/// own); a fit that is sure of no frame leaves every sample missed.
fn label_segment_fitted(
    template: &Template,
    unlabeled: &Unlabeled,
    range: std::ops::Range<usize>,
    config: &LabelConfig,
    up: UpAxis,
) -> Result<Score, LabelError> {
    let frames = unlabeled.frames.slice_frames(range.clone());
    let by_frame = unlabeled.truth_by_frame();
    let truth = &by_frame[range];
    let started = Instant::now();
    let fit = fit_start(&frames, template, up, &config.fit);
    let fit_seconds = started.elapsed().as_secs_f64();
    let fitted = Score { fits: 1, fit_seconds, ..Score::default() };
    let fit = match fit {
        Ok(fit) => fit,
        Err(LabelError::FirstFrame(_)) => {
            let nothing = Labels::from_frames(template.marker_count(), &vec![Vec::new(); truth.len()]);
            return Ok(Score { failed_fits: 1, ..fitted.plus(score(truth, &nothing, template.marker_count())) });
        }
        Err(e) => return Err(e),
    };
    let started = Instant::now();
    let (labels, _) = label_frames(&frames, template, config, Start::Fitted(&fit), None)?;
    let seconds = started.elapsed().as_secs_f64();
    Ok(Score { seconds, ..fitted.plus(score(truth, &labels, template.marker_count())) })
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
            "{:>6} {:>6} {:<6} {:<15} {:>8} {:>9} {:>8} {:>8} {:>12} {:>8} {:>8}",
            "fps",
            "ghosts",
            "method",
            "template",
            "zeta %",
            "samples %",
            "wrong %",
            "missed %",
            "frames/s",
            "trajs",
            "fit ms"
        );
        for r in &self.rows {
            let fit = if r.score.fits > 0 { format!("{:.1}", r.fit_ms) } else { "-".to_string() };
            let _ = writeln!(
                s,
                "{:>6} {:>6} {:<6} {:<15} {:>8.2} {:>9.3} {:>8.3} {:>8.3} {:>12.0} {:>8} {:>8}",
                r.frame_rate_hz,
                r.ghosts,
                r.method,
                r.template,
                r.identification_rate,
                r.accuracy,
                r.wrong_percent,
                r.missed_percent,
                r.frames_per_second,
                r.score.trajectories,
                fit
            );
            if r.score.failed_fits > 0 {
                let _ = writeln!(
                    s,
                    "       {} of {} first fits were sure of no frame: their samples count as missed",
                    r.score.failed_fits, r.score.fits
                );
            }
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
        // Three methods from each segment's first frame, then ours with the other half of
        // the take as template.
        assert_eq!(report.rows.len(), 4);
        let ours = &report.rows[0];
        assert_eq!((ours.method.as_str(), ours.template.as_str()), ("ours", OWN_FIRST_FRAME));
        assert_eq!(ours.score.samples, 60 * 6);
        assert!(ours.accuracy > 99.0, "{}", report.table());
        assert!(report.table().contains("ugm"));
        let cross = &report.rows[3];
        assert_eq!((cross.method.as_str(), cross.template.as_str()), ("ours", OTHER_HALF));
        // Both halves, 30 frames each; each fitted once.
        assert_eq!((cross.score.samples, cross.score.fits), (60 * 6, 2));
        assert!(cross.accuracy > 95.0, "{}", report.table());
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
