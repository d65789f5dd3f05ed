//! Virtual actuator: determinism, safe handling of bad commands, physics magnitudes, preset calibration.
use bmr::plant::effects::{Effect, EffectKind};
use bmr::plant::presets::{bmr2013, ideal};
use bmr::plant::{PlantError, VirtualActuator, preset};

fn excitation(n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| 1.3 * (k as f64 * 1.7e-3).sin() * (k as f64 * 3.1e-4).cos())
        .collect()
}

#[test]
fn same_seed_is_bit_identical_and_seed_only_changes_noise() {
    let u = excitation(50_000);
    let a = VirtualActuator::new(bmr2013(), 42).unwrap().run(&u);
    let b = VirtualActuator::new(bmr2013(), 42).unwrap().run(&u);
    assert_eq!(a, b);
    let c = VirtualActuator::new(bmr2013(), 43).unwrap().run(&u);
    assert_eq!(a.torque_true_nmm, c.torque_true_nmm);
    assert_eq!(a.theta_rad, c.theta_rad);
    assert_ne!(a.torque_nmm, c.torque_nmm);
}

#[test]
fn reset_replays_the_same_run() {
    let u = excitation(10_000);
    let mut act = VirtualActuator::new(bmr2013(), 1).unwrap();
    let first = act.run(&u);
    act.reset();
    assert_eq!(act.time_s(), 0.0);
    assert_eq!(act.run(&u), first);
}

#[test]
fn non_finite_command_applies_zero_current_and_is_flagged() {
    let mut act = VirtualActuator::new(bmr2013(), 0).unwrap();
    act.step(0.8);
    let s = act.step(f64::NAN);
    assert!(!s.command_valid);
    assert_eq!(s.current_cmd_a, 0.0);
    assert_eq!((s.coil1_a, s.coil2_a), (0.0, 0.0));
    assert!(s.torque_nmm.is_finite());
    let s = act.step(f64::INFINITY);
    assert!(!s.command_valid && s.torque_nmm.is_finite());
    assert!(act.step(0.1).command_valid);
}

#[test]
fn viscous_drag_is_small_and_cancels_between_the_rotors() {
    let mut act = VirtualActuator::new(bmr2013(), 0).unwrap();
    let s = act.step(0.0);
    // Bingham viscous torque of one rotor at 1 rev/s: well under a N·mm, against ±600 N·mm of field torque.
    assert!(
        s.viscous_nmm > 0.05 && s.viscous_nmm < 1.0,
        "{}",
        s.viscous_nmm
    );
    let mut ideal_act = VirtualActuator::new(ideal(), 0).unwrap();
    assert_eq!(ideal_act.step(0.0).viscous_nmm, 0.0);
}

#[test]
fn bmr2013_calibration() {
    let mut act = VirtualActuator::new(bmr2013(), 0).unwrap();
    let ramp = |a: f64, b: f64, n: usize| (1..=n).map(move |k| a + (b - a) * k as f64 / n as f64);
    let u: Vec<f64> = ramp(0.0, 1.25, 2500)
        .chain(ramp(1.25, -1.25, 5000))
        .collect();
    let t = act.run(&u);
    let pos = t.field_torque_nmm[2499];
    let neg = *t.field_torque_nmm.last().unwrap();
    assert!((540.0..660.0).contains(&pos), "{pos}");
    assert!((-660.0..-540.0).contains(&neg), "{neg}");
    let f: Vec<f64> = (0..720)
        .map(|k| act.true_friction_nmm(k as f64 * std::f64::consts::TAU / 720.0))
        .collect();
    let (lo, hi) = f
        .iter()
        .fold((f64::MAX, f64::MIN), |(l, h), &v| (l.min(v), h.max(v)));
    assert!(
        (-25.0..-15.0).contains(&lo) && (45.0..55.0).contains(&hi),
        "{lo} {hi}"
    );
}

#[test]
fn presets_and_effects_by_name() {
    assert!(matches!(preset("nope"), Err(PlantError::UnknownPreset(_))));
    let act = VirtualActuator::from_preset(
        "bmr2013",
        500.0,
        &[Effect::parse("time_delay:delay_s=0.02").unwrap()],
        0,
    )
    .unwrap();
    let fx = &act.config().effects;
    assert_eq!(fx.len(), 2);
    assert_eq!(
        fx.get(EffectKind::TimeDelay),
        Some(&Effect::TimeDelay { delay_s: 0.02 })
    );
    let mut bad = bmr2013();
    bad.sample_rate_hz = -1.0;
    let e = VirtualActuator::new(bad, 0).unwrap_err().to_string();
    assert!(e.contains("sample_rate_hz"), "{e}");
    let mut bad = bmr2013();
    bad.steel2.grid = 3;
    assert!(
        VirtualActuator::new(bad, 0)
            .unwrap_err()
            .to_string()
            .contains("steel2.grid")
    );
}

#[test]
fn throughput_is_over_a_million_samples_per_second_in_release() {
    // Measured in release builds only (debug builds are ~20x slower); `cargo bench --bench plant` reports it.
    if cfg!(debug_assertions) {
        return;
    }
    let u = excitation(2_000_000);
    let mut act = VirtualActuator::new(bmr2013(), 0).unwrap();
    let t0 = std::time::Instant::now();
    let trace = act.run(&u);
    let rate = u.len() as f64 / t0.elapsed().as_secs_f64();
    assert_eq!(trace.len(), u.len());
    assert!(rate > 1e6, "{rate} samples/s");
}
