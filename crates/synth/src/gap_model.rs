//! Realistic occlusion gaps to hide in clean takes (LocalMoCap section 3.3, Eq. 6).
//!
//! A [`GapModel`] holds what real captures say about occlusion: the distribution of per-marker
//! missing fractions and the gap-length histogram, both measured with
//! [`locap_core::GapStatistics`] (or read from the statistics published with the paper). To
//! corrupt a take, each marker draws a missing fraction from the pool, then gap lengths are
//! drawn from the histogram until that fraction is reached; the gaps are placed longest
//! first, each at a random position where it overlaps no earlier gap and leaves at least one
//! visible frame on each side, so every hidden sample has ground truth and real borders. The
//! marker sets of the statistics and of the take need not match: fractions are drawn from the
//! pool, not matched by name. [`GapModel::sample`] is the benchmark's sampler; training data
//! uses the exact Eq. 6 counts of [`crate::augment`], which match markers by name where the
//! statistics name them ([`GapModel::marker_names`]).

use locap_core::GapStatistics;
use locap_core::gaps::{Gap, add_histogram};
use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};

/// Errors building a gap model.
#[derive(Debug, thiserror::Error)]
pub enum GapModelError {
    /// The statistics contain no gaps at all.
    #[error("the gap statistics contain no gaps: nothing to learn gap lengths from")]
    NoGaps,
    /// A JSON file is neither locap's form nor the paper's.
    #[error("unrecognised gap statistics JSON: {0}")]
    Json(String),
}

/// Occlusion statistics to sample gaps from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GapModel {
    /// Missing fraction of each marker of the source captures (the pool markers draw from).
    pub missing_fractions: Vec<f64>,
    /// Label of each entry of `missing_fractions` (subject prefix removed; empty where the
    /// statistics do not name it), so a take's markers can use their own occlusion
    /// probability (Eq. 6's per-marker `p_occ,i`).
    #[serde(default)]
    pub marker_names: Vec<String>,
    /// `length_histogram[n]`: number of real gaps of `n` frames.
    pub length_histogram: Vec<usize>,
    /// Longest gap hidden, in frames (longer ones in the histogram are ignored).
    pub max_gap_frames: usize,
}

