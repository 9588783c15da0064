//! Occlusion and shift augmentation (LocalMoCap section 3.3, Eq. 6), and the per-frame random
//! corruption of Holden (2018) as the comparison the paper makes.
//!
//! # Eq. 6
//! Given the overall occlusion probability `p_occ`, the take length `L`, the real gap-length
//! distribution `g_l` and the real per-marker occlusion probabilities `p_i`, marker `i` gets
//!
//! ```text
//! N_{l,i} = round( L/l * (l g_l / sum_l(l g_l)) * p_occ * p_i / mean_i(p_i) )
//! ```
//!
//! gaps of length `l`: the share of occluded *frames* in gaps of length `l` times the frames
//! marker `i` should lose. Two choices differ from the printed equation, both documented:
//! - **mean, not sum**: the paper normalises `p_i` by `sum_i p_i`; then a 41-marker take would
//!   lose `p_occ / 41` of its samples, not `p_occ`. With the mean, `p_occ` *is* the expected
//!   missing fraction of the take, which is what the paper says it is.
//! - **rounding**: the paper floors. For a take of a few thousand frames, most long lengths
//!   then get `floor(0.3) = 0` gaps and the heavy tail vanishes. [`Rounding::Stochastic`]
//!   (the default) rounds up with probability equal to the fractional part, so expected counts
//!   are exact and the synthesized gap-length histogram matches the real one over many takes;
//!   [`Rounding::Floor`] is the paper's rule.
//!
//! `p_i` is the real probability of the marker *of the same label* when the statistics name
//! it (see [`GapModel::fraction_of`]), otherwise one drawn from the pool of all real markers.
//!
//! # Placement
//! Gaps are placed longest first, each uniformly at random among all positions where it covers
//! only visible samples and keeps at least one visible frame between it and any other gap (two
//! touching gaps would read as one longer gap and bend the length histogram). Gaps may touch
//! the take's ends. A gap that fits nowhere is dropped and counted. Shortest-first or random
//! order runs out of room for long gaps, as the paper notes.
//!
//! # Shifts
//! Each remaining visible sample is shifted with probability `p_shift` by an offset whose
//! axes are drawn from `U(-sigma, sigma)` mm.
//!
//! # Per-frame random (Holden 2018)
//! Every visible sample is hidden independently with the marker's probability: the same
//! missing fraction, but geometric gap lengths (gaps longer than a few frames almost never
//! occur, the paper's Fig. 4b).

use crate::gap_model::GapModel;
use locap_core::gaps::{Gap, add_histogram, gaps_of};
use locap_core::{Take, Vec3};
use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};

/// How occlusions are generated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum OcclusionMode {
    /// Eq. 6: real gap-length distribution, placed longest first.
    #[default]
    Eq6,
    /// Independent per-sample drops (Holden 2018).
    PerFrame,
}

/// How Eq. 6's expected counts become integers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Rounding {
    /// Round up with probability equal to the fractional part (unbiased).
    #[default]
    Stochastic,
    /// The paper's floor.
    Floor,
}

/// Settings of [`augment`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AugmentConfig {
    /// Occlusion generator.
    pub mode: OcclusionMode,
    /// Overall occlusion probability `p_occ`; `None`: the real statistics' mean.
    pub missing_fraction: Option<f64>,
    /// Rounding of Eq. 6 counts.
    pub rounding: Rounding,
    /// Probability that a visible sample is shifted.
    pub shift_probability: f64,
    /// Largest shift per axis, mm.
    pub shift_sigma_mm: f64,
}

impl Default for AugmentConfig {
    /// Eq. 6 at the real statistics' occlusion rate, 0.5% shifted samples by up to 50 mm.
    fn default() -> Self {
        AugmentConfig {
            mode: OcclusionMode::Eq6,
            missing_fraction: None,
            rounding: Rounding::Stochastic,
            shift_probability: 0.005,
            shift_sigma_mm: 50.0,
        }
    }
}

