//! Regressors of a Preisach model whose Everett function is tabulated on a grid.
//!
//! The Everett function `E(β, α)` (β ≤ α) is the output rise when the input goes up from a reversal minimum `β`
//! to `α`: the ascending first-order curve from `m` is `y(m) + E(m, u)` and the descending one from `M` is
//! `y(M) − E(u, M)`. It is parameterised by nonnegative masses `w_pq` of the grid cells
//! (β in interval `p`, α in interval `q`, `p ≤ q`):
//! `E(g_i, g_j) = Σ_{i ≤ p ≤ q < j} w_pq`, so `E` is nondecreasing in α and nonincreasing in β (a monotone
//! model) by construction whenever `w ≥ 0`. Off the nodes `E` is bilinear inside off-diagonal cells (uniform
//! density) and linear inside diagonal triangles (a reversible part spread along the diagonal), so every
//! first-order curve is piecewise linear between grid nodes.
//!
//! Given the input history, the output is `offset + Σ ±E(β_k, α_k)` over the reversal pairs of the memory
//! staircase, i.e. linear in the node values and hence in the masses: this module produces those weights.
use alloc::vec::Vec;

use super::error::{IdentificationError, RunError};
use crate::limits::{self, MAX_EVERETT_INTERVALS, MAX_EVERETT_UNKNOWNS};

/// Strictly increasing input grid `g_0 < … < g_N` (N ≥ 1) of an Everett table.
#[derive(Clone, Debug, PartialEq)]
pub struct EverettGrid {
    nodes: Vec<f64>,
}

impl EverettGrid {
    /// Validate and wrap the grid nodes (finite, strictly increasing, at least two, at most
    /// [`MAX_EVERETT_INTERVALS`] intervals).
    pub fn new(nodes: Vec<f64>) -> Result<Self, IdentificationError> {
        if nodes.len() < 2 {
            return Err(IdentificationError::GridTooShort { nodes: nodes.len() });
        }
        limits::check(
            "number of Everett grid intervals",
            nodes.len() - 1,
            MAX_EVERETT_INTERVALS,
        )?;
        if let Some(i) = nodes.iter().position(|v| !v.is_finite()) {
            return Err(IdentificationError::NonFinite {
                what: "Everett grid node",
                index: i,
                value: nodes[i],
            });
        }
        if let Some(i) = nodes.windows(2).position(|w| w[1] <= w[0]) {
            return Err(IdentificationError::GridNotIncreasing {
                index: i + 1,
                value: nodes[i + 1],
                previous: nodes[i],
            });
        }
        Ok(Self { nodes })
    }

    /// Uniform grid of `n_intervals` intervals over `[lo, hi]`.
    pub fn uniform(lo: f64, hi: f64, n_intervals: usize) -> Result<Self, IdentificationError> {
        if n_intervals == 0 || !(lo.is_finite() && hi.is_finite()) || hi <= lo {
            return Err(IdentificationError::BadUniformGrid {
                lo,
                hi,
                intervals: n_intervals,
            });
        }
        limits::check(
            "number of Everett grid intervals",
            n_intervals,
            MAX_EVERETT_INTERVALS,
        )?;
        let h = (hi - lo) / n_intervals as f64;
        let mut nodes: Vec<f64> = (0..=n_intervals).map(|i| lo + h * i as f64).collect();
        nodes[n_intervals] = hi;
        Self::new(nodes)
    }

    /// The grid nodes.
    pub fn nodes(&self) -> &[f64] {
        &self.nodes
    }

    /// Number of intervals `N`.
    pub fn n_intervals(&self) -> usize {
        self.nodes.len() - 1
    }

    /// Number of cell masses (also of independent node values): `N (N + 1) / 2`.
    pub fn n_cells(&self) -> usize {
        let n = self.n_intervals();
        n * (n + 1) / 2
    }

    /// Lowest grid input (negative saturation).
    pub fn lo(&self) -> f64 {
        self.nodes[0]
    }

