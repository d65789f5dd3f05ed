//! Python bindings of the identification least squares: `fit_friction_order`, `EverettModel`, `fit_everett`,
//! `EverettRegression`, `EverettFolds`.
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::cbh::Initial;
use crate::identification::{
    EverettFit, EverettFitOptions, EverettFoldRun, EverettFolds, EverettGrid, EverettInput,
    EverettModel, EverettRegression, EverettRun, fit_everett as fit_everett_rs, fit_friction,
};
use crate::python::arrays::{curves_to_py, extract_f64_array};
use crate::python::hysteresis::PyHysteresis;
use crate::python::{BmrError, identification_err};
use crate::table_builder::BuildOptions;

/// A 1-D float array argument (lists and integer arrays accepted).
/// (Floats or integers, as a numpy array or a sequence; anything else is a TypeError naming the argument.)
type Array<'py> = Bound<'py, PyAny>;
/// One training run as passed from Python: input, output, row weights, offset column, and optionally the
/// initial history (inputs after negative saturation that set the run's state) and the run's gain.
#[derive(FromPyObject)]
enum RunArrays<'py> {
    Full((Array<'py>, Array<'py>, Array<'py>, usize, Array<'py>, f64)),
    WithHistory((Array<'py>, Array<'py>, Array<'py>, usize, Array<'py>)),
    Plain((Array<'py>, Array<'py>, Array<'py>, usize)),
}
/// The same run copied out of Python (so the fit can run without the interpreter lock).
type RunData = (Vec<f64>, Vec<f64>, Vec<f64>, usize, Vec<f64>, f64);

impl RunArrays<'_> {
    /// Run `i`'s arrays, checked and named as `runs[i] ...` in errors.
    fn into_data(self, i: usize) -> PyResult<RunData> {
        let (u, y, w, o, h, g) = match self {
            RunArrays::Full((u, y, w, o, h, g)) => (u, y, w, o, Some(h), g),
            RunArrays::WithHistory((u, y, w, o, h)) => (u, y, w, o, Some(h), 1.0),
            RunArrays::Plain((u, y, w, o)) => (u, y, w, o, None, 1.0),
        };
        Ok((
            extract_f64_array(&u, &format!("runs[{i}] input"))?,
            extract_f64_array(&y, &format!("runs[{i}] output"))?,
            extract_f64_array(&w, &format!("runs[{i}] weights"))?,
            o,
            h.map(|h| extract_f64_array(&h, &format!("runs[{i}] history")))
                .transpose()?
                .unwrap_or_default(),
            g,
        ))
    }
}

/// Result of `fit_friction_order`: the harmonic series `c0 + Σ a_k sin(kθ) + b_k cos(kθ)` (N·mm) of one order
/// with the standard errors and covariance of its coefficients.
#[pyclass(name = "FrictionOrderFit", module = "bmr", frozen)]
pub struct PyFrictionOrderFit {
    inner: crate::identification::FrictionFit,
}

#[pymethods]
impl PyFrictionOrderFit {
    /// Harmonic order `K`.
    #[getter]
    fn order(&self) -> usize {
        self.inner.order
    }
    /// Constant term `c0` (N·mm).
    #[getter]
    fn c0(&self) -> f64 {
        self.inner.c0
    }
    /// Sine coefficients `a_1..a_K` (N·mm).
    #[getter]
    fn a<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.inner.a)
    }
    /// Cosine coefficients `b_1..b_K` (N·mm).
    #[getter]
    fn b<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.inner.b)
    }
    /// Standard error of `c0` (N·mm).
    #[getter]
    fn c0_stderr(&self) -> f64 {
        self.inner.c0_stderr
    }
    /// Standard errors of `a_k` (N·mm).
    #[getter]
    fn a_stderr<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.inner.a_stderr)
    }
    /// Standard errors of `b_k` (N·mm).
    #[getter]
    fn b_stderr<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.inner.b_stderr)
    }
    /// Covariance of `[c0, a_1, b_1, …, a_K, b_K]` (`(2K+1) × (2K+1)`, N·mm²).
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let p = self.inner.n_params();
        PyArray1::from_slice(py, &self.inner.covariance).reshape([p, p])
    }
    /// Residual sum of squares (N·mm²).
    #[getter]
    fn rss(&self) -> f64 {
        self.inner.rss
    }
    /// Number of samples used.
    #[getter]
    fn n(&self) -> usize {
        self.inner.n
    }

    fn __repr__(&self) -> String {
        format!(
            "FrictionOrderFit(order={}, c0={:.6} N·mm, residual RMS {:.4e} N·mm over {} samples)",
            self.inner.order,
            self.inner.c0,
            self.inner.residual_rms(),
            self.inner.n
        )
    }
}

