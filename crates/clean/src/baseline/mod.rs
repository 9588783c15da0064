//! Gap-fill baselines to measure the locality EDM fill ([`crate::edm`]) against.
//!
//! Each module fills every gap of every marker of a take with one classic method and returns
//! a [`crate::Filled`] whose mask holds exactly the samples it computed; a gap a method cannot
//! fill stays missing. They are reached through [`crate::fill_gaps`] or called directly:
//! - [`linear`]: straight line between the gap's two border samples;
//! - [`spline`]: natural cubic spline through a window of visible samples around the gap
//!   (and [`spline::spline_fill_range`], the refill the outlier stage uses);
//! - [`pca`]: the marker-intercorrelation PCA of Gløersen & Federolf (2016);
//! - [`rigid`]: the rigid-body ("relational") fill of Vicon Nexus and QTM from 3 neighbours.
//!
//! # Take edges
//! A gap touching the first or last frame has one border. The temporal methods (linear,
//! spline) hold that border sample constant: extrapolating a line or a cubic runs away within
//! a few frames. The rigid fill carries the single border along with its neighbours; PCA needs
//! no border at all.

pub mod linear;
pub mod pca;
pub mod rigid;
pub mod spline;

use crate::Filled;
use locap_core::Vec3;

/// Writes a computed sample into `out` and marks it, unless it is not finite (then the sample
/// stays as it was). Returns whether it was written.
pub(crate) fn put(out: &mut Filled, frame: usize, marker: usize, p: Vec3) -> bool {
    let m = out.take.marker_count();
    if out.take.set_position_mm(frame, marker, Some(p)).is_ok() {
        out.filled[frame * m + marker] = true;
        true
    } else {
        false
    }
}

/// The frame just before `start` and the frame `end`, where they exist in a take of `frames`
/// frames: the borders of the frame range `start..end`.
pub(crate) fn borders(start: usize, end: usize, frames: usize) -> (Option<usize>, Option<usize>) {
    (start.checked_sub(1), (end < frames).then_some(end))
}

#[cfg(test)]
pub(crate) mod testing {
    //! Small takes shared by the baseline tests.

    use locap_core::{MarkerName, Take, Vec3};

    /// A take of `markers` markers over `frames` frames, positions from `f(frame, marker)`.
    pub fn take_from(frames: usize, markers: usize, f: impl Fn(usize, usize) -> Vec3) -> Take {
        let names = (0..markers).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let samples: Vec<Option<Vec3>> =
            (0..frames).flat_map(|t| (0..markers).map(move |m| (t, m))).map(|(t, m)| Some(f(t, m))).collect();
        Take::from_samples(names, &samples, 100.0).unwrap()
    }

    /// Removes `marker` over `frames`.
    pub fn hide(take: &mut Take, marker: usize, frames: impl IntoIterator<Item = usize>) {
        for f in frames {
            take.set_position_mm(f, marker, None).unwrap();
        }
    }

    /// Checks the `filled` mask is exactly "missing before, present after" and that every
    /// present sample is finite; returns the number of filled samples.
    pub fn check_mask(before: &Take, after: &crate::Filled) -> usize {
        let m = before.marker_count();
        for f in 0..before.frame_count() {
            for k in 0..m {
                let was = before.is_valid(f, k);
                let now = after.take.is_valid(f, k);
                assert!(!was || now, "captured sample lost at {f},{k}");
                assert_eq!(after.filled[f * m + k], !was && now, "mask wrong at {f},{k}");
                if was {
                    assert_eq!(before.position_mm(f, k), after.take.position_mm(f, k), "captured sample changed");
                }
                if let Some(p) = after.take.position_mm(f, k) {
                    assert!(p.iter().all(|x| x.is_finite()));
                }
            }
        }
        after.filled_count()
    }
}
