//! Regularised nonnegative least-squares identification of a tabulated Everett function (a Preisach model) from
//! any excitation, and the identified model itself (simulation, first-order curves).
//!
//! A nonnegative density gives loops that run counter-clockwise in the input-output plane (the output lags the
//! input). With [`EverettFitOptions::signed`] the masses are free in sign: the same regularised least squares
//! without the bound, for loops that run clockwise (an output that leads its input, e.g. a force driven by the
//! rate of a displacement). Such a table predicts, but its branches need not be monotone: no exact inverse.
//!
//! The output of the model is linear in the cell masses given the input history
//! ([`super::everett_regressors`]); the masses are found by minimising
//! `Σ (y − ŷ)² + λ_s ‖D ρ‖² + λ_r ‖w‖²` subject to `w ≥ 0` (monotone tables), where `ρ` is the density
//! (mass per cell area, or per diagonal length for the reversible part) and `D` takes first differences between
//! neighbouring cells (smoothness). `λ_s = smoothing · tr(Q)/tr(DᵀD)` and `λ_r = ridge · tr(Q)/n` make both
//! weights dimensionless.
use alloc::vec::Vec;

use super::error::{IdentificationError, RunError};
use super::everett_regressors::{EverettGrid, NormalEquations, simulate_everett_from};
use super::nnls::{NnlsSolution, PassiveFactor, nnls_gram_carried};
use crate::from_curves::CurveData;
use crate::limits::{self, MAX_CURVE_POINTS, MAX_SOLVER_ITERATIONS};

/// A Preisach model: Everett table on a grid (from cell masses, nonnegative unless built signed) and the output at
/// negative saturation.
#[derive(Clone, Debug, PartialEq)]
pub struct EverettModel {
    grid: EverettGrid,
    masses: Vec<f64>,
    node_values: Vec<f64>,
    offset: f64,
}

impl EverettModel {
    /// Build from cell masses (packed like [`EverettGrid::cell_index`], finite, nonnegative) and the output at
    /// negative saturation `offset`.
    pub fn new(
        grid: EverettGrid,
        masses: Vec<f64>,
        offset: f64,
    ) -> Result<Self, IdentificationError> {
        // The count and the offset are checked where signed masses are; here only what a density adds.
        if masses.len() == grid.n_cells()
            && let Some(i) = masses.iter().position(|m| !m.is_finite() || *m < 0.0)
        {
            return Err(IdentificationError::NegativeMass {
                index: i,
                value: masses[i],
            });
        }
        Self::with_signed_masses(grid, masses, offset)
    }

    /// Build from cell masses of either sign (finite): a signed density, whose loops may run clockwise and whose
    /// branches need not be monotone. [`Self::is_monotone`] says whether the masses happen to be nonnegative.
    pub fn with_signed_masses(
        grid: EverettGrid,
        masses: Vec<f64>,
        offset: f64,
    ) -> Result<Self, IdentificationError> {
        if masses.len() != grid.n_cells() {
            return Err(IdentificationError::MassCount {
                intervals: grid.n_intervals(),
                expected: grid.n_cells(),
                got: masses.len(),
            });
        }
        if let Some(i) = masses.iter().position(|m| !m.is_finite()) {
            return Err(IdentificationError::NonFinite {
                what: "mass",
                index: i,
                value: masses[i],
            });
        }
        if !offset.is_finite() {
            return Err(IdentificationError::NonFinite {
                what: "offset",
                index: 0,
                value: offset,
            });
        }
        let node_values = grid.masses_to_nodes(&masses);
        Ok(Self {
            grid,
            masses,
            node_values,
            offset,
        })
    }

    /// Whether every cell mass is nonnegative: a Preisach density, whose branches are monotone and which has an
    /// exact inverse.
    pub fn is_monotone(&self) -> bool {
        self.masses.iter().all(|&m| m >= 0.0)
    }

    /// The input grid.
    pub fn grid(&self) -> &EverettGrid {
        &self.grid
    }

    /// Cell masses (packed).
    pub fn masses(&self) -> &[f64] {
        &self.masses
    }

    /// Output at negative saturation.
    pub fn offset(&self) -> f64 {
        self.offset
    }

    /// Packed node values `E(g_i, g_j)`, `i < j`.
    pub fn node_values(&self) -> &[f64] {
        &self.node_values
    }

    /// `E(β, α)` (0 when β ≥ α; inputs clamped to the grid).
    pub fn everett(&self, beta: f64, alpha: f64) -> f64 {
        self.grid.everett_value(&self.node_values, beta, alpha)
    }

    /// Output along input `u` from negative saturation, with output offset `offset` (None: the model's).
    pub fn simulate(&self, u: &[f64], offset: Option<f64>) -> Vec<f64> {
        self.simulate_from(&[], u, offset)
    }

    /// Output along `u` from the state negative saturation followed by `history` leaves.
    pub fn simulate_from(&self, history: &[f64], u: &[f64], offset: Option<f64>) -> Vec<f64> {
        simulate_everett_from(
            &self.grid,
            &self.node_values,
            offset.unwrap_or(self.offset),
            history,
            u,
        )
    }

    /// Candidate initial states for a run that starts at input `u0` from an unknown history: negative or positive
    /// saturation, or one reversal after either (a maximum `a > u0` reached from negative saturation, or a
    /// minimum `b < u0` reached from positive saturation) at every grid node. Each is a `history` for
    /// [`Self::simulate_from`].
    pub fn initial_candidates(&self, u0: f64) -> Vec<Vec<f64>> {
        let g = self.grid.nodes();
        let (lo, hi) = (self.grid.lo(), self.grid.hi());
        let mut out = alloc::vec![Vec::new(), alloc::vec![hi]];
        for &x in g {
            if x > u0 && x < hi {
                out.push(alloc::vec![x]);
            }
            if x < u0 && x > lo {
                out.push(alloc::vec![hi, x]);
            }
        }
        out
    }

    /// The candidate initial state ([`Self::initial_candidates`]) under which the run `(u, y)` (rows weighted by
    /// `weight`) is predicted best, with the output offset free (`free_offset`) or the model's, and the output
    /// multiplied by `gain` around the offset. Returns the history, its weighted residual sum of squares and the
    /// offset it implies.
    pub fn best_initial_state(
        &self,
        u: &[f64],
        y: &[f64],
        weight: &[f64],
        free_offset: bool,
        gain: f64,
    ) -> (Vec<f64>, f64, f64) {
        let mut best: (Vec<f64>, f64, f64) = (Vec::new(), f64::INFINITY, self.offset);
        let Some(&u0) = u.first() else {
            return best;
        };
        for h in self.initial_candidates(u0) {
            let p = self.simulate_from(&h, u, Some(0.0));
            let (mut sw, mut swr) = (0.0, 0.0);
            for ((&yi, &pi), &wi) in y.iter().zip(&p).zip(weight) {
                if wi > 0.0 {
                    sw += wi;
                    swr += wi * (yi - gain * pi);
                }
            }
            if sw <= 0.0 {
                continue;
            }
            let offset = if free_offset { swr / sw } else { self.offset };
            let rss: f64 = y
                .iter()
                .zip(&p)
                .zip(weight)
                .filter(|&(_, &wi)| wi > 0.0)
                .map(|((&yi, &pi), &wi)| {
                    let r = yi - offset - gain * pi;
                    wi * r * r
                })
                .sum();
            if rss < best.1 {
                best = (h, rss, offset);
            }
        }
        best
    }

