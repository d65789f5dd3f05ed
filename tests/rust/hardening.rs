//! Hostile sizes and values: documented limits checked before allocation, clear range errors instead of wrong
//! output, whole-table snapshot fingerprints, state serialisation that refuses damaged words.
mod common;

use bmr::limits::{MAX_CURVES, MAX_GENERATED_SAMPLES, MAX_NODES, MAX_TABLE_VALUES};
use bmr::plant::{
    Effect, EffectKind, SETTABLE, VirtualActuator, VirtualDevice, device_preset, preset,
};
use bmr::{BuildOptions, FamilyKind, Hysteresis, Initial, TableError};

type Op = Hysteresis<Vec<f64>, 16>;
type Curves = Vec<common::Curve>;

fn build(a: &[common::Curve], d: &[common::Curve]) -> Result<Op, TableError> {
    Op::from_curve_data(a, d, &BuildOptions::default(), Initial::Negative)
}

/// What a result is, without the (huge) tables of a successful build.
fn outcome(r: Result<Op, TableError>) -> Result<(), TableError> {
    r.map(|_| ())
}

/// `count` first-order curves per family of a congruent table on `[-scale, scale]` with outputs scaled by
/// `out_scale`, each with `samples` points (at positions that differ from curve to curve).
fn scaled_curves(count: usize, samples: usize, scale: f64, out_scale: f64) -> (Curves, Curves) {
    let shape = |x: f64| out_scale * (x + 1.0); // output as a function of the normalised input
    let mut asc = Vec::new();
    let mut desc = Vec::new();
    for c in 0..count {
        let r = -1.0 + 2.0 * c as f64 / count as f64;
        let warp = 1.0 + c as f64 / count as f64;
        let u: Vec<f64> = (0..samples)
            .map(|k| r + (1.0 - r) * (k as f64 / (samples - 1) as f64).powf(warp))
            .collect();
        let y: Vec<f64> = u.iter().map(|&x| shape(x)).collect();
        asc.push((u.iter().map(|x| x * scale).collect(), y));
        let top = -r;
        let u: Vec<f64> = (0..samples)
            .map(|k| top - (top + 1.0) * k as f64 / (samples - 1) as f64)
            .collect();
        let y: Vec<f64> = u.iter().map(|&x| shape(x)).collect();
        desc.push((u.iter().map(|x| x * scale).collect(), y));
    }
    (asc, desc)
}

#[test]
fn curve_count_is_bounded_before_the_table_is_allocated() {
    // 100 001 curves asked for ~80 GB (table = curves × nodes) and aborted the process.
    let (a, d) = scaled_curves(100_001, 2, 1.0, 1.0);
    match outcome(build(&a, &d)) {
        Err(TableError::TooLarge {
            family: Some(FamilyKind::Ascending),
            limit,
        }) => {
            assert_eq!(limit.requested, 100_001);
            assert_eq!(limit.limit, MAX_CURVES);
        }
        other => panic!("expected a size limit error, got {other:?}"),
    }
}

#[test]
fn table_values_are_bounded_and_max_nodes_is_limited() {
    // Below the curve limit but with a grid so fine that curves × nodes exceeds the value limit.
    let (a, d) = scaled_curves(300, 300, 1.0, 1.0);
    let opts = BuildOptions {
        max_nodes: MAX_NODES,
        ..BuildOptions::default()
    };
    match outcome(Op::from_curve_data(&a, &d, &opts, Initial::Negative)) {
        Err(TableError::TooLarge { limit, .. }) => {
            assert_eq!(limit.limit, MAX_TABLE_VALUES);
            assert!(limit.requested > MAX_TABLE_VALUES);
        }
        other => panic!("expected a size limit error, got {other:?}"),
    }
    let opts = BuildOptions {
        max_nodes: usize::MAX,
        ..BuildOptions::default()
    };
    let (a, d) = scaled_curves(3, 5, 1.0, 1.0);
    assert!(matches!(
        outcome(Op::from_curve_data(&a, &d, &opts, Initial::Negative)),
        Err(TableError::TooLarge { family: None, .. })
    ));
    // The largest allowed number of curves still builds.
    let (a, d) = scaled_curves(2000, 2, 1.0, 1.0);
    let h = build(&a, &d).unwrap();
    assert_eq!(h.ascending().curves(), 2000);
}

#[test]
fn inputs_beyond_the_supported_magnitude_are_a_range_error() {
    // At 4e154 the strip interpolation `(r_next - r_j) * (u - m)` overflowed and the operator returned inf.
    for scale in [4e154, 1e200, 1e308] {
        let (a, d) = scaled_curves(5, 9, scale, 1.0);
        let err = outcome(build(&a, &d)).unwrap_err();
        assert!(
            matches!(err, TableError::OutOfRange { what: "input", .. }),
            "{scale}: {err}"
        );
        let msg = err.to_string();
        assert!(msg.contains("supported magnitude"), "{msg}");
        assert!(!msg.contains("grid nodes"), "{msg}");
    }
    let (a, d) = scaled_curves(5, 9, 1.0, 1e300);
    assert!(matches!(
        outcome(build(&a, &d)),
        Err(TableError::OutOfRange { what: "output", .. })
    ));
}

#[test]
fn tables_at_the_magnitude_limit_give_finite_outputs_and_exact_inverses() {
    // Inputs and outputs just inside ±1e150: every step must stay finite.
    let (a, d) = scaled_curves(7, 11, 0.99e150, 1e149);
    let mut h = build(&a, &d).unwrap();
    let mut rng = common::Rng(5);
    let (y_lo, y_hi) = h.output_range();
    for u in common::random_history(&mut rng, 60, 7) {
        let y = h.step(u * 0.99e150);
        assert!(y.is_finite(), "output {y} at input {}", u * 0.99e150);
        // And the exact inverse to a random reachable target: a finite input that reproduces it.
        let target = y_lo + (y_hi - y_lo) * rng.uniform();
        let mut probe = h.clone();
        let inv = probe.step_inverse(target);
        assert!(inv.input.is_finite(), "inverse {inv:?} of {target}");
        if !inv.saturated {
            let mut check = h.clone();
            let back = check.step(inv.input);
            assert!(
                (back - target).abs() <= 1e-9 * (y_hi - y_lo),
                "{back} vs {target}"
            );
        }
    }
}

