//! `locap.clean`, `locap.label`, `locap.solve` and `locap.Motion`: the library stages the CLI
//! runs (LocalMoCap sections 3.1-3.2; the labeling paper's sections 3-4), with the CLI's
//! defaults and shipped models.
//!
//! Each function takes and returns in-memory objects; the file a take came from travels with
//! it, so `locap.clean(locap.read(a)).write(b)` writes what `locap clean a -o b` writes.

use crate::take::{PyTake, parse_unit};
use crate::{failure, usage};
use anyhow::Context;
use locap_clean::outliers::OutlierConfig;
use locap_clean::swaps::SwapConfig;
use locap_clean::{CleanConfig, Cleaned, FillConfig, FillMethod, neighbours::Selection};
use locap_core::Motion;
use locap_label::{FitConfig, LabelConfig, Template};
use locap_nn::kinematic::KinematicSolver;
use locap_nn::method::{SolveMethod, solve_take};
use locap_nn::solver::Solver;
use locap_nn::{Refiner, RefinerSource};
use locap_synth::Layout;
use numpy::IntoPyArray;
use numpy::ndarray::{Array2, Array3};
use numpy::{PyArray2, PyArray3};
use pyo3::prelude::*;
use serde_json::json;
use std::path::{Path, PathBuf};

/// `method=` of [`clean`]: the fill, and whether the learned refiner refines it.
fn fill_method(name: &str) -> PyResult<(FillMethod, bool)> {
    Ok(match name {
        "edm" => (FillMethod::Edm, false),
        "linear" => (FillMethod::Linear, false),
        "spline" => (FillMethod::Spline, false),
        "pca" => (FillMethod::Pca, false),
        "pca-aligned" => (FillMethod::PcaAligned, false),
        "rigid" => (FillMethod::Rigid, false),
        "rigid-spline" => (FillMethod::RigidSpline, false),
        "distance" => (FillMethod::Distance, false),
        "pose-match" => (FillMethod::PoseMatch, false),
        "auto" => (FillMethod::Auto, false),
        // The refiner starts from EDM's fill.
        "neural" => (FillMethod::Edm, true),
        other => {
            return Err(usage(format!(
                "method {other:?}: one of edm, linear, spline, pca, pca-aligned, rigid, rigid-spline, distance, pose-match, auto, neural"
            )));
        }
    })
}

fn selection(name: &str) -> PyResult<Selection> {
    match name {
        "variance" => Ok(Selection::Variance),
        "nearest" => Ok(Selection::MeanDistance),
        other => Err(usage(format!("ranking {other:?}: one of variance, nearest"))),
    }
}

fn positive(name: &str, value: f64) -> PyResult<f64> {
    if !(value.is_finite() && value > 0.0) {
        return Err(usage(format!("{name} {value}: must be a finite number greater than 0")));
    }
    Ok(value)
}

/// Reads model files, naming the file in the error.
fn read_models(paths: &[PathBuf]) -> PyResult<Vec<Vec<u8>>> {
    paths
        .iter()
        .map(|path| {
            locap_io::atomic::protect(path);
            std::fs::read(path)
                .with_context(|| format!("{}: cannot read the model", path.display()))
                .map_err(|e| failure(Some(path), &e))
        })
        .collect()
}

/// What `locap clean` prints for a take, as JSON.
fn clean_report(cleaned: &Cleaned) -> serde_json::Value {
    json!({
        "method": cleaned.method,
        "gaps": cleaned.gap_count(),
        "filled_samples": cleaned.filled_samples(),
        "still_missing": cleaned.still_missing(),
        "outliers": cleaned.outliers.len(),
        "outlier_samples": cleaned.outlier_samples,
        "swaps": cleaned.swaps.len(),
        "filled_by": cleaned.fills_by_method().iter()
            .map(|(method, gaps, samples)| json!({"method": method, "gaps": gaps, "samples": samples}))
            .collect::<Vec<_>>(),
        "markers": cleaned.markers.iter()
            .map(|m| json!({
                "label": m.label, "gaps": m.gaps, "filled_samples": m.filled_samples,
                "still_missing": m.still_missing, "outliers": m.outliers,
            }))
            .collect::<Vec<_>>(),
    })
}

