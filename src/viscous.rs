//! Viscous loss: a term proportional to the input's rate adds to the hysteretic core's output,
//! `y = H(u) + c·du/dt` (`c` in output units per input unit per second, `c ≥ 0`). The shear of an MR fluid
//! driven by a displacement (force per velocity), the damping of a positioning stage. Independent of the loop's
//! local slope, unlike `rate_dependence`, and no shift in time, unlike `time_delay` and `coil_lag`.
//!
//! Forward (simulation), with the rate of the sample, `y_k = H(u_k) + (c/dt)·(u_k − u_{k−1})`.
//!
//! Inverse (compensator): differencing the commanded input would put a loop gain `c/(dt·s)` in the command
//! (noise amplified by `c/dt`, unstable for small `dt`). Instead the one-step implicit equation is solved for the
//! core output `v = H(u_k)`:
//!
//! `f(v) = v + (c/dt)·(H⁻¹(v) − u_{k−1}) − y_ref = 0`,
//!
//! `H⁻¹` the exact inverse from the core's present state (monotone along the branch it selects, clamped at the
//! input range's ends), so `f` increases at least with slope 1 and `[y_ref − f(y_ref), y_ref]` (or the reverse)
//! brackets its root. Regula falsi with the Illinois step, bisection as a safeguard; a bounded number of
//! iterations, no allocation, the same answer from the same state bit for bit.
use crate::cbh::Hysteresis;
use crate::stages::Stage;
use crate::vocabulary::EffectKind;

/// Most iterations of the implicit solve (the Illinois steps converge superlinearly; bisection alone would halve
/// a bracket of 1e9 output units to 1e-9 in 60).
pub const MAX_ITERATIONS: usize = 80;

/// The viscous stage: the loss coefficient per sample and the core input of the last sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Viscous {
    c: f64,
    dt_s: f64,
    /// `c/dt`: output per unit of input change within one sample.
    per_step: f64,
    last_input: f64,
}

impl Viscous {
    /// Loss coefficient `c` (≥ 0, finite; output units per input unit per second) at sample period `dt_s`, at rest
    /// at core input `u0`. `None` for invalid arguments.
    pub fn new(c: f64, dt_s: f64, u0: f64) -> Option<Self> {
        let ok = c.is_finite() && c >= 0.0 && dt_s.is_finite() && dt_s > 0.0 && u0.is_finite();
        let per_step = c / dt_s;
        (ok && per_step.is_finite()).then_some(Viscous {
            c,
            dt_s,
            per_step,
            last_input: u0,
        })
    }

    /// The loss coefficient `c`.
    pub fn coefficient(&self) -> f64 {
        self.c
    }

    /// The core input of the last sample.
    pub fn last_input(&self) -> f64 {
        self.last_input
    }

    /// At rest at core input `u0` (no rate).
    pub fn reset(&mut self, u0: f64) {
        self.last_input = u0;
    }

    /// The loss of this sample's core input `u` (output units), advancing the state to it.
    #[inline]
    pub fn step(&mut self, u: f64) -> f64 {
        let loss = self.per_step * (u - self.last_input);
        self.last_input = u;
        loss
    }

    /// The core output `v` that, with the loss of the core input reaching it, gives `total`: the root of
    /// `v + (c/dt)·(H⁻¹(v) − u_{k−1}) = total` (module doc), from the core's present state. The state does not
    /// change ([`Viscous::step`] with the core input actually applied advances it). Non-finite `total` or
    /// core answers come back as NaN (the caller faults).
    #[inline]
    pub fn core_output_for<S: AsRef<[f64]>, const N: usize>(
        &self,
        core: &Hysteresis<S, N>,
        total: f64,
    ) -> f64 {
        if !total.is_finite() {
            return f64::NAN;
        }
        let f =
            |v: f64| v + self.per_step * (core.inverse_input(v).input - self.last_input) - total;
        let f_total = f(total);
        if f_total == 0.0 || !f_total.is_finite() {
            return if f_total == 0.0 { total } else { f64::NAN };
        }
        // f(v) − v never decreases, so one step of f(total) back crosses the root.
        let (mut a, mut b) = if f_total > 0.0 {
            (total - f_total, total)
        } else {
            (total, total - f_total)
        };
        let (mut fa, mut fb) = (f(a), f(b));
        if !(fa.is_finite() && fb.is_finite()) {
            return f64::NAN;
        }
        if fa >= 0.0 {
            return a;
        }
        if fb <= 0.0 {
            return b;
        }
        // `ra`, `rb`: the residuals at the ends; `fa`, `fb`: the Illinois weights (halved when an end is kept).
        let (mut ra, mut rb) = (fa, fb);
        let f_tol = 1e-13 * (1.0 + libm::fabs(total));
        let mut side = 0i8;
        for _ in 0..MAX_ITERATIONS {
            let secant = b - fb * (b - a) / (fb - fa);
            let m = if secant > a && secant < b {
                secant
            } else {
                0.5 * (a + b)
            };
            if !(m > a && m < b) {
                break; // the bracket is down to adjacent floats
            }
            let fm = f(m);
            if !fm.is_finite() {
                return f64::NAN;
            }
            if libm::fabs(fm) <= f_tol {
                return m;
            }
            if fm < 0.0 {
                (a, fa, ra) = (m, fm, fm);
                if side < 0 {
                    fb *= 0.5;
                }
                side = -1;
            } else {
                (b, fb, rb) = (m, fm, fm);
                if side > 0 {
                    fa *= 0.5;
                }
                side = 1;
            }
        }
        if libm::fabs(ra) <= libm::fabs(rb) {
            a
        } else {
            b
        }
    }
}

fn take_float(words: &mut &[u64]) -> Option<f64> {
    let (&first, rest) = words.split_first()?;
    *words = rest;
    Some(f64::from_bits(first)).filter(|v| v.is_finite())
}

impl Stage for Viscous {
    const KIND: EffectKind = EffectKind::Viscous;
    type Saved = Viscous;
    fn save(&self) -> Viscous {
        *self
    }
    fn load(&mut self, saved: &Viscous) -> bool {
        if (saved.c, saved.dt_s) != (self.c, self.dt_s) {
            return false;
        }
        *self = *saved;
        true
    }
    fn rest(&mut self, field_a: f64, _: f64) {
        self.reset(field_a);
    }
    fn write_words(&self, push: &mut dyn FnMut(u64)) {
        push(self.last_input.to_bits());
    }
    fn read_words(&mut self, words: &mut &[u64]) -> Option<()> {
        self.last_input = take_float(words)?;
        Some(())
    }
    fn write_saved(saved: &Viscous, push: &mut dyn FnMut(u64)) {
        saved.write_words(push);
    }
}
