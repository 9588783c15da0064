//! PCA fill from marker intercorrelations (Gløersen & Federolf 2016, "Predicting missing
//! marker trajectories in human motion data using marker intercorrelations", PLoS ONE 11(3):
//! e0152616), reconstruction strategy R2, the authors' default.
//!
//! # What is implemented
//! The take is a `T x 3M` matrix of coordinates. Then:
//! 1. the *mean trajectory* (per frame, the centroid of the markers that have no gap) is
//!    subtracted from every marker, giving a frame that moves with the subject;
//! 2. for every marker `i` with gaps, separately (R2):
//!    - `d_ij`, the mean distance from `i` to every marker `j` over the frames both are
//!      captured; markers with gaps farther than `distal_threshold` times the mean of `d_i.`
//!      (`i` itself included, at 0) are dropped ("distal"), and so is any marker with a gap
//!      that overlaps a gap of `i`; markers without gaps are always kept;
//!    - the *complete* frames are those where `i` and every kept marker are captured; their
//!      per-column mean and standard deviation normalise the data (a zero deviation counts
//!      as 1), then each marker's 3 columns are multiplied by the weight
//!      `w_j = exp(-d_ij^2 / (2 sigma^2))` (`sigma` = `weight_scale_mm`, 200 mm), `i`'s own by
//!      `missing_marker_weight` (0.02);
//!    - two PCAs: of the complete frames `N`, and of the same frames with `i`'s columns set
//!      to zero `N0`; each keeps the leading components whose *singular values* sum to
//!      `min_cumulative_sv` (99%) of the total, and both keep the larger of the two counts `k`;
//!    - each frame where `i` is missing, with `i`'s columns zero, is mapped into `N0`'s basis,
//!      through `T = PC_N^T PC_N0` into `N`'s basis and back to coordinates:
//!      `x = m0 PC_N0 T PC_N^T` (the paper's reconstruction, from Federolf 2013, Eq. 1); `i`'s
//!      columns of `x`, un-weighted, de-normalised and with the mean trajectory added back,
//!      are the fill.
//!
//! The PCAs are eigen-decompositions (nalgebra `SymmetricEigen`) of covariance matrices
//! accumulated over the complete frames in blocks, never an SVD of the `T x 3M` matrix, so a
//! 72,000-frame take of 41 markers takes seconds. `d_ij` is averaged over at most
//! [`DISTANCE_FRAMES`] evenly spaced frames (the authors' later code also subsamples).
//!
//! # Departures, where the paper's method has no answer
//! - No marker is gap-free: the mean trajectory is the centroid of all markers after a
//!   linear pre-fill ([`super::linear`]) instead.
//! - Fewer than [`MIN_COMPLETE_FRAMES`] complete frames for marker `i`: the other markers are
//!   taken from the linear pre-fill (no overlap rule then), and every frame where `i` is
//!   captured counts as complete.
//! - A marker never captured stays missing; a marker never seen together with `i` counts as
//!   distal.
//!
//! # Left out
//! Strategy R1 (all gaps reconstructed at once with the smallest distance as weight) and any
//! iteration: the published method is a single projection, not an iterative imputation
//! (project, replace the missing entries, repeat), so none is done here.

use super::{linear, put};
use crate::Filled;
use locap_core::{Take, Vec3};
use nalgebra::{DMatrix, SymmetricEigen};
use serde::{Deserialize, Serialize};

/// Most frames the marker-to-marker mean distances are averaged over.
pub const DISTANCE_FRAMES: usize = 10_000;
/// Fewest complete frames for a PCA of a marker's neighbourhood before falling back to a
/// linear pre-fill of the other markers.
pub const MIN_COMPLETE_FRAMES: usize = 10;
/// Frames per block when accumulating a covariance matrix.
const BLOCK: usize = 2048;

/// Parameters of the PCA fill; the defaults are the authors'.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PcaConfig {
    /// `sigma` of the distance weighting `exp(-d^2 / (2 sigma^2))`, in mm (200).
    pub weight_scale_mm: f64,
    /// Weight of the missing marker's own columns (0.02).
    pub missing_marker_weight: f64,
    /// Markers with gaps farther than this times the mean distance are dropped (0.5).
    pub distal_threshold: f64,
    /// Fraction of the summed singular values the kept components must reach (0.99).
    pub min_cumulative_sv: f64,
}

