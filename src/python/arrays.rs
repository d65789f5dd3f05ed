//! Conversions between numpy arrays / Python sequences and slices.
use numpy::{AllowTypeChange, PyArray1, PyArrayLike1, PyArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};

use crate::from_curves::CurveData;

/// Arrays longer than this are processed with the GIL released.
pub(crate) const DETACH_LEN: usize = 4096;

/// Any 1-D array-like of numbers as `Vec<f64>` (ints and lists accepted).
fn to_vec(a: PyArrayLike1<'_, f64, AllowTypeChange>) -> Vec<f64> {
    a.as_array().iter().copied().collect()
}

pub(crate) fn to_numpy<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_vec(py, v)
}

/// A 1-D float array from a Python object (floats or integers); anything else is a `TypeError` naming the
/// argument. Booleans and complex numbers are refused rather than silently turned into 0/1 or real parts.
pub(crate) fn extract_f64_array(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
    if let Ok(a) = obj.cast::<PyArray1<f64>>() {
        let a = a.readonly();
        // A contiguous array is one copy of its memory; a strided one is gathered element by element.
        return Ok(match a.as_slice() {
            Ok(s) => s.to_vec(),
            Err(_) => a.as_array().iter().copied().collect(),
        });
    }
    let type_err = |detail: String| PyTypeError::new_err(format!("{what}: {detail}"));
    let arr = obj
        .py()
        .import("numpy")?
        .call_method1("asarray", (obj,))
        .map_err(|e| type_err(format!("expected a 1-D array of numbers ({e})")))?;
    let dtype = arr.getattr("dtype")?;
    let kind: String = dtype.getattr("kind")?.extract()?;
    match kind.as_str() {
        "f" | "i" | "u" => {}
        "b" => {
            return Err(type_err(String::from(
                "boolean values are not numbers; convert them explicitly (e.g. astype(float))",
            )));
        }
        "c" => {
            return Err(type_err(String::from(
                "complex values; pass the real part or the magnitude explicitly",
            )));
        }
        _ => {
            return Err(type_err(format!(
                "expected numbers, got an array of dtype {}",
                dtype.str()?
            )));
        }
    }
    // Numbers in the wrong shape are a value problem (as in numpy), not a type problem.
    let a: PyArrayLike1<'_, f64, AllowTypeChange> = arr.extract().map_err(|_| {
        let ndim: usize = arr.getattr("ndim").and_then(|n| n.extract()).unwrap_or(0);
        crate::python::BmrError::new_err(format!(
            "{what}: expected a 1-D array, got {ndim} dimensions"
        ))
    })?;
    Ok(to_vec(a))
}

/// Curves as a Python list of `(u, y)` numpy array pairs.
pub(crate) fn curves_to_py<'py>(
    py: Python<'py>,
    curves: Vec<CurveData>,
) -> PyResult<Bound<'py, PyList>> {
    let items: Vec<_> = curves
        .into_iter()
        .map(|(u, y)| PyTuple::new(py, [to_numpy(py, u), to_numpy(py, y)]))
        .collect::<PyResult<_>>()?;
    PyList::new(py, items)
}
