//! Nonnegative least squares in normal-equation form: minimise `½ xᵀ Q x − cᵀ x` subject to `x_i ≥ 0` for the
//! constrained variables (others are free).
//!
//! Block principal pivoting (Kim & Park 2011) first: each iteration solves one unconstrained system on the
//! passive set with a Cholesky factorisation (faer) and exchanges every infeasible variable at once; when that
//! stops reducing the number of infeasibilities it exchanges a single variable (Murty's rule). A set a few
//! exchanges from the last factored one is solved through that factor instead (a small saddle system for the
//! exchanged variables); the set the answer is read from is always factored itself. Pivoting is exact
//! but on ill-conditioned problems (a drifting, slowly varying input leaves many Preisach cells nearly
//! collinear) round-off can make it cycle, and each iteration costs a factorisation. So when it has not
//! finished within `max_iter` iterations, or a passive system is not numerically positive definite, the solve
//! continues with projected coordinate descent from the last pivoting iterate: every sweep lowers the objective
//! of the strictly convex quadratic, so it terminates, and its support is polished by one exact solve when that
//! solve is feasible. The result always carries how well it satisfies the optimality conditions and an
//! estimate of the conditioning: a least-squares fit on finite data never fails for numerical reasons.
use alloc::vec::Vec;

use super::error::IdentificationError;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt;
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Conj, Mat, Par};

/// Projected coordinate-descent sweeps allowed after pivoting gave up (each sweep costs one product with `Q`).
pub const MAX_DESCENT_SWEEPS: usize = 20_000;

/// Relative optimality-condition violation at which the solution is taken as converged.
pub const KKT_TOLERANCE: f64 = 1e-9;

/// Solution of a bound-constrained quadratic.
#[derive(Clone, Debug)]
pub struct NnlsSolution {
    /// Minimiser (or the best point found, see `converged`).
    pub x: Vec<f64>,
    /// Number of pivoting iterations plus coordinate-descent sweeps used.
    pub iterations: usize,
    /// The final passive set (variables off their bound; every free variable is passive).
    pub passive: Vec<bool>,
    /// Whether the optimality conditions hold to [`KKT_TOLERANCE`] (relative to the largest `|c_i|` or
    /// `|Q_ii x_i|`); false only after the descent's sweep budget ran out, the point is then the best found.
    pub converged: bool,
    /// The largest violation of the optimality conditions, relative as for `converged`.
    pub kkt_violation: f64,
    /// Estimate of the condition number of the passive system (squared ratio of the largest to the smallest
    /// Cholesky pivot; a lower bound of the 2-norm condition number; infinite when it is numerically singular).
    pub condition: f64,
    /// Whether pivoting gave way to projected coordinate descent.
    pub descent: bool,
}

/// Solve `min ½ xᵀ Q x − cᵀ x`, `x_i ≥ 0` where `constrained[i]`. `q` is `n × n` row-major symmetric positive
/// definite (add a ridge beforehand if it may be singular).
pub fn nnls_gram(
    q: &[f64],
    c: &[f64],
    constrained: &[bool],
    max_iter: usize,
) -> Result<NnlsSolution, IdentificationError> {
    nnls_gram_warm(q, c, constrained, max_iter, None)
}

/// [`nnls_gram`] started from the passive set `warm_start` (e.g. the solution of a neighbouring problem)
/// instead of all constrained variables at their bound. The minimiser is unique, so the start changes only the
/// number of iterations: from a good guess, one or two Cholesky solves instead of ten or twenty.
///
/// Errors only for inconsistent dimensions or a `q` with a non-positive or non-finite diagonal entry.
pub fn nnls_gram_warm(
    q: &[f64],
    c: &[f64],
    constrained: &[bool],
    max_iter: usize,
    warm_start: Option<&[bool]>,
) -> Result<NnlsSolution, IdentificationError> {
    nnls_gram_carried(q, c, constrained, max_iter, warm_start, None).map(|(solution, _)| solution)
}

/// The Cholesky factor of one passive set of a quadratic (`Q_FF = L Lᵀ`, the set `F` in increasing order), as
/// [`nnls_gram_carried`] hands it back for its next solve of the same `Q` (another right-hand side).
#[derive(Clone, Debug)]
pub struct PassiveFactor {
    n: usize,
    idx: Vec<usize>,
    factor: Mat<f64>,
    condition: f64,
}

impl PassiveFactor {
    /// The passive set as a mask of the unknowns (a warm start).
    pub fn passive(&self) -> Vec<bool> {
        let mut mask = alloc::vec![false; self.n];
        for &i in &self.idx {
            mask[i] = true;
        }
        mask
    }
}

