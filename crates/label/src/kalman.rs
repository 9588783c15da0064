//! Constant-velocity Kalman filter for one marker (labeling paper section 3: "candidate match
//! b(i) of marker i are ... the distance between which and the predicted marker using Kalman
//! filter is less than a specific threshold"; section 4, Eq. 8-9).
//!
//! The three axes are independent and share the same noise model, so they share one 2 x 2
//! covariance (position, velocity): the whole filter is a handful of multiplications and
//! never allocates. The process noise is the discrete white-noise-acceleration model
//! (acceleration standard deviation `accel_std_mm_s2`), the usual choice for tracking points
//! whose acceleration is unknown but bounded.

use locap_core::Vec3;
use serde::{Deserialize, Serialize};

/// Noise model of the marker tracks.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KalmanConfig {
    /// Standard deviation of a marker's acceleration (mm/s^2). Hands and feet reach
    /// 50-100 m/s^2 in fast moves; 20 m/s^2 keeps gates tight during ordinary motion and
    /// still opens them when a marker stops being seen.
    pub accel_std_mm_s2: f64,
    /// Standard deviation of a measured position (mm): reconstruction noise of the cameras.
    pub measurement_std_mm: f64,
    /// Standard deviation of an estimated position of a missing marker (mm): how far the
    /// rigid-neighbour estimate is trusted.
    pub estimate_std_mm: f64,
    /// Time constant (s) with which the velocity of a marker that is neither seen nor
    /// estimated decays, so an occluded marker coasts to a stop instead of flying off along
    /// its last velocity.
    pub coast_time_constant_s: f64,
}

impl Default for KalmanConfig {
    fn default() -> KalmanConfig {
        KalmanConfig {
            accel_std_mm_s2: 50_000.0,
            measurement_std_mm: 2.0,
            estimate_std_mm: 15.0,
            coast_time_constant_s: 0.3,
        }
    }
}

/// State of one marker: position, velocity and their shared per-axis covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Track {
    /// Position (mm).
    pub position_mm: Vec3,
    /// Velocity (mm/s).
    pub velocity_mm_s: Vec3,
    /// Per-axis covariance `[[pp, pv], [pv, vv]]` (mm^2, mm^2/s, mm^2/s^2).
    pub covariance: [f64; 3],
}

impl Track {
    /// A track starting at `position_mm` at rest, with position uncertainty `position_std_mm`
    /// and an unknown velocity (1 m/s standard deviation).
    pub fn new(position_mm: Vec3, position_std_mm: f64) -> Track {
        Track { position_mm, velocity_mm_s: Vec3::zeros(), covariance: [position_std_mm * position_std_mm, 0.0, 1.0e6] }
    }

    /// Advances the track by `dt_s` seconds (prediction step).
    pub fn predict(&mut self, dt_s: f64, config: &KalmanConfig) {
        self.position_mm += self.velocity_mm_s * dt_s;
        let [pp, pv, vv] = self.covariance;
        let q = config.accel_std_mm_s2 * config.accel_std_mm_s2;
        let (dt2, dt3, dt4) = (dt_s * dt_s, dt_s * dt_s * dt_s, dt_s * dt_s * dt_s * dt_s);
        self.covariance =
            [pp + 2.0 * dt_s * pv + dt2 * vv + q * dt4 / 4.0, pv + dt_s * vv + q * dt3 / 2.0, vv + q * dt2];
    }

    /// Variance (mm^2, per axis) of the innovation of a measurement with standard deviation
    /// `measurement_std_mm`: what gates candidate points.
    pub fn innovation_variance(&self, measurement_std_mm: f64) -> f64 {
        self.covariance[0] + measurement_std_mm * measurement_std_mm
    }

    /// Corrects the track with a measured (or estimated) position (update step).
    pub fn update(&mut self, measured_mm: &Vec3, measurement_std_mm: f64) {
        let [pp, pv, vv] = self.covariance;
        let s = pp + measurement_std_mm * measurement_std_mm;
        let (k_p, k_v) = (pp / s, pv / s);
        let innovation = measured_mm - self.position_mm;
        self.position_mm += innovation * k_p;
        self.velocity_mm_s += innovation * k_v;
        self.covariance = [(1.0 - k_p) * pp, (1.0 - k_p) * pv, vv - k_v * pv];
    }

    /// Neither seen nor estimated for `dt_s`: slow down (see
    /// [`KalmanConfig::coast_time_constant_s`]).
    pub fn coast(&mut self, dt_s: f64, config: &KalmanConfig) {
        self.velocity_mm_s *= (-dt_s / config.coast_time_constant_s).exp();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn learns_constant_velocity() {
        let config = KalmanConfig::default();
        let dt = 1.0 / 120.0;
        let velocity = Vec3::new(1000.0, -500.0, 0.0);
        let mut track = Track::new(Vec3::zeros(), 2.0);
        for f in 1..60 {
            track.predict(dt, &config);
            track.update(&(velocity * (f as f64 * dt)), config.measurement_std_mm);
        }
        track.predict(dt, &config);
        let expected = velocity * (60.0 * dt);
        assert!((track.position_mm - expected).norm() < 0.5, "{:?}", track.position_mm);
        assert!((track.velocity_mm_s - velocity).norm() < 10.0);
    }

    #[test]
    fn uncertainty_grows_without_measurements_and_shrinks_with_them() {
        let config = KalmanConfig::default();
        let mut track = Track::new(Vec3::zeros(), 2.0);
        let before = track.innovation_variance(2.0);
        for _ in 0..10 {
            track.predict(1.0 / 60.0, &config);
            track.coast(1.0 / 60.0, &config);
        }
        let grown = track.innovation_variance(2.0);
        assert!(grown > before);
        track.update(&Vec3::zeros(), 2.0);
        assert!(track.innovation_variance(2.0) < grown);
        let [pp, pv, vv] = track.covariance;
        assert!(pp > 0.0 && vv > 0.0 && pv * pv <= pp * vv + 1e-9, "covariance stays positive definite");
    }
}
