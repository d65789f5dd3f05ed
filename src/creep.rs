//! Creep: after every change of the output (a reversal, a step, the start of a dwell) part of the change keeps
//! coming for a long time — the magnetic after-effect of steel (thermally activated domain-wall jumps), the creep
//! of a piezo stack (slow domain reorientation).
//!
//! Model (a linear relaxation operator after the hysteretic core, as in Kuhnen's creep operator): the core's
//! output `v` is the equilibrium the output relaxes to; a share `fraction` of every change arrives through a
//! spectrum of first-order relaxations,
//!
//! `y = v + fraction · Σᵢ wᵢ (xᵢ − v)`,  `xᵢ' = (v − xᵢ)/τᵢ`,  `Σᵢ wᵢ = 1`,
//!
//! so after a step `Δ` of `v` held from `t = 0`, `y(t) = v − fraction·Δ·Σᵢ wᵢ e^{−t/τᵢ}`. Equal weights on time
//! constants spaced evenly in `log τ` between `tau_min_s` and `tau_max_s` make the relaxation logarithmic in
//! time between them (`fraction / decades` of the step per decade of time, the classic `1 + γ log t` law); one
//! time constant is a single exponential. Each relaxation is sampled exactly for a held input (zero-order hold).
//!
//! `no_std`, allocation-free, fixed sample period; the inverse ([`Creep::input_for`]) gives the core output that
//! produces a wanted output this sample, so a compensator can undo creep before the hysteresis inverse.

use crate::filters::Lag;

/// Most relaxation terms of one creep operator.
pub const MAX_CREEP_TERMS: usize = 16;

/// Time constants per decade of a log-uniform creep spectrum.
pub const CREEP_TERMS_PER_DECADE: f64 = 3.0;

/// Time constants (s) spaced evenly in `log τ` from `tau_min_s` to `tau_max_s` (both included, three per decade,
/// at most [`MAX_CREEP_TERMS`]), written into `out`; returns how many. One when the two are equal. `None` unless
/// `0 < tau_min_s ≤ tau_max_s` (finite).
pub fn log_uniform_taus(
    tau_min_s: f64,
    tau_max_s: f64,
    out: &mut [f64; MAX_CREEP_TERMS],
) -> Option<usize> {
    if !(tau_min_s > 0.0 && tau_max_s >= tau_min_s && tau_max_s.is_finite()) {
        return None;
    }
    let decades = libm::log10(tau_max_s / tau_min_s);
    let n = ((libm::ceil(decades * CREEP_TERMS_PER_DECADE) as usize) + 1).clamp(1, MAX_CREEP_TERMS);
    if n == 1 {
        out[0] = tau_min_s;
        return Some(1);
    }
    for (i, slot) in out.iter_mut().take(n).enumerate() {
        let f = i as f64 / (n - 1) as f64;
        *slot = tau_min_s * libm::pow(tau_max_s / tau_min_s, f);
    }
    Some(n)
}

/// The creep operator (see the module doc). Construct, then [`Creep::step`] once per sample with the core output.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Creep {
    fraction: f64,
    n: usize,
    weight: [f64; MAX_CREEP_TERMS],
    relax: [Lag; MAX_CREEP_TERMS],
}

impl Creep {
    /// Log-uniform spectrum between `tau_min_s` and `tau_max_s` (equal weights), `fraction` in `[0, 1)`, sample
    /// period `dt_s` (> 0), at rest at output `y0`. `None` for invalid arguments.
    pub fn log_uniform(
        fraction: f64,
        tau_min_s: f64,
        tau_max_s: f64,
        dt_s: f64,
        y0: f64,
    ) -> Option<Self> {
        let mut taus = [0.0; MAX_CREEP_TERMS];
        let n = log_uniform_taus(tau_min_s, tau_max_s, &mut taus)?;
        let weights = [1.0 / n as f64; MAX_CREEP_TERMS];
        Creep::with_spectrum(fraction, &taus[..n], &weights[..n], dt_s, y0)
    }

