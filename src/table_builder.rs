//! Building the internal Everett tables from *measured* first-order curves (needs `alloc`; done once).
//!
//! Each ascending curve is the `(u, y)` samples from its reversal minimum up to positive saturation; each
//! descending curve from its reversal maximum down to negative saturation. Samples need not share a grid, need
//! not be monotone and need not be clean:
//!
//! - **Real curves are accepted, measured and fitted.** Samples are sorted by input (equal inputs averaged) and
//!   the outputs get their least-squares monotone fit. How far each curve's data moved against its direction, and
//!   how much the fit changed them, is in the [`BuildReport`]. Only a move larger than `monotone_tolerance` of the
//!   span (not a first-order curve of that family at all) is an error.
//! - **Nodes by an error bound.** The grid starts from every sample input; a node is dropped only where linear
//!   interpolation of every curve stays within `node_tolerance` (a fraction of the output span). A node budget
//!   (`max_nodes`) raises the tolerance if needed; the bound used and the error incurred are reported.
//! - **One family is enough.** Under congruency (a Preisach system) one family plus the opposite major branch
//!   determines the other: with one family of at least two curves and at most one curve of the other (its major
//!   branch; without it, the measured curves' reversal points trace it), the other family is derived
//!   ([`crate::derived_family`]) and the report says so.
//!
//! The lowest ascending curve and the highest descending curve are the major branches; they fix the input range.
use alloc::vec::Vec;

use crate::congruency::{Congruency, congruency};
use crate::curve_fit::monotone_curve;
use crate::derived_family::{
    DerivedFamily, MajorSource, densify_family, densify_with_family, derive_family,
};
use crate::error::{FamilyKind, TableError};
use crate::everett::{Family, family_len};
use crate::limits::{self, MAX_CURVES, MAX_MAGNITUDE, MAX_NODES, MAX_TABLE_VALUES};
use crate::node_selection::{interpolation_error, select_nodes_within};

/// One measured curve: inputs and outputs in sample order, starting at the reversal point.
pub type MeasuredCurve<'a> = (&'a [f64], &'a [f64]);

/// Options for turning measured curves into tables.
#[derive(Debug, Clone, Copy)]
pub struct BuildOptions {
    /// Largest move of a curve against its direction accepted as real data, as a fraction of the major-loop span
    /// (output) or input range (input). Smaller moves are measured, reported and fitted monotonically; larger ones
    /// mean the curve does not belong to that family.
    pub monotone_tolerance: f64,
    /// How far short of saturation a curve may stop, as a fraction of the input span; the rest is held flat.
    pub reach_tolerance: f64,
    /// How far the major branches may disagree at the saturations, as a fraction of the output span.
    pub closure_tolerance: f64,
    /// Grid nodes are dropped only where linear interpolation of every curve stays within this fraction of the
    /// output span (default 0: only nodes on straight stretches).
    pub node_tolerance: f64,
    /// Upper bound on grid nodes per family (8 to [`MAX_NODES`]); the node tolerance is raised (and reported)
    /// when the data need more.
    pub max_nodes: usize,
    /// Curves per interval between measured reversals: `k > 1` adds `k − 1` curves to a measured family from
    /// the strip shapes the opposite family calibrates, and gives a derived family `k` reversals per interval.
    /// The default 1 keeps the measured curves as they are (`from_curves(h.curves())` rebuilds `h` exactly).
    pub subdivisions: usize,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            monotone_tolerance: 0.25,
            reach_tolerance: 0.01,
            closure_tolerance: 0.05,
            node_tolerance: 0.0,
            max_nodes: 16384,
            subdivisions: 1,
        }
    }
}

/// What building did to one measured curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurveReport {
    pub family: FamilyKind,
    /// Index of the curve as given.
    pub curve: usize,
    pub samples: usize,
    /// Reversal input (the curve's first sample).
    pub reversal: f64,
    /// Largest move of the output against the curve's direction (output units, >= 0).
    pub violation: f64,
    /// Sample (as given) at the bottom of that move.
    pub violation_sample: usize,
    /// Input at that sample.
    pub violation_input: f64,
    /// RMS change made by the monotone fit (output units).
    pub reshaped_rms: f64,
    /// Largest step of the input against the curve's direction (input units, >= 0).
    pub input_backtrack: f64,
}

