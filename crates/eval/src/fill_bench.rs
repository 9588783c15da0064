//! The gap-fill accuracy benchmark (the OMPE column of the LocalMoCap paper's Table 1, on real
//! takes and without learning).
//!
//! For every take: hide gaps drawn from a [`GapModel`] (seeded: every method sees the same
//! gaps), fill them with every method, and compare each hidden sample with the captured
//! truth. Reported per method: OMPE (mean, median and 95th percentile position error in mm,
//! hidden samples only), the error by gap length, how many hidden samples the method left
//! unfilled, and throughput (take frames filled per second of wall time on one core).
//!
//! Every method under test is a [`Candidate`]: a name and a [`Filler`], so the methods of
//! `locap_clean` ([`Variant`]s, through [`VariantFiller`]) and learned refiners are scored
//! alike, on the same gaps. Errors by gap length use the bins of every locap metric,
//! [`locap_core::gaps::LENGTH_BINS`].

use crate::gap_model::GapModel;
use locap_clean::{FillConfig, FillError, FillMethod, Filled, Filler, fill_gaps, neighbours::Selection};
use locap_core::Take;
use locap_core::gaps::{ErrorByGapLength, LENGTH_BINS, range_label};
use rand::SeedableRng;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// One method configuration under test.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Variant {
    /// Method.
    pub method: FillMethod,
    /// Neighbour ranking (matters for EDM and rigid).
    pub selection: Selection,
}

impl Variant {
    /// Display name: the method, plus the ranking when it is not the default.
    pub fn name(&self) -> String {
        match self.selection {
            Selection::Variance => self.method.name().to_string(),
            Selection::MeanDistance => format!("{}-nearest", self.method.name()),
        }
    }

    /// Every method with default neighbours, plus EDM with nearest-distance neighbours (the
    /// paper chose variance; this measures that choice), plus the per-gap choice among them
    /// ([`FillMethod::Auto`]), first.
    pub fn all() -> Vec<Variant> {
        let mut v: Vec<Variant> =
            FillMethod::ALL.iter().map(|m| Variant { method: *m, selection: Selection::Variance }).collect();
        v.insert(1, Variant { method: FillMethod::Edm, selection: Selection::MeanDistance });
        v.insert(0, Variant { method: FillMethod::Auto, selection: Selection::Variance });
        v
    }
}

/// A filler under test, with its name in the report.
#[derive(Clone, Copy)]
pub struct Candidate<'a> {
    /// Name in the report.
    pub name: &'a str,
    /// The filler.
    pub filler: &'a dyn Filler,
}

/// Most markers a take may have for the PCA fill to run on it in the benchmark.
///
/// The PCA fill ([`locap_clean::baseline::pca`]) eigen-decomposes a `3P x 3P` covariance
/// matrix for every marker with gaps, `P` its predictors (nearly every other marker), so its
/// cost grows as `markers^4` whatever the frame count, while every other method grows as
/// `markers^2` (issue 14: `bench fill` "hung" on a 3,000 x 5 take). Above the ceiling the PCA
/// variant refuses the take (a failure in the report, its hidden samples unfilled) and every
/// other method still runs. 256 markers is over three times the largest marker set in the
/// shared data; the timings behind the choice are in `docs/benchmarks.md`. Making the PCA
/// itself cheap on short takes (a `T x T` Gram matrix instead of the `3P x 3P` covariance) is
/// a change to `locap_clean`.
pub const MAX_PCA_MARKERS: usize = 256;

/// The PCA variant refused a take above [`MAX_PCA_MARKERS`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("{markers} markers: the PCA fill's cost grows as markers^4, it runs on at most {MAX_PCA_MARKERS}")]
pub struct TooManyMarkersForPca {
    /// Markers of the take.
    pub markers: usize,
}

/// A [`Variant`] with its neighbour count, as the benchmark runs it: [`fill_gaps`], except
/// that the PCA variants (the paper's frame and the aligned one) refuse takes of more than
/// [`MAX_PCA_MARKERS`] markers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VariantFiller {
    /// The variant.
    pub variant: Variant,
    /// Its fill configuration.
    pub config: FillConfig,
}

impl Variant {
    /// This variant as a [`Filler`] with `neighbours` neighbours.
    pub fn filler(self, neighbours: usize) -> VariantFiller {
        VariantFiller {
            variant: self,
            config: FillConfig { method: self.method, neighbours, selection: self.selection },
        }
    }
}

impl Filler for VariantFiller {
    fn describe(&self) -> String {
        self.config.describe()
    }

