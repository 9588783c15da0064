//! PCA fill from marker intercorrelations (Gløersen & Federolf 2016, "Predicting missing
//! marker trajectories in human motion data using marker intercorrelations", PLoS ONE 11(3):
//! e0152616), reconstruction strategy R2, the authors' default.
//!
//! # What is implemented
//! The take is a `T x 3M` matrix of coordinates. For every marker `i` with gaps, separately
//! (R2):
//! - `d_ij`, the mean distance from `i` to every marker `j` over the frames both are captured;
//!   markers with gaps farther than `distal_threshold` times the mean of `d_i.` (`i` itself
//!   included, at 0) are dropped ("distal"); markers without gaps are always kept;
//! - the *predictors* of a frame where `i` is missing are the kept markers captured in that
//!   frame (see the first departure below); the frames where `i` is missing are grouped by
//!   their predictors and each group is reconstructed by one projection:
//!   - the *mean trajectory* (per frame, the centroid of the gap-free markers; of the group's
//!     predictors when no marker is gap-free) is subtracted from every marker, giving a frame
//!     that moves with the subject;
//!   - the *complete* frames are those where `i` and every predictor are captured; their
//!     per-column mean and standard deviation normalise the data (a zero deviation counts as
//!     1), then each marker's 3 columns are multiplied by the weight
//!     `w_j = exp(-d_ij^2 / (2 sigma^2))` (`sigma` = `weight_scale_mm`, 200 mm), `i`'s own by
//!     `missing_marker_weight` (0.02);
//!   - two PCAs: of the complete frames `N`, and of the same frames with `i`'s columns set to
//!     zero `N0`; each keeps the leading components whose *singular values* sum to
//!     `min_cumulative_sv` (99%) of the total, and both keep the larger of the two counts `k`;
//!   - each frame of the group, with `i`'s columns zero, is mapped into `N0`'s basis, through
//!     `T = PC_N^T PC_N0` into `N`'s basis and back to coordinates: `x = m0 PC_N0 T PC_N^T`
//!     (the paper's reconstruction, from Federolf 2013, Eq. 1, with `T` as in the authors'
//!     MATLAB code); `i`'s columns of `x`, un-weighted, de-normalised and with the mean
//!     trajectory added back, are the fill.
//!
//! The PCAs are eigen-decompositions (nalgebra `SymmetricEigen`) of covariance matrices
//! accumulated over the complete frames in blocks, never an SVD of the `T x 3M` matrix, so a
//! 72,000-frame take of 41 markers takes seconds. `d_ij` is averaged over at most
//! [`DISTANCE_FRAMES`] evenly spaced frames (the authors' later code also subsamples).
//!
//! # Departures, where the paper's method has no answer
//! - Gaps in most markers at once. The published R2 drops, for all of `i`'s gaps, every
//!   marker with a gap that overlaps *any* gap of `i`, and takes the mean trajectory from the
//!   gap-free markers. With realistic occlusion (most markers missing 10-25% of the take, in
//!   gaps of up to hundreds of frames) almost every marker overlaps `i` somewhere and none is
//!   gap-free, so nothing but `i` was left: the PCA had no predictor and every fill was `i`'s
//!   mean position about a linearly pre-filled centroid, 180-260 mm off even for 1-frame
//!   gaps (the authors' MATLAB code divides by an empty set there and returns NaN). Here the
//!   overlap rule is applied frame by frame instead: a marker is a predictor wherever it is
//!   captured, which is the rule's purpose (predictors must be present in the frames being
//!   reconstructed). Where no marker overlaps a gap of `i` this is exactly the published R2.
//! - No marker is gap-free: the mean trajectory is the centroid of the group's predictors,
//!   which are captured in every frame the group uses, so it needs no pre-fill.
//! - Fewer than [`MIN_PREDICTORS`] predictors in a frame (or none left by the distal rule):
//!   the nearest other captured markers are added, distal or not. No marker captured: the
//!   linear pre-fill ([`super::linear`]).
//! - Fewer than [`MIN_COMPLETE_FRAMES`] complete frames for a group: the predictors are taken
//!   from the linear pre-fill, and every frame where `i` is captured counts as complete.
//! - A marker never captured stays missing; a marker never seen together with `i` counts as
//!   distal.
//!
//! # Aligned frame (locap's, not the paper's)
//! The paper's frame only translates with the subject. A subject who turns, leans or rolls
//! moves every marker by a rotation, which is not a linear mix of coordinates: the
//! components spent on describing headings are missing for the posture, and a heading the
//! complete frames never showed is reconstructed badly. [`PcaFrame::Aligned`] removes the
//! rotation as well: in every frame the predictors are rigidly aligned (weighted Kabsch,
//! [`crate::procrustes`]) to their mean shape over the complete frames (two rounds of
//! generalised Procrustes from the first complete frame), with the PCA's own distance
//! weights, so the frame turns with the markers nearest to the missing one, like a rigid-body
//! fill's; the PCA then models what the neighbourhood's motion does not explain, and the
//! reconstruction is turned back. Everything else is the paper's R2 as above. Where the
//! weights leave the predictors on a line ([`MIN_ALIGNED_SPREAD_MM`]) a rotation is not
//! defined and the paper's frame is used.
//! [`crate::FillMethod::PcaAligned`] runs it; the per-gap choice ([`crate::auto`]) has it
//! among its candidates, beside the paper's frame.
//!
//! # Meeting the borders (locap's, not the paper's)
//! The published method does not use the samples either side of a gap, so its fill jumps
//! at each border by its reconstruction error there, and its error does not shrink on short
//! gaps as interpolation's does. With [`PcaConfig::border_fade_s`] set, [`fill_marker`] also
//! reconstructs each border sample as if it were missing, from the predictors of the gap
//! frame next to it (they are hidden there with it, so the border sees the gap's
//! neighbourhood), and adds the border errors to the fill: linearly weighted across the
//! gap as interpolation weighs its borders, and each faded with `exp(-t / fade)` over the
//! time `t` from its border, so a short gap is corrected throughout and the middle of a long
//! one keeps the reconstruction (an error a second away says little about this frame). A
//! gap with one border carries that border's error, faded. Off by default; the per-gap
//! choice ([`crate::auto`]) turns it on for its PCA candidates.
//!
//! # Residuals of the nearest poses (locap's, not the paper's)
//! A linear model of the posture misses what is not linear in it: a thigh marker on muscle
//! that bulges as the knee bends, a marker that swings along an arc. Where a take shows a pose
//! again (a run's cycles, a repeated exercise), the reconstruction misses the marker again by
//! about as much. With [`PcaConfig::residual_neighbours`] `K` set, every complete frame is
//! also reconstructed (with `i`'s columns zero, by the same projection: in sample) and its
//! error kept beside its scores in `N0`'s basis; each missing frame's reconstruction is
//! corrected by the errors of the `K` complete frames nearest it in that basis, weighted by
//! the inverse square of their distance: nearest-neighbour regression of what PCA leaves
//! (the [`crate::pose_match`] idea on PCA's residual instead of the marker, which varies far
//! less between neighbouring poses). In the moving frame, so a heading does not matter. Off
//! by default; the per-gap choice ([`crate::auto`]) turns it on for its PCA candidates.
//!
//! # Left out
//! Strategy R1 (all gaps reconstructed at once with the smallest distance as weight) and any
//! iteration: the published method is a single projection per frame, not an iterative
//! imputation (project, replace the missing entries, repeat).

