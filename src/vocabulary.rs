//! The effect vocabulary: every physical effect the virtual actuator can switch on, the diagnosis can name and the
//! compensator can undo — name, where it acts, documentation and parameters (unit, default, valid range).
//!
//! This is the one definition: the plant (`crate::plant::effects`), the compensator stages
//! (`crate::stages`), the model file and the Python diagnosis (through `bmr.EFFECTS` and
//! `bmr.effect_parameters()`) all read it. Static data, `no_std`. A new effect is one entry in the
//! `vocabulary!` list below (plus its physics where it acts).

use core::fmt;

/// A parameter of an effect: name, unit, default and valid range (inclusive).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    pub name: &'static str,
    pub unit: &'static str,
    pub default: f64,
    pub min: f64,
    pub max: f64,
    /// The value must be a whole number (a harmonic order, say).
    pub whole: bool,
    /// Where 0 means "automatic" (a full scale taken from the device), the smallest magnitude a set value may
    /// have: values between 0 and this are refused, since the physics divides by them. 0 = no such gap.
    pub smallest_nonzero: f64,
    pub doc: &'static str,
}

impl ParamSpec {
    /// Whether `value` is a valid setting of this parameter.
    pub fn accepts(&self, value: f64) -> bool {
        value.is_finite()
            && value >= self.min
            && value <= self.max
            && (!self.whole || libm::trunc(value) == value)
            && (value == 0.0 || libm::fabs(value) >= self.smallest_nonzero)
    }
}

/// Where in the physical chain an effect acts (and so which compensator stage, if any, undoes it).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Acts {
    /// On the current between the command and the field (delay, coil lag): undone after the CBH inverse.
    Current,
    /// On the field torque after the hysteretic core (output map, thermal gain, ripple): undone before the CBH
    /// inverse.
    Field,
    /// On the seal friction: part of the friction feedforward.
    Friction,
    /// On the measurement only (sensor drift): never compensated.
    Sensor,
}

impl Acts {
    pub fn name(self) -> &'static str {
        match self {
            Acts::Current => "current",
            Acts::Field => "field",
            Acts::Friction => "friction",
            Acts::Sensor => "sensor",
        }
    }
}

/// Where an effect's compensator stage sits in the loop and what it needs and carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoopStage {
    /// Place in the physical chain, command side first (the compensator walks it backwards); unique.
    pub order: u8,
    /// The stage is built for a sample period (a filter, a delay, a rate): it cannot be built without one.
    pub needs_period: bool,
    /// The state it carries from sample to sample (empty: none), with units.
    pub state: &'static str,
}

const fn stage(order: u8, needs_period: bool, state: &'static str) -> Option<LoopStage> {
    Some(LoopStage {
        order,
        needs_period,
        state,
    })
}

/// The stage needs the sample period.
const PERIOD: bool = true;
/// The stage needs no sample period.
const NO_PERIOD: bool = false;
/// Never compensated (acts on the measurement, or no stage undoes it).
const NOT_IN_LOOP: Option<LoopStage> = None;
/// The effect lives on the rotor angle (an actuator's seal friction or rotor): it needs an angle signal.
const ON_ANGLE: bool = true;
const NO_ANGLE: bool = false;

/// Everything the vocabulary says about one effect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EffectSpec {
    pub name: &'static str,
    pub acts: Acts,
    /// Its compensator stage, if the compensator undoes it.
    pub stage: Option<LoopStage>,
    /// It depends on the rotor angle (needs an angle signal to be seen or fitted).
    pub on_angle: bool,
    /// The physics and the signature it leaves in the data.
    pub doc: &'static str,
    pub params: &'static [ParamSpec],
}

impl EffectSpec {
    /// Index of parameter `name` in [`EffectSpec::params`].
    pub fn param_index(&self, name: &str) -> Option<usize> {
        self.params.iter().position(|p| p.name == name)
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
        whole: false,
        smallest_nonzero: 0.0,
        doc,
    }
}

const fn whole(spec: ParamSpec) -> ParamSpec {
    ParamSpec {
        whole: true,
        ..spec
    }
}

/// `spec` whose 0 means "automatic" and whose set values are at least `smallest` in magnitude.
const fn zero_or_at_least(smallest: f64, spec: ParamSpec) -> ParamSpec {
    ParamSpec {
        smallest_nonzero: smallest,
        ..spec
    }
}

/// Highest harmonic order the friction model (and so the `friction_harmonics` effect) supports.
pub const MAX_HARMONIC: usize = 24;

