//! The virtual BMR actuator: all stages wired together, fixed sample period, seeded, bit-for-bit deterministic.
//!
//! Per sample: (time delay) → coil split and converters → (coil lag) → steel Preisach per coil → yield and
//! viscous stress → rotor torques (non-congruent output map) → `T = T2 − T1` (thermal gain, torque ripple) →
//! plus seal friction at the encoder angle (current-dependent growth, extra harmonic) → torque sensor (drift).
//!
//! Positive nominal current excites coil 2 and gives positive torque.

use super::converter::{Converter, ConverterParams, coil_split};
use super::effects::{Effect, EffectSet};
use super::mr_fluid::MrFluid;
use super::rng::Rng;
use super::rotor_drive::{DriveParams, RotorDrive};
use super::rotor_geometry::RotorGeometry;
use super::rotor_geometry::ViscousDrag;
use super::seal_friction::SealFriction;
use super::steel_preisach::{PreisachSteel, SteelParams};
use super::torque_sensor::SensorParams;
use super::{PlantError, StateReader, check_range};
use crate::accommodation::Accommodation;
use crate::creep::{Creep, MAX_CREEP_TERMS};
use crate::filters::{DelayLine, Heating, Lag};
use crate::friction::{Friction, MAX_ORDER};
use crate::rate_dependence::RateDependence;
use crate::stages::Ripple;

/// Everything that defines a virtual actuator (a preset is one of these).
#[derive(Clone, Debug, PartialEq)]
pub struct ActuatorConfig {
    /// Free-text name written into bundles.
    pub name: String,
    /// Fixed sample rate of the simulation and of its output, Hz.
    pub sample_rate_hz: f64,
    /// Converter of each coil (both identical).
    pub converter: ConverterParams,
    /// Steel of the coil-1 and coil-2 magnetic circuits.
    pub steel1: SteelParams,
    pub steel2: SteelParams,
    pub fluid: MrFluid,
    /// Geometry of each rotor (both identical).
    pub geometry: RotorGeometry,
    pub drive: DriveParams,
    pub friction: SealFriction,
    pub sensor: SensorParams,
    /// Full-scale coil current (A): the reference of the thermal model.
    pub full_current_a: f64,
    /// Full-scale field torque of one rotor (N·mm): the reference of the non-congruent output map.
    pub full_torque_nmm: f64,
    pub effects: EffectSet,
}

/// Scalar parameters that [`ActuatorConfig::set`] can change, by dotted name.
pub const SETTABLE: [&str; 33] = [
    "converter.gain_a_per_v",
    "converter.limit_a",
    "converter.bandwidth_hz",
    "steel1.saturation_t",
    "steel1.coercivity_a",
    "steel1.coercivity_width_a",
    "steel1.interaction_width_a",
    "steel1.reversible_fraction",
    "steel1.reversible_width_a",
    "steel2.saturation_t",
    "steel2.coercivity_a",
    "steel2.coercivity_width_a",
    "steel2.interaction_width_a",
    "steel2.reversible_fraction",
    "steel2.reversible_width_a",
    "fluid.viscosity_pa_s",
    "geometry.shaft_radius_mm",
    "geometry.disc_radius_mm",
    "geometry.drum_width_mm",
    "geometry.gap_mm",
    "drive.speed_rad_s",
    "drive.speed_ripple",
    "drive.theta0_rad",
    "friction.offset_nmm",
    "friction.scale",
    "sensor.lever_mm",
    "sensor.noise_n",
    "sensor.resolution_n",
    "sensor.range_n",
    "sensor.offset_n",
    "full_current_a",
    "full_torque_nmm",
    "sample_rate_hz",
];

