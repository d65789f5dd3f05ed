//! Building a compensator: from its parts and a model's extension entries (checked against the vocabulary).
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyMapping};

use super::*;
use crate::compensator::InverseKind;
use crate::friction::{Friction, MAX_ORDER};
use crate::python::hysteresis::PyHysteresis;
use crate::python::{BmrError, bmr_err};
use crate::vocabulary::{EffectKind, NameList, Params, SPECS, extension_spec};

impl PyCompensator {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn build(
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
                None => {
                    let timed: Vec<&str> = extensions
                        .iter()
                        .filter(|p| {
                            EffectKind::from_name(p.spec.name).is_some_and(|k| k.needs_period())
                        })
                        .map(|p| p.spec.name)
                        .collect();
                    if !timed.is_empty() {
                        return Err(BmrError::new_err(format!(
                            "extensions with {} need dt_s (the control period, s)",
                            timed.join(", ")
                        )));
                    }
                    // No stage of these keeps time: any period builds the same stages.
                    1.0
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
            commands: CommandSlots::default(),
        })
    }

    pub(super) fn rebuilt(&self) -> PyResult<Self> {
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

pub(super) fn extensions_to_py<'py>(
    py: Python<'py>,
    ext: &[Params],
) -> PyResult<Bound<'py, PyList>> {
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

/// Validate a model's `extensions` against the vocabulary: every name known, every parameter known and in range.
/// Returns the entries as `[{"name", "params"}]` with every parameter filled in (defaults included).
#[pyfunction]
pub(super) fn check_extensions<'py>(
    py: Python<'py>,
    extensions: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyList>> {
    extensions_to_py(py, &parse_extensions(Some(extensions))?)
}
