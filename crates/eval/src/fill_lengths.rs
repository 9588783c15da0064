//! The fixed-length gap protocol (issue 15, item 4): gaps of set lengths hidden in a gap-free
//! take, filled by every candidate, scored by RMSE over exactly the hidden samples.
//!
//! [`crate::fill_bench`] draws gaps from real occlusion statistics, which says how a method does
//! on the gaps a capture has; this protocol asks how it does per gap *length*, the comparison
//! the published gap fillers report (Gløersen & Federolf 2016; Tits et al. 2018), so a table
//! from their papers or their code can be set beside locap's on the same take:
//! - `per_length` gaps of each length in [`LengthsConfig::lengths_s`] (seeded), each on a
//!   marker captured from one frame before to one frame after (never at the take's edges);
//! - "single" input: one gap per input, each filled on its own;
//! - "multi" input: every gap at once, plus a *limb gap*: three neighbouring markers hidden
//!   together for [`LIMB_S`] (scored as the bucket `limb`), the case where a whole segment
//!   disappears and the methods that fill a marker from its neighbours lose them.
//!
//! A hidden sample a candidate leaves missing (or every sample of an input it fails on) counts
//! with the error of the linear fill there, so every candidate is scored on the same samples;
//! the count is reported. Unlabeled points (`*N`) are dropped before gaps are hidden: the
//! protocol scores labeled markers.
//!
//! The limb is the left forearm (`LFRM`, `LWRA`, `LWRB`) where a take has the CMU / HDM05
//! names, so tables of those takes compare with the issue's; any other marker set gets a
//! seeded marker and its two nearest neighbours by mean distance.

use crate::fill_bench::Candidate;
use locap_clean::neighbours::{self, Selection};
use locap_clean::{Filled, baseline};
use locap_core::Take;
use serde::{Deserialize, Serialize};
use std::ops::Range;
use std::time::Instant;

/// The gap lengths of the published comparisons, seconds.
pub const DEFAULT_LENGTHS_S: [f64; 4] = [0.1, 0.5, 1.0, 2.0];

/// The limb gap's markers where a take has them (CMU / HDM05 left forearm).
pub const NAMED_LIMB: [&str; 3] = ["LFRM", "LWRA", "LWRB"];

/// The rows the ratio column compares against: the published and industry fills locap
/// reimplements (the baselines), not locap's own methods (`auto`, `pca-aligned`,
/// `rigid-spline`, a learned refiner).
pub const BASELINES: [&str; 6] = ["edm", "edm-nearest", "linear", "spline", "pca", "rigid"];

/// Length of the limb gap, seconds.
pub const LIMB_S: f64 = 1.0;

/// Placement attempts per gap before the protocol gives up on it (a take too short, or a
/// marker seldom captured).
const PLACEMENT_TRIES: usize = 10_000;

/// What the protocol hides.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LengthsConfig {
    /// Gap lengths, seconds.
    pub lengths_s: Vec<f64>,
    /// Gaps of each length.
    pub per_length: usize,
    /// Seed of the placement (same seed, same gaps).
    pub seed: u64,
    /// Add the limb gap to the multi input.
    pub limb: bool,
}

impl Default for LengthsConfig {
    fn default() -> LengthsConfig {
        LengthsConfig { lengths_s: DEFAULT_LENGTHS_S.to_vec(), per_length: 5, seed: 0, limb: true }
    }
}

/// One hidden gap.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct HiddenGap {
    /// Marker index.
    pub marker: usize,
    /// Frames hidden.
    pub frames: Range<usize>,
    /// Bucket: the length (`0.1s`, ...) or `limb`.
    pub bucket: String,
}

/// RMSE over one bucket's hidden samples.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BucketRmse {
    /// Bucket name.
    pub bucket: String,
    /// RMSE over the bucket's hidden samples, mm.
    pub rmse_mm: f64,
    /// Hidden samples scored.
    pub samples: usize,
    /// Of those, left missing by the candidate (scored with the linear fill's error).
    pub unfilled: usize,
}

