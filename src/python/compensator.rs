//! `bmr.Compensator`: hysteresis + friction compensation for one control loop, and its `Command`.
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};

use crate::compensator::{Command, Compensator, CompensatorState, InverseKind};
use crate::friction::{Friction, MAX_ORDER};
use crate::python::arrays::{DETACH_LEN, extract_f64_array, to_numpy};
use crate::python::friction::PyFriction;
use crate::python::hysteresis::{MEMORY, Operator, PyHysteresis, initial_or_negative};
use crate::python::{
    BmrError, bmr_err, borrow, borrow_mut, bytes_to_words, table_err, words_to_bytes,
};

type Core = Compensator<Vec<f64>, MEMORY, MAX_ORDER>;

/// One control-period command: nominal current, coil currents (A), converter voltages (V) and flags.
#[pyclass(name = "Command", module = "bmr", frozen, get_all)]
#[derive(Clone, Copy)]
pub(crate) struct PyCommand {
    current_a: f64,
    coil1_a: f64,
    coil2_a: f64,
    volt1_v: f64,
    volt2_v: f64,
    saturated: bool,
    fault: bool,
}

#[pymethods]
impl PyCommand {
    fn __copy__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf // immutable: a copy is the object itself
    }
    fn __deepcopy__<'py>(slf: PyRef<'py, Self>, _memo: &Bound<'py, PyAny>) -> PyRef<'py, Self> {
        slf
    }
    #[allow(clippy::type_complexity)]
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (f64, f64, f64, f64, f64, bool, bool))> {
        let rebuild = py.import("bmr._core")?.getattr("_rebuild_command")?;
        Ok((
            rebuild,
            (
                self.current_a,
                self.coil1_a,
                self.coil2_a,
                self.volt1_v,
                self.volt2_v,
                self.saturated,
                self.fault,
            ),
        ))
    }

    fn __repr__(&self) -> String {
        format!(
            "Command(current_a={:.6}, coil1_a={:.6}, coil2_a={:.6}, volt1_v={:.6}, volt2_v={:.6}, saturated={}, fault={})",
            self.current_a,
            self.coil1_a,
            self.coil2_a,
            self.volt1_v,
            self.volt2_v,
            if self.saturated { "True" } else { "False" },
            if self.fault { "True" } else { "False" }
        )
    }
}

impl From<Command> for PyCommand {
    fn from(c: Command) -> Self {
        PyCommand {
            current_a: c.current_a,
            coil1_a: c.coil1_a,
            coil2_a: c.coil2_a,
            volt1_v: c.volt1_v,
            volt2_v: c.volt2_v,
            saturated: c.saturated,
            fault: c.fault,
        }
    }
}

/// Unpickle a `Command` (a plain record of one step's outputs).
#[pyfunction]
fn _rebuild_command(
    current_a: f64,
    coil1_a: f64,
    coil2_a: f64,
    volt1_v: f64,
    volt2_v: f64,
    saturated: bool,
    fault: bool,
) -> PyCommand {
    PyCommand {
        current_a,
        coil1_a,
        coil2_a,
        volt1_v,
        volt2_v,
        saturated,
        fault,
    }
}

/// A compensator snapshot as taken, or as read back from a pickle: the words of the forward operator's state and,
/// with the paper's inverse, of the inverse operator's (checked against the tables when it is restored).
#[derive(Clone)]
#[allow(clippy::large_enum_variant)] // the live snapshot stays inline (no extra allocation per snapshot)
enum StateData {
    Live(CompensatorState<MEMORY>),
    Words(Vec<u64>, Option<Vec<u64>>),
}

/// Snapshot of a Compensator's memory.
#[pyclass(name = "CompensatorState", module = "bmr", frozen)]
pub(crate) struct PyCompensatorState(StateData);

