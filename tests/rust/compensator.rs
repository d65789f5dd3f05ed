//! Compensator safety invariants over random references and angles, including NaN/inf and out-of-range inputs.
mod common;

use bmr::{BuildOptions, Compensator, Friction, Hysteresis, Initial, InverseKind};
use proptest::prelude::*;
use std::sync::OnceLock;

type Table = (Vec<common::Curve>, Vec<common::Curve>);
type Comp = Compensator<Vec<f64>, 16, 12>;

fn table() -> &'static Table {
    static T: OnceLock<Table> = OnceLock::new();
    // Input range ±1 A scaled to ±1.25 A below; output span ±300 N·mm.
    T.get_or_init(|| common::measure_first_order(60, 13))
}

fn forward() -> Hysteresis<Vec<f64>, 16> {
    let (a, d) = table();
    let scale = |c: &Vec<common::Curve>| -> Vec<common::Curve> {
        c.iter()
            .map(|(u, y)| (u.iter().map(|x| 1.25 * x).collect(), y.clone()))
            .collect()
    };
    let (a, d) = (scale(a), scale(d));
    Hysteresis::from_curve_data(&a, &d, &BuildOptions::default(), Initial::Negative).unwrap()
}

fn compensator(paper: bool, limit: f64) -> Comp {
    let fwd = forward();
    let inv = if paper {
        InverseKind::Paper(fwd.paper_inverse().unwrap())
    } else {
        InverseKind::Exact
    };
    let f = Friction::from_amplitude_phase(12.0, &[25.0, 8.0, 4.0], &[0.3, 1.1, -0.7]).unwrap();
    Compensator::new(fwd, inv, f, 0.125, limit).unwrap()
}

fn any_value() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => -800.0f64..800.0,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => -1e12f64..1e12,
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2_000, ..ProptestConfig::default() })]

    #[test]
    fn safety_invariants_hold(refs in prop::collection::vec((any_value(), any_value()), 1..60),
                              paper in any::<bool>(), limit in 0.2f64..2.0) {
        let mut c = compensator(paper, limit);
        for (r, th) in refs {
            let cmd = c.step(r, th);
            prop_assert!(cmd.coil1_a == 0.0 || cmd.coil2_a == 0.0, "both coils energised: {:?}", cmd);
            prop_assert!(cmd.coil1_a >= 0.0 && cmd.coil2_a >= 0.0);
            prop_assert!(cmd.current_a.abs() <= limit, "{:?} over limit {}", cmd, limit);
            prop_assert!(cmd.current_a.is_finite() && cmd.volt1_v.is_finite() && cmd.volt2_v.is_finite());
            prop_assert_eq!(cmd.volt1_v * 0.125, cmd.coil1_a);
            prop_assert_eq!(cmd.volt2_v * 0.125, cmd.coil2_a);
            if !(r.is_finite() && th.is_finite()) {
                prop_assert!(cmd.fault && cmd.current_a == 0.0);
            } else {
                prop_assert!(!cmd.fault);
            }
            // The forward memory follows what was actually commanded.
            prop_assert_eq!(c.forward().state().input(), cmd.current_a);
        }
    }
}

fn extreme_value() -> impl Strategy<Value = f64> {
    prop_oneof![
        2 => -1e3f64..1e3,
        1 => Just(f64::MAX),
        1 => Just(-f64::MAX),
        1 => Just(1.7e308),
        1 => Just(1e150),
        1 => Just(-1e150),
        1 => Just(5e-324),
        1 => Just(f64::NAN),
        1 => prop::num::f64::ANY,
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1_000, ..ProptestConfig::default() })]

    /// Whatever friction and converter gain construct, every command is finite and a fault commands zero current:
    /// coefficients whose sum cannot be evaluated finitely and gains that would need infinite volts are refused.
    #[test]
    fn extreme_parameters_never_give_a_non_finite_command(
        c0 in extreme_value(), a in prop::collection::vec(extreme_value(), 0..4),
        b in prop::collection::vec(extreme_value(), 0..4), gain in extreme_value(),
        refs in prop::collection::vec((extreme_value(), extreme_value()), 1..20), paper in any::<bool>(),
    ) {
        let Ok(f) = Friction::<12>::from_coefficients(c0, &a, &b) else { return Ok(()) };
        prop_assert!(c0.abs() + a.iter().chain(&b).map(|x| x.abs()).sum::<f64>() <= bmr::friction::MAX_MAGNITUDE);
        let fwd = forward();
        let inv = if paper { InverseKind::Paper(fwd.paper_inverse().unwrap()) } else { InverseKind::Exact };
        let Ok(mut c) = Comp::new(fwd, inv, f, gain, 1.25) else { return Ok(()) };
        for (r, th) in refs {
            let cmd = c.step(r, th);
            prop_assert!(cmd.current_a.is_finite() && cmd.volt1_v.is_finite() && cmd.volt2_v.is_finite(),
                         "{:?}", cmd);
            prop_assert!(!cmd.fault || cmd.current_a == 0.0);
            // A fault for non-finite inputs, or for a finite reference so close to f64::MAX that subtracting the
            // friction overflows (the documented safe output: zero current).
            let overflow = r.is_finite() && th.is_finite() && !(r - f.eval(th)).is_finite();
            prop_assert_eq!(cmd.fault, !(r.is_finite() && th.is_finite()) || overflow);
            prop_assert_eq!(c.forward().state().input(), cmd.current_a);
        }
    }
}

