//! Neighbour markers by locality (LocalMoCap section 3, "neighbor markers").
//!
//! For marker `i`, every other marker is ranked by how much its distance to `i` varies over
//! the frames where both are visible: markers on the same body segment keep nearly constant
//! distances and predict each other. The paper ranks by variance; ranking by mean distance is
//! offered to measure that choice.

use locap_core::Take;
use serde::{Deserialize, Serialize};

/// How neighbours are ranked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Selection {
    /// Lowest variance of the pairwise distance (the paper's choice).
    #[default]
    Variance,
    /// Lowest mean distance (nearest markers).
    MeanDistance,
}

/// Most frames sampled for the distance statistics.
const MAX_FRAMES: usize = 12_000;

/// Pairs seen together in fewer frames than this are ranked last: their statistics mean little.
const MIN_SHARED_FRAMES: u32 = 10;

/// For every marker, all other markers, best neighbour first.
///
/// Pairs never (or rarely) visible together come last, ordered by index. Cost: one pass over
/// the take per pair, `O(T M^2)`.
pub fn rank(take: &Take, selection: Selection) -> Vec<Vec<usize>> {
    rank_scored(take, selection).into_iter().map(|list| list.into_iter().map(|(j, _)| j).collect()).collect()
}

/// Like [`rank`], with each neighbour's variance of the distance in mm^2 (`f64::INFINITY` for
/// pairs seen together too rarely), whatever the ranking.
pub fn rank_scored(take: &Take, selection: Selection) -> Vec<Vec<(usize, f64)>> {
    let m = take.marker_count();
    let stats = distance_statistics(take, None);
    (0..m).map(|i| ordered(i, m, selection, |j| stats[i.min(j) * m + i.max(j)])).collect()
}

/// [`rank_scored`]`(take, selection)[marker]`, computed for that marker alone (`O(T M)`): what
/// a fill that works on one marker's neighbourhood needs.
pub fn rank_scored_of(take: &Take, marker: usize, selection: Selection) -> Vec<(usize, f64)> {
    let m = take.marker_count();
    if marker >= m {
        return Vec::new();
    }
    let stats = distance_statistics(take, Some(marker));
    ordered(marker, m, selection, |j| stats[marker.min(j) * m + marker.max(j)])
}

/// Running statistics of one marker pair's distance: frames seen together, mean, and the sum
/// of squared deviations (Welford).
#[derive(Debug, Clone, Copy, Default)]
struct PairStatistics {
    count: u32,
    mean: f64,
    m2: f64,
}

/// Distance statistics of every marker pair (of the pairs with `only` where given), stored at
/// `min(i, j) * M + max(i, j)`.
fn distance_statistics(take: &Take, only: Option<usize>) -> Vec<PairStatistics> {
    let m = take.marker_count();
    let t = take.frame_count();
    let mut stats = vec![PairStatistics::default(); m * m];
    let mut frame = Vec::with_capacity(m);
    // Distance statistics settle long before every frame is seen: past MAX_FRAMES, evenly
    // spaced frames are used (a 10-minute take at 120 Hz: every 6th), which keeps ranking
    // from dominating the cost of a fill.
    let stride = t.div_ceil(MAX_FRAMES).max(1);
    for f in (0..t).step_by(stride) {
        frame.clear();
        frame.extend((0..m).map(|k| take.position_mm(f, k)));
        let firsts = only.map_or(0..m, |i| i..i + 1);
        for i in firsts {
            let Some(pi) = frame[i] else { continue };
            // Every pair once: the markers after `i` when every pair is wanted, else all but `i`.
            for (j, pj) in frame.iter().enumerate().skip(if only.is_none() { i + 1 } else { 0 }) {
                let Some(pj) = *pj else { continue };
                if j == i {
                    continue;
                }
                let d = (pi - pj).norm();
                let s = &mut stats[i.min(j) * m + i.max(j)];
                s.count += 1;
                let delta = d - s.mean;
                s.mean += delta / s.count as f64;
                s.m2 += delta * (d - s.mean);
            }
        }
    }
    stats
}

