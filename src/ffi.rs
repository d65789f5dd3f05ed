//! C ABI of the compensator and the closed-loop controller (feature `ffi`, `no_std`, no allocation):
//! `bmr_compensator_init` builds a compensator from a model's data (as `bmr export MODEL --c OUT.h` writes it)
//! into caller-provided storage, `bmr_compensator_step` runs one control period, `bmr_compensator_reset` returns
//! to the start state, `bmr_compensator_run` drives a whole reference known in advance exactly as Python's
//! `Compensator.run`; `bmr_controller_init` / `bmr_controller_step` do the same for the closed loop around it
//! (`bmr::Controller`). The header `include/bmr.h` is generated from this file by cbindgen.
//!
//! The tables the model points to must stay valid and unchanged for as long as the compensator is used (exported
//! tables are `static const`).
use crate::compensator::{Command, Compensator};
use crate::friction::MAX_ORDER;
use crate::model_data::{EffectValues, MEMORY, ModelData};
use core::mem::{align_of, size_of};

type Inner = Compensator<&'static [f64], MEMORY, MAX_ORDER>;

/// Size of a compensator's storage in 8-byte words.
pub const BMR_COMPENSATOR_WORDS: usize = 6144;
/// Most parameters of one effect (the vocabulary's `MAX_PARAMS`).
pub const BMR_MAX_PARAMS: usize = 5;

const _: () = assert!(size_of::<Inner>() <= 8 * BMR_COMPENSATOR_WORDS);
const _: () = assert!(align_of::<Inner>() <= 8);
const _: () = assert!(BMR_MAX_PARAMS == crate::vocabulary::MAX_PARAMS);

/// Storage for one compensator (opaque; initialise it with `bmr_compensator_init`).
#[repr(C)]
pub struct BmrCompensator {
    words: [u64; BMR_COMPENSATOR_WORDS],
}

/// One extension stage: `kind` is the effect's number in the vocabulary, `values` its parameters in the
/// vocabulary's order (as `bmr export` writes them).
#[repr(C)]
#[derive(Clone, Copy)]
pub struct BmrEffect {
    pub kind: u32,
    pub values: [f64; BMR_MAX_PARAMS],
}

/// A model as `bmr export --c` writes it: tables in the core's layout (grid, reversal inputs, rows), friction,
/// converter gain, current limit, the output map's full scale and the extension stages.
#[repr(C)]
pub struct BmrModel {
    pub ascending: *const f64,
    pub ascending_len: usize,
    pub ascending_nodes: usize,
    pub ascending_curves: usize,
    pub descending: *const f64,
    pub descending_len: usize,
    pub descending_nodes: usize,
    pub descending_curves: usize,
    pub y_lo: f64,
    pub y_hi: f64,
    pub friction_c0: f64,
    pub friction_a: *const f64,
    pub friction_b: *const f64,
    pub friction_order: usize,
    pub converter_gain_a_per_v: f64,
    pub current_limit_a: f64,
    pub full_torque_nmm: f64,
    pub effects: *const BmrEffect,
    pub effects_len: usize,
}

/// One control-period command (see `bmr::Command`).
#[repr(C)]
#[derive(Clone, Copy)]
pub struct BmrCommand {
    pub current_a: f64,
    pub coil1_a: f64,
    pub coil2_a: f64,
    pub volt1_v: f64,
    pub volt2_v: f64,
    pub saturated: bool,
    pub fault: bool,
}

impl From<Command> for BmrCommand {
    fn from(c: Command) -> Self {
        BmrCommand {
            current_a: c.current_a,
            coil1_a: c.coil1_a,
            coil2_a: c.coil2_a,
            volt1_v: c.volt1_v,
            volt2_v: c.volt2_v,
            saturated: c.saturated,
            fault: c.fault,
        }
    }
}

