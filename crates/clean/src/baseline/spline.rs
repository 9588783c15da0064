//! Cubic-spline interpolation across each gap.
//!
//! For a gap `[s, e)` of one marker, the knots are the marker's visible samples nearest the
//! gap: up to [`WINDOW`] on each side, counted outward from the borders and skipping any other
//! missing frames. A *natural* cubic spline (second derivative zero at the outer knots) through
//! those knots, one per coordinate, gives the filled samples. The local window keeps the cost
//! per gap constant however long the take, and changes the fill very little: the influence of
//! a knot on a natural spline decays by about `2 - sqrt 3 ~ 0.27` per knot, so knots 8 away
//! weigh less than `3e-5`. For the same reason a cubic trajectory is reproduced to within
//! rounding near the middle of a long window, though not exactly (the natural end conditions
//! are not those of a cubic).
//!
//! Two knots give a straight line, one knot a constant. A gap touching the take's start or end
//! holds its single border sample constant: extrapolating a cubic beyond its last knot grows
//! without bound within a few frames.
//!
//! The tridiagonal system of the second derivatives is solved here (Thomas algorithm, a dozen
//! lines): no spline crate is needed for something this small, and all three coordinates
//! share one matrix, so they are solved together.
//!
//! [`spline_fill_range`] refills an arbitrary frame range of one marker the same way: the
//! outlier stage removes a window around an outlier and calls it (LocalMoCap section 3.1).

use super::{borders, put};
use crate::Filled;
use locap_core::gaps::gaps_of;
use locap_core::{Take, Vec3};
use std::ops::Range;

/// Largest number of visible samples used as knots on each side of a gap.
pub const WINDOW: usize = 8;

/// Fills every gap of every marker of `take` with a natural cubic spline through up to
/// [`WINDOW`] captured samples on each side (held constant at the take's edges).
pub fn fill(take: &Take) -> Filled {
    let mut out = Filled::unchanged(take);
    let frames = take.frame_count();
    for marker in 0..take.marker_count() {
        let trajectory = take.trajectory_mm(marker);
        for gap in gaps_of(trajectory.iter().map(Option::is_some)) {
            let _ = fill_from(&trajectory, &mut out, marker, gap.start..gap.end().min(frames));
        }
    }
    out
}

/// Removes the samples of `marker` in frames `range` (clamped to the take) and refills them
/// with a natural cubic spline through up to [`WINDOW`] samples on each side that are present
/// in `out.take` (captured or filled earlier), skipping missing frames. With samples on one
/// side only, that side's nearest sample is held constant; with none, the range stays missing.
///
/// Refilled samples are marked in `out.filled`; samples left missing are unmarked. Returns the
/// number of samples written.
pub fn spline_fill_range(out: &mut Filled, marker: usize, range: Range<usize>) -> usize {
    let frames = out.take.frame_count();
    let range = range.start.min(frames)..range.end.min(frames);
    let m = out.take.marker_count();
    let mut trajectory = out.take.trajectory_mm(marker);
    for t in range.clone() {
        trajectory[t] = None;
        // Cannot fail: removing a sample is always allowed.
        let _ = out.take.set_position_mm(t, marker, None);
        out.filled[t * m + marker] = false;
    }
    fill_from(&trajectory, out, marker, range)
}