#[pymethods]
impl PyCompensatorState {
    fn __copy__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf // immutable: a copy is the object itself
    }
    fn __deepcopy__<'py>(slf: PyRef<'py, Self>, _memo: &Bound<'py, PyAny>) -> PyRef<'py, Self> {
        slf
    }
    #[allow(clippy::type_complexity)]
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(
        Bound<'py, PyAny>,
        (Bound<'py, PyBytes>, Option<Bound<'py, PyBytes>>),
    )> {
        let (forward, paper) = match &self.0 {
            StateData::Live(s) => s.to_words(),
            StateData::Words(f, p) => (f.clone(), p.clone()),
        };
        let rebuild = py
            .import("bmr._core")?
            .getattr("_rebuild_compensator_state")?;
        Ok((
            rebuild,
            (
                words_to_bytes(py, &forward),
                paper.map(|p| words_to_bytes(py, &p)),
            ),
        ))
    }
    fn __repr__(&self) -> String {
        let paper = match &self.0 {
            StateData::Live(s) => s.to_words().1.is_some(),
            StateData::Words(_, p) => p.is_some(),
        };
        format!(
            "CompensatorState(inverse={:?})",
            if paper { "paper" } else { "exact" }
        )
    }
}

/// Unpickle a `CompensatorState` (checked against the compensator's tables when it is restored).
#[pyfunction]
#[pyo3(signature = (forward, paper=None))]
fn _rebuild_compensator_state(
    forward: &[u8],
    paper: Option<&[u8]>,
) -> PyResult<PyCompensatorState> {
    let forward = bytes_to_words(forward, "CompensatorState")?;
    let paper = paper
        .map(|p| bytes_to_words(p, "CompensatorState"))
        .transpose()?;
    let is_state = |w: &[u64]| crate::cbh::state_words_io(w).is_some();
    if !is_state(&forward) || paper.as_deref().is_some_and(|p| !is_state(p)) {
        return Err(BmrError::new_err(
            "CompensatorState: the pickled data is not a compensator state",
        ));
    }
    Ok(PyCompensatorState(StateData::Words(forward, paper)))
}

/// Open-loop torque compensator: `I = H⁻¹[T_ref − T_f(θ)]`, coil split, current limit, converter voltages.
#[pyclass(name = "Compensator", module = "bmr")]
#[derive(Clone)]
pub(crate) struct PyCompensator {
    core: Core,
    inverse: &'static str,
}

impl PyCompensator {
    /// A compensator on `forward` (in its current state) with the named inverse.
    fn build(
        forward: Operator,
        friction: Option<PyRef<'_, PyFriction>>,
        inverse: &str,
        converter_gain: f64,
        current_limit: f64,
    ) -> PyResult<Self> {
        let (kind, name) = match inverse {
            "exact" => (InverseKind::Exact, "exact"),
            "paper" => (
                InverseKind::Paper(forward.paper_inverse().map_err(|e| {
                    BmrError::new_err(format!(
                        "cannot build the paper's inverse from these tables: {e}"
                    ))
                })?),
                "paper",
            ),
            other => {
                return Err(BmrError::new_err(format!(
                    "inverse={other:?}: expected 'exact' or 'paper'"
                )));
            }
        };
        let friction = friction.map_or(Friction::zero(), |f| f.f);
        let core =
            Core::new(forward, kind, friction, converter_gain, current_limit).map_err(bmr_err)?;
        Ok(PyCompensator {
            core,
            inverse: name,
        })
    }
}

/// Unpickle a `Compensator`: its operator (tables and state), friction, settings and the paper inverse's state.
#[pyfunction]
#[pyo3(signature = (hysteresis, friction, inverse, converter_gain, current_limit, paper_state=None))]
fn _rebuild_compensator(
    hysteresis: PyRef<'_, PyHysteresis>,
    friction: PyRef<'_, PyFriction>,
    inverse: &str,
    converter_gain: f64,
    current_limit: f64,
    paper_state: Option<&[u8]>,
) -> PyResult<PyCompensator> {
    let mut c = PyCompensator::build(
        hysteresis.op.clone(),
        Some(friction),
        inverse,
        converter_gain,
        current_limit,
    )?;
    let forward = c.core.forward().snapshot().to_words();
    let paper = paper_state
        .map(|p| bytes_to_words(p, "Compensator"))
        .transpose()?;
    let state = c
        .core
        .state_from_words(&forward, paper.as_deref())
        .map_err(table_err)?;
    c.core.restore(&state).map_err(table_err)?;
    Ok(c)
}

