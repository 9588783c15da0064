//! Online labeling, one frame after another (labeling paper section 3, Eq. 1-5, and the
//! rigid-neighbour part of section 4, Eq. 13).
//!
//! Every frame:
//! 1. each marker's Kalman track predicts where it is ([`crate::kalman`]); the points inside
//!    a gate around the prediction (a few standard deviations of the innovation, clamped)
//!    are its candidates `b(i)`;
//! 2. each candidate pair is scored: `w_p * c_p + (1 - w_p) * c_lg` (Eq. 1-4), where `c_p` is
//!    the squared distance to the prediction and `c_lg` averages, over the marker's rigid
//!    edges, the best edge cost (length change + `w_a` x direction change) among the
//!    neighbour's candidates;
//! 3. markers take points by the Hungarian algorithm with "missing" dummies at cost `w_max`
//!    ([`crate::assignment`]); points nobody takes are ghosts;
//! 4. a label whose point breaks every edge to the labeled rigid neighbours is dropped (the
//!    edge check, below);
//! 5. labeled markers correct their tracks and edge lengths; a missing marker is estimated
//!    from its visible rigid neighbours (the rigid motion of the neighbours since the marker
//!    was last seen, carried to the marker: Eq. 13 with a measured instead of a skeleton-model
//!    offset), in two passes so a marker whose neighbours are missing too can use their
//!    estimates (the paper's "iterative scheme"). The estimate corrects the track with a
//!    larger noise, so a marker occluded for seconds is predicted where its limb went and is
//!    picked up again when it reappears.
//!
//! Choices where the paper is silent, in millimetre units throughout (`w_a = 1e4` then weighs
//! a 1% direction change like a 1 mm length change):
//! - the model graph uses the *predicted* positions (direction term included), so fast limbs
//!   at low frame rates are compared with where they are going, not where they were;
//! - costs are normalised so they mean the same at every frame rate: the point cost is the
//!   squared distance in units of the prediction's variance (Mahalanobis; at 30 fps the
//!   prediction is poorer, so distance counts less and geometry more), and an edge cost in
//!   units of the edge's squared tolerance (its spread over the template plus 3 mm). Measured
//!   on the CMU + HDM05 takes, the raw millimetre costs of the paper let near ghosts win at
//!   30 fps (labeling accuracy 60% against 87% normalised), and `w_a = 1e4` in mm^2 makes the
//!   direction term negligible; the paper's `w_p = 0.5` and `w_a` are kept;
//! - `w_max = w_p * gate_sigmas^2 + (1 - w_p) * geometry_limit`: any point in the gate with
//!   plausible local geometry is accepted, and a ghost in the gate that breaks the edges is
//!   refused;
//! - a marker lost by its prediction gets a second chance at the free points within
//!   `recover_gate_mm` of its rigid-neighbour estimate (a point that breaks every edge to its
//!   labeled neighbours excepted).
//!
//! Three choices make labeling hold up under heavy occlusion (real occlusion statistics, 23%
//! of the samples missing in long gaps) and at 30 fps. Measured with `locap bench label` on
//! the CMU + HDM05 takes, identification rate zeta at 120 / 60 / 30 fps, without ghosts and
//! with as many near ghosts as markers, before -> after all three: 60.1 / 46.6 / 19.3 ->
//! 66.4 / 66.1 / 55.5 % and 11.3 / 7.9 / 2.2 -> 24.4 / 21.9 / 12.0 %:
//! - *truncated edge costs* (`edge_outlier_cost`, 16 squared tolerances): an edge cost is
//!   the cheapest match among the neighbour's candidates, and a neighbour that is occluded
//!   still has candidates (other markers' points in its gate) that all break the edge. Left
//!   untruncated, one occluded neighbour vetoed a marker sitting 1-10 mm from its prediction
//!   (96% of the markers lost while visible at 30 fps were lost that way). An edge with no
//!   candidate at all counts as truncated too. Zeta without it (no ghosts): 8.4 / 16.4 /
//!   24.3 %;
//! - *a learned prediction variance per marker* (`innovation_rise` / `innovation_fall`,
//!   `min_prediction_std_mm`): the constant-velocity model's variance, scaled by how far
//!   this marker's predictions really missed (an exponential average of the measured over
//!   the modelled squared innovation, rising fast and falling slowly). The Kalman model,
//!   tuned for the fastest limbs, gave every marker a 32 mm standard deviation at 30 fps
//!   while most missed by 1-10 mm, so a ghost 15 mm away cost as little as the marker. The
//!   point cost is capped at `gate_sigmas^2` (what a point at the gate's edge costs): the
//!   gate itself is the Kalman one, so a point that jumped with its whole limb is still taken
//!   when its local geometry is right. Zeta with M ghosts without it: 23.4 / 15.0 / 3.1 %;
//! - *an edge check after the assignment* (`edge_check_limit`, 9 squared tolerances): a
//!   label whose point breaks every edge to the labeled rigid neighbours is dropped, judged
//!   on the edge lengths for a marker re-acquired this frame and on the change of the
//!   lengths since the previous frame for a tracked one (a switch to a ghost changes them at
//!   once; a marker slipping on the skin, or a source trajectory that drifts off the foot as
//!   CMU 85_12's RTOE does, slowly). Markers farthest from their predictions are judged
//!   first, and a dropped label stops counting as a neighbour, so a marker whose neighbours
//!   switched to ghosts keeps its own. Zeta without it: 64.6 / 64.1 / 51.0 % and 22.8 / 23.0
//!   / 12.2 % (more wrong samples: 12.2 / 19.5 / 41.0 % against 8.8 / 14.0 / 28.3 %).
//!
//! The baselines of the paper's comparison run in the same loop: `Unary` (UGM: Kalman
//! prediction and Hungarian on the point cost only) and `ClosestPoint` (CP: every marker takes
//! the nearest point to its last position, nearest pairs first). Neither estimates missing
//! markers.