/// `locap.clean(take, ...)`: swapped labels undone, outliers removed and refilled, every gap
/// between captured samples filled (`locap clean`, same defaults). Returns the cleaned take;
/// its `report` is what `locap clean` prints, and writing it as C3D records the changes in the
/// `LOCAP` group.
#[pyfunction]
#[pyo3(signature = (
    take, *, method = "auto", models = Vec::new(), neighbours = 6, ranking = "variance", outliers = true,
    body_threshold_m_s2 = OutlierConfig::default().body_threshold_m_s2,
    hand_threshold_m_s2 = OutlierConfig::default().hand_threshold_m_s2,
))]
#[allow(clippy::too_many_arguments)] // Python keyword arguments, one per CLI flag.
pub fn clean(
    py: Python<'_>,
    take: PyRef<'_, PyTake>,
    method: &str,
    models: Vec<PathBuf>,
    neighbours: usize,
    ranking: &str,
    outliers: bool,
    body_threshold_m_s2: f64,
    hand_threshold_m_s2: f64,
) -> PyResult<PyTake> {
    let (fill, neural) = fill_method(method)?;
    if !neural && !models.is_empty() {
        return Err(usage("models are only used with method=\"neural\""));
    }
    if !(1..=locap_nn::limits::MAX_NEIGHBOURS).contains(&neighbours) {
        return Err(usage(format!("neighbours {neighbours}: must be 1 to {}", locap_nn::limits::MAX_NEIGHBOURS)));
    }
    let config = CleanConfig {
        swaps: outliers.then(SwapConfig::default),
        outliers: outliers.then(|| OutlierConfig {
            body_threshold_m_s2,
            hand_threshold_m_s2,
            ..OutlierConfig::default()
        }),
        fill: FillConfig { method: fill, neighbours, selection: selection(ranking)? },
    };
    positive("body_threshold_m_s2", body_threshold_m_s2)?;
    positive("hand_threshold_m_s2", hand_threshold_m_s2)?;
    let model_bytes: Vec<(String, Vec<u8>)> = models
        .iter()
        .map(|p| p.file_name().unwrap_or_default().to_string_lossy().into_owned())
        .zip(read_models(&models)?)
        .collect();
    // A bad model is one clear error before any work, as in the CLI.
    for ((_, bytes), path) in model_bytes.iter().zip(&models) {
        Refiner::from_bytes(bytes, &Default::default())
            .with_context(|| path.display().to_string())
            .map_err(|e| failure(Some(path), &e))?;
    }
    let inner: &PyTake = &take;
    let cleaned = py
        .detach(|| -> anyhow::Result<Cleaned> {
            let source = match neural {
                false => RefinerSource::None,
                true if model_bytes.is_empty() => RefinerSource::Shipped,
                true => RefinerSource::Given(model_bytes),
            };
            let filler = locap_nn::filler_for(&inner.take, config.fill, &source)?;
            Ok(locap_clean::clean_with(&inner.take, &config, filler.as_ref())?)
        })
        .map_err(|e| failure(inner.path.as_deref(), &e))?;
    let mut out = inner.derived(cleaned.take().clone());
    out.record = Some(cleaned.provenance());
    out.report = Some(clean_report(&cleaned));
    Ok(out)
}

