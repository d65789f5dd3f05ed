//! Open-loop torque compensator (paper figs 20 and 23): `I = H⁻¹[T_ref − T_f(θ)]`, split to the two coils
//! (eq 8), limited, and converted to converter voltages; optionally extended by the stages of a diagnosed model
//! ([`crate::stages`]): `time_delay` preview or prediction, current-dependent friction and extra harmonics in the
//! one friction feedforward, the thermal and ripple field gains, the `non_congruent` output-map inverse before
//! the CBH inverse, its mean field (the core's last output fed back) taken off after it, and the `coil_lag` lead.
//!
//! Safety invariants (property-tested): never both coils energised; `|I| <= limit`; a NaN/inf reference or angle,
//! or any non-finite intermediate, gives zero current with `fault` set (no panic); the forward memory and every
//! stage state always follow the current actually commanded, including after limiting and faults. No allocation
//! in `step`.
use crate::cbh::Hysteresis;
use crate::friction::{Friction, MAX_MAGNITUDE};
use crate::inverse::InverseInput;
use crate::stages::{MIN_FIELD_GAIN, Scales, StageError, StageState, Stages};
use crate::vocabulary::Params;

/// Which inverse drives the command.
// Held once per compensator and `no_std` has no `Box`: the size difference is fine.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
pub enum InverseKind<S, const N: usize> {
    /// Exact inverse of the forward operator (docs/architecture.md §2.5).
    Exact,
    /// The paper's inverse CBH operator on current curves (input torque, output current). Its torque-domain
    /// memory follows the targets it is given (and the torque actually produced after a fault).
    Paper(Hysteresis<S, N>),
}

/// One control-period command: nominal current, coil currents (A), converter voltages (V) and flags.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(
    feature = "python",
    pyo3::pyclass(name = "Command", module = "bmr", get_all, eq)
)]
pub struct Command {
    /// Nominal current (A): negative drives coil 1, positive coil 2.
    pub current_a: f64,
    /// Coil 1 current (A, ≥ 0).
    pub coil1_a: f64,
    /// Coil 2 current (A, ≥ 0).
    pub coil2_a: f64,
    /// Converter 1 input voltage (V).
    pub volt1_v: f64,
    /// Converter 2 input voltage (V).
    pub volt2_v: f64,
    /// The torque asked for was not reachable (input range or current limit).
    pub saturated: bool,
    /// The reference or angle (or an intermediate) was NaN/inf: zero current commanded.
    pub fault: bool,
}

impl Command {
    /// Split a nominal current to the coils (eq 8) and convert to voltages.
    #[inline]
    pub fn from_current(
        current_a: f64,
        gain_a_per_v: f64,
        saturated: bool,
        fault: bool,
    ) -> Command {
        let coil1_a = if current_a < 0.0 { -current_a } else { 0.0 };
        let coil2_a = if current_a > 0.0 { current_a } else { 0.0 };
        Command {
            current_a,
            coil1_a,
            coil2_a,
            volt1_v: coil1_a / gain_a_per_v,
            volt2_v: coil2_a / gain_a_per_v,
            saturated,
            fault,
        }
    }
}

/// Compensator state that changes per step (a plain copy).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompensatorState<const N: usize> {
    forward: crate::cbh::State<N>,
    paper: Option<crate::cbh::State<N>>,
    stages: StageState,
}

/// Hysteresis + friction compensator with a memory of `N` reversal points and `K` friction harmonics.
#[derive(Debug, Clone)]
pub struct Compensator<S, const N: usize, const K: usize> {
    forward: Hysteresis<S, N>,
    inverse: InverseKind<S, N>,
    friction: Friction<K>,
    stages: Stages,
    /// Any stage on, or current-dependent friction: `step` takes the extended path.
    extended: bool,
    gain_a_per_v: f64,
    limit_a: f64,
    /// Friction feedforward of the last step (N·mm; NaN after a fault).
    friction_nmm: f64,
    /// Field gain (thermal × ripple) the last step divided by.
    field_gain: f64,
    /// Field torque before the gains (core output through creep, the output map and accommodation) of the last
    /// extended step (N·mm).
    field_nmm: f64,
}

/// A compensator parameter outside its range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CompensatorError {
    /// Converter gain must be finite and positive, and `limit / gain` finite (A/V).
    Gain(f64),
    /// Current limit must be finite and positive (A).
    Limit(f64),
    /// The friction feedforward could overflow at the current limit (its bound, N·mm).
    FrictionBound(f64),
    /// An extension stage could not be built.
    Stage(StageError),
    /// A friction model with a current gain needs the `friction_current` stage (built with the control period).
    CurrentDependentFriction,
}