#[test]
fn reversals_closer_than_the_resolution_name_the_users_curves() {
    // Two ascending curves 1e-13 apart used to fail with "reversal is not a grid node (at index 1)", an index
    // after sorting; the error names both curves in the caller's numbering and their inputs.
    let (mut a, d) = scaled_curves(5, 9, 1.0, 1.0);
    let mut near = a[2].clone();
    near.0[0] += 1e-13;
    a.push(near);
    match outcome(build(&a, &d)) {
        Err(TableError::ReversalsTooClose {
            family: FamilyKind::Ascending,
            curve: 5,
            other: 2,
            ..
        }) => {}
        other => panic!("expected curves 2 and 5 to be named, got {other:?}"),
    }
    let (a, mut d) = scaled_curves(5, 9, 1.0, 1.0);
    let mut near = d[3].clone();
    near.0[0] -= 1e-13;
    d.insert(1, near);
    let err = outcome(build(&a, &d)).unwrap_err();
    match err {
        TableError::ReversalsTooClose {
            family: FamilyKind::Descending,
            curve,
            other,
            input,
            other_input,
            ..
        } => {
            assert_eq!((other, curve), (1, 4));
            // Descending inputs in the caller's units and sign.
            assert!(
                (input + 0.2).abs() < 1e-9 && (other_input + 0.2).abs() < 1e-9,
                "{err}"
            );
        }
        other => panic!("expected descending curves 1 and 4, got {other:?}"),
    }
    assert!(err.to_string().contains("curves 1 and 4"), "{err}");
}

#[test]
fn snapshot_of_a_table_with_one_value_changed_is_refused() {
    // The fingerprint used to sample 5 table values: a table with one output changed by 1e-6 accepted it.
    let (a, d) = common::measure_first_order(40, 9);
    let h1 = build(&a, &d).unwrap();
    let s = h1.snapshot();
    for (family, curve) in [(0usize, 3usize), (1, 5)] {
        let (mut a2, mut d2) = (a.clone(), d.clone());
        let target = if family == 0 { &mut a2 } else { &mut d2 };
        let mid = target[curve].1.len() / 2;
        target[curve].1[mid] += if family == 0 { 1e-6 } else { -1e-6 };
        let mut h2 = build(&a2, &d2).unwrap();
        assert_eq!(h2.restore(&s), Err(TableError::ForeignState));
    }
    let mut same = build(&a, &d).unwrap();
    assert_eq!(same.restore(&s), Ok(()));
}

#[test]
fn state_words_round_trip_and_damaged_words_are_errors() {
    let (a, d) = common::measure_first_order(40, 9);
    let mut h = build(&a, &d).unwrap();
    let mut rng = common::Rng(11);
    // Enough reversals to fill the 16-point memory and merge.
    let hist = common::random_history(&mut rng, 80, 5);
    for &u in &hist {
        h.step(u);
    }
    let words = h.snapshot().to_words();
    let mut fresh = build(&a, &d).unwrap();
    let st = fresh.state_from_words(&words).unwrap();
    fresh.restore(&st).unwrap();
    assert_eq!(fresh.snapshot().to_words(), words);
    let tail = common::random_history(&mut rng, 30, 5);
    for &u in &tail {
        assert_eq!(fresh.step(u).to_bits(), h.step(u).to_bits());
    }
    // Every single-word corruption is either refused or gives a state with finite outputs: never a panic.
    for i in 0..words.len() {
        for bad in [0, u64::MAX, 1 << 62, f64::NAN.to_bits(), 1e300f64.to_bits()] {
            let mut w = words.clone();
            w[i] = bad;
            if let Ok(st) = fresh.state_from_words(&w) {
                let mut g = build(&a, &d).unwrap();
                g.restore(&st).unwrap();
                for &u in &tail {
                    g.step(u);
                }
            }
        }
    }
    assert!(fresh.state_from_words(&words[..words.len() - 1]).is_err());
    assert!(fresh.state_from_words(&[]).is_err());
}

#[test]
fn simulator_state_round_trips_with_every_effect_on() {
    let mut config = preset("bmr2013").unwrap();
    for spec in [
        "coil_lag:tau_s=0.01",
        "time_delay:delay_s=0.004",
        "thermal_drift",
        "friction_current",
        "friction_harmonics",
        "torque_ripple",
        "sensor_drift",
        "non_congruent",
    ] {
        config
            .effects
            .insert(bmr::plant::Effect::parse(spec).unwrap());
    }
    let mut a = VirtualActuator::new(config.clone(), 3).unwrap();
    let cmd: Vec<f64> = (0..700).map(|k| 1.2 * (k as f64 * 0.021).sin()).collect();
    a.run(&cmd);
    let words = a.save_state();
    let mut b = VirtualActuator::new(config.clone(), 3).unwrap();
    b.load_state(&words).unwrap();
    assert_eq!(a.run(&cmd), b.run(&cmd));
    // Damaged or foreign words are refused and leave the actuator as it was.
    let before = b.save_state();
    assert!(b.load_state(&words[..words.len() - 1]).is_err());
    let mut longer = words.clone();
    longer.push(0);
    assert!(b.load_state(&longer).is_err());
    let mut nan = words.clone();
    nan[5] = f64::NAN.to_bits();
    assert!(b.load_state(&nan).is_err());
    assert_eq!(b.save_state(), before);
    let plain = VirtualActuator::new(preset("bmr2013").unwrap(), 3).unwrap();
    let mut plain2 = plain.clone();
    assert!(
        plain2.load_state(&words).is_err(),
        "delay line of another configuration"
    );
    for i in 0..words.len() {
        let mut w = words.clone();
        w[i] = u64::MAX;
        let mut c = VirtualActuator::new(config.clone(), 3).unwrap();
        if c.load_state(&w).is_ok() {
            for s in c.run(&cmd).torque_nmm {
                assert!(!s.is_nan());
            }
        }
    }
}

#[test]
fn angle_preview_is_bounded() {
    let a = VirtualActuator::new(preset("bmr2013").unwrap(), 0).unwrap();
    assert!(a.theta_ahead(1usize << 62).is_err());
    assert!(a.theta_ahead(MAX_GENERATED_SAMPLES + 1).is_err());
    assert_eq!(a.theta_ahead(10).unwrap().len(), 10);
}

#[test]
fn a_branch_over_flat_tables_stays_continuous_and_invertible() {
    // Ascending curves flat after their reversal while the descending ones fall (families that disagree, as
    // after a running maximum clips measured dips): no scale of the flat tables can close the branch on its
    // target. It used to stay flat and jump at the wipe-out, and the inverse returned the jump's input for
    // targets inside it. Now the branch is a straight line to its target.
    let a: Curves = vec![
        (vec![-1.0, 0.0, 1.0], vec![0.0, 0.0, 2.0]),
        (vec![0.0, 0.6, 1.0], vec![1.0, 1.0, 2.0]),
    ];
    let d: Curves = vec![
        (vec![1.0, -1.0], vec![2.0, 0.0]),
        (vec![0.0, -1.0], vec![1.0, 0.0]),
    ];
    let mut h = build(&a, &d).unwrap();
    h.step(0.5);
    let y_max = h.output();
    let y_min = h.step(0.2);
    assert!(y_max - y_min > 0.1, "{y_min} .. {y_max}");
    let mut prev = y_min;
    let steps = 300;
    for k in 1..=steps {
        let u = 0.2 + 0.3 * k as f64 / steps as f64;
        let before = h.clone();
        let y = h.step(u);
        assert!(y >= prev, "not monotone at {u}");
        assert!(
            y - prev <= 4.0 * (y_max - y_min) / steps as f64,
            "jump of {} at {u}",
            y - prev
        );
        // Every output on the way is reachable by the exact inverse.
        let mut probe = before;
        let inv = probe.step_inverse(y);
        assert!(
            !inv.saturated && (inv.input - u).abs() < 1e-9,
            "{inv:?} for {y} at {u}"
        );
        prev = y;
    }
    assert_eq!(h.output(), y_max, "return-point memory");
    // The state words carry the straight branch.
    let words = h.snapshot().to_words();
    assert_eq!(h.state_from_words(&words).unwrap().to_words(), words);
}

