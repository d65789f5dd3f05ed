//! `bmr.Controller`: the closed loop around a `bmr.Compensator` (integral feedback on the measured torque and
//! gain/offset adaptation, see `crate::controller`), its `ControllerDesign`, and the batch closed loop on a
//! `bmr.VirtualActuator` (`bmr.simulate_closed_loop` wraps it into a typed result).
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::cbh::Initial;
use crate::compensator::{Command, Compensator};
use crate::controller::{Controller, ControllerDesign, ControllerSettings, ControllerState};
use crate::friction::MAX_ORDER;
use crate::limits::{MAX_GENERATED_SAMPLES, check};
use crate::plant::run_closed_loop;
use crate::python::arrays::{extract_f64_array, to_numpy};
use crate::python::compensator::PyCompensator;
use crate::python::compensator::command::CommandSlots;
use crate::python::hysteresis::{MEMORY, initial_or_negative};
use crate::python::virtual_actuator::PyVirtualActuator;
use crate::python::{BmrError, bmr_err, bytes_to_words, limit_err, table_err, words_to_bytes};

type Core = Controller<Vec<f64>, MEMORY, MAX_ORDER>;

/// The closed loop as designed from the model: bandwidth asked and given (Hz), integral gain (1/s), the loop's
/// delay (s) and the phase margin it leaves (degrees), the coil lag the feedforward leads (s).
#[pyclass(name = "ControllerDesign", module = "bmr", frozen, get_all, eq)]
#[derive(Clone, PartialEq)]
pub(crate) struct PyControllerDesign {
    dt_s: f64,
    asked_hz: f64,
    bandwidth_hz: f64,
    ki_per_s: f64,
    loop_delay_s: f64,
    phase_margin_deg: f64,
    coil_lag_s: f64,
    delay_samples: usize,
    forgetting: f64,
    correction_limit_nmm: f64,
    full_torque_nmm: f64,
    fault_after: u32,
    feedback: bool,
}

impl From<ControllerDesign> for PyControllerDesign {
    fn from(d: ControllerDesign) -> Self {
        PyControllerDesign {
            dt_s: d.dt_s,
            asked_hz: d.asked_hz,
            bandwidth_hz: d.bandwidth_hz,
            ki_per_s: d.ki_per_s,
            loop_delay_s: d.loop_delay_s,
            phase_margin_deg: d.phase_margin_deg,
            coil_lag_s: d.coil_lag_s,
            delay_samples: d.delay_samples,
            forgetting: d.forgetting,
            correction_limit_nmm: d.correction_limit_nmm,
            full_torque_nmm: d.full_torque_nmm,
            fault_after: d.fault_after,
            feedback: d.feedback,
        }
    }
}

#[pymethods]
impl PyControllerDesign {
    fn __repr__(&self) -> String {
        format!(
            "ControllerDesign(asked_hz={}, bandwidth_hz={:.4}, ki_per_s={:.4}, phase_margin_deg={:.2}, \
             loop_delay_s={}, coil_lag_s={}, delay_samples={}, feedback={})",
            self.asked_hz,
            self.bandwidth_hz,
            self.ki_per_s,
            self.phase_margin_deg,
            self.loop_delay_s,
            self.coil_lag_s,
            self.delay_samples,
            if self.feedback { "True" } else { "False" }
        )
    }
}

/// Snapshot of a Controller (compensator memory, stages, correction, adaptation).
#[pyclass(name = "ControllerState", module = "bmr", frozen)]
#[derive(Clone)]
pub(crate) struct PyControllerState(Box<ControllerState<MEMORY>>);

/// Closed-loop torque controller: the compensator as feedforward, integral feedback on the measured torque
/// (gain from the loop the model describes), online gain/offset adaptation between model and measurement.
#[pyclass(name = "Controller", module = "bmr")]
pub(crate) struct PyController {
    core: Core,
    /// The compensator it was built from (copies and pickles are rebuilt from it).
    source: Py<PyCompensator>,
    settings: ControllerSettings,
    /// The `Command` objects `step` hands out again.
    commands: CommandSlots,
}

