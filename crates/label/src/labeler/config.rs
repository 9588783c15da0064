//! Labeling settings: the paper's weights (section 3: `w_p = 0.5`, `w_a = 1e4`), the gates,
//! limits and rates it leaves open, each documented where it is declared, and the first-frame
//! fit (section 3, last paragraph) and output of a whole take's labeling.

use crate::LabelError;
use crate::initial_fit::FitConfig;
use crate::kalman::KalmanConfig;
use serde::{Deserialize, Serialize};

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
    /// edge costs are measured in units of each edge's own spread (a tighter limit leaves
    /// some markers a single edge: `docs/labeling.md`).
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
    /// The first frame's fit of the template ([`crate::label_take`]; [`crate::label_frames`]
    /// takes its own in [`crate::Start::Fit`]).
    pub fit: FitConfig,
    /// Whether the take [`crate::label_take`] builds keeps the points no marker took, as
    /// unlabeled `*0`, `*1`, ... columns after the markers' (else they are dropped).
    pub keep_unlabeled: bool,
    /// Whether a body segment lost or broken for long is fitted again ([`crate::reacquire`];
    /// whole takes only, [`crate::label_take`] and [`crate::label_frames`], with a template
    /// whose body places at least 90% of its markers).
    #[serde(default = "yes")]
    pub reacquire: bool,
}

fn yes() -> bool {
    true
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
            fit: FitConfig::default(),
            keep_unlabeled: false,
            reacquire: true,
        }
    }
}

impl LabelConfig {
    /// The defaults with another method.
    pub fn with_method(method: Method) -> LabelConfig {
        LabelConfig { method, ..LabelConfig::default() }
    }

    pub(crate) fn check(&self) -> Result<(), LabelError> {
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
            || !positive(self.fit.accept_mm)
            || !(0.0..=1.0).contains(&self.fit.min_matched_fraction)
        {
            return Err(LabelError::Config(format!("invalid labeling settings: {self:?}")));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::Labeler;
    use super::super::scenario::{limb, template_of};
    use super::LabelConfig;
    use locap_core::Vec3;

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