/// Most parameters any effect has.
pub const MAX_PARAMS: usize = 5;

macro_rules! vocabulary {
    ($($kind:ident = $name:literal, $acts:ident, $stage:expr, $angle:expr, $doc:expr,
       [$($param:expr),* $(,)?];)*) => {
        /// The names of the effect vocabulary, in vocabulary order.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum EffectKind {
            $($kind,)*
        }

        /// Every effect, in vocabulary order (`SPECS[kind as usize]` describes `kind`).
        pub static SPECS: &[EffectSpec] = &[
            $(EffectSpec {
                name: $name,
                acts: Acts::$acts,
                stage: $stage,
                on_angle: $angle,
                doc: $doc,
                params: &[$($param),*],
            },)*
        ];

        impl EffectKind {
            pub const ALL: [EffectKind; [$($name),*].len()] = [$(EffectKind::$kind,)*];
        }
    };
}

vocabulary! {
    CoilLag = "coil_lag", Current, stage(2, PERIOD, "field current (A)"), NO_ANGLE,
        "The field lags the coil current (coil L/R, eddy currents): each coil's magnetising current is a \
         first-order lag of the converter current with time constant tau_s. Signature: residual proportional to \
         the current rate; loops widen with frequency.",
        [p("tau_s", "s", 0.02, 0.0, 10.0, "first-order field time constant")];
    ThermalDrift = "thermal_drift", Field,
        stage(8, PERIOD, "coil heating state (1 = steady full current)"), NO_ANGLE,
        "Coil heating lowers the torque gain: a thermal state driven by (I/I_full)^2 with time constant tau_s \
         scales the field torque by (1 - gain_loss * state). Signature: slow multiplicative drift.",
        [p("gain_loss", "1", 0.08, -0.9, 0.9,
           "fractional torque-gain loss at steady full current (negative: the gain rises)"),
         p("tau_s", "s", 120.0, 1e-3, 1e6, "thermal time constant")];
    FrictionCurrent = "friction_current", Friction,
        stage(11, PERIOD, "smoothed |field current| (A)"), ON_ANGLE,
        "Seal friction grows with current (magnetic pull on the seals): the angle-dependent friction is scaled \
         by (1 + gain_per_a * |I|). Signature: angle ripple whose size grows with |current|.",
        [p("gain_per_a", "1/A", 0.6, -0.5, 100.0,
           "relative growth of the angle-dependent friction per ampere of |I|")];
    FrictionHarmonics = "friction_harmonics", Friction, stage(10, NO_PERIOD, ""), ON_ANGLE,
        "A friction harmonic above the 3rd (gear mesh, seal lobes): amplitude_nmm * sin(order * theta + \
         phase_rad). Signature: a periodogram line at order cycles/rev.",
        [whole(p("order", "cycles/rev", 5.0, 4.0, MAX_HARMONIC as f64, "harmonic number k (a whole number)")),
         p("amplitude_nmm", "N·mm", 6.0, -1e4, 1e4, "amplitude"),
         p("phase_rad", "rad", 0.0, -1e3, 1e3, "phase")];
    TorqueRipple = "torque_ripple", Field, stage(9, NO_PERIOD, ""), ON_ANGLE,
        "Eccentric gap: the field torque is multiplied by (1 + eps * cos(theta + phase_rad)). Signature: angle \
         ripple proportional to |torque|.",
        [p("eps", "1", 0.05, 0.0, 0.9, "relative field-torque modulation"),
         p("phase_rad", "rad", 0.0, -1e3, 1e3, "phase of the once-per-revolution modulation")];
    SensorDrift = "sensor_drift", Sensor, NOT_IN_LOOP, NO_ANGLE,
        "The torque sensor offset drifts with time from the actuator's start at rate_nmm_per_s, linearly, or \
         settling as a strain bridge warms up: rate_nmm_per_s * (1 - exp(-settle_per_s * t)) / settle_per_s \
         (0: a drift that never settles). Signature: a trend in zero-torque segments.",
        [p("rate_nmm_per_s", "N·mm/s", 0.02, -1e3, 1e3, "offset drift rate at the start"),
         p("settle_per_s", "1/s", 0.0, 0.0, 1.0,
           "rate at which the drift settles (1/the warm-up time constant; 0: linear)")];
    TimeDelay = "time_delay", Current,
        stage(1, PERIOD, "the last references and angles (output units, rad)"), NO_ANGLE,
        "Pure delay of delay_s (rounded to whole samples) between the commanded current and the coils. \
         Signature: residual proportional to rate, no loop widening with amplitude.",
        [p("delay_s", "s", 0.01, 0.0, 1.0, "command-to-coil delay")];
    NonCongruent = "non_congruent", Field, stage(6, NO_PERIOD, ""), NO_ANGLE,
        "Extra output nonlinearity after the Preisach core: the field torque T becomes S * n (1 + curvature |n| \
         + cubic n^2) / (1 + curvature + cubic) with n = T / S and S the full-scale torque, an odd map through \
         (0, 0) and (S, S): curvature bends it like a square, cubic like the yield stress of an MR fluid that is \
         a cubic function of the steel's flux. The compensator inverts it exactly on a monotone table (up to the \
         map's turning point when it is concave). Mean-field form (the moving Preisach model, Della Torre): the \
         interaction of the hysterons feeds the core's own output back into its input, the core seeing \
         u + feedback * y / S with y its output of the sample before (positive feedback: magnetizing, the loop \
         steepens and tilts; negative: demagnetizing, it shears). The compensator inverts it exactly: the input \
         the core needs less feedback times the output it already has. Signature: error only after \
         higher-order reversals (minor loops scale with the local slope).",
        [p("curvature", "1", 1.0, -0.45, 5.0,
           "output nonlinearity strength (0 = off; >0 convex, <0 concave)"),
         zero_or_at_least(1e-3, p("scale_nmm", "N·mm", 0.0, 0.0, 1e9,
           "full-scale torque S (0: the actuator's own — the plant's full_torque_nmm per rotor, a model's \
            largest |torque|; else at least 1e-3)")),
         p("cubic", "1", 0.0, -0.3, 3.0,
           "odd cubic term (0 = off; >0 stiffening towards full scale, <0 saturating; in this range the map \
            rises over |n| <= 1 whenever curvature >= 0)"),
         p("feedback", "A", 0.0, -1e3, 1e3,
           "mean-field interaction: input added per full-scale core output, y/S, of the sample before (input \
            units; 0 = off, > 0 magnetizing). Physical only while the loop stays single-valued: feedback times \
            the core's steepest normalised slope (max dy/du / S, per input unit) below 1, checked where the \
            diagnosis accepts it")];
    Creep = "creep", Field, stage(5, PERIOD, "the relaxations' outputs (output units)"), NO_ANGLE,
        "After every change of the output (a reversal, a step, a dwell) a share of the change keeps arriving: the \
         magnetic after-effect of steel, the creep of a piezo stack. The core output v is the equilibrium and \
         y = v + fraction * sum_i w_i (x_i - v) with x_i first-order lags of v, time constants spaced evenly in \
         log(tau) from tau_min_s to tau_max_s (equal weights: creep logarithmic in time between them). \
         Unbounded form (magnetic viscosity: thermally activated switching over a flat spectrum of barrier \
         energies): a fluctuation field pushes the core input the way it last moved, by \
         fluctuation * ln(1 + t/tau0_s) with t the time since the input last turned, so the output moves by the \
         branch's differential slope times it (S = slope * fluctuation per e-fold of time) and never settles \
         within a run; it starts again from zero when the input turns. \
         Signature: after each reversal or dwell the residual relaxes with log(time since it).",
        [p("fraction", "1", 0.02, 0.0, 0.9, "share of every output change that arrives by relaxation"),
         p("tau_min_s", "s", 0.1, 1e-4, 1e5, "shortest relaxation time"),
         p("tau_max_s", "s", 100.0, 1e-4, 1e6, "longest relaxation time (tau_min_s..tau_max_s: log-uniform)"),
         p("fluctuation", "A", 0.0, 0.0, 1e3,
           "thermal fluctuation field of the log-time after-effect, per e-fold of time (input units; 0 = off)"),
         p("tau0_s", "s", 0.05, 1e-4, 1e3,
           "onset of the log-time after-effect: it grows as ln(1 + t/tau0_s)")];
    RateDependence = "rate_dependence", Current,
        stage(3, PERIOD, "core input and its last value (input units), last core output, relative slope"),
        NO_ANGLE,
        "The loop widens with the input rate: a dynamic field opposes the change of the material's state (eddy \
         currents in solid steel, domain-wall damping), u_core = u - k dy/dt. The core input lags the applied \
         input with a time constant tau_s * s / s_ref that follows the differential slope s of the branch \
         (s_ref: the major loop's mean slope), so steep branches lag and saturated ones do not. Signature: loop \
         widening with rate that grows with the local slope, unlike coil_lag (one time constant) or time_delay.",
        [p("tau_s", "s", 0.005, 0.0, 10.0, "dynamic-field time constant at the reference slope")];
    RunGainOffset = "run_gain_offset", Sensor, NOT_IN_LOOP, NO_ANGLE,
        "The calibration changes between recordings (runs, days): each run's measured output is \
         gain_k * y + offset_k with gain_k and offset_k drawn around 1 and 0 with spreads gain_sd and offset_sd \
         (a measurement effect). Signature: per-run scale and offset of the residual.",
        [p("gain_sd", "1", 0.02, 0.0, 0.5, "standard deviation of the per-run gain"),
         p("offset_sd", "N·mm", 3.0, 0.0, 1e6, "standard deviation of the per-run offset (output units)")];
    Leakage = "leakage", Sensor, NOT_IN_LOOP, NO_ANGLE,
        "The measured output integrates the input: a leakage current through the sample into a charge \
         amplifier (ferroelectric, charge measurements) adds rate_per_s * q, q the charge from the start of \
         the run, q' = u - decay_per_s * q (the amplifier's feedback discharges it; 0: an ideal integrator, \
         q = integral of u dt). Signature: a residual that follows that charge in every recording.",
        [p("rate_per_s", "N·mm/(A·s)", 1.0, -1e6, 1e6, "output added per unit of input-time (output/(input·s))"),
         p("decay_per_s", "1/s", 0.0, 0.0, 10.0,
           "rate at which the charge amplifier's feedback discharges the integral (1/its time constant)")];
    Accommodation = "accommodation", Field,
        stage(7, NO_PERIOD, "reversal memory (input, output units) and the shift (output units)"), NO_ANGLE,
        "Minor loops drift over repeated cycling between the same extremes (accommodation, reptation): once the \
         input has reversed twice since a saturation, the output carries a shift that relaxes, per loop cycle, \
         towards -kappa * (loop centre - output-range centre), settling in `cycles` cycles; a saturation wipes \
         it out. Signature: repeated minor loops that do not close, drifting towards the middle.",
        [p("kappa", "1", 0.05, -0.9, 0.9, "share of the loop centre's distance from the middle it drifts"),
         p("cycles", "1", 3.0, 0.1, 1e4, "loop cycles to settle (e-folding)")];
    Viscous = "viscous", Field, stage(4, PERIOD, "the core input of the last sample (input units)"), NO_ANGLE,
        "A loss of the input's rate adds to the hysteretic core's output, in the Bingham form \
         y = H(u) + c * du/dt + f_y * tanh((du/dt) / v0): a viscous part in proportion to the rate (the shear of an \
         MR fluid driven by a displacement, the damping of a stage) and a yield part that takes the sign of the \
         motion once the rate passes v0 (the yield stress of the fluid: a smooth Coulomb force), independent of \
         the loop's local slope. The compensator solves the one-step implicit (backward Euler) equation \
         H(u_k) + c r + f_y tanh(r / v0) = y_ref, r = (u_k - u_(k-1)) / dt, instead of differencing the \
         command; its left side rises with u_k. A loss never feeds energy in: c >= 0, f_y >= 0 (0 = no yield \
         part). Signature: loop width that grows with the drive rate across runs of different speed, the same \
         on steep and saturated branches; a time shift (time_delay, coil_lag) does not explain it, as it moves \
         the loop tips too.",
        [p("c", "N·mm·s/A", 4.0, 0.0, 1e9,
           "output per unit of input rate (output units per input unit per second; 0 = off)"),
         p("f_y", "N·mm", 0.0, 0.0, 1e9,
           "yield output the loss tends to at rates well above v0 (output units; 0 = off)"),
         p("v0", "A/s", 1.0, 1e-9, 1e9,
           "input rate at which the yield part reaches tanh(1) = 0.76 of f_y (input units per second)")];
}

