//! The closed-loop controller on a plant that differs from its model: the extended simulation of the same tables
//! with a different coil lag and delay, a heating the model does not hold, a sensor gain and offset, noise and
//! dropouts. Tracking stays bounded, the integrator does not wind up, the fault comes when it should, the
//! adaptation finds a hidden gain, and the state replays bit for bit.
mod common;

use bmr::simulation::Simulation;
use bmr::stages::Scales;
use bmr::vocabulary::{EffectKind, Params};
use bmr::{
    BuildOptions, Compensator, Controller, ControllerError, ControllerSettings, Friction,
    Hysteresis, Initial, InverseKind,
};

const DT: f64 = 0.002;
const NOISE_NMM: f64 = 1.5;
type Ctl = Controller<Vec<f64>, 16, 24>;

fn forward() -> Hysteresis<Vec<f64>, 16> {
    let (a, d) = common::measure_first_order(40, 9);
    let scale = |c: &Vec<common::Curve>| -> Vec<common::Curve> {
        c.iter()
            .map(|(u, y)| (u.iter().map(|x| 1.25 * x).collect(), y.clone()))
            .collect()
    };
    Hysteresis::from_curve_data(
        &scale(&a),
        &scale(&d),
        &BuildOptions::default(),
        Initial::Negative,
    )
    .unwrap()
}

fn friction() -> Friction<24> {
    Friction::from_amplitude_phase(12.0, &[25.0, 8.0, 4.0], &[0.3, 1.1, -0.7]).unwrap()
}

fn p(k: EffectKind, v: &[(&'static str, f64)]) -> Params {
    Params::new(k.spec(), v).unwrap()
}

/// The model's stages: a 20 ms coil lag and a 2-sample delay.
fn model_effects(lag_s: f64, delay_samples: f64) -> Vec<Params> {
    vec![
        p(EffectKind::CoilLag, &[("tau_s", lag_s)]),
        p(EffectKind::TimeDelay, &[("delay_s", delay_samples * DT)]),
    ]
}

fn controller(settings: ControllerSettings) -> Ctl {
    let c = Compensator::new(forward(), InverseKind::Exact, friction(), 0.125, 1.25)
        .unwrap()
        .with_extensions(&model_effects(0.02, 2.0), DT, 300.0)
        .unwrap();
    Controller::new(c, DT, settings).unwrap()
}

/// How the plant differs from the model.
#[derive(Clone, Copy)]
struct Plant {
    gain: f64,
    /// Gain from the middle of the run on (a linear drift from `gain` over the first half).
    gain_end: f64,
    offset_nmm: f64,
    lag_s: f64,
    delay_samples: f64,
    /// Heating the model does not hold: field-gain loss at full current and its time constant.
    heating: (f64, f64),
}

const NOMINAL: Plant = Plant {
    gain: 1.0,
    gain_end: 1.0,
    offset_nmm: 3.0,
    lag_s: 0.02,
    delay_samples: 2.0,
    heating: (0.1, 5.0),
};

/// A multi-peak reference within ±220 N·mm (the tables reach ±300).
fn reference(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let t = i as f64 * DT;
            160.0 * (0.7 * t).sin() + 50.0 * (2.3 * t + 0.4).sin() + 10.0 * (9.0 * t).sin()
        })
        .collect()
}

struct Run {
    err_rms: f64,
    current: Vec<f64>,
    error: Vec<f64>,
    commands: Vec<bmr::Command>,
    /// The plant's output gain at each step (sensor gain × the heating's field gain) and the adapted one.
    true_gain: Vec<f64>,
    adapted_gain: Vec<f64>,
}

