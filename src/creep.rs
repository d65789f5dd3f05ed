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
//! A second, unbounded form acts on the core's input: the magnetic viscosity of thermally activated switching over
//! a flat spectrum of barrier energies (Néel's fluctuation field, [`FluctuationField`]). The core's input is pushed
//! the way it last moved by `S_v · ln(1 + t/τ₀)` (`S_v` the fluctuation field in input units per e-fold of time,
//! `t` the time since the input last turned, `τ₀` the onset of the log law), so the output moves by the branch's
//! irreversible susceptibility times it (the magnetic viscosity `S = χ_irr · S_v`): it never settles within a run,
//! stops where the branch is saturated, and starts again from zero when the input turns.
//!
//! `no_std`, allocation-free, fixed sample period; the inverse ([`Creep::input_for`]) gives the core output that
//! produces a wanted output this sample, so a compensator can undo creep before the hysteresis inverse, and
//! [`Creep::applied_input_for`] the input that gives a wanted core input after it.

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

/// Words of a [`FluctuationField`]'s state ([`FluctuationField::state`]).
pub const FLUCTUATION_STATE: usize = 3;

/// The thermal fluctuation field of the log-time after-effect (see the module doc): the core input is the applied
/// input `u` plus `S_v · d · ln(1 + t/τ₀)`, `d` = ±1 the way `u` last moved (an unchanged input keeps it), `t` the
/// time since it turned (the sample it turns in adds nothing).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FluctuationField {
    field: f64,
    tau0_s: f64,
    dt_s: f64,
    /// The way the input last moved (±1; 0 before it first moved).
    direction: f64,
    /// Time since it last turned (s).
    since_s: f64,
    last_u: f64,
}

impl FluctuationField {
    /// Field `field` (input units per e-fold of time, ≥ 0), onset `tau0_s` (> 0), sample period `dt_s` (> 0), at
    /// rest at input `u0`. `None` for invalid arguments.
    pub fn new(field: f64, tau0_s: f64, dt_s: f64, u0: f64) -> Option<Self> {
        let valid = field >= 0.0
            && field.is_finite()
            && tau0_s > 0.0
            && tau0_s.is_finite()
            && dt_s > 0.0
            && dt_s.is_finite()
            && u0.is_finite();
        valid.then_some(FluctuationField {
            field,
            tau0_s,
            dt_s,
            direction: 0.0,
            since_s: 0.0,
            last_u: u0,
        })
    }

    /// The fluctuation field (input units per e-fold of time).
    pub fn field(&self) -> f64 {
        self.field
    }

    /// The onset of the log law (s).
    pub fn tau0_s(&self) -> f64 {
        self.tau0_s
    }

    /// At rest at input `u0`: no direction yet, nothing added.
    pub fn reset(&mut self, u0: f64) {
        (self.direction, self.since_s, self.last_u) = (0.0, 0.0, u0);
    }

    /// `(direction, time since it turned (s), last input)`.
    pub fn state(&self) -> [f64; FLUCTUATION_STATE] {
        [self.direction, self.since_s, self.last_u]
    }

    /// Restore a state written by [`FluctuationField::state`] (`false`, nothing changed, if it is not one).
    pub fn set_state(&mut self, s: &[f64; FLUCTUATION_STATE]) -> bool {
        let ok = s.iter().all(|x| x.is_finite())
            && (s[0] == 0.0 || libm::fabs(s[0]) == 1.0)
            && s[1] >= 0.0;
        if ok {
            (self.direction, self.since_s, self.last_u) = (s[0], s[1], s[2]);
        }
        ok
    }

    /// The way an input `u` this sample moves (the last direction when it does not).
    #[inline]
    fn direction_of(&self, u: f64) -> f64 {
        if u > self.last_u {
            1.0
        } else if u < self.last_u {
            -1.0
        } else {
            self.direction
        }
    }

    /// The field added this sample per unit `S_v` when the input moves the way `d`: the log of the time since the
    /// turn when it keeps its direction, nothing in the sample it turns.
    #[inline]
    fn unit_shift(&self, d: f64) -> f64 {
        if d == 0.0 || d != self.direction {
            return 0.0;
        }
        d * libm::log1p((self.since_s + self.dt_s) / self.tau0_s)
    }

