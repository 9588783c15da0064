//! `locap.bench_fill`: the gap-fill benchmark of `locap bench fill` (`locap_eval::fill_bench`:
//! realistic gaps hidden in takes with ground truth, every method on the same gaps, LocalMoCap
//! section 4's OMPE), its report as a dict.

use crate::take::PyTake;
use crate::{failure, json_to_py, usage};
use anyhow::Context;
use locap_core::{GapStatistics, Take};
use locap_eval::fill_bench;
use locap_eval::fill_candidates::{self, FillCandidates, GapSource};
use locap_eval::gap_model::GapModel;
use locap_nn::Refiner;
use pyo3::prelude::*;
use std::path::{Path, PathBuf};

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
    match gaps {
        "uniform" => {
            let mut model = GapModel::uniform(uniform_fraction, max_gap);
            model.max_gap_frames = max_gap.min(model.length_histogram.len().saturating_sub(1)).max(1);
            Ok(model)
        }
        "real" => {
            let mut read = Vec::new();
            for source in sources {
                read.push(match source_model(source)? {
                    Ok(model) => GapSource::Model(model),
                    Err(statistics) => GapSource::Statistics(statistics),
                });
            }
            let (model, _) = fill_candidates::real_gap_model(takes, read, max_gap).map_err(|e| {
                usage(format!("the takes have no real gaps to learn from ({e}): give gap_source=[...]"))
            })?;
            Ok(model)
        }
        other => Err(usage(format!("gaps {other:?}: one of real, uniform"))),
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
    let mut given = Vec::new();
    for path in &models {
        locap_io::atomic::protect(path);
        let refiner = std::fs::read(path)
            .context("cannot read the model")
            .and_then(|bytes| Ok(Refiner::from_bytes(&bytes, &device)?))
            .with_context(|| path.display().to_string())
            .map_err(|e| failure(Some(path), &e))?;
        given.push((path.file_stem().unwrap_or_default().to_string_lossy().into_owned(), refiner));
    }
    let shipped = if no_neural {
        Vec::new()
    } else {
        locap_nn::shipped::refiners(&device).map_err(|e| failure(None, &e.into()))?
    };
    let report = py.detach(|| {
        let candidates = FillCandidates::new(neighbours, given, shipped);
        let fitting = candidates.fitting();
        let methods = candidates.for_takes(&takes, &fitting);
        fill_bench::run_candidates(&takes, &model, &methods, seed)
    });
    let mut value = serde_json::to_value(&report).map_err(|e| failure(None, &e.into()))?;
    if let Some(map) = value.as_object_mut() {
        map.insert("table".into(), report.table().into());
    }
    json_to_py(py, &value)
}