impl ActuatorConfig {
    /// Change one scalar parameter by dotted name (see [`SETTABLE`]); `friction.scale` multiplies every
    /// friction harmonic amplitude and `converter.bandwidth_hz = 0` removes the bandwidth limit. The value is
    /// range-checked when the actuator is built.
    pub fn set(&mut self, key: &str, value: f64) -> Result<(), PlantError> {
        let slot: &mut f64 = match key {
            "converter.gain_a_per_v" => &mut self.converter.gain_a_per_v,
            "converter.limit_a" => &mut self.converter.limit_a,
            "converter.bandwidth_hz" => {
                self.converter.bandwidth_hz = if value == 0.0 { None } else { Some(value) };
                return Ok(());
            }
            "steel1.saturation_t" => &mut self.steel1.saturation_t,
            "steel1.coercivity_a" => &mut self.steel1.coercivity_a,
            "steel1.coercivity_width_a" => &mut self.steel1.coercivity_width_a,
            "steel1.interaction_width_a" => &mut self.steel1.interaction_width_a,
            "steel1.reversible_fraction" => &mut self.steel1.reversible_fraction,
            "steel1.reversible_width_a" => &mut self.steel1.reversible_width_a,
            "steel2.saturation_t" => &mut self.steel2.saturation_t,
            "steel2.coercivity_a" => &mut self.steel2.coercivity_a,
            "steel2.coercivity_width_a" => &mut self.steel2.coercivity_width_a,
            "steel2.interaction_width_a" => &mut self.steel2.interaction_width_a,
            "steel2.reversible_fraction" => &mut self.steel2.reversible_fraction,
            "steel2.reversible_width_a" => &mut self.steel2.reversible_width_a,
            "fluid.viscosity_pa_s" => &mut self.fluid.viscosity_pa_s,
            "geometry.shaft_radius_mm" => &mut self.geometry.shaft_radius_mm,
            "geometry.disc_radius_mm" => &mut self.geometry.disc_radius_mm,
            "geometry.drum_width_mm" => &mut self.geometry.drum_width_mm,
            "geometry.gap_mm" => &mut self.geometry.gap_mm,
            "drive.speed_rad_s" => &mut self.drive.speed_rad_s,
            "drive.speed_ripple" => &mut self.drive.speed_ripple,
            "drive.theta0_rad" => &mut self.drive.theta0_rad,
            "friction.offset_nmm" => &mut self.friction.offset_nmm,
            "friction.scale" => {
                if !value.is_finite() {
                    return Err(PlantError::InvalidParameter(format!(
                        "friction.scale = {value} is not finite"
                    )));
                }
                self.friction
                    .harmonics
                    .iter_mut()
                    .for_each(|h| h.0 *= value);
                return Ok(());
            }
            "sensor.lever_mm" => &mut self.sensor.lever_mm,
            "sensor.noise_n" => &mut self.sensor.noise_n,
            "sensor.resolution_n" => &mut self.sensor.resolution_n,
            "sensor.range_n" => &mut self.sensor.range_n,
            "sensor.offset_n" => &mut self.sensor.offset_n,
            "full_current_a" => &mut self.full_current_a,
            "full_torque_nmm" => &mut self.full_torque_nmm,
            "sample_rate_hz" => &mut self.sample_rate_hz,
            _ => {
                return Err(PlantError::InvalidParameter(format!(
                    "unknown actuator parameter {key:?}; settable: {}",
                    SETTABLE.join(", ")
                )));
            }
        };
        *slot = value;
        Ok(())
    }

    pub fn validate(&self) -> Result<(), PlantError> {
        check_range("sample_rate_hz", self.sample_rate_hz, 1.0, 1e7)?;
        self.converter.validate()?;
        self.steel1.validate("steel1")?;
        self.steel2.validate("steel2")?;
        self.fluid.validate()?;
        self.geometry.validate()?;
        self.drive.validate()?;
        self.friction.validate()?;
        self.sensor.validate()?;
        check_range("full_current_a", self.full_current_a, 1e-6, 100.0)?;
        check_range("full_torque_nmm", self.full_torque_nmm, 1e-6, 1e9)?;
        Ok(())
    }
}

/// One output sample: what the rig logs plus the hidden true quantities (for tests and studies).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Time of the sample since start (or reset), s.
    pub t_s: f64,
    /// Commanded nominal current, A (NaN commands are logged as 0).
    pub current_cmd_a: f64,
    /// Converter output currents of coil 1 and coil 2, A.
    pub coil1_a: f64,
    pub coil2_a: f64,
    /// Flux density in the gap of circuit 1 and 2, T.
    pub b1_t: f64,
    pub b2_t: f64,
    /// Encoder rotor angle in [0, 2π), rad, and rotor speed, rad/s.
    pub theta_rad: f64,
    pub speed_rad_s: f64,
    /// Noise-free field torque T2 − T1 (yield + viscous, after the field effects), N·mm.
    pub field_torque_nmm: f64,
    /// Noise-free seal friction, N·mm.
    pub friction_nmm: f64,
    /// Viscous torque of one rotor, N·mm (the two cancel when the rotors turn at equal speed).
    pub viscous_nmm: f64,
    /// Noise-free torque on the casing (field + friction), N·mm.
    pub torque_true_nmm: f64,
    /// Measured torque (sensor noise, quantisation, drift), N·mm.
    pub torque_nmm: f64,
    /// False when the command was not finite and the safe command (0 A) was applied instead.
    pub command_valid: bool,
}

/// A run of samples, column by column.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    pub t_s: Vec<f64>,
    pub current_cmd_a: Vec<f64>,
    pub coil1_a: Vec<f64>,
    pub coil2_a: Vec<f64>,
    pub b1_t: Vec<f64>,
    pub b2_t: Vec<f64>,
    pub theta_rad: Vec<f64>,
    pub speed_rad_s: Vec<f64>,
    pub field_torque_nmm: Vec<f64>,
    pub friction_nmm: Vec<f64>,
    pub torque_true_nmm: Vec<f64>,
    pub torque_nmm: Vec<f64>,
}