/// A candidate's score on one input kind (single or multi).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct InputScore {
    /// Per bucket, in the order of the lengths, then `limb`.
    pub buckets: Vec<BucketRmse>,
    /// RMSE over every hidden sample, mm.
    pub overall_mm: f64,
    /// Hidden samples left missing.
    pub unfilled: usize,
}

impl InputScore {
    /// The RMSE of bucket `name`.
    pub fn rmse_mm(&self, name: &str) -> Option<f64> {
        self.buckets.iter().find(|b| b.bucket == name).map(|b| b.rmse_mm)
    }
}

/// One candidate on one take.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LengthsRow {
    /// Candidate name.
    pub method: String,
    /// One gap per input.
    pub single: InputScore,
    /// All gaps (and the limb gap) at once.
    pub multi: InputScore,
    /// Wall time of every fill of this candidate on this take, seconds.
    pub seconds: f64,
    /// Inputs the candidate refused, with the reason.
    pub failures: Vec<String>,
}

/// Every candidate on one take.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TakeLengths {
    /// The take's name (its path, as given).
    pub take: String,
    /// Frames.
    pub frames: usize,
    /// Labeled markers.
    pub markers: usize,
    /// Frame rate, Hz.
    pub rate_hz: f64,
    /// The gaps of the length buckets.
    pub gaps: Vec<HiddenGap>,
    /// The limb gap's marker names (empty without one).
    pub limb_markers: Vec<String>,
    /// One row per candidate, in the order given.
    pub rows: Vec<LengthsRow>,
}

/// The protocol's result on every take.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LengthsReport {
    /// What was hidden.
    pub config: LengthsConfig,
    /// Per take.
    pub takes: Vec<TakeLengths>,
}

/// `take` without its unlabeled points.
pub fn labeled_only(take: &Take) -> Take {
    let keep: Vec<usize> = (0..take.marker_count()).filter(|i| !take.markers()[*i].is_unlabeled()).collect();
    if keep.len() == take.marker_count() {
        return take.clone();
    }
    let names = keep.iter().map(|i| take.markers()[*i].clone()).collect();
    let samples: Vec<_> = (0..take.frame_count())
        .flat_map(|f| keep.iter().map(move |i| (f, *i)))
        .map(|(f, i)| take.position_mm(f, i))
        .collect();
    Take::from_samples(names, &samples, take.frame_rate_hz()).expect("a subset of a take's markers is a take")
}

/// SplitMix64 step: the protocol's own generator, so its gaps do not change with a crate's
/// (public so tests that hide their own seeded gaps draw them the same way).
pub fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A long take for timing a fill: `source` played forward and backward in turn up to `frames`
/// frames (so the motion stays continuous), with seeded gaps of 1 frame to 2 s on random
/// markers until `missing` (a fraction) of its samples are hidden. Returns the take and the
/// number of gaps drawn (overlapping ones included). What `locap clean` is timed on for the
/// issue's "10-minute take with 2% missing" (`examples/long_take.rs` writes it as C3D).
/// Never more samples are hidden than are captured, and the draws are bounded, so a source
/// with few captured samples ends with fewer hidden than asked; a source without frames or
/// markers comes back as it is.
pub fn long_take(source: &Take, frames: usize, missing: f64, seed: u64) -> (Take, usize) {
    let (n, m) = (source.frame_count(), source.marker_count());
    if n == 0 || m == 0 {
        return (source.clone(), 0);
    }
    let mut samples = Vec::with_capacity(frames * m);
    for f in 0..frames {
        let (lap, k) = (f / n, f % n);
        let src = if lap % 2 == 0 { k } else { n - 1 - k };
        samples.extend((0..m).map(|j| source.position_mm(src, j)));
    }
    let mut take = Take::from_samples(source.markers().to_vec(), &samples, source.frame_rate_hz())
        .expect("samples of a valid take make a valid take");
    let longest = ((2.0 * source.frame_rate_hz()).round() as usize).clamp(1, frames.saturating_sub(1).max(1));
    let captured = samples.iter().filter(|p| p.is_some()).count();
    let target = ((frames as f64 * m as f64 * missing.clamp(0.0, 1.0)) as usize).min(captured);
    let mut state = seed;
    let (mut hidden, mut gaps) = (0, 0);
    while hidden < target && frames > longest && gaps < frames * m {
        let marker = (splitmix(&mut state) % m as u64) as usize;
        let len = 1 + (splitmix(&mut state) % longest as u64) as usize;
        let start = (splitmix(&mut state) % (frames - len) as u64) as usize;
        for f in start..start + len {
            if take.is_valid(f, marker) {
                let _ = take.set_position_mm(f, marker, None);
                hidden += 1;
            }
        }
        gaps += 1;
    }
    (take, gaps)
}

