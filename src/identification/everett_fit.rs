//! Regularised nonnegative least-squares identification of a tabulated Everett function (a Preisach model) from
//! any excitation, and the identified model itself (simulation, first-order curves).
//!
//! The output of the model is linear in the cell masses given the input history
//! ([`super::everett_regressors`]); the masses are found by minimising
//! `Σ (y − ŷ)² + λ_s ‖D ρ‖² + λ_r ‖w‖²` subject to `w ≥ 0` (monotone tables), where `ρ` is the density
//! (mass per cell area, or per diagonal length for the reversible part) and `D` takes first differences between
//! neighbouring cells (smoothness). `λ_s = smoothing · tr(Q)/tr(DᵀD)` and `λ_r = ridge · tr(Q)/n` make both
//! weights dimensionless.
use alloc::vec::Vec;

use super::error::IdentificationError;
use super::everett_regressors::{EverettGrid, NormalEquations, simulate_everett};
use super::nnls::nnls_gram;
use crate::from_curves::CurveData;
use crate::limits::{self, MAX_CURVE_POINTS, MAX_SOLVER_ITERATIONS};

/// A Preisach model: Everett table on a grid (from nonnegative cell masses) and the output at negative saturation.
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
        if masses.len() != grid.n_cells() {
            return Err(IdentificationError::MassCount {
                intervals: grid.n_intervals(),
                expected: grid.n_cells(),
                got: masses.len(),
            });
        }
        if let Some(i) = masses.iter().position(|m| !m.is_finite() || *m < 0.0) {
            return Err(IdentificationError::NegativeMass {
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
        simulate_everett(
            &self.grid,
            &self.node_values,
            offset.unwrap_or(self.offset),
            u,
        )
    }

    /// The CBH operator of this Everett table (its first-order curves with `subdivisions` reversals per grid
    /// interval, see [`Self::first_order_curves_subdivided`]), built without leaving Rust.
    pub fn hysteresis<const N: usize>(
        &self,
        subdivisions: usize,
        opts: &crate::table_builder::BuildOptions,
        initial: crate::cbh::Initial,
    ) -> Result<crate::cbh::Hysteresis<Vec<f64>, N>, IdentificationError> {
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
    /// grid nodes beyond it); more reversals make a CBH operator built from them follow the Everett table
    /// closely between grid reversals as well. The points of both families are at most [`MAX_CURVE_POINTS`].
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
    /// Pivoting iterations allowed in the NNLS solve.
    pub max_iter: usize,
}

impl Default for EverettFitOptions {
    fn default() -> Self {
        Self {
            smoothing: 1e-4,
            ridge: 1e-9,
            max_iter: 500,
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
}

/// Result of [`fit_everett`].
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
    /// NNLS pivoting iterations.
    pub iterations: usize,
}

/// Identify the Everett masses on `grid` and `n_offsets` free output offsets from `runs`.
pub fn fit_everett(
    grid: &EverettGrid,
    runs: &[EverettRun<'_>],
    n_offsets: usize,
    options: EverettFitOptions,
) -> Result<EverettFit, IdentificationError> {
    if n_offsets == 0 {
        return Err(IdentificationError::NoOffsets);
    }
    for (name, value) in [("smoothing", options.smoothing), ("ridge", options.ridge)] {
        if !(value.is_finite() && value >= 0.0) {
            return Err(IdentificationError::BadParameter { name, value });
        }
    }
    limits::check(
        "solver iterations (max_iter)",
        options.max_iter,
        MAX_SOLVER_ITERATIONS,
    )?;
    let mut ne = NormalEquations::new(grid, n_offsets)?;
    for (k, run) in runs.iter().enumerate() {
        ne.add_run(grid, run.u, run.y, run.weight, run.offset_col)
            .map_err(|error| IdentificationError::Run { run: k, error })?;
    }
    if ne.n_rows == 0 {
        return Err(IdentificationError::NoSamples);
    }
    let nn = ne.n_nodes;
    let m = ne.n_cols();
    // Cᵀ G C on the node block, Cᵀ G on the node/offset block.
    let mut b_nodes = alloc::vec![0.0; nn * nn]; // B = Cᵀ Gnn, row-major
    let mut col = alloc::vec![0.0; nn];
    for k in 0..nn {
        for (i, c) in col.iter_mut().enumerate() {
            *c = ne.gram[i * m + k];
        }
        let t = grid.nodes_to_masses_adjoint(&col);
        for (i, v) in t.into_iter().enumerate() {
            b_nodes[i * nn + k] = v;
        }
    }
    let mut q = alloc::vec![0.0; m * m];
    for k in 0..nn {
        let t = grid.nodes_to_masses_adjoint(&b_nodes[k * nn..(k + 1) * nn]);
        q[k * m..k * m + nn].copy_from_slice(&t);
    }
    for o in nn..m {
        for (i, c) in col.iter_mut().enumerate() {
            *c = ne.gram[i * m + o];
        }
        let t = grid.nodes_to_masses_adjoint(&col);
        for (i, v) in t.into_iter().enumerate() {
            q[i * m + o] = v;
            q[o * m + i] = v;
        }
        for o2 in nn..m {
            q[o * m + o2] = ne.gram[o * m + o2];
        }
    }
    let mut c = grid.nodes_to_masses_adjoint(&ne.rhs[..nn]);
    c.extend_from_slice(&ne.rhs[nn..]);

    // Regularisation.
    let trace_q: f64 = (0..nn)
        .map(|i| q[i * m + i])
        .sum::<f64>()
        .max(f64::MIN_POSITIVE);
    add_smoothness(grid, &mut q, m, options.smoothing, trace_q);
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
    let constrained: Vec<bool> = (0..m).map(|i| i < nn).collect();
    let sol = nnls_gram(&q, &c, &constrained, options.max_iter)?;
    let masses: Vec<f64> = sol.x[..nn].iter().map(|&v| v.max(0.0)).collect();
    let offsets = sol.x[nn..].to_vec();
    let model = EverettModel::new(grid.clone(), masses, offsets[0])?;
    // Data-term RSS from the unregularised normal equations: yy − 2 zᵀ r + zᵀ G z, z = [C w, offsets].
    let mut z = model.node_values().to_vec();
    z.extend_from_slice(&offsets);
    let mut zgz = 0.0;
    for i in 0..m {
        let gi = &ne.gram[i * m..(i + 1) * m];
        zgz += z[i] * gi.iter().zip(&z).map(|(a, b)| a * b).sum::<f64>();
    }
    let zr: f64 = z.iter().zip(&ne.rhs).map(|(a, b)| a * b).sum();
    let rss = (ne.yy - 2.0 * zr + zgz).max(0.0);
    Ok(EverettFit {
        rms: (rss / ne.weight_sum).sqrt(),
        model,
        offsets,
        rss,
        n_rows: ne.n_rows,
        iterations: sol.iterations,
    })
}

/// Add `λ Dᵀ D` for first differences of the density between neighbouring cells.
fn add_smoothness(grid: &EverettGrid, q: &mut [f64], m: usize, smoothing: f64, trace_q: f64) {
    if smoothing <= 0.0 {
        return;
    }
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
    let mut pairs: Vec<((usize, f64), (usize, f64))> = Vec::new();
    for p in 0..n {
        for qq in p..n {
            let a = (grid.cell_index(p, qq), scale(p, qq));
            if p == qq {
                if p + 1 < n {
                    pairs.push((a, (grid.cell_index(p + 1, p + 1), scale(p + 1, p + 1))));
                }
                continue;
            }
            if qq + 1 < n {
                pairs.push((a, (grid.cell_index(p, qq + 1), scale(p, qq + 1))));
            }
            if p + 1 < qq {
                pairs.push((a, (grid.cell_index(p + 1, qq), scale(p + 1, qq))));
            }
        }
    }
    let trace_d: f64 = pairs
        .iter()
        .map(|&((_, sa), (_, sb))| sa * sa + sb * sb)
        .sum();
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
    fn sizes_are_bounded_before_allocation() {
        use crate::limits::{MAX_EVERETT_INTERVALS, MAX_EVERETT_UNKNOWNS};
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
        };
        let fit = |n_offsets, max_iter| {
            let opts = EverettFitOptions {
                max_iter,
                ..Default::default()
            };
            fit_everett(&grid, &[run], n_offsets, opts)
        };
        assert!(limit(fit(MAX_EVERETT_UNKNOWNS, 10).unwrap_err()));
        assert!(limit(fit(usize::MAX, 10).unwrap_err()));
        assert!(limit(fit(1, usize::MAX).unwrap_err()));
        let model = EverettModel::new(grid.clone(), alloc::vec![0.1; grid.n_cells()], 0.0).unwrap();
        assert!(limit(
            model.first_order_curves_subdivided(1 << 40).unwrap_err()
        ));
        assert!(model.first_order_curves_subdivided(3).is_ok());
    }

    #[test]
    fn rejects_bad_masses() {
        let grid = EverettGrid::uniform(0.0, 1.0, 2).unwrap();
        assert!(EverettModel::new(grid.clone(), alloc::vec![1.0; 2], 0.0).is_err());
        assert!(EverettModel::new(grid.clone(), alloc::vec![1.0, -1.0, 0.0], 0.0).is_err());
        assert!(EverettModel::new(grid, alloc::vec![1.0, f64::NAN, 0.0], 0.0).is_err());
    }
}
