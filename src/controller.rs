//! Closed-loop torque controller: the (extended) compensator as feedforward, integral feedback on the measured
//! torque, and an online estimate of the slowly varying output gain and offset between the model and the
//! measurement.
//!
//! Per sample, with `r` the reference, `y` the torque measured at the previous sample, `ŷ` the torque the model
//! predicted for that sample, `c` the integral correction and `(g, b)` the adapted gain and offset:
//!
//! ```text
//! c ← c + ki·dt·(r_prev − y)                (frozen at a saturated command pushing further: anti-windup)
//! (g, b) ← RLS with forgetting on y ≈ g·ŷ + b (bounded; skipped on a missing sample or a saturated command)
//! command = Compensator[(r + c − b) / g]
//! ```
//!
//! Design (see [`ControllerDesign`]): the compensator inverts every stage the model holds — the exact inverse
//! divides a torque change by the local slope of the present CBH branch, the thermal stage divides by the heating
//! gain, the coil-lag stage leads the lag — and `(g, b)` divides out what is left of a slow gain and offset, so
//! the loop the integrator closes is a unit gain behind the loop delay `T = (d + 1.5)·dt` (`d` whole samples of
//! `time_delay`, one sample until the measurement arrives, half a sample of hold). The integral gain is then the
//! crossover `ωc = ki` along the whole loop, with phase margin `90° − ωc·T`. The gain is scheduled on the local
//! slope of the hysteresis by where the correction enters: in torque, ahead of the exact inverse, which divides
//! it by the slope of the present branch at every sample (flat after a reversal, steep mid-branch); a `ki/slope`
//! schedule on top would count the slope twice. The proportional part is left out on purpose: on top of the
//! coil-lag lead it feeds sensor noise straight to the coils and fights the lead.
//!
//! Safety: the compensator's invariants hold (never both coils, `|I| ≤ limit`, zero current with `fault` on a
//! non-finite reference or angle). A non-finite `measured` means no new value: the correction and the adapted
//! gain and offset are held; after [`ControllerSettings::fault_after`] such samples in a row the command is zero
//! current with `fault` set, until a measurement arrives. `step` never allocates and is deterministic to the bit.
use crate::compensator::{Command, Compensator, CompensatorState};

/// Model predictions kept to pair a measurement with the prediction of its own sample (the `time_delay` stage
/// puts `d` samples between a command and its torque); a longer delay pairs with the oldest one kept.
pub const PREDICTION_HISTORY: usize = 64;
/// Smallest phase margin (degrees) a bandwidth asked for may leave.
pub const MIN_PHASE_MARGIN_DEG: f64 = 30.0;
/// Phase margin (degrees) the automatic bandwidth keeps at least.
pub const AUTO_PHASE_MARGIN_DEG: f64 = 60.0;
/// Bounds of the adapted output gain (model torque → measured torque).
pub const GAIN_RANGE: (f64, f64) = (0.5, 2.0);
/// Bound of the adapted offset, as a share of the model's full torque.
pub const OFFSET_SHARE: f64 = 0.2;
/// Bound of the adaptation covariance's trace (normalised units): with forgetting and no excitation it would
/// grow without end and the next excitation would throw the estimate.
const COVARIANCE_BOUND: f64 = 10.0;
/// Initial adaptation covariance (normalised units).
const COVARIANCE_START: f64 = 1.0;

/// What the controller is asked for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControllerSettings {
    /// Loop crossover asked for (Hz); 0: automatic (the largest that keeps the sensor-noise share and a
    /// phase margin of [`AUTO_PHASE_MARGIN_DEG`]).
    pub bandwidth_hz: f64,
    /// Share of the sensor-noise variance the integrator may add to the torque (automatic bandwidth only).
    pub noise_share: f64,
    /// Memory of the gain/offset adaptation (s): the forgetting factor is `1 − dt/adaptation_time_s`.
    pub adaptation_time_s: f64,
    /// Missing measurements in a row after which the command is a fault (zero current); at least 1.
    pub fault_after: u32,
    /// Largest integral correction (N·mm); 0: a quarter of the model's full torque.
    pub correction_limit_nmm: f64,
    /// Integral feedback on (off: feedforward with adaptation only).
    pub feedback: bool,
    /// Gain/offset adaptation on (off: frozen at its present estimate).
    pub adaptation: bool,
}