impl Trace {
    fn with_capacity(n: usize) -> Self {
        let v = || Vec::with_capacity(n);
        Trace {
            t_s: v(),
            current_cmd_a: v(),
            coil1_a: v(),
            coil2_a: v(),
            b1_t: v(),
            b2_t: v(),
            theta_rad: v(),
            speed_rad_s: v(),
            field_torque_nmm: v(),
            friction_nmm: v(),
            torque_true_nmm: v(),
            torque_nmm: v(),
        }
    }

    fn push(&mut self, s: &Sample) {
        self.t_s.push(s.t_s);
        self.current_cmd_a.push(s.current_cmd_a);
        self.coil1_a.push(s.coil1_a);
        self.coil2_a.push(s.coil2_a);
        self.b1_t.push(s.b1_t);
        self.b2_t.push(s.b2_t);
        self.theta_rad.push(s.theta_rad);
        self.speed_rad_s.push(s.speed_rad_s);
        self.field_torque_nmm.push(s.field_torque_nmm);
        self.friction_nmm.push(s.friction_nmm);
        self.torque_true_nmm.push(s.torque_true_nmm);
        self.torque_nmm.push(s.torque_nmm);
    }

    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }
}

/// Effect parameters flattened for the per-sample loop (neutral values when an effect is off).
#[derive(Clone, Debug)]
struct ActiveEffects {
    lag_tau_s: f64,
    thermal_loss: f64,
    thermal_tau_s: f64,
    friction_gain_per_a: f64,
    harmonic: Option<(usize, f64, f64)>,
    ripple: Option<(f64, f64)>,
    drift_nmm_per_s: f64,
    drift_settle_per_s: f64,
    delay_samples: usize,
    curvature: f64,
    /// Full-scale torque of the output map (0: the configuration's `full_torque_nmm`).
    curvature_scale_nmm: f64,
    /// Odd cubic term of the output map (`non_congruent`).
    cubic: f64,
    /// Mean-field feedback of each circuit's flux into its field current (`non_congruent`): A per saturation flux.
    feedback_a: f64,
    /// Creep of each circuit's flux density: (fraction, tau_min_s, tau_max_s, fluctuation field (A), tau0_s).
    creep: Option<(f64, f64, f64, f64, f64)>,
    rate_tau_s: f64,
    /// Spread of the per-run sensor gain and offset (N·mm).
    run_gain_offset: Option<(f64, f64)>,
    leak_per_s: f64,
    /// The leakage integral's decay over one sample (`filters::leak_pole`; 1: an ideal integrator).
    leak_pole: f64,
    /// Minor-loop accommodation: (kappa, cycles).
    accommodation: Option<(f64, f64)>,
    /// `viscous`: loss torque per unit of field-current rate (N·mm·s/A), yield torque (N·mm), yield rate (A/s).
    viscous: (f64, f64, f64),
}

impl ActiveEffects {
    /// Whether the `viscous` loss is on (a viscous or a yield part).
    fn viscous_on(&self) -> bool {
        self.viscous.0 > 0.0 || self.viscous.1 > 0.0
    }

    fn from_set(set: &EffectSet, dt_s: f64) -> Self {
        let mut a = ActiveEffects {
            lag_tau_s: 0.0,
            thermal_loss: 0.0,
            thermal_tau_s: 0.0,
            friction_gain_per_a: 0.0,
            harmonic: None,
            ripple: None,
            drift_nmm_per_s: 0.0,
            drift_settle_per_s: 0.0,
            delay_samples: 0,
            curvature: 0.0,
            curvature_scale_nmm: 0.0,
            cubic: 0.0,
            feedback_a: 0.0,
            creep: None,
            rate_tau_s: 0.0,
            run_gain_offset: None,
            leak_per_s: 0.0,
            leak_pole: 1.0,
            accommodation: None,
            viscous: (0.0, 0.0, 1.0),
        };
        for e in set.iter() {
            match *e {
                Effect::CoilLag { tau_s } => a.lag_tau_s = tau_s,
                Effect::ThermalDrift { gain_loss, tau_s } => {
                    a.thermal_loss = gain_loss;
                    a.thermal_tau_s = tau_s;
                }
                Effect::FrictionCurrent { gain_per_a } => a.friction_gain_per_a = gain_per_a,
                Effect::FrictionHarmonics {
                    order,
                    amplitude_nmm,
                    phase_rad,
                } => a.harmonic = Some((order as usize, amplitude_nmm, phase_rad)),
                Effect::TorqueRipple { eps, phase_rad } => a.ripple = Some((eps, phase_rad)),
                Effect::SensorDrift {
                    rate_nmm_per_s,
                    settle_per_s,
                } => {
                    a.drift_nmm_per_s = rate_nmm_per_s;
                    a.drift_settle_per_s = settle_per_s;
                }
                Effect::TimeDelay { delay_s } => {
                    a.delay_samples = libm::round(delay_s / dt_s) as usize
                }
                Effect::NonCongruent {
                    curvature,
                    scale_nmm,
                    cubic,
                    feedback,
                } => {
                    a.curvature = curvature;
                    a.curvature_scale_nmm = scale_nmm;
                    a.cubic = cubic;
                    a.feedback_a = feedback;
                }
                Effect::Creep {
                    fraction,
                    tau_min_s,
                    tau_max_s,
                    fluctuation,
                    tau0_s,
                } => a.creep = Some((fraction, tau_min_s, tau_max_s, fluctuation, tau0_s)),
                Effect::RateDependence { tau_s } => a.rate_tau_s = tau_s,
                Effect::RunGainOffset { gain_sd, offset_sd } => {
                    a.run_gain_offset = Some((gain_sd, offset_sd))
                }
                Effect::Leakage {
                    rate_per_s,
                    decay_per_s,
                } => {
                    a.leak_per_s = rate_per_s;
                    a.leak_pole = crate::filters::leak_pole(dt_s, decay_per_s);
                }
                Effect::Accommodation { kappa, cycles } => a.accommodation = Some((kappa, cycles)),
                Effect::Viscous { c, f_y, v0 } => a.viscous = (c, f_y, v0),
            }
        }
        a
    }
}

