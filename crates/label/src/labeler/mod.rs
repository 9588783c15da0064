//! Online labeling, one frame after another (labeling paper section 3, Eq. 1-5, and the
//! missing-marker estimation of section 4, Eq. 13). [`Labeler`] holds every marker's track and
//! runs the frame loop; each concept of the loop has its own module:
//!
//! 1. each marker's Kalman track predicts where it is ([`crate::kalman`]); the points inside
//!    a gate around the prediction (a few standard deviations of the innovation, clamped)
//!    are its candidates `b(i)` (this module);
//! 2. each candidate pair is scored by soft graph matching, `w_p * c_p + (1 - w_p) * c_lg`
//!    (Eq. 1-4), where `c_lg` compares the marker's rigid edges with the data ([`edges`]);
//! 3. markers take points by the Hungarian algorithm with "missing" dummies at cost `w_max`
//!    (Eq. 5, [`crate::assignment`]); points nobody takes are ghosts;
//! 4. a label whose point breaks every edge to the labeled rigid neighbours is dropped (the
//!    edge check, [`edges`]);
//! 5. a missing marker is estimated from its visible rigid neighbours or from a fitted pose
//!    (section 4, [`estimate`]), and a marker the prediction lost gets a second chance near
//!    its estimate;
//! 6. labeled markers correct their tracks, estimated ones correct them with a larger noise
//!    (so a marker occluded for seconds is predicted where its limb went and is picked up
//!    again when it reappears), and the others coast (this module).
//!
//! The baselines of the paper's comparison (section 5.1), closest point and unary graph
//! matching, run in the same loop ([`baselines`]).
//!
//! # Choices where the paper is silent (prediction)
//! - *A learned prediction variance per marker* (`innovation_rise` / `innovation_fall`,
//!   `min_prediction_std_mm`): the constant-velocity model's variance, scaled by how far this
//!   marker's predictions really missed (an exponential average of the measured over the
//!   modelled squared innovation, rising fast and falling slowly). The Kalman model is tuned
//!   for the fastest limbs, so without it every marker at a low frame rate gets the variance
//!   of the fastest one, and a ghost a little farther than the marker costs as little as the
//!   marker. The gate itself stays the Kalman one, so a point that jumped with its whole limb
//!   is still a candidate. The measurements behind this and the choices of [`edges`] are in
//!   `docs/labeling.md`.

pub mod baselines;
pub mod config;
pub mod edges;
pub mod estimate;
#[cfg(test)]
mod scenario;

pub use config::{LabelConfig, Method};

use crate::LabelError;
use crate::assignment::GatedAssignment;
use crate::ik::{IkConfig, MarkerModel, PoseTracker};
use crate::kalman::Track;
use crate::template::Template;
use edges::EDGE_NOISE_MM;
use locap_core::Vec3;

/// Bounds of a marker's innovation scale: its predictions may be judged up to 10 times
/// sharper (1/100 of the variance) or twice as loose as the Kalman model says.
const MIN_INNOVATION_SCALE: f64 = 0.01;
const MAX_INNOVATION_SCALE: f64 = 4.0;

