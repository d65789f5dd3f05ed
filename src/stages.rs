//! Extension stages: each undoes (in the compensator) or reproduces (in the extended simulation) one effect of
//! the vocabulary, at the place in the chain where the physics acts.
//!
//! The forward chain (the extended simulation, [`crate::simulation`]) is
//!
//! `command → time_delay → coil_lag → rate_dependence → CBH core → creep → non_congruent output map
//! → + accommodation shift → × thermal gain × ripple gain → + friction(θ, |field current|)`
//! (`friction_harmonics` and `friction_current` live in the one [`crate::friction::Friction`]),
//!
//! and the compensator ([`crate::compensator`]) walks it backwards once per step:
//!
//! `reference (time_delay: taken delay ahead) − friction → ÷ (thermal gain × ripple gain) − accommodation
//! shift → output-map inverse → creep inverse → CBH inverse → rate-dependence inverse → coil_lag lead (limited)
//! → command`.
//!
//! `creep` ([`crate::creep::Creep`]), `rate_dependence` ([`crate::rate_dependence::RateDependence`]) and
//! `accommodation` ([`crate::accommodation::Accommodation`]) are their own stages: each has a forward step, an
//! inverse from the state before the sample and a commit with what the core actually did. `leakage` and
//! `run_gain_offset` act on the measurement only and are never compensated (the extended simulation adds the
//! leakage integral to what the sensor reads).
//!
//! Every stage is `no_std`, allocation-free and deterministic, with its sample period fixed at construction. A
//! stage offers `forward` (simulation: advance with what happened this sample) and, for the compensator, an
//! inverse that reads the state *before* this sample plus a commit that advances the state with what was
//! actually commanded (after limiting or a fault), so the compensator's states always follow the real command.
//! A new stage (creep, rate dependence, ...) is a struct with those three operations, a field in [`Stages`] and
//! one line in each walk.
use crate::accommodation::Accommodation;
use crate::creep::Creep;
use crate::filters::{DelayLine, Heating, Lag};
use crate::friction::{AngleTerms, FrictionError};
use crate::rate_dependence::RateDependence;
use crate::vocabulary::{EffectKind, Params};
use core::fmt;

/// Samples of reference history the `time_delay` predictor fits its slope over (at most).
pub const PREDICT_WINDOW: usize = 16;
/// Nodes of an output-map table.
pub const MAP_NODES: usize = 257;
/// The field-torque target is divided by the field gain, but never by less than this.
pub const MIN_FIELD_GAIN: f64 = 1e-3;

/// `coil_lag`: the field current is a first-order lag of the coil current.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoilLag {
    lag: Lag,
}

impl CoilLag {
    pub fn new(tau_s: f64, dt_s: f64) -> Self {
        CoilLag {
            lag: Lag::new(tau_s, dt_s, 0.0),
        }
    }
    /// `exp(−dt/τ)` of the lag.
    pub fn pole(&self) -> f64 {
        self.lag.pole()
    }
    /// Field current reached at the last sample (A).
    pub fn field_a(&self) -> f64 {
        self.lag.output()
    }
    /// Start at rest at field current `field_a`.
    pub fn reset(&mut self, field_a: f64) {
        self.lag.set_output(field_a);
    }
    /// Forward: coil current this sample → field current at its end.
    #[inline]
    pub fn forward(&mut self, current_a: f64) -> f64 {
        self.lag.step(current_a)
    }
    /// Inverse (the exact lead): the coil current that brings the field current to `field_a` this sample.
    #[inline]
    pub fn command_for(&self, field_a: f64) -> f64 {
        self.lag.input_for(field_a)
    }
    /// The wanted field current was reached exactly (the command was not limited): hold it as the state.
    #[inline]
    pub fn reached(&mut self, field_a: f64) {
        self.lag.set_output(field_a);
    }
}