use super::{borders, linear, put};
use crate::Filled;
use crate::procrustes::{self, RigidTransform};
use locap_core::gaps::{Gap, gaps_of};
use locap_core::{Take, Vec3};
use nalgebra::{DMatrix, Rotation3, SymmetricEigen};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::OnceLock;

/// Most frames the marker-to-marker mean distances are averaged over.
pub const DISTANCE_FRAMES: usize = 10_000;
/// Fewest complete frames for a PCA of a marker's predictors before falling back to a linear
/// pre-fill of the predictors.
pub const MIN_COMPLETE_FRAMES: usize = 10;
/// Fewest predictors of a missing marker: with fewer, their positions about their own
/// centroid (the mean trajectory when no marker is gap-free) cannot fix an orientation, so
/// the nearest other captured markers are added, distal or not.
pub const MIN_PREDICTORS: usize = 3;
/// Least spread (mm, the square root of the second eigenvalue of the predictors' weighted
/// scatter about their weighted centroid, in the mean shape) for the aligned frame. Below it
/// the weight sits on two markers, or on markers in a line, the rotation about their line
/// is fixed by markers of negligible weight, and the frame swings freely between frames
/// (on a short, heavily occluded take a foot marker predicted from two shin markers was
/// filled metres off). The paper's translated frame is used instead. A degeneracy guard, not
/// a tuning: larger limits also dropped frames the alignment served (docs/benchmarks.md).
pub const MIN_ALIGNED_SPREAD_MM: f64 = 0.1;
/// Most complete frames the aligned frame's mean shape is averaged over.
const REFERENCE_FRAMES: usize = 100;
/// Frames per block when accumulating a covariance matrix.
const BLOCK: usize = 2048;
/// Most coordinates of complete frames kept in memory between the passes over them (32 MB).
const ROW_CACHE: usize = 1 << 22;

/// Parameters of the PCA fill; the defaults are the authors'.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PcaConfig {
    /// `sigma` of the distance weighting `exp(-d^2 / (2 sigma^2))`, in mm (200).
    pub weight_scale_mm: f64,
    /// Weight of the missing marker's own columns (0.02).
    pub missing_marker_weight: f64,
    /// Markers with gaps farther than this times the mean distance are dropped (0.5).
    pub distal_threshold: f64,
    /// Fraction of the summed singular values the kept components must reach (0.99).
    pub min_cumulative_sv: f64,
    /// Frame the coordinates are decomposed in (the paper's: translated by the mean trajectory).
    #[serde(default)]
    pub frame: PcaFrame,
    /// Where set, [`fill_marker`] makes each gap's fill meet the captured samples at its
    /// borders: the error the reconstruction makes at a border sample, predicted from the
    /// gap's predictors as if missing, is removed from the fill, fading with this time
    /// constant in seconds (see "Meeting the borders" in the module doc). `None` (or a
    /// constant that is not positive), the paper's method, leaves the jump at the borders.
    #[serde(default)]
    pub border_fade_s: Option<f64>,
    /// Where not 0, each reconstruction is corrected by the reconstruction errors of this many
    /// complete frames nearest it in the PCA's scores (see "Residuals of the nearest poses" in
    /// the module doc). 0, the paper's method, corrects nothing.
    #[serde(default)]
    pub residual_neighbours: usize,
}

/// The moving frame PCA sees each frame's markers in.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PcaFrame {
    /// Translated by the mean trajectory (the paper's).
    #[default]
    Translated,
    /// Translated and turned: each frame's predictors, weighted as in the PCA (nearest to the
    /// missing marker most), rigidly aligned to their mean shape (see "Aligned frame" in the
    /// module doc). locap's, not the paper's.
    Aligned,
}

impl PcaConfig {
    /// The authors' parameters in the [`PcaFrame::Aligned`] frame.
    pub fn aligned() -> PcaConfig {
        PcaConfig { frame: PcaFrame::Aligned, ..PcaConfig::default() }
    }
}

impl Default for PcaConfig {
    fn default() -> PcaConfig {
        PcaConfig {
            weight_scale_mm: 200.0,
            missing_marker_weight: 0.02,
            distal_threshold: 0.5,
            min_cumulative_sv: 0.99,
            frame: PcaFrame::Translated,
            border_fade_s: None,
            residual_neighbours: 0,
        }
    }
}

/// Fills every gap of every marker of `take` by the PCA method (strategy R2).
pub fn fill(take: &Take, config: &PcaConfig) -> Filled {
    let frames = take.frame_count();
    let markers = take.marker_count();
    let mut out = Filled::unchanged(take);
    let seen: Vec<bool> = (0..markers).map(|k| (0..frames).any(|f| take.is_valid(f, k))).collect();
    let gapped: Vec<bool> = (0..markers).map(|k| (0..frames).any(|f| !take.is_valid(f, k))).collect();
    if !(0..markers).any(|k| seen[k] && gapped[k]) {
        return out;
    }
    let context = Context { take, prefill: OnceLock::new(), gapped: &gapped, config, only: 0..frames };
    for i in (0..markers).filter(|k| seen[*k] && gapped[*k]) {
        let distances = mean_distances(take, i);
        fill_marker_into(&context, &distances, i, &mut out);
    }
    out
}

