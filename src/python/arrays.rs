//! Conversions between numpy arrays / Python sequences and slices.
use numpy::{AllowTypeChange, PyArray1, PyArrayLike1};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};

use crate::from_curves::CurveData;

/// Arrays longer than this are processed with the GIL released.
pub(crate) const DETACH_LEN: usize = 4096;

/// Any 1-D array-like of numbers as `Vec<f64>` (ints and lists accepted).
pub(crate) fn to_vec(a: PyArrayLike1<'_, f64, AllowTypeChange>) -> Vec<f64> {
    a.as_array().iter().copied().collect()
}

pub(crate) fn to_numpy<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_vec(py, v)
}

/// A 1-D float array from a Python object, with a clear error naming the argument.
pub(crate) fn extract_f64_array(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
    let a: PyArrayLike1<'_, f64, AllowTypeChange> = obj.extract().map_err(|_| {
        crate::python::BmrError::new_err(format!("{what}: expected a 1-D array of numbers"))
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
