//! Voltage→current converters and the coil split of the nominal current (paper eq 8).
//!
//! The controller writes control voltages `u = I / gain`; each converter drives its coil with `gain · u`
//! amperes (0.125 A/V on the paper's rig), clamped to `[0, limit_a]`, optionally through a first-order
//! bandwidth. Nominal current `I > 0` excites coil 2, `I < 0` excites coil 1 with `|I|`; the other is off.

use super::{PlantError, check_range};
use crate::filters::Lag;

/// Parameters of one voltage→current converter.
#[derive(Clone, Debug, PartialEq)]
pub struct ConverterParams {
    /// Conversion gain (A/V); 0.125 on the paper's rig.
    pub gain_a_per_v: f64,
    /// Current limit of the converter (A).
    pub limit_a: f64,
    /// Closed-loop bandwidth (Hz) of the current control; `None` = ideal (instantaneous).
    pub bandwidth_hz: Option<f64>,
}

impl Default for ConverterParams {
    fn default() -> Self {
        ConverterParams {
            gain_a_per_v: 0.125,
            limit_a: 1.5,
            bandwidth_hz: None,
        }
    }
}

impl ConverterParams {
    pub fn validate(&self) -> Result<(), PlantError> {
        check_range("converter.gain_a_per_v", self.gain_a_per_v, 1e-6, 100.0)?;
        check_range("converter.limit_a", self.limit_a, 1e-6, 100.0)?;
        if let Some(bw) = self.bandwidth_hz {
            check_range("converter.bandwidth_hz", bw, 1e-3, 1e9)?;
        }
        Ok(())
    }
}

/// Split nominal current into (coil 1, coil 2) currents (eq 8): only one coil carries current.
pub fn coil_split(nominal_a: f64) -> (f64, f64) {
    if nominal_a < 0.0 {
        (-nominal_a, 0.0)
    } else {
        (0.0, nominal_a)
    }
}

/// One converter with its (optional) bandwidth state.
#[derive(Clone, Debug)]
pub struct Converter {
    params: ConverterParams,
    /// The bandwidth limit (pass-through without one).
    lag: Lag,
}

impl Converter {
    pub fn new(params: ConverterParams, dt_s: f64) -> Self {
        let tau_s = match params.bandwidth_hz {
            Some(bw) => 1.0 / (2.0 * core::f64::consts::PI * bw),
            None => 0.0,
        };
        Converter {
            params,
            lag: Lag::new(tau_s, dt_s, 0.0),
        }
    }

    /// Control voltage (V) the controller writes for a coil current command (A).
    pub fn voltage_for(&self, current_a: f64) -> f64 {
        current_a / self.params.gain_a_per_v
    }

    /// Advance one sample with control voltage `u_v`; returns the coil current (A).
    pub fn step(&mut self, u_v: f64) -> f64 {
        let target = (self.params.gain_a_per_v * u_v).clamp(0.0, self.params.limit_a);
        self.lag.step(target)
    }

    /// [`Self::step`] with the voltage for coil current command `current_a` (A): `step(voltage_for(current_a))`
    /// to the bit. The coil that carries no current (every sample one of the two) skips the division: a zero
    /// command gives its own zero back through the gain and the clamp.
    #[inline]
    pub fn step_current(&mut self, current_a: f64) -> f64 {
        let target = if current_a == 0.0 {
            current_a
        } else {
            (self.params.gain_a_per_v * self.voltage_for(current_a)).clamp(0.0, self.params.limit_a)
        };
        self.lag.step(target)
    }

    pub fn reset(&mut self) {
        self.lag.set_output(0.0);
    }

    pub(crate) fn save_state(&self, out: &mut Vec<u64>) {
        out.push(self.lag.output().to_bits());
    }

    pub(crate) fn load_state(&mut self, r: &mut super::StateReader<'_>) -> Result<(), PlantError> {
        self.lag.set_output(r.float()?);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_and_limit() {
        assert_eq!(coil_split(-0.5), (0.5, 0.0));
        assert_eq!(coil_split(0.7), (0.0, 0.7));
        let mut c = Converter::new(ConverterParams::default(), 1e-3);
        assert_eq!(c.voltage_for(1.25), 10.0);
        assert_eq!(c.step(10.0), 1.25);
        assert_eq!(c.step(100.0), 1.5);
        assert_eq!(c.step(-3.0), 0.0);
    }

    /// A current command gives the bits of its voltage stepped, zeros of both signs included, with and without a
    /// bandwidth limit.
    #[test]
    fn a_current_command_is_its_voltage_to_the_bit() {
        for bandwidth_hz in [None, Some(200.0)] {
            let params = ConverterParams {
                gain_a_per_v: 0.3,
                bandwidth_hz,
                ..ConverterParams::default()
            };
            let (mut by_voltage, mut by_current) = (
                Converter::new(params.clone(), 1e-3),
                Converter::new(params, 1e-3),
            );
            for i in 0..400 {
                let a = match i % 5 {
                    0 => 0.0,
                    1 => -0.0,
                    _ => 2.0 * libm::sin(0.37 * i as f64),
                };
                let v = by_voltage.step(by_voltage.voltage_for(a));
                assert_eq!(v.to_bits(), by_current.step_current(a).to_bits(), "{a}");
            }
        }
    }
}