/// `time_delay`: the coil current is the command of `samples` samples ago. The compensator commands now what
/// must act `samples` later: with the reference known ahead it is given the reference (and angle) of that sample
/// (`Compensator::step_ahead`); otherwise this predictor extrapolates both along their slope over the last
/// `min(samples, PREDICT_WINDOW)` samples (no extrapolation until that much history is seen; the angle
/// difference is wrapped to (−π, π], so encoder angles in [0, 2π) work).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Predictor {
    samples: usize,
    reach: f64,
    refs: DelayLine<[f64; PREDICT_WINDOW]>,
    thetas: DelayLine<[f64; PREDICT_WINDOW]>,
    seen: usize,
}

impl Predictor {
    pub fn new(delay_s: f64, dt_s: f64) -> Self {
        let samples = libm::round(delay_s / dt_s).clamp(0.0, u32::MAX as f64) as usize;
        let window = samples.clamp(1, PREDICT_WINDOW);
        let line = || match DelayLine::new([0.0; PREDICT_WINDOW], window, 0.0) {
            Some(l) => l,
            None => unreachable!("window <= PREDICT_WINDOW"),
        };
        Predictor {
            samples,
            reach: samples as f64 / window as f64,
            refs: line(),
            thetas: line(),
            seen: 0,
        }
    }
    /// The delay in whole samples.
    pub fn samples(&self) -> usize {
        self.samples
    }
    /// Forget the history.
    pub fn reset(&mut self) {
        self.refs.fill(0.0);
        self.thetas.fill(0.0);
        self.seen = 0;
    }
    /// The reference and angle `samples` ahead, predicted from this sample's and the history (finite inputs).
    #[inline]
    pub fn predict(&mut self, reference: f64, theta: f64) -> (f64, f64) {
        let r_old = self.refs.step(reference);
        let t_old = self.thetas.step(theta);
        if self.seen < self.refs.samples() {
            self.seen += 1;
            return (reference, theta);
        }
        let d_theta = wrap_angle(theta - t_old);
        (
            reference + self.reach * (reference - r_old),
            theta + self.reach * d_theta,
        )
    }
}

/// `x` wrapped to (−π, π] (up to the rounding of the nearest whole turn; exact for |x| < 2^51 turns).
#[inline(always)]
pub fn wrap_angle(x: f64) -> f64 {
    const SHIFT: f64 = 6_755_399_441_055_744.0; // 1.5·2^52: adding and subtracting it rounds to an integer
    let turns = (x * (1.0 / core::f64::consts::TAU) + SHIFT) - SHIFT;
    x - turns * core::f64::consts::TAU
}

/// `thermal_drift`: the field torque is scaled by `1 − gain_loss·x`, `x` the coil heating state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thermal {
    heating: Heating,
    gain_loss: f64,
}

impl Thermal {
    pub fn new(gain_loss: f64, tau_s: f64, dt_s: f64, full_current_a: f64) -> Self {
        Thermal {
            heating: Heating::new(tau_s, dt_s, full_current_a, 0.0),
            gain_loss,
        }
    }
    /// Heating state (1 = steady full current).
    pub fn state(&self) -> f64 {
        self.heating.state()
    }
    pub fn reset(&mut self, state: f64) {
        self.heating.set_state(state);
    }
    /// Field gain of the state before this sample (what the compensator divides by: the heating of this
    /// sample's own current, `(1 − p)` of a step, is not known yet).
    #[inline]
    pub fn gain(&self) -> f64 {
        1.0 - self.gain_loss * self.heating.state()
    }
    /// Forward: heat with this sample's coil current, return the field gain.
    #[inline]
    pub fn forward(&mut self, current_a: f64) -> f64 {
        1.0 - self.gain_loss * self.heating.step(current_a)
    }
    /// Compensator: advance with the coil current commanded.
    #[inline]
    pub fn commit(&mut self, current_a: f64) {
        self.heating.step(current_a);
    }
}

/// `friction_current`: the compensator's estimate of the |field current| the seal friction grows with. The current
/// of this sample is not known before the inverse, and the last one fed straight back would close a loop through
/// the friction and the inverse that chatters near reversals (where the branch is flat and a small torque change
/// needs a large current change); so the estimate is the last field current smoothed over [`FRICTION_CURRENT_TAU_S`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrictionCurrent {
    smooth: Lag,
}

