//! Python bindings: the `bmr._core` extension module. Each bound concept has its own file with a `register`.
use pyo3::prelude::*;

mod arrays;
mod compensator;
mod curve_fit;
mod friction;
mod hysteresis;
mod identification;
mod reversals;
mod table_report;
mod virtual_actuator;

pyo3::create_exception!(
    bmr,
    BmrError,
    pyo3::exceptions::PyValueError,
    "Invalid bmr input, table or file."
);

/// `x` with `digits` significant digits (like Python's `g` format) for one-screen reprs.
pub(crate) fn sig(x: f64, digits: usize) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let e = libm::floor(libm::log10(libm::fabs(x))) as i32;
    if (-4..6).contains(&e) {
        let decimals = (digits as i32 - 1 - e).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{:.*e}", digits.saturating_sub(1), x)
    }
}

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
    table_report::register(m)?;
    curve_fit::register(m)?;
    virtual_actuator::register(m)?;
    compensator::register(m)?;
    Ok(())
}
