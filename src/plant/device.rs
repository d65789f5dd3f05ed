//! A virtual hysteretic device of any kind (piezo stack, ferroelectric capacitor, magnet): one input, one output,
//! no angle. The second plant structure beside the BMR actuator, so that the diagnosis is calibrated on more than
//! one generator.
//!
//! Per sample: command → (`time_delay`) → (`coil_lag`: the drive's first-order lag, amplifier bandwidth) →
//! (`rate_dependence`: dynamic field) → (`non_congruent`'s mean field: plus feedback × the core's last
//! normalised output) → Preisach core (a physical switching-field density, fields in input units, output
//! normalised to ±1) → (`creep`) → output scale and offset → (`non_congruent` output map,
//! `accommodation`, `thermal_drift`: self-heating by (u/u_full)²) → sensor: (`leakage` integral,
//! `run_gain_offset`, `sensor_drift`), noise, quantisation.
//!
//! Effects that need an angle or seal friction (`friction_current`, `friction_harmonics`, `torque_ripple`) are
//! refused. Seeded, bit-for-bit deterministic (the seed changes only the noise and the per-run calibration).

use super::effects::{Effect, EffectSet};
use super::rng::Rng;
use super::steel_preisach::{PreisachSteel, SteelParams};
use super::virtual_actuator::{calibration_stream, draw_run_calibration, preisach_flux};
use super::{PlantError, check_range};
use crate::accommodation::Accommodation;
use crate::creep::Creep;
use crate::filters::{DelayLine, Heating, Lag};
use crate::rate_dependence::RateDependence;

/// Everything that defines a virtual device.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceConfig {
    pub name: String,
    /// Input quantity name and unit, output quantity name and unit (what bundles declare).
    pub input: (String, String),
    pub output: (String, String),
    pub sample_rate_hz: f64,
    /// Centre and half-span of the input range (saturation at `centre ± half_span`).
    pub input_centre: f64,
    pub input_half_span: f64,
    /// Preisach core: fields in units of the input's half-span relative to its centre (saturation at ±1, the
    /// table reaching `±range_a`); its output spans `±saturation_t` (the presets use 1).
    pub core: SteelParams,
    /// Output at core output 0 and per unit of core output.
    pub output_offset: f64,
    pub output_scale: f64,
    /// Sensor noise (standard deviation) and quantisation step (0: none), output units.
    pub noise: f64,
    pub resolution: f64,
    pub effects: EffectSet,
}

/// Names accepted by [`device_preset`].
pub const DEVICE_PRESETS: [&str; 2] = ["piezo", "ferroelectric"];

/// A piezo stack: drive voltage ±90 V → displacement ±20 µm (soft PZT: a slim loop with a large reversible
/// part), 20 nm noise; or a ferroelectric capacitor: ±10 V → polarization ±30 µC/cm² (a square loop).
pub fn device_preset(name: &str) -> Result<DeviceConfig, PlantError> {
    let base =
        |input: (&str, &str), output: (&str, &str), half: f64, core: SteelParams| DeviceConfig {
            name: String::new(),
            input: (input.0.to_string(), input.1.to_string()),
            output: (output.0.to_string(), output.1.to_string()),
            sample_rate_hz: 1000.0,
            input_centre: 0.0,
            input_half_span: half,
            core,
            output_offset: 0.0,
            output_scale: 1.0,
            noise: 0.0,
            resolution: 0.0,
            effects: EffectSet::new(),
        };
    match name {
        "piezo" => Ok(DeviceConfig {
            name: "piezo virtual device (PZT stack, ±90 V)".to_string(),
            output_scale: 20.0,
            noise: 0.02,
            resolution: 0.001,
            ..base(
                ("voltage", "V"),
                ("displacement", "µm"),
                90.0,
                SteelParams {
                    saturation_t: 1.0,
                    coercivity_a: 0.13,
                    coercivity_width_a: 0.1,
                    interaction_width_a: 0.5,
                    reversible_fraction: 0.45,
                    reversible_width_a: 0.6,
                    range_a: 1.5,
                    grid: 241,
                },
            )
        }),
        "ferroelectric" => Ok(DeviceConfig {
            name: "ferroelectric virtual device (capacitor, ±10 V)".to_string(),
            output_scale: 30.0,
            noise: 0.05,
            resolution: 0.0,
            ..base(
                ("voltage", "V"),
                ("polarization", "µC/cm²"),
                10.0,
                SteelParams {
                    saturation_t: 1.0,
                    coercivity_a: 0.3,
                    coercivity_width_a: 0.08,
                    interaction_width_a: 0.15,
                    reversible_fraction: 0.1,
                    reversible_width_a: 0.4,
                    range_a: 1.5,
                    grid: 241,
                },
            )
        }),
        _ => Err(PlantError::UnknownPreset(name.to_string())),
    }
}