/// Entries of a model file's `extensions` list that are not physical effects.
pub static MODEL_ENTRIES: &[EffectSpec] = &[
    EffectSpec {
        name: "core_tables",
        acts: Acts::Field,
        stage: stage(0, NO_PERIOD, ""),
        on_angle: NO_ANGLE,
        doc: "The hysteretic core's own first-order curve tables (refined by least squares, or identified \
              again under the field effects); they replace the model's tables.",
        params: &[],
    },
    EffectSpec {
        name: "table_resolution",
        acts: Acts::Field,
        stage: NOT_IN_LOOP,
        on_angle: NO_ANGLE,
        doc: "Not physics: the first-order curve tables were too coarse or noisy and were refined (the refined \
              tables are the core_tables entry).",
        params: &[p(
            "n_intervals",
            "1",
            40.0,
            1.0,
            1e4,
            "input intervals of the refined tables",
        )],
    },
    EffectSpec {
        name: "learned_discrepancy",
        acts: Acts::Sensor,
        stage: NOT_IN_LOOP,
        on_angle: NO_ANGLE,
        doc: "A term no named effect explains, learned by sparse regression of the residual on signals of the run \
              (its `terms`: signal names of bmr._core.CANDIDATES with coefficients in the declared units, an \
              `intercept` and the reversal `deadband`); added to the predicted output, never compensated.",
        params: &[],
    },
    EffectSpec {
        name: "offset",
        acts: Acts::Sensor,
        stage: NOT_IN_LOOP,
        on_angle: NO_ANGLE,
        doc: "Constant torque-sensor offset fitted by the diagnosis (measurement only).",
        params: &[p("offset_nmm", "N·mm", 0.0, -1e6, 1e6, "sensor offset")],
    },
];

