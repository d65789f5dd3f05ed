//! Batch signals of the effects the diagnosis fits and learns: creep relaxations, the accommodation shift and
//! the candidate library of run signals ([`crate::creep`], [`crate::accommodation`], [`crate::discrepancy`]).
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::accommodation::Accommodation;
use crate::creep::{MAX_CREEP_TERMS, fluctuation_shift, mean_relaxation};
use crate::discrepancy::{CANDIDATES, candidate_library, library_width};
use crate::python::BmrError;
use crate::python::arrays::{DETACH_LEN, extract_f64_array};

fn finite(v: &[f64], what: &str) -> PyResult<()> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(BmrError::new_err(format!(
            "{what}[{i}] = {} is not finite",
            v[i]
        ))),
        None => Ok(()),
    }
}

fn matrix<'py>(
    py: Python<'py>,
    data: Vec<f64>,
    rows: usize,
    cols: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let a = numpy::ndarray::Array2::from_shape_vec((rows, cols), data)
        .map_err(|e| BmrError::new_err(e.to_string()))?;
    Ok(PyArray2::from_owned_array(py, a))
}

/// Creep relaxation signal of a core output ``v`` sampled every ``dt_s``: the mean over ``taus_s`` of
/// ``lag(v, τ) − v`` (exact first-order lags from rest at ``v[0]``), one value per sample. The creep output of an
/// equal-weight spectrum over ``taus_s`` is ``v + fraction · relaxation``.
#[pyfunction]
fn creep_relaxation<'py>(
    py: Python<'py>,
    v: Bound<'py, PyAny>,
    taus_s: Bound<'py, PyAny>,
    dt_s: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let v = extract_f64_array(&v, "v")?;
    let taus = extract_f64_array(&taus_s, "taus_s")?;
    finite(&v, "v")?;
    let mut out = vec![0.0; v.len()];
    let run = |out: &mut [f64]| mean_relaxation(&v, &taus, dt_s, out);
    let ok = if v.len() > DETACH_LEN {
        py.detach(|| run(&mut out))
    } else {
        run(&mut out)
    };
    if !ok {
        return Err(BmrError::new_err(format!(
            "creep_relaxation needs dt_s > 0 and 1 to {MAX_CREEP_TERMS} positive finite time constants \
             (dt_s={dt_s}, taus_s={taus:?})"
        )));
    }
    Ok(PyArray1::from_vec(py, out))
}

/// The fluctuation field's shift per unit field along an applied input ``u`` sampled every ``dt_s`` (from rest at
/// ``u[0]``): the direction the input last moved times ``ln(1 + t/tau0_s)``, ``t`` the time since it turned. Creep's
/// log-time after-effect feeds the core ``u + fluctuation · shift``.
#[pyfunction]
fn creep_fluctuation_shift<'py>(
    py: Python<'py>,
    u: Bound<'py, PyAny>,
    tau0_s: f64,
    dt_s: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let u = extract_f64_array(&u, "u")?;
    finite(&u, "u")?;
    let mut out = vec![0.0; u.len()];
    let run = |out: &mut [f64]| fluctuation_shift(&u, tau0_s, dt_s, out);
    let ok = if u.len() > DETACH_LEN {
        py.detach(|| run(&mut out))
    } else {
        run(&mut out)
    };
    if !ok {
        return Err(BmrError::new_err(format!(
            "creep_fluctuation_shift needs tau0_s > 0 and dt_s > 0, finite (tau0_s={tau0_s}, dt_s={dt_s})"
        )));
    }
    Ok(PyArray1::from_vec(py, out))
}

