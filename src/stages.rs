//! Extension stages: each undoes (in the compensator) or reproduces (in the extended simulation) one effect of
//! the vocabulary, at the place in the chain where the physics acts.
//!
//! The forward chain (the extended simulation, [`crate::simulation`]) is
//!
//! `command → time_delay → coil_lag → rate_dependence → creep's fluctuation field → + non_congruent mean field
//! (its feedback × the core's last output / S) → CBH core + viscous loss → creep → non_congruent output map
//! → + accommodation shift → × thermal gain × ripple gain → + friction(θ, |field current|)`
//! (`friction_harmonics` and `friction_current` live in the one [`crate::friction::Friction`]),
//!
//! and the compensator ([`crate::compensator`]) walks it backwards once per step:
//!
//! `reference (time_delay: taken delay ahead) − friction → ÷ (thermal gain × ripple gain) − accommodation
//! shift → output-map inverse → creep inverse → implicit viscous solve → CBH inverse → − mean field →
//! fluctuation-field inverse → rate-dependence inverse →
//! coil_lag lead (limited)
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
//! A new stage is a struct with those three operations, its [`Stage`] impl (what a snapshot keeps, how it rests,
//! its state words) and one line in the stage list (`stage_list!`, in the vocabulary's loop order): every walk
//! over the stages (snapshot, restore, words, reset, the names of those that are on) is generated from that list.
use crate::accommodation::Accommodation;
use crate::creep::{Creep, FLUCTUATION_STATE, MAX_CREEP_TERMS};
use crate::filters::{Heating, Lag};
use crate::friction::{AngleTerms, FrictionError};
use crate::rate_dependence::RateDependence;
use crate::viscous::Viscous;
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
    /// The last `window` references and angles, one ring (`head`: the oldest, the next to be replaced).
    refs: [f64; PREDICT_WINDOW],
    thetas: [f64; PREDICT_WINDOW],
    window: usize,
    head: usize,
    seen: usize,
}

