//! Property tests of the CBH operator over random input histories (proptest, 10⁴ cases each).
mod common;

use bmr::{BuildOptions, Hysteresis, Initial};
use proptest::prelude::*;
use std::sync::OnceLock;

type Table = (Vec<common::Curve>, Vec<common::Curve>);

/// A Preisach-derived table (60 thresholds, 13 curves per family), measured once.
fn table() -> &'static Table {
    static T: OnceLock<Table> = OnceLock::new();
    T.get_or_init(|| common::measure_first_order(60, 13))
}

fn build<const N: usize>() -> Hysteresis<Vec<f64>, N> {
    let (asc, desc) = table();
    Hysteresis::from_curve_data(asc, desc, &BuildOptions::default(), Initial::Negative).unwrap()
}

/// Steepest output slope of the tables (output units per input unit), for the continuity bound.
fn max_slope<const N: usize>(h: &Hysteresis<Vec<f64>, N>) -> f64 {
    let mut s: f64 = 0.0;
    for f in [h.ascending(), h.descending()] {
        let g = f.grid();
        for j in 0..f.curves() {
            let r = f.row(j);
            for k in 0..g.len() - 1 {
                s = s.max((r[k + 1] - r[k]) / (g[k + 1] - g[k]));
            }
        }
    }
    s
}

/// Random histories with nested reversals (shrinking alternation), occasional large jumps and out-of-range inputs.
fn history() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec((0.0f64..1.0, 0.0f64..1.0), 1..60).prop_map(|steps| {
        let (mut lo, mut hi, mut cur, mut up) = (-1.0f64, 1.0f64, -1.0f64, true);
        let mut out = Vec::with_capacity(steps.len());
        for (a, b) in steps {
            if b < 0.1 {
                cur = -1.2 + 2.4 * a; // a jump anywhere, even past saturation
                lo = -1.0;
                hi = 1.0;
            } else {
                let next = if up {
                    cur + (hi - cur) * a
                } else {
                    cur - (cur - lo) * a
                };
                if up {
                    lo = cur
                } else {
                    hi = cur
                }
                cur = next;
                up = !up;
            }
            out.push(cur);
        }
        out
    })
}

