//! Owned operators built from measured curves, and the tables given back in the same form (for model files).
use alloc::vec::Vec;

use crate::cbh::{Hysteresis, Initial};
use crate::error::TableError;
use crate::everett::Family;
use crate::table_builder::{
    BuildOptions, BuildReport, FamilyNodes, MeasuredCurve, build_tables, select_family_nodes,
};

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
        Self::from_curves_reported(ascending, descending, opts, initial).map(|(h, _)| h)
    }

    /// [`Self::from_curves`], also returning what the build measured, fitted and derived.
    pub fn from_curves_reported(
        ascending: &[MeasuredCurve<'_>],
        descending: &[MeasuredCurve<'_>],
        opts: &BuildOptions,
        initial: Initial,
    ) -> Result<(Self, BuildReport), TableError> {
        let t = build_tables(ascending, descending, opts)?;
        let h = Hysteresis::new(t.ascending, t.descending, t.y_lo, t.y_hi, initial)?;
        Ok((h, t.report))
    }

    /// [`Self::from_curves`] for owned curves (`(inputs, outputs)` vectors).
    pub fn from_curve_data(
        ascending: &[CurveData],
        descending: &[CurveData],
        opts: &BuildOptions,
        initial: Initial,
    ) -> Result<Self, TableError> {
        Self::from_curve_data_reported(ascending, descending, opts, initial).map(|(h, _)| h)
    }

    /// [`Self::from_curve_data`], also returning the build report.
    pub fn from_curve_data_reported(
        ascending: &[CurveData],
        descending: &[CurveData],
        opts: &BuildOptions,
        initial: Initial,
    ) -> Result<(Self, BuildReport), TableError> {
        let a: Vec<MeasuredCurve<'_>> = ascending
            .iter()
            .map(|(u, y)| (u.as_slice(), y.as_slice()))
            .collect();
        let d: Vec<MeasuredCurve<'_>> = descending
            .iter()
            .map(|(u, y)| (u.as_slice(), y.as_slice()))
            .collect();
        Self::from_curves_reported(&a, &d, opts, initial)
    }

    /// The same operator on fewer nodes (for a firmware export with its own error bound): a node of either
    /// family is dropped only where linear interpolation of every curve stays within `tolerance` (a fraction of
    /// the output span), at most `max_nodes` per family (the tolerance is raised if needed). Returns the new
    /// operator (after negative saturation) and the node grids it got, with the bound used and reached.
    pub fn compressed(
        &self,
        tolerance: f64,
        max_nodes: usize,
    ) -> Result<(Self, [FamilyNodes; 2]), TableError> {
        if !(tolerance.is_finite() && tolerance >= 0.0) {
            return Err(TableError::BadParameter {
                name: "tolerance",
                value: tolerance,
            });
        }
        if max_nodes < 2 {
            return Err(TableError::BadParameter {
                name: "max_nodes",
                value: max_nodes as f64,
            });
        }
        let tol = tolerance * (self.y_hi - self.y_lo);
        let shrink = |f: &Family<Vec<f64>>| {
            let rows: Vec<Vec<f64>> = (0..f.curves()).map(|j| f.row(j).to_vec()).collect();
            select_family_nodes(f.grid(), f.reversals(), &rows, tol, max_nodes, f.kind())
        };
        let (a, an) = shrink(&self.asc)?;
        let (d, dn) = shrink(&self.desc)?;
        let h = Hysteresis::new(a, d, self.y_lo, self.y_hi, Initial::Negative)?;
        Ok((h, [an, dn]))
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
