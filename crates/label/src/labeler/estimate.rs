//! Missing-marker estimation (labeling paper section 4): where a marker the labeler does not
//! see this frame is, so that its track follows its limb and it is picked up again when it
//! reappears.
//!
//! - *From rigid neighbours* (Eq. 13 with a measured instead of a skeleton-model offset): the
//!   marker's last snapshot (its position and its neighbours' the last time it was measured
//!   with them; the template's reference pose before that) is carried along with the rigid
//!   motion of the neighbours known now (a weighted Procrustes fit with three or more, their
//!   mean displacement with one or two). A neighbour counts by `1 / (1 + std^2)` of its
//!   distance spread over the template, so a neighbour that is only nearly rigid barely
//!   bends the estimate.
//! - *From a pose* (Eq. 6-13, [`crate::ik`]), when a skeleton and the markers' offsets are
//!   known: a pose is fitted every frame to the labeled markers and the Kalman predictions
//!   of the others, and a missing marker is placed where its known neighbours put it with
//!   the pose's offsets between them, or on the pose itself when no neighbour is known. The
//!   rigid-neighbour estimate is still preferred where at least three neighbours are truly
//!   rigid with the marker (`RIGID_WEIGHT`): measured offsets beat a layout's, but a
//!   forearm marker carried by upper-arm markers is better off with the pose.
//! - Estimates run in two passes, so a marker whose neighbours are missing too can use their
//!   estimates (the paper's "iterative scheme").
//! - *Recovery* (a choice where the paper is silent): a marker lost by its prediction gets a
//!   second chance at the free points within `recover_gate_mm` of its estimate (a point that
//!   breaks every edge to its labeled neighbours excepted), which catches markers whose
//!   Kalman prediction fell behind a sudden move of the whole limb.
//!
//! # The estimates stay inside the labeler
//! They steer the tracks and the recovery, and [`Labeler::positions_mm`] shows them frame by
//! frame, but a labeled take carries only what the cameras saw, named: [`crate::label_take`]
//! hands no estimate out. On gaps cut into gap-free real takes the estimates are no closer
//! to the truth than the clean stage's rigid-body and EDM fills, farther on most takes, and
//! missing where the labeler gave the marker a wrong point (`docs/labeling.md`, `cargo run
//! --release -p locap-label --example estimate_error`): the fills see both ends of a gap, an
//! online estimate only its start. Writing the estimates would give a technician a second,
//! poorer fill, outside the clean stage that records its fills in the take's provenance and
//! runs the swap and outlier checks before it fills. Gaps are filled once, by `locap_clean`.

use super::{Labeler, Method};
use locap_clean::procrustes::align_weighted;
use locap_core::Vec3;

/// Weight of a neighbour whose distance spread is 5 mm (`1 / (1 + 5^2)`): three of these
/// make a rigid-neighbour estimate preferred to the pose's.
const RIGID_WEIGHT: f64 = 1.0 / 26.0;

impl Labeler {
    /// Positions of this frame's labeled markers, and estimates for the others (two passes:
    /// the second may lean on estimates made in the first).
    pub(super) fn estimate_missing(&mut self, points: &[Vec3]) {
        for m in 0..self.markers {
            self.estimated[m] = false;
            self.known_mm[m] = self.labels[m].map(|p| points[p as usize]);
        }
        if self.config.method != Method::SoftGraph {
            return;
        }
        for _ in 0..2 {
            for m in 0..self.markers {
                if self.known_mm[m].is_none()
                    && let Some(estimate) = self.best_estimate(m)
                {
                    self.known_mm[m] = Some(estimate);
                    self.estimated[m] = true;
                }
            }
        }
    }

    /// Fits this frame's pose to the labeled markers and the Kalman predictions of the others.
    pub(super) fn fit_pose(&mut self, points: &[Vec3]) {
        let Some(pose) = &mut self.pose else { return };
        let observed: Vec<Option<Vec3>> = self.labels.iter().map(|l| l.map(|p| points[p as usize])).collect();
        let measurement = self.config.kalman.measurement_std_mm;
        let predicted: Vec<Option<(Vec3, f64)>> = (0..self.markers)
            .map(|m| {
                (self.labels[m].is_none() && !self.lost[m])
                    .then(|| (self.tracks[m].position_mm, self.tracks[m].innovation_variance(measurement)))
            })
            .collect();
        self.pose_markers_mm = pose.fit(&observed, &predicted);
    }

