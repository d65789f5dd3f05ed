//! Angle-periodic seal friction (paper eq 21): `T_f(θ) = c0 + Σ_{k=1..K} a_k sin kθ + b_k cos kθ` (N·mm).
//!
//! The sine/cosine form is linear in its coefficients (identified in closed form by least squares); the paper's
//! amplitude/phase form `c0 + Σ A_k sin(kθ + φ_k)` converts exactly: `a_k = A_k cos φ_k`, `b_k = A_k sin φ_k`.
use nalgebra::SVector;

use crate::limits::MAX_MAGNITUDE;

/// Highest harmonic order supported by the fixed-size friction model.
pub const MAX_ORDER: usize = 12;

/// Friction model with up to `K` harmonics, fixed-size (no allocation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Friction<const K: usize> {
    c0: f64,
    a: SVector<f64, K>,
    b: SVector<f64, K>,
    /// Highest non-zero harmonic: `eval` stops there.
    order: usize,
}

impl<const K: usize> Friction<K> {
    /// No friction.
    pub fn zero() -> Self {
        Friction {
            c0: 0.0,
            a: SVector::zeros(),
            b: SVector::zeros(),
            order: 0,
        }
    }

    /// From sine/cosine coefficients; missing harmonics are zero. `None` if more than `K` are given, any value is
    /// not finite or the largest torque the model can give, `|c0| + Σ |a_k| + |b_k|`, exceeds
    /// [`MAX_MAGNITUDE`] (so that every evaluation, and a reference minus it, is finite).
    pub fn from_coefficients(c0: f64, a: &[f64], b: &[f64]) -> Option<Self> {
        if a.len() > K || b.len() > K {
            return None;
        }
        let bound = a.iter().chain(b).fold(c0.abs(), |t, x| t + x.abs());
        if bound.is_nan() || bound > MAX_MAGNITUDE {
            return None;
        }
        let mut f = Self::zero();
        f.c0 = c0;
        f.a.as_mut_slice()[..a.len()].copy_from_slice(a);
        f.b.as_mut_slice()[..b.len()].copy_from_slice(b);
        f.order = (0..K)
            .rev()
            .find(|&k| f.a[k] != 0.0 || f.b[k] != 0.0)
            .map_or(0, |k| k + 1);
        Some(f)
    }

    /// From the paper's amplitude/phase form `c0 + Σ A_k sin(kθ + φ_k)`.
    pub fn from_amplitude_phase(c0: f64, amplitude: &[f64], phase: &[f64]) -> Option<Self> {
        if amplitude.len() != phase.len() || amplitude.len() > K {
            return None;
        }
        let mut a = [0.0; K];
        let mut b = [0.0; K];
        for k in 0..amplitude.len() {
            a[k] = amplitude[k] * libm::cos(phase[k]);
            b[k] = amplitude[k] * libm::sin(phase[k]);
        }
        Self::from_coefficients(c0, &a[..amplitude.len()], &b[..amplitude.len()])
    }

    /// Amplitude `A_k` and phase `φ_k` (rad, in (-π, π]) of harmonic `k` (1-based).
    pub fn amplitude_phase(&self, k: usize) -> (f64, f64) {
        let (a, b) = (self.a[k - 1], self.b[k - 1]);
        (libm::hypot(a, b), libm::atan2(b, a))
    }

    /// Highest harmonic with a non-zero coefficient.
    pub fn order(&self) -> usize {
        self.order
    }
    /// Constant term (N·mm).
    pub fn c0(&self) -> f64 {
        self.c0
    }
    /// Sine coefficients of harmonics 1..=K (N·mm).
    pub fn a(&self) -> &SVector<f64, K> {
        &self.a
    }
    /// Cosine coefficients of harmonics 1..=K (N·mm).
    pub fn b(&self) -> &SVector<f64, K> {
        &self.b
    }

    /// Friction torque at rotor angle `theta` (rad). One `sincos` call; higher harmonics by the angle-addition
    /// recurrence. NaN in, NaN out.
    #[inline]
    pub fn eval(&self, theta: f64) -> f64 {
        if self.order == 0 {
            return self.c0;
        }
        let (s1, c1) = crate::trig::sincos(theta);
        let (mut s, mut c) = (s1, c1);
        let mut t = self.c0;
        for k in 0..self.order.min(K) {
            t += self.a[k] * s + self.b[k] * c;
            let s_next = s * c1 + c * s1;
            c = c * c1 - s * s1;
            s = s_next;
        }
        t
    }
}
