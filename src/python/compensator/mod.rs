//! `bmr.Compensator`: hysteresis + friction compensation for one control loop (optionally extended by a model's
//! stages). One file per aspect: the command it returns (`command`), building it from parts and extension
//! entries (`build`), offline runs (`run`), snapshots and pickles (`state`), the forward chain it inverts
//! (`extended_simulation`) and firmware export (`export`).
mod build;
pub(crate) mod command;
mod export;
mod extended_simulation;
mod run;
mod state;

use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

use crate::compensator::{Command, Compensator};
use crate::friction::{Friction, MAX_ORDER};
use crate::python::friction::PyFriction;
use crate::python::hysteresis::{MEMORY, PyHysteresis, initial_or_negative};
use crate::python::{BmrError, table_err};
use crate::stages::Stages;
use crate::vocabulary::{EffectKind, Params, loop_stages};

use build::extensions_to_py;
pub(crate) use build::parse_extensions;
use command::CommandSlots;
use state::{PyCompensatorState, StateData};

type Core = Compensator<Vec<f64>, MEMORY, MAX_ORDER>;
// Exported firmware remembers as much as the Python operators: the same commands, bit for bit.
const _: () = assert!(MEMORY == crate::model_data::MEMORY);

/// Open-loop torque compensator: `I = H⁻¹[T_ref − T_f(θ)]`, coil split, current limit, converter voltages;
/// optionally extended by a diagnosed model's stages (`extensions`, see `bmr.effect_parameters()`).
#[pyclass(name = "Compensator", module = "bmr")]
pub(crate) struct PyCompensator {
    core: Core,
    inverse: &'static str,
    /// What the compensator was built from (for copies, pickles and the repr).
    hysteresis: PyHysteresis,
    base_friction: Friction<MAX_ORDER>,
    extensions: Vec<Params>,
    dt_s: Option<f64>,
    full_torque_nmm: f64,
    /// The `Command` objects `step` hands out again.
    commands: CommandSlots,
}

impl PyCompensator {
    /// The Rust compensator (the closed-loop controller starts from a copy of it).
    pub(crate) fn core(&self) -> &Core {
        &self.core
    }
    /// Control period the stages were built for (s), None without extensions.
    pub(crate) fn control_period_s(&self) -> Option<f64> {
        self.dt_s
    }
}

/// Borrow `slf` (an `InUseError` while another thread is inside its `run`).
pub(super) fn busy<'py>(slf: &Bound<'py, PyCompensator>) -> PyResult<PyRefMut<'py, PyCompensator>> {
    crate::python::borrow_mut(slf)
}

pub(super) fn shared<'py>(slf: &Bound<'py, PyCompensator>) -> PyResult<PyRef<'py, PyCompensator>> {
    crate::python::borrow(slf)
}

