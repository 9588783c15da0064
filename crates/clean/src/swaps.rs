//! Swapped labels: two markers that exchange names from one frame on (a labeling error, common
//! when markers pass close to each other).
//!
//! At frame `t`, each marker's position is predicted from its last two samples (constant
//! velocity). A pair `(a, b)` has swapped when both markers jump away from their predictions
//! (by more than [`SwapConfig::min_jump_mm`]) and the crossed assignment (`a` where `b` was
//! predicted, `b` where `a` was) explains the frame at least four times better than the
//! straight one. The swap lasts until the same test fires again for the pair (they swap
//! back), or to the end of the take. Cost: `O(T M^2)` distance checks, on frames where at
//! least two markers jumped.

use locap_core::{Take, Vec3};
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// Settings of swap detection.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SwapConfig {
    /// Smallest departure from the prediction that counts as a jump, mm.
    pub min_jump_mm: f64,
    /// How much better (ratio) the crossed assignment must explain the frame.
    pub ratio: f64,
}

impl Default for SwapConfig {
    fn default() -> SwapConfig {
        SwapConfig { min_jump_mm: 20.0, ratio: 4.0 }
    }
}

/// Two markers whose labels are exchanged over `frames`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Swap {
    /// First marker index.
    pub a: usize,
    /// Second marker index.
    pub b: usize,
    /// Frames over which their samples are exchanged (0-based, end excluded).
    pub frames: Range<usize>,
}

fn predict(take: &Take, marker: usize, t: usize) -> Option<Vec3> {
    let p1 = take.position_mm(t.checked_sub(1)?, marker)?;
    let p2 = take.position_mm(t.checked_sub(2)?, marker)?;
    Some(2.0 * p1 - p2)
}

/// Frames at which the pair `(a, b)` trades places.
fn crossings(take: &Take, config: &SwapConfig) -> Vec<(usize, usize, usize)> {
    let m = take.marker_count();
    let mut out = Vec::new();
    let labeled: Vec<bool> = take.markers().iter().map(|n| !n.is_unlabeled()).collect();
    for t in 2..take.frame_count() {
        // Markers that jumped away from their prediction at t.
        let jumped: Vec<(usize, Vec3, Vec3)> = (0..m)
            .filter(|k| labeled[*k])
            .filter_map(|k| {
                let (pred, now) = (predict(take, k, t)?, take.position_mm(t, k)?);
                ((now - pred).norm() > config.min_jump_mm).then_some((k, pred, now))
            })
            .collect();
        for (x, &(a, pred_a, now_a)) in jumped.iter().enumerate() {
            for &(b, pred_b, now_b) in &jumped[x + 1..] {
                let straight = (now_a - pred_a).norm() + (now_b - pred_b).norm();
                let crossed = (now_b - pred_a).norm() + (now_a - pred_b).norm();
                if crossed * config.ratio < straight {
                    out.push((t, a, b));
                }
            }
        }
    }
    out
}

/// Finds swapped pairs (see the module doc).
pub fn detect(take: &Take, config: &SwapConfig) -> Vec<Swap> {
    let mut open: Vec<(usize, usize, usize)> = Vec::new(); // (a, b, start)
    let mut out = Vec::new();
    for (t, a, b) in crossings(take, config) {
        match open.iter().position(|(x, y, _)| (*x, *y) == (a, b)) {
            Some(i) => {
                let (_, _, start) = open.remove(i);
                out.push(Swap { a, b, frames: start..t });
            }
            None => open.push((a, b, t)),
        }
    }
    for (a, b, start) in open {
        out.push(Swap { a, b, frames: start..take.frame_count() });
    }
    out.sort_by_key(|s| (s.frames.start, s.a, s.b));
    out
}

/// Exchanges the samples of each swapped pair back over its frames.
pub fn unswap(take: &mut Take, swaps: &[Swap]) {
    for s in swaps {
        for f in s.frames.clone() {
            let (pa, qa) = (take.position_mm(f, s.a), take.quality(f, s.a));
            let (pb, qb) = (take.position_mm(f, s.b), take.quality(f, s.b));
            // Both positions came from the take, so they are finite and setting cannot fail.
            let _ = take.set_position_mm(f, s.a, pb);
            let _ = take.set_position_mm(f, s.b, pa);
            take.set_quality(f, s.a, qb);
            take.set_quality(f, s.b, qa);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::MarkerName;

    fn take() -> Take {
        let names = (0..4).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let mut samples = Vec::new();
        for f in 0..300 {
            let s = f as f64 / 120.0;
            for k in 0..4 {
                samples.push(Some(Vec3::new(100.0 * k as f64 + 50.0 * s.sin(), 30.0 * s, 900.0 + 80.0 * k as f64)));
            }
        }
        Take::from_samples(names, &samples, 120.0).unwrap()
    }

    #[test]
    fn a_swap_is_found_and_undone() {
        let truth = take();
        let mut swapped = truth.clone();
        unswap(&mut swapped, &[Swap { a: 1, b: 2, frames: 100..180 }]);
        let found = detect(&swapped, &SwapConfig::default());
        assert_eq!(found, vec![Swap { a: 1, b: 2, frames: 100..180 }]);
        unswap(&mut swapped, &found);
        assert_eq!(swapped, truth);
        assert!(detect(&truth, &SwapConfig::default()).is_empty());
    }

    #[test]
    fn a_swap_to_the_end_stays_open() {
        let mut swapped = take();
        unswap(&mut swapped, &[Swap { a: 0, b: 3, frames: 250..300 }]);
        assert_eq!(detect(&swapped, &SwapConfig::default()), vec![Swap { a: 0, b: 3, frames: 250..300 }]);
    }
}