/// Whether `marker` may be hidden over `start..start + len`: captured from one frame before to
/// one frame after, and at least two frames from every gap of it already in `placed`.
fn placeable(take: &Take, placed: &[HiddenGap], marker: usize, start: usize, len: usize) -> bool {
    (start - 1..start + len + 1).all(|f| take.is_valid(f, marker))
        && !placed.iter().any(|h| h.marker == marker && h.frames.start < start + len + 2 && start < h.frames.end + 2)
}

/// The seeded gaps of the length buckets: `per_length` of each length where they can be placed.
pub fn length_gaps(take: &Take, config: &LengthsConfig) -> Vec<HiddenGap> {
    let frames = take.frame_count();
    let markers = take.marker_count();
    let mut state = config.seed;
    let mut out: Vec<HiddenGap> = Vec::new();
    for &len_s in &config.lengths_s {
        // Compared as floats first: a length of any size (or NaN) must not overflow.
        let len_frames = (len_s * take.frame_rate_hz()).round().max(1.0);
        if markers == 0 || !(len_s > 0.0) || !(len_frames + 4.0 <= frames as f64) {
            continue;
        }
        let len = len_frames as usize;
        let mut placed = 0;
        for _ in 0..PLACEMENT_TRIES {
            if placed == config.per_length {
                break;
            }
            let marker = (splitmix(&mut state) % markers as u64) as usize;
            let start = 1 + (splitmix(&mut state) % (frames - len - 2) as u64) as usize;
            if placeable(take, &out, marker, start, len) {
                out.push(HiddenGap { marker, frames: start..start + len, bucket: format!("{len_s}s") });
                placed += 1;
            }
        }
    }
    out
}

/// The limb gap of the multi input ([`NAMED_LIMB`], or a seeded marker and its two nearest
/// neighbours), [`LIMB_S`] long at a seeded start where the three are captured and none of
/// `others` touches them. Empty where no such start is found.
pub fn limb_gap(take: &Take, others: &[HiddenGap], seed: u64) -> Vec<HiddenGap> {
    let mut state = seed ^ 0x11AB;
    let named: Option<Vec<usize>> = NAMED_LIMB.iter().map(|n| take.marker_index(n)).collect();
    let ids = match named {
        Some(ids) => ids,
        None if take.marker_count() >= 3 => {
            let nearest = neighbours::rank(take, Selection::MeanDistance);
            let first = (splitmix(&mut state) % take.marker_count() as u64) as usize;
            let mut ids = vec![first];
            ids.extend(nearest[first].iter().copied().take(2));
            if ids.len() < 3 {
                return Vec::new();
            }
            ids
        }
        None => return Vec::new(),
    };
    let len = ((LIMB_S * take.frame_rate_hz()).round() as usize).max(1);
    let frames = take.frame_count();
    if frames < len + 4 {
        return Vec::new();
    }
    for _ in 0..PLACEMENT_TRIES {
        let start = 1 + (splitmix(&mut state) % (frames - len - 2) as u64) as usize;
        if ids.iter().all(|m| placeable(take, others, *m, start, len)) {
            return ids
                .iter()
                .map(|m| HiddenGap { marker: *m, frames: start..start + len, bucket: "limb".into() })
                .collect();
        }
    }
    Vec::new()
}

/// `take` with `gaps` removed.
pub fn holed(take: &Take, gaps: &[HiddenGap]) -> Take {
    let mut out = take.clone();
    for h in gaps {
        for f in h.frames.clone() {
            out.set_position_mm(f, h.marker, None).expect("a hidden gap lies inside the take");
        }
    }
    out
}

/// Squared-error sums per bucket while scoring.
#[derive(Default)]
struct Sums {
    /// (bucket, sum of squared errors, samples, unfilled)
    buckets: Vec<(String, f64, usize, usize)>,
}