/// [`nnls_gram_warm`] carrying the factor of the answer's passive set from one solve of `Q` to the next: given
/// `carried` (the factor a solve of this same `Q` returned), pivoting starts from its set unless `warm_start`
/// says otherwise, solves sets a few exchanges from it through that factor, and an answer on that very set takes
/// no factorisation at all (the factor of a set is the same to the bit however it was reached, so the answer is
/// the one a fresh factorisation gives). Returns the solution and the factor of its passive set (None after the
/// descent, or when its set was never factored). A `carried` factor of a problem of another size is ignored.
pub fn nnls_gram_carried(
    q: &[f64],
    c: &[f64],
    constrained: &[bool],
    max_iter: usize,
    warm_start: Option<&[bool]>,
    carried: Option<PassiveFactor>,
) -> Result<(NnlsSolution, Option<PassiveFactor>), IdentificationError> {
    let n = c.len();
    if q.len() != crate::limits::product(n, n)
        || constrained.len() != n
        || warm_start.is_some_and(|w| w.len() != n)
    {
        return Err(IdentificationError::SolverDimensions {
            q: q.len(),
            c: n,
            mask: warm_start.map_or(constrained.len(), <[bool]>::len),
        });
    }
    if (0..n).any(|i| !(q[i * n + i].is_finite() && q[i * n + i] > 0.0))
        || c.iter().any(|v| !v.is_finite())
    {
        return Err(IdentificationError::NotPositiveDefinite);
    }
    let carried = carried.filter(|f| f.n == n);
    let carried_start = carried.as_ref().map(PassiveFactor::passive);
    let warm_start = warm_start.or(carried_start.as_deref());
    // Passive (free to move) set F; every other variable sits at its bound 0 (or the warm start's guess).
    let cold: Vec<bool> = constrained.iter().map(|&c| !c).collect();
    let mut iterations = 0;
    let mut x = alloc::vec![0.0; n];
    let mut grad = alloc::vec![0.0; n];
    let mut workspace = PassiveWorkspace::default();
    if let Some(f) = carried {
        workspace.idx = f.idx;
        workspace.factor = Some(f.factor);
        workspace.base = Some(f.condition);
    }
    let mut passive = match warm_start {
        Some(w) => constrained.iter().zip(w).map(|(&c, &p)| !c || p).collect(),
        None => cold.clone(),
    };
    // A start from a distant problem can leave pivoting cycling where the cold start does not: the warm start
    // gets a tenth of the budget, then pivoting starts again cold before the (much slower) descent.
    let first_budget = if warm_start.is_some() {
        max_iter.div_ceil(10)
    } else {
        max_iter
    };
    match pivot(
        q,
        c,
        constrained,
        first_budget,
        &mut passive,
        &mut x,
        &mut grad,
        &mut iterations,
        &mut workspace,
    ) {
        Some(solution) => return Ok(with_factor(solution, workspace)),
        None if warm_start.is_some() => {
            passive = cold;
            if let Some(solution) = pivot(
                q,
                c,
                constrained,
                max_iter,
                &mut passive,
                &mut x,
                &mut grad,
                &mut iterations,
                &mut workspace,
            ) {
                return Ok(with_factor(solution, workspace));
            }
        }
        None => {}
    }
    // Pivoting gave up: projected coordinate descent from its last (feasible-clipped) iterate.
    for (xi, &ci) in x.iter_mut().zip(constrained) {
        if !xi.is_finite() || (ci && *xi < 0.0) {
            *xi = 0.0;
        }
    }
    let sweeps = coordinate_descent(q, c, constrained, &mut x, &mut grad);
    iterations += sweeps;
    let mut kkt = kkt_violation(q, c, constrained, &x, &grad);
    for (p, (&xi, &ci)) in passive.iter_mut().zip(x.iter().zip(constrained)) {
        *p = !ci || xi > 0.0;
    }
    // Polish: the exact minimiser on the descent's support, kept when feasible and at least as optimal.
    let mut exact = alloc::vec![0.0; n];
    let mut condition = f64::INFINITY;
    if let Some(cond) = solve_passive(q, c, &passive, &mut exact, &mut workspace) {
        condition = cond;
        if exact
            .iter()
            .zip(constrained)
            .all(|(&v, &ci)| !ci || v >= 0.0)
        {
            let mut g = alloc::vec![0.0; n];
            gradient(q, c, &exact, &mut g);
            let k = kkt_violation(q, c, constrained, &exact, &g);
            if k <= kkt {
                x = exact;
                kkt = k;
            }
        }
    }
    Ok(with_factor(
        NnlsSolution {
            x,
            iterations,
            passive,
            converged: kkt <= KKT_TOLERANCE,
            kkt_violation: kkt,
            condition,
            descent: true,
        },
        workspace,
    ))
}

/// The solution and, when `workspace` holds the factor of the solution's own passive set, that factor.
fn with_factor(
    solution: NnlsSolution,
    workspace: PassiveWorkspace,
) -> (NnlsSolution, Option<PassiveFactor>) {
    let n = solution.passive.len();
    let held = workspace.base.zip(workspace.factor).filter(|_| {
        workspace.idx.len() == solution.passive.iter().filter(|&&p| p).count()
            && workspace.idx.iter().all(|&i| solution.passive[i])
    });
    let factor = held.map(|(condition, factor)| PassiveFactor {
        n,
        idx: workspace.idx,
        factor,
        condition,
    });
    (solution, factor)
}