/// Scalar parameters that [`DeviceConfig::set`] can change, by name.
pub const DEVICE_SETTABLE: [&str; 13] = [
    "sample_rate_hz",
    "input_centre",
    "input_half_span",
    "output_offset",
    "output_scale",
    "noise",
    "resolution",
    "core.coercivity",
    "core.coercivity_width",
    "core.interaction_width",
    "core.reversible_fraction",
    "core.reversible_width",
    "core.grid",
];

impl DeviceConfig {
    /// Change one scalar parameter by name (see [`DEVICE_SETTABLE`]; core fields in units of the input's
    /// half-span). Ranges are checked when the device is built.
    pub fn set(&mut self, key: &str, value: f64) -> Result<(), PlantError> {
        let slot: &mut f64 = match key {
            "sample_rate_hz" => &mut self.sample_rate_hz,
            "input_centre" => &mut self.input_centre,
            "input_half_span" => &mut self.input_half_span,
            "output_offset" => &mut self.output_offset,
            "output_scale" => &mut self.output_scale,
            "noise" => &mut self.noise,
            "resolution" => &mut self.resolution,
            "core.coercivity" => &mut self.core.coercivity_a,
            "core.coercivity_width" => &mut self.core.coercivity_width_a,
            "core.interaction_width" => &mut self.core.interaction_width_a,
            "core.reversible_fraction" => &mut self.core.reversible_fraction,
            "core.reversible_width" => &mut self.core.reversible_width_a,
            "core.grid" => {
                if !(value.is_finite() && value.fract() == 0.0 && (8.0..=2001.0).contains(&value)) {
                    return Err(PlantError::InvalidParameter(format!(
                        "core.grid = {value} must be a whole number in [8, 2001]"
                    )));
                }
                self.core.grid = value as usize;
                return Ok(());
            }
            _ => {
                return Err(PlantError::InvalidParameter(format!(
                    "unknown device parameter {key:?}; settable: {}",
                    DEVICE_SETTABLE.join(", ")
                )));
            }
        };
        *slot = value;
        Ok(())
    }

    pub fn validate(&self) -> Result<(), PlantError> {
        check_range("sample_rate_hz", self.sample_rate_hz, 1.0, 1e7)?;
        check_range("input_centre", self.input_centre, -1e9, 1e9)?;
        check_range("input_half_span", self.input_half_span, 1e-12, 1e9)?;
        check_range("output_offset", self.output_offset, -1e12, 1e12)?;
        check_range("output_scale", self.output_scale, 1e-12, 1e12)?;
        check_range("noise", self.noise, 0.0, 1e12)?;
        check_range("resolution", self.resolution, 0.0, 1e12)?;
        self.core.validate("core")?;
        for e in self.effects.iter() {
            if matches!(
                e,
                Effect::FrictionCurrent { .. }
                    | Effect::FrictionHarmonics { .. }
                    | Effect::TorqueRipple { .. }
            ) {
                return Err(PlantError::InvalidEffect(format!(
                    "effect {} needs a rotor angle and seal friction; a virtual device has neither",
                    e.name()
                )));
            }
        }
        Ok(())
    }
}

/// One output sample of a device.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviceSample {
    pub t_s: f64,
    pub input: f64,
    /// Noise-free output of the device (before the sensor), and the measured output.
    pub output_true: f64,
    pub output: f64,
}

