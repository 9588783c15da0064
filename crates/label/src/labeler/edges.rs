//! Soft graph matching on the rigid edges (labeling paper section 3, Eq. 1-5): the
//! local-geometry cost of a candidate, the soft assignment cost, the edge check after the
//! assignment and the edge lengths that follow the data.
//!
//! A marker's edges join it to the template neighbours whose distance to it stays nearly
//! fixed (`max_edge_std_mm`). Choices where the paper is silent, in millimetre units
//! throughout (`w_a = 1e4` then weighs a 1% direction change like a 1 mm length change):
//! - the model graph uses the *predicted* positions (direction term included), so fast limbs
//!   at low frame rates are compared with where they are going, not where they were;
//! - costs are normalised so they mean the same at every frame rate: the point cost is the
//!   squared distance in units of the prediction's variance (Mahalanobis; at 30 fps the
//!   prediction is poorer, so distance counts less and geometry more), capped at what a
//!   point at the gate's edge costs, and an edge cost is in units of the edge's squared
//!   tolerance (its spread over the template plus `EDGE_NOISE_MM`). The paper's raw
//!   millimetre costs let near ghosts win at low frame rates; its `w_p` and `w_a` are kept;
//! - `w_max = w_p * gate_sigmas^2 + (1 - w_p) * geometry_limit`: any point in the gate with
//!   plausible local geometry is accepted, and a ghost in the gate that breaks the edges is
//!   refused;
//! - *truncated edge costs* (`edge_outlier_cost`): an edge cost is the cheapest match among
//!   the neighbour's candidates, and a neighbour that is occluded still has candidates
//!   (other markers' points in its gate) that all break the edge. Untruncated, one occluded
//!   neighbour vetoes a marker sitting right at its prediction. An edge with no candidate
//!   at all counts as truncated too;
//! - *an edge check after the assignment* (`edge_check_limit`): a label whose point breaks
//!   every edge to the labeled rigid neighbours is dropped, judged on the edge lengths for a
//!   marker re-acquired this frame and on the change of the lengths since the previous frame
//!   for a tracked one (a switch to a ghost changes them at once; a marker slipping on the
//!   skin, or a source trajectory that drifts off the foot, slowly). Markers farthest from
//!   their predictions are judged first, and a dropped label stops counting as a neighbour,
//!   so a marker whose neighbours switched to ghosts keeps its own.
//!
//! What each choice is worth is measured in `docs/labeling.md`.

use super::Labeler;
use locap_core::Vec3;

/// Reconstruction noise added to every edge's tolerance (mm).
pub(super) const EDGE_NOISE_MM: f64 = 3.0;

impl Labeler {
    /// `w_max` of Eq. 5 for soft graph matching: what a point at the gate's edge with
    /// local geometry at `geometry_limit` costs.
    pub(super) fn soft_missing_cost(&self) -> f64 {
        let wp = self.config.point_weight;
        let sigmas2 = self.config.gate_sigmas * self.config.gate_sigmas;
        wp * sigmas2 + (1.0 - wp) * self.config.geometry_limit
    }

    /// `w_ij` of Eq. 5 for marker `m` and its candidate `c`: Eq. 1 with the point cost in
    /// units of the prediction's (adapted) variance, at most what the gate's edge costs, so
    /// that inside the gate good local geometry can outweigh a sudden move.
    pub(super) fn soft_cost(&self, m: usize, c: usize, points: &[Vec3]) -> f64 {
        let wp = self.config.point_weight;
        let sigmas2 = self.config.gate_sigmas * self.config.gate_sigmas;
        let j = self.candidate_point[c] as usize;
        wp * (self.candidate_cost[c] / self.point_variance_mm2[m]).min(sigmas2)
            + (1.0 - wp) * self.local_geometry_cost(m, j, points)
    }

    /// Eq. 3-4: mean over the rigid edges of marker `i` of the cheapest edge match when `i`
    /// takes point `j`.
    fn local_geometry_cost(&self, i: usize, j: usize, points: &[Vec3]) -> f64 {
        let mut sum = 0.0;
        let edges = self.neighbour_count[i].min(self.config.edges);
        for n in 0..edges {
            let k = self.neighbour[i * self.ranked + n] as usize;
            let length = self.edge_length_mm[i * self.ranked + n];
            let model = self.predicted_mm[i] - self.predicted_mm[k];
            let model_norm = model.norm();
            let mut best = f64::INFINITY;
            for c in self.candidates(k) {
                let u = self.candidate_point[c] as usize;
                if u == j {
                    continue;
                }
                let data = points[j] - points[u];
                let data_norm = data.norm();
                let cosine =
                    if model_norm > 0.0 && data_norm > 0.0 { model.dot(&data) / (model_norm * data_norm) } else { 1.0 };
                let cost = ((data_norm - length).powi(2) + self.config.angle_weight * (1.0 - cosine).powi(2))
                    / self.edge_tolerance_mm2[i * self.ranked + n];
                best = best.min(cost);
            }
            // Truncated: a neighbour that is missing (no candidate, or only other markers'
            // points) costs the same as one that disagrees, and no single edge vetoes.
            sum += best.min(self.config.edge_outlier_cost);
        }
        if edges == 0 { 0.0 } else { sum / edges as f64 }
    }

