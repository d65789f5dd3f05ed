//! `step` never allocates: a counting global allocator watches a long random run.
mod common;

use bmr::{BuildOptions, Hysteresis, Initial};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;
static ALLOCS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    // Only the thread under test counts (the test harness runs tests on parallel threads).
    static WATCHED: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        if WATCHED.with(|w| w.get()) {
            ALLOCS.fetch_add(1, Ordering::SeqCst);
        }
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn hysteresis_step_does_not_allocate() {
    let (asc, desc) = common::measure_first_order(60, 13);
    let mut h = Hysteresis::<Vec<f64>, 8>::from_curve_data(
        &asc,
        &desc,
        &BuildOptions::default(),
        Initial::Negative,
    )
    .unwrap();
    let inputs = common::random_history(&mut common::Rng(3), 2000, 9);
    WATCHED.with(|w| w.set(true));
    let before = ALLOCS.load(Ordering::SeqCst);
    let mut acc = 0.0;
    for &u in &inputs {
        acc += h.step(u); // overflows the 8-point memory: merges must not allocate either
    }
    let snap = h.snapshot();
    h.restore(&snap).unwrap();
    let after = ALLOCS.load(Ordering::SeqCst);
    WATCHED.with(|w| w.set(false));
    assert!(acc.is_finite());
    assert_eq!(after - before, 0, "step allocated {} times", after - before);
}

#[test]
fn compensator_step_does_not_allocate() {
    let (asc, desc) = common::measure_first_order(60, 13);
    let fwd = Hysteresis::<Vec<f64>, 8>::from_curve_data(
        &asc,
        &desc,
        &BuildOptions::default(),
        Initial::Negative,
    )
    .unwrap();
    let paper = bmr::InverseKind::Paper(fwd.paper_inverse().unwrap());
    let f =
        bmr::Friction::<12>::from_coefficients(5.0, &[10.0, 3.0, 1.0], &[2.0, 1.0, 0.5]).unwrap();
    let mut exact =
        bmr::Compensator::new(fwd.clone(), bmr::InverseKind::Exact, f, 0.125, 1.25).unwrap();
    let mut paper = bmr::Compensator::new(fwd, paper, f, 0.125, 1.25).unwrap();
    let refs = common::random_history(&mut common::Rng(8), 2000, 9);
    WATCHED.with(|w| w.set(true));
    let before = ALLOCS.load(Ordering::SeqCst);
    let mut acc = 0.0;
    for (i, &r) in refs.iter().enumerate() {
        let th = 0.01 * i as f64;
        acc += exact.step(280.0 * r, th).current_a + paper.step(280.0 * r, th).current_a;
        acc += exact.step(f64::NAN, th).current_a;
    }
    let after = ALLOCS.load(Ordering::SeqCst);
    WATCHED.with(|w| w.set(false));
    assert!(acc.is_finite());
    assert_eq!(
        after - before,
        0,
        "Compensator::step allocated {} times",
        after - before
    );
}

#[test]
fn extended_compensator_step_does_not_allocate() {
    use bmr::vocabulary::{EffectKind, Params};
    let (asc, desc) = common::measure_first_order(60, 13);
    let fwd = Hysteresis::<Vec<f64>, 8>::from_curve_data(
        &asc,
        &desc,
        &BuildOptions::default(),
        Initial::Negative,
    )
    .unwrap();
    let p = |k: EffectKind, v: &[(&'static str, f64)]| Params::new(k.spec(), v).unwrap();
    // Every stage the compensator has.
    let effects = [
        p(EffectKind::CoilLag, &[("tau_s", 0.02)]),
        p(EffectKind::TimeDelay, &[("delay_s", 0.01)]),
        p(
            EffectKind::ThermalDrift,
            &[("gain_loss", 0.1), ("tau_s", 30.0)],
        ),
        p(EffectKind::TorqueRipple, &[("eps", 0.05)]),
        p(
            EffectKind::NonCongruent,
            &[("curvature", 1.5), ("cubic", 0.5), ("feedback", 0.05)],
        ),
        p(EffectKind::FrictionCurrent, &[("gain_per_a", 0.4)]),
        p(EffectKind::FrictionHarmonics, &[("order", 7.0)]),
        p(
            EffectKind::Creep,
            &[("fraction", 0.05), ("fluctuation", 0.003)],
        ),
        p(EffectKind::RateDependence, &[("tau_s", 0.005)]),
        p(EffectKind::Accommodation, &[("kappa", 0.1)]),
        p(EffectKind::Viscous, &[("c", 2.0)]),
    ];
    let f =
        bmr::Friction::<24>::from_coefficients(5.0, &[10.0, 3.0, 1.0], &[2.0, 1.0, 0.5]).unwrap();
    let paper = bmr::InverseKind::Paper(fwd.paper_inverse().unwrap());
    let mut exact = bmr::Compensator::new(fwd.clone(), bmr::InverseKind::Exact, f, 0.125, 1.25)
        .unwrap()
        .with_extensions(&effects, 0.002, 300.0)
        .unwrap();
    let mut paper = bmr::Compensator::new(fwd, paper, f, 0.125, 1.25)
        .unwrap()
        .with_extensions(&effects, 0.002, 300.0)
        .unwrap();
    let refs = common::random_history(&mut common::Rng(9), 2000, 9);
    let thetas: Vec<f64> = (0..refs.len()).map(|i| 0.01 * i as f64).collect();
    let scaled: Vec<f64> = refs.iter().map(|r| 280.0 * r).collect();
    WATCHED.with(|w| w.set(true));
    let before = ALLOCS.load(Ordering::SeqCst);
    let mut acc = 0.0;
    for (i, &r) in scaled.iter().enumerate() {
        let th = thetas[i];
        acc += exact.step(r, th).current_a + paper.step(r, th).current_a;
        acc += exact.step_ahead(r, th).current_a;
        acc += exact.step(f64::NAN, th).current_a;
    }
    let snap = exact.snapshot();
    exact.restore(&snap).unwrap();
    exact.run_with(&scaled, &thetas, |_, c, _| acc += c.current_a);
    let after = ALLOCS.load(Ordering::SeqCst);
    WATCHED.with(|w| w.set(false));
    // The closed loop around it: measurements, dropouts (to a fault), saturation, snapshot/restore.
    let settings = bmr::ControllerSettings {
        fault_after: 5,
        ..Default::default()
    };
    let mut ctl = bmr::Controller::new(exact, 0.002, settings).unwrap();
    WATCHED.with(|w| w.set(true));
    let before_loop = ALLOCS.load(Ordering::SeqCst);
    let mut y = f64::NAN;
    for (i, &r) in scaled.iter().enumerate() {
        let measured = if i % 50 < 8 { f64::NAN } else { y };
        let r = if i % 300 < 20 { 5000.0 } else { r };
        let c = if i % 2 == 0 {
            ctl.step(r, thetas[i], measured)
        } else {
            ctl.step_with_sincos(r, thetas[i], measured, bmr::trig::sincos(thetas[i]))
        };
        y = 0.9 * ctl.compensator().model_torque_nmm() + 2.0;
        acc += c.current_a;
    }
    let snap = ctl.snapshot();
    ctl.restore(&snap).unwrap();
    let after_loop = ALLOCS.load(Ordering::SeqCst);
    WATCHED.with(|w| w.set(false));
    assert_eq!(
        after_loop - before_loop,
        0,
        "Controller::step allocated {} times",
        after_loop - before_loop
    );
    assert!(acc.is_finite());
    assert_eq!(
        after - before,
        0,
        "extended Compensator::step allocated {} times",
        after - before
    );
}
