//! Open-loop torque compensator (paper figs 20 and 23): `I = H⁻¹[T_ref − T_f(θ)]`, split to the two coils
//! (eq 8), limited, and converted to converter voltages.
//!
//! Safety invariants (property-tested): never both coils energised; `|I| <= limit`; a NaN/inf reference or angle,
//! or any intermediate that is not finite, gives zero current with `fault` set (no panic); the forward memory always follows the current actually
//! commanded, including after limiting and faults. No allocation in `step`.
use crate::cbh::Hysteresis;
use crate::friction::Friction;
use crate::inverse::InverseInput;

/// Which inverse drives the command.
// Held once per compensator and `no_std` has no `Box`: the size difference is fine.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
pub enum InverseKind<S, const N: usize> {
    /// Exact inverse of the forward operator (docs/architecture.md §2.5).
    Exact,
    /// The paper's inverse CBH operator on current curves (input torque, output current).
    Paper(Hysteresis<S, N>),
}

/// One control-period command.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
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
    /// The reference, the angle or an intermediate (friction, torque target, inverse) was not finite: zero current
    /// commanded.
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
}

#[cfg(feature = "alloc")]
impl<const N: usize> CompensatorState<N> {
    /// The state as plain words: the forward operator's and, with the paper's inverse, the inverse operator's
    /// ([`crate::cbh::State::to_words`]); [`Compensator::state_from_words`] reads them back bit for bit.
    pub fn to_words(&self) -> (alloc::vec::Vec<u64>, Option<alloc::vec::Vec<u64>>) {
        (
            self.forward.to_words(),
            self.paper.as_ref().map(crate::cbh::State::to_words),
        )
    }
}

/// Hysteresis + friction compensator with a memory of `N` reversal points and `K` friction harmonics.
#[derive(Debug, Clone)]
pub struct Compensator<S, const N: usize, const K: usize> {
    forward: Hysteresis<S, N>,
    inverse: InverseKind<S, N>,
    friction: Friction<K>,
    gain_a_per_v: f64,
    limit_a: f64,
    /// Friction feedforward of the last fault-free step (N·mm).
    friction_nmm: f64,
}

/// A compensator parameter outside its range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CompensatorError {
    /// Converter gain must be finite and positive (A/V).
    Gain(f64),
    /// Converter gain so small that the current limit would need infinite volts.
    GainForLimit { gain_a_per_v: f64, limit_a: f64 },
    /// Current limit must be finite and positive (A).
    Limit(f64),
}