    /// Highest grid input (positive saturation).
    pub fn hi(&self) -> f64 {
        self.nodes[self.nodes.len() - 1]
    }

    /// Index of cell `(p, q)`, `p ≤ q < N` (rows of the upper triangle, packed).
    pub fn cell_index(&self, p: usize, q: usize) -> usize {
        let n = self.n_intervals();
        debug_assert!(p <= q && q < n);
        p * n - p * (p + 1) / 2 + q
    }

    /// Index of node value `E(g_i, g_j)`, `i < j ≤ N`; shares the packing of cell `(i, j − 1)`.
    pub fn node_index(&self, i: usize, j: usize) -> usize {
        self.cell_index(i, j - 1)
    }

    /// Clamp `u` into the grid; return the interval index and the fraction inside it.
    pub fn locate(&self, u: f64) -> (usize, f64) {
        let n = self.n_intervals();
        if u.is_nan() || u <= self.nodes[0] {
            return (0, 0.0);
        }
        if u >= self.nodes[n] {
            return (n - 1, 1.0);
        }
        // Last node ≤ u.
        let i = self.nodes.partition_point(|&g| g <= u) - 1;
        let i = i.min(n - 1);
        let t = (u - self.nodes[i]) / (self.nodes[i + 1] - self.nodes[i]);
        (i, t)
    }

    /// Add `sign · E(β, α)` to `row` as (node index, weight) pairs. Requires β ≤ α (else nothing is added).
    pub fn push_everett(&self, beta: f64, alpha: f64, sign: f64, row: &mut Vec<(usize, f64)>) {
        if beta >= alpha {
            return;
        }
        self.push_everett_located(self.locate(beta), self.locate(alpha), sign, row);
    }

    /// [`Self::push_everett`] with β and α already located ([`Self::locate`]), β < α.
    fn push_everett_located(
        &self,
        (i, s): (usize, f64),
        (j, t): (usize, f64),
        sign: f64,
        row: &mut Vec<(usize, f64)>,
    ) {
        if i == j {
            // Diagonal triangle: E = E(g_i, g_{i+1}) · (t − s).
            let w = t - s;
            if w > 0.0 {
                row.push((self.node_index(i, i + 1), sign * w));
            }
            return;
        }
        // Bilinear over nodes (i, j), (i+1, j), (i, j+1), (i+1, j+1); nodes on the diagonal are zero.
        let corners = [
            (i, j, (1.0 - s) * (1.0 - t)),
            (i + 1, j, s * (1.0 - t)),
            (i, j + 1, (1.0 - s) * t),
            (i + 1, j + 1, s * t),
        ];
        for (a, b, w) in corners {
            if a < b && w != 0.0 {
                row.push((self.node_index(a, b), sign * w));
            }
        }
    }

    /// Node values `E(g_i, g_j)` from cell masses: `E = C w` (a 2-D cumulative sum, O(N²)).
    /// Input and output are packed like [`Self::cell_index`].
    pub fn masses_to_nodes(&self, w: &[f64]) -> Vec<f64> {
        let n = self.n_intervals();
        let mut e = alloc::vec![0.0; self.n_cells()];
        // E(i, j) = E(i, j − 1) + Σ_{p = i..j−1} w(p, j − 1)  (add column j − 1 from row i down to the diagonal).
        for i in 0..n {
            let mut acc = 0.0;
            for j in i + 1..=n {
                let q = j - 1;
                let mut col = 0.0;
                for p in i..=q {
                    col += w[self.cell_index(p, q)];
                }
                acc += col;
                e[self.node_index(i, j)] = acc;
            }
        }
        e
    }

