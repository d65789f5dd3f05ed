//! `bmr.Hysteresis`: the CBH operator with a 64-point memory.
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList, PyString, PyTuple};

use crate::cbh::{Hysteresis, Initial, State, state_words_io};
use crate::congruency::congruency;
use crate::error::FamilyKind;
use crate::everett::Family;
use crate::python::arrays::{DETACH_LEN, curves_to_py, extract_f64_array, to_numpy};
use crate::python::table_report::{PyTableReport, congruency_dict};
use crate::python::{BmrError, borrow, borrow_mut, bytes_to_words, table_err, words_to_bytes};
use crate::rate_dependence::RateDependence;
use crate::stages::MeanField;
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
    let shape_err = || {
        pyo3::exceptions::PyTypeError::new_err(
            "initial: expected 'negative', 'positive', ('ascending', u) or ('descending', u)",
        )
    };
    if let Ok(t) = obj.cast::<PyTuple>()
        && t.len() == 2
    {
        let kind: String = t.get_item(0)?.extract().map_err(|_| shape_err())?;
        let u: f64 = t.get_item(1)?.extract().map_err(|_| shape_err())?;
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
    Err(shape_err())
}

/// A family argument: a sequence of `(u, y)` pairs of 1-D arrays.
fn parse_family(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<(Vec<f64>, Vec<f64>)>> {
    let seq = obj.try_iter().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(format!(
            "{name}: expected a sequence of (u, y) array pairs"
        ))
    })?;
    let mut out = Vec::new();
    for (i, item) in seq.enumerate() {
        let item = item?;
        let pair: (Bound<'_, PyAny>, Bound<'_, PyAny>) = item.extract().map_err(|_| {
            pyo3::exceptions::PyTypeError::new_err(format!(
                "{name} curve {i}: expected a (u, y) pair of 1-D arrays"
            ))
        })?;
        let u = extract_f64_array(&pair.0, &format!("{name} curve {i} inputs"))?;
        let y = extract_f64_array(&pair.1, &format!("{name} curve {i} outputs"))?;
        out.push((u, y));
    }
    Ok(out)
}

/// A snapshot as taken, or as read back from a pickle (checked against the operator's tables when restored).
#[derive(Clone)]
#[allow(clippy::large_enum_variant)] // the live snapshot stays inline (no extra allocation per snapshot)
pub(crate) enum StateData {
    Live(State<MEMORY>),
    Words(Vec<u64>),
}

/// Snapshot of a `Hysteresis` state (an opaque copy; restore it into the operator it came from).
#[pyclass(name = "HysteresisState", module = "bmr", frozen)]
#[derive(Clone)]
pub(crate) struct PyState(pub(crate) StateData);

impl PyState {
    /// `(input, output, reversals)`.
    fn summary(&self) -> (f64, f64, usize) {
        match &self.0 {
            StateData::Live(s) => (s.input(), s.output(), s.history().len()),
            StateData::Words(w) => state_words_io(w).unwrap_or((f64::NAN, f64::NAN, 0)),
        }
    }

    fn words(&self) -> Vec<u64> {
        match &self.0 {
            StateData::Live(s) => s.to_words(),
            StateData::Words(w) => w.clone(),
        }
    }
}

#[pymethods]
impl PyState {
    /// Input at the time of the snapshot.
    #[getter]
    fn input(&self) -> f64 {
        self.summary().0
    }
    /// Output at the time of the snapshot.
    #[getter]
    fn output(&self) -> f64 {
        self.summary().1
    }
    fn __copy__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf // immutable: a copy is the object itself
    }
    fn __deepcopy__<'py>(slf: PyRef<'py, Self>, _memo: &Bound<'py, PyAny>) -> PyRef<'py, Self> {
        slf
    }
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyBytes>,))> {
        let rebuild = py
            .import("bmr._core")?
            .getattr("_rebuild_hysteresis_state")?;
        Ok((rebuild, (words_to_bytes(py, &self.words()),)))
    }
    fn __repr__(&self) -> String {
        let (u, y, n) = self.summary();
        format!("HysteresisState(input={u}, output={y}, reversals={n})")
    }
}

/// Unpickle a `HysteresisState` (checked against the tables when it is restored).
#[pyfunction]
fn _rebuild_hysteresis_state(state: &[u8]) -> PyResult<PyState> {
    let words = bytes_to_words(state, "HysteresisState")?;
    if state_words_io(&words).is_none() {
        return Err(BmrError::new_err(
            "HysteresisState: the pickled data is not an operator state",
        ));
    }
    Ok(PyState(StateData::Words(words)))
}