/// Block principal pivoting from the passive set `passive` for at most `max_iter` iterations (counted into
/// `iterations`): the solution when the optimality conditions hold, None when it gave up (`x` then holds the
/// last iterate, `passive` the last set).
#[allow(clippy::too_many_arguments)]
fn pivot(
    q: &[f64],
    c: &[f64],
    constrained: &[bool],
    max_iter: usize,
    passive: &mut [bool],
    x: &mut [f64],
    grad: &mut [f64],
    iterations: &mut usize,
    workspace: &mut PassiveWorkspace,
) -> Option<NnlsSolution> {
    let n = c.len();
    let mut best_infeasible = usize::MAX;
    let mut backup_left = 3usize;
    let tol = 1e-12 * (0..n).map(|i| q[i * n + i]).fold(0.0, f64::max);
    let infeasible_of = |x: &[f64], grad: &[f64], passive: &[bool]| -> Vec<usize> {
        (0..n)
            .filter(|&i| {
                constrained[i] && ((passive[i] && x[i] < 0.0) || (!passive[i] && grad[i] < -tol))
            })
            .collect()
    };
    for _ in 0..max_iter {
        *iterations += 1;
        // A set a few exchanges away from the last factored one is solved through that factor; the answer's
        // set is always solved again on a factor of its own (its bits and condition estimate are that solve's).
        let mut condition = match solve_passive_updated(q, c, passive, x, workspace) {
            Some(exact) => exact,
            None => Some(solve_passive(q, c, passive, x, workspace)?),
        };
        gradient(q, c, x, grad);
        let mut infeasible = infeasible_of(x, grad, passive);
        if infeasible.is_empty() && condition.is_none() {
            condition = Some(solve_passive(q, c, passive, x, workspace)?);
            gradient(q, c, x, grad);
            infeasible = infeasible_of(x, grad, passive);
        }
        if infeasible.is_empty() {
            let condition = condition.unwrap_or(f64::INFINITY);
            for (xi, &ci) in x.iter_mut().zip(constrained) {
                if ci && *xi < 0.0 {
                    *xi = 0.0;
                }
            }
            let kkt_violation = kkt_violation(q, c, constrained, x, grad);
            return Some(NnlsSolution {
                x: x.to_vec(),
                iterations: *iterations,
                passive: passive.to_vec(),
                converged: true,
                kkt_violation,
                condition,
                descent: false,
            });
        }
        if infeasible.len() < best_infeasible {
            best_infeasible = infeasible.len();
            backup_left = 3;
            for &i in &infeasible {
                passive[i] = !passive[i];
            }
        } else if backup_left > 0 {
            backup_left -= 1;
            for &i in &infeasible {
                passive[i] = !passive[i];
            }
        } else {
            let i = *infeasible.last().unwrap_or(&0);
            passive[i] = !passive[i];
        }
    }
    None
}

/// `grad = Q x − c`: on a variable at its bound, its Lagrange multiplier (must be ≥ 0).
///
/// Accumulated over the rows of `Q` whose `x_j` is not zero (`Q` is symmetric: row `j` is column `j`), in
/// increasing `j`: the same sums in the same order as the products of the rows of `Q` with `x` (to the bit when
/// `Q` is symmetric to the bit; a normal matrix built as `Cᵀ G C` may differ from its transpose by round-off),
/// but reading only the passive set's rows (a quarter of `Q` in a table fit) instead of all of it.
fn gradient(q: &[f64], c: &[f64], x: &[f64], grad: &mut [f64]) {
    let n = c.len();
    grad.iter_mut().for_each(|g| *g = -0.0);
    for (j, &xj) in x.iter().enumerate() {
        if xj != 0.0 {
            for (g, &a) in grad.iter_mut().zip(&q[j * n..(j + 1) * n]) {
                *g += a * xj;
            }
        }
    }
    for (g, &ci) in grad.iter_mut().zip(c) {
        *g -= ci;
    }
}

/// The largest violation of the optimality conditions (`grad_i = 0` off the bound, `grad_i ≥ 0` on it),
/// relative to the largest `|c_i|` and `|Q_ii x_i|`.
fn kkt_violation(q: &[f64], c: &[f64], constrained: &[bool], x: &[f64], grad: &[f64]) -> f64 {
    let n = c.len();
    let mut scale = 0.0f64;
    let mut worst = 0.0f64;
    for i in 0..n {
        scale = scale.max(c[i].abs()).max((q[i * n + i] * x[i]).abs());
        let v = if constrained[i] && x[i] <= 0.0 {
            (-grad[i]).max(0.0)
        } else {
            grad[i].abs()
        };
        worst = worst.max(v);
    }
    if scale > 0.0 { worst / scale } else { worst }
}

