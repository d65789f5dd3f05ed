//! Nonnegative least squares in normal-equation form by block principal pivoting (Kim & Park 2011):
//! minimise `½ xᵀ Q x − cᵀ x` subject to `x_i ≥ 0` for the constrained variables (others are free).
//!
//! Each iteration solves one unconstrained system on the passive set with a Cholesky factorisation (faer) and
//! exchanges every infeasible variable at once; when that stops reducing the number of infeasibilities it
//! falls back to exchanging a single variable (Murty's rule), which guarantees termination.
use alloc::vec::Vec;

use super::error::IdentificationError;

use faer::prelude::Solve;
use faer::{Mat, Side};

/// Solution of a bound-constrained quadratic.
#[derive(Clone, Debug)]
pub struct NnlsSolution {
    /// Minimiser.
    pub x: Vec<f64>,
    /// Number of pivoting iterations used.
    pub iterations: usize,
    /// The final passive set (variables off their bound; every free variable is passive).
    pub passive: Vec<bool>,
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
pub fn nnls_gram_warm(
    q: &[f64],
    c: &[f64],
    constrained: &[bool],
    max_iter: usize,
    warm_start: Option<&[bool]>,
) -> Result<NnlsSolution, IdentificationError> {
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
    // Passive (free to move) set F; every other variable sits at its bound 0 (or the warm start's guess).
    let mut passive: Vec<bool> = match warm_start {
        Some(w) => constrained.iter().zip(w).map(|(&c, &p)| !c || p).collect(),
        None => constrained.iter().map(|&c| !c).collect(),
    };
    let mut x = alloc::vec![0.0; n];
    let mut grad = alloc::vec![0.0; n];
    let mut best_infeasible = usize::MAX;
    let mut backup_left = 3usize;
    let tol = 1e-12
        * (0..n)
            .map(|i| q[i * n + i].abs())
            .fold(0.0, f64::max)
            .max(1e-300);
    for iter in 0..max_iter {
        solve_passive(q, c, &passive, &mut x)?;
        // grad = Q x − c: its value on a bound variable is its Lagrange multiplier (must be ≥ 0).
        for i in 0..n {
            let row = &q[i * n..(i + 1) * n];
            grad[i] = row.iter().zip(&x).map(|(a, b)| a * b).sum::<f64>() - c[i];
        }
        let infeasible: Vec<usize> = (0..n)
            .filter(|&i| {
                constrained[i] && ((passive[i] && x[i] < 0.0) || (!passive[i] && grad[i] < -tol))
            })
            .collect();
        if infeasible.is_empty() {
            for (xi, &ci) in x.iter_mut().zip(constrained) {
                if ci && *xi < 0.0 {
                    *xi = 0.0;
                }
            }
            return Ok(NnlsSolution {
                x,
                iterations: iter + 1,
                passive,
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
    Err(IdentificationError::NotConverged {
        iterations: max_iter,
    })
}

/// `x_F = Q_FF⁻¹ c_F`, zero elsewhere.
fn solve_passive(
    q: &[f64],
    c: &[f64],
    passive: &[bool],
    x: &mut [f64],
) -> Result<(), IdentificationError> {
    let n = c.len();
    let idx: Vec<usize> = (0..n).filter(|&i| passive[i]).collect();
    x.iter_mut().for_each(|v| *v = 0.0);
    if idx.is_empty() {
        return Ok(());
    }
    let k = idx.len();
    let a = Mat::<f64>::from_fn(k, k, |r, s| q[idx[r] * n + idx[s]]);
    let b = Mat::<f64>::from_fn(k, 1, |r, _| c[idx[r]]);
    let llt = a
        .llt(Side::Lower)
        .map_err(|_| IdentificationError::NotPositiveDefinite)?;
    let sol = llt.solve(&b);
    for (r, &i) in idx.iter().enumerate() {
        x[i] = sol[(r, 0)];
    }
    Ok(())
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
    }
}