/// Errors of augmentation.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum AugmentError {
    /// A probability or magnitude out of range.
    #[error("{what} = {value} is out of range ({range})")]
    OutOfRange {
        /// Which setting.
        what: &'static str,
        /// Its value.
        value: f64,
        /// The allowed range.
        range: &'static str,
    },
}

impl AugmentConfig {
    fn check(&self) -> Result<(), AugmentError> {
        let out = |what, value, range| Err(AugmentError::OutOfRange { what, value, range });
        if let Some(p) = self.missing_fraction
            && !(0.0..0.95).contains(&p)
        {
            return out("missing_fraction", p, "0 to 0.95");
        }
        if !(0.0..=1.0).contains(&self.shift_probability) {
            return out("shift_probability", self.shift_probability, "0 to 1");
        }
        if !(self.shift_sigma_mm.is_finite() && self.shift_sigma_mm >= 0.0) {
            return out("shift_sigma_mm", self.shift_sigma_mm, "0 or more");
        }
        Ok(())
    }
}

/// A corrupted take and what was done to it.
#[derive(Debug, Clone, PartialEq)]
pub struct Augmented {
    /// The corrupted take (hidden samples missing, shifted samples moved).
    pub take: Take,
    /// Gaps hidden per marker (in time order).
    pub gaps: Vec<Vec<Gap>>,
    /// Frame-major mask of shifted samples.
    pub shifted: Vec<bool>,
    /// Eq. 6 gaps that found no room.
    pub dropped_gaps: usize,
}

impl Augmented {
    /// Histogram of the hidden gap lengths (`[n]` = gaps of `n` frames).
    pub fn gap_length_histogram(&self) -> Vec<usize> {
        let mut h = Vec::new();
        for g in self.gaps.iter().flatten() {
            add_histogram(&mut h, &one_hot(g.len));
        }
        h
    }
}

fn one_hot(len: usize) -> Vec<usize> {
    let mut h = vec![0; len + 1];
    h[len] = 1;
    h
}

/// Occlusion probability of each of `labels` (Eq. 6's `p_occ * p_i / mean(p_i)`, at most
/// 0.95): `p_i` by label where the model names the marker, else drawn from its pool.
pub fn marker_probabilities(
    model: &GapModel,
    labels: &[String],
    missing_fraction: Option<f64>,
    rng: &mut impl Rng,
) -> Vec<f64> {
    let p_occ = missing_fraction.unwrap_or_else(|| model.mean_fraction());
    let raw: Vec<f64> = labels
        .iter()
        .map(|l| {
            model.fraction_of(l).unwrap_or_else(|| {
                if model.missing_fractions.is_empty() {
                    p_occ
                } else {
                    model.missing_fractions[rng.random_range(0..model.missing_fractions.len())]
                }
            })
        })
        .collect();
    let mean = raw.iter().sum::<f64>() / raw.len().max(1) as f64;
    raw.iter().map(|p| if mean > 0.0 { (p_occ * p / mean).min(0.95) } else { p_occ }).collect()
}

/// Eq. 6 expected gap counts for one marker: `(length, expected count)` for every length of
/// the model's histogram up to `max_gap_frames` and `frames`.
pub fn eq6_expected_counts(model: &GapModel, frames: usize, probability: f64) -> Vec<(usize, f64)> {
    let top = model.max_gap_frames.min(model.length_histogram.len().saturating_sub(1)).min(frames);
    let weighted: f64 = (1..=top).map(|l| l as f64 * model.length_histogram[l] as f64).sum();
    if weighted <= 0.0 {
        return Vec::new();
    }
    (1..=top)
        .filter(|&l| model.length_histogram[l] > 0)
        .map(|l| {
            let share = l as f64 * model.length_histogram[l] as f64 / weighted;
            (l, frames as f64 / l as f64 * share * probability)
        })
        .collect()
}

