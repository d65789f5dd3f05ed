//! `find_reversals` and `reversal_order`: the dead-band reversal machines of [`crate::reversals`] over arrays.
use numpy::PyArray1;
use pyo3::prelude::*;

use crate::python::BmrError;
use crate::python::arrays::{DETACH_LEN, extract_f64_array};
use crate::reversals::{ReversalFinder, ReversalOrder};

fn finite_input(u: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
    let v = extract_f64_array(u, "u")?;
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(BmrError::new_err(format!(
            "{what}: input sample {i} is not finite ({})",
            v[i]
        )));
    }
    Ok(v)
}

/// Indices of the reversal extrema of `u`: a maximum (minimum) is confirmed once the input has come back from
/// it by more than `deadband` (input units, > 0). Noise and backward slips below the dead-band are ignored; the
/// run's start is no reversal.
#[pyfunction]
#[pyo3(signature = (u, deadband))]
fn find_reversals<'py>(
    py: Python<'py>,
    u: &Bound<'py, PyAny>,
    deadband: f64,
) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let mut finder = ReversalFinder::new(deadband).ok_or_else(|| {
        BmrError::new_err(format!(
            "reversal dead-band must be positive and finite, got {deadband}"
        ))
    })?;
    let u = finite_input(u, "find_reversals")?;
    let mut scan = || -> Vec<i64> {
        u.iter()
            .filter_map(|&x| finder.push(x).map(|r| r.index as i64))
            .collect()
    };
    let out = if u.len() > DETACH_LEN {
        py.detach(scan)
    } else {
        scan()
    };
    Ok(PyArray1::from_vec(py, out))
}

/// Reversal order of every sample of `u`: 0 on the major loop (reset whenever the input comes within
/// `saturation_tol` of `lo` or `hi`; default 0.2 % of `hi - lo`), +1 at every later reversal beyond `deadband`
/// (default 1 % of `hi - lo`).
#[pyfunction]
#[pyo3(signature = (u, lo, hi, deadband=None, *, saturation_tol=None))]
fn reversal_order<'py>(
    py: Python<'py>,
    u: &Bound<'py, PyAny>,
    lo: f64,
    hi: f64,
    deadband: Option<f64>,
    saturation_tol: Option<f64>,
) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let span = hi - lo;
    let db = deadband.unwrap_or(0.01 * span);
    let tol = saturation_tol.unwrap_or(0.002 * span);
    let mut counter = ReversalOrder::new(lo, hi, db, tol).ok_or_else(|| {
        BmrError::new_err(format!(
            "reversal_order needs finite lo < hi, a positive dead-band and a nonnegative saturation tolerance \
             (lo={lo}, hi={hi}, deadband={db}, saturation_tol={tol})"
        ))
    })?;
    let u = finite_input(u, "reversal_order")?;
    let mut scan = || -> Vec<i64> { u.iter().map(|&x| i64::from(counter.push(x))).collect() };
    let out = if u.len() > DETACH_LEN {
        py.detach(scan)
    } else {
        scan()
    };
    Ok(PyArray1::from_vec(py, out))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(find_reversals, m)?)?;
    m.add_function(wrap_pyfunction!(reversal_order, m)?)?;
    Ok(())
}