    /// The CBH operator of this Everett table (its first-order curves with `subdivisions` reversals per grid
    /// interval, see [`Self::first_order_curves_subdivided`]), built without leaving Rust. A signed table has
    /// none (its branches need not be monotone): [`IdentificationError::SignedTable`].
    pub fn hysteresis<const N: usize>(
        &self,
        subdivisions: usize,
        opts: &crate::table_builder::BuildOptions,
        initial: crate::cbh::Initial,
    ) -> Result<crate::cbh::Hysteresis<Vec<f64>, N>, IdentificationError> {
        if let Some(index) = self.masses.iter().position(|&m| m < 0.0) {
            return Err(IdentificationError::SignedTable {
                index,
                value: self.masses[index],
            });
        }
        let (asc, desc) = self.first_order_curves_subdivided(subdivisions)?;
        Ok(crate::cbh::Hysteresis::from_curve_data(
            &asc, &desc, opts, initial,
        )?)
    }

    /// First-order curves at every grid node: ascending from each reversal minimum `g_i` (i < N) up to
    /// positive saturation (`y(m) + E(m, u)`), descending from each reversal maximum `g_j` (j > 0) down to
    /// negative saturation (`y(M) − E(u, M)`), in traversal order. The first of each family is the major branch.
    pub fn first_order_curves(&self) -> (Vec<CurveData>, Vec<CurveData>) {
        // At most MAX_EVERETT_INTERVALS intervals: the points stay within MAX_CURVE_POINTS.
        self.curves_with_subdivisions(1)
    }

    /// As [`Self::first_order_curves`], with reversals also at `subdivisions − 1` evenly spaced points inside
    /// every grid interval. The curves stay exact (piecewise linear in `u` with nodes at the reversal and the
    /// grid nodes beyond it). A CBH operator built from the curves at the grid nodes alone already reproduces the
    /// table at any reversal (its strip rule is exact for bilinear cells and a reversible diagonal); more
    /// reversals only cost table size. The points of both families are at most [`MAX_CURVE_POINTS`].
    pub fn first_order_curves_subdivided(
        &self,
        subdivisions: usize,
    ) -> Result<(Vec<CurveData>, Vec<CurveData>), IdentificationError> {
        let n = self.grid.n_intervals();
        // Each family: n·k curves of at most n + 2 points.
        let points = limits::product(
            2,
            limits::product(limits::product(n, subdivisions.max(1)), n + 2),
        );
        limits::check(
            "points of the first-order curves (both families)",
            points,
            MAX_CURVE_POINTS,
        )?;
        Ok(self.curves_with_subdivisions(subdivisions))
    }

    fn curves_with_subdivisions(&self, subdivisions: usize) -> (Vec<CurveData>, Vec<CurveData>) {
        let k = subdivisions.max(1);
        let g = self.grid.nodes();
        let n = self.grid.n_intervals();
        let (lo, hi) = (g[0], g[n]);
        let y_pos = self.offset + self.everett(lo, hi);
        let point = |i: usize, l: usize| g[i] + (g[i + 1] - g[i]) * l as f64 / k as f64;
        let mut ascending = Vec::with_capacity(n * k);
        for i in 0..n {
            for l in 0..k {
                let m = point(i, l);
                let y_m = y_pos - self.everett(m, hi);
                let mut u = Vec::with_capacity(n - i + 1);
                u.push(m);
                u.extend_from_slice(&g[i + 1..]);
                let y: Vec<f64> = u.iter().map(|&x| y_m + self.everett(m, x)).collect();
                ascending.push((u, y));
            }
        }
        let mut descending = Vec::with_capacity(n * k);
        for j in (0..n).rev() {
            for l in (1..=k).rev() {
                let big_m = point(j, l);
                let y_m = self.offset + self.everett(lo, big_m);
                let mut u = Vec::with_capacity(j + 2);
                u.push(big_m);
                u.extend(g[..=j].iter().rev().copied());
                let y: Vec<f64> = u.iter().map(|&x| y_m - self.everett(x, big_m)).collect();
                descending.push((u, y));
            }
        }
        (ascending, descending)
    }
}

/// Regularisation and solver settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EverettFitOptions {
    /// Weight of the density smoothness penalty (dimensionless, relative to the data term).
    pub smoothing: f64,
    /// Weight of the ridge on the masses (dimensionless; keeps cells without data determined).
    pub ridge: f64,
    /// Pivoting iterations allowed in the NNLS solve (then it continues by projected coordinate descent).
    pub max_iter: usize,
    /// Masses free in sign (loops that run clockwise: an output leading its input); false keeps them
    /// nonnegative (a Preisach density).
    pub signed: bool,
    /// Share of the smoothness penalty taken along the diagonal, between cells of equal `α − β` (equal switching
    /// width), in `[0, 1]`; the rest between neighbours along `α` and `β`. 0: the isotropic penalty. A density
    /// narrow in `α − β` and broad along it (hard steel, a narrow coercivity spread) is smooth along the diagonal
    /// only, and between a few measured first-order curves this penalty carries it along the ridge.
    pub diagonal_smoothing: f64,
}

impl Default for EverettFitOptions {
    fn default() -> Self {
        Self {
            smoothing: 1e-4,
            ridge: 1e-9,
            max_iter: 500,
            signed: false,
            diagonal_smoothing: 0.0,
        }
    }
}

/// One run of training data: input, output, per-sample row weight (0 excludes a sample from the fit while
/// it still drives the memory) and which offset column it uses.
#[derive(Clone, Copy, Debug)]
pub struct EverettRun<'a> {
    /// Input samples.
    pub u: &'a [f64],
    /// Output samples.
    pub y: &'a [f64],
    /// Row weights.
    pub weight: &'a [f64],
    /// Offset column of this run (`< n_offsets`).
    pub offset_col: usize,
    /// Inputs applied after negative saturation before the run starts (its initial state; empty: negative
    /// saturation).
    pub history: &'a [f64],
    /// Calibration gain of this run (the model's output is scaled by it; 1 for none).
    pub gain: f64,
    /// Values of a drift regressor on this run's samples (empty: none), e.g. the running integral of the input
    /// a leakage current adds to a charge measurement. Every run's drift shares one fitted coefficient.
    pub drift: &'a [f64],
}

/// Result of [`fit_everett`] and [`EverettRegression::fit`].
#[derive(Clone, Debug)]
pub struct EverettFit {
    /// The identified model (its offset is offset column 0).
    pub model: EverettModel,
    /// All fitted offsets (one per offset column).
    pub offsets: Vec<f64>,
    /// Weighted residual sum of squares of the data term.
    pub rss: f64,
    /// Number of regression rows.
    pub n_rows: usize,
    /// Weighted RMS residual.
    pub rms: f64,
    /// NNLS pivoting iterations (plus coordinate-descent sweeps when pivoting gave up).
    pub iterations: usize,
    /// The NNLS passive set (variables off their bound): a warm start for a neighbouring problem.
    pub passive: Vec<bool>,
    /// Whether the solver met its optimality conditions (see [`super::NnlsSolution::converged`]).
    pub converged: bool,
    /// The solver's largest relative optimality-condition violation.
    pub kkt_violation: f64,
    /// Condition-number estimate of the regularised normal equations on the passive set.
    pub condition: f64,
    /// The fitted coefficient of the runs' drift regressor (output units per drift-regressor unit), when any run
    /// has one.
    pub drift: Option<f64>,
}

