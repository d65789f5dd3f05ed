//! `bmr.Compensator`: hysteresis + friction compensation for one control loop (optionally extended by a model's
//! stages), its `Command`, and `bmr.ExtendedSimulation`, the forward chain the extended compensator inverts.
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyMapping, PyTuple};

use crate::cbh::Initial;
use crate::compensator::{Command, Compensator, CompensatorState, InverseKind};
use crate::friction::{Friction, MAX_ORDER};
use crate::model_data::{EffectValues, ModelData};
use crate::python::arrays::{DETACH_LEN, extract_f64_array, to_numpy};
use crate::python::friction::PyFriction;
use crate::python::hysteresis::{MEMORY, PyHysteresis, initial_or_negative};
use crate::python::{BmrError, bmr_err, bytes_to_words, table_err, words_to_bytes};
use crate::simulation::Simulation;
use crate::stages::{OutputMap, Scales};
use crate::vocabulary::{NameList, Params, SPECS, extension_spec};

type Core = Compensator<Vec<f64>, MEMORY, MAX_ORDER>;
// Exported firmware remembers as much as the Python operators: the same commands, bit for bit.
const _: () = assert!(MEMORY == crate::model_data::MEMORY);
type Sim = Simulation<Vec<f64>, Vec<f64>, MEMORY, MAX_ORDER>;

/// One control-period command: nominal current, coil currents (A), converter voltages (V) and flags.
#[pyclass(name = "Command", module = "bmr", frozen, get_all, eq)]
#[derive(Clone, PartialEq)]
pub(crate) struct PyCommand {
    /// Nominal current (A): negative drives coil 1, positive coil 2.
    current_a: f64,
    /// Coil 1 current (A, ≥ 0).
    coil1_a: f64,
    /// Coil 2 current (A, ≥ 0).
    coil2_a: f64,
    /// Converter 1 input voltage (V).
    volt1_v: f64,
    /// Converter 2 input voltage (V).
    volt2_v: f64,
    /// The torque asked for was not reachable (input range or current limit).
    saturated: bool,
    /// The reference or angle (or an intermediate) was not finite: zero current commanded.
    fault: bool,
}

#[pymethods]
impl PyCommand {
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
        PyCommand {
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
        self.clone()
    }
    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
        self.clone()
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

impl From<Command> for PyCommand {
    fn from(c: Command) -> Self {
        PyCommand {
            current_a: c.current_a,
            coil1_a: c.coil1_a,
            coil2_a: c.coil2_a,
            volt1_v: c.volt1_v,
            volt2_v: c.volt2_v,
            saturated: c.saturated,
            fault: c.fault,
        }
    }
}

/// Snapshot of a Compensator's memory and stage states (restore it into the compensator it came from, or a copy
/// or unpickled copy of it).
#[pyclass(name = "CompensatorState", module = "bmr", frozen)]
#[derive(Clone)]
pub(crate) struct PyCompensatorState(StateData);

/// A snapshot taken here, or unpickled words (checked against the tables when restored).
#[derive(Clone)]
pub(crate) enum StateData {
    Live(Box<CompensatorState<MEMORY>>),
    Words(Vec<u64>),
}

#[pymethods]
impl PyCompensatorState {
    fn __copy__(&self) -> Self {
        self.clone()
    }
    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
        self.clone()
    }
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, pyo3::types::PyBytes>,))> {
        let words = match &self.0 {
            StateData::Live(s) => s.to_words(),
            StateData::Words(w) => w.clone(),
        };
        let rebuild = py
            .import("bmr._core")?
            .getattr("_rebuild_compensator_state")?;
        Ok((rebuild, (words_to_bytes(py, &words),)))
    }
}

/// Unpickle a `CompensatorState` (checked against the compensator when it is restored).
#[pyfunction]
fn _rebuild_compensator_state(state: &[u8]) -> PyResult<PyCompensatorState> {
    Ok(PyCompensatorState(StateData::Words(bytes_to_words(
        state,
        "CompensatorState",
    )?)))
}

