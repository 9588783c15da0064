//! What happened to each sample: captured, filled by locap, an outlier locap replaced, or
//! still missing.
//!
//! `locap clean` records its changes in the C3D parameters `LOCAP:FILLED` (`LABEL first-last`
//! per run of filled samples) and `LOCAP:OUTLIERS` (`LABEL first-last Kind` per removed
//! window), with C3D frame numbers (the take's `first_frame` is the first). The viewer reads
//! them back here, so any take cleaned by locap shows which samples are real. The lists are
//! stored in the compact form of [`locap_core::range_list`]; files written by earlier versions
//! hold the lines themselves, and both are read.

use crate::ViewError;
use locap_core::Take;

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

/// The state of every sample of `take` (frame-major, like the take), from the strings of
/// `LOCAP:FILLED` and `LOCAP:OUTLIERS` (empty for a take locap did not clean), in either
/// storage form of [`locap_core::range_list`].
///
/// A sample the take has no position for is [`SampleState::Missing`] whatever the lists say;
/// otherwise an outlier window wins over a filled range (outlier windows are refilled, so
/// `locap clean` lists them in both).
///
/// # Errors
/// A corrupt compact list, a line that is not `LABEL first-last` (`LABEL first-last Kind` for
/// outliers), a label the take does not have, or a range outside the take's frames.
pub fn sample_states(take: &Take, filled: &[String], outliers: &[String]) -> Result<Vec<SampleState>, ViewError> {
    let filled = decode(filled, "LOCAP:FILLED")?;
    let outliers = decode(outliers, "LOCAP:OUTLIERS")?;
    let m = take.marker_count();
    let mut states: Vec<SampleState> =
        take.validity().iter().map(|&v| if v { SampleState::Visible } else { SampleState::Missing }).collect();
    let mut mark = |marker: usize, frames: std::ops::Range<usize>, state| {
        for f in frames {
            let s = &mut states[f * m + marker];
            if *s != SampleState::Missing && *s < state {
                *s = state;
            }
        }
    };
    for line in &filled {
        let (marker, frames) = parse_range_line(take, line, "LOCAP:FILLED")?;
        mark(marker, frames, SampleState::Filled);
    }
    for line in &outliers {
        // The kind (`Spike`, `Stuck`) follows the range.
        let head = line
            .trim_end()
            .rsplit_once(' ')
            .map(|(head, _kind)| head)
            .ok_or_else(|| bad_line(line, "LOCAP:OUTLIERS"))?;
        let (marker, frames) = parse_range_line(take, head, "LOCAP:OUTLIERS")?;
        mark(marker, frames, SampleState::OutlierFixed);
    }
    Ok(states)
}

/// The lines of a stored list, compact or plain.
fn decode(strings: &[String], parameter: &'static str) -> Result<Vec<String>, ViewError> {
    locap_core::range_list::decode(strings).map_err(|e| ViewError::BadParameter {
        parameter,
        line: strings.first().cloned().unwrap_or_default(),
        reason: e.to_string(),
    })
}

fn bad_line(line: &str, parameter: &'static str) -> ViewError {
    ViewError::BadParameter { parameter, line: line.to_string(), reason: "expected `LABEL first-last`".into() }
}