/// The online labeler: feed it frames with [`Labeler::step`].
#[derive(Debug, Clone)]
pub struct Labeler {
    config: LabelConfig,
    dt_s: f64,
    markers: usize,
    /// Ranked neighbours of marker i: `neighbour[i * ranked..][..neighbours[i]]`.
    ranked: usize,
    neighbour_count: Vec<usize>,
    neighbour: Vec<u32>,
    edge_length_mm: Vec<f64>,
    /// How much each neighbour counts when estimating a missing marker: `1 / (1 + std^2)` of
    /// its distance over the template, so a neighbour that is only nearly rigid barely bends
    /// the estimate.
    neighbour_weight: Vec<f64>,
    /// Squared tolerance of each edge (mm^2): its spread over the template plus 3 mm for
    /// reconstruction noise; edge costs are measured in these units.
    edge_tolerance_mm2: Vec<f64>,
    tracks: Vec<Track>,
    /// Marker never placed: no track yet.
    lost: Vec<bool>,
    /// Last measured position (closest-point baseline).
    last_seen_mm: Vec<Vec3>,
    predicted_mm: Vec<Vec3>,
    gate_mm: Vec<f64>,
    /// Variance of the predicted position used in the point cost (mm^2).
    point_variance_mm2: Vec<f64>,
    /// Kalman innovation variance of this frame's prediction (mm^2).
    innovation_mm2: Vec<f64>,
    /// Ratio of measured to modelled innovation, averaged over time.
    innovation_scale: Vec<f64>,
    /// Whether each marker was labeled in the previous frame (the edge check judges a
    /// re-acquired marker on edge lengths, a tracked one on their change).
    was_labeled: Vec<bool>,
    labels: Vec<Option<u32>>,
    /// Position of each marker this frame: measured, estimated or unknown.
    known_mm: Vec<Option<Vec3>>,
    /// The marker and its neighbours the last time it was measured: `1 + ranked` per marker.
    snapshot_mm: Vec<Vec3>,
    snapshot_ok: Vec<bool>,
    candidate_start: Vec<usize>,
    candidate_point: Vec<u32>,
    candidate_cost: Vec<f64>,
    assignment: GatedAssignment,
    /// Scratch `(key, marker, point)` triples: closest-point pairs by distance, or labels to
    /// check by surprise.
    greedy: Vec<(f64, u32, u32)>,
    /// Markers given a second chance this frame ([`Labeler::recover`]).
    recovering: Vec<u32>,
    point_used: Vec<bool>,
    from_mm: Vec<Vec3>,
    to_mm: Vec<Vec3>,
    weights: Vec<f64>,
    estimated: Vec<bool>,
    /// Pose reconstruction (section 4), when the skeleton and marker offsets are known.
    pose: Option<PoseTracker>,
    /// The fitted pose's markers this frame.
    pose_markers_mm: Vec<Option<Vec3>>,
}

impl Labeler {
    /// A labeler for `template`'s markers on a take recorded at `frame_rate_hz`.
    pub fn new(template: &Template, config: LabelConfig, frame_rate_hz: f64) -> Result<Labeler, LabelError> {
        config.check()?;
        if !(frame_rate_hz > 0.0 && frame_rate_hz.is_finite()) {
            return Err(LabelError::Config(format!("frame rate {frame_rate_hz} Hz is not positive")));
        }
        let m = template.marker_count();
        let ranked = config.edges.max(config.estimate_neighbours);
        let mut neighbour_count = vec![0; m];
        let mut neighbour = vec![0u32; m * ranked];
        let mut edge_length_mm = vec![0.0; m * ranked];
        let mut neighbour_weight = vec![0.0; m * ranked];
        let mut edge_tolerance_mm2 = vec![1.0; m * ranked];
        for (i, edges) in template.edges().iter().enumerate() {
            let rigid = edges.iter().filter(|e| e.std_mm <= config.max_edge_std_mm);
            for (n, e) in rigid.take(ranked).enumerate() {
                neighbour[i * ranked + n] = e.neighbour as u32;
                edge_length_mm[i * ranked + n] = e.length_mm;
                neighbour_weight[i * ranked + n] = 1.0 / (1.0 + e.std_mm * e.std_mm);
                edge_tolerance_mm2[i * ranked + n] = e.std_mm * e.std_mm + EDGE_NOISE_MM * EDGE_NOISE_MM;
                neighbour_count[i] = n + 1;
            }
        }
        Ok(Labeler {
            config,
            dt_s: 1.0 / frame_rate_hz,
            markers: m,
            ranked,
            neighbour_count,
            neighbour,
            edge_length_mm,
            neighbour_weight,
            edge_tolerance_mm2,
            tracks: vec![Track::new(Vec3::zeros(), 1.0); m],
            lost: vec![true; m],
            last_seen_mm: vec![Vec3::zeros(); m],
            predicted_mm: vec![Vec3::zeros(); m],
            gate_mm: vec![0.0; m],
            point_variance_mm2: vec![1.0; m],
            innovation_mm2: vec![1.0; m],
            innovation_scale: vec![1.0; m],
            was_labeled: vec![false; m],
            labels: vec![None; m],
            known_mm: vec![None; m],
            snapshot_mm: vec![Vec3::zeros(); m * (1 + ranked)],
            snapshot_ok: vec![false; m * (1 + ranked)],
            candidate_start: Vec::with_capacity(m + 1),
            candidate_point: Vec::new(),
            candidate_cost: Vec::new(),
            assignment: GatedAssignment::default(),
            greedy: Vec::new(),
            recovering: Vec::new(),
            point_used: Vec::new(),
            from_mm: Vec::with_capacity(ranked),
            to_mm: Vec::with_capacity(ranked),
            weights: Vec::with_capacity(ranked),
            estimated: vec![false; m],
            pose: None,
            pose_markers_mm: Vec::new(),
        })
    }