/// Fills frames `range` of `marker` in `out` from the knots of `trajectory` around it.
fn fill_from(trajectory: &[Option<Vec3>], out: &mut Filled, marker: usize, range: Range<usize>) -> usize {
    if range.is_empty() {
        return 0;
    }
    let (before, after) = borders(range.start, range.end, trajectory.len());
    let left: Vec<usize> =
        before.map(|b| (0..=b).rev().filter(|f| trajectory[*f].is_some()).take(WINDOW).collect()).unwrap_or_default();
    let right: Vec<usize> = after
        .map(|a| (a..trajectory.len()).filter(|f| trajectory[*f].is_some()).take(WINDOW).collect())
        .unwrap_or_default();
    let knot = |f: usize| (f as f64, trajectory[f].unwrap_or_else(Vec3::zeros));
    let estimate: Box<dyn Fn(usize) -> Vec3> = match (left.first(), right.first()) {
        (None, None) => return 0,
        (Some(&l), None) => Box::new(move |_| knot(l).1),
        (None, Some(&r)) => Box::new(move |_| knot(r).1),
        (Some(_), Some(_)) => {
            let knots: Vec<(f64, Vec3)> = left.iter().rev().chain(right.iter()).map(|f| knot(*f)).collect();
            let spline = NaturalSpline::new(knots);
            Box::new(move |t| spline.at(t as f64))
        }
    };
    range.filter(|t| put(out, *t, marker, estimate(*t))).count()
}

/// A natural cubic spline through knots `(x, y)` with strictly increasing `x`, all three
/// coordinates at once.
pub struct NaturalSpline {
    knots: Vec<(f64, Vec3)>,
    /// Second derivative at each knot (zero at both ends).
    second: Vec<Vec3>,
}

impl NaturalSpline {
    /// Fits the spline. One knot gives a constant, two a straight line.
    ///
    /// # Panics
    /// If `knots` is empty (a programming error).
    pub fn new(knots: Vec<(f64, Vec3)>) -> NaturalSpline {
        assert!(!knots.is_empty(), "a spline needs at least one knot");
        let n = knots.len();
        let mut second = vec![Vec3::zeros(); n];
        if n >= 3 {
            // Rows 1..n-1: h[i-1] M[i-1] + 2 (h[i-1] + h[i]) M[i] + h[i] M[i+1] = rhs[i].
            let h: Vec<f64> = knots.windows(2).map(|w| w[1].0 - w[0].0).collect();
            let slope: Vec<Vec3> = knots.windows(2).zip(&h).map(|(w, h)| (w[1].1 - w[0].1) / *h).collect();
            // Thomas algorithm: forward sweep (c' and d'), then back substitution.
            let inner = n - 2;
            let mut c = vec![0.0; inner];
            let mut d = vec![Vec3::zeros(); inner];
            for k in 0..inner {
                let i = k + 1;
                let (sub, diag, sup) = (h[i - 1], 2.0 * (h[i - 1] + h[i]), h[i]);
                let rhs = (slope[i] - slope[i - 1]) * 6.0;
                let (c_prev, d_prev) = if k == 0 { (0.0, Vec3::zeros()) } else { (c[k - 1], d[k - 1]) };
                let denom = diag - sub * c_prev;
                c[k] = sup / denom;
                d[k] = (rhs - d_prev * sub) / denom;
            }
            for k in (0..inner).rev() {
                let next = if k + 1 < inner { second[k + 2] } else { Vec3::zeros() };
                second[k + 1] = d[k] - next * c[k];
            }
        }
        NaturalSpline { knots, second }
    }