/// `locap.label(raw, template, ...)`: names the points of a raw take online from a labeled
/// template take (or the path of one), as `locap label`: one column per template marker,
/// missing where no point was labeled; ghosts dropped, or kept as `*N` with
/// `keep_unlabeled=True`. `method`: "ours" (soft graph matching), "ugm" or "cp".
#[pyfunction]
#[pyo3(signature = (
    raw, template, *, template_frame = None, fit_distance_mm = FitConfig::default().accept_mm,
    keep_unlabeled = false, method = "ours",
))]
pub fn label(
    py: Python<'_>,
    raw: PyRef<'_, PyTake>,
    template: &Bound<'_, PyAny>,
    template_frame: Option<usize>,
    fit_distance_mm: f64,
    keep_unlabeled: bool,
    method: &str,
) -> PyResult<PyTake> {
    let template = match template.cast::<PyTake>() {
        Ok(take) => take.borrow().clone(),
        Err(_) => {
            let path: PathBuf = template.extract()?;
            py.detach(|| PyTake::read_path(&path)).map_err(|e| failure(Some(&path), &e))?
        }
    };
    let method = match method {
        "ours" => locap_label::Method::SoftGraph,
        "ugm" => locap_label::Method::Unary,
        "cp" => locap_label::Method::ClosestPoint,
        other => return Err(usage(format!("method {other:?}: one of ours, ugm, cp"))),
    };
    let config = LabelConfig {
        fit: FitConfig { accept_mm: positive("fit_distance_mm", fit_distance_mm)?, ..FitConfig::default() },
        keep_unlabeled,
        ..LabelConfig::with_method(method)
    };
    let template_name = template.name();
    let built = Template::from_take(&template.take, template_frame)
        .with_context(|| template_name.clone())
        .map_err(|e| failure(template.path.as_deref(), &e))?;
    let inner: &PyTake = &raw;
    let labeled = py
        .detach(|| locap_label::label_take(&inner.take, &built, &config))
        .with_context(|| inner.name())
        .map_err(|e| failure(inner.path.as_deref(), &e))?;
    let mut out = inner.derived(labeled.take.clone());
    // What `locap label` records, with the same edge tolerance; another subject's labels are
    // checked against the template calibrated on the take, as there.
    let own = labeled.subject_template(&built);
    let confidence = labeled.labels.confidence(&labeled.frames, own, LABEL_EDGE_TOLERANCE_MM);
    let (lines, uncertain) = confidence
        .parameters(&built, labeled.take.first_frame)
        .context("LOCAP:LABEL_UNCERTAIN")
        .map_err(|e| failure(inner.path.as_deref(), &e))?;
    out.labeled = Some(crate::take::LabelNotes {
        note: format!("{} template {template_name}", config.method.name()),
        confidence: lines,
        uncertain,
    });
    let samples = (labeled.labels.frame_count() * built.marker_count()).max(1);
    out.report = Some(json!({
        "frames": labeled.labels.frame_count(),
        "markers": built.marker_count(),
        "labeled_samples": labeled.labeled_samples(),
        "labeled_fraction": labeled.labeled_samples() as f64 / samples as f64,
        "unlabeled_points": labeled.unlabeled_points(),
        "fit_rms_mm": labeled.fit.rms_mm,
    }));
    Ok(out)
}

/// Distance a labeled marker's edges may stretch and still confirm its label, mm (as
/// `locap label`'s).
const LABEL_EDGE_TOLERANCE_MM: f64 = 20.0;

/// Skeleton motion solved from markers.
#[pyclass(name = "Motion", module = "locap", frozen)]
pub struct PyMotion {
    motion: Motion,
    cleaned: PyTake,
}

/// One solver model file, or several as one ensemble (`locap solve --model A --model B`).
#[derive(FromPyObject)]
pub enum ModelFiles {
    /// One file.
    One(PathBuf),
    /// Several, their answers averaged.
    Many(Vec<PathBuf>),
}