/// Unpickle a `Compensator`: rebuilt from its parts, then its state restored.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn _rebuild_compensator(
    hysteresis: PyRef<'_, PyHysteresis>,
    friction: PyRef<'_, PyFriction>,
    inverse: &str,
    converter_gain: f64,
    current_limit: f64,
    extensions: &Bound<'_, PyAny>,
    dt_s: Option<f64>,
    full_torque_nmm: f64,
    state: &[u8],
) -> PyResult<PyCompensator> {
    let ext = parse_extensions(Some(extensions))?;
    let mut c = PyCompensator::build(
        PyHysteresis {
            op: hysteresis.op.clone(),
            report: None,
        },
        friction.f,
        inverse,
        converter_gain,
        current_limit,
        ext,
        dt_s,
        Some(full_torque_nmm),
    )?;
    let words = bytes_to_words(state, "Compensator")?;
    let s = c.core.state_from_words(&words).map_err(table_err)?;
    c.core.restore(&s).map_err(table_err)?;
    Ok(c)
}

/// Parse `extensions`: a sequence of `{"name": str, "params": {param: value}}` (other keys are ignored, e.g. a
/// model file's tables) or `(name, params)` pairs. Unknown names and parameters are errors naming the valid ones.
pub(crate) fn parse_extensions(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<Params>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(Vec::new());
    };
    let items = obj.try_iter().map_err(|_| {
        PyTypeError::new_err(
            "extensions must be a sequence of {\"name\": ..., \"params\": {...}} entries",
        )
    })?;
    let mut out = Vec::new();
    for (i, item) in items.enumerate() {
        let item = item?;
        let (name, params): (String, Option<Bound<'_, PyAny>>) = if let Ok(m) =
            item.cast::<PyMapping>()
        {
            let name = m
                .get_item("name")
                .map_err(|_| BmrError::new_err(format!("extensions[{i}] has no 'name'")))?;
            let name: String = name.extract().map_err(|_| {
                BmrError::new_err(format!("extensions[{i}]: 'name' must be a string"))
            })?;
            let params = m.get_item("params").ok().filter(|p| !p.is_none());
            (name, params)
        } else if let Ok((name, params)) = item.extract::<(String, Bound<'_, PyAny>)>() {
            (name, Some(params).filter(|p| !p.is_none()))
        } else {
            return Err(BmrError::new_err(format!(
                "extensions[{i}] must be {{\"name\": ..., \"params\": {{...}}}} or a (name, params) pair"
            )));
        };
        let Some(spec) = extension_spec(&name) else {
            return Err(BmrError::new_err(format!(
                "unknown model extension {name:?}; known: {}, core_tables, table_resolution, offset",
                NameList(SPECS)
            )));
        };
        let mut given: Vec<(String, f64)> = Vec::new();
        if let Some(p) = params {
            let p = p.cast::<PyDict>().map_err(|_| {
                BmrError::new_err(format!("extension {name}: 'params' must be a dict"))
            })?;
            for (k, v) in p.iter() {
                let k: String = k.extract().map_err(|_| {
                    BmrError::new_err(format!("extension {name}: parameter names must be strings"))
                })?;
                let v: f64 = v.extract().map_err(|_| {
                    BmrError::new_err(format!("extension {name}: {k} = {v} is not a number"))
                })?;
                given.push((k, v));
            }
        }
        let refs: Vec<(&str, f64)> = given.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        out.push(Params::new(spec, &refs).map_err(bmr_err)?);
    }
    Ok(out)
}

fn extensions_to_py<'py>(py: Python<'py>, ext: &[Params]) -> PyResult<Bound<'py, PyList>> {
    let items = ext
        .iter()
        .map(|p| {
            let d = PyDict::new(py);
            d.set_item("name", p.spec.name)?;
            let params = PyDict::new(py);
            for (k, v) in p.iter() {
                params.set_item(k, v)?;
            }
            d.set_item("params", params)?;
            Ok(d)
        })
        .collect::<PyResult<Vec<_>>>()?;
    PyList::new(py, items)
}

/// The columns `run` can return, in order: floats then flags.
const COLUMNS: [&str; 8] = [
    "current_a",
    "coil1_a",
    "coil2_a",
    "volt1_v",
    "volt2_v",
    "model_torque_nmm",
    "saturated",
    "fault",
];
const FLOAT_COLUMNS: usize = 6;