/// Time constant of the compensator's `friction_current` estimate (s).
pub const FRICTION_CURRENT_TAU_S: f64 = 0.01;

impl FrictionCurrent {
    pub fn new(dt_s: f64) -> Self {
        FrictionCurrent {
            smooth: Lag::new(FRICTION_CURRENT_TAU_S, dt_s, 0.0),
        }
    }
    /// The |current| (A) the friction feedforward uses this sample.
    #[inline]
    pub fn current_a(&self) -> f64 {
        self.smooth.output()
    }
    /// Advance with the field current reached this sample.
    #[inline]
    pub fn commit(&mut self, field_a: f64) {
        self.smooth.step(field_a.abs());
    }
    pub fn reset(&mut self, field_a: f64) {
        self.smooth.set_output(field_a.abs());
    }
}

/// `torque_ripple`: the field torque is scaled by `1 + eps·cos(θ + phase)`, from the friction's `sincos`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ripple {
    eps_cos: f64,
    eps_sin: f64,
}

impl Ripple {
    pub fn new(eps: f64, phase_rad: f64) -> Self {
        Ripple {
            eps_cos: eps * libm::cos(phase_rad),
            eps_sin: eps * libm::sin(phase_rad),
        }
    }
    #[inline]
    pub fn gain(&self, t: &AngleTerms) -> f64 {
        1.0 + (self.eps_cos * t.cos1 - self.eps_sin * t.sin1)
    }
}

/// `non_congruent`: a monotone output map after the hysteretic core, as a table `core torque → field torque`
/// (linear between nodes, the end segments extended). Forward and inverse use the same nodes, so each is the
/// other's exact inverse up to round-off; the cell is always the one holding the value (never hint-dependent), so
/// results replay bit for bit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputMap {
    len: usize,
    core: [f64; MAP_NODES],
    field: [f64; MAP_NODES],
    hint: usize,
}

impl OutputMap {
    /// From `(core, field)` nodes, both strictly increasing and finite (2 to [`MAP_NODES`] nodes).
    pub fn from_table(core: &[f64], field: &[f64]) -> Result<Self, StageError> {
        let n = core.len();
        if n != field.len() || !(2..=MAP_NODES).contains(&n) {
            return Err(StageError::OutputMap(
                "needs 2 to MAP_NODES (core, field) nodes of equal count",
            ));
        }
        let increasing =
            |v: &[f64]| v.iter().all(|x| x.is_finite()) && v.windows(2).all(|w| w[1] > w[0]);
        if !increasing(core) || !increasing(field) {
            return Err(StageError::OutputMap(
                "nodes must be finite and strictly increasing (a monotone map)",
            ));
        }
        let mut m = OutputMap {
            len: n,
            core: [0.0; MAP_NODES],
            field: [0.0; MAP_NODES],
            hint: 0,
        };
        m.core[..n].copy_from_slice(core);
        m.field[..n].copy_from_slice(field);
        Ok(m)
    }

    /// The vocabulary's map `T = S·n(1 + c|n|)/(1 + c)`, `n = T_core/S`, tabulated on [`MAP_NODES`] even nodes
    /// over `|T_core| ≤ 2S` (a concave map only up to its turning point `|n| = 1/(2|c|)`).
    pub fn curvature(curvature: f64, scale_nmm: f64) -> Result<Self, StageError> {
        if !(curvature.is_finite() && curvature > -1.0) {
            return Err(StageError::OutputMap(
                "curvature must be finite and above -1",
            ));
        }
        if !(scale_nmm.is_finite() && scale_nmm > 0.0) {
            return Err(StageError::OutputMap(
                "full-scale torque must be positive and finite",
            ));
        }
        let reach = if curvature < 0.0 {
            (0.999 / (-2.0 * curvature)).min(2.0)
        } else {
            2.0
        };
        let mut core = [0.0; MAP_NODES];
        let mut field = [0.0; MAP_NODES];
        for i in 0..MAP_NODES {
            let n = reach * (2.0 * i as f64 / (MAP_NODES - 1) as f64 - 1.0);
            core[i] = scale_nmm * n;
            field[i] = scale_nmm * n * (1.0 + curvature * n.abs()) / (1.0 + curvature);
        }
        Self::from_table(&core, &field)
    }