/// How a family was derived from the other one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Derivation {
    /// The derived family.
    pub family: FamilyKind,
    /// Where the opposite major branch came from.
    pub major: MajorSource,
    /// Curves in the derived family.
    pub curves: usize,
    /// Largest correction needed to keep the derived curves monotone (output units; zero for Preisach data).
    pub adjusted: f64,
}

/// The node grid of one family.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FamilyNodes {
    /// Distinct inputs before node selection.
    pub inputs: usize,
    /// Nodes kept.
    pub nodes: usize,
    /// Tolerance used (output units): the requested one, or the one the node budget forced.
    pub tolerance: f64,
    /// Largest interpolation error at a dropped node (output units, <= tolerance).
    pub error: f64,
}

/// Everything the build measured, changed or derived.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildReport {
    /// One entry per measured curve, ascending first.
    pub curves: Vec<CurveReport>,
    /// Set when one family was derived from the other.
    pub derived: Option<Derivation>,
    /// Ascending family grid.
    pub ascending: FamilyNodes,
    /// Descending family grid.
    pub descending: FamilyNodes,
    /// Mismatch between the families at pairs of measured reversals when both were measured (zero for exactly
    /// congruent data).
    pub mismatch: Option<Congruency>,
    /// Curves added between the measured reversals of `[ascending, descending]` from the strip shapes the opposite
    /// major branch calibrates (`subdivisions`; zero when not measured or not densified).
    pub densified: [usize; 2],
    /// Largest correction that kept those added curves monotone (output units).
    pub densify_adjusted: f64,
}

impl BuildReport {
    /// The curve with the largest output violation, if any curve moved against its direction.
    pub fn worst_violation(&self) -> Option<&CurveReport> {
        self.curves
            .iter()
            .filter(|c| c.violation > 0.0)
            .max_by(|a, b| a.violation.total_cmp(&b.violation))
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
    pub report: BuildReport,
}

/// Validate the measured curves, fit them and build the tables. Errors name the family, curve and sample.
///
/// Sizes are bounded before anything is allocated: at most [`MAX_CURVES`] curves per family, `max_nodes` at most
/// [`MAX_NODES`], at most [`MAX_TABLE_VALUES`] values (curves × grid nodes) per family, also while the grid still
/// holds every sample input; inputs and outputs within ±[`MAX_MAGNITUDE`].
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
        (opts.node_tolerance, "node_tolerance"),
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
    if opts.subdivisions == 0 || opts.subdivisions > 64 {
        return Err(TableError::BadParameter {
            name: "subdivisions",
            value: opts.subdivisions as f64,
        });
    }
    check_shape(ascending, Ascending)?;
    check_shape(descending, Descending)?;
    let (na, nd) = (ascending.len(), descending.len());
    let derive = match (na >= 2, nd >= 2) {
        (true, true) => None,
        (true, false) => Some(Descending),
        (false, true) => Some(Ascending),
        (false, false) => {
            return Err(TableError::NotEnoughCurves {
                ascending: na,
                descending: nd,
            });
        }
    };
    let input_span = input_span(ascending, descending);
    // Rising orientation: descending curves mirrored (v = -u, increments positive).
    let (asc, asc_reports) = prepare(ascending, Ascending, opts, input_span)?;
    let (desc, desc_reports) = prepare(descending, Descending, opts, input_span)?;
    check_duplicates(&asc, Ascending)?;
    check_duplicates(&desc, Descending)?;