/// Fills the gaps of `marker` alone within frames `only`, exactly as [`fill`] fills them;
/// every other sample stays as captured. The per-gap fill of [`crate::auto`] needs one gap's
/// reconstruction, and the cost of [`fill`] grows with the number of gapped markers.
///
/// With [`PcaConfig::border_fade_s`] set, each gap's fill is also made to meet its borders.
pub fn fill_marker(take: &Take, marker: usize, only: Range<usize>, config: &PcaConfig) -> Filled {
    match config.border_fade_s {
        // A fade that is not positive corrects nothing: the paper's fill, not a copy of it
        // with the border samples hidden.
        Some(fade_s) if fade_s > 0.0 && marker < take.marker_count() => {
            fill_marker_meeting_borders(take, marker, only, config, fade_s)
        }
        _ => fill_marker_alone(take, marker, only, config),
    }
}

/// [`fill_marker`] as the paper reconstructs: each gap on its own, without its borders.
fn fill_marker_alone(take: &Take, marker: usize, only: Range<usize>, config: &PcaConfig) -> Filled {
    let frames = take.frame_count();
    let mut out = Filled::unchanged(take);
    if marker >= take.marker_count() || !(0..frames).any(|f| take.is_valid(f, marker)) {
        return out;
    }
    let gapped: Vec<bool> = (0..take.marker_count()).map(|k| (0..frames).any(|f| !take.is_valid(f, k))).collect();
    if !gapped[marker] {
        return out;
    }
    let context = Context { take, prefill: OnceLock::new(), gapped: &gapped, config, only };
    fill_marker_into(&context, &mean_distances(take, marker), marker, &mut out);
    out
}

/// [`fill_marker`] with every gap of `marker` within `only` made to meet its borders: the
/// border samples are hidden too (with the markers missing in the gap's adjacent frame, so
/// they are predicted from the gap's own predictors), the reconstruction's error there is
/// measured, and each gap's fill is corrected by the errors of its borders, each weighted
/// linearly across the gap and faded by `exp(-t / fade_s)` with the time `t` from its border.
fn fill_marker_meeting_borders(
    take: &Take,
    marker: usize,
    only: Range<usize>,
    config: &PcaConfig,
    fade_s: f64,
) -> Filled {
    let frames = take.frame_count();
    let first = only.start.min(frames);
    let last = only.end.min(frames);
    let gaps: Vec<Gap> = gaps_of((first..last).map(|f| take.is_valid(f, marker)))
        .into_iter()
        .map(|g| Gap { start: g.start + first, len: g.len })
        .collect();
    // Each gap's borders, and at each the gap frame next to it.
    let bordered: Vec<(Gap, Option<usize>, Option<usize>)> = gaps
        .into_iter()
        .map(|gap| {
            let (before, after) = borders(gap.start, gap.end(), frames);
            (gap, before, after)
        })
        .collect();
    let mut hidden = take.clone();
    for (gap, before, after) in &bordered {
        for (b, adjacent) in [before.map(|b| (b, gap.start)), after.map(|b| (b, gap.end() - 1))].into_iter().flatten() {
            for j in 0..take.marker_count() {
                if j == marker || !take.is_valid(adjacent, j) {
                    // In range by construction: `b` is a frame of the take, `j` one of its markers.
                    let _ = hidden.set_position_mm(b, j, None);
                }
            }
        }
    }
    let widened = first.saturating_sub(1)..(last + 1).min(frames);
    let predicted = fill_marker_alone(&hidden, marker, widened, config);
    let mut out = Filled::unchanged(take);
    let fade_frames = fade_s * take.frame_rate_hz();
    let fade = |t: f64| (-t / fade_frames).exp();
    for &(gap, before, after) in &bordered {
        // The reconstruction's error at a border, where both it and the capture exist.
        let error_at = |b: Option<usize>| -> Option<Vec3> {
            Some(take.position_mm(b?, marker)? - predicted.computed(b?, marker)?)
        };
        let (e0, e1) = (error_at(before), error_at(after));
        let span = (gap.len + 1) as f64;
        for f in gap.start..gap.end() {
            let Some(p) = predicted.computed(f, marker) else { continue };
            let from_start = (f + 1 - gap.start) as f64;
            let from_end = (gap.end() - f) as f64;
            // One border alone carries its error with the fade; two share it linearly too.
            let (w0, w1) = match (e0, e1) {
                (Some(_), Some(_)) => (from_end / span, from_start / span),
                _ => (1.0, 1.0),
            };
            let correction = e0.map_or(Vec3::zeros(), |e| e * (w0 * fade(from_start)))
                + e1.map_or(Vec3::zeros(), |e| e * (w1 * fade(from_end)));
            put(&mut out, f, marker, p + correction);
        }
    }
    out
}

/// What every marker's reconstruction shares.
struct Context<'a> {
    take: &'a Take,
    /// The linear pre-fill, made the first time a fallback needs it (most fills never do).
    prefill: OnceLock<Take>,
    gapped: &'a [bool],
    config: &'a PcaConfig,
    /// Frames to reconstruct (missing frames outside stay missing).
    only: Range<usize>,
}

impl Context<'_> {
    fn prefill(&self) -> &Take {
        self.prefill.get_or_init(|| linear::fill(self.take).take)
    }
}

/// Mean distance from marker `i` to every marker over the frames both are captured (sampled
/// evenly, at most [`DISTANCE_FRAMES`] frames); `None` if never captured together.
fn mean_distances(take: &Take, i: usize) -> Vec<Option<f64>> {
    let frames = take.frame_count();
    let stride = frames.div_ceil(DISTANCE_FRAMES).max(1);
    let mut sum = vec![0.0; take.marker_count()];
    let mut count = vec![0usize; take.marker_count()];
    for f in (0..frames).step_by(stride) {
        let Some(p) = take.position_mm(f, i) else { continue };
        for (j, (s, c)) in sum.iter_mut().zip(count.iter_mut()).enumerate() {
            if let Some(q) = take.position_mm(f, j) {
                *s += (p - q).norm();
                *c += 1;
            }
        }
    }
    sum.iter().zip(&count).map(|(s, c)| (*c > 0).then(|| s / *c as f64)).collect()
}

