//! Viscous loss in the Bingham form: a function of the input's rate `r = du/dt` adds to the hysteretic core's
//! output, `y = H(u) + c·r + f_y·tanh(r/v0)`: `c` (≥ 0, output units per input unit per second) the viscous
//! part, `f_y` (≥ 0, output units) the yield part that takes the sign of the motion once `|r|` passes `v0` (> 0,
//! input units per second; a smooth Coulomb force, the yield stress of an MR fluid). The shear of an MR fluid
//! driven by a displacement, the damping of a positioning stage. Independent of the loop's local slope, unlike
//! `rate_dependence`, and no shift in time, unlike `time_delay` and `coil_lag`.
//!
//! Forward (simulation), with the rate of the sample, `y_k = H(u_k) + loss((u_k − u_{k−1})/dt)`.
//!
//! Inverse (compensator): differencing the commanded input would put a loop gain `c/(dt·s)` in the command
//! (noise amplified by `c/dt`, unstable for small `dt`). Instead the one-step implicit equation is solved for the
//! core output `v = H(u_k)`:
//!
//! `f(v) = v + loss((H⁻¹(v) − u_{k−1})/dt) − y_ref = 0`,
//!
//! `H⁻¹` the exact inverse from the core's present state (monotone along the branch it selects, clamped at the
//! input range's ends) and `loss` non-decreasing, so `f` increases at least with slope 1 and
//! `[y_ref − f(y_ref), y_ref]` (or the reverse) brackets its root. Regula falsi with the Illinois step, bisection
//! as a safeguard (a yield part with a small `v0` is nearly a step); a bounded number of iterations, no
//! allocation, the same answer from the same state bit for bit.
use crate::cbh::Hysteresis;
use crate::stages::Stage;
use crate::vocabulary::EffectKind;

/// Most iterations of the implicit solve (the Illinois steps converge superlinearly; bisection alone would halve
/// a bracket of 1e9 output units to 1e-9 in 60).
pub const MAX_ITERATIONS: usize = 80;

/// The loss of an input rate `rate` (input units per second): `c·rate + f_y·tanh(rate/v0)` (output units), the
/// one formula of the stage, the virtual plants and the diagnosis. Non-decreasing in `rate` for `c, f_y ≥ 0`.
#[inline]
pub fn loss(c: f64, f_y: f64, v0: f64, rate: f64) -> f64 {
    let viscous = c * rate;
    if f_y > 0.0 {
        viscous + f_y * libm::tanh(rate / v0)
    } else {
        viscous
    }
}

/// The viscous stage: the loss's parameters, the sample period and the core input of the last sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Viscous {
    c: f64,
    f_y: f64,
    v0: f64,
    dt_s: f64,
    /// `c/dt`: output per unit of input change within one sample.
    per_step: f64,
    /// `v0·dt`: the input change within one sample at rate `v0`.
    v0_step: f64,
    last_input: f64,
}

impl Viscous {
    /// Loss coefficient `c` (≥ 0; output units per input unit per second), yield output `f_y` (≥ 0; output units)
    /// and yield rate `v0` (> 0; input units per second), all finite, at sample period `dt_s`, at rest at core
    /// input `u0`. `None` for invalid arguments.
    pub fn new(c: f64, f_y: f64, v0: f64, dt_s: f64, u0: f64) -> Option<Self> {
        let ok = c.is_finite()
            && c >= 0.0
            && f_y.is_finite()
            && f_y >= 0.0
            && v0.is_finite()
            && v0 > 0.0
            && dt_s.is_finite()
            && dt_s > 0.0
            && u0.is_finite();
        let (per_step, v0_step) = (c / dt_s, v0 * dt_s);
        (ok && per_step.is_finite() && v0_step > 0.0).then_some(Viscous {
            c,
            f_y,
            v0,
            dt_s,
            per_step,
            v0_step,
            last_input: u0,
        })
    }

    /// The loss coefficient `c`.
    pub fn coefficient(&self) -> f64 {
        self.c
    }

    /// The yield output `f_y` and the yield rate `v0`.
    pub fn yield_part(&self) -> (f64, f64) {
        (self.f_y, self.v0)
    }

    /// The loss of an input change `du` within one sample.
    #[inline]
    fn loss_of_step(&self, du: f64) -> f64 {
        let viscous = self.per_step * du;
        if self.f_y > 0.0 {
            viscous + self.f_y * libm::tanh(du / self.v0_step)
        } else {
            viscous
        }
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
        let loss = self.loss_of_step(u - self.last_input);
        self.last_input = u;
        loss
    }

    /// The core output `v` that, with the loss of the core input reaching it, gives `total`: the root of
    /// `v + loss((H⁻¹(v) − u_{k−1})/dt) = total` (module doc), from the core's present state. The state does not
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
            |v: f64| v + self.loss_of_step(core.inverse_input(v).input - self.last_input) - total;
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
        if (saved.c, saved.f_y, saved.v0, saved.dt_s) != (self.c, self.f_y, self.v0, self.dt_s) {
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