/// Memory invariants: anchor at the lowest input; maxima strictly decreasing, minima strictly increasing and every
/// stored point inside the previous pair (nesting).
fn check_memory(mem: &[(f64, f64)], lo: f64) -> Result<(), TestCaseError> {
    prop_assert_eq!(mem[0].0, lo);
    for i in 2..mem.len() {
        if i % 2 == 0 {
            prop_assert!(mem[i].0 > mem[i - 2].0, "minima must increase: {:?}", mem);
        } else {
            prop_assert!(
                mem[i].0 < mem[i - 2].0 || i == 1,
                "maxima must decrease: {:?}",
                mem
            );
        }
        prop_assert!(
            mem[i].0 > mem[i - 2].0.min(mem[i - 1].0) && mem[i].0 < mem[i - 2].0.max(mem[i - 1].0)
                || i < 3
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 10_000, max_global_rejects: 100_000, ..ProptestConfig::default() })]

    #[test]
    fn wiping_out_keeps_memory_nested(inputs in history()) {
        let mut h = build::<64>();
        let lo = h.input_range().0;
        for &u in &inputs {
            h.step(u);
            let mem: Vec<_> = h.state().memory().collect();
            check_memory(&mem, lo)?;
            // Every stored maximum lies above the current input, every minimum below (else it was wiped out).
            let cur = h.state().input();
            for (i, &(m, _)) in mem.iter().enumerate().skip(1) {
                if i % 2 == 1 { prop_assert!(m >= cur) } else { prop_assert!(m <= cur) }
            }
        }
    }

    #[test]
    fn return_point_memory_is_exact(inputs in history(), frac in 0.05f64..0.95) {
        let mut h = build::<64>();
        for &u in &inputs { h.step(u); }
        let mem: Vec<_> = h.state().memory().collect();
        prop_assume!(mem.len() >= 3);
        // Leave towards the newest reversal's target, turn part way, come back, then close on the target.
        let (u_rev, _) = mem[mem.len() - 1];
        let (u_target, y_target) = mem[mem.len() - 2];
        let cur = h.state().input();
        let inner = cur + frac * (u_target - cur);
        h.step(inner);
        h.step(u_rev + 0.5 * (inner - u_rev));
        let y = h.step(u_target);
        prop_assert_eq!(y.to_bits(), y_target.to_bits(), "closing the loop at {} gives {} not {}", u_target, y, y_target);
    }

    #[test]
    fn small_input_steps_give_small_output_steps(inputs in history(), du in -1e-6f64..1e-6) {
        let mut h = build::<64>();
        let l = max_slope(&h);
        for &u in &inputs { h.step(u); }
        let y0 = h.output();
        let u0 = h.state().input();
        let y1 = h.step(u0 + du);
        let du_eff = (h.state().input() - u0).abs();
        prop_assert!((y1 - y0).abs() <= 1.01 * l * du_eff + 1e-9, "Δy {} for Δu {}", y1 - y0, du_eff);
    }

    #[test]
    fn full_memory_merges_without_jumps(amps in prop::collection::vec(0.01f64..1.0, 8..80)) {
        // Decaying nested oscillations overflow a 6-point memory; the output must stay continuous.
        let mut h = build::<6>();
        let l = max_slope(&h);
        let mut amp = 1.0;
        let mut prev = (h.state().input(), h.output());
        for (i, a) in amps.iter().enumerate() {
            amp *= 0.7 + 0.29 * a;
            let target = if i % 2 == 0 { amp } else { -amp };
            for s in 1..=20 {
                let u = prev.0 + (target - prev.0) * s as f64 / 20.0;
                let from = prev;
                let y = h.step(u);
                prop_assert!(h.state().history().len() <= 6);
                prop_assert!((y - from.1).abs() <= 1.01 * l * (u - from.0).abs() + 1e-9,
                    "jump {} over Δu {}", y - from.1, u - from.0);
                prev = (u, y);
            }
        }
    }

    #[test]
    fn run_equals_repeated_step_and_snapshot_replays(inputs in history(), split in 0usize..60) {
        let mut a = build::<64>();
        let mut b = build::<64>();
        let mut ys = vec![0.0; inputs.len()];
        a.run_into(&inputs, &mut ys);
        for (u, y) in inputs.iter().zip(&ys) {
            prop_assert_eq!(b.step(*u).to_bits(), y.to_bits());
        }
        let split = split.min(inputs.len());
        let mut c = build::<64>();
        for &u in &inputs[..split] { c.step(u); }
        let snap = c.snapshot();
        let first: Vec<u64> = inputs[split..].iter().map(|&u| c.step(u).to_bits()).collect();
        c.restore(&snap).unwrap();
        let second: Vec<u64> = inputs[split..].iter().map(|&u| c.step(u).to_bits()).collect();
        prop_assert_eq!(first, second);
    }
}

#[test]
fn nan_input_returns_nan_and_keeps_memory() {
    let mut h = build::<64>();
    h.step(0.3);
    h.step(-0.2);
    let before = h.snapshot();
    assert!(h.step(f64::NAN).is_nan());
    assert_eq!(h.snapshot(), before);
    assert_eq!(h.step(f64::INFINITY), h.output_range().1);
}

#[test]
fn snapshot_of_another_table_is_rejected() {
    let a = build::<64>();
    let (asc, desc) = common::measure_first_order(40, 5);
    let mut other = Hysteresis::<Vec<f64>, 64>::from_curve_data(
        &asc,
        &desc,
        &BuildOptions::default(),
        Initial::Negative,
    )
    .unwrap();
    assert_eq!(
        other.restore(&a.snapshot()),
        Err(bmr::TableError::ForeignState)
    );
}
