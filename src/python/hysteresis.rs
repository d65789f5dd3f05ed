//! `bmr.Hysteresis`: the CBH operator with a 64-point memory.
use numpy::{AllowTypeChange, PyArray1, PyArrayLike1};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString, PyTuple};

use crate::cbh::{Hysteresis, Initial, State};
use crate::congruency::congruency;
use crate::python::arrays::{DETACH_LEN, curves_to_py, extract_f64_array, to_numpy, to_vec};
use crate::python::{BmrError, bmr_err};
use crate::table_builder::BuildOptions;

/// Memory capacity (reversal points) of the Python operator.
pub(crate) const MEMORY: usize = 64;
pub(crate) type Operator = Hysteresis<Vec<f64>, MEMORY>;

/// Parse `initial`: "negative", "positive", ("ascending", u) or ("descending", u).
/// An optional `initial` argument; `None` means after negative saturation.
pub(crate) fn initial_or_negative(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Initial> {
    obj.map(parse_initial)
        .transpose()
        .map(|i| i.unwrap_or(Initial::Negative))
}

fn parse_initial(obj: &Bound<'_, PyAny>) -> PyResult<Initial> {
    if let Ok(s) = obj.cast::<PyString>() {
        return match s.to_cow()?.as_ref() {
            "negative" => Ok(Initial::Negative),
            "positive" => Ok(Initial::Positive),
            other => Err(BmrError::new_err(format!(
                "initial={other:?}: expected 'negative', 'positive', ('ascending', u) or ('descending', u)"
            ))),
        };
    }
    if let Ok(t) = obj.cast::<PyTuple>()
        && t.len() == 2
    {
        let kind: String = t.get_item(0)?.extract()?;
        let u: f64 = t.get_item(1)?.extract()?;
        if !u.is_finite() {
            return Err(BmrError::new_err(format!(
                "initial=({kind:?}, {u}): the input must be finite"
            )));
        }
        return match kind.as_str() {
            "ascending" => Ok(Initial::Ascending(u)),
            "descending" => Ok(Initial::Descending(u)),
            other => Err(BmrError::new_err(format!(
                "initial=({other:?}, u): expected 'ascending' or 'descending'"
            ))),
        };
    }
    Err(BmrError::new_err(
        "initial: expected 'negative', 'positive', ('ascending', u) or ('descending', u)",
    ))
}

/// A family argument: a sequence of `(u, y)` pairs of 1-D arrays.
fn parse_family(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<(Vec<f64>, Vec<f64>)>> {
    let seq = obj.try_iter().map_err(|_| {
        BmrError::new_err(format!("{name}: expected a sequence of (u, y) array pairs"))
    })?;
    let mut out = Vec::new();
    for (i, item) in seq.enumerate() {
        let item = item?;
        let pair: (Bound<'_, PyAny>, Bound<'_, PyAny>) = item.extract().map_err(|_| {
            BmrError::new_err(format!(
                "{name} curve {i}: expected a (u, y) pair of 1-D arrays"
            ))
        })?;
        let u = extract_f64_array(&pair.0, &format!("{name} curve {i} inputs"))?;
        let y = extract_f64_array(&pair.1, &format!("{name} curve {i} outputs"))?;
        out.push((u, y));
    }
    Ok(out)
}

/// Snapshot of a `Hysteresis` state (an opaque copy; restore it into the operator it came from).
#[pyclass(name = "HysteresisState", module = "bmr", frozen)]
#[derive(Clone)]
pub(crate) struct PyState(pub(crate) State<MEMORY>);

#[pymethods]
impl PyState {
    /// Input at the time of the snapshot.
    #[getter]
    fn input(&self) -> f64 {
        self.0.input()
    }
    /// Output at the time of the snapshot.
    #[getter]
    fn output(&self) -> f64 {
        self.0.output()
    }
    fn __repr__(&self) -> String {
        format!(
            "HysteresisState(input={}, output={}, reversals={})",
            self.0.input(),
            self.0.output(),
            self.0.history().len()
        )
    }
}

/// CBH hysteresis operator built from measured first-order reversal curves.
#[pyclass(name = "Hysteresis", module = "bmr")]
#[derive(Clone)]
pub(crate) struct PyHysteresis {
    pub(crate) op: Operator,
}

#[pymethods]
impl PyHysteresis {
    /// Build from measured curves. `ascending`: sequence of `(u, y)` array pairs, each from its reversal minimum
    /// up to positive saturation; `descending`: from reversal maxima down to negative saturation. The lowest
    /// ascending and highest descending curves are the major branches.
    #[staticmethod]
    #[pyo3(signature = (ascending, descending, *, initial=None, monotone_tolerance=0.005, reach_tolerance=0.01,
                        closure_tolerance=0.05, max_nodes=1024))]
    #[allow(clippy::too_many_arguments)]
    fn from_curves(
        ascending: &Bound<'_, PyAny>,
        descending: &Bound<'_, PyAny>,
        initial: Option<&Bound<'_, PyAny>>,
        monotone_tolerance: f64,
        reach_tolerance: f64,
        closure_tolerance: f64,
        max_nodes: usize,
    ) -> PyResult<Self> {
        let initial = initial_or_negative(initial)?;
        let asc = parse_family(ascending, "ascending")?;
        let desc = parse_family(descending, "descending")?;
        let opts = BuildOptions {
            monotone_tolerance,
            reach_tolerance,
            closure_tolerance,
            max_nodes,
        };
        let op = Operator::from_curve_data(&asc, &desc, &opts, initial).map_err(bmr_err)?;
        Ok(PyHysteresis { op })
    }

    /// Apply one input (A) and return the output. NaN returns NaN and leaves the memory unchanged; inputs outside
    /// `input_range` saturate.
    fn step(&mut self, u: f64) -> f64 {
        self.op.step(u)
    }

    /// Apply an array of inputs, continuing from the current state; returns the outputs.
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        u: PyArrayLike1<'py, f64, AllowTypeChange>,
    ) -> Bound<'py, PyArray1<f64>> {
        let inputs = to_vec(u);
        let mut out = vec![0.0; inputs.len()];
        if inputs.len() > DETACH_LEN {
            let op = &mut self.op;
            py.detach(|| op.run_into(&inputs, &mut out));
        } else {
            self.op.run_into(&inputs, &mut out);
        }
        to_numpy(py, out)
    }

    /// Forget the memory and start from `initial` ("negative", "positive", ("ascending", u), ("descending", u)).
    #[pyo3(signature = (initial=None))]
    fn reset(&mut self, initial: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let initial = initial_or_negative(initial)?;
        self.op.reset(initial);
        Ok(())
    }

    fn snapshot(&self) -> PyState {
        PyState(self.op.snapshot())
    }

    fn restore(&mut self, state: &PyState) -> PyResult<()> {
        self.op.restore(&state.0).map_err(bmr_err)
    }

    /// Reversal points `(u, y)` now stored, oldest (the negative-saturation anchor) first.
    #[getter]
    fn memory(&self) -> Vec<(f64, f64)> {
        self.op.state().memory().collect()
    }

    /// Maximum number of stored reversal points.
    #[getter]
    fn capacity(&self) -> usize {
        MEMORY
    }

    /// Current (saturated) input.
    #[getter]
    fn input(&self) -> f64 {
        self.op.state().input()
    }

    /// Current output.
    #[getter]
    fn output(&self) -> f64 {
        self.op.output()
    }

    /// `(lowest, highest)` input of the tables.
    #[getter]
    fn input_range(&self) -> (f64, f64) {
        self.op.input_range()
    }

    /// `(output at negative saturation, output at positive saturation)`.
    #[getter]
    fn output_range(&self) -> (f64, f64) {
        self.op.output_range()
    }

    /// Mismatch between the ascending and descending families (output units): `max_abs`, `rms`, `pairs`.
    /// Zero for Preisach data; large values mean the data are not congruent.
    fn consistency<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = congruency(self.op.ascending(), self.op.descending());
        let d = PyDict::new(py);
        d.set_item("max_abs", c.max_abs)?;
        d.set_item("rms", c.rms)?;
        d.set_item("pairs", c.pairs)?;
        Ok(d)
    }

    /// The stored tables as `(ascending, descending)` curve lists in `from_curves` form.
    fn curves<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyList>, Bound<'py, PyList>)> {
        let (a, d) = self.op.curves();
        Ok((curves_to_py(py, a)?, curves_to_py(py, d)?))
    }

    /// The paper's current curves (eq 17-20): the stored first-order curves with inputs and outputs swapped,
    /// `(torque, current)` pairs with torque strictly monotone along each curve; the paper's inverse operator is
    /// built from them.
    fn current_curves<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyList>, Bound<'py, PyList>)> {
        let (a, d) = self.op.current_curves();
        Ok((curves_to_py(py, a)?, curves_to_py(py, d)?))
    }

    fn __copy__(&self) -> Self {
        self.clone()
    }

    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
        self.clone()
    }

    fn __repr__(&self) -> String {
        let (lo, hi) = self.op.input_range();
        let (ylo, yhi) = self.op.output_range();
        format!(
            "Hysteresis(input_range=({lo}, {hi}), output_range=({ylo}, {yhi}), curves=({}, {}), nodes=({}, {}))",
            self.op.ascending().curves(),
            self.op.descending().curves(),
            self.op.ascending().nodes(),
            self.op.descending().nodes()
        )
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyHysteresis>()?;
    m.add_class::<PyState>()?;
    Ok(())
}
