//! What a fill benchmark runs: the methods under test and the gaps it hides, chosen the same
//! way for `locap bench fill` and `locap.bench_fill` (Python), so both front ends score the
//! same candidates on the same gaps from the same flags.
//!
//! - [`FillCandidates`]: every [`Variant`] (auto first), the refiners given as model files
//!   (named `neural:STEM`, or `neural-no-edm:STEM` for a refiner that starts from linear
//!   interpolation: the paper's "w/o EDM initial value" ablation), and the shipped refiners as
//!   one candidate `neural`, scored only where some take carries their markers.
//! - [`real_gap_model`]: the occlusion statistics the hidden gaps are drawn from: the takes'
//!   own gaps where they have enough, else the built-in real statistics, plus any given
//!   sources (statistics files or takes with real occlusions), merged.

use crate::fill_bench::{Candidate, Variant, VariantFiller};
use crate::gap_model::{GapModel, GapModelError};
use locap_clean::{FillMethod, Filler};
use locap_core::{GapStatistics, Take};
use locap_nn::{FittingRefiners, Refiner};

/// Fewest real gaps the takes under test must have between them for the hidden gaps to be
/// drawn from their own statistics; below it the built-in statistics are used (a gap-free
/// take has nothing to learn from).
pub const MIN_OWN_GAPS: usize = 50;

/// The fill methods a benchmark scores, owned; [`FillCandidates::for_takes`] lends them.
pub struct FillCandidates {
    variants: Vec<(String, VariantFiller)>,
    refiners: Vec<(String, Refiner)>,
    shipped: Vec<Refiner>,
}

impl FillCandidates {
    /// Every variant with `neighbours` EDM neighbours, the `given` refiners (with their files'
    /// stems), and the `shipped` refiners (empty: not scored).
    pub fn new(neighbours: usize, given: Vec<(String, Refiner)>, shipped: Vec<Refiner>) -> FillCandidates {
        let variants = Variant::all().into_iter().map(|v| (v.name(), v.filler(neighbours))).collect();
        let refiners = given
            .into_iter()
            .map(|(stem, refiner)| {
                let name = match refiner.meta.init {
                    FillMethod::Linear => format!("neural-no-edm:{stem}"),
                    _ => format!("neural:{stem}"),
                };
                (name, refiner)
            })
            .collect();
        FillCandidates { variants, refiners, shipped }
    }

    /// The candidates for `takes`: the shipped refiners only where some take carries their
    /// markers (elsewhere they would score as failures on every input).
    pub fn for_takes<'a>(&'a self, takes: &[(String, Take)], fitting: &'a FittingRefiners<'a>) -> Vec<Candidate<'a>> {
        let mut methods: Vec<Candidate> =
            self.variants.iter().map(|(name, filler)| Candidate { name, filler: filler as &dyn Filler }).collect();
        methods.extend(self.refiners.iter().map(|(name, refiner)| Candidate { name, filler: refiner as &dyn Filler }));
        if takes.iter().any(|(_, take)| self.shipped.iter().any(|r| r.fits(take))) {
            methods.push(Candidate { name: "neural", filler: fitting });
        }
        methods
    }

    /// The shipped refiners as one filler, for [`FillCandidates::for_takes`].
    pub fn fitting(&self) -> FittingRefiners<'_> {
        FittingRefiners(&self.shipped)
    }
}

/// A source of occlusion statistics for the hidden gaps, already read.
#[derive(Debug, Clone)]
pub enum GapSource {
    /// The gaps of a take with real occlusions.
    Statistics(GapStatistics),
    /// A gap model (a statistics file).
    Model(GapModel),
}

