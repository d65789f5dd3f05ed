//! Rate dependence: the hysteresis loop widens with the input rate because the material resists changes of its
//! own state — eddy currents in solid steel (Bertotti's classical dynamic field `H_dyn = k·dB/dt`),
//! domain-wall damping in ferroelectrics and piezo ceramics.
//!
//! Model (dynamic field proportional to the output rate): the hysteretic core sees the applied input minus a
//! dynamic field that opposes the change of its output, `u_core = u − k·dy/dt`. With `dy/dt = s·du_core/dt`
//! (`s` the differential slope of the branch being traversed) this is a first-order lag of the core input whose
//! time constant follows the slope:
//!
//! `u_core' = (u − u_core)/(tau_s · ŝ)`,  `ŝ = s / s_ref`,
//!
//! where `s_ref` is a reference slope (the major loop's mean slope, output span over input span) and `tau_s` the
//! time constant at that slope. Where the loop is steep the input lags strongly; in saturation and on flat
//! branches not at all — unlike `coil_lag` (one time constant everywhere) or `time_delay` (a shift of every
//! sample). Signature: loops widen with rate by an amount that grows with the local slope, the loop tips are
//! reached without delay.
//!
//! The slope is measured along the path as the secant of the core's last move (kept through dwells). The lag is
//! sampled exactly for the time constant of the sample. `no_std`, allocation-free; [`RateDependence::input_for`]
//! is the exact inverse (the command that puts the core input where a compensator wants it).

use crate::filters::lag_pole;

/// Slopes below this share of the reference count as flat (no lag); above [`MAX_RELATIVE_SLOPE`] they are capped.
const MIN_RELATIVE_SLOPE: f64 = 1e-6;
/// Cap of the relative slope (a vertical jump of a measured table must not freeze the input).
pub const MAX_RELATIVE_SLOPE: f64 = 50.0;

/// The rate-dependence stage in front of a hysteretic core (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RateDependence {
    tau_s: f64,
    dt_s: f64,
    inv_slope_ref: f64,
    /// Minimum core-input move (input units) for a new slope estimate.
    min_move: f64,
    u_core: f64,
    last_u_core: f64,
    last_y: f64,
    rel_slope: f64,
    pole: f64,
}

impl RateDependence {
    /// Time constant `tau_s` (≥ 0; 0 = pass-through) at the reference slope `slope_ref` (> 0, output per input),
    /// sample period `dt_s`, input span `input_span` (sets the smallest move that updates the slope: 1e-6 of it),
    /// at rest at core input `u0` with core output `y0`. `None` for invalid arguments.
    pub fn new(
        tau_s: f64,
        slope_ref: f64,
        dt_s: f64,
        input_span: f64,
        u0: f64,
        y0: f64,
    ) -> Option<Self> {
        let ok = tau_s >= 0.0
            && tau_s.is_finite()
            && slope_ref > 0.0
            && slope_ref.is_finite()
            && dt_s > 0.0
            && dt_s.is_finite()
            && input_span > 0.0
            && input_span.is_finite()
            && u0.is_finite()
            && y0.is_finite();
        if !ok {
            return None;
        }
        Some(RateDependence {
            tau_s,
            dt_s,
            inv_slope_ref: 1.0 / slope_ref,
            min_move: 1e-6 * input_span,
            u_core: u0,
            last_u_core: u0,
            last_y: y0,
            rel_slope: 0.0,
            pole: 0.0,
        })
    }

    /// Back to rest at core input `u0`, core output `y0` (slope unknown: no lag until the core moves).
    pub fn reset(&mut self, u0: f64, y0: f64) {
        self.u_core = u0;
        self.last_u_core = u0;
        self.last_y = y0;
        self.rel_slope = 0.0;
        self.pole = 0.0;
    }

    /// The compensator reached the core input it asked for ([`RateDependence::input_for`] was commanded without
    /// limiting): hold it exactly as the state (no round-off drift between the two).
    #[inline]
    pub fn reached(&mut self, u_core: f64) {
        self.u_core = u_core;
    }

    /// The evolving state `[u_core, last_u_core, last_y, relative slope]`, for saving.
    pub fn state(&self) -> [f64; 4] {
        [self.u_core, self.last_u_core, self.last_y, self.rel_slope]
    }