    /// Estimates missing markers from a pose fitted every frame to the skeleton `model`
    /// (paper section 4, Eq. 6-13) instead of from the last rigid snapshot of their
    /// neighbours. `model` must attach the template's markers, in template order. Costs a
    /// pose fit per frame (milliseconds), so labeling runs at hundreds of frames per second.
    pub fn with_pose_model(mut self, model: MarkerModel, config: IkConfig) -> Result<Labeler, LabelError> {
        if model.marker_count() != self.markers {
            return Err(LabelError::Config(format!(
                "the skeleton model attaches {} markers, the template has {}",
                model.marker_count(),
                self.markers
            )));
        }
        self.pose = Some(PoseTracker::new(model, config, 1.0 / self.dt_s));
        Ok(self)
    }

    /// Starts from the first frame: `points` (mm) and, for every template marker, the index
    /// of its point (`None` where it is not in the frame). Markers not in the frame are
    /// placed where the template's reference pose, moved onto the frame, puts them; rigid
    /// relations of the template seed the missing-marker estimation.
    pub fn start(&mut self, template: &Template, points: &[Vec3], initial: &[Option<usize>]) -> Result<(), LabelError> {
        self.start_with(template, points, initial, None)
    }

    /// [`Labeler::start`] from a fit that knows where some unseen markers are
    /// (`expected_mm`, one per template marker): those start there; the markers the fit is
    /// not sure of (`None`) start without a track, until their rigid neighbours place them.
    pub fn start_fitted(
        &mut self,
        template: &Template,
        points: &[Vec3],
        initial: &[Option<usize>],
        expected_mm: &[Option<Vec3>],
    ) -> Result<(), LabelError> {
        if expected_mm.len() != self.markers {
            return Err(LabelError::Config(format!(
                "{} expected positions for {} template markers",
                expected_mm.len(),
                self.markers
            )));
        }
        self.start_with(template, points, initial, Some(expected_mm))
    }

    fn start_with(
        &mut self,
        template: &Template,
        points: &[Vec3],
        initial: &[Option<usize>],
        expected_mm: Option<&[Option<Vec3>]>,
    ) -> Result<(), LabelError> {
        if initial.len() != self.markers {
            return Err(LabelError::Config(format!(
                "{} initial labels for {} template markers",
                initial.len(),
                self.markers
            )));
        }
        if let Some(bad) = initial.iter().flatten().find(|&&p| p >= points.len()) {
            return Err(LabelError::Config(format!("initial label points at point {bad} of {}", points.len())));
        }
        let reference = template.reference_mm();
        let (from, to): (Vec<Vec3>, Vec<Vec3>) =
            initial.iter().zip(reference).filter_map(|(p, r)| Some(((*r)?, points[(*p)?]))).unzip();
        let placement = locap_clean::procrustes::align(&from, &to);
        let std = self.config.kalman.measurement_std_mm;
        self.innovation_scale.fill(1.0);
        for m in 0..self.markers {
            self.estimated[m] = false;
            // With a fit, its expectation replaces the reference pose (which was another pose).
            let placed = match expected_mm {
                Some(expected) => expected[m],
                None => reference[m].zip(placement).map(|(r, t)| t.apply(&r)),
            };
            match (initial[m], placed) {
                (Some(p), _) => {
                    self.tracks[m] = Track::new(points[p], std);
                    self.last_seen_mm[m] = points[p];
                    self.known_mm[m] = Some(points[p]);
                    self.lost[m] = false;
                }
                (None, Some(at)) => {
                    self.tracks[m] = Track::new(at, 5.0 * self.config.kalman.estimate_std_mm);
                    self.last_seen_mm[m] = at;
                    self.known_mm[m] = None;
                    self.lost[m] = false;
                }
                _ => {
                    self.known_mm[m] = None;
                    self.lost[m] = true;
                }
            }
            self.labels[m] = initial[m].map(|p| p as u32);
            self.was_labeled[m] = initial[m].is_some();
        }
        // The template's rigid relations stand in until a marker is seen with its neighbours.
        for i in 0..self.markers {
            let base = i * (1 + self.ranked);
            self.snapshot_ok[base..base + 1 + self.ranked].fill(false);
            if let Some(r) = reference[i] {
                self.snapshot_mm[base] = r;
                self.snapshot_ok[base] = true;
                for n in 0..self.neighbour_count[i] {
                    if let Some(q) = reference[self.neighbour[i * self.ranked + n] as usize] {
                        self.snapshot_mm[base + 1 + n] = q;
                        self.snapshot_ok[base + 1 + n] = true;
                    }
                }
            }
        }
        self.take_snapshots();
        if let Some(pose) = &mut self.pose {
            pose.reset();
            self.pose_markers_mm = pose.fit(&self.known_mm, &vec![None; self.markers]);
        }
        Ok(())
    }