/// The real-gap model of a fill benchmark on `takes`, and whether the built-in statistics
/// were used because the takes have fewer than [`MIN_OWN_GAPS`] real gaps and no source was
/// given. Gap lengths are capped at `max_gap_frames`.
///
/// Takes' statistics are pooled into one model; given models are merged into it (or, with no
/// statistics, into the last given model).
///
/// # Errors
/// The statistics hold no gap to learn from.
pub fn real_gap_model(
    takes: &[(String, Take)],
    sources: Vec<GapSource>,
    max_gap_frames: usize,
) -> Result<(GapModel, bool), GapModelError> {
    let mut stats = Vec::new();
    let mut models = Vec::new();
    let mut builtin = false;
    if sources.is_empty() {
        let own: Vec<GapStatistics> = takes.iter().map(|(_, t)| GapStatistics::of_take(t)).collect();
        if own.iter().map(|s| s.gap_count()).sum::<usize>() >= MIN_OWN_GAPS {
            stats.extend(own);
        } else {
            builtin = true;
            models.push(GapModel::builtin());
        }
    }
    for source in sources {
        match source {
            GapSource::Statistics(s) => stats.push(s),
            GapSource::Model(m) => models.push(m),
        }
    }
    let mut model = match models.pop() {
        Some(last) if stats.is_empty() => last,
        last => {
            models.extend(last);
            GapModel::from_statistics(&stats)?
        }
    };
    for m in &models {
        model.merge(m);
    }
    model.max_gap_frames = max_gap_frames.min(model.length_histogram.len().saturating_sub(1)).max(1);
    Ok((model, builtin))
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::MarkerName;

    fn take_with_gaps(gaps: usize) -> Take {
        let frames = 40 * gaps + 40;
        let mut samples = Vec::new();
        for f in 0..frames {
            for m in 0..2 {
                let hidden = m == 0 && (f % 40) >= 20 && (f % 40) < 23 && f / 40 < gaps;
                samples.push((!hidden).then(|| locap_core::Vec3::new(f as f64, m as f64, 0.0)));
            }
        }
        Take::from_samples(vec![MarkerName::parse("A"), MarkerName::parse("B")], &samples, 120.0).unwrap()
    }

    #[test]
    fn own_gaps_are_used_when_there_are_enough_else_the_builtin_statistics() {
        let many = [("a".to_string(), take_with_gaps(MIN_OWN_GAPS))];
        let (model, builtin) = real_gap_model(&many, Vec::new(), 600).unwrap();
        assert!(!builtin);
        assert_eq!(model.max_gap_frames, 3.min(model.length_histogram.len() - 1).max(1));
        let few = [("a".to_string(), take_with_gaps(3))];
        let (model, builtin) = real_gap_model(&few, Vec::new(), 600).unwrap();
        assert!(builtin);
        assert_eq!(model, {
            let mut m = GapModel::builtin();
            m.max_gap_frames = 600.min(m.length_histogram.len() - 1).max(1);
            m
        });
    }

    #[test]
    fn a_given_source_replaces_the_takes_own_gaps() {
        let many = [("a".to_string(), take_with_gaps(MIN_OWN_GAPS))];
        let (model, builtin) = real_gap_model(&many, vec![GapSource::Model(GapModel::builtin())], 600).unwrap();
        assert!(!builtin);
        let mut expected = GapModel::builtin();
        expected.max_gap_frames = 600.min(expected.length_histogram.len() - 1).max(1);
        assert_eq!(model, expected);
        let gap_free =
            Take::from_samples(vec![MarkerName::parse("A")], &[Some(locap_core::Vec3::zeros()); 10], 120.0).unwrap();
        let none = real_gap_model(&[], vec![GapSource::Statistics(GapStatistics::of_take(&gap_free))], 600);
        assert!(none.is_err());
    }

    #[test]
    fn candidates_are_every_variant_auto_first() {
        let candidates = FillCandidates::new(6, Vec::new(), Vec::new());
        let fitting = candidates.fitting();
        let methods = candidates.for_takes(&[], &fitting);
        let names: Vec<&str> = methods.iter().map(|c| c.name).collect();
        let expected: Vec<String> = Variant::all().iter().map(|v| v.name()).collect();
        assert_eq!(names, expected);
        assert_eq!(names[0], "auto");
    }
}