use crate::LabelError;
use crate::assignment::GatedAssignment;
use crate::ik::{IkConfig, MarkerModel, PoseTracker};
use crate::kalman::{KalmanConfig, Track};
use crate::template::Template;
use locap_clean::procrustes::align_weighted;
use locap_core::Vec3;
use serde::{Deserialize, Serialize};

/// Weight of a neighbour whose distance spread is 5 mm (`1 / (1 + 5^2)`): three of these
/// make a rigid-neighbour estimate preferred to the pose's.
const RIGID_WEIGHT: f64 = 1.0 / 26.0;

/// Bounds of a marker's innovation scale: its predictions may be judged up to 10 times
/// sharper (1/100 of the variance) or twice as loose as the Kalman model says.
const MIN_INNOVATION_SCALE: f64 = 0.01;
const MAX_INNOVATION_SCALE: f64 = 4.0;

/// Reconstruction noise added to every edge's tolerance (mm).
const EDGE_NOISE_MM: f64 = 3.0;

/// Which labeling method runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Soft graph matching with missing-marker estimation (the paper's method).
    #[default]
    SoftGraph,
    /// Unary graph matching (UGM): Hungarian on the point cost to the Kalman prediction.
    Unary,
    /// Closest point (CP): nearest point to the last position, nearest pairs first.
    ClosestPoint,
}

impl Method {
    /// Every method, ours first.
    pub const ALL: [Method; 3] = [Method::SoftGraph, Method::Unary, Method::ClosestPoint];

    /// Short name for tables and flags.
    pub fn name(self) -> &'static str {
        match self {
            Method::SoftGraph => "ours",
            Method::Unary => "ugm",
            Method::ClosestPoint => "cp",
        }
    }
}

/// Labeling settings; defaults from the paper where it gives them.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LabelConfig {
    /// The method.
    pub method: Method,
    /// `w_p` of Eq. 1: weight of the point cost against the local-geometry cost (paper: 0.5).
    pub point_weight: f64,
    /// `w_a` of Eq. 4: weight of the direction term, mm^2 per unit of squared cosine change
    /// (paper: 1e4).
    pub angle_weight: f64,
    /// Local-geometry cost (in squared edge tolerances) above which a candidate is worse than
    /// "missing".
    pub geometry_limit: f64,
    /// Largest cost one edge adds to the local-geometry cost (squared edge tolerances): an
    /// edge this bad more likely has its neighbour missing or taken by a ghost than its
    /// marker elsewhere, so it counts as a bad edge but cannot veto a point that sits where
    /// the marker was predicted.
    pub edge_outlier_cost: f64,
    /// After the assignment, a labeled marker whose point breaks every edge to its labeled
    /// rigid neighbours by more than this (squared edge tolerances) is left missing.
    pub edge_check_limit: f64,
    /// Rigid edges per marker used in the local-geometry cost.
    pub edges: usize,
    /// Neighbours whose distance to a marker varied more than this over the template (mm,
    /// standard deviation) are not rigid: they are neither edges nor used for estimation.
    /// Markers on one body segment vary by a few millimetres, across a joint by centimetres;
    /// 25 mm keeps the near-rigid neighbours across a joint, which count for less because
    /// edge costs are measured in units of each edge's own spread (measured on the CMU +
    /// HDM05 benchmark: 12 mm left thigh markers with a single edge and lost 1-5 points of
    /// accuracy).
    pub max_edge_std_mm: f64,
    /// Visible neighbours used to estimate a missing marker.
    pub estimate_neighbours: usize,
    /// Gate radius in standard deviations of the predicted position.
    pub gate_sigmas: f64,
    /// A marker the prediction lost takes a free point this close to its rigid-neighbour
    /// estimate (mm).
    pub recover_gate_mm: f64,
    /// Smallest standard deviation of a predicted position in the point cost (mm).
    pub min_prediction_std_mm: f64,
    /// How fast a marker's innovation scale follows a larger miss than modelled (exponential
    /// average per labeled frame).
    pub innovation_rise: f64,
    /// How fast it follows a smaller miss.
    pub innovation_fall: f64,
    /// Smallest gate radius (mm).
    pub min_gate_mm: f64,
    /// Largest gate radius (mm).
    pub max_gate_mm: f64,
    /// How fast edge lengths follow the labeled data (exponential average per frame).
    pub edge_adaptation: f64,
    /// Kalman noise model.
    pub kalman: KalmanConfig,
}

