//! The clean stage as one call (LocalMoCap section 3.1, "Preprocess"): swapped labels
//! exchanged back, outliers detected and removed, every gap filled, the outlier windows
//! refilled with a cubic spline through the completed trajectory, and a record of what changed.
//!
//! `locap clean`, `locap solve` (before the solver sees the markers) and the solver's training
//! data all clean through [`clean`] / [`clean_with`], so a take is cleaned the same way
//! wherever it goes. The order matters: a swap seen as two outliers would be cut out of both
//! markers, and a fill started before the outliers are removed would carry them into the gaps.

use crate::outliers::{self, Outlier, OutlierConfig};
use crate::swaps::{self, Swap, SwapConfig};
use crate::{FillConfig, FillError, FillMethod, Filled, Filler};
use locap_core::provenance::{FillRecord, MarkerFrames, OutlierRecord, Provenance, SwapRecord};
use locap_core::{GapStatistics, Take};
use serde::{Deserialize, Serialize};

/// Settings of [`clean`]. The default is what `locap clean` and `locap solve` do without
/// options: swaps and outliers repaired with their default thresholds, every gap filled by the
/// method (or blend) that filled trial gaps of its length best in the same take
/// ([`FillMethod::Auto`], [`crate::auto`]; EDM's K = 6 where EDM is a candidate). Auto is the
/// default because on every held-out take of the fixed-length protocol it beats EDM, the
/// paper's fill, and on most it beats every single method (`docs/benchmarks.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CleanConfig {
    /// Swap detection (`None`: swaps are left as they are).
    pub swaps: Option<SwapConfig>,
    /// Outlier detection (`None`: nothing is removed).
    pub outliers: Option<OutlierConfig>,
    /// The fill [`clean`] uses ([`clean_with`] takes any [`Filler`] instead).
    pub fill: FillConfig,
}

impl Default for CleanConfig {
    fn default() -> CleanConfig {
        CleanConfig {
            swaps: Some(SwapConfig::default()),
            outliers: Some(OutlierConfig::default()),
            fill: FillConfig { method: FillMethod::Auto, ..FillConfig::default() },
        }
    }
}

impl CleanConfig {
    /// The default fill with swap and outlier repair switched off: only gaps are filled.
    pub fn fill_only(fill: FillConfig) -> CleanConfig {
        CleanConfig { swaps: None, outliers: None, fill }
    }
}

/// What cleaning did to one marker.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct MarkerReport {
    /// The marker's full label.
    pub label: String,
    /// Gaps in the input (after swaps were undone).
    pub gaps: usize,
    /// Missing samples the fill computed (outlier windows not counted).
    pub filled_samples: usize,
    /// Samples still missing after cleaning.
    pub still_missing: usize,
    /// Outlier windows removed and refilled.
    pub outliers: usize,
}

/// A cleaned take and what was done to it.
#[derive(Debug, Clone)]
pub struct Cleaned {
    /// The cleaned take, with every computed sample marked (gaps and outlier windows).
    pub filled: Filled,
    /// `[frame * markers + marker]`: captured and kept (not missing, not an outlier).
    pub visible: Vec<bool>,
    /// Outlier windows removed (then refilled).
    pub outliers: Vec<Outlier>,
    /// Captured samples removed as outliers.
    pub outlier_samples: usize,
    /// Label swaps undone.
    pub swaps: Vec<Swap>,
    /// The filler, as it describes itself (`LOCAP:METHOD`).
    pub method: String,
    /// Per gap, what filled it, when the filler chooses per gap (`LOCAP:FILLS`).
    pub fills: Vec<FillRecord>,
    /// Per marker, take order.
    pub markers: Vec<MarkerReport>,
}

impl Cleaned {
    /// The cleaned take.
    pub fn take(&self) -> &Take {
        &self.filled.take
    }

    /// The record to store with the take (`LOCAP` parameters).
    pub fn provenance(&self) -> Provenance {
        Provenance {
            method: Some(self.method.clone()),
            filled: Provenance::runs_of(&self.filled.take, &self.filled.filled),
            outliers: self
                .outliers
                .iter()
                .map(|o| OutlierRecord {
                    at: MarkerFrames { marker: o.marker, frames: o.frames.clone() },
                    kind: format!("{:?}", o.kind),
                })
                .collect(),
            swaps: self.swaps.iter().map(|s| SwapRecord { a: s.a, b: s.b, frames: s.frames.clone() }).collect(),
            fills: self.fills.clone(),
        }
    }

    /// Gaps in the input, summed over markers.
    pub fn gap_count(&self) -> usize {
        self.markers.iter().map(|m| m.gaps).sum()
    }

    /// Missing samples the fill computed, summed over markers.
    pub fn filled_samples(&self) -> usize {
        self.markers.iter().map(|m| m.filled_samples).sum()
    }