/// Reconstructs the gaps of marker `i` (strategy R2, the overlap rule applied frame by frame)
/// into `out`.
fn fill_marker_into(cx: &Context, distances: &[Option<f64>], i: usize, out: &mut Filled) {
    let take = cx.take;
    let markers = take.marker_count();
    let known: Vec<f64> = distances.iter().flatten().copied().collect();
    let threshold = cx.config.distal_threshold * known.iter().sum::<f64>() / known.len().max(1) as f64;
    let near = |j: usize| distances[j].is_some_and(|d| d <= threshold);
    // Frames where `i` is missing, grouped by their predictors: the markers captured there
    // that are gap-free or not distal (any captured marker where that leaves none).
    let mut groups: BTreeMap<Vec<usize>, Vec<usize>> = BTreeMap::new();
    for f in cx.only.clone().filter(|f| *f < take.frame_count() && !take.is_valid(*f, i)) {
        let captured: Vec<usize> = (0..markers).filter(|j| *j != i && take.is_valid(f, *j)).collect();
        let kept: Vec<usize> = captured.iter().copied().filter(|j| !cx.gapped[*j] || near(*j)).collect();
        let mut kept = if kept.is_empty() { captured.clone() } else { kept };
        if kept.len() < MIN_PREDICTORS {
            // Too few to fix an orientation about their centroid: add the nearest captured.
            let mut rest: Vec<usize> = captured.iter().copied().filter(|j| !kept.contains(j)).collect();
            rest.sort_by(|a, b| distances[*a].unwrap_or(f64::MAX).total_cmp(&distances[*b].unwrap_or(f64::MAX)));
            kept.extend(rest.into_iter().take(MIN_PREDICTORS - kept.len()));
            kept.sort_unstable();
        }
        groups.entry(kept).or_default().push(f);
    }
    for (predictors, missing) in groups {
        if predictors.is_empty() {
            // Nothing captured in these frames: the linear pre-fill is all there is.
            for f in missing {
                if let Some(p) = cx.prefill().position_mm(f, i) {
                    put(out, f, i, p);
                }
            }
        } else {
            project(cx, distances, i, &predictors, &missing, out);
        }
    }
}