#[test]
fn merging_a_full_memory_keeps_the_output_continuous_at_later_wipe_outs() {
    // A full 6-point memory merges the nested pair (a2, b2) away; rising again past a3 (the reversal above the
    // merged pair) used to continue on b1's branch, which does not pass through a3's output: the output jumped
    // there and the exact inverse could not reach the outputs inside the jump.
    let (a, d) = common::measure_first_order(40, 9);
    let mut h: Hysteresis<Vec<f64>, 6> =
        Hysteresis::from_curve_data(&a, &d, &BuildOptions::default(), Initial::Negative).unwrap();
    let path = [0.9, -0.8, 0.6, -0.2, 0.55, 0.3]; // a1, b1, a2, b2 (small excursion a2-b2), a3, b3
    for &u in &path {
        let steps = 40;
        let from = h.state().input();
        for s in 1..=steps {
            h.step(from + (u - from) * s as f64 / steps as f64);
        }
    }
    assert_eq!(
        h.state().history().len(),
        6,
        "memory full: [anchor, a1, b1, a2, b2, a3] + turning at b3"
    );
    let (y_lo, y_hi) = h.output_range();
    let span = y_hi - y_lo;
    // Rise from b3 through a3 (0.55) up to a1 (0.9): the merge happens at the turn.
    let mut prev = (h.state().input(), h.output());
    let n = 2000;
    let mut steepest = 0.0f64;
    for k in 1..=n {
        let u = 0.3 + 0.6 * k as f64 / n as f64;
        let before = h.clone();
        let y = h.step(u);
        steepest = steepest.max((y - prev.1) / (u - prev.0));
        assert!(
            y >= prev.1 && y - prev.1 <= 0.01 * span,
            "step of {} at {u} (from {} at {})",
            y - prev.1,
            prev.1,
            prev.0
        );
        let mut probe = before;
        let inv = probe.step_inverse(y);
        assert!(
            !inv.saturated && (probe.output() - y).abs() <= 1e-9 * span,
            "inverse of {y} at {u}: {inv:?}"
        );
        prev = (u, y);
    }
    assert!(steepest.is_finite());
}