/// `locap.solve(take, ...)`: the whole `locap solve` pipeline (swaps, outliers, the fill,
/// then the motion solver). `model`: a solver from `locap train solve`, or a list of them as
/// one ensemble (default: the built-in CMU 41-marker solver); `refiner`: a refiner model; `method`: as `locap solve --method`
/// (`auto`, `network`, `ik`, `refine`); `layout`: the kinematic solver's layout, with a
/// skeleton section (default: the CMU 41-marker layout).
#[pyfunction]
#[pyo3(signature = (take, *, model = None, fill = "auto", refiner = None, method = "auto", layout = None))]
pub fn solve(
    py: Python<'_>,
    take: PyRef<'_, PyTake>,
    model: Option<ModelFiles>,
    fill: &str,
    refiner: Option<PathBuf>,
    method: &str,
    layout: Option<PathBuf>,
) -> PyResult<PyMotion> {
    let model = match model {
        None => Vec::new(),
        Some(ModelFiles::One(path)) => vec![path],
        Some(ModelFiles::Many(paths)) => paths,
    };
    let (fill_method, refine) = fill_method(fill)?;
    let method = match method {
        "auto" => SolveMethod::Auto,
        "network" => SolveMethod::Network,
        "ik" => SolveMethod::Kinematic,
        "refine" => SolveMethod::Refine,
        other => return Err(usage(format!("method {other:?}: one of auto, network, ik, refine"))),
    };
    let kinematic = match &layout {
        _ if method == SolveMethod::Network => None,
        None => Some(KinematicSolver::cmu41().map_err(|e| failure(None, &e.into()))?),
        Some(path) => Some(read_kinematic(path).map_err(|e| failure(Some(path), &e))?),
    };
    let model_files: Vec<(String, Vec<u8>)> =
        model.iter().map(|p| p.display().to_string()).zip(read_models(&model)?).collect();
    let refiner_bytes = read_models(refiner.as_slice())?.pop();
    // As `locap solve --model`.
    let load = |device: &_| -> anyhow::Result<Solver> {
        if model_files.is_empty() {
            return locap_nn::shipped::solver(device).context("the built-in solver");
        }
        Ok(locap_nn::solver::ensemble::from_named_files(&model_files, device)?)
    };
    // The models are checked once up front, so a bad file names itself, not the take.
    let device = Default::default();
    load(&device).map_err(|e| failure(None, &e))?;
    if let (Some(bytes), Some(path)) = (&refiner_bytes, &refiner) {
        Refiner::from_bytes(bytes, &device)
            .with_context(|| path.display().to_string())
            .map_err(|e| failure(Some(path), &e))?;
    }
    // As `locap solve --fill / --refiner`: a refiner only when asked for.
    let source = match (refiner_bytes, &refiner) {
        (Some(bytes), Some(path)) => {
            RefinerSource::Given(vec![(path.file_name().unwrap_or_default().to_string_lossy().into_owned(), bytes)])
        }
        _ if refine => RefinerSource::Shipped,
        _ => RefinerSource::None,
    };
    let inner: &PyTake = &take;
    let (motion, cleaned) = py
        .detach(|| -> anyhow::Result<(Motion, Cleaned)> {
            let device = Default::default();
            let solver = load(&device)?;
            let filler = locap_nn::filler_for(
                &inner.take,
                FillConfig { method: fill_method, ..FillConfig::default() },
                &source,
            )?;
            // As `locap solve --method`.
            let solved = solve_take(&inner.take, filler.as_ref(), &solver, kinematic.as_ref(), method)?;
            let (motion, cleaned) = (solved.motion, solved.cleaned);
            // In the animation tools' Y-up frame, as `locap solve` writes it.
            let lab = solver.meta.lab;
            let motion = locap_io::axes::motion_to_tools_y_up(&motion, lab.motion_to_lab_rotation(), lab.up_axis());
            Ok((motion, cleaned))
        })
        .map_err(|e| failure(inner.path.as_deref(), &e))?;
    let mut markers = inner.derived(cleaned.take().clone());
    let mut record = cleaned.provenance();
    // Recorded as `locap solve --markers-out` records it.
    record.method = Some(format!("locap solve: {}", cleaned.method));
    markers.record = Some(record);
    markers.report = Some(clean_report(&cleaned));
    Ok(PyMotion { motion, cleaned: markers })
}

/// The kinematic solver on a layout file (TOML, or JSON by extension) that carries its
/// skeleton.
fn read_kinematic(path: &Path) -> anyhow::Result<KinematicSolver> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read layout", path.display()))?;
    let json = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let layout = if json { Layout::from_json(&text) } else { Layout::from_toml(&text) };
    let layout = layout.with_context(|| path.display().to_string())?;
    KinematicSolver::from_layout(&layout).with_context(|| path.display().to_string())
}

impl PyMotion {
    fn joints(&self) -> usize {
        self.motion.skeleton.len()
    }
}