    /// [`Self::masses_to_nodes`] into `out` (`n_cells` long) with `scratch` (at least `N + 1` long), in O(N²)
    /// without allocating: `E(i, j) = R(i, j) + E(i + 1, j)` with the row prefix `R(i, j) = Σ_{q = i..j−1} w(i, q)`.
    pub fn masses_to_nodes_into(&self, w: &[f64], out: &mut [f64], scratch: &mut [f64]) {
        let n = self.n_intervals();
        // below[j] = E(i + 1, j) for the row i being filled (0 on and below the diagonal).
        let below = &mut scratch[..=n];
        below.fill(0.0);
        for i in (0..n).rev() {
            let start = self.cell_index(i, i);
            let len = n - i;
            let mut prefix = 0.0;
            for l in 0..len {
                let j = i + 1 + l;
                prefix += w[start + l];
                let e = prefix + below[j];
                out[start + l] = e;
                below[j] = e;
            }
        }
    }

    /// Adjoint of [`Self::masses_to_nodes`]: `(Cᵀ g)(p, q) = Σ_{i ≤ p, j ≥ q + 1} g(i, j)`, O(N²).
    pub fn nodes_to_masses_adjoint(&self, g: &[f64]) -> Vec<f64> {
        let mut out = alloc::vec![0.0; self.n_cells()];
        let mut scratch = alloc::vec![0.0; self.n_intervals()];
        self.nodes_to_masses_adjoint_into(g, &mut out, &mut scratch);
        out
    }

    /// [`Self::nodes_to_masses_adjoint`] into `out` (`n_cells` long) with `scratch` (at least `N` long), without
    /// allocating.
    pub fn nodes_to_masses_adjoint_into(&self, g: &[f64], out: &mut [f64], scratch: &mut [f64]) {
        let n = self.n_intervals();
        // Packed row p holds cells (p, p..n) and node values E(g_p, g_{p+1..=n}) at the same positions.
        // suffix[q] = Σ_{j ≥ q+1} g(p, j), then a running prefix over p: colsum[q] = Σ_{i ≤ p} suffix_i[q].
        let colsum = &mut scratch[..n];
        colsum.fill(0.0);
        let mut start = 0;
        for p in 0..n {
            let len = n - p;
            let g_row = &g[start..start + len];
            let out_row = &mut out[start..start + len];
            let mut suffix = 0.0;
            for (l, &gv) in g_row.iter().enumerate().rev() {
                suffix += gv;
                out_row[l] = suffix;
            }
            for (o, c) in out_row.iter_mut().zip(&mut colsum[p..]) {
                *c += *o;
                *o = *c;
            }
            start += len;
        }
    }

    /// [`Self::nodes_to_masses_adjoint_into`] of `L` vectors at once (`g[r]` into `out[r]`, `scratch` at least
    /// `L · N` long): the running sums of the vectors are independent, so the processor overlaps them.
    pub fn nodes_to_masses_adjoint_lanes<const L: usize>(
        &self,
        g: [&[f64]; L],
        out: &mut [&mut [f64]; L],
        scratch: &mut [f64],
    ) {
        let n = self.n_intervals();
        let colsum = &mut scratch[..L * n]; // colsum[q * L + r]
        colsum.fill(0.0);
        let mut start = 0;
        for p in 0..n {
            let len = n - p;
            let mut suffix = [0.0; L];
            for l in (0..len).rev() {
                let c = &mut colsum[(p + l) * L..(p + l + 1) * L];
                for r in 0..L {
                    suffix[r] += g[r][start + l];
                }
                for r in 0..L {
                    // colsum[q] += suffix(q) for this row p, in the single-vector order.
                    c[r] += suffix[r];
                    out[r][start + l] = c[r];
                }
            }
            start += len;
        }
    }

    /// `E(β, α)` from packed node values (0 when β ≥ α).
    pub fn everett_value(&self, node_values: &[f64], beta: f64, alpha: f64) -> f64 {
        let mut row = Vec::with_capacity(4);
        self.push_everett(beta, alpha, 1.0, &mut row);
        row.iter().map(|&(k, w)| w * node_values[k]).sum()
    }
}