/// Identify the Everett masses on `grid` and `n_offsets` free output offsets from `runs`. Up to
/// [`crate::limits::MAX_EVERETT_UNKNOWNS`] unknowns on the dense normal equations (exact active-set solve), past
/// it matrix-free ([`super::everett_large`], up to [`crate::limits::MAX_EVERETT_LARGE_UNKNOWNS`]).
pub fn fit_everett(
    grid: &EverettGrid,
    runs: &[EverettRun<'_>],
    n_offsets: usize,
    options: EverettFitOptions,
) -> Result<EverettFit, IdentificationError> {
    check_options(n_offsets, options)?;
    // The drift coefficient is one more free column after the offsets.
    let with_drift = runs.iter().any(|r| !r.drift.is_empty());
    let unknowns = limits::sum(
        grid.n_cells(),
        limits::sum(n_offsets, usize::from(with_drift)),
    );
    if super::everett_large::needs_large_path(unknowns) {
        let views: Vec<super::EverettFoldRun<'_>> = runs
            .iter()
            .map(|r| super::EverettFoldRun {
                u: r.u,
                y: r.y,
                weight: r.weight,
                fold: &[],
                offset_col: r.offset_col,
                history: r.history,
                gain: r.gain,
                drift: r.drift,
            })
            .collect();
        return super::everett_large::fit_everett_large(grid, &views, n_offsets, options);
    }
    let mut ne = NormalEquations::new(grid, n_offsets + usize::from(with_drift))?;
    for (k, run) in runs.iter().enumerate() {
        ne.add_run(
            grid,
            run.u,
            run.y,
            run.weight,
            run.offset_col,
            run.history,
            run.gain,
            (!run.drift.is_empty()).then_some((n_offsets, run.drift)),
        )
        .map_err(|error| IdentificationError::Run { run: k, error })?;
    }
    if ne.n_rows == 0 {
        return Err(IdentificationError::NoSamples);
    }
    ne.finish();
    let q = mass_space_matrix(grid, &ne, options)?;
    let (mut fit, _) = solve(
        grid,
        &DataTerm::of(&ne, &ne.rhs, ne.yy),
        &q,
        options,
        None,
        None,
    )?;
    if with_drift {
        fit.drift = fit.offsets.pop();
    }
    Ok(fit)
}

pub(super) fn check_options(
    n_offsets: usize,
    options: EverettFitOptions,
) -> Result<(), IdentificationError> {
    if n_offsets == 0 {
        return Err(IdentificationError::NoOffsets);
    }
    for (name, value) in [("smoothing", options.smoothing), ("ridge", options.ridge)] {
        if !(value.is_finite() && value >= 0.0) {
            return Err(IdentificationError::BadParameter { name, value });
        }
    }
    let share = options.diagonal_smoothing;
    if !(0.0..=1.0).contains(&share) {
        return Err(IdentificationError::BadParameter {
            name: "diagonal_smoothing",
            value: share,
        });
    }
    limits::check(
        "solver iterations (max_iter)",
        options.max_iter,
        MAX_SOLVER_ITERATIONS,
    )?;
    Ok(())
}

/// The data term of the least squares: node-space Gram matrix, right-hand side, `Σ w y²` and the row counts.
pub(super) struct DataTerm<'a> {
    gram: &'a [f64],
    rhs: &'a [f64],
    yy: f64,
    n_nodes: usize,
    n_rows: usize,
    weight_sum: f64,
}

impl<'a> DataTerm<'a> {
    pub(super) fn of(ne: &'a NormalEquations, rhs: &'a [f64], yy: f64) -> Self {
        Self {
            gram: &ne.gram,
            rhs,
            yy,
            n_nodes: ne.n_nodes,
            n_rows: ne.n_rows,
            weight_sum: ne.weight_sum,
        }
    }
}

/// The regularised quadratic in mass space: `Q = Cᵀ G C + λ_s DᵀD + λ_r I` on the node block (`C` maps masses
/// to node values), `Cᵀ G` on the node/offset block, `G` on the offset block. Depends on the input history and
/// the row weights only, not on the output.
pub(super) fn mass_space_matrix(
    grid: &EverettGrid,
    ne: &NormalEquations,
    options: EverettFitOptions,
) -> Result<Vec<f64>, IdentificationError> {
    let mut q = data_matrix(grid, ne);
    regularise(grid, &mut q, ne.n_cols(), ne.n_nodes, options)?;
    Ok(q)
}

/// The data part of [`mass_space_matrix`] (`Cᵀ G C` and its offset blocks, no regularisation): the same for
/// every smoothing, so that problems differing only in their options share it.
pub(super) fn data_matrix(grid: &EverettGrid, ne: &NormalEquations) -> Vec<f64> {
    let nn = ne.n_nodes;
    let m = ne.n_cols();
    // The Gram matrix is symmetric to the bit (`NormalEquations::finish` mirrors it), so its rows are its
    // columns: T = G C row by row (row k = Cᵀ G[k, ..nn]), then B = Cᵀ G = Tᵀ on the node block and Q = B C.
    let mut t = alloc::vec![0.0; m * nn];
    adjoint_rows(grid, &ne.gram, m, nn, m, &mut t, nn);
    // Q's node block written in place (rows of length nn at stride m), then its offset rows and columns. Row i
    // of Q is Cᵀ applied to column i of T: the columns are gathered a strip of rows of B at a time, not as a
    // whole second copy of T (a fresh, page-faulted allocation of the matrix's size per input history).
    let mut q = alloc::vec![0.0; m * m];
    const STRIP: usize = 32;
    let mut b_strip = alloc::vec![0.0; STRIP * nn];
    for i0 in (0..nn).step_by(STRIP) {
        let rows = STRIP.min(nn - i0);
        for k in 0..nn {
            let t_row = &t[k * nn + i0..k * nn + i0 + rows];
            for (r, &v) in t_row.iter().enumerate() {
                b_strip[r * nn + k] = v;
            }
        }
        adjoint_rows(grid, &b_strip, nn, nn, rows, &mut q[i0 * m..], m);
    }
    drop(b_strip);
    for k in 0..nn {
        for o in nn..m {
            q[k * m + o] = t[o * nn + k];
        }
    }
    for o in nn..m {
        q[o * m..o * m + nn].copy_from_slice(&t[o * nn..(o + 1) * nn]);
        q[o * m + nn..(o + 1) * m].copy_from_slice(&ne.gram[o * m + nn..(o + 1) * m]);
    }
    q
}

/// Adds the smoothness and ridge terms of `options` to a [`data_matrix`] `q` (`m × m`, the first `nn` columns
/// the nodes); an error when an offset column is empty.
pub(super) fn regularise(
    grid: &EverettGrid,
    q: &mut [f64],
    m: usize,
    nn: usize,
    options: EverettFitOptions,
) -> Result<(), IdentificationError> {
    let trace_q: f64 = (0..nn)
        .map(|i| q[i * m + i])
        .sum::<f64>()
        .max(f64::MIN_POSITIVE);
    add_smoothness(
        grid,
        q,
        m,
        options.smoothing,
        options.diagonal_smoothing,
        trace_q,
    );
    let ridge = options.ridge * trace_q / nn as f64;
    for i in 0..nn {
        q[i * m + i] += ridge.max(1e-14 * trace_q / nn as f64);
    }
    for o in nn..m {
        if q[o * m + o] <= 0.0 {
            return Err(IdentificationError::EmptyOffset { column: o - nn });
        }
        q[o * m + o] *= 1.0 + 1e-12;
    }
    Ok(())
}