#[test]
fn a_curve_leaving_the_major_loop_is_refused() {
    // Found by fuzzing (table_build): an ascending family whose second curve climbs to 1e70 while the major
    // branch ends at 814.875 was accepted; the derived descending family then held -1e70 and the operator did not
    // rebuild from its own curves.
    let asc: Curves = vec![
        (vec![-100000.0, -272.0625], vec![-273.125, 814.875]),
        (vec![-285.125, -273.125], vec![272.0, 1.0000000000000002e70]),
    ];
    let err = outcome(build(&asc, &[])).unwrap_err();
    assert!(
        matches!(
            err,
            TableError::OutsideMajorLoop {
                family: FamilyKind::Ascending,
                curve: 1,
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("outside the major loop"), "{err}");
    // The same family inside the loop builds and rebuilds from its own curves.
    let asc: Curves = vec![
        (vec![-100000.0, -272.0625], vec![-273.125, 814.875]),
        (vec![-285.125, -273.125], vec![272.0, 800.0]),
    ];
    let h = build(&asc, &[]).unwrap();
    let (a, d) = h.curves();
    outcome(build(&a, &d)).unwrap();
}

#[test]
fn an_actuator_started_just_below_angle_zero_saves_a_state_it_can_load() {
    // Found by fuzzing (plant_config): `drive.theta0_rad` of -1e-17 wrapped to exactly 2π, outside the state's
    // [0, 2π), so the actuator's own saved state (and its pickle) was refused.
    for theta0 in [
        -1e-17,
        -5e-324,
        -0.0,
        core::f64::consts::TAU,
        -core::f64::consts::TAU,
    ] {
        let mut config = preset("bmr2013").unwrap();
        config.set("drive.theta0_rad", theta0).unwrap();
        let mut act = VirtualActuator::new(config, 3).unwrap();
        let saved = act.save_state();
        act.load_state(&saved).unwrap();
        let s = act.step(0.2);
        assert!(
            (0.0..core::f64::consts::TAU).contains(&s.theta_rad),
            "{theta0}: {}",
            s.theta_rad
        );
        act.reset();
        act.load_state(&act.save_state()).unwrap();
    }
}

#[test]
fn a_sensor_resolution_finer_than_round_off_quantises_nothing() {
    // Found by fuzzing (plant_config): a force resolution of 5e-324 N (subnormal, accepted as >= 0) made
    // force / resolution overflow, and the measured torque was infinite. A step that fine quantises nothing.
    for resolution in [5e-324, 1e-300, 1e-17] {
        let mut config = preset("bmr2013").unwrap();
        config.set("sensor.resolution_n", resolution).unwrap();
        config.set("sensor.noise_n", 0.0).unwrap();
        let mut act = VirtualActuator::new(config, 5).unwrap();
        for i in 0..50 {
            let s = act.step(0.02 * f64::from(i));
            assert!(s.torque_nmm.is_finite(), "{resolution:e}: {s:?}");
            assert!(
                (s.torque_nmm - s.torque_true_nmm).abs() < 1.0,
                "{resolution:e}: measured {} true {}",
                s.torque_nmm,
                s.torque_true_nmm
            );
        }
    }
    for name in ["piezo", "ferroelectric"] {
        let mut config = device_preset(name).unwrap();
        config.set("resolution", 5e-324).unwrap();
        config.set("noise", 0.0).unwrap();
        let mut dev = VirtualDevice::new(config, 5).unwrap();
        for i in 0..50 {
            let s = dev.step(0.5 * (f64::from(i) * 0.3).sin());
            assert!(s.output.is_finite(), "{name}: {s:?}");
        }
    }
}

#[test]
fn an_inverse_to_a_via_points_output_stays_on_the_first_piece() {
    // A merged branch whose first piece ends at its via point, over a table that is flat beyond it: a target
    // equal to the via point's output put `dy / k` a hair above the piece's increment by round-off, and the
    // search ran past the via point to the closure target (an output error of 40 % of the span). Found by
    // fuzzing (fuzz/corpus/table_build/regression-via-point-inverse); the steps and targets are that input's.
    let a: Curves = vec![
        (
            vec![
                -0.001,
                -0.0009966666666666668,
                -0.0009933333333333333,
                -0.00099,
            ],
            vec![
                -0.9964904249637598,
                -0.9964904249637598,
                -0.9964751659418631,
                -0.9962581487415546,
            ],
        ),
        (
            vec![-0.0009966666666666668, -0.0009933333333333333, -0.00099],
            vec![
                -0.9962734077634513,
                -0.9962581487415546,
                -0.9962581487415546,
            ],
        ),
        (
            vec![-0.0009933333333333333, -0.00099],
            vec![-0.9962581487415546, -0.9962581487415546],
        ),
    ];
    let d: Curves = vec![
        (
            vec![
                -0.00099,
                -0.0009933333333333333,
                -0.0009966666666666668,
                -0.001,
            ],
            vec![
                -0.9962581487415546,
                -0.9962581487415546,
                -0.9962734077634513,
                -0.9964904249637598,
            ],
        ),
        (
            vec![-0.0009933333333333333, -0.0009966666666666668, -0.001],
            vec![
                -0.9964751659418631,
                -0.9964904249637598,
                -0.9964904249637598,
            ],
        ),
        (
            vec![-0.0009966666666666668, -0.001],
            vec![-0.9964904249637598, -0.9964904249637598],
        ),
    ];
    // (is an inverse, input or target)
    let ops: &[(bool, f64)] = &[
        (true, -0.9964021599993218),
        (true, -0.9964021599993218),
        (false, 1.0000000000000003e+130),
        (true, -0.9962447587005099),
        (true, -0.9962447587005099),
        (false, -0.0009894235294117648),
        (true, -0.9962453031062126),
        (true, -0.9962447587005099),
        (true, -0.9962447587005099),
        (true, -0.9964532490719907),
        (true, -0.9963802987078202),
        (false, -0.0009952529640650035),
        (true, -0.9962360056775701),
        (true, -0.9964721161321272),
        (true, -0.9964721161321272),
        (true, -0.9963458140090856),
        (true, -0.9963801626063945),
        (true, -0.9963803072141593),
        (true, -0.9964775474296462),
        (true, -0.9963799074162213),
        (true, -0.9964611174356635),
        (true, -0.9962753645086122),
        (true, -0.9963802731888028),
        (true, -0.9964754548702262),
        (true, -0.9963453206414176),
        (true, -0.9963801626063945),
        (true, -0.9963802987078202),
        (false, -0.0009952529640650035),
        (true, -0.9963802987078202),
        (false, -0.0009952507667658503),
        (true, -0.9963802987078202),
        (true, -0.9964109045159225),
        (true, -0.9964109045159225),
        (true, -0.9963194443578579),
        (true, -0.9964721161321272),
        (true, -0.9964721161321272),
        (true, -0.9963458140090856),
        (true, -0.9963801626063945),
        (true, -0.9963824763306313),
        (true, -0.9964775474296462),
        (true, -0.9963799074162213),
        (true, -0.9964605730299607),
        (true, -0.9962753645086122),
        (true, -0.9963802731888028),
        (true, -0.9964754548702262),
        (true, -0.9963453206414176),
        (true, -0.9963801626063945),
        (true, -0.9963802987078202),
        (false, -0.0009952588235294117),
        (true, -0.9963801626063945),
        (false, -0.0009952613870450903),
        (true, -0.9963802987078202),
    ];
    replay_exact_inverses(
        &a,
        &d,
        &BuildOptions::default(),
        Initial::Descending(-1028.0625),
        ops,
    );
}

/// Steps (`false`) and exact inverses (`true`) replayed on an operator of 8 reversals built from `a`, `d` with
/// `opts`: every reachable target is hit to 1e-9 of the output span (the fuzzing invariant).
fn replay_exact_inverses(
    a: &Curves,
    d: &Curves,
    opts: &BuildOptions,
    start: Initial,
    ops: &[(bool, f64)],
) {
    let mut h = Hysteresis::<Vec<f64>, 8>::from_curve_data(a, d, opts, start).unwrap();
    let (y_lo, y_hi) = h.output_range();
    for (i, &(inverse, v)) in ops.iter().enumerate() {
        if !inverse {
            h.step(v);
            continue;
        }
        let mut forward = h.clone();
        let inv = h.step_inverse(v);
        if !inv.saturated {
            let y = forward.step(inv.input);
            assert!(
                (y - v).abs() <= 1e-9 * (y_hi - y_lo),
                "operation {i}: forward(inverse({v})) = {y}"
            );
        }
    }
}

#[test]
fn a_second_piece_over_a_flat_stretch_of_a_noisy_table_is_a_straight_line() {
    // A merge left a second branch piece whose Everett increment (8.5e-14) was round-off of a flat stretch of a
    // noisy table, 6e-9 of the Everett values it is the difference of: its scale (1.2e9) magnified their
    // rounding into the output and the exact inverse missed by 1.1e-9 of the span. Such a piece is now a
    // straight line to its target. Found by fuzzing (fuzz/corpus/table_build/regression-unresolved-increment).
    let a: Curves = vec![
        (
            vec![
                -0.001,
                -0.0009966666666666668,
                -0.0009933333333333333,
                -0.00099,
            ],
            vec![
                -1.0000000258136734,
                -1.0000000259403372,
                -0.9999847669184405,
                -0.9997406204504341,
            ],
        ),
        (
            vec![-0.0009966666666666668, -0.0009933333333333333, -0.00099],
            vec![-0.9997829700315911, -0.9997677108584896, -0.999740583708451],
        ),
        (
            vec![-0.0009933333333333333, -0.00099],
            vec![-0.9997677108584896, -0.9997405838335314],
        ),
    ];
    let d: Curves = vec![
        (
            vec![
                -0.00099,
                -0.0009933333333333333,
                -0.0009966666666666668,
                -0.001,
            ],
            vec![
                -0.9997406225680934,
                -0.999767749718132,
                -0.9997830087400287,
                -1.0000000166178862,
            ],
        ),
        (
            vec![-0.0009933333333333333, -0.0009966666666666668, -0.001],
            vec![
                -0.9999847280587981,
                -1.0000000073468924,
                -0.9999999870806948,
            ],
        ),
        (
            vec![-0.0009966666666666668, -0.001],
            vec![-1.0000000086459875, -1.000000008646779],
        ),
    ];
    // (is an inverse, input or target)
    let ops: &[(bool, f64)] = &[
        (true, -0.9997256687302855),
        (true, -0.9997256687302855),
        (true, -0.9997256687302855),
        (true, -0.9998764492043181),
        (true, -0.9998384405931409),
        (true, -0.9999795787926559),
        (true, -0.9999795787926559),
        (true, -0.9999722829632672),
        (true, -0.9998768861940992),
        (true, -0.9998770476903226),
        (true, -0.9999856444008131),
        (true, -0.9998766012007637),
        (true, -0.999967295579896),
        (true, -0.9997598489309892),
        (true, -0.9998770096912112),
        (true, -0.9999833074554619),
        (true, -0.9998379751040263),
        (true, -0.9998768861940992),
        (true, -0.9998770381905447),
        (false, -0.0009937529411764706),
        (true, -0.9998770381905447),
        (false, -0.0009952507667658503),
        (true, -0.9998774134317698),
    ];
    replay_exact_inverses(&a, &d, &BuildOptions::default(), Initial::Positive, ops);
}

#[test]
fn an_inverse_inside_a_flat_stretch_does_not_step_back() {
    // The output sat on a flat stretch of a falling branch, 2e-13 above its target (the closure target's output):
    // the first input of the branch reaching the target lay behind the current input, and stepping back there
    // turned the input and left the branch (1135 off). The answer now stays on the side the output moves to.
    // Found by fuzzing (fuzz/corpus/table_build/regression-flat-stretch-step-back); tables and options are that
    // input's (tolerances far beyond the defaults).
    let a: Curves = vec![
        (
            vec![19.3125, -575.6875, -1356.1875, 1959.625],
            vec![1959.125, -824.375, -111.375, 979.8125],
        ),
        (
            vec![-1356.1875, 1959.625, 1703.625, 1955.0, 1952.5, 83.3125],
            vec![-1356.1875, -0.0625, -0.0625, 979.8125, 1962.375, 1953.75],
        ),
        (
            vec![
                -824.375, -111.375, 979.8125, 989.75, 986.6875, 455.625, 22.625, 83.8125,
            ],
            vec![
                -940.1875, 455.625, 1959.125, 1959.625, 1953.75, 775.625, 140.75, 862.625,
            ],
        ),
    ];
    let d: Curves = vec![
        (
            vec![
                -12.1875, -0.0625, 991.9375, -933.3125, 455.625, 1959.125, -824.375, -111.375,
            ],
            vec![
                131.8125, 979.8125, 1955.8125, 1953.75, 848.0625, 989.75, -933.3125, 455.625,
            ],
        ),
        (vec![1959.625, 167.625], vec![979.8125, 989.75]),
        (
            vec![
                -8.375, -0.0625, -111.375, 979.8125, 989.75, 986.6875, 455.625,
            ],
            vec![
                848.0625, 989.75, -933.3125, 455.625, 1959.125, -824.375, -111.375,
            ],
        ),
    ];
    let opts = BuildOptions {
        monotone_tolerance: 131.8125,
        reach_tolerance: 979.8125,
        closure_tolerance: 1955.8125,
        node_tolerance: 0.0,
        max_nodes: 1503,
        subdivisions: 1,
    };
    // (is an inverse, input or target)
    let ops: &[(bool, f64)] = &[
        (true, -250.57941162165253),
        (true, -1347.9252573529411),
        (true, 671.1910987926299),
        (true, -1347.9252573529411),
        (true, -1347.9252573529411),
        (true, -246.29290441176477),
        (true, 1218.8781249999997),
        (false, 1964.3125),
        (true, -250.3222211890593),
        (true, -246.29290441176477),
        (true, -242.77796849965648),
        (true, 99.32817192149218),
        (false, -575.5),
        (false, 986.6875),
        (true, -1277.797999399176),
        (true, -246.9787455653468),
        (false, 1490.4325981345846),
        (false, 1956.7258460173953),
        (false, 989.75),
        (false, 1967.9375),
        (true, 99.32817192149218),
        (false, -575.5),
        (false, 986.6875),
        (true, -1277.797999399176),
        (true, -1574.767218900206),
        (false, 989.75),
        (false, 1964.3125),
        (true, -250.3222211890593),
        (true, -246.29290441176477),
        (true, -242.77796849965648),
        (true, 99.32817192149218),
        (false, -575.5),
        (false, 986.6875),
        (true, -1315.9907786392766),
        (false, -0.0625),
        (true, -250.57941162165253),
        (true, -1347.9252573529411),
        (true, 671.1910987926299),
        (true, -1347.9252573529411),
        (true, -1347.9252573529411),
        (true, -246.29290441176477),
        (true, 1218.8781249999997),
        (false, 1964.3125),
        (true, -250.3222211890593),
        (true, -246.29290441176477),
        (true, -242.77796849965648),
        (true, 99.32817192149218),
        (false, -575.5),
        (false, 986.6875),
        (true, -1277.797999399176),
        (true, -246.9787455653468),
        (false, 1490.4325981345846),
        (false, 1956.7258460173953),
        (false, 989.75),
        (false, -12.1875),
        (false, -0.0625),
        (false, -933.3125),
        (true, -1277.797999399176),
        (true, -246.63582498855567),
        (true, 653.5306890878921),
        (true, 1142.5354315918971),
        (false, 131.8125),
        (false, -735.9355147058824),
        (true, -250.57941162165253),
        (true, -1347.9252573529411),
        (true, 671.1910987926299),
        (true, -1347.9252573529411),
        (true, 572.4299726768138),
        (true, -1277.797999399176),
        (true, -246.63582498855567),
        (true, 653.5306890878921),
        (true, 1142.5354315918971),
        (false, 131.8125),
        (false, -735.9355147058824),
        (false, 455.625),
        (true, -246.9787455653468),
        (false, 1490.4325981345846),
        (false, 1956.7258460173953),
        (false, 989.75),
        (false, -12.1875),
        (false, -0.0625),
        (false, -933.3125),
        (true, -1277.797999399176),
        (true, -246.63582498855567),
        (true, 653.5306890878921),
        (true, 1142.5354315918971),
        (false, 131.8125),
        (false, -735.9355147058824),
        (true, -250.57941162165253),
        (true, -1347.9252573529411),
        (true, 671.1910987926299),
        (true, -250.57941162165253),
        (true, -1347.9252573529411),
        (true, 671.1910987926299),
        (true, -1347.9252573529411),
        (true, -1347.9252573529411),
        (true, -246.29290441176477),
        (true, 1218.8781249999997),
        (false, 1964.3125),
        (true, -250.3222211890593),
        (true, -246.29290441176477),
        (true, 1218.8781249999997),
        (true, -250.57941162165253),
        (true, -1347.9252573529411),
        (true, 671.1910987926299),
        (true, -1347.9252573529411),
        (true, -1347.9252573529411),
        (true, -246.29290441176477),
        (true, 1218.8781249999997),
        (false, 1964.3125),
        (true, -250.3222211890593),
        (true, -246.29290441176477),
        (true, -242.77796849965648),
        (true, 99.32817192149218),
        (false, -575.5),
        (false, 986.6875),
        (true, -1277.797999399176),
        (true, -246.9787455653468),
        (false, 1490.4325981345846),
        (false, 220.45136558709078),
        (true, -250.3222211890593),
        (true, -246.29290441176477),
        (true, -242.77796849965648),
        (true, 99.32817192149218),
        (false, -575.5),
        (false, -0.0625),
        (true, -250.57941162165253),
        (true, -1347.9252573529411),
        (true, 671.1910987926299),
        (true, -1347.9252573529411),
        (true, -1347.9252573529411),
        (true, -246.29290441176477),
        (true, 1218.8781249999997),
        (false, -0.0625),
        (false, -933.3125),
        (true, -1277.797999399176),
        (true, -246.63582498855567),
        (true, 653.5306890878921),
        (true, 1142.5354315918971),
        (false, 131.8125),
        (false, -735.9355147058824),
        (false, 455.625),
        (true, -1574.767218900206),
        (false, 989.75),
        (false, 1964.3125),
        (true, -250.3222211890593),
        (true, -246.29290441176477),
        (true, -242.77796849965648),
        (true, 209.062756494621),
        (true, 62.16415441176491),
        (true, 62.16415441176491),
        (true, 288.7917905985348),
        (false, -0.0625),
        (true, 1142.5354315918971),
        (false, 131.8125),
        (false, -735.9355147058824),
        (false, 455.625),
        (true, -1574.767218900206),
        (false, 989.75),
        (false, 1964.3125),
        (true, -250.3222211890593),
        (true, -246.29290441176477),
        (true, -242.77796849965648),
        (true, 99.32817192149218),
        (false, -575.5),
        (false, 986.6875),
        (true, 1218.8781249999997),
        (false, 15.9375),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, 2291.2062499999997),
        (true, -250.57941162165253),
        (true, -1347.9252573529411),
        (true, 671.1910987926299),
        (true, -1347.9252573529411),
        (true, -1347.9252573529411),
        (true, -246.29290441176477),
        (true, 1218.8781249999997),
        (false, 1964.3125),
        (true, -250.3222211890593),
        (true, -246.29290441176477),
        (true, -242.77796849965648),
        (true, 99.32817192149218),
        (false, -575.5),
        (false, 986.6875),
        (true, -1277.797999399176),
        (false, 215.89772058823542),
        (false, -37.28494134813445),
        (true, 982.7344428072784),
        (false, 989.75),
        (false, -12.1875),
        (false, -0.0625),
        (false, -933.3125),
        (true, -1277.797999399176),
    ];
    replay_exact_inverses(&a, &d, &opts, Initial::Descending(355.8125), ops);
}

#[test]
fn a_branch_whose_table_increment_is_round_off_is_a_straight_line() {
    // Rising again just after a fall from a maximum: the ascending tables are flat over the whole way back to the
    // maximum but for 3e-15 of interpolation round-off, so the branch's scale was 4e12: flat, then a jump at the
    // wipe-out, and the exact inverse of a target inside the jump returned the maximum's input. A scale beyond
    // 1e6 is round-off, and the branch is a straight line to its target. Found by fuzzing the step sequences
    // (fuzz/corpus/step_sequences/regression-round-off-scale); the tables are that input's.
    let a: Curves = vec![
        (
            vec![-1.0, -0.9966666666666667, -0.9933333333333333, -0.99],
            vec![
                -0.9984130617227436,
                -0.9984130617227436,
                -0.8916728126615973,
                -0.8508345837254054,
            ],
        ),
        (
            vec![-0.9933333333333333, -0.99],
            vec![-0.8508379746191602, -0.8508345837254054],
        ),
    ];
    let d: Curves = vec![
        (
            vec![
                -0.99,
                -0.9933333333333333,
                -0.9940625060400294,
                -0.9966666666666667,
                -1.0,
            ],
            vec![
                -0.8508345837254054,
                -0.8508379746191602,
                -0.8536444392927797,
                -0.8636674211405271,
                -0.9984130617227436,
            ],
        ),
        (
            vec![
                -0.9933333333333333,
                -0.9940625060400294,
                -0.9966666666666667,
                -1.0,
            ],
            vec![
                -0.8916728126615973,
                -0.8944792773352169,
                -0.9045022591829641,
                -0.9984130617227436,
            ],
        ),
        (
            vec![-0.9966666666666667, -1.0],
            vec![-0.9984130617227436, -0.9984130617227436],
        ),
    ];
    let (mut h, _) = forward_start(&a, &d);
    let (y_lo, y_hi) = h.output_range();
    let target = -0.8951081271246069;
    let mut forward = h.clone();
    let inv = h.step_inverse(target);
    assert!(!inv.saturated);
    let y = forward.step(inv.input);
    assert!(
        (y - target).abs() <= 1e-9 * (y_hi - y_lo),
        "forward(inverse({target})) = {y}"
    );
    // On the way back up to the maximum the output moves evenly: no jump at the wipe-out.
    let mut prev = forward_start(&a, &d);
    for k in 1..=100 {
        let u =
            -0.9966666666666667 + (0.9966666666666667 - 0.9933333333333333) * f64::from(k) / 100.0;
        let y = prev.0.step(u);
        assert!(
            (y - prev.1).abs() <= 0.05 * (y_hi - y_lo),
            "jump of {} at {u}",
            y - prev.1
        );
        prev.1 = y;
    }
}

/// The operator of [`a_branch_whose_table_increment_is_round_off_is_a_straight_line`] after its two steps, with
/// its output.
fn forward_start(a: &Curves, d: &Curves) -> (Op, f64) {
    let mut h = build(a, d).unwrap();
    h.step(-0.9933333333333333);
    let y = h.step(-0.9966666666666667);
    (h, y)
}

#[test]
fn a_derived_family_whose_major_branch_does_not_close_is_refused() {
    // One ascending family whose reversal points trace no descending major branch between the saturations (a
    // curve starting above positive saturation's output, another whose input runs back below its reversal):
    // the derived descending major branch ended 384 below the ascending one's start, and the operator's own
    // curves did not rebuild it. Found by fuzzing (fuzz/corpus/table_build/regression-derived-major-open).
    let a: Curves = vec![
        (vec![-100000.0, 1263.9375], vec![-284.3125, 1959.625]),
        (vec![864.0625, 989.75], vec![-0.0625, 1953.75]),
        (
            vec![1124.375, 1120.375, 1124.375, 1844.375, -8.8125, -0.0625],
            vec![511.9375, 1847.1875, -1992.8125, 1855.9375, -15.6875, 1952.0],
        ),
        (
            vec![140.75, 864.0625, 978.25],
            vec![1955.8125, 1953.75, 1959.625],
        ),
    ];
    match build(&a, &Vec::new()) {
        Err(TableError::MajorLoopOpen { at_input, .. }) => assert_eq!(at_input, -100000.0),
        other => panic!("expected an open major loop, got {other:?}"),
    }
}

#[test]
fn an_inverse_past_a_wiped_entry_does_not_stop_short_of_it() {
    // Rising from a minimum that sat on a flat stretch 2e-13 above the minimum below it, a target equal to that
    // lower minimum's output wipes the pair out: the deeper branch's first input reaching it lay behind the
    // wiped minimum's input (the flat stretch), and the answer stopped at the current input (361 off). The answer
    // now lies beyond the input of the last entry wiped out. Found by fuzzing in a CI-like run
    // (fuzz/corpus/table_build/regression-past-wiped-entry); tables, options and operations are that input's.
    let a: Curves = vec![
        (
            vec![19.3125, -575.6875, -1356.1875, 1959.625],
            vec![1959.125, -824.375, -111.375, 979.8125],
        ),
        (
            vec![-1356.1875, 1959.625, 1703.625, 1955.0, 1952.5, 83.3125],
            vec![-1356.1875, -0.0625, -0.0625, 979.8125, 1962.375, 1953.75],
        ),
        (
            vec![
                -824.375, -111.375, 979.8125, 989.75, 986.6875, 455.625, 22.625, 83.8125,
            ],
            vec![
                -940.3125, 455.625, 1959.125, 1959.625, 1953.75, 775.625, 140.75, 862.625,
            ],
        ),
    ];
    let d: Curves = vec![
        (
            vec![
                -12.1875, -0.0625, 991.9375, -933.3125, 455.625, 1959.125, -824.375, 48.6875,
            ],
            vec![
                131.8125, 979.8125, 1955.8125, 1953.75, 848.0625, 989.75, -933.3125, 455.625,
            ],
        ),
        (vec![1959.625, 167.625], vec![979.8125, 989.75]),
        (
            vec![
                -8.375, -0.0625, -111.375, 979.8125, 989.75, 986.6875, 455.625,
            ],
            vec![
                848.0625, 989.75, -933.3125, 455.625, 1959.125, -824.375, -111.375,
            ],
        ),
    ];
    let opts = BuildOptions {
        monotone_tolerance: 131.8125,
        reach_tolerance: 979.8125,
        closure_tolerance: 1955.8125,
        node_tolerance: 0.0,
        max_nodes: 1503,
        subdivisions: 1,
    };
    // (is an inverse, input or target)
    let ops: &[(bool, f64)] = &[
        (true, -246.29290441176477),
        (false, -1524.9304048409247),
        (false, 979.8125),
        (false, -726.2817873083086),
        (false, -0.5),
        (true, -250.57941162165253),
        (true, -1347.9252573529411),
        (true, 671.1910987926299),
        (true, -1346.2535195410849),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, 2275.7238570038908),
        (true, -250.57941162165253),
        (true, -1347.9252573529411),
        (true, 671.1910987926299),
        (true, -1347.9252573529411),
        (true, -1347.9252573529411),
        (true, -246.29290441176477),
        (true, 1218.8781249999997),
        (false, 1964.3125),
        (true, -250.3222211890593),
        (true, -246.29290441176477),
        (true, -242.77796849965648),
        (true, 99.32817192149218),
        (false, -575.5),
        (false, 986.6875),
        (true, -1277.797999399176),
        (false, 215.89772058823542),
        (false, -37.28494134813445),
        (true, 982.7344428072784),
        (false, -0.0625),
        (true, 671.1910987926299),
        (true, -1347.9252573529411),
        (true, -1347.9252573529411),
        (true, -246.29290441176477),
        (true, 1218.8781249999997),
        (false, 91.55285448615246),
        (true, -246.29290441176477),
        (false, -1342.1167369535362),
        (false, 15.9375),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, -1687.76875),
        (false, 2291.2062499999997),
        (true, -250.57941162165253),
        (true, -1347.9252573529411),
        (true, 671.1910987926299),
        (true, -1347.9252573529411),
        (true, -1347.9252573529411),
        (true, -246.29290441176477),
        (true, 1218.8781249999997),
        (false, 1964.3125),
        (true, -250.3222211890593),
        (true, -246.29290441176477),
        (true, -242.77796849965648),
        (true, 99.32817192149218),
        (false, -575.5),
        (false, 986.6875),
        (true, -1277.797999399176),
        (false, 215.89772058823542),
        (false, -37.28494134813445),
        (true, 982.7344428072784),
        (false, -0.0625),
        (false, -933.3125),
        (true, -915.6738703078507),
        (true, -1277.797999399176),
    ];
    replay_exact_inverses(&a, &d, &opts, Initial::Descending(355.8125), ops);
}