    /// The nodes `(core, field)`.
    pub fn nodes(&self) -> (&[f64], &[f64]) {
        (&self.core[..self.len], &self.field[..self.len])
    }

    /// Cell `k` (nodes `k`, `k+1`) holding `v` in `xs`: the last node `≤ v`, within `0..len−1` (ends extend).
    #[inline]
    fn cell(xs: &[f64], v: f64, hint: usize) -> usize {
        let last = xs.len() - 2;
        let h = hint.min(last);
        let inside = |k: usize| (k == 0 || xs[k] <= v) && (k == last || v < xs[k + 1]);
        if inside(h) {
            return h;
        }
        if h < last && inside(h + 1) {
            return h + 1;
        }
        if h > 0 && inside(h - 1) {
            return h - 1;
        }
        xs.partition_point(|&x| x <= v).clamp(1, last + 1) - 1
    }

    #[inline]
    fn interpolate(xs: &[f64], ys: &[f64], k: usize, v: f64) -> f64 {
        ys[k] + (v - xs[k]) * ((ys[k + 1] - ys[k]) / (xs[k + 1] - xs[k]))
    }

    /// Field torque of core torque `core_nmm`.
    #[inline]
    pub fn forward(&self, core_nmm: f64) -> f64 {
        let (c, f) = self.nodes();
        let k = Self::cell(c, core_nmm, self.hint);
        Self::interpolate(c, f, k, core_nmm)
    }

    /// Core torque giving field torque `field_nmm` (the hint only speeds the search up).
    #[inline]
    pub fn inverse(&mut self, field_nmm: f64) -> f64 {
        let n = self.len;
        let k = Self::cell(&self.field[..n], field_nmm, self.hint);
        self.hint = k;
        Self::interpolate(&self.field[..n], &self.core[..n], k, field_nmm)
    }
}

/// Why a set of extensions could not be built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StageError {
    /// The sample period must be positive and finite.
    SamplePeriod(f64),
    /// The same effect given twice.
    Twice(EffectKind),
    Friction(FrictionError),
    OutputMap(&'static str),
    /// A full-scale value the stages need is not positive and finite (`what`, value).
    Scale(&'static str, f64),
}

impl fmt::Display for StageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            StageError::SamplePeriod(dt) => write!(
                f,
                "the sample period must be a positive finite number of seconds, got {dt}"
            ),
            StageError::Twice(k) => write!(f, "effect {k} is given twice"),
            StageError::Friction(e) => e.fmt(f),
            StageError::OutputMap(m) => write!(f, "non_congruent output map: {m}"),
            StageError::Scale(what, v) => {
                write!(f, "{what} must be positive and finite, got {v}")
            }
        }
    }
}

impl From<FrictionError> for StageError {
    fn from(e: FrictionError) -> Self {
        StageError::Friction(e)
    }
}

/// The stages of one extended model (each `None` when its effect is off) and the changes to the friction model.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Stages {
    pub coil_lag: Option<CoilLag>,
    pub time_delay: Option<Predictor>,
    pub thermal: Option<Thermal>,
    pub ripple: Option<Ripple>,
    pub output_map: Option<OutputMap>,
    pub friction_current: Option<FrictionCurrent>,
    pub creep: Option<Creep>,
    pub rate: Option<RateDependence>,
    pub accommodation: Option<Accommodation>,
    /// `leakage`: measured output added per unit of input-time (output/(input·s)); measurement only.
    pub leak_per_s: f64,
}

/// What the friction model gains from the extensions: an extra harmonic and a current gain.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct FrictionExtension {
    /// `(order, amplitude_nmm, phase_rad)` of `friction_harmonics`.
    pub harmonic: Option<(usize, f64, f64)>,
    /// `gain_per_a` of `friction_current`.
    pub gain_per_a: Option<f64>,
}