/// Accommodation shift (output units) along input ``u`` and core output ``v``: the minor-loop drift of
/// :mod:`accommodation` with share ``kappa`` and ``cycles`` loop cycles to settle; reversals beyond ``deadband``
/// (input units), saturation within ``saturation_tol`` of ``lo``/``hi``, drift towards the output centre ``y_mid``.
#[pyfunction]
#[pyo3(signature = (u, v, *, kappa, cycles, lo, hi, deadband, saturation_tol, y_mid))]
#[allow(clippy::too_many_arguments)]
fn accommodation_shift<'py>(
    py: Python<'py>,
    u: Bound<'py, PyAny>,
    v: Bound<'py, PyAny>,
    kappa: f64,
    cycles: f64,
    lo: f64,
    hi: f64,
    deadband: f64,
    saturation_tol: f64,
    y_mid: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (u, v) = (extract_f64_array(&u, "u")?, extract_f64_array(&v, "v")?);
    finite(&u, "u")?;
    finite(&v, "v")?;
    if u.len() != v.len() {
        return Err(BmrError::new_err(format!(
            "accommodation_shift: u and v differ in length ({} vs {})",
            u.len(),
            v.len()
        )));
    }
    let mut a = Accommodation::new(kappa, cycles, lo, hi, deadband, saturation_tol, y_mid)
        .ok_or_else(|| {
            BmrError::new_err(format!(
                "accommodation_shift needs finite kappa, cycles > 0, lo < hi, deadband > 0, saturation_tol >= 0 \
                 (kappa={kappa}, cycles={cycles}, lo={lo}, hi={hi}, deadband={deadband}, \
                 saturation_tol={saturation_tol})"
            ))
        })?;
    let mut scan = || -> Vec<f64> { u.iter().zip(&v).map(|(&x, &y)| a.step(x, y)).collect() };
    let out = if u.len() > DETACH_LEN {
        py.detach(scan)
    } else {
        scan()
    };
    Ok(PyArray1::from_vec(py, out))
}

/// The candidate library of one run for sparse discrepancy regression: an ``n × m`` array of the signals named in
/// ``bmr._core.CANDIDATES`` (then ``sin(kθ), cos(kθ)`` for ``k = 1..harmonics`` when ``theta_rad`` is given),
/// from time ``t_s`` (increasing), input ``u``, model output ``y`` and the input ``deadband`` of reversals.
#[pyfunction]
#[pyo3(signature = (t_s, u, y, *, deadband, theta_rad=None, harmonics=0))]
fn candidate_signals<'py>(
    py: Python<'py>,
    t_s: Bound<'py, PyAny>,
    u: Bound<'py, PyAny>,
    y: Bound<'py, PyAny>,
    deadband: f64,
    theta_rad: Option<Bound<'py, PyAny>>,
    harmonics: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let (t, u, y) = (
        extract_f64_array(&t_s, "t_s")?,
        extract_f64_array(&u, "u")?,
        extract_f64_array(&y, "y")?,
    );
    let th = theta_rad
        .map(|t| extract_f64_array(&t, "theta_rad"))
        .transpose()?;
    for (a, name) in [(&t, "t_s"), (&u, "u"), (&y, "y")] {
        finite(a, name)?;
    }
    if let Some(th) = &th {
        finite(th, "theta_rad")?;
    }
    if harmonics > 64 {
        return Err(BmrError::new_err(format!(
            "harmonics = {harmonics} exceeds the limit of 64"
        )));
    }
    let width = library_width(if th.is_some() { harmonics } else { 0 });
    let n = u.len();
    let build = || candidate_library(&t, &u, &y, th.as_deref(), harmonics, deadband);
    let lib = if n > DETACH_LEN {
        py.detach(build)
    } else {
        build()
    };
    let lib = lib.ok_or_else(|| {
        BmrError::new_err(format!(
            "candidate_signals needs t_s, u, y (and theta_rad) of one length, strictly increasing time and a \
             positive dead-band (lengths {}, {}, {}; deadband {deadband})",
            t.len(),
            u.len(),
            y.len()
        ))
    })?;
    matrix(py, lib, n, width)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(creep_relaxation, m)?)?;
    m.add_function(wrap_pyfunction!(creep_fluctuation_shift, m)?)?;
    m.add_function(wrap_pyfunction!(accommodation_shift, m)?)?;
    m.add_function(wrap_pyfunction!(candidate_signals, m)?)?;
    let items: Vec<Bound<'_, PyTuple>> = CANDIDATES
        .iter()
        .map(|c| PyTuple::new(m.py(), [c.name, c.unit, c.doc]))
        .collect::<PyResult<_>>()?;
    m.add("CANDIDATES", PyTuple::new(m.py(), items)?)?;
    m.add(
        "ACCOMMODATION_DEADBAND_SHARE",
        crate::accommodation::DEADBAND_SHARE,
    )?;
    m.add(
        "ACCOMMODATION_SATURATION_SHARE",
        crate::accommodation::SATURATION_SHARE,
    )?;
    Ok(())
}