#[test]
fn a_state_on_a_near_jump_of_the_tables_round_trips_its_words() {
    // Tables with a grid node at 8e-308 next to one at 3e-5 (a cell of 3e-5 in an input range of 3300) and an
    // output step of ~100 across it: the input's own rounding (2e-13) moves the output by 5e-6, 1.6e-9 of the
    // span. The exact inverse commits the target as the output; the state's words must still be accepted (the
    // branch's outputs a few ulps of the input either side bracket it), and the inverse is exact to the input's
    // round-off. Found by fuzzing (fuzz/corpus/table_build/regression-near-jump-state); tables and options are
    // that input's.
    let a: Curves = vec![
        (
            vec![19.3125, -575.6875, -1356.1875, 1959.625],
            vec![1959.125, -0.0625, -0.0625, 31.9375],
        ),
        (
            vec![-1356.1875, 1959.625, 1703.625, 1955.25, 1952.5, 83.3125],
            vec![-1356.1875, -0.0625, -0.0625, 979.8125, 1962.375, -1806.25],
        ),
        (
            vec![
                -824.375, -111.375, 979.8125, 989.75, 986.6875, 455.625, 22.625, 83.8125,
            ],
            vec![
                -940.1875, 455.625, 1959.125, 1959.625, 1953.75, 775.625, 140.75, 862.625,
            ],
        ),
    ];
    let d: Curves = vec![
        (
            vec![
                -12.1875, -0.0625, 991.9375, -933.3125, 455.625, 1959.125, -824.375, -111.375,
            ],
            vec![
                131.8125,
                979.8125,
                1963.6875,
                1953.75,
                9.999999999999998e-156,
                5e-324,
                7.4617604e-316,
                1.390671347747314e-309,
            ],
        ),
        (
            vec![
                8.344026969402005e-308,
                -1028.0625,
                -1028.0625,
                -4.0625,
                -1028.0625,
                -1028.0625,
                -1028.0625,
                -1028.0625,
            ],
            vec![
                -1028.0625, -1028.0625, -144.625, -144.625, -1616.625, 1961.625, -1624.375, 7.625,
            ],
        ),
        (
            vec![
                1961.625,
                3.1374394893647365e-05,
                1967.9375,
                1959.625,
                3.131513062514021e-294,
                535.625,
                1959.625,
            ],
            vec![
                535.625, 1959.625, 1959.625, -144.625, 175.375, 1967.375, 7.625,
            ],
        ),
    ];
    let opts = BuildOptions {
        monotone_tolerance: 7.205460959719922e283,
        reach_tolerance: 1.0000000000000003e130,
        closure_tolerance: 1076.1875,
        node_tolerance: 0.0,
        max_nodes: 1190,
        subdivisions: 1,
    };
    let mut h =
        Hysteresis::<Vec<f64>, 8>::from_curve_data(&a, &d, &opts, Initial::Positive).unwrap();
    for u in [989.75, 1964.3125, 216.84595588235288] {
        h.step(u);
    }
    let target = -240.01400735294123;
    let before = h.clone();
    let inv = h.step_inverse(target);
    assert!(!inv.saturated);
    let d_u = h.input_round_off();
    let (below, above) = (
        before.clone().step(inv.input - d_u),
        before.clone().step(inv.input + d_u),
    );
    assert!(
        below.min(above) <= target && target <= below.max(above),
        "{below} {target} {above}"
    );
    let words = h.snapshot().to_words();
    let back = h.state_from_words(&words).expect("its own state words");
    assert_eq!(back.to_words(), words);
}