/// The device simulator.
#[derive(Clone, Debug)]
pub struct VirtualDevice {
    config: DeviceConfig,
    seed: u64,
    dt_s: f64,
    delay_line: DelayLine<Vec<f64>>,
    input_lag: Lag,
    rate: Option<RateDependence>,
    core: PreisachSteel,
    creep: Option<Creep>,
    curvature: f64,
    /// Odd cubic term of the output map (`non_congruent`).
    cubic: f64,
    /// Mean-field feedback of the core's normalised output into its normalised input (`non_congruent`'s
    /// feedback over the input half span).
    feedback: f64,
    accommodation: Option<Accommodation>,
    thermal_loss: f64,
    thermal_tau_s: f64,
    heating: Heating,
    drift_per_s: f64,
    drift_settle_per_s: f64,
    leak_per_s: f64,
    /// The leakage integral's decay over one sample (`filters::leak_pole`; 1: an ideal integrator).
    leak_pole: f64,
    leak_integral: f64,
    last_applied: f64,
    /// `viscous`: loss per unit of input rate (output units · s per input unit), yield output (output units) and
    /// yield rate (input units per second), and the core input of the last sample (input units).
    viscous: (f64, f64, f64),
    last_core_input: f64,
    run_gain_offset: Option<(f64, f64)>,
    run_gain: f64,
    run_offset: f64,
    calibration_rng: Rng,
    rng: Rng,
    index: u64,
}

impl VirtualDevice {
    pub fn new(config: DeviceConfig, seed: u64) -> Result<Self, PlantError> {
        config.validate()?;
        let dt_s = 1.0 / config.sample_rate_hz;
        let half = config.input_half_span;
        let (mut delay, mut lag_tau, mut rate_tau) = (0usize, 0.0, 0.0);
        let (mut creep, mut curvature, mut cubic, mut accommodation) = (None, 0.0, 0.0, None);
        let mut feedback = 0.0;
        let (mut thermal_loss, mut thermal_tau_s, mut drift, mut leak) = (0.0, 0.0, 0.0, 0.0);
        let mut leak_pole = 1.0;
        let mut drift_settle = 0.0;
        let mut run_gain_offset = None;
        let mut viscous = (0.0, 0.0, 1.0);
        for e in config.effects.iter() {
            match *e {
                Effect::TimeDelay { delay_s } => delay = libm::round(delay_s / dt_s) as usize,
                Effect::CoilLag { tau_s } => lag_tau = tau_s,
                Effect::RateDependence { tau_s } => rate_tau = tau_s,
                Effect::Creep {
                    fraction,
                    tau_min_s,
                    tau_max_s,
                    fluctuation,
                    tau0_s,
                } => {
                    // The core runs on the input normalised by its half span: so does the fluctuation field.
                    let half = config.input_half_span;
                    creep = Creep::log_uniform(fraction, tau_min_s, tau_max_s, dt_s, 0.0)
                        .and_then(|c| c.with_fluctuation(fluctuation / half, tau0_s, dt_s, 0.0));
                }
                Effect::NonCongruent {
                    curvature: c,
                    cubic: k,
                    feedback: f,
                    ..
                } => {
                    (curvature, cubic) = (c, k);
                    // The core runs on the input normalised by its half span and gives ±1 at saturation.
                    feedback = f / half;
                }
                Effect::Accommodation { kappa, cycles } => {
                    use crate::accommodation::{DEADBAND_SHARE, SATURATION_SHARE};
                    accommodation = Accommodation::new(
                        kappa,
                        cycles,
                        config.input_centre - half,
                        config.input_centre + half,
                        DEADBAND_SHARE * 2.0 * half,
                        SATURATION_SHARE * 2.0 * half,
                        config.output_offset,
                    )
                }
                Effect::ThermalDrift { gain_loss, tau_s } => {
                    thermal_loss = gain_loss;
                    thermal_tau_s = tau_s;
                }
                Effect::SensorDrift {
                    rate_nmm_per_s,
                    settle_per_s,
                } => {
                    drift = rate_nmm_per_s;
                    drift_settle = settle_per_s;
                }
                Effect::Leakage {
                    rate_per_s,
                    decay_per_s,
                } => {
                    leak = rate_per_s;
                    leak_pole = crate::filters::leak_pole(dt_s, decay_per_s);
                }
                Effect::RunGainOffset { gain_sd, offset_sd } => {
                    run_gain_offset = Some((gain_sd, offset_sd))
                }
                Effect::Viscous { c, f_y, v0 } => viscous = (c, f_y, v0),
                Effect::FrictionCurrent { .. }
                | Effect::FrictionHarmonics { .. }
                | Effect::TorqueRipple { .. } => {}
            }
        }
        let rate = (rate_tau > 0.0)
            .then(|| RateDependence::new(rate_tau, config.core.saturation_t, dt_s, 2.0, 0.0, 0.0))
            .flatten();
        let mut calibration_rng = calibration_stream(seed);
        let (run_gain, run_offset) = draw_run_calibration(run_gain_offset, &mut calibration_rng);
        Ok(VirtualDevice {
            delay_line: DelayLine::new(vec![0.0; delay], delay, 0.0).expect("sized to the delay"),
            input_lag: Lag::new(lag_tau, dt_s, 0.0),
            rate,
            core: PreisachSteel::new(config.core.clone())?,
            creep,
            curvature,
            cubic,
            feedback,
            accommodation,
            thermal_loss,
            thermal_tau_s,
            heating: Heating::new(thermal_tau_s, dt_s, half, 0.0),
            drift_per_s: drift,
            drift_settle_per_s: drift_settle,
            leak_per_s: leak,
            leak_pole,
            leak_integral: 0.0,
            last_applied: 0.0,
            viscous,
            last_core_input: config.input_centre,
            run_gain_offset,
            run_gain,
            run_offset,
            calibration_rng,
            rng: Rng::new(seed),
            index: 0,
            dt_s,
            seed,
            config,
        })
    }

