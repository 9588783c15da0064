//! Distance-constrained smoothing: a gap filled as the least-squares trajectory that agrees
//! with the distances to the marker's neighbours and with its own motion at the borders.
//!
//! The locality EDM fill ([`crate::edm`], LocalMoCap section 3.1, Eq. 1-2) places a marker
//! frame by frame from the distances to its neighbours interpolated between the gap's
//! borders. It trusts every interpolated distance alike, ignores how the marker was moving
//! at the borders, and fills a marker whose steadiest neighbours are missing with it (a whole
//! forearm occluded) from the others alone. Tits et al. (2018, "mcrecovery") add soft
//! skeleton constraints to their gap fills: the distances between markers of one segment
//! are held. This fill states those ideas as one least-squares problem over every missing
//! sample of the gap, the marker's and those of its best neighbours missing with it
//! ([`DistanceConfig::partners`]):
//! - each pair of such a marker and another marker of the neighbourhood keeps its distance
//!   interpolated between the gap's borders, weighted by `1 / sigma`, `sigma` being how far
//!   that pair's distance strays from its own interpolation over windows of the gap's length
//!   near the gap (a pair on one segment holds the marker to a few millimetres, a pair
//!   across a turning joint barely counts);
//! - each missing marker stays near its cubic Hermite prediction from the border samples and
//!   velocities, weighted by `1 / sigma` of that prediction over windows of the same length
//!   near the gap (over a few frames the prediction is hard to beat; over a second it is
//!   off by decimetres and the distances decide).
//!
//! Markers missing together keep their shape, since their pairs enter with both unknown. The
//! problem starts from the EDM fill (linear interpolation where EDM leaves a frame) and is
//! solved by Gauss-Newton with Levenberg damping. Its normal matrix is banded (a sample meets
//! only the samples of its own frame), solved by a banded Cholesky factorisation written
//! here (`O(n b^2)`, `n` unknowns, band `b`), no dense solve of every sample at once.
//!
//! Distances fix a point only up to its mirror image in the plane of the neighbours that
//! hold it, and a neighbourhood that is nearly flat fixes it poorly across that plane; the
//! start from EDM (whose alignment chooses the mirror image) and the Hermite term keep the
//! solution on the right side. Gaps touching the take's start or end keep the EDM fill: with
//! one border the distances have nothing to be interpolated towards.
//!
//! Alone it beats EDM on realistic gaps, but not where a whole segment is missing: with a
//! forearm gone, its distances to the markers that remain change together with the elbow,
//! and the interpolated targets are wrong together. Its use is as a candidate of the per-gap
//! choice ([`crate::auto`]), whose blends gain from a fill whose errors differ from EDM's and
//! the interpolations' (docs/benchmarks.md, "Distance-constrained smoothing").

use crate::neighbours::{self, Selection};
use crate::{Filled, baseline, edm};
use locap_core::gaps::{Gap, gaps_of};
use locap_core::{Take, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// Settings of [`fill`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DistanceConfig {
    /// EDM's neighbour count `K` for the starting fill.
    pub edm_neighbours: usize,
    /// How neighbours are ranked.
    pub selection: Selection,
    /// Neighbours of the marker whose distances enter the problem.
    pub markers: usize,
    /// How many of the best of them, where missing with the marker, are solved with it
    /// (the rest keep the starting fill).
    pub partners: usize,
    /// Added in quadrature to every pair's `sigma` (mm): marker noise, and a cap on the
    /// weight of a pair that happened to stay exactly constant near the gap.
    pub floor_mm: f64,
    /// Most Gauss-Newton steps.
    pub iterations: usize,
    /// Frames either side of a gap (in seconds, at least the gap's length) whose captured
    /// samples give the pairs' and the prior's spreads.
    pub context_s: f64,
}

impl Default for DistanceConfig {
    fn default() -> DistanceConfig {
        DistanceConfig {
            edm_neighbours: 6,
            selection: Selection::Variance,
            markers: 10,
            partners: 3,
            floor_mm: 2.0,
            iterations: 10,
            context_s: 2.0,
        }
    }
}

