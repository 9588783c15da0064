//! `locap.bench_fill`: the gap-fill benchmark of `locap bench fill` (`locap_eval::fill_bench`:
//! realistic gaps hidden in takes with ground truth, every method on the same gaps, LocalMoCap
//! section 4's OMPE), its report as a dict.

use crate::take::PyTake;
use crate::{failure, json_to_py, usage};
use anyhow::Context;
use locap_clean::{FillError, Filled, Filler};
use locap_core::{GapStatistics, Take};
use locap_eval::fill_bench::{self, Candidate, Variant};
use locap_eval::gap_model::GapModel;
use locap_nn::Refiner;
use pyo3::prelude::*;
use std::path::{Path, PathBuf};

/// Fewer real gaps than this in the takes under test say too little about occlusion (the
/// CLI's threshold for falling back to the built-in statistics).
const MIN_OWN_GAPS: usize = 50;

/// A take given as a `Take` or a path, with the name the report uses for it.
fn named_take(item: &Bound<'_, PyAny>) -> PyResult<(String, Take)> {
    if let Ok(take) = item.cast::<PyTake>() {
        let take = take.borrow();
        return Ok((take.name(), take.take.clone()));
    }
    let path: PathBuf = item.extract()?;
    let take = PyTake::read_path(&path).map_err(|e| failure(Some(&path), &e))?;
    Ok((path.display().to_string(), take.take))
}

/// Occlusion statistics of a gap source: a statistics JSON file or a take with real gaps.
fn source_model(path: &Path) -> PyResult<Result<GapModel, GapStatistics>> {
    locap_io::atomic::protect(path);
    if crate::take::extension(path) == "json" {
        let text = std::fs::read_to_string(path)
            .with_context(|| path.display().to_string())
            .map_err(|e| failure(Some(path), &e))?;
        let model = GapModel::from_json(&text)
            .with_context(|| path.display().to_string())
            .map_err(|e| failure(Some(path), &e))?;
        return Ok(Ok(model));
    }
    let take = PyTake::read_path(path).map_err(|e| failure(Some(path), &e))?;
    Ok(Err(GapStatistics::of_take(&take.take)))
}

/// The gaps to hide, chosen as `locap bench fill` chooses them.
fn gap_model(
    takes: &[(String, Take)],
    gaps: &str,
    sources: &[PathBuf],
    max_gap: usize,
    uniform_fraction: f64,
) -> PyResult<GapModel> {
    let mut model = match gaps {
        "uniform" => GapModel::uniform(uniform_fraction, max_gap),
        "real" => {
            let mut stats = Vec::new();
            let mut models = Vec::new();
            if sources.is_empty() {
                let own: Vec<_> = takes.iter().map(|(_, t)| GapStatistics::of_take(t)).collect();
                if own.iter().map(|s| s.gap_count()).sum::<usize>() >= MIN_OWN_GAPS {
                    stats.extend(own);
                } else {
                    models.push(GapModel::builtin());
                }
            }
            for source in sources {
                match source_model(source)? {
                    Ok(model) => models.push(model),
                    Err(statistics) => stats.push(statistics),
                }
            }
            let mut model = match (stats.is_empty(), models.pop()) {
                (true, Some(model)) => model,
                (true, None) => return Err(usage("no gap statistics")),
                (false, last) => {
                    models.extend(last);
                    GapModel::from_statistics(&stats).map_err(|e| {
                        usage(format!("the takes have no real gaps to learn from ({e}): give gap_source=[...]"))
                    })?
                }
            };
            for m in &models {
                model.merge(m);
            }
            model
        }
        other => return Err(usage(format!("gaps {other:?}: one of real, uniform"))),
    };
    model.max_gap_frames = max_gap.min(model.length_histogram.len().saturating_sub(1)).max(1);
    Ok(model)
}

/// The shipped refiners that carry a take's markers, refined together (scored as `neural`).
struct FittingRefiners<'a>(&'a [Refiner]);