    /// The core input an applied input `u` gives this sample, without changing the state.
    #[inline]
    pub fn peek(&self, u: f64) -> f64 {
        u + self.field * self.unit_shift(self.direction_of(u))
    }

    /// One sample: applied input `u` → the core input.
    #[inline]
    pub fn step(&mut self, u: f64) -> f64 {
        u + self.field * self.advance(u)
    }

    /// [`FluctuationField::step`]'s shift per unit field, advancing the state.
    #[inline]
    fn advance(&mut self, u: f64) -> f64 {
        let d = self.direction_of(u);
        let shift = self.unit_shift(d);
        if d != self.direction {
            (self.direction, self.since_s) = (d, 0.0);
        } else {
            self.since_s += self.dt_s;
        }
        self.last_u = u;
        shift
    }

    /// The applied input whose core input this sample is `h`, without changing the state: kept direction (the
    /// clock running on) or turned (the field starting again from zero), whichever is consistent. Between the two
    /// (a core input the sample cannot reach: the field drops as the input turns) the input is held, the core input
    /// then past `h` by less than this sample's field.
    #[inline]
    pub fn input_for(&self, h: f64) -> f64 {
        let d = self.direction;
        let kept = h - self.field * self.unit_shift(d);
        if d == 0.0 || (kept - self.last_u) * d >= 0.0 {
            return kept;
        }
        if (h - self.last_u) * d < 0.0 {
            return h;
        }
        self.last_u
    }
}

/// The fluctuation field's shift per unit `S_v` along an applied input `u` sampled every `dt_s` from rest at
/// `u[0]` (`out[i]`: what [`FluctuationField::step`] adds per unit field: the last direction times the log of the
/// time since the input turned). `false` (nothing written) when the sizes differ or `tau0_s`, `dt_s` are not
/// positive and finite.
pub fn fluctuation_shift(u: &[f64], tau0_s: f64, dt_s: f64, out: &mut [f64]) -> bool {
    if out.len() != u.len() {
        return false;
    }
    let Some(mut f) = FluctuationField::new(1.0, tau0_s, dt_s, u.first().copied().unwrap_or(0.0))
    else {
        return false;
    };
    for (o, &ui) in out.iter_mut().zip(u) {
        *o = f.advance(ui);
    }
    true
}

