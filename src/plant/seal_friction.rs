//! Angle-periodic seal friction (paper eq 21): `T_f(θ) = c0 + Σ_{k=1..3} A_k sin(kθ + φ_k)` in N·mm, evaluated
//! as the compensator evaluates its own (one `sincos` of θ and the angle-addition recurrence, see
//! [`crate::friction::harmonic_series`]).

use super::{PlantError, check_range};
use crate::friction::{Friction, MAX_ORDER};

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
        if self.harmonics.len() > MAX_ORDER {
            return Err(PlantError::InvalidParameter(format!(
                "friction: {} harmonics, at most {MAX_ORDER}",
                self.harmonics.len()
            )));
        }
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

    /// The friction in the evaluated form (sine/cosine coefficients, [`crate::friction::Friction`]) with the
    /// actuator's extra harmonic `(order, amplitude N·mm, phase rad)` and its growth per ampere of field current.
    pub fn evaluated(
        &self,
        extra_harmonic: Option<(usize, f64, f64)>,
        gain_per_a: f64,
    ) -> Result<Friction<MAX_ORDER>, PlantError> {
        let (amplitudes, phases): (Vec<f64>, Vec<f64>) = self.harmonics.iter().copied().unzip();
        let bad = |e: crate::friction::FrictionError| PlantError::InvalidParameter(format!("{e}"));
        let mut f =
            Friction::from_amplitude_phase(self.offset_nmm, &amplitudes, &phases).map_err(bad)?;
        if let Some((order, amplitude_nmm, phase_rad)) = extra_harmonic {
            f = f
                .with_harmonic(order, amplitude_nmm, phase_rad)
                .map_err(bad)?;
        }
        f.with_current_gain(gain_per_a).map_err(bad)
    }
}
