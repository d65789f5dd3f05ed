//! `bmr.Friction`: angle-periodic seal friction `c0 + (1 + g|I|)·Σ a_k sin kθ + b_k cos kθ` (N·mm), and
//! `friction_series`, the batch evaluator of the one friction series for fitted models of any order.
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::friction::{Friction, MAX_MAGNITUDE, MAX_ORDER, harmonic_series};
use crate::python::arrays::{DETACH_LEN, extract_f64_array, to_numpy};
use crate::python::{BmrError, bmr_err};

pub(crate) type Model = Friction<MAX_ORDER>;

/// Angle-periodic seal friction torque (N·mm) as a function of rotor angle (rad) and, with `gain_per_a`, current.
#[pyclass(name = "Friction", module = "bmr", frozen)]
#[derive(Clone)]
pub(crate) struct PyFriction {
    pub(crate) f: Model,
}

fn map_detached(
    py: Python<'_>,
    x: Vec<f64>,
    f: impl Fn(usize, f64) -> f64 + Send + Sync,
) -> Vec<f64> {
    let n = x.len();
    let run = move || {
        x.iter()
            .enumerate()
            .map(|(i, &v)| f(i, v))
            .collect::<Vec<f64>>()
    };
    if n > DETACH_LEN {
        py.detach(run)
    } else {
        run()
    }
}

#[pymethods]
impl PyFriction {
    /// `c0` (N·mm), sine coefficients `a` and cosine coefficients `b` of harmonics 1..K (K ≤ 24), and the
    /// growth of the angle-dependent part per ampere of |I| `gain_per_a` (1/A).
    #[new]
    #[pyo3(signature = (c0=0.0, a=None, b=None, gain_per_a=0.0))]
    fn new(
        c0: f64,
        a: Option<&Bound<'_, PyAny>>,
        b: Option<&Bound<'_, PyAny>>,
        gain_per_a: f64,
    ) -> PyResult<Self> {
        let a = a.map_or(Ok(Vec::new()), |x| extract_f64_array(x, "a"))?;
        let b = b.map_or(Ok(Vec::new()), |x| extract_f64_array(x, "b"))?;
        Model::from_coefficients(c0, &a, &b)
            .and_then(|f| f.with_current_gain(gain_per_a))
            .map(|f| PyFriction { f })
            .map_err(bmr_err)
    }

    /// From the paper's form `c0 + Σ A_k sin(kθ + φ_k)` (amplitudes N·mm, phases rad).
    #[staticmethod]
    fn from_amplitude_phase(
        c0: f64,
        amplitude: &Bound<'_, PyAny>,
        phase: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let amplitude = extract_f64_array(amplitude, "amplitude")?;
        let phase = extract_f64_array(phase, "phase")?;
        Model::from_amplitude_phase(c0, &amplitude, &phase)
            .map(|f| PyFriction { f })
            .map_err(bmr_err)
    }

