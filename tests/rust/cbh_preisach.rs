//! The CBH operator against an independent discretised Preisach plant (200 thresholds per axis).
mod common;

use bmr::{BuildOptions, Hysteresis, Initial};
use common::{PreisachPlant, Rng, edge_grid, measure_first_order, random_history};

const N_THRESHOLDS: usize = 200;
type H = Hysteresis<Vec<f64>, 64>;

fn build(curves: usize) -> H {
    let (asc, desc) = measure_first_order(N_THRESHOLDS, curves);
    H::from_curve_data(&asc, &desc, &BuildOptions::default(), Initial::Negative)
        .expect("plant curves are valid")
}

fn span(h: &H) -> f64 {
    let (lo, hi) = h.output_range();
    hi - lo
}

#[test]
fn reproduces_plant_to_round_off_when_reversals_are_on_measured_curves() {
    let curves = 21;
    let mut h = build(curves);
    let grid = edge_grid(N_THRESHOLDS);
    let stride = N_THRESHOLDS / (curves - 1);
    let mut plant = PreisachPlant::new(N_THRESHOLDS);
    let mut rng = Rng(7);
    // Reversals on measured reversal nodes (nested and not), inputs on the measurement grid.
    let mut idx = 0usize;
    let mut worst: f64 = 0.0;
    for _ in 0..400 {
        let target = stride * (rng.next_u64() as usize % curves);
        let dir: isize = if target > idx { 1 } else { -1 };
        while idx != target {
            idx = (idx as isize + dir) as usize;
            let y_p = plant.step(grid[idx]);
            let y_h = h.step(grid[idx]);
            worst = worst.max((y_p - y_h).abs());
        }
    }
    let rel = worst / span(&h);
    println!("on-grid reversals: max |error| = {worst:.3e} ({rel:.2e} of span)");
    assert!(rel <= 1e-9, "max error {rel:.3e} of span");
}

/// RMS error over a random history, relative to the output span. `on_edges`: inputs snapped to the plant's
/// threshold-cell edges (reversals anywhere between the measured curves, but no sub-cell staircase error).
fn offgrid_rms(curves: usize, seed: u64, on_edges: bool) -> f64 {
    let mut h = build(curves);
    let mut rng = Rng(seed);
    let mut history = random_history(&mut rng, 300, 17);
    if on_edges {
        let cells = N_THRESHOLDS as f64 / 2.0;
        for u in &mut history {
            *u = ((*u + 1.0) * cells).round() / cells - 1.0;
        }
    }
    let mut plant = PreisachPlant::new(N_THRESHOLDS);
    let mut sum = 0.0;
    for &u in &history {
        let d = plant.step(u) - h.step(u);
        sum += d * d;
    }
    (sum / history.len() as f64).sqrt() / span(&h)
}

#[test]
fn off_grid_histories_within_one_percent_of_span() {
    for curves in [21, 41] {
        for on_edges in [true, false] {
            let rms: Vec<f64> = (1..=3).map(|s| offgrid_rms(curves, s, on_edges)).collect();
            let mean = rms.iter().sum::<f64>() / rms.len() as f64;
            let what = if on_edges {
                "inputs on threshold edges"
            } else {
                "inputs anywhere (incl. plant staircase)"
            };
            println!(
                "off-grid random histories, {curves} curves, {what}: RMS error {:.3} % of span",
                100.0 * mean
            );
            assert!(mean <= 0.01, "{curves} curves: RMS {mean:.4} of span");
        }
    }
}

/// The plant's Everett increment from reversal minimum `m` (after positive saturation) to `u`.
fn plant_everett(m: f64, u: f64) -> f64 {
    let mut p = PreisachPlant::new(N_THRESHOLDS);
    p.step(1.0);
    let y_m = p.step(m);
    p.step(u) - y_m
}

#[test]
fn strip_uniform_interpolation_beats_linear_interpolation_of_reversals() {
    let h = build(21);
    let fam = h.ascending();
    let grid = edge_grid(N_THRESHOLDS);
    let r = fam.reversals().to_vec();
    let mut rng = Rng(11);
    let (mut e_strip, mut e_lin, mut count) = (0.0, 0.0, 0);
    for _ in 0..150 {
        // A threshold-cell edge that is not a measured reversal: pure interpolation error, no staircase.
        let m = grid[(rng.next_u64() % (N_THRESHOLDS as u64 - 1)) as usize];
        let strip = fam.strip(m);
        for &u in grid.iter().filter(|&&u| u > m) {
            let truth = plant_everett(m, u);
            let mut hint = 0;
            let ours = fam.everett(&strip, u, &mut hint);
            // The interpolation baseline (docs/architecture.md §2.3): (1-λ)[E_j(u) - E_j(m)] + λ E_{j+1}(u).
            let ej = |x: f64| row_interp(fam.grid(), fam.row(strip.j), x);
            let ej1 = |x: f64| {
                if strip.j + 1 < r.len() {
                    row_interp(fam.grid(), fam.row(strip.j + 1), x)
                } else {
                    0.0
                }
            };
            let l = strip.lambda;
            let lin = (1.0 - l) * (ej(u) - ej(m)) + l * ej1(u);
            e_strip += (ours - truth).powi(2);
            e_lin += (lin - truth).powi(2);
            count += 1;
        }
    }
    let s = span(&h);
    let (rs, rl) = (
        (e_strip / count as f64).sqrt() / s,
        (e_lin / count as f64).sqrt() / s,
    );
    println!(
        "Everett error at off-grid reversals: strip-uniform {:.4} % vs linear {:.4} % of span",
        100.0 * rs,
        100.0 * rl
    );
    assert!(rs < rl, "strip-uniform {rs:.5} should beat linear {rl:.5}");
}

fn row_interp(grid: &[f64], row: &[f64], x: f64) -> f64 {
    let k = grid.partition_point(|&g| g <= x).clamp(1, grid.len() - 1) - 1;
    let t = (x - grid[k]) / (grid[k + 1] - grid[k]);
    row[k] + t * (row[k + 1] - row[k])
}