#[test]
fn exact_compensator_tracks_reachable_references_to_round_off() {
    let mut c = compensator(false, 1.25);
    let f = *c.friction();
    let mut rng = common::Rng(4);
    let mut worst: f64 = 0.0;
    for i in 0..50_000 {
        let th = 0.01 * i as f64;
        let r = 250.0 * (0.001 * i as f64).sin() + 30.0 * (rng.uniform() - 0.5);
        let cmd = c.step(r, th);
        assert!(!cmd.saturated);
        worst = worst.max((c.predicted_torque() + f.eval(th) - r).abs());
    }
    assert!(worst < 1e-9 * 600.0, "worst model-torque error {worst}");
}

#[test]
fn saturation_is_flagged_and_memory_follows_the_limited_current() {
    let mut c = compensator(false, 0.5);
    let cmd = c.step(290.0, 0.0);
    assert!(cmd.saturated && cmd.current_a == 0.5 && cmd.coil2_a == 0.5 && cmd.coil1_a == 0.0);
    assert_eq!(c.forward().state().input(), 0.5);
    let cmd = c.step(-5000.0, 0.0);
    assert!(cmd.saturated && cmd.current_a == -0.5 && cmd.coil1_a == 0.5);
    assert_eq!(c.forward().state().input(), -0.5);
}

#[test]
fn bad_parameters_are_errors() {
    assert!(Comp::new(forward(), InverseKind::Exact, Friction::zero(), 0.0, 1.0).is_err());
    assert!(
        Comp::new(
            forward(),
            InverseKind::Exact,
            Friction::zero(),
            0.125,
            f64::NAN
        )
        .is_err()
    );
}

#[test]
fn friction_matches_closed_form_and_round_trips_amplitude_phase() {
    let amp = [25.0, 8.0, 4.0, 0.0, 1.5];
    let ph = [0.3, 1.1, -0.7, 0.0, 2.0];
    let f = Friction::<12>::from_amplitude_phase(12.0, &amp, &ph).unwrap();
    for i in 0..1000 {
        let th = -20.0 + 0.04 * i as f64;
        let closed: f64 = 12.0
            + amp
                .iter()
                .zip(&ph)
                .enumerate()
                .map(|(k, (a, p))| a * ((k + 1) as f64 * th + p).sin())
                .sum::<f64>();
        assert!(
            (f.eval(th) - closed).abs() < 1e-9,
            "θ={th}: {} vs {closed}",
            f.eval(th)
        );
    }
    for k in [1, 2, 3, 5] {
        let (a, p) = f.amplitude_phase(k);
        assert!((a - amp[k - 1]).abs() < 1e-12 && (p - ph[k - 1]).abs() < 1e-12);
    }
    assert_eq!(f.order(), 5);
    assert!(Friction::<3>::from_coefficients(0.0, &[1.0; 4], &[]).is_err());
    assert!(f.eval(f64::NAN).is_nan());
}

// ------------------------------------------------------------------------------------------- extended stages

use bmr::simulation::Simulation;
use bmr::stages::Scales;
use bmr::vocabulary::{EffectKind, Params};

/// Every stage on, parameters drawn from their documented ranges (the realistic part of them).
#[derive(Debug, Clone)]
struct StageDraw {
    tau_s: f64,
    delay_samples: usize,
    gain_loss: f64,
    heat_tau_s: f64,
    eps: f64,
    ripple_phase: f64,
    curvature: f64,
    cubic: f64,
    gain_per_a: f64,
    order: u32,
    amplitude: f64,
    creep_fraction: f64,
    rate_tau_s: f64,
    kappa: f64,
    viscous_c: f64,
    viscous_f_y: f64,
    viscous_v0: f64,
    creep_fluctuation: f64,
    feedback: f64,
}

fn stage_draw() -> impl Strategy<Value = StageDraw> {
    (
        (0.0f64..0.1, 0usize..12, -0.5f64..0.9, 0.01f64..100.0),
        (0.0f64..0.9, -4.0f64..4.0, -0.45f64..5.0, -0.3f64..3.0),
        (-0.5f64..5.0, 4u32..25, -50.0f64..50.0),
        (0.0f64..0.2, 0.0f64..0.02, -0.3f64..0.3, 0.0f64..5.0),
        (0.0f64..40.0, 0.01f64..10.0, 0.0f64..0.01, -0.1f64..0.1),
    )
        .prop_map(
            |(
                (tau_s, delay_samples, gain_loss, heat_tau_s),
                (eps, ripple_phase, curvature, cubic),
                (gain_per_a, order, amplitude),
                (creep_fraction, rate_tau_s, kappa, viscous_c),
                (viscous_f_y, viscous_v0, creep_fluctuation, feedback),
            )| StageDraw {
                tau_s,
                delay_samples,
                gain_loss,
                heat_tau_s,
                eps,
                ripple_phase,
                curvature,
                cubic,
                gain_per_a,
                order,
                amplitude,
                creep_fraction,
                rate_tau_s,
                kappa,
                viscous_c,
                viscous_f_y,
                viscous_v0,
                creep_fluctuation,
                feedback,
            },
        )
}