impl Predictor {
    pub fn new(delay_s: f64, dt_s: f64) -> Self {
        let samples = libm::round(delay_s / dt_s).clamp(0.0, u32::MAX as f64) as usize;
        let window = samples.clamp(1, PREDICT_WINDOW);
        Predictor {
            samples,
            reach: samples as f64 / window as f64,
            refs: [0.0; PREDICT_WINDOW],
            thetas: [0.0; PREDICT_WINDOW],
            window,
            head: 0,
            seen: 0,
        }
    }
    /// The delay in whole samples.
    pub fn samples(&self) -> usize {
        self.samples
    }
    /// Forget the history.
    pub fn reset(&mut self) {
        self.refs = [0.0; PREDICT_WINDOW];
        self.thetas = [0.0; PREDICT_WINDOW];
        self.head = 0;
        self.seen = 0;
    }
    /// The history, oldest first: references, then angles.
    fn history(&self) -> impl Iterator<Item = f64> + '_ {
        let (w, h) = (self.window, self.head);
        let (r, t) = (&self.refs[..w], &self.thetas[..w]);
        r[h..]
            .iter()
            .chain(&r[..h])
            .chain(&t[h..])
            .chain(&t[..h])
            .copied()
    }
    /// The reference and angle `samples` ahead, predicted from this sample's and the history (finite inputs).
    #[inline]
    pub fn predict(&mut self, reference: f64, theta: f64) -> (f64, f64) {
        // `head < window ≤ PREDICT_WINDOW` always; said here so the ring needs no bounds check.
        let h = self.head.min(PREDICT_WINDOW - 1);
        let r_old = core::mem::replace(&mut self.refs[h], reference);
        let t_old = core::mem::replace(&mut self.thetas[h], theta);
        self.head = if h + 1 == self.window { 0 } else { h + 1 };
        if self.seen < self.window {
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
    core: MapAxis,
    field: MapAxis,
    /// The cell each axis was last looked up in (where its next search starts).
    core_hint: usize,
    field_hint: usize,
}

/// One axis of an output map, as the per-sample search and interpolation read it: the nodes, each cell's lower
/// edge (the first cell open below, the last open above, so one cell holds every value) and each cell's slope
/// towards the other axis (worked out once: the very quotient the interpolation would take).
#[derive(Clone, Copy, Debug, PartialEq)]
struct MapAxis {
    nodes: [f64; MAP_NODES],
    /// `edges[k] ≤ v < edges[k + 1]` for `v` in cell `k`: `−∞`, the inner nodes, then `+∞`.
    edges: [f64; MAP_NODES],
    /// `(other[k + 1] − other[k]) / (nodes[k + 1] − nodes[k])` of cell `k`.
    slope: [f64; MAP_NODES],
}

impl MapAxis {
    fn new(nodes: &[f64], other: &[f64]) -> Self {
        let n = nodes.len();
        let mut a = MapAxis {
            nodes: [0.0; MAP_NODES],
            edges: [f64::INFINITY; MAP_NODES],
            slope: [0.0; MAP_NODES],
        };
        a.nodes[..n].copy_from_slice(nodes);
        a.edges[..n - 1].copy_from_slice(&nodes[..n - 1]);
        a.edges[0] = f64::NEG_INFINITY;
        for k in 0..n - 1 {
            a.slope[k] = (other[k + 1] - other[k]) / (nodes[k + 1] - nodes[k]);
        }
        a
    }

    /// The other axis's value at `v` and the cell `k` (nodes `k`, `k+1`) holding `v`: the last node `≤ v`,
    /// within `0..len−1` (the end cells extend).
    #[inline(always)]
    fn map(&self, other: &MapAxis, len: usize, v: f64, hint: usize) -> (f64, usize) {
        let interpolate = |k: usize| other.nodes[k] + (v - self.nodes[k]) * self.slope[k];
        // `hint ≤ len − 2 ≤ MAP_NODES − 2` always; said here so the hot path needs no bounds check.
        let h = hint.min(MAP_NODES - 2);
        if self.edges[h] <= v && v < self.edges[h + 1] {
            return (interpolate(h), h);
        }
        let k = self.cell_searched(len, v, h).min(MAP_NODES - 2);
        (interpolate(k), k)
    }

    /// The cell holding `v` when it is not cell `h`: a neighbour of it, or found by bisection.
    #[cold]
    fn cell_searched(&self, len: usize, v: f64, h: usize) -> usize {
        let last = len - 2;
        let inside = |k: usize| self.edges[k] <= v && v < self.edges[k + 1];
        if h < last && inside(h + 1) {
            return h + 1;
        }
        if h > 0 && inside(h - 1) {
            return h - 1;
        }
        self.nodes[..len]
            .partition_point(|&x| x <= v)
            .clamp(1, last + 1)
            - 1
    }
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
        Ok(OutputMap {
            len: n,
            core: MapAxis::new(core, field),
            field: MapAxis::new(field, core),
            core_hint: 0,
            field_hint: 0,
        })
    }

    /// The vocabulary's map `T = S·n(1 + c|n| + k·n²)/(1 + c + k)`, `n = T_core/S` (curvature `c`, cubic term
    /// `k`), tabulated on [`MAP_NODES`] even nodes over `|T_core| ≤ 2S`, or up to the map's turning point where
    /// it has one (a concave map: `1 + 2c|n| + 3k·n² = 0`), so the table is monotone and the inverse exact.
    pub fn polynomial(curvature: f64, cubic: f64, scale_nmm: f64) -> Result<Self, StageError> {
        if !(curvature.is_finite()
            && curvature > -1.0
            && cubic.is_finite()
            && 1.0 + curvature + cubic > 0.0)
        {
            return Err(StageError::OutputMap(
                "curvature and cubic must be finite with curvature above -1 and 1 + curvature + cubic above 0",
            ));
        }
        if !(scale_nmm.is_finite() && scale_nmm > 0.0) {
            return Err(StageError::OutputMap(
                "full-scale torque must be positive and finite",
            ));
        }
        let reach = if cubic == 0.0 && curvature < 0.0 {
            (0.999 / (-2.0 * curvature)).min(2.0)
        } else {
            turning_point(curvature, cubic).map_or(2.0, |x| (0.999 * x).min(2.0))
        };
        let mut core = [0.0; MAP_NODES];
        let mut field = [0.0; MAP_NODES];
        for i in 0..MAP_NODES {
            let n = reach * (2.0 * i as f64 / (MAP_NODES - 1) as f64 - 1.0);
            core[i] = scale_nmm * n;
            // Written so that `cubic = 0` gives the curvature map's very bits.
            field[i] = scale_nmm * n * (1.0 + curvature * n.abs() + cubic * n * n)
                / (1.0 + curvature + cubic);
        }
        Self::from_table(&core, &field)
    }

    /// The nodes `(core, field)`.
    pub fn nodes(&self) -> (&[f64], &[f64]) {
        (&self.core.nodes[..self.len], &self.field.nodes[..self.len])
    }

    /// Field torque of core torque `core_nmm` (the hint only speeds the search up).
    #[inline]
    pub fn forward(&mut self, core_nmm: f64) -> f64 {
        let (field, k) = self
            .core
            .map(&self.field, self.len, core_nmm, self.core_hint);
        self.core_hint = k;
        field
    }

    /// Core torque giving field torque `field_nmm` (the hint only speeds the search up).
    #[inline]
    pub fn inverse(&mut self, field_nmm: f64) -> f64 {
        let (core, k) = self
            .field
            .map(&self.core, self.len, field_nmm, self.field_hint);
        self.field_hint = k;
        core
    }
}