fn column_value(c: &Command, core: &Core, col: usize) -> f64 {
    match col {
        0 => c.current_a,
        1 => c.coil1_a,
        2 => c.coil2_a,
        3 => c.volt1_v,
        4 => c.volt2_v,
        _ => core.model_torque_nmm(),
    }
}

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
}

/// Borrow `slf` (an `InUseError` while another thread is inside its `run`).
fn busy<'py>(slf: &Bound<'py, PyCompensator>) -> PyResult<PyRefMut<'py, PyCompensator>> {
    crate::python::borrow_mut(slf)
}

fn shared<'py>(slf: &Bound<'py, PyCompensator>) -> PyResult<PyRef<'py, PyCompensator>> {
    crate::python::borrow(slf)
}

/// A float64 argument as a slice: a contiguous float64 array is read in place, anything else is converted
/// (`TypeError` naming the argument for non-numbers).
enum Floats<'py> {
    Borrowed(numpy::PyReadonlyArray1<'py, f64>),
    Owned(Vec<f64>),
}

impl<'py> Floats<'py> {
    fn of(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<Self> {
        if let Ok(a) = obj.cast::<PyArray1<f64>>()
            && a.is_contiguous()
        {
            return Ok(Floats::Borrowed(a.readonly()));
        }
        Ok(Floats::Owned(extract_f64_array(obj, what)?))
    }
    fn slice(&self) -> &[f64] {
        match self {
            Floats::Borrowed(a) => a.as_slice().unwrap_or(&[]),
            Floats::Owned(v) => v,
        }
    }
}

impl PyCompensator {
    #[allow(clippy::too_many_arguments)]
    fn build(
        hysteresis: PyHysteresis,
        friction: Friction<MAX_ORDER>,
        inverse: &str,
        converter_gain: f64,
        current_limit: f64,
        extensions: Vec<Params>,
        dt_s: Option<f64>,
        full_torque_nmm: Option<f64>,
    ) -> PyResult<Self> {
        let forward = hysteresis.op.clone();
        let (kind, name) = match inverse {
            "exact" => (InverseKind::Exact, "exact"),
            "paper" => (
                InverseKind::Paper(forward.paper_inverse().map_err(|e| {
                    BmrError::new_err(format!(
                        "cannot build the paper's inverse from these tables: {e}"
                    ))
                })?),
                "paper",
            ),
            other => {
                return Err(BmrError::new_err(format!(
                    "inverse={other:?}: expected 'exact' or 'paper'"
                )));
            }
        };
        let (ylo, yhi) = forward.output_range();
        let full_torque_nmm = full_torque_nmm.unwrap_or(ylo.abs().max(yhi.abs()));
        let mut core =
            Core::new(forward, kind, friction, converter_gain, current_limit).map_err(bmr_err)?;
        if !extensions.is_empty() {
            let dt = match dt_s {
                Some(dt) => dt,
                None if extensions.iter().all(|p| {
                    // Effects that need no sample period: friction terms, the sensor, model-file entries.
                    !matches!(
                        p.spec.name,
                        "coil_lag" | "time_delay" | "thermal_drift" | "friction_current"
                    )
                }) =>
                {
                    1.0
                }
                None => {
                    return Err(BmrError::new_err(
                        "extensions with coil_lag, time_delay, thermal_drift or friction_current need dt_s (the control period, s)",
                    ));
                }
            };
            core = core
                .with_extensions(&extensions, dt, full_torque_nmm)
                .map_err(bmr_err)?;
        }
        Ok(PyCompensator {
            core,
            inverse: name,
            hysteresis,
            base_friction: friction,
            extensions,
            dt_s,
            full_torque_nmm,
        })
    }

    fn rebuilt(&self) -> PyResult<Self> {
        let mut c = Self::build(
            PyHysteresis {
                op: self.hysteresis.op.clone(),
                report: None,
            },
            self.base_friction,
            self.inverse,
            self.core.gain_a_per_v(),
            self.core.limit_a(),
            self.extensions.clone(),
            self.dt_s,
            Some(self.full_torque_nmm),
        )?;
        c.core.restore(&self.core.snapshot()).map_err(bmr_err)?;
        Ok(c)
    }
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