fn f64_bytes<'py>(py: Python<'py>, values: &[f64]) -> Bound<'py, PyBytes> {
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    PyBytes::new(py, &bytes)
}

fn bytes_f64(bytes: &[u8]) -> PyResult<Vec<f64>> {
    Ok(bytes_to_words(bytes, "Hysteresis")?
        .into_iter()
        .map(f64::from_bits)
        .collect())
}

/// Unpickle a `Hysteresis`: both raw tables (validated as on any construction), the major-loop outputs and the
/// state.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn _rebuild_hysteresis(
    asc: &[u8],
    asc_nodes: usize,
    asc_curves: usize,
    desc: &[u8],
    desc_nodes: usize,
    desc_curves: usize,
    y_lo: f64,
    y_hi: f64,
    state: &[u8],
) -> PyResult<PyHysteresis> {
    let a = Family::new(
        bytes_f64(asc)?,
        asc_nodes,
        asc_curves,
        FamilyKind::Ascending,
    )
    .map_err(table_err)?;
    let d = Family::new(
        bytes_f64(desc)?,
        desc_nodes,
        desc_curves,
        FamilyKind::Descending,
    )
    .map_err(table_err)?;
    let mut op = Operator::new(a, d, y_lo, y_hi, Initial::Negative).map_err(table_err)?;
    let st = op
        .state_from_words(&bytes_to_words(state, "Hysteresis")?)
        .map_err(table_err)?;
    op.restore(&st).map_err(table_err)?;
    Ok(PyHysteresis { op, report: None })
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
            .map_err(table_err)?;
        Ok(PyHysteresis {
            op,
            report: Some(report),
        })
    }

    /// What `from_curves` measured, fitted and derived (a `TableReport`), or None for an operator not built
    /// from curves (e.g. `compressed`).
    #[getter]
    fn build_report(slf: &Bound<'_, Self>) -> PyResult<Option<PyTableReport>> {
        Ok(borrow(slf)?
            .report
            .clone()
            .map(|inner| PyTableReport { inner }))
    }

    /// The same operator on fewer nodes, e.g. for a firmware export with its own error bound: a node is dropped
    /// only where linear interpolation of every stored curve stays within `tolerance` (fraction of the output
    /// span), at most `max_nodes` per family. Returns `(operator, bound)`: the new operator (after negative
    /// saturation) and a dict with, per family, the nodes kept, the tolerance used and the error reached
    /// (output units).
    #[pyo3(signature = (tolerance, max_nodes=16384))]
    fn compressed<'py>(
        slf: &Bound<'py, Self>,
        tolerance: f64,
        max_nodes: usize,
    ) -> PyResult<(Self, Bound<'py, PyDict>)> {
        let py = slf.py();
        let (op, [a, d]) = borrow(slf)?
            .op
            .compressed(tolerance, max_nodes)
            .map_err(table_err)?;
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
    fn step(slf: &Bound<'_, Self>, u: f64) -> PyResult<f64> {
        Ok(borrow_mut(slf)?.op.step(u))
    }

    /// Apply an array of inputs, continuing from the current state; returns the outputs.
    fn run<'py>(
        slf: &Bound<'py, Self>,
        u: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let py = slf.py();
        let inputs = extract_f64_array(u, "u")?;
        let mut out = vec![0.0; inputs.len()];
        let mut me = borrow_mut(slf)?;
        if inputs.len() > DETACH_LEN {
            let op = &mut me.op;
            py.detach(|| op.run_into(&inputs, &mut out));
        } else {
            me.op.run_into(&inputs, &mut out);
        }
        Ok(to_numpy(py, out))
    }

    /// Run ``u`` (sampled every ``dt_s``) through the rate-dependence stage (``rate_dependence``: a lag of the core
    /// input whose time constant ``tau_s`` is scaled by the branch's differential slope over ``slope_ref``; default
    /// the major loop's mean slope, output span over input span), continuing from the current state with the stage
    /// at rest at ``u[0]``. Returns ``(outputs, core_inputs)``.
    #[pyo3(signature = (u, *, tau_s, dt_s, slope_ref=None))]
    #[allow(clippy::type_complexity)]
    fn run_rate_dependent<'py>(
        slf: &Bound<'py, Self>,
        u: &Bound<'py, PyAny>,
        tau_s: f64,
        dt_s: f64,
        slope_ref: Option<f64>,
    ) -> PyResult<(Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>)> {
        run_core_stages(slf, u, Some((tau_s, dt_s, slope_ref)), 0.0)
    }

    /// Run ``u`` through the core with ``non_congruent``'s mean field (a moving Preisach model): the core sees
    /// ``u + per_output · y`` with ``y`` its own output of the sample before (``per_output``: the feedback over
    /// the full-scale output, input units per output unit), after the rate-dependence stage when ``tau_s > 0``
    /// (sampled every ``dt_s``, as in :meth:`run_rate_dependent`), continuing from the current state. Returns
    /// ``(outputs, core_inputs)``.
    #[pyo3(signature = (u, *, per_output, tau_s=0.0, dt_s=1.0, slope_ref=None))]
    #[allow(clippy::type_complexity)]
    fn run_mean_field<'py>(
        slf: &Bound<'py, Self>,
        u: &Bound<'py, PyAny>,
        per_output: f64,
        tau_s: f64,
        dt_s: f64,
        slope_ref: Option<f64>,
    ) -> PyResult<(Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>)> {
        if !per_output.is_finite() {
            return Err(BmrError::new_err(format!(
                "per_output = {per_output} must be finite"
            )));
        }
        let rate = (tau_s > 0.0).then_some((tau_s, dt_s, slope_ref));
        run_core_stages(slf, u, rate, per_output)
    }

    /// Forget the memory and start from `initial` ("negative", "positive", ("ascending", u), ("descending", u)).
    #[pyo3(signature = (initial=None))]
    fn reset(slf: &Bound<'_, Self>, initial: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let initial = initial_or_negative(initial)?;
        borrow_mut(slf)?.op.reset(initial);
        Ok(())
    }

    /// A copy of the state (memory, input, output): `restore` it into this operator (or one with identical
    /// tables) to continue bit for bit from here.
    fn snapshot(slf: &Bound<'_, Self>) -> PyResult<PyState> {
        Ok(PyState(StateData::Live(borrow(slf)?.op.snapshot())))
    }

    /// Return to a `snapshot` of this operator (or of one with identical tables; a `TableError` otherwise).
    fn restore(slf: &Bound<'_, Self>, state: &PyState) -> PyResult<()> {
        let mut me = borrow_mut(slf)?;
        let st = match &state.0 {
            StateData::Live(s) => *s,
            StateData::Words(w) => me.op.state_from_words(w).map_err(table_err)?,
        };
        me.op.restore(&st).map_err(table_err)
    }

    /// Reversal points `(u, y)` now stored, oldest (the negative-saturation anchor) first.
    #[getter]
    fn memory(slf: &Bound<'_, Self>) -> PyResult<Vec<(f64, f64)>> {
        Ok(borrow(slf)?.op.state().memory().collect())
    }

    /// Maximum number of stored reversal points.
    #[getter]
    fn capacity(_slf: &Bound<'_, Self>) -> usize {
        MEMORY
    }

    /// Current (saturated) input.
    #[getter]
    fn input(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(borrow(slf)?.op.state().input())
    }

    /// Current output.
    #[getter]
    fn output(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(borrow(slf)?.op.output())
    }

    /// `(lowest, highest)` input of the tables.
    #[getter]
    fn input_range(slf: &Bound<'_, Self>) -> PyResult<(f64, f64)> {
        Ok(borrow(slf)?.op.input_range())
    }

    /// `(output at negative saturation, output at positive saturation)`.
    #[getter]
    fn output_range(slf: &Bound<'_, Self>) -> PyResult<(f64, f64)> {
        Ok(borrow(slf)?.op.output_range())
    }

    /// Mismatch between the ascending and descending families (output units): `max_abs`, `rms`, `pairs`, over
    /// pairs of measured reversals (as built from curves; the stored tables otherwise). Zero for Preisach data;
    /// large values mean the data are not congruent.
    fn consistency<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        let me = borrow(slf)?;
        let c = match me.report.as_ref().and_then(|r| r.mismatch) {
            Some(c) => c,
            None => congruency(me.op.ascending(), me.op.descending()),
        };
        congruency_dict(slf.py(), &c)
    }

    /// The stored tables as `(ascending, descending)` curve lists in `from_curves` form.
    fn curves<'py>(slf: &Bound<'py, Self>) -> PyResult<(Bound<'py, PyList>, Bound<'py, PyList>)> {
        let py = slf.py();
        let (a, d) = borrow(slf)?.op.curves();
        Ok((curves_to_py(py, a)?, curves_to_py(py, d)?))
    }

    /// The paper's current curves (eq 17-20): the stored first-order curves with inputs and outputs swapped,
    /// `(torque, current)` pairs with torque strictly monotone along each curve; the paper's inverse operator is
    /// built from them.
    fn current_curves<'py>(
        slf: &Bound<'py, Self>,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyList>, Bound<'py, PyList>)> {
        let (a, d) = borrow(slf)?.op.current_curves();
        Ok((curves_to_py(py, a)?, curves_to_py(py, d)?))
    }

    /// An independent operator with the same tables and state.
    fn __copy__(slf: &Bound<'_, Self>) -> PyResult<Self> {
        Ok(borrow(slf)?.clone())
    }

    fn __deepcopy__(slf: &Bound<'_, Self>, _memo: &Bound<'_, PyAny>) -> PyResult<Self> {
        Ok(borrow(slf)?.clone())
    }

    /// Pickled as its raw tables and state: an unpickled operator continues bit for bit.
    #[allow(clippy::type_complexity)]
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let py = slf.py();
        let me = borrow(slf)?;
        let op = &me.op;
        let (y_lo, y_hi) = op.output_range();
        let (a, d) = (op.ascending(), op.descending());
        let args = (
            f64_bytes(py, a.data()),
            a.nodes(),
            a.curves(),
            f64_bytes(py, d.data()),
            d.nodes(),
            d.curves(),
            y_lo,
            y_hi,
            words_to_bytes(py, &op.snapshot().to_words()),
        )
            .into_pyobject(py)?;
        let rebuild = py.import("bmr._core")?.getattr("_rebuild_hysteresis")?;
        Ok((rebuild, args))
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let me = borrow(slf)?;
        let op = &me.op;
        let (lo, hi) = op.input_range();
        let (ylo, yhi) = op.output_range();
        Ok(format!(
            "Hysteresis(input_range=({lo}, {hi}), output_range=({ylo}, {yhi}), curves=({}, {}), nodes=({}, {}))",
            op.ascending().curves(),
            op.descending().curves(),
            op.ascending().nodes(),
            op.descending().nodes()
        ))
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyHysteresis>()?;
    m.add_class::<PyState>()?;
    m.add_function(wrap_pyfunction!(_rebuild_hysteresis, m)?)?;
    m.add_function(wrap_pyfunction!(_rebuild_hysteresis_state, m)?)?;
    Ok(())
}

