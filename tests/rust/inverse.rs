//! Exact inverse: `forward(inverse(T)) == T` over random memories and references; the paper's inverse measured.
mod common;

use bmr::{BuildOptions, Hysteresis, Initial};
use proptest::prelude::*;
use std::sync::OnceLock;

type Table = (Vec<common::Curve>, Vec<common::Curve>);

fn preisach() -> &'static Table {
    static T: OnceLock<Table> = OnceLock::new();
    T.get_or_init(|| common::measure_first_order(60, 13))
}

/// A non-congruent table: the Preisach output bent by `y + c·y|y|` (branch scales `k != 1`).
fn bent() -> &'static Table {
    static T: OnceLock<Table> = OnceLock::new();
    T.get_or_init(|| {
        let (a, d) = common::measure_first_order(60, 13);
        let bend = |c: Vec<common::Curve>| -> Vec<common::Curve> {
            c.into_iter()
                .map(|(u, y)| (u, y.iter().map(|v| v + 0.0015 * v * v.abs()).collect()))
                .collect()
        };
        (bend(a), bend(d))
    })
}

fn build<const N: usize>(t: &Table) -> Hysteresis<Vec<f64>, N> {
    Hysteresis::from_curve_data(&t.0, &t.1, &BuildOptions::default(), Initial::Negative).unwrap()
}

fn check_inverse<const N: usize>(
    h: &mut Hysteresis<Vec<f64>, N>,
    history: &[f64],
    frac: f64,
) -> Result<(), TestCaseError> {
    for &u in history {
        h.step(u);
    }
    let (lo, hi) = h.output_range();
    let span = hi - lo;
    let target = lo + frac * span;
    let inv = h.inverse_input(target);
    prop_assert!(
        !inv.saturated,
        "target {} inside [{}, {}] flagged saturated",
        target,
        lo,
        hi
    );
    let y = h.step(inv.input);
    prop_assert!(
        (y - target).abs() <= 1e-9 * span,
        "forward(inverse({})) = {} (error {:.3e} of span)",
        target,
        y,
        (y - target).abs() / span
    );
    Ok(())
}

fn history() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(-1.1f64..1.1, 0..40)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 10_000, ..ProptestConfig::default() })]

    #[test]
    fn exact_inverse_round_trips_on_preisach_tables(h in history(), frac in 0.0f64..=1.0) {
        check_inverse(&mut build::<64>(preisach()), &h, frac)?;
    }

    #[test]
    fn exact_inverse_round_trips_on_non_congruent_tables(h in history(), frac in 0.0f64..=1.0) {
        check_inverse(&mut build::<64>(bent()), &h, frac)?;
    }

    #[test]
    fn exact_inverse_round_trips_with_merged_memory(h in prop::collection::vec(-1.1f64..1.1, 10..60), frac in 0.0f64..=1.0) {
        check_inverse(&mut build::<5>(bent()), &h, frac)?;
    }

    #[test]
    fn unreachable_targets_saturate_and_are_flagged(h in history(), above in any::<bool>(), extra in 1e-6f64..1e6) {
        let mut op = build::<64>(preisach());
        for &u in &h { op.step(u); }
        let (lo, hi) = op.output_range();
        let target = if above { hi + extra } else { lo - extra };
        let inv = op.inverse_input(target);
        prop_assert!(inv.saturated);
        let y = op.step(inv.input);
        prop_assert_eq!(y, if above { hi } else { lo });
    }
}

#[test]
fn repeated_tracking_of_a_random_multipeak_reference_is_exact() {
    let mut h = build::<64>(bent());
    let (lo, hi) = h.output_range();
    let mut rng = common::Rng(99);
    let mut worst: f64 = 0.0;
    let mut t = 0.0;
    for _ in 0..20_000 {
        t += 0.37 * (rng.uniform() - 0.5) * (hi - lo) * 0.05;
        let target = t.clamp(lo, hi);
        let y = h.step_inverse(target);
        worst = worst.max((h.output() - target).abs());
        assert!(!y.saturated);
    }
    assert!(worst <= 1e-9 * (hi - lo), "worst {worst}");
}

#[test]
fn paper_inverse_error_is_measured() {
    // The paper's inverse assumes the inverse is congruent; on Preisach tables it is not exactly: report its error.
    for (name, table) in [("preisach", preisach()), ("bent", bent())] {
        let fwd = build::<64>(table);
        let mut inv = fwd.paper_inverse().unwrap();
        let mut plant = build::<64>(table);
        let mut exact = build::<64>(table);
        let (lo, hi) = fwd.output_range();
        let mut rng = common::Rng(5);
        let (mut e_paper, mut e_exact, mut n) = (0.0, 0.0, 0);
        let mut t = lo;
        for step in 0..20_000 {
            if step % 400 == 0 {
                t = lo + (hi - lo) * (0.1 + 0.8 * rng.uniform());
            }
            let target = (t + 0.2 * (hi - lo) * ((step as f64) * 0.03).sin()).clamp(lo, hi);
            let u_paper = inv.step(target);
            let y_paper = plant.step(u_paper);
            let r = exact.step_inverse(target);
            let _ = r;
            e_paper += (y_paper - target).powi(2);
            e_exact += (exact.output() - target).powi(2);
            n += 1;
        }
        let rp = (e_paper / n as f64).sqrt() / (hi - lo);
        let re = (e_exact / n as f64).sqrt() / (hi - lo);
        println!(
            "{name}: tracking RMS error, paper inverse {:.3} % vs exact {:.2e} % of span",
            100.0 * rp,
            100.0 * re
        );
        assert!(re < 1e-9);
        assert!(rp.is_finite());
    }
}