    /// The full (extended) compensator of a model: a `bmr.Model` or the path of a model file
    /// (`Model.compensator(dt_s=..., **kwargs)`).
    #[staticmethod]
    #[pyo3(signature = (model, *, dt_s, **kwargs))]
    fn from_model<'py>(
        py: Python<'py>,
        model: &Bound<'py, PyAny>,
        dt_s: f64,
        kwargs: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let model_cls = py.import("bmr")?.getattr("Model")?;
        let model = if model.is_instance(&model_cls)? {
            model.clone()
        } else if model.is_instance_of::<pyo3::types::PyString>() || model.hasattr("__fspath__")? {
            model_cls.call_method1("load", (model,))?
        } else {
            return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "model: expected a bmr.Model or the path of a model file, got {}",
                model.get_type().name()?
            )));
        };
        let kw = PyDict::new(py);
        if let Some(k) = kwargs {
            kw.update(k.as_mapping())?;
        }
        kw.set_item("dt_s", dt_s)?;
        model.call_method("compensator", (), Some(&kw))
    }

    /// One control period: reference torque (N·mm) and rotor angle (rad) → `Command`. Never raises: a NaN/inf
    /// input gives zero current with `fault=True`. With a `time_delay` stage the reference `delay` ahead is
    /// predicted; use `step_ahead` when it is known.
    fn step(slf: &Bound<'_, Self>, torque_ref_nmm: f64, theta_rad: f64) -> PyResult<PyCommand> {
        Ok(busy(slf)?.core.step(torque_ref_nmm, theta_rad).into())
    }

    /// One control period given the reference torque and angle of the sample the command acts on
    /// (`preview_samples` ahead of now; the same as `step` without a `time_delay` stage).
    fn step_ahead(
        slf: &Bound<'_, Self>,
        torque_ref_ahead_nmm: f64,
        theta_ahead_rad: f64,
    ) -> PyResult<PyCommand> {
        Ok(busy(slf)?
            .core
            .step_ahead(torque_ref_ahead_nmm, theta_ahead_rad)
            .into())
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
        let py = slf.py();
        let ref_in = Floats::of(torque_ref_nmm, "torque_ref_nmm")?;
        let th_in = Floats::of(theta_rad, "theta_rad")?;
        let n = ref_in.slice().len();
        if n != th_in.slice().len() {
            return Err(BmrError::new_err(format!(
                "run: torque_ref_nmm has {n} samples but theta_rad has {}",
                th_in.slice().len()
            )));
        }
        let wanted: Vec<usize> = match &columns {
            None => (0..COLUMNS.len()).collect(),
            Some(names) => names
                .iter()
                .map(|c| {
                    COLUMNS.iter().position(|k| k == c).ok_or_else(|| {
                        BmrError::new_err(format!(
                            "run: unknown column {c:?}; columns: {}",
                            COLUMNS.join(", ")
                        ))
                    })
                })
                .collect::<PyResult<_>>()?,
        };
        let result = PyDict::new(py);
        let mut floats: Vec<(usize, Bound<'py, PyArray1<f64>>)> = Vec::new();
        let mut flags: Vec<(usize, Bound<'py, PyArray1<bool>>)> = Vec::new();
        for &col in &wanted {
            let name = COLUMNS[col];
            let given = match out {
                Some(o) => o.get_item(name)?,
                None => None,
            };
            if col < FLOAT_COLUMNS {
                let arr = match given {
                    Some(a) => a.cast_into::<PyArray1<f64>>().map_err(|_| {
                        BmrError::new_err(format!("run: out[{name:?}] must be a 1-D float64 array"))
                    })?,
                    None => unsafe { PyArray1::<f64>::new(py, n, false) },
                };
                floats.push((col, arr));
            } else {
                let arr = match given {
                    Some(a) => a.cast_into::<PyArray1<bool>>().map_err(|_| {
                        BmrError::new_err(format!("run: out[{name:?}] must be a 1-D bool array"))
                    })?,
                    None => unsafe { PyArray1::<bool>::new(py, n, false) },
                };
                flags.push((col, arr));
            }
        }
        let mut float_views = Vec::with_capacity(floats.len());
        for (col, a) in &floats {
            let v = a.try_readwrite().map_err(|_| {
                BmrError::new_err(format!("run: out[{:?}] is not writeable", COLUMNS[*col]))
            })?;
            float_views.push((*col, v));
        }
        let mut flag_views = Vec::with_capacity(flags.len());
        for (col, a) in &flags {
            let v = a.try_readwrite().map_err(|_| {
                BmrError::new_err(format!("run: out[{:?}] is not writeable", COLUMNS[*col]))
            })?;
            flag_views.push((*col, v));
        }
        let mut float_slices: Vec<(usize, &mut [f64])> = Vec::with_capacity(floats.len());
        for (col, v) in float_views.iter_mut() {
            let s = v.as_slice_mut().map_err(|_| {
                BmrError::new_err(format!("run: out[{:?}] must be contiguous", COLUMNS[*col]))
            })?;
            if s.len() != n {
                return Err(BmrError::new_err(format!(
                    "run: out[{:?}] has {} elements, the run {n}",
                    COLUMNS[*col],
                    s.len()
                )));
            }
            float_slices.push((*col, s));
        }
        let mut flag_slices: Vec<(usize, &mut [bool])> = Vec::with_capacity(flags.len());
        for (col, v) in flag_views.iter_mut() {
            let s = v.as_slice_mut().map_err(|_| {
                BmrError::new_err(format!("run: out[{:?}] must be contiguous", COLUMNS[*col]))
            })?;
            if s.len() != n {
                return Err(BmrError::new_err(format!(
                    "run: out[{:?}] has {} elements, the run {n}",
                    COLUMNS[*col],
                    s.len()
                )));
            }
            flag_slices.push((*col, s));
        }
        let (refs, th) = (ref_in.slice(), th_in.slice());
        {
            let mut me = busy(slf)?;
            let core = &mut me.core;
            let mut work = move || {
                let current_only =
                    float_slices.len() == 1 && float_slices[0].0 == 0 && flag_slices.is_empty();
                if current_only {
                    let out = &mut *float_slices[0].1;
                    core.run_with(refs, th, |i, c, _| out[i] = c.current_a);
                    return;
                }
                core.run_with(refs, th, |i, c, core| {
                    for (col, s) in float_slices.iter_mut() {
                        s[i] = column_value(&c, core, *col);
                    }
                    for (col, s) in flag_slices.iter_mut() {
                        s[i] = if *col == FLOAT_COLUMNS {
                            c.saturated
                        } else {
                            c.fault
                        };
                    }
                });
            };
            if n > DETACH_LEN {
                py.detach(work);
            } else {
                work();
            }
        }
        drop(float_views);
        drop(flag_views);
        for (col, a) in floats {
            result.set_item(COLUMNS[col], a)?;
        }
        for (col, a) in flags {
            result.set_item(COLUMNS[col], a)?;
        }
        Ok(result)
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
        let py = slf.py();
        let me = shared(slf)?;
        let hysteresis = Bound::new(
            py,
            PyHysteresis {
                op: me.hysteresis.op.clone(),
                report: None,
            },
        )?;
        let friction = Bound::new(
            py,
            PyFriction {
                f: me.base_friction,
            },
        )?;
        let args = (
            hysteresis,
            friction,
            me.inverse,
            me.core.gain_a_per_v(),
            me.core.limit_a(),
            extensions_to_py(py, &me.extensions)?,
            me.dt_s,
            me.full_torque_nmm,
            words_to_bytes(py, &me.core.snapshot().to_words()),
        )
            .into_pyobject(py)?;
        let rebuild = py.import("bmr._core")?.getattr("_rebuild_compensator")?;
        Ok((rebuild, args))
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
        let f = me.core.friction();
        let has = |n: &str| me.extensions.iter().any(|p| p.spec.name == n);
        let mut out = Vec::new();
        if st.time_delay.is_some() {
            out.push("time_delay");
        }
        if st.coil_lag.is_some() {
            out.push("coil_lag");
        }
        if st.output_map.is_some() {
            out.push("non_congruent");
        }
        if st.thermal.is_some() {
            out.push("thermal_drift");
        }
        if st.ripple.is_some() {
            out.push("torque_ripple");
        }
        if has("friction_harmonics") {
            out.push("friction_harmonics");
        }
        if f.gain_per_a() != 0.0 {
            out.push("friction_current");
        }
        Ok(out)
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

/// The forward chain of a model with its extensions: commanded current and rotor angle → torque (see
/// `bmr.effect_parameters()`); the very stages the extended `Compensator` inverts.
#[pyclass(name = "ExtendedSimulation", module = "bmr")]
pub(crate) struct PySimulation {
    sim: Sim,
}

#[pymethods]
impl PySimulation {
    /// `hysteresis` (the core's tables), `friction`, the model's `extensions` at sample period `dt_s`;
    /// `full_current_a`: current of unit heating (A); `full_torque_nmm`: the output map's full scale when its
    /// `scale_nmm` is 0 (default: the largest |torque| of `hysteresis`).
    #[new]
    #[pyo3(signature = (hysteresis, friction=None, *, extensions=None, dt_s, full_current_a, full_torque_nmm=None))]
    fn new(
        hysteresis: PyRef<'_, PyHysteresis>,
        friction: Option<PyRef<'_, PyFriction>>,
        extensions: Option<&Bound<'_, PyAny>>,
        dt_s: f64,
        full_current_a: f64,
        full_torque_nmm: Option<f64>,
    ) -> PyResult<Self> {
        let ext = parse_extensions(extensions)?;
        let core = hysteresis.op.clone();
        let (ylo, yhi) = core.output_range();
        let scales = Scales::of_core(
            &core,
            full_current_a,
            full_torque_nmm.unwrap_or(ylo.abs().max(yhi.abs())),
        );
        let friction = friction.map_or(Friction::zero(), |f| f.f);
        let sim =
            Sim::new(core, friction, &ext, dt_s, scales, |n| vec![0.0; n]).map_err(bmr_err)?;
        Ok(PySimulation { sim })
    }

    /// Simulate commanded currents (A) at rotor angles (rad), from `initial` (default after negative
    /// saturation), heating state `heating` and drift clock `t0_s` (s): a dict of `coil_current_a,
    /// field_current_a, core_nmm, field_torque_nmm, friction_nmm, torque_nmm, measured_nmm` arrays.
    #[pyo3(signature = (current_a, theta_rad, *, initial=None, heating=0.0, t0_s=0.0))]
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        current_a: &Bound<'py, PyAny>,
        theta_rad: &Bound<'py, PyAny>,
        initial: Option<&Bound<'_, PyAny>>,
        heating: f64,
        t0_s: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let initial: Initial = initial_or_negative(initial)?;
        let u = extract_f64_array(current_a, "current_a")?;
        let th = extract_f64_array(theta_rad, "theta_rad")?;
        if u.len() != th.len() {
            return Err(BmrError::new_err(format!(
                "run: current_a has {} samples but theta_rad has {}",
                u.len(),
                th.len()
            )));
        }
        if let Some(i) = u.iter().position(|v| !v.is_finite()) {
            return Err(BmrError::new_err(format!(
                "run: current sample {i} is not finite ({})",
                u[i]
            )));
        }
        if !(heating.is_finite() && t0_s.is_finite()) {
            return Err(BmrError::new_err("run: heating and t0_s must be finite"));
        }
        let sim = &mut self.sim;
        let n = u.len();
        let mut work = move || {
            sim.reset(initial, heating, t0_s);
            let mut cols: [Vec<f64>; 7] = core::array::from_fn(|_| Vec::with_capacity(n));
            for (&c, &a) in u.iter().zip(&th) {
                let s = sim.step(c, a);
                for (col, v) in cols.iter_mut().zip([
                    s.coil_current_a,
                    s.field_current_a,
                    s.core_nmm,
                    s.field_torque_nmm,
                    s.friction_nmm,
                    s.torque_nmm,
                    s.measured_nmm,
                ]) {
                    col.push(v);
                }
            }
            cols
        };
        let cols = if n > DETACH_LEN {
            py.detach(work)
        } else {
            work()
        };
        let d = PyDict::new(py);
        let names = [
            "coil_current_a",
            "field_current_a",
            "core_nmm",
            "field_torque_nmm",
            "friction_nmm",
            "torque_nmm",
            "measured_nmm",
        ];
        for (name, col) in names.into_iter().zip(cols) {
            d.set_item(name, to_numpy(py, col))?;
        }
        Ok(d)
    }
}

/// Firmware source of `compensator` (exact inverse): `language` "rust" (static tables and `compensator(dt_s)` for
/// the no_std crate) or "c" (arrays and a `BmrModel` named `<prefix>_model` for `bmr_compensator_init`).
#[pyfunction]
#[pyo3(signature = (compensator, language, *, title="bmr compensator", prefix="bmr"))]
fn export_source(
    compensator: &Bound<'_, PyCompensator>,
    language: &str,
    title: &str,
    prefix: &str,
) -> PyResult<String> {
    let me = shared(compensator)?;
    if me.inverse != "exact" {
        return Err(BmrError::new_err(
            "export: only the exact inverse runs in firmware (build the compensator with inverse=\"exact\")",
        ));
    }
    if !(prefix
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic())
        && prefix
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_'))
    {
        return Err(BmrError::new_err(format!(
            "export: prefix {prefix:?} must be a C identifier (letters, digits, _)"
        )));
    }
    let op = &me.hysteresis.op;
    let (a, d) = (op.ascending(), op.descending());
    let (y_lo, y_hi) = op.output_range();
    let f = &me.base_friction;
    let effects: Vec<EffectValues> = me.extensions.iter().filter_map(EffectValues::of).collect();
    let data = ModelData {
        ascending: a.data(),
        ascending_nodes: a.nodes(),
        ascending_curves: a.curves(),
        descending: d.data(),
        descending_nodes: d.nodes(),
        descending_curves: d.curves(),
        y_lo,
        y_hi,
        friction_c0: f.c0(),
        friction_a: f.a(),
        friction_b: f.b(),
        converter_gain_a_per_v: me.core.gain_a_per_v(),
        current_limit_a: me.core.limit_a(),
        full_torque_nmm: me.full_torque_nmm,
        effects: &effects,
    };
    let title = title.replace("*/", "* /").replace('\n', " ");
    match language {
        "rust" => Ok(crate::export::rust_source(&data, &title)),
        "c" => Ok(crate::export::c_header(&data, &title, prefix)),
        other => Err(BmrError::new_err(format!(
            "export: language {other:?}: expected 'rust' or 'c'"
        ))),
    }
}

/// Validate a model's `extensions` against the vocabulary: every name known, every parameter known and in range.
/// Returns the entries as `[{"name", "params"}]` with every parameter filled in (defaults included).
#[pyfunction]
fn check_extensions<'py>(
    py: Python<'py>,
    extensions: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyList>> {
    extensions_to_py(py, &parse_extensions(Some(extensions))?)
}

fn output_map_of(curvature: f64, scale_nmm: f64) -> PyResult<OutputMap> {
    OutputMap::curvature(curvature, scale_nmm).map_err(bmr_err)
}

/// The `non_congruent` output map (the compensator's own table) applied to core torques (N·mm).
#[pyfunction]
fn output_map<'py>(
    py: Python<'py>,
    core_nmm: &Bound<'py, PyAny>,
    curvature: f64,
    scale_nmm: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let m = output_map_of(curvature, scale_nmm)?;
    let x = extract_f64_array(core_nmm, "core_nmm")?;
    Ok(to_numpy(py, x.iter().map(|&v| m.forward(v)).collect()))
}

/// The inverse of `output_map`: the core torques (N·mm) giving field torques `field_nmm`.
#[pyfunction]
fn output_map_inverse<'py>(
    py: Python<'py>,
    field_nmm: &Bound<'py, PyAny>,
    curvature: f64,
    scale_nmm: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let mut m = output_map_of(curvature, scale_nmm)?;
    let x = extract_f64_array(field_nmm, "field_nmm")?;
    Ok(to_numpy(py, x.iter().map(|&v| m.inverse(v)).collect()))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(check_extensions, m)?)?;
    m.add_function(wrap_pyfunction!(export_source, m)?)?;
    m.add_function(wrap_pyfunction!(_rebuild_compensator, m)?)?;
    m.add_function(wrap_pyfunction!(_rebuild_compensator_state, m)?)?;
    m.add_function(wrap_pyfunction!(output_map, m)?)?;
    m.add_function(wrap_pyfunction!(output_map_inverse, m)?)?;
    m.add_class::<PyCompensator>()?;
    m.add_class::<PyCommand>()?;
    m.add_class::<PyCompensatorState>()?;
    m.add_class::<PySimulation>()?;
    Ok(())
}
