//! `locap.Take` and `locap.read`: a marker take as numpy arrays, read from and written to C3D,
//! TRC and CSV (formats as `locap_io` reads them: C3D User Guide, the TRC and CSV layouts of
//! `locap convert`).
//!
//! A take read from a C3D file keeps the whole file ([`Source`]) so that writing it as C3D
//! loses nothing: unchanged, it is written as `locap convert a.c3d b.c3d` writes it; changed
//! (cleaned, relabeled, positions replaced), through `C3dFile::write_changed`, the call
//! `locap clean` writes with, with what cleaning did in the `LOCAP` group. Like the CLI, the
//! package never overwrites a file it has read (`locap_io::atomic::protect`).

use crate::{failure, json_to_py, usage};
use anyhow::bail;
use locap_core::{LengthUnit, MarkerName, Provenance, Take, UpAxis, Vec3};
use locap_io::c3d::{self, C3dFile, ParamData};
use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray2, PyArray3, PyReadonlyArray3};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The C3D file a take was read from, whole.
#[derive(Debug)]
pub struct Source {
    /// Every parameter, the analog data and the points as read.
    pub file: C3dFile,
    /// Where it was read from (errors of putting the take back name it, as the CLI's do).
    pub path: PathBuf,
}

/// What `locap label` records in the `LOCAP` group of a labeled take.
#[derive(Debug, Clone)]
pub struct LabelNotes {
    /// `LOCAP:LABELED`: the method and template.
    pub note: String,
    /// `LOCAP:LABEL_CONFIDENCE`.
    pub confidence: Vec<String>,
    /// `LOCAP:LABEL_UNCERTAIN`.
    pub uncertain: Vec<String>,
}

/// A marker take: positions in millimetres, frames x markers x 3, NaN where a marker is
/// missing.
#[pyclass(name = "Take", module = "locap", skip_from_py_object)]
#[derive(Debug, Clone)]
pub struct PyTake {
    /// The take.
    pub take: Take,
    /// The C3D file it came from, if any (shared by the takes derived from it).
    pub source: Option<Arc<Source>>,
    /// The file it was read from, any format.
    pub path: Option<PathBuf>,
    /// What cleaning did, stored in the `LOCAP` group when written as C3D.
    pub record: Option<Provenance>,
    /// `LOCAP:LABELED`, `LABEL_CONFIDENCE` and `LABEL_UNCERTAIN`, as `locap label` records
    /// them.
    pub labeled: Option<LabelNotes>,
    /// The points differ from the source file's.
    pub changed: bool,
    /// What the reader noticed but read past (the CLI prints these as warnings).
    pub warnings: Vec<String>,
    /// The stage's summary (what `locap clean` prints), as JSON.
    pub report: Option<serde_json::Value>,
}

impl PyTake {
    /// A take with no file behind it.
    pub fn bare(take: Take) -> PyTake {
        PyTake {
            take,
            source: None,
            path: None,
            record: None,
            labeled: None,
            changed: true,
            warnings: Vec::new(),
            report: None,
        }
    }

    /// `take`, a changed version of this one (same source file, notes kept).
    pub fn derived(&self, take: Take) -> PyTake {
        PyTake { take, changed: true, record: None, report: None, warnings: Vec::new(), ..self.clone() }
    }

    /// Reads `path`: TRC and CSV by extension, anything else as C3D (whose reader says clearly
    /// when it is not), as the CLI reads takes.
    pub fn read_path(path: &Path) -> anyhow::Result<PyTake> {
        if let Ok(meta) = std::fs::metadata(path)
            && !meta.is_file()
        {
            bail!("{}: not a regular file (a folder, pipe or device?); not read", path.display());
        }
        locap_io::atomic::protect(path);
        let (take, source, warnings) = match extension(path).as_str() {
            "trc" => {
                let file = locap_io::trc::read_trc_file_path(path)?;
                (file.take, None, file.notes)
            }
            "csv" => (locap_io::csv::read_csv_path(path)?, None, Vec::new()),
            _ => {
                let file = c3d::read_path(path)?;
                let take = file.to_take().map_err(|e| e.in_file(path))?;
                let warnings = file.warnings.clone();
                (take, Some(Arc::new(Source { file, path: path.to_path_buf() })), warnings)
            }
        };
        Ok(PyTake { changed: source.is_none(), source, path: Some(path.to_path_buf()), warnings, ..PyTake::bare(take) })
    }

    /// Writes the take to `path` in the format of its extension.
    pub fn write_path(&self, path: &Path, trc_unit: LengthUnit) -> anyhow::Result<()> {
        match extension(path).as_str() {
            "c3d" => self.write_c3d(path)?,
            "trc" => locap_io::trc::write_trc_path(&self.take, trc_unit, path)?,
            "csv" => locap_io::csv::write_csv_path(&self.take, path)?,
            other => bail!("{}: unknown output format {other:?} (c3d, trc, csv)", path.display()),
        }
        Ok(())
    }