/// Least-squares friction fit of one harmonic order (a `FrictionOrderFit`). Raises BmrError on bad input or
/// rank deficiency.
#[pyfunction]
#[pyo3(signature = (theta_rad, torque_nmm, order))]
fn fit_friction_order(
    py: Python<'_>,
    theta_rad: Array<'_>,
    torque_nmm: Array<'_>,
    order: usize,
) -> PyResult<PyFrictionOrderFit> {
    let theta = extract_f64_array(&theta_rad, "theta_rad")?;
    let torque = extract_f64_array(&torque_nmm, "torque_nmm")?;
    let inner = py
        .detach(|| fit_friction(&theta, &torque, order))
        .map_err(|e| identification_err("friction fit", e))?;
    Ok(PyFrictionOrderFit { inner })
}

/// A Preisach model with a tabulated Everett function `E(β, α)` on an input grid (see the Rust docs of
/// `identification::everett_regressors`). The ascending first-order curve from reversal m is
/// `y(m) + E(m, u)`, the descending one from M is `y(M) − E(u, M)`.
#[pyclass(name = "EverettModel", module = "bmr", frozen)]
pub struct PyEverettModel {
    inner: EverettModel,
}

#[pymethods]
impl PyEverettModel {
    /// Build from grid nodes (strictly increasing), packed cell masses (nonnegative unless `signed`) and the
    /// negative-saturation output `offset`.
    #[new]
    #[pyo3(signature = (grid, masses, offset, signed=false))]
    fn new(grid: Array<'_>, masses: Array<'_>, offset: f64, signed: bool) -> PyResult<Self> {
        let grid = EverettGrid::new(extract_f64_array(&grid, "grid")?)
            .map_err(|e| identification_err("EverettModel", e))?;
        let masses = extract_f64_array(&masses, "masses")?;
        let inner = if signed {
            EverettModel::with_signed_masses(grid, masses, offset)
        } else {
            EverettModel::new(grid, masses, offset)
        }
        .map_err(|e| identification_err("EverettModel", e))?;
        Ok(Self { inner })
    }