    /// Eq. 13: the marker where its known rigid neighbours put it, with the pose's offsets
    /// between them; on the pose itself when no neighbour is known.
    fn estimate_from_pose(&self, i: usize) -> Option<Vec3> {
        let own = (*self.pose_markers_mm.get(i)?)?;
        let (mut sum, mut n) = (Vec3::zeros(), 0);
        for k in 0..self.neighbour_count[i].min(self.config.estimate_neighbours) {
            let j = self.neighbour[i * self.ranked + k] as usize;
            if let (Some(seen), Some(model)) = (self.known_mm[j], self.pose_markers_mm[j]) {
                sum += seen - (model - own);
                n += 1;
            }
        }
        Some(if n > 0 { sum / n as f64 } else { own })
    }

    /// Second chance for markers the prediction lost: a point nobody took that lies within
    /// `recover_gate_mm` of where the marker's rigid neighbours put it is taken (optimal
    /// assignment again, on these markers and points only). This catches markers whose
    /// Kalman prediction fell behind a sudden move of the whole limb.
    pub(super) fn recover(&mut self, points: &[Vec3]) {
        self.point_used.clear();
        self.point_used.resize(points.len(), false);
        for p in self.labels.iter().flatten() {
            self.point_used[*p as usize] = true;
        }
        let gate2 = self.config.recover_gate_mm * self.config.recover_gate_mm;
        let mut assignment = std::mem::take(&mut self.assignment);
        assignment.begin(points.len());
        self.recovering.clear();
        for m in 0..self.markers {
            let (true, Some(estimate)) = (self.estimated[m], self.known_mm[m]) else { continue };
            self.recovering.push(m as u32);
            assignment.push_marker(gate2);
            for (j, p) in points.iter().enumerate() {
                let d2 = (p - estimate).norm_squared();
                if !self.point_used[j] && d2 < gate2 && !self.breaks_every_edge(m, p, points) {
                    assignment.push_candidate(j, d2);
                }
            }
        }
        if !self.recovering.is_empty() {
            for (k, found) in assignment.solve().iter().enumerate() {
                if let Some(p) = found {
                    let m = self.recovering[k] as usize;
                    self.labels[m] = Some(*p);
                    self.known_mm[m] = Some(points[*p as usize]);
                    self.estimated[m] = false;
                }
            }
        }
        self.assignment = assignment;
    }

    /// Records, for every measured marker, its position and its measured neighbours'.
    pub(super) fn take_snapshots(&mut self) {
        for i in 0..self.markers {
            let Some(pi) = self.labels[i].and(self.known_mm[i]) else { continue };
            let base = i * (1 + self.ranked);
            self.snapshot_mm[base] = pi;
            self.snapshot_ok[base] = true;
            for n in 0..self.neighbour_count[i] {
                let k = self.neighbour[i * self.ranked + n] as usize;
                match self.labels[k].and(self.known_mm[k]) {
                    Some(pk) => {
                        self.snapshot_mm[base + 1 + n] = pk;
                        self.snapshot_ok[base + 1 + n] = true;
                    }
                    None => self.snapshot_ok[base + 1 + n] = false,
                }
            }
        }
    }

    /// The rigid-neighbour estimate where the neighbours are truly rigid with the marker (at
    /// least three with a spread of 5 mm or better), else the pose's estimate (Eq. 13) when a
    /// skeleton is known, else the rigid-neighbour estimate from what neighbours there are.
    /// Measured offsets beat a layout's (calibrated to about 20 mm), but a forearm marker
    /// carried by upper-arm markers is worse off than with a pose.
    fn best_estimate(&mut self, i: usize) -> Option<Vec3> {
        let rigid = self.estimate_from_neighbours(i);
        let trusted = self.weights.iter().filter(|&&w| w >= RIGID_WEIGHT).count() >= 3;
        match rigid {
            Some(e) if trusted || self.pose.is_none() => Some(e),
            _ => self.estimate_from_pose(i).or(rigid),
        }
    }