    pub fn config(&self) -> &DeviceConfig {
        &self.config
    }

    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Time of the next sample, s.
    pub fn time_s(&self) -> f64 {
        self.index as f64 * self.dt_s
    }

    /// This recording's sensor gain and offset (output units) of `run_gain_offset` (1 and 0 when it is off).
    pub fn run_calibration(&self) -> (f64, f64) {
        (self.run_gain, self.run_offset)
    }

    /// A new recording after a rest of `rest_s` seconds at the input centre (see
    /// [`super::VirtualActuator::start_run`]).
    pub fn start_run(&mut self, rest_s: f64) -> Result<(), PlantError> {
        if rest_s.is_nan() || rest_s < 0.0 {
            return Err(PlantError::InvalidParameter(format!(
                "rest_s = {rest_s} must be a nonnegative number of seconds (inf: settled)"
            )));
        }
        if rest_s > 0.0 {
            let c = self.config.input_centre;
            self.delay_line.fill(c);
            self.input_lag.set_output(c);
            let b = self.core.apply(0.0);
            self.rate.iter_mut().for_each(|r| r.reset(0.0, b));
            if let Some(cr) = self.creep.as_mut() {
                cr.hold(b, rest_s, self.dt_s);
                // The core went to the input centre without the fluctuation field: it starts again from there.
                cr.fluctuation_mut().into_iter().for_each(|f| f.reset(0.0));
            }
            let cooled = if self.thermal_tau_s > 0.0 {
                self.heating.state() * libm::exp(-rest_s / self.thermal_tau_s)
            } else {
                0.0
            };
            self.heating.set_state(cooled);
            self.last_applied = c;
            self.last_core_input = c;
            let periods = rest_s / self.dt_s;
            if periods.is_finite() && periods < 4.5e15 {
                self.index += libm::round(periods) as u64;
            }
        }
        self.leak_integral = 0.0;
        (self.run_gain, self.run_offset) =
            draw_run_calibration(self.run_gain_offset, &mut self.calibration_rng);
        Ok(())
    }