/// Fills every gap of `take`: interior gaps by distance-constrained smoothing, the rest as
/// the starting fill (EDM) left them.
pub fn fill(take: &Take, config: &DistanceConfig) -> Filled {
    let start = starting_fill(&edm::fill(take, config.edm_neighbours, config.selection));
    let ranked = neighbours::rank_scored(take, config.selection);
    let frames = take.frame_count();
    let work: Vec<(usize, Gap)> = (0..take.marker_count())
        .flat_map(|i| gaps_of((0..frames).map(|f| take.is_valid(f, i))).into_iter().map(move |g| (i, g)))
        .filter(|(_, g)| g.start > 0 && g.end() < frames)
        .collect();
    let refined: Vec<(usize, Vec<(usize, Vec3)>)> = work
        .par_iter()
        .map(|(i, g)| (*i, refine_gap(take, &start.take, *i, &members(&ranked[*i], *i, config), *g, config)))
        .collect();
    let mut out = start;
    for (i, samples) in refined {
        for (f, p) in samples {
            let _ = out.take.set_position_mm(f, i, Some(p));
        }
    }
    out
}

/// `marker`'s fill over `range` (the samples missing in `take` there; `None` where nothing
/// filled them), the rest of the take serving as its neighbourhood: what the per-gap choice
/// ([`crate::auto`]) runs on its sub-takes.
pub fn fill_marker(take: &Take, marker: usize, range: Range<usize>, config: &DistanceConfig) -> Vec<Option<Vec3>> {
    fill_marker_from(take, &edm::fill(take, config.edm_neighbours, config.selection), marker, range, config)
}

/// [`fill_marker`] from `edm`, the take's EDM fill with `config`'s neighbours (the per-gap
/// choice has it already).
pub fn fill_marker_from(
    take: &Take,
    edm: &Filled,
    marker: usize,
    range: Range<usize>,
    config: &DistanceConfig,
) -> Vec<Option<Vec3>> {
    let start = starting_fill(edm);
    let frames = take.frame_count();
    let mut out: Vec<Option<Vec3>> = range.clone().map(|f| start.take.position_mm(f, marker)).collect();
    let near = members(&neighbours::rank_scored_of(take, marker, config.selection), marker, config);
    for g in gaps_of((0..frames).map(|f| take.is_valid(f, marker))) {
        if g.start == 0 || g.end() == frames || g.end() <= range.start || g.start >= range.end {
            continue;
        }
        for (f, p) in refine_gap(take, &start.take, marker, &near, g, config) {
            if range.contains(&f) {
                out[f - range.start] = Some(p);
            }
        }
    }
    out
}

/// The EDM fill `edm`, then linear interpolation where EDM left an interior sample missing.
fn starting_fill(edm: &Filled) -> Filled {
    let linear = baseline::linear::fill(&edm.take);
    let filled = edm.filled.iter().zip(&linear.filled).map(|(a, b)| *a || *b).collect();
    Filled { take: linear.take, filled }
}

/// `marker` and its best `config.markers` neighbours (finite variance), marker first.
fn members(ranked: &[(usize, f64)], marker: usize, config: &DistanceConfig) -> Vec<usize> {
    let mut list = vec![marker];
    list.extend(ranked.iter().filter(|(_, v)| v.is_finite()).map(|(j, _)| *j).take(config.markers));
    list
}

/// One term of the least-squares problem, its samples resolved once (the solve evaluates
/// every term a few dozen times).
enum Term {
    /// `(|p_a - p_b| - target) * weight` at one frame.
    Distance { a: Point, b: Point, target: f64, weight: f64 },
    /// `(x[unknown] - target) * weight`, three residuals: the temporal prediction.
    Temporal { unknown: usize, target: Vec3, weight: f64 },
}

/// A sample in a term: one of the unknowns, or a position the solve does not move.
#[derive(Clone, Copy)]
enum Point {
    Unknown(usize),
    Known(Vec3),
}

impl Point {
    fn at(self, x: &[Vec3]) -> Vec3 {
        match self {
            Point::Unknown(i) => x[i],
            Point::Known(p) => p,
        }
    }

    fn unknown(self) -> Option<usize> {
        match self {
            Point::Unknown(i) => Some(i),
            Point::Known(_) => None,
        }
    }
}

