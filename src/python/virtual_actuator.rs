//! Python binding of the virtual BMR actuator (`bmr.VirtualActuator`, `bmr.EFFECTS`, `bmr.effect_parameters`).
use crate::limits::{MAX_GENERATED_SAMPLES, check};
use crate::plant::effects::{Effect, EffectKind, EffectSet, kind_named};
use crate::plant::mr_fluid::YieldStress;
use crate::plant::presets::{DEFAULT_SAMPLE_RATE_HZ, PRESETS, preset as preset_config};
use crate::plant::{ActuatorConfig, SETTABLE, Sample, VirtualActuator};
use crate::python::arrays::{extract_f64_array, to_numpy};
use crate::python::errors::InUseError;
use crate::python::{BmrError, bmr_err, bytes_to_words, limit_err, words_to_bytes};
use crate::vocabulary::{EffectSpec, MODEL_ENTRIES, SPECS, loop_stages};
use numpy::PyArray1;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString, PyTuple};
use std::sync::{Mutex, MutexGuard, TryLockError};

/// Apply a Python effects specification to `set`: None, a dict `{name: {param: value} | None}` (None
/// removes the preset's effect), or a list of `"name:key=value,..."` strings (`"name:off"` removes it).
pub(crate) fn apply_effects(set: &mut EffectSet, spec: &Bound<'_, PyAny>) -> PyResult<()> {
    if spec.is_none() {
        return Ok(());
    }
    if let Ok(dict) = spec.cast::<PyDict>() {
        for (name, params) in dict.iter() {
            let name: String = name.extract().map_err(|_| {
                PyTypeError::new_err(format!("effects: effect names must be strings, got {name}"))
            })?;
            let kind = kind_named(&name).map_err(bmr_err)?;
            if params.is_none() {
                set.remove(kind);
                continue;
            }
            let params = params.cast::<PyDict>().map_err(|_| {
                PyTypeError::new_err(format!(
                    "effects: effect {name}: parameters must be a dict {{param: value}} or None"
                ))
            })?;
            let mut given: Vec<(String, f64)> = Vec::new();
            for (k, v) in params.iter() {
                let k: String = k.extract().map_err(|_| {
                    PyTypeError::new_err(format!(
                        "effects: effect {name}: parameter names must be strings"
                    ))
                })?;
                let v: f64 = v.extract().map_err(|_| {
                    PyTypeError::new_err(format!(
                        "effects: effect {name}: {k} = {v} is not a number"
                    ))
                })?;
                given.push((k, v));
            }
            let refs: Vec<(&str, f64)> = given.iter().map(|(k, v)| (k.as_str(), *v)).collect();
            set.insert(Effect::from_params(kind, &refs).map_err(bmr_err)?);
        }
        return Ok(());
    }
    let items: Vec<String> = if let Ok(s) = spec.cast::<PyString>() {
        vec![s.to_string()]
    } else if spec.cast::<PyList>().is_ok() || spec.cast::<PyTuple>().is_ok() {
        spec.extract().map_err(|_| {
            PyTypeError::new_err("effects: a list must hold strings like \"coil_lag:tau_s=0.02\"")
        })?
    } else {
        return Err(PyTypeError::new_err(
            "effects must be None, a dict {name: {param: value}} or a list of \"name:key=value\" strings",
        ));
    };
    for item in items {
        match item.split_once(':') {
            Some((name, rest)) if rest.trim() == "off" => {
                set.remove(kind_named(name.trim()).map_err(bmr_err)?)
            }
            _ => set.insert(Effect::parse(&item).map_err(bmr_err)?),
        }
    }
    Ok(())
}

