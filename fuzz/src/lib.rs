//! Shared decoding of fuzz inputs into curves, tables and operation sequences, and the invariants every target
//! checks. A failed invariant panics, which libFuzzer reports as a crash with the input that caused it.
use bmr::{Command, Compensator, Hysteresis, Initial};

/// Reads structured values from the fuzzer's bytes; past the end every read gives zeros.
pub struct Reader<'a> {
    data: &'a [u8],
}

impl<'a> Reader<'a> {
    pub fn new(data: &'a [u8]) -> Self {
        Reader { data }
    }

    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    pub fn byte(&mut self) -> u8 {
        match self.data.split_first() {
            Some((&b, rest)) => {
                self.data = rest;
                b
            }
            None => 0,
        }
    }

    pub fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.byte(), self.byte()])
    }

    pub fn u64(&mut self) -> u64 {
        let mut b = [0u8; 8];
        b.iter_mut().for_each(|x| *x = self.byte());
        u64::from_le_bytes(b)
    }

    /// A count in `0..=max`.
    pub fn count(&mut self, max: usize) -> usize {
        self.u16() as usize % (max + 1)
    }

    /// A value in `[0, 1]`.
    pub fn unit(&mut self) -> f64 {
        self.u16() as f64 / u16::MAX as f64
    }

    /// Any float, mostly ordinary: small multiples of 1/16, sometimes raw bits (NaN, infinities, subnormals,
    /// 1e308), sometimes a large power of ten.
    pub fn float(&mut self) -> f64 {
        match self.byte() % 16 {
            0 => f64::from_bits(self.u64()),
            1 => {
                let e = (self.byte() % 64) as i32 * 5 - 160;
                let sign = if self.byte() % 2 == 0 { 1.0 } else { -1.0 };
                sign * 10f64.powi(e)
            }
            2 => [
                f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY,
                0.0,
                -0.0,
                f64::MAX,
                f64::MIN_POSITIVE,
                5e-324,
            ][(self.byte() % 8) as usize],
            _ => (self.u16() as i16) as f64 / 16.0,
        }
    }

    /// A finite float in `[-scale, scale]`.
    pub fn finite(&mut self, scale: f64) -> f64 {
        (2.0 * self.unit() - 1.0) * scale
    }
}

/// One curve: inputs and outputs.
pub type Curve = (Vec<f64>, Vec<f64>);

/// Curves with arbitrary lengths and values (mostly invalid tables).
pub fn arbitrary_curves(r: &mut Reader<'_>) -> Vec<Curve> {
    let n = r.count(6);
    (0..n)
        .map(|_| {
            let len = r.count(8);
            let u = (0..len).map(|_| r.float()).collect();
            let y = (0..len + usize::from(r.byte() % 8 == 0))
                .map(|_| r.float())
                .collect();
            (u, y)
        })
        .collect()
}

/// First-order curves of a random discrete Preisach model (nonnegative masses on an `n × n` grid over
/// `[lo, hi]`), optionally perturbed: always a table a careful user could measure. Returns
/// `(ascending, descending)`.
pub fn preisach_curves(r: &mut Reader<'_>) -> (Vec<Curve>, Vec<Curve>) {
    let n = 2 + r.count(10);
    let scale = [1.0, 1e-3, 1e3, 1e-9, 1e9, 1e149][(r.byte() % 6) as usize];
    let lo = r.finite(scale);
    let hi = lo + scale * (0.01 + r.unit());
    let g: Vec<f64> = (0..=n)
        .map(|i| lo + (hi - lo) * i as f64 / n as f64)
        .collect();
    let out_scale = [1.0, 300.0, 1e-6, 1e6, 1e149][(r.byte() % 5) as usize];
    // mass[p][q] for cells p <= q (β in interval p, α in interval q); the diagonal holds a reversible part.
    let mut mass = vec![vec![0.0; n]; n];
    for (p, row) in mass.iter_mut().enumerate() {
        for m in row.iter_mut().skip(p) {
            *m = out_scale * r.unit() / (n * n) as f64;
        }
    }
    // E(g_i, g_j) = sum of masses with i <= p <= q < j.
    let everett = |i: usize, j: usize| -> f64 {
        let mut s = 0.0;
        for (p, row) in mass.iter().enumerate().take(j).skip(i) {
            s += row[p..j].iter().sum::<f64>();
        }
        s
    };
    let y_lo = r.finite(out_scale);
    let y_hi = y_lo + everett(0, n);
    let noise = if r.byte() % 4 == 0 {
        1e-4 * (y_hi - y_lo)
    } else {
        0.0
    };
    let jitter = |r: &mut Reader<'_>| noise * (2.0 * r.unit() - 1.0);
    let mut asc = Vec::new();
    let mut desc = Vec::new();
    for i in 0..n {
        // Ascending from g_i (after positive saturation, down to g_i): y(g_i) = y_hi - E(g_i, g_n).
        let y_m = y_hi - everett(i, n);
        let u: Vec<f64> = g[i..].to_vec();
        let y: Vec<f64> = (i..=n).map(|j| y_m + everett(i, j) + jitter(r)).collect();
        asc.push((u, y));
        // Descending from g_{n-i}: y(M) = y_lo + E(g_0, M).
        let top = n - i;
        let y_top = y_lo + everett(0, top);
        let u: Vec<f64> = g[..=top].iter().rev().copied().collect();
        let y: Vec<f64> = (0..=top)
            .rev()
            .map(|j| y_top - everett(j, top) + jitter(r))
            .collect();
        desc.push((u, y));
    }
    // Sometimes drop a curve (fewer reversals in one family) or resample a curve off the grid.
    if r.byte() % 4 == 0 && asc.len() > 2 {
        let k = 1 + r.count(asc.len() - 2);
        asc.remove(k);
    }
    if r.byte() % 4 == 0 {
        let k = r.count(desc.len() - 1);
        let (u, y) = &desc[k];
        if u.len() >= 3 {
            let t = 0.1 + 0.8 * r.unit();
            let mid_u = u[0] + t * (u[1] - u[0]);
            let mid_y = y[0] + t * (y[1] - y[0]);
            let (mut u2, mut y2) = (u.clone(), y.clone());
            u2.insert(1, mid_u);
            y2.insert(1, mid_y);
            desc[k] = (u2, y2);
        }
    }
    (asc, desc)
}