/// The refined samples of `marker` over `gap`, `(frame, position)`: the joint solution over
/// the gap's frames of every missing sample of `near` (the marker first), starting from
/// `start` (the take filled by the starting fill).
fn refine_gap(
    take: &Take,
    start: &Take,
    marker: usize,
    near: &[usize],
    gap: Gap,
    config: &DistanceConfig,
) -> Vec<(usize, Vec3)> {
    let frames = take.frame_count();
    let (s, e) = (gap.start, gap.end());
    let len = gap.len;
    let context = ((config.context_s * take.frame_rate_hz()).round() as usize).max(len);
    let around = s.saturating_sub(context)..(e + context).min(frames);
    // The unknowns: samples of `near` missing in the take over the gap that the start filled.
    // Only the best-ranked neighbours missing with the marker are solved with it: they are what
    // holds its shape, and every further one adds unknowns (on a take missing a fifth of its
    // samples, twice the cost) for little.
    let unknown_markers: Vec<usize> = near
        .iter()
        .take(1 + config.partners)
        .copied()
        .filter(|a| *a == marker || (s..e).any(|t| !take.is_valid(t, *a) && start.is_valid(t, *a)))
        .collect();
    let mut index = vec![usize::MAX; len * near.len()];
    let mut x: Vec<Vec3> = Vec::new();
    let slot = |t: usize, k: usize| (t - s) * near.len() + k;
    for t in s..e {
        for (k, a) in near.iter().enumerate() {
            if unknown_markers.contains(a)
                && !take.is_valid(t, *a)
                && let Some(p) = start.position_mm(t, *a)
            {
                index[slot(t, k)] = x.len();
                x.push(p);
            }
        }
    }
    if x.is_empty() {
        return Vec::new();
    }
    let k_of = |a: usize| near.iter().position(|j| *j == a).unwrap_or(usize::MAX);
    let var = |t: usize, a: usize| -> Option<usize> {
        if !(s..e).contains(&t) {
            return None;
        }
        let i = index[slot(t, k_of(a))];
        (i != usize::MAX).then_some(i)
    };
    let point = |t: usize, a: usize| match var(t, a) {
        Some(i) => Point::Unknown(i),
        None => Point::Known(start.position_mm(t, a).unwrap_or_else(Vec3::zeros)),
    };
    let floor2 = config.floor_mm * config.floor_mm;
    let mut terms: Vec<Term> = Vec::new();
    for (ka, &a) in near.iter().enumerate() {
        if !unknown_markers.contains(&a) {
            continue;
        }
        // The temporal prediction of each of `a`'s own gaps that overlap this one.
        for own in gaps_of((0..frames).map(|f| take.is_valid(f, a))) {
            if own.end() <= s || own.start >= e || own.start == 0 || own.end() == frames {
                continue;
            }
            let Some(spread2) = hermite_spread2(take, a, own.len, around.clone()) else { continue };
            let weight = 1.0 / (spread2 + floor2).sqrt();
            for t in own.start.max(s)..own.end().min(e) {
                if let Some(unknown) = var(t, a)
                    && let Some(target) = hermite(take, a, own, t)
                {
                    terms.push(Term::Temporal { unknown, target, weight });
                }
            }
        }
        for (kb, &b) in near.iter().enumerate() {
            // Each pair once: an unknown with every known marker, and two unknowns in order.
            if kb == ka || (unknown_markers.contains(&b) && kb < ka) {
                continue;
            }
            let dist = |f: usize| Some((start.position_mm(f, a)? - start.position_mm(f, b)?).norm());
            let (Some(d0), Some(d1)) = (dist(s - 1), dist(e)) else { continue };
            let Some(spread2) = pair_spread2(take, a, b, len, around.clone()) else { continue };
            let weight = 1.0 / (spread2 + floor2).sqrt();
            for t in s..e {
                let (pa, pb) = (point(t, a), point(t, b));
                let involved = pa.unknown().is_some() || pb.unknown().is_some();
                if involved && start.is_valid(t, a) && start.is_valid(t, b) {
                    let w = (t + 1 - s) as f64 / (len + 1) as f64;
                    terms.push(Term::Distance { a: pa, b: pb, target: d0 + (d1 - d0) * w, weight });
                }
            }
        }
    }
    // Bandwidth (in samples) of the normal matrix.
    let mut band = 0usize;
    for term in &terms {
        if let Term::Distance { a: Point::Unknown(i), b: Point::Unknown(j), .. } = term {
            band = band.max(i.abs_diff(*j));
        }
    }
    let cost = |x: &[Vec3]| -> f64 {
        terms
            .iter()
            .map(|term| match term {
                Term::Distance { a, b, target, weight } => {
                    let r = ((a.at(x) - b.at(x)).norm() - target) * weight;
                    r * r
                }
                Term::Temporal { unknown, target, weight } => ((x[*unknown] - target) * *weight).norm_squared(),
            })
            .sum()
    };
    let n = 3 * x.len();
    let mut damping = 1e-3;
    let mut current = cost(&x);
    for _ in 0..config.iterations {
        let mut normal = Banded::zeros(n, 3 * band + 2);
        let mut gradient = vec![0.0; n];
        for term in &terms {
            // Each term adds `J^T r` to the gradient and `J^T J` to the normal matrix, over
            // the unknowns it touches.
            match term {
                Term::Distance { a, b, target, weight } => {
                    let d = a.at(&x) - b.at(&x);
                    let norm = d.norm().max(1e-9);
                    let u = d / norm * *weight;
                    let r = (norm - target) * weight;
                    let parts = [(a.unknown(), u), (b.unknown(), -u)];
                    let parts = parts.iter().filter_map(|(v, g)| Some((v.as_ref()?, g)));
                    for (p, gp) in parts.clone() {
                        for c in 0..3 {
                            gradient[3 * p + c] += gp[c] * r;
                        }
                        for (q, gq) in parts.clone() {
                            for c in 0..3 {
                                for c2 in 0..3 {
                                    normal.add(3 * p + c, 3 * q + c2, gp[c] * gq[c2]);
                                }
                            }
                        }
                    }
                }
                Term::Temporal { unknown: p, target, weight } => {
                    let r = (x[*p] - target) * *weight;
                    for c in 0..3 {
                        gradient[3 * p + c] += weight * r[c];
                        normal.add(3 * p + c, 3 * p + c, weight * weight);
                    }
                }
            }
        }
        let mut improved = false;
        for _ in 0..6 {
            let mut system = normal.clone();
            for i in 0..n {
                let d = system.get(i, i);
                system.add(i, i, damping * d.max(1e-9));
            }
            let Some(step) = system.solve(&gradient) else {
                damping *= 10.0;
                continue;
            };
            let trial: Vec<Vec3> = x
                .iter()
                .enumerate()
                .map(|(i, p)| p - Vec3::new(step[3 * i], step[3 * i + 1], step[3 * i + 2]))
                .collect();
            let value = cost(&trial);
            if value.is_finite() && value <= current {
                let moved = step.iter().map(|v| v * v).sum::<f64>().sqrt();
                x = trial;
                current = value;
                damping = (damping * 0.3).max(1e-9);
                improved = moved > 1e-3;
                break;
            }
            damping *= 10.0;
        }
        if !improved {
            break;
        }
    }
    (s..e).filter_map(|t| var(t, marker).map(|i| (t, x[i]))).filter(|(_, p)| p.iter().all(|v| v.is_finite())).collect()
}

