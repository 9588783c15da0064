//! Occlusion gap statistics of a take.
//!
//! These numbers drive the occlusion augmentation of the LocalMoCap paper (section 3.3,
//! Eq. 6): per-marker occlusion probability (`missing_frames / total_frames`) and a gap-length
//! distribution. The JSON form ([`GapStatistics`] with serde) deliberately uses the same field
//! names as the paper repository's published statistics (`missing_frames`, `total_frames`,
//! `gap_length_histogram` with index = gap length in frames), so statistics measured by locap
//! and the shipped real production statistics can be used interchangeably. The form is
//! versioned by [`GapStatistics::FORMAT_VERSION`].

use crate::Take;
use serde::{Deserialize, Serialize};

/// One run of consecutive missing frames of one marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Gap {
    /// First missing frame (0-based index into the take).
    pub start: usize,
    /// Number of missing frames.
    pub len: usize,
}

impl Gap {
    /// One past the last missing frame.
    pub fn end(&self) -> usize {
        self.start + self.len
    }

    /// True if the gap touches the first or last frame of a take of `frames` frames (only one
    /// visible border exists, which gap fillers must handle differently).
    pub fn is_at_edge(&self, frames: usize) -> bool {
        self.start == 0 || self.end() == frames
    }
}

/// The gaps of one marker's validity sequence, in time order.
pub fn gaps_of(valid: impl IntoIterator<Item = bool>) -> Vec<Gap> {
    let mut gaps = Vec::new();
    let mut open: Option<usize> = None;
    let mut frame = 0;
    for v in valid {
        match (v, open) {
            (false, None) => open = Some(frame),
            (true, Some(start)) => {
                gaps.push(Gap { start, len: frame - start });
                open = None;
            }
            _ => {}
        }
        frame += 1;
    }
    if let Some(start) = open {
        gaps.push(Gap { start, len: frame - start });
    }
    gaps
}

/// Gap statistics of one marker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MarkerGapStatistics {
    /// Full marker name (with subject prefix, if any).
    pub name: String,
    /// Number of frames in which the marker is missing.
    pub missing_frames: usize,
    /// Number of frames of the take.
    pub total_frames: usize,
    /// Number of gaps.
    pub gap_count: usize,
    /// Length of the longest gap in frames (0 if none).
    pub longest_gap: usize,
    /// `gap_length_histogram[n]` = number of gaps of exactly `n` frames (index 0 unused).
    pub gap_length_histogram: Vec<usize>,
}

impl MarkerGapStatistics {
    /// Fraction of missing frames, in `[0, 1]` (0 for an empty take).
    pub fn missing_fraction(&self) -> f64 {
        if self.total_frames == 0 { 0.0 } else { self.missing_frames as f64 / self.total_frames as f64 }
    }
}

/// Gap statistics of a whole take.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GapStatistics {
    /// Version of this JSON form.
    pub format_version: u32,
    /// Frame rate of the take the statistics come from, in Hz (gap lengths are in frames).
    pub frame_rate_hz: f64,
    /// Number of frames of the take.
    pub total_frames: usize,
    /// One entry per marker, in the take's order.
    pub markers: Vec<MarkerGapStatistics>,
    /// Gap-length histogram over all markers (`[n]` = gaps of `n` frames, index 0 unused).
    pub gap_length_histogram: Vec<usize>,
}

impl GapStatistics {
    /// Version written to `format_version`.
    pub const FORMAT_VERSION: u32 = 1;

    /// Measures the gaps of every marker of `take`.
    pub fn of_take(take: &Take) -> GapStatistics {
        let frames = take.frame_count();
        let mut all = Vec::new();
        let markers: Vec<MarkerGapStatistics> = (0..take.marker_count())
            .map(|m| {
                let gaps = gaps_of((0..frames).map(|f| take.is_valid(f, m)));
                let histogram = histogram(gaps.iter().map(|g| g.len));
                add_histogram(&mut all, &histogram);
                MarkerGapStatistics {
                    name: take.markers()[m].full(),
                    missing_frames: gaps.iter().map(|g| g.len).sum(),
                    total_frames: frames,
                    gap_count: gaps.len(),
                    longest_gap: gaps.iter().map(|g| g.len).max().unwrap_or(0),
                    gap_length_histogram: histogram,
                }
            })
            .collect();
        GapStatistics {
            format_version: Self::FORMAT_VERSION,
            frame_rate_hz: take.frame_rate_hz(),
            total_frames: frames,
            markers,
            gap_length_histogram: all,
        }
    }

