//! Switchable physical effects of the virtual actuator (the effect vocabulary, docs/architecture.md §4).
//!
//! The effect set is data: an [`Effect`] enum carrying its parameters, parsed from `"name:key=value,…"`
//! strings. Each effect changes the data with its documented signature and nothing else.

use super::PlantError;
use std::fmt;

/// A parameter of an effect: name, unit, default and valid range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    pub name: &'static str,
    pub unit: &'static str,
    pub default: f64,
    pub min: f64,
    pub max: f64,
    pub doc: &'static str,
}

/// The names of the effect vocabulary, in the order the diagnosis tries them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum EffectKind {
    CoilLag,
    ThermalDrift,
    FrictionCurrent,
    FrictionHarmonics,
    TorqueRipple,
    SensorDrift,
    TimeDelay,
    NonCongruent,
}

impl EffectKind {
    pub const ALL: [EffectKind; 8] = [
        EffectKind::CoilLag,
        EffectKind::ThermalDrift,
        EffectKind::FrictionCurrent,
        EffectKind::FrictionHarmonics,
        EffectKind::TorqueRipple,
        EffectKind::SensorDrift,
        EffectKind::TimeDelay,
        EffectKind::NonCongruent,
    ];

    pub fn name(self) -> &'static str {
        match self {
            EffectKind::CoilLag => "coil_lag",
            EffectKind::ThermalDrift => "thermal_drift",
            EffectKind::FrictionCurrent => "friction_current",
            EffectKind::FrictionHarmonics => "friction_harmonics",
            EffectKind::TorqueRipple => "torque_ripple",
            EffectKind::SensorDrift => "sensor_drift",
            EffectKind::TimeDelay => "time_delay",
            EffectKind::NonCongruent => "non_congruent",
        }
    }

    pub fn from_name(name: &str) -> Result<Self, PlantError> {
        EffectKind::ALL
            .iter()
            .copied()
            .find(|k| k.name() == name)
            .ok_or_else(|| {
                PlantError::InvalidEffect(format!(
                    "unknown effect {name:?}; known effects: {}",
                    EffectKind::ALL.map(|k| k.name()).join(", ")
                ))
            })
    }

    /// The physics and the signature it leaves in the data.
    pub fn doc(self) -> &'static str {
        match self {
            EffectKind::CoilLag => {
                "The field lags the coil current (coil L/R, eddy currents): each coil's magnetising current is a \
                 first-order lag of the converter current with time constant tau_s. Signature: residual \
                 proportional to the current rate; loops widen with frequency."
            }
            EffectKind::ThermalDrift => {
                "Coil heating lowers the torque gain: a thermal state driven by (I/I_full)^2 with time constant \
                 tau_s scales the field torque by (1 - gain_loss * state). Signature: slow multiplicative drift."
            }
            EffectKind::FrictionCurrent => {
                "Seal friction grows with current (magnetic pull on the seals): the angle-dependent friction is \
                 scaled by (1 + gain_per_a * |I|). Signature: angle ripple whose size grows with |current|."
            }
            EffectKind::FrictionHarmonics => {
                "A friction harmonic above the 3rd (gear mesh, seal lobes): amplitude_nmm * sin(order * theta + \
                 phase_rad). Signature: a periodogram line at order cycles/rev."
            }
            EffectKind::TorqueRipple => {
                "Eccentric gap: the field torque is multiplied by (1 + eps * cos(theta + phase_rad)). Signature: \
                 angle ripple proportional to |torque|."
            }
            EffectKind::SensorDrift => {
                "The torque sensor offset drifts linearly with time at rate_nmm_per_s (from the actuator's start). \
                 Signature: a trend in zero-torque segments."
            }
            EffectKind::TimeDelay => {
                "Pure delay of delay_s (rounded to whole samples) between the commanded current and the coils. \
                 Signature: residual proportional to rate, no loop widening with amplitude."
            }
            EffectKind::NonCongruent => {
                "Extra output nonlinearity after the Preisach core: each rotor's field torque T becomes \
                 T_full * n (1 + curvature |n|) / (1 + curvature) with n = T / T_full. Signature: error only \
                 after higher-order reversals (minor loops scale with the local slope)."
            }
        }
    }

    pub fn params(self) -> &'static [ParamSpec] {
        match self {
            EffectKind::CoilLag => COIL_LAG,
            EffectKind::ThermalDrift => THERMAL_DRIFT,
            EffectKind::FrictionCurrent => FRICTION_CURRENT,
            EffectKind::FrictionHarmonics => FRICTION_HARMONICS,
            EffectKind::TorqueRipple => TORQUE_RIPPLE,
            EffectKind::SensorDrift => SENSOR_DRIFT,
            EffectKind::TimeDelay => TIME_DELAY,
            EffectKind::NonCongruent => NON_CONGRUENT,
        }
    }
}