/// The reversal memory of a Preisach model on `[lo, hi]`: the alternating staircase of dominant extrema
/// `m_0 = lo < M_1 > m_1 < M_2 …` with wiping-out, plus the current input. Starts at negative saturation.
#[derive(Clone, Debug, PartialEq)]
pub struct PreisachMemory {
    lo: f64,
    hi: f64,
    stack: Vec<f64>,
    tip: f64,
    rising: bool,
}

/// Where the entries of a memory's staircase lie on a grid ([`EverettGrid::locate`]), kept from one sample to the
/// next: the staircase changes at reversals only, so a regression row locates the current input alone.
#[derive(Clone, Debug, Default)]
struct LocatedStack {
    /// (entry, its grid interval and fraction) for the staircase's entries, bottom first.
    cells: Vec<(f64, (usize, f64))>,
}

impl LocatedStack {
    /// `visit(β, α, sign)` of [`PreisachMemory::for_each_term`] as `sign · E(β, α)` pushed onto `row`, the
    /// entries located once while they stay in the staircase.
    fn push_terms(
        &mut self,
        grid: &EverettGrid,
        memory: &PreisachMemory,
        gain: f64,
        row: &mut Vec<(usize, f64)>,
    ) {
        let len = memory.stack.len();
        self.cells.truncate(len);
        for (k, &v) in memory.stack.iter().enumerate() {
            match self.cells.get_mut(k) {
                Some(cell) if cell.0 == v => {}
                Some(cell) => *cell = (v, grid.locate(v)),
                None => self.cells.push((v, grid.locate(v))),
            }
        }
        let tip = (memory.tip, grid.locate(memory.tip));
        let at = |k: usize| if k < len { self.cells[k] } else { tip };
        memory.for_each_pair(|b, a, sign| {
            let (beta, alpha) = (at(b), at(a));
            if beta.0 < alpha.0 {
                grid.push_everett_located(beta.1, alpha.1, gain * sign, row);
            }
        });
    }
}

impl PreisachMemory {
    /// Negative saturation (all hysterons down) on the grid's input range.
    pub fn new(grid: &EverettGrid) -> Self {
        Self {
            lo: grid.lo(),
            hi: grid.hi(),
            stack: alloc::vec![grid.lo()],
            tip: grid.lo(),
            rising: true,
        }
    }

    /// Negative saturation, then the inputs of `history` (an initial state the run starts from: e.g. `[hi, b]`
    /// is positive saturation followed by a fall to `b`).
    pub fn with_history(grid: &EverettGrid, history: &[f64]) -> Self {
        let mut m = Self::new(grid);
        for &x in history {
            m.update(x);
        }
        m
    }

    /// Back to negative saturation.
    pub fn reset(&mut self) {
        self.stack.clear();
        self.stack.push(self.lo);
        self.tip = self.lo;
        self.rising = true;
    }

    /// Number of stored reversal points (excluding the current input).
    pub fn depth(&self) -> usize {
        self.stack.len()
    }

    /// Apply input `u` (clamped to the grid range; NaN keeps the state).
    pub fn update(&mut self, u: f64) {
        if u.is_nan() {
            return;
        }
        let u = u.clamp(self.lo, self.hi);
        if self.rising {
            if u < self.tip {
                self.stack.push(self.tip);
                self.rising = false;
                self.tip = u;
                self.wipe_falling();
            } else {
                self.tip = u;
                self.wipe_rising();
            }
        } else if u > self.tip {
            self.stack.push(self.tip);
            self.rising = true;
            self.tip = u;
            self.wipe_rising();
        } else {
            self.tip = u;
            self.wipe_falling();
        }
    }

    // Rising: stack ends with a minimum; the maximum before it is wiped out once exceeded.
    fn wipe_rising(&mut self) {
        while self.stack.len() >= 3 && self.tip >= self.stack[self.stack.len() - 2] {
            self.stack.truncate(self.stack.len() - 2);
        }
    }