/// The cubic Hermite prediction of `marker` at frame `t` inside its interior gap `gap`, from
/// the border samples and the velocities just outside them (the border's slope where the
/// sample before it is missing too).
fn hermite(take: &Take, marker: usize, gap: Gap, t: usize) -> Option<Vec3> {
    let (b0, b1) = (gap.start.checked_sub(1)?, gap.end());
    let p0 = take.position_mm(b0, marker)?;
    let p1 = take.position_mm(b1, marker)?;
    let h = (b1 - b0) as f64;
    let chord = (p1 - p0) / h;
    let v0 = b0.checked_sub(1).and_then(|f| take.position_mm(f, marker)).map_or(chord, |q| p0 - q);
    let after = (b1 + 1 < take.frame_count()).then(|| take.position_mm(b1 + 1, marker)).flatten();
    let v1 = after.map_or(chord, |q| q - p1);
    let u = (t - b0) as f64 / h;
    let (u2, u3) = (u * u, u * u * u);
    Some(
        p0 * (2.0 * u3 - 3.0 * u2 + 1.0)
            + v0 * h * (u3 - 2.0 * u2 + u)
            + p1 * (-2.0 * u3 + 3.0 * u2)
            + v1 * h * (u3 - u2),
    )
}

/// Mean squared error per axis (mm^2) of the Hermite prediction ([`hermite`]) of `marker`
/// over windows of `len` frames in `frames` where it is captured; `None` without a window.
fn hermite_spread2(take: &Take, marker: usize, len: usize, frames: Range<usize>) -> Option<f64> {
    let step = (len / 8).max(1);
    let (mut sum, mut count) = (0.0, 0usize);
    let mut c = frames.start + 2;
    while c + len + 2 < frames.end {
        let gap = Gap { start: c, len };
        if (c - 2..c + len + 2).all(|f| take.is_valid(f, marker)) {
            for t in c..c + len {
                if let (Some(p), Some(q)) = (hermite(take, marker, gap, t), take.position_mm(t, marker)) {
                    sum += (p - q).norm_squared() / 3.0;
                    count += 1;
                }
            }
        }
        c += step;
    }
    (count >= len.max(1)).then(|| sum / count as f64)
}