/// Every marker but `i` of `m`, best neighbour first by `selection`, with its variance.
fn ordered(i: usize, m: usize, selection: Selection, pair: impl Fn(usize) -> PairStatistics) -> Vec<(usize, f64)> {
    let mut others: Vec<(bool, f64, usize, f64)> = (0..m)
        .filter(|j| *j != i)
        .map(|j| {
            let s = pair(j);
            let reliable = s.count >= MIN_SHARED_FRAMES;
            let variance = if reliable { s.m2 / s.count as f64 } else { f64::INFINITY };
            let score = match selection {
                Selection::Variance => variance,
                Selection::MeanDistance => s.mean,
            };
            // `false` sorts first: reliable pairs before unreliable ones.
            (!reliable, if reliable { score } else { 0.0 }, j, variance)
        })
        .collect();
    others.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2)));
    others.into_iter().map(|(_, _, j, variance)| (j, variance)).collect()
}

/// Marker pairs joined by an edge when drawing a take: each marker with its `per_marker`
/// most stable neighbours ([`rank_scored`] by variance; pairs never seen together left out),
/// each pair once as `[lower index, higher index]`, sorted. Empty for `per_marker == 0`.
pub fn stable_edges(take: &Take, per_marker: usize) -> Vec<[usize; 2]> {
    if per_marker == 0 || take.marker_count() < 2 {
        return Vec::new();
    }
    let ranked = rank_scored(take, Selection::Variance);
    let mut edges: Vec<[usize; 2]> = ranked
        .iter()
        .enumerate()
        .flat_map(|(i, list)| {
            list.iter().filter(|(_, v)| v.is_finite()).take(per_marker).map(move |&(j, _)| [i.min(j), i.max(j)])
        })
        .collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{MarkerName, Vec3};

    /// Markers 0-2 ride one rigid segment, marker 3 swings independently, marker 4 is close to
    /// marker 0 but moves on its own.
    fn take() -> Take {
        let names = (0..5).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let mut samples = Vec::new();
        for f in 0..100 {
            let a = f as f64 * 0.05;
            let base = Vec3::new(10.0 * f as f64, 0.0, 0.0);
            let rot = nalgebra::Rotation3::from_euler_angles(0.0, 0.0, a);
            samples.push(Some(base + rot * Vec3::new(0.0, 0.0, 0.0)));
            samples.push(Some(base + rot * Vec3::new(200.0, 0.0, 0.0)));
            samples.push(Some(base + rot * Vec3::new(0.0, 150.0, 0.0)));
            samples.push(Some(base + Vec3::new(300.0 * a.sin(), 500.0, 0.0)));
            samples.push(Some(base + Vec3::new(20.0 + 15.0 * (3.0 * a).sin(), 0.0, 0.0)));
        }
        Take::from_samples(names, &samples, 100.0).unwrap()
    }

    #[test]
    fn rigid_partners_rank_first_by_variance() {
        let ranked = rank(&take(), Selection::Variance);
        assert_eq!(&ranked[0][..2], &[1, 2]);
        assert_eq!(ranked[0].len(), 4);
    }

    #[test]
    fn one_marker_ranks_as_in_the_whole_ranking() {
        // With a sample missing so that pairs differ in their counts.
        let mut holed = take();
        holed.set_position_mm(7, 3, None).unwrap();
        for selection in [Selection::Variance, Selection::MeanDistance] {
            let all = rank_scored(&holed, selection);
            for (i, row) in all.iter().enumerate() {
                assert_eq!(&rank_scored_of(&holed, i, selection), row, "marker {i}");
            }
        }
        assert!(rank_scored_of(&holed, 5, Selection::Variance).is_empty());
    }

    #[test]
    fn nearest_ranks_first_by_mean_distance() {
        let ranked = rank(&take(), Selection::MeanDistance);
        assert_eq!(ranked[0][0], 4);
    }

    #[test]
    fn stable_edges_join_rigid_partners_once() {
        let edges = stable_edges(&take(), 1);
        // Markers 0-2 are rigid: each one's steadiest neighbour is another of them.
        assert!(edges.contains(&[0, 1]) || edges.contains(&[0, 2]), "{edges:?}");
        assert!(edges.windows(2).all(|w| w[0] < w[1]), "sorted, each pair once: {edges:?}");
        assert!(edges.iter().all(|[a, b]| a < b));
        assert!(edges.len() <= 5);
        assert!(stable_edges(&take(), 0).is_empty());
    }
}