impl FrictionExtension {
    /// `friction` with these changes.
    pub fn apply<const K: usize>(
        &self,
        mut friction: crate::friction::Friction<K>,
    ) -> Result<crate::friction::Friction<K>, FrictionError> {
        if let Some((order, amplitude, phase)) = self.harmonic {
            friction = friction.with_harmonic(order, amplitude, phase)?;
        }
        if let Some(g) = self.gain_per_a {
            friction = friction.with_current_gain(g)?;
        }
        Ok(friction)
    }
}

/// Full-scale values of the model the stages are built for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scales {
    /// Current of unit heating (A) for `thermal_drift`.
    pub full_current_a: f64,
    /// Full-scale torque (N·mm) for `non_congruent` when its `scale_nmm` is 0.
    pub full_torque_nmm: f64,
    /// The core's input and output ranges: the reference slope of `rate_dependence` (output span over input
    /// span), the saturation ends, reversal dead-band and output centre of `accommodation`.
    pub input_range: (f64, f64),
    pub output_range: (f64, f64),
}

impl Scales {
    /// Full values and the ranges of `core`.
    pub fn of_core<S: AsRef<[f64]>, const N: usize>(
        core: &crate::cbh::Hysteresis<S, N>,
        full_current_a: f64,
        full_torque_nmm: f64,
    ) -> Self {
        Scales {
            full_current_a,
            full_torque_nmm,
            input_range: core.input_range(),
            output_range: core.output_range(),
        }
    }

    fn spans(&self) -> Result<(f64, f64), StageError> {
        let (lo, hi) = self.input_range;
        let (ylo, yhi) = self.output_range;
        let (du, dy) = (hi - lo, yhi - ylo);
        if !(du.is_finite() && du > 0.0) {
            return Err(StageError::Scale("input span", du));
        }
        if !(dy.is_finite() && dy > 0.0) {
            return Err(StageError::Scale("output span", dy));
        }
        Ok((du, dy))
    }
}

