//! Angle-periodic seal friction (paper eq 21): `T_f(θ) = c0 + Σ_{k=1..3} A_k sin(kθ + φ_k)` in N·mm.

use super::{PlantError, check_range};

#[derive(Clone, Debug, PartialEq)]
pub struct SealFriction {
    /// Mean friction torque, N·mm.
    pub offset_nmm: f64,
    /// Amplitude (N·mm) and phase (rad) of harmonics k = 1, 2, 3, … (at least three on the rig).
    pub harmonics: Vec<(f64, f64)>,
}

impl SealFriction {
    pub fn none() -> Self {
        SealFriction {
            offset_nmm: 0.0,
            harmonics: Vec::new(),
        }
    }

    pub fn validate(&self) -> Result<(), PlantError> {
        check_range("friction.offset_nmm", self.offset_nmm, -1e4, 1e4)?;
        for (k, &(a, p)) in self.harmonics.iter().enumerate() {
            check_range(
                &format!("friction.harmonic[{}].amplitude_nmm", k + 1),
                a,
                -1e4,
                1e4,
            )?;
            check_range(
                &format!("friction.harmonic[{}].phase_rad", k + 1),
                p,
                -1e3,
                1e3,
            )?;
        }
        Ok(())
    }

    /// The angle-dependent part `Σ A_k sin(kθ + φ_k)` (N·mm).
    #[inline]
    pub fn ripple_nmm(&self, theta_rad: f64) -> f64 {
        self.harmonics
            .iter()
            .enumerate()
            .map(|(k, &(a, p))| a * libm::sin((k + 1) as f64 * theta_rad + p))
            .sum()
    }

    /// Full friction torque (N·mm) at angle `theta_rad`.
    #[inline]
    pub fn torque_nmm(&self, theta_rad: f64) -> f64 {
        self.offset_nmm + self.ripple_nmm(theta_rad)
    }
}