    // Major branches and the range: measured where available, else from the other family's curves.
    let a_major = (!asc.is_empty()).then(|| argmin_start(&asc));
    let d_major = (!desc.is_empty()).then(|| argmin_start(&desc));
    let lo = match (a_major, d_major) {
        (Some(a), _) => asc[a].u[0],
        (None, Some(_)) => -desc
            .iter()
            .map(Curve::end)
            .fold(f64::NEG_INFINITY, f64::max),
        (None, None) => unreachable!("one family has at least two curves"),
    };
    let hi = match (d_major, a_major) {
        (Some(d), _) => -desc[d].u[0],
        (None, Some(_)) => asc.iter().map(Curve::end).fold(f64::NEG_INFINITY, f64::max),
        (None, None) => unreachable!("one family has at least two curves"),
    };
    if hi <= lo {
        return Err(TableError::ReversalOutOfRange {
            family: if d_major.is_some() {
                Descending
            } else {
                Ascending
            },
            curve: d_major.unwrap_or(0),
            input: hi,
            lo,
            hi: lo,
        });
    }
    // A family given as one curve is its major branch: it must start where the other family saturates.
    let reach = opts.reach_tolerance * (hi - lo);
    if derive == Some(Descending) && d_major.is_some() {
        let end = asc.iter().map(Curve::end).fold(f64::NEG_INFINITY, f64::max);
        if hi < end - reach {
            return Err(TableError::NotAMajorBranch {
                family: Descending,
                start: hi,
                saturation: end,
            });
        }
    }
    if derive == Some(Ascending) && a_major.is_some() {
        let end = -desc
            .iter()
            .map(Curve::end)
            .fold(f64::NEG_INFINITY, f64::max);
        if lo > end + reach {
            return Err(TableError::NotAMajorBranch {
                family: Ascending,
                start: lo,
                saturation: end,
            });
        }
    }
    let (y_lo, y_hi) = match (a_major, d_major) {
        (Some(a), Some(d)) => (asc[a].y0, desc[d].y0),
        (Some(a), None) => (asc[a].y0, asc[a].y0 + asc[a].increment_at(hi)),
        (None, Some(d)) => (desc[d].y0 - desc[d].increment_at(-lo), desc[d].y0),
        (None, None) => unreachable!("one family has at least two curves"),
    };
    if y_hi.is_nan() || y_lo.is_nan() || y_hi <= y_lo {
        return Err(TableError::NoOutputSpan { lo: y_lo, hi: y_hi });
    }
    let span_y = y_hi - y_lo;
    let tol_u = opts.reach_tolerance * (hi - lo);
    check_range_and_reach(&asc, Ascending, lo, hi, tol_u)?;
    check_range_and_reach(&desc, Descending, -hi, -lo, tol_u)?;
    let limit = opts.monotone_tolerance * span_y;
    for r in asc_reports.iter().chain(&desc_reports) {
        if r.violation > limit {
            return Err(TableError::OutputNotMonotone {
                family: r.family,
                curve: r.curve,
                sample: r.violation_sample,
                drop: r.violation,
                tolerance: limit,
            });
        }
    }

    // The major branches must meet at both saturations (within tolerance).
    let tol_close = opts.closure_tolerance * span_y;
    if let (Some(a), Some(d)) = (a_major, d_major) {
        let a_top = y_lo + asc[a].increment_at(hi);
        let d_bottom = y_hi - desc[d].increment_at(-lo);
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
    }

