//! Rigid-body ("relational") fill from three neighbours, as in Vicon Nexus and QTM.
//!
//! For a gap `[s, e)` of marker `i`:
//! 1. the donors are the first 3 markers in `i`'s neighbour ranking ([`crate::neighbours`])
//!    that are captured at every existing border (`s-1`, `e`) and at every frame of the gap,
//!    skipping triples that are (nearly) collinear at a border, which fix no rotation;
//! 2. at frame `t`, Procrustes ([`crate::procrustes::align`], proper rotation) maps the donors'
//!    border positions onto their positions at `t`; applied to `i`'s border position, it
//!    carries `i` along as if rigidly attached to the donors;
//! 3. with both borders, the two estimates are blended linearly across the gap (weight of the
//!    later border `(t - s + 1) / (e - s + 1)`), so the fill meets both borders exactly; a
//!    gap touching the take's start or end uses its one border.
//!
//! [`Across::Spline`] (locap's, [`crate::FillMethod::RigidSpline`]) replaces step 3: the
//! marker's position in the donors' frame (their positions at the first border as reference)
//! at up to [`super::spline::WINDOW`] frames each side where it and every donor are captured
//! is interpolated by a natural cubic spline, and carried with the donors through the gap.
//! The spline follows what the marker does relative to its segment near the gap (skin and
//! joint motion), which the linear blend cuts off at the borders; over long gaps it drifts as
//! any spline does, so it is one of the per-gap choice's candidates, never a default.
//!
//! On a truly rigid cluster the fill is exact. Fewer than 3 usable donors leaves the whole
//! gap missing, as the commercial tools do; no donor may be a filled sample. The commercial
//! tools let the user pick the donors; here the locality ranking picks them.

use super::{borders, put};
use crate::Filled;
use crate::neighbours::{self, Selection};
use crate::procrustes;
use locap_core::gaps::{Gap, gaps_of};
use locap_core::{Take, Vec3};

/// Donors per gap.
pub const DONORS: usize = 3;
/// How many of the best-ranked usable neighbours are searched for a non-collinear triple.
const SEARCH: usize = 8;

/// How the marker's position relative to its donors goes from one border to the other.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Across {
    /// Linearly between the two borders (the commercial tools').
    Linear,
    /// A natural cubic spline through the frames around the gap, as [`super::spline`] runs on
    /// the marker's coordinates, here on its coordinates in the donors' frame (locap's).
    Spline,
}

/// Fills every gap of every marker of `take` by the rigid-body method, donors ranked by
/// `selection`.
pub fn fill(take: &Take, selection: Selection) -> Filled {
    fill_across(take, selection, Across::Linear)
}

/// [`fill`] with the donors' frame carrying the marker's relative position `across` the gap.
pub fn fill_across(take: &Take, selection: Selection, across: Across) -> Filled {
    fill_across_ranked(take, &neighbours::rank_scored(take, selection), across)
}

/// [`fill_across`] with every marker's donors ranked as given, best first, as
/// [`neighbours::rank_scored`] gives them (one entry per marker of `take`; only the order
/// counts here, so an EDM fill's ranking serves as is).
pub fn fill_across_ranked(take: &Take, ranked: &[Vec<(usize, f64)>], across: Across) -> Filled {
    let mut out = Filled::unchanged(take);
    for (marker, ranked) in ranked.iter().enumerate() {
        for gap in gaps_of((0..take.frame_count()).map(|f| take.is_valid(f, marker))) {
            fill_gap(take, &mut out, marker, gap, ranked, across);
        }
    }
    out
}