impl core::fmt::Display for CompensatorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            CompensatorError::Gain(g) => write!(
                f,
                "converter gain must be a positive finite A/V value whose voltage at the current limit is \
                 finite, got {g}"
            ),
            CompensatorError::Limit(l) => write!(
                f,
                "current limit must be a positive finite A value, got {l}"
            ),
            CompensatorError::FrictionBound(b) => write!(
                f,
                "the friction feedforward at the current limit is bounded by {b:e} N·mm, above {MAX_MAGNITUDE:e}: \
                 it could not be evaluated finitely"
            ),
            CompensatorError::Stage(e) => e.fmt(f),
            CompensatorError::CurrentDependentFriction => f.write_str(
                "a friction model with gain_per_a needs the friction_current extension (and the control period \
                 dt_s) to estimate the current it grows with",
            ),
        }
    }
}

impl From<StageError> for CompensatorError {
    fn from(e: StageError) -> Self {
        CompensatorError::Stage(e)
    }
}

impl<S: AsRef<[f64]>, const N: usize, const K: usize> Compensator<S, N, K> {
    /// `forward`: the identified operator (its current state is the compensator's start state).
    pub fn new(
        forward: Hysteresis<S, N>,
        inverse: InverseKind<S, N>,
        friction: Friction<K>,
        gain_a_per_v: f64,
        limit_a: f64,
    ) -> Result<Self, CompensatorError> {
        if !(limit_a.is_finite() && limit_a > 0.0) {
            return Err(CompensatorError::Limit(limit_a));
        }
        if !(gain_a_per_v.is_finite() && gain_a_per_v > 0.0 && (limit_a / gain_a_per_v).is_finite())
        {
            return Err(CompensatorError::Gain(gain_a_per_v));
        }
        let mut c = Compensator {
            forward,
            inverse,
            friction: Friction::zero(),
            stages: Stages::default(),
            extended: false,
            gain_a_per_v,
            limit_a,
            friction_nmm: 0.0,
            field_gain: 1.0,
            field_nmm: 0.0,
        };
        c.set_friction(friction)?;
        Ok(c)
    }

    fn set_friction(&mut self, friction: Friction<K>) -> Result<(), CompensatorError> {
        if friction.gain_per_a() != 0.0 && self.stages.friction_current.is_none() {
            return Err(CompensatorError::CurrentDependentFriction);
        }
        let bound = friction.magnitude() * (1.0 + friction.gain_per_a().abs() * self.limit_a);
        if bound.is_nan() || bound > MAX_MAGNITUDE {
            return Err(CompensatorError::FrictionBound(bound));
        }
        self.friction = friction;
        self.extended = self.stages.any();
        Ok(())
    }

    /// This compensator extended by the stages of `effects` (validated vocabulary parameters, see
    /// [`Stages::new`]) at sample period `dt_s`. The current limit is the thermal model's full current;
    /// `full_torque_nmm` the output map's full scale when its `scale_nmm` is 0.
    pub fn with_extensions(
        mut self,
        effects: &[Params],
        dt_s: f64,
        full_torque_nmm: f64,
    ) -> Result<Self, CompensatorError> {
        let scales = Scales::of_core(&self.forward, self.limit_a, full_torque_nmm);
        let (stages, fx) = Stages::new(effects, dt_s, scales)?;
        let friction = fx.apply(self.friction).map_err(StageError::Friction)?;
        self.stages = stages;
        self.set_friction(friction)?;
        self.stages
            .reset(self.forward.state().input(), self.forward.output());
        self.field_nmm = self.field_of(self.forward.output());
        Ok(self)
    }

    pub fn forward(&self) -> &Hysteresis<S, N> {
        &self.forward
    }
    pub fn inverse_kind(&self) -> &InverseKind<S, N> {
        &self.inverse
    }
    pub fn friction(&self) -> &Friction<K> {
        &self.friction
    }
    pub fn stages(&self) -> &Stages {
        &self.stages
    }
    pub fn limit_a(&self) -> f64 {
        self.limit_a
    }
    pub fn gain_a_per_v(&self) -> f64 {
        self.gain_a_per_v
    }
    /// Friction feedforward (N·mm) of the last step (NaN after a fault).
    pub fn friction_nmm(&self) -> f64 {
        self.friction_nmm
    }
    /// Torque (N·mm, without friction) the forward model predicts at the hysteretic core for the last command.
    pub fn predicted_torque(&self) -> f64 {
        self.forward.output()
    }
    /// Torque (N·mm, with friction) the model predicts for the last command: the core torque through the output
    /// map and the field gain the step used, plus the friction feedforward.
    pub fn model_torque_nmm(&self) -> f64 {
        let field = if self.extended {
            self.field_nmm
        } else {
            self.forward.output()
        };
        field * self.field_gain + self.friction_nmm
    }