/// Every sample field of an actuator run over hard commands (steps to and past the converter's limits, reversals,
/// a non-finite command), checked finite; `what` names the configuration.
fn assert_finite_run(act: &mut VirtualActuator, what: &str) {
    for (k, i) in [0.0, 2.0, -2.0, 0.3, 1e9, -0.1, f64::NAN, 1.2, -1.2, 0.0]
        .into_iter()
        .cycle()
        .take(40)
        .enumerate()
    {
        let s = act.step(i);
        for v in [
            s.t_s,
            s.current_cmd_a,
            s.coil1_a,
            s.coil2_a,
            s.b1_t,
            s.b2_t,
            s.theta_rad,
            s.speed_rad_s,
            s.field_torque_nmm,
            s.friction_nmm,
            s.viscous_nmm,
            s.torque_true_nmm,
            s.torque_nmm,
        ] {
            assert!(v.is_finite(), "{what}, step {k} (command {i}): {s:?}");
        }
    }
}

/// Values at and around the edges of any range: subnormals, the tiniest and the largest magnitudes.
const EDGE_VALUES: [f64; 14] = [
    0.0, 5e-324, -5e-324, 1e-300, 1e-12, 1e-6, 1e-3, 0.5, 1.0, 1e3, 1e4, 1e6, 1e9, 1e12,
];