/// Reconstructs marker `i` at the frames `missing`, where every one of `predictors` is
/// captured, by one projection (the paper's R2 step for one marker) into `out`.
fn project(
    cx: &Context,
    distances: &[Option<f64>],
    i: usize,
    predictors: &[usize],
    missing: &[usize],
    out: &mut Filled,
) {
    let (take, config) = (cx.take, cx.config);
    let frames = take.frame_count();
    let mut kept: Vec<usize> = predictors.to_vec();
    kept.push(i);
    let own = kept.len() - 1;
    let mut source = take;
    let mut fit: Vec<usize> = (0..frames).filter(|f| kept.iter().all(|j| take.is_valid(*f, *j))).collect();
    if fit.len() < MIN_COMPLETE_FRAMES {
        // Fallback: predictors from the linear pre-fill, complete wherever `i` is captured.
        source = cx.prefill();
        fit = (0..frames).filter(|f| take.is_valid(*f, i)).collect();
    }
    // Mean trajectory: centroid of the gap-free predictors (the paper's), else of all the
    // predictors, which are captured in every frame used here.
    let gap_free: Vec<usize> = predictors.iter().copied().filter(|j| !cx.gapped[*j]).collect();
    let centred = if gap_free.is_empty() { predictors.to_vec() } else { gap_free };
    let centre = |f: usize| -> Vec3 {
        let points: Vec<Vec3> = centred.iter().filter_map(|k| source.position_mm(f, *k)).collect();
        points.iter().sum::<Vec3>() / points.len().max(1) as f64
    };
    let weights: Vec<f64> = kept
        .iter()
        .map(|j| match (*j == i, distances[*j]) {
            (true, _) => config.missing_marker_weight,
            (false, Some(d)) => (-d * d / (2.0 * config.weight_scale_mm.powi(2))).exp(),
            (false, None) => 0.0,
        })
        .collect();
    let cols = 3 * kept.len();
    let moving = moving_frame(cx, &kept, &weights[..own], &fit, source, &centre);
    // Row of coordinates of the kept markers at frame f, in the moving frame; `i`'s columns
    // are zero where `i` is missing.
    let row_in = |f: usize, to_frame: &RigidTransform, buf: &mut [f64]| {
        for (slot, j) in kept.iter().enumerate() {
            let p = if *j == i { take.position_mm(f, i) } else { source.position_mm(f, *j) };
            let p = p.map(|p| to_frame.apply(&p)).unwrap_or_else(Vec3::zeros);
            buf[3 * slot..3 * slot + 3].copy_from_slice(p.as_slice());
        }
    };
    let row = |f: usize, buf: &mut [f64]| row_in(f, &moving(f), buf);
    // The complete frames' rows are read three times (mean, deviation, covariance): kept once
    // where they fit in memory, rebuilt each time otherwise.
    let cache: Option<Vec<f64>> = (fit.len() * cols <= ROW_CACHE).then(|| {
        let mut all = vec![0.0; fit.len() * cols];
        for (f, slot) in fit.iter().zip(all.chunks_exact_mut(cols)) {
            row(*f, slot);
        }
        all
    });
    let fit_row = |k: usize, buf: &mut [f64]| match &cache {
        Some(all) => buf.copy_from_slice(&all[k * cols..(k + 1) * cols]),
        None => row(fit[k], buf),
    };
    // Mean and population standard deviation over the complete frames.
    let mut buf = vec![0.0; cols];
    let mut mean = vec![0.0; cols];
    let mut sq = vec![0.0; cols];
    for k in 0..fit.len() {
        fit_row(k, &mut buf);
        for c in 0..cols {
            mean[c] += buf[c];
        }
    }
    let n = fit.len() as f64;
    mean.iter_mut().for_each(|m| *m /= n);
    for k in 0..fit.len() {
        fit_row(k, &mut buf);
        for c in 0..cols {
            sq[c] += (buf[c] - mean[c]).powi(2);
        }
    }
    let scale: Vec<f64> = (0..cols)
        .map(|c| {
            let sd = (sq[c] / n).sqrt();
            weights[c / 3] / if sd > 0.0 { sd } else { 1.0 }
        })
        .collect();
    // Covariance of the normalised, weighted complete frames, accumulated block by block.
    let mut cov = DMatrix::<f64>::zeros(cols, cols);
    for first in (0..fit.len()).step_by(BLOCK) {
        let block = first..(first + BLOCK).min(fit.len());
        let mut a = DMatrix::<f64>::zeros(cols, block.len());
        for (k, at) in block.enumerate() {
            fit_row(at, &mut buf);
            for c in 0..cols {
                a[(c, k)] = (buf[c] - mean[c]) * scale[c];
            }
        }
        cov += &a * a.transpose();
    }
    cov /= (n - 1.0).max(1.0);
    let mut cov_zero = cov.clone();
    for c in 3 * own..3 * own + 3 {
        cov_zero.row_mut(c).fill(0.0);
        cov_zero.column_mut(c).fill(0.0);
    }
    let (pc, sv) = principal_components(cov);
    let (pc_zero, sv_zero) = principal_components(cov_zero);
    let k = components(&sv, config.min_cumulative_sv).max(components(&sv_zero, config.min_cumulative_sv));
    let pc = pc.columns(0, k);
    let pc_zero = pc_zero.columns(0, k);
    let transform = pc.transpose() * pc_zero;
    // Only `i`'s three output columns are needed: B = PC_N0 T PC_N^T restricted to them.
    let b = pc_zero * transform * pc.rows(3 * own, 3).transpose();
    // `i` in the moving frame (mm) from a row's reconstruction in normalised units.
    let local_of = |x: &Vec3| Vec3::from_fn(|axis, _| mean[3 * own + axis] + x[axis] / scale[3 * own + axis]);
    // Residuals only from frames where every predictor was captured, not pre-filled.
    let neighbours = if std::ptr::eq(source, take) { config.residual_neighbours.min(fit.len()) } else { 0 };
    if neighbours == 0 {
        for &f in missing {
            let to_frame = moving(f);
            row_in(f, &to_frame, &mut buf);
            let mut x = Vec3::zeros();
            for c in (0..cols).filter(|c| c / 3 != own) {
                let z = (buf[c] - mean[c]) * scale[c];
                for axis in 0..3 {
                    x[axis] += z * b[(c, axis)];
                }
            }
            put(out, f, i, to_frame.apply_inverse(&local_of(&x)));
        }
        return;
    }
    // With the residuals of the nearest poses: rows by the block, each block's scores in N0's
    // basis and reconstructions in one matrix product, and its distances to the complete
    // frames' scores in another.
    let mut both = DMatrix::<f64>::zeros(cols, k + 3);
    both.columns_mut(0, k).copy_from(&pc_zero);
    both.columns_mut(k, 3).copy_from(&b);
    let normalise = |buf: &[f64], z: &mut DMatrix<f64>, r: usize| {
        for c in (0..cols).filter(|c| c / 3 != own) {
            z[(r, c)] = (buf[c] - mean[c]) * scale[c];
        }
    };
    let reconstruction = |projected: &DMatrix<f64>, r: usize| {
        local_of(&Vec3::new(projected[(r, k)], projected[(r, k + 1)], projected[(r, k + 2)]))
    };
    // The complete frames' scores (a row each) and the reconstruction's error there, in the
    // moving frame (in sample: the frame helped fit the model, which a held-out frame's error
    // would not share, but with hundreds of frames and `i` weighted 0.02 the difference is
    // small).
    let mut library = DMatrix::<f64>::zeros(fit.len(), k);
    let mut errors = Vec::with_capacity(fit.len());
    for first in (0..fit.len()).step_by(BLOCK) {
        let block = first..(first + BLOCK).min(fit.len());
        let mut z = DMatrix::<f64>::zeros(block.len(), cols);
        let mut captured = Vec::with_capacity(block.len());
        for (r, at) in block.clone().enumerate() {
            fit_row(at, &mut buf);
            normalise(&buf, &mut z, r);
            captured.push(Vec3::new(buf[3 * own], buf[3 * own + 1], buf[3 * own + 2]));
        }
        let projected = z * &both;
        errors.extend(captured.iter().enumerate().map(|(r, c)| c - reconstruction(&projected, r)));
        library.rows_mut(first, block.len()).copy_from(&projected.columns(0, k));
    }
    let library_norms: Vec<f64> = library.row_iter().map(|row| row.norm_squared()).collect();
    let library_t = library.transpose();
    // Rows a block: the distances of a block take at most 8 MB.
    let rows = ((1 << 20) / fit.len()).clamp(1, BLOCK);
    let mut near: Vec<(f64, usize)> = Vec::with_capacity(fit.len());
    for chunk in missing.chunks(rows) {
        let mut z = DMatrix::<f64>::zeros(chunk.len(), cols);
        let mut frames = Vec::with_capacity(chunk.len());
        for (r, &f) in chunk.iter().enumerate() {
            let to_frame = moving(f);
            row_in(f, &to_frame, &mut buf);
            normalise(&buf, &mut z, r);
            frames.push(to_frame);
        }
        let projected = z * &both;
        let scores = projected.columns(0, k);
        let cross = scores * &library_t;
        for (r, (&f, to_frame)) in chunk.iter().zip(&frames).enumerate() {
            let own_norm = scores.row(r).norm_squared();
            // Squared distances in the scores' space; the K nearest weighted by their inverse.
            near.clear();
            near.extend(
                library_norms.iter().enumerate().map(|(at, n)| ((own_norm + n - 2.0 * cross[(r, at)]).max(0.0), at)),
            );
            near.select_nth_unstable_by(neighbours - 1, |p, q| p.0.total_cmp(&q.0));
            let (mut sum, mut total) = (Vec3::zeros(), 0.0);
            for &(squared, at) in &near[..neighbours] {
                let w = 1.0 / (squared + f64::EPSILON);
                sum += errors[at] * w;
                total += w;
            }
            put(out, f, i, to_frame.apply_inverse(&(reconstruction(&projected, r) + sum / total)));
        }
    }
}