    /// Field torque before the gains of a core output with the stages' present state (no creep or
    /// accommodation advanced): through the output map, plus the accommodation shift.
    fn field_of(&mut self, core_nmm: f64) -> f64 {
        let mapped = match &mut self.stages.output_map {
            Some(m) => m.forward(core_nmm),
            None => core_nmm,
        };
        mapped + self.stages.accommodation.map_or(0.0, |a| a.shift())
    }

    /// Advance the stages after the core (creep, accommodation) with the core output `core_nmm` it reached for
    /// core input `core_a`; returns the field torque before the gains.
    #[inline]
    fn after_core(&mut self, core_nmm: f64, core_a: f64) -> f64 {
        self.stages.after_core(core_nmm, core_a)
    }
    /// Delay (whole samples) the reference must be taken ahead by (`time_delay`; 0 without it).
    pub fn preview_samples(&self) -> usize {
        self.stages.time_delay.map_or(0, |p| p.samples())
    }

    /// One control period: reference torque (N·mm) and rotor angle (rad) → command. With a `time_delay` stage the
    /// reference and angle `delay` ahead are predicted (see [`crate::stages::Predictor`]); use
    /// [`Self::step_ahead`] when they are known.
    #[inline]
    pub fn step(&mut self, torque_ref_nmm: f64, theta_rad: f64) -> Command {
        self.step_sharing(torque_ref_nmm, theta_rad, None)
    }

    /// [`Self::step`] given `sincos = crate::trig::sincos(theta_rad)`, computed by a loop that owns the angle and
    /// needs it elsewhere too (the plant's friction): the same command to the bit, one `sincos` fewer. A
    /// predicted angle (`time_delay`) is not `theta_rad` and gets its own.
    #[inline]
    pub fn step_with_sincos(
        &mut self,
        torque_ref_nmm: f64,
        theta_rad: f64,
        sincos: (f64, f64),
    ) -> Command {
        self.step_sharing(torque_ref_nmm, theta_rad, Some(sincos))
    }

    #[inline(always)]
    fn step_sharing(
        &mut self,
        torque_ref_nmm: f64,
        theta_rad: f64,
        sincos: Option<(f64, f64)>,
    ) -> Command {
        if !(torque_ref_nmm.is_finite() && theta_rad.is_finite()) {
            return self.fault();
        }
        if !self.extended {
            return self.step_base(torque_ref_nmm, theta_rad, sincos);
        }
        match &mut self.stages.time_delay {
            Some(p) => {
                let (r, th) = p.predict(torque_ref_nmm, theta_rad);
                self.step_extended(r, th, None)
            }
            None => self.step_extended(torque_ref_nmm, theta_rad, sincos),
        }
    }

    /// One control period given the reference torque and rotor angle of the sample this command will act on:
    /// [`Self::preview_samples`] ahead of now (the same as [`Self::step`] without a `time_delay` stage).
    #[inline]
    pub fn step_ahead(&mut self, torque_ref_ahead_nmm: f64, theta_ahead_rad: f64) -> Command {
        if !(torque_ref_ahead_nmm.is_finite() && theta_ahead_rad.is_finite()) {
            return self.fault();
        }
        if !self.extended {
            return self.step_base(torque_ref_ahead_nmm, theta_ahead_rad, None);
        }
        self.step_extended(torque_ref_ahead_nmm, theta_ahead_rad, None)
    }

