//! The paper's inverse CBH (eq 17-20): an operator of the same structure whose input is torque and whose output
//! is current, built from the first-order *current* curves `I^a(T_min, T)`, `I^d(T_max, T)` obtained by inverting
//! each torque curve. It assumes the inverse is congruent too, which it is not in general: kept so that it can be
//! compared with the exact inverse on the same data.
use alloc::vec::Vec;

use crate::cbh::{Hysteresis, Initial};
use crate::error::TableError;
use crate::from_curves::CurveData;
use crate::table_builder::BuildOptions;

impl<const N: usize> Hysteresis<Vec<f64>, N> {
    /// Build the paper's inverse operator from this operator's first-order curves (axes swapped; flat stretches
    /// of a torque curve keep their first sample, curves that start at an already used torque are dropped).
    pub fn paper_inverse(&self) -> Result<Hysteresis<Vec<f64>, N>, TableError> {
        let (asc, desc) = self.current_curves();
        // Inverted curves end where the torque curves end; allow the table's closure slack.
        let opts = BuildOptions {
            reach_tolerance: 0.05,
            closure_tolerance: 0.1,
            ..BuildOptions::default()
        };
        Hysteresis::from_curve_data(&asc, &desc, &opts, Initial::Negative)
    }

    /// The paper's current curves `I^a(T_min, T)`, `I^d(T_max, T)` (eq 17-20): this operator's first-order curves
    /// with inputs and outputs swapped, in traversal order, torque strictly monotone along each curve.
    pub fn current_curves(&self) -> (Vec<CurveData>, Vec<CurveData>) {
        let (asc, desc) = self.curves();
        (swap_family(asc, 1.0), swap_family(desc, -1.0))
    }
}

/// Swap inputs and outputs of every curve; `sign` is the direction of the torque along the curve.
fn swap_family(curves: Vec<CurveData>, sign: f64) -> Vec<CurveData> {
    let mut out: Vec<CurveData> = Vec::with_capacity(curves.len());
    for (u, y) in curves {
        let (mut t, mut i) = (Vec::with_capacity(y.len()), Vec::with_capacity(u.len()));
        for (&cur, &torque) in u.iter().zip(&y) {
            if t.last()
                .is_none_or(|&last: &f64| sign * (torque - last) > 0.0)
            {
                t.push(torque);
                i.push(cur);
            }
        }
        if t.len() >= 2 && !out.iter().any(|(t0, _)| t0[0] == t[0]) {
            out.push((t, i));
        }
    }
    out
}