    fn __copy__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf // immutable: a copy is the object itself
    }

    fn __deepcopy__<'py>(slf: PyRef<'py, Self>, _memo: &Bound<'py, PyAny>) -> PyRef<'py, Self> {
        slf
    }

    /// Pickled as its constructor arguments.
    #[allow(clippy::type_complexity)]
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(
        Bound<'py, PyAny>,
        (
            Bound<'py, PyArray1<f64>>,
            Bound<'py, PyArray1<f64>>,
            f64,
            bool,
        ),
    )> {
        let py = slf.py();
        let me = slf.get();
        Ok((
            slf.get_type().into_any(),
            (
                PyArray1::from_slice(py, me.inner.grid().nodes()),
                PyArray1::from_slice(py, me.inner.masses()),
                me.inner.offset(),
                !me.inner.is_monotone(),
            ),
        ))
    }

    /// Whether every cell mass is nonnegative (a Preisach density: monotone branches, an exact inverse); false
    /// for a signed table (loops that may run clockwise).
    #[getter]
    fn monotone(&self) -> bool {
        self.inner.is_monotone()
    }

    /// Input grid nodes.
    #[getter]
    fn grid<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.inner.grid().nodes())
    }

    /// Packed cell masses.
    #[getter]
    fn masses<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.inner.masses())
    }

    /// Output at negative saturation.
    #[getter]
    fn offset(&self) -> f64 {
        self.inner.offset()
    }

    /// `E(β, α)` (0 when β ≥ α).
    fn everett(&self, beta: f64, alpha: f64) -> f64 {
        self.inner.everett(beta, alpha)
    }

    /// The Everett table at the nodes as an (N+1) × (N+1) array `E[i, j] = E(g_i, g_j)` (NaN below the
    /// diagonal).
    fn everett_table<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let g = self.inner.grid().nodes();
        let n = g.len();
        let mut out = vec![f64::NAN; n * n];
        for i in 0..n {
            for j in i..n {
                out[i * n + j] = self.inner.everett(g[i], g[j]);
            }
        }
        PyArray1::from_vec(py, out).reshape([n, n])
    }

    /// Output along input `u` starting from negative saturation followed by `history` (inputs that set the run's
    /// initial state; default none); `offset` overrides the model's offset.
    #[pyo3(signature = (u, offset=None, history=None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        u: Array<'py>,
        offset: Option<f64>,
        history: Option<Array<'py>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let u = extract_f64_array(&u, "u")?;
        let history = history
            .map(|h| extract_f64_array(&h, "history"))
            .transpose()?
            .unwrap_or_default();
        if let Some(i) = u.iter().position(|v| !v.is_finite()) {
            return Err(crate::python::BmrError::new_err(format!(
                "input sample {i} is not finite ({})",
                u[i]
            )));
        }
        if let Some(i) = history.iter().position(|v| !v.is_finite()) {
            return Err(BmrError::new_err(format!(
                "history entry {i} is not finite ({})",
                history[i]
            )));
        }
        let y = py.detach(|| self.inner.simulate_from(&history, &u, offset));
        Ok(PyArray1::from_vec(py, y))
    }

    /// The initial state under which run `(u, y)` is predicted best, among negative or positive saturation and
    /// one reversal after either at every grid node. `weight` (default all 1) selects the rows that count;
    /// `free_offset`: fit the run's own output offset; `gain`: the run's calibration gain. Returns
    /// `(history, rss, offset)`: the inputs that set the state (for `simulate(history=...)`), the weighted
    /// residual sum of squares and the offset.
    #[pyo3(signature = (u, y, weight=None, *, free_offset=true, gain=1.0))]
    fn best_initial_state(
        &self,
        py: Python<'_>,
        u: Array<'_>,
        y: Array<'_>,
        weight: Option<Array<'_>>,
        free_offset: bool,
        gain: f64,
    ) -> PyResult<(Vec<f64>, f64, f64)> {
        let (u, y) = (extract_f64_array(&u, "u")?, extract_f64_array(&y, "y")?);
        let w = match weight {
            Some(w) => extract_f64_array(&w, "weight")?,
            None => vec![1.0; u.len()],
        };
        if y.len() != u.len() || w.len() != u.len() {
            return Err(BmrError::new_err(format!(
                "best_initial_state: {} inputs, {} outputs, {} weights",
                u.len(),
                y.len(),
                w.len()
            )));
        }
        if let Some(i) = u
            .iter()
            .zip(&y)
            .position(|(a, b)| !a.is_finite() || !b.is_finite())
        {
            return Err(BmrError::new_err(format!(
                "best_initial_state: sample {i} is not finite"
            )));
        }
        if !(gain.is_finite() && gain > 0.0) {
            return Err(BmrError::new_err(format!(
                "best_initial_state: gain must be positive and finite, got {gain}"
            )));
        }
        Ok(py.detach(|| self.inner.best_initial_state(&u, &y, &w, free_offset, gain)))
    }

    /// First-order curves at every grid node (and at `subdivisions − 1` points inside every interval),
    /// `(ascending, descending)`, each a list of `(u, y)` arrays in traversal order; the first curve of each
    /// family is the major branch.
    #[pyo3(signature = (subdivisions=1))]
    fn first_order_curves<'py>(
        &self,
        py: Python<'py>,
        subdivisions: usize,
    ) -> PyResult<Bound<'py, PyTuple>> {
        if subdivisions == 0 {
            return Err(crate::python::BmrError::new_err(
                "subdivisions must be at least 1",
            ));
        }
        let (asc, desc) = self
            .inner
            .first_order_curves_subdivided(subdivisions)
            .map_err(|e| identification_err("first_order_curves", e))?;
        PyTuple::new(py, [curves_to_py(py, asc)?, curves_to_py(py, desc)?])
    }

    /// The CBH operator (`bmr.Hysteresis`, memory of 64 reversals, starting after negative saturation) of this
    /// table, built in Rust from its first-order curves with `subdivisions` reversals per grid interval (1
    /// reproduces the table exactly; more only add curves).
    #[pyo3(signature = (subdivisions=1))]
    fn hysteresis(&self, subdivisions: usize) -> PyResult<PyHysteresis> {
        if subdivisions == 0 {
            return Err(BmrError::new_err("subdivisions must be at least 1"));
        }
        let op = self
            .inner
            .hysteresis(subdivisions, &BuildOptions::default(), Initial::Negative)
            .map_err(|e| identification_err("EverettModel.hysteresis", e))?;
        Ok(PyHysteresis { op, report: None })
    }

    fn __repr__(&self) -> String {
        format!(
            "EverettModel(intervals={}, range=[{}, {}], offset={})",
            self.inner.grid().n_intervals(),
            self.inner.grid().lo(),
            self.inner.grid().hi(),
            self.inner.offset()
        )
    }
}