impl GapModel {
    /// Pools the statistics of several takes or marker sets.
    pub fn from_statistics<'a>(stats: impl IntoIterator<Item = &'a GapStatistics>) -> Result<GapModel, GapModelError> {
        let mut fractions = Vec::new();
        let mut names = Vec::new();
        let mut histogram: Vec<usize> = Vec::new();
        for s in stats {
            for m in &s.markers {
                fractions.push(m.missing_fraction());
                names.push(label_of(&m.name));
                add_histogram(&mut histogram, &m.gap_length_histogram);
            }
        }
        GapModel::new(fractions, names, histogram)
    }

    /// Reads gap statistics JSON: either [`GapStatistics`] (what `locap info --json` prints
    /// under `gaps`) or the paper repository's form (`{"sets": {NAME: {"markers": [{
    /// "missing_frames", "total_frames", "gap_length_histogram"}]}}}`).
    pub fn from_json(text: &str) -> Result<GapModel, GapModelError> {
        let value: serde_json::Value = serde_json::from_str(text).map_err(|e| GapModelError::Json(e.to_string()))?;
        let mut fractions = Vec::new();
        let mut names = Vec::new();
        let mut histogram = Vec::new();
        let mut read_markers = |markers: &serde_json::Value| -> Result<(), GapModelError> {
            let list = markers.as_array().ok_or_else(|| GapModelError::Json("`markers` is not a list".into()))?;
            for m in list {
                let missing = m["missing_frames"].as_f64().unwrap_or(0.0);
                let total = m["total_frames"].as_f64().unwrap_or(0.0);
                if total > 0.0 {
                    fractions.push(missing / total);
                    names.push(label_of(m["name"].as_str().unwrap_or("")));
                }
                let h: Vec<usize> = m["gap_length_histogram"]
                    .as_array()
                    .map(|a| a.iter().map(|v| v.as_u64().unwrap_or(0) as usize).collect())
                    .unwrap_or_default();
                add_histogram(&mut histogram, &h);
            }
            Ok(())
        };
        if let Some(sets) = value.get("sets").and_then(|s| s.as_object()) {
            for set in sets.values() {
                read_markers(&set["markers"])?;
            }
        } else if value.get("markers").is_some() {
            read_markers(&value["markers"])?;
        } else if let Some(gaps) = value.get("gaps") {
            read_markers(&gaps["markers"])?;
        } else {
            return Err(GapModelError::Json("expected `sets`, `markers` or `gaps`".into()));
        }
        GapModel::new(fractions, names, histogram)
    }

    /// The built-in model: real occlusions of a Qualisys capture (numediart `03_rolling`, 68
    /// markers, 23% missing, gaps up to 1896 frames; see `data/README.md` of this crate).
    pub fn builtin() -> GapModel {
        const JSON: &str = include_str!("../data/real_gaps_numediart_03_rolling.json");
        // The file is part of the crate and checked by a test: it always parses.
        GapModel::from_json(JSON).unwrap_or_else(|_| GapModel::uniform(0.1, 120))
    }

    /// Pools another model into this one (fractions and length counts).
    pub fn merge(&mut self, other: &GapModel) {
        self.marker_names.resize(self.missing_fractions.len(), String::new());
        self.missing_fractions.extend(&other.missing_fractions);
        self.marker_names.extend(other.names_padded());
        add_histogram(&mut self.length_histogram, &other.length_histogram);
        self.max_gap_frames = self.max_gap_frames.max(other.max_gap_frames);
    }

    /// A model with a fixed missing fraction and gap lengths uniform in `1..=max_len`.
    pub fn uniform(missing_fraction: f64, max_len: usize) -> GapModel {
        let mut h = vec![1usize; max_len.max(1) + 1];
        h[0] = 0;
        GapModel {
            missing_fractions: vec![missing_fraction],
            marker_names: vec![String::new()],
            length_histogram: h,
            max_gap_frames: max_len.max(1),
        }
    }

    fn new(
        missing_fractions: Vec<f64>,
        marker_names: Vec<String>,
        length_histogram: Vec<usize>,
    ) -> Result<GapModel, GapModelError> {
        if length_histogram.iter().skip(1).all(|c| *c == 0) {
            return Err(GapModelError::NoGaps);
        }
        let max_gap_frames = length_histogram.len() - 1;
        Ok(GapModel { missing_fractions, marker_names, length_histogram, max_gap_frames })
    }

    /// `marker_names` with one entry per missing fraction (older JSON has none).
    fn names_padded(&self) -> Vec<String> {
        let mut names = self.marker_names.clone();
        names.resize(self.missing_fractions.len(), String::new());
        names
    }

    /// Occlusion probability of the marker labelled `label` in the statistics (the mean over
    /// entries of that label), if they name it.
    pub fn fraction_of(&self, label: &str) -> Option<f64> {
        let values: Vec<f64> = self
            .marker_names
            .iter()
            .zip(&self.missing_fractions)
            .filter(|(n, _)| !n.is_empty() && n.as_str() == label)
            .map(|(_, f)| *f)
            .collect();
        (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
    }

    /// Mean of the per-marker missing fractions (0 without any).
    pub fn mean_fraction(&self) -> f64 {
        if self.missing_fractions.is_empty() {
            0.0
        } else {
            self.missing_fractions.iter().sum::<f64>() / self.missing_fractions.len() as f64
        }
    }

    /// Draws one gap length from the histogram (lengths above `max_gap_frames` excluded).
    fn draw_length(&self, rng: &mut impl Rng) -> usize {
        let top = self.max_gap_frames.min(self.length_histogram.len() - 1);
        let total: usize = self.length_histogram[1..=top].iter().sum();
        if total == 0 {
            return 1;
        }
        // Drawn as u64 so the seeded gap sequence does not depend on the platform's usize.
        let mut pick = rng.random_range(0..total as u64);
        for (len, count) in self.length_histogram.iter().enumerate().take(top + 1).skip(1) {
            if pick < *count as u64 {
                return len;
            }
            pick -= *count as u64;
        }
        top
    }

    /// Gaps to hide for each of `markers` markers in a take of `frames` frames, where
    /// `visible(frame, marker)` says whether ground truth exists. Gaps are placed only over
    /// visible samples with visible borders.
    pub fn sample(
        &self,
        frames: usize,
        markers: usize,
        visible: impl Fn(usize, usize) -> bool,
        rng: &mut impl Rng,
    ) -> Vec<Vec<Gap>> {
        (0..markers)
            .map(|marker| {
                if self.missing_fractions.is_empty() || frames < 3 {
                    return Vec::new();
                }
                let fraction = self.missing_fractions[rng.random_range(0..self.missing_fractions.len())];
                let target = (fraction * frames as f64).round() as usize;
                let mut lengths = Vec::new();
                let mut sum = 0;
                while sum < target && lengths.len() < frames {
                    let len = self.draw_length(rng).min(frames - 2);
                    lengths.push(len);
                    sum += len;
                }
                lengths.sort_unstable_by(|a, b| b.cmp(a));
                let mut taken = vec![false; frames];
                let mut gaps = Vec::new();
                for len in lengths {
                    // A few random tries; a gap that does not fit anywhere is dropped.
                    for _ in 0..20 {
                        let start = rng.random_range(1..frames - len);
                        let free = (start - 1..start + len + 1).all(|f| !taken[f] && visible(f, marker));
                        if free {
                            taken[start..start + len].fill(true);
                            gaps.push(Gap { start, len });
                            break;
                        }
                    }
                }
                gaps.sort_by_key(|g| g.start);
                gaps
            })
            .collect()
    }
}

