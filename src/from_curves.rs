//! Owned operators built from measured curves, and the tables given back in the same form (for model files).
use alloc::vec::Vec;

use crate::cbh::{Hysteresis, Initial};
use crate::error::TableError;
use crate::table_builder::{BuildOptions, MeasuredCurve, build_tables};

/// A curve as owned `(inputs, outputs)`.
pub type CurveData = (Vec<f64>, Vec<f64>);

impl<const N: usize> Hysteresis<Vec<f64>, N> {
    /// Validate measured first-order curves and build the operator (see [`crate::table_builder`]).
    pub fn from_curves(
        ascending: &[MeasuredCurve<'_>],
        descending: &[MeasuredCurve<'_>],
        opts: &BuildOptions,
        initial: Initial,
    ) -> Result<Self, TableError> {
        let t = build_tables(ascending, descending, opts)?;
        Hysteresis::new(t.ascending, t.descending, t.y_lo, t.y_hi, initial)
    }

    /// [`Self::from_curves`] for owned curves (`(inputs, outputs)` vectors).
    pub fn from_curve_data(
        ascending: &[CurveData],
        descending: &[CurveData],
        opts: &BuildOptions,
        initial: Initial,
    ) -> Result<Self, TableError> {
        let a: Vec<MeasuredCurve<'_>> = ascending
            .iter()
            .map(|(u, y)| (u.as_slice(), y.as_slice()))
            .collect();
        let d: Vec<MeasuredCurve<'_>> = descending
            .iter()
            .map(|(u, y)| (u.as_slice(), y.as_slice()))
            .collect();
        Self::from_curves(&a, &d, opts, initial)
    }

    /// The stored tables as first-order curves `(ascending, descending)` in [`Self::from_curves`] form: each
    /// ascending curve on the grid from its reversal up, starting on the descending major branch; each
    /// descending curve from its reversal down, starting on the ascending major branch.
    pub fn curves(&self) -> (Vec<CurveData>, Vec<CurveData>) {
        let anchor = self.anchor;
        let mut hint = 0;
        // Major-branch outputs where the first-order curves leave them.
        let top_strip = self.desc.strip(-self.hi);
        let k_top =
            crate::cbh::branch_scale(self.y_hi - self.y_lo, self.desc.everett_max(&top_strip))
                .unwrap_or(1.0);
        let mut asc = Vec::with_capacity(self.asc.curves());
        for (j, &m) in self.asc.reversals().iter().enumerate() {
            let y0 = if j == 0 {
                self.y_lo
            } else {
                self.y_hi - k_top * self.desc.everett(&top_strip, -m, &mut hint)
            };
            let (u, y): (Vec<f64>, Vec<f64>) = self
                .asc
                .grid()
                .iter()
                .zip(self.asc.row(j))
                .filter(|&(&g, _)| g >= m)
                .map(|(&g, &e)| (g, y0 + e))
                .unzip();
            asc.push((u, y));
        }
        let mut desc = Vec::with_capacity(self.desc.curves());
        for (j, &v) in self.desc.reversals().iter().enumerate() {
            let y0 = if j == 0 {
                self.y_hi
            } else {
                self.y_lo + anchor.k * self.asc.everett(&anchor.strip, -v, &mut hint)
            };
            let (u, y): (Vec<f64>, Vec<f64>) = self
                .desc
                .grid()
                .iter()
                .zip(self.desc.row(j))
                .filter(|&(&g, _)| g >= v)
                .map(|(&g, &e)| (-g, y0 - e))
                .unzip();
            desc.push((u, y));
        }
        (asc, desc)
    }
}
