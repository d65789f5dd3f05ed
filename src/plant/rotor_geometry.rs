//! Rotor geometry → torque (paper eq 7): two disc faces plus the drum, stresses uniform over the gap.
//!
//! Disc faces (both sides, radii `R_S..R_D`): `2 · 2π ∫ r² τ dr`; drum (radius `R_D`, width `L`):
//! `2π R_D² L τ`. With a yield stress `τ_y` that is `τ_y · [4π (R_D³ − R_S³)/3 + 2π R_D² L]`; with the
//! Bingham viscous stress `η r ω / h` it is `η ω [π (R_D⁴ − R_S⁴) + 2π R_D³ L] / h`. Lengths in mm, stresses
//! in kPa (1 kPa = 1e-3 N/mm²), torque in N·mm.

use super::{PlantError, check_range};
use core::f64::consts::PI;

#[derive(Clone, Debug, PartialEq)]
pub struct RotorGeometry {
    /// Shaft (inner) radius of the disc faces, mm.
    pub shaft_radius_mm: f64,
    /// Disc (outer) radius, mm.
    pub disc_radius_mm: f64,
    /// Drum width, mm.
    pub drum_width_mm: f64,
    /// MR fluid gap, mm.
    pub gap_mm: f64,
}

impl Default for RotorGeometry {
    fn default() -> Self {
        RotorGeometry {
            shaft_radius_mm: 5.0,
            disc_radius_mm: 17.0,
            drum_width_mm: 6.0,
            gap_mm: 0.8,
        }
    }
}

impl RotorGeometry {
    pub fn validate(&self) -> Result<(), PlantError> {
        check_range("geometry.shaft_radius_mm", self.shaft_radius_mm, 0.0, 1e3)?;
        check_range(
            "geometry.disc_radius_mm",
            self.disc_radius_mm,
            self.shaft_radius_mm + 1e-6,
            1e3,
        )?;
        check_range("geometry.drum_width_mm", self.drum_width_mm, 0.0, 1e3)?;
        check_range("geometry.gap_mm", self.gap_mm, 1e-3, 100.0)?;
        Ok(())
    }

    /// Torque (N·mm) per kPa of uniform shear stress over faces and drum.
    pub fn yield_torque_per_kpa(&self) -> f64 {
        let (rs, rd, l) = (
            self.shaft_radius_mm,
            self.disc_radius_mm,
            self.drum_width_mm,
        );
        // Plain products (not powi) so every platform rounds alike.
        1e-3 * (4.0 * PI * (rd * rd * rd - rs * rs * rs) / 3.0 + 2.0 * PI * rd * rd * l)
    }

    /// Viscous torque (N·mm) of a rotor at relative speed `omega_rad_s` in a fluid of viscosity `eta_pa_s`.
    pub fn viscous_torque_nmm(&self, eta_pa_s: f64, omega_rad_s: f64) -> f64 {
        self.viscous_drag(eta_pa_s).torque_nmm(omega_rad_s)
    }

    /// The speed-independent factors of the viscous torque in a fluid of viscosity `eta_pa_s`, computed once
    /// for a simulator whose fluid and geometry are fixed.
    pub fn viscous_drag(&self, eta_pa_s: f64) -> ViscousDrag {
        let (rs, rd, l) = (
            self.shaft_radius_mm,
            self.disc_radius_mm,
            self.drum_width_mm,
        );
        let (rd3, rs3) = (rd * rd * rd, rs * rs * rs);
        ViscousDrag {
            // eta in N·s/mm² is 1e-6 × Pa·s.
            eta_ns_per_mm2: eta_pa_s * 1e-6,
            geometry_mm4: PI * (rd3 * rd - rs3 * rs) + 2.0 * PI * rd3 * l,
            gap_mm: self.gap_mm,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn twenty_kpa_gives_about_600_nmm_and_viscous_is_small() {
        let g = RotorGeometry::default();
        let t = 20.0 * g.yield_torque_per_kpa();
        assert!((550.0..700.0).contains(&t), "{t}");
        let v = g.viscous_torque_nmm(0.11, 2.0 * PI);
        assert!(v > 0.05 && v < 2.0, "{v}");
    }
}

/// A rotor's viscous drag: `T = η·ω·G/h` with the fluid's viscosity `η` (N·s/mm²), the faces' and drum's
/// geometric factor `G = π(rd⁴ − rs⁴) + 2π·rd³·l` (mm⁴) and the gap `h` (mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViscousDrag {
    eta_ns_per_mm2: f64,
    geometry_mm4: f64,
    gap_mm: f64,
}

impl ViscousDrag {
    /// Viscous torque (N·mm) at relative speed `omega_rad_s` (rad/s).
    #[inline]
    pub fn torque_nmm(&self, omega_rad_s: f64) -> f64 {
        self.eta_ns_per_mm2 * omega_rad_s * self.geometry_mm4 / self.gap_mm
    }
}