#[test]
fn every_settable_parameter_at_its_edges_gives_finite_samples_or_an_error() {
    // Each parameter alone, at values at and beyond its range, with every effect on at its defaults: building
    // either refuses the value or gives an actuator whose every sample is finite.
    let mut all = preset("bmr2013").unwrap();
    for kind in EffectKind::ALL {
        all.effects.insert(Effect::default_of(kind));
    }
    for key in SETTABLE {
        for v in EDGE_VALUES.into_iter().flat_map(|v| [v, -v]) {
            let mut config = all.clone();
            if config.set(key, v).is_err() {
                continue;
            }
            if let Ok(mut act) = VirtualActuator::new(config, 11) {
                assert_finite_run(&mut act, &format!("{key} = {v:e}"));
            }
        }
    }
}

#[test]
fn every_effect_parameter_at_its_edges_gives_finite_samples() {
    // Found with this sweep: `non_congruent:scale_nmm=5e-324` was accepted (range [0, 1e9]) and the output map
    // divided by it (NaN torque); a full scale is now 0 (the actuator's own) or at least 1e-3 N·mm.
    for kind in EffectKind::ALL {
        for spec in kind.params() {
            for v in common::edge_values(spec) {
                // Refused: outside the spec, or against another parameter (creep's tau_min_s above tau_max_s).
                let Ok(effect) = Effect::from_params(kind, &[(spec.name, v)]) else {
                    continue;
                };
                let mut config = preset("bmr2013").unwrap();
                config.effects.insert(effect);
                let mut act = VirtualActuator::new(config, 13).unwrap();
                assert_finite_run(&mut act, &format!("{}:{}={v:e}", kind.name(), spec.name));
            }
        }
    }
}

