//! The baselines of the labeling paper's comparison (section 5.1), run in the same frame loop
//! as soft graph matching so that only the matching differs:
//! - `Unary` (UGM, the paper's "original unary graph matching"): the Kalman prediction and
//!   the Hungarian assignment on the point cost alone (squared distance to the prediction,
//!   "missing" at the gate's squared radius);
//! - `ClosestPoint` (CP): every marker takes the nearest point to its last measured
//!   position, nearest pairs first.
//!
//! Neither checks edges nor estimates missing markers: a marker they lose coasts on its
//! Kalman track.

use super::Labeler;
use locap_core::Vec3;

impl Labeler {
    /// UGM's "missing" cost for marker `m`: a point outside the gate is never taken.
    pub(super) fn unary_missing_cost(&self, m: usize) -> f64 {
        self.gate_mm[m] * self.gate_mm[m]
    }

    /// UGM's cost of candidate `c`: the squared distance to the prediction (Eq. 2 alone).
    pub(super) fn unary_cost(&self, c: usize) -> f64 {
        self.candidate_cost[c]
    }

    pub(super) fn assign_closest(&mut self, points: &[Vec3]) {
        self.greedy.clear();
        for m in 0..self.markers {
            for c in self.candidates(m) {
                self.greedy.push((self.candidate_cost[c], m as u32, self.candidate_point[c]));
            }
        }
        self.greedy.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        self.point_used.clear();
        self.point_used.resize(points.len(), false);
        self.labels.fill(None);
        for &(_, m, p) in &self.greedy {
            if self.labels[m as usize].is_none() && !self.point_used[p as usize] {
                self.labels[m as usize] = Some(p);
                self.point_used[p as usize] = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::Method;
    use super::super::scenario::{limb, run};
    use locap_core::Vec3;

    #[test]
    fn crossing_markers_keep_their_labels() {
        // Two free markers pass within 8 mm of each other at 1.5 m/s, at 30 Hz.
        let rate = 30.0;
        let frame = |f: usize| {
            let t = f as f64 / rate;
            let mut cloud: Vec<(Option<usize>, Vec3)> =
                limb(t).into_iter().enumerate().take(3).map(|(m, p)| (Some(m), p)).collect();
            cloud.push((Some(3), Vec3::new(-900.0 + 1500.0 * t, 0.0, 4.0)));
            cloud.push((Some(4), Vec3::new(900.0 - 1500.0 * t, 0.0, -4.0)));
            cloud
        };
        assert_eq!(run(Method::Unary, rate, 40, frame), 0);
        assert_eq!(run(Method::SoftGraph, rate, 40, frame), 0);
    }
}