/// `bmr_compensator_init` succeeded.
pub const BMR_OK: i32 = 0;
/// A null pointer where data was needed.
pub const BMR_ERR_NULL: i32 = -1;
/// The tables are not valid CBH tables.
pub const BMR_ERR_TABLE: i32 = -2;
/// The friction coefficients are refused.
pub const BMR_ERR_FRICTION: i32 = -3;
/// Converter gain, current limit or a stage parameter is refused.
pub const BMR_ERR_PARAMETER: i32 = -4;

unsafe fn slice<'a>(p: *const f64, len: usize) -> Option<&'a [f64]> {
    if len == 0 {
        return Some(&[]);
    }
    if p.is_null() {
        return None;
    }
    Some(unsafe { core::slice::from_raw_parts(p, len) })
}

fn code(e: crate::model_data::BuildError) -> i32 {
    use crate::model_data::BuildError::*;
    match e {
        Table(_) => BMR_ERR_TABLE,
        Friction(_) => BMR_ERR_FRICTION,
        Compensator(_) | UnknownEffect { .. } | Param { .. } => BMR_ERR_PARAMETER,
    }
}

/// Build the compensator of `model` at control period `dt_s` (s) into `out`. Returns `BMR_OK` or a negative
/// `BMR_ERR_*` code (then `out` is not a compensator).
///
/// # Safety
/// `out` must point to writable storage; `model` and every array it points to must be valid for reads of the
/// given lengths, and the tables must outlive every use of the compensator.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bmr_compensator_init(
    out: *mut BmrCompensator,
    model: *const BmrModel,
    dt_s: f64,
) -> i32 {
    if out.is_null() {
        return BMR_ERR_NULL;
    }
    match unsafe { build(model, dt_s) } {
        Ok(c) => {
            unsafe { out.cast::<Inner>().write(c) };
            BMR_OK
        }
        Err(code) => code,
    }
}

/// The compensator of `model` at control period `dt_s`, or a `BMR_ERR_*` code.
///
/// # Safety
/// As `bmr_compensator_init`.
unsafe fn build(model: *const BmrModel, dt_s: f64) -> Result<Inner, i32> {
    if model.is_null() {
        return Err(BMR_ERR_NULL);
    }
    let m = unsafe { &*model };
    let (Some(asc), Some(desc), Some(fa), Some(fb)) = (unsafe {
        (
            slice(m.ascending, m.ascending_len),
            slice(m.descending, m.descending_len),
            slice(m.friction_a, m.friction_order),
            slice(m.friction_b, m.friction_order),
        )
    }) else {
        return Err(BMR_ERR_NULL);
    };
    let effects: &[EffectValues] = if m.effects_len == 0 {
        &[]
    } else if m.effects.is_null() {
        return Err(BMR_ERR_NULL);
    } else {
        // BmrEffect and EffectValues have the same repr(C) layout.
        unsafe { core::slice::from_raw_parts(m.effects.cast::<EffectValues>(), m.effects_len) }
    };
    let data = ModelData {
        ascending: asc,
        ascending_nodes: m.ascending_nodes,
        ascending_curves: m.ascending_curves,
        descending: desc,
        descending_nodes: m.descending_nodes,
        descending_curves: m.descending_curves,
        y_lo: m.y_lo,
        y_hi: m.y_hi,
        friction_c0: m.friction_c0,
        friction_a: fa,
        friction_b: fb,
        converter_gain_a_per_v: m.converter_gain_a_per_v,
        current_limit_a: m.current_limit_a,
        full_torque_nmm: m.full_torque_nmm,
        effects,
    };
    data.compensator::<MEMORY, MAX_ORDER>(dt_s).map_err(code)
}

const _: () = assert!(size_of::<BmrEffect>() == size_of::<EffectValues>());

unsafe fn inner<'a>(c: *mut BmrCompensator) -> &'a mut Inner {
    unsafe { &mut *c.cast::<Inner>() }
}