    fn fill(&self, take: &Take) -> Result<Filled, FillError> {
        let markers = take.marker_count();
        let pca = matches!(self.config.method, FillMethod::Pca | FillMethod::PcaAligned);
        if pca && markers > MAX_PCA_MARKERS {
            return Err(FillError::new(self, TooManyMarkersForPca { markers }));
        }
        Ok(fill_gaps(take, &self.config))
    }
}

/// Error of one method on gaps of one length bin ([`LENGTH_BINS`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Bucket {
    /// Shortest gap in the bucket, frames.
    pub min_frames: usize,
    /// Longest gap in the bucket, frames (`usize::MAX` = no limit).
    pub max_frames: usize,
    /// Hidden samples scored.
    pub samples: usize,
    /// Mean error, mm (`null` without samples).
    pub mean_mm: Option<f64>,
}

impl Bucket {
    /// The bin's label: `1-10`, `241+`.
    pub fn label(&self) -> String {
        range_label(self.min_frames, self.max_frames)
    }
}

/// The result of one method.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodResult {
    /// Variant name.
    pub method: String,
    /// Hidden samples that the method filled and were scored.
    pub scored_samples: usize,
    /// Hidden samples the method left missing (not in the error figures).
    pub unfilled_samples: usize,
    /// OMPE: mean error over hidden samples, mm.
    pub ompe_mean_mm: f64,
    /// Mean error over the hidden samples that *every* method filled, mm: the fair comparison
    /// when some method leaves samples unfilled.
    pub ompe_common_mm: f64,
    /// Median error, mm.
    pub ompe_median_mm: f64,
    /// 95th percentile error, mm.
    pub ompe_p95_mm: f64,
    /// Error by gap length.
    pub by_gap_length: Vec<Bucket>,
    /// Wall time of all fills, seconds.
    pub seconds: f64,
    /// Take frames filled per second.
    pub frames_per_second: f64,
    /// Why the method could not fill some takes (`take: reason`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub failures: Vec<String>,
}

/// The whole benchmark.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FillBenchReport {
    /// Takes used.
    pub takes: Vec<String>,
    /// Seed of the gap sampler.
    pub seed: u64,
    /// Hidden samples per take, summed.
    pub hidden_samples: usize,
    /// Hidden gaps, summed.
    pub hidden_gaps: usize,
    /// One entry per variant.
    pub methods: Vec<MethodResult>,
}

/// Hides gaps drawn from `model` in `truth`, the `index`-th take of a benchmark run with
/// `seed` (the same gaps for every method and every tool that scores fills). Returns the holed
/// take, the hidden samples as `(frame, marker, gap length)` and the number of gaps.
pub fn hide_gaps(truth: &Take, model: &GapModel, seed: u64, index: usize) -> (Take, Vec<(usize, usize, usize)>, usize) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed.wrapping_add(index as u64 * 0x9E37_79B9));
    // Unlabeled points (`*N`) are not markers: no method fills them, so none are hidden.
    let labeled: Vec<bool> = truth.markers().iter().map(|n| !n.is_unlabeled()).collect();
    let gaps =
        model.sample(truth.frame_count(), truth.marker_count(), |f, m| labeled[m] && truth.is_valid(f, m), &mut rng);
    let mut holed = truth.clone();
    let mut hidden = Vec::new();
    let mut count = 0;
    for (marker, marker_gaps) in gaps.iter().enumerate() {
        for gap in marker_gaps {
            count += 1;
            for f in gap.start..gap.end() {
                // Hiding a sample cannot fail.
                let _ = holed.set_position_mm(f, marker, None);
                hidden.push((f, marker, gap.len));
            }
        }
    }
    (holed, hidden, count)
}

/// Runs the benchmark on `takes` (name, take) with gaps from `model`.
pub fn run(
    takes: &[(String, Take)],
    model: &GapModel,
    variants: &[Variant],
    neighbours: usize,
    seed: u64,
) -> FillBenchReport {
    let fillers: Vec<(String, VariantFiller)> = variants.iter().map(|v| (v.name(), v.filler(neighbours))).collect();
    let candidates: Vec<Candidate> = fillers.iter().map(|(name, filler)| Candidate { name, filler }).collect();
    run_candidates(takes, model, &candidates, seed)
}

