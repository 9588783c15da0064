//! Fitting a layout to a real take *without* skeleton motion (issue 5, `locap layout fit`): a
//! user brings their own marker set and one labeled capture of it.
//!
//! Without motion, the only pose-free facts in a take are the distances between markers on
//! the same rigid segment: markers riding on one joint keep their mutual distances in every
//! frame. The fit therefore moves each joint's markers (those without a blend, which slide
//! and are left as they are) so that their pairwise distances match the real take's median
//! distances, while staying close to the layout's initial offsets:
//!
//! ```text
//! min_o  sum_pairs (|o_a - o_b| - d_ab)^2  +  lambda * sum_a |o_a - o_a0|^2
//! ```
//!
//! The prior (`lambda`) fixes what distances cannot: where the group sits on its segment and
//! how it is turned (distances are invariant to rigid motions of the group). Joints carrying a
//! single marker have no pair and keep their offsets; the report lists them. Each joint's group
//! is solved by Levenberg-Marquardt (a handful of unknowns per group). The residual reported is
//! the RMS of `|o_a - o_b| - d_ab` over all pairs, before and after, next to the real spread of
//! each distance (soft tissue and reconstruction noise: no layout can do better than that).

use crate::layout::Layout;
use locap_core::{Take, Vec3};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Errors of [`fit_to_distances`].
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FitError {
    /// No two markers of the layout share a joint and appear together in the take.
    #[error("no pair of markers on the same joint is visible together in the take: nothing to fit")]
    NoPairs,
    /// The prior weight is not a positive number.
    #[error("prior weight {0} is not a positive number")]
    BadPrior(f64),
}

/// Settings of [`fit_to_distances`].
#[derive(Debug, Clone, PartialEq)]
pub struct DistanceFitOptions {
    /// Weight of the pull towards the initial offsets (`lambda`, per mm^2 of offset change
    /// against mm^2 of distance error).
    pub prior_weight: f64,
    /// Levenberg-Marquardt iterations per group.
    pub iterations: usize,
    /// Use at most this many evenly spaced frames for the distance medians.
    pub max_frames: usize,
}

impl Default for DistanceFitOptions {
    fn default() -> Self {
        DistanceFitOptions { prior_weight: 0.01, iterations: 100, max_frames: 5000 }
    }
}

/// One same-segment pair.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairFit {
    /// First marker.
    pub a: String,
    /// Second marker.
    pub b: String,
    /// Their joint.
    pub joint: String,
    /// Median real distance, mm.
    pub real_mm: f64,
    /// Standard deviation of the real distance over the take, mm.
    pub real_sd_mm: f64,
    /// Layout distance before the fit, mm.
    pub before_mm: f64,
    /// Layout distance after the fit, mm.
    pub after_mm: f64,
}

/// What [`fit_to_distances`] did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DistanceFitReport {
    /// Every pair used.
    pub pairs: Vec<PairFit>,
    /// Markers the fit could not move (alone on their joint, blended, or not in the take).
    pub unconstrained: Vec<String>,
}

impl DistanceFitReport {
    fn rms(&self, value: impl Fn(&PairFit) -> f64) -> f64 {
        let n = self.pairs.len().max(1) as f64;
        (self.pairs.iter().map(|p| (value(p) - p.real_mm).powi(2)).sum::<f64>() / n).sqrt()
    }

    /// RMS distance error over the pairs before the fit, mm.
    pub fn rms_before_mm(&self) -> f64 {
        self.rms(|p| p.before_mm)
    }

    /// RMS distance error over the pairs after the fit, mm.
    pub fn rms_after_mm(&self) -> f64 {
        self.rms(|p| p.after_mm)
    }

    /// RMS of the real distances' own spread, mm (the floor a rigid layout can reach).
    pub fn real_spread_mm(&self) -> f64 {
        let n = self.pairs.len().max(1) as f64;
        (self.pairs.iter().map(|p| p.real_sd_mm * p.real_sd_mm).sum::<f64>() / n).sqrt()
    }
}