    // Falling: stack ends with a maximum; the minimum before it is wiped out once undershot.
    fn wipe_falling(&mut self) {
        while self.stack.len() >= 2 && self.tip <= self.stack[self.stack.len() - 2] {
            if self.stack.len() == 2 {
                // Back down to the bottom of the range: negative saturation.
                self.reset();
                return;
            }
            self.stack.truncate(self.stack.len() - 2);
        }
    }

    /// Visit the Everett terms of the output: `y = offset + Σ sign · E(β, α)`.
    pub fn for_each_term(&self, mut f: impl FnMut(f64, f64, f64)) {
        let len = self.stack.len();
        let at = |k: usize| if k < len { self.stack[k] } else { self.tip };
        self.for_each_pair(|b, a, sign| f(at(b), at(a), sign));
    }

    /// The terms of [`Self::for_each_term`] as positions in the staircase (its length: the current input).
    fn for_each_pair(&self, mut f: impl FnMut(usize, usize, f64)) {
        for k in 1..=self.stack.len() {
            if k % 2 == 1 {
                f(k - 1, k, 1.0);
            } else {
                f(k, k - 1, -1.0);
            }
        }
    }
}

/// Normal equations `G = Σ r rᵀ`, `b = Σ r y`, `Σ y²` of the regression in node space, with extra unconstrained
/// offset columns after the `n_cells` node columns. Dense, symmetric, row-major.
#[derive(Clone, Debug)]
pub struct NormalEquations {
    /// Number of node columns.
    pub n_nodes: usize,
    /// Number of offset columns (one per run or one shared).
    pub n_offsets: usize,
    /// `(n_nodes + n_offsets)²` Gram matrix, row-major.
    pub gram: Vec<f64>,
    /// Right-hand side `Σ r y`.
    pub rhs: Vec<f64>,
    /// `Σ w y²` (weighted).
    pub yy: f64,
    /// Number of rows accumulated.
    pub n_rows: usize,
    /// Sum of row weights.
    pub weight_sum: f64,
}

impl NormalEquations {
    /// Empty normal equations for `grid` with `n_offsets` offset columns; the unknowns (cells plus offsets) are
    /// at most [`MAX_EVERETT_UNKNOWNS`], checked before the dense Gram matrix is allocated.
    pub fn new(grid: &EverettGrid, n_offsets: usize) -> Result<Self, IdentificationError> {
        let n_nodes = grid.n_cells();
        let m = limits::check(
            "unknowns of the Everett fit (grid cells + offsets)",
            limits::sum(n_nodes, n_offsets),
            MAX_EVERETT_UNKNOWNS,
        )?;
        Ok(Self {
            n_nodes,
            n_offsets,
            gram: alloc::vec![0.0; m * m],
            rhs: alloc::vec![0.0; m],
            yy: 0.0,
            n_rows: 0,
            weight_sum: 0.0,
        })
    }

    /// Total number of columns.
    pub fn n_cols(&self) -> usize {
        self.n_nodes + self.n_offsets
    }

    /// Accumulate one run: the memory starts at negative saturation, follows `history` (the run's initial state)
    /// and then every sample of `u`; rows with weight `weight[i] > 0` enter the regression
    /// `y[i] ≈ offset[offset_col] + gain · Σ ±E` (`gain`: the run's calibration gain, 1 for none), plus
    /// `coefficient[c] · d[i]` for `drift = Some((c, d))` (a free column `c` after the offsets, e.g. a leakage
    /// integral shared by the runs). Call [`Self::finish`] after the last run.
    #[allow(clippy::too_many_arguments)]
    pub fn add_run(
        &mut self,
        grid: &EverettGrid,
        u: &[f64],
        y: &[f64],
        weight: &[f64],
        offset_col: usize,
        history: &[f64],
        gain: f64,
        drift: Option<(usize, &[f64])>,
    ) -> Result<(), RunError> {
        if y.len() != u.len() || weight.len() != u.len() {
            return Err(RunError::Lengths {
                inputs: u.len(),
                outputs: y.len(),
                weights: weight.len(),
            });
        }
        let mut rhs = core::mem::take(&mut self.rhs);
        let mut yy = self.yy;
        let result = self.add_rows(
            grid,
            u,
            weight,
            offset_col,
            history,
            gain,
            drift,
            |i, w, row| {
                if !y[i].is_finite() {
                    return Err(RunError::NonFinite {
                        what: "output",
                        sample: i,
                        value: y[i],
                    });
                }
                for &(a, va) in row {
                    rhs[a] += w * va * y[i];
                }
                yy += w * y[i] * y[i];
                Ok(())
            },
        );
        self.rhs = rhs;
        self.yy = yy;
        result
    }

