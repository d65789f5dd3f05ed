//! The least-squares Everett identification against the CBH core: a table identified from noisy triangle data
//! reproduces the plant on held-out inputs, and the CBH operator built from its first-order curves agrees with it
//! exactly at grid reversals.
#![cfg(feature = "lstsq")]

use bmr::identification::{
    EverettFitOptions, EverettFoldRun, EverettFolds, EverettGrid, EverettModel, EverettRows,
    EverettRun, IdentificationError, fit_everett,
};
use bmr::limits::{MAX_EVERETT_LARGE_UNKNOWNS, MAX_EVERETT_UNKNOWNS};
use bmr::{BuildOptions, Hysteresis, Initial};

type H = Hysteresis<Vec<f64>, 64>;

/// SplitMix64 + Box-Muller: deterministic noise without a dependency.
struct Noise(u64);
impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (a, b) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * a.ln()).sqrt() * (core::f64::consts::TAU * b).cos()
    }
}

fn plant(grid: &EverettGrid) -> EverettModel {
    let n = grid.n_intervals();
    let mut masses = Vec::new();
    for p in 0..n {
        for q in p..n {
            let width = (q - p) as f64 / n as f64;
            masses.push(if p == q {
                3.0
            } else {
                10.0 * (-(width - 0.4).powi(2) / 0.05).exp()
            });
        }
    }
    EverettModel::new(grid.clone(), masses, -100.0).unwrap()
}

fn sweep(amplitudes: &[f64], samples: usize) -> Vec<f64> {
    let mut u = Vec::new();
    for &a in amplitudes {
        for k in 0..samples {
            u.push(-a + 2.0 * a * k as f64 / samples as f64);
        }
        for k in 0..samples {
            u.push(a - 2.0 * a * k as f64 / samples as f64);
        }
    }
    u
}

