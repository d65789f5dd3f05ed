//! `bmr.ExtendedSimulation`, the forward chain of a model with its extensions (the very stages the extended
//! compensator inverts), and the `non_congruent` output map the diagnosis fits.
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::*;
use crate::cbh::Initial;
use crate::friction::{Friction, MAX_ORDER};
use crate::python::arrays::{DETACH_LEN, extract_f64_array, to_numpy};
use crate::python::friction::PyFriction;
use crate::python::hysteresis::{MEMORY, PyHysteresis, initial_or_negative};
use crate::python::{BmrError, bmr_err};
use crate::simulation::Simulation;
use crate::stages::{OutputMap, Scales};

type Sim = Simulation<Vec<f64>, Vec<f64>, MEMORY, MAX_ORDER>;

/// The forward chain of a model with its extensions: commanded current and rotor angle → torque (see
/// `bmr.effect_parameters()`); the very stages the extended `Compensator` inverts.
#[pyclass(name = "ExtendedSimulation", module = "bmr")]
pub(crate) struct PySimulation {
    sim: Sim,
}

#[pymethods]
impl PySimulation {
    /// `hysteresis` (the core's tables), `friction`, the model's `extensions` at sample period `dt_s`;
    /// `full_current_a`: current of unit heating (A); `full_torque_nmm`: the output map's full scale when its
    /// `scale_nmm` is 0 (default: the largest |torque| of `hysteresis`).
    #[new]
    #[pyo3(signature = (hysteresis, friction=None, *, extensions=None, dt_s, full_current_a, full_torque_nmm=None))]
    fn new(
        hysteresis: PyRef<'_, PyHysteresis>,
        friction: Option<PyRef<'_, PyFriction>>,
        extensions: Option<&Bound<'_, PyAny>>,
        dt_s: f64,
        full_current_a: f64,
        full_torque_nmm: Option<f64>,
    ) -> PyResult<Self> {
        let ext = parse_extensions(extensions)?;
        let core = hysteresis.op.clone();
        let (ylo, yhi) = core.output_range();
        let scales = Scales::of_core(
            &core,
            full_current_a,
            full_torque_nmm.unwrap_or(ylo.abs().max(yhi.abs())),
        );
        let friction = friction.map_or(Friction::zero(), |f| f.f);
        let sim =
            Sim::new(core, friction, &ext, dt_s, scales, |n| vec![0.0; n]).map_err(bmr_err)?;
        Ok(PySimulation { sim })
    }

    /// Simulate commanded currents (A) at rotor angles (rad), from `initial` (default after negative
    /// saturation), heating state `heating` and drift clock `t0_s` (s): a dict of `coil_current_a,
    /// field_current_a, core_nmm, field_torque_nmm, friction_nmm, torque_nmm, measured_nmm` arrays.
    #[pyo3(signature = (current_a, theta_rad, *, initial=None, heating=0.0, t0_s=0.0))]
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        current_a: &Bound<'py, PyAny>,
        theta_rad: &Bound<'py, PyAny>,
        initial: Option<&Bound<'_, PyAny>>,
        heating: f64,
        t0_s: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let initial: Initial = initial_or_negative(initial)?;
        let u = extract_f64_array(current_a, "current_a")?;
        let th = extract_f64_array(theta_rad, "theta_rad")?;
        if u.len() != th.len() {
            return Err(BmrError::new_err(format!(
                "run: current_a has {} samples but theta_rad has {}",
                u.len(),
                th.len()
            )));
        }
        if let Some(i) = u.iter().position(|v| !v.is_finite()) {
            return Err(BmrError::new_err(format!(
                "run: current sample {i} is not finite ({})",
                u[i]
            )));
        }
        if !(heating.is_finite() && t0_s.is_finite()) {
            return Err(BmrError::new_err("run: heating and t0_s must be finite"));
        }
        let sim = &mut self.sim;
        let n = u.len();
        let mut work = move || {
            sim.reset(initial, heating, t0_s);
            let mut cols: [Vec<f64>; 7] = core::array::from_fn(|_| Vec::with_capacity(n));
            for (&c, &a) in u.iter().zip(&th) {
                let s = sim.step(c, a);
                for (col, v) in cols.iter_mut().zip([
                    s.coil_current_a,
                    s.field_current_a,
                    s.core_nmm,
                    s.field_torque_nmm,
                    s.friction_nmm,
                    s.torque_nmm,
                    s.measured_nmm,
                ]) {
                    col.push(v);
                }
            }
            cols
        };
        let cols = if n > DETACH_LEN {
            py.detach(work)
        } else {
            work()
        };
        let d = PyDict::new(py);
        let names = [
            "coil_current_a",
            "field_current_a",
            "core_nmm",
            "field_torque_nmm",
            "friction_nmm",
            "torque_nmm",
            "measured_nmm",
        ];
        for (name, col) in names.into_iter().zip(cols) {
            d.set_item(name, to_numpy(py, col))?;
        }
        Ok(d)
    }
}

pub(super) fn output_map_of(curvature: f64, scale_nmm: f64, cubic: f64) -> PyResult<OutputMap> {
    OutputMap::polynomial(curvature, cubic, scale_nmm).map_err(bmr_err)
}

/// The `non_congruent` output map (the compensator's own table) applied to core torques (N·mm).
#[pyfunction]
#[pyo3(signature = (core_nmm, curvature, scale_nmm, cubic = 0.0))]
pub(super) fn output_map<'py>(
    py: Python<'py>,
    core_nmm: &Bound<'py, PyAny>,
    curvature: f64,
    scale_nmm: f64,
    cubic: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let mut m = output_map_of(curvature, scale_nmm, cubic)?;
    let x = extract_f64_array(core_nmm, "core_nmm")?;
    Ok(to_numpy(py, x.iter().map(|&v| m.forward(v)).collect()))
}

/// The inverse of `output_map`: the core torques (N·mm) giving field torques `field_nmm`.
#[pyfunction]
#[pyo3(signature = (field_nmm, curvature, scale_nmm, cubic = 0.0))]
pub(super) fn output_map_inverse<'py>(
    py: Python<'py>,
    field_nmm: &Bound<'py, PyAny>,
    curvature: f64,
    scale_nmm: f64,
    cubic: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let mut m = output_map_of(curvature, scale_nmm, cubic)?;
    let x = extract_f64_array(field_nmm, "field_nmm")?;
    Ok(to_numpy(py, x.iter().map(|&v| m.inverse(v)).collect()))
}
