//! Links the bmr real-time core into a `#![no_std]` static library with no global allocator: a CBH operator on
//! static tables, stepped, a compensator (exact inverse + friction) on it, the extended compensator of an exported
//! model (`model.rs`, written by `bmr export`), the closed-loop controller around it and the C ABI
//! (`bmr_compensator_*`, header `include/bmr.h`). If anything in that path needed `std` or `alloc`, this would
//! not build.
#![no_std]

use bmr::{
    Compensator, Controller, ControllerSettings, Family, FamilyKind, Friction, Hysteresis, Initial,
    InverseKind,
};
use core::panic::PanicInfo;

// The C ABI, linked into the static library.
pub use bmr::ffi::*;

include!("model.rs");

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    loop {}
}

// Three-node tables: grid | reversals | rows (rising orientation; see bmr::everett).
static ASC: [f64; 3 + 2 + 6] = [-1.0, 0.0, 1.0, -1.0, 0.0, 0.0, 1.0, 2.0, 0.0, 0.0, 1.0];
static DESC: [f64; 3 + 2 + 6] = [-1.0, 0.0, 1.0, -1.0, 0.0, 0.0, 1.0, 2.0, 0.0, 0.0, 1.0];

/// Step a fresh operator through `n` inputs of `inputs` and return the last output plus friction at `theta`.
///
/// # Safety
/// `inputs` must point to `n` readable `f64`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bmr_nostd_demo(inputs: *const f64, n: usize, theta: f64) -> f64 {
    let asc = match Family::new(&ASC[..], 3, 2, FamilyKind::Ascending) {
        Ok(f) => f,
        Err(_) => return f64::NAN,
    };
    let desc = match Family::new(&DESC[..], 3, 2, FamilyKind::Descending) {
        Ok(f) => f,
        Err(_) => return f64::NAN,
    };
    let Ok(mut h) = Hysteresis::<_, 8>::new(asc, desc, -1.0, 1.0, Initial::Negative) else {
        return f64::NAN;
    };
    let inputs = unsafe { core::slice::from_raw_parts(inputs, n) };
    let mut y = 0.0;
    for &u in inputs {
        y = h.step(u);
    }
    let f = Friction::<12>::from_coefficients(1.0, &[0.5], &[0.25]).unwrap_or(Friction::zero());
    let Ok(mut c) = Compensator::new(h, InverseKind::Exact, f, 0.125, 1.25) else {
        return f64::NAN;
    };
    let cmd = c.step(0.5, theta);
    y + cmd.current_a + cmd.volt2_v
}

/// One step of the exported extended model's compensator (every stage on) at a 2 ms control period: the
/// commanded current, NaN if the model does not build.
#[unsafe(no_mangle)]
pub extern "C" fn bmr_nostd_model_demo(torque_ref_nmm: f64, theta_rad: f64) -> f64 {
    match model::compensator(0.002) {
        Ok(mut c) => c.step(torque_ref_nmm, theta_rad).current_a,
        Err(_) => f64::NAN,
    }
}

/// Closed loop around the exported model's compensator at a 2 ms control period: `n` steps towards
/// `torque_ref_nmm`, each measuring `gain` times the torque the model predicted; the last commanded current (NaN
/// if the model or the controller does not build).
#[unsafe(no_mangle)]
pub extern "C" fn bmr_nostd_controller_demo(torque_ref_nmm: f64, gain: f64, n: usize) -> f64 {
    let Ok(c) = model::compensator(0.002) else {
        return f64::NAN;
    };
    let Ok(mut ctl) = Controller::new(c, 0.002, ControllerSettings::default()) else {
        return f64::NAN;
    };
    let mut measured = f64::NAN;
    let mut current = 0.0;
    for i in 0..n {
        current = ctl
            .step(torque_ref_nmm, 0.001 * i as f64, measured)
            .current_a;
        measured = gain * ctl.compensator().model_torque_nmm();
    }
    current
}