    /// Per leading method of [`Cleaned::fills`] (a blend's first, `default` kept apart when no
    /// trial chose it): `(method, gaps, samples in those gaps)`, by name. The summary of a
    /// per-gap fill.
    pub fn fills_by_method(&self) -> Vec<(String, usize, usize)> {
        let mut counts: std::collections::BTreeMap<String, (usize, usize)> = Default::default();
        for r in &self.fills {
            let (prefix, rest) = match r.method.strip_prefix("default: ") {
                Some(rest) => ("default ", rest),
                None => ("", r.method.as_str()),
            };
            let lead = format!("{prefix}{}", rest.split(' ').next().unwrap_or_default());
            let entry = counts.entry(lead).or_default();
            entry.0 += 1;
            entry.1 += r.at.frames.len();
        }
        counts.into_iter().map(|(m, (g, n))| (m, g, n)).collect()
    }

    /// Samples still missing, summed over markers.
    pub fn still_missing(&self) -> usize {
        self.markers.iter().map(|m| m.still_missing).sum()
    }
}

/// Cleans `take` with `config`, filling with `config.fill`.
///
/// ```
/// use locap_clean::{CleanConfig, clean};
/// use locap_core::{MarkerName, Take, Vec3};
///
/// // Four markers of one rigid segment moving along x; marker 0 is occluded for 10 frames.
/// let names: Vec<MarkerName> = ["A", "B", "C", "D"].into_iter().map(MarkerName::parse).collect();
/// let corners = [[0.0, 0.0, 0.0], [100.0, 0.0, 0.0], [0.0, 80.0, 0.0], [0.0, 0.0, 60.0]];
/// let samples: Vec<Option<Vec3>> = (0..200)
///     .flat_map(|f| corners.iter().enumerate().map(move |(k, c)| {
///         let hidden = k == 0 && (90..100).contains(&f);
///         (!hidden).then(|| Vec3::new(c[0] + 3.0 * f as f64, c[1], c[2] + 1000.0))
///     }))
///     .collect();
/// let take = Take::from_samples(names, &samples, 120.0)?;
///
/// let cleaned = clean(&take, &CleanConfig::default());
/// assert_eq!((cleaned.filled_samples(), cleaned.still_missing()), (10, 0));
/// let filled = cleaned.take().position_mm(95, 0).unwrap();
/// assert!((filled - Vec3::new(285.0, 0.0, 1000.0)).norm() < 1.0);
/// // What to store with the take (`LOCAP:FILLED A 91-100`, `LOCAP:METHOD Auto trials=3 blend=3`, ...).
/// assert_eq!(cleaned.provenance().filled[0].frames, 90..100);
/// # Ok::<(), locap_core::TakeError>(())
/// ```
pub fn clean(take: &Take, config: &CleanConfig) -> Cleaned {
    match clean_with(take, config, &config.fill) {
        Ok(cleaned) => cleaned,
        // `FillConfig::fill` returns no error.
        Err(e) => unreachable!("a classical fill failed: {e}"),
    }
}

/// Cleans `take` with `config`'s swap and outlier settings, filling with `filler` (a learned
/// refiner, for instance) instead of `config.fill`.
///
/// # Errors
/// The filler cannot run on the take.
pub fn clean_with(take: &Take, config: &CleanConfig, filler: &dyn Filler) -> Result<Cleaned, FillError> {
    let mut raw = take.clone();
    let swapped = match &config.swaps {
        Some(c) => swaps::detect(&raw, c),
        None => Vec::new(),
    };
    swaps::unswap(&mut raw, &swapped);
    let found = match &config.outliers {
        Some(c) => outliers::detect(&raw, c),
        None => Vec::new(),
    };
    let mut holed = raw.clone();
    let removed = outliers::remove(&mut holed, &found);
    let (mut filled, mut fills) = filler.fill_recorded(&holed)?;
    crate::refill_outliers(&mut filled, &found);
    // A gap that is an outlier window is refilled by the spline: it is recorded as an outlier.
    let m = take.marker_count();
    fills.retain(|r| !r.at.frames.clone().all(|f| removed[f * m + r.at.marker]));
    let markers = reports(&raw, &filled, &removed, &found);
    Ok(Cleaned {
        visible: holed.validity().to_vec(),
        filled,
        outlier_samples: removed.iter().filter(|r| **r).count(),
        outliers: found,
        swaps: swapped,
        method: filler.describe(),
        fills,
        markers,
    })
}