/// Drive the plant for `refs`; `drop(i)`: the measurement of step `i` is missing.
fn run(ctl: &mut Ctl, plant: Plant, refs: &[f64], drop: impl Fn(usize) -> bool) -> Run {
    let effects = [
        p(EffectKind::CoilLag, &[("tau_s", plant.lag_s)]),
        p(
            EffectKind::TimeDelay,
            &[("delay_s", plant.delay_samples * DT)],
        ),
        p(
            EffectKind::ThermalDrift,
            &[("gain_loss", plant.heating.0), ("tau_s", plant.heating.1)],
        ),
    ];
    let core = forward();
    let scales = Scales::of_core(&core, 1.25, 300.0);
    let mut sim: Simulation<Vec<f64>, Vec<f64>, 16, 24> =
        Simulation::new(core, friction(), &effects, DT, scales, |n| vec![0.0; n]).unwrap();
    // The plant's lag and delay start at rest at the current the compensator's state holds.
    sim.step(ctl.compensator().forward().state().input(), 0.0);
    let mut rng = common::Rng(11);
    let mut measured = f64::NAN;
    let (mut current, mut error, mut commands) = (vec![], vec![], vec![]);
    let (mut true_gain, mut adapted_gain) = (vec![], vec![]);
    let n = refs.len();
    for (i, &r) in refs.iter().enumerate() {
        let theta = 0.5 * i as f64 * DT;
        let m = if drop(i) { f64::NAN } else { measured };
        let c = ctl.step(r, theta, m);
        let s = sim.step(c.current_a, theta);
        let g = plant.gain + (plant.gain_end - plant.gain) * (2.0 * i as f64 / n as f64).min(1.0);
        let heating_gain = sim.stages().thermal.map_or(1.0, |t| t.gain());
        true_gain.push(g * heating_gain);
        adapted_gain.push(ctl.gain());
        // Gaussian-like noise (sum of 4 uniforms, unit variance) of NOISE_NMM.
        let z: f64 = (0..4).map(|_| rng.uniform() - 0.5).sum::<f64>() * 3f64.sqrt();
        measured = g * s.torque_nmm + plant.offset_nmm + NOISE_NMM * z;
        current.push(c.current_a);
        error.push(g * s.torque_nmm + plant.offset_nmm - r);
        commands.push(c);
    }
    let skip = n / 10;
    let e = &error[skip..];
    let err_rms = (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt();
    Run {
        err_rms,
        current,
        error,
        commands,
        true_gain,
        adapted_gain,
    }
}

fn never(_: usize) -> bool {
    false
}

fn safe(r: &Run) {
    for c in &r.commands {
        assert!(c.current_a.abs() <= 1.25 && c.current_a.is_finite());
        assert!(c.coil1_a == 0.0 || c.coil2_a == 0.0, "both coils on: {c:?}");
    }
}

#[test]
fn feedback_and_adaptation_beat_the_feedforward_alone_on_a_heating_plant() {
    let refs = reference(10_000);
    let open = ControllerSettings {
        feedback: false,
        adaptation: false,
        ..Default::default()
    };
    let open = run(&mut controller(open), NOMINAL, &refs, never);
    let closed = run(
        &mut controller(ControllerSettings::default()),
        NOMINAL,
        &refs,
        never,
    );
    safe(&closed);
    assert!(
        closed.err_rms < 0.5 * open.err_rms && closed.err_rms < 3.0,
        "closed {} open {}",
        closed.err_rms,
        open.err_rms
    );
}

#[test]
fn tracking_stays_bounded_when_the_plant_is_not_the_model() {
    let refs = reference(10_000);
    let nominal = run(&mut controller(Default::default()), NOMINAL, &refs, never).err_rms;
    for (what, plant) in [
        (
            "gain -30 %",
            Plant {
                gain: 0.7,
                gain_end: 0.7,
                ..NOMINAL
            },
        ),
        (
            "gain +30 %",
            Plant {
                gain: 1.3,
                gain_end: 1.3,
                ..NOMINAL
            },
        ),
        (
            "lag x2",
            Plant {
                lag_s: 0.04,
                ..NOMINAL
            },
        ),
        (
            "delay x2",
            Plant {
                delay_samples: 4.0,
                ..NOMINAL
            },
        ),
    ] {
        let r = run(&mut controller(Default::default()), plant, &refs, never);
        safe(&r);
        let tail = &r.error[r.error.len() - 500..];
        let tail_rms = (tail.iter().map(|x| x * x).sum::<f64>() / 500.0).sqrt();
        // Bounded: within 3 % of the reference's amplitude over the run (at -30 % the peaks are out of
        // reach, 210 of 220 N·mm), and back to a few times the nominal error once the adaptation has settled.
        assert!(
            r.err_rms < 6.0,
            "{what}: RMS {} (nominal {nominal})",
            r.err_rms
        );
        assert!(
            tail_rms < 4.0 * nominal + 1.0,
            "{what}: tail {tail_rms} (nominal {nominal})"
        );
    }
}

#[test]
fn the_adapted_gain_finds_a_hidden_drift() {
    // The sensor gain drifts from 1 to 0.8 over 20 s, then stays; no heating, so the gain is all the model
    // misses.
    let plant = Plant {
        gain: 1.0,
        gain_end: 0.8,
        offset_nmm: 4.0,
        heating: (0.0, 5.0),
        ..NOMINAL
    };
    let refs = reference(20_000);
    let mut ctl = controller(Default::default());
    run(&mut ctl, plant, &refs, never);
    assert!((ctl.gain() - 0.8).abs() < 0.02, "gain {}", ctl.gain());
    assert!(
        (ctl.offset_nmm() - 4.0).abs() < 2.0,
        "offset {}",
        ctl.offset_nmm()
    );
    // Frozen, it holds; reset, it starts again.
    let g = ctl.gain();
    ctl.freeze_adaptation(true);
    run(&mut ctl, NOMINAL, &refs[..2000], never);
    assert_eq!(ctl.gain(), g);
    ctl.reset_adaptation();
    assert_eq!((ctl.gain(), ctl.offset_nmm()), (1.0, 0.0));
}

#[test]
fn the_adapted_gain_follows_a_heating_the_model_never_saw_and_the_feedforward_uses_it() {
    // Only the heating differs from the model: 30 % field-gain loss at full current, 4 s thermal constant, so
    // the plant's gain falls by several percent while the reference runs.
    let plant = Plant {
        offset_nmm: 0.0,
        heating: (0.5, 15.0),
        ..NOMINAL
    };
    let refs = reference(20_000);
    let feedforward = |adaptation| ControllerSettings {
        feedback: false,
        adaptation,
        ..Default::default()
    };
    let adapted = run(&mut controller(feedforward(true)), plant, &refs, never);
    let frozen = run(&mut controller(feedforward(false)), plant, &refs, never);
    let fall = 1.0
        - adapted
            .true_gain
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min);
    assert!(fall > 0.03, "the heating must matter: gain falls by {fall}");
    // Found to its size: after the adaptation's first memory (5 s) the estimate lags the fall by less than
    // a third of it, and once the heating settles it sits on the true gain.
    let off = |from: usize, to: usize| {
        adapted.true_gain[from..to]
            .iter()
            .zip(&adapted.adapted_gain[from..to])
            .map(|(t, a)| (t - a).abs())
    };
    let worst = off(2500, 20_000).fold(0.0, f64::max);
    assert!(
        worst < 0.3 * fall,
        "adapted gain off by {worst} for a fall of {fall}"
    );
    let settled = off(18_000, 20_000).sum::<f64>() / 2000.0;
    assert!(
        settled < 0.15 * fall,
        "settled gain off by {settled} for a fall of {fall}"
    );
    // The feedforward divides it out: without feedback, adaptation removes most of the heating's error.
    assert!(
        adapted.err_rms < 0.6 * frozen.err_rms,
        "feedforward with adaptation {} vs frozen {}",
        adapted.err_rms,
        frozen.err_rms
    );
}