impl core::fmt::Display for CompensatorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            CompensatorError::Gain(g) => write!(
                f,
                "converter gain must be a positive finite A/V value, got {g}"
            ),
            CompensatorError::GainForLimit {
                gain_a_per_v,
                limit_a,
            } => write!(
                f,
                "converter gain {gain_a_per_v} A/V is too small: the current limit {limit_a} A would need \
                 infinite volts"
            ),
            CompensatorError::Limit(l) => write!(
                f,
                "current limit must be a positive finite A value, got {l}"
            ),
        }
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
        if !(gain_a_per_v.is_finite() && gain_a_per_v > 0.0) {
            return Err(CompensatorError::Gain(gain_a_per_v));
        }
        if !(limit_a.is_finite() && limit_a > 0.0) {
            return Err(CompensatorError::Limit(limit_a));
        }
        if !(limit_a / gain_a_per_v).is_finite() {
            return Err(CompensatorError::GainForLimit {
                gain_a_per_v,
                limit_a,
            });
        }
        Ok(Compensator {
            forward,
            inverse,
            friction,
            gain_a_per_v,
            limit_a,
            friction_nmm: 0.0,
        })
    }

    pub fn forward(&self) -> &Hysteresis<S, N> {
        &self.forward
    }
    pub fn friction(&self) -> &Friction<K> {
        &self.friction
    }
    pub fn limit_a(&self) -> f64 {
        self.limit_a
    }
    pub fn gain_a_per_v(&self) -> f64 {
        self.gain_a_per_v
    }
    /// Friction feedforward (N·mm) of the last step that was not a fault.
    pub fn friction_nmm(&self) -> f64 {
        self.friction_nmm
    }
    /// Torque (N·mm, without friction) the forward model predicts for the last command.
    pub fn predicted_torque(&self) -> f64 {
        self.forward.output()
    }

    /// One control period: reference torque (N·mm) and rotor angle (rad) → command.
    #[inline]
    pub fn step(&mut self, torque_ref_nmm: f64, theta_rad: f64) -> Command {
        if !(torque_ref_nmm.is_finite() && theta_rad.is_finite()) {
            return self.commit(0.0, false, true);
        }
        let friction_nmm = self.friction.eval(theta_rad);
        let target = torque_ref_nmm - friction_nmm;
        if !target.is_finite() {
            return self.commit(0.0, false, true);
        }
        self.friction_nmm = friction_nmm;
        let InverseInput { input, saturated } = match &mut self.inverse {
            InverseKind::Exact => self.forward.inverse_input(target),
            InverseKind::Paper(inv) => {
                let (lo, hi) = inv.input_range();
                InverseInput {
                    input: inv.step(target),
                    saturated: target < lo || target > hi,
                }
            }
        };
        if !input.is_finite() {
            return self.commit(0.0, false, true);
        }
        let limited = input.clamp(-self.limit_a, self.limit_a);
        if matches!(self.inverse, InverseKind::Exact) && !saturated && limited == input {
            // The exact inverse already knows the output: commit without evaluating the branch again.
            self.forward.commit(input, target);
            return Command::from_current(input, self.gain_a_per_v, false, false);
        }
        self.commit(limited, saturated || limited != input, false)
    }

    /// Command `current_a` and make the forward memory follow it.
    #[inline]
    fn commit(&mut self, current_a: f64, saturated: bool, fault: bool) -> Command {
        let y = self.forward.step(current_a);
        if fault && let InverseKind::Paper(inv) = &mut self.inverse {
            // Keep the torque-domain memory consistent with the zero current actually commanded.
            inv.step(y);
        }
        Command::from_current(current_a, self.gain_a_per_v, saturated, fault)
    }

    pub fn snapshot(&self) -> CompensatorState<N> {
        CompensatorState {
            forward: self.forward.snapshot(),
            paper: match &self.inverse {
                InverseKind::Paper(inv) => Some(inv.snapshot()),
                InverseKind::Exact => None,
            },
        }
    }

    pub fn restore(&mut self, s: &CompensatorState<N>) -> Result<(), crate::error::TableError> {
        match (&mut self.inverse, &s.paper) {
            (InverseKind::Paper(inv), Some(p)) => inv.restore(p)?,
            (InverseKind::Exact, None) => {}
            _ => return Err(crate::error::TableError::ForeignState),
        }
        self.forward.restore(&s.forward)
    }

    /// Read back the words of [`CompensatorState::to_words`], checked against this compensator's tables as
    /// [`Hysteresis::state_from_words`] checks them; paper-inverse words are needed exactly when this
    /// compensator uses the paper's inverse.
    pub fn state_from_words(
        &self,
        forward: &[u64],
        paper: Option<&[u64]>,
    ) -> Result<CompensatorState<N>, crate::error::TableError> {
        let paper = match (&self.inverse, paper) {
            (InverseKind::Paper(inv), Some(w)) => Some(inv.state_from_words(w)?),
            (InverseKind::Exact, None) => None,
            _ => return Err(crate::error::TableError::ForeignState),
        };
        Ok(CompensatorState {
            forward: self.forward.state_from_words(forward)?,
            paper,
        })
    }

    /// Reset both operators to `initial`.
    pub fn reset(&mut self, initial: crate::cbh::Initial) {
        self.forward.reset(initial);
        if let InverseKind::Paper(inv) = &mut self.inverse {
            inv.reset(initial_of_torque(initial, &self.forward));
        }
    }
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
