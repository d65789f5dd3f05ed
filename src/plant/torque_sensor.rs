//! Torque sensor: a force sensor on a lever (Nano17 on the paper's rig) with noise, quantisation, range and an
//! optional offset. Torque = lever × force.

use super::rng::Rng;
use super::{PlantError, check_range, quantise};

#[derive(Clone, Debug, PartialEq)]
pub struct SensorParams {
    /// Lever arm from the actuator axis to the force sensor, mm.
    pub lever_mm: f64,
    /// Standard deviation of the force noise, N.
    pub noise_n: f64,
    /// Force resolution (quantisation step), N; 0 = none.
    pub resolution_n: f64,
    /// Force range (clips beyond ±range), N.
    pub range_n: f64,
    /// Constant force offset (untared sensor), N.
    pub offset_n: f64,
}

impl Default for SensorParams {
    fn default() -> Self {
        SensorParams {
            lever_mm: 60.0,
            noise_n: 0.025,
            resolution_n: 1.0 / 320.0,
            range_n: 12.0,
            offset_n: 0.0,
        }
    }
}

impl SensorParams {
    /// Noise-free, unquantised sensor with a wide range.
    pub fn perfect() -> Self {
        SensorParams {
            lever_mm: 60.0,
            noise_n: 0.0,
            resolution_n: 0.0,
            range_n: 1e6,
            offset_n: 0.0,
        }
    }

    pub fn validate(&self) -> Result<(), PlantError> {
        check_range("sensor.lever_mm", self.lever_mm, 1e-3, 1e4)?;
        check_range("sensor.noise_n", self.noise_n, 0.0, 1e3)?;
        check_range("sensor.resolution_n", self.resolution_n, 0.0, 1e3)?;
        check_range("sensor.range_n", self.range_n, 1e-6, 1e9)?;
        check_range("sensor.offset_n", self.offset_n, -1e3, 1e3)?;
        Ok(())
    }

    /// Torque noise standard deviation, N·mm.
    pub fn noise_nmm(&self) -> f64 {
        self.noise_n * self.lever_mm
    }

    /// Measure `torque_nmm` with an extra additive torque offset `drift_nmm` (sensor drift).
    #[inline]
    pub fn measure(&self, torque_nmm: f64, drift_nmm: f64, rng: &mut Rng) -> f64 {
        let noise = if self.noise_n > 0.0 {
            self.noise_n * rng.normal()
        } else {
            0.0
        };
        let force = ((torque_nmm + drift_nmm) / self.lever_mm + self.offset_n + noise)
            .clamp(-self.range_n, self.range_n);
        quantise(force, self.resolution_n) * self.lever_mm
    }
}