/// The marker label of a full name (`Subject:LABEL` -> `LABEL`).
fn label_of(name: &str) -> String {
    locap_core::MarkerName::parse(name).label
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn sampled_gaps_follow_the_model_and_never_touch() {
        let model = GapModel::uniform(0.2, 50);
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let gaps = model.sample(2000, 10, |_, _| true, &mut rng);
        for marker_gaps in &gaps {
            let hidden: usize = marker_gaps.iter().map(|g| g.len).sum();
            assert!(hidden > 250 && hidden <= 450, "{hidden}");
            for g in marker_gaps {
                assert!(g.start >= 1 && g.end() < 2000 && g.len <= 50);
            }
            for w in marker_gaps.windows(2) {
                assert!(w[0].end() < w[1].start, "gaps must keep a visible frame between them");
            }
        }
        // Same seed, same gaps.
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        assert_eq!(model.sample(2000, 10, |_, _| true, &mut rng), gaps);
    }

    #[test]
    fn builtin_model_is_the_real_one() {
        let model = GapModel::builtin();
        assert_eq!(model.missing_fractions.len(), 68);
        assert_eq!(model.length_histogram.iter().sum::<usize>(), 215);
    }

    #[test]
    fn reads_the_paper_json_form() {
        let json = r#"{"sets": {"a": {"markers": [
            {"name": "X", "missing_frames": 10, "total_frames": 100, "gap_length_histogram": [0, 2, 0, 1]}]}}}"#;
        let model = GapModel::from_json(json).unwrap();
        assert_eq!(model.missing_fractions, vec![0.1]);
        assert_eq!(model.fraction_of("X"), Some(0.1));
        assert_eq!(model.fraction_of("Y"), None);
        assert_eq!(model.length_histogram, vec![0, 2, 0, 1]);
        assert!(matches!(GapModel::from_json("{}"), Err(GapModelError::Json(_))));
    }
}
