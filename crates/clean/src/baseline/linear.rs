//! Linear interpolation across each gap.
//!
//! A gap `[s, e)` with both borders visible gets `p(t) = p(s-1) + (t-s+1)/(e-s+1) (p(e) -
//! p(s-1))`: exact on motion at constant velocity, and the classic first baseline. A gap that
//! touches the take's start or end has one border, whose sample is held constant across the
//! gap (extrapolating the last velocity would drift without bound). A marker never visible
//! stays missing.

use super::{borders, put};
use crate::Filled;
use locap_core::Take;
use locap_core::gaps::gaps_of;

/// Fills every gap of every marker of `take` by linear interpolation (held constant at the
/// take's edges).
pub fn fill(take: &Take) -> Filled {
    let mut out = Filled::unchanged(take);
    let frames = take.frame_count();
    for marker in 0..take.marker_count() {
        for gap in gaps_of((0..frames).map(|f| take.is_valid(f, marker))) {
            let (before, after) = borders(gap.start, gap.end(), frames);
            let a = before.and_then(|b| take.position_mm(b, marker));
            let b = after.and_then(|b| take.position_mm(b, marker));
            for t in gap.start..gap.end() {
                let p = match (a, b, before, after) {
                    (Some(a), Some(b), Some(fa), Some(fb)) => {
                        let w = (t - fa) as f64 / (fb - fa) as f64;
                        a + (b - a) * w
                    }
                    (Some(a), None, ..) => a,
                    (None, Some(b), ..) => b,
                    _ => break,
                };
                put(&mut out, t, marker, p);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baseline::testing::{check_mask, hide, take_from};
    use locap_core::Vec3;

    #[test]
    fn constant_velocity_is_exact() {
        let truth = take_from(100, 2, |t, m| Vec3::new(3.0 * t as f64, -2.0 * t as f64 + m as f64, 7.0));
        let mut holed = truth.clone();
        hide(&mut holed, 0, 20..45);
        hide(&mut holed, 1, (50..51).chain(60..90));
        let out = fill(&holed);
        assert_eq!(check_mask(&holed, &out), 25 + 1 + 30);
        for t in 0..100 {
            for m in 0..2 {
                let d = out.take.position_mm(t, m).unwrap() - truth.position_mm(t, m).unwrap();
                assert!(d.norm() < 1e-9, "{t},{m}: {d:?}");
            }
        }
    }

    #[test]
    fn edges_hold_the_border_and_invisible_markers_stay_missing() {
        let truth = take_from(50, 2, |t, _| Vec3::new(t as f64, 0.0, 0.0));
        let mut holed = truth.clone();
        hide(&mut holed, 0, (0..10).chain(40..50));
        hide(&mut holed, 1, 0..50);
        let out = fill(&holed);
        assert_eq!(check_mask(&holed, &out), 20);
        assert_eq!(out.take.position_mm(0, 0), Some(Vec3::new(10.0, 0.0, 0.0)));
        assert_eq!(out.take.position_mm(49, 0), Some(Vec3::new(39.0, 0.0, 0.0)));
        assert_eq!(out.take.position_mm(5, 1), None);
    }
}