fn busy<'py>(slf: &Bound<'py, PyController>) -> PyResult<PyRefMut<'py, PyController>> {
    crate::python::borrow_mut(slf)
}

fn shared<'py>(slf: &Bound<'py, PyController>) -> PyResult<PyRef<'py, PyController>> {
    crate::python::borrow(slf)
}

impl PyController {
    fn build(
        py: Python<'_>,
        compensator: &Bound<'_, PyCompensator>,
        dt_s: Option<f64>,
        settings: ControllerSettings,
    ) -> PyResult<Self> {
        let source: Bound<'_, PyCompensator> = compensator.call_method0("__copy__")?.cast_into()?;
        let (core, dt) = {
            let c = crate::python::borrow(&source)?;
            let core: Compensator<Vec<f64>, MEMORY, MAX_ORDER> = c.core().clone();
            (core, dt_s.or(c.control_period_s()))
        };
        let Some(dt) = dt else {
            return Err(BmrError::new_err(
                "dt_s (the control period, s) is needed: the compensator was built without one",
            ));
        };
        let core = Controller::new(core, dt, settings).map_err(bmr_err)?;
        Ok(PyController {
            core,
            source: source.unbind(),
            settings,
            commands: CommandSlots::default(),
        })
        .inspect(|_| {
            let _ = py;
        })
    }

    fn rebuilt(&self, py: Python<'_>) -> PyResult<Self> {
        let mut c = Self::build(
            py,
            self.source.bind(py),
            Some(self.core.design().dt_s),
            self.settings,
        )?;
        c.core.restore(&self.core.snapshot()).map_err(table_err)?;
        Ok(c)
    }
}