    /// One sample with command `input` (a non-finite command applies the input centre).
    pub fn step(&mut self, input: f64) -> DeviceSample {
        let c = self.config.input_centre;
        let cmd = if input.is_finite() { input } else { c };
        let t_s = self.time_s();
        let applied = self.delay_line.step(cmd);
        let driven = self.input_lag.step(applied);
        let b = preisach_flux(
            &mut self.core,
            &mut self.rate,
            &mut self.creep,
            self.feedback,
            (driven - c) / self.config.input_half_span,
        );
        // The input the core saw, back in input units (accommodation follows it).
        let core_input = self
            .rate
            .as_ref()
            .map_or(driven, |r| c + r.core_input() * self.config.input_half_span);
        let cfg = &self.config;
        let mut y =
            cfg.output_offset + cfg.output_scale * output_map(b, self.curvature, self.cubic);
        // The viscous loss of the input's rate (backward difference over the sample).
        let (c, f_y, v0) = self.viscous;
        if c > 0.0 || f_y > 0.0 {
            y += crate::viscous::loss(c, f_y, v0, (core_input - self.last_core_input) / self.dt_s);
        }
        self.last_core_input = core_input;
        if let Some(a) = self.accommodation.as_mut() {
            y += a.step(core_input, y);
        }
        if self.thermal_loss != 0.0 {
            let x = self.heating.step(applied - c);
            y = cfg.output_offset + (y - cfg.output_offset) * (1.0 - self.thermal_loss * x);
        }
        self.leak_integral = crate::filters::leak_step(
            self.leak_integral,
            self.leak_pole,
            self.dt_s,
            applied - c,
            self.last_applied - c,
        );
        self.last_applied = applied;
        let sensed = self.run_gain * (y + self.leak_per_s * self.leak_integral)
            + self.run_offset
            + self.drift_per_s * crate::filters::drift_offset(t_s, self.drift_settle_per_s);
        let measured = sensed
            + cfg.noise
                * if cfg.noise > 0.0 {
                    self.rng.normal()
                } else {
                    0.0
                };
        let measured = super::quantise(measured, cfg.resolution);
        self.index += 1;
        DeviceSample {
            t_s,
            input: cmd,
            output_true: y,
            output: measured,
        }
    }

    pub fn run(&mut self, inputs: &[f64]) -> Vec<DeviceSample> {
        inputs.iter().map(|&u| self.step(u)).collect()
    }
}

/// The `non_congruent` output map on a normalised output (identity when both terms are 0).
#[inline]
fn output_map(n: f64, curvature: f64, cubic: f64) -> f64 {
    if curvature == 0.0 && cubic == 0.0 {
        n
    } else {
        n * (1.0 + curvature * n.abs() + cubic * n * n) / (1.0 + curvature + cubic)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_make_a_hysteresis_loop_and_refuse_angle_effects() {
        for name in DEVICE_PRESETS {
            let cfg = device_preset(name).unwrap();
            let half = cfg.input_half_span;
            let mut d = VirtualDevice::new(cfg, 1).unwrap();
            let n = 2000;
            let up: Vec<f64> = (0..=n)
                .map(|k| -half + 2.0 * half * k as f64 / n as f64)
                .collect();
            let down: Vec<f64> = up.iter().rev().copied().collect();
            d.run(&down);
            let rise = d.run(&up);
            let fall = d.run(&down);
            // At the centre the rising branch lies below the falling one.
            let mid_rise = rise[n / 2].output_true;
            let mid_fall = fall[n / 2].output_true;
            assert!(mid_fall - mid_rise > 0.05 * rise[n].output_true, "{name}");
        }
        let mut cfg = device_preset("piezo").unwrap();
        cfg.effects
            .insert(Effect::parse("torque_ripple:eps=0.1").unwrap());
        assert!(
            VirtualDevice::new(cfg, 0)
                .unwrap_err()
                .to_string()
                .contains("rotor angle")
        );
        assert!(device_preset("nope").is_err());
    }

    #[test]
    fn same_seed_same_bits() {
        let mut cfg = device_preset("piezo").unwrap();
        cfg.effects
            .insert(Effect::parse("creep:fraction=0.05").unwrap());
        cfg.effects
            .insert(Effect::parse("run_gain_offset").unwrap());
        let u: Vec<f64> = (0..3000)
            .map(|k| 80.0 * libm::sin(k as f64 * 0.01))
            .collect();
        let mut a = VirtualDevice::new(cfg.clone(), 7).unwrap();
        let mut b = VirtualDevice::new(cfg, 7).unwrap();
        a.start_run(5.0).unwrap();
        b.start_run(5.0).unwrap();
        let ya: Vec<u64> = a.run(&u).iter().map(|s| s.output.to_bits()).collect();
        let yb: Vec<u64> = b.run(&u).iter().map(|s| s.output.to_bits()).collect();
        assert_eq!(ya, yb);
    }
}