/// One control period: reference torque (N·mm) and rotor angle (rad) → `*out`. Never fails: a NaN/inf input gives
/// zero current with `fault`.
///
/// # Safety
/// `c` must have been initialised by `bmr_compensator_init`; `out` must be writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bmr_compensator_step(
    c: *mut BmrCompensator,
    torque_ref_nmm: f64,
    theta_rad: f64,
    out: *mut BmrCommand,
) {
    let cmd = unsafe { inner(c) }.step(torque_ref_nmm, theta_rad);
    unsafe { out.write(cmd.into()) };
}

/// One control period given the reference and angle of the sample the command acts on (the `time_delay`
/// stage's delay ahead of now).
///
/// # Safety
/// As `bmr_compensator_step`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bmr_compensator_step_ahead(
    c: *mut BmrCompensator,
    torque_ref_ahead_nmm: f64,
    theta_ahead_rad: f64,
    out: *mut BmrCommand,
) {
    let cmd = unsafe { inner(c) }.step_ahead(torque_ref_ahead_nmm, theta_ahead_rad);
    unsafe { out.write(cmd.into()) };
}

/// Samples the reference must be taken ahead by (the `time_delay` stage; 0 without it).
///
/// # Safety
/// `c` must have been initialised by `bmr_compensator_init`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bmr_compensator_preview_samples(c: *mut BmrCompensator) -> usize {
    unsafe { inner(c) }.preview_samples()
}

/// Back to the start state (after negative saturation, stages at rest).
///
/// # Safety
/// `c` must have been initialised by `bmr_compensator_init`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bmr_compensator_reset(c: *mut BmrCompensator) {
    unsafe { inner(c) }.reset(crate::cbh::Initial::Negative);
}

/// Drive `n` samples of a reference known in advance (as Python's `Compensator.run`): `current_a[i]` gets the
/// nominal current commanded at sample `i`.
///
/// # Safety
/// `c` initialised; `torque_ref_nmm` and `theta_rad` readable and `current_a` writable for `n` values.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bmr_compensator_run(
    c: *mut BmrCompensator,
    torque_ref_nmm: *const f64,
    theta_rad: *const f64,
    n: usize,
    current_a: *mut f64,
) {
    if n == 0 || torque_ref_nmm.is_null() || theta_rad.is_null() || current_a.is_null() {
        return;
    }
    let (r, th, out) = unsafe {
        (
            core::slice::from_raw_parts(torque_ref_nmm, n),
            core::slice::from_raw_parts(theta_rad, n),
            core::slice::from_raw_parts_mut(current_a, n),
        )
    };
    unsafe { inner(c) }.run_with(r, th, |i, cmd, _| out[i] = cmd.current_a);
}

type InnerController = crate::controller::Controller<&'static [f64], MEMORY, MAX_ORDER>;

/// Size of a controller's storage in 8-byte words.
pub const BMR_CONTROLLER_WORDS: usize = 6400;

const _: () = assert!(size_of::<InnerController>() <= 8 * BMR_CONTROLLER_WORDS);
const _: () = assert!(align_of::<InnerController>() <= 8);

/// Storage for one closed-loop controller (opaque; initialise it with `bmr_controller_init`).
#[repr(C)]
pub struct BmrController {
    words: [u64; BMR_CONTROLLER_WORDS],
}

/// What the controller is asked for (see `bmr::ControllerSettings`; `bmr_controller_default_settings` fills it
/// with the defaults): bandwidth in Hz (0: automatic), the sensor-noise share, the adaptation memory in s, the
/// missing measurements before a fault, the largest correction in N·mm (0: automatic), feedback and adaptation on.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct BmrControllerSettings {
    pub bandwidth_hz: f64,
    pub noise_share: f64,
    pub adaptation_time_s: f64,
    pub fault_after: u32,
    pub correction_limit_nmm: f64,
    pub feedback: bool,
    pub adaptation: bool,
}

