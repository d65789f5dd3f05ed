//! Calibrated configurations of the virtual actuator.
//!
//! - `bmr2013`: the paper's rig (Nguyen & Choi). +1.25 A gives about +615 N·mm and −1.25 A about −590 N·mm
//!   (paper: about ±600); off-state seal friction spans −19.9…49.8 N·mm over a revolution (figs 11-12: about
//!   −20…50); the major loop is at most about 85 N·mm wide, near ±0.5 A (figs 14-15). It is physically honest
//!   rather than CBH-shaped: the MRF-132DG yield stress makes torque a nonlinear map of the flux density, the
//!   steel has a broad switching-field spread (coercivity 0.05 A ± 0.1 A, 35 % reversible), the two circuits
//!   differ slightly, and the coils have a real field lag (`coil_lag` on, 8 ms). Sensor noise 1.5 N·mm (std),
//!   0.19 N·mm steps; rotors at 1 rev/s with 1 % speed ripple.
//! - `ideal`: exactly Preisach in the nominal current — torque linear in B, no viscous drag, no friction, no
//!   lag, a perfect sensor. The CBH model built from its first-order curves reproduces it to round-off.
//! - `rig_preisach`: the `ideal` field path (exactly Preisach, no lag) with the rig's seal friction, speed ripple
//!   and torque sensor: the paper's model is exactly right up to sensor noise, so any effect switched on is the
//!   only thing the model misses (the reference plant of diagnosis studies).

use super::PlantError;
use super::converter::ConverterParams;
use super::effects::{Effect, EffectSet};
use super::mr_fluid::{MrFluid, YieldStress};
use super::rotor_drive::DriveParams;
use super::rotor_geometry::RotorGeometry;
use super::seal_friction::SealFriction;
use super::steel_preisach::SteelParams;
use super::torque_sensor::SensorParams;
use super::virtual_actuator::ActuatorConfig;

/// Names accepted by [`preset`].
pub const PRESETS: [&str; 3] = ["bmr2013", "ideal", "rig_preisach"];

/// Default sample rate of the presets, Hz.
pub const DEFAULT_SAMPLE_RATE_HZ: f64 = 1000.0;

/// The configuration of a preset by name.
pub fn preset(name: &str) -> Result<ActuatorConfig, PlantError> {
    match name {
        "bmr2013" => Ok(bmr2013()),
        "ideal" => Ok(ideal()),
        "rig_preisach" => Ok(rig_preisach()),
        _ => Err(PlantError::UnknownPreset(name.to_string())),
    }
}

fn bmr2013_steel() -> SteelParams {
    SteelParams {
        saturation_t: 0.53,
        coercivity_a: 0.05,
        coercivity_width_a: 0.1,
        interaction_width_a: 0.9,
        reversible_fraction: 0.35,
        reversible_width_a: 1.0,
        range_a: 3.0,
        grid: 241,
    }
}

/// The paper's rig.
pub fn bmr2013() -> ActuatorConfig {
    let steel2 = bmr2013_steel();
    // The two circuits are machined separately: coil 1 saturates slightly lower and is a bit harder.
    let steel1 = SteelParams {
        saturation_t: steel2.saturation_t * 0.97,
        coercivity_a: steel2.coercivity_a * 1.08,
        ..steel2.clone()
    };
    let mut effects = EffectSet::new();
    effects.insert(Effect::CoilLag { tau_s: 0.008 });
    ActuatorConfig {
        name: "bmr2013 virtual actuator (Nguyen & Choi BMR rig)".to_string(),
        sample_rate_hz: DEFAULT_SAMPLE_RATE_HZ,
        converter: ConverterParams::default(),
        steel1,
        steel2,
        fluid: MrFluid::mrf132dg(),
        geometry: RotorGeometry::default(),
        drive: DriveParams {
            speed_rad_s: core::f64::consts::TAU,
            speed_ripple: 0.01,
            theta0_rad: 0.0,
        },
        friction: SealFriction {
            offset_nmm: 20.0,
            harmonics: vec![(30.0, 0.4), (9.3, 1.9), (4.6, -0.7)],
        },
        sensor: SensorParams::default(),
        full_current_a: 1.25,
        full_torque_nmm: 600.0,
        effects,
    }
}

/// Exactly Preisach in the nominal current (for tests).
pub fn ideal() -> ActuatorConfig {
    let steel = bmr2013_steel();
    ActuatorConfig {
        name: "ideal virtual actuator (exactly Preisach)".to_string(),
        sample_rate_hz: DEFAULT_SAMPLE_RATE_HZ,
        converter: ConverterParams::default(),
        steel1: steel.clone(),
        steel2: steel,
        fluid: MrFluid {
            yield_stress: YieldStress::Linear { kpa_per_t: 48.5 },
            viscosity_pa_s: 0.0,
        },
        geometry: RotorGeometry::default(),
        drive: DriveParams::default(),
        friction: SealFriction::none(),
        sensor: SensorParams::perfect(),
        full_current_a: 1.25,
        full_torque_nmm: 600.0,
        effects: EffectSet::new(),
    }
}

/// Exactly Preisach in the nominal current, with the rig's seal friction, drive and sensor.
pub fn rig_preisach() -> ActuatorConfig {
    let rig = bmr2013();
    ActuatorConfig {
        name: "rig_preisach virtual actuator (Preisach field path, rig friction and sensor)"
            .to_string(),
        drive: rig.drive,
        friction: rig.friction,
        sensor: rig.sensor,
        ..ideal()
    }
}