const DT: f64 = 0.002;

fn effects(d: &StageDraw) -> Vec<Params> {
    let p = |k: EffectKind, v: &[(&'static str, f64)]| Params::new(k.spec(), v).unwrap();
    vec![
        p(EffectKind::CoilLag, &[("tau_s", d.tau_s)]),
        p(
            EffectKind::TimeDelay,
            &[("delay_s", d.delay_samples as f64 * DT)],
        ),
        p(
            EffectKind::ThermalDrift,
            &[("gain_loss", d.gain_loss), ("tau_s", d.heat_tau_s)],
        ),
        p(
            EffectKind::TorqueRipple,
            &[("eps", d.eps), ("phase_rad", d.ripple_phase)],
        ),
        p(
            EffectKind::NonCongruent,
            &[
                ("curvature", d.curvature),
                ("cubic", d.cubic),
                ("feedback", d.feedback),
            ],
        ),
        p(EffectKind::FrictionCurrent, &[("gain_per_a", d.gain_per_a)]),
        p(
            EffectKind::FrictionHarmonics,
            &[("order", d.order as f64), ("amplitude_nmm", d.amplitude)],
        ),
        p(
            EffectKind::Creep,
            &[
                ("fraction", d.creep_fraction),
                ("tau_min_s", 0.01),
                ("tau_max_s", 10.0),
                ("fluctuation", d.creep_fluctuation),
                ("tau0_s", 0.05),
            ],
        ),
        p(EffectKind::RateDependence, &[("tau_s", d.rate_tau_s)]),
        p(
            EffectKind::Accommodation,
            &[("kappa", d.kappa), ("cycles", 2.0)],
        ),
        p(
            EffectKind::Viscous,
            &[
                ("c", d.viscous_c),
                ("f_y", d.viscous_f_y),
                ("v0", d.viscous_v0),
            ],
        ),
    ]
}

fn extended(paper: bool, limit: f64, d: &StageDraw) -> Comp24 {
    let fwd = forward();
    let inv = if paper {
        InverseKind::Paper(fwd.paper_inverse().unwrap())
    } else {
        InverseKind::Exact
    };
    let f = Friction::from_amplitude_phase(12.0, &[25.0, 8.0, 4.0], &[0.3, 1.1, -0.7]).unwrap();
    Compensator::new(fwd, inv, f, 0.125, limit)
        .unwrap()
        .with_extensions(&effects(d), DT, 300.0)
        .unwrap()
}

type Comp24 = Compensator<Vec<f64>, 16, 24>;

proptest! {
    #![proptest_config(ProptestConfig { cases: 600, ..ProptestConfig::default() })]

    #[test]
    fn safety_invariants_hold_with_every_stage_on(
        refs in prop::collection::vec((any_value(), any_value()), 1..80),
        paper in any::<bool>(), limit in 0.2f64..2.0, ahead in any::<bool>(), d in stage_draw()) {
        let mut c = extended(paper, limit, &d);
        for (r, th) in refs {
            // The mean field's share of the core's output before the step.
            let fed = c.stages().mean_field.map_or(0.0, |m| m.shift(c.forward().output()));
            let cmd = if ahead { c.step_ahead(r, th) } else { c.step(r, th) };
            prop_assert!(cmd.coil1_a == 0.0 || cmd.coil2_a == 0.0, "both coils energised: {:?}", cmd);
            prop_assert!(cmd.current_a.abs() <= limit, "{:?} over limit {}", cmd, limit);
            prop_assert!(cmd.current_a.is_finite() && cmd.volt1_v.is_finite() && cmd.volt2_v.is_finite());
            if !(r.is_finite() && th.is_finite()) {
                prop_assert!(cmd.fault && cmd.current_a == 0.0);
            }
            if cmd.fault {
                prop_assert!(cmd.current_a == 0.0 && !cmd.saturated);
            }
            // The forward memory holds the core input the stages reached: the lag's field current, through the
            // rate-dependence stage when there is one, pushed by creep's fluctuation field when there is one.
            let pushed = |u: f64| match c.stages().creep.as_ref().and_then(|k| k.fluctuation()) {
                Some(f) => {
                    let [d, since_s, last_u] = f.state();
                    prop_assert_eq!(last_u, u);
                    Ok(u + f.field() * (d * (since_s / f.tau0_s()).ln_1p()))
                }
                None => Ok(u),
            };
            // Plus the mean field's share (the same sum up to its rounding).
            let reached = |u: f64| -> Result<(), TestCaseError> {
                let want = (pushed(u)? + fed).clamp(-1.25, 1.25);
                let got = c.forward().state().input();
                if fed == 0.0 {
                    prop_assert_eq!(got, want);
                } else {
                    prop_assert!((got - want).abs() <= 1e-12, "{} vs {}", got, want);
                }
                Ok(())
            };
            if let Some(r) = c.stages().rate {
                reached(r.core_input())?;
            } else if let Some(l) = c.stages().coil_lag {
                reached(l.field_a())?;
            }
        }
    }

    #[test]
    fn snapshot_restore_replays_bit_for_bit_with_every_stage_on(
        head in prop::collection::vec((-700.0f64..700.0, 0.0f64..6.3), 1..60),
        tail in prop::collection::vec((-700.0f64..700.0, 0.0f64..6.3), 1..60),
        paper in any::<bool>(), d in stage_draw()) {
        let mut c = extended(paper, 1.25, &d);
        for &(r, th) in &head {
            c.step(r, th);
        }
        let snap = c.snapshot();
        let first: Vec<u64> = tail.iter().map(|&(r, th)| c.step(r, th).current_a.to_bits()).collect();
        c.restore(&snap).unwrap();
        let again: Vec<u64> = tail.iter().map(|&(r, th)| c.step(r, th).current_a.to_bits()).collect();
        prop_assert_eq!(first, again);
        // A copy restores too; a compensator with other stages refuses the snapshot.
        let mut other = extended(paper, 1.25, &StageDraw { tau_s: d.tau_s + 0.01, ..d.clone() });
        prop_assert!(other.restore(&snap).is_err());
    }

    #[test]
    fn every_stage_alone_and_all_together_continue_bit_for_bit_from_words_and_snapshots(
        head in prop::collection::vec((-700.0f64..700.0, 0.0f64..6.3), 1..80),
        tail in prop::collection::vec((-700.0f64..700.0, 0.0f64..6.3), 1..80),
        which in 0usize..=EffectKind::ALL.len(), d in stage_draw()) {
        // `which`: one effect of the draw alone, or (past the last) all of them.
        let all = effects(&d);
        let fx: Vec<Params> = match all.get(which) {
            Some(p) => vec![*p],
            None => all.clone(),
        };
        let build = || {
            let f = Friction::from_amplitude_phase(12.0, &[25.0, 8.0, 4.0], &[0.3, 1.1, -0.7]).unwrap();
            Comp24::new(forward(), InverseKind::Exact, f, 0.125, 1.25)
                .unwrap()
                .with_extensions(&fx, DT, 300.0)
                .unwrap()
        };
        let mut c = build();
        for &(r, th) in &head {
            c.step(r, th);
        }
        let words = c.snapshot().to_words();
        let snap = c.snapshot();
        let run = |c: &mut Comp24| -> Vec<(u64, u64)> {
            tail.iter()
                .map(|&(r, th)| (c.step(r, th).current_a.to_bits(), c.model_torque_nmm().to_bits()))
                .collect()
        };
        let first = run(&mut c);
        // Words into a fresh compensator of the same configuration (what unpickling does).
        let mut fresh = build();
        let s = fresh.state_from_words(&words).unwrap();
        fresh.restore(&s).unwrap();
        prop_assert_eq!(&first, &run(&mut fresh));
        // A snapshot into a copy.
        let mut copy = build();
        copy.restore(&snap).unwrap();
        prop_assert_eq!(&first, &run(&mut copy));
        // Read back, the state writes the very same words (every stage that is on has its state in them).
        let mut again = build();
        again.restore(&again.state_from_words(&words).unwrap()).unwrap();
        prop_assert_eq!(again.snapshot().to_words(), words);
    }
}

#[test]
fn nan_intermediates_are_faults_and_extreme_friction_is_refused() {
    // Coefficients whose sum overflows: refused where the friction is made.
    assert!(
        Friction::<12>::from_coefficients(0.0, &[1.7e308, 0.0, -1.7e308], &[1.7e308, 0.0, 1.7e308])
            .is_err()
    );
    // A converter gain whose voltage at the limit overflows: refused.
    assert!(
        Comp::new(
            forward(),
            InverseKind::Exact,
            Friction::zero(),
            5e-324,
            1.25
        )
        .is_err()
    );
    // A reference so large that the target overflows with the friction: a fault, not a NaN.
    let f = Friction::<12>::from_coefficients(-1e300, &[], &[]).unwrap();
    let mut c = Comp::new(forward(), InverseKind::Exact, f, 0.125, 1.25).unwrap();
    let cmd = c.step(-f64::MAX, 0.5);
    assert!(cmd.saturated && cmd.current_a == -1.25, "{cmd:?}");
    let cmd = c.step(f64::MAX, 0.5);
    assert!(cmd.fault && cmd.current_a == 0.0, "{cmd:?}");
}

#[test]
fn extended_compensator_inverts_the_extended_simulation() {
    // Tracking a smooth reference known ahead through the extended simulation of the same model: the torque
    // follows the reference to within what the one-sample-old heating and friction-current states leave.
    let d = StageDraw {
        tau_s: 0.02,
        delay_samples: 5,
        gain_loss: 0.1,
        heat_tau_s: 5.0,
        eps: 0.05,
        ripple_phase: 0.4,
        curvature: 1.5,
        cubic: 0.0,
        gain_per_a: 0.3,
        order: 6,
        amplitude: 4.0,
        creep_fraction: 0.05,
        rate_tau_s: 0.005,
        kappa: 0.1,
        viscous_c: 2.0,
        viscous_f_y: 20.0,
        viscous_v0: 0.5,
        creep_fluctuation: 0.0,
        feedback: 0.08,
    };
    // With every stage on the error is what the estimated current of the current-dependent friction leaves
    // (smoothed over 10 ms: 0.3/A × ~37 N·mm × its lag); the plant's noise floor is ~1.5 N·mm.
    let worst = inversion_error(&d);
    assert!(worst < 1.0, "worst tracking error {worst} N·mm");
    // Each stage alone is inverted to round-off (the heating and the current-dependent friction one sample late).
    let off = StageDraw {
        tau_s: 0.0,
        delay_samples: 0,
        gain_loss: 0.0,
        eps: 0.0,
        curvature: 0.0,
        gain_per_a: 0.0,
        amplitude: 0.0,
        creep_fraction: 0.0,
        rate_tau_s: 0.0,
        kappa: 0.0,
        viscous_c: 0.0,
        viscous_f_y: 0.0,
        feedback: 0.0,
        ..d.clone()
    };
    let alone = [
        // The mean field (a moving Preisach core), magnetizing and demagnetizing.
        StageDraw {
            feedback: 0.08,
            ..off.clone()
        },
        StageDraw {
            feedback: -0.1,
            ..off.clone()
        },
        StageDraw {
            tau_s: 0.02,
            ..off.clone()
        },
        StageDraw {
            delay_samples: 5,
            ..off.clone()
        },
        StageDraw {
            eps: 0.05,
            ..off.clone()
        },
        StageDraw {
            curvature: 1.5,
            ..off.clone()
        },
        StageDraw {
            cubic: 0.8,
            ..off.clone()
        },
        StageDraw {
            curvature: 0.4,
            cubic: -0.25,
            ..off.clone()
        },
        StageDraw {
            amplitude: 4.0,
            ..off.clone()
        },
        StageDraw {
            creep_fraction: 0.05,
            ..off.clone()
        },
        StageDraw {
            rate_tau_s: 0.005,
            ..off.clone()
        },
        StageDraw {
            viscous_c: 2.0,
            ..off.clone()
        },
        // The Bingham yield part alone and with the viscous part: a nearly stepped loss (v0 well under the
        // reference's input rates) is solved to round-off too.
        StageDraw {
            viscous_f_y: 30.0,
            viscous_v0: 0.05,
            ..off.clone()
        },
        StageDraw {
            viscous_c: 2.0,
            viscous_f_y: 30.0,
            viscous_v0: 0.5,
            ..off.clone()
        },
    ];
    for s in &alone {
        let e = inversion_error(s);
        assert!(e < 1e-9, "{s:?}: {e}");
    }
    // Accommodation is undone with the shift of the state before the sample: it moves by a small share of a
    // cycle per sample.
    let acc = inversion_error(&StageDraw {
        kappa: 0.1,
        ..off.clone()
    });
    assert!(acc < 0.05, "accommodation alone: {acc} N·mm");
}

#[test]
fn the_viscous_stage_damps_reference_noise_instead_of_differencing_it() {
    // Compensating y = H(u) + c·du/dt by differencing the command would multiply reference noise by c/dt; the
    // implicit solve divides a reference step by (branch slope + c/dt): the command's sample-to-sample steps
    // shrink as c grows, and the model torque still meets the reference to round-off.
    let steps = |c_loss: f64| -> (f64, f64) {
        let d = StageDraw {
            tau_s: 0.0,
            delay_samples: 0,
            gain_loss: 0.0,
            heat_tau_s: 5.0,
            eps: 0.0,
            ripple_phase: 0.0,
            curvature: 0.0,
            cubic: 0.0,
            gain_per_a: 0.0,
            order: 5,
            amplitude: 0.0,
            creep_fraction: 0.0,
            rate_tau_s: 0.0,
            kappa: 0.0,
            viscous_c: c_loss,
            viscous_f_y: 0.0,
            viscous_v0: 1.0,
            creep_fluctuation: 0.0,
            feedback: 0.0,
        };
        let mut c = extended(false, 1.25, &d);
        let mut rng = common::Rng(5);
        let (mut last, mut sq, mut worst, mut n) = (f64::NAN, 0.0, 0.0f64, 0.0);
        for i in 0..4000 {
            let t = i as f64 * DT;
            let r = 150.0 * (2.0 * t).sin() + 5.0 * (rng.uniform() - 0.5);
            let cmd = c.step(r, 0.0);
            if i > 500 {
                sq += (cmd.current_a - last).powi(2);
                n += 1.0;
                if !cmd.saturated {
                    worst = worst.max((c.model_torque_nmm() - r).abs());
                }
            }
            last = cmd.current_a;
        }
        ((sq / n).sqrt(), worst)
    };
    let (plain, _) = steps(0.0);
    let (damped, worst) = steps(2.0);
    assert!(
        damped < 0.5 * plain,
        "command steps {damped} A with the loss, {plain} A without"
    );
    assert!(
        worst < 1e-8,
        "model torque off the reference by {worst} N·mm"
    );
}

#[test]
fn the_creep_fluctuation_field_is_inverted_wherever_the_core_input_is_reachable() {
    // The log-time after-effect pushes the core input along its last direction; the compensator takes the field
    // off before the rate and lag inverses. Where the reference turns back by less than the field the turn drops,
    // the sample cannot reach it: the command is flagged and the torque is off by less than that field's torque.
    let d = StageDraw {
        tau_s: 0.0,
        delay_samples: 0,
        gain_loss: 0.0,
        heat_tau_s: 5.0,
        eps: 0.0,
        ripple_phase: 0.0,
        curvature: 0.0,
        cubic: 0.0,
        gain_per_a: 0.0,
        order: 5,
        amplitude: 0.0,
        creep_fraction: 0.0,
        rate_tau_s: 0.0,
        kappa: 0.0,
        viscous_c: 0.0,
        viscous_f_y: 0.0,
        viscous_v0: 1.0,
        creep_fluctuation: 0.003,
        feedback: 0.0,
    };
    let mut c = extended(false, 1.25, &d);
    let f = Friction::from_amplitude_phase(12.0, &[25.0, 8.0, 4.0], &[0.3, 1.1, -0.7]).unwrap();
    let scales = Scales::of_core(&forward(), 1.25, 300.0);
    let mut sim: Simulation<Vec<f64>, Vec<f64>, 16, 24> =
        Simulation::new(forward(), f, &effects(&d), DT, scales, |n| vec![0.0; n]).unwrap();
    let mut plain = extended(
        false,
        1.25,
        &StageDraw {
            creep_fluctuation: 0.0,
            ..d.clone()
        },
    );
    let (mut flagged, mut worst, mut worst_plain) = (0, 0.0f64, 0.0f64);
    for i in 0..6000 {
        // An opening beyond reach both ways (plant and compensator start from one state), then a smooth reference.
        let r = match i {
            0..200 => 10.0 * i as f64,
            200..600 => 2000.0 - 10.0 * (i - 200) as f64,
            600..800 => -2000.0 + 10.0 * (i - 600) as f64,
            _ => {
                let t = (i - 800) as f64 * DT;
                100.0 * (t * 1.3).sin() + 20.0 * (t * 3.1).sin()
            }
        };
        let cmd = c.step(r, 0.0);
        let s = sim.step(cmd.current_a, 0.0);
        let without = plain.step(r, 0.0);
        if i > 1000 {
            if cmd.saturated {
                flagged += 1;
            } else {
                worst = worst.max((s.torque_nmm - r).abs());
            }
            // Without the stage the command differs (the field is not taken off).
            worst_plain = worst_plain.max((without.current_a - cmd.current_a).abs());
        }
    }
    assert!(worst < 1e-9, "worst tracking error {worst} N·mm");
    assert!(flagged < 500, "{flagged} samples flagged");
    assert!(
        worst_plain > 1e-3,
        "the field changes the command: {worst_plain} A"
    );
}

fn inversion_error(d: &StageDraw) -> f64 {
    let mut c = extended(false, 1.25, d);
    let f = Friction::from_amplitude_phase(12.0, &[25.0, 8.0, 4.0], &[0.3, 1.1, -0.7]).unwrap();
    let scales = Scales::of_core(&forward(), 1.25, 300.0);
    let mut sim: Simulation<Vec<f64>, Vec<f64>, 16, 24> =
        Simulation::new(forward(), f, &effects(d), DT, scales, |n| vec![0.0; n]).unwrap();
    let n = 6000;
    // An opening beyond reach both ways (so plant and compensator start from one state), then a smooth reference.
    let refs: Vec<f64> = (0..n)
        .map(|i| match i {
            0..200 => 10.0 * i as f64,
            200..600 => 2000.0 - 10.0 * (i - 200) as f64,
            600..800 => -2000.0 + 10.0 * (i - 600) as f64,
            _ => {
                let t = (i - 800) as f64 * DT;
                100.0 * (t * 1.3).sin() + 20.0 * (t * 3.1).sin()
            }
        })
        .collect();
    let thetas: Vec<f64> = (0..n)
        .map(|i| (i as f64 * DT * 2.0) % std::f64::consts::TAU)
        .collect();
    let mut currents = vec![0.0; n];
    let mut sat = 0;
    c.run_with(&refs, &thetas, |i, cmd, _| {
        currents[i] = cmd.current_a;
        // (The last samples see the reference held past its end: a kink the leads answer with a spike.)
        if i > 1000 && i + 10 < n && cmd.saturated {
            sat += 1;
        }
    });
    assert_eq!(
        sat, 0,
        "the reference is within reach after the opening: {d:?}"
    );
    let mut worst: f64 = 0.0;
    for i in 0..n {
        let s = sim.step(currents[i], thetas[i]);
        if i > 1000 && i + 10 < n {
            worst = worst.max((s.torque_nmm - refs[i]).abs());
        }
    }
    worst
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    /// The inverse's shortcut (same branch, same table cell as the last answer) gives the bits of the full search:
    /// a compensator restored from its own snapshot after every step (which drops the shortcut) commands the same.
    #[test]
    fn the_inverse_shortcut_gives_the_bits_of_the_full_search(
        seed in 0u64..1000, extended_stages in any::<bool>(), d in stage_draw()) {
        let make = || if extended_stages { extended(false, 1.25, &d) } else {
            let f = Friction::from_amplitude_phase(12.0, &[25.0, 8.0, 4.0], &[0.3, 1.1, -0.7]).unwrap();
            Comp24::new(forward(), InverseKind::Exact, f, 0.125, 1.25).unwrap()
        };
        let mut fast = make();
        let mut slow = make();
        let mut rng = common::Rng(seed);
        let (mut r, mut v) = (0.0f64, 0.0f64);
        for i in 0..3000 {
            // A smooth random reference: slowly varying slopes, reversals now and then.
            v = (v + 0.4 * (rng.uniform() - 0.5)).clamp(-3.0, 3.0);
            r = (r + v).clamp(-320.0, 320.0);
            let th = 0.002 * i as f64;
            let a = fast.step(r, th).current_a;
            let snap = slow.snapshot();
            slow.restore(&snap).unwrap();
            let b = slow.step(r, th).current_a;
            prop_assert_eq!(a.to_bits(), b.to_bits(), "sample {}", i);
        }
    }

    /// The same under sensor-like noise on the reference (a turn nearly every sample, many back over the last
    /// reversal, where the shortcut is taken from the branch below): the commands and the memory are the full
    /// search's to the bit.
    #[test]
    fn the_inverse_shortcut_under_a_dithered_reference_gives_the_bits_of_the_full_search(
        seed in 0u64..1000, extended_stages in any::<bool>(), d in stage_draw()) {
        let make = || if extended_stages { extended(false, 1.25, &d) } else {
            let f = Friction::from_amplitude_phase(12.0, &[25.0, 8.0, 4.0], &[0.3, 1.1, -0.7]).unwrap();
            Comp24::new(forward(), InverseKind::Exact, f, 0.125, 1.25).unwrap()
        };
        let mut fast = make();
        let mut slow = make();
        let mut rng = common::Rng(seed);
        for i in 0..3000 {
            let r = 250.0 * (0.004 * i as f64).sin() + 3.0 * (rng.uniform() - 0.5);
            let th = 0.002 * i as f64;
            let a = fast.step(r, th).current_a;
            let snap = slow.snapshot();
            slow.restore(&snap).unwrap();
            let b = slow.step(r, th).current_a;
            prop_assert_eq!(a.to_bits(), b.to_bits(), "sample {}", i);
            prop_assert_eq!(fast.snapshot().to_words(), slow.snapshot().to_words(), "sample {}", i);
        }
    }
}

#[test]
fn a_finite_reference_whose_friction_correction_overflows_is_a_fault_with_zero_current() {
    // Found by the property test: a reference of f64::MAX minus a friction of -7e297 is not finite.
    let f = Friction::<12>::from_coefficients(1e150, &[], &[-0.0, -6.947536949712869e297]).unwrap();
    let mut c = Comp::new(forward(), InverseKind::Exact, f, 1.7e308, 1.25).unwrap();
    let cmd = c.step(f64::MAX, f64::MAX);
    assert!(cmd.fault && cmd.current_a == 0.0, "{cmd:?}");
    assert!(cmd.volt1_v.is_finite() && cmd.volt2_v.is_finite());
    let cmd = c.step(100.0, 0.3);
    assert!(!cmd.fault && cmd.current_a.is_finite());
}

#[test]
fn the_stage_list_is_the_vocabulary_loop_order_and_refuses_a_missing_period() {
    use bmr::stages::{Scales, Stages};
    use bmr::vocabulary::loop_stages;
    let in_loop: Vec<EffectKind> = loop_stages()
        .filter_map(|s| EffectKind::from_name(s.name))
        .collect();
    let at: Vec<usize> = Stages::KINDS
        .iter()
        .map(|k| {
            in_loop
                .iter()
                .position(|x| x == k)
                .expect("a stage of an effect outside the loop")
        })
        .collect();
    assert!(
        at.windows(2).all(|w| w[0] < w[1]),
        "stage list out of loop order: {:?}",
        Stages::KINDS
    );
    for k in &in_loop {
        // An effect that carries state has a stage in the list (else its state would be lost in a snapshot).
        if !k.spec().stage.unwrap().state.is_empty() {
            assert!(
                Stages::KINDS.contains(k),
                "{k} carries state but has no stage"
            );
        }
    }
    let scales = Scales {
        full_current_a: 1.25,
        full_torque_nmm: 300.0,
        input_range: (-1.25, 1.25),
        output_range: (-300.0, 300.0),
    };
    for k in EffectKind::ALL {
        let p = Params::defaults(k.spec());
        for dt in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
            assert!(
                Stages::new(&[p], dt, scales).is_err(),
                "{k} built at dt = {dt}"
            );
        }
        let (st, _) = Stages::new(&[p], 1e-3, scales).unwrap();
        assert_eq!(
            st.has(k),
            Stages::KINDS.contains(&k),
            "{k}: its default builds its stage"
        );
    }
}

#[test]
fn every_stage_parameter_at_its_edges_gives_finite_commands_or_an_error() {
    // Each effect's stage alone, each parameter at its min, max, middle and just above its minimum (subnormals,
    // `next_up`, a tiny nonzero full scale): the compensator is refused, or every command is finite, within the
    // limit, and a fault commands zero current. A value inside the documented range where a stage divides by it
    // would show here as a non-finite command.
    let refs = [
        (0.0, 0.0),
        (250.0, 0.1),
        (-250.0, 0.2),
        (1e6, 0.3),
        (-1e-300, 0.4),
        (f64::NAN, 0.5),
        (100.0, 1e9),
        (-30.0, -1e9),
        (0.0, 0.0),
    ];
    let limit = 1.25;
    let mut built = 0;
    for kind in EffectKind::ALL {
        for spec in kind.params() {
            for v in common::edge_values(spec) {
                let Ok(params) = Params::new(kind.spec(), &[(spec.name, v)]) else {
                    continue;
                };
                let what = format!("{}:{}={v:e}", kind.name(), spec.name);
                let Ok(mut c) = compensator(false, limit).with_extensions(&[params], DT, 0.0)
                else {
                    continue;
                };
                built += 1;
                for (k, &(r, th)) in refs.iter().cycle().take(40).enumerate() {
                    let cmd = if k % 2 == 0 {
                        c.step(r, th)
                    } else {
                        c.step_ahead(r, th)
                    };
                    assert!(
                        cmd.current_a.is_finite()
                            && cmd.volt1_v.is_finite()
                            && cmd.volt2_v.is_finite(),
                        "{what}, step {k}: {cmd:?}"
                    );
                    assert!(cmd.current_a.abs() <= limit, "{what}, step {k}: {cmd:?}");
                    assert!(
                        !cmd.fault || cmd.current_a == 0.0,
                        "{what}, step {k}: {cmd:?}"
                    );
                    assert!(
                        c.predicted_torque().is_finite(),
                        "{what}, step {k}: {cmd:?}"
                    );
                }
            }
        }
    }
    assert!(built > 100, "only {built} compensators built");
}

#[test]
fn the_mean_field_is_fed_back_one_sample_late_and_taken_off_exactly() {
    // Forward: the extended simulation's core sees the field current plus feedback × its last output over the
    // full scale (300 N·mm here), the very operator stepped by hand on that input.
    let f = Friction::from_amplitude_phase(12.0, &[25.0, 8.0, 4.0], &[0.3, 1.1, -0.7]).unwrap();
    let scales = Scales::of_core(&forward(), 1.25, 300.0);
    let fx = [Params::new(
        EffectKind::NonCongruent.spec(),
        &[("curvature", 0.0), ("feedback", 0.1)],
    )
    .unwrap()];
    let mut sim: Simulation<Vec<f64>, Vec<f64>, 16, 24> =
        Simulation::new(forward(), f, &fx, DT, scales, |n| vec![0.0; n]).unwrap();
    let mut core = forward();
    let mut plain = forward();
    let mut apart = 0.0f64;
    for i in 0..3000 {
        let u = 1.1 * (i as f64 * 0.004).sin() * (i as f64 * 0.0007).cos();
        let s = sim.step(u, 0.0);
        let want = core.step(u + 0.1 / 300.0 * core.output());
        assert_eq!(s.core_nmm.to_bits(), want.to_bits(), "sample {i}");
        apart = apart.max((want - plain.step(u)).abs());
    }
    // Without the feedback the loop is another one (N·mm).
    assert!(
        apart > 5.0,
        "the mean field moves the output by {apart} N·mm only"
    );
    // Off, it is no stage at all: the compensator commands the bits of the one without the effect.
    let build = |fx: &[Params]| {
        let f = Friction::from_amplitude_phase(12.0, &[25.0, 8.0, 4.0], &[0.3, 1.1, -0.7]).unwrap();
        Comp24::new(forward(), InverseKind::Exact, f, 0.125, 1.25)
            .unwrap()
            .with_extensions(fx, DT, 300.0)
            .unwrap()
    };
    let off = [Params::new(
        EffectKind::NonCongruent.spec(),
        &[("curvature", 0.5), ("feedback", 0.0)],
    )
    .unwrap()];
    let map_only = [Params::new(EffectKind::NonCongruent.spec(), &[("curvature", 0.5)]).unwrap()];
    let (mut a, mut b) = (build(&off), build(&map_only));
    assert!(a.stages().mean_field.is_none());
    for i in 0..2000 {
        let r = 250.0 * (i as f64 * 0.003).sin();
        let th = 0.002 * i as f64;
        assert_eq!(a.step(r, th), b.step(r, th));
    }
    // On alone, it is a stage (the extended path) and the vocabulary's effect is on.
    let c = build(&fx);
    assert!(c.stages().has(EffectKind::NonCongruent));
    assert!(c.stages().mean_field.is_some() && c.stages().output_map.is_none());
}