const fn p(
    name: &'static str,
    unit: &'static str,
    default: f64,
    min: f64,
    max: f64,
    doc: &'static str,
) -> ParamSpec {
    ParamSpec {
        name,
        unit,
        default,
        min,
        max,
        doc,
    }
}

const COIL_LAG: &[ParamSpec] = &[p(
    "tau_s",
    "s",
    0.02,
    0.0,
    10.0,
    "first-order field time constant",
)];
const THERMAL_DRIFT: &[ParamSpec] = &[
    p(
        "gain_loss",
        "1",
        0.08,
        0.0,
        0.9,
        "fractional torque-gain loss at steady full current",
    ),
    p("tau_s", "s", 120.0, 1e-3, 1e6, "thermal time constant"),
];
const FRICTION_CURRENT: &[ParamSpec] = &[p(
    "gain_per_a",
    "1/A",
    0.6,
    0.0,
    100.0,
    "relative growth of the angle-dependent friction per ampere of |I|",
)];
const FRICTION_HARMONICS: &[ParamSpec] = &[
    p(
        "order",
        "cycles/rev",
        5.0,
        4.0,
        12.0,
        "harmonic number k (integer 4..12)",
    ),
    p("amplitude_nmm", "N·mm", 6.0, -1e4, 1e4, "amplitude"),
    p("phase_rad", "rad", 0.0, -1e3, 1e3, "phase"),
];
const TORQUE_RIPPLE: &[ParamSpec] = &[
    p(
        "eps",
        "1",
        0.05,
        0.0,
        0.9,
        "relative field-torque modulation",
    ),
    p(
        "phase_rad",
        "rad",
        0.0,
        -1e3,
        1e3,
        "phase of the once-per-revolution modulation",
    ),
];
const SENSOR_DRIFT: &[ParamSpec] = &[p(
    "rate_nmm_per_s",
    "N·mm/s",
    0.02,
    -1e3,
    1e3,
    "offset drift rate",
)];
const TIME_DELAY: &[ParamSpec] = &[p("delay_s", "s", 0.01, 0.0, 1.0, "command-to-coil delay")];
const NON_CONGRUENT: &[ParamSpec] = &[p(
    "curvature",
    "1",
    1.0,
    -0.45,
    5.0,
    "output nonlinearity strength (0 = off; >0 convex, <0 concave)",
)];

impl fmt::Display for EffectKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One effect with its parameters (units in the names).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Effect {
    CoilLag {
        tau_s: f64,
    },
    ThermalDrift {
        gain_loss: f64,
        tau_s: f64,
    },
    FrictionCurrent {
        gain_per_a: f64,
    },
    FrictionHarmonics {
        order: u32,
        amplitude_nmm: f64,
        phase_rad: f64,
    },
    TorqueRipple {
        eps: f64,
        phase_rad: f64,
    },
    SensorDrift {
        rate_nmm_per_s: f64,
    },
    TimeDelay {
        delay_s: f64,
    },
    NonCongruent {
        curvature: f64,
    },
}

impl Effect {
    pub fn kind(&self) -> EffectKind {
        match self {
            Effect::CoilLag { .. } => EffectKind::CoilLag,
            Effect::ThermalDrift { .. } => EffectKind::ThermalDrift,
            Effect::FrictionCurrent { .. } => EffectKind::FrictionCurrent,
            Effect::FrictionHarmonics { .. } => EffectKind::FrictionHarmonics,
            Effect::TorqueRipple { .. } => EffectKind::TorqueRipple,
            Effect::SensorDrift { .. } => EffectKind::SensorDrift,
            Effect::TimeDelay { .. } => EffectKind::TimeDelay,
            Effect::NonCongruent { .. } => EffectKind::NonCongruent,
        }
    }