/// First word of a serialised simulator state (format tag and version).
const PLANT_STATE_TAG: u64 = 0x626d_725f_7661_0002;

/// The simulator. `new(config, seed)`, then `step`/`run` with commanded nominal current (A).
#[derive(Clone, Debug)]
pub struct VirtualActuator {
    config: ActuatorConfig,
    seed: u64,
    dt_s: f64,
    fx: ActiveEffects,
    torque_per_kpa: f64,
    viscous_drag: ViscousDrag,
    /// The seal friction with the extra harmonic and the current growth, in the compensator's evaluated form.
    friction: Friction<MAX_ORDER>,
    ripple: Option<Ripple>,
    delay_line: DelayLine<Vec<f64>>,
    converter1: Converter,
    converter2: Converter,
    /// Each coil's magnetising (field) current: the coil lag of its converter current.
    field1: Lag,
    field2: Lag,
    steel1: PreisachSteel,
    steel2: PreisachSteel,
    heating: Heating,
    /// Magnetic after-effect of each circuit's flux density (`creep`).
    creep1: Option<Creep>,
    creep2: Option<Creep>,
    /// Dynamic field of each circuit (`rate_dependence`).
    rate1: Option<RateDependence>,
    rate2: Option<RateDependence>,
    accommodation: Option<Accommodation>,
    /// Integral of the applied command since the run's start (`leakage`), A·s, and the last applied command.
    leak_integral: f64,
    last_applied: f64,
    /// The nominal field current the steel saw at the last sample (A; `viscous`).
    last_core_a: f64,
    /// This run's sensor calibration (`run_gain_offset`) and the stream it is drawn from.
    run_gain: f64,
    run_offset_nmm: f64,
    calibration_rng: Rng,
    drive: RotorDrive,
    rng: Rng,
    index: u64,
}

/// The calibration draws use their own stream, so that switching `run_gain_offset` on leaves the noise alone.
pub(super) fn calibration_stream(seed: u64) -> Rng {
    Rng::new(seed ^ 0xC0FF_EE15_CA1B_0A7E)
}