    /// The paper's compensator: friction feedforward, CBH inverse, limit. `sincos`: of `theta_rad`, if known.
    #[inline(always)]
    fn step_base(
        &mut self,
        torque_ref_nmm: f64,
        theta_rad: f64,
        sincos: Option<(f64, f64)>,
    ) -> Command {
        self.friction_nmm = match sincos {
            Some(sc) => self.friction.eval_from(sc),
            None => self.friction.eval(theta_rad),
        };
        let target = torque_ref_nmm - self.friction_nmm;
        if !target.is_finite() {
            return self.fault();
        }
        let inv = self.inverse_input(target);
        let (input, saturated) = (inv.input, inv.saturated);
        let limited = limit(input, self.limit_a);
        if !limited.is_finite() {
            return self.fault();
        }
        if matches!(self.inverse, InverseKind::Exact) && !saturated && limited == input {
            // The exact inverse already knows the output: commit without evaluating the branch again.
            self.forward.commit(input, target, &inv);
            return Command::from_current(input, self.gain_a_per_v, false, false);
        }
        self.forward.step_made(limited, inv.turn.as_ref());
        Command::from_current(
            limited,
            self.gain_a_per_v,
            saturated || limited != input,
            false,
        )
    }

    /// The extended compensator (module doc), for the reference and angle of the sample the command acts on.
    /// `sincos`: of `theta_rad`, if known.
    #[inline(always)]
    fn step_extended(
        &mut self,
        torque_ref_nmm: f64,
        theta_rad: f64,
        sincos: Option<(f64, f64)>,
    ) -> Command {
        let terms = match sincos {
            Some(sc) => self.friction.angle_terms_from(sc),
            None => self.friction.angle_terms(theta_rad),
        };
        let current_a = self.stages.friction_current.map_or(0.0, |f| f.current_a());
        self.friction_nmm = self.friction.with_terms(&terms, current_a);
        let mut gain = 1.0;
        if let Some(t) = &self.stages.thermal {
            gain *= t.gain();
        }
        if let Some(r) = &self.stages.ripple {
            gain *= r.gain(&terms);
        }
        self.field_gain = gain.max(MIN_FIELD_GAIN);
        // Without a thermal or ripple stage the gain is exactly 1 and `x / 1` is `x`: no division.
        let wanted = torque_ref_nmm - self.friction_nmm;
        let mut field = if self.field_gain == 1.0 {
            wanted
        } else {
            wanted / self.field_gain
        };
        if let Some(a) = &self.stages.accommodation {
            // The shift of the state before this sample (it moves by a small share of a cycle per sample).
            field -= a.shift();
        }
        let crept = match &mut self.stages.output_map {
            Some(m) => m.inverse(field),
            None => field,
        };
        let target = match &self.stages.creep {
            Some(c) => c.input_for(crept),
            None => crept,
        };
        // The core output that, with the viscous loss of the input reaching it, gives the target (solved
        // implicitly: no differenced command).
        let target = match &self.stages.viscous {
            Some(v) => v.core_output_for(&self.forward, target),
            None => target,
        };
        if !target.is_finite() {
            return self.fault();
        }
        let inv = self.inverse_input(target);
        let (input, saturated) = (inv.input, inv.saturated);
        // The mean field adds its share of the core's last output to whatever reaches the core: the stages before
        // it must bring `wanted`. Then the input before creep's fluctuation field that gives that, the field
        // current that brings it there (rate dependence), then the coil command (lag).
        // (Off: `fed` is +0.0, and `x − 0.0` is `x` to the bit.)
        let fed = match &self.stages.mean_field {
            Some(m) => m.shift(self.forward.output()),
            None => 0.0,
        };
        let wanted = input - fed;
        let pushed = match &self.stages.creep {
            Some(c) => c.applied_input_for(wanted),
            None => wanted,
        };
        let field_wanted = match &self.stages.rate {
            Some(r) => r.input_for(pushed),
            None => pushed,
        };
        let command = match &self.stages.coil_lag {
            Some(l) => l.command_for(field_wanted),
            None => field_wanted,
        };
        let limited = limit(command, self.limit_a);
        if !limited.is_finite() || !field_wanted.is_finite() {
            return self.fault();
        }
        let commanded = !saturated && limited == command;
        // The field current actually reached; the lag state is kept exactly on it.
        let field_a = match &mut self.stages.coil_lag {
            Some(l) if commanded => {
                l.reached(field_wanted);
                field_wanted
            }
            Some(l) => l.forward(limited),
            None => limited,
        };
        let core_in = match &mut self.stages.rate {
            Some(r) if commanded => {
                r.reached(pushed);
                pushed
            }
            Some(r) => r.step(field_a),
            None => field_a,
        };
        // Exact: the core reaches the inverse's input (the fluctuation field may not let it, see
        // `FluctuationField::input_for`); without creep a commanded input is reached.
        let (core_in, exact) = match &mut self.stages.creep {
            Some(c) => {
                let reached = c.core_input(if commanded { pushed } else { core_in });
                (reached, commanded && reached == wanted)
            }
            None => (core_in, commanded),
        };
        // What the core sees (when exact the inverse's `input`, up to the rounding of the sum). Written as
        // `− (0 − fed)` so that off (`fed` = +0.0) it is `core_in` to the bit, a −0.0 included.
        let core_in = core_in - (0.0 - fed);
        if let Some(t) = &mut self.stages.thermal {
            t.commit(limited);
        }
        if let Some(f) = &mut self.stages.friction_current {
            f.commit(field_a);
        }
        let core_out = if exact && matches!(self.inverse, InverseKind::Exact) {
            // Exact means the core reaches `input`: the inverse's cell applies.
            self.forward.commit(input, target, &inv);
            target
        } else {
            self.forward.step_made(core_in, inv.turn.as_ref())
        };
        self.field_nmm = self.after_core(core_out, core_in);
        Command::from_current(limited, self.gain_a_per_v, !exact, false)
    }