impl From<BmrControllerSettings> for crate::controller::ControllerSettings {
    fn from(s: BmrControllerSettings) -> Self {
        crate::controller::ControllerSettings {
            bandwidth_hz: s.bandwidth_hz,
            noise_share: s.noise_share,
            adaptation_time_s: s.adaptation_time_s,
            fault_after: s.fault_after,
            correction_limit_nmm: s.correction_limit_nmm,
            feedback: s.feedback,
            adaptation: s.adaptation,
        }
    }
}

/// The default controller settings.
#[unsafe(no_mangle)]
pub extern "C" fn bmr_controller_default_settings() -> BmrControllerSettings {
    let d = crate::controller::ControllerSettings::default();
    BmrControllerSettings {
        bandwidth_hz: d.bandwidth_hz,
        noise_share: d.noise_share,
        adaptation_time_s: d.adaptation_time_s,
        fault_after: d.fault_after,
        correction_limit_nmm: d.correction_limit_nmm,
        feedback: d.feedback,
        adaptation: d.adaptation,
    }
}

/// Build the closed-loop controller around the compensator of `model` at control period `dt_s` (s) into `out`
/// (`settings` null: the defaults). Returns `BMR_OK` or a negative `BMR_ERR_*` code (then `out` is not a
/// controller).
///
/// # Safety
/// As `bmr_compensator_init`; `settings` null or readable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bmr_controller_init(
    out: *mut BmrController,
    model: *const BmrModel,
    dt_s: f64,
    settings: *const BmrControllerSettings,
) -> i32 {
    if out.is_null() {
        return BMR_ERR_NULL;
    }
    let settings = if settings.is_null() {
        crate::controller::ControllerSettings::default()
    } else {
        unsafe { *settings }.into()
    };
    let c = match unsafe { build(model, dt_s) } {
        Ok(c) => c,
        Err(code) => return code,
    };
    match crate::controller::Controller::new(c, dt_s, settings) {
        Ok(ctl) => {
            unsafe { out.cast::<InnerController>().write(ctl) };
            BMR_OK
        }
        Err(_) => BMR_ERR_PARAMETER,
    }
}

unsafe fn controller<'a>(c: *mut BmrController) -> &'a mut InnerController {
    unsafe { &mut *c.cast::<InnerController>() }
}

/// One control period: reference torque (N·mm) and rotor angle (rad) of this sample, the torque measured at the
/// previous sample (N·mm; NaN/inf: none) → `*out`. Never fails.
///
/// # Safety
/// `c` must have been initialised by `bmr_controller_init`; `out` must be writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bmr_controller_step(
    c: *mut BmrController,
    reference_nmm: f64,
    theta_rad: f64,
    measured_nmm: f64,
    out: *mut BmrCommand,
) {
    let cmd = unsafe { controller(c) }.step(reference_nmm, theta_rad, measured_nmm);
    unsafe { out.write(cmd.into()) };
}

/// The adapted output gain and offset (N·mm) and the integral correction (N·mm), written to the non-null
/// pointers.
///
/// # Safety
/// `c` initialised; each pointer null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bmr_controller_estimates(
    c: *mut BmrController,
    gain: *mut f64,
    offset_nmm: *mut f64,
    correction_nmm: *mut f64,
) {
    let ctl = unsafe { controller(c) };
    for (p, v) in [
        (gain, ctl.gain()),
        (offset_nmm, ctl.offset_nmm()),
        (correction_nmm, ctl.correction_nmm()),
    ] {
        if !p.is_null() {
            unsafe { p.write(v) };
        }
    }
}

/// Hold the adapted gain and offset (`frozen` true) or let them adapt again.
///
/// # Safety
/// `c` must have been initialised by `bmr_controller_init`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bmr_controller_freeze_adaptation(c: *mut BmrController, frozen: bool) {
    unsafe { controller(c) }.freeze_adaptation(frozen);
}

/// Back to the start state (compensator after negative saturation, correction 0, gain 1, offset 0).
///
/// # Safety
/// `c` must have been initialised by `bmr_controller_init`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bmr_controller_reset(c: *mut BmrController) {
    unsafe { controller(c) }.reset(crate::cbh::Initial::Negative);
}