fn fill_gap(take: &Take, out: &mut Filled, marker: usize, gap: Gap, ranked: &[(usize, f64)], across: Across) {
    let (before, after) = borders(gap.start, gap.end(), take.frame_count());
    let borders: Vec<(usize, Vec3)> = [before, after]
        .into_iter()
        .flatten()
        .map(|b| (b, take.position_mm(b, marker).expect("border of a gap is visible")))
        .collect();
    if borders.is_empty() {
        return;
    }
    let usable: Vec<usize> = ranked
        .iter()
        .map(|(j, _)| *j)
        .filter(|j| borders.iter().all(|(b, _)| take.is_valid(*b, *j)))
        .filter(|j| (gap.start..gap.end()).all(|f| take.is_valid(f, *j)))
        .take(SEARCH)
        .collect();
    let positions = |donors: &[usize], f: usize| -> Vec<Vec3> {
        donors.iter().map(|j| take.position_mm(f, *j).expect("donors are visible")).collect()
    };
    let Some(donors) = triples(usable.len())
        .map(|[a, b, c]| [usable[a], usable[b], usable[c]])
        .find(|d| borders.iter().all(|(b, _)| !collinear(&positions(d, *b))))
    else {
        return;
    };
    if borders.len() == 2 && across == Across::Spline {
        spline_in_donor_frame(take, out, marker, gap, &donors, borders[0].0, borders[1].0);
        return;
    }
    let reference: Vec<(Vec<Vec3>, Vec3)> = borders.iter().map(|(b, p)| (positions(&donors, *b), *p)).collect();
    for t in gap.start..gap.end() {
        let now = positions(&donors, t);
        let estimates: Option<Vec<Vec3>> = reference
            .iter()
            .map(|(source, p)| procrustes::align(source, &now).map(|transform| transform.apply(p)))
            .collect();
        let Some(estimates) = estimates else { continue };
        let p = match (estimates.as_slice(), before, after) {
            ([a, b], Some(fa), Some(fb)) => {
                let w = (t - fa) as f64 / (fb - fa) as f64;
                a * (1.0 - w) + b * w
            }
            ([a], ..) => *a,
            _ => continue,
        };
        put(out, t, marker, p);
    }
}

/// The marker's position in the frame of `donors` (their positions at `before` as reference),
/// splined through up to [`super::spline::WINDOW`] frames each side where the marker and every
/// donor are captured, carried with the donors through the gap.
fn spline_in_donor_frame(
    take: &Take,
    out: &mut Filled,
    marker: usize,
    gap: Gap,
    donors: &[usize; 3],
    before: usize,
    after: usize,
) {
    let positions = |f: usize| -> Option<Vec<Vec3>> { donors.iter().map(|j| take.position_mm(f, *j)).collect() };
    let Some(reference) = positions(before) else { return };
    let local = |f: usize| -> Option<Vec3> {
        let p = take.position_mm(f, marker)?;
        let t = procrustes::align(&reference, &positions(f)?)?;
        Some(t.apply_inverse(&p))
    };
    let window = super::spline::WINDOW;
    let mut left: Vec<(f64, Vec3)> =
        (0..=before).rev().filter_map(|f| Some((f as f64, local(f)?))).take(window).collect();
    left.reverse();
    let right: Vec<(f64, Vec3)> =
        (after..take.frame_count()).filter_map(|f| Some((f as f64, local(f)?))).take(window).collect();
    if left.is_empty() || right.is_empty() {
        return;
    }
    let spline = super::spline::NaturalSpline::new(left.into_iter().chain(right).collect());
    for t in gap.start..gap.end() {
        let Some(now) = positions(t) else { continue };
        let Some(transform) = procrustes::align(&reference, &now) else { continue };
        put(out, t, marker, transform.apply(&spline.at(t as f64)));
    }
}

/// Index triples `a < b < c < n` in lexicographic order (best-ranked first).
fn triples(n: usize) -> impl Iterator<Item = [usize; 3]> {
    (0..n).flat_map(move |a| (a + 1..n).flat_map(move |b| (b + 1..n).map(move |c| [a, b, c])))
}

