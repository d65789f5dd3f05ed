//! `bmr.Hysteresis`: the CBH operator with a 64-point memory.
use numpy::{AllowTypeChange, PyArray1, PyArrayLike1};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString, PyTuple};

use crate::cbh::{Hysteresis, Initial, State};
use crate::congruency::congruency;
use crate::python::arrays::{DETACH_LEN, extract_f64_array, to_numpy, to_vec};
use crate::python::table_report::{PyTableReport, congruency_dict};
use crate::python::{BmrError, bmr_err};
use crate::table_builder::{BuildOptions, BuildReport};

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

fn curves_to_py<'py>(
    py: Python<'py>,
    curves: Vec<(Vec<f64>, Vec<f64>)>,
) -> PyResult<Bound<'py, PyList>> {
    let items: Vec<_> = curves
        .into_iter()
        .map(|(u, y)| PyTuple::new(py, [to_numpy(py, u), to_numpy(py, y)]))
        .collect::<PyResult<_>>()?;
    PyList::new(py, items)
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
    /// What the build from measured curves measured, fitted and derived (None for operators made otherwise).
    pub(crate) report: Option<BuildReport>,
}

#[pymethods]
impl PyHysteresis {
    /// Build from measured curves. `ascending`: sequence of `(u, y)` array pairs, each from its reversal minimum
    /// up to positive saturation; `descending`: from reversal maxima down to negative saturation. The lowest
    /// ascending and highest descending curves are the major branches.
    ///
    /// Real curves are accepted as they are: samples are sorted by input (equal inputs averaged) and fitted
    /// monotonically; how far each curve moved against its direction is in `build_report` (a move beyond
    /// `monotone_tolerance` of the span is an error: not a curve of that family). One family of at least two
    /// curves is enough: the other one is derived (congruency) from it and the opposite major branch, if given
    /// as that family's only curve, else from the measured curves' reversal points. Grid nodes are dropped only
    /// where linear interpolation of every curve stays within `node_tolerance` of the output span, at most
    /// `max_nodes` per family (the bound is raised, and reported, if needed; the default 0 drops only nodes on
    /// straight stretches). `reach_tolerance`: how far short of
    /// saturation a curve may stop (fraction of the input span); `closure_tolerance`: how far the major branches
    /// may miss each other at saturation (fraction of the output span); `subdivisions`: curves per interval
    /// between measured reversals (`k > 1` adds `k − 1` from the strip shapes the opposite family calibrates, and
    /// gives a derived family `k` reversals per interval; 1 keeps the measured curves, so that
    /// `from_curves(*h.curves())` rebuilds `h` exactly).
    #[staticmethod]
    #[pyo3(signature = (ascending, descending, *, initial=None, monotone_tolerance=0.25, reach_tolerance=0.01,
                        closure_tolerance=0.05, node_tolerance=0.0, max_nodes=16384, subdivisions=1))]
    #[allow(clippy::too_many_arguments)]
    fn from_curves(
        py: Python<'_>,
        ascending: &Bound<'_, PyAny>,
        descending: &Bound<'_, PyAny>,
        initial: Option<&Bound<'_, PyAny>>,
        monotone_tolerance: f64,
        reach_tolerance: f64,
        closure_tolerance: f64,
        node_tolerance: f64,
        max_nodes: usize,
        subdivisions: usize,
    ) -> PyResult<Self> {
        let initial = initial_or_negative(initial)?;
        let asc = parse_family(ascending, "ascending")?;
        let desc = parse_family(descending, "descending")?;
        let opts = BuildOptions {
            monotone_tolerance,
            reach_tolerance,
            closure_tolerance,
            node_tolerance,
            max_nodes,
            subdivisions,
        };
        let (op, report) = py
            .detach(|| Operator::from_curve_data_reported(&asc, &desc, &opts, initial))
            .map_err(bmr_err)?;
        Ok(PyHysteresis {
            op,
            report: Some(report),
        })
    }

    /// What `from_curves` measured, fitted and derived (a `TableReport`), or None for an operator not built
    /// from curves (e.g. `compressed`).
    #[getter]
    fn build_report(&self) -> Option<PyTableReport> {
        self.report.clone().map(|inner| PyTableReport { inner })
    }

    /// The same operator on fewer nodes, e.g. for a firmware export with its own error bound: a node is dropped
    /// only where linear interpolation of every stored curve stays within `tolerance` (fraction of the output
    /// span), at most `max_nodes` per family. Returns `(operator, bound)`: the new operator (after negative
    /// saturation) and a dict with, per family, the nodes kept, the tolerance used and the error reached
    /// (output units).
    #[pyo3(signature = (tolerance, max_nodes=16384))]
    fn compressed<'py>(
        &self,
        py: Python<'py>,
        tolerance: f64,
        max_nodes: usize,
    ) -> PyResult<(Self, Bound<'py, PyDict>)> {
        let (op, [a, d]) = self.op.compressed(tolerance, max_nodes).map_err(bmr_err)?;
        let out = PyDict::new(py);
        for (name, n) in [("ascending", a), ("descending", d)] {
            let e = PyDict::new(py);
            e.set_item("nodes", n.nodes)?;
            e.set_item("tolerance", n.tolerance)?;
            e.set_item("error", n.error)?;
            out.set_item(name, e)?;
        }
        Ok((PyHysteresis { op, report: None }, out))
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

    /// Mismatch between the ascending and descending families (output units): `max_abs`, `rms`, `pairs`, over
    /// pairs of measured reversals (as built from curves; the stored tables otherwise). Zero for Preisach data;
    /// large values mean the data are not congruent.
    fn consistency<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = match self.report.as_ref().and_then(|r| r.mismatch) {
            Some(c) => c,
            None => congruency(self.op.ascending(), self.op.descending()),
        };
        congruency_dict(py, &c)
    }

    /// The stored tables as `(ascending, descending)` curve lists in `from_curves` form.
    fn curves<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyList>, Bound<'py, PyList>)> {
        let (a, d) = self.op.curves();
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