impl VirtualActuator {
    /// Build from a validated configuration; `seed` fixes every random bit (sensor noise).
    pub fn new(config: ActuatorConfig, seed: u64) -> Result<Self, PlantError> {
        config.validate()?;
        let dt_s = 1.0 / config.sample_rate_hz;
        let fx = ActiveEffects::from_set(&config.effects, dt_s);
        let steel1 = PreisachSteel::new(config.steel1.clone())?;
        let steel2 = PreisachSteel::new_beside(config.steel2.clone(), Some(&steel1))?;
        let creep = || {
            fx.creep.and_then(|(f, lo, hi, field, tau0)| {
                Creep::log_uniform(f, lo, hi, dt_s, 0.0)?.with_fluctuation(field, tau0, dt_s, 0.0)
            })
        };
        let full = config.full_current_a;
        let rate = |steel: &SteelParams| {
            (fx.rate_tau_s > 0.0)
                .then(|| {
                    RateDependence::new(
                        fx.rate_tau_s,
                        steel.saturation_t / full,
                        dt_s,
                        full,
                        0.0,
                        0.0,
                    )
                })
                .flatten()
        };
        let accommodation = fx.accommodation.and_then(|(kappa, cycles)| {
            use crate::accommodation::{DEADBAND_SHARE, SATURATION_SHARE};
            let span = 2.0 * full;
            Accommodation::new(
                kappa,
                cycles,
                -full,
                full,
                DEADBAND_SHARE * span,
                SATURATION_SHARE * span,
                0.0,
            )
        });
        let friction = config
            .friction
            .evaluated(fx.harmonic, fx.friction_gain_per_a)?;
        let ripple = fx.ripple.map(|(eps, phase)| Ripple::new(eps, phase));
        let mut calibration_rng = calibration_stream(seed);
        let (run_gain, run_offset_nmm) =
            draw_run_calibration(fx.run_gain_offset, &mut calibration_rng);
        Ok(VirtualActuator {
            creep1: creep(),
            creep2: creep(),
            rate1: rate(&config.steel1),
            rate2: rate(&config.steel2),
            accommodation,
            leak_integral: 0.0,
            last_applied: 0.0,
            last_core_a: 0.0,
            run_gain,
            run_offset_nmm,
            calibration_rng,
            torque_per_kpa: config.geometry.yield_torque_per_kpa(),
            viscous_drag: config.geometry.viscous_drag(config.fluid.viscosity_pa_s),
            friction,
            ripple,
            delay_line: DelayLine::new(vec![0.0; fx.delay_samples], fx.delay_samples, 0.0)
                .expect("sized to the delay"),
            converter1: Converter::new(config.converter.clone(), dt_s),
            converter2: Converter::new(config.converter.clone(), dt_s),
            field1: Lag::new(fx.lag_tau_s, dt_s, 0.0),
            field2: Lag::new(fx.lag_tau_s, dt_s, 0.0),
            steel1,
            steel2,
            heating: Heating::new(fx.thermal_tau_s, dt_s, config.full_current_a, 0.0),
            drive: RotorDrive::new(config.drive.clone(), dt_s),
            rng: Rng::new(seed),
            index: 0,
            fx,
            dt_s,
            seed,
            config,
        })
    }

    /// A preset by name with extra effects (each replaces the preset's effect of the same kind).
    pub fn from_preset(
        name: &str,
        sample_rate_hz: f64,
        effects: &[Effect],
        seed: u64,
    ) -> Result<Self, PlantError> {
        let mut config = super::presets::preset(name)?;
        config.sample_rate_hz = sample_rate_hz;
        for e in effects {
            config.effects.insert(*e);
        }
        VirtualActuator::new(config, seed)
    }

    pub fn config(&self) -> &ActuatorConfig {
        &self.config
    }

    pub fn seed(&self) -> u64 {
        self.seed
    }

    pub fn sample_period_s(&self) -> f64 {
        self.dt_s
    }

    /// Time of the next sample, s.
    pub fn time_s(&self) -> f64 {
        self.index as f64 * self.dt_s
    }

    /// Back to the state right after construction (demagnetised steel, cold coils, same noise stream).
    pub fn reset(&mut self) {
        self.delay_line.fill(0.0);
        self.converter1.reset();
        self.converter2.reset();
        self.field1.set_output(0.0);
        self.field2.set_output(0.0);
        self.steel1.demagnetise();
        self.steel2.demagnetise();
        self.heating.set_state(0.0);
        for c in self.creep1.iter_mut().chain(self.creep2.iter_mut()) {
            c.reset(0.0);
            c.fluctuation_mut().into_iter().for_each(|f| f.reset(0.0));
        }
        self.rate1.iter_mut().for_each(|r| r.reset(0.0, 0.0));
        self.rate2.iter_mut().for_each(|r| r.reset(0.0, 0.0));
        self.accommodation.iter_mut().for_each(|a| a.reset());
        self.leak_integral = 0.0;
        self.last_applied = 0.0;
        self.last_core_a = 0.0;
        self.calibration_rng = calibration_stream(self.seed);
        (self.run_gain, self.run_offset_nmm) =
            draw_run_calibration(self.fx.run_gain_offset, &mut self.calibration_rng);
        self.drive.reset();
        self.rng = Rng::new(self.seed);
        self.index = 0;
    }

