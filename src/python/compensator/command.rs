//! `bmr.Command`: the core's [`Command`] itself, bound (its fields are the Python attributes), and the objects a
//! stepping loop hands out again.
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::compensator::Command;

/// The last two `Command` objects a `step` returned. A step at 1-10 kHz would otherwise allocate (and the caller
/// free) one object per sample, a large share of the call: once no reference but this one is left to an object
/// (the caller dropped it or moved on to the next command), the next command is written into it and it is
/// returned again. Nothing else can see that object, so to Python every command is still a new, unchanging
/// value; two slots cover `cmd = c.step(...)`, where the previous command is still held during the call.
#[derive(Default)]
pub(crate) struct CommandSlots([Option<Py<Command>>; 2]);

impl CommandSlots {
    /// `command` as a Python object: a slot no one else holds, else a new object (which takes the older slot).
    pub(crate) fn give(&mut self, py: Python<'_>, command: Command) -> PyResult<Py<Command>> {
        for slot in self.0.iter().flatten() {
            let obj = slot.bind(py);
            // SAFETY: reads the reference count of a live object this thread holds a reference to, while
            // attached to the interpreter.
            if unsafe { pyo3::ffi::Py_REFCNT(obj.as_ptr()) } == 1 {
                // Held here only: its borrow cannot fail and no reader can see the change.
                *obj.try_borrow_mut()? = command;
                return Ok(slot.clone_ref(py));
            }
        }
        let obj = Py::new(py, command)?;
        self.0.swap(0, 1);
        self.0[1] = Some(obj.clone_ref(py));
        Ok(obj)
    }
}

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
        let c = *slf.try_borrow()?;
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