impl Default for ControllerSettings {
    fn default() -> Self {
        ControllerSettings {
            bandwidth_hz: 0.0,
            noise_share: 0.02,
            adaptation_time_s: 5.0,
            fault_after: 50,
            correction_limit_nmm: 0.0,
            feedback: true,
            adaptation: true,
        }
    }
}

/// The loop as designed from the model: what was asked and what it gives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControllerDesign {
    /// Control period (s).
    pub dt_s: f64,
    /// Bandwidth asked for (Hz; 0: automatic).
    pub asked_hz: f64,
    /// Loop crossover (Hz): `ki / 2π` (0 with feedback off).
    pub bandwidth_hz: f64,
    /// Integral gain on the torque error (1/s).
    pub ki_per_s: f64,
    /// Delay the loop sees (s): `time_delay` samples + one sample to the measurement + half a sample of hold.
    pub loop_delay_s: f64,
    /// Phase margin at the crossover (degrees; 90 with feedback off).
    pub phase_margin_deg: f64,
    /// Coil-lag time constant the feedforward leads (s; 0 without the stage).
    pub coil_lag_s: f64,
    /// Samples between a command and its torque (`time_delay`).
    pub delay_samples: usize,
    /// Forgetting factor of the adaptation per sample.
    pub forgetting: f64,
    /// Largest integral correction (N·mm).
    pub correction_limit_nmm: f64,
    /// Full torque of the model (N·mm): the scale of the offset bound and of the adaptation's units.
    pub full_torque_nmm: f64,
    /// Missing measurements in a row before a fault.
    pub fault_after: u32,
    pub feedback: bool,
}

/// A controller setting outside its range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ControllerError {
    /// The control period must be finite and positive (s).
    Period(f64),
    /// The bandwidth asked for must be finite and ≥ 0 (Hz), and leave a phase margin of at least
    /// [`MIN_PHASE_MARGIN_DEG`] (the margin it would leave).
    Bandwidth { hz: f64, margin_deg: f64 },
    /// The noise share must lie in (0, 1].
    NoiseShare(f64),
    /// The adaptation memory must be finite and longer than the control period (s).
    AdaptationTime(f64),
    /// The fault count must be at least 1.
    FaultAfter(u32),
    /// The correction limit must be finite and ≥ 0 (N·mm).
    CorrectionLimit(f64),
}

impl core::fmt::Display for ControllerError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            ControllerError::Period(v) => {
                write!(
                    f,
                    "dt_s must be a positive finite control period in s, got {v}"
                )
            }
            ControllerError::Bandwidth { hz, margin_deg } => write!(
                f,
                "bandwidth_hz={hz} is not a finite bandwidth ≥ 0 Hz leaving a phase margin of at least \
                 {MIN_PHASE_MARGIN_DEG}° with this loop's delay (it leaves {margin_deg:.1}°)"
            ),
            ControllerError::NoiseShare(v) => write!(f, "noise_share must lie in (0, 1], got {v}"),
            ControllerError::AdaptationTime(v) => write!(
                f,
                "adaptation_time_s must be finite and longer than the control period, got {v}"
            ),
            ControllerError::FaultAfter(v) => write!(f, "fault_after must be at least 1, got {v}"),
            ControllerError::CorrectionLimit(v) => write!(
                f,
                "correction_limit_nmm must be finite and ≥ 0 N·mm (0: automatic), got {v}"
            ),
        }
    }
}

/// Recursive least squares with forgetting of `z = g·x + β` (normalised torques), bounded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GainOffset {
    gain: f64,
    /// Offset in units of the full torque.
    beta: f64,
    p00: f64,
    p01: f64,
    p11: f64,
}

impl GainOffset {
    pub const fn new() -> Self {
        GainOffset {
            gain: 1.0,
            beta: 0.0,
            p00: COVARIANCE_START,
            p01: 0.0,
            p11: COVARIANCE_START,
        }
    }
    pub fn gain(&self) -> f64 {
        self.gain
    }
    /// Offset in units of the full torque.
    pub fn offset(&self) -> f64 {
        self.beta
    }

