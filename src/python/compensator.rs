//! `bmr.Compensator`: hysteresis + friction compensation for one control loop, and its `Command`.
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::compensator::{Command, Compensator, CompensatorState, InverseKind};
use crate::friction::{Friction, MAX_ORDER};
use crate::python::arrays::{DETACH_LEN, extract_f64_array, to_numpy};
use crate::python::friction::PyFriction;
use crate::python::hysteresis::{MEMORY, PyHysteresis, initial_or_negative};
use crate::python::{BmrError, bmr_err};

type Core = Compensator<Vec<f64>, MEMORY, MAX_ORDER>;

/// One control-period command: nominal current, coil currents (A), converter voltages (V) and flags.
#[pyclass(name = "Command", module = "bmr", frozen, get_all)]
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

/// Snapshot of a Compensator's memory.
#[pyclass(name = "CompensatorState", module = "bmr", frozen)]
pub(crate) struct PyCompensatorState(CompensatorState<MEMORY>);

/// Open-loop torque compensator: `I = H⁻¹[T_ref − T_f(θ)]`, coil split, current limit, converter voltages.
#[pyclass(name = "Compensator", module = "bmr")]
pub(crate) struct PyCompensator {
    core: Core,
    inverse: &'static str,
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
        hysteresis: PyRef<'_, PyHysteresis>,
        friction: Option<PyRef<'_, PyFriction>>,
        inverse: &str,
        converter_gain: f64,
        current_limit: f64,
        initial: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let initial = initial_or_negative(initial)?;
        let forward = hysteresis.op.clone();
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
        let mut core =
            Core::new(forward, kind, friction, converter_gain, current_limit).map_err(bmr_err)?;
        core.reset(initial);
        Ok(PyCompensator {
            core,
            inverse: name,
        })
    }

    /// One control period: reference torque (N·mm) and rotor angle (rad) → `Command`. Never raises: a NaN/inf
    /// input gives zero current with `fault=True`.
    fn step(&mut self, torque_ref_nmm: f64, theta_rad: f64) -> PyCommand {
        self.core.step(torque_ref_nmm, theta_rad).into()
    }

    /// Offline run over arrays (same length): dict of arrays with the `Command` fields plus
    /// `model_torque_nmm` (forward-model torque with friction for the commanded current).
    fn run<'py>(
        &mut self,
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
        let core = &mut self.core;
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
    fn reset(&mut self, initial: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let initial = initial_or_negative(initial)?;
        self.core.reset(initial);
        Ok(())
    }

    fn snapshot(&self) -> PyCompensatorState {
        PyCompensatorState(self.core.snapshot())
    }

    fn restore(&mut self, state: &PyCompensatorState) -> PyResult<()> {
        self.core.restore(&state.0).map_err(bmr_err)
    }

    /// "exact" or "paper".
    #[getter]
    fn inverse(&self) -> &'static str {
        self.inverse
    }
    /// Converter gain (A/V).
    #[getter]
    fn converter_gain(&self) -> f64 {
        self.core.gain_a_per_v()
    }
    /// Current limit (A).
    #[getter]
    fn current_limit(&self) -> f64 {
        self.core.limit_a()
    }
    /// Forward-model torque (N·mm, without friction) for the last command.
    #[getter]
    fn predicted_torque_nmm(&self) -> f64 {
        self.core.predicted_torque()
    }
    /// A copy of the forward operator in its current state.
    #[getter]
    fn hysteresis(&self) -> PyHysteresis {
        PyHysteresis {
            op: self.core.forward().clone(),
            report: None,
        }
    }
    /// The friction model used in the feedforward.
    #[getter]
    fn friction(&self) -> PyFriction {
        PyFriction {
            f: *self.core.friction(),
        }
    }
    fn __repr__(&self) -> String {
        format!(
            "Compensator(inverse={:?}, converter_gain={}, current_limit={}, friction_order={})",
            self.inverse,
            self.core.gain_a_per_v(),
            self.core.limit_a(),
            self.core.friction().order()
        )
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyCompensator>()?;
    m.add_class::<PyCommand>()?;
    m.add_class::<PyCompensatorState>()?;
    Ok(())
}