impl Default for PcaConfig {
    fn default() -> PcaConfig {
        PcaConfig {
            weight_scale_mm: 200.0,
            missing_marker_weight: 0.02,
            distal_threshold: 0.5,
            min_cumulative_sv: 0.99,
        }
    }
}

/// Fills every gap of every marker of `take` by the PCA method (strategy R2).
pub fn fill(take: &Take, config: &PcaConfig) -> Filled {
    let frames = take.frame_count();
    let markers = take.marker_count();
    let mut out = Filled::unchanged(take);
    let seen: Vec<bool> = (0..markers).map(|k| (0..frames).any(|f| take.is_valid(f, k))).collect();
    let gapped: Vec<bool> = (0..markers).map(|k| (0..frames).any(|f| !take.is_valid(f, k))).collect();
    if !(0..markers).any(|k| seen[k] && gapped[k]) {
        return out;
    }
    let prefill = linear::fill(take).take;
    let centre = mean_trajectory(take, &prefill, &seen, &gapped);
    for i in (0..markers).filter(|k| seen[*k] && gapped[*k]) {
        let distances = mean_distances(take, i);
        fill_marker(take, &prefill, &centre, &distances, &seen, &gapped, i, config, &mut out);
    }
    out
}

/// Per frame, the centroid of the gap-free markers (of all seen markers after the linear
/// pre-fill when every marker has a gap).
fn mean_trajectory(take: &Take, prefill: &Take, seen: &[bool], gapped: &[bool]) -> Vec<Vec3> {
    let complete: Vec<usize> = (0..take.marker_count()).filter(|k| seen[*k] && !gapped[*k]).collect();
    let (source, chosen) = if complete.is_empty() {
        (prefill, (0..take.marker_count()).filter(|k| seen[*k]).collect())
    } else {
        (take, complete)
    };
    (0..take.frame_count())
        .map(|f| {
            let points: Vec<Vec3> = chosen.iter().filter_map(|k| source.position_mm(f, *k)).collect();
            points.iter().sum::<Vec3>() / points.len().max(1) as f64
        })
        .collect()
}

/// Mean distance from marker `i` to every marker over the frames both are captured (sampled
/// evenly, at most [`DISTANCE_FRAMES`] frames); `None` if never captured together.
fn mean_distances(take: &Take, i: usize) -> Vec<Option<f64>> {
    let frames = take.frame_count();
    let stride = frames.div_ceil(DISTANCE_FRAMES).max(1);
    let mut sum = vec![0.0; take.marker_count()];
    let mut count = vec![0usize; take.marker_count()];
    for f in (0..frames).step_by(stride) {
        let Some(p) = take.position_mm(f, i) else { continue };
        for (j, (s, c)) in sum.iter_mut().zip(count.iter_mut()).enumerate() {
            if let Some(q) = take.position_mm(f, j) {
                *s += (p - q).norm();
                *c += 1;
            }
        }
    }
    sum.iter().zip(&count).map(|(s, c)| (*c > 0).then(|| s / *c as f64)).collect()
}

