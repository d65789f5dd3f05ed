//! Python bindings: the `bmr._core` extension module.
use pyo3::prelude::*;

mod virtual_actuator;

pyo3::create_exception!(
    bmr,
    BmrError,
    pyo3::exceptions::PyValueError,
    "Invalid bmr input or table."
);

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("BmrError", m.py().get_type::<BmrError>())?;
    virtual_actuator::register(m)?;
    Ok(())
}