/// The optional drift regressor: one array per run (`runs` of them), or none.
fn drift_columns(drift: Option<Vec<Array<'_>>>, runs: usize) -> PyResult<Vec<Vec<f64>>> {
    let Some(arrays) = drift else {
        return Ok(Vec::new());
    };
    if arrays.len() != runs {
        return Err(BmrError::new_err(format!(
            "drift has {} arrays, runs {runs}: give one per run",
            arrays.len()
        )));
    }
    arrays
        .iter()
        .enumerate()
        .map(|(i, a)| extract_f64_array(a, &format!("drift[{i}]")))
        .collect()
}

/// Regularised nonnegative least squares for an Everett table on `grid` from `runs`, a list of
/// `(u, y, weight, offset_col[, history[, gain]])` (weight 0 keeps a sample out of the fit while it drives the
/// memory; `history`: inputs after negative saturation that set the run's initial state; `gain`: the run's
/// calibration gain on the model output). `drift`: one array per run (same length as its input) of a drift
/// regressor whose single coefficient is fitted with the table (e.g. the running integral of the input for a
/// leakage), reported as `EverettFit.drift`. Returns an `EverettFit`.
#[pyfunction]
#[pyo3(signature = (grid, runs, n_offsets=1, *, smoothing=1e-4, ridge=1e-9, max_iter=500, drift=None, signed=false,
                    diagonal_smoothing=0.0))]
#[allow(clippy::too_many_arguments)]
fn fit_everett<'py>(
    py: Python<'py>,
    grid: Array<'py>,
    runs: Vec<RunArrays<'py>>,
    n_offsets: usize,
    smoothing: f64,
    ridge: f64,
    max_iter: usize,
    drift: Option<Vec<Array<'py>>>,
    signed: bool,
    diagonal_smoothing: f64,
) -> PyResult<PyEverettFit> {
    let grid = EverettGrid::new(extract_f64_array(&grid, "grid")?)
        .map_err(|e| identification_err("Everett table fit", e))?;
    let data: Vec<RunData> = runs
        .into_iter()
        .enumerate()
        .map(|(i, run)| run.into_data(i))
        .collect::<PyResult<_>>()?;
    let drift = drift_columns(drift, data.len())?;
    let options = EverettFitOptions {
        smoothing,
        ridge,
        max_iter,
        signed,
        diagonal_smoothing,
    };
    let fit = py
        .detach(|| {
            let views: Vec<EverettRun<'_>> = data
                .iter()
                .enumerate()
                .map(|(k, (u, y, w, o, h, g))| EverettRun {
                    u,
                    y,
                    weight: w,
                    offset_col: *o,
                    history: h,
                    gain: *g,
                    drift: drift.get(k).map_or(&[], Vec::as_slice),
                })
                .collect();
            fit_everett_rs(&grid, &views, n_offsets, options)
        })
        .map_err(|e| identification_err("Everett table fit", e))?;
    fit_result(py, fit)
}