/// Runs the benchmark on `takes` (name, take) with gaps from `model` for any fillers. A
/// filler that fails on a take leaves that take's hidden samples unfilled and its reason in
/// [`MethodResult::failures`].
pub fn run_candidates(
    takes: &[(String, Take)],
    model: &GapModel,
    variants: &[Candidate],
    seed: u64,
) -> FillBenchReport {
    let mut failures: Vec<Vec<String>> = vec![Vec::new(); variants.len()];
    let mut errors: Vec<Vec<(f64, usize)>> = vec![Vec::new(); variants.len()];
    // Per variant, the error of every hidden sample in one global order (`None` = unfilled),
    // to score all methods on the samples every one of them filled.
    let mut per_sample: Vec<Vec<Option<f64>>> = vec![Vec::new(); variants.len()];
    let mut unfilled = vec![0usize; variants.len()];
    let mut seconds = vec![0.0f64; variants.len()];
    let (mut hidden_samples, mut hidden_gaps, mut total_frames) = (0, 0, 0);
    for (index, (name, truth)) in takes.iter().enumerate() {
        let (holed, hidden, gaps) = hide_gaps(truth, model, seed, index);
        hidden_gaps += gaps;
        hidden_samples += hidden.len();
        total_frames += truth.frame_count();
        for (v, variant) in variants.iter().enumerate() {
            let start = Instant::now();
            let filled = match variant.filler.fill(&holed) {
                Ok(filled) => filled.take,
                Err(why) => {
                    // The candidate's name already says which filler; its reason is enough.
                    failures[v].push(format!("{name}: {}", why.source));
                    holed.clone()
                }
            };
            seconds[v] += start.elapsed().as_secs_f64();
            for &(f, m, len) in &hidden {
                match (filled.position_mm(f, m), truth.position_mm(f, m)) {
                    (Some(a), Some(b)) => {
                        errors[v].push(((a - b).norm(), len));
                        per_sample[v].push(Some((a - b).norm()));
                    }
                    _ => {
                        unfilled[v] += 1;
                        per_sample[v].push(None);
                    }
                }
            }
        }
    }
    let common: Vec<bool> = (0..hidden_samples).map(|i| per_sample.iter().all(|errors| errors[i].is_some())).collect();
    let common_count = common.iter().filter(|c| **c).count();
    let methods = variants
        .iter()
        .enumerate()
        .map(|(v, variant)| {
            let common_sum: f64 =
                per_sample[v].iter().zip(&common).filter(|(_, c)| **c).map(|(e, _)| e.unwrap_or(0.0)).sum();
            let e = &errors[v];
            let mut sorted: Vec<f64> = e.iter().map(|x| x.0).collect();
            sorted.sort_by(f64::total_cmp);
            let pick = |q: f64| -> f64 {
                if sorted.is_empty() { f64::NAN } else { sorted[((sorted.len() - 1) as f64 * q).round() as usize] }
            };
            let by_gap_length = LENGTH_BINS
                .iter()
                .map(|&(lo, hi)| {
                    let in_bucket: Vec<f64> = e.iter().filter(|x| x.1 >= lo && x.1 <= hi).map(|x| x.0).collect();
                    Bucket {
                        min_frames: lo,
                        max_frames: hi,
                        samples: in_bucket.len(),
                        mean_mm: (!in_bucket.is_empty())
                            .then(|| in_bucket.iter().sum::<f64>() / in_bucket.len() as f64),
                    }
                })
                .collect();
            MethodResult {
                method: variant.name.to_string(),
                failures: failures[v].clone(),
                scored_samples: e.len(),
                unfilled_samples: unfilled[v],
                ompe_mean_mm: if e.is_empty() { f64::NAN } else { sorted.iter().sum::<f64>() / e.len() as f64 },
                ompe_common_mm: if common_count == 0 { f64::NAN } else { common_sum / common_count as f64 },
                ompe_median_mm: pick(0.5),
                ompe_p95_mm: pick(0.95),
                by_gap_length,
                seconds: seconds[v],
                frames_per_second: total_frames as f64 / seconds[v].max(1e-9),
            }
        })
        .collect();
    FillBenchReport {
        takes: takes.iter().map(|(n, _)| n.clone()).collect(),
        seed,
        hidden_samples,
        hidden_gaps,
        methods,
    }
}

impl FillBenchReport {
    /// Mean error by gap length as data series: per method, its name and `(bin label, mean
    /// mm)` points (`None` without samples), e.g. for `locap_view::plot::Chart::fill_error`.
    pub fn error_by_gap_length(&self) -> Vec<ErrorByGapLength> {
        self.methods
            .iter()
            .map(|m| (m.method.clone(), m.by_gap_length.iter().map(|b| (b.label(), b.mean_mm)).collect()))
            .collect()
    }

