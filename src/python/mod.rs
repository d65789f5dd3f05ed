//! Python bindings: the `bmr._core` extension module. Each bound concept has its own file with a `register`.
use pyo3::prelude::*;
use pyo3::pyclass::boolean_struct::False;
use pyo3::{PyClass, PyTypeInfo};

mod arrays;
mod compensator;
mod controller;
mod curve_fit;
mod effect_signals;
mod filters;
mod friction;
mod hysteresis;
mod identification;
mod reversals;
mod table_report;
mod virtual_actuator;
mod virtual_device;

/// The exception hierarchy, created here so that Rust and Python raise the same classes. `BmrError` (a
/// `ValueError`) is the base; each subclass names a kind of problem.
pub(crate) mod errors {
    pyo3::create_exception!(
        bmr,
        BmrError,
        pyo3::exceptions::PyValueError,
        "Invalid bmr input, table or file."
    );
    pyo3::create_exception!(
        bmr,
        TableError,
        BmrError,
        "Curves or tables that cannot make a hysteresis operator (the message names family, curve and sample)."
    );
    pyo3::create_exception!(
        bmr,
        BundleError,
        BmrError,
        "A bundle folder, manifest or run file that cannot be read or written (the message names the file)."
    );
    pyo3::create_exception!(
        bmr,
        ModelFileError,
        BmrError,
        "A model file that cannot be read or written (the message names the file and the field)."
    );
    pyo3::create_exception!(
        bmr,
        ExcitationError,
        BmrError,
        "An excitation or experiment protocol with invalid parameters."
    );
    pyo3::create_exception!(
        bmr,
        IdentificationError,
        BmrError,
        "Data from which friction or tables cannot be identified."
    );
    pyo3::create_exception!(
        bmr,
        ResourceLimitError,
        BmrError,
        "A requested size above its documented limit (checked before anything is allocated)."
    );
    pyo3::create_exception!(
        bmr,
        InUseError,
        BmrError,
        "The object is in use by another thread (inside a run() that released the interpreter lock)."
    );
}

pub(crate) use errors::BmrError;

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

/// A table error as `ResourceLimitError` (size limits) or `TableError`.
pub(crate) fn table_err(e: crate::error::TableError) -> PyErr {
    match e {
        crate::error::TableError::TooLarge { .. } => {
            errors::ResourceLimitError::new_err(e.to_string())
        }
        _ => errors::TableError::new_err(e.to_string()),
    }
}

/// A size above its limit, as `ResourceLimitError`.
pub(crate) fn limit_err(e: crate::limits::LimitError) -> PyErr {
    errors::ResourceLimitError::new_err(e.to_string())
}

/// An identification error as `ResourceLimitError` (size limits) or `IdentificationError`, prefixed with what
/// was being identified.
pub(crate) fn identification_err(
    context: &str,
    e: crate::identification::IdentificationError,
) -> PyErr {
    match e {
        crate::identification::IdentificationError::Limit(l) => {
            errors::ResourceLimitError::new_err(format!("{context}: {l}"))
        }
        _ => errors::IdentificationError::new_err(format!("{context}: {e}")),
    }
}

fn in_use<T: PyClass>() -> PyErr {
    errors::InUseError::new_err(format!(
        "this {} is in use by another thread (inside a run() that released the interpreter lock); wait for \
         that call to return, or give each thread its own copy (copy.copy)",
        T::NAME
    ))
}

/// Borrow `slf` for reading; `InUseError` (not `RuntimeError: Already borrowed`) while another thread is inside a
/// GIL-released call on it.
pub(crate) fn borrow<'py, T: PyClass>(slf: &Bound<'py, T>) -> PyResult<PyRef<'py, T>> {
    slf.try_borrow().map_err(|_| in_use::<T>())
}

/// Borrow `slf` for changing it; `InUseError` while another thread is inside a GIL-released call on it.
pub(crate) fn borrow_mut<'py, T: PyClass<Frozen = False>>(
    slf: &Bound<'py, T>,
) -> PyResult<PyRefMut<'py, T>> {
    slf.try_borrow_mut().map_err(|_| in_use::<T>())
}

/// Words of a serialised state as Python `bytes` (little-endian `u64`s) and back; pickling support.
pub(crate) fn words_to_bytes<'py>(
    py: Python<'py>,
    words: &[u64],
) -> Bound<'py, pyo3::types::PyBytes> {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    pyo3::types::PyBytes::new(py, &bytes)
}

pub(crate) fn bytes_to_words(bytes: &[u8], what: &str) -> PyResult<Vec<u64>> {
    if !bytes.len().is_multiple_of(8) {
        return Err(BmrError::new_err(format!(
            "{what}: serialised state has {} bytes, not a whole number of 8-byte words",
            bytes.len()
        )));
    }
    Ok(bytes
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
        .collect())
}

/// The documented size limits (`bmr.LIMITS`), by name.
fn limits_dict(py: Python<'_>) -> PyResult<Bound<'_, pyo3::types::PyDict>> {
    use crate::limits::*;
    let d = pyo3::types::PyDict::new(py);
    d.set_item("curves_per_family", MAX_CURVES)?;
    d.set_item("max_nodes", MAX_NODES)?;
    d.set_item("table_values_per_family", MAX_TABLE_VALUES)?;
    d.set_item("magnitude", MAX_MAGNITUDE)?;
    d.set_item("generated_samples", MAX_GENERATED_SAMPLES)?;
    d.set_item("friction_fit_order", MAX_FIT_ORDER)?;
    d.set_item("everett_intervals", MAX_EVERETT_INTERVALS)?;
    d.set_item("everett_unknowns", MAX_EVERETT_UNKNOWNS)?;
    d.set_item("everett_large_unknowns", MAX_EVERETT_LARGE_UNKNOWNS)?;
    d.set_item("everett_entries", MAX_EVERETT_ENTRIES)?;
    d.set_item("solver_iterations", MAX_SOLVER_ITERATIONS)?;
    d.set_item("cv_folds", MAX_CV_FOLDS)?;
    d.set_item("curve_points", MAX_CURVE_POINTS)?;
    Ok(d)
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("BmrError", py.get_type::<BmrError>())?;
    m.add("TableError", errors::TableError::type_object(py))?;
    m.add("BundleError", errors::BundleError::type_object(py))?;
    m.add("ModelFileError", errors::ModelFileError::type_object(py))?;
    m.add("ExcitationError", errors::ExcitationError::type_object(py))?;
    m.add(
        "IdentificationError",
        errors::IdentificationError::type_object(py),
    )?;
    m.add(
        "ResourceLimitError",
        errors::ResourceLimitError::type_object(py),
    )?;
    m.add("InUseError", errors::InUseError::type_object(py))?;
    m.add("LIMITS", limits_dict(py)?)?;
    hysteresis::register(m)?;
    friction::register(m)?;
    identification::register(m)?;
    reversals::register(m)?;
    table_report::register(m)?;
    curve_fit::register(m)?;
    virtual_actuator::register(m)?;
    virtual_device::register(m)?;
    compensator::register(m)?;
    controller::register(m)?;
    effect_signals::register(m)?;
    filters::register(m)?;
    Ok(())
}