impl Stages {
    /// Build the stages of `effects` (validated vocabulary parameters; entries that are not effects, and the
    /// measurement-only `sensor_drift`, are skipped) at sample period `dt_s`.
    pub fn new(
        effects: &[Params],
        dt_s: f64,
        scales: Scales,
    ) -> Result<(Stages, FrictionExtension), StageError> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(StageError::SamplePeriod(dt_s));
        }
        let mut st = Stages::default();
        let mut fr = FrictionExtension::default();
        let mut seen = [false; EffectKind::ALL.len()];
        for p in effects {
            let Some(kind) = EffectKind::from_name(p.spec.name) else {
                continue;
            };
            if core::mem::replace(&mut seen[kind as usize], true) {
                return Err(StageError::Twice(kind));
            }
            let v = p.values();
            match kind {
                EffectKind::CoilLag => {
                    if v[0] > 0.0 {
                        st.coil_lag = Some(CoilLag::new(v[0], dt_s));
                    }
                }
                EffectKind::TimeDelay => {
                    let pred = Predictor::new(v[0], dt_s);
                    if pred.samples() > 0 {
                        st.time_delay = Some(pred);
                    }
                }
                EffectKind::ThermalDrift => {
                    let full = scales.full_current_a;
                    if !(full.is_finite() && full > 0.0) {
                        return Err(StageError::Scale("full current (A)", full));
                    }
                    if v[0] != 0.0 {
                        st.thermal = Some(Thermal::new(v[0], v[1], dt_s, full));
                    }
                }
                EffectKind::TorqueRipple => {
                    if v[0] != 0.0 {
                        st.ripple = Some(Ripple::new(v[0], v[1]));
                    }
                }
                EffectKind::NonCongruent => {
                    let scale = if v[1] > 0.0 {
                        v[1]
                    } else {
                        scales.full_torque_nmm
                    };
                    if !(scale.is_finite() && scale > 0.0) {
                        return Err(StageError::Scale("full-scale torque (N·mm)", scale));
                    }
                    if v[0] != 0.0 {
                        st.output_map = Some(OutputMap::curvature(v[0], scale)?);
                    }
                }
                EffectKind::FrictionHarmonics => fr.harmonic = Some((v[0] as usize, v[1], v[2])),
                EffectKind::FrictionCurrent => {
                    fr.gain_per_a = Some(v[0]);
                    if v[0] != 0.0 {
                        st.friction_current = Some(FrictionCurrent::new(dt_s));
                    }
                }
                EffectKind::SensorDrift | EffectKind::RunGainOffset => {}
                EffectKind::Leakage => st.leak_per_s = v[0],
                EffectKind::Creep => {
                    if v[0] != 0.0 {
                        st.creep = Some(
                            Creep::log_uniform(v[0], v[1], v[2], dt_s, 0.0)
                                .ok_or(StageError::Scale("creep time constants (s)", v[1]))?,
                        );
                    }
                }
                EffectKind::RateDependence => {
                    let (du, dy) = scales.spans()?;
                    if v[0] > 0.0 {
                        let lo = scales.input_range.0;
                        st.rate = RateDependence::new(v[0], dy / du, dt_s, du, lo, 0.0);
                    }
                }
                EffectKind::Accommodation => {
                    let (du, _) = scales.spans()?;
                    let (lo, hi) = scales.input_range;
                    let (ylo, yhi) = scales.output_range;
                    if v[0] != 0.0 {
                        st.accommodation = Accommodation::new(
                            v[0],
                            v[1],
                            lo,
                            hi,
                            crate::accommodation::DEADBAND_SHARE * du,
                            crate::accommodation::SATURATION_SHARE * du,
                            0.5 * (ylo + yhi),
                        );
                    }
                }
            }
        }
        Ok((st, fr))
    }

    /// Whether any stage is on.
    pub fn any(&self) -> bool {
        self.coil_lag.is_some()
            || self.time_delay.is_some()
            || self.thermal.is_some()
            || self.ripple.is_some()
            || self.output_map.is_some()
            || self.friction_current.is_some()
            || self.creep.is_some()
            || self.rate.is_some()
            || self.accommodation.is_some()
    }

    /// Back to rest: field current `field_a` with core output `core_out` (creep settled there), cold coils, no
    /// reference history, no accommodation.
    pub fn reset(&mut self, field_a: f64, core_out: f64) {
        if let Some(c) = &mut self.creep {
            c.reset(core_out);
        }
        if let Some(r) = &mut self.rate {
            r.reset(field_a, core_out);
        }
        if let Some(a) = &mut self.accommodation {
            a.reset();
        }
        if let Some(l) = &mut self.coil_lag {
            l.reset(field_a);
        }
        if let Some(p) = &mut self.time_delay {
            p.reset();
        }
        if let Some(t) = &mut self.thermal {
            t.reset(0.0);
        }
        if let Some(f) = &mut self.friction_current {
            f.reset(field_a);
        }
    }

    /// The stateful stages (a plain copy).
    pub fn state(&self) -> StageState {
        StageState {
            coil_lag: self.coil_lag,
            time_delay: self.time_delay,
            thermal: self.thermal,
            friction_current: self.friction_current,
            creep: self.creep,
            rate: self.rate,
            accommodation: self.accommodation,
        }
    }

    /// Return to `s` (taken from stages with the same configuration, else `false` and nothing changes).
    pub fn restore(&mut self, s: &StageState) -> bool {
        fn same<T: Copy + PartialEq>(
            a: &Option<T>,
            b: &Option<T>,
            config: impl Fn(&T) -> T,
        ) -> bool {
            match (a, b) {
                (None, None) => true,
                (Some(x), Some(y)) => config(x) == config(y),
                _ => false,
            }
        }
        let ok = same(&self.coil_lag, &s.coil_lag, |l| {
            let mut l = *l;
            l.reset(0.0);
            l
        }) && same(&self.time_delay, &s.time_delay, |p| {
            let mut p = *p;
            p.reset();
            p
        }) && same(&self.thermal, &s.thermal, |t| {
            let mut t = *t;
            t.reset(0.0);
            t
        }) && same(&self.friction_current, &s.friction_current, |f| {
            let mut f = *f;
            f.reset(0.0);
            f
        }) && same(&self.creep, &s.creep, |c| {
            let mut c = *c;
            c.reset(0.0);
            c
        }) && same(&self.rate, &s.rate, |r| {
            let mut r = *r;
            r.reset(0.0, 0.0);
            r
        }) && same(&self.accommodation, &s.accommodation, |a| {
            let mut a = *a;
            a.reset();
            a
        });
        if ok {
            self.coil_lag = s.coil_lag;
            self.time_delay = s.time_delay;
            self.thermal = s.thermal;
            self.friction_current = s.friction_current;
            self.creep = s.creep;
            self.rate = s.rate;
            self.accommodation = s.accommodation;
        }
        ok
    }
}