    /// Drops labels whose point breaks every edge to the labeled rigid neighbours: with the
    /// neighbours where they are, the point is a ghost or another marker's. A marker
    /// re-acquired this frame is judged against its edge lengths; a marker tracked from the
    /// previous frame against how its edges changed since then (a switch to a ghost changes
    /// them at once; a marker slipping on the skin, slowly). Markers are judged one after
    /// another, those farthest from their predictions first, and a dropped label no longer
    /// counts as a neighbour: a marker whose neighbours switched to ghosts keeps its label.
    pub(super) fn check_edges(&mut self, points: &[Vec3]) {
        self.greedy.clear();
        for m in 0..self.markers {
            if let Some(p) = self.labels[m] {
                let surprise = (points[p as usize] - self.predicted_mm[m]).norm_squared() / self.point_variance_mm2[m];
                self.greedy.push((-surprise, m as u32, p));
            }
        }
        self.greedy.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        for k in 0..self.greedy.len() {
            let (_, m, p) = self.greedy[k];
            if self.breaks_every_edge(m as usize, &points[p as usize], points) {
                self.labels[m as usize] = None;
            }
        }
    }

    /// Whether marker `m` at `at_mm` breaks every edge to its labeled rigid neighbours by
    /// more than `edge_check_limit` squared tolerances (false when none can be judged): its
    /// length when `m` was not labeled in the previous frame, else its change since then
    /// (edges whose neighbour was not labeled then are not judged).
    pub(super) fn breaks_every_edge(&self, m: usize, at_mm: &Vec3, points: &[Vec3]) -> bool {
        let mut judged = false;
        for e in m * self.ranked..m * self.ranked + self.neighbour_count[m] {
            let k = self.neighbour[e] as usize;
            let Some(q) = self.labels[k] else { continue };
            let length_mm = (at_mm - points[q as usize]).norm();
            let expected_mm = if !self.was_labeled[m] {
                self.edge_length_mm[e]
            } else if self.was_labeled[k] {
                (self.last_seen_mm[m] - self.last_seen_mm[k]).norm()
            } else {
                continue;
            };
            if (length_mm - expected_mm).powi(2) / self.edge_tolerance_mm2[e] <= self.config.edge_check_limit {
                return false;
            }
            judged = true;
        }
        judged
    }

    pub(super) fn adapt_edge_lengths(&mut self) {
        let rate = self.config.edge_adaptation;
        for i in 0..self.markers {
            let Some(pi) = self.labels[i].and(self.known_mm[i]) else { continue };
            for n in 0..self.neighbour_count[i] {
                let k = self.neighbour[i * self.ranked + n] as usize;
                if let Some(pk) = self.labels[k].and(self.known_mm[k]) {
                    let length = &mut self.edge_length_mm[i * self.ranked + n];
                    *length += rate * ((pi - pk).norm() - *length);
                }
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
    fn rejects_ghosts_that_break_the_rigid_edges() {
        // Every frame, a ghost 25 mm from marker 1 (on the far side from its neighbours),
        // listed before the real points.
        let rate = 60.0;
        let frame = |f: usize| {
            let truth = limb(f as f64 / rate);
            let mut cloud = vec![(None, truth[1] + (truth[1] - truth[0]).normalize() * 25.0)];
            cloud.extend(truth.into_iter().enumerate().map(|(m, p)| (Some(m), p)).rev());
            cloud
        };
        assert_eq!(run(Method::SoftGraph, rate, 300, frame), 0);
    }

    #[test]
    fn keeps_a_marker_whose_neighbours_vanish_beside_ghosts() {
        // At 30 Hz, marker 0's three rigid neighbours vanish after a second; from then on two
        // ghosts move 60 mm beyond where neighbours 1 and 2 are. Marker 0, right where it
        // was predicted, keeps its label although no edge of it can be matched (one bad edge
        // must not veto it), and the ghosts, which break every edge to marker 0, are never
        // taken for the hidden neighbours.
        let rate = 30.0;
        let hidden = 30..;
        let frame = |f: usize| {
            let truth = limb(f as f64 / rate);
            let mut cloud: Vec<(Option<usize>, Vec3)> = Vec::new();
            if hidden.contains(&f) {
                for k in [1, 2] {
                    cloud.push((None, truth[k] + (truth[k] - truth[0]).normalize() * 60.0));
                }
            }
            cloud.extend(
                truth
                    .into_iter()
                    .enumerate()
                    .filter(|(m, _)| !(hidden.contains(&f) && (1..4).contains(m)))
                    .map(|(m, p)| (Some(m), p)),
            );
            cloud
        };
        assert_eq!(run(Method::SoftGraph, rate, 90, frame), 0);
    }
}