/// Result of `fit_everett` and `EverettRegression.fit`: the identified `EverettModel` (its offset is offset
/// column 0), every fitted offset, the data term's residual and the solver's passive set (a warm start).
#[pyclass(name = "EverettFit", module = "bmr", frozen)]
pub struct PyEverettFit {
    model: Py<PyEverettModel>,
    offsets: Vec<f64>,
    rss: f64,
    rms: f64,
    n_rows: usize,
    iterations: usize,
    passive: Vec<bool>,
    converged: bool,
    kkt_violation: f64,
    condition: f64,
    drift: Option<f64>,
}

#[pymethods]
impl PyEverettFit {
    /// The identified Preisach model.
    #[getter]
    fn model(&self, py: Python<'_>) -> Py<PyEverettModel> {
        self.model.clone_ref(py)
    }
    /// Every fitted output offset (one per offset column, output units).
    #[getter]
    fn offsets<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.offsets)
    }
    /// Weighted residual sum of squares of the data term.
    #[getter]
    fn rss(&self) -> f64 {
        self.rss
    }
    /// Weighted RMS residual (output units).
    #[getter]
    fn rms(&self) -> f64 {
        self.rms
    }
    /// Number of regression rows.
    #[getter]
    fn n_rows(&self) -> usize {
        self.n_rows
    }
    /// Pivoting iterations of the nonnegative solver.
    #[getter]
    fn iterations(&self) -> usize {
        self.iterations
    }
    /// The solver's passive set (unknowns off their bound): a warm start for `EverettRegression.fit`.
    #[getter]
    fn passive<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        PyArray1::from_slice(py, &self.passive)
    }
    /// Whether the nonnegative solve met its optimality conditions to 1e-9 (relative); false only when its
    /// coordinate-descent budget ran out, and the table is then the best point found.
    #[getter]
    fn converged(&self) -> bool {
        self.converged
    }
    /// The largest relative violation of the solve's optimality conditions.
    #[getter]
    fn kkt_violation(&self) -> f64 {
        self.kkt_violation
    }
    /// Condition-number estimate of the regularised normal equations on the unknowns off their bound (squared
    /// ratio of the largest to the smallest Cholesky pivot; inf when numerically singular).
    #[getter]
    fn condition(&self) -> f64 {
        self.condition
    }
    /// The fitted coefficient of the `drift` regressor (output units per regressor unit); None without one.
    #[getter]
    fn drift(&self) -> Option<f64> {
        self.drift
    }

    fn __repr__(&self) -> String {
        format!(
            "EverettFit(rms={:.4e} on {} rows, {} offset(s), {} solver iterations)",
            self.rms,
            self.n_rows,
            self.offsets.len(),
            self.iterations
        )
    }
}

fn fit_result(py: Python<'_>, fit: EverettFit) -> PyResult<PyEverettFit> {
    Ok(PyEverettFit {
        model: Py::new(py, PyEverettModel { inner: fit.model })?,
        offsets: fit.offsets,
        rss: fit.rss,
        rms: fit.rms,
        n_rows: fit.n_rows,
        iterations: fit.iterations,
        passive: fit.passive,
        converged: fit.converged,
        kkt_violation: fit.kkt_violation,
        condition: fit.condition,
        drift: fit.drift,
    })
}