    /// Any spectrum: time constants `taus_s` (> 0) with nonnegative `weights` (normalised here; their sum must be
    /// positive), at most [`MAX_CREEP_TERMS`]. `None` for invalid arguments.
    pub fn with_spectrum(
        fraction: f64,
        taus_s: &[f64],
        weights: &[f64],
        dt_s: f64,
        y0: f64,
    ) -> Option<Self> {
        let n = taus_s.len();
        let valid = (0.0..1.0).contains(&fraction)
            && dt_s > 0.0
            && dt_s.is_finite()
            && y0.is_finite()
            && (1..=MAX_CREEP_TERMS).contains(&n)
            && weights.len() == n
            && taus_s.iter().all(|t| *t > 0.0 && t.is_finite())
            && weights.iter().all(|w| *w >= 0.0 && w.is_finite());
        let total: f64 = weights.iter().sum();
        if !valid || total <= 0.0 {
            return None;
        }
        let mut c = Creep {
            fraction,
            n,
            weight: [0.0; MAX_CREEP_TERMS],
            relax: [Lag::new(0.0, dt_s, y0); MAX_CREEP_TERMS],
        };
        for i in 0..n {
            c.weight[i] = weights[i] / total;
            c.relax[i] = Lag::new(taus_s[i], dt_s, y0);
        }
        Some(c)
    }

    /// Share of every change that arrives by relaxation.
    pub fn fraction(&self) -> f64 {
        self.fraction
    }

    /// Number of relaxation terms.
    pub fn terms(&self) -> usize {
        self.n
    }

    /// The relaxations' states (the unused tail is zero), for saving a state.
    pub fn states(&self) -> [f64; MAX_CREEP_TERMS] {
        let mut out = [0.0; MAX_CREEP_TERMS];
        for (o, r) in out.iter_mut().zip(&self.relax).take(self.n) {
            *o = r.output();
        }
        out
    }

    /// Restore the relaxations' states written by [`Creep::states`] (`false`, nothing changed, if one is not
    /// finite).
    pub fn set_states(&mut self, states: &[f64; MAX_CREEP_TERMS]) -> bool {
        if !states.iter().all(|x| x.is_finite()) {
            return false;
        }
        for (r, &v) in self.relax.iter_mut().zip(states).take(self.n) {
            r.set_output(v);
        }
        true
    }

    /// Back to rest at `y0` (every relaxation settled).
    pub fn reset(&mut self, y0: f64) {
        self.relax.iter_mut().for_each(|r| r.set_output(y0));
    }

    /// Let every relaxation run for `duration_s` with the core output held at `v` (a rest between runs).
    pub fn hold(&mut self, v: f64, duration_s: f64, dt_s: f64) {
        if duration_s.is_nan() || duration_s <= 0.0 {
            return;
        }
        let periods = duration_s / dt_s;
        for r in self.relax.iter_mut().take(self.n) {
            let p = libm::pow(r.pole(), periods);
            r.set_output(p * r.output() + (1.0 - p) * v);
        }
    }

    /// One sample: core output `v` held over this period → output at its end.
    #[inline]
    pub fn step(&mut self, v: f64) -> f64 {
        v + self.fraction * self.relaxation(v)
    }

    /// One sample of the spectrum alone: `Σᵢ wᵢ (xᵢ − v)`, what [`Creep::step`] adds per unit `fraction`.
    #[inline]
    pub fn relaxation(&mut self, v: f64) -> f64 {
        let mut lagged = 0.0;
        for i in 0..self.n {
            lagged += self.weight[i] * (self.relax[i].step(v) - v);
        }
        lagged
    }

    /// The core output `v` that makes [`Creep::step`] return `y` this sample (the inverse), without changing the
    /// state. `y = v·(1 − γ Σ wᵢpᵢ) + γ Σ wᵢpᵢxᵢ` with `γ = fraction < 1`, so the division is safe.
    #[inline]
    pub fn input_for(&self, y: f64) -> f64 {
        let mut wp = 0.0;
        let mut wpx = 0.0;
        for i in 0..self.n {
            let a = self.weight[i] * self.relax[i].pole();
            wp += a;
            wpx += a * self.relax[i].output();
        }
        (y - self.fraction * wpx) / (1.0 - self.fraction * wp)
    }
}