/// `out[k] = Cᵀ a[k, ..nn]` for the first `rows` rows `k` of the row-major `a` (row length `stride`), into the
/// rows of `out` (row `k` at `k · out_stride`, `nn` long), four rows at a time.
fn adjoint_rows(
    grid: &EverettGrid,
    a: &[f64],
    stride: usize,
    nn: usize,
    rows: usize,
    out: &mut [f64],
    out_stride: usize,
) {
    const L: usize = 4;
    let mut scratch = alloc::vec![0.0; L * grid.n_intervals()];
    let mut k = 0;
    while k + L <= rows {
        let block = &mut out[k * out_stride..];
        let (o0, rest) = block.split_at_mut(out_stride);
        let (o1, rest) = rest.split_at_mut(out_stride);
        let (o2, o3) = rest.split_at_mut(out_stride);
        let g = core::array::from_fn(|r| &a[(k + r) * stride..(k + r) * stride + nn]);
        grid.nodes_to_masses_adjoint_lanes::<L>(
            g,
            &mut [&mut o0[..nn], &mut o1[..nn], &mut o2[..nn], &mut o3[..nn]],
            &mut scratch,
        );
        k += L;
    }
    for row in k..rows {
        let o = &mut out[row * out_stride..row * out_stride + nn];
        grid.nodes_to_masses_adjoint_into(&a[row * stride..row * stride + nn], o, &mut scratch);
    }
}

/// Solve the nonnegative quadratic for the right-hand side of `data` (optionally warm-started from a passive
/// set, and from the factor of a passive set an earlier solve of `q` handed back: [`nnls_gram_carried`]) and
/// measure the data-term residual. Returns the fit and the factor of its passive set.
pub(super) fn solve(
    grid: &EverettGrid,
    data: &DataTerm<'_>,
    q: &[f64],
    options: EverettFitOptions,
    warm_start: Option<&[bool]>,
    carried: Option<PassiveFactor>,
) -> Result<(EverettFit, Option<PassiveFactor>), IdentificationError> {
    let m = data.rhs.len();
    let (sol, model, offsets, factor) = solve_masses(
        grid,
        data.rhs,
        data.n_nodes,
        q,
        options,
        warm_start,
        carried,
    )?;
    // Data-term RSS from the unregularised normal equations: yy − 2 zᵀ r + zᵀ G z, z = [C w, offsets].
    let mut z = model.node_values().to_vec();
    z.extend_from_slice(&offsets);
    // Four rows at a time: each row's sum runs in the same order as alone (the same bits), the four chains of
    // additions overlap instead of waiting on one another.
    let mut zgz = 0.0;
    let mut i = 0;
    while i + 4 <= m {
        let rows: [&[f64]; 4] = core::array::from_fn(|r| &data.gram[(i + r) * m..(i + r + 1) * m]);
        let mut sums = [0.0f64; 4];
        for (j, &zj) in z.iter().enumerate() {
            for r in 0..4 {
                sums[r] += rows[r][j] * zj;
            }
        }
        for (r, sum) in sums.iter().enumerate() {
            zgz += z[i + r] * sum;
        }
        i += 4;
    }
    for i in i..m {
        let gi = &data.gram[i * m..(i + 1) * m];
        zgz += z[i] * gi.iter().zip(&z).map(|(a, b)| a * b).sum::<f64>();
    }
    let zr: f64 = z.iter().zip(data.rhs).map(|(a, b)| a * b).sum();
    let rss = (data.yy - 2.0 * zr + zgz).max(0.0);
    let fit = EverettFit {
        rms: (rss / data.weight_sum).sqrt(),
        model,
        offsets,
        rss,
        n_rows: data.n_rows,
        iterations: sol.iterations,
        passive: sol.passive,
        converged: sol.converged,
        kkt_violation: sol.kkt_violation,
        condition: sol.condition,
        drift: None,
    };
    Ok((fit, factor))
}

/// The nonnegative solve of [`solve`] alone: the solver's result, the table, the offsets and the factor of the
/// solution's passive set for the normal right-hand side `rhs` (its first `nn` entries the nodes) and the
/// regularised matrix `q` (`carried`: a factor an earlier solve of `q` handed back).
pub(super) fn solve_masses(
    grid: &EverettGrid,
    rhs: &[f64],
    nn: usize,
    q: &[f64],
    options: EverettFitOptions,
    warm_start: Option<&[bool]>,
    carried: Option<PassiveFactor>,
) -> Result<(NnlsSolution, EverettModel, Vec<f64>, Option<PassiveFactor>), IdentificationError> {
    let m = rhs.len();
    let mut c = grid.nodes_to_masses_adjoint(&rhs[..nn]);
    c.extend_from_slice(&rhs[nn..]);
    let constrained: Vec<bool> = (0..m).map(|i| i < nn && !options.signed).collect();
    let (sol, factor) =
        nnls_gram_carried(q, &c, &constrained, options.max_iter, warm_start, carried)?;
    let offsets = sol.x[nn..].to_vec();
    let model = if options.signed {
        EverettModel::with_signed_masses(grid.clone(), sol.x[..nn].to_vec(), offsets[0])?
    } else {
        let masses: Vec<f64> = sol.x[..nn].iter().map(|&v| v.max(0.0)).collect();
        EverettModel::new(grid.clone(), masses, offsets[0])?
    };
    Ok((sol, model, offsets, factor))
}

/// Entries of a sparse regressor row reserved per row when a regression is prepared (rows of a deep memory take
/// more, and the storage then grows).
const ROW_ENTRIES_RESERVED: usize = 24;

/// One run of an [`EverettRegression`]: input, per-sample row weight (0 keeps a sample out of the fit while it
/// drives the memory) and its offset column.
#[derive(Clone, Copy, Debug)]
pub struct EverettInput<'a> {
    /// Input samples.
    pub u: &'a [f64],
    /// Row weights.
    pub weight: &'a [f64],
    /// Offset column of this run (`< n_offsets`).
    pub offset_col: usize,
}

/// The least-squares problem of [`fit_everett`] prepared for one input history: the regressors (sparse rows)
/// and the regularised normal matrix are built once, and [`Self::fit`] then identifies the table for any
/// output at the cost of one right-hand side and a (warm-started) nonnegative solve. Used where many outputs
/// share one input, e.g. when the same runs are re-identified with different corrections of the measured
/// output: each fit starts from the passive set of the last one and the factor of its normal matrix on that set
/// (an output whose answer keeps that set takes no factorisation).
#[derive(Clone, Debug)]
pub struct EverettRegression {
    grid: EverettGrid,
    options: EverettFitOptions,
    normal: NormalEquations,
    q: Vec<f64>,
    run_lengths: Vec<usize>,
    // Sparse regressor rows: row r covers entries row_ptr[r]..row_ptr[r + 1] and reads output sample
    // row_sample[r] (flat index over the runs) with weight row_weight[r].
    row_ptr: Vec<usize>,
    row_sample: Vec<usize>,
    row_weight: Vec<f64>,
    col: Vec<u32>,
    val: Vec<f64>,
    last: LastAnswer,
}

