//! Python binding of the virtual hysteretic device (`bmr.VirtualDevice`): a piezo stack, a ferroelectric
//! capacitor — one input, one output, no angle.
use crate::plant::{DEVICE_PRESETS, DEVICE_SETTABLE, VirtualDevice, device_preset};
use crate::python::arrays::{DETACH_LEN, extract_f64_array, to_numpy};
use crate::python::virtual_actuator::apply_effects;
use crate::python::{BmrError, bmr_err};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

/// A seeded virtual hysteretic device with one input and one output and no angle.
///
/// ``VirtualDevice(preset="piezo", *, seed=0, sample_rate_hz=None, effects=None, overrides=None)``: presets
/// ``bmr.DEVICE_PRESETS`` (``piezo``: ±90 V → ±20 µm; ``ferroelectric``: ±10 V → ±30 µC/cm²); ``effects`` as for
/// ``bmr.VirtualActuator`` (those that need an angle are refused); ``overrides`` by the names in
/// ``bmr.DEVICE_PARAMETERS``.
#[pyclass(name = "VirtualDevice", module = "bmr._core")]
pub struct PyVirtualDevice {
    inner: VirtualDevice,
    preset: String,
}

#[pymethods]
impl PyVirtualDevice {
    #[new]
    #[pyo3(signature = (preset = "piezo", *, seed = 0, sample_rate_hz = None, effects = None, overrides = None))]
    fn new(
        preset: &str,
        seed: u64,
        sample_rate_hz: Option<f64>,
        effects: Option<&Bound<'_, PyAny>>,
        overrides: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let mut config = device_preset(preset).map_err(|_| {
            BmrError::new_err(format!(
                "unknown virtual device preset {preset:?}; available: {}",
                DEVICE_PRESETS.join(", ")
            ))
        })?;
        if let Some(rate) = sample_rate_hz {
            config.sample_rate_hz = rate;
        }
        if let Some(spec) = effects {
            apply_effects(&mut config.effects, spec)?;
        }
        if let Some(over) = overrides.filter(|o| !o.is_none()) {
            let over = over.cast::<PyDict>().map_err(|_| {
                BmrError::new_err("overrides must be a dict {\"parameter\": value}")
            })?;
            for (k, v) in over.iter() {
                let k: String = k.extract().map_err(|_| {
                    BmrError::new_err(format!(
                        "overrides: parameter names must be strings, got {k}"
                    ))
                })?;
                let v: f64 = v.extract().map_err(|_| {
                    BmrError::new_err(format!("overrides: {k} = {v} is not a number"))
                })?;
                config.set(&k, v).map_err(bmr_err)?;
            }
        }
        let inner = VirtualDevice::new(config, seed).map_err(bmr_err)?;
        Ok(PyVirtualDevice {
            inner,
            preset: preset.to_string(),
        })
    }

    /// Run commanded inputs from the current state; returns ``{"t_s", "input", "output", "output_true"}``
    /// (``output`` as measured; ``output_true`` before the sensor).
    fn run<'py>(&mut self, py: Python<'py>, u: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
        let cmd = extract_f64_array(u, "u")?;
        if let Some(i) = cmd.iter().position(|v| !v.is_finite()) {
            return Err(BmrError::new_err(format!(
                "u[{i}] = {} is not finite",
                cmd[i]
            )));
        }
        let inner = &mut self.inner;
        let n = cmd.len();
        let samples = if n > DETACH_LEN {
            py.detach(move || inner.run(&cmd))
        } else {
            inner.run(&cmd)
        };
        let out = PyDict::new(py);
        out.set_item("t_s", to_numpy(py, samples.iter().map(|s| s.t_s).collect()))?;
        out.set_item(
            "input",
            to_numpy(py, samples.iter().map(|s| s.input).collect()),
        )?;
        out.set_item(
            "output",
            to_numpy(py, samples.iter().map(|s| s.output).collect()),
        )?;
        out.set_item(
            "output_true",
            to_numpy(py, samples.iter().map(|s| s.output_true).collect()),
        )?;
        Ok(out)
    }

    /// A new recording after resting ``rest_s`` seconds at the input centre (inf: settled).
    #[pyo3(signature = (rest_s = 0.0))]
    fn start_run(&mut self, rest_s: f64) -> PyResult<()> {
        self.inner.start_run(rest_s).map_err(bmr_err)
    }

    /// Active effects and their parameters: ``{name: {param: value}}``.
    #[getter]
    fn effects<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for e in self.inner.config().effects.iter() {
            let params = PyDict::new(py);
            for (k, v) in e.params() {
                params.set_item(k, v)?;
            }
            out.set_item(e.name(), params)?;
        }
        Ok(out)
    }

    /// ``((name, unit), (name, unit))`` of the input and the output.
    #[getter]
    fn quantities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let c = self.inner.config();
        let i = PyTuple::new(py, [c.input.0.as_str(), c.input.1.as_str()])?;
        let o = PyTuple::new(py, [c.output.0.as_str(), c.output.1.as_str()])?;
        PyTuple::new(py, [i, o])
    }

    /// This recording's sensor calibration ``(gain, offset)`` (``run_gain_offset``; ``(1, 0)`` when off).
    #[getter]
    fn run_calibration(&self) -> (f64, f64) {
        self.inner.run_calibration()
    }

    /// ``(low, high)`` input saturation ends.
    #[getter]
    fn input_range(&self) -> (f64, f64) {
        let c = self.inner.config();
        (
            c.input_centre - c.input_half_span,
            c.input_centre + c.input_half_span,
        )
    }

    /// Standard deviation of the sensor noise (output units).
    #[getter]
    fn noise(&self) -> f64 {
        self.inner.config().noise
    }

    #[getter]
    fn preset(&self) -> &str {
        &self.preset
    }

    #[getter]
    fn name(&self) -> &str {
        &self.inner.config().name
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.inner.seed()
    }

    #[getter]
    fn sample_rate_hz(&self) -> f64 {
        self.inner.config().sample_rate_hz
    }

    /// Time of the next sample, s.
    #[getter]
    fn time_s(&self) -> f64 {
        self.inner.time_s()
    }

    fn __repr__(&self) -> String {
        let effects: Vec<String> = self
            .inner
            .config()
            .effects
            .iter()
            .map(|e| e.to_string())
            .collect();
        format!(
            "VirtualDevice(preset={:?}, seed={}, sample_rate_hz={}, effects=[{}])",
            self.preset,
            self.inner.seed(),
            self.inner.config().sample_rate_hz,
            effects.join(", ")
        )
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyVirtualDevice>()?;
    m.add("DEVICE_PRESETS", PyTuple::new(m.py(), DEVICE_PRESETS)?)?;
    m.add("DEVICE_PARAMETERS", PyTuple::new(m.py(), DEVICE_SETTABLE)?)?;
    Ok(())
}