/// The virtual BMR actuator: a seeded physical simulator of the paper's rig.
///
/// ``VirtualActuator(preset="bmr2013", *, seed=0, sample_rate_hz=1000.0, effects=None, overrides=None)``;
/// ``effects`` adds to (or, with ``None`` / ``"name:off"``, removes from) the preset's effects; ``overrides``
/// changes physical parameters by dotted name, e.g. ``{"sensor.noise_n": 0.0, "friction.scale": 0.5}``
/// (``bmr.ACTUATOR_PARAMETERS`` lists them).
///
/// Copyable and picklable (an unpickled actuator continues bit for bit). The configuration can be read at any
/// time; a call that needs the simulation state while another thread is inside ``run`` raises ``InUseError``.
#[pyclass(name = "VirtualActuator", module = "bmr", frozen)]
pub struct PyVirtualActuator {
    /// The simulation; locked (never waited for) by every call that reads or advances its state.
    inner: Mutex<VirtualActuator>,
    /// Immutable copies for the getters, and the construction arguments for pickling.
    config: ActuatorConfig,
    seed: u64,
    preset: String,
    sample_rate_hz: f64,
    overrides: Vec<(String, f64)>,
}

impl PyVirtualActuator {
    /// The simulation, or `InUseError` while another thread runs it.
    pub(crate) fn sim(&self) -> PyResult<MutexGuard<'_, VirtualActuator>> {
        match self.inner.try_lock() {
            Ok(guard) => Ok(guard),
            Err(TryLockError::WouldBlock) => Err(InUseError::new_err(
                "this VirtualActuator is in use by another thread (inside a run() that released the interpreter \
                 lock); wait for that call to return, or give each thread its own copy (copy.copy)",
            )),
            // A panic inside a locked section would be a bug; the state is still a valid simulator state.
            Err(TryLockError::Poisoned(p)) => Ok(p.into_inner()),
        }
    }

    fn with_state(&self, sim: VirtualActuator) -> Self {
        PyVirtualActuator {
            inner: Mutex::new(sim),
            config: self.config.clone(),
            seed: self.seed,
            preset: self.preset.clone(),
            sample_rate_hz: self.sample_rate_hz,
            overrides: self.overrides.clone(),
        }
    }

    /// Every effect kind: its parameters when active, None when off (rebuilds exactly this effect set).
    fn effects_spec<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for kind in EffectKind::ALL {
            out.set_item(kind.name(), py.None())?;
        }
        for e in self.config.effects.iter() {
            let params = PyDict::new(py);
            for (k, v) in e.params() {
                params.set_item(k, v)?;
            }
            out.set_item(e.name(), params)?;
        }
        Ok(out)
    }
}

/// Unpickle a `VirtualActuator`: rebuilt from its construction arguments, then its state restored.
#[pyfunction]
fn _rebuild_virtual_actuator(
    preset: &str,
    seed: u64,
    sample_rate_hz: f64,
    effects: &Bound<'_, PyAny>,
    overrides: &Bound<'_, PyAny>,
    state: &[u8],
) -> PyResult<PyVirtualActuator> {
    let seed = seed.into_pyobject(effects.py())?.into_any();
    let a = PyVirtualActuator::new(
        preset,
        Some(&seed),
        sample_rate_hz,
        Some(effects),
        Some(overrides),
    )?;
    let words = bytes_to_words(state, "VirtualActuator")?;
    a.sim()?.load_state(&words).map_err(bmr_err)?;
    Ok(a)
}

/// Names of the signals of one sample, in the order of [`PyActuatorSample::signals`] (also the columns of `run`).
const SIGNALS: [&str; 12] = [
    "t_s",
    "current_a",
    "coil1_a",
    "coil2_a",
    "theta_rad",
    "speed_rad_s",
    "torque_nmm",
    "b1_t",
    "b2_t",
    "field_torque_nmm",
    "friction_nmm",
    "torque_true_nmm",
];