    /// Value at `x`. Outside the knots the end segments continue (the callers here only ask
    /// between the first and last knot).
    pub fn at(&self, x: f64) -> Vec3 {
        let n = self.knots.len();
        if n == 1 {
            return self.knots[0].1;
        }
        // Segment i with knots[i].0 <= x < knots[i+1].0, clamped to the end segments.
        let i = self.knots.partition_point(|k| k.0 <= x).clamp(1, n - 1) - 1;
        let ((x0, y0), (x1, y1)) = (self.knots[i], self.knots[i + 1]);
        let (m0, m1) = (self.second[i], self.second[i + 1]);
        let h = x1 - x0;
        let (a, b) = (x1 - x, x - x0);
        m0 * (a * a * a / (6.0 * h))
            + m1 * (b * b * b / (6.0 * h))
            + (y0 / h - m0 * (h / 6.0)) * a
            + (y1 / h - m1 * (h / 6.0)) * b
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baseline::testing::{check_mask, hide, take_from};

    fn cubic(t: usize) -> Vec3 {
        let x = t as f64 / 10.0;
        Vec3::new(0.5 * x * x * x - 4.0 * x * x + 3.0 * x + 100.0, -x * x * x / 3.0 + 20.0 * x, 2.0 * x * x)
    }

    #[test]
    fn spline_interpolates_its_knots_and_lines_exactly() {
        let knots: Vec<(f64, Vec3)> =
            [0.0, 1.0, 2.5, 3.0, 7.0].iter().map(|x| (*x, Vec3::new(2.0 * x + 1.0, -x, 5.0))).collect();
        let s = NaturalSpline::new(knots.clone());
        for (x, y) in &knots {
            assert!((s.at(*x) - y).norm() < 1e-12);
        }
        for x in [0.3, 1.7, 4.4, 6.9] {
            assert!((s.at(x) - Vec3::new(2.0 * x + 1.0, -x, 5.0)).norm() < 1e-12);
        }
        let one = NaturalSpline::new(vec![(2.0, Vec3::new(1.0, 2.0, 3.0))]);
        assert_eq!(one.at(10.0), Vec3::new(1.0, 2.0, 3.0));
    }

    /// Cubic motion with short gaps and other gaps inside the knot window: close to exact.
    #[test]
    fn cubic_motion_is_filled_closely() {
        let truth = take_from(300, 1, |t, _| cubic(t));
        let mut holed = truth.clone();
        hide(&mut holed, 0, (100..112).chain(115..117).chain(95..97).chain(200..203));
        let out = fill(&holed);
        assert_eq!(check_mask(&holed, &out), 12 + 2 + 2 + 3);
        for t in 90..210 {
            let (a, b) = (out.take.position_mm(t, 0).unwrap(), truth.position_mm(t, 0).unwrap());
            // Trajectory spans hundreds of mm; end effects of the window are ~1e-4 of that.
            assert!((a - b).norm() < 0.05, "frame {t}: {a:?} vs {b:?}");
        }
    }

    #[test]
    fn edges_hold_the_border_and_short_sides_degrade() {
        let truth = take_from(40, 2, |t, m| cubic(t) + Vec3::new(m as f64, 0.0, 0.0));
        let mut holed = truth.clone();
        hide(&mut holed, 0, (0..5).chain(30..40));
        hide(&mut holed, 1, (0..39).filter(|t| *t != 20));
        let out = fill(&holed);
        assert_eq!(check_mask(&holed, &out), 15 + 38);
        assert_eq!(out.take.position_mm(0, 0), truth.position_mm(5, 0));
        assert_eq!(out.take.position_mm(39, 0), truth.position_mm(29, 0));
        // Marker 1 has two knots: a line between them, constant outside.
        assert_eq!(out.take.position_mm(0, 1), truth.position_mm(20, 1));
        let mid = out.take.position_mm(29, 1).unwrap();
        let want = truth.position_mm(20, 1).unwrap() * (10.0 / 19.0) + truth.position_mm(39, 1).unwrap() * (9.0 / 19.0);
        assert!((mid - want).norm() < 1e-9);
    }

    #[test]
    fn fill_range_replaces_a_window_and_marks_it() {
        let truth = take_from(100, 2, |t, m| cubic(t) * (1.0 + m as f64));
        let mut noisy = truth.clone();
        noisy.set_position_mm(50, 0, Some(Vec3::new(1e4, 0.0, 0.0))).unwrap();
        let mut out = Filled::unchanged(&noisy);
        assert_eq!(spline_fill_range(&mut out, 0, 47..54), 7);
        assert_eq!(out.filled_count(), 7);
        assert!((47..54).all(|t| out.filled[t * 2]));
        for t in 40..60 {
            let d = out.take.position_mm(t, 0).unwrap() - truth.position_mm(t, 0).unwrap();
            assert!(d.norm() < 0.05, "{t}: {d:?}");
        }
        // A range covering the whole take has nothing to refill from.
        assert_eq!(spline_fill_range(&mut out, 1, 0..500), 0);
        assert_eq!(out.take.position_mm(3, 1), None);
        assert_eq!(out.filled_count(), 7);
    }
}