#[pymethods]
impl PyController {
    /// Close the loop around `compensator` (a copy of it, in its present state) at control period `dt_s`
    /// (default: the compensator's). `bandwidth_hz`: loop crossover (0: automatic, the largest that adds at most
    /// `noise_share` of the sensor-noise variance and keeps a 60° phase margin); `adaptation_time_s`: memory of
    /// the gain/offset estimate; `fault_after`: missing measurements in a row before a fault (zero current);
    /// `correction_limit_nmm`: largest integral correction (0: a quarter of the model's full torque);
    /// `feedback`, `adaptation`: switch the integral feedback and the adaptation.
    #[new]
    #[pyo3(signature = (compensator, *, dt_s=None, bandwidth_hz=0.0, noise_share=0.02, adaptation_time_s=5.0,
                        fault_after=50, correction_limit_nmm=0.0, feedback=true, adaptation=true))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        compensator: &Bound<'_, PyCompensator>,
        dt_s: Option<f64>,
        bandwidth_hz: f64,
        noise_share: f64,
        adaptation_time_s: f64,
        fault_after: u32,
        correction_limit_nmm: f64,
        feedback: bool,
        adaptation: bool,
    ) -> PyResult<Self> {
        let settings = ControllerSettings {
            bandwidth_hz,
            noise_share,
            adaptation_time_s,
            fault_after,
            correction_limit_nmm,
            feedback,
            adaptation,
        };
        Self::build(py, compensator, dt_s, settings)
    }

    /// The controller around a model's full (extended) compensator (`bmr.Compensator.from_model(model,
    /// dt_s=dt_s)`); `kwargs` are the controller's settings.
    #[staticmethod]
    #[pyo3(signature = (model, *, dt_s, **kwargs))]
    fn from_model<'py>(
        py: Python<'py>,
        model: &Bound<'py, PyAny>,
        dt_s: f64,
        kwargs: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let comp_cls = py.import("bmr")?.getattr("Compensator")?;
        let kw = PyDict::new(py);
        kw.set_item("dt_s", dt_s)?;
        let comp = comp_cls.call_method("from_model", (model,), Some(&kw))?;
        let kw = PyDict::new(py);
        if let Some(k) = kwargs {
            kw.update(k.as_mapping())?;
        }
        kw.set_item("dt_s", dt_s)?;
        py.get_type::<PyController>().call((comp,), Some(&kw))
    }

    /// One control period: reference torque (N·mm) and rotor angle (rad) of this sample, and the torque measured
    /// at the previous sample (N·mm; NaN/inf: no new value). Never raises.
    fn step(
        slf: &Bound<'_, Self>,
        reference_nmm: f64,
        theta_rad: f64,
        measured_nmm: f64,
    ) -> PyResult<Py<Command>> {
        let mut me = busy(slf)?;
        let c = me.core.step(reference_nmm, theta_rad, measured_nmm);
        me.commands.give(slf.py(), c)
    }

    /// The loop as designed.
    #[getter]
    fn design(slf: &Bound<'_, Self>) -> PyResult<PyControllerDesign> {
        Ok((*shared(slf)?.core.design()).into())
    }
    /// Adapted output gain (measured torque per model torque).
    #[getter]
    fn gain(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(shared(slf)?.core.gain())
    }
    /// Adapted output offset (N·mm).
    #[getter]
    fn offset_nmm(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(shared(slf)?.core.offset_nmm())
    }
    /// Integral correction added to the reference (N·mm).
    #[getter]
    fn correction_nmm(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(shared(slf)?.core.correction_nmm())
    }
    /// Missing measurements in a row so far.
    #[getter]
    fn missing_samples(slf: &Bound<'_, Self>) -> PyResult<u32> {
        Ok(shared(slf)?.core.missing_samples())
    }
    /// The gain and offset are held where they are.
    #[getter]
    fn adaptation_frozen(slf: &Bound<'_, Self>) -> PyResult<bool> {
        Ok(shared(slf)?.core.adaptation_frozen())
    }
    /// Hold the gain and offset (`True`) or let them adapt again.
    #[pyo3(signature = (frozen=true))]
    fn freeze_adaptation(slf: &Bound<'_, Self>, frozen: bool) -> PyResult<()> {
        busy(slf)?.core.freeze_adaptation(frozen);
        Ok(())
    }
    /// Gain back to 1, offset to 0.
    fn reset_adaptation(slf: &Bound<'_, Self>) -> PyResult<()> {
        busy(slf)?.core.reset_adaptation();
        Ok(())
    }
    /// Compensator memory back to `initial` (default: after negative saturation), correction and adaptation to
    /// their start.
    #[pyo3(signature = (initial=None))]
    fn reset(slf: &Bound<'_, Self>, initial: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let initial: Initial = initial_or_negative(initial)?;
        busy(slf)?.core.reset(initial);
        Ok(())
    }
    /// A copy of the whole state (restore it with `restore`).
    fn snapshot(slf: &Bound<'_, Self>) -> PyResult<PyControllerState> {
        Ok(PyControllerState(Box::new(shared(slf)?.core.snapshot())))
    }
    /// Return to a snapshot of this controller (or of a copy of it).
    fn restore(slf: &Bound<'_, Self>, state: &PyControllerState) -> PyResult<()> {
        busy(slf)?.core.restore(&state.0).map_err(table_err)
    }
    /// The compensator it was built from (a copy, in the state it was given in).
    #[getter]
    fn compensator<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        shared(slf)?.source.bind(slf.py()).call_method0("__copy__")
    }
    fn __copy__(slf: &Bound<'_, Self>) -> PyResult<Self> {
        shared(slf)?.rebuilt(slf.py())
    }
    fn __deepcopy__(slf: &Bound<'_, Self>, _memo: &Bound<'_, PyAny>) -> PyResult<Self> {
        shared(slf)?.rebuilt(slf.py())
    }
    /// Pickled as its compensator, settings and state: an unpickled controller continues bit for bit.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let py = slf.py();
        let me = shared(slf)?;
        let s = me.settings;
        let args = (
            me.source.clone_ref(py),
            me.core.design().dt_s,
            (
                s.bandwidth_hz,
                s.noise_share,
                s.adaptation_time_s,
                s.fault_after,
                s.correction_limit_nmm,
                s.feedback,
                s.adaptation,
            ),
            words_to_bytes(py, &me.core.snapshot().to_words()),
        )
            .into_pyobject(py)?;
        let rebuild = py.import("bmr._core")?.getattr("_rebuild_controller")?;
        Ok((rebuild, args))
    }
    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let me = shared(slf)?;
        let d = me.core.design();
        Ok(format!(
            "Controller(dt_s={}, bandwidth_hz={:.4}, phase_margin_deg={:.2}, feedback={}, gain={:.6}, offset_nmm={:.4})",
            d.dt_s,
            d.bandwidth_hz,
            d.phase_margin_deg,
            if d.feedback { "True" } else { "False" },
            me.core.gain(),
            me.core.offset_nmm()
        ))
    }
}