/// The Everett-table least squares of `fit_everett` split into `folds` folds for cross-validation, the regressors
/// built once: `runs` is a list of `(u, y, weight, fold, offset_col, history, gain)` where `fold[i]` is the fold
/// holding sample `i` out (an integer; negative or `>= folds`: never held out) and `drift` one array per run as
/// in `fit_everett`. `score(smoothing)` fits each fold's training part and returns every fold's held-out
/// `(sse, weight)`: one warm-started nonnegative solve per fold and no pass over the data.
#[pyclass(name = "EverettFolds", module = "bmr._core")]
pub struct PyEverettFolds {
    inner: EverettFolds,
}

#[pymethods]
impl PyEverettFolds {
    #[new]
    #[pyo3(signature = (grid, runs, n_offsets=1, folds=3, *, drift=None))]
    #[allow(clippy::type_complexity)]
    fn new(
        py: Python<'_>,
        grid: Array<'_>,
        runs: Vec<(
            Array<'_>,
            Array<'_>,
            Array<'_>,
            Array<'_>,
            usize,
            Array<'_>,
            f64,
        )>,
        n_offsets: usize,
        folds: usize,
        drift: Option<Vec<Array<'_>>>,
    ) -> PyResult<Self> {
        let grid = EverettGrid::new(extract_f64_array(&grid, "grid")?)
            .map_err(|e| identification_err("Everett table cross-validation", e))?;
        let mut data = Vec::with_capacity(runs.len());
        for (i, (u, y, w, f, o, h, g)) in runs.into_iter().enumerate() {
            let fold: Vec<usize> = extract_f64_array(&f, &format!("runs[{i}] fold"))?
                .into_iter()
                .map(|x| {
                    if x.is_finite() && x >= 0.0 && x < folds as f64 {
                        x as usize
                    } else {
                        usize::MAX
                    }
                })
                .collect();
            data.push((
                extract_f64_array(&u, &format!("runs[{i}] input"))?,
                extract_f64_array(&y, &format!("runs[{i}] output"))?,
                extract_f64_array(&w, &format!("runs[{i}] weights"))?,
                fold,
                o,
                extract_f64_array(&h, &format!("runs[{i}] history"))?,
                g,
            ));
        }
        let drift = drift_columns(drift, data.len())?;
        let inner = py
            .detach(|| {
                let views: Vec<EverettFoldRun<'_>> = data
                    .iter()
                    .enumerate()
                    .map(|(k, (u, y, w, f, o, h, g))| EverettFoldRun {
                        u,
                        y,
                        weight: w,
                        fold: f,
                        offset_col: *o,
                        history: h,
                        gain: *g,
                        drift: drift.get(k).map_or(&[], Vec::as_slice),
                    })
                    .collect();
                EverettFolds::new(&grid, &views, n_offsets, folds)
            })
            .map_err(|e| identification_err("Everett table cross-validation", e))?;
        Ok(Self { inner })
    }

    /// Number of unknowns (cell masses, offsets, the drift coefficient).
    #[getter]
    fn n_unknowns(&self) -> usize {
        self.inner.n_unknowns()
    }

    /// Every fold's held-out `(sse, weight)` (output units², row weights) of the table fitted on the rest with
    /// this `smoothing` and `ridge`; each fold's solve is warm-started from its solve at the nearest smoothing,
    /// its first one from `warm_start` (a passive set of `n_unknowns` entries, e.g. a fit of the whole).
    #[pyo3(signature = (smoothing=1e-4, *, ridge=1e-9, max_iter=500, warm_start=None, signed=false,
                        diagonal_smoothing=0.0))]
    #[allow(clippy::too_many_arguments)]
    fn score(
        &mut self,
        py: Python<'_>,
        smoothing: f64,
        ridge: f64,
        max_iter: usize,
        warm_start: Option<Vec<bool>>,
        signed: bool,
        diagonal_smoothing: f64,
    ) -> PyResult<Vec<(f64, f64)>> {
        let options = EverettFitOptions {
            smoothing,
            ridge,
            max_iter,
            signed,
            diagonal_smoothing,
        };
        let inner = &mut self.inner;
        let scores = py
            .detach(|| inner.score(options, warm_start.as_deref()))
            .map_err(|e| identification_err("Everett table cross-validation", e))?;
        Ok(scores.iter().map(|s| (s.sse, s.weight)).collect())
    }
}

