//! Building the internal Everett tables from *measured* first-order curves (needs `alloc`; done once).
//!
//! Each ascending curve is the `(u, y)` samples from its reversal minimum up to positive saturation; each
//! descending curve from its reversal maximum down to negative saturation. Samples need not share a grid.
//! The lowest ascending curve and the highest descending curve are the major branches; they fix the input range.
use alloc::vec::Vec;

use crate::error::{FamilyKind, TableError};
use crate::everett::Family;
use crate::limits::{self, MAX_CURVES, MAX_MAGNITUDE, MAX_NODES, MAX_TABLE_VALUES};

/// One measured curve: inputs and outputs in sample order, starting at the reversal point.
pub type MeasuredCurve<'a> = (&'a [f64], &'a [f64]);

/// Options for turning measured curves into tables.
#[derive(Debug, Clone, Copy)]
pub struct BuildOptions {
    /// Largest allowed move of the output against a curve's direction, as a fraction of the major-loop output
    /// span (measured curves are noisy). Allowed dips are removed by a running maximum (minimum).
    pub monotone_tolerance: f64,
    /// How far short of saturation a curve may stop, as a fraction of the input span; the rest is held flat.
    pub reach_tolerance: f64,
    /// How far the major branches may disagree at the saturations, as a fraction of the output span.
    pub closure_tolerance: f64,
    /// Above this many distinct sample inputs the grid is resampled uniformly to this many nodes
    /// (8 to [`MAX_NODES`]).
    pub max_nodes: usize,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            monotone_tolerance: 0.005,
            reach_tolerance: 0.01,
            closure_tolerance: 0.05,
            max_nodes: 1024,
        }
    }
}

/// Both families as owned tables plus the major-loop end points.
#[derive(Debug, Clone)]
pub struct BuiltTables {
    pub ascending: Family<Vec<f64>>,
    pub descending: Family<Vec<f64>>,
    /// Output at negative saturation (start of the ascending major branch).
    pub y_lo: f64,
    /// Output at positive saturation (start of the descending major branch).
    pub y_hi: f64,
}

