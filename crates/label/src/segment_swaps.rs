//! Two markers of one segment labeled the other way round, found against the template's
//! shape.
//!
//! Labeling another subject calibrates the template on the take's own labels
//! ([`crate::subject`]): whatever the first pass labeled becomes this subject's shape. Two
//! markers of one segment that the first pass exchanged (a plate marker and the wrist
//! landmark beside it, where the generic shape leaves room for both) stay exchanged through
//! every round, since the calibrated shape then has them exchanged too. The template's own
//! shape does not: with the two labels exchanged back, its segment fits the frame's points
//! by whole tolerances better. So, per segment and frame with at least [`MIN_CHECKED`] of
//! its markers labeled, every exchange of two of them is scored against the template's
//! shape (rigid fit, residuals in the markers' tolerances); a frame votes for the exchange
//! that lowers the cost by at least [`MIN_GAIN`] and halves it, and the exchange is made
//! where the votes within [`VOTE_WINDOW_S`] say so, so that one noisy frame neither makes
//! nor blocks it.
//!
//! A frame also votes for an exchange that gains less than [`MIN_GAIN`] (at least
//! [`MIN_MIRROR_GAIN`]) where the labels fit the *mirror image* of the shape at half the cost
//! of the shape itself and the exchange fits the shape at least as well as that: a rigid
//! segment cannot turn into its mirror image, two of its markers exchanged can. That is what a generic model's flatter foot
//! leaves (four landmarks that fit it within tolerances either way; `docs/labeling.md`).
//! A plate's markers lie in a plane, which fits its mirror image as well as itself, so the
//! rule leaves plates to the gain.

use crate::body::Body;
use crate::{Labels, PointFrames};
use locap_clean::procrustes::{RigidTransform, align_weighted_and_mirrored};
use locap_core::Vec3;

/// A frame's segment is checked when at least this many of its markers are labeled: three
/// points fit any triangle of about the right size, exchanged or not.
pub const MIN_CHECKED: usize = 4;

/// An exchange must lower the segment's cost (squared residuals in tolerances) by at least
/// this: two markers' worth.
pub const MIN_GAIN: f64 = 2.0;

/// An exchange that the mirror image calls for must still lower the cost by this much (half
/// a marker's worth): a nearly square plate turned over its diagonal fits itself and its
/// mirror image within noise, and noise must not exchange its labels.
pub const MIN_MIRROR_GAIN: f64 = 0.5;

/// Votes are counted over this many seconds on each side of a frame.
pub const VOTE_WINDOW_S: f64 = 0.25;

/// Exchanges, in `labels` of `frames`, the labels of two markers of a segment of `body` (the
/// template's) where its shape says they are exchanged (module docs). Returns how many
/// frames changed.
pub fn unswap_segments(labels: &mut Labels, frames: &PointFrames, body: &Body) -> usize {
    let n = labels.frame_count().min(frames.frame_count());
    let window = (VOTE_WINDOW_S * frames.frame_rate_hz()).round().max(1.0) as usize;
    let mut changed = vec![false; n];
    for seg in &body.segments {
        let k = seg.markers.len();
        if k < MIN_CHECKED {
            continue;
        }
        let pairs: Vec<(usize, usize)> = (0..k).flat_map(|a| (a + 1..k).map(move |b| (a, b))).collect();
        // Per frame: the pair this frame votes to exchange, or None (keep), or not checked.
        let votes: Vec<Option<Option<usize>>> = (0..n).map(|f| vote(labels, frames, seg, f, &pairs)).collect();
        // Checked frames up to each frame (prefix sums), for the windows' tallies.
        let checked = prefix(votes.iter().map(Option::is_some));
        for (p, &(a, b)) in pairs.iter().enumerate() {
            if !votes.contains(&Some(Some(p))) {
                continue;
            }
            let yes = prefix(votes.iter().map(|v| *v == Some(Some(p))));
            for (f, changed) in changed.iter_mut().enumerate() {
                let (lo, hi) = (f.saturating_sub(window), (f + window + 1).min(n));
                let for_it = yes[hi] - yes[lo];
                let against = checked[hi] - checked[lo] - for_it;
                if for_it > against {
                    labels.exchange(f, seg.markers[a], seg.markers[b]);
                    *changed = true;
                }
            }
        }
    }
    changed.iter().filter(|&&c| c).count()
}

/// `out[i]`: how many of the first `i` flags are set.
fn prefix(flags: impl Iterator<Item = bool>) -> Vec<usize> {
    std::iter::once(0)
        .chain(flags.scan(0, |count, flag| {
            *count += usize::from(flag);
            Some(*count)
        }))
        .collect()
}