    fn write_c3d(&self, path: &Path) -> anyhow::Result<()> {
        let Some(source) = &self.source else {
            // `locap convert x.trc x.c3d`, and `locap solve --markers-out` for a TRC take.
            let mut file = C3dFile::from_take(&self.take)?;
            self.note_labeled(&mut file);
            if let Some(record) = &self.record {
                file.set_provenance(&self.take, record).map_err(|e| locap_io::Error::from(e).in_file(path))?;
            }
            return Ok(c3d::write_path(&file, path)?);
        };
        let mut file = source.file.clone();
        self.note_labeled(&mut file);
        if self.changed || self.record.is_some() || self.labeled.is_some() {
            file.write_changed(&self.take, self.record.as_ref(), &source.path, path)?;
        } else {
            c3d::write_path(&file, path)?;
        }
        Ok(())
    }

    fn note_labeled(&self, file: &mut C3dFile) {
        if let Some(notes) = &self.labeled {
            file.parameters.set_strings("LOCAP", "LABELED", std::slice::from_ref(&notes.note));
            file.parameters.set_strings("LOCAP", "LABEL_CONFIDENCE", &notes.confidence);
            file.parameters.set_strings("LOCAP", "LABEL_UNCERTAIN", &notes.uncertain);
        }
    }

    /// Positions as frames x markers x 3, NaN where missing.
    pub fn positions_array(&self) -> Array3<f64> {
        let (frames, markers) = (self.take.frame_count(), self.take.marker_count());
        let mut out = Array3::from_elem((frames, markers, 3), f64::NAN);
        for f in 0..frames {
            for m in 0..markers {
                if let Some(p) = self.take.position_mm(f, m) {
                    for a in 0..3 {
                        out[[f, m, a]] = p[a];
                    }
                }
            }
        }
        out
    }

    /// The label shown in errors and reprs: the file, or "take".
    pub fn name(&self) -> String {
        self.path.as_ref().map_or("take".into(), |p| p.display().to_string())
    }
}

/// Lower-case extension of `path`.
pub fn extension(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase()
}

/// A sample of a positions array: a position, `None` when any coordinate is NaN.
fn sample(p: [f64; 3]) -> Result<Option<Vec3>, String> {
    if p.iter().any(|c| c.is_nan()) {
        return Ok(None);
    }
    if p.iter().any(|c| !c.is_finite()) {
        return Err("positions must be finite numbers or NaN (missing)".into());
    }
    Ok(Some(Vec3::new(p[0], p[1], p[2])))
}

fn parse_up_axis(text: &str) -> PyResult<UpAxis> {
    match text.trim().to_ascii_uppercase().as_str() {
        "Y" | "+Y" => Ok(UpAxis::Y),
        "Z" | "+Z" => Ok(UpAxis::Z),
        other => Err(usage(format!("up_axis {other:?}: expected \"Y\" or \"Z\""))),
    }
}

/// Parses a length unit name as the CLI does (`mm`, `cm`, `m`, `in`).
pub fn parse_unit(text: &str) -> PyResult<LengthUnit> {
    LengthUnit::parse(text).ok_or_else(|| usage(format!("unknown length unit {text:?} (mm, cm, m, in)")))
}

fn check_shape(positions: &PyReadonlyArray3<'_, f64>, markers: usize) -> PyResult<()> {
    let shape = positions.as_array().shape().to_vec();
    if shape[2] != 3 || shape[1] != markers {
        return Err(usage(format!(
            "positions of shape {shape:?}: expected (frames, {markers}, 3), one column per label, in mm"
        )));
    }
    Ok(())
}

/// `locap.read(path)`: a take from a C3D, TRC or CSV file.
///
/// Raises `locap.Error` (`path: reason`) for a file that cannot be read.
#[pyfunction]
pub fn read(py: Python<'_>, path: PathBuf) -> PyResult<PyTake> {
    py.detach(|| PyTake::read_path(&path)).map_err(|e| failure(Some(&path), &e))
}