#[test]
fn missing_measurements_hold_then_fault_then_recover() {
    let settings = ControllerSettings {
        fault_after: 20,
        ..Default::default()
    };
    let refs = reference(6000);
    // Short dropouts (10 samples every 100): never a fault.
    let mut ctl = controller(settings);
    let r = run(&mut ctl, NOMINAL, &refs, |i| i % 100 < 10);
    safe(&r);
    assert!(r.commands.iter().all(|c| !c.fault));
    // A 100-sample dropout from step 3000: the fault comes at its 20th missing sample and lasts until the
    // measurement returns.
    let mut ctl = controller(settings);
    let r = run(&mut ctl, NOMINAL, &refs, |i| (3000..3100).contains(&i));
    safe(&r);
    for (i, c) in r.commands.iter().enumerate() {
        let should = (3019..3100).contains(&i);
        assert_eq!(c.fault, should, "step {i}: {c:?}");
        if should {
            assert_eq!(c.current_a, 0.0);
        }
    }
    // Recovered: the last 2 s track.
    let tail = &r.error[r.error.len() - 1000..];
    let tail_rms = (tail.iter().map(|x| x * x).sum::<f64>() / 1000.0).sqrt();
    assert!(tail_rms < 5.0, "after the dropout {tail_rms}");
}

