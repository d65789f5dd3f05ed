//! The Everett-table least squares of [`super::fit_everett`] for tables past the dense solver's size: the same
//! regularised objective, solved matrix-free.
//!
//! The dense path holds the normal matrix of the unknowns (`(cells + offsets)²` values): at
//! [`MAX_EVERETT_UNKNOWNS`] (about 88 grid intervals) that is 128 MiB. A first-order reversal curve family
//! measures its Everett function directly on a grid as fine as its reversal fields (a hundred or more), whose
//! switching fields move by a fraction of a coarse cell from curve to curve. Here the regressor rows are kept
//! instead (sparse: a few Everett terms of four corners each) and the quadratic is applied as
//! `Q x = Cᵀ Aᵀ W A C x + λ_s DᵀD x + λ_r x` — `C` the 2-D cumulative sum from cell masses to node values
//! (O(N²)), `A` the rows, `D` the density's first differences — so one product costs one pass over the rows and
//! a few passes over the cells, and memory grows with the data and the cells, not with their square.
//!
//! The bound-constrained quadratic is solved by gradient projection with conjugate gradients on the face
//! (Moré & Toraldo 1991): projected steepest-descent steps (exact step along the gradient, halved until the
//! projected point lowers the objective enough) find which masses sit at zero, Jacobi-preconditioned
//! conjugate gradients then minimise over the others, followed by a projected search along that direction.
//! Every step lowers the strictly convex objective, and the work is bounded by [`MAX_LARGE_PRODUCTS`] products
//! with `Q`: the solve always ends, with its optimality-condition violation reported.
//!
//! Bounds: unknowns (cells, offsets, a drift coefficient) at most [`MAX_EVERETT_LARGE_UNKNOWNS`] (about 510
//! intervals; a dozen vectors of that length, 13 MiB), stored regressor entries at most
//! [`MAX_EVERETT_ENTRIES`] (12 bytes each, 384 MiB); time per product O(entries + unknowns).
use alloc::vec::Vec;

use super::error::{IdentificationError, RunError};
use super::everett_fit::{
    DensityDifference, EverettFit, EverettFitOptions, EverettModel, check_options, smoothness_pairs,
};
use super::everett_folds::{EverettFoldRun, FoldScore, nearest};
use super::everett_regressors::{EverettGrid, RunColumns, regressor_rows};
use crate::limits::{self, MAX_EVERETT_ENTRIES, MAX_EVERETT_LARGE_UNKNOWNS, MAX_EVERETT_UNKNOWNS};

/// Products with the quadratic's matrix one solve may spend (each one pass over the regressor rows).
pub const MAX_LARGE_PRODUCTS: usize = 20_000;

/// Relative optimality-condition violation at which the iterative solve counts as converged (as the dense
/// solver's, relative to the largest `|c_i|` and `|Q_ii x_i|`).
pub const LARGE_KKT_TOLERANCE: f64 = 1e-11;

// Gradient-projection steps per outer iteration (before conjugate gradients on the face found).
const PROJECTION_STEPS: usize = 8;
// Conjugate-gradient iterations per face.
const FACE_CG_STEPS: usize = 400;
// Sufficient decrease of the projected searches (Armijo).
const ARMIJO: f64 = 1e-4;
// Conjugate gradients on a face stop when one step lowers the objective by less than this share of the best.
const CG_STALL: f64 = 1e-3;

/// Whether a fit of `unknowns` unknowns needs the matrix-free path (above the dense solver's limit).
pub fn needs_large_path(unknowns: usize) -> bool {
    unknowns > MAX_EVERETT_UNKNOWNS
}

/// The regressor rows of an Everett fit kept sparse, each with the fold that holds it out (`usize::MAX`: none).
#[derive(Clone, Debug)]
pub struct EverettRows {
    grid: EverettGrid,
    n_nodes: usize,
    n_free: usize,
    row_ptr: Vec<usize>,
    col: Vec<u32>,
    val: Vec<f64>,
    y: Vec<f64>,
    weight: Vec<f64>,
    fold: Vec<usize>,
    pairs: Vec<DensityDifference>,
    trace_d: f64,
    // Per fold (and one more entry for the whole): the last solution, a warm start for the next smoothing.
    warm: Vec<Vec<(f64, Vec<f64>)>>,
}