#[pymethods]
impl PyCompensator {
    /// `hysteresis`: the current→torque operator (N·mm without friction); `friction`: seal friction (optional);
    /// `inverse`: "exact" or "paper"; `converter_gain` in A/V; `current_limit` in A; `initial`: start state of the
    /// memory (default after negative saturation). `extensions`: a model's extension entries
    /// (`[{"name": ..., "params": {...}}]`, see `bmr.effect_parameters()`) made into compensator stages at control
    /// period `dt_s`; `full_torque_nmm`: the output map's full scale when its `scale_nmm` is 0 (default: the
    /// largest |torque| of `hysteresis`). `Compensator.from_model` builds all of it from a model file.
    #[new]
    #[pyo3(signature = (hysteresis, friction=None, *, inverse="exact", converter_gain=0.125, current_limit=1.25,
                        initial=None, extensions=None, dt_s=None, full_torque_nmm=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        hysteresis: PyRef<'_, PyHysteresis>,
        friction: Option<PyRef<'_, PyFriction>>,
        inverse: &str,
        converter_gain: f64,
        current_limit: f64,
        initial: Option<&Bound<'_, PyAny>>,
        extensions: Option<&Bound<'_, PyAny>>,
        dt_s: Option<f64>,
        full_torque_nmm: Option<f64>,
    ) -> PyResult<Self> {
        let initial = initial_or_negative(initial)?;
        let friction = friction.map_or(Friction::zero(), |f| f.f);
        let ext = parse_extensions(extensions)?;
        let mut c = Self::build(
            PyHysteresis {
                op: hysteresis.op.clone(),
                report: None,
            },
            friction,
            inverse,
            converter_gain,
            current_limit,
            ext,
            dt_s,
            full_torque_nmm,
        )?;
        c.core.reset(initial);
        Ok(c)
    }

    /// One control period: reference torque (N·mm) and rotor angle (rad) → `Command`. Never raises: a NaN/inf
    /// input gives zero current with `fault=True`. With a `time_delay` stage the reference `delay` ahead is
    /// predicted; use `step_ahead` when it is known.
    fn step(slf: &Bound<'_, Self>, torque_ref_nmm: f64, theta_rad: f64) -> PyResult<Py<Command>> {
        let mut me = busy(slf)?;
        let c = me.core.step(torque_ref_nmm, theta_rad);
        me.commands.give(slf.py(), c)
    }

    /// One control period given the reference torque and angle of the sample the command acts on
    /// (`preview_samples` ahead of now; the same as `step` without a `time_delay` stage).
    fn step_ahead(
        slf: &Bound<'_, Self>,
        torque_ref_ahead_nmm: f64,
        theta_ahead_rad: f64,
    ) -> PyResult<Py<Command>> {
        let mut me = busy(slf)?;
        let c = me.core.step_ahead(torque_ref_ahead_nmm, theta_ahead_rad);
        me.commands.give(slf.py(), c)
    }

    /// `step` without creating a `Command`: writes `current_a, coil1_a, coil2_a, volt1_v, volt2_v, saturated,
    /// fault` (flags as 0.0/1.0) into `out` (a float64 array of at least 7 elements) and returns the current (A).
    fn step_into(
        slf: &Bound<'_, Self>,
        torque_ref_nmm: f64,
        theta_rad: f64,
        out: &Bound<'_, PyAny>,
    ) -> PyResult<f64> {
        let bad = || {
            BmrError::new_err(
                "step_into: out must be a writeable, contiguous float64 array of at least 7 elements",
            )
        };
        let arr = out.cast::<PyArray1<f64>>().map_err(|_| bad())?;
        // SAFETY: a raw read of the array's flags field.
        let writeable =
            unsafe { (*arr.as_array_ptr()).fields.flags } & numpy::npyffi::NPY_ARRAY_WRITEABLE != 0;
        if !(writeable && arr.is_contiguous() && arr.len() >= 7) {
            return Err(bad());
        }
        let c = busy(slf)?.core.step(torque_ref_nmm, theta_rad);
        // SAFETY: checked writeable and contiguous; the GIL is held and nothing else runs while we write (numpy's
        // borrow tracking is skipped on purpose: it costs more than the step).
        let o = unsafe { arr.as_slice_mut() }.map_err(|_| bad())?;
        o[..7].copy_from_slice(&[
            c.current_a,
            c.coil1_a,
            c.coil2_a,
            c.volt1_v,
            c.volt2_v,
            f64::from(u8::from(c.saturated)),
            f64::from(u8::from(c.fault)),
        ]);
        Ok(c.current_a)
    }

    /// Offline run over arrays of one length: a dict of arrays with the `Command` fields plus `model_torque_nmm`
    /// (the model's torque with friction for the command). The reference is known in advance: with a
    /// `time_delay` stage each sample is commanded on the reference `delay` later (`step_ahead`).
    /// `columns`: the names to compute (default all); `out`: a dict of preallocated arrays (float64, bool for
    /// the flags) of the run's length, filled in place and returned.
    #[pyo3(signature = (torque_ref_nmm, theta_rad, *, columns=None, out=None))]
    fn run<'py>(
        slf: &Bound<'py, Self>,
        torque_ref_nmm: &Bound<'py, PyAny>,
        theta_rad: &Bound<'py, PyAny>,
        columns: Option<Vec<String>>,
        out: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        run::run(slf, torque_ref_nmm, theta_rad, columns, out)
    }

    /// Forget the memory and start from `initial` (default: after negative saturation); stages back to rest.
    #[pyo3(signature = (initial=None))]
    fn reset(slf: &Bound<'_, Self>, initial: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let initial = initial_or_negative(initial)?;
        busy(slf)?.core.reset(initial);
        Ok(())
    }

    /// A copy of the memory and stage states (restore it with `restore`).
    fn snapshot(slf: &Bound<'_, Self>) -> PyResult<PyCompensatorState> {
        Ok(PyCompensatorState(StateData::Live(Box::new(
            shared(slf)?.core.snapshot(),
        ))))
    }

    /// Return to a snapshot of this compensator (or of one with identical tables and stages).
    fn restore(slf: &Bound<'_, Self>, state: &PyCompensatorState) -> PyResult<()> {
        let mut me = busy(slf)?;
        let s = match &state.0 {
            StateData::Live(s) => **s,
            StateData::Words(w) => me.core.state_from_words(w).map_err(table_err)?,
        };
        me.core.restore(&s).map_err(table_err)
    }

    /// Pickled as its parts (tables, friction, inverse, gain, limit, extensions, control period) and its state:
    /// an unpickled compensator continues bit for bit.
    #[allow(clippy::type_complexity)]
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        state::reduce(slf)
    }

    /// "exact" or "paper".
    #[getter]
    fn inverse(slf: &Bound<'_, Self>) -> PyResult<&'static str> {
        Ok(shared(slf)?.inverse)
    }
    /// Converter gain (A/V).
    #[getter]
    fn converter_gain(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(shared(slf)?.core.gain_a_per_v())
    }
    /// Current limit (A).
    #[getter]
    fn current_limit(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(shared(slf)?.core.limit_a())
    }
    /// Control period the stages were built for (s), None without extensions.
    #[getter]
    fn dt_s(slf: &Bound<'_, Self>) -> PyResult<Option<f64>> {
        Ok(shared(slf)?.dt_s)
    }
    /// Forward-model torque (N·mm, at the hysteretic core, without friction) for the last command.
    #[getter]
    fn predicted_torque_nmm(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(shared(slf)?.core.predicted_torque())
    }
    /// Samples the reference is taken ahead by (`time_delay`; 0 without it).
    #[getter]
    fn preview_samples(slf: &Bound<'_, Self>) -> PyResult<usize> {
        Ok(shared(slf)?.core.preview_samples())
    }
    /// The extension entries the compensator was built with (`[{"name", "params"}]`).
    #[getter]
    fn extensions<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyList>> {
        extensions_to_py(slf.py(), &shared(slf)?.extensions)
    }
    /// Names of the stages that are on, in the order the physics acts.
    #[getter]
    fn stages(slf: &Bound<'_, Self>) -> PyResult<Vec<&'static str>> {
        let me = shared(slf)?;
        let st = me.core.stages();
        // Effects without a stage of their own (a friction term) are on when given.
        let given = |k: EffectKind| me.extensions.iter().any(|p| p.spec.name == k.name());
        Ok(loop_stages()
            .filter_map(|s| EffectKind::from_name(s.name))
            .filter(|&k| {
                if Stages::KINDS.contains(&k) {
                    st.has(k)
                } else {
                    given(k)
                }
            })
            .map(EffectKind::name)
            .collect())
    }
    /// A copy of the forward operator in its current state.
    #[getter]
    fn hysteresis(slf: &Bound<'_, Self>) -> PyResult<PyHysteresis> {
        Ok(PyHysteresis {
            op: shared(slf)?.core.forward().clone(),
            report: None,
        })
    }
    /// The friction model of the feedforward (with any extra harmonic and current gain of the extensions).
    #[getter]
    fn friction(slf: &Bound<'_, Self>) -> PyResult<PyFriction> {
        Ok(PyFriction {
            f: *shared(slf)?.core.friction(),
        })
    }
    fn __copy__(slf: &Bound<'_, Self>) -> PyResult<Self> {
        shared(slf)?.rebuilt()
    }
    fn __deepcopy__(slf: &Bound<'_, Self>, _memo: &Bound<'_, PyAny>) -> PyResult<Self> {
        shared(slf)?.rebuilt()
    }
    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let me = shared(slf)?;
        let names: Vec<&str> = me.extensions.iter().map(|p| p.spec.name).collect();
        Ok(format!(
            "Compensator(inverse={:?}, converter_gain={}, current_limit={}, friction_order={}, extensions={:?})",
            me.inverse,
            me.core.gain_a_per_v(),
            me.core.limit_a(),
            me.core.friction().order(),
            names
        ))
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(build::check_extensions, m)?)?;
    m.add_function(wrap_pyfunction!(export::export_source, m)?)?;
    m.add_function(wrap_pyfunction!(state::_rebuild_compensator, m)?)?;
    m.add_function(wrap_pyfunction!(state::_rebuild_compensator_state, m)?)?;
    m.add_function(wrap_pyfunction!(extended_simulation::output_map, m)?)?;
    m.add_function(wrap_pyfunction!(
        extended_simulation::output_map_inverse,
        m
    )?)?;
    m.add_class::<PyCompensator>()?;
    m.add_class::<Command>()?;
    m.add_class::<state::PyCompensatorState>()?;
    m.add_class::<extended_simulation::PySimulation>()?;
    Ok(())
}
