//! `bmr.TableReport` / `bmr.CurveReport`: what building tables from measured curves measured, fitted and derived.
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::congruency::Congruency;
use crate::derived_family::MajorSource;
use crate::error::FamilyKind;
use crate::table_builder::{BuildReport, CurveReport, FamilyNodes};

fn family_name(f: FamilyKind) -> &'static str {
    match f {
        FamilyKind::Ascending => "ascending",
        FamilyKind::Descending => "descending",
    }
}

/// One measured curve: how far its data moved against the curve's direction and what the monotone fit changed
/// (output units for outputs, input units for inputs).
#[pyclass(name = "CurveReport", module = "bmr", frozen, get_all)]
#[derive(Clone)]
pub(crate) struct PyCurveReport {
    /// "ascending" or "descending".
    family: &'static str,
    /// Index of the curve as given.
    curve: usize,
    samples: usize,
    /// Reversal input (the curve's first sample).
    reversal: f64,
    /// Largest move of the output against the curve's direction (>= 0).
    violation: f64,
    /// Sample (as given) at the bottom of that move, and its input.
    violation_sample: usize,
    violation_input: f64,
    /// RMS change made by the monotone fit.
    reshaped_rms: f64,
    /// Largest step of the input against the curve's direction.
    input_backtrack: f64,
}

impl From<&CurveReport> for PyCurveReport {
    fn from(c: &CurveReport) -> Self {
        PyCurveReport {
            family: family_name(c.family),
            curve: c.curve,
            samples: c.samples,
            reversal: c.reversal,
            violation: c.violation,
            violation_sample: c.violation_sample,
            violation_input: c.violation_input,
            reshaped_rms: c.reshaped_rms,
            input_backtrack: c.input_backtrack,
        }
    }
}

#[pymethods]
impl PyCurveReport {
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("family", self.family)?;
        d.set_item("curve", self.curve)?;
        d.set_item("samples", self.samples)?;
        d.set_item("reversal", self.reversal)?;
        d.set_item("violation", self.violation)?;
        d.set_item("violation_sample", self.violation_sample)?;
        d.set_item("violation_input", self.violation_input)?;
        d.set_item("reshaped_rms", self.reshaped_rms)?;
        d.set_item("input_backtrack", self.input_backtrack)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "CurveReport({} curve {} from {}: {} samples, moves against its direction by {} at sample {} \
             (input {}), monotone fit changed it by {} RMS, input steps back by {})",
            self.family,
            self.curve,
            crate::python::sig(self.reversal, 6),
            self.samples,
            crate::python::sig(self.violation, 4),
            self.violation_sample,
            crate::python::sig(self.violation_input, 6),
            crate::python::sig(self.reshaped_rms, 4),
            crate::python::sig(self.input_backtrack, 4)
        )
    }
}

/// What `Hysteresis.from_curves` measured, fitted and derived: per-curve violations, the derived family (if
/// one family was built from the other), the node grids with their error bound, and the family mismatch when
/// both families were measured. Output quantities are in the curves' output units.
#[pyclass(name = "TableReport", module = "bmr", frozen)]
#[derive(Clone)]
pub(crate) struct PyTableReport {
    pub(crate) inner: BuildReport,
}

fn nodes_dict<'py>(py: Python<'py>, n: &FamilyNodes) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("inputs", n.inputs)?;
    d.set_item("nodes", n.nodes)?;
    d.set_item("tolerance", n.tolerance)?;
    d.set_item("error", n.error)?;
    Ok(d)
}

pub(crate) fn congruency_dict<'py>(
    py: Python<'py>,
    c: &Congruency,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("max_abs", c.max_abs)?;
    d.set_item("rms", c.rms)?;
    d.set_item("pairs", c.pairs)?;
    Ok(d)
}

#[pymethods]
impl PyTableReport {
    /// One `CurveReport` per measured curve (ascending first).
    #[getter]
    fn curves(&self) -> Vec<PyCurveReport> {
        self.inner.curves.iter().map(PyCurveReport::from).collect()
    }

    /// The measured curve with the largest move against its direction, or None.
    #[getter]
    fn worst_violation(&self) -> Option<PyCurveReport> {
        self.inner.worst_violation().map(PyCurveReport::from)
    }

