//! Angle-periodic seal friction (paper eq 21) with a current-dependent part:
//! `T_f(θ, I) = c0 + (1 + g·|I|)·Σ_{k=1..K} (a_k sin kθ + b_k cos kθ)` (N·mm).
//!
//! This is the one friction series of the library: the compensator's feedforward, the extended simulation, the
//! virtual actuator's seal friction, the identification's fitted model (`identification::FrictionFit::eval`) and
//! the Python friction models all evaluate it through [`harmonic_series`]. The sine/cosine form is linear in its coefficients (identified in
//! closed form by least squares); the paper's amplitude/phase form `c0 + Σ A_k sin(kθ + φ_k)` converts exactly:
//! `a_k = A_k cos φ_k`, `b_k = A_k sin φ_k`. `g` (1/A, the `friction_current` effect) is 0 in the paper's model.
use core::fmt;

/// Highest harmonic order supported by the fixed-size friction model.
pub const MAX_ORDER: usize = crate::vocabulary::MAX_HARMONIC;

/// Largest `|c0| + Σ |a_k| + |b_k|` accepted (N·mm): every evaluation of the series (and of its
/// recurrence, whose rotated terms stay bounded by the coefficients) is then finite. Far above any physical friction.
pub const MAX_MAGNITUDE: f64 = 1e300;

/// `Σ_{k=1..n} a_k sin kθ + b_k cos kθ` from `sin θ` and `cos θ` (higher harmonics by the angle-addition
/// recurrence; `n` = the shorter length). NaN in, NaN out. Accuracy with [`crate::trig::sincos`] over θ in
/// [0, 2π), measured against libm's `sin kθ`, `cos kθ` (whose own rounding of `kθ` is most of it): at most
/// 1.1e-16 for k = 1, 2.2e-15 for k = 3, 1.7e-14 for k = 24, per unit of amplitude (tested).
#[inline(always)]
pub fn harmonic_series(a: &[f64], b: &[f64], sin1: f64, cos1: f64) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let (mut s, mut c) = (sin1, cos1);
    let mut t = 0.0;
    let mut k = 0;
    while k < n {
        t += a[k] * s + b[k] * c;
        k += 1;
        // The last harmonic's rotation would go unused.
        if k == n {
            break;
        }
        let s_next = s * cos1 + c * sin1;
        c = c * cos1 - s * sin1;
        s = s_next;
    }
    t
}

/// Why a friction model was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrictionError {
    /// More harmonics than the model holds.
    TooManyHarmonics { given: usize, max: usize },
    /// Amplitude and phase lists of different lengths.
    LengthMismatch { amplitudes: usize, phases: usize },
    /// A coefficient (or the current gain) is NaN or infinite.
    NonFinite,
    /// `|c0| + Σ |a_k| + |b_k|` exceeds [`MAX_MAGNITUDE`]: the series could overflow.
    TooLarge { sum: f64 },
    /// A harmonic order outside `1..=K`.
    Order { order: usize, max: usize },
}

impl fmt::Display for FrictionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            FrictionError::TooManyHarmonics { given, max } => write!(
                f,
                "friction: {given} harmonics given, at most {max} are supported"
            ),
            FrictionError::LengthMismatch { amplitudes, phases } => write!(
                f,
                "friction: {amplitudes} amplitudes but {phases} phases (one per harmonic)"
            ),
            FrictionError::NonFinite => f.write_str("friction: coefficients must be finite"),
            FrictionError::TooLarge { sum } => write!(
                f,
                "friction: |c0| + Σ|a_k| + |b_k| = {sum:e} N·mm exceeds {MAX_MAGNITUDE:e}: the series could not \
                 be evaluated finitely"
            ),
            FrictionError::Order { order, max } => {
                write!(f, "friction: harmonic order {order} is outside 1..={max}")
            }
        }
    }
}

/// The angle-dependent part of one evaluation (one `sincos`): reused by the torque-ripple stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AngleTerms {
    pub sin1: f64,
    pub cos1: f64,
    /// `Σ a_k sin kθ + b_k cos kθ` (N·mm).
    pub harmonics_nmm: f64,
}

/// Friction model with up to `K` harmonics and a current-dependent part, fixed-size (no allocation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Friction<const K: usize> {
    c0: f64,
    a: [f64; K],
    b: [f64; K],
    /// Highest non-zero harmonic: `eval` stops there.
    order: usize,
    /// Relative growth of the angle-dependent part per ampere of |I| (1/A).
    gain_per_a: f64,
}

impl<const K: usize> Friction<K> {
    /// No friction.
    pub const fn zero() -> Self {
        Friction {
            c0: 0.0,
            a: [0.0; K],
            b: [0.0; K],
            order: 0,
            gain_per_a: 0.0,
        }
    }