    /// Restore a state written by [`RateDependence::state`] (`false`, nothing changed, if it is not valid).
    pub fn set_state(&mut self, s: [f64; 4]) -> bool {
        if !(s.iter().all(|x| x.is_finite()) && (0.0..=MAX_RELATIVE_SLOPE).contains(&s[3])) {
            return false;
        }
        [self.u_core, self.last_u_core, self.last_y, self.rel_slope] = s;
        self.update_pole();
        true
    }

    /// The core input of the last step.
    pub fn core_input(&self) -> f64 {
        self.u_core
    }

    /// The current relative slope `ŝ`.
    pub fn relative_slope(&self) -> f64 {
        self.rel_slope
    }

    #[inline]
    fn update_pole(&mut self) {
        self.pole = lag_pole(self.dt_s, self.tau_s * self.rel_slope);
    }

    /// One sample, first half: applied input `u` held over this period → core input at its end.
    #[inline]
    pub fn step(&mut self, u: f64) -> f64 {
        self.u_core = self.pole * self.u_core + (1.0 - self.pole) * u;
        self.u_core
    }

    /// One sample, second half: the core's output `y` for the core input [`RateDependence::step`] returned; updates
    /// the slope (and so the time constant of the next sample).
    #[inline]
    pub fn observe(&mut self, y: f64) {
        let du = self.u_core - self.last_u_core;
        if libm::fabs(du) > self.min_move {
            let s = libm::fabs((y - self.last_y) / du) * self.inv_slope_ref;
            self.rel_slope = if s < MIN_RELATIVE_SLOPE {
                0.0
            } else {
                s.min(MAX_RELATIVE_SLOPE)
            };
            self.last_u_core = self.u_core;
            self.last_y = y;
            self.update_pole();
        }
    }

    /// The applied input that brings the core input to `u_core` this sample (the inverse of
    /// [`RateDependence::step`]), without changing the state.
    #[inline]
    pub fn input_for(&self, u_core: f64) -> f64 {
        (u_core - self.pole * self.u_core) / (1.0 - self.pole)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth single-valued "core": y = tanh(2u), slope 2 at 0, flat in saturation.
    fn core(u: f64) -> f64 {
        libm::tanh(2.0 * u)
    }

    fn run(tau: f64, rate: f64, dt: f64) -> (f64, f64) {
        // Ramp from -1.5 to 1.5 at `rate`; returns the core-input lag at u = 0 and at u = 1.4 (saturation).
        let mut r = RateDependence::new(tau, 1.0, dt, 3.0, -1.5, core(-1.5)).unwrap();
        let n = (3.0 / (rate * dt)) as usize;
        let (mut lag0, mut lag_sat) = (f64::NAN, f64::NAN);
        for k in 1..=n {
            let u = -1.5 + rate * dt * k as f64;
            let uc = r.step(u);
            r.observe(core(uc));
            if lag0.is_nan() && u >= 0.0 {
                lag0 = u - uc;
            }
            if lag_sat.is_nan() && u >= 1.4 {
                lag_sat = u - uc;
            }
        }
        (lag0, lag_sat)
    }

    #[test]
    fn lag_follows_the_slope_and_grows_with_rate() {
        let dt = 1e-4;
        let (l1, s1) = run(0.01, 1.0, dt);
        let (l2, _) = run(0.01, 2.0, dt);
        // On the steep part (relative slope 2) the lag is about rate·tau·2; doubling the rate doubles it.
        assert!((l1 - 0.02).abs() < 0.004, "{l1}");
        assert!((l2 / l1 - 2.0).abs() < 0.1, "{l1} {l2}");
        // In saturation (slope ~ 0.0015) it has all but vanished.
        assert!(s1 < 0.05 * l1, "{s1} vs {l1}");
        let (z, _) = run(0.0, 1.0, dt);
        assert_eq!(z, 0.0);
    }

    #[test]
    fn inverse_undoes_the_stage() {
        let dt = 1e-3;
        let mut fwd = RateDependence::new(0.02, 1.0, dt, 3.0, 0.0, 0.0).unwrap();
        let mut inv = fwd;
        for n in 0..4000 {
            let want = libm::sin(0.004 * n as f64);
            let u = inv.input_for(want);
            let got = inv.step(u);
            assert!((got - want).abs() < 1e-9);
            inv.observe(core(got));
            let f = fwd.step(u);
            fwd.observe(core(f));
            assert!((f - want).abs() < 1e-9);
        }
        assert!(RateDependence::new(-1.0, 1.0, dt, 1.0, 0.0, 0.0).is_none());
        assert!(RateDependence::new(0.1, 0.0, dt, 1.0, 0.0, 0.0).is_none());
    }
}