impl EverettRows {
    /// The rows of `runs` on `grid` with `n_offsets` free offsets (and a drift coefficient after them when any
    /// run has a drift regressor); `n_folds` folds (a run's `fold[i] >= n_folds`, or an empty `fold`: never held
    /// out).
    pub fn new(
        grid: &EverettGrid,
        runs: &[EverettFoldRun<'_>],
        n_offsets: usize,
        n_folds: usize,
    ) -> Result<Self, IdentificationError> {
        check_options(n_offsets, EverettFitOptions::default())?;
        let with_drift = runs.iter().any(|r| !r.drift.is_empty());
        let n_free = n_offsets + usize::from(with_drift);
        let n_nodes = grid.n_cells();
        limits::check(
            "unknowns of the Everett fit (grid cells + offsets)",
            limits::sum(n_nodes, n_free),
            MAX_EVERETT_LARGE_UNKNOWNS,
        )?;
        let (mut row_ptr, mut col, mut val) = (alloc::vec![0], Vec::new(), Vec::new());
        let (mut y, mut weight, mut fold) = (Vec::new(), Vec::new(), Vec::new());
        for (k, run) in runs.iter().enumerate() {
            if run.y.len() != run.u.len()
                || (!run.fold.is_empty() && run.fold.len() != run.u.len())
                || run.weight.len() != run.u.len()
            {
                return Err(IdentificationError::Run {
                    run: k,
                    error: RunError::Lengths {
                        inputs: run.u.len(),
                        outputs: run.y.len(),
                        weights: run.weight.len(),
                    },
                });
            }
            let columns = RunColumns {
                n_nodes,
                n_offsets: n_free,
                offset_col: run.offset_col,
                drift: (!run.drift.is_empty()).then_some((n_offsets, run.drift)),
            };
            if run.offset_col >= n_offsets {
                return Err(IdentificationError::Run {
                    run: k,
                    error: RunError::OffsetColumn {
                        column: run.offset_col,
                        columns: n_offsets,
                    },
                });
            }
            regressor_rows(
                grid,
                run.u,
                run.weight,
                run.history,
                run.gain,
                columns,
                |i, w, row| {
                    let yi = run.y[i];
                    if !yi.is_finite() {
                        return Err(RunError::NonFinite {
                            what: "output",
                            sample: i,
                            value: yi,
                        });
                    }
                    if col.len() + row.len() > MAX_EVERETT_ENTRIES {
                        return Err(RunError::Limit(limits::LimitError {
                            what: "stored regressor entries of the Everett fit",
                            requested: col.len() + row.len(),
                            limit: MAX_EVERETT_ENTRIES,
                        }));
                    }
                    for &(a, v) in row {
                        col.push(a as u32);
                        val.push(v);
                    }
                    row_ptr.push(col.len());
                    y.push(yi);
                    weight.push(w);
                    fold.push(match run.fold.get(i) {
                        Some(&f) if f < n_folds => f,
                        _ => usize::MAX,
                    });
                    Ok(())
                },
            )
            .map_err(|error| IdentificationError::Run { run: k, error })?;
        }
        if y.is_empty() {
            return Err(IdentificationError::NoSamples);
        }
        let (pairs, trace_d) = smoothness_pairs(grid, 0.0);
        Ok(Self {
            grid: grid.clone(),
            n_nodes,
            n_free,
            row_ptr,
            col,
            val,
            y,
            weight,
            fold,
            pairs,
            trace_d,
            warm: alloc::vec![Vec::new(); n_folds + 1],
        })
    }

    /// Number of unknowns (cell masses, offsets and the drift coefficient).
    pub fn n_unknowns(&self) -> usize {
        self.n_nodes + self.n_free
    }

    /// Number of regression rows.
    pub fn n_rows(&self) -> usize {
        self.y.len()
    }

    /// The table fitted to every row (none held out) with `options`; its offsets are the free columns (the
    /// drift coefficient, when there is one, is the last).
    pub fn fit(&mut self, options: EverettFitOptions) -> Result<EverettFit, IdentificationError> {
        check_options(self.n_free, options)?;
        let slot = self.warm.len() - 1;
        let (fit, x) = self.solve(None, options, slot)?;
        self.warm[slot].push((options.smoothing, x));
        Ok(fit)
    }

    /// Every fold's held-out error of the table fitted with `options` on the rest (see
    /// [`super::EverettFolds::score`]); each fold warm-starts from its solve at the nearest smoothing.
    pub fn score(
        &mut self,
        options: EverettFitOptions,
    ) -> Result<Vec<FoldScore>, IdentificationError> {
        check_options(self.n_free, options)?;
        let n_folds = self.warm.len() - 1;
        let mut out = Vec::with_capacity(n_folds);
        let mut z = alloc::vec![0.0; self.n_unknowns()];
        let mut scratch = alloc::vec![0.0; self.grid.n_intervals() + 1];
        for f in 0..n_folds {
            if !self.fold.contains(&f) {
                out.push(FoldScore {
                    sse: 0.0,
                    weight: 0.0,
                    converged: true,
                });
                continue;
            }
            let (fit, x) = self.solve(Some(f), options, f)?;
            self.grid.masses_to_nodes_into(
                &x[..self.n_nodes],
                &mut z[..self.n_nodes],
                &mut scratch,
            );
            z[self.n_nodes..].copy_from_slice(&x[self.n_nodes..]);
            let (mut sse, mut weight) = (0.0, 0.0);
            for r in 0..self.y.len() {
                if self.fold[r] == f {
                    let e = self.y[r] - self.row_dot(r, &z);
                    sse += self.weight[r] * e * e;
                    weight += self.weight[r];
                }
            }
            out.push(FoldScore {
                sse,
                weight,
                converged: fit.converged,
            });
            self.warm[f].push((options.smoothing, x));
        }
        Ok(out)
    }

    fn row_dot(&self, r: usize, z: &[f64]) -> f64 {
        let (a, b) = (self.row_ptr[r], self.row_ptr[r + 1]);
        self.col[a..b]
            .iter()
            .zip(&self.val[a..b])
            .map(|(&c, &v)| v * z[c as usize])
            .sum()
    }

    // Whether row `r` is in the training part when fold `skip` is held out.
    fn trains(&self, r: usize, skip: Option<usize>) -> bool {
        skip.is_none_or(|f| self.fold[r] != f)
    }

    /// Solve with the rows of fold `skip` left out, warm-started from `slot`'s solve at the nearest smoothing.
    fn solve(
        &self,
        skip: Option<usize>,
        options: EverettFitOptions,
        slot: usize,
    ) -> Result<(EverettFit, Vec<f64>), IdentificationError> {
        let nn = self.n_nodes;
        let m = self.n_unknowns();
        let n = self.grid.n_intervals();
        let mut scratch = alloc::vec![0.0; n + 1];
        // Data part of the diagonal of Q and the right-hand side c = [Cᵀ Aᵀ W y, A_freeᵀ W y].
        let mut h = alloc::vec![0.0; nn]; // node-packed: Σ w v v' at the corner of each pair's rectangle
        let mut gy = alloc::vec![0.0; m];
        let mut diag = alloc::vec![0.0; m];
        let (mut rows, mut weight_sum) = (0usize, 0.0);
        let first = row_starts(&self.grid);
        for r in (0..self.y.len()).filter(|&r| self.trains(r, skip)) {
            let (a, b) = (self.row_ptr[r], self.row_ptr[r + 1]);
            let w = self.weight[r];
            rows += 1;
            weight_sum += w;
            for e in a..b {
                let (ce, ve) = (self.col[e] as usize, self.val[e]);
                gy[ce] += w * ve * self.y[r];
                if ce >= nn {
                    diag[ce] += w * ve * ve;
                    continue;
                }
                // (Cᵀ a)(p, q) = Σ a(i, j) over i ≤ p, j > q: the square's diagonal sums each pair of entries
                // over the cells both rectangles cover, p ≥ max i, q < min j.
                let (ie, je) = node_of(&first, n, ce);
                for e2 in a..b {
                    let c2 = self.col[e2] as usize;
                    if c2 >= nn {
                        continue;
                    }
                    let (i2, j2) = node_of(&first, n, c2);
                    let (ii, jj) = (ie.max(i2), je.min(j2));
                    if ii < jj {
                        h[self.grid.node_index(ii, jj)] += w * ve * self.val[e2];
                    }
                }
            }
        }
        if rows == 0 {
            return Err(IdentificationError::NoSamples);
        }
        self.grid
            .nodes_to_masses_adjoint_into(&h, &mut diag[..nn], &mut scratch);
        drop(h);
        let mut c = alloc::vec![0.0; m];
        self.grid
            .nodes_to_masses_adjoint_into(&gy[..nn], &mut c[..nn], &mut scratch);
        c[nn..].copy_from_slice(&gy[nn..]);
        drop(gy);
        // Regularisation weights as the dense path takes them (tr Q over the node block).
        let trace_q = diag[..nn].iter().sum::<f64>().max(f64::MIN_POSITIVE);
        // The isotropic pairs are kept; a diagonal share makes its own.
        let other;
        let (pairs, trace_d) = if options.diagonal_smoothing == 0.0 {
            (&self.pairs[..], self.trace_d)
        } else {
            other = smoothness_pairs(&self.grid, options.diagonal_smoothing);
            (&other.0[..], other.1)
        };
        let lambda_s = if options.smoothing > 0.0 && trace_d > 0.0 {
            options.smoothing * trace_q / trace_d
        } else {
            0.0
        };
        let lambda_r = (options.ridge * trace_q / nn as f64).max(1e-14 * trace_q / nn as f64);
        for (o, d) in diag[nn..].iter_mut().enumerate() {
            if *d <= 0.0 {
                return Err(IdentificationError::EmptyOffset { column: o });
            }
            *d *= 1.0 + 1e-12;
        }
        let free_diag: Vec<f64> = diag[nn..].to_vec();
        for d in &mut diag[..nn] {
            *d += lambda_r;
        }
        for &((a, sa), (b, sb)) in pairs {
            diag[a] += lambda_s * sa * sa;
            diag[b] += lambda_s * sb * sb;
        }
        let constrained: Vec<bool> = (0..m).map(|i| i < nn && !options.signed).collect();
        let mut x = nearest(&self.warm[slot], options.smoothing)
            .or_else(|| {
                nearest(
                    self.warm.last().map_or(&[][..], Vec::as_slice),
                    options.smoothing,
                )
            })
            .map_or_else(|| alloc::vec![0.0; m], <[f64]>::to_vec);
        // Q v for the training rows.
        let mut z = alloc::vec![0.0; m];
        let mut gz = alloc::vec![0.0; m];
        let mut apply = |v: &[f64], out: &mut [f64]| {
            self.grid
                .masses_to_nodes_into(&v[..nn], &mut z[..nn], &mut scratch);
            z[nn..].copy_from_slice(&v[nn..]);
            gz.fill(0.0);
            for r in (0..self.y.len()).filter(|&r| self.trains(r, skip)) {
                let (a, b) = (self.row_ptr[r], self.row_ptr[r + 1]);
                let cols = &self.col[a..b];
                let vals = &self.val[a..b];
                let s: f64 = cols
                    .iter()
                    .zip(vals)
                    .map(|(&cc, &vv)| vv * z[cc as usize])
                    .sum::<f64>()
                    * self.weight[r];
                for (&cc, &vv) in cols.iter().zip(vals) {
                    gz[cc as usize] += vv * s;
                }
            }
            self.grid
                .nodes_to_masses_adjoint_into(&gz[..nn], &mut out[..nn], &mut scratch);
            for o in 0..m - nn {
                out[nn + o] = gz[nn + o] + 1e-12 * free_diag[o] * v[nn + o];
            }
            for (o, &vi) in out[..nn].iter_mut().zip(&v[..nn]) {
                *o += lambda_r * vi;
            }
            if lambda_s > 0.0 {
                for &((a, sa), (b, sb)) in pairs {
                    let d = lambda_s * (sa * v[a] - sb * v[b]);
                    out[a] += sa * d;
                    out[b] -= sb * d;
                }
            }
        };
        let sol = solve_bounded(&mut apply, &diag, &c, &constrained, &mut x);
        // Data-term residual of the training rows.
        let mut nodes = alloc::vec![0.0; m];
        let mut scratch = alloc::vec![0.0; n + 1];
        let masses: Vec<f64> = if options.signed {
            x[..nn].to_vec()
        } else {
            x[..nn].iter().map(|&v| v.max(0.0)).collect()
        };
        self.grid
            .masses_to_nodes_into(&masses, &mut nodes[..nn], &mut scratch);
        nodes[nn..].copy_from_slice(&x[nn..]);
        let mut rss = 0.0;
        for r in (0..self.y.len()).filter(|&r| self.trains(r, skip)) {
            let e = self.y[r] - self.row_dot(r, &nodes);
            rss += self.weight[r] * e * e;
        }
        let offsets = x[nn..].to_vec();
        let model = if options.signed {
            EverettModel::with_signed_masses(self.grid.clone(), masses, offsets[0])?
        } else {
            EverettModel::new(self.grid.clone(), masses, offsets[0])?
        };
        let passive: Vec<bool> = (0..m).map(|i| !constrained[i] || x[i] > 0.0).collect();
        // max/min diagonal on the passive set: a lower bound of the 2-norm condition number.
        let (mut dmax, mut dmin) = (0.0f64, f64::INFINITY);
        for i in (0..m).filter(|&i| passive[i]) {
            dmax = dmax.max(diag[i]);
            dmin = dmin.min(diag[i]);
        }
        let fit = EverettFit {
            model,
            offsets,
            rss,
            n_rows: rows,
            rms: (rss / weight_sum).sqrt(),
            iterations: sol.products,
            passive,
            converged: sol.converged,
            kkt_violation: sol.kkt_violation,
            condition: if dmin > 0.0 && dmin.is_finite() {
                dmax / dmin
            } else {
                f64::INFINITY
            },
            drift: None,
        };
        Ok((fit, x))
    }
}

/// The table fitted to `runs` by the matrix-free path (the counterpart of [`super::fit_everett`]'s dense one).
pub(super) fn fit_everett_large(
    grid: &EverettGrid,
    runs: &[EverettFoldRun<'_>],
    n_offsets: usize,
    options: EverettFitOptions,
) -> Result<EverettFit, IdentificationError> {
    let with_drift = runs.iter().any(|r| !r.drift.is_empty());
    let mut rows = EverettRows::new(grid, runs, n_offsets, 0)?;
    let mut fit = rows.fit(options)?;
    if with_drift {
        fit.drift = fit.offsets.pop();
    }
    Ok(fit)
}

/// Index of the first packed cell of each row `p` (cell `(p, p)`).
fn row_starts(grid: &EverettGrid) -> Vec<usize> {
    (0..grid.n_intervals())
        .map(|p| grid.cell_index(p, p))
        .collect()
}

/// The node `(i, j)` whose value is packed at `index`.
fn node_of(first: &[usize], n: usize, index: usize) -> (usize, usize) {
    let i = first.partition_point(|&s| s <= index) - 1;
    debug_assert!(i < n);
    (i, i + 1 + index - first[i])
}

/// How an iterative bound-constrained solve ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundedSolution {
    /// Products with the matrix spent.
    pub products: usize,
    /// Whether the optimality conditions hold to [`LARGE_KKT_TOLERANCE`].
    pub converged: bool,
    /// Their largest relative violation (relative to the largest `|c_i|` and `|Q_ii x_i|`).
    pub kkt_violation: f64,
}

/// Minimise `½ xᵀ Q x − cᵀ x` subject to `x_i ≥ 0` where `constrained[i]`, from `x` (projected first), for a
/// symmetric positive definite `Q` given by `apply(v, out)` (`out = Q v`) and its diagonal `diag`: gradient
/// projection with preconditioned conjugate gradients on the face (see the module). At most
/// [`MAX_LARGE_PRODUCTS`] products.
pub fn solve_bounded(
    apply: &mut impl FnMut(&[f64], &mut [f64]),
    diag: &[f64],
    c: &[f64],
    constrained: &[bool],
    x: &mut [f64],
) -> BoundedSolution {
    let m = c.len();
    project(x, constrained);
    let at_bound = |xi: f64, k: bool| k && xi <= 0.0;
    let mut g = alloc::vec![0.0; m];
    apply(x, &mut g);
    for (gi, ci) in g.iter_mut().zip(c) {
        *gi -= ci;
    }
    let mut products = 1;
    let (mut p, mut qp, mut s, mut qs) = (
        alloc::vec![0.0; m],
        alloc::vec![0.0; m],
        alloc::vec![0.0; m],
        alloc::vec![0.0; m],
    );
    let (mut r, mut zr, mut dir) = (
        alloc::vec![0.0; m],
        alloc::vec![0.0; m],
        alloc::vec![0.0; m],
    );
    let violation = |x: &[f64], g: &[f64]| {
        let (mut scale, mut worst) = (0.0f64, 0.0f64);
        for i in 0..m {
            scale = scale.max(c[i].abs()).max((diag[i] * x[i]).abs());
            let v = if at_bound(x[i], constrained[i]) {
                (-g[i]).max(0.0)
            } else {
                g[i].abs()
            };
            worst = worst.max(v);
        }
        if scale > 0.0 { worst / scale } else { worst }
    };
    let any_bound = constrained.iter().any(|&k| k);
    let mut kkt = violation(x, &g);
    while kkt > LARGE_KKT_TOLERANCE && products < MAX_LARGE_PRODUCTS {
        let before = products;
        // Gradient projection: the exact step along the gradient's feasible part, projected and halved as needed,
        // until the set at the bound stops changing.
        // Without bounds the face is everything: conjugate gradients alone.
        let steps = if any_bound { PROJECTION_STEPS } else { 0 };
        for _ in 0..steps {
            for i in 0..m {
                p[i] = if at_bound(x[i], constrained[i]) && g[i] > 0.0 {
                    0.0
                } else {
                    -g[i]
                };
            }
            apply(&p, &mut qp);
            products += 1;
            let pp: f64 = p.iter().map(|v| v * v).sum();
            let pqp: f64 = p.iter().zip(&qp).map(|(a, b)| a * b).sum();
            if !(pp > 0.0 && pqp > 0.0) {
                break;
            }
            let bound_before: Vec<bool> = (0..m).map(|i| at_bound(x[i], constrained[i])).collect();
            if !projected_search(
                apply,
                constrained,
                x,
                &mut g,
                &p,
                pp / pqp,
                &mut products,
                (&mut s, &mut qs),
            ) {
                break;
            }
            if (0..m).all(|i| at_bound(x[i], constrained[i]) == bound_before[i]) {
                break;
            }
        }
        // Conjugate gradients (Jacobi-preconditioned) on the variables off the bound.
        let face: Vec<bool> = (0..m).map(|i| !at_bound(x[i], constrained[i])).collect();
        dir.fill(0.0);
        for i in 0..m {
            r[i] = if face[i] { -g[i] } else { 0.0 };
            zr[i] = if face[i] { r[i] / diag[i] } else { 0.0 };
        }
        p.copy_from_slice(&zr);
        let mut rz: f64 = r.iter().zip(&zr).map(|(a, b)| a * b).sum();
        let mut best = 0.0f64;
        // The residual at which the face's optimality conditions hold (the violation's scale).
        let scale = (0..m)
            .map(|i| c[i].abs().max((diag[i] * x[i]).abs()))
            .fold(0.0f64, f64::max);
        let cg_steps = if any_bound {
            FACE_CG_STEPS
        } else {
            MAX_LARGE_PRODUCTS
        };
        for _ in 0..cg_steps {
            if !positive(rz) || products >= MAX_LARGE_PRODUCTS {
                break;
            }
            apply(&p, &mut qp);
            products += 1;
            let pqp: f64 = (0..m).filter(|&i| face[i]).map(|i| p[i] * qp[i]).sum();
            if !positive(pqp) {
                break;
            }
            let alpha = rz / pqp;
            for i in 0..m {
                if face[i] {
                    dir[i] += alpha * p[i];
                    r[i] -= alpha * qp[i];
                    zr[i] = r[i] / diag[i];
                }
            }
            let decrease = 0.5 * alpha * rz;
            best = best.max(decrease);
            let rz_new: f64 = r.iter().zip(&zr).map(|(a, b)| a * b).sum();
            let residual = r.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            if residual <= 0.1 * LARGE_KKT_TOLERANCE * scale
                || (any_bound && decrease <= CG_STALL * best)
            {
                break;
            }
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..m {
                p[i] = zr[i] + beta * p[i];
            }
        }
        projected_search(
            apply,
            constrained,
            x,
            &mut g,
            &dir,
            1.0,
            &mut products,
            (&mut s, &mut qs),
        );
        kkt = violation(x, &g);
        if products == before {
            break;
        }
    }
    // The gradient was updated step by step: refresh it once so the reported violation is exact.
    apply(x, &mut g);
    for (gi, ci) in g.iter_mut().zip(c) {
        *gi -= ci;
    }
    let kkt = violation(x, &g);
    BoundedSolution {
        products: products + 1,
        converged: kkt <= LARGE_KKT_TOLERANCE,
        kkt_violation: kkt,
    }
}

/// Whether `x > 0` (false for NaN).
fn positive(x: f64) -> bool {
    x > 0.0
}

/// Set the constrained entries of `v` that are not positive to 0.
fn project(v: &mut [f64], constrained: &[bool]) {
    for (vi, &k) in v.iter_mut().zip(constrained) {
        if k && !positive(*vi) {
            *vi = 0.0;
        }
    }
}

/// Projected search from `x` along `d`, starting at step `t` and halving it until the projected step `s` lowers
/// the objective enough (Armijo): moves `x`, updates the gradient `g`; false when no step lowers it.
#[allow(clippy::too_many_arguments)]
fn projected_search(
    apply: &mut impl FnMut(&[f64], &mut [f64]),
    constrained: &[bool],
    x: &mut [f64],
    g: &mut [f64],
    d: &[f64],
    mut t: f64,
    products: &mut usize,
    (s, qs): (&mut [f64], &mut [f64]),
) -> bool {
    let m = x.len();
    for _ in 0..60 {
        for i in 0..m {
            let mut xi = x[i] + t * d[i];
            if constrained[i] && !positive(xi) {
                xi = 0.0;
            }
            s[i] = xi - x[i];
        }
        let gs: f64 = g.iter().zip(s.iter()).map(|(a, b)| a * b).sum();
        if !positive(-gs) {
            return false;
        }
        apply(s, qs);
        *products += 1;
        let sqs: f64 = s.iter().zip(qs.iter()).map(|(a, b)| a * b).sum();
        if gs + 0.5 * sqs <= ARMIJO * gs {
            for i in 0..m {
                x[i] += s[i];
                g[i] += qs[i];
            }
            project(x, constrained);
            return true;
        }
        t *= 0.5;
    }
    false
}