#[test]
fn a_saturated_reference_does_not_wind_up_the_integrator() {
    let mut refs = reference(8000);
    let normal = run(&mut controller(Default::default()), NOMINAL, &refs, never);
    // 2 s far above reach, then back.
    for r in &mut refs[2000..3000] {
        *r = 5000.0;
    }
    let mut ctl = controller(Default::default());
    let r = run(&mut ctl, NOMINAL, &refs, never);
    safe(&r);
    assert!(ctl.correction_nmm().abs() <= ctl.design().correction_limit_nmm);
    assert!(r.commands[2500].saturated);
    // 0.5 s after the return, tracking is back to what it is without the saturation.
    let rms = |e: &[f64]| (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt();
    let after = rms(&r.error[3250..4000]);
    let without = rms(&normal.error[3250..4000]);
    assert!(
        after < without + 1.0,
        "after saturation {after}, without {without}"
    );
    assert!(r.current.iter().all(|c| c.abs() <= 1.25));
}

#[test]
fn snapshot_and_words_replay_bit_for_bit() {
    let refs = reference(3000);
    let mut a = controller(Default::default());
    run(&mut a, NOMINAL, &refs[..1000], never);
    let snap = a.snapshot();
    let words = snap.to_words();
    let first = run(&mut a, NOMINAL, &refs[1000..], |i| i % 37 == 0);
    let mut b = controller(Default::default());
    b.restore(&b.state_from_words(&words).unwrap()).unwrap();
    let second = run(&mut b, NOMINAL, &refs[1000..], |i| i % 37 == 0);
    assert_eq!(first.commands, second.commands);
    assert_eq!(a.gain().to_bits(), b.gain().to_bits());
    // Damaged words are an error.
    let mut bad = words.clone();
    bad[2] = f64::NAN.to_bits();
    assert!(b.state_from_words(&bad).is_err());
    assert!(b.state_from_words(&words[..20]).is_err());
}

#[test]
fn the_design_reports_its_margin_and_refuses_a_bandwidth_the_delay_cannot_carry() {
    let c = controller(Default::default());
    let d = *c.design();
    assert_eq!(d.delay_samples, 2);
    assert!((d.loop_delay_s - 3.5 * DT).abs() < 1e-15);
    assert!((d.coil_lag_s - 0.02).abs() < 1e-12);
    assert!(d.phase_margin_deg >= 60.0 && d.phase_margin_deg < 90.0);
    assert!((d.ki_per_s - 2.0 * std::f64::consts::PI * d.bandwidth_hz).abs() < 1e-9);
    let asked = ControllerSettings {
        bandwidth_hz: 5.0,
        ..Default::default()
    };
    let d = *controller(asked).design();
    let expected = 90.0 - (2.0 * std::f64::consts::PI * 5.0 * 3.5 * DT).to_degrees();
    assert!((d.phase_margin_deg - expected).abs() < 1e-9);
    let comp = || {
        Compensator::new(forward(), InverseKind::Exact, friction(), 0.125, 1.25)
            .unwrap()
            .with_extensions(&model_effects(0.02, 2.0), DT, 300.0)
            .unwrap()
    };
    for (settings, dt) in [
        (
            ControllerSettings {
                bandwidth_hz: 40.0,
                ..Default::default()
            },
            DT,
        ),
        (
            ControllerSettings {
                bandwidth_hz: f64::NAN,
                ..Default::default()
            },
            DT,
        ),
        (
            ControllerSettings {
                fault_after: 0,
                ..Default::default()
            },
            DT,
        ),
        (
            ControllerSettings {
                noise_share: 0.0,
                ..Default::default()
            },
            DT,
        ),
        (
            ControllerSettings {
                adaptation_time_s: 0.001,
                ..Default::default()
            },
            DT,
        ),
        (
            ControllerSettings {
                correction_limit_nmm: -1.0,
                ..Default::default()
            },
            DT,
        ),
        (ControllerSettings::default(), 0.0),
    ] {
        let e: ControllerError = Controller::new(comp(), dt, settings).unwrap_err();
        assert!(!e.to_string().is_empty());
    }
}

#[test]
fn non_finite_reference_or_angle_is_a_fault_with_zero_current() {
    let mut c = controller(Default::default());
    for (r, th) in [(f64::NAN, 0.0), (0.0, f64::INFINITY), (f64::INFINITY, 0.0)] {
        let cmd = c.step(r, th, 1.0);
        assert!(cmd.fault && cmd.current_a == 0.0);
        assert!(c.correction_nmm().is_finite());
    }
    let cmd = c.step(10.0, 0.0, 1.0);
    assert!(!cmd.fault && cmd.current_a.is_finite());
}

/// Response of the loop to an output offset stepping by `STEP_NMM` while the reference holds at 0 N·mm, reached
/// from `peak_nmm` (positive: from above, along a descending branch; negative: from below, along an ascending
/// one). Plant = model, no noise, adaptation off: the integrator alone removes the offset. Returns the time (s)
/// the error takes to fall to 1/e of the step, and the model's local slope (N·mm/A) in the direction the
/// correction moves (down) at the hold.
fn offset_step_response(peak_nmm: f64) -> (f64, f64, f64) {
    const STEP_NMM: f64 = 15.0;
    let mut ctl = controller(ControllerSettings {
        adaptation: false,
        ..Default::default()
    });
    let ramp = |a: f64, b: f64, n: usize| (0..n).map(move |i| a + (b - a) * i as f64 / n as f64);
    let refs: Vec<f64> = ramp(0.0, peak_nmm, 500)
        .chain(ramp(peak_nmm, 0.0, 500))
        .chain(std::iter::repeat_n(0.0, 1500))
        .collect();
    let t0 = 1500;
    let effects = model_effects(0.02, 2.0);
    let core = forward();
    let scales = Scales::of_core(&core, 1.25, 300.0);
    let mut sim: Simulation<Vec<f64>, Vec<f64>, 16, 24> =
        Simulation::new(core, friction(), &effects, DT, scales, |n| vec![0.0; n]).unwrap();
    sim.step(ctl.compensator().forward().state().input(), 0.0);
    let (mut measured, mut slope, mut tau) = (f64::NAN, f64::NAN, f64::NAN);
    for (i, &r) in refs.iter().enumerate() {
        // The rotor at rest: no friction ripple moving the hysteresis back and forth at the hold.
        let theta = 0.0;
        if i == t0 {
            // The slope the correction meets: the forward model stepped down by 0.1 A from the present state
            // (about the current the offset takes on a steep branch).
            let mut h = ctl.compensator().forward().clone();
            let (u, y) = (h.state().input(), h.output());
            slope = (y - h.step(u - 0.1)) / 0.1;
        }
        let c = ctl.step(r, theta, measured);
        let offset = if i >= t0 { STEP_NMM } else { 0.0 };
        measured = sim.step(c.current_a, theta).torque_nmm + offset;
        if i > t0 && tau.is_nan() && (measured - r).abs() < STEP_NMM * (-1.0f64).exp() {
            tau = (i - t0) as f64 * DT;
        }
    }
    (tau, slope, ctl.design().ki_per_s)
}

#[test]
fn the_loop_bandwidth_is_the_same_where_the_hysteresis_is_flat_and_where_it_is_steep() {
    // Held at the same torque, reached from below the correction meets the flat start of a descending branch
    // (a reversal), reached from above the steep middle of one. The exact inverse divides every torque change
    // by that local slope, so the integrator sees a unit gain at both and its time constant is 1/ki.
    let (tau_flat, slope_flat, ki) = offset_step_response(-250.0);
    let (tau_steep, slope_steep, _) = offset_step_response(250.0);
    assert!(
        slope_steep > 3.0 * slope_flat,
        "slopes {slope_flat} and {slope_steep} N·mm/A"
    );
    for tau in [tau_flat, tau_steep] {
        assert!(
            (tau * ki - 1.0).abs() < 0.25,
            "time constant {tau} s against 1/ki = {} s (flat {tau_flat}, steep {tau_steep})",
            1.0 / ki
        );
    }
    assert!(
        (tau_flat / tau_steep - 1.0).abs() < 0.1,
        "{tau_flat} vs {tau_steep}"
    );
}

/// The batch closed loop on the virtual actuator (one `sincos` of each sample's angle shared by the plant's
/// seal friction and the controller's friction feedforward) gives the commands, samples and loop states of
/// `Controller::step` and `VirtualActuator::step` called in turn, to the bit: on the plant's own angle, on a
/// given angle equal to it, and on one that is not (which needs its own `sincos`); the base compensator, the
/// extended one, and the extended one with a `time_delay` stage (a predicted angle, not the plant's).
#[test]
fn the_batch_closed_loop_is_the_steps_in_turn_to_the_bit() {
    use bmr::plant::effects::{Effect, EffectKind as PlantEffect};
    use bmr::plant::{VirtualActuator, run_closed_loop};
    type Row = (u64, bool, bool, u64, u64, u64, u64, u64);
    let plant = || {
        let effects = [
            Effect::from_params(PlantEffect::CoilLag, &[("tau_s", 0.02)]).unwrap(),
            Effect::from_params(
                PlantEffect::ThermalDrift,
                &[("gain_loss", 0.1), ("tau_s", 60.0)],
            )
            .unwrap(),
        ];
        VirtualActuator::from_preset("rig_preisach", 1.0 / DT, &effects, 1).unwrap()
    };
    let refs = reference(4000);
    let n = refs.len();
    let own = plant().theta_ahead(n).unwrap();
    let compensators: [&dyn Fn() -> Compensator<Vec<f64>, 16, 24>; 3] = [
        &|| Compensator::new(forward(), InverseKind::Exact, friction(), 0.125, 1.25).unwrap(),
        &|| {
            Compensator::new(forward(), InverseKind::Exact, friction(), 0.125, 1.25)
                .unwrap()
                .with_extensions(&[p(EffectKind::CoilLag, &[("tau_s", 0.02)])], DT, 300.0)
                .unwrap()
        },
        &|| {
            Compensator::new(forward(), InverseKind::Exact, friction(), 0.125, 1.25)
                .unwrap()
                .with_extensions(&model_effects(0.02, 2.0), DT, 300.0)
                .unwrap()
        },
    ];
    for make in compensators {
        for shift in [None, Some(0.0), Some(1e-3)] {
            let thetas: Option<Vec<f64>> = shift.map(|d| own.iter().map(|t| t + d).collect());
            let row = |c: &bmr::Command, s: &bmr::plant::Sample, k: &Ctl| -> Row {
                (
                    c.current_a.to_bits(),
                    c.saturated,
                    c.fault,
                    s.torque_nmm.to_bits(),
                    s.torque_true_nmm.to_bits(),
                    k.correction_nmm().to_bits(),
                    k.gain().to_bits(),
                    k.offset_nmm().to_bits(),
                )
            };
            let new_ctl = || Controller::new(make(), DT, ControllerSettings::default()).unwrap();
            let (mut ctl, mut act) = (new_ctl(), plant());
            let mut batch = Vec::with_capacity(n);
            run_closed_loop(
                &mut ctl,
                &mut act,
                &refs,
                thetas.as_deref(),
                |_, c, s, k| batch.push(row(c, s, k)),
            );
            let (mut ctl, mut act) = (new_ctl(), plant());
            let mut measured = f64::NAN;
            let mut stepped = Vec::with_capacity(n);
            for (i, &r) in refs.iter().enumerate() {
                let theta = thetas.as_ref().map_or(act.theta_rad(), |t| t[i]);
                let c = ctl.step(r, theta, measured);
                let s = act.step(c.current_a);
                measured = s.torque_nmm;
                stepped.push(row(&c, &s, &ctl));
            }
            assert_eq!(batch.len(), n);
            let first = batch.iter().zip(&stepped).position(|(a, b)| a != b);
            assert_eq!(first, None, "shift {shift:?}: first differing sample");
            // The loop did track (a run of zero commands would compare equal whatever the angle).
            assert!(batch.iter().filter(|r| f64::from_bits(r.0) != 0.0).count() > n / 2);
        }
    }
}