/// Unpickle a `Controller`: rebuilt from its compensator and settings, then its state restored.
#[pyfunction]
#[allow(clippy::type_complexity)]
fn _rebuild_controller(
    py: Python<'_>,
    compensator: &Bound<'_, PyCompensator>,
    dt_s: f64,
    settings: &Bound<'_, PyAny>,
    state: &[u8],
) -> PyResult<PyController> {
    let settings: (f64, f64, f64, u32, f64, bool, bool) = settings.extract().map_err(|_| {
        BmrError::new_err(
            "Controller settings: expected (bandwidth_hz, noise_share, adaptation_time_s, fault_after, \
             correction_limit_nmm, feedback, adaptation)",
        )
    })?;
    let (
        bandwidth_hz,
        noise_share,
        adaptation_time_s,
        fault_after,
        correction_limit_nmm,
        feedback,
        adaptation,
    ) = settings;
    let settings = ControllerSettings {
        bandwidth_hz,
        noise_share,
        adaptation_time_s,
        fault_after,
        correction_limit_nmm,
        feedback,
        adaptation,
    };
    let mut c = PyController::build(py, compensator, Some(dt_s), settings)?;
    let words = bytes_to_words(state, "Controller")?;
    let s = c.core.state_from_words(&words).map_err(table_err)?;
    c.core.restore(&s).map_err(table_err)?;
    Ok(c)
}

/// The writable slices of freshly made (contiguous) numpy columns.
fn column_slices<'a, 'py, T: numpy::Element>(
    views: &'a mut [numpy::PyReadwriteArray1<'py, T>],
) -> PyResult<Vec<&'a mut [T]>> {
    views
        .iter_mut()
        .map(|v| {
            v.as_slice_mut()
                .map_err(|_| BmrError::new_err("column not contiguous"))
        })
        .collect()
}

