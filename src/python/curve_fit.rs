//! `bmr._core.fit_curve`: one raw measured curve binned on the input axis and fitted monotonically.
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::curve_fit::binned_curve;
use crate::python::BmrError;
use crate::python::arrays::extract_f64_array;

/// A curve fitted from raw samples: bin nodes, the monotone fit at them, and what the data did against the
/// curve's direction (output units unless stated).
#[pyclass(name = "CurveFit", module = "bmr", frozen)]
pub(crate) struct PyCurveFit {
    u: Vec<f64>,
    y: Vec<f64>,
    counts: Vec<usize>,
    /// "ascending" or "descending".
    #[pyo3(get)]
    direction: &'static str,
    /// Raw samples fitted.
    #[pyo3(get)]
    samples: usize,
    /// Estimated noise of one output sample (from third differences along the input).
    #[pyo3(get)]
    noise: f64,
    /// Typical standard deviation of a node.
    #[pyo3(get)]
    node_sigma: f64,
    /// Largest move of the binned outputs against the curve's direction (>= 0).
    #[pyo3(get)]
    violation: f64,
    /// Sample (as given) where that move is largest, and its input.
    #[pyo3(get)]
    violation_sample: usize,
    #[pyo3(get)]
    violation_input: f64,
    /// RMS change made by the monotone fit.
    #[pyo3(get)]
    reshaped_rms: f64,
    /// Largest step of the input against the curve's direction (input units).
    #[pyo3(get)]
    input_backtrack: f64,
}

#[pymethods]
impl PyCurveFit {
    /// Node inputs in traversal order, starting at the reversal.
    #[getter]
    fn u<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.u)
    }
    /// Monotone outputs at the nodes.
    #[getter]
    fn y<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.y)
    }
    /// Raw samples in each node's bin.
    #[getter]
    fn counts<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        PyArray1::from_vec(py, self.counts.iter().map(|&c| c as i64).collect())
    }
    /// Nodes in the fit.
    #[getter]
    fn nodes(&self) -> usize {
        self.u.len()
    }

    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("direction", self.direction)?;
        d.set_item("samples", self.samples)?;
        d.set_item("nodes", self.u.len())?;
        d.set_item("noise", self.noise)?;
        d.set_item("node_sigma", self.node_sigma)?;
        d.set_item("violation", self.violation)?;
        d.set_item("violation_sample", self.violation_sample)?;
        d.set_item("violation_input", self.violation_input)?;
        d.set_item("reshaped_rms", self.reshaped_rms)?;
        d.set_item("input_backtrack", self.input_backtrack)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "CurveFit({} from {}: {} samples in {} bins, noise {} (node {}), moves against its \
             direction by {} at sample {}, monotone fit changed it by {} RMS)",
            self.direction,
            crate::python::sig(self.u.first().copied().unwrap_or(f64::NAN), 6),
            self.samples,
            self.u.len(),
            crate::python::sig(self.noise, 3),
            crate::python::sig(self.node_sigma, 3),
            crate::python::sig(self.violation, 3),
            self.violation_sample,
            crate::python::sig(self.reshaped_rms, 3)
        )
    }
}

/// Fit one raw measured curve (samples in traversal order, the first at its reversal): adaptive bins on the
/// input axis (wide where the curve is straight, narrow where it switches sharply, one sample per bin for
/// noise-free data), each bin's local linear fit, then the least-squares monotone fit of the nodes.
/// `direction`: "ascending" (input and output rise) or "descending". `pilot`: samples per bin of the pilot fit
/// that estimates curvature and noise.
#[pyfunction]
#[pyo3(signature = (u, y, direction, *, pilot=16))]
fn fit_curve(
    py: Python<'_>,
    u: &Bound<'_, PyAny>,
    y: &Bound<'_, PyAny>,
    direction: &str,
    pilot: usize,
) -> PyResult<PyCurveFit> {
    let (sign, direction) = match direction {
        "ascending" => (1.0, "ascending"),
        "descending" => (-1.0, "descending"),
        other => {
            return Err(BmrError::new_err(format!(
                "direction={other:?}: expected 'ascending' or 'descending'"
            )));
        }
    };
    let u: Vec<f64> = extract_f64_array(u, "u")?
        .into_iter()
        .map(|x| sign * x)
        .collect();
    let y: Vec<f64> = extract_f64_array(y, "y")?
        .into_iter()
        .map(|x| sign * x)
        .collect();
    if u.len() != y.len() {
        return Err(BmrError::new_err(format!(
            "fit_curve: {} inputs but {} outputs",
            u.len(),
            y.len()
        )));
    }
    if let Some(i) = u
        .iter()
        .zip(&y)
        .position(|(a, b)| !a.is_finite() || !b.is_finite())
    {
        return Err(BmrError::new_err(format!(
            "fit_curve: sample {i} is not finite"
        )));
    }
    if pilot < 3 {
        return Err(BmrError::new_err(format!(
            "fit_curve: pilot must be at least 3 samples, got {pilot}"
        )));
    }
    let fit = py.detach(|| binned_curve(&u, &y, pilot)).ok_or_else(|| {
        BmrError::new_err(format!(
            "fit_curve: {} sample(s) with {} distinct input(s); a curve needs at least 2",
            u.len(),
            {
                let mut v = u.clone();
                v.sort_by(f64::total_cmp);
                v.dedup();
                v.len()
            }
        ))
    })?;
    Ok(PyCurveFit {
        u: fit.u.iter().map(|&x| sign * x).collect(),
        y: fit.y.iter().map(|&x| sign * x).collect(),
        counts: fit.counts,
        direction,
        samples: u.len(),
        noise: fit.noise,
        node_sigma: fit.node_sigma,
        violation: fit.violation.amount,
        violation_sample: fit.violation_sample,
        violation_input: sign * u[fit.violation_sample],
        reshaped_rms: fit.reshaped_rms,
        input_backtrack: fit.input_backtrack,
    })
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(fit_curve, m)?)?;
    m.add_class::<PyCurveFit>()?;
    Ok(())
}