/// The factor of the last fit's passive set, the start of the next fit (not cloned: a copy starts afresh).
#[derive(Default)]
struct LastAnswer(std::sync::Mutex<Option<PassiveFactor>>);

impl LastAnswer {
    /// The factor, taken out (None when another fit holds it or there is none).
    fn take(&self) -> Option<PassiveFactor> {
        self.0.try_lock().ok().and_then(|mut held| held.take())
    }

    fn put(&self, factor: Option<PassiveFactor>) {
        if let (Some(f), Ok(mut held)) = (factor, self.0.try_lock()) {
            *held = Some(f);
        }
    }
}

impl Clone for LastAnswer {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl core::fmt::Debug for LastAnswer {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("LastAnswer")
    }
}

impl EverettRegression {
    /// Regressors of `inputs` on `grid` with `n_offsets` free offsets.
    pub fn new(
        grid: &EverettGrid,
        inputs: &[EverettInput<'_>],
        n_offsets: usize,
        options: EverettFitOptions,
    ) -> Result<Self, IdentificationError> {
        check_options(n_offsets, options)?;
        let mut normal = NormalEquations::new(grid, n_offsets)?;
        // Room for every row at once (the sparse rows hold a few dozen entries each): no copy as they grow.
        let rows: usize = inputs
            .iter()
            .map(|r| r.weight.iter().filter(|&&w| w > 0.0).count())
            .sum();
        let (mut row_ptr, mut row_sample, mut row_weight) = (
            Vec::with_capacity(rows + 1),
            Vec::with_capacity(rows),
            Vec::with_capacity(rows),
        );
        row_ptr.push(0);
        let entries = limits::product(rows, ROW_ENTRIES_RESERVED);
        let (mut col, mut val) = (Vec::with_capacity(entries), Vec::with_capacity(entries));
        let mut base = 0;
        for (k, run) in inputs.iter().enumerate() {
            normal
                .add_rows(
                    grid,
                    run.u,
                    run.weight,
                    run.offset_col,
                    &[],
                    1.0,
                    None,
                    |i, w, row| {
                        for &(a, va) in row {
                            col.push(a as u32);
                            val.push(va);
                        }
                        row_ptr.push(col.len());
                        row_sample.push(base + i);
                        row_weight.push(w);
                        Ok(())
                    },
                )
                .map_err(|error| IdentificationError::Run { run: k, error })?;
            base += run.u.len();
        }
        if normal.n_rows == 0 {
            return Err(IdentificationError::NoSamples);
        }
        // The room reserved and not taken is given back (the regression is kept while it is reused).
        col.shrink_to_fit();
        val.shrink_to_fit();
        normal.finish();
        let q = mass_space_matrix(grid, &normal, options)?;
        Ok(Self {
            grid: grid.clone(),
            options,
            normal,
            q,
            run_lengths: inputs.iter().map(|r| r.u.len()).collect(),
            row_ptr,
            row_sample,
            row_weight,
            col,
            val,
            last: LastAnswer::default(),
        })
    }

    /// Number of regression rows.
    pub fn n_rows(&self) -> usize {
        self.normal.n_rows
    }

    /// Number of unknowns (cell masses and offsets), the length of a warm start.
    pub fn n_unknowns(&self) -> usize {
        self.normal.n_cols()
    }

    /// Identify the table for the outputs of the runs (one slice per run, each as long as its input);
    /// `warm_start`: a passive set from an earlier fit (e.g. [`EverettFit::passive`]) to start the nonnegative
    /// solver from when this regression has not been fitted yet (afterwards each fit starts from the last one's
    /// answer). The result does not depend on the start (the solution is unique), only the work does.
    pub fn fit(
        &self,
        outputs: &[&[f64]],
        warm_start: Option<&[bool]>,
    ) -> Result<EverettFit, IdentificationError> {
        if outputs.len() != self.run_lengths.len() {
            return Err(IdentificationError::LengthMismatch {
                first: "runs",
                first_len: self.run_lengths.len(),
                second: "outputs",
                second_len: outputs.len(),
            });
        }
        for (k, (y, &n)) in outputs.iter().zip(&self.run_lengths).enumerate() {
            if y.len() != n {
                return Err(IdentificationError::Run {
                    run: k,
                    error: RunError::Lengths {
                        inputs: n,
                        outputs: y.len(),
                        weights: n,
                    },
                });
            }
        }
        if let Some(w) = warm_start
            && w.len() != self.n_unknowns()
        {
            return Err(IdentificationError::LengthMismatch {
                first: "unknowns",
                first_len: self.n_unknowns(),
                second: "warm start",
                second_len: w.len(),
            });
        }
        let mut rhs = alloc::vec![0.0; self.n_unknowns()];
        let mut yy = 0.0;
        // The rows run through the runs in order: each run's rows read its output in place (no joined copy).
        let mut run = 0;
        let mut base = 0;
        for r in 0..self.row_sample.len() {
            let mut i = self.row_sample[r] - base;
            while i >= self.run_lengths[run] {
                i -= self.run_lengths[run];
                base += self.run_lengths[run];
                run += 1;
            }
            let y = outputs[run][i];
            if !y.is_finite() {
                return Err(IdentificationError::Run {
                    run,
                    error: RunError::NonFinite {
                        what: "output",
                        sample: i,
                        value: y,
                    },
                });
            }
            let w = self.row_weight[r];
            for e in self.row_ptr[r]..self.row_ptr[r + 1] {
                rhs[self.col[e] as usize] += w * self.val[e] * y;
            }
            yy += w * y * y;
        }
        let data = DataTerm::of(&self.normal, &rhs, yy);
        let carried = self.last.take();
        let warm_start = if carried.is_some() { None } else { warm_start };
        let (fit, factor) = solve(
            &self.grid,
            &data,
            &self.q,
            self.options,
            warm_start,
            carried,
        )?;
        self.last.put(factor);
        Ok(fit)
    }
}

/// One first difference of the density between neighbouring cells: `(cell a, scale a), (cell b, scale b)`, the
/// difference being `scale_a · w_a − scale_b · w_b` (a scale turns a mass into a density).
pub(super) type DensityDifference = ((usize, f64), (usize, f64));

/// The first differences of the density between neighbouring cells (the rows of `D`) and `tr(DᵀD)`: along `α`
/// and `β` with weight `1 − diagonal`, along the diagonal (equal `α − β`) with weight `diagonal`; the reversible
/// part's cells on the diagonal with weight 1 (they have only diagonal neighbours).
pub(super) fn smoothness_pairs(grid: &EverettGrid, diagonal: f64) -> (Vec<DensityDifference>, f64) {
    let g = grid.nodes();
    let n = grid.n_intervals();
    let h = |p: usize| g[p + 1] - g[p];
    // Density scale of each cell: 1/area off the diagonal, 1/length on it.
    let scale = |p: usize, q: usize| {
        if p == q {
            1.0 / h(p)
        } else {
            1.0 / (h(p) * h(q))
        }
    };
    let (axis, along) = ((1.0 - diagonal).sqrt(), diagonal.sqrt());
    let mut pairs: Vec<DensityDifference> = Vec::new();
    let mut push = |a: (usize, usize), b: (usize, usize), w: f64| {
        if w > 0.0 {
            pairs.push((
                (grid.cell_index(a.0, a.1), w * scale(a.0, a.1)),
                (grid.cell_index(b.0, b.1), w * scale(b.0, b.1)),
            ));
        }
    };
    for p in 0..n {
        for qq in p..n {
            if p == qq {
                if p + 1 < n {
                    push((p, p), (p + 1, p + 1), 1.0);
                }
                continue;
            }
            if qq + 1 < n {
                push((p, qq), (p, qq + 1), axis);
                push((p, qq), (p + 1, qq + 1), along);
            }
            if p + 1 < qq {
                push((p, qq), (p + 1, qq), axis);
            }
        }
    }
    let trace_d: f64 = pairs
        .iter()
        .map(|&((_, sa), (_, sb))| sa * sa + sb * sb)
        .sum();
    (pairs, trace_d)
}

/// Add `λ Dᵀ D` for first differences of the density between neighbouring cells (see [`smoothness_pairs`]).
fn add_smoothness(
    grid: &EverettGrid,
    q: &mut [f64],
    m: usize,
    smoothing: f64,
    diagonal: f64,
    trace_q: f64,
) {
    if smoothing <= 0.0 {
        return;
    }
    let (pairs, trace_d) = smoothness_pairs(grid, diagonal);
    if trace_d <= 0.0 {
        return;
    }
    let lambda = smoothing * trace_q / trace_d;
    for ((a, sa), (b, sb)) in pairs {
        q[a * m + a] += lambda * sa * sa;
        q[b * m + b] += lambda * sb * sb;
        q[a * m + b] -= lambda * sa * sb;
        q[b * m + a] -= lambda * sa * sb;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn triangle(n: usize, amps: &[f64]) -> Vec<f64> {
        let mut u = Vec::new();
        for &a in amps {
            for k in 0..n {
                u.push(-a + 2.0 * a * k as f64 / n as f64);
            }
            for k in 0..n {
                u.push(a - 2.0 * a * k as f64 / n as f64);
            }
        }
        u
    }

    #[test]
    fn recovers_a_model_on_its_own_grid() {
        let grid = EverettGrid::uniform(-1.0, 1.0, 10).unwrap();
        let masses: Vec<f64> = (0..grid.n_cells())
            .map(|k| 0.02 + 0.01 * ((k * 37) % 7) as f64)
            .collect();
        let truth = EverettModel::new(grid.clone(), masses, -2.0).unwrap();
        let mut u = triangle(200, &[1.0]);
        u.extend(triangle(97, &[0.9, 0.7, 0.5, 0.3, 0.8, 0.2, 0.6]));
        let y = truth.simulate(&u, None);
        let w = alloc::vec![1.0; u.len()];
        let opts = EverettFitOptions {
            smoothing: 0.0,
            ..Default::default()
        };
        let fit = fit_everett(
            &grid,
            &[EverettRun {
                u: &u,
                y: &y,
                weight: &w,
                offset_col: 0,
                history: &[],
                gain: 1.0,
                drift: &[],
            }],
            1,
            opts,
        )
        .unwrap();
        assert!(fit.rms < 1e-6, "rms {}", fit.rms);
        let test = triangle(50, &[0.95, 0.45, 0.65]);
        let a = truth.simulate(&test, None);
        let b = fit.model.simulate(&test, None);
        let err = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-4, "held-out error {err}");
    }

    /// One run from negative saturation with one offset column, unit gain and no drift.
    fn plain_run<'a>(u: &'a [f64], y: &'a [f64], w: &'a [f64]) -> EverettRun<'a> {
        EverettRun {
            u,
            y,
            weight: w,
            offset_col: 0,
            history: &[],
            gain: 1.0,
            drift: &[],
        }
    }

    /// The input of one major loop, then a first-order reversal curve at each of `reversals` (from positive
    /// saturation down to the reversal, then up again), `n` samples a sweep.
    fn forc_input(reversals: &[f64], n: usize) -> Vec<f64> {
        let mut u = triangle(200, &[1.0]);
        for &r in reversals {
            for k in 0..=n {
                u.push(1.0 - (1.0 - r) * k as f64 / n as f64);
            }
            for k in 1..=n {
                u.push(r + (1.0 - r) * k as f64 / n as f64);
            }
        }
        u
    }

    #[test]
    fn the_diagonal_penalty_carries_a_coercivity_ridge_between_few_curves() {
        // A hard material: switching widths `α − β` in a narrow band around 0.5, interaction field broad. Five
        // first-order curves cross the band; between them the isotropic penalty blurs it, the diagonal one follows it.
        let grid = EverettGrid::uniform(-1.0, 1.0, 24).unwrap();
        let g = grid.nodes().to_vec();
        let mut masses = alloc::vec![0.0; grid.n_cells()];
        for p in 0..24 {
            for q in p..24 {
                let (b, a) = (0.5 * (g[p] + g[p + 1]), 0.5 * (g[q] + g[q + 1]));
                let width = (a - b - 0.5) / 0.06;
                let field = 0.5 * (a + b) / 0.5;
                masses[grid.cell_index(p, q)] =
                    libm::exp(-0.5 * (width * width + field * field)) + 1e-4;
            }
        }
        let truth = EverettModel::new(grid.clone(), masses, -1.0).unwrap();
        let u = forc_input(&[-0.8, -0.45, -0.1, 0.25, 0.6], 60);
        let y = truth.simulate(&u, None);
        let w = alloc::vec![1.0; u.len()];
        let test = {
            let mut t = triangle(200, &[1.0]);
            t.extend(triangle(40, &[0.62, 0.33, 0.47, 0.2, 0.55]));
            t
        };
        let want = truth.simulate(&test, None);
        let held_out = |diagonal: f64| {
            let opts = EverettFitOptions {
                smoothing: 1e-4,
                diagonal_smoothing: diagonal,
                ..Default::default()
            };
            let fit = fit_everett(&grid, &[plain_run(&u, &y, &w)], 1, opts).unwrap();
            let got = fit.model.simulate(&test, None);
            let sse: f64 = want.iter().zip(&got).map(|(a, b)| (a - b) * (a - b)).sum();
            libm::sqrt(sse / want.len() as f64)
        };
        let (isotropic, diagonal) = (held_out(0.0), held_out(1.0));
        assert!(
            diagonal < 0.7 * isotropic,
            "diagonal {diagonal}, isotropic {isotropic}"
        );
        // A share outside [0, 1] is refused.
        let bad = EverettFitOptions {
            diagonal_smoothing: 1.5,
            ..Default::default()
        };
        assert!(matches!(
            check_options(1, bad),
            Err(IdentificationError::BadParameter {
                name: "diagonal_smoothing",
                ..
            })
        ));
    }

    #[test]
    fn the_isotropic_penalty_has_no_diagonal_pairs() {
        let grid = EverettGrid::uniform(-1.0, 1.0, 6).unwrap();
        let (iso, _) = smoothness_pairs(&grid, 0.0);
        let (half, _) = smoothness_pairs(&grid, 0.5);
        let (along, _) = smoothness_pairs(&grid, 1.0);
        // Axis pairs: 2 per off-diagonal cell less the edges; diagonal pairs: one per off-diagonal cell below the
        // top row; the reversible cells' pairs in all three.
        assert_eq!(half.len(), iso.len() + along.len() - 5);
        assert!(iso.len() > along.len());
    }

    #[test]
    fn a_signed_table_fits_loops_that_run_clockwise() {
        // Negative hysteretic masses on a positive reversible diagonal: every loop runs clockwise (the output
        // leads the input), which no nonnegative density can produce.
        let grid = EverettGrid::uniform(-1.0, 1.0, 10).unwrap();
        let masses: Vec<f64> = (0..grid.n_cells())
            .map(|k| {
                let m = 0.02 + 0.01 * ((k * 37) % 7) as f64;
                if (0..grid.n_intervals()).any(|i| grid.cell_index(i, i) == k) {
                    m + 0.3
                } else {
                    -m
                }
            })
            .collect();
        let truth = EverettModel::with_signed_masses(grid.clone(), masses, -2.0).unwrap();
        assert!(!truth.is_monotone());
        assert!(matches!(
            EverettModel::new(grid.clone(), truth.masses().to_vec(), -2.0),
            Err(IdentificationError::NegativeMass { .. })
        ));
        let mut u = triangle(200, &[1.0]);
        u.extend(triangle(97, &[0.9, 0.7, 0.5, 0.3, 0.8, 0.2, 0.6]));
        let y = truth.simulate(&u, None);
        let w = alloc::vec![1.0; u.len()];
        let fit_with = |signed| {
            let opts = EverettFitOptions {
                smoothing: 0.0,
                signed,
                ..Default::default()
            };
            fit_everett(&grid, &[plain_run(&u, &y, &w)], 1, opts).unwrap()
        };
        let signed = fit_with(true);
        assert!(signed.rms < 1e-6, "signed rms {}", signed.rms);
        assert!(!signed.model.is_monotone());
        let test = triangle(50, &[0.95, 0.45, 0.65]);
        let a = truth.simulate(&test, None);
        let b = signed.model.simulate(&test, None);
        let err = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-4, "held-out error {err}");
        assert!(matches!(
            signed
                .model
                .hysteresis::<16>(1, &Default::default(), crate::cbh::Initial::Negative),
            Err(IdentificationError::SignedTable { .. })
        ));
        let bounded = fit_with(false);
        assert!(bounded.model.is_monotone());
        assert!(
            bounded.rms > 1e3 * signed.rms.max(1e-9),
            "nonnegative rms {}",
            bounded.rms
        );
    }

    #[test]
    fn first_order_curves_are_monotone_and_meet_the_major_loop() {
        let grid = EverettGrid::uniform(0.0, 2.0, 6).unwrap();
        let masses: Vec<f64> = (0..grid.n_cells())
            .map(|k| 0.1 + 0.05 * (k % 3) as f64)
            .collect();
        let model = EverettModel::new(grid, masses, 1.0).unwrap();
        let (asc, desc) = model.first_order_curves();
        assert_eq!(asc.len(), 6);
        assert_eq!(desc.len(), 6);
        for (u, y) in asc.iter().chain(desc.iter()) {
            assert_eq!(u.len(), y.len());
            for k in 1..y.len() {
                assert!((y[k] - y[k - 1]) * (u[k] - u[k - 1]) >= -1e-12);
            }
        }
        let top = asc[0].1.last().unwrap();
        for (_, y) in &asc {
            assert!((y.last().unwrap() - top).abs() < 1e-12);
        }
        assert!((asc[0].1[0] - 1.0).abs() < 1e-12);
        assert!(model.everett(0.5, 0.4) == 0.0);
        // Subdivided reversals: same major branches, four times the curves, each exact against `everett`.
        let (asc4, desc4) = model.first_order_curves_subdivided(4).unwrap();
        assert_eq!((asc4.len(), desc4.len()), (24, 24));
        assert_eq!(asc4[0], asc[0]);
        assert_eq!(desc4[0], desc[0]);
        let (u, y) = &asc4[5];
        let m = u[0];
        let mid = 0.5 * (u[0] + u[1]);
        let y_mid = y[0] + 0.5 * (y[1] - y[0]);
        assert!((y_mid - (y[0] + model.everett(m, mid))).abs() < 1e-12);
    }

    #[test]
    fn an_unknown_start_state_is_found_among_the_candidates() {
        let grid = EverettGrid::uniform(-1.0, 1.0, 8).unwrap();
        let masses: Vec<f64> = (0..grid.n_cells())
            .map(|k| 0.1 + 0.02 * (k % 5) as f64)
            .collect();
        let model = EverettModel::new(grid, masses, 0.5).unwrap();
        // The run starts at 0.1 after positive saturation and a fall to -0.5 (a grid node), then wanders.
        let u = [0.1, 0.3, -0.2, 0.6, 0.0, 0.45, -0.1];
        let y: Vec<f64> = model
            .simulate_from(&[1.0, -0.5], &u, None)
            .iter()
            .map(|v| v + 2.0)
            .collect();
        let w = [1.0; 7];
        let (h, rss, offset) = model.best_initial_state(&u, &y, &w, true, 1.0);
        assert_eq!(h, [1.0, -0.5]);
        assert!(rss < 1e-20 && (offset - 2.5).abs() < 1e-12);
    }

    /// A FORC-like family whose output also integrates the input (a leakage into a charge amplifier): the
    /// tables and the leakage rate are identified together, and without the drift column the fit is far off.
    #[test]
    fn drift_column_is_identified_with_the_table() {
        let grid = EverettGrid::uniform(-1.0, 1.0, 10).unwrap();
        let masses: Vec<f64> = (0..grid.n_cells())
            .map(|k| 0.05 + 0.01 * (k % 3) as f64)
            .collect();
        let model = EverettModel::new(grid.clone(), masses, 0.0).unwrap();
        let mut u = Vec::new();
        for k in 0..8 {
            let turn = -1.0 + 0.25 * k as f64;
            let up = (0..=40).map(|i| -1.0 + (turn + 1.0) * i as f64 / 40.0);
            let down = (0..=40).map(|i| turn - (turn + 1.0) * i as f64 / 40.0);
            u.extend(up.chain(down));
            u.extend((0..=40).map(|i| -1.0 + 2.0 * i as f64 / 40.0));
            u.extend((0..=40).map(|i| 1.0 - 2.0 * i as f64 / 40.0));
        }
        let dt = 0.01;
        let rate = -0.8;
        let mut integral = alloc::vec![0.0; u.len()];
        for i in 1..u.len() {
            integral[i] = integral[i - 1] + 0.5 * dt * (u[i] + u[i - 1]);
        }
        let clean = model.simulate_from(&[], &u, None);
        let y: Vec<f64> = clean
            .iter()
            .zip(&integral)
            .map(|(v, d)| v + rate * d)
            .collect();
        let w = alloc::vec![1.0; u.len()];
        let run = |drift| EverettRun {
            u: &u,
            y: &y,
            weight: &w,
            offset_col: 0,
            history: &[],
            gain: 1.0,
            drift,
        };
        let opts = EverettFitOptions::default();
        let joint = fit_everett(&grid, &[run(&integral)], 1, opts).unwrap();
        let plain = fit_everett(&grid, &[run(&[])], 1, opts).unwrap();
        let found = joint.drift.unwrap();
        assert!((found - rate).abs() < 0.02 * rate.abs(), "{found}");
        assert_eq!((joint.offsets.len(), plain.drift), (1, None));
        assert!(
            joint.rms < 0.1 * plain.rms,
            "{} vs {}",
            joint.rms,
            plain.rms
        );
    }

    #[test]
    fn sizes_are_bounded_before_allocation() {
        use crate::limits::{MAX_EVERETT_INTERVALS, MAX_EVERETT_LARGE_UNKNOWNS};
        let limit = |e: IdentificationError| matches!(e, IdentificationError::Limit(_));
        assert!(limit(
            EverettGrid::uniform(0.0, 1.0, MAX_EVERETT_INTERVALS + 1).unwrap_err()
        ));
        let grid = EverettGrid::uniform(0.0, 1.0, 8).unwrap();
        let run = EverettRun {
            u: &[0.0, 1.0],
            y: &[0.0, 1.0],
            weight: &[1.0, 1.0],
            offset_col: 0,
            history: &[],
            gain: 1.0,
            drift: &[],
        };
        let fit = |n_offsets, max_iter| {
            let opts = EverettFitOptions {
                max_iter,
                ..Default::default()
            };
            fit_everett(&grid, &[run], n_offsets, opts)
        };
        assert!(limit(fit(MAX_EVERETT_LARGE_UNKNOWNS, 10).unwrap_err()));
        assert!(limit(fit(usize::MAX, 10).unwrap_err()));
        assert!(limit(fit(1, usize::MAX).unwrap_err()));
        let model = EverettModel::new(grid.clone(), alloc::vec![0.1; grid.n_cells()], 0.0).unwrap();
        assert!(limit(
            model.first_order_curves_subdivided(1 << 40).unwrap_err()
        ));
        assert!(model.first_order_curves_subdivided(3).is_ok());
    }

    #[test]
    fn prepared_regression_matches_the_one_shot_fit_and_warm_starts() {
        let grid = EverettGrid::uniform(-1.0, 1.0, 12).unwrap();
        let masses: Vec<f64> = (0..grid.n_cells())
            .map(|k| {
                if k % 4 == 0 {
                    0.0
                } else {
                    0.01 * ((k * 13) % 5) as f64
                }
            })
            .collect();
        let truth = EverettModel::new(grid.clone(), masses, 1.0).unwrap();
        let u = triangle(61, &[1.0, 0.8, 0.35, 0.9, 0.1, 0.6]);
        let y: Vec<f64> = truth
            .simulate(&u, None)
            .iter()
            .enumerate()
            .map(|(i, v)| v + 0.01 * (((i * 7919) % 17) as f64 - 8.0))
            .collect();
        let w: Vec<f64> = (0..u.len())
            .map(|i| if i < 100 { 0.0 } else { 1.0 })
            .collect();
        let opts = EverettFitOptions::default();
        let run = EverettRun {
            u: &u,
            y: &y,
            weight: &w,
            offset_col: 0,
            history: &[],
            gain: 1.0,
            drift: &[],
        };
        let once = fit_everett(&grid, &[run], 1, opts).unwrap();
        let input = EverettInput {
            u: &u,
            weight: &w,
            offset_col: 0,
        };
        let reg = EverettRegression::new(&grid, &[input], 1, opts).unwrap();
        let cold = reg.fit(&[&y], None).unwrap();
        assert_eq!(cold.model, once.model);
        assert_eq!((cold.rss, cold.iterations), (once.rss, once.iterations));
        // Another output on the same input: started from the first fit's answer (its passive set and factor),
        // the same answer to the bit as a cold start on a regression of its own.
        let y2: Vec<f64> = y.iter().zip(&u).map(|(a, b)| a + 0.3 * b * b).collect();
        let carried2 = reg.fit(&[&y2], None).unwrap();
        let fresh = EverettRegression::new(&grid, &[input], 1, opts).unwrap();
        let cold2 = fresh.fit(&[&y2], None).unwrap();
        assert_eq!(carried2.model, cold2.model);
        assert_eq!(carried2.rss.to_bits(), cold2.rss.to_bits());
        assert!(carried2.iterations <= cold2.iterations);
        // A warm start on a fresh regression: the same answer too.
        let warm2 = EverettRegression::new(&grid, &[input], 1, opts)
            .unwrap()
            .fit(&[&y2], Some(&cold.passive))
            .unwrap();
        assert_eq!(warm2.model, cold2.model);
        // The first output again, from the second's answer: the first fit to the bit.
        let again = reg.fit(&[&y], None).unwrap();
        assert_eq!(again.model, cold.model);
        assert!(reg.fit(&[&y2[1..]], None).is_err());
        assert!(reg.fit(&[&y2], Some(&[true; 3])).is_err());
    }

    #[test]
    fn a_regression_reads_each_runs_output_in_place() {
        // Three runs of different lengths, each with its offset: the rows read the outputs where they lie (the same
        // fit as `fit_everett` on the runs), and a non-finite output is named by its run and sample, unless its row
        // is weighted out.
        let grid = EverettGrid::uniform(-1.0, 1.0, 6).unwrap();
        let lengths = [310usize, 170, 250];
        let us: Vec<Vec<f64>> = lengths
            .iter()
            .enumerate()
            .map(|(k, &n)| {
                (0..n)
                    .map(|i| (0.7 + 0.1 * k as f64) * (i as f64 * 0.05 * (k + 1) as f64).sin())
                    .collect()
            })
            .collect();
        let ys: Vec<Vec<f64>> = us
            .iter()
            .enumerate()
            .map(|(k, u)| u.iter().map(|v| v + 0.2 * v * v + k as f64).collect())
            .collect();
        let ws: Vec<Vec<f64>> = lengths
            .iter()
            .map(|&n| (0..n).map(|i| if i < 20 { 0.0 } else { 1.0 }).collect())
            .collect();
        let opts = EverettFitOptions::default();
        let runs: Vec<EverettRun<'_>> = (0..3)
            .map(|k| EverettRun {
                u: &us[k],
                y: &ys[k],
                weight: &ws[k],
                offset_col: k,
                history: &[],
                gain: 1.0,
                drift: &[],
            })
            .collect();
        let once = fit_everett(&grid, &runs, 3, opts).unwrap();
        let inputs: Vec<EverettInput<'_>> = (0..3)
            .map(|k| EverettInput {
                u: &us[k],
                weight: &ws[k],
                offset_col: k,
            })
            .collect();
        let reg = EverettRegression::new(&grid, &inputs, 3, opts).unwrap();
        let views: Vec<&[f64]> = ys.iter().map(Vec::as_slice).collect();
        let fit = reg.fit(&views, None).unwrap();
        assert_eq!(fit.model, once.model);
        assert_eq!(fit.offsets, once.offsets);
        let mut bad = ys.clone();
        bad[2][57] = f64::NAN;
        bad[1][3] = f64::INFINITY; // weighted out: not a row
        let views: Vec<&[f64]> = bad.iter().map(Vec::as_slice).collect();
        match reg.fit(&views, None) {
            Err(IdentificationError::Run {
                run: 2,
                error: RunError::NonFinite { sample: 57, .. },
            }) => {}
            other => panic!("expected run 2 sample 57 named, got {other:?}"),
        }
    }

    #[test]
    fn rejects_bad_masses() {
        let grid = EverettGrid::uniform(0.0, 1.0, 2).unwrap();
        assert!(EverettModel::new(grid.clone(), alloc::vec![1.0; 2], 0.0).is_err());
        assert!(EverettModel::new(grid.clone(), alloc::vec![1.0, -1.0, 0.0], 0.0).is_err());
        assert!(EverettModel::new(grid, alloc::vec![1.0, f64::NAN, 0.0], 0.0).is_err());
    }
}