    /// Accumulate the upper triangle of the Gram matrix of one run's regressors (memory from negative
    /// saturation followed by `history`, Everett terms scaled by `gain`, rows where `weight[i] > 0`) and hand every row to `visit(sample, weight, row)`
    /// (sparse `(column, value)` pairs sorted by column, one entry per column, the offset column included); the
    /// right-hand side is the visitor's business. Call [`Self::finish`] after the last run.
    #[allow(clippy::too_many_arguments)]
    pub fn add_rows(
        &mut self,
        grid: &EverettGrid,
        u: &[f64],
        weight: &[f64],
        offset_col: usize,
        history: &[f64],
        gain: f64,
        drift: Option<(usize, &[f64])>,
        mut visit: impl FnMut(usize, f64, &[(usize, f64)]) -> Result<(), RunError>,
    ) -> Result<(), RunError> {
        let m = self.n_cols();
        let gram = &mut self.gram;
        let (mut n_rows, mut weight_sum) = (0, 0.0);
        let columns = RunColumns {
            n_nodes: self.n_nodes,
            n_offsets: self.n_offsets,
            offset_col,
            drift,
        };
        regressor_rows(grid, u, weight, history, gain, columns, |i, w, row| {
            visit(i, w, row)?;
            // Upper triangle only (the row is sorted by column); `finish` mirrors it.
            for (e, &(a, va)) in row.iter().enumerate() {
                let wa = w * va;
                let ga = &mut gram[a * m..(a + 1) * m];
                for &(b, vb) in &row[e..] {
                    ga[b] += wa * vb;
                }
            }
            n_rows += 1;
            weight_sum += w;
            Ok(())
        })?;
        self.n_rows += n_rows;
        self.weight_sum += weight_sum;
        Ok(())
    }

    /// Accumulate one sparse regressor row (as handed to the visitor of [`Self::add_rows`]: sorted by column, one
    /// entry per column) with weight `w` and output `y`: the upper triangle of the Gram matrix, the right-hand
    /// side and the counts. Call [`Self::finish`] after the last row.
    pub fn add_row(&mut self, w: f64, row: &[(usize, f64)], y: f64) {
        let m = self.n_cols();
        for (e, &(a, va)) in row.iter().enumerate() {
            let wa = w * va;
            self.rhs[a] += wa * y;
            let ga = &mut self.gram[a * m..(a + 1) * m];
            for &(b, vb) in &row[e..] {
                ga[b] += wa * vb;
            }
        }
        self.yy += w * y * y;
        self.n_rows += 1;
        self.weight_sum += w;
    }

    /// Complete the Gram matrix: the runs accumulate its upper triangle only; this copies it onto the lower one
    /// (symmetric to the bit). Call once after the last run.
    pub fn finish(&mut self) {
        let m = self.n_cols();
        mirror_upper(&mut self.gram, m);
    }
}

/// Where one run's regressors go among the columns of a fit: `n_nodes` node columns, then `n_offsets` free
/// columns (offsets and drift coefficients); the run's offset column `offset_col` and its drift regressor
/// `drift = Some((column, values))` (`column` counted among the free columns).
#[derive(Clone, Copy, Debug)]
pub struct RunColumns<'a> {
    /// Number of node columns.
    pub n_nodes: usize,
    /// Number of free columns after them.
    pub n_offsets: usize,
    /// The run's offset column (`< n_offsets`).
    pub offset_col: usize,
    /// The run's drift regressor and its free column.
    pub drift: Option<(usize, &'a [f64])>,
}

