//! Least-squares fit of the angle-dependent seal friction (paper eq 22):
//! `T_f(θ) = c0 + Σ_{k=1..K} a_k sin kθ + b_k cos kθ`, linear in its `2K + 1` coefficients.
//!
//! Solved with a QR factorisation (faer) of the regressors augmented with the data column, taken block by block
//! (the triangular factor of the rows so far stacked on the next block), so memory stays `O(block × p)` whatever
//! the number of samples. The coefficient covariance is `σ² (XᵀX)⁻¹` with `σ²` the residual variance
//! `RSS / (n − p)`, obtained from the triangular factor `R` (`(XᵀX)⁻¹ = R⁻¹ R⁻ᵀ`).
use alloc::vec::Vec;

use faer::Mat;

use super::error::IdentificationError;
use crate::limits::{self, MAX_FIT_ORDER};

/// Rows of regressors factorised at a time.
const BLOCK_ROWS: usize = 4096;

/// Result of one friction fit at a fixed harmonic order.
#[derive(Clone, Debug, PartialEq)]
pub struct FrictionFit {
    /// Harmonic order `K`.
    pub order: usize,
    /// Constant term `c0` (N·mm).
    pub c0: f64,
    /// Sine coefficients `a_1..a_K` (N·mm).
    pub a: Vec<f64>,
    /// Cosine coefficients `b_1..b_K` (N·mm).
    pub b: Vec<f64>,
    /// Standard error of `c0` (N·mm).
    pub c0_stderr: f64,
    /// Standard errors of `a_k` (N·mm).
    pub a_stderr: Vec<f64>,
    /// Standard errors of `b_k` (N·mm).
    pub b_stderr: Vec<f64>,
    /// Full covariance of `[c0, a_1, b_1, …, a_K, b_K]` (row-major, `p × p`, N·mm²).
    pub covariance: Vec<f64>,
    /// Residual sum of squares (N·mm²).
    pub rss: f64,
    /// Number of samples used.
    pub n: usize,
}

impl FrictionFit {
    /// Number of fitted coefficients `2K + 1`.
    pub fn n_params(&self) -> usize {
        2 * self.order + 1
    }

    /// Residual RMS (N·mm).
    pub fn residual_rms(&self) -> f64 {
        (self.rss / self.n as f64).sqrt()
    }

    /// Friction torque at angle `theta_rad` (N·mm): the core's friction series
    /// ([`crate::friction::harmonic_series`]).
    pub fn eval(&self, theta_rad: f64) -> f64 {
        let (s, c) = crate::trig::sincos(theta_rad);
        self.c0 + crate::friction::harmonic_series(&self.a, &self.b, s, c)
    }
}

/// Fit `c0 + Σ a_k sin kθ + b_k cos kθ` of order `order` (at most [`MAX_FIT_ORDER`]) to
/// `(theta_rad, torque_nmm)` by least squares.
///
/// Errors when lengths differ, values are not finite, the order is above its limit, or there are too few samples
/// or too little angle coverage for the requested order (the regressors would be rank deficient).
pub fn fit_friction(
    theta_rad: &[f64],
    torque_nmm: &[f64],
    order: usize,
) -> Result<FrictionFit, IdentificationError> {
    let n = theta_rad.len();
    limits::check("friction fit harmonic order", order, MAX_FIT_ORDER)?;
    if torque_nmm.len() != n {
        return Err(IdentificationError::LengthMismatch {
            first: "theta",
            first_len: n,
            second: "torque",
            second_len: torque_nmm.len(),
        });
    }
    for (what, values) in [("theta sample", theta_rad), ("torque sample", torque_nmm)] {
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(IdentificationError::NonFinite {
                what,
                index: i,
                value: values[i],
            });
        }
    }
    let p = 2 * order + 1;
    if n <= p {
        return Err(IdentificationError::TooFewSamples {
            order,
            needed: p,
            got: n,
        });
    }
    // Triangular factor of [X | y], updated block by block: QR of [R; X_block y_block].
    let mut r_aug = Mat::<f64>::zeros(p + 1, p + 1);
    let mut start = 0;
    while start < n {
        let end = (start + BLOCK_ROWS).min(n);
        let rows = p + 1 + (end - start);
        let stacked = Mat::<f64>::from_fn(rows, p + 1, |i, j| {
            if i <= p {
                r_aug[(i, j)]
            } else {
                let s = start + i - (p + 1);
                if j < p {
                    regressor(theta_rad[s], j)
                } else {
                    torque_nmm[s]
                }
            }
        });
        let qr = stacked.qr();
        let r = qr.thin_R();
        r_aug = Mat::<f64>::from_fn(p + 1, p + 1, |i, j| if j >= i { r[(i, j)] } else { 0.0 });
        start = end;
    }
    // Rank check: a tiny diagonal of R means the angles do not excite some harmonic.
    let rmax = (0..p).map(|i| r_aug[(i, i)].abs()).fold(0.0, f64::max);
    for i in 0..p {
        let d = r_aug[(i, i)].abs();
        if d.is_nan() || d <= 1e-9 * rmax.max(f64::MIN_POSITIVE) {
            return Err(IdentificationError::Undetermined {
                order,
                coefficient: i,
            });
        }
    }
    // R c = Qᵀy by back substitution.
    let mut coef = alloc::vec![0.0; p];
    for i in (0..p).rev() {
        let mut s = r_aug[(i, p)];
        for (k, c) in coef.iter().enumerate().skip(i + 1) {
            s -= r_aug[(i, k)] * c;
        }
        coef[i] = s / r_aug[(i, i)];
    }
    // The last diagonal entry of the augmented factor is the residual norm.
    let rss = r_aug[(p, p)] * r_aug[(p, p)];
    let sigma2 = rss / (n - p) as f64;
    // R⁻¹ by back substitution (upper triangular p × p), then (XᵀX)⁻¹ = R⁻¹ R⁻ᵀ.
    let r = |i: usize, j: usize| r_aug[(i, j)];
    let mut rinv = alloc::vec![0.0; p * p];
    for col in 0..p {
        for row in (0..=col).rev() {
            let mut s = if row == col { 1.0 } else { 0.0 };
            for k in row + 1..=col {
                s -= r(row, k) * rinv[k * p + col];
            }
            rinv[row * p + col] = s / r(row, row);
        }
    }
    let mut cov = alloc::vec![0.0; p * p];
    for i in 0..p {
        for j in 0..p {
            let mut s = 0.0;
            for k in i.max(j)..p {
                s += rinv[i * p + k] * rinv[j * p + k];
            }
            cov[i * p + j] = sigma2 * s;
        }
    }
    let se = |j: usize| cov[j * p + j].max(0.0).sqrt();
    Ok(FrictionFit {
        order,
        c0: coef[0],
        a: (0..order).map(|k| coef[1 + 2 * k]).collect(),
        b: (0..order).map(|k| coef[2 + 2 * k]).collect(),
        c0_stderr: se(0),
        a_stderr: (0..order).map(|k| se(1 + 2 * k)).collect(),
        b_stderr: (0..order).map(|k| se(2 + 2 * k)).collect(),
        covariance: cov,
        rss,
        n,
    })
}