#[cfg(feature = "alloc")]
impl StageState {
    /// The states as plain words: a presence mask, then each present stage's values.
    pub fn to_words(&self, out: &mut alloc::vec::Vec<u64>) {
        let mask = u64::from(self.coil_lag.is_some())
            | (u64::from(self.time_delay.is_some()) << 1)
            | (u64::from(self.thermal.is_some()) << 2)
            | (u64::from(self.friction_current.is_some()) << 3);
        out.push(mask);
        if let Some(l) = &self.coil_lag {
            out.push(l.field_a().to_bits());
        }
        if let Some(p) = &self.time_delay {
            out.push(p.seen as u64);
            out.push(p.refs.samples() as u64);
            out.extend(p.refs.values().map(f64::to_bits));
            out.extend(p.thetas.values().map(f64::to_bits));
        }
        if let Some(t) = &self.thermal {
            out.push(t.state().to_bits());
        }
        if let Some(f) = &self.friction_current {
            out.push(f.current_a().to_bits());
        }
    }
}

impl Stages {
    /// Advance the stages after the hysteretic core (rate dependence observes the core, then creep, the output
    /// map and accommodation) for the core output `core_nmm` reached at core input `core_a`; the field torque
    /// before the gains. One chain for the compensator's forward model and the extended simulation.
    #[inline]
    pub fn after_core(&mut self, core_nmm: f64, core_a: f64) -> f64 {
        if let Some(r) = &mut self.rate {
            r.observe(core_nmm);
        }
        let crept = match &mut self.creep {
            Some(c) => c.step(core_nmm),
            None => core_nmm,
        };
        let mut field = match &self.output_map {
            Some(m) => m.forward(crept),
            None => crept,
        };
        if let Some(a) = &mut self.accommodation {
            field += a.step(core_a, field);
        }
        field
    }
}

impl Stages {
    /// Read stage states written by [`StageState::to_words`] for stages configured like these, from `words`
    /// (advanced past them); `None` if they do not fit this configuration or a value is not finite.
    pub fn state_from_words(&self, words: &mut &[u64]) -> Option<StageState> {
        fn take(w: &mut &[u64]) -> Option<u64> {
            let (&first, rest) = w.split_first()?;
            *w = rest;
            Some(first)
        }
        fn float(w: &mut &[u64]) -> Option<f64> {
            Some(f64::from_bits(take(w)?)).filter(|v| v.is_finite())
        }
        let mask = take(words)?;
        let want = u64::from(self.coil_lag.is_some())
            | (u64::from(self.time_delay.is_some()) << 1)
            | (u64::from(self.thermal.is_some()) << 2)
            | (u64::from(self.friction_current.is_some()) << 3);
        if mask != want {
            return None;
        }
        let mut st = self.state();
        if let Some(l) = &mut st.coil_lag {
            l.reset(float(words)?);
        }
        if let Some(p) = &mut st.time_delay {
            let seen = usize::try_from(take(words)?).ok()?;
            let window = usize::try_from(take(words)?).ok()?;
            if window != p.refs.samples() || seen > window {
                return None;
            }
            let mut refs = [0.0; PREDICT_WINDOW];
            let mut thetas = [0.0; PREDICT_WINDOW];
            for v in refs.iter_mut().take(window) {
                *v = float(words)?;
            }
            for v in thetas.iter_mut().take(window) {
                *v = float(words)?;
            }
            p.refs.set_values(refs);
            p.thetas.set_values(thetas);
            p.seen = seen;
        }
        if let Some(t) = &mut st.thermal {
            t.reset(float(words)?);
        }
        if let Some(f) = &mut st.friction_current {
            f.smooth.set_output(float(words)?);
        }
        Some(st)
    }
}