/// Reconstructs the gaps of marker `i` (strategy R2) into `out`.
#[allow(clippy::too_many_arguments)]
fn fill_marker(
    take: &Take,
    prefill: &Take,
    centre: &[Vec3],
    distances: &[Option<f64>],
    seen: &[bool],
    gapped: &[bool],
    i: usize,
    config: &PcaConfig,
    out: &mut Filled,
) {
    let frames = take.frame_count();
    let markers = take.marker_count();
    let missing: Vec<usize> = (0..frames).filter(|f| !take.is_valid(*f, i)).collect();
    let known: Vec<f64> = distances.iter().flatten().copied().collect();
    let threshold = config.distal_threshold * known.iter().sum::<f64>() / known.len().max(1) as f64;
    let near = |j: usize| distances[j].is_some_and(|d| d <= threshold);
    let overlaps = |j: usize| missing.iter().any(|f| !take.is_valid(*f, j));
    // Strategy R2 on the captured data, as published.
    let mut kept: Vec<usize> =
        (0..markers).filter(|j| *j == i || (seen[*j] && (!gapped[*j] || (near(*j) && !overlaps(*j))))).collect();
    let mut source = take;
    let mut fit: Vec<usize> = (0..frames).filter(|f| kept.iter().all(|j| take.is_valid(*f, *j))).collect();
    if fit.len() < MIN_COMPLETE_FRAMES {
        // Fallback: other markers from the linear pre-fill, complete wherever `i` is captured.
        kept = (0..markers).filter(|j| *j == i || (seen[*j] && (!gapped[*j] || near(*j)))).collect();
        source = prefill;
        fit = (0..frames).filter(|f| take.is_valid(*f, i)).collect();
    }
    let own = kept.iter().position(|j| *j == i).expect("i is kept");
    let weights: Vec<f64> = kept
        .iter()
        .map(|j| match (*j == i, distances[*j]) {
            (true, _) => config.missing_marker_weight,
            (false, Some(d)) => (-d * d / (2.0 * config.weight_scale_mm.powi(2))).exp(),
            (false, None) => 0.0,
        })
        .collect();
    let cols = 3 * kept.len();
    // Row of coordinates of the kept markers at frame f, relative to the mean trajectory;
    // `i`'s columns are zero where `i` is missing.
    let row = |f: usize, buf: &mut [f64]| {
        for (slot, j) in kept.iter().enumerate() {
            let p = if *j == i { take.position_mm(f, i) } else { source.position_mm(f, *j) };
            let p = p.map(|p| p - centre[f]).unwrap_or_else(Vec3::zeros);
            buf[3 * slot..3 * slot + 3].copy_from_slice(p.as_slice());
        }
    };
    // Mean and population standard deviation over the complete frames.
    let mut buf = vec![0.0; cols];
    let mut mean = vec![0.0; cols];
    let mut sq = vec![0.0; cols];
    for f in &fit {
        row(*f, &mut buf);
        for c in 0..cols {
            mean[c] += buf[c];
        }
    }
    let n = fit.len() as f64;
    mean.iter_mut().for_each(|m| *m /= n);
    for f in &fit {
        row(*f, &mut buf);
        for c in 0..cols {
            sq[c] += (buf[c] - mean[c]).powi(2);
        }
    }
    let scale: Vec<f64> = (0..cols)
        .map(|c| {
            let sd = (sq[c] / n).sqrt();
            weights[c / 3] / if sd > 0.0 { sd } else { 1.0 }
        })
        .collect();
    // Covariance of the normalised, weighted complete frames, accumulated block by block.
    let mut cov = DMatrix::<f64>::zeros(cols, cols);
    for block in fit.chunks(BLOCK) {
        let mut a = DMatrix::<f64>::zeros(cols, block.len());
        for (k, f) in block.iter().enumerate() {
            row(*f, &mut buf);
            for c in 0..cols {
                a[(c, k)] = (buf[c] - mean[c]) * scale[c];
            }
        }
        cov += &a * a.transpose();
    }
    cov /= (n - 1.0).max(1.0);
    let mut cov_zero = cov.clone();
    for c in 3 * own..3 * own + 3 {
        cov_zero.row_mut(c).fill(0.0);
        cov_zero.column_mut(c).fill(0.0);
    }
    let (pc, sv) = principal_components(cov);
    let (pc_zero, sv_zero) = principal_components(cov_zero);
    let k = components(&sv, config.min_cumulative_sv).max(components(&sv_zero, config.min_cumulative_sv));
    let pc = pc.columns(0, k);
    let pc_zero = pc_zero.columns(0, k);
    let transform = pc.transpose() * pc_zero;
    // Only `i`'s three output columns are needed: B = PC_N0 T PC_N^T restricted to them.
    let b = pc_zero * transform * pc.rows(3 * own, 3).transpose();
    for f in missing {
        row(f, &mut buf);
        let mut x = Vec3::zeros();
        for c in (0..cols).filter(|c| c / 3 != own) {
            let z = (buf[c] - mean[c]) * scale[c];
            for axis in 0..3 {
                x[axis] += z * b[(c, axis)];
            }
        }
        let p = Vec3::from_fn(|axis, _| {
            let c = 3 * own + axis;
            mean[c] + x[axis] / scale[c]
        }) + centre[f];
        put(out, f, i, p);
    }
}

/// Eigenvectors of a covariance matrix as columns, largest eigenvalue first, with the square
/// roots of the eigenvalues (the singular values of the data matrix, up to a constant).
fn principal_components(cov: DMatrix<f64>) -> (DMatrix<f64>, Vec<f64>) {
    let eigen = SymmetricEigen::new(cov);
    let mut order: Vec<usize> = (0..eigen.eigenvalues.len()).collect();
    order.sort_by(|a, b| eigen.eigenvalues[*b].total_cmp(&eigen.eigenvalues[*a]));
    let vectors = DMatrix::from_fn(eigen.eigenvectors.nrows(), order.len(), |r, c| eigen.eigenvectors[(r, order[c])]);
    let sv = order.iter().map(|k| eigen.eigenvalues[*k].max(0.0).sqrt()).collect();
    (vectors, sv)
}

