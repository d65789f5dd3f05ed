//! The virtual BMR actuator: a physical simulator richer than the CBH model, used as "measured" data.
//!
//! The physics chain, one stage per file:
//! command → [`effects`] time delay → [`converter`] (voltage→current, coil split, eq 8) → coil lag →
//! [`steel_preisach`] (coil current → gap flux density, one hysteretic circuit per coil) → [`mr_fluid`]
//! (yield stress and Bingham viscosity) → [`rotor_geometry`] (eq 7, torque per rotor) → `T = T2 − T1` →
//! [`seal_friction`] (angle-periodic, θ from [`rotor_drive`]) → [`torque_sensor`] (lever, noise, quantisation).
//! [`presets`] holds calibrated configurations; [`virtual_actuator`] wires the stages together.

pub mod closed_loop;
pub mod converter;
pub mod device;
pub mod effects;
pub mod mr_fluid;
pub mod presets;
pub mod rng;
pub mod rotor_drive;
pub mod rotor_geometry;
pub mod seal_friction;
pub mod steel_preisach;
pub mod torque_sensor;
pub mod virtual_actuator;

pub use closed_loop::run_closed_loop;
pub use device::{
    DEVICE_PRESETS, DEVICE_SETTABLE, DeviceConfig, DeviceSample, VirtualDevice, device_preset,
};
pub use effects::{Effect, EffectKind, EffectSet, ParamSpec};
pub use presets::{PRESETS, preset};
pub use virtual_actuator::{ActuatorConfig, SETTABLE, Sample, Trace, VirtualActuator};

use std::fmt;

/// Everything that can be wrong when configuring the virtual actuator.
#[derive(Clone, Debug, PartialEq)]
pub enum PlantError {
    /// A configuration value is out of its physical range; the message names the parameter.
    InvalidParameter(String),
    /// An effect string or parameter could not be understood; the message says which and lists the valid ones.
    InvalidEffect(String),
    /// No preset by that name.
    UnknownPreset(String),
    /// A serialised simulator state that is damaged or belongs to another configuration.
    BadState(&'static str),
}

impl fmt::Display for PlantError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PlantError::InvalidParameter(m) | PlantError::InvalidEffect(m) => f.write_str(m),
            PlantError::BadState(what) => {
                write!(f, "serialised virtual actuator state is not valid: {what}")
            }
            PlantError::UnknownPreset(name) => write!(
                f,
                "unknown virtual actuator preset {name:?}; available: {}",
                PRESETS.join(", ")
            ),
        }
    }
}

impl std::error::Error for PlantError {}

/// Reads back the dynamic state words a simulator wrote (pickling), checking each value as it goes.
pub(crate) struct StateReader<'a> {
    words: &'a [u64],
}

impl<'a> StateReader<'a> {
    pub(crate) fn new(words: &'a [u64]) -> Self {
        StateReader { words }
    }

    pub(crate) fn word(&mut self) -> Result<u64, PlantError> {
        let (&first, rest) = self
            .words
            .split_first()
            .ok_or(PlantError::BadState("too few words"))?;
        self.words = rest;
        Ok(first)
    }

    /// A finite float.
    pub(crate) fn float(&mut self) -> Result<f64, PlantError> {
        let v = f64::from_bits(self.word()?);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(PlantError::BadState("a state value is not finite"))
        }
    }

    /// A count no larger than the words left (so that nothing is allocated beyond the input's size).
    pub(crate) fn count(&mut self) -> Result<usize, PlantError> {
        let n = self.word()?;
        match usize::try_from(n) {
            Ok(n) if n <= self.words.len() => Ok(n),
            _ => Err(PlantError::BadState("a length is larger than the state")),
        }
    }

    pub(crate) fn finish(self) -> Result<(), PlantError> {
        if self.words.is_empty() {
            Ok(())
        } else {
            Err(PlantError::BadState("words left over"))
        }
    }
}

/// `value` rounded to a multiple of `step` (a sensor's resolution); 0 = none. A step so fine that the value holds
/// 2^52 or more of them (e.g. a subnormal resolution) quantises nothing and the value is returned as it is,
/// where `value / step` would overflow to infinity.
#[inline]
pub(crate) fn quantise(value: f64, step: f64) -> f64 {
    const EXACT_STEPS: f64 = 4_503_599_627_370_496.0; // 2^52: every f64 this large is already a whole number
    if step > 0.0 {
        let steps = value / step;
        if steps.abs() < EXACT_STEPS {
            return libm::round(steps) * step;
        }
    }
    value
}

/// Check that `value` is finite and within `[lo, hi]`; the error names `what` and its unit.
pub(crate) fn check_range(what: &str, value: f64, lo: f64, hi: f64) -> Result<f64, PlantError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(PlantError::InvalidParameter(format!(
            "{what} = {value} is outside [{lo}, {hi}]"
        )))
    }
}