impl Sums {
    fn add(&mut self, bucket: &str, squared_mm2: f64, unfilled: bool) {
        let k = match self.buckets.iter().position(|b| b.0 == bucket) {
            Some(k) => k,
            None => {
                self.buckets.push((bucket.to_string(), 0.0, 0, 0));
                self.buckets.len() - 1
            }
        };
        let entry = &mut self.buckets[k];
        entry.1 += squared_mm2;
        entry.2 += 1;
        entry.3 += unfilled as usize;
    }

    /// Scores `filled` (None: the candidate failed) on `gaps`; `linear` stands in where it left
    /// a sample missing.
    fn score(&mut self, truth: &Take, filled: Option<&Filled>, linear: &Filled, gaps: &[HiddenGap]) {
        for h in gaps {
            for f in h.frames.clone() {
                let t = truth.position_mm(f, h.marker).expect("hidden samples were captured");
                match filled.and_then(|x| x.take.position_mm(f, h.marker)) {
                    Some(p) => self.add(&h.bucket, (p - t).norm_squared(), false),
                    None => {
                        let p = linear.take.position_mm(f, h.marker).expect("an interior gap fills linearly");
                        self.add(&h.bucket, (p - t).norm_squared(), true);
                    }
                }
            }
        }
    }

    fn finish(self) -> InputScore {
        let (sq, n, unfilled) = self.buckets.iter().fold((0.0, 0, 0), |(s, n, u), b| (s + b.1, n + b.2, u + b.3));
        InputScore {
            buckets: self
                .buckets
                .into_iter()
                .map(|(bucket, sq, samples, unfilled)| BucketRmse {
                    bucket,
                    rmse_mm: (sq / samples.max(1) as f64).sqrt(),
                    samples,
                    unfilled,
                })
                .collect(),
            overall_mm: (sq / n.max(1) as f64).sqrt(),
            unfilled,
        }
    }
}

/// One input of the protocol: the holed take, its gaps and its linear fill.
struct Input {
    take: Take,
    gaps: Vec<HiddenGap>,
    linear: Filled,
}

impl Input {
    fn new(truth: &Take, gaps: Vec<HiddenGap>) -> Input {
        let take = holed(truth, &gaps);
        let linear = baseline::linear::fill(&take);
        Input { take, gaps, linear }
    }
}

/// Runs the protocol on every take with every candidate, on the same gaps.
pub fn run_lengths(takes: &[(String, Take)], candidates: &[Candidate], config: &LengthsConfig) -> LengthsReport {
    let takes = takes
        .iter()
        .map(|(name, take)| {
            let truth = labeled_only(take);
            let gaps = length_gaps(&truth, config);
            let limb = if config.limb { limb_gap(&truth, &gaps, config.seed) } else { Vec::new() };
            let singles: Vec<Input> = gaps.iter().map(|g| Input::new(&truth, vec![g.clone()])).collect();
            let multi = Input::new(&truth, gaps.iter().chain(&limb).cloned().collect());
            let rows = candidates.iter().map(|c| score_candidate(&truth, c, &singles, &multi)).collect();
            TakeLengths {
                take: name.clone(),
                frames: truth.frame_count(),
                markers: truth.marker_count(),
                rate_hz: truth.frame_rate_hz(),
                limb_markers: limb.iter().map(|h| truth.markers()[h.marker].to_string()).collect(),
                gaps,
                rows,
            }
        })
        .collect();
    LengthsReport { config: config.clone(), takes }
}

fn score_candidate(truth: &Take, candidate: &Candidate, singles: &[Input], multi: &Input) -> LengthsRow {
    let started = Instant::now();
    let mut failures = Vec::new();
    let mut fill_scored = |input: &Input, sums: &mut Sums| match candidate.filler.fill(&input.take) {
        Ok(filled) => sums.score(truth, Some(&filled), &input.linear, &input.gaps),
        Err(e) => {
            failures.push(e.to_string());
            sums.score(truth, None, &input.linear, &input.gaps);
        }
    };
    let mut single = Sums::default();
    for input in singles {
        fill_scored(input, &mut single);
    }
    let mut all = Sums::default();
    fill_scored(multi, &mut all);
    LengthsRow {
        method: candidate.name.to_string(),
        single: single.finish(),
        multi: all.finish(),
        seconds: started.elapsed().as_secs_f64(),
        failures,
    }
}

