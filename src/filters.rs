//! Per-sample filters shared by the virtual actuator, the compensator stages and the batch functions the Python
//! diagnosis calls: the exact first-order lag, its exact inverse (lead), an integer-sample delay line, the
//! coil heating state and the leakage integral of a charge measurement. `no_std`, allocation-free, the sample
//! period fixed at construction.
//!
//! The lag is the zero-order-hold discretisation of `y' = (x − y)/τ`: with the input held over a period `dt`,
//! `y[n] = p·y[n−1] + (1 − p)·x[n]`, `p = exp(−dt/τ)`, exact for a held input (a converter's output is).

/// Exact discretisation factor of a first-order lag: `exp(-dt/tau)` (0 when `tau` is 0 or negative: no lag).
#[inline]
pub fn lag_pole(dt_s: f64, tau_s: f64) -> f64 {
    if tau_s > 0.0 {
        libm::exp(-dt_s / tau_s)
    } else {
        0.0
    }
}

/// Factor by which a charge amplifier's leakage integral decays over one sample: `exp(−decay·dt)` (1 for an
/// ideal integrator, `decay_per_s` 0 or less).
#[inline]
pub fn leak_pole(dt_s: f64, decay_per_s: f64) -> f64 {
    if decay_per_s > 0.0 {
        libm::exp(-decay_per_s * dt_s)
    } else {
        1.0
    }
}

/// A torque sensor's zero drift at time `t_s` (s from the device's start) per unit of its initial rate: `t` for a
/// drift that never settles (`settle_per_s` 0 or less), `(1 − e^(−settle·t))/settle` for a strain bridge warming up
/// towards its final zero, which it approaches with time constant `1/settle_per_s`.
#[inline]
pub fn drift_offset(t_s: f64, settle_per_s: f64) -> f64 {
    if settle_per_s > 0.0 {
        -libm::expm1(-settle_per_s * t_s) / settle_per_s
    } else {
        t_s
    }
}

/// One sample of the charge a leakage current `x` leaves on a charge amplifier whose feedback discharges it
/// (`q' = x − decay·q`, `pole` from [`leak_pole`]): trapezoids of the input, the older end and the charge before
/// decayed over the period, `q[n] = p·q[n−1] + dt/2·(x[n] + p·x[n−1])`. With `pole` 1 exactly the trapezoid rule.
#[inline]
pub fn leak_step(q: f64, pole: f64, dt_s: f64, x: f64, last_x: f64) -> f64 {
    pole * q + 0.5 * dt_s * (x + pole * last_x)
}

/// First-order lag `y[n] = p·y[n−1] + (1 − p)·x[n]` (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lag {
    pole: f64,
    y: f64,
}

impl Lag {
    /// Time constant `tau_s` (0: pass-through) at sample period `dt_s`, at rest at `y0`.
    pub fn new(tau_s: f64, dt_s: f64, y0: f64) -> Self {
        Lag {
            pole: lag_pole(dt_s, tau_s),
            y: y0,
        }
    }
    /// `exp(−dt/τ)`.
    pub fn pole(&self) -> f64 {
        self.pole
    }
    /// Output of the last step (the state).
    pub fn output(&self) -> f64 {
        self.y
    }
    pub fn set_output(&mut self, y: f64) {
        self.y = y;
    }
    /// One sample: input held over this period → output at its end.
    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        self.y = self.pole * self.y + (1.0 - self.pole) * x;
        self.y
    }
    /// The input that would bring the output to `y` this sample (the lead), without changing the state.
    #[inline]
    pub fn input_for(&self, y: f64) -> f64 {
        (y - self.pole * self.y) / (1.0 - self.pole)
    }
}

/// Exact inverse of [`Lag`]: `x[n] = (y[n] − p·y[n−1])/(1 − p)`, so that `lag(lead(y)) == y` up to round-off.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lead {
    pole: f64,
    prev: f64,
}