/// The regression rows of one run: the memory starts at negative saturation, follows `history` and then every
/// sample of `u`; for each sample with `weight[i] > 0`, `visit(i, weight[i], row)` gets its sparse row
/// (`(column, value)` pairs sorted by column, one entry per column): the Everett terms scaled by `gain`, the
/// offset column and the drift regressor. Checks the run's lengths, columns and values first.
pub fn regressor_rows(
    grid: &EverettGrid,
    u: &[f64],
    weight: &[f64],
    history: &[f64],
    gain: f64,
    columns: RunColumns<'_>,
    mut visit: impl FnMut(usize, f64, &[(usize, f64)]) -> Result<(), RunError>,
) -> Result<(), RunError> {
    let RunColumns {
        n_nodes,
        n_offsets,
        offset_col,
        drift,
    } = columns;
    if weight.len() != u.len() {
        return Err(RunError::Lengths {
            inputs: u.len(),
            outputs: u.len(),
            weights: weight.len(),
        });
    }
    if let Some((column, d)) = drift {
        if column >= n_offsets {
            return Err(RunError::OffsetColumn {
                column,
                columns: n_offsets,
            });
        }
        if d.len() != u.len() {
            return Err(RunError::Lengths {
                inputs: u.len(),
                outputs: d.len(),
                weights: weight.len(),
            });
        }
        if let Some(i) = d.iter().position(|v| !v.is_finite()) {
            return Err(RunError::NonFinite {
                what: "drift regressor",
                sample: i,
                value: d[i],
            });
        }
    }
    if offset_col >= n_offsets {
        return Err(RunError::OffsetColumn {
            column: offset_col,
            columns: n_offsets,
        });
    }
    if let Some(i) = u.iter().position(|v| !v.is_finite()) {
        return Err(RunError::NonFinite {
            what: "input",
            sample: i,
            value: u[i],
        });
    }
    if let Some(i) = history.iter().position(|v| !v.is_finite()) {
        return Err(RunError::NonFinite {
            what: "initial history",
            sample: i,
            value: history[i],
        });
    }
    if !(gain.is_finite() && gain > 0.0) {
        return Err(RunError::BadGain { gain });
    }
    let off = n_nodes + offset_col;
    let mut memory = PreisachMemory::with_history(grid, history);
    let mut located = LocatedStack::default();
    let mut row: Vec<(usize, f64)> = Vec::with_capacity(64);
    for i in 0..u.len() {
        memory.update(u[i]);
        let w = weight[i];
        if w.is_nan() || w <= 0.0 {
            continue;
        }
        row.clear();
        located.push_terms(grid, &memory, gain, &mut row);
        row.push((off, 1.0));
        if let Some((column, d)) = drift {
            row.push((n_nodes + column, d[i]));
        }
        merge_duplicates(&mut row);
        visit(i, w, &row)?;
    }
    Ok(())
}

/// Sort a sparse row by column and add up entries of one column.
fn merge_duplicates(row: &mut Vec<(usize, f64)>) {
    row.sort_unstable_by_key(|e| e.0);
    let mut k = 0;
    for e in 1..row.len() {
        if row[e].0 == row[k].0 {
            row[k].1 += row[e].1;
        } else {
            k += 1;
            row[k] = row[e];
        }
    }
    row.truncate(k + 1);
}

/// Copy the upper triangle of the row-major `m × m` matrix `a` onto its lower triangle (symmetric to the bit).
fn mirror_upper(a: &mut [f64], m: usize) {
    const BLOCK: usize = 32;
    for i0 in (0..m).step_by(BLOCK) {
        for j0 in (i0..m).step_by(BLOCK) {
            for i in i0..(i0 + BLOCK).min(m) {
                for j in j0.max(i + 1)..(j0 + BLOCK).min(m) {
                    a[j * m + i] = a[i * m + j];
                }
            }
        }
    }
}