/// One sample of the virtual actuator: what the rig measures (``t_s`` s, commanded ``current_a`` A, converter
/// currents ``coil1_a``/``coil2_a`` A, encoder ``theta_rad`` rad, ``speed_rad_s`` rad/s, sensor ``torque_nmm``
/// N·mm) and the hidden truth (gap flux densities ``b1_t``/``b2_t`` T, noise-free ``field_torque_nmm``,
/// ``friction_nmm`` and ``torque_true_nmm`` N·mm); ``command_valid`` is False when a non-finite command was
/// replaced by the safe 0 A. Fields are attributes; ``sample["torque_nmm"]`` reads one by name as well.
#[pyclass(name = "ActuatorSample", module = "bmr", frozen)]
#[derive(Clone)]
pub(crate) struct PyActuatorSample(Sample);

impl PyActuatorSample {
    /// The float signals in the order of [`SIGNALS`].
    fn signals(&self) -> [f64; 12] {
        let s = &self.0;
        [
            s.t_s,
            s.current_cmd_a,
            s.coil1_a,
            s.coil2_a,
            s.theta_rad,
            s.speed_rad_s,
            s.torque_nmm,
            s.b1_t,
            s.b2_t,
            s.field_torque_nmm,
            s.friction_nmm,
            s.torque_true_nmm,
        ]
    }
}

#[pymethods]
impl PyActuatorSample {
    #[getter]
    fn t_s(&self) -> f64 {
        self.0.t_s
    }
    #[getter]
    fn current_a(&self) -> f64 {
        self.0.current_cmd_a
    }
    #[getter]
    fn coil1_a(&self) -> f64 {
        self.0.coil1_a
    }
    #[getter]
    fn coil2_a(&self) -> f64 {
        self.0.coil2_a
    }
    #[getter]
    fn theta_rad(&self) -> f64 {
        self.0.theta_rad
    }
    #[getter]
    fn speed_rad_s(&self) -> f64 {
        self.0.speed_rad_s
    }
    #[getter]
    fn torque_nmm(&self) -> f64 {
        self.0.torque_nmm
    }
    #[getter]
    fn b1_t(&self) -> f64 {
        self.0.b1_t
    }
    #[getter]
    fn b2_t(&self) -> f64 {
        self.0.b2_t
    }
    #[getter]
    fn field_torque_nmm(&self) -> f64 {
        self.0.field_torque_nmm
    }
    #[getter]
    fn friction_nmm(&self) -> f64 {
        self.0.friction_nmm
    }
    #[getter]
    fn torque_true_nmm(&self) -> f64 {
        self.0.torque_true_nmm
    }
    #[getter]
    fn command_valid(&self) -> bool {
        self.0.command_valid
    }

    /// A signal by name (the column names of ``run``, or ``command_valid``).
    fn __getitem__<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        if name == "command_valid" {
            return Ok(pyo3::types::PyBool::new(py, self.0.command_valid)
                .to_owned()
                .into_any());
        }
        match SIGNALS.iter().position(|n| *n == name) {
            Some(i) => Ok(pyo3::types::PyFloat::new(py, self.signals()[i]).into_any()),
            None => Err(pyo3::exceptions::PyKeyError::new_err(format!(
                "{name:?}: an ActuatorSample has {} and command_valid",
                SIGNALS.join(", ")
            ))),
        }
    }

    /// The signal names, in order (``command_valid`` last).
    #[staticmethod]
    fn keys() -> Vec<&'static str> {
        SIGNALS.iter().copied().chain(["command_valid"]).collect()
    }

    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other.cast::<Self>().is_ok_and(|o| {
            let o = o.get();
            // Bit for bit (a seed fixes every sample), so NaN-free samples compare as plain floats do.
            o.signals().map(f64::to_bits) == self.signals().map(f64::to_bits)
                && o.0.command_valid == self.0.command_valid
        })
    }

    fn __repr__(&self) -> String {
        let fields: Vec<String> = SIGNALS
            .iter()
            .zip(self.signals())
            .map(|(n, v)| format!("{n}={v}"))
            .collect();
        format!(
            "ActuatorSample({}, command_valid={})",
            fields.join(", "),
            if self.0.command_valid {
                "True"
            } else {
                "False"
            }
        )
    }
}

