//! Accommodation: a minor loop cycled between the same extremes does not close at once; it drifts from cycle to
//! cycle towards a stable position (magnetic accommodation, reptation; the "wiping-out" of a Preisach model holds
//! only for the stable loop). Saturation wipes the drift out with the rest of the memory.
//!
//! Model: once the input has reversed twice since the last saturation (a minor loop exists), the output carries a
//! shift `a` that relaxes, per loop cycle traversed, towards `−kappa · (c − y_mid)`, where `c` is the output at
//! the loop's centre (mean of the outputs at the last two reversals) and `y_mid` the centre of the output range:
//! loops drift towards the demagnetised middle, by a share `kappa` of their distance from it, with `cycles` loop
//! cycles to settle (e-folding):
//!
//! `da = (1 − exp(−dn/cycles)) · (−kappa·(c − y_mid) − a)`,  `dn = |dv| / (2 w)`,
//!
//! `v` the core output, `w` the loop's output swing (so one full cycle of any loop counts 1). The shift is linear
//! in `kappa` for fixed `cycles`: a diagnosis fits `kappa` by least squares on the unit-`kappa` shift.
//!
//! Reversals are found with a dead-band on the input and saturation by a tolerance (as in
//! [`crate::reversals`]). `no_std`, allocation-free.

/// Reversal dead-band of accommodation as a share of the input span (the plant, the stages and the diagnosis use it).
pub const DEADBAND_SHARE: f64 = 0.01;
/// Saturation tolerance of accommodation as a share of the input span.
pub const SATURATION_SHARE: f64 = 0.002;

/// The accommodation state machine (see the module doc). [`Accommodation::step`] once per sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Accommodation {
    kappa: f64,
    inv_cycles: f64,
    lo: f64,
    hi: f64,
    deadband: f64,
    saturation_tol: f64,
    y_mid: f64,
    direction: i8,
    started: bool,
    /// The running extreme is a saturation end (leaving it is not a reversal).
    at_end: bool,
    ext_u: f64,
    ext_v: f64,
    /// Outputs at the last two reversals (most recent first) and how many reversals since saturation.
    rev_v: [f64; 2],
    reversals: u32,
    last_v: f64,
    shift: f64,
}

impl Accommodation {
    /// `kappa` (any finite; 0 = off), `cycles` (> 0), input saturation ends `lo < hi`, input dead-band (> 0) and
    /// saturation tolerance (≥ 0), output-range centre `y_mid`. `None` for invalid arguments.
    pub fn new(
        kappa: f64,
        cycles: f64,
        lo: f64,
        hi: f64,
        deadband: f64,
        saturation_tol: f64,
        y_mid: f64,
    ) -> Option<Self> {
        let ok = kappa.is_finite()
            && cycles > 0.0
            && cycles.is_finite()
            && lo.is_finite()
            && hi.is_finite()
            && hi > lo
            && deadband > 0.0
            && deadband.is_finite()
            && saturation_tol >= 0.0
            && y_mid.is_finite();
        if !ok {
            return None;
        }
        Some(Accommodation {
            kappa,
            inv_cycles: 1.0 / cycles,
            lo,
            hi,
            deadband,
            saturation_tol,
            y_mid,
            direction: 0,
            started: false,
            at_end: false,
            ext_u: 0.0,
            ext_v: 0.0,
            rev_v: [0.0; 2],
            reversals: 0,
            last_v: 0.0,
            shift: 0.0,
        })
    }

    /// Forget everything (no loop, no shift).
    pub fn reset(&mut self) {
        self.direction = 0;
        self.started = false;
        self.at_end = false;
        self.ext_u = 0.0;
        self.ext_v = 0.0;
        self.rev_v = [0.0; 2];
        self.reversals = 0;
        self.last_v = 0.0;
        self.shift = 0.0;
    }

    /// The evolving state as numbers (direction, flags and counts included), for saving.
    pub fn state(&self) -> [f64; 11] {
        [
            f64::from(self.direction),
            f64::from(u8::from(self.started)),
            f64::from(u8::from(self.at_end)),
            self.ext_u,
            self.ext_v,
            self.rev_v[0],
            self.rev_v[1],
            f64::from(self.reversals),
            self.last_v,
            self.shift,
            0.0,
        ]
    }

    /// Restore a state written by [`Accommodation::state`] (`false`, nothing changed, if it is not valid).
    pub fn set_state(&mut self, s: &[f64; 11]) -> bool {
        let flag = |x: f64| x == 0.0 || x == 1.0;
        let ok = s.iter().all(|x| x.is_finite())
            && [-1.0, 0.0, 1.0].contains(&s[0])
            && flag(s[1])
            && flag(s[2])
            && s[7] >= 0.0
            && s[7] <= f64::from(u32::MAX)
            && libm::trunc(s[7]) == s[7];
        if !ok {
            return false;
        }
        self.direction = s[0] as i8;
        self.started = s[1] == 1.0;
        self.at_end = s[2] == 1.0;
        self.ext_u = s[3];
        self.ext_v = s[4];
        self.rev_v = [s[5], s[6]];
        self.reversals = s[7] as u32;
        self.last_v = s[8];
        self.shift = s[9];
        true
    }

