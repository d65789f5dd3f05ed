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

#[cfg(test)]
mod tests {
    use super::*;

    /// The evaluated form is the paper's `c0 + (1 + g|I|) Σ A_k sin(kθ + φ_k)` (plus the extra harmonic) to
    /// round-off, over more than a turn and both current signs.
    #[test]
    fn the_evaluated_form_is_the_amplitude_phase_sum() {
        let f = SealFriction {
            offset_nmm: 20.0,
            harmonics: vec![(30.0, 0.4), (9.3, 1.9), (4.6, -0.7)],
        };
        let (g, extra) = (0.3, (6, 4.0, -0.3));
        let e = f.evaluated(Some(extra), g).unwrap();
        for i in 0..5000 {
            let th = -1.0 + 0.0017 * i as f64;
            let current = 1.25 * libm::sin(0.01 * i as f64);
            let ripple: f64 = f
                .harmonics
                .iter()
                .enumerate()
                .map(|(k, &(a, p))| a * libm::sin((k + 1) as f64 * th + p))
                .sum::<f64>()
                + extra.1 * libm::sin(extra.0 as f64 * th + extra.2);
            let want = f.offset_nmm + ripple * (1.0 + g * current.abs());
            let got = e.eval_at(th, current);
            assert!((got - want).abs() < 1e-12, "θ={th}: {got} vs {want}");
        }
    }

    #[test]
    fn more_harmonics_than_the_series_holds_are_refused() {
        let f = SealFriction {
            offset_nmm: 0.0,
            harmonics: vec![(1.0, 0.0); MAX_ORDER + 1],
        };
        let e = f.validate().unwrap_err().to_string();
        assert!(e.contains(&format!("at most {MAX_ORDER}")), "{e}");
        assert!(
            SealFriction::none()
                .evaluated(Some((MAX_ORDER + 1, 1.0, 0.0)), 0.0)
                .is_err()
        );
    }
}