    /// A new recording. The rig first rests `rest_s` seconds (≥ 0; `f64::INFINITY`: long enough for everything
    /// to settle) at zero command: the steel goes to zero current and keeps its remanence, the converters and
    /// field lags settle, the coils cool (the heating state decays with its time constant), creep relaxes; the
    /// clock advances by a finite rest (sensor drift goes on) and the rotor stands. Then the run starts: the
    /// leakage integral restarts from zero and the per-run calibration (`run_gain_offset`) is drawn anew. With
    /// `rest_s = 0` only the run-start part happens.
    pub fn start_run(&mut self, rest_s: f64) -> Result<(), PlantError> {
        if rest_s.is_nan() || rest_s < 0.0 {
            return Err(PlantError::InvalidParameter(format!(
                "rest_s = {rest_s} must be a nonnegative number of seconds (inf: settled)"
            )));
        }
        if rest_s > 0.0 {
            let periods = rest_s / self.dt_s;
            self.delay_line.fill(0.0);
            self.converter1.reset();
            self.converter2.reset();
            self.field1.set_output(0.0);
            self.field2.set_output(0.0);
            let b1 = self.steel1.apply(0.0);
            let b2 = self.steel2.apply(0.0);
            self.rate1.iter_mut().for_each(|r| r.reset(0.0, b1));
            self.rate2.iter_mut().for_each(|r| r.reset(0.0, b2));
            if let Some(c) = self.creep1.as_mut() {
                c.hold(b1, rest_s, self.dt_s);
            }
            if let Some(c) = self.creep2.as_mut() {
                c.hold(b2, rest_s, self.dt_s);
            }
            // The steel went to zero current without the fluctuation field: it starts again from there.
            for c in self.creep1.iter_mut().chain(self.creep2.iter_mut()) {
                c.fluctuation_mut().into_iter().for_each(|f| f.reset(0.0));
            }
            let cooled = if self.fx.thermal_tau_s > 0.0 {
                self.heating.state() * libm::exp(-rest_s / self.fx.thermal_tau_s)
            } else {
                0.0
            };
            self.heating.set_state(cooled);
            self.last_applied = 0.0;
            self.last_core_a = 0.0;
            // A finite rest moves the clock (drift continues); beyond 2^52 samples it counts as settled.
            if periods.is_finite() && periods < 4.5e15 {
                self.index += libm::round(periods) as u64;
            }
        }
        self.leak_integral = 0.0;
        (self.run_gain, self.run_offset_nmm) =
            draw_run_calibration(self.fx.run_gain_offset, &mut self.calibration_rng);
        Ok(())
    }

    /// Everything that evolves (memories, filter states, effect states, angle, noise and calibration streams,
    /// time) as plain words, for pickling. [`Self::load_state`] on an actuator built from the same configuration
    /// and seed continues bit for bit.
    pub fn save_state(&self) -> Vec<u64> {
        let f = |w: &mut Vec<u64>, v: f64| w.push(v.to_bits());
        let mut w = vec![
            PLANT_STATE_TAG,
            self.index,
            self.delay_line.samples() as u64,
        ];
        w.extend(self.delay_line.values().map(f64::to_bits));
        self.converter1.save_state(&mut w);
        self.converter2.save_state(&mut w);
        for v in [
            self.field1.output(),
            self.field2.output(),
            self.heating.state(),
            self.leak_integral,
            self.last_applied,
            self.run_gain,
            self.run_offset_nmm,
        ] {
            f(&mut w, v);
        }
        for c in [&self.creep1, &self.creep2].into_iter().flatten() {
            w.extend(c.states().map(f64::to_bits));
        }
        for r in [&self.rate1, &self.rate2].into_iter().flatten() {
            w.extend(r.state().map(f64::to_bits));
        }
        if let Some(a) = &self.accommodation {
            w.extend(a.state().map(f64::to_bits));
        }
        if self.fx.viscous_on() {
            f(&mut w, self.last_core_a);
        }
        self.drive.save_state(&mut w);
        self.rng.save_state(&mut w);
        self.calibration_rng.save_state(&mut w);
        self.steel1.save_state(&mut w);
        self.steel2.save_state(&mut w);
        w
    }

    /// Continue from words written by [`Self::save_state`] of an actuator with the same configuration. Every
    /// value is checked; on error the actuator is unchanged.
    pub fn load_state(&mut self, words: &[u64]) -> Result<(), PlantError> {
        let mut next = self.clone();
        let mut r = StateReader::new(words);
        if r.word()? != PLANT_STATE_TAG {
            return Err(PlantError::BadState("not a virtual actuator state"));
        }
        next.index = r.word()?;
        if next.index > 1 << 53 {
            return Err(PlantError::BadState("sample index beyond 2^53"));
        }
        if r.count()? != self.fx.delay_samples {
            return Err(PlantError::BadState(
                "delay line length differs from this configuration's",
            ));
        }
        let mut delayed = Vec::with_capacity(self.fx.delay_samples);
        for _ in 0..self.fx.delay_samples {
            delayed.push(r.float()?);
        }
        next.delay_line.set_values(delayed);
        next.converter1.load_state(&mut r)?;
        next.converter2.load_state(&mut r)?;
        next.field1.set_output(r.float()?);
        next.field2.set_output(r.float()?);
        next.heating.set_state(r.float()?);
        next.leak_integral = r.float()?;
        next.last_applied = r.float()?;
        next.run_gain = r.float()?;
        next.run_offset_nmm = r.float()?;
        for c in [&mut next.creep1, &mut next.creep2].into_iter().flatten() {
            let mut v = [0.0; MAX_CREEP_TERMS];
            for slot in v.iter_mut() {
                *slot = r.float()?;
            }
            if !c.set_states(&v) {
                return Err(PlantError::BadState("creep state"));
            }
        }
        for rd in [&mut next.rate1, &mut next.rate2].into_iter().flatten() {
            let mut v = [0.0; 4];
            for slot in v.iter_mut() {
                *slot = r.float()?;
            }
            if !rd.set_state(v) {
                return Err(PlantError::BadState("rate-dependence state"));
            }
        }
        if let Some(a) = next.accommodation.as_mut() {
            let mut v = [0.0; 11];
            for slot in v.iter_mut() {
                *slot = r.float()?;
            }
            if !a.set_state(&v) {
                return Err(PlantError::BadState("accommodation state"));
            }
        }
        if self.fx.viscous_on() {
            next.last_core_a = r.float()?;
        }
        next.drive.load_state(&mut r)?;
        next.rng.load_state(&mut r)?;
        next.calibration_rng.load_state(&mut r)?;
        next.steel1.load_state(&mut r)?;
        next.steel2.load_state(&mut r)?;
        r.finish()?;
        *self = next;
        Ok(())
    }