impl Lead {
    /// Inverse of a lag of time constant `tau_s` at sample period `dt_s` whose output rests at `y0`.
    pub fn new(tau_s: f64, dt_s: f64, y0: f64) -> Self {
        Lead {
            pole: lag_pole(dt_s, tau_s),
            prev: y0,
        }
    }
    #[inline]
    pub fn step(&mut self, y: f64) -> f64 {
        let x = (y - self.pole * self.prev) / (1.0 - self.pole);
        self.prev = y;
        x
    }
}

/// Delay by a whole number of samples over caller-chosen storage: a fixed array (`[f64; CAP]`, no allocation,
/// the real-time core) or a `Vec` sized once (the virtual actuator's long delays). The delay is the storage's
/// length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DelayLine<S> {
    buf: S,
    len: usize,
    head: usize,
}

impl<S: AsRef<[f64]> + AsMut<[f64]>> DelayLine<S> {
    /// A delay of `samples` (at most the storage's length) filled with `fill`; `None` if the storage is too short.
    pub fn new(mut buf: S, samples: usize, fill: f64) -> Option<Self> {
        if samples > buf.as_ref().len() {
            return None;
        }
        buf.as_mut()[..samples].fill(fill);
        Some(DelayLine {
            buf,
            len: samples,
            head: 0,
        })
    }
    /// The delay in samples.
    pub fn samples(&self) -> usize {
        self.len
    }
    /// Push `x`, return the value pushed `samples` steps ago (`x` itself for a zero delay).
    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        if self.len == 0 {
            return x;
        }
        let slot = &mut self.buf.as_mut()[self.head];
        let out = *slot;
        *slot = x;
        self.head += 1;
        if self.head == self.len {
            self.head = 0;
        }
        out
    }
    /// The value pushed `k` steps ago (`1 ≤ k ≤ samples`; `k = samples` is what the next `step` returns).
    #[inline]
    pub fn ago(&self, k: usize) -> f64 {
        let i = (self.head + self.len - k) % self.len;
        self.buf.as_ref()[i]
    }
    /// The stored values, oldest (the next one out) first.
    pub fn values(&self) -> impl Iterator<Item = f64> + '_ {
        let b = &self.buf.as_ref()[..self.len];
        b[self.head..].iter().chain(&b[..self.head]).copied()
    }

    /// Replace the stored values, oldest first (as [`Self::values`] gives them; extra values are ignored).
    pub fn set_values(&mut self, values: impl IntoIterator<Item = f64>) {
        let n = self.len;
        let b = &mut self.buf.as_mut()[..n];
        for (slot, v) in b.iter_mut().zip(values) {
            *slot = v;
        }
        self.head = 0;
    }

    /// Fill the line with `value`.
    pub fn fill(&mut self, value: f64) {
        let n = self.len;
        self.buf.as_mut()[..n].fill(value);
        self.head = 0;
    }
}

/// Coil heating state: `x' = (heat − x)/τ` sampled exactly for a held input, `heat = (I/I_full)²` (so `x = 1` is
/// steady full current). `x[n] = x[n−1] + (1 − p)·(heat[n] − x[n−1])`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Heating {
    rate: f64,
    inv_full_sq: f64,
    x: f64,
}