/// The Everett-table least squares of `fit_everett` prepared for one input history: `inputs` is a list of
/// `(u, weight, offset_col)`. The regressors and the regularised normal matrix are built once; `fit(outputs)`
/// then identifies the table for any outputs of the same runs (one array per run) at the cost of a right-hand
/// side and a nonnegative solve, optionally warm-started from an earlier result's `passive` set (same answer,
/// fewer iterations).
#[pyclass(name = "EverettRegression", module = "bmr._core", frozen)]
pub struct PyEverettRegression {
    inner: EverettRegression,
}

#[pymethods]
impl PyEverettRegression {
    #[new]
    #[pyo3(signature = (grid, inputs, n_offsets=1, *, smoothing=1e-4, ridge=1e-9, max_iter=500,
                        diagonal_smoothing=0.0))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        grid: Array<'_>,
        inputs: Vec<(Array<'_>, Array<'_>, usize)>,
        n_offsets: usize,
        smoothing: f64,
        ridge: f64,
        max_iter: usize,
        diagonal_smoothing: f64,
    ) -> PyResult<Self> {
        let grid = EverettGrid::new(extract_f64_array(&grid, "grid")?)
            .map_err(|e| identification_err("Everett table fit", e))?;
        let data: Vec<(Vec<f64>, Vec<f64>, usize)> = inputs
            .into_iter()
            .enumerate()
            .map(|(i, (u, w, o))| {
                Ok((
                    extract_f64_array(&u, &format!("inputs[{i}] input"))?,
                    extract_f64_array(&w, &format!("inputs[{i}] weights"))?,
                    o,
                ))
            })
            .collect::<PyResult<_>>()?;
        let options = EverettFitOptions {
            smoothing,
            ridge,
            max_iter,
            diagonal_smoothing,
            ..EverettFitOptions::default()
        };
        let inner = py
            .detach(|| {
                let views: Vec<EverettInput<'_>> = data
                    .iter()
                    .map(|(u, w, o)| EverettInput {
                        u,
                        weight: w,
                        offset_col: *o,
                    })
                    .collect();
                EverettRegression::new(&grid, &views, n_offsets, options)
            })
            .map_err(|e| identification_err("Everett table fit", e))?;
        Ok(Self { inner })
    }

    /// Number of regression rows.
    #[getter]
    fn n_rows(&self) -> usize {
        self.inner.n_rows()
    }

    /// Identify the table for `outputs` (one array per run); returns an `EverettFit`.
    #[pyo3(signature = (outputs, warm_start=None))]
    fn fit<'py>(
        &self,
        py: Python<'py>,
        outputs: Vec<Array<'py>>,
        warm_start: Option<Vec<bool>>,
    ) -> PyResult<PyEverettFit> {
        let ys: Vec<Vec<f64>> = outputs
            .iter()
            .enumerate()
            .map(|(i, y)| extract_f64_array(y, &format!("outputs[{i}]")))
            .collect::<PyResult<_>>()?;
        let fit = py
            .detach(|| {
                let views: Vec<&[f64]> = ys.iter().map(Vec::as_slice).collect();
                self.inner.fit(&views, warm_start.as_deref())
            })
            .map_err(|e| identification_err("Everett table fit", e))?;
        fit_result(py, fit)
    }

    fn __repr__(&self) -> String {
        format!("EverettRegression(rows={})", self.inner.n_rows())
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(fit_friction_order, m)?)?;
    m.add_function(wrap_pyfunction!(fit_everett, m)?)?;
    m.add_class::<PyEverettModel>()?;
    m.add_class::<PyEverettRegression>()?;
    m.add_class::<PyEverettFolds>()?;
    m.add_class::<PyEverettFit>()?;
    m.add_class::<PyFrictionOrderFit>()?;
    Ok(())
}