/// Mean squared departure (mm^2) of the distance between `a` and `b` from its linear
/// interpolation over windows of `len` frames in `frames` where both are captured at the
/// window's borders; without such a window, the distance's variance over `frames`; `None`
/// where they are never captured together.
fn pair_spread2(take: &Take, a: usize, b: usize, len: usize, frames: Range<usize>) -> Option<f64> {
    let dist = |f: usize| Some((take.position_mm(f, a)? - take.position_mm(f, b)?).norm());
    let step = (len / 8).max(1);
    let (mut sum, mut count) = (0.0, 0usize);
    let mut c = frames.start;
    while c + len + 1 < frames.end {
        if let (Some(d0), Some(d1)) = (dist(c), dist(c + len + 1)) {
            for t in c + 1..=c + len {
                if let Some(d) = dist(t) {
                    let w = (t - c) as f64 / (len + 1) as f64;
                    let dev = d - (d0 + (d1 - d0) * w);
                    sum += dev * dev;
                    count += 1;
                }
            }
        }
        c += step;
    }
    if count >= len.max(1) {
        return Some(sum / count as f64);
    }
    let seen: Vec<f64> = frames.filter_map(dist).collect();
    if seen.len() < 2 {
        return None;
    }
    let mean = seen.iter().sum::<f64>() / seen.len() as f64;
    Some(seen.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / seen.len() as f64)
}

/// A symmetric banded matrix, lower half stored by rows: entry `(i, j)`, `i >= j`, `i - j <=
/// band`, at `data[i * (band + 1) + i - j]`.
#[derive(Clone)]
struct Banded {
    n: usize,
    band: usize,
    data: Vec<f64>,
}

impl Banded {
    fn zeros(n: usize, band: usize) -> Banded {
        let band = band.min(n.saturating_sub(1));
        Banded { n, band, data: vec![0.0; n * (band + 1)] }
    }

    fn get(&self, i: usize, j: usize) -> f64 {
        let (i, j) = if i >= j { (i, j) } else { (j, i) };
        if i - j > self.band { 0.0 } else { self.data[i * (self.band + 1) + i - j] }
    }

    /// Adds `v` at `(i, j)` when `i >= j` (the symmetric half is implied; calls with `i < j`
    /// are skipped, as every caller adds both halves).
    fn add(&mut self, i: usize, j: usize, v: f64) {
        if i >= j && i - j <= self.band {
            self.data[i * (self.band + 1) + i - j] += v;
        }
    }