impl EffectKind {
    pub fn spec(self) -> &'static EffectSpec {
        &SPECS[self as usize]
    }
    pub fn name(self) -> &'static str {
        self.spec().name
    }
    pub fn doc(self) -> &'static str {
        self.spec().doc
    }
    pub fn params(self) -> &'static [ParamSpec] {
        self.spec().params
    }
    pub fn acts(self) -> Acts {
        self.spec().acts
    }
    /// Its compensator stage is built for a sample period.
    pub fn needs_period(self) -> bool {
        self.spec().stage.is_some_and(|s| s.needs_period)
    }
    /// The effect named `name`, if the vocabulary has one.
    pub fn from_name(name: &str) -> Option<EffectKind> {
        EffectKind::ALL.into_iter().find(|k| k.name() == name)
    }
}

impl fmt::Display for EffectKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The entries of a model file the compensator undoes (effects and [`MODEL_ENTRIES`]), in loop order (command
/// side first).
pub fn loop_stages() -> impl Iterator<Item = &'static EffectSpec> {
    (0..=u8::MAX).filter_map(|order| {
        SPECS
            .iter()
            .chain(MODEL_ENTRIES)
            .find(|s| s.stage.is_some_and(|st| st.order == order))
    })
}

/// The spec of a model-file extension entry: an effect or one of [`MODEL_ENTRIES`].
pub fn extension_spec(name: &str) -> Option<&'static EffectSpec> {
    SPECS.iter().chain(MODEL_ENTRIES).find(|s| s.name == name)
}