    /// From sine/cosine coefficients of harmonics `1..` (missing ones are zero).
    pub fn from_coefficients(c0: f64, a: &[f64], b: &[f64]) -> Result<Self, FrictionError> {
        let given = a.len().max(b.len());
        if given > K {
            return Err(FrictionError::TooManyHarmonics { given, max: K });
        }
        let mut f = Self::zero();
        f.c0 = c0;
        f.a[..a.len()].copy_from_slice(a);
        f.b[..b.len()].copy_from_slice(b);
        f.checked()
    }

    /// From the paper's amplitude/phase form `c0 + Σ A_k sin(kθ + φ_k)`.
    pub fn from_amplitude_phase(
        c0: f64,
        amplitude: &[f64],
        phase: &[f64],
    ) -> Result<Self, FrictionError> {
        if amplitude.len() != phase.len() {
            return Err(FrictionError::LengthMismatch {
                amplitudes: amplitude.len(),
                phases: phase.len(),
            });
        }
        if amplitude.len() > K {
            return Err(FrictionError::TooManyHarmonics {
                given: amplitude.len(),
                max: K,
            });
        }
        let mut f = Self::zero();
        f.c0 = c0;
        for k in 0..amplitude.len() {
            f.a[k] = amplitude[k] * libm::cos(phase[k]);
            f.b[k] = amplitude[k] * libm::sin(phase[k]);
        }
        f.checked()
    }

    /// This model plus `amplitude·sin(order·θ + phase)` (the `friction_harmonics` effect).
    pub fn with_harmonic(
        mut self,
        order: usize,
        amplitude_nmm: f64,
        phase_rad: f64,
    ) -> Result<Self, FrictionError> {
        if order == 0 || order > K {
            return Err(FrictionError::Order { order, max: K });
        }
        self.a[order - 1] += amplitude_nmm * libm::cos(phase_rad);
        self.b[order - 1] += amplitude_nmm * libm::sin(phase_rad);
        self.checked()
    }

    /// This model with its angle-dependent part growing by `gain_per_a` per ampere of |I| (the `friction_current`
    /// effect).
    pub fn with_current_gain(mut self, gain_per_a: f64) -> Result<Self, FrictionError> {
        self.gain_per_a = gain_per_a;
        self.checked()
    }