    pub fn name(&self) -> &'static str {
        self.kind().name()
    }

    /// The effect with its default parameters.
    pub fn default_of(kind: EffectKind) -> Effect {
        Effect::from_params(kind, &[]).expect("defaults are valid")
    }

    /// Build an effect from `(key, value)` pairs; missing keys take their defaults. Unknown keys and values
    /// outside the documented range are errors naming the effect and the key.
    pub fn from_params(kind: EffectKind, given: &[(&str, f64)]) -> Result<Effect, PlantError> {
        let specs = kind.params();
        let mut values: Vec<f64> = specs.iter().map(|s| s.default).collect();
        for &(key, value) in given {
            let Some(i) = specs.iter().position(|s| s.name == key) else {
                return Err(PlantError::InvalidEffect(format!(
                    "effect {kind} has no parameter {key:?}; its parameters: {}",
                    specs.iter().map(|s| s.name).collect::<Vec<_>>().join(", ")
                )));
            };
            let s = &specs[i];
            if !(value.is_finite() && value >= s.min && value <= s.max) {
                return Err(PlantError::InvalidEffect(format!(
                    "effect {kind}: {key} = {value} {} is outside [{}, {}]",
                    s.unit, s.min, s.max
                )));
            }
            values[i] = value;
        }
        Ok(match kind {
            EffectKind::CoilLag => Effect::CoilLag { tau_s: values[0] },
            EffectKind::ThermalDrift => Effect::ThermalDrift {
                gain_loss: values[0],
                tau_s: values[1],
            },
            EffectKind::FrictionCurrent => Effect::FrictionCurrent {
                gain_per_a: values[0],
            },
            EffectKind::FrictionHarmonics => {
                if values[0].fract() != 0.0 {
                    return Err(PlantError::InvalidEffect(format!(
                        "effect friction_harmonics: order = {} must be a whole number in 4..12",
                        values[0]
                    )));
                }
                Effect::FrictionHarmonics {
                    order: values[0] as u32,
                    amplitude_nmm: values[1],
                    phase_rad: values[2],
                }
            }
            EffectKind::TorqueRipple => Effect::TorqueRipple {
                eps: values[0],
                phase_rad: values[1],
            },
            EffectKind::SensorDrift => Effect::SensorDrift {
                rate_nmm_per_s: values[0],
            },
            EffectKind::TimeDelay => Effect::TimeDelay { delay_s: values[0] },
            EffectKind::NonCongruent => Effect::NonCongruent {
                curvature: values[0],
            },
        })
    }

    /// Parameters as `(name, value)` in the order of [`EffectKind::params`].
    pub fn params(&self) -> Vec<(&'static str, f64)> {
        let values: Vec<f64> = match *self {
            Effect::CoilLag { tau_s } => vec![tau_s],
            Effect::ThermalDrift { gain_loss, tau_s } => vec![gain_loss, tau_s],
            Effect::FrictionCurrent { gain_per_a } => vec![gain_per_a],
            Effect::FrictionHarmonics {
                order,
                amplitude_nmm,
                phase_rad,
            } => vec![order as f64, amplitude_nmm, phase_rad],
            Effect::TorqueRipple { eps, phase_rad } => vec![eps, phase_rad],
            Effect::SensorDrift { rate_nmm_per_s } => vec![rate_nmm_per_s],
            Effect::TimeDelay { delay_s } => vec![delay_s],
            Effect::NonCongruent { curvature } => vec![curvature],
        };
        self.kind()
            .params()
            .iter()
            .map(|s| s.name)
            .zip(values)
            .collect()
    }

    /// Parse `"name"` or `"name:key=value,key=value"`.
    pub fn parse(text: &str) -> Result<Effect, PlantError> {
        let text = text.trim();
        let (name, rest) = match text.split_once(':') {
            Some((n, r)) => (n.trim(), Some(r)),
            None => (text, None),
        };
        let kind = EffectKind::from_name(name)?;
        let mut given = Vec::new();
        if let Some(rest) = rest {
            for item in rest.split(',').map(str::trim).filter(|s| !s.is_empty()) {
                let Some((key, value)) = item.split_once('=') else {
                    return Err(PlantError::InvalidEffect(format!(
                        "effect {kind}: expected key=value, got {item:?} (in {text:?})"
                    )));
                };
                let key = key.trim();
                let value: f64 = value.trim().parse().map_err(|_| {
                    PlantError::InvalidEffect(format!(
                        "effect {kind}: {key} = {:?} is not a number (in {text:?})",
                        value.trim()
                    ))
                })?;
                given.push((key, value));
            }
        }
        Effect::from_params(kind, &given)
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.name())?;
        let params = self.params();
        for (i, (k, v)) in params.iter().enumerate() {
            write!(f, "{}{k}={v}", if i == 0 { ':' } else { ',' })?;
        }
        Ok(())
    }
}