/// The creep operator (see the module doc). Construct, then [`Creep::step`] once per sample with the core output
/// (and [`Creep::core_input`] before the core, with its input, when it has a fluctuation field).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Creep {
    fraction: f64,
    n: usize,
    weight: [f64; MAX_CREEP_TERMS],
    relax: [Lag; MAX_CREEP_TERMS],
    fluctuation: Option<FluctuationField>,
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
            fluctuation: None,
        };
        for i in 0..n {
            c.weight[i] = weights[i] / total;
            c.relax[i] = Lag::new(taus_s[i], dt_s, y0);
        }
        Some(c)
    }

    /// This operator plus the log-time after-effect's fluctuation field `field` (input units per e-fold of time;
    /// 0: none) with onset `tau0_s`, sample period `dt_s`, at rest at input `u0` (see [`FluctuationField::new`]).
    /// `None` for invalid arguments.
    pub fn with_fluctuation(mut self, field: f64, tau0_s: f64, dt_s: f64, u0: f64) -> Option<Self> {
        let f = FluctuationField::new(field, tau0_s, dt_s, u0)?;
        self.fluctuation = (field > 0.0).then_some(f);
        Some(self)
    }

    /// The fluctuation field, when there is one.
    pub fn fluctuation(&self) -> Option<&FluctuationField> {
        self.fluctuation.as_ref()
    }

    /// The fluctuation field, to reset or restore it.
    pub fn fluctuation_mut(&mut self) -> Option<&mut FluctuationField> {
        self.fluctuation.as_mut()
    }

    /// One sample before the core: applied input `u` → the core's input (`u` without a fluctuation field).
    #[inline]
    pub fn core_input(&mut self, u: f64) -> f64 {
        match &mut self.fluctuation {
            Some(f) => f.step(u),
            None => u,
        }
    }

    /// The applied input that makes [`Creep::core_input`] return `h` this sample (see
    /// [`FluctuationField::input_for`]), without changing the state.
    #[inline]
    pub fn applied_input_for(&self, h: f64) -> f64 {
        match &self.fluctuation {
            Some(f) => f.input_for(h),
            None => h,
        }
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
    fn fluctuation_field_grows_with_log_time_along_the_last_direction_and_restarts_when_the_input_turns()
     {
        let (dt, field, tau0) = (1e-3, 0.01, 0.05);
        let mut f = FluctuationField::new(field, tau0, dt, 0.0).unwrap();
        let mut u = 0.0;
        // The first move sets the direction (and adds nothing: the clock starts there).
        u += 1e-3;
        assert_eq!(f.step(u), u);
        for k in 1..100 {
            u += 1e-3;
            let h = f.step(u);
            assert!((h - u - field * libm::log1p(k as f64 * dt / tau0)).abs() < 1e-15);
        }
        // A dwell: the clock runs on, the field keeps growing (unbounded: by `field` per e-fold of time).
        for k in 100..5000 {
            let h = f.step(u);
            assert!(
                (h - u - field * libm::log1p(k as f64 * dt / tau0)).abs() < 1e-12,
                "dwell sample {k}"
            );
        }
        // The input turns: the field starts again from zero, then grows the other way.
        u -= 1e-3;
        assert_eq!(f.step(u), u);
        u -= 1e-3;
        assert!((f.step(u) - (u - field * libm::log1p(dt / tau0))).abs() < 1e-15);
    }

    #[test]
    fn fluctuation_inverse_is_exact_wherever_the_core_input_is_reachable() {
        let dt = 2e-3;
        let mut f = FluctuationField::new(0.003, 0.05, dt, 0.0).unwrap();
        let (mut held, mut last_u) = (0, 0.0);
        for n in 0..20_000 {
            let target = libm::sin(0.003 * n as f64) + 0.3 * libm::sin(0.021 * n as f64);
            let u = f.input_for(target);
            let before = f;
            let h = f.step(u);
            assert_eq!(before.peek(u), h);
            if n > 0 && u == last_u {
                // Held: the target turned back by less than the field the turn drops; past it by less than
                // this sample's field.
                held += 1;
                assert!(
                    (h - target).abs() <= (h - u).abs() + 1e-12,
                    "n={n}: {h} vs {target}"
                );
            } else {
                assert!((h - target).abs() < 1e-12, "n={n}: {h} vs {target}");
            }
            last_u = u;
        }
        // Only around the target's turns.
        assert!(held < 2_000, "held {held} samples");
    }

    #[test]
    fn zero_fluctuation_field_leaves_creep_unchanged() {
        let dt = 2e-3;
        let plain = Creep::log_uniform(0.1, 0.05, 50.0, dt, 0.3).unwrap();
        let with = plain.with_fluctuation(0.0, 0.05, dt, 0.0).unwrap();
        assert_eq!(plain, with);
        let mut c = with;
        assert_eq!(c.core_input(0.7), 0.7);
        assert_eq!(c.applied_input_for(0.7), 0.7);
        assert!(plain.with_fluctuation(-1.0, 0.05, dt, 0.0).is_none());
        assert!(plain.with_fluctuation(0.1, 0.0, dt, 0.0).is_none());
    }

    #[test]
    fn fluctuation_shift_is_the_field_per_unit_s_v() {
        let dt = 1e-2;
        let u: [f64; 300] = core::array::from_fn(|i| {
            if i > 150 && i < 200 {
                0.3
            } else {
                libm::sin(0.05 * i as f64)
            }
        });
        let mut out = [0.0; 300];
        assert!(fluctuation_shift(&u, 0.1, dt, &mut out));
        let mut f = FluctuationField::new(0.3, 0.1, dt, u[0]).unwrap();
        for i in 0..300 {
            assert!((f.step(u[i]) - (u[i] + 0.3 * out[i])).abs() < 1e-12);
        }
        assert!(!fluctuation_shift(&u, 0.1, dt, &mut out[..299]));
        assert!(!fluctuation_shift(&u, 0.0, dt, &mut out));
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