#[test]
fn every_device_parameter_and_effect_at_its_edges_gives_finite_samples_or_an_error() {
    // The generic device (piezo, ferroelectric presets) under the same sweep as the actuator.
    let run = |dev: &mut VirtualDevice, what: &str| {
        for (k, u) in [0.0, 1.0, -1.0, 0.3, 1e9, f64::NAN, -0.2, 0.0]
            .into_iter()
            .cycle()
            .take(32)
            .enumerate()
        {
            let s = dev.step(u);
            for v in [s.t_s, s.input, s.output_true, s.output] {
                assert!(v.is_finite(), "{what}, step {k} (input {u}): {s:?}");
            }
        }
    };
    for name in ["piezo", "ferroelectric"] {
        let base = device_preset(name).unwrap();
        // Every effect a device has (the rotor's friction and ripple it has not).
        let mut all = base.clone();
        for kind in EffectKind::ALL {
            let mut with = all.clone();
            with.effects.insert(Effect::default_of(kind));
            if VirtualDevice::new(with.clone(), 0).is_ok() {
                all = with;
            }
        }
        assert!(all.effects.len() >= 10, "{name}: {:?}", all.effects);
        for key in bmr::plant::DEVICE_SETTABLE {
            for v in EDGE_VALUES.into_iter().flat_map(|v| [v, -v]) {
                let mut config = all.clone();
                if config.set(key, v).is_err() {
                    continue;
                }
                if let Ok(mut dev) = VirtualDevice::new(config, 17) {
                    run(&mut dev, &format!("{name}: {key} = {v:e}"));
                }
            }
        }
        for kind in EffectKind::ALL {
            for spec in kind.params() {
                for v in common::edge_values(spec) {
                    let Ok(effect) = Effect::from_params(kind, &[(spec.name, v)]) else {
                        continue;
                    };
                    let mut config = base.clone();
                    config.effects.insert(effect);
                    let Ok(mut dev) = VirtualDevice::new(config, 19) else {
                        continue; // an effect of the rotor
                    };
                    run(
                        &mut dev,
                        &format!("{name}: {}:{}={v:e}", kind.name(), spec.name),
                    );
                }
            }
        }
    }
}