#[test]
fn noisy_triangles_identify_the_plant_and_the_cbh_agrees() {
    let grid = EverettGrid::uniform(-1.0, 1.0, 16).unwrap();
    let truth = plant(&grid);
    let u = sweep(&[1.0, 0.85, 0.7, 0.55, 0.4, 0.25, 0.9, 0.6, 0.3], 400);
    let mut noise = Noise(42);
    let y: Vec<f64> = truth
        .simulate(&u, None)
        .iter()
        .map(|v| v + 0.5 * noise.normal())
        .collect();
    let w = vec![1.0; u.len()];
    let opts = EverettFitOptions {
        smoothing: 1e-6,
        ..Default::default()
    };
    let fit = fit_everett(
        &grid,
        &[EverettRun {
            u: &u,
            y: &y,
            weight: &w,
            offset_col: 0,
            history: &[],
            gain: 1.0,
            drift: &[],
        }],
        1,
        opts,
    )
    .unwrap();
    assert!(
        (fit.rms - 0.5).abs() < 0.05,
        "fit rms {} vs noise 0.5",
        fit.rms
    );

    // Held out: other amplitudes and nested minor loops.
    let test = sweep(&[1.0, 0.95, 0.45, 0.75, 0.35], 300);
    let a = truth.simulate(&test, None);
    let b = fit.model.simulate(&test, None);
    let rms = (a.iter().zip(&b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt();
    let span = truth.everett(-1.0, 1.0);
    assert!(rms < 1e-3 * span, "held-out rms {rms} on a {span} span");

    // The CBH operator from the identified first-order curves reproduces the identified model at grid reversals.
    let (asc, desc) = fit.model.first_order_curves();
    let mut h =
        H::from_curve_data(&asc, &desc, &BuildOptions::default(), Initial::Negative).unwrap();
    let nodes = grid.nodes();
    let on_grid: Vec<f64> = [16, 3, 12, 6, 10, 8, 16, 0, 5]
        .iter()
        .map(|&k| nodes[k])
        .collect();
    let mut path = Vec::new();
    for win in on_grid.windows(2) {
        for k in 0..50 {
            path.push(win[0] + (win[1] - win[0]) * k as f64 / 50.0);
        }
    }
    let expect = fit.model.simulate(&path, None);
    let max_err = path
        .iter()
        .zip(&expect)
        .map(|(&x, &e)| (h.step(x) - e).abs())
        .fold(0.0, f64::max);
    assert!(max_err < 1e-9 * span, "CBH vs Everett model: {max_err}");

    // Off the grid too: the operator's strip rule keeps a curve's shape relative to its reversal inside the strip
    // and is linear in the reversal above it, which is what the bilinear table is (a reversible part included).
    let mut noise = Noise(7);
    let mut x = -1.0f64;
    let wander: Vec<f64> = (0..4000)
        .map(|_| {
            x = (x + 0.08 * noise.normal()).clamp(-1.0, 1.0);
            x
        })
        .collect();
    h.reset(Initial::Negative);
    let expect = fit.model.simulate(&wander, None);
    let max_err = wander
        .iter()
        .zip(&expect)
        .map(|(&x, &e)| (h.step(x) - e).abs())
        .fold(0.0, f64::max);
    assert!(
        max_err < 1e-9 * span,
        "CBH vs Everett model off the grid: {max_err}"
    );
}

/// First-order reversal curves of `truth` (down from positive saturation to each reversal, then up), with noise.
fn forc_runs(
    truth: &EverettModel,
    reversals: usize,
    points: usize,
    seed: u64,
) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut noise = Noise(seed);
    (0..reversals)
        .map(|k| {
            let turn = -1.0 + 1.9 * k as f64 / reversals as f64 + 0.013;
            let u: Vec<f64> = (0..=points)
                .map(|i| turn + (1.0 - turn) * i as f64 / points as f64)
                .collect();
            let y: Vec<f64> = truth
                .simulate_from(&[1.0, turn], &u, None)
                .iter()
                .map(|v| v + 0.05 * noise.normal())
                .collect();
            (u, y)
        })
        .collect()
}

#[test]
fn the_matrix_free_solver_finds_the_dense_solution() {
    // Nonuniform grid, a per-curve offset, smoothing: the dense active-set solve and the matrix-free one minimise
    // the same objective, so their tables and offsets agree.
    let nodes: Vec<f64> = (0..=14)
        .map(|k| -1.0 + 2.0 * (k as f64 / 14.0).powf(1.3))
        .collect();
    let grid = EverettGrid::new(nodes).unwrap();
    let truth = plant(&grid);
    let curves = forc_runs(&truth, 20, 60, 3);
    let w: Vec<Vec<f64>> = curves.iter().map(|(u, _)| vec![1.0; u.len()]).collect();
    let history: Vec<[f64; 2]> = curves.iter().map(|(u, _)| [1.0, u[0]]).collect();
    for (smoothing, signed) in [(1e-4, false), (1e-2, false), (1e-4, true)] {
        let opts = EverettFitOptions {
            smoothing,
            signed,
            ..Default::default()
        };
        let dense_runs: Vec<EverettRun<'_>> = curves
            .iter()
            .enumerate()
            .map(|(k, (u, y))| EverettRun {
                u,
                y,
                weight: &w[k],
                offset_col: k,
                history: &history[k],
                gain: 1.0,
                drift: &[],
            })
            .collect();
        let dense = fit_everett(&grid, &dense_runs, curves.len(), opts).unwrap();
        let large_runs: Vec<EverettFoldRun<'_>> = dense_runs
            .iter()
            .map(|r| EverettFoldRun {
                u: r.u,
                y: r.y,
                weight: r.weight,
                fold: &[],
                offset_col: r.offset_col,
                history: r.history,
                gain: 1.0,
                drift: &[],
            })
            .collect();
        let large = EverettRows::new(&grid, &large_runs, curves.len(), 0)
            .unwrap()
            .fit(opts)
            .unwrap();
        assert!(large.converged, "kkt {}", large.kkt_violation);
        let span = truth.everett(-1.0, 1.0);
        let worst = dense
            .model
            .node_values()
            .iter()
            .zip(large.model.node_values())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            worst < 1e-5 * span,
            "smoothing {smoothing}: node values differ by {worst} of {span}"
        );
        let worst = dense
            .offsets
            .iter()
            .zip(&large.offsets)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-5 * span, "offsets differ by {worst} of {span}");
        assert!(
            (dense.rss - large.rss).abs() <= 1e-5 * dense.rss,
            "{} vs {}",
            dense.rss,
            large.rss
        );
        assert_eq!(dense.n_rows, large.n_rows);
    }
}