#[pymethods]
impl PyTake {
    /// A take from numpy positions (frames x markers x 3, mm, NaN where missing) and one
    /// label per marker.
    #[new]
    #[pyo3(signature = (positions, labels, rate_hz, first_frame = 1, up_axis = "Z"))]
    fn new(
        positions: PyReadonlyArray3<'_, f64>,
        labels: Vec<String>,
        rate_hz: f64,
        first_frame: u32,
        up_axis: &str,
    ) -> PyResult<PyTake> {
        check_shape(&positions, labels.len())?;
        let view = positions.as_array();
        let markers: Vec<MarkerName> = labels.iter().map(|l| MarkerName::parse(l)).collect();
        let mut take = Take::empty(markers, view.shape()[0], rate_hz).map_err(|e| usage(e.to_string()))?;
        for f in 0..take.frame_count() {
            for m in 0..take.marker_count() {
                let p = sample([view[[f, m, 0]], view[[f, m, 1]], view[[f, m, 2]]]).map_err(usage)?;
                take.set_position_mm(f, m, p).map_err(|e| usage(e.to_string()))?;
            }
        }
        take.first_frame = first_frame;
        take.up_axis = parse_up_axis(up_axis)?;
        Ok(PyTake::bare(take))
    }

    /// Marker positions, frames x markers x 3, millimetres, NaN where missing (a copy; assign
    /// to `positions` to change the take).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f64>> {
        py.detach(|| self.positions_array()).into_pyarray(py)
    }

    /// Replaces the positions (same frames and markers; NaN = missing). Samples that keep
    /// their value keep their residual and camera mask.
    #[setter]
    fn set_positions(&mut self, positions: PyReadonlyArray3<'_, f64>) -> PyResult<()> {
        check_shape(&positions, self.take.marker_count())?;
        let view = positions.as_array();
        if view.shape()[0] != self.take.frame_count() {
            return Err(usage(format!(
                "positions of {} frames for a take of {}; build a new Take to change the frame count",
                view.shape()[0],
                self.take.frame_count()
            )));
        }
        let mut take = self.take.clone();
        for f in 0..take.frame_count() {
            for m in 0..take.marker_count() {
                let p = sample([view[[f, m, 0]], view[[f, m, 1]], view[[f, m, 2]]]).map_err(usage)?;
                if p != take.position_mm(f, m) {
                    take.set_position_mm(f, m, p).map_err(|e| usage(e.to_string()))?;
                }
            }
        }
        if take != self.take {
            self.take = take;
            self.changed = true;
        }
        Ok(())
    }

    /// Residuals, frames x markers, millimetres (0 for samples locap computed), NaN where
    /// missing.
    #[getter]
    fn residuals_mm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let (frames, markers) = (self.take.frame_count(), self.take.marker_count());
        let mut out = Array2::from_elem((frames, markers), f64::NAN);
        for f in 0..frames {
            for m in 0..markers {
                if self.take.is_valid(f, m) {
                    out[[f, m]] = self.take.quality(f, m).residual_mm as f64;
                }
            }
        }
        out.into_pyarray(py)
    }

    /// Frames x markers, True where locap computed the sample (filled gaps and refilled
    /// outliers), from what cleaning recorded (`LOCAP:FILLED`, also read back from a file
    /// `locap clean` wrote).
    #[getter]
    fn filled<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<bool>>> {
        let record = match (&self.record, &self.source) {
            (Some(record), _) => Some(record.clone()),
            (None, Some(source)) if !self.changed => {
                Some(source.file.provenance(&self.take).map_err(|e| failure(Some(&source.path), &e.into()))?)
            }
            _ => None,
        };
        let mut out = Array2::from_elem((self.take.frame_count(), self.take.marker_count()), false);
        for run in record.iter().flat_map(|r| &r.filled) {
            for f in run.frames.clone() {
                if let Some(cell) = out.get_mut([f, run.marker]) {
                    *cell = true;
                }
            }
        }
        Ok(out.into_pyarray(py))
    }

    /// Marker names as in the file (`Subject:LABEL` where a subject prefix is present).
    #[getter]
    fn labels(&self) -> Vec<String> {
        self.take.markers().iter().map(|n| n.full()).collect()
    }

    /// Frame rate, Hz.
    #[getter]
    fn rate_hz(&self) -> f64 {
        self.take.frame_rate_hz()
    }

    /// Number of the first frame as the capture system counted it.
    #[getter]
    fn first_frame(&self) -> u32 {
        self.take.first_frame
    }

    /// The lab's vertical axis: "Y" or "Z".
    #[getter]
    fn up_axis(&self) -> &'static str {
        match self.take.up_axis {
            UpAxis::Y => "Y",
            UpAxis::Z => "Z",
        }
    }

    /// Number of frames.
    #[getter]
    fn frame_count(&self) -> usize {
        self.take.frame_count()
    }

    /// Number of markers.
    #[getter]
    fn marker_count(&self) -> usize {
        self.take.marker_count()
    }

    /// The file the take was read from (None for a take built from arrays).
    #[getter]
    fn path(&self) -> Option<String> {
        self.path.as_ref().map(|p| p.display().to_string())
    }

    /// What the reader noticed but read past (an empty POINT:UNITS read as mm, ...).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    /// The stage's summary (for a cleaned take: gaps, samples filled, still missing,
    /// outliers, swaps, per marker), or None.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match &self.report {
            Some(report) => json_to_py(py, report),
            None => Ok(py.None().into_bound(py)),
        }
    }

    /// The C3D parameters, `{"GROUP": {"NAME": value}}`: text as a list of strings, numbers
    /// as a list (a single number when the parameter has no dimensions). Empty for TRC/CSV.
    /// After cleaning, what will be written (the `LOCAP` group with it).
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        let Some(source) = &self.source else { return Ok(out) };
        let mut file = source.file.clone();
        if self.changed || self.record.is_some() || self.labeled.is_some() {
            self.note_labeled(&mut file);
            file.set_take(&self.take).map_err(|e| failure(Some(&source.path), &e.into()))?;
            if let Some(record) = &self.record {
                file.set_provenance(&self.take, record).map_err(|e| failure(Some(&source.path), &e.into()))?;
            }
        }
        for group in file.parameters.groups() {
            let values = PyDict::new(py);
            for p in file.parameters.parameters_of(group.id) {
                let value = match &p.data {
                    ParamData::Char(_) => PyList::new(py, p.strings())?.into_any(),
                    _ if p.dims.is_empty() => match &p.data {
                        ParamData::Float(v) => v.first().copied().unwrap_or(f32::NAN).into_pyobject(py)?.into_any(),
                        _ => p.as_i64().unwrap_or_default().into_pyobject(py)?.into_any(),
                    },
                    ParamData::Byte(v) => PyList::new(py, v)?.into_any(),
                    ParamData::Int(v) => PyList::new(py, v)?.into_any(),
                    ParamData::Float(v) => PyList::new(py, v)?.into_any(),
                };
                values.set_item(&p.name, value)?;
            }
            out.set_item(&group.name, values)?;
        }
        Ok(out)
    }

    /// Writes the take: C3D, TRC or CSV by the extension of `path`, atomically. A take read
    /// from C3D keeps every parameter and analog channel of its file. `trc_unit`: length unit
    /// of TRC output (mm, cm, m, in). Raises `locap.Error` (`path: reason`); never overwrites
    /// a file this process has read.
    #[pyo3(signature = (path, *, trc_unit = "mm"))]
    fn write(&self, py: Python<'_>, path: PathBuf, trc_unit: &str) -> PyResult<()> {
        let unit = parse_unit(trc_unit)?;
        py.detach(|| self.write_path(&path, unit)).map_err(|e| failure(Some(&path), &e))
    }

    fn __repr__(&self) -> String {
        format!(
            "<locap.Take {}: {} frames x {} markers at {} Hz, {} missing>",
            self.name(),
            self.take.frame_count(),
            self.take.marker_count(),
            self.take.frame_rate_hz(),
            self.take.missing_count()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/cmu_01_01_last10s.c3d")
    }

    #[test]
    fn a_read_take_writes_its_file_back_unchanged_and_a_changed_one_through_write_changed() {
        let dir = tempfile::tempdir().unwrap();
        let read = PyTake::read_path(&example()).unwrap();
        assert!(!read.changed && read.source.is_some());
        read.write_path(&dir.path().join("same.c3d"), LengthUnit::Millimetre).unwrap();
        let mut file = c3d::read_path(&example()).unwrap();
        let mut bytes = Vec::new();
        c3d::write(&file, &mut bytes).unwrap();
        assert_eq!(std::fs::read(dir.path().join("same.c3d")).unwrap(), bytes);

        let mut take = read.take.clone();
        take.set_position_mm(0, 0, None).unwrap();
        let changed = read.derived(take.clone());
        changed.write_path(&dir.path().join("changed.c3d"), LengthUnit::Millimetre).unwrap();
        file.write_changed(&take, None, &example(), &dir.path().join("direct.c3d")).unwrap();
        assert_eq!(
            std::fs::read(dir.path().join("changed.c3d")).unwrap(),
            std::fs::read(dir.path().join("direct.c3d")).unwrap()
        );
        let positions = changed.positions_array();
        assert!(positions[[0, 0, 0]].is_nan() && positions[[0, 0, 1]].is_nan());
    }

    #[test]
    fn a_take_read_is_never_overwritten_and_unknown_formats_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.c3d");
        std::fs::copy(example(), &path).unwrap();
        let read = PyTake::read_path(&path).unwrap();
        assert!(read.write_path(&path, LengthUnit::Millimetre).is_err());
        let err = read.write_path(&dir.path().join("t.bvh"), LengthUnit::Millimetre).unwrap_err();
        assert!(format!("{err:#}").contains("unknown output format"));
        assert!(PyTake::read_path(dir.path()).is_err());
    }
}