/// True if three points are (nearly) on one line: the triangle's smallest height is under
/// 1% of its longest side (or the points coincide).
fn collinear(p: &[Vec3]) -> bool {
    let (u, v) = (p[1] - p[0], p[2] - p[0]);
    let longest = u.norm().max(v.norm()).max((p[2] - p[1]).norm());
    // Twice the area over the longest side is the smallest height.
    longest <= 0.0 || u.cross(&v).norm() / longest < 0.01 * longest
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baseline::testing::{check_mask, hide, take_from};

    const OFFSETS: [[f64; 3]; 5] =
        [[0.0, 0.0, 0.0], [120.0, 10.0, 0.0], [0.0, 90.0, 30.0], [40.0, 40.0, 110.0], [-70.0, 20.0, 50.0]];

    fn rigid(frames: usize) -> Take {
        take_from(frames, OFFSETS.len(), |f, m| {
            let a = f as f64 * 0.03;
            let rot = nalgebra::Rotation3::from_euler_angles(0.3 * a, a, 0.5 * a.sin());
            Vec3::new(5.0 * f as f64, 100.0 * a.cos(), 900.0) + rot * Vec3::from(OFFSETS[m])
        })
    }

    #[test]
    fn rigid_motion_is_filled_exactly() {
        let truth = rigid(200);
        let mut holed = truth.clone();
        hide(&mut holed, 0, (0..15).chain(80..140).chain(185..200));
        hide(&mut holed, 3, 100..120); // a donor candidate missing in the gap is skipped
        let out = fill(&holed, Selection::Variance);
        assert_eq!(check_mask(&holed, &out), 15 + 60 + 15 + 20);
        for f in 0..200 {
            for m in 0..OFFSETS.len() {
                let d = out.take.position_mm(f, m).unwrap() - truth.position_mm(f, m).unwrap();
                assert!(d.norm() < 1e-6, "frame {f} marker {m}: {d:?}");
            }
        }
    }

    /// The rigid cluster of [`rigid`] with marker 0 sliding on it (skin over a segment): the
    /// linear blend of the two borders cuts its curved slide short, the spline in the donors'
    /// frame follows it; on the rigid cluster alone both are exact.
    #[test]
    fn the_spline_follows_a_marker_sliding_on_its_segment() {
        let sliding = |frames: usize| {
            let body = rigid(frames);
            take_from(frames, OFFSETS.len(), |f, m| {
                let p = body.position_mm(f, m).unwrap();
                if m != 0 {
                    return p;
                }
                // Along the cluster's own first axis (marker 1's offset), in a parabola.
                let a = f as f64 * 0.03;
                let rot = nalgebra::Rotation3::from_euler_angles(0.3 * a, a, 0.5 * a.sin());
                let slide = 20.0 * ((f as f64 - 100.0) / 40.0).powi(2);
                p + rot * Vec3::new(slide, 0.0, 0.0)
            })
        };
        let truth = sliding(200);
        let mut holed = truth.clone();
        hide(&mut holed, 0, 90..110);
        let error = |out: &Filled| -> f64 {
            (90..110)
                .map(|f| (out.take.position_mm(f, 0).unwrap() - truth.position_mm(f, 0).unwrap()).norm())
                .sum::<f64>()
                / 20.0
        };
        let splined = fill_across(&holed, Selection::Variance, Across::Spline);
        assert_eq!(check_mask(&holed, &splined), 20);
        let (splined, linear) = (error(&splined), error(&fill(&holed, Selection::Variance)));
        assert!(splined < 0.01 && linear > 0.5, "spline {splined} mm, linear {linear} mm");
        let truth = rigid(200);
        let mut holed = truth.clone();
        hide(&mut holed, 0, 90..110);
        let out = fill_across(&holed, Selection::Variance, Across::Spline);
        for f in 90..110 {
            assert!((out.take.position_mm(f, 0).unwrap() - truth.position_mm(f, 0).unwrap()).norm() < 1e-6);
        }
    }

    #[test]
    fn fewer_than_three_donors_leave_the_gap() {
        let truth = rigid(60);
        let mut holed = truth.clone();
        hide(&mut holed, 0, 20..30);
        for m in 1..4 {
            hide(&mut holed, m, 25..26);
        }
        // Only marker 4 stays visible throughout the gap of marker 0.
        let out = fill(&holed, Selection::Variance);
        assert!((20..30).all(|f| !out.take.is_valid(f, 0)));
        check_mask(&holed, &out);
    }

    #[test]
    fn collinear_donors_are_skipped() {
        let line = [Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.001, 0.0)];
        assert!(collinear(&line));
        assert!(!collinear(&[Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)]));
        assert_eq!(triples(4).count(), 4);
    }
}