#[test]
fn a_table_past_the_dense_limit_identifies_and_the_new_limit_is_a_clear_error() {
    // 92 intervals: 4278 cells, past the dense solver's unknowns.
    let grid = EverettGrid::uniform(-1.0, 1.0, 92).unwrap();
    assert!(grid.n_cells() > MAX_EVERETT_UNKNOWNS);
    let truth = plant(&grid);
    let curves = forc_runs(&truth, 80, 80, 5);
    let w: Vec<Vec<f64>> = curves.iter().map(|(u, _)| vec![1.0; u.len()]).collect();
    let history: Vec<[f64; 2]> = curves.iter().map(|(u, _)| [1.0, u[0]]).collect();
    let runs: Vec<EverettRun<'_>> = curves
        .iter()
        .enumerate()
        .map(|(k, (u, y))| EverettRun {
            u,
            y,
            weight: &w[k],
            offset_col: 0,
            history: &history[k],
            gain: 1.0,
            drift: &[],
        })
        .collect();
    let opts = EverettFitOptions {
        smoothing: 1e-3,
        ..Default::default()
    };
    let fit = fit_everett(&grid, &runs, 1, opts).unwrap();
    assert!(fit.model.is_monotone());
    // The noise is 0.05: the fit reaches it, not far below (overfitting) nor above (an unsolved problem).
    assert!(fit.rms > 0.04 && fit.rms < 0.06, "rms {}", fit.rms);
    // Held out: curves between the measured reversals.
    let span = truth.everett(-1.0, 1.0);
    let mut worst = 0.0f64;
    for k in 0..10 {
        let turn = -0.9 + 0.17 * k as f64;
        let u: Vec<f64> = (0..=50)
            .map(|i| turn + (1.0 - turn) * i as f64 / 50.0)
            .collect();
        let a = truth.simulate_from(&[1.0, turn], &u, None);
        let b = fit.model.simulate_from(&[1.0, turn], &u, None);
        worst = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(worst, f64::max);
    }
    assert!(
        worst < 0.01 * span,
        "held-out curves off by {worst} of a {span} span"
    );
    // Cross-validation takes the same path.
    let folds: Vec<Vec<usize>> = curves
        .iter()
        .enumerate()
        .map(|(k, (u, _))| vec![k % 2; u.len()])
        .collect();
    let fold_runs: Vec<EverettFoldRun<'_>> = runs
        .iter()
        .zip(&folds)
        .map(|(r, f)| EverettFoldRun {
            u: r.u,
            y: r.y,
            weight: r.weight,
            fold: f,
            offset_col: 0,
            history: r.history,
            gain: 1.0,
            drift: &[],
        })
        .collect();
    let mut cv = EverettFolds::new(&grid, &fold_runs, 1, 2).unwrap();
    assert!(cv.is_large());
    let scores = cv.score(opts, None).unwrap();
    let rms = (scores.iter().map(|s| s.sse).sum::<f64>()
        / scores.iter().map(|s| s.weight).sum::<f64>())
    .sqrt();
    // Every other curve held out: its reversal row of cells has no data of its own, the smoothing fills it in.
    assert!(
        rms > 0.04 && rms < 1e-3 * span,
        "cross-validated rms {rms} on a {span} span"
    );

    // Past the matrix-free path's unknowns: the limit error names what was asked, before anything is allocated.
    let n = (1..)
        .find(|&n: &usize| n * (n + 1) / 2 > MAX_EVERETT_LARGE_UNKNOWNS)
        .unwrap();
    let huge = EverettGrid::uniform(-1.0, 1.0, n).unwrap();
    match fit_everett(&huge, &runs, 1, opts) {
        Err(IdentificationError::Limit(e)) => {
            assert_eq!(e.limit, MAX_EVERETT_LARGE_UNKNOWNS);
            assert!(e.to_string().contains("unknowns of the Everett fit"), "{e}");
        }
        other => panic!("expected the limit error, got {other:?}"),
    }
}

mod properties {
    use bmr::identification::{EverettGrid, EverettModel, nnls_gram};
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// The NNLS solution satisfies the KKT conditions of `min ½xᵀQx − cᵀx, x ≥ 0`.
        #[test]
        fn nnls_meets_kkt(a in proptest::collection::vec(-1.0f64..1.0, 36), c in proptest::collection::vec(-1.0f64..1.0, 6)) {
            let n = 6;
            // Q = AᵀA + 0.1 I is symmetric positive definite.
            let mut q = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    q[i * n + j] = (0..n).map(|k| a[k * n + i] * a[k * n + j]).sum::<f64>()
                        + if i == j { 0.1 } else { 0.0 };
                }
            }
            let constrained = [true, true, true, true, false, false];
            let sol = nnls_gram(&q, &c, &constrained, 200).unwrap();
            for i in 0..n {
                let g: f64 = (0..n).map(|j| q[i * n + j] * sol.x[j]).sum::<f64>() - c[i];
                if constrained[i] {
                    prop_assert!(sol.x[i] >= 0.0);
                    prop_assert!(g >= -1e-9, "negative multiplier {g} at {i}");
                    if sol.x[i] > 1e-12 {
                        prop_assert!(g.abs() < 1e-9);
                    }
                } else {
                    prop_assert!(g.abs() < 1e-9);
                }
            }
        }

        /// Nonnegative masses give a monotone, wiping-out Preisach model: rising input never lowers the output and
        /// a closed minor loop returns to its starting output.
        #[test]
        fn everett_model_is_monotone_with_return_point_memory(
            masses in proptest::collection::vec(0.0f64..1.0, 28),
            path in proptest::collection::vec(-1.0f64..1.0, 2..30),
        ) {
            let grid = EverettGrid::uniform(-1.0, 1.0, 7).unwrap();
            let model = EverettModel::new(grid, masses, 0.0).unwrap();
            let mut u = vec![-1.0, 1.0];
            u.extend(&path);
            let y = model.simulate(&u, None);
            for k in 1..u.len() {
                prop_assert!((y[k] - y[k - 1]) * (u[k] - u[k - 1]) >= -1e-12);
            }
            // Go to a, reverse to b, return to a: the output at a is restored.
            let (a, b) = (path[0], path[path.len() - 1]);
            let mut loop_path = u.clone();
            loop_path.extend([a, b, a]);
            let yl = model.simulate(&loop_path, None);
            let n = yl.len();
            prop_assert!((yl[n - 1] - yl[n - 3]).abs() < 1e-9);
        }
    }
}