impl LengthsReport {
    /// The report as Markdown: per take, RMSE mm per bucket and overall for both inputs, each
    /// row's overall against the best *other* row's (below 1: it beats every other candidate),
    /// and its time against EDM's in the same run where EDM is a candidate.
    pub fn table(&self) -> String {
        let mut out = String::new();
        let buckets: Vec<String> = self.config.lengths_s.iter().map(|l| format!("{l}s")).collect();
        for take in &self.takes {
            out += &format!(
                "\n## {}: {} frames at {} Hz, {} markers, {} gaps{}\n",
                take.take,
                take.frames,
                take.rate_hz,
                take.markers,
                take.gaps.len(),
                if take.limb_markers.is_empty() {
                    String::new()
                } else {
                    format!(" + limb {}", take.limb_markers.join(" "))
                }
            );
            let mut header = String::from("| method |");
            for b in &buckets {
                header += &format!(" single {b} |");
            }
            header += " **single** |";
            for b in &buckets {
                header += &format!(" multi {b} |");
            }
            if !take.limb_markers.is_empty() {
                header += " multi limb |";
            }
            header +=
                " **multi** | single / best baseline | multi / best baseline | unfilled | time s | time / edm |\n";
            out += &header;
            out += &format!("|{}\n", "---|".repeat(header.matches('|').count() - 1));
            let edm = take.rows.iter().find(|r| r.method == "edm").map(|r| r.seconds);
            // Against the best baseline other than the row itself.
            let best_other = |k: usize, pick: fn(&LengthsRow) -> f64| {
                take.rows
                    .iter()
                    .enumerate()
                    .filter(|(j, r)| *j != k && BASELINES.contains(&r.method.as_str()))
                    .map(|(_, r)| pick(r))
                    .fold(f64::INFINITY, f64::min)
            };
            let cell = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
            for (k, row) in take.rows.iter().enumerate() {
                let mut line = format!("| {} |", row.method);
                for b in &buckets {
                    line += &format!(" {} |", cell(row.single.rmse_mm(b)));
                }
                line += &format!(" **{:.1}** |", row.single.overall_mm);
                for b in &buckets {
                    line += &format!(" {} |", cell(row.multi.rmse_mm(b)));
                }
                if !take.limb_markers.is_empty() {
                    line += &format!(" {} |", cell(row.multi.rmse_mm("limb")));
                }
                let ratio = |v: f64, best: f64| if best.is_finite() { format!("{:.2}", v / best) } else { "-".into() };
                line += &format!(
                    " **{:.1}** | {} | {} | {}/{} | {:.2} | {} |\n",
                    row.multi.overall_mm,
                    ratio(row.single.overall_mm, best_other(k, |r| r.single.overall_mm)),
                    ratio(row.multi.overall_mm, best_other(k, |r| r.multi.overall_mm)),
                    row.single.unfilled,
                    row.multi.unfilled,
                    row.seconds,
                    edm.filter(|e| *e > 0.0).map_or("-".to_string(), |e| format!("{:.1}", row.seconds / e)),
                );
                out += &line;
            }
            for row in take.rows.iter().filter(|r| !r.failures.is_empty()) {
                out += &format!("\n{} failed on {} inputs: {}\n", row.method, row.failures.len(), row.failures[0]);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_clean::{FillConfig, FillMethod, Filler};

    fn wave(frames: usize) -> Take {
        let names = ["LFRM", "LWRA", "LWRB", "RFRM", "RWRA", "HEAD"];
        locap_testkit::rigid_cluster(frames, names.len(), |i| names[i].to_string(), |_, _| [0.0; 3])
    }

    #[test]
    fn a_long_take_plays_its_source_back_and_forth_and_stops_when_nothing_is_left_to_hide() {
        let source = wave(300);
        let (long, gaps) = long_take(&source, 1000, 0.02, 7);
        assert_eq!((long.frame_count(), long.marker_count()), (1000, 6));
        assert!(gaps > 0);
        let hidden = (0..1000).map(|f| (0..6).filter(|j| !long.is_valid(f, *j)).count()).sum::<usize>();
        assert!((120..320).contains(&hidden), "{hidden} hidden");
        // Frame 450 is the backward lap's frame 300 - 1 - 150.
        let j = (0..6).find(|j| long.is_valid(450, *j)).unwrap();
        assert_eq!(long.position_mm(450, j), source.position_mm(149, j));
        // A source with one captured sample cannot give 50% missing: it ends anyway.
        let mut sparse = wave(300);
        for f in 0..300 {
            for j in 0..6 {
                if (f, j) != (0, 0) {
                    sparse.set_position_mm(f, j, None).unwrap();
                }
            }
        }
        let (long, _) = long_take(&sparse, 1000, 0.5, 7);
        assert!((0..1000).all(|f| (1..6).all(|j| !long.is_valid(f, j))));
        let (empty, gaps) = long_take(&Take::from_samples(vec![], &[], 100.0).unwrap(), 1000, 0.02, 7);
        assert_eq!((empty.frame_count(), gaps), (0, 0));
    }

    #[test]
    fn gaps_are_placed_where_the_marker_is_captured_and_scored_on_exactly_those_samples() {
        let truth = wave(2000);
        let config = LengthsConfig { per_length: 3, ..LengthsConfig::default() };
        let gaps = length_gaps(&truth, &config);
        assert_eq!(gaps.len(), 12);
        let limb = limb_gap(&truth, &gaps, config.seed);
        let names: Vec<String> = limb.iter().map(|h| truth.markers()[h.marker].to_string()).collect();
        assert_eq!(names, NAMED_LIMB);
        let input = Input::new(&truth, gaps.iter().chain(&limb).cloned().collect());
        let hidden: usize = input.gaps.iter().map(|g| g.frames.len()).sum();
        assert_eq!(input.take.missing_count(), hidden);
        // The truth itself scores zero; a candidate that fills nothing is scored as linear.
        let mut exact = Sums::default();
        let truth_filled = Filled::unchanged(&truth);
        exact.score(&truth, Some(&truth_filled), &input.linear, &input.gaps);
        let exact = exact.finish();
        assert_eq!((exact.overall_mm, exact.unfilled), (0.0, 0));
        let mut none = Sums::default();
        none.score(&truth, None, &input.linear, &input.gaps);
        let none = none.finish();
        assert_eq!(none.unfilled, hidden);
        assert!(none.overall_mm > 0.0);
    }

    #[test]
    fn a_rigid_cluster_is_filled_best_by_the_rigid_fill_and_the_table_says_so() {
        let truth = wave(1500);
        let rigid = FillConfig { method: FillMethod::Rigid, ..FillConfig::default() };
        let linear = FillConfig { method: FillMethod::Linear, ..FillConfig::default() };
        let candidates =
            [Candidate { name: "rigid", filler: &rigid as &dyn Filler }, Candidate { name: "linear", filler: &linear }];
        let report = run_lengths(&[("wave".into(), truth)], &candidates, &LengthsConfig::default());
        let rows = &report.takes[0].rows;
        assert!(rows[0].single.overall_mm < 0.5 * rows[1].single.overall_mm, "{rows:?}");
        assert!(rows[0].multi.overall_mm < rows[1].multi.overall_mm, "{rows:?}");
        let table = report.table();
        assert!(table.contains("| rigid |") && table.contains("multi limb"), "{table}");
    }

    #[test]
    fn a_take_too_short_for_a_length_gets_no_gaps_of_it() {
        let truth = wave(100);
        let config = LengthsConfig { lengths_s: vec![0.1, 0.5, 1.0, 1e300, f64::NAN], ..LengthsConfig::default() };
        let gaps = length_gaps(&truth, &config);
        // 0.1 s and 0.5 s fit in 100 frames at 120 Hz; 1 s, a huge and a NaN length do not.
        assert_eq!(gaps.len(), 10);
        assert!(gaps.iter().all(|g| [12, 60].contains(&g.frames.len())));
        assert!(gaps.iter().all(|g| g.frames.start >= 1 && g.frames.end < 100));
    }
}