    /// This recording's sensor calibration: gain and offset (N·mm) of `run_gain_offset` (1 and 0 when it is off).
    pub fn run_calibration(&self) -> (f64, f64) {
        (self.run_gain, self.run_offset_nmm)
    }

    /// Noise-free seal friction (N·mm) at zero current and angle `theta_rad`, including any extra harmonic.
    pub fn true_friction_nmm(&self, theta_rad: f64) -> f64 {
        self.friction.eval(theta_rad)
    }

    /// The encoder angle (rad) of the next sample: the first of [`Self::theta_ahead`].
    #[inline]
    pub fn theta_rad(&self) -> f64 {
        self.drive.theta_rad()
    }

    /// The encoder angles (rad) of the next `n` samples, without advancing the actuator (the rotor angle does
    /// not depend on the current, so a controller can be fed it ahead of time).
    /// At most [`crate::limits::MAX_GENERATED_SAMPLES`] at a time (checked before allocating).
    pub fn theta_ahead(&self, n: usize) -> Result<Vec<f64>, crate::limits::LimitError> {
        use crate::limits::{MAX_GENERATED_SAMPLES, check};
        check("angle samples asked for ahead", n, MAX_GENERATED_SAMPLES)?;
        let mut d = self.drive.clone();
        Ok((0..n)
            .map(|_| {
                let th = d.theta_rad();
                d.advance();
                th
            })
            .collect())
    }

    /// Output map of one rotor's field torque (the `non_congruent` effect; identity when off).
    #[inline]
    fn output_map(&self, torque_nmm: f64) -> f64 {
        let (c, k) = (self.fx.curvature, self.fx.cubic);
        if c == 0.0 && k == 0.0 {
            return torque_nmm;
        }
        let full = if self.fx.curvature_scale_nmm > 0.0 {
            self.fx.curvature_scale_nmm
        } else {
            self.config.full_torque_nmm
        };
        let n = torque_nmm / full;
        full * n * (1.0 + c * n.abs() + k * n * n) / (1.0 + c + k)
    }

    /// Advance one sample with commanded nominal current `current_cmd_a` (A). A non-finite command applies the
    /// safe command 0 A and is flagged in the sample.
    pub fn step(&mut self, current_cmd_a: f64) -> Sample {
        self.step_with_sincos(current_cmd_a, crate::trig::sincos(self.drive.theta_rad()))
    }

