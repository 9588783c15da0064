//! Pose-matching fill: a missing sample taken from the frames where the marker's neighbours
//! stood most nearly as they stand now (locap's; issue 15, "anything better you find").
//!
//! A run, a gait cycle or a repeated exercise shows the same poses again and again. Where a
//! marker is missing, the frames of the take in which its neighbours were arranged the same
//! way show where it was relative to them, whatever the motion is and however far from a
//! linear mix of other frames it lies (PCA's assumption, [`crate::baseline::pca`]). This is
//! nearest-neighbour regression on the shape of the neighbourhood: the non-parametric
//! counterpart of the PCA fill.
//!
//! # The method
//! For every gap of marker `i` over frames `[s, e)`:
//! 1. *predictors*: `i`'s best [`PoseMatchConfig::predictors`] neighbours (by the ranking
//!    given, [`crate::neighbours`]) captured at every frame of the gap; with fewer than 3 the
//!    gap stays missing;
//! 2. *library*: the frames outside the gap, within [`PoseMatchConfig::library_s`] of it
//!    (30 s), where `i` and every predictor are captured;
//! 3. for each gap frame `t`, the predictors' shape (their pairwise distances, which do not
//!    change as the subject turns or moves) is compared with the shape in every library frame;
//!    of the [`PoseMatchConfig::shortlist`] nearest shapes, each library frame `f` is
//!    aligned onto `t` (Procrustes, [`crate::procrustes`]) and `i`'s position at `f` carried
//!    with it; the [`PoseMatchConfig::matches`] frames that align best are averaged, each
//!    weighted by the inverse square of its alignment RMS (at least [`RMS_FLOOR_MM`]);
//! 4. *borders*: the same estimate at each captured border sample, from the library without
//!    the frames near the border, is off the captured sample by some offset; the offsets are
//!    taken out across the gap, linearly from one border to the other, so the fill meets both
//!    borders (one at the take's edges).
//!
//! Where the take never showed the pose, the nearest shapes are far and the fill is poor: the
//! method can be one of the per-gap choice's candidates ([`crate::auto`], where
//! `AutoConfig::pose_match` is set; off by default since the paper's PCA frame became one),
//! which measures it on trial gaps before using it, and `locap clean --method pose-match`
//! alone for comparison.

use crate::neighbours::{self, Selection};
use crate::{Filled, baseline, procrustes};
use locap_core::gaps::{Gap, gaps_of};
use locap_core::{Take, Vec3};
use rayon::prelude::*;
use std::ops::Range;

/// Smallest alignment RMS (mm) used for a weight: one exact match does not take all the weight.
pub const RMS_FLOOR_MM: f64 = 0.5;

/// Settings of the pose-matching fill.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseMatchConfig {
    /// Neighbours whose shape is matched (at least 3 must be captured throughout a gap).
    pub predictors: usize,
    /// Library frames, nearest in shape, that are aligned for each gap frame.
    pub shortlist: usize,
    /// Best-aligned library frames averaged for each gap frame.
    pub matches: usize,
    /// How the predictors are ranked.
    pub selection: Selection,
    /// How far from a gap (s, each side) its library reaches; `None`: the whole take. Every
    /// gap frame is compared with every library frame, so on a long take the whole take costs
    /// time in proportion to its length for little: the nearest poses in time are the likest
    /// (the same subject, markers not yet slipped).
    pub library_s: Option<f64>,
}

impl Default for PoseMatchConfig {
    /// Six predictors; the four nearest shapes, all averaged: aligning sixteen and keeping the
    /// four best aligned cost more and was no better as a candidate of auto
    /// (docs/benchmarks.md, "Pose matching, an eighth candidate").
    /// The library reaches 30 s each side of a gap, as auto's sub-takes for PCA and pose
    /// matching do.
    fn default() -> PoseMatchConfig {
        PoseMatchConfig {
            predictors: 6,
            shortlist: 4,
            matches: 4,
            selection: Selection::Variance,
            library_s: Some(30.0),
        }
    }
}

/// Fills every gap of every marker of `take` (markers in parallel: each gap reads only the
/// take as captured).
pub fn fill(take: &Take, config: &PoseMatchConfig) -> Filled {
    let ranked = neighbours::rank_scored(take, config.selection);
    let filled: Vec<(usize, Vec<(usize, Vec3)>)> = ranked
        .par_iter()
        .enumerate()
        .map(|(marker, ranked)| {
            let gaps = gaps_of((0..take.frame_count()).map(|f| take.is_valid(f, marker)));
            (marker, gaps.into_iter().flat_map(|gap| fill_gap(take, marker, gap, ranked, config)).collect())
        })
        .collect();
    let mut out = Filled::unchanged(take);
    for (marker, samples) in filled {
        for (t, p) in samples {
            baseline::put(&mut out, t, marker, p);
        }
    }
    out
}

