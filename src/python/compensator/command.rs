//! `bmr.Command`: the core's [`Command`] itself, bound (its fields are the Python attributes).
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::compensator::Command;

#[pymethods]
impl Command {
    #[new]
    #[pyo3(signature = (current_a, coil1_a, coil2_a, volt1_v, volt2_v, saturated, fault))]
    fn new(
        current_a: f64,
        coil1_a: f64,
        coil2_a: f64,
        volt1_v: f64,
        volt2_v: f64,
        saturated: bool,
        fault: bool,
    ) -> Self {
        Command {
            current_a,
            coil1_a,
            coil2_a,
            volt1_v,
            volt2_v,
            saturated,
            fault,
        }
    }
    fn __copy__(&self) -> Self {
        *self
    }
    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
        *self
    }
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let c = slf.get();
        let args = (
            c.current_a,
            c.coil1_a,
            c.coil2_a,
            c.volt1_v,
            c.volt2_v,
            c.saturated,
            c.fault,
        );
        PyTuple::new(
            slf.py(),
            [
                slf.get_type().into_any(),
                args.into_pyobject(slf.py())?.into_any(),
            ],
        )
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