    /// One update with prediction `x` and measurement `z` (both finite, normalised).
    #[inline]
    fn update(&mut self, x: f64, z: f64, lambda: f64, inv_lambda: f64, offset_bound: f64) {
        let px0 = self.p00 * x + self.p01;
        let px1 = self.p01 * x + self.p11;
        let inv_denom = 1.0 / (lambda + x * px0 + px1);
        let k0 = px0 * inv_denom;
        let k1 = px1 * inv_denom;
        let residual = z - (self.gain * x + self.beta);
        let gain = self.gain + k0 * residual;
        let beta = self.beta + k1 * residual;
        let mut p00 = (self.p00 - k0 * px0) * inv_lambda;
        let mut p01 = (self.p01 - k0 * px1) * inv_lambda;
        let mut p11 = (self.p11 - k1 * px1) * inv_lambda;
        let trace = p00 + p11;
        if trace > COVARIANCE_BOUND {
            (p00, p01, p11) = bound_covariance(p00, p01, p11, trace);
        }
        // One test for all five: a NaN or an infinity in any term makes the sum non-finite (a finite overflow of
        // the sum only rejects an update the clamps below would have cut anyway).
        if !(gain + beta + p00 + p01 + p11).is_finite() {
            return; // a degenerate update keeps the last good estimate
        }
        self.gain = gain.clamp(GAIN_RANGE.0, GAIN_RANGE.1);
        self.beta = beta.clamp(-offset_bound, offset_bound);
        self.p00 = p00;
        self.p01 = p01;
        self.p11 = p11;
    }
}

/// The covariance scaled down to the trace bound (rare: only after a long stretch without excitation).
#[cold]
#[inline(never)]
fn bound_covariance(p00: f64, p01: f64, p11: f64, trace: f64) -> (f64, f64, f64) {
    let s = COVARIANCE_BOUND / trace;
    (p00 * s, p01 * s, p11 * s)
}

impl Default for GainOffset {
    fn default() -> Self {
        Self::new()
    }
}

/// The loop's own state (a plain copy).
#[derive(Debug, Clone, Copy, PartialEq)]
struct LoopState {
    correction: f64,
    estimate: GainOffset,
    adaptation_frozen: bool,
    missing: u32,
    /// Reference of the last step (the torque the measurement arriving next should show).
    reference_prev: f64,
    /// Model torque predictions of the last steps (ring, newest at `head`; NaN: none).
    predictions: [f64; PREDICTION_HISTORY],
    head: usize,
}

impl LoopState {
    const fn new() -> Self {
        LoopState {
            correction: 0.0,
            estimate: GainOffset::new(),
            adaptation_frozen: false,
            missing: 0,
            reference_prev: f64::NAN,
            predictions: [f64::NAN; PREDICTION_HISTORY],
            head: 0,
        }
    }
}

/// Controller state that changes per step (a plain copy).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControllerState<const N: usize> {
    compensator: CompensatorState<N>,
    state: LoopState,
}

/// Feedforward compensator + integral feedback + gain/offset adaptation (module doc).
#[derive(Debug, Clone)]
pub struct Controller<S, const N: usize, const K: usize> {
    compensator: Compensator<S, N, K>,
    design: ControllerDesign,
    state: LoopState,
    /// Reciprocals of the forgetting factor and the full torque (a multiply per step instead of a division).
    inv_forgetting: f64,
    inv_full_torque: f64,
    /// Integral step per N·mm of error, `ki·dt` (0 with feedback off).
    ki_dt: f64,
    /// Ring positions back from the newest prediction to the one a measurement pairs with.
    pair_back: usize,
}

