//! Offline runs of a compensator over arrays, into fresh or preallocated columns.
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::*;
use crate::compensator::Command;
use crate::python::BmrError;
use crate::python::arrays::{DETACH_LEN, extract_f64_array};

/// The columns `run` can return, in order: floats then flags.
pub(super) const COLUMNS: [&str; 8] = [
    "current_a",
    "coil1_a",
    "coil2_a",
    "volt1_v",
    "volt2_v",
    "model_torque_nmm",
    "saturated",
    "fault",
];
pub(super) const FLOAT_COLUMNS: usize = 6;

pub(super) fn column_value(c: &Command, core: &Core, col: usize) -> f64 {
    match col {
        0 => c.current_a,
        1 => c.coil1_a,
        2 => c.coil2_a,
        3 => c.volt1_v,
        4 => c.volt2_v,
        _ => core.model_torque_nmm(),
    }
}

/// A float64 argument as a slice: a contiguous float64 array is read in place, anything else is converted
/// (`TypeError` naming the argument for non-numbers).
pub(super) enum Floats<'py> {
    Borrowed(numpy::PyReadonlyArray1<'py, f64>),
    Owned(Vec<f64>),
}

impl<'py> Floats<'py> {
    pub(super) fn of(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<Self> {
        if let Ok(a) = obj.cast::<PyArray1<f64>>()
            && a.is_contiguous()
        {
            return Ok(Floats::Borrowed(a.readonly()));
        }
        Ok(Floats::Owned(extract_f64_array(obj, what)?))
    }
    pub(super) fn slice(&self) -> &[f64] {
        match self {
            Floats::Borrowed(a) => a.as_slice().unwrap_or(&[]),
            Floats::Owned(v) => v,
        }
    }
}

pub(super) fn run<'py>(
    slf: &Bound<'py, PyCompensator>,
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