/// Fills the gaps of `marker` within frames `only`, its predictors ranked by `ranked` (as
/// [`neighbours::rank_scored`] gives one marker's list); every other sample stays as
/// captured. What the per-gap choice of [`crate::auto`] needs.
pub fn fill_marker(
    take: &Take,
    marker: usize,
    only: Range<usize>,
    ranked: &[(usize, f64)],
    config: &PoseMatchConfig,
) -> Filled {
    let mut out = Filled::unchanged(take);
    let gaps = gaps_of((0..take.frame_count()).map(|f| take.is_valid(f, marker)));
    for gap in gaps.into_iter().filter(|g| g.start < only.end && only.start < g.end()) {
        for (t, p) in fill_gap(take, marker, gap, ranked, config) {
            baseline::put(&mut out, t, marker, p);
        }
    }
    out
}

/// The fill `(frame, position)` of one gap of `marker`.
fn fill_gap(
    take: &Take,
    marker: usize,
    gap: Gap,
    ranked: &[(usize, f64)],
    config: &PoseMatchConfig,
) -> Vec<(usize, Vec3)> {
    let frames = take.frame_count();
    let predictors: Vec<usize> = ranked
        .iter()
        .map(|(j, _)| *j)
        .filter(|&j| j != marker && (gap.start..gap.end()).all(|f| take.is_valid(f, j)))
        .take(config.predictors)
        .collect();
    let p = predictors.len();
    if p < 3 {
        return Vec::new();
    }
    // The library's reach, at least the borders.
    let reach = config
        .library_s
        .filter(|s| s.is_finite() && *s >= 0.0)
        .map_or(frames, |s| (s * take.frame_rate_hz()).round() as usize)
        .max(1);
    let span = gap.start.saturating_sub(reach)..gap.end().saturating_add(reach).min(frames);
    let library: Vec<usize> =
        span.clone().filter(|&f| take.is_valid(f, marker) && predictors.iter().all(|&j| take.is_valid(f, j))).collect();
    if library.is_empty() {
        return Vec::new();
    }
    // The predictors' positions in every frame of the span, flat (zero where not captured:
    // never read).
    let positions: Vec<Vec3> = span
        .clone()
        .flat_map(|f| predictors.iter().map(move |&j| take.position_mm(f, j).unwrap_or_else(Vec3::zeros)))
        .collect();
    let at = |f: usize| &positions[(f - span.start) * p..(f - span.start + 1) * p];
    let pairs = p * (p - 1) / 2;
    let shape_into = |points: &[Vec3], d: &mut Vec<f64>| {
        d.clear();
        for a in 0..points.len() {
            for b in a + 1..points.len() {
                d.push((points[a] - points[b]).norm());
            }
        }
    };
    let mut shapes = Vec::with_capacity(library.len() * pairs);
    let mut buffer = Vec::with_capacity(pairs);
    for &f in &library {
        shape_into(at(f), &mut buffer);
        shapes.extend_from_slice(&buffer);
    }
    // The estimate at frame `t` from the library frames `allowed` admits.
    let estimate = |t: usize, allowed: &dyn Fn(usize) -> bool| -> Option<Vec3> {
        let now = at(t);
        let mut here = Vec::with_capacity(pairs);
        shape_into(now, &mut here);
        let mut near: Vec<(f64, usize)> = library
            .iter()
            .enumerate()
            .filter(|(_, f)| allowed(**f))
            .map(|(k, _)| {
                let s = &shapes[k * pairs..(k + 1) * pairs];
                (s.iter().zip(&here).map(|(a, b)| (a - b) * (a - b)).sum::<f64>(), k)
            })
            .collect();
        let n = config.shortlist.max(1).min(near.len());
        if n == 0 {
            return None;
        }
        near.select_nth_unstable_by(n - 1, |a, b| a.0.total_cmp(&b.0));
        near.truncate(n);
        let mut aligned: Vec<(f64, Vec3)> = near
            .iter()
            .filter_map(|&(_, k)| {
                let f = library[k];
                let then = at(f);
                let transform = procrustes::align(then, now)?;
                let rms = procrustes::rms_error(&transform, then, now);
                Some((rms, transform.apply(&take.position_mm(f, marker)?)))
            })
            .collect();
        aligned.sort_by(|a, b| a.0.total_cmp(&b.0));
        aligned.truncate(config.matches.max(1));
        let (mut sum, mut weights) = (Vec3::zeros(), 0.0);
        for (rms, p) in &aligned {
            let w = 1.0 / rms.max(RMS_FLOOR_MM).powi(2);
            sum += p * w;
            weights += w;
        }
        (weights > 0.0).then(|| sum / weights)
    };
    // Each border's offset, from the library without the frames as near to it as the gap is
    // long: the border's own neighbourhood in time would match it trivially.
    let offset = |b: usize| -> Option<Vec3> {
        let captured = take.position_mm(b, marker)?;
        let far = |f: usize| f.abs_diff(b) > gap.len;
        Some(captured - estimate(b, &far)?)
    };
    let (before, after) = baseline::borders(gap.start, gap.end(), frames);
    let usable = |b: Option<usize>| b.filter(|&b| predictors.iter().all(|&j| take.is_valid(b, j)));
    let (o_before, o_after) = (usable(before).and_then(offset), usable(after).and_then(offset));
    let outside = |f: usize| !(gap.start..gap.end()).contains(&f);
    let mut samples = Vec::with_capacity(gap.len);
    for t in gap.start..gap.end() {
        let Some(estimated) = estimate(t, &outside) else { continue };
        let correction = match (o_before, o_after) {
            (Some(a), Some(b)) => {
                let w = (t + 1 - gap.start) as f64 / (gap.len + 1) as f64;
                a * (1.0 - w) + b * w
            }
            (Some(a), None) => a,
            (None, Some(b)) => b,
            (None, None) => Vec3::zeros(),
        };
        samples.push((t, estimated + correction));
    }
    samples
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baseline::testing::{check_mask, hide, take_from};

    /// Six markers of a limb that bends back and forth (two rigid parts joined at a hinge),
    /// walking along: the same shapes recur every cycle.
    fn cyclic(frames: usize) -> Take {
        take_from(frames, 6, |f, m| {
            let phase = f as f64 * 0.09;
            let bend = 0.8 * phase.sin();
            let base = Vec3::new(4.0 * f as f64, 0.0, 1000.0);
            let on_upper = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(60.0, 20.0, 0.0), Vec3::new(20.0, -40.0, 30.0)];
            let on_lower = [Vec3::new(0.0, 0.0, -200.0), Vec3::new(50.0, 10.0, -260.0), Vec3::new(-30.0, 30.0, -320.0)];
            if m < 3 {
                base + on_upper[m]
            } else {
                let hinge = nalgebra::Rotation3::from_euler_angles(bend, 0.0, 0.0);
                base + hinge * on_lower[m - 3]
            }
        })
    }

    /// On a motion that repeats, a long gap is filled from the other cycles within a fraction of
    /// a millimetre, where the spline over the gap is centimetres off.
    #[test]
    fn a_recurring_pose_fills_a_long_gap() {
        let truth = cyclic(700);
        let mut holed = truth.clone();
        hide(&mut holed, 4, 300..420);
        let out = fill(&holed, &PoseMatchConfig::default());
        assert_eq!(check_mask(&holed, &out), 120);
        let worst = (300..420)
            .map(|f| (out.take.position_mm(f, 4).unwrap() - truth.position_mm(f, 4).unwrap()).norm())
            .fold(0.0, f64::max);
        assert!(worst < 1.0, "worst {worst} mm");
        let spline = crate::baseline::spline::fill(&holed);
        let spline_worst = (300..420)
            .map(|f| (spline.take.position_mm(f, 4).unwrap() - truth.position_mm(f, 4).unwrap()).norm())
            .fold(0.0, f64::max);
        assert!(spline_worst > 20.0, "spline {spline_worst} mm");
    }

    /// With fewer than three predictors captured throughout the gap, or no frame where all are
    /// captured with the marker, the gap stays missing.
    /// The library reaches `library_s` each side of the gap: 2 s holds several cycles, no
    /// reach at all only the two borders, whose poses are not the gap's.
    #[test]
    fn the_library_reaches_as_far_as_it_is_told() {
        let truth = cyclic(700);
        let mut holed = truth.clone();
        hide(&mut holed, 4, 300..420);
        let worst = |library_s: Option<f64>| {
            let out = fill(&holed, &PoseMatchConfig { library_s, ..PoseMatchConfig::default() });
            assert_eq!(check_mask(&holed, &out), 120);
            (300..420)
                .map(|f| (out.take.position_mm(f, 4).unwrap() - truth.position_mm(f, 4).unwrap()).norm())
                .fold(0.0, f64::max)
        };
        assert!(worst(Some(2.0)) < 1.0, "2 s: {} mm", worst(Some(2.0)));
        assert!(worst(Some(0.0)) > 10.0, "borders only: {} mm", worst(Some(0.0)));
    }

    #[test]
    fn without_predictors_or_library_the_gap_stays() {
        let truth = cyclic(200);
        let mut holed = truth.clone();
        hide(&mut holed, 0, 50..80);
        for m in 1..4 {
            hide(&mut holed, m, 60..61);
        }
        let out = fill(&holed, &PoseMatchConfig::default());
        assert!((50..80).all(|f| !out.take.is_valid(f, 0)));
        let mut holed = truth.clone();
        hide(&mut holed, 0, 0..200);
        let out = fill(&holed, &PoseMatchConfig::default());
        assert_eq!(out.filled_count(), 0);
    }
}