    /// Eq. 13 with measured offsets: carry the marker's last snapshot along with the rigid
    /// motion of its neighbours known now (three or more), or their mean displacement (one
    /// or two).
    fn estimate_from_neighbours(&mut self, i: usize) -> Option<Vec3> {
        let base = i * (1 + self.ranked);
        if !self.snapshot_ok[base] {
            return None;
        }
        self.from_mm.clear();
        self.to_mm.clear();
        self.weights.clear();
        for n in 0..self.neighbour_count[i].min(self.config.estimate_neighbours) {
            let k = self.neighbour[i * self.ranked + n] as usize;
            if let (true, Some(now)) = (self.snapshot_ok[base + 1 + n], self.known_mm[k]) {
                self.from_mm.push(self.snapshot_mm[base + 1 + n]);
                self.to_mm.push(now);
                self.weights.push(self.neighbour_weight[i * self.ranked + n]);
            }
        }
        let then = self.snapshot_mm[base];
        match self.from_mm.len() {
            0 => None,
            1 | 2 => {
                let total: f64 = self.weights.iter().sum();
                let shift: Vec3 = self
                    .to_mm
                    .iter()
                    .zip(&self.from_mm)
                    .zip(&self.weights)
                    .map(|((a, b), w)| (a - b) * *w)
                    .sum::<Vec3>();
                Some(then + shift / total)
            }
            _ => align_weighted(&self.from_mm, &self.to_mm, &self.weights).map(|t| t.apply(&then)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::scenario::{limb, run};
    use super::super::{LabelConfig, Labeler, Method};
    use crate::template::Template;
    use locap_core::{MarkerName, Take, Vec3};

    #[test]
    fn reacquires_a_marker_after_a_two_second_occlusion() {
        let rate = 120.0;
        let hidden = 150..390; // 2 s
        let frame = |f: usize| {
            limb(f as f64 / rate)
                .into_iter()
                .enumerate()
                .filter(|(m, _)| !(*m == 3 && hidden.contains(&f)))
                .map(|(m, p)| (Some(m), p))
                .collect::<Vec<_>>()
        };
        assert_eq!(run(Method::SoftGraph, rate, 500, frame), 0);
        // Without the neighbour estimate the marker is lost (the limb moved ~0.6 m meanwhile).
        assert!(run(Method::Unary, rate, 500, frame) > 50);
    }

    #[test]
    fn the_pose_keeps_a_hidden_forearm_with_its_arm() {
        use crate::ik::tests::arm_model;
        let model = arm_model();
        let rate = 60.0;
        // Shoulder swinging and elbow bending; from frame 24 the elbow holds still; from 30 to 90
        // the shoulder swings on (the hand travels about half a metre) and the whole forearm
        // (markers 6-8) is hidden.
        let pose = |f: usize| {
            let t = f as f64 / rate;
            let mut theta = vec![0.0; model.parameter_count()];
            theta[0] = 5.0;
            theta[2] = 10.0;
            theta[3 + 5] = 2.0 * (0.9 * t).sin();
            theta[3 + 8] = 0.9 + 0.6 * (1.7 * t.min(0.4)).sin();
            theta
        };
        let truth = |f: usize| -> Vec<Vec3> { model.markers_mm(&pose(f)).into_iter().map(|p| p.unwrap()).collect() };
        let names: Vec<MarkerName> = (0..9).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let samples: Vec<Option<Vec3>> = (0..30).flat_map(|f| truth(f).into_iter().map(Some)).collect();
        let template = Template::from_take(&Take::from_samples(names, &samples, rate).unwrap(), Some(0)).unwrap();
        let hidden = 30..90;
        let run = |with_pose: bool| {
            let mut labeler = Labeler::new(&template, LabelConfig::default(), rate).unwrap();
            if with_pose {
                labeler = labeler.with_pose_model(model.clone(), crate::ik::IkConfig::default()).unwrap();
            }
            labeler.start(&template, &truth(0), &(0..9).map(Some).collect::<Vec<_>>()).unwrap();
            let (mut wrong, mut error_sum, mut error_count) = (0, 0.0, 0.0);
            for f in 1..200 {
                let visible: Vec<usize> = (0..9).filter(|&m| !(m >= 6 && hidden.contains(&f))).collect();
                let points: Vec<Vec3> = visible.iter().map(|&m| truth(f)[m]).collect();
                let labels = labeler.step(&points).to_vec();
                if hidden.contains(&f) {
                    for m in 6..9 {
                        let estimate = labeler.positions_mm()[m].expect("hidden markers are estimated");
                        error_sum += (estimate - truth(f)[m]).norm();
                        error_count += 1.0;
                    }
                }
                for (m, label) in labels.iter().enumerate() {
                    let own = visible.iter().position(|&v| v == m).map(|p| p as u32);
                    wrong += usize::from(*label != own);
                }
            }
            (wrong, error_sum / error_count)
        };
        let (with, without) = (run(true), run(false));
        eprintln!("hidden forearm estimate: {:.1} mm with the pose, {:.1} mm without", with.1, without.1);
        assert_eq!(with.0, 0, "with the pose, every label is right");
        // The hidden forearm's estimate: within centimetres of the truth with the pose, and
        // closer than from the upper arm's markers (which are not rigid with it).
        assert!(
            with.1 < 20.0 && with.1 < without.1,
            "mean estimate error {} mm, without the pose {} mm",
            with.1,
            without.1
        );
    }
}