impl<S: AsRef<[f64]>, const N: usize, const K: usize> Controller<S, N, K> {
    /// Close the loop around `compensator` (its present state is the start) at control period `dt_s`.
    pub fn new(
        compensator: Compensator<S, N, K>,
        dt_s: f64,
        settings: ControllerSettings,
    ) -> Result<Self, ControllerError> {
        let design = design(&compensator, dt_s, &settings)?;
        Ok(Controller {
            compensator,
            inv_forgetting: 1.0 / design.forgetting,
            inv_full_torque: 1.0 / design.full_torque_nmm,
            ki_dt: design.ki_per_s * design.dt_s,
            pair_back: design.delay_samples.min(PREDICTION_HISTORY - 1),
            design,
            state: LoopState {
                adaptation_frozen: !settings.adaptation,
                ..LoopState::new()
            },
        })
    }

    pub fn design(&self) -> &ControllerDesign {
        &self.design
    }
    pub fn compensator(&self) -> &Compensator<S, N, K> {
        &self.compensator
    }
    /// Adapted output gain (measured torque per model torque).
    pub fn gain(&self) -> f64 {
        self.state.estimate.gain
    }
    /// Adapted output offset (N·mm).
    pub fn offset_nmm(&self) -> f64 {
        self.state.estimate.beta * self.design.full_torque_nmm
    }
    /// Integral correction added to the reference (N·mm).
    pub fn correction_nmm(&self) -> f64 {
        self.state.correction
    }
    /// Missing measurements in a row so far.
    pub fn missing_samples(&self) -> u32 {
        self.state.missing
    }
    pub fn adaptation_frozen(&self) -> bool {
        self.state.adaptation_frozen
    }
    /// Hold the gain and offset where they are (`true`) or let them adapt again.
    pub fn freeze_adaptation(&mut self, frozen: bool) {
        self.state.adaptation_frozen = frozen;
    }
    /// Gain back to 1, offset to 0, the covariance to its start.
    pub fn reset_adaptation(&mut self) {
        self.state.estimate = GainOffset::new();
    }

    /// One control period: reference torque (N·mm) and rotor angle (rad) of this sample, and the torque measured
    /// at the previous sample (N·mm; NaN/inf: no new value).
    #[inline]
    pub fn step(&mut self, reference_nmm: f64, theta_rad: f64, measured_nmm: f64) -> Command {
        self.step_sharing(reference_nmm, theta_rad, measured_nmm, None)
    }

    /// [`Self::step`] given `sincos = crate::trig::sincos(theta_rad)`, computed by a loop that owns the angle
    /// (see [`Compensator::step_with_sincos`]): the same command to the bit.
    #[inline]
    pub fn step_with_sincos(
        &mut self,
        reference_nmm: f64,
        theta_rad: f64,
        measured_nmm: f64,
        sincos: (f64, f64),
    ) -> Command {
        self.step_sharing(reference_nmm, theta_rad, measured_nmm, Some(sincos))
    }

    #[inline(always)]
    fn step_sharing(
        &mut self,
        reference_nmm: f64,
        theta_rad: f64,
        measured_nmm: f64,
        sincos: Option<(f64, f64)>,
    ) -> Command {
        let d = &self.design;
        let st = &mut self.state;
        let mut increment = 0.0;
        if measured_nmm.is_finite() {
            st.missing = 0;
            if st.reference_prev.is_finite() {
                increment = self.ki_dt * (st.reference_prev - measured_nmm);
            }
            if !st.adaptation_frozen {
                // The prediction of the sample measured: made `delay_samples` steps before the last one.
                let i = (st.head + PREDICTION_HISTORY - self.pair_back) % PREDICTION_HISTORY;
                let predicted = st.predictions[i];
                if predicted.is_finite() {
                    let inv_scale = self.inv_full_torque;
                    st.estimate.update(
                        predicted * inv_scale,
                        measured_nmm * inv_scale,
                        d.forgetting,
                        self.inv_forgetting,
                        OFFSET_SHARE,
                    );
                }
            }
        } else {
            st.missing = st.missing.saturating_add(1);
        }
        st.reference_prev = reference_nmm;
        let limit = d.correction_limit_nmm;
        // Two compares (a NaN passes through and is not kept below), not `clamp`'s ordering assertion.
        let mut correction = st.correction + increment;
        if correction > limit {
            correction = limit;
        } else if correction < -limit {
            correction = -limit;
        }
        let faulted = st.missing >= d.fault_after;
        let est = st.estimate;
        let target = if faulted {
            f64::NAN // the compensator's fault path: zero current, every stage follows it
        } else {
            (reference_nmm + correction - est.beta * d.full_torque_nmm) / est.gain
        };
        let command = match sincos {
            Some(sc) => self.compensator.step_with_sincos(target, theta_rad, sc),
            None => self.compensator.step(target, theta_rad),
        };
        let st = &mut self.state;
        // Anti-windup: a saturated command keeps the correction only where it pulls back from the saturation
        // (a torque above reach needs more current in the direction of the current's sign).
        let pushes_further = command.saturated && (increment > 0.0) == (command.current_a > 0.0);
        if !command.fault && !pushes_further && correction.is_finite() {
            st.correction = correction;
        }
        st.head = (st.head + 1) % PREDICTION_HISTORY;
        // A saturated command drives the model out of the region it describes (its saturation plateau is not the
        // plant's): the adaptation skips that sample rather than learn a gain from it.
        st.predictions[st.head] = if command.fault || command.saturated {
            f64::NAN
        } else {
            self.compensator.model_torque_nmm()
        };
        command
    }