/// `LABEL first-last` (labels may contain spaces, so the range is the last word) to a marker
/// index and 0-based frame range.
fn parse_range_line(
    take: &Take,
    line: &str,
    parameter: &'static str,
) -> Result<(usize, std::ops::Range<usize>), ViewError> {
    let (label, range) = line.trim_end().rsplit_once(' ').ok_or_else(|| bad_line(line, parameter))?;
    let (first, last) = range.split_once('-').ok_or_else(|| bad_line(line, parameter))?;
    let (Ok(first), Ok(last)) = (first.parse::<usize>(), last.parse::<usize>()) else {
        return Err(bad_line(line, parameter));
    };
    let marker =
        take.markers().iter().position(|n| n.full() == label.trim()).ok_or_else(|| ViewError::BadParameter {
            parameter,
            line: line.to_string(),
            reason: format!("the take has no marker `{}`", label.trim()),
        })?;
    let base = take.first_frame as usize;
    let frames = take.frame_count();
    if first > last || first < base || last - base >= frames {
        return Err(ViewError::BadParameter {
            parameter,
            line: line.to_string(),
            reason: format!("frames {first}-{last} are outside the take's frames {base}-{}", base + frames - 1),
        });
    }
    Ok((marker, first - base..last - base + 1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{MarkerName, Vec3};

    fn take() -> Take {
        let markers = vec![MarkerName::parse("A"), MarkerName::parse("Sub:B C")];
        let mut samples = vec![Some(Vec3::new(1.0, 2.0, 3.0)); 10 * 2];
        samples[4 * 2 + 1] = None; // B C missing at frame 4
        let mut t = Take::from_samples(markers, &samples, 100.0).unwrap();
        t.first_frame = 11;
        t
    }

    #[test]
    fn states_follow_the_ranges_that_clean_writes() {
        let t = take();
        let filled = vec!["A 12-14".to_string(), "Sub:B C 13-16".to_string()];
        let outliers = vec!["Sub:B C 16-17 Spike".to_string()];
        let s = sample_states(&t, &filled, &outliers).unwrap();
        let a: Vec<SampleState> = (0..10).map(|f| s[f * 2]).collect();
        let b: Vec<SampleState> = (0..10).map(|f| s[f * 2 + 1]).collect();
        use SampleState::*;
        assert_eq!(a, [Visible, Filled, Filled, Filled, Visible, Visible, Visible, Visible, Visible, Visible]);
        // Frame 4 (C3D 15) has no position: missing wins over the filled range.
        assert_eq!(
            b,
            [Visible, Visible, Filled, Filled, Missing, OutlierFixed, OutlierFixed, Visible, Visible, Visible]
        );
    }

    #[test]
    fn bad_lines_are_clear_errors() {
        let t = take();
        let err = |filled: &str| sample_states(&t, &[filled.to_string()], &[]).unwrap_err().to_string();
        assert!(err("A 12").contains("expected `LABEL first-last`"), "{}", err("A 12"));
        assert!(err("Z 12-13").contains("no marker `Z`"));
        assert!(err("A 5-13").contains("outside the take's frames 11-20"), "{}", err("A 5-13"));
        assert!(err("A 19-21").contains("outside"));
        assert!(err("A 14-12").contains("outside"));
        let e = sample_states(&t, &[], &["A 12-13".to_string()]).unwrap_err().to_string();
        assert!(e.contains("LOCAP:OUTLIERS"), "{e}");
    }

    #[test]
    fn compact_lists_give_the_same_states_as_plain_lines() {
        use locap_core::range_list::{MAGIC, encode};
        let t = take();
        let filled = vec!["A 12-14".to_string(), "Sub:B C 13-16".to_string()];
        let outliers = vec!["Sub:B C 16-17 Spike".to_string()];
        let (f, o) = (encode(&filled).unwrap(), encode(&outliers).unwrap());
        assert_eq!(f[0], MAGIC);
        assert_eq!(sample_states(&t, &f, &o).unwrap(), sample_states(&t, &filled, &outliers).unwrap());
        // Decoded lines are checked like plain ones.
        let e = sample_states(&t, &encode(&["A 5-13".to_string()]).unwrap(), &[]).unwrap_err().to_string();
        assert!(e.contains("outside the take's frames 11-20"), "{e}");
        let e = sample_states(&t, &[MAGIC.to_string(), "g".to_string()], &[]).unwrap_err().to_string();
        assert!(e.contains("LOCAP:FILLED") && e.contains("corrupt"), "{e}");
    }

    #[test]
    fn an_uncleaned_take_is_visible_or_missing() {
        let t = take();
        let s = sample_states(&t, &[], &[]).unwrap();
        assert_eq!(s.iter().filter(|x| **x == SampleState::Missing).count(), 1);
        assert_eq!(s.iter().filter(|x| **x == SampleState::Visible).count(), 19);
    }
}