    /// [`Self::step`] given `sincos = crate::trig::sincos(self.theta_rad())`, computed by a loop that needs it
    /// elsewhere too (a compensator's friction feedforward at the same angle): the same sample to the bit.
    #[inline(always)]
    pub fn step_with_sincos(&mut self, current_cmd_a: f64, sincos: (f64, f64)) -> Sample {
        let valid = current_cmd_a.is_finite();
        let cmd = if valid { current_cmd_a } else { 0.0 };
        let t_s = self.time_s();
        let applied = self.delay_line.step(cmd);
        let (c1, c2) = coil_split(applied);
        let coil1_a = self.converter1.step_current(c1);
        let coil2_a = self.converter2.step_current(c2);
        let field1_a = self.field1.step(coil1_a);
        let field2_a = self.field2.step(coil2_a);
        let b1_t = preisach_flux(
            &mut self.steel1,
            &mut self.rate1,
            &mut self.creep1,
            self.fx.feedback_a,
            field1_a,
        );
        let b2_t = preisach_flux(
            &mut self.steel2,
            &mut self.rate2,
            &mut self.creep2,
            self.fx.feedback_a,
            field2_a,
        );

        let theta_rad = self.drive.theta_rad();
        // One `sincos` of the angle for the friction, the torque ripple and the drive's speed ripple.
        let angle = self.friction.angle_terms_from(sincos);
        let speed_rad_s = self.drive.speed_at_sin(angle.sin1);
        let fluid = &self.config.fluid;
        let yield1 = self.output_map(fluid.yield_stress_kpa(b1_t) * self.torque_per_kpa);
        let yield2 = self.output_map(fluid.yield_stress_kpa(b2_t) * self.torque_per_kpa);
        let viscous_nmm = self.viscous_drag.torque_nmm(speed_rad_s);
        // Both rotors turn at the same speed in opposite directions: their viscous drags oppose.
        let mut field = (yield2 + viscous_nmm) - (yield1 + viscous_nmm);
        // The field the steel sees: the coils' core inputs recombined as a nominal current.
        let core1 = self.rate1.as_ref().map_or(field1_a, |r| r.core_input());
        let core2 = self.rate2.as_ref().map_or(field2_a, |r| r.core_input());
        let core_a = core2 - core1;
        // `viscous`: a loss torque of that current's rate (backward difference over the sample).
        if self.fx.viscous_on() {
            let (c, f_y, v0) = self.fx.viscous;
            field += crate::viscous::loss(c, f_y, v0, (core_a - self.last_core_a) / self.dt_s);
        }
        self.last_core_a = core_a;
        if let Some(a) = self.accommodation.as_mut() {
            field += a.step(core_a, field);
        }

        if self.fx.thermal_loss != 0.0 {
            let full = self.config.full_current_a;
            let heat = (coil1_a * coil1_a + coil2_a * coil2_a) / (full * full);
            field *= 1.0 - self.fx.thermal_loss * self.heating.step_heat(heat);
        }
        if let Some(r) = &self.ripple {
            field *= r.gain(&angle);
        }
        let friction_nmm = self.friction.with_terms(&angle, field1_a + field2_a);
        let torque_true_nmm = field + friction_nmm;
        let drift =
            self.fx.drift_nmm_per_s * crate::filters::drift_offset(t_s, self.fx.drift_settle_per_s);
        // What reaches the sensor: a charge-type measurement integrates the leakage (trapezoids of the applied
        // command), scaled and offset by this run's calibration.
        self.leak_integral = crate::filters::leak_step(
            self.leak_integral,
            self.fx.leak_pole,
            self.dt_s,
            applied,
            self.last_applied,
        );
        self.last_applied = applied;
        let sensed = self.run_gain * (torque_true_nmm + self.fx.leak_per_s * self.leak_integral)
            + self.run_offset_nmm;
        let torque_nmm = self.config.sensor.measure(sensed, drift, &mut self.rng);

        self.drive.advance_at(speed_rad_s);
        self.index += 1;
        Sample {
            t_s,
            current_cmd_a: cmd,
            coil1_a,
            coil2_a,
            b1_t,
            b2_t,
            theta_rad,
            speed_rad_s,
            field_torque_nmm: field,
            friction_nmm,
            viscous_nmm,
            torque_true_nmm,
            torque_nmm,
            command_valid: valid,
        }
    }

    /// Run a command sequence from the current state; returns every sample, column by column.
    pub fn run(&mut self, current_cmd_a: &[f64]) -> Trace {
        let mut trace = Trace::with_capacity(current_cmd_a.len());
        for &c in current_cmd_a {
            let s = self.step(c);
            trace.push(&s);
        }
        trace
    }
}

/// One circuit's flux density (any Preisach core's output): the input through the dynamic field (rate
/// dependence), the thermal fluctuation field (creep's log-time after-effect) and the mean field (`feedback`
/// input units per saturation flux times the core's output of the sample before: a moving Preisach model) into
/// the core, then the relaxations (creep).
#[inline(always)]
pub(super) fn preisach_flux(
    steel: &mut PreisachSteel,
    rate: &mut Option<RateDependence>,
    creep: &mut Option<Creep>,
    feedback: f64,
    field_current_a: f64,
) -> f64 {
    let mut core_input = |steel: &PreisachSteel, h: f64| {
        let h = creep.as_mut().map_or(h, |c| c.core_input(h));
        if feedback != 0.0 {
            h + feedback * steel.normalised_output()
        } else {
            h
        }
    };
    let b = match rate {
        Some(r) => {
            let h = core_input(steel, r.step(field_current_a));
            let b = steel.apply(h);
            r.observe(b);
            b
        }
        None => {
            let h = core_input(steel, field_current_a);
            steel.apply(h)
        }
    };
    match creep {
        Some(c) => c.step(b),
        None => b,
    }
}

/// This run's sensor gain and offset (output units): 1 and 0 unless `run_gain_offset` (spreads) is on.
pub(super) fn draw_run_calibration(spread: Option<(f64, f64)>, rng: &mut Rng) -> (f64, f64) {
    match spread {
        Some((gain_sd, offset_sd)) => (1.0 + gain_sd * rng.normal(), offset_sd * rng.normal()),
        None => (1.0, 0.0),
    }
}