    // Every measured curve runs inside the major loop (within the closure tolerance): one whose output leaves it
    // is not a first-order curve between these major branches, and its table values would lie outside the
    // operator's output range.
    for (family, fam, sign) in [(Ascending, &asc, 1.0), (Descending, &desc, -1.0)] {
        for c in fam.iter() {
            let (e_min, e_max) =
                c.e.iter()
                    .fold((0.0f64, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
            for output in [c.y0, c.y0 + sign * e_min, c.y0 + sign * e_max] {
                if output < y_lo - tol_close || output > y_hi + tol_close {
                    return Err(TableError::OutsideMajorLoop {
                        family,
                        curve: c.index,
                        output,
                        lo: y_lo,
                        hi: y_hi,
                    });
                }
            }
        }
    }

    let node_tol = opts.node_tolerance * span_y;
    let mut curves = asc_reports;
    curves.extend(desc_reports);
    let k = opts.subdivisions;
    // Opposite major branches as the other family's curve in its rising orientation: measured, or traced by
    // the measured family's reversal points.
    let asc_major = |desc_fam: &[Curve]| match a_major {
        Some(a) => ((asc[a].u.clone(), asc[a].e.clone()), MajorSource::Measured),
        None => (
            reversal_trace(desc_fam, |c| (-c.u[0], c.y0 - y_lo), (lo, 0.0)),
            MajorSource::ReversalPoints,
        ),
    };
    let desc_major = |asc_fam: &[Curve]| match d_major {
        Some(d) => (
            (desc[d].u.clone(), desc[d].e.clone()),
            MajorSource::Measured,
        ),
        None => (
            reversal_trace(asc_fam, |c| (-c.u[0], y_hi - c.y0), (-hi, 0.0)),
            MajorSource::ReversalPoints,
        ),
    };
    let mut densified = [0usize; 2];
    let mut densify_adjusted = 0.0f64;
    let select = |d: &DerivedFamily, kind: FamilyKind| {
        select_family_nodes(
            &d.grid,
            &d.reversals,
            &d.rows,
            node_tol,
            opts.max_nodes,
            kind,
        )
    };
    // Curves added between measured reversals, from strip shapes calibrated on the opposite family's curves
    // (every measured one when both families were measured, else its major branch).
    let (ascending, descending, derived, a_nodes, d_nodes, mismatch) = match derive {
        None => {
            let (a, an) = build_family(&asc, lo, hi, node_tol, opts.max_nodes, Ascending)?;
            let (d, dn) = build_family(&desc, -hi, -lo, node_tol, opts.max_nodes, Descending)?;
            // Mismatch between the measured families, before anything is added to them.
            let mismatch = congruency(&a, &d);
            if k > 1 {
                check_added(&a, k, 0)?;
                check_added(&d, k, 0)?;
                let da = densify_with_family(&a, &d, k);
                let dd = densify_with_family(&d, &a, k);
                densified = [
                    da.reversals.len() - a.curves(),
                    dd.reversals.len() - d.curves(),
                ];
                densify_adjusted = da.adjusted.max(dd.adjusted);
                let (a, an) = select(&da, Ascending)?;
                let (d, dn) = select(&dd, Descending)?;
                (a, d, None, an, dn, Some(mismatch))
            } else {
                (a, d, None, an, dn, Some(mismatch))
            }
        }
        Some(kind) => {
            // Measured family A (report slot ma), derived family B.
            let ma = if kind == Descending { 0 } else { 1 };
            let (a, an) = if kind == Descending {
                build_family(&asc, lo, hi, node_tol, opts.max_nodes, Ascending)?
            } else {
                build_family(&desc, -hi, -lo, node_tol, opts.max_nodes, Descending)?
            };
            let (major, source) = if kind == Descending {
                desc_major(&asc)
            } else {
                asc_major(&desc)
            };
            check_added(&a, k, major.0.len())?;
            let db = derive_family(&a, &major.0, &major.1, k);
            let (b, bn) = select(&db, kind)?;
            // The derived major branch must close on the measured one like a measured one would: a family whose
            // reversal points trace no major branch between the saturations (curves that are not first-order
            // curves of one device) gives none, and its tables would not rebuild from their own curves.
            let total = b.row(0)[b.nodes() - 1];
            let (at_input, ascending, descending) = if kind == Descending {
                (lo, y_lo, y_hi - total)
            } else {
                (hi, y_lo + total, y_hi)
            };
            let gap = (ascending - descending).abs();
            if gap.is_nan() || gap > tol_close {
                return Err(TableError::MajorLoopOpen {
                    at_input,
                    ascending,
                    descending,
                });
            }
            let info = Derivation {
                family: kind,
                major: source,
                curves: b.curves(),
                adjusted: db.adjusted,
            };
            let (a, an) = if k > 1 {
                let da = densify_family(&a, &major.0, &major.1, k);
                densified[ma] = da.reversals.len() - a.curves();
                densify_adjusted = da.adjusted;
                select(&da, a.kind())?
            } else {
                (a, an)
            };
            if kind == Descending {
                (a, b, Some(info), an, bn, None)
            } else {
                (b, a, Some(info), bn, an, None)
            }
        }
    };
    Ok(BuiltTables {
        ascending,
        descending,
        y_lo,
        y_hi,
        report: BuildReport {
            curves,
            derived,
            ascending: a_nodes,
            descending: d_nodes,
            mismatch,
            densified,
            densify_adjusted,
        },
    })
}

/// A measured curve in rising orientation after its monotone fit: `u` strictly increasing, `e` the nondecreasing
/// increment from the fitted first value `y0` (in real output units).
struct Curve {
    u: Vec<f64>,
    e: Vec<f64>,
    y0: f64,
    /// Index as given.
    index: usize,
}

impl Curve {
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

    /// Last input reached, in real units (rising orientation for ascending curves).
    fn end(&self) -> f64 {
        self.u[self.u.len() - 1]
    }
}

fn check_shape(curves: &[MeasuredCurve<'_>], family: FamilyKind) -> Result<(), TableError> {
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

/// Refuse curves added to (or derived from) family `a` with `k` per interval when the table could exceed the
/// size limit (`extra` more grid nodes from an opposite major branch).
fn check_added(a: &Family<Vec<f64>>, k: usize, extra: usize) -> Result<(), TableError> {
    let curves = limits::product(a.curves(), k).saturating_add(1);
    let nodes = a.nodes().saturating_add(curves).saturating_add(extra);
    check_table_size(a.kind(), curves, nodes).map(|_| ())
}

/// Refuse a table of `curves × nodes` values above [`MAX_TABLE_VALUES`] before it is allocated.
fn check_table_size(kind: FamilyKind, curves: usize, nodes: usize) -> Result<usize, TableError> {
    limits::check(
        "table size (curves × grid nodes)",
        limits::product(curves, nodes),
        MAX_TABLE_VALUES,
    )
    .map_err(|limit| TableError::TooLarge {
        family: Some(kind),
        limit,
    })
}

/// Range of every input of every curve (for the input-backtrack limit).
fn input_span(a: &[MeasuredCurve<'_>], d: &[MeasuredCurve<'_>]) -> f64 {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for &(u, _) in a.iter().chain(d) {
        for &x in u {
            lo = lo.min(x);
            hi = hi.max(x);
        }
    }
    (hi - lo).max(0.0)
}

/// Sort, average and monotone-fit every curve of a family (rising orientation) and report what that did.
fn prepare(
    curves: &[MeasuredCurve<'_>],
    family: FamilyKind,
    opts: &BuildOptions,
    input_span: f64,
) -> Result<(Vec<Curve>, Vec<CurveReport>), TableError> {
    let sign = match family {
        FamilyKind::Ascending => 1.0,
        FamilyKind::Descending => -1.0,
    };
    let mut out = Vec::with_capacity(curves.len());
    let mut reports = Vec::with_capacity(curves.len());
    for (c, &(u, y)) in curves.iter().enumerate() {
        let ru: Vec<f64> = u.iter().map(|&x| sign * x).collect();
        let ry: Vec<f64> = y.iter().map(|&v| sign * v).collect();
        let m = monotone_curve(&ru, &ry);
        let limit = opts.monotone_tolerance * input_span;
        if m.input_backtrack > limit {
            return Err(TableError::InputBacktrack {
                family,
                curve: c,
                sample: m.input_backtrack_sample,
                by: m.input_backtrack,
                limit,
            });
        }
        if m.u.len() < 2 {
            // Every sample at (or behind) the reversal input.
            return Err(TableError::NoInputSpan { family, curve: c });
        }
        reports.push(CurveReport {
            family,
            curve: c,
            samples: u.len(),
            reversal: u[0],
            violation: m.violation.amount,
            violation_sample: m.violation_sample,
            violation_input: u[m.violation_sample],
            reshaped_rms: m.reshaped_rms,
            input_backtrack: m.input_backtrack,
        });
        let y0 = m.y[0];
        out.push(Curve {
            e: m.y.iter().map(|&v| v - y0).collect(),
            y0: sign * y0,
            u: m.u,
            index: c,
        });
    }
    Ok((out, reports))
}

fn check_duplicates(curves: &[Curve], family: FamilyKind) -> Result<(), TableError> {
    let sign = if family == FamilyKind::Ascending {
        1.0
    } else {
        -1.0
    };
    let mut starts: Vec<(f64, usize)> = curves.iter().map(|c| (c.u[0], c.index)).collect();
    starts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    for w in starts.windows(2) {
        if w[0].0 == w[1].0 {
            return Err(TableError::DuplicateReversal {
                family,
                curve: w[1].1,
                other: w[0].1,
                input: sign * w[0].0,
            });
        }
    }
    Ok(())
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
    for curve in curves {
        let start = curve.u[0];
        if start < lo || start >= hi {
            let (a, b) = if sign > 0.0 { (lo, hi) } else { (-hi, -lo) };
            return Err(TableError::ReversalOutOfRange {
                family,
                curve: curve.index,
                input: sign * start,
                lo: a,
                hi: b,
            });
        }
        if curve.end() < hi - tol_u {
            return Err(TableError::ShortCurve {
                family,
                curve: curve.index,
                reaches: sign * curve.end(),
                needed: sign * hi,
            });
        }
    }
    Ok(())
}

/// The opposite major branch traced by a family's reversal points (each first-order curve starts on it), in the
/// derived family's rising orientation, from its start `first` to its end (the measured major's reversal).
fn reversal_trace(
    curves: &[Curve],
    point: impl Fn(&Curve) -> (f64, f64),
    first: (f64, f64),
) -> (Vec<f64>, Vec<f64>) {
    let mut pts: Vec<(f64, f64)> = curves.iter().map(point).collect();
    pts.push(first);
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    pts.dedup_by(|b, a| a.0 == b.0);
    let (w, mut e): (Vec<f64>, Vec<f64>) = pts.into_iter().unzip();
    let ones = alloc::vec![1.0; e.len()];
    crate::curve_fit::isotonic(&mut e, &ones);
    (w, e)
}

/// Shared grid: every sample input and reversal inside `[lo, hi]`, each curve's increments at the nodes, then the
/// nodes an error bound needs.
fn build_family(
    curves: &[Curve],
    lo: f64,
    hi: f64,
    node_tol: f64,
    max_nodes: usize,
    kind: FamilyKind,
) -> Result<(Family<Vec<f64>>, FamilyNodes), TableError> {
    let mut order: Vec<usize> = (0..curves.len()).collect();
    order.sort_by(|&a, &b| curves[a].u[0].total_cmp(&curves[b].u[0]));
    let reversals: Vec<f64> = order.iter().map(|&i| curves[i].u[0]).collect();
    // Nodes closer than this are merged; reversals must stay apart by more (and from saturation).
    let eps = 1e-12 * (hi - lo);
    let sign = if kind == FamilyKind::Ascending {
        1.0
    } else {
        -1.0
    };
    for w in order.windows(2) {
        let (a, b) = (&curves[w[0]], &curves[w[1]]);
        if b.u[0] - a.u[0] <= eps {
            let (first, second) = if a.index < b.index { (a, b) } else { (b, a) };
            return Err(TableError::ReversalsTooClose {
                family: kind,
                curve: second.index,
                input: sign * second.u[0],
                other: first.index,
                other_input: sign * first.u[0],
                resolution: eps,
            });
        }
    }
    if let Some(&top) = order.last()
        && hi - curves[top].u[0] <= eps
    {
        return Err(TableError::ReversalAtSaturation {
            family: kind,
            curve: curves[top].index,
            input: sign * curves[top].u[0],
            saturation: sign * hi,
        });
    }
    let samples: usize = curves.iter().map(|c| c.u.len()).sum();
    check_table_size(kind, curves.len(), samples + curves.len() + 2)?;

    let mut grid: Vec<f64> = curves
        .iter()
        .flat_map(|c| c.u.iter().copied())
        .filter(|&x| x > lo && x < hi)
        .collect();
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
    let mut rows: Vec<Vec<f64>> = Vec::with_capacity(curves.len());
    for &i in &order {
        let curve = &curves[i];
        let mut peak = 0.0f64;
        let row: Vec<f64> = merged
            .iter()
            .map(|&x| {
                let v = if x <= curve.u[0] {
                    0.0
                } else {
                    curve.increment_at(x).max(0.0)
                };
                peak = peak.max(v);
                peak
            })
            .collect();
        rows.push(row);
    }
    select_family_nodes(&merged, &reversals, &rows, node_tol, max_nodes, kind)
}

/// Keep the nodes the error bound needs (reversals and range ends always) and assemble the family table.
pub(crate) fn select_family_nodes(
    grid: &[f64],
    reversals: &[f64],
    rows: &[Vec<f64>],
    node_tol: f64,
    max_nodes: usize,
    kind: FamilyKind,
) -> Result<(Family<Vec<f64>>, FamilyNodes), TableError> {
    let mut forced: Vec<usize> = reversals
        .iter()
        .filter_map(|r| grid.binary_search_by(|x| x.total_cmp(r)).ok())
        .collect();
    forced.sort_unstable();
    forced.dedup();
    let row = |r: usize| rows[r].as_slice();
    let (keep, tolerance) =
        select_nodes_within(grid, rows.len(), row, node_tol, max_nodes, &forced);
    let error = interpolation_error(grid, rows.len(), row, &keep);
    let nodes = keep.len();
    let mut data = Vec::with_capacity(family_len(nodes, rows.len()));
    data.extend(keep.iter().map(|&k| grid[k]));
    data.extend_from_slice(reversals);
    for r in rows {
        data.extend(keep.iter().map(|&k| r[k]));
    }
    let family = Family::new(data, nodes, rows.len(), kind)?;
    Ok((
        family,
        FamilyNodes {
            inputs: grid.len(),
            nodes,
            tolerance,
            error,
        },
    ))
}