    pub fn snapshot(&self) -> ControllerState<N> {
        ControllerState {
            compensator: self.compensator.snapshot(),
            state: self.state,
        }
    }

    /// Return to a snapshot of this controller (or of one with identical tables and stages).
    pub fn restore(&mut self, s: &ControllerState<N>) -> Result<(), crate::error::TableError> {
        self.compensator.restore(&s.compensator)?;
        self.state = s.state;
        Ok(())
    }

    /// Compensator back to `initial` (see [`Compensator::reset`]), correction and adaptation to their start.
    pub fn reset(&mut self, initial: crate::cbh::Initial) {
        self.compensator.reset(initial);
        let frozen = self.state.adaptation_frozen;
        self.state = LoopState {
            adaptation_frozen: frozen,
            ..LoopState::new()
        };
    }
}

/// The loop designed from the compensator's stages (module doc).
fn design<S: AsRef<[f64]>, const N: usize, const K: usize>(
    c: &Compensator<S, N, K>,
    dt_s: f64,
    s: &ControllerSettings,
) -> Result<ControllerDesign, ControllerError> {
    if !(dt_s.is_finite() && dt_s > 0.0) {
        return Err(ControllerError::Period(dt_s));
    }
    if !(s.noise_share > 0.0 && s.noise_share <= 1.0) {
        return Err(ControllerError::NoiseShare(s.noise_share));
    }
    if !(s.adaptation_time_s.is_finite() && s.adaptation_time_s > dt_s) {
        return Err(ControllerError::AdaptationTime(s.adaptation_time_s));
    }
    if s.fault_after == 0 {
        return Err(ControllerError::FaultAfter(s.fault_after));
    }
    if !(s.correction_limit_nmm.is_finite() && s.correction_limit_nmm >= 0.0) {
        return Err(ControllerError::CorrectionLimit(s.correction_limit_nmm));
    }
    let delay_samples = c.preview_samples();
    let loop_delay_s = (delay_samples as f64 + 1.5) * dt_s;
    let two_pi = 2.0 * core::f64::consts::PI;
    let margin = |w: f64| 90.0 - w * loop_delay_s * 180.0 / core::f64::consts::PI;
    let wc = if s.bandwidth_hz == 0.0 {
        // The integrator's step a = ki·dt adds a/(2 − a) of the sensor-noise variance to the torque.
        let a = 2.0 * s.noise_share / (1.0 + s.noise_share);
        let by_noise = a / dt_s;
        let by_margin = (90.0 - AUTO_PHASE_MARGIN_DEG).to_radians() / loop_delay_s;
        by_noise.min(by_margin)
    } else {
        let w = two_pi * s.bandwidth_hz;
        let m = margin(w);
        if !(w.is_finite() && w > 0.0 && m >= MIN_PHASE_MARGIN_DEG) {
            return Err(ControllerError::Bandwidth {
                hz: s.bandwidth_hz,
                margin_deg: if m.is_finite() { m } else { f64::NEG_INFINITY },
            });
        }
        w
    };
    let (ylo, yhi) = c.forward().output_range();
    let full_torque_nmm = ylo.abs().max(yhi.abs());
    let correction_limit_nmm = if s.correction_limit_nmm == 0.0 {
        0.25 * full_torque_nmm
    } else {
        s.correction_limit_nmm
    };
    let ki = if s.feedback { wc } else { 0.0 };
    Ok(ControllerDesign {
        dt_s,
        asked_hz: s.bandwidth_hz,
        bandwidth_hz: ki / two_pi,
        ki_per_s: ki,
        loop_delay_s,
        phase_margin_deg: margin(ki),
        coil_lag_s: c.stages().coil_lag.map_or(0.0, |l| {
            let p = l.pole();
            if p > 0.0 { -dt_s / libm::log(p) } else { 0.0 }
        }),
        delay_samples,
        forgetting: 1.0 - dt_s / s.adaptation_time_s,
        correction_limit_nmm,
        full_torque_nmm,
        fault_after: s.fault_after,
        feedback: s.feedback,
    })
}

