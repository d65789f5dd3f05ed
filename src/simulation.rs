//! The extended simulation: the forward chain of a model with its extensions (see [`crate::stages`]) —
//! commanded current and rotor angle → torque. It runs the very stages the extended compensator inverts, so the
//! diagnosis, predictions and the compensator agree on what the model is.
//!
//! Per sample: `coil current = delay(command)`, `field current = coil_lag(coil current)`, `core =
//! creep(H(rate_dependence(field current)) + c·d(core input)/dt)` (the `viscous` loss), `field torque = (output_map(core) + accommodation shift along the
//! core input) ×
//! (1 − gain_loss·x(coil current)) × (1 + eps cos(θ + φ))`, `torque = field torque + friction(θ, |field
//! current|)`, and the measurement adds the sensor offset, drift and the leakage integral of the coil current.
//! The delay line and the lag start at rest at the first command (as the plant's state before a run is
//! unknown, the run is assumed to have held its first value), the core at its own start state.
use crate::cbh::Hysteresis;
use crate::filters::DelayLine;
use crate::friction::Friction;
use crate::stages::{Scales, StageError, Stages};
use crate::vocabulary::{EffectKind, Params};

/// One simulated sample.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SimSample {
    /// Coil current after the delay (A).
    pub coil_current_a: f64,
    /// Field (magnetising) current after the lag (A).
    pub field_current_a: f64,
    /// Output of the hysteretic core (N·mm).
    pub core_nmm: f64,
    /// Field torque after the output map and the gains (N·mm).
    pub field_torque_nmm: f64,
    /// Seal friction (N·mm).
    pub friction_nmm: f64,
    /// Field torque + friction (N·mm).
    pub torque_nmm: f64,
    /// What the torque sensor reads: torque + offset + drift (N·mm).
    pub measured_nmm: f64,
}

/// The forward extended model over table storage `S` and delay storage `D`.
#[derive(Debug, Clone)]
pub struct Simulation<S, D, const N: usize, const K: usize> {
    core: Hysteresis<S, N>,
    friction: Friction<K>,
    stages: Stages,
    delay: DelayLine<D>,
    primed: bool,
    dt_s: f64,
    offset_nmm: f64,
    drift_nmm_per_s: f64,
    drift_settle_per_s: f64,
    t0_s: f64,
    index: u64,
    /// Leakage charge of the coil current since the reset (A·s, `filters::leak_step`) and the last coil current
    /// (`leakage`).
    leak_integral: f64,
    last_coil: f64,
    /// The leakage integral's decay over one sample (`filters::leak_pole`).
    leak_pole: f64,
}