impl Heating {
    /// Thermal time constant `tau_s` at sample period `dt_s`, unit heating at `full_current_a`, from state `x0`.
    pub fn new(tau_s: f64, dt_s: f64, full_current_a: f64, x0: f64) -> Self {
        Heating {
            rate: 1.0 - lag_pole(dt_s, tau_s),
            inv_full_sq: 1.0 / (full_current_a * full_current_a),
            x: x0,
        }
    }
    /// The state (1 = steady full current).
    pub fn state(&self) -> f64 {
        self.x
    }
    pub fn set_state(&mut self, x: f64) {
        self.x = x;
    }
    /// One sample with normalised heat input `heat` (`(I/I_full)²`).
    #[inline]
    pub fn step_heat(&mut self, heat: f64) -> f64 {
        self.x += self.rate * (heat - self.x);
        self.x
    }
    /// One sample with coil current `current_a` (A).
    #[inline]
    pub fn step(&mut self, current_a: f64) -> f64 {
        self.step_heat(current_a * current_a * self.inv_full_sq)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leak_integral_is_the_trapezoid_rule_without_decay_and_settles_at_input_over_decay_with_it() {
        let dt = 1e-3;
        let (mut q, mut last) = (0.0, 0.0);
        for n in 0..1000 {
            let x = n as f64 * dt; // a ramp: its integral t²/2 is exact for trapezoids
            q = leak_step(q, leak_pole(dt, 0.0), dt, x, last);
            last = x;
        }
        assert!((q - 0.5 * (999.0 * dt) * (999.0 * dt)).abs() < 1e-12, "{q}");
        // A held input x with decay d: q(t) = x/d · (1 − exp(−d t)), steady at x/d.
        let (d, x) = (2.0, 3.0);
        let pole = leak_pole(dt, d);
        let mut q = 0.0;
        for n in 1..=5000 {
            q = leak_step(q, pole, dt, x, x);
            let t = n as f64 * dt;
            let exact = x / d * (1.0 - libm::exp(-d * t));
            assert!((q - exact).abs() < 1e-6 * x / d, "n {n}: {q} vs {exact}");
        }
    }

    #[test]
    fn lead_inverts_lag_and_lag_matches_the_continuous_step_response() {
        let dt = 1e-3;
        let tau = 0.02;
        let mut lag = Lag::new(tau, dt, 0.0);
        // Unit step held from t = 0: y(n·dt) = 1 − exp(−n·dt/τ).
        for n in 1..200 {
            let y = lag.step(1.0);
            let exact = 1.0 - libm::exp(-(n as f64) * dt / tau);
            assert!((y - exact).abs() < 1e-12, "n={n}: {y} vs {exact}");
        }
        let mut lead = Lead::new(tau, dt, 0.3);
        let mut lag = Lag::new(tau, dt, 0.3);
        for n in 0..500 {
            let target = libm::sin(0.05 * n as f64);
            let x = lead.step(target);
            assert!((lag.step(x) - target).abs() < 1e-12);
        }
        let mut pass = Lag::new(0.0, dt, 5.0);
        assert_eq!(pass.step(2.0), 2.0);
    }

    #[test]
    fn delay_line_delays_by_whole_samples() {
        let mut d = DelayLine::new([0.0; 8], 3, -1.0).unwrap();
        let out: [f64; 6] = core::array::from_fn(|i| d.step(i as f64));
        assert_eq!(out, [-1.0, -1.0, -1.0, 0.0, 1.0, 2.0]);
        assert_eq!(d.ago(1), 5.0);
        assert_eq!(d.ago(3), 3.0);
        let order: [f64; 3] = core::array::from_fn(|i| d.values().nth(i).unwrap());
        assert_eq!(order, [3.0, 4.0, 5.0]);
        let mut e = DelayLine::new([0.0; 8], 3, 0.0).unwrap();
        e.set_values(d.values());
        assert_eq!([e.step(9.0), e.step(9.0), e.step(9.0)], [3.0, 4.0, 5.0]);
        let mut z = DelayLine::new([0.0; 0], 0, 0.0).unwrap();
        assert_eq!(z.step(4.0), 4.0);
        assert!(DelayLine::new([0.0; 2], 3, 0.0).is_none());
    }

    #[test]
    fn heating_settles_at_the_normalised_square_current() {
        let mut h = Heating::new(1.0, 1e-2, 2.0, 0.0);
        let mut x = 0.0;
        for _ in 0..5000 {
            x = h.step(1.0);
        }
        assert!((x - 0.25).abs() < 1e-12);
    }
}
