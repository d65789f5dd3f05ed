//! The least-squares Everett identification against the CBH core: a table identified from noisy triangle data
//! reproduces the plant on held-out inputs, and the CBH operator built from its first-order curves agrees with it
//! exactly at grid reversals.
#![cfg(feature = "lstsq")]

use bmr::identification::{EverettFitOptions, EverettGrid, EverettModel, EverettRun, fit_everett};
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
