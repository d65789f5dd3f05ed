//! Batch versions of the per-sample filters (`crate::filters`) for the Python diagnosis: `lag`, `lead`, `delay`,
//! `heating_state`, `leak_integral`, `drift_offset`. Each runs the very filter the plant and the compensator step,
//! over a whole array.
use numpy::PyArray1;
use pyo3::prelude::*;

use crate::filters::{self, DelayLine, Heating, Lag, Lead, leak_pole, leak_step};
use crate::python::BmrError;
use crate::python::arrays::{DETACH_LEN, extract_f64_array, to_numpy};

fn check(what: &str, value: f64, positive: bool) -> PyResult<f64> {
    let ok = value.is_finite() && if positive { value > 0.0 } else { value >= 0.0 };
    if ok {
        Ok(value)
    } else {
        let need = if positive { "positive" } else { "nonnegative" };
        Err(BmrError::new_err(format!(
            "{what} must be a {need} finite number, got {value}"
        )))
    }
}

/// Run `f` over `x` (without the interpreter lock for long arrays) and return a new array.
fn map_array<'py>(
    py: Python<'py>,
    x: Vec<f64>,
    f: impl FnOnce(Vec<f64>) -> Vec<f64> + Send,
) -> Bound<'py, PyArray1<f64>> {
    let out = if x.len() > DETACH_LEN {
        py.detach(move || f(x))
    } else {
        f(x)
    };
    to_numpy(py, out)
}

/// Exact first-order lag (zero-order hold) of `x` with time constant `tau_s` at sample period `dt_s`:
/// `y[n] = p·y[n−1] + (1 − p)·x[n]`, `p = exp(−dt/τ)`, at rest at `initial` (default `x[0]`) before the start.
#[pyfunction]
#[pyo3(signature = (x, tau_s, dt_s, *, initial=None))]
fn lag<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    tau_s: f64,
    dt_s: f64,
    initial: Option<f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (tau_s, dt_s) = (check("tau_s", tau_s, false)?, check("dt_s", dt_s, true)?);
    let x = extract_f64_array(x, "x")?;
    let y0 = initial.unwrap_or(x.first().copied().unwrap_or(0.0));
    Ok(map_array(py, x, move |mut x| {
        let mut f = Lag::new(tau_s, dt_s, y0);
        x.iter_mut().for_each(|v| *v = f.step(*v));
        x
    }))
}

/// Exact inverse of `lag`: `x[n] = (y[n] − p·y[n−1])/(1 − p)` with `y[−1] = initial` (default `y[0]`), so that
/// `lag(lead(y)) == y` up to round-off.
#[pyfunction]
#[pyo3(signature = (y, tau_s, dt_s, *, initial=None))]
fn lead<'py>(
    py: Python<'py>,
    y: &Bound<'py, PyAny>,
    tau_s: f64,
    dt_s: f64,
    initial: Option<f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (tau_s, dt_s) = (check("tau_s", tau_s, false)?, check("dt_s", dt_s, true)?);
    let y = extract_f64_array(y, "y")?;
    let y0 = initial.unwrap_or(y.first().copied().unwrap_or(0.0));
    Ok(map_array(py, y, move |mut y| {
        let mut f = Lead::new(tau_s, dt_s, y0);
        y.iter_mut().for_each(|v| *v = f.step(*v));
        y
    }))
}

/// `x` delayed by `round(delay_s/dt_s)` samples, `fill` (default `x[0]`) before the start.
#[pyfunction]
#[pyo3(signature = (x, delay_s, dt_s, *, fill=None))]
fn delay<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    delay_s: f64,
    dt_s: f64,
    fill: Option<f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (delay_s, dt_s) = (
        check("delay_s", delay_s, false)?,
        check("dt_s", dt_s, true)?,
    );
    let x = extract_f64_array(x, "x")?;
    let fill = fill.unwrap_or(x.first().copied().unwrap_or(0.0));
    // A delay as long as the signal already outputs only `fill`: no need for a longer line.
    let samples = (libm::round(delay_s / dt_s)).min(x.len() as f64) as usize;
    Ok(map_array(py, x, move |mut x| {
        let mut d = DelayLine::new(vec![0.0; samples], samples, fill).expect("sized to the delay");
        x.iter_mut().for_each(|v| *v = d.step(*v));
        x
    }))
}

/// Coil heating state along `current_a` (A): `x[n] = x[n−1] + (1 − p)·((I[n]/I_full)² − x[n−1])`,
/// `p = exp(−dt/τ)`, from `initial`; 1 means steady full current.
#[pyfunction]
#[pyo3(signature = (current_a, tau_s, dt_s, full_current_a, *, initial=0.0))]
fn heating_state<'py>(
    py: Python<'py>,
    current_a: &Bound<'py, PyAny>,
    tau_s: f64,
    dt_s: f64,
    full_current_a: f64,
    initial: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let tau_s = check("tau_s", tau_s, true)?;
    let dt_s = check("dt_s", dt_s, true)?;
    let full = check("full_current_a", full_current_a, true)?;
    let initial = check("initial", initial.abs(), false).map(|_| initial)?;
    let x = extract_f64_array(current_a, "current_a")?;
    Ok(map_array(py, x, move |mut x| {
        let mut h = Heating::new(tau_s, dt_s, full, initial);
        x.iter_mut().for_each(|v| *v = h.step(*v));
        x
    }))
}

/// The leakage integral of `x` from its first sample (0 there): `q[n] = p·q[n−1] + dt/2·(x[n] + p·x[n−1])`,
/// `p = exp(−decay·dt)`: the charge a leakage current leaves on a charge amplifier that discharges it at
/// `decay_per_s` (0: an ideal integrator, the trapezoid rule).
#[pyfunction]
#[pyo3(signature = (x, dt_s, decay_per_s=0.0))]
fn leak_integral<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    dt_s: f64,
    decay_per_s: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let dt_s = check("dt_s", dt_s, true)?;
    let decay = check("decay_per_s", decay_per_s, false)?;
    let x = extract_f64_array(x, "x")?;
    Ok(map_array(py, x, move |mut x| {
        let pole = leak_pole(dt_s, decay);
        let (mut q, mut last) = (0.0, x.first().copied().unwrap_or(0.0));
        x.iter_mut().for_each(|v| {
            q = leak_step(q, pole, dt_s, *v, last);
            last = *v;
            *v = q;
        });
        x
    }))
}

/// A torque sensor's zero drift per unit of its initial rate at times `t_s` (s from the device's start): `t`, or
/// `(1 − e^(−settle·t))/settle` for a drift that settles at `settle_per_s` (a strain bridge warming up).
#[pyfunction]
#[pyo3(signature = (t_s, settle_per_s=0.0))]
fn drift_offset<'py>(
    py: Python<'py>,
    t_s: &Bound<'py, PyAny>,
    settle_per_s: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let settle = check("settle_per_s", settle_per_s, false)?;
    let t = extract_f64_array(t_s, "t_s")?;
    Ok(map_array(py, t, move |mut t| {
        t.iter_mut()
            .for_each(|v| *v = filters::drift_offset(*v, settle));
        t
    }))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(lag, m)?)?;
    m.add_function(wrap_pyfunction!(lead, m)?)?;
    m.add_function(wrap_pyfunction!(delay, m)?)?;
    m.add_function(wrap_pyfunction!(heating_state, m)?)?;
    m.add_function(wrap_pyfunction!(leak_integral, m)?)?;
    m.add_function(wrap_pyfunction!(drift_offset, m)?)?;
    Ok(())
}