/// The map of each frame's coordinates into the frame PCA decomposes them in: the paper's
/// translation by the mean trajectory, or ([`PcaFrame::Aligned`]) the rigid motion that best
/// aligns the predictors (`kept` but its last, weighted by `weights`) with their mean shape
/// over the complete frames `fit`.
fn moving_frame<'a>(
    cx: &Context<'a>,
    kept: &'a [usize],
    weights: &'a [f64],
    fit: &[usize],
    source: &'a Take,
    centre: &'a dyn Fn(usize) -> Vec3,
) -> Box<dyn Fn(usize) -> RigidTransform + 'a> {
    let translated = move |f: usize| RigidTransform { rotation: Rotation3::identity(), translation: -centre(f) };
    let predictors = &kept[..kept.len() - 1];
    if cx.config.frame == PcaFrame::Translated || predictors.len() < MIN_PREDICTORS || fit.is_empty() {
        return Box::new(translated);
    }
    let shape = |f: usize| -> Option<Vec<Vec3>> { predictors.iter().map(|j| source.position_mm(f, *j)).collect() };
    // Mean shape: the first complete frame, then the mean of the complete frames (a sample)
    // aligned to it, twice (generalised Procrustes converges in a few rounds).
    let stride = fit.len().div_ceil(REFERENCE_FRAMES).max(1);
    let Some(mut reference) = shape(fit[0]) else { return Box::new(translated) };
    for _ in 0..2 {
        let mut sum = vec![Vec3::zeros(); predictors.len()];
        let mut count = 0usize;
        for f in fit.iter().step_by(stride) {
            let Some(points) = shape(*f) else { continue };
            let Some(t) = procrustes::align_weighted(&points, &reference, weights) else { continue };
            for (s, p) in sum.iter_mut().zip(&points) {
                *s += t.apply(p);
            }
            count += 1;
        }
        if count == 0 {
            return Box::new(translated);
        }
        reference = sum.into_iter().map(|s| s / count as f64).collect();
    }
    if weighted_spread_mm(&reference, weights) < MIN_ALIGNED_SPREAD_MM {
        return Box::new(translated);
    }
    Box::new(move |f: usize| {
        shape(f)
            .and_then(|points| procrustes::align_weighted(&points, &reference, weights))
            .unwrap_or_else(|| translated(f))
    })
}

/// The square root of the second-largest eigenvalue of the `weights`-weighted scatter of
/// `points` about their weighted centroid (normalised by the total weight), in mm: how far
/// the weighted points are from lying on one line.
fn weighted_spread_mm(points: &[Vec3], weights: &[f64]) -> f64 {
    let total: f64 = weights.iter().sum();
    if !(total > 0.0) {
        return 0.0;
    }
    let centre = points.iter().zip(weights).map(|(p, w)| p * *w).sum::<Vec3>() / total;
    let mut scatter = nalgebra::Matrix3::zeros();
    for (p, w) in points.iter().zip(weights) {
        scatter += (p - centre) * (p - centre).transpose() * (*w / total);
    }
    let mut eigenvalues: Vec<f64> = scatter.symmetric_eigenvalues().iter().copied().collect();
    eigenvalues.sort_by(|a, b| b.total_cmp(a));
    eigenvalues[1].max(0.0).sqrt()
}

/// Eigenvectors of a covariance matrix as columns, largest eigenvalue first, with the square
/// roots of the eigenvalues (the singular values of the data matrix, up to a constant).
fn principal_components(cov: DMatrix<f64>) -> (DMatrix<f64>, Vec<f64>) {
    let eigen = SymmetricEigen::new(cov);
    let mut order: Vec<usize> = (0..eigen.eigenvalues.len()).collect();
    order.sort_by(|a, b| eigen.eigenvalues[*b].total_cmp(&eigen.eigenvalues[*a]));
    let vectors = DMatrix::from_fn(eigen.eigenvectors.nrows(), order.len(), |r, c| eigen.eigenvectors[(r, order[c])]);
    let sv = order.iter().map(|k| eigen.eigenvalues[*k].max(0.0).sqrt()).collect();
    (vectors, sv)
}