/// Eq. 6 gap lengths for one marker, longest first.
pub fn eq6_lengths(
    model: &GapModel,
    frames: usize,
    probability: f64,
    rounding: Rounding,
    rng: &mut impl Rng,
) -> Vec<usize> {
    let mut lengths = Vec::new();
    for (l, expected) in eq6_expected_counts(model, frames, probability).into_iter().rev() {
        let whole = expected.floor();
        let n = match rounding {
            Rounding::Floor => whole as usize,
            Rounding::Stochastic => whole as usize + usize::from(rng.random::<f64>() < expected - whole),
        };
        lengths.extend(std::iter::repeat_n(l, n));
    }
    lengths
}

/// Places gaps of `lengths` (longest first) in a track of `visible.len()` frames, each
/// uniformly among the positions that cover only visible frames and keep one visible frame
/// from every other gap (placed or already missing). Returns the gaps in time order and how many found no room.
pub fn place_longest_first(lengths: &[usize], visible: &[bool], rng: &mut impl Rng) -> (Vec<Gap>, usize) {
    let mut order: Vec<usize> = lengths.iter().copied().filter(|l| *l > 0).collect();
    order.sort_unstable_by(|a, b| b.cmp(a));
    // Free runs [start, end) of frames a gap may cover: visible runs, less the frame next to
    // an existing (real) gap, so a new gap never merges with one.
    let frames = visible.len();
    let mut free: Vec<(usize, usize)> = gaps_of(visible.iter().map(|v| !v))
        .into_iter()
        .map(|g| (g.start + usize::from(g.start > 0), g.end() - usize::from(g.end() < frames)))
        .filter(|(a, b)| a < b)
        .collect();
    let mut gaps = Vec::with_capacity(order.len());
    let mut dropped = 0;
    for len in order {
        let total: usize = free.iter().map(|(a, b)| (b - a + 1).saturating_sub(len)).sum();
        if total == 0 {
            dropped += 1;
            continue;
        }
        let mut pick = rng.random_range(0..total as u64) as usize;
        let mut k = 0;
        loop {
            let (a, b) = free[k];
            let n = (b - a + 1).saturating_sub(len);
            if pick < n {
                break;
            }
            pick -= n;
            k += 1;
        }
        let (a, b) = free[k];
        let start = a + pick;
        gaps.push(Gap { start, len });
        // The gap and one frame on each side are no longer free.
        let mut pieces = Vec::with_capacity(2);
        if start > a + 1 {
            pieces.push((a, start - 1));
        }
        if start + len + 1 < b {
            pieces.push((start + len + 1, b));
        }
        free.splice(k..=k, pieces);
    }
    gaps.sort_by_key(|g| g.start);
    (gaps, dropped)
}

/// Corrupts `clean` with occlusions and shifts drawn from `model` (see the module docs).
pub fn augment(
    clean: &Take,
    model: &GapModel,
    config: &AugmentConfig,
    rng: &mut impl Rng,
) -> Result<Augmented, AugmentError> {
    config.check()?;
    let (frames, markers) = (clean.frame_count(), clean.marker_count());
    let labels: Vec<String> = clean.markers().iter().map(|m| m.label.clone()).collect();
    let probabilities = marker_probabilities(model, &labels, config.missing_fraction, rng);
    let mut take = clean.clone();
    let mut all_gaps = Vec::with_capacity(markers);
    let mut dropped_gaps = 0;
    for (m, p) in probabilities.iter().enumerate() {
        let visible: Vec<bool> = (0..frames).map(|f| clean.is_valid(f, m)).collect();
        let gaps = match config.mode {
            OcclusionMode::Eq6 => {
                let lengths = eq6_lengths(model, frames, *p, config.rounding, rng);
                let (gaps, dropped) = place_longest_first(&lengths, &visible, rng);
                dropped_gaps += dropped;
                gaps
            }
            OcclusionMode::PerFrame => {
                let hidden: Vec<bool> = visible.iter().map(|v| *v && rng.random::<f64>() < *p).collect();
                gaps_of(hidden.iter().map(|h| !h))
            }
        };
        for g in &gaps {
            for f in g.start..g.end() {
                // Removing a sample cannot fail.
                let _ = take.set_position_mm(f, m, None);
            }
        }
        all_gaps.push(gaps);
    }
    let mut shifted = vec![false; frames * markers];
    if config.shift_probability > 0.0 {
        let s = config.shift_sigma_mm;
        for f in 0..frames {
            for m in 0..markers {
                let Some(p) = take.position_mm(f, m) else { continue };
                if rng.random::<f64>() < config.shift_probability {
                    let o = Vec3::new(rng.random_range(-s..=s), rng.random_range(-s..=s), rng.random_range(-s..=s));
                    // p and o are finite.
                    let _ = take.set_position_mm(f, m, Some(p + o));
                    shifted[f * markers + m] = true;
                }
            }
        }
    }
    Ok(Augmented { take, gaps: all_gaps, shifted, dropped_gaps })
}

