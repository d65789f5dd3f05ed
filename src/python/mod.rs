//! Python bindings: the `bmr._core` extension module. Each bound concept has its own file with a `register`.
use pyo3::prelude::*;

mod arrays;
mod compensator;
mod effect_signals;
mod filters;
mod friction;
mod hysteresis;
mod identification;
mod reversals;
mod virtual_actuator;
mod virtual_device;

pyo3::create_exception!(
    bmr,
    BmrError,
    pyo3::exceptions::PyValueError,
    "Invalid bmr input, table or file."
);

/// Turn any displayable core error into a `BmrError`.
pub(crate) fn bmr_err(e: impl core::fmt::Display) -> PyErr {
    BmrError::new_err(e.to_string())
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("BmrError", m.py().get_type::<BmrError>())?;
    hysteresis::register(m)?;
    friction::register(m)?;
    identification::register(m)?;
    reversals::register(m)?;
    virtual_actuator::register(m)?;
    virtual_device::register(m)?;
    compensator::register(m)?;
    effect_signals::register(m)?;
    filters::register(m)?;
    Ok(())
}
