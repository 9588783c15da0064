//! locap in Python: the module `locap._locap`, which the pure-Python package `locap`
//! (`python/locap/`) re-exports and extends with the Ray fan-out (`locap.ray`).
//!
//! # What it binds
//! The same one-call library stages the `locap` binary runs, on the same defaults, with numpy
//! arrays in and out:
//!
//! - [`take`]: `locap.read(path)` gives a `Take` (positions frames x markers x 3 in mm, NaN
//!   where missing; labels, rate, first frame, up axis, the C3D parameters as a dict), and
//!   `Take.write(path)` writes C3D, TRC or CSV by extension. A take read from a C3D file keeps
//!   the whole file, so writing it back keeps every parameter and analog channel, through the
//!   same library calls the CLI makes (`locap_io::c3d::C3dFile::write_changed` for a changed
//!   take): the same bytes as `locap convert` and `locap clean`.
//! - [`stages`]: `locap.clean` (`locap_clean::clean_with` with `locap clean`'s defaults and
//!   methods), `locap.label` (`locap_label::label_take`), `locap.solve`
//!   (`locap_nn::shipped::solver` and the shipped refiners that fit the take, as `locap solve`)
//!   giving a `Motion`.
//! - [`bench`]: `locap.bench_fill`, the table of `locap bench fill` as a dict.
//!
//! # Errors
//! A take or file that fails raises `locap.Error` with the message the CLI prints for it,
//! `path: reason`; an argument that cannot make sense (the CLI's usage errors) raises
//! `ValueError`. Nothing panics on bad input.
//!
//! # Threads
//! The work runs with the interpreter released (`Python::detach`), so Python threads (a
//! `ThreadPoolExecutor` over takes) run stages in parallel.

pub mod bench;
pub mod stages;
pub mod take;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::Path;

pyo3::create_exception!(
    locap,
    Error,
    pyo3::exceptions::PyException,
    "A take or file locap could not process; the message is the CLI's `path: reason`."
);

/// `err` as `locap.Error`, worded as the CLI reports a failed take: the error's own text when
/// it names `path` already (the readers' and writers' errors do), else `path: ` in front.
pub fn failure(path: Option<&Path>, err: &anyhow::Error) -> PyErr {
    Error::new_err(message(path, err))
}

/// The text of [`failure`].
pub fn message(path: Option<&Path>, err: &anyhow::Error) -> String {
    let text = format!("{err:#}");
    match path {
        Some(path) if !text.contains(&path.display().to_string()) => format!("{}: {text}", path.display()),
        _ => text,
    }
}

/// A usage error: an argument value that cannot make sense (`ValueError`).
pub fn usage(message: impl Into<String>) -> PyErr {
    pyo3::exceptions::PyValueError::new_err(message.into())
}

/// A JSON value (a report serialised by serde) as plain Python objects: dicts, lists, str,
/// int, float, bool and None.
pub fn json_to_py<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    use serde_json::Value;
    Ok(match value {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_u64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, Some(u)) => u.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(json_to_py(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (key, item) in map {
                dict.set_item(key, json_to_py(py, item)?)?;
            }
            dict.into_any()
        }
    })
}

/// The native module.
#[pymodule]
fn _locap(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add_class::<take::PyTake>()?;
    m.add_class::<stages::PyMotion>()?;
    m.add_function(wrap_pyfunction!(take::read, m)?)?;
    m.add_function(wrap_pyfunction!(stages::clean, m)?)?;
    m.add_function(wrap_pyfunction!(stages::label, m)?)?;
    m.add_function(wrap_pyfunction!(stages::solve, m)?)?;
    m.add_function(wrap_pyfunction!(bench::bench_fill, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_path_once() {
        let path = Path::new("takes/a.c3d");
        let bare = anyhow::anyhow!("no frame rate");
        assert_eq!(message(Some(path), &bare), "takes/a.c3d: no frame rate");
        let named = anyhow::anyhow!("takes/a.c3d: C3D header malformed at byte 0");
        assert_eq!(message(Some(path), &named), "takes/a.c3d: C3D header malformed at byte 0");
        let context = anyhow::anyhow!("bad list").context("models/x.locapnn");
        assert_eq!(message(None, &context), "models/x.locapnn: bad list");
    }
}