#[pymethods]
impl PyVirtualActuator {
    #[new]
    #[pyo3(signature = (preset = "bmr2013", *, seed = None, sample_rate_hz = DEFAULT_SAMPLE_RATE_HZ, effects = None,
                        overrides = None))]
    fn new(
        preset: &str,
        seed: Option<&Bound<'_, PyAny>>,
        sample_rate_hz: f64,
        effects: Option<&Bound<'_, PyAny>>,
        overrides: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let seed: u64 = match seed {
            None => 0,
            Some(s) => s.extract().map_err(|e: PyErr| {
                if e.is_instance_of::<PyTypeError>(s.py()) {
                    PyTypeError::new_err(format!("seed must be an integer, got {s}"))
                } else {
                    BmrError::new_err(format!("seed must be an integer in [0, 2**64), got {s}"))
                }
            })?,
        };
        let mut config = preset_config(preset).map_err(bmr_err)?;
        config.sample_rate_hz = sample_rate_hz;
        if let Some(spec) = effects {
            apply_effects(&mut config.effects, spec)?;
        }
        let mut applied = Vec::new();
        if let Some(over) = overrides.filter(|o| !o.is_none()) {
            let over = over.cast::<PyDict>().map_err(|_| {
                PyTypeError::new_err("overrides must be a dict {\"group.parameter\": value}")
            })?;
            for (k, v) in over.iter() {
                let k: String = k.extract().map_err(|_| {
                    PyTypeError::new_err(format!(
                        "overrides: parameter names must be strings, got {k}"
                    ))
                })?;
                let v: f64 = v.extract().map_err(|_| {
                    PyTypeError::new_err(format!("overrides: {k} = {v} is not a number"))
                })?;
                config.set(&k, v).map_err(bmr_err)?;
                applied.push((k, v));
            }
        }
        let inner = VirtualActuator::new(config, seed).map_err(bmr_err)?;
        Ok(PyVirtualActuator {
            config: inner.config().clone(),
            inner: Mutex::new(inner),
            seed,
            preset: preset.to_string(),
            sample_rate_hz,
            overrides: applied,
        })
    }

    /// An independent actuator in the same state (same configuration, memory, time and noise stream).
    fn __copy__(&self) -> PyResult<Self> {
        let sim = self.sim()?.clone();
        Ok(self.with_state(sim))
    }

    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> PyResult<Self> {
        self.__copy__()
    }

    /// Pickled as its construction arguments and its state: an unpickled actuator continues bit for bit.
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let state = self.sim()?.save_state();
        let overrides = PyDict::new(py);
        for (k, v) in &self.overrides {
            overrides.set_item(k, v)?;
        }
        let args = (
            self.preset.as_str(),
            self.seed,
            self.sample_rate_hz,
            self.effects_spec(py)?,
            overrides,
            words_to_bytes(py, &state),
        )
            .into_pyobject(py)?;
        let rebuild = py
            .import("bmr._core")?
            .getattr("_rebuild_virtual_actuator")?;
        Ok((rebuild, args))
    }

    /// Run commanded nominal currents (A) from the current state; releases the GIL. Returns a dict of arrays:
    /// ``t_s, current_a, coil1_a, coil2_a, theta_rad, speed_rad_s, torque_nmm`` (what the rig logs) and the
    /// hidden truths ``b1_t, b2_t, field_torque_nmm, friction_nmm, torque_true_nmm``.
    /// At most 2**24 samples per call (``bmr.LIMITS``); longer simulations continue over several calls.
    fn run<'py>(
        &self,
        py: Python<'py>,
        current_a: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let cmd = extract_f64_array(current_a, "current_a")?;
        check(
            "samples in one VirtualActuator.run call",
            cmd.len(),
            MAX_GENERATED_SAMPLES,
        )
        .map_err(limit_err)?;
        if let Some(i) = cmd.iter().position(|v| !v.is_finite()) {
            return Err(BmrError::new_err(format!(
                "current_a[{i}] = {} is not finite; commands must be finite currents in A",
                cmd[i]
            )));
        }
        let mut sim = self.sim()?;
        let inner = &mut *sim;
        let trace = py.detach(move || inner.run(&cmd));
        drop(sim);
        let out = PyDict::new(py);
        let cols: [Vec<f64>; 12] = [
            trace.t_s,
            trace.current_cmd_a,
            trace.coil1_a,
            trace.coil2_a,
            trace.theta_rad,
            trace.speed_rad_s,
            trace.torque_nmm,
            trace.b1_t,
            trace.b2_t,
            trace.field_torque_nmm,
            trace.friction_nmm,
            trace.torque_true_nmm,
        ];
        for (name, v) in SIGNALS.iter().zip(cols) {
            out.set_item(*name, to_numpy(py, v))?;
        }
        Ok(out)
    }

    /// Advance one sample with commanded nominal current ``current_a`` (A): an :class:`ActuatorSample` (the
    /// columns of ``run`` as floats, plus ``command_valid``: a non-finite command applies the safe 0 A and is
    /// flagged False).
    fn step(&self, current_a: f64) -> PyResult<PyActuatorSample> {
        Ok(PyActuatorSample(self.sim()?.step(current_a)))
    }

    /// Start a new recording after the rig rested ``rest_s`` seconds at zero current (``float("inf")``: long enough
    /// for the coils to cool and creep to settle; 0: back to back). The steel keeps its remanence; the leakage
    /// integral restarts and the per-run calibration (``run_gain_offset``) is drawn anew.
    #[pyo3(signature = (rest_s = 0.0))]
    fn start_run(&self, rest_s: f64) -> PyResult<()> {
        self.sim()?.start_run(rest_s).map_err(bmr_err)
    }

    /// This recording's sensor calibration ``(gain, offset_nmm)`` (``run_gain_offset``; ``(1, 0)`` when off): the
    /// hidden truth a calibration study compares the diagnosis with.
    #[getter]
    fn run_calibration(&self) -> PyResult<(f64, f64)> {
        Ok(self.sim()?.run_calibration())
    }

    /// Back to the state right after construction (demagnetised, cold, t = 0, same noise stream).
    fn reset(&self) -> PyResult<()> {
        self.sim()?.reset();
        Ok(())
    }

    /// Noise-free seal friction (N·mm) at zero current for each angle in ``theta_rad``.
    fn true_friction<'py>(
        &self,
        py: Python<'py>,
        theta_rad: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let th = extract_f64_array(theta_rad, "theta_rad")?;
        let sim = self.sim()?;
        let v: Vec<f64> = th.iter().map(|&t| sim.true_friction_nmm(t)).collect();
        Ok(to_numpy(py, v))
    }

    /// Encoder angles (rad) of the next ``n`` samples, without advancing (the angle does not depend on current).
    /// At most 2**24 samples per call (``bmr.LIMITS``).
    fn theta_ahead<'py>(&self, py: Python<'py>, n: usize) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let theta = self.sim()?.theta_ahead(n).map_err(limit_err)?;
        Ok(to_numpy(py, theta))
    }

    /// Active effects and their parameters: ``{name: {param: value}}``.
    #[getter]
    fn effects<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for e in self.config.effects.iter() {
            let params = PyDict::new(py);
            for (k, v) in e.params() {
                params.set_item(k, v)?;
            }
            out.set_item(e.name(), params)?;
        }
        Ok(out)
    }

    #[getter]
    fn preset(&self) -> &str {
        &self.preset
    }

    /// Free-text description of the actuator (written into bundles).
    #[getter]
    fn name(&self) -> &str {
        &self.config.name
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.seed
    }

    #[getter]
    fn sample_rate_hz(&self) -> f64 {
        self.config.sample_rate_hz
    }

    /// Time of the next sample, s.
    #[getter]
    fn time_s(&self) -> PyResult<f64> {
        Ok(self.sim()?.time_s())
    }

    /// The physical parameters of every stage (units in the names), for reports and ground-truth studies.
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = &self.config;
        let out = PyDict::new(py);
        let conv = PyDict::new(py);
        conv.set_item("gain_a_per_v", c.converter.gain_a_per_v)?;
        conv.set_item("limit_a", c.converter.limit_a)?;
        conv.set_item("bandwidth_hz", c.converter.bandwidth_hz)?;
        out.set_item("converter", conv)?;
        for (name, st) in [("steel1", &c.steel1), ("steel2", &c.steel2)] {
            let d = PyDict::new(py);
            d.set_item("saturation_t", st.saturation_t)?;
            d.set_item("coercivity_a", st.coercivity_a)?;
            d.set_item("coercivity_width_a", st.coercivity_width_a)?;
            d.set_item("interaction_width_a", st.interaction_width_a)?;
            d.set_item("reversible_fraction", st.reversible_fraction)?;
            d.set_item("reversible_width_a", st.reversible_width_a)?;
            d.set_item("range_a", st.range_a)?;
            d.set_item("grid", st.grid)?;
            out.set_item(name, d)?;
        }
        let fluid = PyDict::new(py);
        match c.fluid.yield_stress {
            YieldStress::Mrf132dg => fluid.set_item("yield_stress", "MRF-132DG cubic")?,
            YieldStress::Linear { kpa_per_t } => {
                fluid.set_item("yield_stress", "linear")?;
                fluid.set_item("kpa_per_t", kpa_per_t)?;
            }
        }
        fluid.set_item("viscosity_pa_s", c.fluid.viscosity_pa_s)?;
        out.set_item("fluid", fluid)?;
        let g = PyDict::new(py);
        g.set_item("shaft_radius_mm", c.geometry.shaft_radius_mm)?;
        g.set_item("disc_radius_mm", c.geometry.disc_radius_mm)?;
        g.set_item("drum_width_mm", c.geometry.drum_width_mm)?;
        g.set_item("gap_mm", c.geometry.gap_mm)?;
        out.set_item("geometry", g)?;
        let d = PyDict::new(py);
        d.set_item("speed_rad_s", c.drive.speed_rad_s)?;
        d.set_item("speed_ripple", c.drive.speed_ripple)?;
        d.set_item("theta0_rad", c.drive.theta0_rad)?;
        out.set_item("drive", d)?;
        let f = PyDict::new(py);
        f.set_item("offset_nmm", c.friction.offset_nmm)?;
        f.set_item(
            "amplitude_nmm",
            c.friction.harmonics.iter().map(|h| h.0).collect::<Vec<_>>(),
        )?;
        f.set_item(
            "phase_rad",
            c.friction.harmonics.iter().map(|h| h.1).collect::<Vec<_>>(),
        )?;
        out.set_item("friction", f)?;
        let s = PyDict::new(py);
        s.set_item("lever_mm", c.sensor.lever_mm)?;
        s.set_item("noise_n", c.sensor.noise_n)?;
        s.set_item("resolution_n", c.sensor.resolution_n)?;
        s.set_item("range_n", c.sensor.range_n)?;
        s.set_item("offset_n", c.sensor.offset_n)?;
        out.set_item("sensor", s)?;
        out.set_item("full_current_a", c.full_current_a)?;
        out.set_item("full_torque_nmm", c.full_torque_nmm)?;
        Ok(out)
    }

    /// Standard deviation of the torque sensor noise, N·mm.
    #[getter]
    fn noise_nmm(&self) -> f64 {
        self.config.sensor.noise_nmm()
    }

    /// Torque quantisation step of the sensor, N·mm (0 = none).
    #[getter]
    fn resolution_nmm(&self) -> f64 {
        let s = &self.config.sensor;
        s.resolution_n * s.lever_mm
    }

    /// Converter gain, A/V.
    #[getter]
    fn converter_gain_a_per_v(&self) -> f64 {
        self.config.converter.gain_a_per_v
    }

    fn __repr__(&self) -> String {
        let effects: Vec<String> = self.config.effects.iter().map(|e| e.to_string()).collect();
        format!(
            "VirtualActuator(preset={:?}, seed={}, sample_rate_hz={}, effects=[{}])",
            self.preset,
            self.seed,
            self.config.sample_rate_hz,
            effects.join(", ")
        )
    }
}