/// Projected Gauss-Seidel on the quadratic from `x` (feasible): each coordinate moves to its exact minimiser
/// given the others, clipped to its bound. Strictly convex (positive diagonal, positive definite `Q`), so the
/// objective falls every sweep. Stops when the optimality conditions hold to [`KKT_TOLERANCE`] or after
/// [`MAX_DESCENT_SWEEPS`]; returns the sweeps used and leaves `grad = Q x − c`.
fn coordinate_descent(
    q: &[f64],
    c: &[f64],
    constrained: &[bool],
    x: &mut [f64],
    grad: &mut [f64],
) -> usize {
    let n = c.len();
    gradient(q, c, x, grad);
    for sweep in 0..MAX_DESCENT_SWEEPS {
        if kkt_violation(q, c, constrained, x, grad) <= KKT_TOLERANCE {
            return sweep;
        }
        for i in 0..n {
            let qii = q[i * n + i];
            let mut xi = x[i] - grad[i] / qii;
            if constrained[i] && xi < 0.0 {
                xi = 0.0;
            }
            let step = xi - x[i];
            if step != 0.0 {
                x[i] = xi;
                // Q is symmetric: column i is row i.
                for (g, a) in grad.iter_mut().zip(&q[i * n..(i + 1) * n]) {
                    *g += a * step;
                }
            }
        }
    }
    MAX_DESCENT_SWEEPS
}

/// Storage the passive systems of one solve share: the Cholesky factor (a column-major square grown to the
/// largest passive set seen, its top-left corner used), the factorisation's scratch and the passive indices.
/// Every pivoting step factors a system of a few hundred unknowns; a fresh factor per step (plus the copy of
/// its lower triangle a `Mat::llt` makes) was a page-faulted allocation of that size each time.
#[derive(Default)]
struct PassiveWorkspace {
    idx: Vec<usize>,
    factor: Option<Mat<f64>>,
    scratch: Option<(usize, MemBuffer)>,
    /// Times the factor storage was allocated (once per new largest passive set).
    allocations: usize,
    /// The condition estimate of the factor held (of the set `idx`), None when it holds none.
    base: Option<f64>,
}

impl PassiveWorkspace {
    /// The factor storage for `k` unknowns (reallocated only when `k` exceeds every earlier size) and the scratch
    /// of a `k × k` factorisation.
    fn for_size(&mut self, k: usize) -> (&mut Mat<f64>, &mut MemBuffer) {
        if self.factor.as_ref().is_none_or(|f| f.nrows() < k) {
            self.factor = Some(Mat::zeros(k, k));
            self.allocations += 1;
        }
        if self.scratch.as_ref().is_none_or(|(size, _)| *size < k) {
            let req =
                llt::factor::cholesky_in_place_scratch::<f64>(k, Par::Seq, Default::default());
            self.scratch = Some((k, MemBuffer::new(req)));
        }
        match (&mut self.factor, &mut self.scratch) {
            (Some(f), Some((_, mem))) => (f, mem),
            _ => unreachable!("both were just made"),
        }
    }
}

/// `x_F = Q_FF⁻¹ c_F`, zero elsewhere; returns the condition estimate of `Q_FF` (squared ratio of its largest to
/// smallest Cholesky pivot), or None when `Q_FF` is not numerically positive definite or the solution is not
/// finite. The factorisation is `Mat::llt`'s (the lower triangle of `Q_FF`, read as `Q[F_r, F_s]`, factored in
/// place sequentially, the upper triangle zero), done in `workspace`'s storage: the same factor to the bit.
fn solve_passive(
    q: &[f64],
    c: &[f64],
    passive: &[bool],
    x: &mut [f64],
    workspace: &mut PassiveWorkspace,
) -> Option<f64> {
    let n = c.len();
    let mut idx = core::mem::take(&mut workspace.idx);
    idx.clear();
    idx.extend((0..n).filter(|&i| passive[i]));
    x.iter_mut().for_each(|v| *v = 0.0);
    let k = idx.len();
    if k == 0 {
        workspace.idx = idx;
        return Some(1.0);
    }
    let (factor, mem) = workspace.for_size(k);
    let mut a = factor.as_mut().submatrix_mut(0, 0, k, k);
    // Row by row of Q (each read where the passive columns lie), into the lower triangle; the upper one zero.
    for (r, &qr) in idx.iter().enumerate() {
        let row = &q[qr * n..(qr + 1) * n];
        for (s, &qs) in idx[..=r].iter().enumerate() {
            a[(r, s)] = row[qs];
        }
    }
    for s in 1..k {
        a.rb_mut().col_mut(s).subrows_mut(0, s).fill(0.0);
    }
    let factored = llt::factor::cholesky_in_place(
        a.rb_mut(),
        Default::default(),
        Par::Seq,
        MemStack::new(mem),
        Default::default(),
    );
    if factored.is_err() {
        workspace.idx = idx;
        workspace.base = None;
        return None;
    }
    for s in 1..k {
        a.rb_mut().col_mut(s).subrows_mut(0, s).fill(0.0);
    }
    let l = a.rb();
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for r in 0..k {
        let d = l[(r, r)].abs();
        lo = lo.min(d);
        hi = hi.max(d);
    }
    let mut sol = Mat::<f64>::from_fn(k, 1, |r, _| c[idx[r]]);
    llt::solve::solve_in_place_with_conj(
        l,
        Conj::No,
        sol.as_mut(),
        Par::Seq,
        MemStack::new(&mut []),
    );
    for (r, &i) in idx.iter().enumerate() {
        x[i] = sol[(r, 0)];
    }
    workspace.idx = idx;
    if x.iter().any(|v| !v.is_finite()) {
        workspace.base = None;
        return None;
    }
    let condition = if lo > 0.0 {
        (hi / lo) * (hi / lo)
    } else {
        f64::INFINITY
    };
    workspace.base = Some(condition);
    Some(condition)
}