impl Filler for FittingRefiners<'_> {
    fn describe(&self) -> String {
        "shipped refiners".into()
    }

    fn fill(&self, take: &Take) -> Result<Filled, FillError> {
        let fitting: Vec<&Refiner> = self.0.iter().filter(|r| r.fits(take)).collect();
        if fitting.is_empty() {
            return Err(FillError::new(self, "no shipped refiner was trained on this marker set"));
        }
        locap_nn::refine_all_of(take, &fitting).map_err(|e| FillError::new(self, e))
    }
}

/// `locap.bench_fill(takes, ...)`: hides realistic gaps in takes with ground truth (Takes or
/// paths), fills them with every method on the same gaps (the shipped refiner as `neural`
/// unless `no_neural`, plus any `models`) and returns the report of `locap bench fill --json`
/// as a dict, with the printed table under `"table"`.
#[pyfunction]
#[pyo3(signature = (
    takes, *, gaps = "real", gap_source = Vec::new(), max_gap = 600, uniform_fraction = 0.1, seed = 1,
    neighbours = 6, models = Vec::new(), no_neural = false,
))]
#[allow(clippy::too_many_arguments)] // Python keyword arguments, one per CLI flag.
pub fn bench_fill<'py>(
    py: Python<'py>,
    takes: Vec<Bound<'py, PyAny>>,
    gaps: &str,
    gap_source: Vec<PathBuf>,
    max_gap: usize,
    uniform_fraction: f64,
    seed: u64,
    neighbours: usize,
    models: Vec<PathBuf>,
    no_neural: bool,
) -> PyResult<Bound<'py, PyAny>> {
    if takes.is_empty() {
        return Err(usage("no takes"));
    }
    if !(1..=1 << 24).contains(&max_gap) {
        return Err(usage(format!("max_gap {max_gap}: must be 1 to {}", 1 << 24)));
    }
    if !(0.0..=1.0).contains(&uniform_fraction) {
        return Err(usage(format!("uniform_fraction {uniform_fraction}: must be between 0 and 1")));
    }
    if !(1..=locap_nn::limits::MAX_NEIGHBOURS).contains(&neighbours) {
        return Err(usage(format!("neighbours {neighbours}: must be 1 to {}", locap_nn::limits::MAX_NEIGHBOURS)));
    }
    let takes: Vec<(String, Take)> = takes.iter().map(named_take).collect::<PyResult<_>>()?;
    let model = gap_model(&takes, gaps, &gap_source, max_gap, uniform_fraction)?;
    let device = Default::default();
    let mut refiners = Vec::new();
    for path in &models {
        locap_io::atomic::protect(path);
        let refiner = std::fs::read(path)
            .context("cannot read the model")
            .and_then(|bytes| Ok(Refiner::from_bytes(&bytes, &device)?))
            .with_context(|| path.display().to_string())
            .map_err(|e| failure(Some(path), &e))?;
        let stem = path.file_stem().unwrap_or_default().to_string_lossy();
        let name = match refiner.meta.init {
            locap_clean::FillMethod::Linear => format!("neural-no-edm:{stem}"),
            _ => format!("neural:{stem}"),
        };
        refiners.push((name, refiner));
    }
    let shipped = if no_neural {
        Vec::new()
    } else {
        locap_nn::shipped::refiners(&device).map_err(|e| failure(None, &e.into()))?
    };
    let report = py.detach(|| {
        let fitting = FittingRefiners(&shipped);
        let variants: Vec<(String, fill_bench::VariantFiller)> =
            Variant::all().into_iter().map(|v| (v.name(), v.filler(neighbours))).collect();
        let mut methods: Vec<Candidate> =
            variants.iter().map(|(name, filler)| Candidate { name, filler: filler as &dyn Filler }).collect();
        methods.extend(refiners.iter().map(|(name, refiner)| Candidate { name, filler: refiner as &dyn Filler }));
        if takes.iter().any(|(_, take)| shipped.iter().any(|r| r.fits(take))) {
            methods.push(Candidate { name: "neural", filler: &fitting });
        }
        fill_bench::run_candidates(&takes, &model, &methods, seed)
    });
    let mut value = serde_json::to_value(&report).map_err(|e| failure(None, &e.into()))?;
    if let Some(map) = value.as_object_mut() {
        map.insert("table".into(), report.table().into());
    }
    json_to_py(py, &value)
}
