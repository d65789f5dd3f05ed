//! An independent discretised Preisach plant (relay hysterons switched one by one, written without any of
//! the CBH code it checks) and helpers to measure it: the fixture of the Rust integration tests and the
//! workload of the benches.
#![allow(dead_code)]

/// A discretised Preisach plant on `[-1, 1]`: `n` thresholds per axis at cell midpoints, a smooth density,
/// relay hysterons switched one by one. Written independently of the CBH code it checks.
pub struct PreisachPlant {
    n: usize,
    weight: Vec<f64>,
    state: Vec<i8>,
    pub u: f64,
    pub y: f64,
}

impl PreisachPlant {
    pub fn new(n: usize) -> Self {
        let h = 2.0 / n as f64;
        let mut weight = vec![0.0; n * n];
        for i in 0..n {
            let alpha = -1.0 + (i as f64 + 0.5) * h;
            for j in 0..=i {
                let beta = -1.0 + (j as f64 + 0.5) * h;
                let (hc, hi) = ((alpha - beta) / 2.0, (alpha + beta) / 2.0);
                // Coercive spread around 0.25, interaction spread 0.3, plus a small reversible part.
                let mu = (-((hc - 0.25) / 0.18).powi(2)).exp() * (-(hi / 0.3).powi(2)).exp() + 0.05;
                weight[i * n + j] = mu * h * h;
            }
        }
        let total: f64 = weight.iter().sum();
        for w in &mut weight {
            *w *= 300.0 / total; // output span about ±300
        }
        let mut p = PreisachPlant {
            n,
            weight,
            state: vec![-1; n * n],
            u: -1.0,
            y: 0.0,
        };
        p.y = -p.weight.iter().sum::<f64>();
        p
    }

    fn alpha(&self, i: usize) -> f64 {
        -1.0 + (i as f64 + 0.5) * 2.0 / self.n as f64
    }

    /// Saturate negatively (all hysterons down).
    pub fn saturate_negative(&mut self) {
        self.step(-1.0);
    }

    /// Relays switch up when the input reaches their up-threshold α and down when it reaches β. After any step
    /// at `u` every relay with `α <= u` is up and every one with `β >= u` is down, so only the thresholds crossed
    /// since the previous input need visiting.
    pub fn step(&mut self, u: f64) -> f64 {
        let n = self.n;
        let (lo, hi) = (self.u.min(u), self.u.max(u));
        for i in 0..n {
            let t = self.alpha(i);
            if u > self.u && t > lo && t <= hi {
                for j in 0..=i {
                    self.set(i, j, 1);
                }
            }
            if u < self.u && t >= lo && t < hi {
                for row in i..n {
                    self.set(row, i, -1);
                }
            }
        }
        self.u = u;
        self.y
    }

    fn set(&mut self, i: usize, j: usize, s: i8) {
        let k = i * self.n + j;
        if self.state[k] != s {
            self.state[k] = s;
            self.y += 2.0 * f64::from(s) * self.weight[k];
        }
    }
}

/// Cell-edge grid of the plant: `n + 1` points from -1 to 1.
pub fn edge_grid(n: usize) -> Vec<f64> {
    (0..=n).map(|i| -1.0 + 2.0 * i as f64 / n as f64).collect()
}

/// One measured curve: inputs and outputs.
pub type Curve = (Vec<f64>, Vec<f64>);

/// First-order curves measured on the plant at the edge grid, reversals at `count` evenly spaced edge nodes.
pub fn measure_first_order(n: usize, count: usize) -> (Vec<Curve>, Vec<Curve>) {
    let grid = edge_grid(n);
    let step = n / (count - 1);
    let mut asc = Vec::new();
    let mut desc = Vec::new();
    for c in 0..count - 1 {
        // Ascending from reversal minimum m, after positive saturation.
        let mi = c * step;
        let mut p = PreisachPlant::new(n);
        p.step(1.0);
        p.step(grid[mi]);
        let (mut u, mut y) = (vec![], vec![]);
        for &g in &grid[mi..] {
            u.push(g);
            y.push(p.step(g));
        }
        asc.push((u, y));
        // Descending from reversal maximum M (after negative saturation).
        let ma = n - c * step;
        let mut p = PreisachPlant::new(n);
        p.step(-1.0);
        p.step(grid[ma]);
        let (mut u, mut y) = (vec![], vec![]);
        for &g in grid[..=ma].iter().rev() {
            u.push(g);
            y.push(p.step(g));
        }
        desc.push((u, y));
    }
    (asc, desc)
}

/// SplitMix64: small deterministic generator for test histories.
pub struct Rng(pub u64);
impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A random input history with nested, decaying reversals (off-grid), sampled finely between reversals.
pub fn random_history(rng: &mut Rng, reversals: usize, per_leg: usize) -> Vec<f64> {
    let mut out = vec![-1.0];
    let mut cur = -1.0;
    let (mut lo, mut hi) = (-1.0f64, 1.0f64);
    for r in 0..reversals {
        let target = if r % 2 == 0 {
            cur + (hi - cur) * (0.2 + 0.8 * rng.uniform())
        } else {
            cur - (cur - lo) * (0.2 + 0.8 * rng.uniform())
        };
        if rng.uniform() < 0.3 {
            // Occasionally restart the nesting so wiping-out happens.
            lo = -1.0;
            hi = 1.0;
        } else if r % 2 == 0 {
            lo = cur;
        } else {
            hi = cur;
        }
        for s in 1..=per_leg {
            out.push(cur + (target - cur) * s as f64 / per_leg as f64);
        }
        cur = target;
    }
    out
}