/// Median and standard deviation of the distance between markers `a` and `b` of `take`.
fn distance_stats(take: &Take, a: usize, b: usize, max_frames: usize) -> Option<(f64, f64)> {
    let stride = take.frame_count().div_ceil(max_frames.max(1)).max(1);
    let mut d: Vec<f64> = (0..take.frame_count())
        .step_by(stride)
        .filter_map(|f| Some((take.position_mm(f, a)? - take.position_mm(f, b)?).norm()))
        .collect();
    if d.len() < 10 {
        return None;
    }
    d.sort_by(f64::total_cmp);
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let sd = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / d.len() as f64).sqrt();
    Some((d[d.len() / 2], sd))
}

/// Levenberg-Marquardt on one group: `offsets` (moved in place), `pairs` of indices into it
/// with target distances.
fn solve_group(offsets: &mut [Vec3], pairs: &[(usize, usize, f64)], lambda: f64, iterations: usize) {
    let n = offsets.len();
    let initial: Vec<Vec3> = offsets.to_vec();
    let residuals = |o: &[Vec3]| -> DVector<f64> {
        let mut r = DVector::zeros(pairs.len() + 3 * n);
        for (k, (a, b, d)) in pairs.iter().enumerate() {
            r[k] = (o[*a] - o[*b]).norm() - d;
        }
        for i in 0..n {
            for c in 0..3 {
                r[pairs.len() + 3 * i + c] = lambda.sqrt() * (o[i][c] - initial[i][c]);
            }
        }
        r
    };
    let mut mu = 1e-3;
    let mut r = residuals(offsets);
    for _ in 0..iterations {
        let mut j = DMatrix::zeros(pairs.len() + 3 * n, 3 * n);
        for (k, (a, b, _)) in pairs.iter().enumerate() {
            let diff = offsets[*a] - offsets[*b];
            let u = diff / diff.norm().max(1e-9);
            for c in 0..3 {
                j[(k, 3 * a + c)] = u[c];
                j[(k, 3 * b + c)] = -u[c];
            }
        }
        for i in 0..3 * n {
            j[(pairs.len() + i, i)] = lambda.sqrt();
        }
        let jt = j.transpose();
        let mut h = &jt * &j;
        for i in 0..3 * n {
            h[(i, i)] *= 1.0 + mu;
        }
        let g = &jt * &r;
        let Some(step) = h.cholesky().map(|c| c.solve(&(-g))) else { break };
        let trial: Vec<Vec3> = offsets
            .iter()
            .enumerate()
            .map(|(i, o)| o + Vec3::new(step[3 * i], step[3 * i + 1], step[3 * i + 2]))
            .collect();
        let r_trial = residuals(&trial);
        if r_trial.norm_squared() < r.norm_squared() {
            let gain = r.norm_squared() - r_trial.norm_squared();
            offsets.copy_from_slice(&trial);
            r = r_trial;
            mu = (mu / 3.0).max(1e-9);
            if gain < 1e-12 {
                break;
            }
        } else {
            mu *= 4.0;
            if mu > 1e9 {
                break;
            }
        }
    }
}