/// Smallest number of leading singular values that reach `fraction` of their sum (at least 1).
fn components(sv: &[f64], fraction: f64) -> usize {
    let total: f64 = sv.iter().sum();
    let mut running = 0.0;
    for (k, s) in sv.iter().enumerate() {
        running += s;
        if running >= fraction * total {
            return k + 1;
        }
    }
    sv.len().max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baseline::testing::{check_mask, hide, take_from};

    /// Twelve markers on four segments ~300 mm apart, three markers each within ~50 mm; the
    /// motion is a linear mix of three latent signals (a rank-4 trajectory matrix, drift
    /// included), each marker with its own small share.
    fn low_rank(frames: usize) -> Take {
        take_from(frames, 12, |t, m| {
            let s = t as f64 * 0.02;
            let latent = [s.sin(), (1.7 * s).cos(), (0.6 * s + 1.0).sin()];
            let segment = m / 3;
            let home = Vec3::new(300.0 * segment as f64, 0.0, 1000.0)
                + Vec3::new(30.0 * (m % 3) as f64, 40.0 * ((m + 1) % 2) as f64, 10.0 * m as f64);
            let mut p = home + Vec3::new(3.0 * t as f64, 0.0, 0.0);
            for (l, a) in latent.iter().enumerate() {
                let k = (segment * 3 + l) as f64;
                let own = (m * 3 + l) as f64;
                p += Vec3::new((k * 1.3).sin(), (k * 0.7).cos(), (k * 2.1).sin()) * (60.0 * a)
                    + Vec3::new(own.cos(), own.sin(), 0.5) * (5.0 * a);
            }
            p
        })
    }

    fn mean_error(out: &Filled, truth: &Take, marker: usize, frames: impl Iterator<Item = usize>) -> f64 {
        let errors: Vec<f64> = frames
            .map(|f| (out.take.position_mm(f, marker).unwrap() - truth.position_mm(f, marker).unwrap()).norm())
            .collect();
        errors.iter().sum::<f64>() / errors.len() as f64
    }

    #[test]
    fn low_rank_motion_is_recovered() {
        let truth = low_rank(1000);
        let mut holed = truth.clone();
        hide(&mut holed, 0, 300..420);
        hide(&mut holed, 5, (0..50).chain(600..700));
        let out = fill(&holed, &PcaConfig::default());
        assert_eq!(check_mask(&holed, &out), 120 + 150);
        let pca = mean_error(&out, &truth, 0, 300..420);
        let lin = linear::fill(&holed);
        let lin = mean_error(&lin, &truth, 0, 300..420);
        assert!(pca < 1.0 && pca < lin / 20.0, "pca {pca} mm, linear {lin} mm");
        assert!(mean_error(&out, &truth, 5, 0..50) < 1.0);
    }

    #[test]
    fn every_marker_gapped_and_never_seen_markers() {
        let truth = low_rank(400);
        let mut holed = truth.clone();
        for m in 0..11 {
            hide(&mut holed, m, (m * 30)..(m * 30 + 20));
        }
        hide(&mut holed, 11, 0..400);
        let out = fill(&holed, &PcaConfig::default());
        assert_eq!(check_mask(&holed, &out), 11 * 20);
        assert!((0..400).all(|f| !out.take.is_valid(f, 11)));
        for m in 0..11 {
            let e = mean_error(&out, &truth, m, (m * 30)..(m * 30 + 20));
            assert!(e < 2.0, "marker {m}: {e} mm");
        }
    }

    #[test]
    fn no_complete_frames_falls_back_to_prefill() {
        // Markers 0 and 1 alternate: no frame shows both, and they are near each other.
        let truth = low_rank(300);
        let mut holed = truth.clone();
        for f in 0..300 {
            hide(&mut holed, (f / 25) % 2, [f]);
        }
        let out = fill(&holed, &PcaConfig::default());
        assert_eq!(check_mask(&holed, &out), 300);
    }

    #[test]
    fn component_count() {
        assert_eq!(components(&[9.0, 0.9, 0.1], 0.99), 2);
        assert_eq!(components(&[0.0, 0.0], 0.99), 1);
    }
}
