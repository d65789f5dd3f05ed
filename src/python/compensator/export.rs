//! Firmware source of a compensator (Rust for the no_std crate, C for the C ABI).
use pyo3::prelude::*;

use super::*;
use crate::model_data::{EffectValues, ModelData};
use crate::python::BmrError;

/// Firmware source of `compensator` (exact inverse): `language` "rust" (static tables and `compensator(dt_s)` for
/// the no_std crate) or "c" (arrays and a `BmrModel` named `<prefix>_model` for `bmr_compensator_init`).
#[pyfunction]
#[pyo3(signature = (compensator, language, *, title="bmr compensator", prefix="bmr"))]
pub(super) fn export_source(
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