    /// Labels one frame of `points` (mm): for every template marker, the index of its point
    /// in `points`, or `None` (missing). Points no marker took are ghosts.
    pub fn step(&mut self, points: &[Vec3]) -> &[Option<u32>] {
        self.predict();
        self.find_candidates(points);
        match self.config.method {
            Method::ClosestPoint => self.assign_closest(points),
            Method::Unary | Method::SoftGraph => self.assign_optimal(points),
        }
        if self.config.method == Method::SoftGraph {
            self.check_edges(points);
        }
        self.correct(points);
        &self.labels
    }

    /// Overrides the last frame's labels of some markers (re-acquisition,
    /// [`crate::reacquire`]): each `(marker, point)` takes that point of `points` (the frame
    /// just labeled) with a fresh track; a marker that held another point lets it go, and a
    /// marker that held the point now given to another is left unlabeled.
    ///
    /// # Errors
    /// [`LabelError::Config`] for a marker or point out of range.
    pub fn relabel(&mut self, points: &[Vec3], changes: &[(usize, usize)]) -> Result<(), LabelError> {
        if let Some(bad) = changes.iter().find(|(m, p)| *m >= self.markers || *p >= points.len()) {
            return Err(LabelError::Config(format!("relabel {bad:?}: out of range")));
        }
        let std = self.config.kalman.measurement_std_mm;
        for &(m, p) in changes {
            for other in 0..self.markers {
                if other != m && self.labels[other] == Some(p as u32) {
                    self.labels[other] = None;
                    self.was_labeled[other] = false;
                    self.known_mm[other] = None;
                }
            }
            self.labels[m] = Some(p as u32);
            self.tracks[m] = Track::new(points[p], std);
            self.last_seen_mm[m] = points[p];
            self.known_mm[m] = Some(points[p]);
            self.innovation_scale[m] = 1.0;
            self.estimated[m] = false;
            self.lost[m] = false;
            self.was_labeled[m] = true;
        }
        Ok(())
    }

    /// The labels of the last frame.
    pub fn labels(&self) -> &[Option<u32>] {
        &self.labels
    }

    /// Where each marker was believed to be in the last frame (mm): measured, estimated from
    /// its neighbours, or `None`.
    pub fn positions_mm(&self) -> &[Option<Vec3>] {
        &self.known_mm
    }

    /// Whether each marker's position in the last frame is an estimate (it was not seen).
    pub fn estimated(&self) -> &[bool] {
        &self.estimated
    }