    fn checked(mut self) -> Result<Self, FrictionError> {
        let all = || core::iter::once(&self.c0).chain(&self.a).chain(&self.b);
        if !self.gain_per_a.is_finite() || all().any(|x| !x.is_finite()) {
            return Err(FrictionError::NonFinite);
        }
        let sum: f64 = all().map(|x| x.abs()).sum();
        if sum.is_nan() || sum > MAX_MAGNITUDE {
            return Err(FrictionError::TooLarge { sum });
        }
        self.order = (0..K)
            .rev()
            .find(|&k| self.a[k] != 0.0 || self.b[k] != 0.0)
            .map_or(0, |k| k + 1);
        Ok(self)
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
    /// Sine coefficients of harmonics `1..=order` (N·mm).
    pub fn a(&self) -> &[f64] {
        &self.a[..self.order]
    }
    /// Cosine coefficients of harmonics `1..=order` (N·mm).
    pub fn b(&self) -> &[f64] {
        &self.b[..self.order]
    }
    /// Growth of the angle-dependent part per ampere of |I| (1/A).
    pub fn gain_per_a(&self) -> f64 {
        self.gain_per_a
    }
    /// `|c0| + Σ|a_k| + |b_k|` (N·mm): a bound on `|T_f|` at zero current.
    pub fn magnitude(&self) -> f64 {
        self.c0.abs()
            + self
                .a()
                .iter()
                .chain(self.b())
                .map(|x| x.abs())
                .sum::<f64>()
    }

    /// The angle-dependent part at `theta` (rad): one `sincos`.
    #[inline(always)]
    pub fn angle_terms(&self, theta: f64) -> AngleTerms {
        self.angle_terms_from(crate::trig::sincos(theta))
    }

    /// The angle-dependent part from `(sin θ, cos θ)` already computed (a loop that owns the angle shares one
    /// `sincos` between the plant and the compensator).
    #[inline(always)]
    pub fn angle_terms_from(&self, (sin1, cos1): (f64, f64)) -> AngleTerms {
        let n = self.order.min(K);
        AngleTerms {
            sin1,
            cos1,
            harmonics_nmm: harmonic_series(&self.a[..n], &self.b[..n], sin1, cos1),
        }
    }

    /// Friction torque (N·mm) from the angle terms at current `current_a` (A).
    #[inline]
    pub fn with_terms(&self, terms: &AngleTerms, current_a: f64) -> f64 {
        self.c0 + terms.harmonics_nmm * (1.0 + self.gain_per_a * current_a.abs())
    }

    /// Friction torque at rotor angle `theta` (rad) and zero current. NaN in, NaN out.
    #[inline]
    pub fn eval(&self, theta: f64) -> f64 {
        if self.order == 0 {
            return self.c0;
        }
        let t = self.angle_terms(theta);
        self.c0 + t.harmonics_nmm
    }

    /// [`Self::eval`] from `(sin θ, cos θ)` already computed.
    #[inline]
    pub fn eval_from(&self, sincos: (f64, f64)) -> f64 {
        if self.order == 0 {
            return self.c0;
        }
        self.c0 + self.angle_terms_from(sincos).harmonics_nmm
    }

    /// Friction torque at rotor angle `theta` (rad) and current `current_a` (A).
    #[inline]
    pub fn eval_at(&self, theta: f64, current_a: f64) -> f64 {
        if self.order == 0 {
            return self.c0;
        }
        let t = self.angle_terms(theta);
        self.with_terms(&t, current_a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    /// The accuracy documented on [`harmonic_series`]: `sin kθ`, `cos kθ` of the recurrence against libm's over
    /// one turn (where the plants' and the compensators' angles lie), per unit amplitude.
    #[test]
    fn the_recurrence_stays_within_its_documented_deviation_from_libm() {
        let n = 100_000;
        let mut worst = [0.0f64; MAX_ORDER + 1];
        for i in 0..n {
            let x = core::f64::consts::TAU * (i as f64 + 0.37) / n as f64;
            let (s1, c1) = crate::trig::sincos(x);
            let (mut s, mut c) = (s1, c1);
            for (k, w) in worst.iter_mut().enumerate().skip(1) {
                let kx = k as f64 * x;
                *w = w
                    .max((s - libm::sin(kx)).abs())
                    .max((c - libm::cos(kx)).abs());
                let s_next = s * c1 + c * s1;
                c = c * c1 - s * s1;
                s = s_next;
            }
        }
        assert!(worst[1] <= 2.3e-16, "sincos: {:e}", worst[1]);
        for (k, &w) in worst.iter().enumerate().skip(1) {
            assert!(w <= 1e-15 * (k + 1) as f64, "harmonic {k}: {w:e}");
        }
        assert!(
            worst[MAX_ORDER] > 1e-16,
            "the reference is not libm's own recurrence"
        );
    }

    #[test]
    fn the_series_matches_the_direct_sum() {
        let a = [3.0, -1.5, 0.25, 0.0, 2.0, 0.7];
        let b = [0.5, 2.5, -0.75, 1.0, 0.0, -0.3];
        for i in 0..2000 {
            let th = -7.0 + 0.00731 * i as f64;
            let direct: f64 = (0..6)
                .map(|k| {
                    let x = (k + 1) as f64 * th;
                    a[k] * libm::sin(x) + b[k] * libm::cos(x)
                })
                .sum();
            let (s, c) = crate::trig::sincos(th);
            let cl = harmonic_series(&a, &b, s, c);
            assert!((cl - direct).abs() < 1e-12, "θ={th}: {cl} vs {direct}");
        }
        assert_eq!(harmonic_series(&[], &[], 0.3, 0.9), 0.0);
    }

    #[test]
    fn sums_that_cannot_be_evaluated_finitely_are_refused() {
        let e = Friction::<3>::from_coefficients(
            0.0,
            &[1.7e308, 0.0, -1.7e308],
            &[1.7e308, 0.0, 1.7e308],
        );
        assert!(matches!(e, Err(FrictionError::TooLarge { .. })), "{e:?}");
        assert_eq!(
            Friction::<2>::from_coefficients(0.0, &[1.0; 3], &[]),
            Err(FrictionError::TooManyHarmonics { given: 3, max: 2 })
        );
        assert_eq!(
            Friction::<2>::from_coefficients(f64::NAN, &[], &[]),
            Err(FrictionError::NonFinite)
        );
        let f = Friction::<4>::from_coefficients(1.0, &[1.0], &[]).unwrap();
        assert!(f.with_harmonic(5, 1.0, 0.0).is_err());
        let g = f.with_harmonic(4, 2.0, 0.5).unwrap();
        assert_eq!(g.order(), 4);
        let th = 0.3;
        let want = 1.0 + libm::sin(th) + 2.0 * libm::sin(4.0 * th + 0.5);
        assert!((g.eval(th) - want).abs() < 1e-12);
        let h = g.with_current_gain(0.5).unwrap();
        assert!((h.eval_at(th, -2.0) - (1.0 + 2.0 * (want - 1.0))).abs() < 1e-12);
    }
}