/// Smallest number of leading singular values that reach `fraction` of their sum (at least 1).
fn components(sv: &[f64], fraction: f64) -> usize {
    let total: f64 = sv.iter().sum();
    let mut running = 0.0;
    for (k, s) in sv.iter().enumerate() {
        running += s;
        if running >= fraction * total {
            return k + 1;
        }
    }
    sv.len().max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baseline::testing::{check_mask, hide, take_from};

    /// Twelve markers on four segments ~300 mm apart, three markers each within ~50 mm; the
    /// motion is a linear mix of three latent signals (a rank-4 trajectory matrix, drift
    /// included), each marker with its own small share.
    fn low_rank(frames: usize) -> Take {
        take_from(frames, 12, |t, m| {
            let s = t as f64 * 0.02;
            let latent = [s.sin(), (1.7 * s).cos(), (0.6 * s + 1.0).sin()];
            let segment = m / 3;
            let home = Vec3::new(300.0 * segment as f64, 0.0, 1000.0)
                + Vec3::new(30.0 * (m % 3) as f64, 40.0 * ((m + 1) % 2) as f64, 10.0 * m as f64);
            let mut p = home + Vec3::new(3.0 * t as f64, 0.0, 0.0);
            for (l, a) in latent.iter().enumerate() {
                let k = (segment * 3 + l) as f64;
                let own = (m * 3 + l) as f64;
                p += Vec3::new((k * 1.3).sin(), (k * 0.7).cos(), (k * 2.1).sin()) * (60.0 * a)
                    + Vec3::new(own.cos(), own.sin(), 0.5) * (5.0 * a);
            }
            p
        })
    }

    fn mean_error(out: &Filled, truth: &Take, marker: usize, frames: impl Iterator<Item = usize>) -> f64 {
        let errors: Vec<f64> = frames
            .map(|f| (out.take.position_mm(f, marker).unwrap() - truth.position_mm(f, marker).unwrap()).norm())
            .collect();
        errors.iter().sum::<f64>() / errors.len() as f64
    }

    /// A cycle repeated eight times: seven markers move linearly with the phase's sine and
    /// cosine, the eighth also bulges with its square, which no linear mix of them holds.
    fn bulging(frames: usize) -> Take {
        take_from(frames, 8, |t, m| {
            let phase = t as f64 * 0.05;
            let (sin, cos) = phase.sin_cos();
            let k = m as f64;
            let home =
                Vec3::new(40.0 * k, 25.0 * (k * 1.3).sin(), 1000.0 + 15.0 * k) + Vec3::new(2.0 * t as f64, 0.0, 0.0);
            let swing = Vec3::new((k + 0.5).cos(), (k * 0.7).sin(), 0.6) * (50.0 * sin)
                + Vec3::new((k * 1.9).sin(), 0.8, (k + 1.0).cos()) * (35.0 * cos);
            let bulge = if m == 0 { Vec3::new(0.0, 0.0, 40.0 * sin * sin) } else { Vec3::zeros() };
            home + swing + bulge
        })
    }

    /// What the linear model misses where a pose recurs is taken from the frames in that pose:
    /// the bulge, about 13 mm off the linear fill on average, comes back within a fraction of
    /// a millimetre.
    #[test]
    fn the_residuals_of_the_nearest_poses_correct_what_is_not_linear() {
        let truth = bulging(1000);
        let mut holed = truth.clone();
        hide(&mut holed, 0, 300..420);
        let paper = fill_marker(&holed, 0, 0..1000, &PcaConfig::default());
        let corrected = fill_marker(&holed, 0, 0..1000, &PcaConfig { residual_neighbours: 8, ..PcaConfig::default() });
        assert_eq!(check_mask(&holed, &corrected), 120);
        let (before, after) = (mean_error(&paper, &truth, 0, 300..420), mean_error(&corrected, &truth, 0, 300..420));
        assert!(before > 8.0, "the linear fill is {before} mm off");
        assert!(after < before / 4.0, "corrected {after} mm, linear {before} mm");
    }

    #[test]
    fn low_rank_motion_is_recovered() {
        let truth = low_rank(1000);
        let mut holed = truth.clone();
        hide(&mut holed, 0, 300..420);
        hide(&mut holed, 5, (0..50).chain(600..700));
        let out = fill(&holed, &PcaConfig::default());
        assert_eq!(check_mask(&holed, &out), 120 + 150);
        let pca = mean_error(&out, &truth, 0, 300..420);
        let lin = linear::fill(&holed);
        let lin = mean_error(&lin, &truth, 0, 300..420);
        assert!(pca < 1.0 && pca < lin / 20.0, "pca {pca} mm, linear {lin} mm");
        assert!(mean_error(&out, &truth, 5, 0..50) < 1.0);
    }

    /// Marker 0 of [`low_rank`] with a slow wobble of its own, which no component of the
    /// other markers explains: the paper's reconstruction is off by the wobble everywhere.
    fn wobbling(frames: usize) -> Take {
        let mut take = low_rank(frames);
        for f in 0..frames {
            let p = take.position_mm(f, 0).unwrap() + Vec3::new(0.0, 20.0 * (f as f64 * 0.01).sin(), 0.0);
            take.set_position_mm(f, 0, Some(p)).unwrap();
        }
        take
    }

    #[test]
    fn a_gap_meets_its_borders_and_a_long_one_keeps_the_reconstruction_inside() {
        let truth = wobbling(1000);
        let mut holed = truth.clone();
        hide(&mut holed, 0, (150..162).chain(400..700));
        let paper = fill_marker(&holed, 0, 0..1000, &PcaConfig::default());
        let config = PcaConfig { border_fade_s: Some(0.5), ..PcaConfig::default() };
        let met = fill_marker(&holed, 0, 0..1000, &config);
        assert_eq!(check_mask(&holed, &met), 12 + 300);
        let (before, after) = (mean_error(&paper, &truth, 0, 150..162), mean_error(&met, &truth, 0, 150..162));
        assert!(before > 5.0 && after < before / 10.0, "short gap: paper {before} mm, met {after} mm");
        // Next to the long gap's borders the fill carries on from the captured samples...
        for f in [400, 699] {
            let (before, after) = (mean_error(&paper, &truth, 0, f..f + 1), mean_error(&met, &truth, 0, f..f + 1));
            assert!(before > 5.0 && after < 1.0, "frame {f}: paper {before} mm, met {after} mm");
        }
        // ...and 1.5 s (three fade constants) inside it the reconstruction is the paper's.
        let jump = |f: usize, border: usize| {
            (truth.position_mm(border, 0).unwrap() - paper.take.position_mm(f, 0).unwrap()).norm()
        };
        let largest = jump(400, 399).max(jump(699, 700));
        let middle = (met.take.position_mm(550, 0).unwrap() - paper.take.position_mm(550, 0).unwrap()).norm();
        assert!(largest > 5.0 && middle < 0.1 * largest, "middle {middle} mm off the paper's, jumps {largest} mm");
    }

    #[test]
    fn every_marker_gapped_and_never_seen_markers() {
        let truth = low_rank(400);
        let mut holed = truth.clone();
        for m in 0..11 {
            hide(&mut holed, m, (m * 30)..(m * 30 + 20));
        }
        hide(&mut holed, 11, 0..400);
        let out = fill(&holed, &PcaConfig::default());
        assert_eq!(check_mask(&holed, &out), 11 * 20);
        assert!((0..400).all(|f| !out.take.is_valid(f, 11)));
        for m in 0..11 {
            let e = mean_error(&out, &truth, m, (m * 30)..(m * 30 + 20));
            assert!(e < 2.0, "marker {m}: {e} mm");
        }
    }

    #[test]
    fn no_complete_frames_falls_back_to_prefill() {
        // Markers 0 and 1 alternate: no frame shows both, and they are near each other.
        let truth = low_rank(300);
        let mut holed = truth.clone();
        for f in 0..300 {
            hide(&mut holed, (f / 25) % 2, [f]);
        }
        let out = fill(&holed, &PcaConfig::default());
        assert_eq!(check_mask(&holed, &out), 300);
    }

    /// Gaps in every marker, overlapping across markers, none gap-free: the published R2 left no
    /// predictor here and filled each gap with the marker's mean position (68 mm off, linear 53).
    #[test]
    fn overlapping_gaps_in_every_marker() {
        let truth = low_rank(2000);
        let mut holed = truth.clone();
        let mut hidden = Vec::new();
        for m in 0..12 {
            // Three gaps per marker (9-15% missing), staggered so each overlaps others'.
            let gaps = [(37 * m + 20, 5 + m), (150 * m + 100, 120 + 10 * m), (1600 + 23 * m, 60)];
            for (start, len) in gaps {
                hide(&mut holed, m, start..start + len);
                hidden.extend((start..start + len).map(|f| (m, f)));
            }
        }
        hidden.sort_unstable();
        hidden.dedup();
        assert!((0..2000).filter(|f| (0..12).all(|m| holed.is_valid(*f, m))).count() > 100);
        let out = fill(&holed, &PcaConfig::default());
        assert_eq!(check_mask(&holed, &out), hidden.len());
        let lin = linear::fill(&holed);
        let error = |filled: &Filled, (m, f): (usize, usize)| {
            (filled.take.position_mm(f, m).unwrap() - truth.position_mm(f, m).unwrap()).norm()
        };
        let pca = hidden.iter().map(|h| error(&out, *h)).sum::<f64>() / hidden.len() as f64;
        let lin = hidden.iter().map(|h| error(&lin, *h)).sum::<f64>() / hidden.len() as f64;
        assert!(pca < 2.0 && pca < lin / 10.0, "pca {pca} mm, linear {lin} mm");
        let short = (0..12).flat_map(|m| (37 * m + 20..37 * m + 25 + m).map(move |f| (m, f)));
        let worst = short.map(|h| error(&out, h)).fold(0.0, f64::max);
        assert!(worst < 2.0, "short gaps: worst {worst} mm");
    }

    /// The low-rank body of [`low_rank`] turning on the spot a quarter turn and back over
    /// frames 550..750, facing one way the rest of the take.
    fn turning(frames: usize) -> Take {
        let body = low_rank(frames);
        take_from(frames, 12, |t, m| {
            let p = body.position_mm(t, m).unwrap() - Vec3::new(3.0 * t as f64 + 450.0, 20.0, 1000.0);
            let turn = 1.0 - (t as f64 - 650.0).abs() / 100.0;
            let heading = std::f64::consts::FRAC_PI_2 * turn.max(0.0);
            Rotation3::from_axis_angle(&Vec3::z_axis(), heading) * p + Vec3::new(0.0, 0.0, 1000.0)
        })
    }

    /// A marker hidden while the body faces a way the complete frames never show: the aligned
    /// frame carries it with its turning neighbourhood, the paper's frame cannot.
    #[test]
    fn the_aligned_frame_follows_a_turning_body() {
        let truth = turning(1000);
        let mut holed = truth.clone();
        let gap = 600..700;
        hide(&mut holed, 4, gap.clone());
        let aligned = fill(&holed, &PcaConfig::aligned());
        assert_eq!(check_mask(&holed, &aligned), 100);
        let paper = fill(&holed, &PcaConfig::default());
        let (aligned, paper) = (mean_error(&aligned, &truth, 4, gap.clone()), mean_error(&paper, &truth, 4, gap));
        assert!(aligned < paper / 3.0, "aligned {aligned} mm, paper's frame {paper} mm");
    }

    proptest::proptest! {
        /// A rigid body under any motion is constant in the aligned frame, so every gap of any
        /// of its markers is filled exactly, whatever the turns (the paper's frame cannot).
        #[test]
        fn the_aligned_frame_fills_a_rigid_body_exactly(
            spin in proptest::array::uniform3(-0.2f64..0.2),
            drift in proptest::array::uniform3(-20.0f64..20.0),
            marker in 0usize..6,
            start in 1usize..150,
            len in 1usize..45,
        ) {
            let shape = [[0.0, 0.0, 0.0], [120.0, 10.0, 0.0], [0.0, 90.0, 30.0], [40.0, 40.0, 110.0], [-70.0, 20.0, 50.0], [30.0, -80.0, 60.0]];
            let truth = take_from(200, shape.len(), |t, m| {
                let a = t as f64;
                let turn = Rotation3::from_euler_angles(spin[0] * a, spin[1] * a, spin[2] * (0.05 * a).sin() * 10.0);
                Vec3::from(drift) * a + turn * Vec3::from(shape[m])
            });
            let mut holed = truth.clone();
            hide(&mut holed, marker, start..start + len);
            let out = fill(&holed, &PcaConfig::aligned());
            proptest::prop_assert_eq!(check_mask(&holed, &out), len);
            for f in start..start + len {
                let e = (out.take.position_mm(f, marker).unwrap() - truth.position_mm(f, marker).unwrap()).norm();
                proptest::prop_assert!(e < 1e-6, "frame {}: {} mm", f, e);
            }
        }
    }

    /// Two heavy predictors and a light one off their line: the rotation about the line rests
    /// on a weight of 1e-10, too little to fix a frame, so the aligned frame is not used; three
    /// heavy ones in a triangle fix it.
    #[test]
    fn a_frame_resting_on_two_markers_is_not_aligned() {
        let pair = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(100.0, 0.0, 0.0), Vec3::new(0.0, 1500.0, 0.0)];
        let spread = weighted_spread_mm(&pair, &[0.8, 0.2, 1e-10]);
        assert!(spread < MIN_ALIGNED_SPREAD_MM, "{spread} mm");
        let triangle = weighted_spread_mm(&pair, &[0.8, 0.2, 0.1]);
        assert!(triangle > 10.0, "{triangle} mm");
        assert_eq!(weighted_spread_mm(&pair, &[0.0; 3]), 0.0);
    }

    #[test]
    fn component_count() {
        assert_eq!(components(&[9.0, 0.9, 0.1], 0.99), 2);
        assert_eq!(components(&[0.0, 0.0], 0.99), 1);
    }
}