/// `non_congruent`'s mean field (the moving Preisach model): the core sees its input plus `per_output` times its
/// own output of the sample before. Stateless: that output is the core's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeanField {
    per_output: f64,
}

impl MeanField {
    /// Feedback `feedback` (input units per full-scale output) over full scale `scale` (output units); `None`
    /// when the feedback is 0 (off) or the ratio is not finite.
    pub fn new(feedback: f64, scale: f64) -> Option<Self> {
        let per_output = feedback / scale;
        (feedback != 0.0 && per_output.is_finite()).then_some(MeanField { per_output })
    }
    /// Input units added per output unit.
    pub fn per_output(&self) -> f64 {
        self.per_output
    }
    /// The field added to the core's input when its last output was `last_out`.
    #[inline(always)]
    pub fn shift(&self, last_out: f64) -> f64 {
        self.per_output * last_out
    }
}

/// The smallest `x > 0` where the odd map `n(1 + c|n| + k·n²)` stops rising (`1 + 2c·x + 3k·x² = 0`), if any.
fn turning_point(c: f64, k: f64) -> Option<f64> {
    if k == 0.0 {
        return (c < 0.0).then(|| -1.0 / (2.0 * c));
    }
    let disc = 4.0 * c * c - 12.0 * k;
    if disc < 0.0 {
        return None;
    }
    let r = libm::sqrt(disc);
    [(-2.0 * c - r) / (6.0 * k), (-2.0 * c + r) / (6.0 * k)]
        .into_iter()
        .filter(|&x| x > 0.0)
        .reduce(f64::min)
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

/// One stage as the stage list ([`Stages`]) walks it: what a snapshot keeps, how it rests and how its state is
/// written as words. Implemented once per stage type, next to it.
pub trait Stage: Copy + PartialEq {
    /// The effect it undoes or reproduces.
    const KIND: EffectKind;
    /// What a snapshot keeps of it: the stage itself when it carries state, `()` when it carries none.
    type Saved: Copy + PartialEq + fmt::Debug;
    fn save(&self) -> Self::Saved;
    /// Take `saved`, kept from a stage with the same configuration (else `false` and nothing changes).
    fn load(&mut self, saved: &Self::Saved) -> bool;
    /// Back to rest at field current `field_a` (A) with core output `core_out` (output units).
    fn rest(&mut self, field_a: f64, core_out: f64);
    /// Its state as plain words, handed to `push` one by one.
    fn write_words(&self, push: &mut dyn FnMut(u64));
    /// Its state read from `words` (advanced past them); `None` if they do not fit or a value is not finite.
    fn read_words(&mut self, words: &mut &[u64]) -> Option<()>;
    /// The words of a kept state (what [`Stage::write_words`] writes for the stage it was kept from).
    fn write_saved(saved: &Self::Saved, push: &mut dyn FnMut(u64));
}

/// The presence mask of the stage list: bit `i` set when its `i`-th stage is on.
fn mask_of<const N: usize>(on: [bool; N]) -> u64 {
    on.iter()
        .enumerate()
        .fold(0, |m, (i, &o)| m | (u64::from(o) << i))
}

fn take_word(w: &mut &[u64]) -> Option<u64> {
    let (&first, rest) = w.split_first()?;
    *w = rest;
    Some(first)
}

fn take_float(w: &mut &[u64]) -> Option<f64> {
    Some(f64::from_bits(take_word(w)?)).filter(|v| v.is_finite())
}

/// `saved` into `stage` if both have the same configuration (their states at rest are equal).
fn load_same<T: Stage>(stage: &mut T, saved: &T) -> bool {
    let (mut a, mut b) = (*stage, *saved);
    a.rest(0.0, 0.0);
    b.rest(0.0, 0.0);
    if a != b {
        return false;
    }
    *stage = *saved;
    true
}

/// A stage carrying state: the snapshot keeps the stage itself.
macro_rules! stateful {
    ($ty:ty, $kind:ident) => {
        const KIND: EffectKind = EffectKind::$kind;
        type Saved = $ty;
        fn save(&self) -> $ty {
            *self
        }
        fn load(&mut self, saved: &$ty) -> bool {
            load_same(self, saved)
        }
        fn write_saved(saved: &$ty, push: &mut dyn FnMut(u64)) {
            saved.write_words(push);
        }
    };
}

/// A stage without state: nothing to keep, rest or write.
macro_rules! stateless {
    ($kind:ident) => {
        const KIND: EffectKind = EffectKind::$kind;
        type Saved = ();
        fn save(&self) {}
        fn load(&mut self, _: &()) -> bool {
            true
        }
        fn rest(&mut self, _: f64, _: f64) {}
        fn write_words(&self, _: &mut dyn FnMut(u64)) {}
        fn read_words(&mut self, _: &mut &[u64]) -> Option<()> {
            Some(())
        }
        fn write_saved(_: &(), _: &mut dyn FnMut(u64)) {}
    };
}

impl Stage for Predictor {
    stateful!(Predictor, TimeDelay);
    fn rest(&mut self, _: f64, _: f64) {
        self.reset();
    }
    fn write_words(&self, push: &mut dyn FnMut(u64)) {
        push(self.seen as u64);
        push(self.window as u64);
        self.history().for_each(|v| push(v.to_bits()));
    }
    fn read_words(&mut self, words: &mut &[u64]) -> Option<()> {
        let seen = usize::try_from(take_word(words)?).ok()?;
        let window = usize::try_from(take_word(words)?).ok()?;
        if window != self.window || seen > window {
            return None;
        }
        let mut refs = [0.0; PREDICT_WINDOW];
        let mut thetas = [0.0; PREDICT_WINDOW];
        for v in refs.iter_mut().take(window) {
            *v = take_float(words)?;
        }
        for v in thetas.iter_mut().take(window) {
            *v = take_float(words)?;
        }
        (self.refs, self.thetas, self.head, self.seen) = (refs, thetas, 0, seen);
        Some(())
    }
}

impl Stage for CoilLag {
    stateful!(CoilLag, CoilLag);
    fn rest(&mut self, field_a: f64, _: f64) {
        self.reset(field_a);
    }
    fn write_words(&self, push: &mut dyn FnMut(u64)) {
        push(self.field_a().to_bits());
    }
    fn read_words(&mut self, words: &mut &[u64]) -> Option<()> {
        self.reset(take_float(words)?);
        Some(())
    }
}

impl Stage for RateDependence {
    stateful!(RateDependence, RateDependence);
    fn rest(&mut self, field_a: f64, core_out: f64) {
        self.reset(field_a, core_out);
    }
    fn write_words(&self, push: &mut dyn FnMut(u64)) {
        self.state().iter().for_each(|v| push(v.to_bits()));
    }
    fn read_words(&mut self, words: &mut &[u64]) -> Option<()> {
        let mut s = [0.0; 4];
        for v in &mut s {
            *v = take_float(words)?;
        }
        self.set_state(s).then_some(())
    }
}

impl Stage for Creep {
    stateful!(Creep, Creep);
    fn rest(&mut self, field_a: f64, core_out: f64) {
        self.reset(core_out);
        if let Some(f) = self.fluctuation_mut() {
            f.reset(field_a);
        }
    }
    fn write_words(&self, push: &mut dyn FnMut(u64)) {
        self.states()[..self.terms()]
            .iter()
            .for_each(|v| push(v.to_bits()));
        // The fluctuation field's state follows, when there is one.
        if let Some(f) = self.fluctuation() {
            f.state().iter().for_each(|v| push(v.to_bits()));
        }
    }
    fn read_words(&mut self, words: &mut &[u64]) -> Option<()> {
        let mut s = [0.0; MAX_CREEP_TERMS];
        for v in s.iter_mut().take(self.terms()) {
            *v = take_float(words)?;
        }
        let mut f = [0.0; FLUCTUATION_STATE];
        if self.fluctuation().is_some() {
            for v in &mut f {
                *v = take_float(words)?;
            }
        }
        // Both checked before either changes.
        let mut next = *self;
        let fluctuation_ok = next.fluctuation_mut().is_none_or(|x| x.set_state(&f));
        (next.set_states(&s) && fluctuation_ok).then(|| *self = next)
    }
}

impl Stage for OutputMap {
    stateless!(NonCongruent);
}

impl Stage for Accommodation {
    stateful!(Accommodation, Accommodation);
    fn rest(&mut self, _: f64, _: f64) {
        self.reset();
    }
    fn write_words(&self, push: &mut dyn FnMut(u64)) {
        self.state().iter().for_each(|v| push(v.to_bits()));
    }
    fn read_words(&mut self, words: &mut &[u64]) -> Option<()> {
        let mut s = [0.0; 11];
        for v in &mut s {
            *v = take_float(words)?;
        }
        self.set_state(&s).then_some(())
    }
}

impl Stage for Thermal {
    stateful!(Thermal, ThermalDrift);
    fn rest(&mut self, _: f64, _: f64) {
        self.reset(0.0);
    }
    fn write_words(&self, push: &mut dyn FnMut(u64)) {
        push(self.state().to_bits());
    }
    fn read_words(&mut self, words: &mut &[u64]) -> Option<()> {
        self.reset(take_float(words)?);
        Some(())
    }
}

impl Stage for Ripple {
    stateless!(TorqueRipple);
}

impl Stage for FrictionCurrent {
    stateful!(FrictionCurrent, FrictionCurrent);
    fn rest(&mut self, field_a: f64, _: f64) {
        self.reset(field_a);
    }
    fn write_words(&self, push: &mut dyn FnMut(u64)) {
        push(self.current_a().to_bits());
    }
    fn read_words(&mut self, words: &mut &[u64]) -> Option<()> {
        self.smooth.set_output(take_float(words)?);
        Some(())
    }
}

/// The one list of stages, in loop order (the vocabulary's `stage.order`; a test holds the two together). From
/// it: the [`Stages`] fields, the snapshot [`StageState`], and every walk over them (any, has, kinds, reset,
/// state, restore, words). A new stage is one line here and its [`Stage`] impl.
macro_rules! stage_list {
    ($($(#[$doc:meta])* $field:ident: $ty:ty,)*) => {
        /// The stages of one extended model (each `None` when its effect is off) and the measurement-only
        /// leakage rate.
        #[derive(Clone, Copy, Debug, PartialEq, Default)]
        pub struct Stages {
            $($(#[$doc])* pub $field: Option<$ty>,)*
            /// `leakage`: measured output added per unit of input-time (output/(input·s)); measurement only.
            pub leak_per_s: f64,
            /// `leakage`: rate at which the charge amplifier discharges the integral (1/s; 0: ideal integrator).
            pub leak_decay_per_s: f64,
            /// `non_congruent`'s mean field: stateless, it acts between the stages before the core and the core
            /// (after the output map in the list: one effect).
            pub mean_field: Option<MeanField>,
        }

        /// The state of the stages (part of a compensator snapshot).
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub struct StageState {
            $($field: Option<<$ty as Stage>::Saved>,)*
        }

        impl Stages {
            /// The effects that have a stage, in loop order.
            pub const KINDS: &'static [EffectKind] = &[$(<$ty as Stage>::KIND,)*];

            /// Whether any stage is on.
            pub fn any(&self) -> bool {
                false $(|| self.$field.is_some())* || self.mean_field.is_some()
            }

            /// Whether the stage of `kind` is on.
            pub fn has(&self, kind: EffectKind) -> bool {
                $(if kind == <$ty as Stage>::KIND && self.$field.is_some() {
                    return true;
                })*
                kind == EffectKind::NonCongruent && self.mean_field.is_some()
            }

            /// The stages that are on, in loop order.
            pub fn kinds(&self) -> impl Iterator<Item = EffectKind> + '_ {
                Self::KINDS.iter().copied().filter(|&k| self.has(k))
            }

            /// Back to rest: field current `field_a` with core output `core_out` (creep settled there), cold
            /// coils, no reference history, no accommodation.
            pub fn reset(&mut self, field_a: f64, core_out: f64) {
                $(if let Some(s) = &mut self.$field {
                    s.rest(field_a, core_out);
                })*
            }

            /// What a snapshot keeps of the stages (a plain copy).
            pub fn state(&self) -> StageState {
                StageState {
                    $($field: self.$field.as_ref().map(Stage::save),)*
                }
            }

            /// Return to `s` (taken from stages with the same configuration, else `false` and nothing changes).
            pub fn restore(&mut self, s: &StageState) -> bool {
                let mut next = *self;
                $(match (&mut next.$field, &s.$field) {
                    (None, None) => {}
                    (Some(stage), Some(saved)) => {
                        if !stage.load(saved) {
                            return false;
                        }
                    }
                    _ => return false,
                })*
                *self = next;
                true
            }

            /// Read stage states written by [`StageState::to_words`] for stages
            /// configured like these, from `words` (advanced past them); `None` if they do not fit this
            /// configuration or a value is not finite.
            pub fn state_from_words(&self, words: &mut &[u64]) -> Option<StageState> {
                if take_word(words)? != mask_of([$(self.$field.is_some()),*]) {
                    return None;
                }
                let mut st = *self;
                $(if let Some(s) = &mut st.$field {
                    s.read_words(words)?;
                })*
                Some(st.state())
            }
        }

        impl StageState {
            /// The words of [`StageState::to_words`], handed to `push`: the presence mask, then each stage
            /// that is on, in list order.
            pub fn words(&self, push: &mut dyn FnMut(u64)) {
                push(mask_of([$(self.$field.is_some()),*]));
                $(if let Some(saved) = &self.$field {
                    <$ty as Stage>::write_saved(saved, push);
                })*
            }
        }
    };
}

stage_list! {
    time_delay: Predictor,
    coil_lag: CoilLag,
    rate: RateDependence,
    viscous: Viscous,
    creep: Creep,
    output_map: OutputMap,
    accommodation: Accommodation,
    thermal: Thermal,
    ripple: Ripple,
    friction_current: FrictionCurrent,
}

#[cfg(feature = "alloc")]
impl StageState {
    /// The states as plain words: a presence mask, then each present stage's values (read back by
    /// [`Stages::state_from_words`]).
    pub fn to_words(&self, out: &mut alloc::vec::Vec<u64>) {
        self.words(&mut |w| out.push(w));
    }
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
                    if v[0] != 0.0 || v[2] != 0.0 {
                        st.output_map = Some(OutputMap::polynomial(v[0], v[2], scale)?);
                    }
                    if v[3] != 0.0 {
                        st.mean_field = Some(
                            MeanField::new(v[3], scale)
                                .ok_or(StageError::Scale("mean-field feedback per output", v[3]))?,
                        );
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
                EffectKind::Leakage => {
                    st.leak_per_s = v[0];
                    st.leak_decay_per_s = v[1];
                }
                EffectKind::Creep => {
                    if v[0] != 0.0 || v[3] != 0.0 {
                        let c = Creep::log_uniform(v[0], v[1], v[2], dt_s, 0.0)
                            .ok_or(StageError::Scale("creep time constants (s)", v[1]))?;
                        st.creep = Some(c.with_fluctuation(v[3], v[4], dt_s, 0.0).ok_or(
                            StageError::Scale("creep fluctuation onset tau0_s (s)", v[4]),
                        )?);
                    }
                }
                EffectKind::RateDependence => {
                    let (du, dy) = scales.spans()?;
                    if v[0] > 0.0 {
                        let lo = scales.input_range.0;
                        st.rate = RateDependence::new(v[0], dy / du, dt_s, du, lo, 0.0);
                    }
                }
                EffectKind::Viscous => {
                    if v[0] > 0.0 || v[1] > 0.0 {
                        st.viscous = Some(Viscous::new(v[0], v[1], v[2], dt_s, 0.0).ok_or(
                            StageError::Scale("viscous loss per sample (c/dt)", v[0] / dt_s),
                        )?);
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
}

impl Stages {
    /// Advance the stages after the hysteretic core (rate dependence observes the core, the viscous loss of the
    /// core input adds to its output, then creep, the output map and accommodation) for the core output `core_nmm` reached at core input `core_a`; the field torque
    /// before the gains. One chain for the compensator's forward model and the extended simulation.
    #[inline(always)]
    pub fn after_core(&mut self, core_nmm: f64, core_a: f64) -> f64 {
        if let Some(r) = &mut self.rate {
            r.observe(core_nmm);
        }
        let core_nmm = match &mut self.viscous {
            Some(v) => core_nmm + v.step(core_a),
            None => core_nmm,
        };
        let crept = match &mut self.creep {
            Some(c) => c.step(core_nmm),
            None => core_nmm,
        };
        let mut field = match &mut self.output_map {
            Some(m) => m.forward(crept),
            None => crept,
        };
        if let Some(a) = &mut self.accommodation {
            field += a.step(core_a, field);
        }
        field
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_map_inverse_is_exact_and_cells_are_canonical() {
        for c in [-0.45, -0.2, 0.5, 1.0, 4.5] {
            let mut m = OutputMap::polynomial(c, 0.0, 300.0).unwrap();
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
            let b = m.forward(v);
            m.forward(650.0);
            assert_eq!(m.forward(v).to_bits(), b.to_bits());
        }
        assert!(OutputMap::from_table(&[0.0, 1.0], &[1.0, 0.0]).is_err());
    }

    #[test]
    fn cubic_output_map_is_the_polynomial_monotone_and_exactly_inverted() {
        let s = 600.0;
        for (c, k) in [
            (0.0, 0.5),
            (0.0, 3.0),
            (0.3, 1.0),
            (0.0, -0.3),
            (-0.45, -0.3),
            (1.0, -0.3),
        ] {
            let mut m = OutputMap::polynomial(c, k, s).unwrap();
            let (core, field) = m.nodes();
            assert!(
                field.windows(2).all(|w| w[1] > w[0]),
                "c={c} k={k}: not monotone"
            );
            let reach = core[core.len() - 1] / s;
            let mut last = f64::NEG_INFINITY;
            for i in 0..=2000 {
                let y = -1.2 * s + 1.2e-3 * s * i as f64;
                let t = m.forward(y);
                assert!(t > last, "c={c} k={k}: {y} -> {t} not rising");
                last = t;
                assert!(
                    (m.inverse(t) - y).abs() < 1e-9 * s,
                    "c={c} k={k}: inverse of {t}"
                );
                let n = y / s;
                if n.abs() <= reach {
                    let g = s * (n + c * n * n.abs() + k * n * n * n) / (1.0 + c + k);
                    assert!((g - t).abs() < 2e-3 * s, "c={c} k={k}: {g} vs {t}");
                }
            }
            if let Some(x) = turning_point(c, k) {
                // A concave map is tabulated up to (just before) the point where it would turn back.
                assert!(
                    reach <= x && reach > 0.99 * x.min(2.0),
                    "c={c} k={k}: reach {reach}, turn {x}"
                );
                let slope = 1.0 + 2.0 * c * x + 3.0 * k * x * x;
                assert!(
                    slope.abs() < 1e-12,
                    "c={c} k={k}: slope {slope} at the turning point"
                );
            } else {
                assert_eq!(reach, 2.0);
            }
        }
        // The cubic term off gives the curvature map's very bits at the nodes.
        for c in [0.7, -0.3] {
            let m = OutputMap::polynomial(c, 0.0, s).unwrap();
            let (core, field) = m.nodes();
            let reach = if c < 0.0 {
                (0.999 / (-2.0 * c)).min(2.0)
            } else {
                2.0
            };
            for (i, (&x, &t)) in core.iter().zip(field).enumerate() {
                let n = reach * (2.0 * i as f64 / (MAP_NODES - 1) as f64 - 1.0);
                assert_eq!(x.to_bits(), (s * n).to_bits());
                assert_eq!(
                    t.to_bits(),
                    (s * n * (1.0 + c * n.abs()) / (1.0 + c)).to_bits()
                );
            }
        }
        assert!(OutputMap::polynomial(0.0, -1.5, s).is_err());
        assert!(OutputMap::polynomial(0.0, f64::NAN, s).is_err());
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