    /// Fraction of all samples that are missing.
    pub fn missing_fraction(&self) -> f64 {
        let total: usize = self.markers.iter().map(|m| m.total_frames).sum();
        let missing: usize = self.markers.iter().map(|m| m.missing_frames).sum();
        if total == 0 { 0.0 } else { missing as f64 / total as f64 }
    }

    /// Total number of gaps over all markers.
    pub fn gap_count(&self) -> usize {
        self.markers.iter().map(|m| m.gap_count).sum()
    }

    /// Pools the statistics of several takes: markers with the same label (subject prefix
    /// ignored) are merged (frames, gaps and histograms add up), in order of first
    /// appearance; the frame rate is the first take's. `None` for no takes.
    pub fn pool<'a>(stats: impl IntoIterator<Item = &'a GapStatistics>) -> Option<GapStatistics> {
        let mut out: Option<GapStatistics> = None;
        for s in stats {
            let pooled = out.get_or_insert_with(|| GapStatistics {
                format_version: Self::FORMAT_VERSION,
                frame_rate_hz: s.frame_rate_hz,
                total_frames: 0,
                markers: Vec::new(),
                gap_length_histogram: Vec::new(),
            });
            pooled.total_frames += s.total_frames;
            add_histogram(&mut pooled.gap_length_histogram, &s.gap_length_histogram);
            for m in &s.markers {
                let label = crate::MarkerName::parse(&m.name).label;
                let entry = match pooled.markers.iter().position(|p| p.name == label) {
                    Some(i) => &mut pooled.markers[i],
                    None => {
                        pooled.markers.push(MarkerGapStatistics {
                            name: label,
                            missing_frames: 0,
                            total_frames: 0,
                            gap_count: 0,
                            longest_gap: 0,
                            gap_length_histogram: Vec::new(),
                        });
                        pooled.markers.last_mut().expect("just pushed")
                    }
                };
                entry.missing_frames += m.missing_frames;
                entry.total_frames += m.total_frames;
                entry.gap_count += m.gap_count;
                entry.longest_gap = entry.longest_gap.max(m.longest_gap);
                add_histogram(&mut entry.gap_length_histogram, &m.gap_length_histogram);
            }
        }
        out
    }
}

/// The gap-length bins every metric and chart of locap reports by, frames, inclusive bounds
/// (the last bin is open, `usize::MAX`): one binning, so the fill benchmark, the solver
/// evaluation and the gap-length histograms of takes can be read side by side.
///
/// They are the fill benchmark's bins: up to 10 frames (interpolation is nearly exact), then
/// roughly doubling up to 2 s at 120 Hz, and everything longer.
pub const LENGTH_BINS: [(usize, usize); 6] = [(1, 10), (11, 30), (31, 60), (61, 120), (121, 240), (241, usize::MAX)];

/// Index in [`LENGTH_BINS`] of a gap of `len` frames (`None` for 0: no gap).
pub fn length_bin(len: usize) -> Option<usize> {
    LENGTH_BINS.iter().position(|&(lo, hi)| len >= lo && len <= hi)
}

/// Label of the bin `lo..=hi` frames: `1-10`, `241+` for an open bin, `5` for one length.
pub fn range_label(lo: usize, hi: usize) -> String {
    if hi == usize::MAX {
        format!("{lo}+")
    } else if lo == hi {
        lo.to_string()
    } else {
        format!("{lo}-{hi}")
    }
}

/// Labels of [`LENGTH_BINS`], in order.
pub fn length_bin_labels() -> Vec<String> {
    LENGTH_BINS.iter().map(|&(lo, hi)| range_label(lo, hi)).collect()
}

/// One method's mean error by gap length, as benchmarks report it and charts draw it: the
/// method's name and its `(bin label, mean error mm)` points, `None` where a bin has no samples.
pub type ErrorByGapLength = (String, Vec<(String, Option<f64>)>);

/// A gap-length histogram (`[n]` = gaps of `n` frames, as in [`GapStatistics`]) summed into
/// [`LENGTH_BINS`].
pub fn binned(histogram: &[usize]) -> [usize; LENGTH_BINS.len()] {
    let mut out = [0; LENGTH_BINS.len()];
    for (len, n) in histogram.iter().enumerate() {
        if let Some(bin) = length_bin(len) {
            out[bin] += n;
        }
    }
    out
}

fn histogram(lengths: impl Iterator<Item = usize>) -> Vec<usize> {
    let mut h = Vec::new();
    for len in lengths {
        if h.len() <= len {
            h.resize(len + 1, 0);
        }
        h[len] += 1;
    }
    h
}