    #[inline(always)]
    fn inverse_input(&mut self, target: f64) -> InverseInput {
        match &mut self.inverse {
            InverseKind::Exact => self.forward.inverse_input(target),
            InverseKind::Paper(inv) => {
                let (lo, hi) = inv.input_range();
                InverseInput::new(inv.step(target), target < lo || target > hi)
            }
        }
    }

    /// Zero current: every state follows it (the field decays through the lag, the coils cool).
    #[cold]
    fn fault(&mut self) -> Command {
        let field_a = match &mut self.stages.coil_lag {
            Some(l) => l.forward(0.0),
            None => 0.0,
        };
        if let Some(t) = &mut self.stages.thermal {
            t.commit(0.0);
        }
        if let Some(f) = &mut self.stages.friction_current {
            f.commit(field_a);
        }
        let core_in = match &mut self.stages.rate {
            Some(r) => r.step(field_a),
            None => field_a,
        };
        let core_in = match &mut self.stages.creep {
            Some(c) => c.core_input(core_in),
            None => core_in,
        };
        let core_in = match &self.stages.mean_field {
            Some(m) => core_in + m.shift(self.forward.output()),
            None => core_in,
        };
        let y = self.forward.step(core_in);
        if self.extended {
            self.field_nmm = self.after_core(y, core_in);
        }
        if let InverseKind::Paper(inv) = &mut self.inverse {
            // Keep the torque-domain memory consistent with the torque the zero current produces.
            inv.step(y);
        }
        self.friction_nmm = f64::NAN;
        Command::from_current(0.0, self.gain_a_per_v, false, true)
    }

    /// Drive a whole reference known in advance: with a `time_delay` stage every sample is commanded with
    /// [`Self::step_ahead`] on the reference and angle `delay` samples later (past the end: the last reference
    /// held, the angle continued at its last step), otherwise with [`Self::step`]. `each(i, command, self)` sees
    /// every sample (the shorter input sets the length). Allocation-free.
    pub fn run_with(
        &mut self,
        refs: &[f64],
        thetas: &[f64],
        mut each: impl FnMut(usize, Command, &Self),
    ) {
        let n = refs.len().min(thetas.len());
        let d = self.preview_samples();
        for i in 0..n {
            let c = if d == 0 {
                self.step(refs[i], thetas[i])
            } else {
                let (r, th) = ahead(refs, thetas, n, i, d);
                self.step_ahead(r, th)
            };
            each(i, c, self);
        }
    }

    pub fn snapshot(&self) -> CompensatorState<N> {
        CompensatorState {
            forward: self.forward.snapshot(),
            paper: match &self.inverse {
                InverseKind::Paper(inv) => Some(inv.snapshot()),
                InverseKind::Exact => None,
            },
            stages: self.stages.state(),
        }
    }

    /// Return to a snapshot of this compensator (or of one with identical tables and stages).
    pub fn restore(&mut self, s: &CompensatorState<N>) -> Result<(), crate::error::TableError> {
        let mut stages = self.stages;
        if !stages.restore(&s.stages) {
            return Err(crate::error::TableError::ForeignState);
        }
        match (&mut self.inverse, &s.paper) {
            (InverseKind::Paper(inv), Some(p)) => inv.restore(p)?,
            (InverseKind::Exact, None) => {}
            _ => return Err(crate::error::TableError::ForeignState),
        }
        self.forward.restore(&s.forward)?;
        self.stages = stages;
        Ok(())
    }