fn reports(raw: &Take, filled: &Filled, removed: &[bool], found: &[Outlier]) -> Vec<MarkerReport> {
    let m = raw.marker_count();
    let stats = GapStatistics::of_take(raw);
    raw.markers()
        .iter()
        .enumerate()
        .map(|(marker, name)| MarkerReport {
            label: name.full(),
            gaps: stats.markers[marker].gap_count,
            filled_samples: (0..raw.frame_count())
                .filter(|f| filled.filled[f * m + marker] && !removed[f * m + marker])
                .count(),
            still_missing: (0..raw.frame_count()).filter(|f| !filled.take.is_valid(*f, marker)).count(),
            outliers: found.iter().filter(|o| o.marker == marker).count(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{MarkerName, Vec3};

    /// Four markers moving together; B has a gap, C a spike.
    fn take() -> Take {
        let names: Vec<MarkerName> = ["A", "B", "C", "D"].into_iter().map(MarkerName::parse).collect();
        let mut samples = Vec::new();
        for f in 0..240 {
            let x = 500.0 * (f as f64 / 40.0).sin();
            let c = if f == 120 { 400.0 } else { 0.0 };
            samples.push(Some(Vec3::new(x, 0.0, 1000.0)));
            samples.push((!(100..110).contains(&f)).then(|| Vec3::new(x + 100.0, 0.0, 1000.0)));
            samples.push(Some(Vec3::new(x, 100.0 + c, 1000.0)));
            samples.push(Some(Vec3::new(x + 30.0, 50.0, 1100.0)));
        }
        Take::from_samples(names, &samples, 120.0).unwrap()
    }

    #[test]
    fn clean_fills_gaps_repairs_outliers_and_records_both() {
        let t = take();
        let cleaned = clean(&t, &CleanConfig::default());
        assert_eq!(cleaned.still_missing(), 0);
        assert_eq!(cleaned.markers[1].gaps, 1);
        assert_eq!(cleaned.markers[1].filled_samples, 10);
        assert_eq!(cleaned.outliers.len(), 1, "{:?}", cleaned.outliers);
        assert_eq!(cleaned.outliers[0].marker, 2);
        assert_eq!(cleaned.outlier_samples, cleaned.outliers[0].frames.len());
        let spike = cleaned.take().position_mm(120, 2).unwrap();
        assert!((spike.y - 100.0).abs() < 5.0, "the spike is refilled: {spike:?}");
        assert!(!cleaned.visible[120 * 4 + 2] && cleaned.visible[120 * 4 + 1]);
        let record = cleaned.provenance();
        assert_eq!(record.method.as_deref(), Some("Auto trials=3 blend=3"));
        assert_eq!(record.fills.len(), 1, "auto records what filled the gap");
        assert!(record.filled.contains(&MarkerFrames { marker: 1, frames: 100..110 }));
        assert_eq!(record.outliers.len(), 1);
        assert_eq!(record.outliers[0].kind, "Spike");
    }

    #[test]
    fn fill_only_leaves_outliers_and_uses_the_given_filler() {
        let t = take();
        let linear = FillConfig { method: FillMethod::Linear, ..FillConfig::default() };
        let cleaned = clean(&t, &CleanConfig::fill_only(linear));
        assert!(cleaned.outliers.is_empty() && cleaned.swaps.is_empty());
        assert_eq!(cleaned.take().position_mm(120, 2).unwrap().y, 500.0);
        assert_eq!(cleaned.method, "Linear");
        assert_eq!(cleaned.filled, crate::fill_gaps(&t, &linear));
        let with = clean_with(&t, &CleanConfig::default(), &linear).unwrap();
        assert_eq!(with.method, "Linear");
        assert_eq!(with.outliers.len(), 1);
    }

    #[test]
    fn a_per_gap_fill_records_what_filled_each_gap() {
        let t = take();
        let auto = FillConfig { method: FillMethod::Auto, ..FillConfig::default() };
        let cleaned = clean(&t, &CleanConfig { fill: auto, ..CleanConfig::default() });
        assert_eq!(cleaned.markers[1].filled_samples, 10);
        assert_eq!(cleaned.fills.len(), 1, "{:?}", cleaned.fills);
        assert_eq!(cleaned.fills[0].at, MarkerFrames { marker: 1, frames: 100..110 });
        let by_method = cleaned.fills_by_method();
        assert_eq!(by_method.len(), 1);
        assert_eq!((by_method[0].1, by_method[0].2), (1, 10));
        assert_eq!(cleaned.provenance().fills, cleaned.fills);
        // One method for every gap: nothing per gap to record.
        let edm = FillConfig { method: FillMethod::Edm, ..FillConfig::default() };
        assert!(clean(&t, &CleanConfig { fill: edm, ..CleanConfig::default() }).fills.is_empty());
    }

    #[test]
    fn a_failing_filler_is_an_error_not_a_panic() {
        struct Broken;
        impl Filler for Broken {
            fn describe(&self) -> String {
                "Broken".into()
            }
            fn fill(&self, _: &Take) -> Result<Filled, FillError> {
                Err(FillError::new(self, "trained on other markers"))
            }
        }
        let e = clean_with(&take(), &CleanConfig::default(), &Broken).unwrap_err();
        assert_eq!(e.to_string(), "Broken: trained on other markers");
    }
}