impl<S: AsRef<[f64]>, D: AsRef<[f64]> + AsMut<[f64]>, const N: usize, const K: usize>
    Simulation<S, D, N, K>
{
    /// `core` (in its start state) and `friction` with `effects` at sample period `dt_s`; `delay_storage(n)`
    /// gives storage of at least `n` values for the `time_delay` line.
    pub fn new(
        core: Hysteresis<S, N>,
        friction: Friction<K>,
        effects: &[Params],
        dt_s: f64,
        scales: Scales,
        delay_storage: impl FnOnce(usize) -> D,
    ) -> Result<Self, StageError> {
        let (stages, fx) = Stages::new(effects, dt_s, scales)?;
        let friction = fx.apply(friction)?;
        let samples = stages.time_delay.map_or(0, |p| p.samples());
        let Some(delay) = DelayLine::new(delay_storage(samples), samples, 0.0) else {
            return Err(StageError::Scale("delay storage (samples)", samples as f64));
        };
        let mut offset_nmm = 0.0;
        let (mut drift_nmm_per_s, mut drift_settle_per_s) = (0.0, 0.0);
        for p in effects {
            if p.spec.name == "offset" {
                offset_nmm = p.values()[0];
            } else if p.spec.name == EffectKind::SensorDrift.name() {
                drift_nmm_per_s = p.values()[0];
                drift_settle_per_s = p.values()[1];
            }
        }
        Ok(Simulation {
            core,
            friction,
            stages,
            delay,
            primed: false,
            dt_s,
            offset_nmm,
            drift_nmm_per_s,
            drift_settle_per_s,
            t0_s: 0.0,
            index: 0,
            leak_integral: 0.0,
            last_coil: 0.0,
            leak_pole: crate::filters::leak_pole(dt_s, stages.leak_decay_per_s),
        })
    }

    pub fn core(&self) -> &Hysteresis<S, N> {
        &self.core
    }
    pub fn friction(&self) -> &Friction<K> {
        &self.friction
    }
    pub fn stages(&self) -> &Stages {
        &self.stages
    }

    /// Start again: the core at `initial`, the coils at heating state `heating`, the drift clock at `t0_s`
    /// (time of the first sample, s), delay and lag at rest at the next command.
    pub fn reset(&mut self, initial: crate::cbh::Initial, heating: f64, t0_s: f64) {
        self.core.reset(initial);
        self.stages.reset(0.0, self.core.output());
        if let Some(t) = &mut self.stages.thermal {
            t.reset(heating);
        }
        self.primed = false;
        self.t0_s = t0_s;
        self.index = 0;
        self.leak_integral = 0.0;
    }

    /// One sample: commanded nominal current (A) and rotor angle (rad).
    #[inline]
    pub fn step(&mut self, current_a: f64, theta_rad: f64) -> SimSample {
        if !self.primed {
            self.primed = true;
            self.delay.fill(current_a);
            if let Some(l) = &mut self.stages.coil_lag {
                l.reset(current_a);
            }
            // The core's start state held long enough for the stages after it to settle there.
            let core_out = self.core.output();
            if let Some(r) = &mut self.stages.rate {
                r.reset(current_a, core_out);
            }
            if let Some(c) = &mut self.stages.creep {
                c.reset(core_out);
                c.fluctuation_mut()
                    .into_iter()
                    .for_each(|f| f.reset(current_a));
            }
            if let Some(v) = &mut self.stages.viscous {
                v.reset(current_a);
            }
            self.last_coil = current_a;
        }
        let coil = self.delay.step(current_a);
        let field_a = match &mut self.stages.coil_lag {
            Some(l) => l.forward(coil),
            None => coil,
        };
        let core_a = match &mut self.stages.rate {
            Some(r) => r.step(field_a),
            None => field_a,
        };
        let core_a = match &mut self.stages.creep {
            Some(c) => c.core_input(core_a),
            None => core_a,
        };
        let core_a = match &self.stages.mean_field {
            Some(m) => core_a + m.shift(self.core.output()),
            None => core_a,
        };
        let core_nmm = self.core.step(core_a);
        let mut field = self.stages.after_core(core_nmm, core_a);
        let terms = self.friction.angle_terms(theta_rad);
        if let Some(t) = &mut self.stages.thermal {
            field *= t.forward(coil);
        }
        if let Some(r) = &self.stages.ripple {
            field *= r.gain(&terms);
        }
        let friction_nmm = self.friction.with_terms(&terms, field_a);
        let torque_nmm = field + friction_nmm;
        let t_s = self.t0_s + self.dt_s * self.index as f64;
        self.index += 1;
        if self.index > 1 {
            self.leak_integral = crate::filters::leak_step(
                self.leak_integral,
                self.leak_pole,
                self.dt_s,
                coil,
                self.last_coil,
            );
        }
        self.last_coil = coil;
        SimSample {
            coil_current_a: coil,
            field_current_a: field_a,
            core_nmm,
            field_torque_nmm: field,
            friction_nmm,
            torque_nmm,
            measured_nmm: torque_nmm
                + self.offset_nmm
                + self.drift_nmm_per_s * crate::filters::drift_offset(t_s, self.drift_settle_per_s)
                + self.stages.leak_per_s * self.leak_integral,
        }
    }
}