    /// Reset both operators to `initial`, the field current to the forward input, the coils cold and the
    /// reference history empty.
    pub fn reset(&mut self, initial: crate::cbh::Initial) {
        self.forward.reset(initial);
        if let InverseKind::Paper(inv) = &mut self.inverse {
            inv.reset(initial_of_torque(initial, &self.forward));
        }
        self.stages
            .reset(self.forward.state().input(), self.forward.output());
        self.friction_nmm = 0.0;
        self.field_gain = 1.0;
        self.field_nmm = self.field_of(self.forward.output());
    }
}

/// `x` limited to `±limit` (NaN stays NaN: the caller turns it into a fault).
#[inline(always)]
fn limit(x: f64, limit: f64) -> f64 {
    if x > limit {
        limit
    } else if x < -limit {
        -limit
    } else {
        x
    }
}

/// First word of a serialised [`CompensatorState`] (format tag and version).
// Version 3: the stage mask gained `viscous` (between rate dependence and creep), so older words are refused.
const STATE_TAG: u64 = 0x626d_725f_636f_0003;

#[cfg(feature = "alloc")]
impl<const N: usize> CompensatorState<N> {
    /// The state as plain words (pickling); [`Compensator::state_from_words`] reads it back bit for bit.
    pub fn to_words(&self) -> alloc::vec::Vec<u64> {
        let fwd = self.forward.to_words();
        let mut w = alloc::vec![STATE_TAG, fwd.len() as u64];
        w.extend(fwd);
        match &self.paper {
            Some(p) => {
                let pw = p.to_words();
                w.push(pw.len() as u64);
                w.extend(pw);
            }
            None => w.push(u64::MAX),
        }
        self.stages.to_words(&mut w);
        w
    }
}

impl<S: AsRef<[f64]>, const N: usize, const K: usize> Compensator<S, N, K> {
    /// Read a state written by [`CompensatorState::to_words`] from a compensator with the same tables and
    /// stages; damaged or foreign words are an error, never a state that could index outside the tables.
    pub fn state_from_words(
        &self,
        words: &[u64],
    ) -> Result<CompensatorState<N>, crate::error::TableError> {
        use crate::error::TableError;
        let bad = |what| TableError::BadState { what };
        let mut w = words;
        let mut take = |n: usize| -> Result<&[u64], TableError> {
            if n > w.len() {
                return Err(bad("compensator state words end early"));
            }
            let (head, rest) = w.split_at(n);
            w = rest;
            Ok(head)
        };
        if take(1)? != [STATE_TAG] {
            return Err(bad("not a serialised compensator state"));
        }
        let n = usize::try_from(take(1)?[0]).map_err(|_| bad("word count"))?;
        let forward = self.forward.state_from_words(take(n)?)?;
        let n = take(1)?[0];
        let paper = match (&self.inverse, n) {
            (InverseKind::Exact, u64::MAX) => None,
            (InverseKind::Paper(inv), n) if n != u64::MAX => {
                let n = usize::try_from(n).map_err(|_| bad("word count"))?;
                Some(inv.state_from_words(take(n)?)?)
            }
            _ => return Err(TableError::ForeignState),
        };
        let stages = self
            .stages
            .state_from_words(&mut w)
            .ok_or(bad("stage states do not fit this compensator's stages"))?;
        if !w.is_empty() {
            return Err(bad("extra words after the compensator state"));
        }
        Ok(CompensatorState {
            forward,
            paper,
            stages,
        })
    }
}

/// Reference and angle `d` samples after sample `i` of a run of `n` (past the end: the last reference held, the
/// angle continued at its last step, wrapped).
#[inline]
pub fn ahead(refs: &[f64], thetas: &[f64], n: usize, i: usize, d: usize) -> (f64, f64) {
    let j = i + d;
    if j < n {
        return (refs[j], thetas[j]);
    }
    let last = thetas[n - 1];
    let step = if n > 1 {
        crate::stages::wrap_angle(last - thetas[n - 2])
    } else {
        0.0
    };
    (refs[n - 1], last + (j - (n - 1)) as f64 * step)
}

/// The paper inverse's start state matching a forward start state (saturations map to saturations).
fn initial_of_torque<S: AsRef<[f64]>, const N: usize>(
    initial: crate::cbh::Initial,
    forward: &Hysteresis<S, N>,
) -> crate::cbh::Initial {
    use crate::cbh::Initial::*;
    match initial {
        Negative => Negative,
        Positive => Positive,
        Ascending(_) => Ascending(forward.output()),
        Descending(_) => Descending(forward.output()),
    }
}