/// Writes `names` separated by ", ".
pub struct NameList<'a>(pub &'a [EffectSpec]);

impl fmt::Display for NameList<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, s) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            f.write_str(s.name)?;
        }
        Ok(())
    }
}

/// Why a set of parameter values was refused. The message names the effect, the parameter and the valid ones.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParamError<'a> {
    /// The effect has no parameter of this name.
    Unknown {
        effect: &'static EffectSpec,
        key: &'a str,
    },
    /// The value is outside the documented range (or not a whole number where one is needed).
    OutOfRange {
        effect: &'static EffectSpec,
        param: &'static ParamSpec,
        value: f64,
    },
}

impl fmt::Display for ParamError<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ParamError::Unknown { effect, key } => {
                write!(
                    f,
                    "effect {} has no parameter {key:?}; its parameters: ",
                    effect.name
                )?;
                for (i, s) in effect.params.iter().enumerate() {
                    write!(f, "{}{}", if i == 0 { "" } else { ", " }, s.name)?;
                }
                Ok(())
            }
            ParamError::OutOfRange {
                effect,
                param,
                value,
            } => {
                let in_range = value.is_finite() && value >= param.min && value <= param.max;
                if in_range && param.smallest_nonzero > 0.0 && value != 0.0 {
                    write!(
                        f,
                        "effect {}: {} = {value} {} must be 0 (automatic) or at least {} in magnitude",
                        effect.name, param.name, param.unit, param.smallest_nonzero
                    )
                } else if param.whole && in_range {
                    write!(
                        f,
                        "effect {}: {} = {value} must be a whole number in {}..{}",
                        effect.name, param.name, param.min, param.max
                    )
                } else {
                    write!(
                        f,
                        "effect {}: {} = {value} {} is outside [{}, {}]",
                        effect.name, param.name, param.unit, param.min, param.max
                    )
                }
            }
        }
    }
}