#[pymethods]
impl PyCompensator {
    /// `hysteresis`: the current→torque operator (N·mm without friction); `friction`: seal friction (optional);
    /// `inverse`: "exact" or "paper"; `converter_gain` in A/V; `current_limit` in A; `initial`: start state of the
    /// memory (default after negative saturation).
    #[new]
    #[pyo3(signature = (hysteresis, friction=None, *, inverse="exact", converter_gain=0.125, current_limit=1.25,
                        initial=None))]
    fn new(
        hysteresis: &Bound<'_, PyHysteresis>,
        friction: Option<PyRef<'_, PyFriction>>,
        inverse: &str,
        converter_gain: f64,
        current_limit: f64,
        initial: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let initial = initial_or_negative(initial)?;
        let forward = borrow(hysteresis)?.op.clone();
        let mut c = Self::build(forward, friction, inverse, converter_gain, current_limit)?;
        c.core.reset(initial);
        Ok(c)
    }

    /// One control period: reference torque (N·mm) and rotor angle (rad) → `Command`. Never raises: a NaN/inf
    /// input gives zero current with `fault=True`.
    /// (An `InUseError` only while another thread is inside `run` on this object.)
    fn step(slf: &Bound<'_, Self>, torque_ref_nmm: f64, theta_rad: f64) -> PyResult<PyCommand> {
        Ok(borrow_mut(slf)?.core.step(torque_ref_nmm, theta_rad).into())
    }

    /// Offline run over arrays (same length): dict of arrays with the `Command` fields plus
    /// `model_torque_nmm` (forward-model torque with friction for the commanded current).
    fn run<'py>(
        slf: &Bound<'py, Self>,
        py: Python<'py>,
        torque_ref_nmm: &Bound<'py, PyAny>,
        theta_rad: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let r = extract_f64_array(torque_ref_nmm, "torque_ref_nmm")?;
        let th = extract_f64_array(theta_rad, "theta_rad")?;
        if r.len() != th.len() {
            return Err(BmrError::new_err(format!(
                "run: torque_ref_nmm has {} samples but theta_rad has {}",
                r.len(),
                th.len()
            )));
        }
        let n = th.len();
        let mut me = borrow_mut(slf)?;
        let core = &mut me.core;
        let mut work = move || {
            let n = r.len();
            let mut cols: [Vec<f64>; 6] = core::array::from_fn(|_| Vec::with_capacity(n));
            let (mut sat, mut fault) = (Vec::with_capacity(n), Vec::with_capacity(n));
            for (&t, &a) in r.iter().zip(&th) {
                let c = core.step(t, a);
                // The step already evaluated the friction unless it was a fault.
                let friction = if c.fault {
                    core.friction().eval(a)
                } else {
                    core.friction_nmm()
                };
                let model = core.predicted_torque() + friction;
                for (col, v) in cols.iter_mut().zip([
                    c.current_a,
                    c.coil1_a,
                    c.coil2_a,
                    c.volt1_v,
                    c.volt2_v,
                    model,
                ]) {
                    col.push(v);
                }
                sat.push(c.saturated);
                fault.push(c.fault);
            }
            (cols, sat, fault)
        };
        let (cols, sat, fault) = if n > DETACH_LEN {
            py.detach(work)
        } else {
            work()
        };
        let d = PyDict::new(py);
        let names = [
            "current_a",
            "coil1_a",
            "coil2_a",
            "volt1_v",
            "volt2_v",
            "model_torque_nmm",
        ];
        for (name, col) in names.into_iter().zip(cols) {
            d.set_item(name, to_numpy(py, col))?;
        }
        d.set_item("saturated", PyArray1::from_vec(py, sat))?;
        d.set_item("fault", PyArray1::from_vec(py, fault))?;
        Ok(d)
    }

    /// Forget the memory and start from `initial` (default: after negative saturation).
    #[pyo3(signature = (initial=None))]
    fn reset(slf: &Bound<'_, Self>, initial: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let initial = initial_or_negative(initial)?;
        borrow_mut(slf)?.core.reset(initial);
        Ok(())
    }

    fn snapshot(slf: &Bound<'_, Self>) -> PyResult<PyCompensatorState> {
        Ok(PyCompensatorState(StateData::Live(
            borrow(slf)?.core.snapshot(),
        )))
    }

    /// Return to a `snapshot` of this compensator (or of one with identical tables and the same inverse; a
    /// `TableError` otherwise).
    fn restore(slf: &Bound<'_, Self>, state: &PyCompensatorState) -> PyResult<()> {
        let mut me = borrow_mut(slf)?;
        let st = match &state.0 {
            StateData::Live(s) => *s,
            StateData::Words(f, p) => me
                .core
                .state_from_words(f, p.as_deref())
                .map_err(table_err)?,
        };
        me.core.restore(&st).map_err(table_err)
    }

    /// An independent compensator with the same tables, settings and state.
    fn __copy__(slf: &Bound<'_, Self>) -> PyResult<Self> {
        Ok(borrow(slf)?.clone())
    }

    fn __deepcopy__(slf: &Bound<'_, Self>, _memo: &Bound<'_, PyAny>) -> PyResult<Self> {
        Ok(borrow(slf)?.clone())
    }

    /// Pickled as its operator, friction, settings and the paper inverse's state: an unpickled compensator
    /// continues bit for bit.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let py = slf.py();
        let me = borrow(slf)?;
        let (_, paper) = me.core.snapshot().to_words();
        let args = (
            PyHysteresis {
                op: me.core.forward().clone(),
                report: None,
            },
            PyFriction {
                f: *me.core.friction(),
            },
            me.inverse,
            me.core.gain_a_per_v(),
            me.core.limit_a(),
            paper.map(|p| words_to_bytes(py, &p)),
        )
            .into_pyobject(py)?;
        let rebuild = py.import("bmr._core")?.getattr("_rebuild_compensator")?;
        Ok((rebuild, args))
    }

    /// "exact" or "paper".
    #[getter]
    fn inverse(slf: &Bound<'_, Self>) -> PyResult<&'static str> {
        Ok(borrow(slf)?.inverse)
    }
    /// Converter gain (A/V).
    #[getter]
    fn converter_gain(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(borrow(slf)?.core.gain_a_per_v())
    }
    /// Current limit (A).
    #[getter]
    fn current_limit(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(borrow(slf)?.core.limit_a())
    }
    /// Forward-model torque (N·mm, without friction) for the last command.
    #[getter]
    fn predicted_torque_nmm(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(borrow(slf)?.core.predicted_torque())
    }
    /// A copy of the forward operator in its current state.
    #[getter]
    fn hysteresis(slf: &Bound<'_, Self>) -> PyResult<PyHysteresis> {
        Ok(PyHysteresis {
            op: borrow(slf)?.core.forward().clone(),
            report: None,
        })
    }
    /// The friction model used in the feedforward.
    #[getter]
    fn friction(slf: &Bound<'_, Self>) -> PyResult<PyFriction> {
        Ok(PyFriction {
            f: *borrow(slf)?.core.friction(),
        })
    }
    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let me = borrow(slf)?;
        Ok(format!(
            "Compensator(inverse={:?}, converter_gain={}, current_limit={}, friction_order={})",
            me.inverse,
            me.core.gain_a_per_v(),
            me.core.limit_a(),
            me.core.friction().order()
        ))
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyCompensator>()?;
    m.add_class::<PyCommand>()?;
    m.add_class::<PyCompensatorState>()?;
    m.add_function(wrap_pyfunction!(_rebuild_command, m)?)?;
    m.add_function(wrap_pyfunction!(_rebuild_compensator, m)?)?;
    m.add_function(wrap_pyfunction!(_rebuild_compensator_state, m)?)?;
    Ok(())
}