/// An initial state for an operator.
pub fn initial(r: &mut Reader<'_>) -> Initial {
    match r.byte() % 4 {
        0 => Initial::Negative,
        1 => Initial::Positive,
        2 => Initial::Ascending(r.float()),
        _ => Initial::Descending(r.float()),
    }
}

/// Stepping invariants: finite output inside the major loop for every non-NaN input, NaN for NaN.
pub fn check_step<const N: usize>(h: &mut Hysteresis<Vec<f64>, N>, u: f64) -> f64 {
    let (y_lo, y_hi) = h.output_range();
    let slack = 1e-9 * (y_hi - y_lo);
    let y = h.step(u);
    if u.is_nan() {
        assert!(y.is_nan(), "NaN input gave {y}");
    } else {
        assert!(y.is_finite(), "input {u} gave {y}");
        assert!(
            y >= y_lo - slack && y <= y_hi + slack,
            "input {u} gave {y} outside the major loop [{y_lo}, {y_hi}]"
        );
    }
    y
}

/// Exact-inverse invariants: a finite input; a reachable target is hit to 1e-9 of the output span, or — where
/// the branch is so steep that the input's own rounding moves the output more (a near-jump of the tables) — the
/// outputs of the input's neighbours a few ulps away bracket it: exact to the round-off of the input.
pub fn check_inverse<const N: usize>(h: &mut Hysteresis<Vec<f64>, N>, target: f64) {
    let (y_lo, y_hi) = h.output_range();
    let before = h.clone();
    let inv = h.step_inverse(target);
    if target.is_nan() {
        assert!(inv.saturated);
        return;
    }
    assert!(inv.input.is_finite(), "inverse of {target} gave {inv:?}");
    if !inv.saturated {
        let tol = 1e-9 * (y_hi - y_lo);
        let y = before.clone().step(inv.input);
        if (y - target).abs() > tol {
            let d = before.input_round_off();
            let below = before.clone().step(inv.input - d);
            let above = before.clone().step(inv.input + d);
            assert!(
                below.min(above) - tol <= target && target <= below.max(above) + tol,
                "forward(inverse({target})) = {y}; at ±{d:e} of the input: {below}, {above}"
            );
        }
    }
}

/// Compensator safety invariants: never both coils, |I| within the limit, finite currents and volts, fault means
/// zero current.
pub fn check_command(c: &Command, limit: f64) {
    assert!(
        [c.current_a, c.coil1_a, c.coil2_a, c.volt1_v, c.volt2_v]
            .iter()
            .all(|v| v.is_finite()),
        "non-finite command {c:?}"
    );
    assert!(!(c.coil1_a > 0.0 && c.coil2_a > 0.0), "both coils {c:?}");
    assert!(
        c.coil1_a >= 0.0 && c.coil2_a >= 0.0,
        "negative coil current {c:?}"
    );
    assert!(
        c.current_a.abs() <= limit,
        "current above the limit {limit}: {c:?}"
    );
    if c.fault {
        assert_eq!(c.current_a, 0.0, "fault with current {c:?}");
    }
}

/// Run `ops` on a compensator twice from the same snapshot: the replay must match to the bit.
pub fn check_compensator_replay<const N: usize, const K: usize>(
    c: &mut Compensator<Vec<f64>, N, K>,
    refs: &[(f64, f64)],
    limit: f64,
) {
    let s = c.snapshot();
    let first: Vec<Command> = refs
        .iter()
        .map(|&(t, th)| {
            let cmd = c.step(t, th);
            check_command(&cmd, limit);
            cmd
        })
        .collect();
    c.restore(&s).expect("own snapshot");
    for (&(t, th), a) in refs.iter().zip(&first) {
        let b = c.step(t, th);
        assert_eq!(
            (a.current_a.to_bits(), a.fault, a.saturated),
            (b.current_a.to_bits(), b.fault, b.saturated),
            "replay differs"
        );
    }
}