/// Kolmogorov-Smirnov statistic between two gap-length histograms (`[n]` = count of length
/// `n`): the largest difference of their cumulative distributions, in `[0, 1]` (1 if either is
/// empty).
pub fn ks_statistic(a: &[usize], b: &[usize]) -> f64 {
    let (ta, tb) = (a.iter().skip(1).sum::<usize>() as f64, b.iter().skip(1).sum::<usize>() as f64);
    if ta == 0.0 || tb == 0.0 {
        return 1.0;
    }
    let (mut ca, mut cb, mut d) = (0.0, 0.0, 0.0f64);
    for l in 1..a.len().max(b.len()) {
        ca += a.get(l).copied().unwrap_or(0) as f64 / ta;
        cb += b.get(l).copied().unwrap_or(0) as f64 / tb;
        d = d.max((ca - cb).abs());
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::MarkerName;
    use proptest::prelude::*;
    use rand::SeedableRng;

    fn model() -> GapModel {
        // Heavy tail: many short gaps, a few long ones.
        let mut h = vec![0usize; 301];
        for (l, c) in h.iter_mut().enumerate().skip(1) {
            *c = (10_000.0 / (l as f64).powf(1.8)) as usize;
        }
        let mut m = GapModel::uniform(0.05, 300);
        m.length_histogram = h;
        m.missing_fractions = vec![0.02, 0.08];
        m.marker_names = vec!["A".into(), "B".into()];
        m
    }

    fn clean(frames: usize, names: &[&str]) -> Take {
        let samples = vec![Some(Vec3::new(1.0, 2.0, 3.0)); frames * names.len()];
        Take::from_samples(names.iter().map(|n| MarkerName::parse(n)).collect(), &samples, 120.0).unwrap()
    }

    /// The gap counts are Eq. 6's, floored, when everything fits.
    #[test]
    fn floor_counts_are_eq6() {
        let model = model();
        let take = clean(20_000, &["A", "B"]);
        let config = AugmentConfig {
            rounding: Rounding::Floor,
            missing_fraction: Some(0.1),
            shift_probability: 0.0,
            ..Default::default()
        };
        let out = augment(&take, &model, &config, &mut rand::rngs::StdRng::seed_from_u64(5)).unwrap();
        assert_eq!(out.dropped_gaps, 0);
        // p_i by label: A 0.02, B 0.08, mean 0.05 -> A 0.04, B 0.16.
        for (m, p) in [(0, 0.04), (1, 0.16)] {
            let weighted: f64 = (1..=300).map(|l| (l * model.length_histogram[l]) as f64).sum();
            for l in 1..=300 {
                let expect = (20_000.0 / l as f64 * (l * model.length_histogram[l]) as f64 / weighted * p).floor();
                let got = out.gaps[m].iter().filter(|g| g.len == l).count();
                assert_eq!(got as f64, expect, "marker {m} length {l}");
            }
            let missing = (0..20_000).filter(|f| !out.take.is_valid(*f, m)).count() as f64 / 20_000.0;
            // Flooring loses the tail: far fewer frames than p are hidden (why Stochastic is
            // the default), but never more.
            assert!(missing <= p && missing > p * 0.25, "marker {m}: {missing}");
        }
    }

    /// Stochastic rounding: the hidden fraction is p_occ on average, and the generated
    /// gap-length distribution is close to the real one (KS), unlike per-frame drops.
    #[test]
    fn eq6_matches_the_real_length_distribution_and_per_frame_does_not() {
        let model = model();
        let take = clean(6000, &["A", "B", "C", "D"]);
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let (mut h_eq6, mut h_pf) = (Vec::new(), Vec::new());
        let mut missing = 0usize;
        for _ in 0..20 {
            let config = AugmentConfig { missing_fraction: Some(0.05), shift_probability: 0.0, ..Default::default() };
            let a = augment(&take, &model, &config, &mut rng).unwrap();
            add_histogram(&mut h_eq6, &a.gap_length_histogram());
            missing += a.take.validity().iter().filter(|v| !**v).count();
            let pf = AugmentConfig { mode: OcclusionMode::PerFrame, ..config };
            add_histogram(&mut h_pf, &augment(&take, &model, &pf, &mut rng).unwrap().gap_length_histogram());
        }
        let fraction = missing as f64 / (20.0 * 6000.0 * 4.0);
        assert!((fraction - 0.05).abs() < 0.01, "{fraction}");
        let (ks_eq6, ks_pf) =
            (ks_statistic(&h_eq6, &model.length_histogram), ks_statistic(&h_pf, &model.length_histogram));
        assert!(ks_eq6 < 0.05, "{ks_eq6}");
        assert!(ks_pf > 0.2, "{ks_pf}");
    }

    #[test]
    fn same_seed_same_corruption_and_shifts_within_sigma() {
        let model = model();
        let take = clean(3000, &["A", "B", "X"]);
        let config = AugmentConfig { shift_probability: 0.05, shift_sigma_mm: 20.0, ..Default::default() };
        let run = |seed| augment(&take, &model, &config, &mut rand::rngs::StdRng::seed_from_u64(seed)).unwrap();
        let (a, b, c) = (run(1), run(1), run(2));
        assert_eq!(a, b);
        assert_ne!(a.take, c.take);
        let shifted = a.shifted.iter().filter(|s| **s).count();
        assert!(shifted > 100, "{shifted}");
        for f in 0..3000 {
            for m in 0..3 {
                if let Some(p) = a.take.position_mm(f, m) {
                    let d = p - Vec3::new(1.0, 2.0, 3.0);
                    assert_eq!(a.shifted[f * 3 + m], d.norm() > 0.0);
                    assert!(d.amax() <= 20.0);
                }
            }
        }
        assert!(
            augment(
                &take,
                &model,
                &AugmentConfig { shift_probability: 2.0, ..config },
                &mut rand::rngs::StdRng::seed_from_u64(1)
            )
            .is_err()
        );
    }

    #[test]
    fn ks_of_identical_and_disjoint_histograms() {
        assert_eq!(ks_statistic(&[0, 3, 2], &[0, 6, 4]), 0.0);
        assert_eq!(ks_statistic(&[0, 1, 0], &[0, 0, 1]), 1.0);
        assert_eq!(ks_statistic(&[0], &[0, 1]), 1.0);
    }

    proptest! {
        /// Placed gaps never overlap or touch, stay on visible frames, and only drop what
        /// cannot fit.
        #[test]
        fn placement_never_overlaps(
            lengths in proptest::collection::vec(1usize..40, 0..30),
            visible in proptest::collection::vec(prop::bool::weighted(0.9), 1..300),
            seed in any::<u64>(),
        ) {
            let (gaps, dropped) = place_longest_first(&lengths, &visible, &mut rand::rngs::StdRng::seed_from_u64(seed));
            prop_assert_eq!(gaps.len() + dropped, lengths.len());
            for g in &gaps {
                prop_assert!(g.end() <= visible.len());
                // Only visible frames, with a visible frame (or the take's end) on each side.
                prop_assert!((g.start.saturating_sub(1)..(g.end() + 1).min(visible.len())).all(|f| visible[f]));
            }
            for w in gaps.windows(2) {
                prop_assert!(w[0].end() < w[1].start, "{:?} touches {:?}", w[0], w[1]);
            }
        }
    }
}
