//! `bmr.Friction`: angle-periodic seal friction `c0 + Σ a_k sin kθ + b_k cos kθ` (N·mm), up to 12 harmonics.
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyType;

use crate::friction::{Friction, MAX_ORDER};
use crate::limits::MAX_MAGNITUDE;
use crate::python::BmrError;
use crate::python::arrays::{DETACH_LEN, extract_f64_array, to_numpy};

pub(crate) type Model = Friction<MAX_ORDER>;

/// Angle-periodic seal friction torque (N·mm) as a function of rotor angle (rad).
#[pyclass(name = "Friction", module = "bmr", frozen)]
#[derive(Clone)]
pub(crate) struct PyFriction {
    pub(crate) f: Model,
}

#[pymethods]
impl PyFriction {
    /// `c0` (N·mm) plus sine coefficients `a` and cosine coefficients `b` of harmonics 1..K (K ≤ 12).
    #[new]
    #[pyo3(signature = (c0=0.0, a=None, b=None))]
    fn new(c0: f64, a: Option<&Bound<'_, PyAny>>, b: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
        let a = a.map_or(Ok(Vec::new()), |x| extract_f64_array(x, "a"))?;
        let b = b.map_or(Ok(Vec::new()), |x| extract_f64_array(x, "b"))?;
        Model::from_coefficients(c0, &a, &b).map(|f| PyFriction { f }).ok_or_else(|| {
            BmrError::new_err(format!(
                "Friction: need finite coefficients whose largest torque |c0| + Σ |a_k| + |b_k| is at most \
                 {MAX_MAGNITUDE:e} N·mm and at most {MAX_ORDER} harmonics (got {} sine, {} cosine)",
                a.len(),
                b.len()
            ))
        })
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
        Model::from_amplitude_phase(c0, &amplitude, &phase).map(|f| PyFriction { f }).ok_or_else(|| {
            BmrError::new_err(format!(
                "Friction.from_amplitude_phase: need as many phases as amplitudes ({} vs {}), finite, a largest \
                 torque |c0| + Σ |a_k| + |b_k| of at most {MAX_MAGNITUDE:e} N·mm and at most {MAX_ORDER} harmonics",
                amplitude.len(),
                phase.len()
            ))
        })
    }

    /// Friction torque (N·mm) at `theta` (rad): a float for a float, an array for an array.
    fn __call__<'py>(
        &self,
        py: Python<'py>,
        theta: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        if let Ok(x) = theta.extract::<f64>() {
            return Ok(self.f.eval(x).into_pyobject(py)?.into_any());
        }
        let th = extract_f64_array(theta, "theta")?;
        let n = th.len();
        let f = self.f;
        let eval = move || th.iter().map(|&x| f.eval(x)).collect::<Vec<f64>>();
        let out = if n > DETACH_LEN {
            py.detach(eval)
        } else {
            eval()
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
        self.f.a().as_slice()[..self.f.order()].to_vec()
    }
    /// Cosine coefficients of harmonics 1..order.
    #[getter]
    fn b(&self) -> Vec<f64> {
        self.f.b().as_slice()[..self.f.order()].to_vec()
    }
    /// Highest harmonic with a non-zero coefficient.
    #[getter]
    fn order(&self) -> usize {
        self.f.order()
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
    fn __copy__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf // immutable: a copy is the object itself
    }
    fn __deepcopy__<'py>(slf: PyRef<'py, Self>, _memo: &Bound<'py, PyAny>) -> PyRef<'py, Self> {
        slf
    }
    /// Pickled as its coefficients (rebuilt through the checked constructor).
    #[allow(clippy::type_complexity)]
    fn __reduce__<'py>(&self, py: Python<'py>) -> (Bound<'py, PyType>, (f64, Vec<f64>, Vec<f64>)) {
        (py.get_type::<Self>(), (self.f.c0(), self.a(), self.b()))
    }
    fn __repr__(&self) -> String {
        format!(
            "Friction(c0={}, a={:?}, b={:?})",
            self.f.c0(),
            self.a(),
            self.b()
        )
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyFriction>()?;
    Ok(())
}