/// First word of a serialised [`ControllerState`] (format tag and version).
const STATE_TAG: u64 = 0x626d_725f_636c_0001;
/// Words of the loop state: correction, 5 estimate words, frozen, missing, previous reference, head, ring.
const LOOP_WORDS: usize = 10 + PREDICTION_HISTORY;

#[cfg(feature = "alloc")]
impl<const N: usize> ControllerState<N> {
    /// The state as plain words (pickling); [`Controller::state_from_words`] reads it back bit for bit.
    pub fn to_words(&self) -> alloc::vec::Vec<u64> {
        let s = &self.state;
        let e = &s.estimate;
        let mut w = alloc::vec![STATE_TAG];
        w.extend([
            s.correction.to_bits(),
            e.gain.to_bits(),
            e.beta.to_bits(),
            e.p00.to_bits(),
            e.p01.to_bits(),
            e.p11.to_bits(),
            u64::from(s.adaptation_frozen),
            u64::from(s.missing),
            s.reference_prev.to_bits(),
            s.head as u64,
        ]);
        w.extend(s.predictions.iter().map(|p| p.to_bits()));
        w.extend(self.compensator.to_words());
        w
    }
}

impl<S: AsRef<[f64]>, const N: usize, const K: usize> Controller<S, N, K> {
    /// Read a state written by [`ControllerState::to_words`] from a controller with the same compensator;
    /// damaged or foreign words are an error.
    pub fn state_from_words(
        &self,
        words: &[u64],
    ) -> Result<ControllerState<N>, crate::error::TableError> {
        use crate::error::TableError;
        let bad = |what| TableError::BadState { what };
        if words.len() < 1 + LOOP_WORDS || words[0] != STATE_TAG {
            return Err(bad("not a serialised controller state"));
        }
        let f = |i: usize| f64::from_bits(words[1 + i]);
        let finite = |x: f64| x.is_finite();
        let estimate = GainOffset {
            gain: f(1),
            beta: f(2),
            p00: f(3),
            p01: f(4),
            p11: f(5),
        };
        let sane = finite(f(0))
            && (GAIN_RANGE.0..=GAIN_RANGE.1).contains(&estimate.gain)
            && estimate.beta.abs() <= OFFSET_SHARE
            && [estimate.p00, estimate.p01, estimate.p11]
                .iter()
                .all(|p| finite(*p))
            && words[7] <= 1
            && words[8] <= u64::from(u32::MAX)
            && words[10] < PREDICTION_HISTORY as u64;
        if !sane {
            return Err(bad("controller state words out of range"));
        }
        let mut predictions = [f64::NAN; PREDICTION_HISTORY];
        for (p, w) in predictions
            .iter_mut()
            .zip(&words[11..11 + PREDICTION_HISTORY])
        {
            *p = f64::from_bits(*w);
        }
        let state = LoopState {
            correction: f(0),
            estimate,
            adaptation_frozen: words[7] == 1,
            missing: words[8] as u32,
            reference_prev: f(8),
            predictions,
            head: words[10] as usize,
        };
        let compensator = self
            .compensator
            .state_from_words(&words[1 + LOOP_WORDS..])?;
        Ok(ControllerState { compensator, state })
    }
}
