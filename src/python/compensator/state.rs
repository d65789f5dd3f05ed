//! Snapshots (`bmr.CompensatorState`) and pickles of a compensator: its parts and its state as words.
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use super::*;
use crate::compensator::CompensatorState;
use crate::python::friction::PyFriction;
use crate::python::hysteresis::{MEMORY, PyHysteresis};
use crate::python::{bytes_to_words, table_err, words_to_bytes};

/// Snapshot of a Compensator's memory and stage states (restore it into the compensator it came from, or a copy
/// or unpickled copy of it).
#[pyclass(name = "CompensatorState", module = "bmr", frozen)]
#[derive(Clone)]
pub(crate) struct PyCompensatorState(pub(super) StateData);

/// A snapshot taken here, or unpickled words (checked against the tables when restored).
#[derive(Clone)]
pub(crate) enum StateData {
    Live(Box<CompensatorState<MEMORY>>),
    Words(Vec<u64>),
}

#[pymethods]
impl PyCompensatorState {
    fn __copy__(&self) -> Self {
        self.clone()
    }
    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
        self.clone()
    }
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, pyo3::types::PyBytes>,))> {
        let words = match &self.0 {
            StateData::Live(s) => s.to_words(),
            StateData::Words(w) => w.clone(),
        };
        let rebuild = py
            .import("bmr._core")?
            .getattr("_rebuild_compensator_state")?;
        Ok((rebuild, (words_to_bytes(py, &words),)))
    }
}

/// Unpickle a `CompensatorState` (checked against the compensator when it is restored).
#[pyfunction]
pub(super) fn _rebuild_compensator_state(state: &[u8]) -> PyResult<PyCompensatorState> {
    Ok(PyCompensatorState(StateData::Words(bytes_to_words(
        state,
        "CompensatorState",
    )?)))
}

/// Unpickle a `Compensator`: rebuilt from its parts, then its state restored.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub(super) fn _rebuild_compensator(
    hysteresis: PyRef<'_, PyHysteresis>,
    friction: PyRef<'_, PyFriction>,
    inverse: &str,
    converter_gain: f64,
    current_limit: f64,
    extensions: &Bound<'_, PyAny>,
    dt_s: Option<f64>,
    full_torque_nmm: f64,
    state: &[u8],
) -> PyResult<PyCompensator> {
    let ext = parse_extensions(Some(extensions))?;
    let mut c = PyCompensator::build(
        PyHysteresis {
            op: hysteresis.op.clone(),
            report: None,
        },
        friction.f,
        inverse,
        converter_gain,
        current_limit,
        ext,
        dt_s,
        Some(full_torque_nmm),
    )?;
    let words = bytes_to_words(state, "Compensator")?;
    let s = c.core.state_from_words(&words).map_err(table_err)?;
    c.core.restore(&s).map_err(table_err)?;
    Ok(c)
}

pub(super) fn reduce<'py>(
    slf: &Bound<'py, PyCompensator>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
    let py = slf.py();
    let me = shared(slf)?;
    let hysteresis = Bound::new(
        py,
        PyHysteresis {
            op: me.hysteresis.op.clone(),
            report: None,
        },
    )?;
    let friction = Bound::new(
        py,
        PyFriction {
            f: me.base_friction,
        },
    )?;
    let args = (
        hysteresis,
        friction,
        me.inverse,
        me.core.gain_a_per_v(),
        me.core.limit_a(),
        extensions_to_py(py, &me.extensions)?,
        me.dt_s,
        me.full_torque_nmm,
        words_to_bytes(py, &me.core.snapshot().to_words()),
    )
        .into_pyobject(py)?;
    let rebuild = py.import("bmr._core")?.getattr("_rebuild_compensator")?;
    Ok((rebuild, args))
}