/// Exchanges (variables left plus variables joined) up to this share of the factored set are solved through
/// its factor: each costs two triangular solves, a fresh factor a third of the set's size in them.
const UPDATE_SHARE: usize = 10;

/// `x_F = Q_FF⁻¹ c_F` through the factor `workspace` holds of another set `F₀` (see [`solve_passive`]): the
/// variables `R = F₀ ∖ F` held at zero by multipliers and those of `A = F ∖ F₀` bordered on, one small saddle
/// system for them (the Schur complement of `Q_F₀F₀`). The same minimiser as a fresh factor of `Q_FF` up to
/// round-off; it serves to find the answer's set, which is then solved fresh. Returns None when there is no
/// factor, the exchanges are too many or the system is not numerically solvable (solve fresh then);
/// `Some(Some(condition))` when `F` is `F₀` itself (the fresh solve's bits), `Some(None)` otherwise.
fn solve_passive_updated(
    q: &[f64],
    c: &[f64],
    passive: &[bool],
    x: &mut [f64],
    workspace: &PassiveWorkspace,
) -> Option<Option<f64>> {
    use faer::prelude::Solve;
    let base_condition = workspace.base?;
    let n = c.len();
    let idx = &workspace.idx;
    let k = idx.len();
    let l = workspace.factor.as_ref()?.as_ref().submatrix(0, 0, k, k);
    let mut in_base = alloc::vec![usize::MAX; n];
    for (r, &i) in idx.iter().enumerate() {
        in_base[i] = r;
    }
    // The exchanges: positions (in F₀) of the variables that left, then the variables that joined.
    let left: Vec<usize> = (0..k).filter(|&r| !passive[idx[r]]).collect();
    let joined: Vec<usize> = (0..n)
        .filter(|&i| passive[i] && in_base[i] == usize::MAX)
        .collect();
    let (a, m) = (joined.len(), joined.len() + left.len());
    if m > k.max(UPDATE_SHARE) / UPDATE_SHARE {
        return None;
    }
    // Columns [Q_F₀A | E_R | c_F₀], solved in place by L Lᵀ: M = Q_F₀F₀⁻¹ [Q_F₀A | E_R], z = Q_F₀F₀⁻¹ c_F₀.
    // Q as the factor reads it: its lower triangle (Q is symmetric up to round-off).
    let lower = |i: usize, j: usize| q[i.max(j) * n + i.min(j)];
    let border = |r: usize, j: usize| -> f64 {
        if j < a {
            lower(idx[r], joined[j])
        } else if j < m {
            f64::from(u8::from(left[j - a] == r))
        } else {
            c[idx[r]]
        }
    };
    let mut sol = Mat::<f64>::from_fn(k, m + 1, border);
    llt::solve::solve_in_place_with_conj(
        l,
        Conj::No,
        sol.as_mut(),
        Par::Seq,
        MemStack::new(&mut []),
    );
    // The saddle system for [x_A, multipliers of R]: S = [Q_AA 0; 0 0] − Bᵀ M, s = [c_A; 0] − Bᵀ z.
    let dot_border = |i: usize, j: usize| -> f64 {
        if i < a {
            (0..k)
                .map(|r| lower(idx[r], joined[i]) * sol[(r, j)])
                .sum::<f64>()
        } else {
            sol[(left[i - a], j)]
        }
    };
    let s = Mat::<f64>::from_fn(m, m, |i, j| {
        let own = if i < a && j < a {
            lower(joined[i], joined[j])
        } else {
            0.0
        };
        own - dot_border(i, j)
    });
    let rhs = Mat::<f64>::from_fn(
        m,
        1,
        |i, _| if i < a { c[joined[i]] } else { 0.0 } - dot_border(i, m),
    );
    let y = if m == 0 {
        rhs
    } else {
        s.as_ref().partial_piv_lu().solve(&rhs)
    };
    x.iter_mut().for_each(|v| *v = 0.0);
    for (r, &i) in idx.iter().enumerate() {
        if passive[i] {
            x[i] = if m == 0 {
                sol[(r, 0)]
            } else {
                sol[(r, m)] - (0..m).map(|j| sol[(r, j)] * y[(j, 0)]).sum::<f64>()
            };
        }
    }
    for (j, &i) in joined.iter().enumerate() {
        x[i] = y[(j, 0)];
    }
    if x.iter().any(|v| !v.is_finite()) {
        return None;
    }
    Some((m == 0).then_some(base_condition))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clips_negative_direction_and_keeps_free_variables() {
        // Q = I: solution is max(c, 0) on constrained, c on free.
        let q = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let c = [1.0, -2.0, -3.0];
        let s = nnls_gram(&q, &c, &[true, true, false], 50).unwrap();
        assert_eq!(s.x, alloc::vec![1.0, 0.0, -3.0]);
    }

    #[test]
    fn coupled_problem_satisfies_kkt() {
        let q = [2.0, 1.0, 1.0, 2.0];
        let c = [-1.0, 2.0];
        let s = nnls_gram(&q, &c, &[true, true], 50).unwrap();
        // Unconstrained minimiser (−4/3, 5/3) is infeasible; the answer is x = (0, 1).
        assert!((s.x[0]).abs() < 1e-12 && (s.x[1] - 1.0).abs() < 1e-12);
        assert!(s.converged && !s.descent);
    }

    /// A dense, badly conditioned problem (a Hilbert-like Gram matrix plus a small ridge) with many active
    /// bounds: size, Gram matrix, linear term, which unknowns are bounded.
    fn hilbert_problem() -> (usize, Vec<f64>, Vec<f64>, Vec<bool>) {
        let n = 24;
        let mut q = alloc::vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                q[i * n + j] = 1.0 / (1.0 + i as f64 + j as f64);
            }
            q[i * n + i] += 1e-6;
        }
        let c: Vec<f64> = (0..n)
            .map(|i| {
                if i % 3 == 0 {
                    -0.5
                } else {
                    1.0 / (1.0 + i as f64)
                }
            })
            .collect();
        let constrained: Vec<bool> = (0..n).map(|i| i + 1 < n).collect();
        (n, q, c, constrained)
    }

    /// On [`hilbert_problem`], pivoting cut off after one iteration hands over to coordinate descent, which
    /// reaches the same minimiser as pivoting left to finish.
    #[test]
    fn descent_after_pivoting_gives_up_reaches_the_pivoting_answer() {
        let (n, q, c, constrained) = hilbert_problem();
        let exact = nnls_gram(&q, &c, &constrained, 500).unwrap();
        let cut = nnls_gram(&q, &c, &constrained, 1).unwrap();
        assert!(exact.converged && !exact.descent);
        assert!(cut.descent && cut.converged, "{cut:?}");
        assert!(cut.condition >= 1.0 && cut.condition.is_finite());
        let objective = |x: &[f64]| {
            let mut g = alloc::vec![0.0; n];
            gradient(&q, &c, x, &mut g);
            (0..n).map(|i| 0.5 * x[i] * (g[i] - c[i])).sum::<f64>()
        };
        let (a, b) = (objective(&exact.x), objective(&cut.x));
        assert!((a - b).abs() <= 1e-9 * a.abs().max(1e-12), "{a} vs {b}");
        assert!(
            cut.x
                .iter()
                .zip(&constrained)
                .all(|(&v, &ci)| !ci || v >= 0.0)
        );
    }

    #[test]
    fn a_warm_start_far_from_the_answer_still_ends_by_pivoting() {
        // The ill-conditioned problem above, started from the complement of its solution's passive set with a
        // budget the cold start needs: the warm start's share of it runs out, pivoting starts again cold and
        // finds the same minimiser without the descent.
        let (_, q, c, constrained) = hilbert_problem();
        let cold = nnls_gram(&q, &c, &constrained, 500).unwrap();
        let far: Vec<bool> = cold.passive.iter().map(|&p| !p).collect();
        let budget = 10 * cold.iterations;
        let warm = nnls_gram_warm(&q, &c, &constrained, budget, Some(&far)).unwrap();
        assert!(warm.converged && !warm.descent, "{warm:?}");
        for (a, b) in warm.x.iter().zip(&cold.x) {
            assert!((a - b).abs() <= 1e-9 * b.abs().max(1.0), "{a} vs {b}");
        }
    }

    #[test]
    fn a_carried_factor_changes_the_work_not_the_bits() {
        // Two right-hand sides of the ill-conditioned problem above: the second solved fresh and from the factor
        // the first handed back gives the same minimiser to the bit, and the first solved again from its own
        // factor takes one iteration and no factorisation of a new set.
        let (n, q, c, constrained) = hilbert_problem();
        let c2: Vec<f64> = c
            .iter()
            .enumerate()
            .map(|(i, v)| v + 0.05 * (i as f64 * 0.7).sin())
            .collect();
        let (first, factor) = nnls_gram_carried(&q, &c, &constrained, 500, None, None).unwrap();
        let factor = factor.expect("pivoting ends on a factored set");
        assert_eq!(factor.passive(), first.passive);
        let fresh = nnls_gram(&q, &c2, &constrained, 500).unwrap();
        let (carried, _) =
            nnls_gram_carried(&q, &c2, &constrained, 500, None, Some(factor.clone())).unwrap();
        assert!(fresh.converged && carried.converged);
        assert_eq!(fresh.passive, carried.passive);
        for i in 0..n {
            assert_eq!(fresh.x[i].to_bits(), carried.x[i].to_bits(), "unknown {i}");
        }
        assert_eq!(fresh.condition.to_bits(), carried.condition.to_bits());
        let (again, _) = nnls_gram_carried(&q, &c, &constrained, 500, None, Some(factor)).unwrap();
        assert_eq!(again.iterations, 1);
        assert!(
            again
                .x
                .iter()
                .zip(&first.x)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
        // A factor of a problem of another size is ignored.
        let small = PassiveFactor {
            n: 2,
            idx: alloc::vec![0],
            factor: Mat::zeros(1, 1),
            condition: 1.0,
        };
        let (other, _) = nnls_gram_carried(&q, &c, &constrained, 500, None, Some(small)).unwrap();
        assert!(
            other
                .x
                .iter()
                .zip(&first.x)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
    }

    #[test]
    fn the_gradient_read_from_the_passive_rows_equals_the_full_product_to_the_bit() {
        let n = 17;
        let mut q = alloc::vec![0.0; n * n];
        for i in 0..n {
            for j in 0..=i {
                let v =
                    ((i * 31 + j * 17) % 13) as f64 / 7.0 - 0.8 + if i == j { 4.0 } else { 0.0 };
                q[i * n + j] = v;
                q[j * n + i] = v;
            }
        }
        let c: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        // Zeros (the variables at their bound) among the values, as in a pivoting iterate.
        let x: Vec<f64> = (0..n)
            .map(|i| {
                if i % 3 == 1 {
                    0.0
                } else {
                    (i as f64 * 1.3).cos()
                }
            })
            .collect();
        let mut grad = alloc::vec![0.0; n];
        gradient(&q, &c, &x, &mut grad);
        for i in 0..n {
            let full = q[i * n..(i + 1) * n]
                .iter()
                .zip(&x)
                .map(|(a, b)| a * b)
                .sum::<f64>()
                - c[i];
            assert_eq!(full.to_bits(), grad[i].to_bits(), "row {i}");
        }
    }

    #[test]
    fn no_pivoting_at_all_still_solves() {
        let q = [2.0, 1.0, 1.0, 2.0];
        let c = [-1.0, 2.0];
        let s = nnls_gram(&q, &c, &[true, true], 0).unwrap();
        assert!(s.converged && s.descent && (s.x[0]).abs() < 1e-9 && (s.x[1] - 1.0).abs() < 1e-9);
    }

    /// `solve_passive` as it was before the workspace: `Mat::llt` on a fresh copy of `Q_FF`.
    fn solve_passive_fresh(q: &[f64], c: &[f64], passive: &[bool]) -> Option<(Vec<f64>, f64)> {
        use faer::Side;
        use faer::prelude::Solve;
        let n = c.len();
        let idx: Vec<usize> = (0..n).filter(|&i| passive[i]).collect();
        let k = idx.len();
        let a = Mat::<f64>::from_fn(k, k, |r, s| q[idx[r] * n + idx[s]]);
        let b = Mat::<f64>::from_fn(k, 1, |r, _| c[idx[r]]);
        let llt = a.llt(Side::Lower).ok()?;
        let l = llt.L();
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for r in 0..k {
            lo = lo.min(l[(r, r)].abs());
            hi = hi.max(l[(r, r)].abs());
        }
        let sol = llt.solve(&b);
        let mut x = alloc::vec![0.0; n];
        for (r, &i) in idx.iter().enumerate() {
            x[i] = sol[(r, 0)];
        }
        Some((x, (hi / lo) * (hi / lo)))
    }

    /// The dense test matrix of the factor tests (`n` unknowns, not symmetric: a factor reads its lower
    /// triangle, positive definite) and a linear term.
    fn dense_problem(n: usize) -> (Vec<f64>, Vec<f64>) {
        let mut q = alloc::vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                let v = 1.0 / (1.0 + (i as f64 - j as f64).abs())
                    + 0.3 * ((i * 7 + j * 3) % 11) as f64 / 11.0;
                q[i * n + j] = v * (1.0 + 1e-15 * ((i + 2 * j) % 5) as f64);
            }
            q[i * n + i] += n as f64;
        }
        let c: Vec<f64> = (0..n).map(|i| ((i * 37) % 17) as f64 - 8.0).collect();
        (q, c)
    }

    #[test]
    fn a_set_a_few_exchanges_from_the_factored_one_solves_through_its_factor() {
        let n = 150;
        let (q, c) = dense_problem(n);
        let mut workspace = PassiveWorkspace::default();
        let base: Vec<bool> = (0..n).map(|i| i % 3 != 0).collect();
        let mut x = alloc::vec![0.0; n];
        let cond = solve_passive(&q, &c, &base, &mut x, &mut workspace).unwrap();
        // The factored set itself: the fresh solve's bits and its condition estimate.
        let mut again = alloc::vec![1.0; n];
        let same = solve_passive_updated(&q, &c, &base, &mut again, &workspace).unwrap();
        assert_eq!((again.clone(), same), (x.clone(), Some(cond)));
        // Variables leaving and joining (at the ends and inside): the minimiser of a fresh factor, to round-off.
        for (leave, join) in [
            (&[1usize, 2][..], &[0usize][..]),
            (&[], &[3, 147]),
            (&[148, 2, 74], &[]),
            (&[5, 146], &[6, 9, 144]),
        ] {
            let mut set = base.clone();
            for &i in leave {
                assert!(set[i]);
                set[i] = false;
            }
            for &i in join {
                assert!(!set[i]);
                set[i] = true;
            }
            let mut y = alloc::vec![1.0; n];
            assert_eq!(
                solve_passive_updated(&q, &c, &set, &mut y, &workspace),
                Some(None)
            );
            let (fresh, _) = solve_passive_fresh(&q, &c, &set).unwrap();
            for (i, (a, b)) in y.iter().zip(&fresh).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-12 * b.abs().max(1.0),
                    "{leave:?} {join:?} x[{i}]: {a} vs {b}"
                );
                assert!(set[i] || *a == 0.0, "x[{i}] off the set is {a}");
            }
        }
        // Past a tenth of the set, a fresh factor (None); with no factor held, likewise.
        let far: Vec<bool> = (0..n).map(|i| i % 3 != 1).collect();
        assert_eq!(
            solve_passive_updated(&q, &c, &far, &mut x, &workspace),
            None
        );
        assert_eq!(
            solve_passive_updated(&q, &c, &base, &mut x, &PassiveWorkspace::default()),
            None
        );
    }

    #[test]
    fn the_answer_is_the_fresh_solve_of_its_own_set_to_the_bit() {
        // Pivoting from a warm start a few exchanges away runs through the factor of the start's set; the answer
        // returned is nonetheless the fresh factor's solve of the final set.
        let n = 150;
        let (q, mut c) = dense_problem(n);
        for (i, v) in c.iter_mut().enumerate() {
            *v += 40.0 * ((i as f64) * 0.21).sin();
        }
        let constrained = alloc::vec![true; n];
        let cold = nnls_gram(&q, &c, &constrained, 500).unwrap();
        let mut start = cold.passive.clone();
        for i in [3usize, 40, 41, 97, 120] {
            start[i] = !start[i];
        }
        let warm = nnls_gram_warm(&q, &c, &constrained, 500, Some(&start)).unwrap();
        assert!(
            warm.converged && !warm.descent && warm.iterations > 1,
            "{warm:?}"
        );
        assert_eq!(warm.passive, cold.passive);
        let (fresh, cond) = solve_passive_fresh(&q, &c, &warm.passive).unwrap();
        let clipped: Vec<f64> = fresh.iter().map(|&v| v.max(0.0)).collect();
        assert_eq!(warm.x, clipped);
        assert_eq!(warm.condition.to_bits(), cond.to_bits());
        assert_eq!(warm.x, cold.x);
    }

    #[test]
    fn passive_systems_share_one_factor_storage_and_solve_as_a_fresh_factor_to_the_bit() {
        let n = 150;
        let (q, c) = dense_problem(n);
        let mut workspace = PassiveWorkspace::default();
        // Passive sets of several sizes, the largest first (as a warm-started pivoting shrinks its set).
        for (m, size) in [
            (1usize, 150usize),
            (2, 120),
            (3, 97),
            (5, 60),
            (7, 13),
            (4, 150),
        ] {
            let passive: Vec<bool> = (0..n).map(|i| (i * m) % n < size).collect();
            let mut x = alloc::vec![1.0; n];
            let cond = solve_passive(&q, &c, &passive, &mut x, &mut workspace).unwrap();
            let (fresh_x, fresh_cond) = solve_passive_fresh(&q, &c, &passive).unwrap();
            assert_eq!(x, fresh_x);
            assert_eq!(cond.to_bits(), fresh_cond.to_bits());
        }
        assert_eq!(
            workspace.allocations, 1,
            "the factor of the largest set serves every smaller one"
        );
    }
}
