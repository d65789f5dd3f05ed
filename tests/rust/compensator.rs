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
        let Some(f) = Friction::<12>::from_coefficients(c0, &a, &b) else { return Ok(()) };
        prop_assert!(c0.abs() + a.iter().chain(&b).map(|x| x.abs()).sum::<f64>() <= 1e150);
        let fwd = forward();
        let inv = if paper { InverseKind::Paper(fwd.paper_inverse().unwrap()) } else { InverseKind::Exact };
        let Ok(mut c) = Comp::new(fwd, inv, f, gain, 1.25) else { return Ok(()) };
        for (r, th) in refs {
            let cmd = c.step(r, th);
            prop_assert!(cmd.current_a.is_finite() && cmd.volt1_v.is_finite() && cmd.volt2_v.is_finite(),
                         "{:?}", cmd);
            prop_assert!(!cmd.fault || cmd.current_a == 0.0);
            prop_assert_eq!(cmd.fault, !(r.is_finite() && th.is_finite()));
            prop_assert_eq!(c.forward().state().input(), cmd.current_a);
        }
    }
}

#[test]
fn friction_whose_sum_overflows_and_gains_needing_infinite_volts_are_refused() {
    // Used to give current NaN with fault unset (friction inf - inf) and infinite volts without a fault.
    assert!(
        Friction::<12>::from_coefficients(0.0, &[1.7e308, 0.0, -1.7e308], &[1.7e308, 0.0, 1.7e308])
            .is_none()
    );
    assert!(Friction::<12>::from_coefficients(1e150, &[1e140], &[]).is_none());
    assert!(Friction::<12>::from_coefficients(5e149, &[2.5e149], &[2.5e149]).is_some());
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
    assert!(Friction::<3>::from_coefficients(0.0, &[1.0; 4], &[]).is_none());
    assert!(f.eval(f64::NAN).is_nan());
}