/// Adds histogram `h` into `total` bin by bin, growing `total` as needed (pooling the
/// gap-length histograms of several markers or takes).
pub fn add_histogram(total: &mut Vec<usize>, h: &[usize]) {
    if total.len() < h.len() {
        total.resize(h.len(), 0);
    }
    for (t, v) in total.iter_mut().zip(h) {
        *t += v;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{MarkerName, Vec3};
    use proptest::prelude::*;

    #[test]
    fn finds_gaps_including_edges() {
        let v = [false, true, true, false, false, true, false];
        assert_eq!(gaps_of(v), vec![Gap { start: 0, len: 1 }, Gap { start: 3, len: 2 }, Gap { start: 6, len: 1 }]);
        assert!(Gap { start: 6, len: 1 }.is_at_edge(7));
        assert!(!Gap { start: 3, len: 2 }.is_at_edge(7));
        assert!(gaps_of([true, true]).is_empty());
    }

    #[test]
    fn statistics_of_a_take() {
        let p = Some(Vec3::zeros());
        // marker 0: gap of 2 at frames 1-2; marker 1: always there.
        let samples = [p, p, None, p, None, p, p, p];
        let take = Take::from_samples(vec![MarkerName::parse("A"), MarkerName::parse("B")], &samples, 120.0).unwrap();
        let stats = GapStatistics::of_take(&take);
        assert_eq!(stats.markers[0].missing_frames, 2);
        assert_eq!(stats.markers[0].gap_count, 1);
        assert_eq!(stats.markers[0].longest_gap, 2);
        assert_eq!(stats.markers[0].gap_length_histogram, vec![0, 0, 1]);
        assert_eq!(stats.markers[1].gap_count, 0);
        assert_eq!(stats.gap_length_histogram, vec![0, 0, 1]);
        assert_eq!(stats.missing_fraction(), 0.25);
        let json = serde_json::to_string(&stats).unwrap();
        assert!(json.contains("\"gap_length_histogram\""));
        let back: GapStatistics = serde_json::from_str(&json).unwrap();
        assert_eq!(back, stats);
        // Pooling a take with itself doubles every count; labels are matched without prefix.
        let mut prefixed = stats.clone();
        prefixed.markers[0].name = "Subject:A".into();
        let pooled = GapStatistics::pool([&stats, &prefixed]).unwrap();
        assert_eq!(pooled.markers.len(), 2);
        assert_eq!(pooled.markers[0].name, "A");
        assert_eq!(pooled.markers[0].gap_length_histogram, vec![0, 0, 2]);
        assert_eq!(pooled.total_frames, 8);
        assert_eq!(pooled.missing_fraction(), 0.25);
        assert!(GapStatistics::pool([]).is_none());
    }

    #[test]
    fn every_gap_length_has_one_bin() {
        assert_eq!(length_bin(0), None);
        assert_eq!(length_bin(1), Some(0));
        assert_eq!(length_bin(10), Some(0));
        assert_eq!(length_bin(11), Some(1));
        assert_eq!(length_bin(240), Some(4));
        assert_eq!(length_bin(241), Some(5));
        assert_eq!(length_bin(usize::MAX), Some(5));
        for w in LENGTH_BINS.windows(2) {
            assert_eq!(w[0].1 + 1, w[1].0, "bins are contiguous");
        }
        assert_eq!(length_bin_labels(), ["1-10", "11-30", "31-60", "61-120", "121-240", "241+"]);
        assert_eq!(range_label(5, 5), "5");
        // Gaps of 1, 10, 11 and 300 frames (index 0 unused).
        let mut h = vec![0; 301];
        h[0] = 7;
        h[1] = 1;
        h[10] = 2;
        h[11] = 1;
        h[300] = 4;
        assert_eq!(binned(&h), [3, 1, 0, 0, 0, 4]);
    }

    proptest! {
        #[test]
        fn gaps_cover_exactly_the_missing_frames(valid in proptest::collection::vec(any::<bool>(), 0..200)) {
            let gaps = gaps_of(valid.iter().copied());
            let mut rebuilt = vec![true; valid.len()];
            for g in &gaps {
                prop_assert!(g.len > 0);
                rebuilt[g.start..g.end()].fill(false);
            }
            prop_assert_eq!(rebuilt, valid);
            for w in gaps.windows(2) { prop_assert!(w[0].end() < w[1].start); }
        }
    }
}