/// The relaxation signal of a core output `v` over an equal-weight spectrum: `out[i]` is the mean over
/// `taus_s` of `xⱼ − v[i]`, `xⱼ` the exact first-order lag of `v` from rest at `v[0]` — the column a diagnosis
/// fits the creep fraction on (creep output `v + fraction·out`, [`Creep::relaxation`] sample by sample).
/// `false` (nothing written) when the sizes differ, `dt_s` is not positive, or `taus_s` is empty, longer than
/// [`MAX_CREEP_TERMS`] or holds a time constant that is not positive and finite.
pub fn mean_relaxation(v: &[f64], taus_s: &[f64], dt_s: f64, out: &mut [f64]) -> bool {
    let m = taus_s.len();
    if out.len() != v.len() || m > MAX_CREEP_TERMS {
        return false;
    }
    let equal = [1.0; MAX_CREEP_TERMS];
    let v0 = v.first().copied().unwrap_or(0.0);
    let Some(mut c) = Creep::with_spectrum(0.0, taus_s, &equal[..m], dt_s, v0) else {
        return false;
    };
    for (o, &vi) in out.iter_mut().zip(v) {
        *o = c.relaxation(vi);
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_term_is_an_exponential_approach() {
        let dt = 1e-3;
        let mut c = Creep::log_uniform(0.2, 0.5, 0.5, dt, 0.0).unwrap();
        assert_eq!(c.terms(), 1);
        for n in 1..3000 {
            let y = c.step(1.0);
            let exact = 1.0 - 0.2 * libm::exp(-(n as f64) * dt / 0.5);
            assert!((y - exact).abs() < 1e-12, "n={n}: {y} vs {exact}");
        }
    }

    #[test]
    fn log_uniform_spectrum_creeps_logarithmically_between_its_time_constants() {
        let dt = 1e-2;
        let (fraction, lo, hi) = (0.3, 0.01, 10_000.0);
        let mut c = Creep::log_uniform(fraction, lo, hi, dt, 0.0).unwrap();
        assert_eq!(c.terms(), 16);
        let mut y = [0.0; 3];
        let marks = [100usize, 1_000, 10_000]; // 1, 10, 100 s: decades well inside the spectrum
        let mut k = 0;
        for n in 1..=10_000usize {
            let v = c.step(1.0);
            if n == marks[k] {
                y[k] = v;
                k += 1;
            }
        }
        // Equal increments per decade of time: fraction / 6 decades.
        let per_decade = fraction / 6.0;
        for w in y.windows(2) {
            assert!(
                ((w[1] - w[0]) - per_decade).abs() < 0.1 * per_decade,
                "{y:?}"
            );
        }
    }

    #[test]
    fn inverse_undoes_the_operator() {
        let dt = 2e-3;
        let mut fwd = Creep::log_uniform(0.1, 0.05, 50.0, dt, 0.3).unwrap();
        let mut inv_state = fwd;
        for n in 0..5000 {
            let target = libm::sin(0.01 * n as f64) + 0.2 * libm::sin(0.13 * n as f64);
            let v = inv_state.input_for(target);
            let y = inv_state.step(v);
            assert!((y - target).abs() < 1e-12);
            assert!((fwd.step(v) - target).abs() < 1e-12);
        }
    }

    #[test]
    fn invalid_arguments_are_refused() {
        assert!(Creep::log_uniform(1.0, 0.1, 1.0, 1e-3, 0.0).is_none());
        assert!(Creep::log_uniform(0.1, 0.0, 1.0, 1e-3, 0.0).is_none());
        assert!(Creep::log_uniform(0.1, 2.0, 1.0, 1e-3, 0.0).is_none());
        assert!(Creep::log_uniform(0.1, 0.1, 1.0, 0.0, 0.0).is_none());
        assert!(Creep::with_spectrum(0.1, &[1.0], &[0.0], 1e-3, 0.0).is_none());
        let mut taus = [0.0; MAX_CREEP_TERMS];
        assert_eq!(
            log_uniform_taus(1e-6, 1e6, &mut taus),
            Some(MAX_CREEP_TERMS)
        );
    }

    #[test]
    fn mean_relaxation_is_the_operator_per_unit_fraction() {
        let dt = 1e-2;
        let v: [f64; 50] = core::array::from_fn(|i| libm::sin(0.2 * i as f64));
        let mut out = [0.0; 50];
        assert!(mean_relaxation(&v, &[0.1, 1.0], dt, &mut out));
        let mut c = Creep::with_spectrum(0.5, &[0.1, 1.0], &[1.0, 1.0], dt, v[0]).unwrap();
        for (i, &vi) in v.iter().enumerate() {
            assert!((c.step(vi) - (vi + 0.5 * out[i])).abs() < 1e-12);
        }
        assert!(!mean_relaxation(&v, &[0.0], dt, &mut out));
        assert!(!mean_relaxation(&v, &[], dt, &mut out));
        assert!(!mean_relaxation(&v, &[1.0], dt, &mut out[..49]));
        assert!(!mean_relaxation(
            &v,
            &[1.0; MAX_CREEP_TERMS + 1],
            dt,
            &mut out
        ));
    }

    #[test]
    fn hold_matches_stepping() {
        let dt = 1e-3;
        let mut a = Creep::log_uniform(0.2, 0.01, 1.0, dt, 0.0).unwrap();
        let mut b = a;
        for _ in 0..500 {
            a.step(1.0);
        }
        b.hold(1.0, 0.5, dt);
        assert!((a.step(1.0) - b.step(1.0)).abs() < 1e-12);
    }
}