/// ``u`` through the core, continuing from its state: after the rate-dependence stage when ``rate`` holds its
/// ``(tau_s, dt_s, slope_ref)`` (the stage at rest at ``u[0]``; ``slope_ref`` default the major loop's mean slope)
/// and with ``non_congruent``'s mean field (``per_output`` input units per output unit of the sample before; 0 is
/// off). Returns ``(outputs, core_inputs)``.
#[allow(clippy::type_complexity)]
fn run_core_stages<'py>(
    slf: &Bound<'py, PyHysteresis>,
    u: &Bound<'py, PyAny>,
    rate: Option<(f64, f64, Option<f64>)>,
    per_output: f64,
) -> PyResult<(Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>)> {
    let py = slf.py();
    let inputs = extract_f64_array(u, "u")?;
    if let Some(i) = inputs.iter().position(|x| !x.is_finite()) {
        return Err(BmrError::new_err(format!(
            "u[{i}] = {} is not finite",
            inputs[i]
        )));
    }
    let mut me = borrow_mut(slf)?;
    let (lo, hi) = me.op.input_range();
    let (ylo, yhi) = me.op.output_range();
    let u0 = inputs.first().copied().unwrap_or(0.0);
    let mut rate = match rate {
        Some((tau_s, dt_s, slope_ref)) => {
            let slope_ref = slope_ref.unwrap_or((yhi - ylo) / (hi - lo));
            Some(
                RateDependence::new(tau_s, slope_ref, dt_s, hi - lo, u0, me.op.output()).ok_or_else(
                    || {
                        BmrError::new_err(format!(
                            "rate dependence needs tau_s >= 0, slope_ref > 0 and dt_s > 0 (tau_s={tau_s}, \
                             slope_ref={slope_ref}, dt_s={dt_s})"
                        ))
                    },
                )?,
            )
        }
        None => None,
    };
    // The one mean-field stage of the compensator and the simulations (1 per unit output over a unit scale).
    let mean = MeanField::new(per_output, 1.0);
    let n = inputs.len();
    let op = &mut me.op;
    let mut scan = move || -> (Vec<f64>, Vec<f64>) {
        let mut ys = Vec::with_capacity(n);
        let mut cores = Vec::with_capacity(n);
        for &x in &inputs {
            let c = rate.as_mut().map_or(x, |r| r.step(x));
            let c = mean.map_or(c, |m| c + m.shift(op.output()));
            let y = op.step(c);
            if let Some(r) = rate.as_mut() {
                r.observe(y);
            }
            ys.push(y);
            cores.push(c);
        }
        (ys, cores)
    };
    let (ys, cores) = if n > DETACH_LEN {
        py.detach(scan)
    } else {
        scan()
    };
    Ok((to_numpy(py, ys), to_numpy(py, cores)))
}