/// Every effect's documentation and parameters: ``{name: {"doc": str, "acts": str, "loop_order": int | None,
/// "needs_period": bool, "state": str, "on_angle": bool, "params": {param: {"unit",
/// "default", "min", "max", "whole", "smallest_nonzero", "doc"}}}}`` (``smallest_nonzero``: where 0 means
/// automatic, the smallest magnitude a set value may have; else 0); ``model_entries=True`` adds the model-file entries that are not
/// physical effects (``core_tables``, ``table_resolution``, ``offset``).
#[pyfunction]
#[pyo3(signature = (*, model_entries=false))]
fn effect_parameters(py: Python<'_>, model_entries: bool) -> PyResult<Bound<'_, PyDict>> {
    let out = PyDict::new(py);
    let extra: &[EffectSpec] = if model_entries { MODEL_ENTRIES } else { &[] };
    for spec in SPECS.iter().chain(extra) {
        let entry = PyDict::new(py);
        entry.set_item("doc", spec.doc)?;
        entry.set_item("acts", spec.acts.name())?;
        entry.set_item("loop_order", spec.stage.map(|st| st.order))?;
        entry.set_item("needs_period", spec.stage.is_some_and(|st| st.needs_period))?;
        entry.set_item("state", spec.stage.map_or("", |st| st.state))?;
        entry.set_item("on_angle", spec.on_angle)?;
        let params = PyDict::new(py);
        for s in spec.params {
            let p = PyDict::new(py);
            p.set_item("unit", s.unit)?;
            p.set_item("default", s.default)?;
            p.set_item("min", s.min)?;
            p.set_item("max", s.max)?;
            p.set_item("whole", s.whole)?;
            p.set_item("smallest_nonzero", s.smallest_nonzero)?;
            p.set_item("doc", s.doc)?;
            params.set_item(s.name, p)?;
        }
        entry.set_item("params", params)?;
        out.set_item(spec.name, entry)?;
    }
    Ok(out)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyVirtualActuator>()?;
    m.add_class::<PyActuatorSample>()?;
    m.add_function(wrap_pyfunction!(_rebuild_virtual_actuator, m)?)?;
    m.add_function(wrap_pyfunction!(effect_parameters, m)?)?;
    m.add(
        "EFFECTS",
        PyTuple::new(m.py(), EffectKind::ALL.map(|k| k.name()))?,
    )?;
    m.add(
        "MODEL_EXTENSIONS",
        PyTuple::new(
            m.py(),
            SPECS
                .iter()
                .chain(MODEL_ENTRIES)
                .map(|s| s.name)
                .collect::<Vec<_>>(),
        )?,
    )?;
    let names = |keep: fn(&EffectSpec) -> bool| -> Vec<&'static str> {
        SPECS.iter().filter(|s| keep(s)).map(|s| s.name).collect()
    };
    m.add(
        "LOOP_STAGES",
        PyTuple::new(m.py(), loop_stages().map(|s| s.name).collect::<Vec<_>>())?,
    )?;
    m.add(
        "PERIOD_EFFECTS",
        PyTuple::new(m.py(), names(|s| s.stage.is_some_and(|st| st.needs_period)))?,
    )?;
    m.add(
        "ANGLE_EFFECTS",
        PyTuple::new(m.py(), names(|s| s.on_angle))?,
    )?;
    m.add("PRESETS", PyTuple::new(m.py(), PRESETS)?)?;
    m.add("ACTUATOR_PARAMETERS", PyTuple::new(m.py(), SETTABLE)?)?;
    Ok(())
}