/// Validated parameter values of one effect (or model entry), in the order of its spec; a plain copy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    pub spec: &'static EffectSpec,
    values: [f64; MAX_PARAMS],
}

impl Params {
    /// The defaults of `spec` overridden by `(key, value)` pairs; unknown keys and values outside the
    /// documented range are errors.
    pub fn new<'a>(
        spec: &'static EffectSpec,
        given: &[(&'a str, f64)],
    ) -> Result<Params, ParamError<'a>> {
        let mut values = [0.0; MAX_PARAMS];
        for (v, s) in values.iter_mut().zip(spec.params) {
            *v = s.default;
        }
        for &(key, value) in given {
            let Some(i) = spec.param_index(key) else {
                return Err(ParamError::Unknown { effect: spec, key });
            };
            let param = &spec.params[i];
            if !param.accepts(value) {
                return Err(ParamError::OutOfRange {
                    effect: spec,
                    param,
                    value,
                });
            }
            values[i] = value;
        }
        Ok(Params { spec, values })
    }

    /// The defaults of `spec`.
    pub fn defaults(spec: &'static EffectSpec) -> Params {
        match Params::new(spec, &[]) {
            Ok(p) => p,
            Err(_) => unreachable!("the vocabulary's defaults are in range"),
        }
    }

    /// Values in the order of `spec.params`.
    pub fn values(&self) -> &[f64] {
        &self.values[..self.spec.params.len()]
    }

    /// The value of parameter `name` (None if the effect has no such parameter).
    pub fn get(&self, name: &str) -> Option<f64> {
        self.spec.param_index(name).map(|i| self.values[i])
    }

    /// `(name, value)` pairs in spec order.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, f64)> + '_ {
        self.spec
            .params
            .iter()
            .map(|s| s.name)
            .zip(self.values())
            .map(|(n, &v)| (n, v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_default_is_in_range_and_names_are_unique() {
        assert!(SPECS.len() == EffectKind::ALL.len());
        for (i, k) in EffectKind::ALL.into_iter().enumerate() {
            assert_eq!(k as usize, i);
            assert_eq!(EffectKind::from_name(k.name()), Some(k));
            assert!(k.params().len() <= MAX_PARAMS);
            for s in k.params() {
                assert!(s.accepts(s.default), "{}.{}", k.name(), s.name);
            }
        }
        let names: Vec<&str> = SPECS.iter().chain(MODEL_ENTRIES).map(|s| s.name).collect();
        for (i, n) in names.iter().enumerate() {
            assert!(!names[i + 1..].contains(n), "{n} twice");
        }
        for s in MODEL_ENTRIES {
            assert!(s.params.len() <= MAX_PARAMS);
            Params::defaults(s);
        }
    }

    #[test]
    fn loop_orders_are_unique_and_only_compensated_effects_have_one() {
        let with_stage = SPECS
            .iter()
            .chain(MODEL_ENTRIES)
            .filter(|s| s.stage.is_some())
            .count();
        assert_eq!(loop_stages().count(), with_stage, "a loop order used twice");
        for s in SPECS {
            if s.acts == Acts::Sensor {
                assert!(s.stage.is_none(), "{} acts on the measurement only", s.name);
            }
        }
        let first = loop_stages().next().unwrap();
        assert_eq!(first.name, "core_tables");
    }

    #[test]
    fn params_validate_and_name_the_problem() {
        let lag = EffectKind::CoilLag.spec();
        let p = Params::new(lag, &[("tau_s", 0.05)]).unwrap();
        assert_eq!(p.get("tau_s"), Some(0.05));
        let e = Params::new(lag, &[("tau", 1.0)]).unwrap_err().to_string();
        assert!(e.contains("its parameters: tau_s"), "{e}");
        let e = Params::new(lag, &[("tau_s", -1.0)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("outside"), "{e}");
        let h = EffectKind::FrictionHarmonics.spec();
        let e = Params::new(h, &[("order", 4.5)]).unwrap_err().to_string();
        assert!(e.contains("whole number"), "{e}");
        assert!(Params::new(h, &[("order", f64::NAN)]).is_err());
        assert_eq!(extension_spec("offset").unwrap().name, "offset");
        assert!(extension_spec("nope").is_none());
    }
}