    fn predict(&mut self) {
        let k = &self.config.kalman;
        for m in 0..self.markers {
            self.tracks[m].predict(self.dt_s, k);
            self.predicted_mm[m] = match self.config.method {
                Method::ClosestPoint => self.last_seen_mm[m],
                _ => self.tracks[m].position_mm,
            };
            let innovation = self.tracks[m].innovation_variance(k.measurement_std_mm);
            self.innovation_mm2[m] = innovation;
            self.gate_mm[m] =
                (self.config.gate_sigmas * innovation.sqrt()).clamp(self.config.min_gate_mm, self.config.max_gate_mm);
            let floor = self.config.min_prediction_std_mm * self.config.min_prediction_std_mm;
            self.point_variance_mm2[m] = (innovation * self.innovation_scale[m]).max(floor);
        }
    }

    fn find_candidates(&mut self, points: &[Vec3]) {
        self.candidate_start.clear();
        self.candidate_point.clear();
        self.candidate_cost.clear();
        for m in 0..self.markers {
            self.candidate_start.push(self.candidate_point.len());
            if self.lost[m] {
                continue;
            }
            let (centre, gate2) = (self.predicted_mm[m], self.gate_mm[m] * self.gate_mm[m]);
            for (j, p) in points.iter().enumerate() {
                let d2 = (p - centre).norm_squared();
                if d2 < gate2 {
                    self.candidate_point.push(j as u32);
                    self.candidate_cost.push(d2);
                }
            }
        }
        self.candidate_start.push(self.candidate_point.len());
    }

    fn candidates(&self, m: usize) -> std::ops::Range<usize> {
        self.candidate_start[m]..self.candidate_start[m + 1]
    }

    /// The Hungarian step (Eq. 5): every marker takes one of its candidates or "missing", at
    /// the costs of the method ([`edges`] for soft graph matching, [`baselines`] for UGM).
    fn assign_optimal(&mut self, points: &[Vec3]) {
        let soft = self.config.method == Method::SoftGraph;
        let mut assignment = std::mem::take(&mut self.assignment);
        assignment.begin(points.len());
        for m in 0..self.markers {
            assignment.push_marker(if soft { self.soft_missing_cost() } else { self.unary_missing_cost(m) });
            for c in self.candidates(m) {
                let j = self.candidate_point[c] as usize;
                let cost = if soft { self.soft_cost(m, c, points) } else { self.unary_cost(c) };
                assignment.push_candidate(j, cost);
            }
        }
        self.labels.copy_from_slice(assignment.solve());
        self.assignment = assignment;
    }

    fn correct(&mut self, points: &[Vec3]) {
        if self.pose.is_some() && self.config.method == Method::SoftGraph {
            self.fit_pose(points);
        }
        self.estimate_missing(points);
        if self.config.method == Method::SoftGraph {
            self.recover(points);
        }
        let std = self.config.kalman.measurement_std_mm;
        let (rise, fall) = (self.config.innovation_rise, self.config.innovation_fall);
        for m in 0..self.markers {
            if let Some(p) = self.labels[m] {
                let p = points[p as usize];
                // Measured against modelled innovation (per axis): the scale learns how far
                // off this marker's predictions really are.
                let ratio = (p - self.predicted_mm[m]).norm_squared() / (3.0 * self.innovation_mm2[m]);
                let scale = &mut self.innovation_scale[m];
                let rate = if ratio > *scale { rise } else { fall };
                *scale = (*scale + rate * (ratio - *scale)).clamp(MIN_INNOVATION_SCALE, MAX_INNOVATION_SCALE);
                self.tracks[m].update(&p, std);
                self.last_seen_mm[m] = p;
                self.lost[m] = false;
            }
        }
        self.adapt_edge_lengths();
        self.take_snapshots();
        // Recovered markers may improve the estimates of those still missing.
        self.estimate_missing(points);
        let estimate_std = self.config.kalman.estimate_std_mm;
        for m in 0..self.markers {
            if self.labels[m].is_some() {
                continue;
            }
            match self.known_mm[m] {
                Some(estimate) if self.lost[m] => {
                    self.tracks[m] = Track::new(estimate, estimate_std);
                    self.lost[m] = false;
                }
                Some(estimate) => self.tracks[m].update(&estimate, estimate_std),
                None => self.tracks[m].coast(self.dt_s, &self.config.kalman),
            }
        }
        for m in 0..self.markers {
            self.was_labeled[m] = self.labels[m].is_some();
        }
    }
}
