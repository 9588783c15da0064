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

/// Fills every gap of every marker of `take` by the rigid-body method, donors ranked by
/// `selection`.
pub fn fill(take: &Take, selection: Selection) -> Filled {
    let ranked = neighbours::rank(take, selection);
    let mut out = Filled::unchanged(take);
    for (marker, ranked) in ranked.iter().enumerate() {
        for gap in gaps_of((0..take.frame_count()).map(|f| take.is_valid(f, marker))) {
            fill_gap(take, &mut out, marker, gap, ranked);
        }
    }
    out
}

fn fill_gap(take: &Take, out: &mut Filled, marker: usize, gap: Gap, ranked: &[usize]) {
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
        .copied()
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
