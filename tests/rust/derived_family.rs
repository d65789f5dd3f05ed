//! One family of first-order curves (plus the opposite major branch) builds the whole operator: the other family
//! is derived under congruency. Checked against an independent discretised Preisach plant.
mod common;

use bmr::derived_family::MajorSource;
use bmr::{BuildOptions, FamilyKind, Hysteresis, Initial, TableError};
use common::{Curve, PreisachPlant, Rng, measure_first_order, random_history};

const N_THRESHOLDS: usize = 200;
type H = Hysteresis<Vec<f64>, 64>;

/// Four curves per interval between measured reversals.
fn opts() -> BuildOptions {
    BuildOptions {
        subdivisions: 4,
        ..BuildOptions::default()
    }
}

fn build(asc: &[Curve], desc: &[Curve]) -> (H, bmr::BuildReport) {
    H::from_curve_data_reported(asc, desc, &opts(), Initial::Negative).expect("plant curves build")
}

/// RMS error over random off-grid histories (inputs on the plant's threshold edges), relative to the span.
fn offgrid_rms(h: &mut H, seed: u64) -> f64 {
    let mut rng = Rng(seed);
    let mut history = random_history(&mut rng, 300, 17);
    let cells = N_THRESHOLDS as f64 / 2.0;
    for u in &mut history {
        *u = ((*u + 1.0) * cells).round() / cells - 1.0;
    }
    h.reset(Initial::Negative);
    let mut plant = PreisachPlant::new(N_THRESHOLDS);
    let mut sum = 0.0;
    for &u in &history {
        let d = plant.step(u) - h.step(u);
        sum += d * d;
    }
    let (lo, hi) = h.output_range();
    (sum / history.len() as f64).sqrt() / (hi - lo)
}

fn mean_rms(h: &mut H) -> f64 {
    (1..=3).map(|s| offgrid_rms(h, s)).sum::<f64>() / 3.0
}

#[test]
fn one_family_plus_the_opposite_major_branch_predicts_like_both_families() {
    let (asc, desc) = measure_first_order(N_THRESHOLDS, 21);
    let (mut both, report) = build(&asc, &desc);
    assert!(report.derived.is_none());
    let mismatch = report.mismatch.expect("both families measured");
    let (lo, hi) = both.output_range();
    assert!(mismatch.max_abs < 1e-9 * (hi - lo), "{mismatch:?}");
    let e_both = mean_rms(&mut both);

    // Ascending family + descending major branch; descending family + ascending major branch.
    let (mut from_asc, r_asc) = build(&asc, &desc[..1]);
    let d = r_asc.derived.expect("descending derived");
    assert_eq!(
        (d.family, d.major),
        (FamilyKind::Descending, MajorSource::Measured)
    );
    assert!(d.curves > 20 && d.adjusted < 1e-9, "{d:?}");
    let (mut from_desc, r_desc) = build(&asc[..1], &desc);
    assert_eq!(r_desc.derived.unwrap().family, FamilyKind::Ascending);
    let e_asc = mean_rms(&mut from_asc);
    let e_desc = mean_rms(&mut from_desc);
    // Without the opposite major branch its reversal points trace it.
    let (mut bare, r_bare) = build(&asc, &[]);
    assert_eq!(r_bare.derived.unwrap().major, MajorSource::ReversalPoints);
    let e_bare = mean_rms(&mut bare);
    println!(
        "off-grid RMS error (% of span): both families {:.4}, ascending + major {:.4}, descending + major {:.4}, \
         ascending alone {:.4}",
        100.0 * e_both,
        100.0 * e_asc,
        100.0 * e_desc,
        100.0 * e_bare
    );
    // Both families calibrate each other's strips at every measured curve; one family only on the major branch.
    assert!(e_both <= e_asc && e_both <= e_desc);
    assert!(e_asc < 4e-4 && e_desc < 4e-4, "{e_asc} {e_desc}");
    assert!(e_bare < 2e-3, "ascending alone: {e_bare}");
}

#[test]
fn derived_family_reproduces_the_plant_at_measured_reversals() {
    let (asc, desc) = measure_first_order(N_THRESHOLDS, 21);
    let (mut h, _) = build(&asc, &desc[..1]);
    // Falling from a measured ascending reversal (a derived reversal maximum) after negative saturation is a
    // derived descending curve: exact where it crosses measured ascending reversals.
    let mut plant = PreisachPlant::new(N_THRESHOLDS);
    h.reset(Initial::Negative);
    let grid = common::edge_grid(N_THRESHOLDS);
    let mut worst = 0.0f64;
    for &top in &[0.5, -0.3, 0.9] {
        for &u in grid.iter().filter(|&&g| g <= top) {
            plant.step(u);
            h.step(u);
        }
        for &u in grid.iter().rev().filter(|&&g| g <= top) {
            let (yp, yh) = (plant.step(u), h.step(u));
            if ((u + 1.0) * 10.0).fract().abs() < 1e-9 {
                worst = worst.max((yp - yh).abs());
            }
        }
    }
    let (lo, hi) = h.output_range();
    assert!(worst < 1e-6 * (hi - lo), "worst {worst}");
}

#[test]
fn too_few_curves_in_both_families_is_a_clear_error() {
    let (asc, desc) = measure_first_order(N_THRESHOLDS, 21);
    let err = H::from_curve_data(
        &asc[..1],
        &desc[..1],
        &BuildOptions::default(),
        Initial::Negative,
    )
    .unwrap_err();
    assert!(matches!(
        err,
        TableError::NotEnoughCurves {
            ascending: 1,
            descending: 1
        }
    ));
    assert!(err.to_string().contains("1 ascending and 1 descending"));
}

#[test]
fn nodes_follow_an_error_bound_and_the_budget_is_reported() {
    let (asc, desc) = measure_first_order(N_THRESHOLDS, 21);
    let (_, r) = build(&asc, &desc);
    assert!(r.ascending.error <= r.ascending.tolerance);
    // A budget below what the bound needs raises the bound (reversals always stay nodes: 21 measured + 60 added).
    let tight = BuildOptions {
        max_nodes: 100,
        node_tolerance: 1e-6,
        ..opts()
    };
    let (h, r) = H::from_curve_data_reported(&asc, &desc, &tight, Initial::Negative).unwrap();
    assert_eq!(r.densified, [60, 60]);
    assert!(r.ascending.nodes <= 100 && r.ascending.tolerance > 1e-6 * 600.0);
    assert!(r.ascending.error <= r.ascending.tolerance * (1.0 + 1e-9));
    assert_eq!(h.ascending().nodes(), r.ascending.nodes);
}