/// At most one effect of each kind, in vocabulary order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EffectSet {
    effects: Vec<Effect>,
}

impl EffectSet {
    pub fn new() -> Self {
        EffectSet::default()
    }

    /// Parse a list of effect strings (later entries replace earlier ones of the same kind).
    pub fn parse_all<S: AsRef<str>>(items: &[S]) -> Result<EffectSet, PlantError> {
        let mut set = EffectSet::new();
        for s in items {
            set.insert(Effect::parse(s.as_ref())?);
        }
        Ok(set)
    }

    /// Add or replace the effect of this kind.
    pub fn insert(&mut self, effect: Effect) {
        self.remove(effect.kind());
        self.effects.push(effect);
        self.effects.sort_by_key(|e| e.kind());
    }

    pub fn remove(&mut self, kind: EffectKind) {
        self.effects.retain(|e| e.kind() != kind);
    }

    pub fn get(&self, kind: EffectKind) -> Option<&Effect> {
        self.effects.iter().find(|e| e.kind() == kind)
    }

    pub fn iter(&self) -> impl Iterator<Item = &Effect> {
        self.effects.iter()
    }

    pub fn is_empty(&self) -> bool {
        self.effects.is_empty()
    }

    pub fn len(&self) -> usize {
        self.effects.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_round_trip_and_errors() {
        let e = Effect::parse("coil_lag:tau_s=0.05").unwrap();
        assert_eq!(e, Effect::CoilLag { tau_s: 0.05 });
        assert_eq!(Effect::parse(&e.to_string()).unwrap(), e);
        assert_eq!(
            Effect::parse("time_delay").unwrap(),
            Effect::TimeDelay { delay_s: 0.01 }
        );
        let h = Effect::parse(" friction_harmonics : order=7, amplitude_nmm=3 ").unwrap();
        assert_eq!(
            h,
            Effect::FrictionHarmonics {
                order: 7,
                amplitude_nmm: 3.0,
                phase_rad: 0.0
            }
        );
        let msg = |s: &str| Effect::parse(s).unwrap_err().to_string();
        assert!(msg("coil_lagg").contains("known effects: coil_lag"));
        assert!(msg("coil_lag:tau=1").contains("its parameters: tau_s"));
        assert!(msg("coil_lag:tau_s=abc").contains("not a number"));
        assert!(msg("coil_lag:tau_s=-1").contains("outside"));
        assert!(msg("friction_harmonics:order=3").contains("outside"));
        assert!(msg("friction_harmonics:order=4.5").contains("whole number"));
        assert!(msg("coil_lag:tau_s").contains("key=value"));
        for k in EffectKind::ALL {
            assert_eq!(EffectKind::from_name(k.name()).unwrap(), k);
            assert_eq!(Effect::default_of(k).kind(), k);
        }
    }

    #[test]
    fn set_replaces_same_kind_and_keeps_order() {
        let set = EffectSet::parse_all(&["time_delay", "coil_lag:tau_s=0.1", "coil_lag:tau_s=0.2"])
            .unwrap();
        assert_eq!(set.len(), 2);
        assert_eq!(set.iter().next().unwrap(), &Effect::CoilLag { tau_s: 0.2 });
    }
}