/// The closed loop on a virtual actuator in one Rust loop: every sample the controller gets the reference, the
/// angle and the torque measured at the previous sample, and the actuator the command. Returns a dict of arrays
/// (`bmr.simulate_closed_loop` makes it a `ClosedLoopRun`).
#[pyfunction]
#[pyo3(signature = (controller, plant, reference_nmm, theta_rad=None))]
fn _simulate_closed_loop<'py>(
    py: Python<'py>,
    controller: &Bound<'py, PyController>,
    plant: &Bound<'py, PyVirtualActuator>,
    reference_nmm: &Bound<'py, PyAny>,
    theta_rad: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    // The reference column: a copy of the input (numpy's allocator, as the other columns), which the loop reads.
    let contiguous = reference_nmm.cast::<PyArray1<f64>>().ok().and_then(|a| {
        a.readonly()
            .as_slice()
            .ok()
            .map(|s| PyArray1::from_slice(py, s))
    });
    let ref_col = match contiguous {
        Some(c) => c,
        None => to_numpy(py, extract_f64_array(reference_nmm, "reference_nmm")?),
    };
    let ref_view = ref_col.readonly();
    let refs = ref_view
        .as_slice()
        .map_err(|_| BmrError::new_err("reference column not contiguous"))?;
    check(
        "samples in one closed-loop simulation",
        refs.len(),
        MAX_GENERATED_SAMPLES,
    )
    .map_err(limit_err)?;
    let plant = plant.get();
    // Without angles given, each sample's is the actuator's own, read as it turns (what `theta_ahead` would
    // give, without a second pass over the drive).
    let thetas = match theta_rad {
        Some(t) => {
            let t = extract_f64_array(t, "theta_rad")?;
            if t.len() != refs.len() {
                return Err(BmrError::new_err(format!(
                    "theta_rad has {} samples for {} reference samples",
                    t.len(),
                    refs.len()
                )));
            }
            Some(t)
        }
        None => None,
    };
    let n = refs.len();
    // The columns are numpy arrays from the start, each written once per sample (numpy's allocator gives long
    // columns huge pages: far fewer page faults than a zero-filled vector per column).
    const NAMES: [&str; 7] = [
        "t_s",
        "torque_nmm",
        "torque_true_nmm",
        "current_a",
        "correction_nmm",
        "gain",
        "offset_nmm",
    ];
    // SAFETY: every element is written below before the arrays reach Python.
    let floats: [Bound<'py, PyArray1<f64>>; 7] =
        std::array::from_fn(|_| unsafe { PyArray1::<f64>::new(py, n, false) });
    let flags: [Bound<'py, PyArray1<bool>>; 2] =
        std::array::from_fn(|_| unsafe { PyArray1::<bool>::new(py, n, false) });
    {
        let mut float_views: Vec<_> = floats.iter().map(|a| a.readwrite()).collect();
        let mut flag_views: Vec<_> = flags.iter().map(|a| a.readwrite()).collect();
        let mut cols = column_slices(&mut float_views)?;
        let mut bits = column_slices(&mut flag_views)?;
        let mut ctl = busy(controller)?;
        let ctl = &mut ctl.core;
        let mut sim = plant.sim()?;
        let sim = &mut *sim;
        py.detach(move || {
            let [t_s, torque, torque_true, current, correction, gain, offset] = &mut cols[..]
            else {
                unreachable!("seven float columns")
            };
            let [saturated, fault] = &mut bits[..] else {
                unreachable!("two flag columns")
            };
            run_closed_loop(ctl, sim, refs, thetas.as_deref(), |i, c, s, ctl| {
                t_s[i] = s.t_s;
                torque[i] = s.torque_nmm;
                torque_true[i] = s.torque_true_nmm;
                current[i] = c.current_a;
                correction[i] = ctl.correction_nmm();
                gain[i] = ctl.gain();
                offset[i] = ctl.offset_nmm();
                saturated[i] = c.saturated;
                fault[i] = c.fault;
            });
        });
    }
    let out = PyDict::new(py);
    let [t_s, rest @ ..] = floats;
    out.set_item(NAMES[0], t_s)?;
    drop(ref_view);
    out.set_item("reference_nmm", ref_col)?;
    for (name, a) in NAMES[1..].iter().zip(rest) {
        out.set_item(*name, a)?;
    }
    for (name, a) in ["saturated", "fault"].iter().zip(flags) {
        out.set_item(*name, a)?;
    }
    Ok(out)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyController>()?;
    m.add_class::<PyControllerDesign>()?;
    m.add_class::<PyControllerState>()?;
    m.add_function(wrap_pyfunction!(_rebuild_controller, m)?)?;
    m.add_function(wrap_pyfunction!(_simulate_closed_loop, m)?)?;
    Ok(())
}
