//! MR fluid: field-dependent yield stress `tau_y(B)` and Bingham viscosity.

use super::{PlantError, check_range};

/// How the yield stress depends on the flux density in the gap.
#[derive(Clone, Debug, PartialEq)]
pub enum YieldStress {
    /// MRF-132DG cubic fit `0.82 + 19.79 B + 90.39 B² − 60.19 B³` kPa of `|B|` for 0 ≤ |B| ≤ 0.8 T; above
    /// 0.8 T it saturates smoothly (slope-continuous `tanh` tail adding at most `slope(0.8 T) × 0.1 T`).
    Mrf132dg,
    /// Linear in the signed flux density: `kpa_per_t · B` (no zero-field stress). Makes torque an exactly
    /// linear map of B (the `ideal` preset).
    Linear { kpa_per_t: f64 },
}

/// The fluid in the gaps.
#[derive(Clone, Debug, PartialEq)]
pub struct MrFluid {
    pub yield_stress: YieldStress,
    /// Off-state (plastic) viscosity, Pa·s (MRF-132DG: about 0.11 at 40 °C).
    pub viscosity_pa_s: f64,
}

const CUBIC_END_T: f64 = 0.8;
const TAIL_WIDTH_T: f64 = 0.1;

fn cubic_kpa(b: f64) -> f64 {
    0.82 + b * (19.79 + b * (90.39 - 60.19 * b))
}

fn cubic_slope_kpa_per_t(b: f64) -> f64 {
    19.79 + b * (2.0 * 90.39 - 3.0 * 60.19 * b)
}

impl MrFluid {
    pub fn mrf132dg() -> Self {
        MrFluid {
            yield_stress: YieldStress::Mrf132dg,
            viscosity_pa_s: 0.11,
        }
    }

    pub fn validate(&self) -> Result<(), PlantError> {
        check_range("fluid.viscosity_pa_s", self.viscosity_pa_s, 0.0, 100.0)?;
        if let YieldStress::Linear { kpa_per_t } = self.yield_stress {
            check_range("fluid.kpa_per_t", kpa_per_t, 0.0, 1e4)?;
        }
        Ok(())
    }

    /// Yield stress (kPa) at flux density `b_t` (T).
    #[inline]
    pub fn yield_stress_kpa(&self, b_t: f64) -> f64 {
        match self.yield_stress {
            YieldStress::Linear { kpa_per_t } => kpa_per_t * b_t,
            YieldStress::Mrf132dg => {
                let b = b_t.abs();
                if b <= CUBIC_END_T {
                    cubic_kpa(b)
                } else {
                    let s = cubic_slope_kpa_per_t(CUBIC_END_T);
                    cubic_kpa(CUBIC_END_T)
                        + s * TAIL_WIDTH_T * libm::tanh((b - CUBIC_END_T) / TAIL_WIDTH_T)
                }
            }
        }
    }

    /// Bingham viscous stress (kPa) at shear rate `shear_per_s` (1/s).
    #[inline]
    pub fn viscous_stress_kpa(&self, shear_per_s: f64) -> f64 {
        self.viscosity_pa_s * shear_per_s * 1e-3
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubic_matches_datasheet_points_and_is_monotone() {
        let f = MrFluid::mrf132dg();
        assert!((f.yield_stress_kpa(0.0) - 0.82).abs() < 1e-12);
        assert!((f.yield_stress_kpa(0.8) - 43.68432).abs() < 1e-9);
        let mut prev = f.yield_stress_kpa(0.0);
        for k in 1..200 {
            let t = f.yield_stress_kpa(0.01 * k as f64);
            assert!(t > prev);
            prev = t;
        }
        assert!(f.yield_stress_kpa(2.0) < 50.0);
        assert_eq!(f.yield_stress_kpa(-0.3), f.yield_stress_kpa(0.3));
    }
}