/// Fits `layout`'s offsets to the same-joint marker distances of a real labeled `take` (see
/// the module docs). Markers are matched by label.
pub fn fit_to_distances(
    layout: &Layout,
    take: &Take,
    options: &DistanceFitOptions,
) -> Result<(Layout, DistanceFitReport), FitError> {
    if !(options.prior_weight.is_finite() && options.prior_weight > 0.0) {
        return Err(FitError::BadPrior(options.prior_weight));
    }
    let mut out = layout.clone();
    let mut report = DistanceFitReport { pairs: Vec::new(), unconstrained: Vec::new() };
    // Groups: joint name -> layout indices of its unblended markers present in the take.
    let mut groups: Vec<(String, Vec<(usize, usize)>)> = Vec::new();
    for (i, m) in layout.markers.iter().enumerate() {
        let (Some(t), None) = (take.marker_index(&m.name), &m.blend) else {
            report.unconstrained.push(m.name.clone());
            continue;
        };
        match groups.iter_mut().find(|(j, _)| *j == m.joint) {
            Some((_, members)) => members.push((i, t)),
            None => groups.push((m.joint.clone(), vec![(i, t)])),
        }
    }
    for (joint, members) in &groups {
        let mut pairs = Vec::new();
        let mut stats = Vec::new();
        for a in 0..members.len() {
            for b in a + 1..members.len() {
                if let Some((median, sd)) = distance_stats(take, members[a].1, members[b].1, options.max_frames) {
                    pairs.push((a, b, median));
                    stats.push(sd);
                }
            }
        }
        if pairs.is_empty() {
            report.unconstrained.extend(members.iter().map(|(i, _)| layout.markers[*i].name.clone()));
            continue;
        }
        let mut offsets: Vec<Vec3> = members.iter().map(|(i, _)| Vec3::from(layout.markers[*i].offset_mm)).collect();
        let before = offsets.clone();
        // Coincident markers (a template with zero offsets) give no direction to move apart:
        // spread them by a few mm along distinct directions first.
        if pairs.iter().any(|(a, b, _)| (offsets[*a] - offsets[*b]).norm() < 1e-6) {
            let dirs = [Vec3::x(), Vec3::y(), Vec3::z(), -Vec3::x(), -Vec3::y(), -Vec3::z()];
            for (k, o) in offsets.iter_mut().enumerate() {
                *o += dirs[k % dirs.len()] * (10.0 * (1 + k / dirs.len()) as f64);
            }
        }
        solve_group(&mut offsets, &pairs, options.prior_weight, options.iterations);
        for ((a, b, d), sd) in pairs.iter().zip(stats) {
            report.pairs.push(PairFit {
                a: layout.markers[members[*a].0].name.clone(),
                b: layout.markers[members[*b].0].name.clone(),
                joint: joint.clone(),
                real_mm: *d,
                real_sd_mm: sd,
                before_mm: (before[*a] - before[*b]).norm(),
                after_mm: (offsets[*a] - offsets[*b]).norm(),
            });
        }
        for ((i, _), o) in members.iter().zip(&offsets) {
            out.markers[*i].offset_mm = [o.x, o.y, o.z].map(|c| (c * 10.0).round() / 10.0);
        }
    }
    if report.pairs.is_empty() {
        return Err(FitError::NoPairs);
    }
    Ok((out, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::marker;
    use locap_core::{EulerOrder, MarkerName};

    /// Three markers on one rigid body moving around: starting from wrong offsets, the fit
    /// recovers the true pairwise distances; a lone marker stays unconstrained.
    #[test]
    fn recovers_rigid_distances() {
        let truth = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(100.0, 0.0, 0.0), Vec3::new(0.0, 80.0, 30.0)];
        let mut samples = Vec::new();
        for f in 0..200 {
            let t = f as f64 * 0.05;
            let q = EulerOrder::XYZ.to_quat_deg([40.0 * t, 10.0 * t.sin(), 5.0 * t]);
            for o in truth {
                samples.push(Some(Vec3::new(t * 100.0, 0.0, 900.0) + q * o));
            }
            samples.push(Some(Vec3::new(0.0, 0.0, f as f64)));
        }
        let names = ["A", "B", "C", "L"].map(MarkerName::parse).to_vec();
        let take = Take::from_samples(names, &samples, 100.0).unwrap();
        let layout = crate::test_util::layout(vec![
            marker("A", "seg", [10.0, -10.0, 5.0]),
            marker("B", "seg", [130.0, 20.0, 0.0]),
            marker("C", "seg", [0.0, 50.0, 0.0]),
            marker("L", "other", [1.0, 2.0, 3.0]),
        ]);
        let (fitted, report) = fit_to_distances(&layout, &take, &DistanceFitOptions::default()).unwrap();
        assert_eq!(report.pairs.len(), 3);
        assert_eq!(report.unconstrained, vec!["L".to_string()]);
        assert!(report.rms_before_mm() > 10.0);
        assert!(report.rms_after_mm() < 0.5, "{}", report.rms_after_mm());
        assert_eq!(fitted.markers[3].offset_mm, [1.0, 2.0, 3.0]);
        let lonely = Layout { markers: vec![layout.markers[3].clone()], ..layout.clone() };
        assert_eq!(fit_to_distances(&lonely, &take, &DistanceFitOptions::default()), Err(FitError::NoPairs));
        // A template with every offset at zero still fits (coincident markers are spread).
        let mut zero = layout.clone();
        zero.markers.iter_mut().for_each(|m| m.offset_mm = [0.0; 3]);
        let (_, report) = fit_to_distances(&zero, &take, &DistanceFitOptions::default()).unwrap();
        assert!(report.rms_after_mm() < 1.0, "{}", report.rms_after_mm());
    }
}
