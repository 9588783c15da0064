//! What happened to each sample: captured, filled by locap, an outlier locap replaced, or
//! still missing.
//!
//! `locap clean` records its changes in the C3D group `LOCAP` (`LOCAP:FILLED`,
//! `LOCAP:OUTLIERS`, ...; the stored form is described in [`locap_core::provenance`]). The
//! caller reads that record ([`Provenance`]) and the viewer turns it into one state per sample
//! here, so any take cleaned by locap shows which samples are real.

use locap_core::{Provenance, Take};

/// The state of one sample, in the order the viewer ranks them (a later state wins when the
/// gap chart merges several frames into one pixel).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum SampleState {
    /// Measured by the capture system and kept as it was.
    Visible = 0,
    /// Missing in the capture, filled by locap (listed in `LOCAP:FILLED`).
    Filled = 1,
    /// Removed by locap as an outlier and replaced (listed in `LOCAP:OUTLIERS`).
    OutlierFixed = 2,
    /// Still missing in this take.
    Missing = 3,
}

impl SampleState {
    /// Every state, in code order.
    pub const ALL: [SampleState; 4] =
        [SampleState::Visible, SampleState::Filled, SampleState::OutlierFixed, SampleState::Missing];

    /// Name used in the page's legend and data attributes.
    pub fn name(self) -> &'static str {
        match self {
            SampleState::Visible => "visible",
            SampleState::Filled => "filled",
            SampleState::OutlierFixed => "outlier",
            SampleState::Missing => "missing",
        }
    }
}

/// The state of every sample of `take` (frame-major, like the take), from what locap recorded
/// about it (`Provenance::default()` for a take locap did not clean).
///
/// A sample the take has no position for is [`SampleState::Missing`] whatever the record says;
/// otherwise an outlier window wins over a filled range (outlier windows are refilled, so
/// `locap clean` lists them in both). Records outside the take's markers or frames are ignored
/// (a record read from the take's file is checked against it already).
pub fn sample_states(take: &Take, record: &Provenance) -> Vec<SampleState> {
    let (m, t) = (take.marker_count(), take.frame_count());
    let mut states: Vec<SampleState> =
        take.validity().iter().map(|&v| if v { SampleState::Visible } else { SampleState::Missing }).collect();
    let mut mark = |marker: usize, frames: &std::ops::Range<usize>, state| {
        if marker >= m {
            return;
        }
        for f in frames.start..frames.end.min(t) {
            let s = &mut states[f * m + marker];
            if *s != SampleState::Missing && *s < state {
                *s = state;
            }
        }
    };
    for run in &record.filled {
        mark(run.marker, &run.frames, SampleState::Filled);
    }
    for o in &record.outliers {
        mark(o.at.marker, &o.at.frames, SampleState::OutlierFixed);
    }
    states
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::provenance::{MarkerFrames, OutlierRecord};
    use locap_core::{MarkerName, Vec3};

    fn take() -> Take {
        let markers = vec![MarkerName::parse("A"), MarkerName::parse("Sub:B C")];
        let mut samples = vec![Some(Vec3::new(1.0, 2.0, 3.0)); 10 * 2];
        samples[4 * 2 + 1] = None; // B C missing at frame 4
        Take::from_samples(markers, &samples, 100.0).unwrap()
    }

    fn run(marker: usize, frames: std::ops::Range<usize>) -> MarkerFrames {
        MarkerFrames { marker, frames }
    }

    #[test]
    fn states_follow_the_record() {
        let t = take();
        let record = Provenance {
            filled: vec![run(0, 1..4), run(1, 2..6)],
            outliers: vec![OutlierRecord { at: run(1, 5..7), kind: "Spike".into() }],
            ..Provenance::default()
        };
        let s = sample_states(&t, &record);
        let a: Vec<SampleState> = (0..10).map(|f| s[f * 2]).collect();
        let b: Vec<SampleState> = (0..10).map(|f| s[f * 2 + 1]).collect();
        use SampleState::*;
        assert_eq!(a, [Visible, Filled, Filled, Filled, Visible, Visible, Visible, Visible, Visible, Visible]);
        // Frame 4 has no position: missing wins over the filled range.
        assert_eq!(
            b,
            [Visible, Visible, Filled, Filled, Missing, OutlierFixed, OutlierFixed, Visible, Visible, Visible]
        );
    }

    #[test]
    fn records_outside_the_take_are_ignored() {
        let t = take();
        let record = Provenance { filled: vec![run(5, 0..3), run(0, 8..40)], ..Provenance::default() };
        let s = sample_states(&t, &record);
        assert_eq!(s.iter().filter(|x| **x == SampleState::Filled).count(), 2);
    }

    #[test]
    fn an_uncleaned_take_is_visible_or_missing() {
        let t = take();
        let s = sample_states(&t, &Provenance::default());
        assert_eq!(s.iter().filter(|x| **x == SampleState::Missing).count(), 1);
        assert_eq!(s.iter().filter(|x| **x == SampleState::Visible).count(), 19);
    }
}