/// Frame `f`'s vote for segment `seg`: `None` when too few of its markers are labeled, else
/// the pair (index into `pairs`) whose exchange fits the shape best, if it gains enough.
fn vote(
    labels: &Labels,
    frames: &PointFrames,
    seg: &crate::body::Segment,
    f: usize,
    pairs: &[(usize, usize)],
) -> Option<Option<usize>> {
    let points = frames.frame(f);
    let at: Vec<Option<Vec3>> = seg.markers.iter().map(|&i| labels.get(f, i).map(|p| points[p])).collect();
    let labeled: Vec<usize> = (0..at.len()).filter(|&m| at[m].is_some()).collect();
    if labeled.len() < MIN_CHECKED {
        return None;
    }
    // Cost of the shape, and of its mirror image, with marker m's label given by `label_of(m)`.
    let costs = |label_of: &dyn Fn(usize) -> usize| -> Option<[f64; 2]> {
        let (from, to): (Vec<Vec3>, Vec<Vec3>) =
            labeled.iter().map(|&m| (seg.local_mm[m], at[label_of(m)].unwrap_or_default())).unzip();
        let fits = align_weighted_and_mirrored(&from, &to, &vec![1.0; from.len()])?;
        let mirror = |v: &Vec3| Vec3::new(v.x, v.y, -v.z);
        let cost = |t: &RigidTransform, mirrored: bool| -> f64 {
            labeled
                .iter()
                .zip(from.iter().zip(&to))
                .map(|(&m, (l, q))| {
                    let l = if mirrored { mirror(l) } else { *l };
                    ((t.apply(&l) - q).norm() / seg.tolerance_mm[m]).powi(2)
                })
                .sum()
        };
        Some([cost(&fits[0], false), cost(&fits[1], true)])
    };
    let cost = |label_of: &dyn Fn(usize) -> usize| costs(label_of).map(|[c, _]| c);
    let [own, own_mirrored] = costs(&|m| m)?;
    let mut best: Option<(f64, usize)> = None;
    for (p, &(a, b)) in pairs.iter().enumerate() {
        if at[a].is_none() || at[b].is_none() {
            continue;
        }
        let swap = |m: usize| {
            if m == a {
                b
            } else if m == b {
                a
            } else {
                m
            }
        };
        let Some(c) = cost(&swap) else { continue };
        if best.is_none_or(|(x, _)| c < x) {
            best = Some((c, p));
        }
    }
    // A rigid segment cannot turn into its mirror image: labels that fit the mirrored shape
    // by half the cost of the shape itself have two markers exchanged, whatever the gain in
    // markers' worth (a foot's four landmarks, which a generic model's flatter foot fits
    // within tolerances either way).
    let mirrored = own_mirrored <= own / 2.0;
    Some(
        best.filter(|&(c, _)| {
            c <= own / 2.0 && (own - c >= MIN_GAIN || (mirrored && c <= own_mirrored && own - c >= MIN_MIRROR_GAIN))
        })
        .map(|(_, p)| p),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Template;
    use crate::body::tests::hinge_take;

    /// The hinge take's true labels: each marker's point in every frame.
    fn truth(frames: &PointFrames, markers: usize) -> Labels {
        let per_frame: Vec<Vec<Option<usize>>> = (0..frames.frame_count())
            .map(|f| (0..markers).map(|m| frames.columns(f).iter().position(|&c| c as usize == m)).collect())
            .collect();
        Labels::from_frames(markers, &per_frame)
    }

    #[test]
    fn exchanged_labels_are_exchanged_back_and_right_ones_kept() {
        let take = hinge_take(200);
        let template = Template::from_take(&take, None).unwrap();
        let body = template.body().unwrap();
        let frames = PointFrames::from_take(&take);
        let right = truth(&frames, take.marker_count());
        let mut labels = right.clone();
        assert_eq!(unswap_segments(&mut labels, &frames, body), 0);
        assert_eq!(labels, right);
        // Two markers of the upper segment exchanged over half the take, and one stray frame
        // of the lower one (a single frame against its window keeps its labels).
        for f in 40..140 {
            labels.exchange(f, 0, 1);
        }
        labels.exchange(170, 4, 6);
        let changed = unswap_segments(&mut labels, &frames, body);
        assert_eq!(changed, 100);
        for f in 0..200 {
            for m in 0..take.marker_count() {
                let expected = if f == 170 && (m == 4 || m == 6) { right.get(f, 10 - m) } else { right.get(f, m) };
                assert_eq!(labels.get(f, m), expected, "frame {f} marker {m}");
            }
        }
    }

    #[test]
    fn labels_that_make_a_rigid_segment_its_mirror_image_are_exchanged_back() {
        // Four markers with a mirror plane (x = 0) that exchanges the first two: with those two
        // labels exchanged the points are the shape's mirror image. Tolerances so wide that
        // the exchange gains less than MIN_GAIN in markers' worth, more than MIN_MIRROR_GAIN (a
        // generic model's foot): the test fails without the mirror-image rule.
        let shape = [[40.0, 0.0, 0.0], [-40.0, 0.0, 0.0], [0.0, 60.0, 10.0], [0.0, -30.0, 80.0]].map(Vec3::from);
        let centroid = shape.iter().sum::<Vec3>() / 4.0;
        let names: Vec<_> = (0..4).map(|i| locap_core::MarkerName::parse(&format!("F{i}"))).collect();
        let mut samples = Vec::new();
        for f in 0..50 {
            let turn = nalgebra::Rotation3::from_euler_angles(0.02 * f as f64, 0.5, 0.01 * f as f64);
            samples.extend(shape.iter().map(|p| Some(Vec3::new(3.0 * f as f64, 0.0, 900.0) + turn * p)));
        }
        let take = locap_core::Take::from_samples(names, &samples, 100.0).unwrap();
        let segment = crate::body::Segment {
            markers: vec![0, 1, 2, 3],
            local_mm: shape.iter().map(|p| p - centroid).collect(),
            tolerance_mm: vec![90.0; 4],
        };
        let body = Body {
            segments: vec![segment],
            joints: Vec::new(),
            attached: Vec::new(),
            member: (0..4).map(|k| Some((0, k))).collect(),
        };
        let frames = PointFrames::from_take(&take);
        let right = truth(&frames, 4);
        let mut labels = right.clone();
        assert_eq!(unswap_segments(&mut labels, &frames, &body), 0);
        for f in 0..50 {
            labels.exchange(f, 0, 1);
        }
        assert_eq!(unswap_segments(&mut labels, &frames, &body), 50);
        assert_eq!(labels, right);
    }
}