/// The state of the stateful stages (part of a compensator snapshot).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageState {
    coil_lag: Option<CoilLag>,
    time_delay: Option<Predictor>,
    thermal: Option<Thermal>,
    friction_current: Option<FrictionCurrent>,
    creep: Option<Creep>,
    rate: Option<RateDependence>,
    accommodation: Option<Accommodation>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_map_inverse_is_exact_and_cells_are_canonical() {
        for c in [-0.45, -0.2, 0.5, 1.0, 4.5] {
            let mut m = OutputMap::curvature(c, 300.0).unwrap();
            for i in 0..=2000 {
                let t = -700.0 + 0.7 * i as f64;
                let y = m.inverse(t);
                assert!((m.forward(y) - t).abs() < 1e-9, "c={c}: {t} -> {y}");
                // The exact map at the nodes, close between them.
                let n = y / 300.0;
                if n.abs() <= 1.0 {
                    let g = 300.0 * n * (1.0 + c * n.abs()) / (1.0 + c);
                    assert!((g - t).abs() < 0.05, "c={c}: {g} vs {t}");
                }
            }
            // The same value from any hint.
            let v = 123.456;
            let a = m.inverse(v);
            m.inverse(-650.0);
            assert_eq!(m.inverse(v).to_bits(), a.to_bits());
        }
        assert!(OutputMap::from_table(&[0.0, 1.0], &[1.0, 0.0]).is_err());
    }

    #[test]
    fn predictor_extrapolates_ramps_exactly_and_wraps_angles() {
        let mut p = Predictor::new(0.005, 0.001);
        assert_eq!(p.samples(), 5);
        let mut last = (0.0, 0.0);
        for n in 0..40 {
            let th = (0.3 * n as f64).rem_euclid(core::f64::consts::TAU);
            last = p.predict(2.0 * n as f64, th);
        }
        assert!((last.0 - 2.0 * 44.0).abs() < 1e-9);
        let want = (0.3 * 44.0f64).rem_euclid(core::f64::consts::TAU);
        let got = last.1.rem_euclid(core::f64::consts::TAU);
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
    }

    #[test]
    fn building_skips_what_is_not_compensated_and_refuses_doubles() {
        use crate::vocabulary::{MODEL_ENTRIES, Params};
        let fx = [
            Params::new(EffectKind::CoilLag.spec(), &[("tau_s", 0.01)]).unwrap(),
            Params::defaults(EffectKind::SensorDrift.spec()),
            Params::defaults(&MODEL_ENTRIES[2]),
            Params::defaults(EffectKind::FrictionHarmonics.spec()),
        ];
        let scales = Scales {
            full_current_a: 1.25,
            full_torque_nmm: 300.0,
            input_range: (-1.25, 1.25),
            output_range: (-300.0, 300.0),
        };
        let (st, fr) = Stages::new(&fx, 1e-3, scales).unwrap();
        assert!(st.coil_lag.is_some() && st.thermal.is_none());
        assert_eq!(fr.harmonic, Some((5, 6.0, 0.0)));
        let twice = [fx[0], fx[0]];
        assert_eq!(
            Stages::new(&twice, 1e-3, scales).unwrap_err(),
            StageError::Twice(EffectKind::CoilLag)
        );
        assert!(Stages::new(&fx, 0.0, scales).is_err());
    }
}