/// Predict a run: output `offset + Σ ±E` along the input history, starting at negative saturation.
pub fn simulate_everett(
    grid: &EverettGrid,
    node_values: &[f64],
    offset: f64,
    u: &[f64],
) -> Vec<f64> {
    simulate_everett_from(grid, node_values, offset, &[], u)
}

/// [`simulate_everett`] from the state that negative saturation followed by `history` leaves.
pub fn simulate_everett_from(
    grid: &EverettGrid,
    node_values: &[f64],
    offset: f64,
    history: &[f64],
    u: &[f64],
) -> Vec<f64> {
    let mut memory = PreisachMemory::with_history(grid, history);
    let mut row: Vec<(usize, f64)> = Vec::with_capacity(64);
    u.iter()
        .map(|&x| {
            memory.update(x);
            row.clear();
            memory
                .for_each_term(|beta, alpha, sign| grid.push_everett(beta, alpha, sign, &mut row));
            offset + row.iter().map(|&(k, w)| w * node_values[k]).sum::<f64>()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packing_is_a_bijection() {
        let g = EverettGrid::uniform(-1.0, 1.0, 7).unwrap();
        let mut seen = alloc::vec![false; g.n_cells()];
        for p in 0..7 {
            for q in p..7 {
                let k = g.cell_index(p, q);
                assert!(!seen[k]);
                seen[k] = true;
            }
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn adjoint_matches_forward() {
        let g = EverettGrid::uniform(0.0, 1.0, 6).unwrap();
        let m = g.n_cells();
        let w: Vec<f64> = (0..m).map(|k| ((k * 7919) % 13) as f64 - 6.0).collect();
        let v: Vec<f64> = (0..m).map(|k| ((k * 104729) % 11) as f64 - 5.0).collect();
        let cw = g.masses_to_nodes(&w);
        let ctv = g.nodes_to_masses_adjoint(&v);
        let lhs: f64 = cw.iter().zip(&v).map(|(a, b)| a * b).sum();
        let rhs: f64 = w.iter().zip(&ctv).map(|(a, b)| a * b).sum();
        assert!((lhs - rhs).abs() < 1e-9);
    }

    #[test]
    fn fast_masses_to_nodes_matches_the_plain_sum() {
        let g = EverettGrid::new(alloc::vec![0.0, 0.5, 0.7, 1.6, 2.0, 2.1, 3.0]).unwrap();
        let w: Vec<f64> = (0..g.n_cells())
            .map(|k| ((k * 7919) % 13) as f64 - 6.0)
            .collect();
        let mut fast = alloc::vec![0.0; g.n_cells()];
        let mut scratch = alloc::vec![0.0; g.n_intervals() + 1];
        g.masses_to_nodes_into(&w, &mut fast, &mut scratch);
        assert_eq!(fast, g.masses_to_nodes(&w));
    }

    #[test]
    fn wiping_out_and_return_point_memory() {
        let g = EverettGrid::uniform(-1.0, 1.0, 8).unwrap();
        let m = g.n_cells();
        let w: Vec<f64> = (0..m).map(|k| 0.1 + (k % 5) as f64 * 0.05).collect();
        let e = g.masses_to_nodes(&w);
        let path = [-1.0, 1.0, -0.3, 0.4, -0.1, 0.2, 0.4, 0.6, -0.3, -0.5, 1.0];
        let y = simulate_everett(&g, &e, 0.0, &path);
        // Returning to 0.4 closes the inner loop: same output as when 0.4 was first reached.
        assert!((y[6] - y[3]).abs() < 1e-12);
        // Positive saturation is the same state whatever the history.
        assert!((y[10] - y[1]).abs() < 1e-12);
        // Monotone: rising input never lowers the output.
        assert!(y[7] >= y[6]);
        assert!(y[9] <= y[8]);
    }
}