    /// Solves `self * x = b` by Cholesky factorisation in the band; `None` when the matrix is
    /// not positive definite.
    fn solve(mut self, b: &[f64]) -> Option<Vec<f64>> {
        let (n, w) = (self.n, self.band + 1);
        for i in 0..n {
            let lo = i.saturating_sub(self.band);
            for j in lo..=i {
                let mut sum = self.data[i * w + i - j];
                for k in lo.max(j.saturating_sub(self.band))..j {
                    sum -= self.data[i * w + i - k] * self.data[j * w + j - k];
                }
                if i == j {
                    if !(sum > 0.0) {
                        return None;
                    }
                    self.data[i * w] = sum.sqrt();
                } else {
                    self.data[i * w + i - j] = sum / self.data[j * w];
                }
            }
        }
        let mut y = b.to_vec();
        for i in 0..n {
            let lo = i.saturating_sub(self.band);
            for k in lo..i {
                y[i] -= self.data[i * w + i - k] * y[k];
            }
            y[i] /= self.data[i * w];
        }
        for i in (0..n).rev() {
            for k in i + 1..(i + w).min(n) {
                y[i] -= self.data[k * w + k - i] * y[k];
            }
            y[i] /= self.data[i * w];
        }
        Some(y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baseline::testing::{hide, take_from};

    #[test]
    fn banded_cholesky_solves_a_banded_system() {
        let n = 12;
        let mut m = Banded::zeros(n, 2);
        for i in 0..n {
            m.add(i, i, 4.0);
            if i >= 1 {
                m.add(i, i - 1, -1.0);
            }
            if i >= 2 {
                m.add(i, i - 2, 0.5);
            }
        }
        let truth: Vec<f64> = (0..n).map(|i| i as f64 * 0.3 - 1.0).collect();
        let b: Vec<f64> = (0..n).map(|i| (0..n).map(|j| m.get(i, j) * truth[j]).sum()).collect();
        let x = m.solve(&b).unwrap();
        for (a, t) in x.iter().zip(&truth) {
            assert!((a - t).abs() < 1e-12, "{a} {t}");
        }
    }

    #[test]
    fn a_rigid_cluster_missing_together_keeps_its_shape() {
        // Five markers of one body turning and moving: two hidden together for 40 frames are
        // filled from the three others to well under a millimetre.
        let body = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(120.0, 0.0, 10.0),
            Vec3::new(0.0, 90.0, -20.0),
            Vec3::new(60.0, 40.0, 80.0),
            Vec3::new(-50.0, 30.0, 40.0),
        ];
        let truth = take_from(200, 5, |t, m| {
            let a = t as f64 * 0.02;
            let r = nalgebra::Rotation3::from_euler_angles(0.3 * a, a, 0.5 * a.sin());
            r * body[m] + Vec3::new(3.0 * t as f64, 200.0 * (t as f64 * 0.03).sin(), 1000.0)
        });
        let mut holed = truth.clone();
        hide(&mut holed, 0, 80..120);
        hide(&mut holed, 1, 80..120);
        let out = fill(&holed, &DistanceConfig::default());
        let mut worst: f64 = 0.0;
        for t in 80..120 {
            for m in 0..2 {
                worst = worst.max((out.take.position_mm(t, m).unwrap() - truth.position_mm(t, m).unwrap()).norm());
            }
        }
        assert!(worst < 1.0, "worst {worst} mm");
    }

    #[test]
    fn a_short_gap_follows_the_motion_at_its_borders() {
        // One marker on a smooth curve, its neighbours turning about it at other rates: no
        // distance holds, and a 10-frame gap is filled from the border motion to about a
        // millimetre (the noise floor keeps the loose distances from being ignored outright),
        // where EDM, which knows only the distances, is centimetres off.
        let truth = take_from(300, 5, |t, m| {
            let t = t as f64;
            let centre = Vec3::new(400.0 * (t * 0.01).sin(), 300.0 * (t * 0.013).cos(), 900.0 + 0.2 * t);
            if m == 0 {
                centre
            } else {
                let a = t * 0.05 * m as f64;
                centre
                    + Vec3::new(200.0 * a.cos(), 200.0 * a.sin(), 50.0 * m as f64)
                        * (1.0 + 0.3 * (t * 0.07 * m as f64).sin())
            }
        });
        let mut holed = truth.clone();
        hide(&mut holed, 0, 150..160);
        let worst_of = |fill: &dyn Fn(usize) -> Vec3| {
            (150..160).map(|t| (fill(t) - truth.position_mm(t, 0).unwrap()).norm()).fold(0.0, f64::max)
        };
        let filled = fill_marker(&holed, 0, 150..160, &DistanceConfig::default());
        let worst = worst_of(&|t| filled[t - 150].unwrap());
        let edm = edm::fill(&holed, 6, Selection::Variance);
        let edm_worst = worst_of(&|t| edm.take.position_mm(t, 0).unwrap());
        assert!(worst < 2.0 && worst * 10.0 < edm_worst, "worst {worst} mm, EDM {edm_worst} mm");
    }
}
