//! Least-squares fit of the angle-dependent seal friction (paper eq 22):
//! `T_f(θ) = c0 + Σ_{k=1..K} a_k sin kθ + b_k cos kθ`, linear in its `2K + 1` coefficients.
//!
//! Solved with a QR factorisation (faer); the coefficient covariance is `σ² (XᵀX)⁻¹` with `σ²` the residual
//! variance `RSS / (n − p)`, obtained from the triangular factor `R` (`(XᵀX)⁻¹ = R⁻¹ R⁻ᵀ`).
use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

use faer::Mat;
use faer::prelude::SolveLstsq;

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

/// Fit `c0 + Σ a_k sin kθ + b_k cos kθ` of order `order` to `(theta_rad, torque_nmm)` by least squares.
///
/// Errors (as text) when lengths differ, values are not finite, or there are too few samples or too little
/// angle coverage for the requested order (the regressors would be rank deficient).
pub fn fit_friction(
    theta_rad: &[f64],
    torque_nmm: &[f64],
    order: usize,
) -> Result<FrictionFit, String> {
    let n = theta_rad.len();
    if torque_nmm.len() != n {
        return Err(format!(
            "theta has {} samples but torque has {}",
            n,
            torque_nmm.len()
        ));
    }
    if let Some(i) = theta_rad.iter().position(|v| !v.is_finite()) {
        return Err(format!("theta sample {i} is not finite ({})", theta_rad[i]));
    }
    if let Some(i) = torque_nmm.iter().position(|v| !v.is_finite()) {
        return Err(format!(
            "torque sample {i} is not finite ({})",
            torque_nmm[i]
        ));
    }
    let p = 2 * order + 1;
    if n <= p {
        return Err(format!(
            "friction order {order} needs more than {p} samples, got {n}"
        ));
    }
    let x = Mat::<f64>::from_fn(n, p, |i, j| regressor(theta_rad[i], j));
    let y = Mat::<f64>::from_fn(n, 1, |i, _| torque_nmm[i]);
    let qr = x.qr();
    let r = qr.thin_R();
    // Rank check: a tiny diagonal of R means the angles do not excite some harmonic.
    let rmax = (0..p).map(|i| r[(i, i)].abs()).fold(0.0, f64::max);
    for i in 0..p {
        let d = r[(i, i)].abs();
        if d.is_nan() || d <= 1e-9 * rmax.max(f64::MIN_POSITIVE) {
            return Err(format!(
                "friction order {order}: the angle samples do not determine coefficient {} \
                 (too little angle coverage); lower the order or use a run covering full revolutions",
                coefficient_name(i)
            ));
        }
    }
    let coef = qr.solve_lstsq(&y);
    let mut rss = 0.0;
    for i in 0..n {
        let mut f = 0.0;
        for j in 0..p {
            f += x[(i, j)] * coef[(j, 0)];
        }
        let e = torque_nmm[i] - f;
        rss += e * e;
    }
    let sigma2 = rss / (n - p) as f64;
    // R⁻¹ by back substitution (upper triangular p × p), then (XᵀX)⁻¹ = R⁻¹ R⁻ᵀ.
    let mut rinv = alloc::vec![0.0; p * p];
    for col in 0..p {
        for row in (0..=col).rev() {
            let mut s = if row == col { 1.0 } else { 0.0 };
            for k in row + 1..=col {
                s -= r[(row, k)] * rinv[k * p + col];
            }
            rinv[row * p + col] = s / r[(row, row)];
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
        c0: coef[(0, 0)],
        a: (0..order).map(|k| coef[(1 + 2 * k, 0)]).collect(),
        b: (0..order).map(|k| coef[(2 + 2 * k, 0)]).collect(),
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

fn coefficient_name(j: usize) -> String {
    if j == 0 {
        return String::from("c0");
    }
    let k = j.div_ceil(2);
    if j % 2 == 1 {
        format!("a_{k}")
    } else {
        format!("b_{k}")
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
}