/// Column `j` of the regressor row at angle `theta`: `[1, sin θ, cos θ, sin 2θ, cos 2θ, …]`.
fn regressor(theta: f64, j: usize) -> f64 {
    if j == 0 {
        return 1.0;
    }
    let k = j.div_ceil(2) as f64;
    if j % 2 == 1 {
        (k * theta).sin()
    } else {
        (k * theta).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_exact_coefficients() {
        let theta: Vec<f64> = (0..2000).map(|i| i as f64 * 0.01).collect();
        let y: Vec<f64> = theta
            .iter()
            .map(|t| 3.0 + 2.0 * t.sin() - 1.0 * t.cos() + 0.5 * (3.0 * t).sin())
            .collect();
        let fit = fit_friction(&theta, &y, 3).unwrap();
        assert!((fit.c0 - 3.0).abs() < 1e-9);
        assert!((fit.a[0] - 2.0).abs() < 1e-9);
        assert!((fit.b[0] + 1.0).abs() < 1e-9);
        assert!((fit.a[2] - 0.5).abs() < 1e-9);
        assert!(fit.rss < 1e-12);
        assert!((fit.eval(1.3) - y[130]).abs() < 1e-9);
    }

    #[test]
    fn rejects_bad_input() {
        assert!(fit_friction(&[0.0, 1.0], &[0.0], 0).is_err());
        assert!(fit_friction(&[0.0, f64::NAN, 2.0], &[0.0, 1.0, 2.0], 0).is_err());
        assert!(fit_friction(&[0.0, 1.0, 2.0], &[0.0, 1.0, 2.0], 3).is_err());
        // Constant angle: sin/cos columns are collinear with the constant.
        let theta = [0.5; 100];
        let y = [1.0; 100];
        assert!(fit_friction(&theta, &y, 1).is_err());
    }

    #[test]
    fn order_is_bounded_before_anything_is_allocated() {
        let e = fit_friction(&[0.0; 4], &[0.0; 4], usize::MAX / 2 + 1).unwrap_err();
        assert!(matches!(e, IdentificationError::Limit(_)), "{e}");
        assert!(e.to_string().contains("harmonic order"), "{e}");
    }

    #[test]
    fn blocks_give_the_single_factorisation_answer() {
        // More samples than one block: the block-updated factor must give the same fit as a small sample.
        let theta: Vec<f64> = (0..3 * BLOCK_ROWS + 17)
            .map(|i| i as f64 * 0.0137)
            .collect();
        let y: Vec<f64> = theta
            .iter()
            .map(|t| -1.5 + 0.7 * (2.0 * t).sin() + 0.2 * (5.0 * t).cos())
            .collect();
        let fit = fit_friction(&theta, &y, 5).unwrap();
        assert!((fit.c0 + 1.5).abs() < 1e-10);
        assert!((fit.a[1] - 0.7).abs() < 1e-10);
        assert!((fit.b[4] - 0.2).abs() < 1e-10);
        assert!(fit.rss < 1e-16 * y.len() as f64);
    }
}