#[pymethods]
impl PyMotion {
    /// Joint names, skeleton order (parents before children).
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.motion.skeleton.joints().iter().map(|j| j.name.clone()).collect()
    }

    /// Parent index of every joint, -1 for the root.
    #[getter]
    fn parents(&self) -> Vec<i64> {
        self.motion.skeleton.joints().iter().map(|j| j.parent.map_or(-1, |p| p as i64)).collect()
    }

    /// Per joint, True for BVH end sites (no rotation of their own).
    #[getter]
    fn end_sites(&self) -> Vec<bool> {
        self.motion.skeleton.joints().iter().map(|j| j.is_end_site).collect()
    }

    /// Bone offsets from the parent, joints x 3, millimetres, in the skeleton's Y-up frame
    /// (fitted to the subject, averaged over the take).
    #[getter]
    fn offsets_mm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let mut out = Array2::zeros((self.joints(), 3));
        for (j, joint) in self.motion.skeleton.joints().iter().enumerate() {
            for a in 0..3 {
                out[[j, a]] = joint.offset_mm[a];
            }
        }
        out.into_pyarray(py)
    }

    /// Local joint rotations, frames x joints x 4 unit quaternions (w, x, y, z), each relative
    /// to its parent.
    #[getter]
    fn rotations<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f64>> {
        let mut out = Array3::zeros((self.motion.frame_count(), self.joints(), 4));
        for f in 0..self.motion.frame_count() {
            for (j, q) in self.motion.local_rotations(f).iter().enumerate() {
                let q = q.quaternion();
                for (a, v) in [q.w, q.i, q.j, q.k].into_iter().enumerate() {
                    out[[f, j, a]] = v;
                }
            }
        }
        out.into_pyarray(py)
    }

    /// Root position per frame, frames x 3, millimetres, Y-up.
    #[getter]
    fn root_translation_mm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let mut out = Array2::zeros((self.motion.frame_count(), 3));
        for f in 0..self.motion.frame_count() {
            let p = self.motion.root_position_mm(f);
            for a in 0..3 {
                out[[f, a]] = p[a];
            }
        }
        out.into_pyarray(py)
    }

    /// Global joint positions by forward kinematics, frames x joints x 3, millimetres, Y-up.
    fn global_positions_mm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f64>> {
        let (frames, joints) = (self.motion.frame_count(), self.joints());
        let out = py.detach(|| {
            let mut out = Array3::zeros((frames, joints, 3));
            for f in 0..frames {
                for (j, p) in self.motion.forward_kinematics(f).positions_mm.iter().enumerate() {
                    for a in 0..3 {
                        out[[f, j, a]] = p[a];
                    }
                }
            }
            out
        });
        out.into_pyarray(py)
    }

    /// Frame rate, Hz (the take's).
    #[getter]
    fn rate_hz(&self) -> f64 {
        self.motion.frame_rate_hz()
    }

    /// Number of frames (the take's).
    #[getter]
    fn frame_count(&self) -> usize {
        self.motion.frame_count()
    }

    /// The cleaned markers the motion was solved from (what `locap solve --markers-out`
    /// writes).
    #[getter]
    fn cleaned(&self) -> PyTake {
        self.cleaned.clone()
    }

    /// Writes the motion as BVH (`unit`: mm, cm, m or in; default cm as `locap solve`),
    /// atomically. Raises `locap.Error` (`path: reason`).
    #[pyo3(signature = (path, *, unit = "cm"))]
    fn write_bvh(&self, py: Python<'_>, path: PathBuf, unit: &str) -> PyResult<()> {
        let unit = parse_unit(unit)?;
        py.detach(|| locap_io::bvh::write_bvh_path(&self.motion, unit, &path))
            .map_err(|e| failure(Some(Path::new(&path)), &e.into()))
    }

    fn __repr__(&self) -> String {
        format!(
            "<locap.Motion: {} frames x {} joints at {} Hz>",
            self.motion.frame_count(),
            self.joints(),
            self.motion.frame_rate_hz()
        )
    }
}