    /// Friction torque (N·mm) at `theta` (rad) and current `current_a` (A, default 0): a float for floats, an
    /// array for arrays.
    #[pyo3(signature = (theta, current_a=None))]
    fn __call__<'py>(
        &self,
        py: Python<'py>,
        theta: &Bound<'py, PyAny>,
        current_a: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let f = self.f;
        let scalar_current = match current_a {
            None => Some(0.0),
            Some(c) => c.extract::<f64>().ok(),
        };
        if let (Ok(x), Some(c)) = (theta.extract::<f64>(), scalar_current) {
            return Ok(f.eval_at(x, c).into_pyobject(py)?.into_any());
        }
        let th = extract_f64_array(theta, "theta")?;
        let out = match (current_a, scalar_current) {
            (_, Some(c)) => {
                let n = th.len();
                let run = move || th.iter().map(|&x| f.eval_at(x, c)).collect::<Vec<f64>>();
                if n > DETACH_LEN {
                    py.detach(run)
                } else {
                    run()
                }
            }
            (Some(c), None) => {
                let cur = extract_f64_array(c, "current_a")?;
                if cur.len() != th.len() {
                    return Err(BmrError::new_err(format!(
                        "Friction(theta, current_a): {} angles but {} currents",
                        th.len(),
                        cur.len()
                    )));
                }
                map_detached(py, th, move |i, x| f.eval_at(x, cur[i]))
            }
            (None, None) => unreachable!("no current means zero current"),
        };
        Ok(to_numpy(py, out).into_any())
    }

    #[getter]
    fn c0(&self) -> f64 {
        self.f.c0()
    }
    /// Sine coefficients of harmonics 1..order.
    #[getter]
    fn a(&self) -> Vec<f64> {
        self.f.a().to_vec()
    }
    /// Cosine coefficients of harmonics 1..order.
    #[getter]
    fn b(&self) -> Vec<f64> {
        self.f.b().to_vec()
    }
    /// Highest harmonic with a non-zero coefficient.
    #[getter]
    fn order(&self) -> usize {
        self.f.order()
    }
    /// Growth of the angle-dependent part per ampere of |I| (1/A).
    #[getter]
    fn gain_per_a(&self) -> f64 {
        self.f.gain_per_a()
    }
    /// `(amplitudes, phases)` of harmonics 1..order in the paper's form.
    fn amplitude_phase<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
        let (amp, ph): (Vec<f64>, Vec<f64>) = (1..=self.f.order())
            .map(|k| self.f.amplitude_phase(k))
            .unzip();
        (to_numpy(py, amp), to_numpy(py, ph))
    }
    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other
            .cast::<PyFriction>()
            .is_ok_and(|o| o.get().f == self.f)
    }
    fn __copy__(&self) -> Self {
        self.clone()
    }
    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
        self.clone()
    }
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let f = slf.get().f;
        let args = (f.c0(), f.a().to_vec(), f.b().to_vec(), f.gain_per_a());
        PyTuple::new(
            slf.py(),
            [
                slf.get_type().into_any(),
                args.into_pyobject(slf.py())?.into_any(),
            ],
        )
    }
    fn __repr__(&self) -> String {
        let g = self.f.gain_per_a();
        format!(
            "Friction(c0={}, a={:?}, b={:?}{})",
            self.f.c0(),
            self.a(),
            self.b(),
            if g != 0.0 {
                format!(", gain_per_a={g}")
            } else {
                String::new()
            }
        )
    }
}

/// The friction series `c0 + Σ a_k sin kθ + b_k cos kθ` (N·mm) of any order at angles `theta_rad` (rad): the one
/// evaluator behind `bmr.Friction` and the fitted friction models.
#[pyfunction]
#[pyo3(signature = (theta_rad, c0, a, b))]
fn friction_series<'py>(
    py: Python<'py>,
    theta_rad: &Bound<'py, PyAny>,
    c0: f64,
    a: &Bound<'py, PyAny>,
    b: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (a, b) = (extract_f64_array(a, "a")?, extract_f64_array(b, "b")?);
    if a.len() != b.len() {
        return Err(BmrError::new_err(format!(
            "friction_series: {} sine but {} cosine coefficients",
            a.len(),
            b.len()
        )));
    }
    let sum = c0.abs() + a.iter().chain(&b).map(|x| x.abs()).sum::<f64>();
    if sum.is_nan() || sum > MAX_MAGNITUDE {
        return Err(BmrError::new_err(format!(
            "friction_series: coefficients must be finite with |c0| + Σ|a_k| + |b_k| ≤ {MAX_MAGNITUDE:e}"
        )));
    }
    let th = extract_f64_array(theta_rad, "theta_rad")?;
    let n = th.len();
    let run = move || {
        th.iter()
            .map(|&x| {
                let (s, c) = crate::trig::sincos(x);
                c0 + harmonic_series(&a, &b, s, c)
            })
            .collect::<Vec<f64>>()
    };
    let out = if n > DETACH_LEN {
        py.detach(run)
    } else {
        run()
    };
    Ok(to_numpy(py, out))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyFriction>()?;
    m.add_function(wrap_pyfunction!(friction_series, m)?)?;
    m.add("FRICTION_MAX_ORDER", MAX_ORDER)?;
    Ok(())
}
