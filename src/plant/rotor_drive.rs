//! Motor and gear set: the rotors turn at a (rippled) speed; the encoder reports the rotor angle.
//!
//! `dθ/dt = ω0 (1 + ripple · sin θ)` — a once-per-revolution speed ripple from gear eccentricity. The two rotors
//! turn in opposite directions at the same speed; θ is the rotor-1 angle, wrapped to [0, 2π).

use super::{PlantError, check_range};
use core::f64::consts::TAU;

#[derive(Clone, Debug, PartialEq)]
pub struct DriveParams {
    /// Mean rotor speed, rad/s.
    pub speed_rad_s: f64,
    /// Relative once-per-revolution speed ripple (0 = none).
    pub speed_ripple: f64,
    /// Rotor angle at t = 0, rad.
    pub theta0_rad: f64,
}

impl Default for DriveParams {
    fn default() -> Self {
        DriveParams {
            speed_rad_s: TAU,
            speed_ripple: 0.0,
            theta0_rad: 0.0,
        }
    }
}

impl DriveParams {
    pub fn validate(&self) -> Result<(), PlantError> {
        check_range("drive.speed_rad_s", self.speed_rad_s, 0.0, 1e4)?;
        check_range("drive.speed_ripple", self.speed_ripple, 0.0, 0.5)?;
        check_range("drive.theta0_rad", self.theta0_rad, -1e6, 1e6)?;
        Ok(())
    }
}

/// Rotor angle state.
#[derive(Clone, Debug)]
pub struct RotorDrive {
    params: DriveParams,
    dt_s: f64,
    theta_rad: f64,
}

/// `theta` in [0, 2π) (`rem_euclid` rounds tiny negative angles up to exactly 2π).
#[inline]
fn wrap(theta: f64) -> f64 {
    // Already inside: `rem_euclid` would return it unchanged (the remainder is exact), without its `fmod`.
    if (0.0..TAU).contains(&theta) {
        return theta;
    }
    let t = theta.rem_euclid(TAU);
    if t >= TAU { 0.0 } else { t }
}

impl RotorDrive {
    pub fn new(params: DriveParams, dt_s: f64) -> Self {
        let theta_rad = wrap(params.theta0_rad);
        RotorDrive {
            params,
            dt_s,
            theta_rad,
        }
    }

    pub fn reset(&mut self) {
        self.theta_rad = wrap(self.params.theta0_rad);
    }

    pub(crate) fn save_state(&self, out: &mut Vec<u64>) {
        out.push(self.theta_rad.to_bits());
    }

    pub(crate) fn load_state(
        &mut self,
        r: &mut super::StateReader<'_>,
    ) -> Result<(), super::PlantError> {
        let theta = r.float()?;
        if !(0.0..TAU).contains(&theta) {
            return Err(super::PlantError::BadState("rotor angle outside [0, 2π)"));
        }
        self.theta_rad = theta;
        Ok(())
    }

    /// Current rotor speed, rad/s.
    #[inline]
    pub fn speed_rad_s(&self) -> f64 {
        self.speed_at_sin(crate::trig::sincos(self.theta_rad).0)
    }

    /// The speed at the present angle from its sine (`crate::trig::sincos`, as the friction evaluates it).
    #[inline]
    pub fn speed_at_sin(&self, sin_theta: f64) -> f64 {
        self.params.speed_rad_s * (1.0 + self.params.speed_ripple * sin_theta)
    }

    /// Rotor angle of the current sample, rad in [0, 2π).
    #[inline]
    pub fn theta_rad(&self) -> f64 {
        self.theta_rad
    }

    /// Advance one sample period.
    #[inline]
    pub fn advance(&mut self) {
        self.advance_at(self.speed_rad_s());
    }

    /// [`Self::advance`] with the speed of the present angle (`speed_rad_s()`) already computed this sample.
    #[inline]
    pub fn advance_at(&mut self, speed_rad_s: f64) {
        let next = self.theta_rad + speed_rad_s * self.dt_s;
        self.theta_rad = wrap(next);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shortcut for an angle already inside [0, 2π) gives `rem_euclid`'s bits, at the ends and across turns.
    #[test]
    fn wrap_is_rem_euclid_to_the_bit() {
        let long_way = |x: f64| {
            let t = x.rem_euclid(TAU);
            if t >= TAU { 0.0 } else { t }
        };
        let mut x = -3.0 * TAU;
        let mut probes = vec![
            0.0,
            -0.0,
            TAU,
            -1e-300,
            f64::from_bits(TAU.to_bits() - 1),
            1e5,
        ];
        while x < 3.0 * TAU {
            probes.push(x);
            x += 0.001_234_567;
        }
        for p in probes {
            assert_eq!(wrap(p).to_bits(), long_way(p).to_bits(), "{p}");
        }
    }
}