    /// "ascending" or "descending" if that family was derived from the other one, else None.
    #[getter]
    fn derived(&self) -> Option<&'static str> {
        self.inner.derived.map(|d| family_name(d.family))
    }

    /// How the derived family's opposite major branch was obtained: "measured" or "reversal points" (None if
    /// nothing was derived).
    #[getter]
    fn derived_major(&self) -> Option<&'static str> {
        self.inner.derived.map(|d| match d.major {
            MajorSource::Measured => "measured",
            MajorSource::ReversalPoints => "reversal points",
        })
    }

    /// Curves in the derived family (0 if none).
    #[getter]
    fn derived_curves(&self) -> usize {
        self.inner.derived.map_or(0, |d| d.curves)
    }

    /// Largest correction that kept the derived curves monotone (output units; 0 for Preisach data).
    #[getter]
    fn derived_adjustment(&self) -> f64 {
        self.inner.derived.map_or(0.0, |d| d.adjusted)
    }

    /// `(ascending, descending)` curves added between measured reversals from the calibrated strip shapes.
    #[getter]
    fn densified(&self) -> (usize, usize) {
        (self.inner.densified[0], self.inner.densified[1])
    }

    /// `(ascending, descending)` nodes kept.
    #[getter]
    fn nodes(&self) -> (usize, usize) {
        (self.inner.ascending.nodes, self.inner.descending.nodes)
    }

    /// `(ascending, descending)` distinct inputs before node selection.
    #[getter]
    fn inputs(&self) -> (usize, usize) {
        (self.inner.ascending.inputs, self.inner.descending.inputs)
    }

    /// `(ascending, descending)` node tolerance used (output units): a node was dropped only where linear
    /// interpolation stays within it.
    #[getter]
    fn node_tolerance(&self) -> (f64, f64) {
        (
            self.inner.ascending.tolerance,
            self.inner.descending.tolerance,
        )
    }

    /// `(ascending, descending)` largest interpolation error at a dropped node (output units).
    #[getter]
    fn node_error(&self) -> (f64, f64) {
        (self.inner.ascending.error, self.inner.descending.error)
    }

    /// Family mismatch at pairs of measured reversals when both families were measured (`max_abs`, `rms`,
    /// `pairs`), else None.
    #[getter]
    fn mismatch<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        self.inner
            .mismatch
            .as_ref()
            .map(|c| congruency_dict(py, c))
            .transpose()
    }

    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let curves: Vec<Bound<'py, PyDict>> = self
            .curves()
            .iter()
            .map(|c| c.to_dict(py))
            .collect::<PyResult<_>>()?;
        d.set_item("curves", PyList::new(py, curves)?)?;
        d.set_item("derived", self.derived())?;
        d.set_item("derived_major", self.derived_major())?;
        d.set_item("derived_curves", self.derived_curves())?;
        d.set_item("derived_adjustment", self.derived_adjustment())?;
        let nodes = PyDict::new(py);
        nodes.set_item("ascending", nodes_dict(py, &self.inner.ascending)?)?;
        nodes.set_item("descending", nodes_dict(py, &self.inner.descending)?)?;
        d.set_item("nodes", nodes)?;
        d.set_item("mismatch", self.mismatch(py)?)?;
        d.set_item("densified", self.densified())?;
        d.set_item("densify_adjustment", self.inner.densify_adjusted)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        let r = &self.inner;
        let mut s = format!(
            "TableReport({} measured curves; nodes {}/{} of {}/{} inputs, bound {}/{}, reached {}/{}",
            r.curves.len(),
            r.ascending.nodes,
            r.descending.nodes,
            r.ascending.inputs,
            r.descending.inputs,
            crate::python::sig(r.ascending.tolerance, 3),
            crate::python::sig(r.descending.tolerance, 3),
            crate::python::sig(r.ascending.error, 3),
            crate::python::sig(r.descending.error, 3)
        );
        if let Some(d) = r.derived {
            s += &format!(
                "; {} family derived ({} curves, opposite major branch {}, adjusted by {})",
                family_name(d.family),
                d.curves,
                match d.major {
                    MajorSource::Measured => "measured",
                    MajorSource::ReversalPoints => "from reversal points",
                },
                crate::python::sig(d.adjusted, 3)
            );
        }
        if r.densified != [0, 0] {
            s += &format!(
                "; {}/{} curves added between measured reversals",
                r.densified[0], r.densified[1]
            );
        }
        if let Some(m) = r.mismatch {
            s += &format!(
                "; family mismatch max {}, RMS {}",
                crate::python::sig(m.max_abs, 4),
                crate::python::sig(m.rms, 4)
            );
        }
        match r.worst_violation() {
            Some(w) => {
                s += &format!(
                    "; largest move against a curve's direction {} ({} curve {}, sample {})",
                    crate::python::sig(w.violation, 4),
                    family_name(w.family),
                    w.curve,
                    w.violation_sample
                )
            }
            None => s += "; every curve monotone",
        }
        s + ")"
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyTableReport>()?;
    m.add_class::<PyCurveReport>()?;
    Ok(())
}