impl Default for LabelConfig {
    fn default() -> LabelConfig {
        LabelConfig {
            method: Method::SoftGraph,
            point_weight: 0.5,
            angle_weight: 1.0e4,
            geometry_limit: 9.0,
            edge_outlier_cost: 16.0,
            edge_check_limit: 9.0,
            edges: crate::template::DEFAULT_EDGES,
            max_edge_std_mm: 25.0,
            estimate_neighbours: 6,
            gate_sigmas: 5.0,
            recover_gate_mm: 50.0,
            min_prediction_std_mm: 3.0,
            innovation_rise: 0.3,
            innovation_fall: 0.05,
            min_gate_mm: 40.0,
            max_gate_mm: 400.0,
            edge_adaptation: 0.01,
            kalman: KalmanConfig::default(),
        }
    }
}

impl LabelConfig {
    /// The defaults with another method.
    pub fn with_method(method: Method) -> LabelConfig {
        LabelConfig { method, ..LabelConfig::default() }
    }

    fn check(&self) -> Result<(), LabelError> {
        let positive = |v: f64| v > 0.0 && v.is_finite();
        if !(0.0..=1.0).contains(&self.point_weight)
            || !(self.angle_weight >= 0.0)
            || !positive(self.geometry_limit)
            || !positive(self.edge_outlier_cost)
            || !positive(self.edge_check_limit)
            || !positive(self.min_prediction_std_mm)
            || !(0.0..=1.0).contains(&self.innovation_rise)
            || !(0.0..=1.0).contains(&self.innovation_fall)
            || !(self.max_edge_std_mm >= 0.0)
            || !positive(self.gate_sigmas)
            || !positive(self.min_gate_mm)
            || !positive(self.recover_gate_mm)
            || !(self.max_gate_mm >= self.min_gate_mm)
            || !(0.0..=1.0).contains(&self.edge_adaptation)
            || !positive(self.kalman.accel_std_mm_s2)
            || !positive(self.kalman.measurement_std_mm)
            || !positive(self.kalman.estimate_std_mm)
            || !positive(self.kalman.coast_time_constant_s)
        {
            return Err(LabelError::Config(format!("invalid labeling settings: {self:?}")));
        }
        Ok(())
    }
}

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
            match (initial[m], reference[m], placement) {
                (Some(p), _, _) => {
                    self.tracks[m] = Track::new(points[p], std);
                    self.last_seen_mm[m] = points[p];
                    self.known_mm[m] = Some(points[p]);
                    self.lost[m] = false;
                }
                (None, Some(r), Some(t)) => {
                    self.tracks[m] = Track::new(t.apply(&r), 5.0 * self.config.kalman.estimate_std_mm);
                    self.last_seen_mm[m] = t.apply(&r);
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

    fn assign_optimal(&mut self, points: &[Vec3]) {
        let wp = self.config.point_weight;
        let soft = self.config.method == Method::SoftGraph;
        let mut assignment = std::mem::take(&mut self.assignment);
        assignment.begin(points.len());
        for m in 0..self.markers {
            let gate2 = self.gate_mm[m] * self.gate_mm[m];
            let sigmas2 = self.config.gate_sigmas * self.config.gate_sigmas;
            let missing = if soft { wp * sigmas2 + (1.0 - wp) * self.config.geometry_limit } else { gate2 };
            let variance = self.point_variance_mm2[m];
            assignment.push_marker(missing);
            for c in self.candidates(m) {
                let j = self.candidate_point[c] as usize;
                let point_cost = self.candidate_cost[c];
                let cost = if soft {
                    // In units of the prediction's (adapted) variance, at most what the gate's
                    // edge costs: inside the gate, good local geometry can outweigh a sudden move.
                    wp * (point_cost / variance).min(sigmas2) + (1.0 - wp) * self.local_geometry_cost(m, j, points)
                } else {
                    point_cost
                };
                assignment.push_candidate(j, cost);
            }
        }
        self.labels.copy_from_slice(assignment.solve());
        self.assignment = assignment;
    }

    /// Drops labels whose point breaks every edge to the labeled rigid neighbours: with the
    /// neighbours where they are, the point is a ghost or another marker's. A marker
    /// re-acquired this frame is judged against its edge lengths; a marker tracked from the
    /// previous frame against how its edges changed since then (a switch to a ghost changes
    /// them at once; a marker slipping on the skin, slowly). Markers are judged one after
    /// another, those farthest from their predictions first, and a dropped label no longer
    /// counts as a neighbour: a marker whose neighbours switched to ghosts keeps its label.
    fn check_edges(&mut self, points: &[Vec3]) {
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
    fn breaks_every_edge(&self, m: usize, at_mm: &Vec3, points: &[Vec3]) -> bool {
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

    fn assign_closest(&mut self, points: &[Vec3]) {
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

    /// Positions of this frame's labeled markers, and estimates for the others (two passes:
    /// the second may lean on estimates made in the first).
    fn estimate_missing(&mut self, points: &[Vec3]) {
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
    fn fit_pose(&mut self, points: &[Vec3]) {
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
    fn recover(&mut self, points: &[Vec3]) {
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

    fn adapt_edge_lengths(&mut self) {
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

    /// Records, for every measured marker, its position and its measured neighbours'.
    fn take_snapshots(&mut self) {
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
    use super::*;
    use locap_core::{MarkerName, Take};

    /// Four markers on a rigid bar-shaped "limb" and one on another moving at its own pace.
    fn limb(t: f64) -> Vec<Vec3> {
        let origin = Vec3::new(500.0 * (0.7 * t).sin(), 300.0 * t, 1000.0);
        let angle = 1.3 * t;
        let (c, s) = (angle.cos(), angle.sin());
        let rotate = |x: f64, y: f64, z: f64| origin + Vec3::new(c * x - s * y, s * x + c * y, z);
        vec![
            rotate(0.0, 0.0, 0.0),
            rotate(120.0, 0.0, 0.0),
            rotate(0.0, 90.0, 10.0),
            rotate(60.0, 40.0, 150.0),
            Vec3::new(-400.0 + 50.0 * t, 200.0 * (2.0 * t).cos(), 800.0),
        ]
    }

    /// A template from the truth of the first 60 frames of a scenario (markers missing there
    /// are missing in the template).
    fn template_of(rate: f64, frame: &impl Fn(usize) -> Vec<(Option<usize>, Vec3)>) -> Template {
        let names = (0..5).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let mut samples = vec![None; 60 * 5];
        for f in 0..60 {
            for (truth, p) in frame(f) {
                if let Some(m) = truth {
                    samples[f * 5 + m] = Some(p);
                }
            }
        }
        Template::from_take(&Take::from_samples(names, &samples, rate).unwrap(), Some(0)).unwrap()
    }

    fn run(method: Method, rate: f64, frames: usize, frame: impl Fn(usize) -> Vec<(Option<usize>, Vec3)>) -> usize {
        let template = template_of(rate, &frame);
        let mut labeler = Labeler::new(&template, LabelConfig::with_method(method), rate).unwrap();
        let first = frame(0);
        let points: Vec<Vec3> = first.iter().map(|p| p.1).collect();
        let mut initial = vec![None; 5];
        for (j, (truth, _)) in first.iter().enumerate() {
            if let Some(m) = truth {
                initial[*m] = Some(j);
            }
        }
        labeler.start(&template, &points, &initial).unwrap();
        let mut wrong = 0;
        for f in 1..frames {
            let cloud = frame(f);
            let points: Vec<Vec3> = cloud.iter().map(|p| p.1).collect();
            let labels = labeler.step(&points).to_vec();
            for (m, label) in labels.iter().enumerate() {
                let truth = cloud.iter().position(|p| p.0 == Some(m));
                if label.map(|l| l as usize) != truth {
                    wrong += 1;
                }
            }
        }
        wrong
    }

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

    #[test]
    fn bad_settings_are_errors() {
        let t = template_of(100.0, &|f| {
            limb(f as f64 / 100.0).into_iter().enumerate().map(|(m, p)| (Some(m), p)).collect()
        });
        assert!(Labeler::new(&t, LabelConfig { point_weight: 2.0, ..LabelConfig::default() }, 100.0).is_err());
        assert!(Labeler::new(&t, LabelConfig::default(), 0.0).is_err());
        let mut l = Labeler::new(&t, LabelConfig::default(), 100.0).unwrap();
        assert!(l.start(&t, &[Vec3::zeros()], &[Some(3), None, None, None, None]).is_err());
    }
}