/// Validate the measured curves and build the tables. Errors name the family, curve and sample.
///
/// Sizes are bounded before anything is allocated: at most [`MAX_CURVES`] curves per family, `max_nodes` at most
/// [`MAX_NODES`], at most [`MAX_TABLE_VALUES`] values (curves × grid nodes) per family; inputs and outputs
/// within ±[`MAX_MAGNITUDE`].
pub fn build_tables(
    ascending: &[MeasuredCurve<'_>],
    descending: &[MeasuredCurve<'_>],
    opts: &BuildOptions,
) -> Result<BuiltTables, TableError> {
    use FamilyKind::{Ascending, Descending};
    for (p, name) in [
        (opts.monotone_tolerance, "monotone_tolerance"),
        (opts.reach_tolerance, "reach_tolerance"),
        (opts.closure_tolerance, "closure_tolerance"),
    ] {
        if !(p.is_finite() && p >= 0.0) {
            return Err(TableError::BadParameter { name, value: p });
        }
    }
    if opts.max_nodes < 8 {
        return Err(TableError::BadParameter {
            name: "max_nodes",
            value: opts.max_nodes as f64,
        });
    }
    limits::check("max_nodes", opts.max_nodes, MAX_NODES).map_err(|limit| {
        TableError::TooLarge {
            family: None,
            limit,
        }
    })?;
    check_shape(ascending, Ascending)?;
    check_shape(descending, Descending)?;
    // Rising orientation: descending curves mirrored (v = -u, increments positive).
    let asc: Vec<Curve> = ascending
        .iter()
        .map(|&(u, y)| Curve::rising(u, y, 1.0))
        .collect();
    let desc: Vec<Curve> = descending
        .iter()
        .map(|&(u, y)| Curve::rising(u, y, -1.0))
        .collect();
    check_inputs(&asc, Ascending)?;
    check_inputs(&desc, Descending)?;

    let a_major = argmin_start(&asc);
    let d_major = argmin_start(&desc);
    let lo = asc[a_major].u[0];
    let hi = -desc[d_major].u[0];
    let y_lo = asc[a_major].y0;
    let y_hi = desc[d_major].y0;
    if hi <= lo {
        return Err(TableError::ReversalOutOfRange {
            family: Descending,
            curve: d_major,
            input: hi,
            lo,
            hi: lo,
        });
    }
    if y_hi <= y_lo {
        return Err(TableError::NoOutputSpan { lo: y_lo, hi: y_hi });
    }
    let span_y = y_hi - y_lo;
    let tol_u = opts.reach_tolerance * (hi - lo);

    check_range_and_reach(&asc, Ascending, lo, hi, tol_u)?;
    check_range_and_reach(&desc, Descending, -hi, -lo, tol_u)?;
    check_outputs(&asc, Ascending, opts.monotone_tolerance * span_y)?;
    check_outputs(&desc, Descending, opts.monotone_tolerance * span_y)?;

    // The major branches must meet at both saturations (within tolerance).
    let a_top = y_lo + asc[a_major].increment_at(hi);
    let d_bottom = y_hi - desc[d_major].increment_at(-lo);
    let tol_close = opts.closure_tolerance * span_y;
    if (a_top - y_hi).abs() > tol_close {
        return Err(TableError::MajorLoopOpen {
            at_input: hi,
            ascending: a_top,
            descending: y_hi,
        });
    }
    if (d_bottom - y_lo).abs() > tol_close {
        return Err(TableError::MajorLoopOpen {
            at_input: lo,
            ascending: y_lo,
            descending: d_bottom,
        });
    }

    let ascending = build_family(&asc, lo, hi, opts.max_nodes, Ascending)?;
    let descending = build_family(&desc, -hi, -lo, opts.max_nodes, Descending)?;
    Ok(BuiltTables {
        ascending,
        descending,
        y_lo,
        y_hi,
    })
}

/// A measured curve in rising orientation: `u` increasing, `e` the increment from the first sample.
struct Curve {
    u: Vec<f64>,
    e: Vec<f64>,
    y0: f64,
}

impl Curve {
    fn rising(u: &[f64], y: &[f64], sign: f64) -> Curve {
        let y0 = y[0];
        Curve {
            u: u.iter().map(|&x| sign * x).collect(),
            e: y.iter().map(|&v| sign * (v - y0)).collect(),
            y0,
        }
    }

    /// Increment at input `x` by linear interpolation, held flat past the last sample.
    fn increment_at(&self, x: f64) -> f64 {
        let n = self.u.len();
        if x <= self.u[0] {
            return 0.0;
        }
        if x >= self.u[n - 1] {
            return self.e[n - 1];
        }
        let k = self.u.partition_point(|&v| v <= x) - 1;
        let t = (x - self.u[k]) / (self.u[k + 1] - self.u[k]);
        self.e[k] + t * (self.e[k + 1] - self.e[k])
    }
}

fn check_shape(curves: &[MeasuredCurve<'_>], family: FamilyKind) -> Result<(), TableError> {
    if curves.len() < 2 {
        return Err(TableError::TooFewCurves {
            family,
            curves: curves.len(),
        });
    }
    limits::check("number of curves", curves.len(), MAX_CURVES).map_err(|limit| {
        TableError::TooLarge {
            family: Some(family),
            limit,
        }
    })?;
    for (c, &(u, y)) in curves.iter().enumerate() {
        if u.len() != y.len() || u.len() < 2 {
            return Err(TableError::BadLength {
                family,
                curve: c,
                inputs: u.len(),
                outputs: y.len(),
            });
        }
        if let Some(s) = u
            .iter()
            .zip(y)
            .position(|(a, b)| !a.is_finite() || !b.is_finite())
        {
            return Err(TableError::NonFinite {
                family,
                curve: c,
                sample: s,
            });
        }
        for (what, values) in [("input", u), ("output", y)] {
            if let Some(s) = values.iter().position(|v| v.abs() > MAX_MAGNITUDE) {
                return Err(TableError::OutOfRange {
                    family,
                    curve: c,
                    sample: s,
                    what,
                    value: values[s],
                });
            }
        }
    }
    Ok(())
}

fn check_inputs(curves: &[Curve], family: FamilyKind) -> Result<(), TableError> {
    let sign = if family == FamilyKind::Ascending {
        1.0
    } else {
        -1.0
    };
    for (c, curve) in curves.iter().enumerate() {
        if let Some(s) = curve.u.windows(2).position(|w| w[1] <= w[0]) {
            return Err(TableError::InputNotMonotone {
                family,
                curve: c,
                sample: s + 1,
                previous: sign * curve.u[s],
                value: sign * curve.u[s + 1],
            });
        }
    }
    let order = by_reversal(curves);
    for w in order.windows(2) {
        if curves[w[0]].u[0] == curves[w[1]].u[0] {
            let (a, b) = (w[0].min(w[1]), w[0].max(w[1]));
            return Err(TableError::DuplicateReversal {
                family,
                curve: b,
                other: a,
                input: sign * curves[a].u[0],
            });
        }
    }
    Ok(())
}

/// Curve indices sorted by reversal input (rising orientation); ties keep the user's order.
fn by_reversal(curves: &[Curve]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..curves.len()).collect();
    order.sort_by(|&a, &b| curves[a].u[0].total_cmp(&curves[b].u[0]));
    order
}

fn argmin_start(curves: &[Curve]) -> usize {
    let mut best = 0;
    for (i, c) in curves.iter().enumerate() {
        if c.u[0] < curves[best].u[0] {
            best = i;
        }
    }
    best
}

fn check_range_and_reach(
    curves: &[Curve],
    family: FamilyKind,
    lo: f64,
    hi: f64,
    tol_u: f64,
) -> Result<(), TableError> {
    let sign = if family == FamilyKind::Ascending {
        1.0
    } else {
        -1.0
    };
    for (c, curve) in curves.iter().enumerate() {
        let start = curve.u[0];
        if start < lo || start >= hi {
            let (a, b) = if sign > 0.0 { (lo, hi) } else { (-hi, -lo) };
            return Err(TableError::ReversalOutOfRange {
                family,
                curve: c,
                input: sign * start,
                lo: a,
                hi: b,
            });
        }
        let end = *curve.u.last().unwrap_or(&start);
        if end < hi - tol_u {
            return Err(TableError::ShortCurve {
                family,
                curve: c,
                reaches: sign * end,
                needed: sign * hi,
            });
        }
    }
    Ok(())
}

fn check_outputs(curves: &[Curve], family: FamilyKind, tolerance: f64) -> Result<(), TableError> {
    for (c, curve) in curves.iter().enumerate() {
        let mut peak = curve.e[0];
        for (s, &v) in curve.e.iter().enumerate() {
            if peak - v > tolerance {
                return Err(TableError::OutputNotMonotone {
                    family,
                    curve: c,
                    sample: s,
                    drop: peak - v,
                    tolerance,
                });
            }
            peak = peak.max(v);
        }
    }
    Ok(())
}

/// Shared grid: every sample input and reversal inside `[lo, hi]` (or a uniform grid plus the reversals when there
/// are too many), then each curve's running-maximum increments at the nodes.
fn build_family(
    curves: &[Curve],
    lo: f64,
    hi: f64,
    max_nodes: usize,
    kind: FamilyKind,
) -> Result<Family<Vec<f64>>, TableError> {
    let order = by_reversal(curves);
    let reversals: Vec<f64> = order.iter().map(|&i| curves[i].u[0]).collect();
    // Nodes closer than this are merged; reversals must stay apart by more (and from saturation).
    let eps = 1e-12 * (hi - lo);
    let sign = if kind == FamilyKind::Ascending {
        1.0
    } else {
        -1.0
    };
    for w in order.windows(2) {
        let (a, b) = (curves[w[0]].u[0], curves[w[1]].u[0]);
        if b - a <= eps {
            let (first, second) = (w[0].min(w[1]), w[0].max(w[1]));
            return Err(TableError::ReversalsTooClose {
                family: kind,
                curve: second,
                input: sign * curves[second].u[0],
                other: first,
                other_input: sign * curves[first].u[0],
                resolution: eps,
            });
        }
    }
    if let Some(&top) = order.last()
        && hi - curves[top].u[0] <= eps
    {
        return Err(TableError::ReversalAtSaturation {
            family: kind,
            curve: top,
            input: sign * curves[top].u[0],
            saturation: sign * hi,
        });
    }

    let mut grid: Vec<f64> = curves
        .iter()
        .flat_map(|c| c.u.iter().copied())
        .filter(|&x| x > lo && x < hi)
        .collect();
    grid.sort_by(f64::total_cmp);
    grid.dedup();
    if grid.len() + reversals.len() + 2 > max_nodes {
        let n = max_nodes.saturating_sub(reversals.len()).max(8);
        grid = (1..n - 1)
            .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
            .collect();
    }
    grid.extend_from_slice(&reversals);
    grid.push(lo);
    grid.push(hi);
    grid.sort_by(f64::total_cmp);
    // Merge nodes closer than round-off, keeping reversals exact.
    let mut merged: Vec<f64> = Vec::with_capacity(grid.len());
    for x in grid {
        match merged.last_mut() {
            Some(last) if x - *last <= eps => {
                // Reversals and the range ends must stay exact nodes.
                if x == hi || reversals.binary_search_by(|r| r.total_cmp(&x)).is_ok() {
                    *last = x;
                }
            }
            _ => merged.push(x),
        }
    }
    let nodes = merged.len();
    let values = limits::check(
        "table size (curves × grid nodes)",
        limits::product(curves.len(), nodes),
        MAX_TABLE_VALUES,
    )
    .map_err(|limit| TableError::TooLarge {
        family: Some(kind),
        limit,
    })?;
    let mut data = Vec::with_capacity(nodes + curves.len() + values);
    data.extend_from_slice(&merged);
    data.extend_from_slice(&reversals);
    for &i in &order {
        let curve = &curves[i];
        let mut peak = 0.0f64;
        for &x in &merged {
            let v = if x <= curve.u[0] {
                0.0
            } else {
                curve.increment_at(x).max(0.0)
            };
            peak = peak.max(v);
            data.push(peak);
        }
    }
    Family::new(data, nodes, curves.len(), kind)
}