    /// The current shift (output units).
    pub fn shift(&self) -> f64 {
        self.shift
    }

    /// One sample: input `u` and core output `v` → the shift to add to `v`.
    #[inline]
    pub fn step(&mut self, u: f64, v: f64) -> f64 {
        if !(u.is_finite() && v.is_finite()) {
            return self.shift;
        }
        if !self.started {
            self.started = true;
            self.ext_u = u;
            self.ext_v = v;
            self.last_v = v;
        }
        if u >= self.hi - self.saturation_tol || u <= self.lo + self.saturation_tol {
            self.reversals = 0;
            self.shift = 0.0;
            self.at_end = true;
            self.direction = if u >= self.hi - self.saturation_tol {
                1
            } else {
                -1
            };
            self.ext_u = u;
            self.ext_v = v;
        } else if self.direction >= 0 {
            if u > self.ext_u {
                self.ext_u = u;
                self.ext_v = v;
                self.direction = 1;
            } else if self.ext_u - u > self.deadband {
                // Leaving the start or a saturation end is no reversal of a loop.
                if self.direction != 0 && !self.at_end {
                    self.reversal();
                }
                self.at_end = false;
                self.direction = -1;
                self.ext_u = u;
                self.ext_v = v;
            }
        } else if u < self.ext_u {
            self.ext_u = u;
            self.ext_v = v;
        } else if u - self.ext_u > self.deadband {
            if !self.at_end {
                self.reversal();
            }
            self.at_end = false;
            self.direction = 1;
            self.ext_u = u;
            self.ext_v = v;
        }
        if self.reversals >= 2 {
            let w = libm::fabs(self.rev_v[0] - self.rev_v[1]);
            if w > 0.0 {
                let dn = libm::fabs(v - self.last_v) / (2.0 * w);
                let target = -self.kappa * (0.5 * (self.rev_v[0] + self.rev_v[1]) - self.y_mid);
                let k = 1.0 - libm::exp(-dn * self.inv_cycles);
                self.shift += k * (target - self.shift);
            }
        }
        self.last_v = v;
        self.shift
    }

    #[inline]
    fn reversal(&mut self) {
        self.rev_v[1] = self.rev_v[0];
        self.rev_v[0] = self.ext_v;
        self.reversals = self.reversals.saturating_add(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeated_minor_loop_drifts_towards_the_middle_and_saturation_wipes_it() {
        let mut a = Accommodation::new(0.1, 3.0, -1.0, 1.0, 0.01, 0.001, 0.0).unwrap();
        // Saturate, come down to 0.3, then cycle 0.3 <-> 0.6 with output = input (a loop centred at 0.45).
        let mut path = vec![];
        let ramp = |a: f64, b: f64, out: &mut Vec<f64>| {
            for k in 1..=100 {
                out.push(a + (b - a) * k as f64 / 100.0);
            }
        };
        ramp(0.0, 1.0, &mut path);
        ramp(1.0, 0.3, &mut path);
        for _ in 0..20 {
            ramp(0.3, 0.6, &mut path);
            ramp(0.6, 0.3, &mut path);
        }
        let mut shift = 0.0;
        for &u in &path {
            shift = a.step(u, u);
        }
        // Settled at -kappa * 0.45 after 20 cycles with 3 to settle.
        assert!((shift + 0.045).abs() < 0.002, "{shift}");
        assert_eq!(a.step(1.0, 1.0), 0.0);
        // Linear in kappa.
        let mut b = Accommodation::new(0.2, 3.0, -1.0, 1.0, 0.01, 0.001, 0.0).unwrap();
        let mut s2 = 0.0;
        for &u in &path {
            s2 = b.step(u, u);
        }
        assert!((s2 - 2.0 * shift).abs() < 1e-12);
    }

    #[test]
    fn first_order_curves_do_not_accommodate() {
        let mut a = Accommodation::new(0.5, 1.0, -1.0, 1.0, 0.01, 0.001, 0.0).unwrap();
        for k in 0..=200 {
            let u = 1.0 - k as f64 / 200.0 * 1.5; // from saturation down to -0.5
            assert_eq!(a.step(u, u), 0.0);
        }
        for k in 0..=100 {
            let u = -0.5 + k as f64 / 100.0; // one reversal: a first-order curve
            assert_eq!(a.step(u, u), 0.0);
        }
        assert!(Accommodation::new(0.1, 0.0, -1.0, 1.0, 0.01, 0.0, 0.0).is_none());
    }
}
