//! Switchable physical effects of the virtual actuator, in the terms of the effect vocabulary (docs/architecture.md
//! §4, [`crate::vocabulary`]): an [`Effect`] enum carrying its parameters, parsed from `"name:key=value,…"`
//! strings. Each effect changes the data with its documented signature and nothing else.

use super::PlantError;
pub use crate::vocabulary::{EffectKind, ParamSpec};
use crate::vocabulary::{NameList, Params, SPECS};
use std::fmt;

/// The effect named `name`, or an error listing the known ones.
pub fn kind_named(name: &str) -> Result<EffectKind, PlantError> {
    EffectKind::from_name(name).ok_or_else(|| {
        PlantError::InvalidEffect(format!(
            "unknown effect {name:?}; known effects: {}",
            NameList(SPECS)
        ))
    })
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
        settle_per_s: f64,
    },
    TimeDelay {
        delay_s: f64,
    },
    NonCongruent {
        curvature: f64,
        scale_nmm: f64,
        cubic: f64,
        feedback: f64,
    },
    Creep {
        fraction: f64,
        tau_min_s: f64,
        tau_max_s: f64,
        fluctuation: f64,
        tau0_s: f64,
    },
    RateDependence {
        tau_s: f64,
    },
    RunGainOffset {
        gain_sd: f64,
        offset_sd: f64,
    },
    Leakage {
        rate_per_s: f64,
        decay_per_s: f64,
    },
    Accommodation {
        kappa: f64,
        cycles: f64,
    },
    Viscous {
        c: f64,
        f_y: f64,
        v0: f64,
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
            Effect::Creep { .. } => EffectKind::Creep,
            Effect::RateDependence { .. } => EffectKind::RateDependence,
            Effect::RunGainOffset { .. } => EffectKind::RunGainOffset,
            Effect::Leakage { .. } => EffectKind::Leakage,
            Effect::Accommodation { .. } => EffectKind::Accommodation,
            Effect::Viscous { .. } => EffectKind::Viscous,
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
        let p = Params::new(kind.spec(), given)
            .map_err(|e| PlantError::InvalidEffect(e.to_string()))?;
        let v = p.values();
        Ok(match kind {
            EffectKind::CoilLag => Effect::CoilLag { tau_s: v[0] },
            EffectKind::ThermalDrift => Effect::ThermalDrift {
                gain_loss: v[0],
                tau_s: v[1],
            },
            EffectKind::FrictionCurrent => Effect::FrictionCurrent { gain_per_a: v[0] },
            EffectKind::FrictionHarmonics => Effect::FrictionHarmonics {
                order: v[0] as u32,
                amplitude_nmm: v[1],
                phase_rad: v[2],
            },
            EffectKind::TorqueRipple => Effect::TorqueRipple {
                eps: v[0],
                phase_rad: v[1],
            },
            EffectKind::SensorDrift => Effect::SensorDrift {
                rate_nmm_per_s: v[0],
                settle_per_s: v[1],
            },
            EffectKind::TimeDelay => Effect::TimeDelay { delay_s: v[0] },
            EffectKind::NonCongruent => Effect::NonCongruent {
                curvature: v[0],
                scale_nmm: v[1],
                cubic: v[2],
                feedback: v[3],
            },
            EffectKind::Creep => {
                if v[2] < v[1] {
                    return Err(PlantError::InvalidEffect(format!(
                        "effect creep: tau_max_s = {} must not be below tau_min_s = {}",
                        v[2], v[1]
                    )));
                }
                Effect::Creep {
                    fraction: v[0],
                    tau_min_s: v[1],
                    tau_max_s: v[2],
                    fluctuation: v[3],
                    tau0_s: v[4],
                }
            }
            EffectKind::RateDependence => Effect::RateDependence { tau_s: v[0] },
            EffectKind::RunGainOffset => Effect::RunGainOffset {
                gain_sd: v[0],
                offset_sd: v[1],
            },
            EffectKind::Leakage => Effect::Leakage {
                rate_per_s: v[0],
                decay_per_s: v[1],
            },
            EffectKind::Accommodation => Effect::Accommodation {
                kappa: v[0],
                cycles: v[1],
            },
            EffectKind::Viscous => Effect::Viscous {
                c: v[0],
                f_y: v[1],
                v0: v[2],
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
            Effect::SensorDrift {
                rate_nmm_per_s,
                settle_per_s,
            } => vec![rate_nmm_per_s, settle_per_s],
            Effect::TimeDelay { delay_s } => vec![delay_s],
            Effect::NonCongruent {
                curvature,
                scale_nmm,
                cubic,
                feedback,
            } => vec![curvature, scale_nmm, cubic, feedback],
            Effect::Creep {
                fraction,
                tau_min_s,
                tau_max_s,
                fluctuation,
                tau0_s,
            } => vec![fraction, tau_min_s, tau_max_s, fluctuation, tau0_s],
            Effect::RateDependence { tau_s } => vec![tau_s],
            Effect::RunGainOffset { gain_sd, offset_sd } => vec![gain_sd, offset_sd],
            Effect::Leakage {
                rate_per_s,
                decay_per_s,
            } => vec![rate_per_s, decay_per_s],
            Effect::Accommodation { kappa, cycles } => vec![kappa, cycles],
            Effect::Viscous { c, f_y, v0 } => vec![c, f_y, v0],
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
        let kind = kind_named(name)?;
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
        assert!(msg("friction_harmonics:order=25").contains("outside"));
        assert!(msg("friction_harmonics:order=4.5").contains("whole number"));
        assert!(msg("coil_lag:tau_s").contains("key=value"));
        for k in EffectKind::ALL {
            assert_eq!(kind_named(k.name()).unwrap(), k);
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