    /// The report as a text table.
    pub fn table(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "{} takes, {} hidden gaps, {} hidden samples, seed {}",
            self.takes.len(),
            self.hidden_gaps,
            self.hidden_samples,
            self.seed
        );
        let w = self.methods.iter().map(|m| m.method.len()).max().unwrap_or(0).max(14);
        let _ = write!(
            s,
            "{:<w$} {:>9} {:>9} {:>9} {:>9} {:>9}",
            "method", "OMPE mm", "common", "median", "p95", "unfilled"
        );
        for (lo, hi) in LENGTH_BINS {
            let label = format!("{} fr", range_label(lo, hi));
            let _ = write!(s, " {label:>9}");
        }
        let _ = writeln!(s, " {:>12}", "frames/s");
        for m in &self.methods {
            let _ = write!(
                s,
                "{:<w$} {:>9.2} {:>9.2} {:>9.2} {:>9.2} {:>9}",
                m.method, m.ompe_mean_mm, m.ompe_common_mm, m.ompe_median_mm, m.ompe_p95_mm, m.unfilled_samples
            );
            for b in &m.by_gap_length {
                match b.mean_mm {
                    Some(v) => {
                        let _ = write!(s, " {v:>9.2}");
                    }
                    None => {
                        let _ = write!(s, " {:>9}", "-");
                    }
                }
            }
            let _ = writeln!(s, " {:>12.0}", m.frames_per_second);
        }
        for m in &self.methods {
            for f in &m.failures {
                let _ = writeln!(s, "{} could not fill {f}", m.method);
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{MarkerName, Vec3};

    /// A rigid cluster: EDM is exact, linear is not.
    #[test]
    fn benchmark_scores_hidden_samples_only() {
        let take = locap_testkit::rigid_cluster(600, 5, |k| format!("M{k}"), |_, _| [0.0; 3]);
        let variants = [
            Variant { method: FillMethod::Edm, selection: Selection::Variance },
            Variant { method: FillMethod::Linear, selection: Selection::Variance },
        ];
        let report = run(&[("rigid".into(), take)], &GapModel::uniform(0.05, 60), &variants, 6, 3);
        assert!(report.hidden_samples > 0);
        let (edm, linear) = (&report.methods[0], &report.methods[1]);
        assert_eq!(edm.scored_samples + edm.unfilled_samples, report.hidden_samples);
        assert!(edm.ompe_mean_mm < 1e-3, "{}", report.table());
        assert!(linear.ompe_mean_mm > 1.0, "{}", report.table());
    }

    /// 3,000 markers x 5 frames: both PCA variants refuse the take at once, with their reason
    /// in the report; linear still fills it.
    #[test]
    fn pca_refuses_takes_above_its_marker_ceiling() {
        let m = MAX_PCA_MARKERS + 1;
        let names = (0..m).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let samples: Vec<Option<Vec3>> =
            (0..5 * m).map(|i| Some(Vec3::new((i % m) as f64 * 3.0, (i / m) as f64, (i % 7) as f64 * 50.0))).collect();
        let take = Take::from_samples(names, &samples, 120.0).unwrap();
        let variants = [FillMethod::Pca, FillMethod::PcaAligned, FillMethod::Linear]
            .map(|method| Variant { method, selection: Selection::Variance });
        let report = run(&[("wide".into(), take)], &GapModel::uniform(0.2, 2), &variants, 6, 3);
        assert!(report.hidden_samples > 0);
        for pca in &report.methods[..2] {
            assert_eq!(
                pca.failures,
                vec![format!(
                    "wide: {m} markers: the PCA fill's cost grows as markers^4, it runs on at most {MAX_PCA_MARKERS}"
                )]
            );
            assert_eq!(pca.unfilled_samples, report.hidden_samples);
        }
        assert!(report.methods[2].failures.is_empty());
    }

    #[test]
    fn the_report_gives_its_errors_by_gap_length_as_series() {
        let json = r#"{"takes":["a.c3d"],"seed":1,"hidden_samples":10,"hidden_gaps":2,"methods":[
            {"method":"edm","scored_samples":10,"unfilled_samples":0,"ompe_mean_mm":5.0,"ompe_common_mm":5.0,
             "ompe_median_mm":4.0,"ompe_p95_mm":9.0,"seconds":0.1,"frames_per_second":100.0,
             "by_gap_length":[{"min_frames":1,"max_frames":10,"samples":4,"mean_mm":1.5},
                              {"min_frames":241,"max_frames":18446744073709551615,"samples":0,"mean_mm":null}]}]}"#;
        let report: FillBenchReport = serde_json::from_str(json).unwrap();
        assert_eq!(
            report.error_by_gap_length(),
            vec![("edm".to_string(), vec![("1-10".to_string(), Some(1.5)), ("241+".to_string(), None)])]
        );
    }
}
