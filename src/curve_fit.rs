//! Measured curves as they come off a bench: monotone least-squares fits, how far the data move against a
//! curve's direction, and adaptive binning of raw samples on the input axis.
//!
//! Real first-order curves are not monotone: the output keeps moving the old way for a while after the input
//! reverses (continued switching, after-effect), samples are noisy and dwell segments creep. None of that is a
//! reason to reject the data or to reshape it silently: every function here *measures* the move against the
//! curve's direction ([`Violation`]) and returns the least-squares monotone fit, so the caller can report both.
//!
//! All curves are handled in *rising orientation* (input increasing, output nondecreasing); a descending curve is
//! passed mirrored (`-u`, `-y`).
use alloc::vec::Vec;

/// Weighted pool-adjacent-violators: replace `y` by its weighted least-squares nondecreasing fit (`w > 0`).
pub fn isotonic(y: &mut [f64], w: &[f64]) {
    debug_assert_eq!(y.len(), w.len());
    // Blocks as (value, weight, count).
    let mut blocks: Vec<(f64, f64, usize)> = Vec::with_capacity(y.len());
    for (&v, &wi) in y.iter().zip(w) {
        blocks.push((v, wi, 1));
        while blocks.len() > 1 {
            let n = blocks.len();
            let (v1, w1, c1) = blocks[n - 2];
            let (v2, w2, c2) = blocks[n - 1];
            if v1 <= v2 {
                break;
            }
            let ws = w1 + w2;
            let v = if ws > 0.0 {
                (v1 * w1 + v2 * w2) / ws
            } else {
                0.5 * (v1 + v2)
            };
            blocks.truncate(n - 2);
            blocks.push((v, ws, c1 + c2));
        }
    }
    let mut k = 0;
    for (v, _, c) in blocks {
        for slot in &mut y[k..k + c] {
            *slot = v;
        }
        k += c;
    }
}

/// The largest move of a sequence against its (rising) direction: `max_k (max_{i<=k} e_i - e_k)`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Violation {
    /// How far the sequence falls below its running peak (>= 0, output units).
    pub amount: f64,
    /// Index (in the sequence) where the fall is largest.
    pub index: usize,
}

/// Measure how far `e` moves against its rising direction.
pub fn violation(e: &[f64]) -> Violation {
    let mut out = Violation::default();
    let mut peak = f64::NEG_INFINITY;
    for (i, &v) in e.iter().enumerate() {
        peak = peak.max(v);
        if peak - v > out.amount {
            out = Violation {
                amount: peak - v,
                index: i,
            };
        }
    }
    out
}

/// A measured curve prepared for a table: strictly increasing inputs, nondecreasing outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct MonotoneCurve {
    /// Inputs, strictly increasing; the first is the curve's reversal.
    pub u: Vec<f64>,
    /// Least-squares monotone outputs at `u`.
    pub y: Vec<f64>,
    /// Largest move of the (input-sorted, equal-input-averaged) data against the curve's direction.
    pub violation: Violation,
    /// Sample index (in the order given) of the violation's lowest point.
    pub violation_sample: usize,
    /// RMS change the monotone fit made to the data (output units).
    pub reshaped_rms: f64,
    /// Largest step of the input against the curve's direction (input units, >= 0).
    pub input_backtrack: f64,
    /// Sample index (in the order given) where the input steps back furthest.
    pub input_backtrack_sample: usize,
}

/// Prepare one measured curve (rising orientation, first sample = reversal) for a table, with no smoothing:
/// samples are sorted by input (inputs at or below the reversal count as the reversal), equal inputs are averaged
/// and the outputs are replaced by their least-squares nondecreasing fit. What that changed is measured.
/// Inputs must be finite and there must be at least one sample.
pub fn monotone_curve(u: &[f64], y: &[f64]) -> MonotoneCurve {
    let n = u.len().min(y.len());
    let start = u[0];
    // How far the input steps back (noisy currents): largest drop below the running maximum.
    let back = violation(&u[..n]);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| u[a].max(start).total_cmp(&u[b].max(start)).then(a.cmp(&b)));
    let mut xs: Vec<f64> = Vec::with_capacity(n);
    let mut ys: Vec<f64> = Vec::with_capacity(n);
    let mut ws: Vec<f64> = Vec::with_capacity(n);
    let mut first: Vec<usize> = Vec::with_capacity(n);
    for &i in &order {
        let x = u[i].max(start);
        match xs.last() {
            Some(&last) if last == x => {
                let k = ys.len() - 1;
                ys[k] += y[i];
                ws[k] += 1.0;
            }
            _ => {
                xs.push(x);
                ys.push(y[i]);
                ws.push(1.0);
                first.push(i);
            }
        }
    }
    for (v, w) in ys.iter_mut().zip(&ws) {
        *v /= *w;
    }
    let viol = violation(&ys);
    let raw = ys.clone();
    isotonic(&mut ys, &ws);
    let mut ss = 0.0;
    let mut wsum = 0.0;
    for ((a, b), w) in raw.iter().zip(&ys).zip(&ws) {
        ss += w * (a - b) * (a - b);
        wsum += w;
    }
    MonotoneCurve {
        violation_sample: first[viol.index],
        violation: viol,
        reshaped_rms: if wsum > 0.0 {
            libm::sqrt(ss / wsum)
        } else {
            0.0
        },
        input_backtrack: back.amount,
        input_backtrack_sample: back.index,
        u: xs,
        y: ys,
    }
}

/// A curve fitted from raw noisy samples by adaptive binning on the input axis and a monotone fit.
#[derive(Debug, Clone, PartialEq)]
pub struct BinnedCurve {
    /// Bin nodes: inputs strictly increasing, starting at the reversal (the first sample's input).
    pub u: Vec<f64>,
    /// Monotone outputs at the nodes.
    pub y: Vec<f64>,
    /// Samples in each bin (the fit's weights).
    pub counts: Vec<usize>,
    /// Estimated noise of one output sample (robust, from third differences along the input).
    pub noise: f64,
    /// Typical standard deviation of a node (noise over the square root of the median bin count).
    pub node_sigma: f64,
    /// Largest move of the binned (unconstrained) outputs against the curve's direction.
    pub violation: Violation,
    /// Sample index (in the order given) at the start of the bin where the violation is largest.
    pub violation_sample: usize,
    /// RMS change the monotone fit made to the binned outputs.
    pub reshaped_rms: f64,
    /// Largest step of the input against the curve's direction (input units).
    pub input_backtrack: f64,
}

/// Noise of `e` sampled along increasing inputs: the median absolute third difference, scaled to one standard
/// deviation of white noise (`Δ³` of white noise has standard deviation `σ√20`; smooth curvature cancels).
pub fn sample_noise(e: &[f64]) -> f64 {
    if e.len() < 4 {
        return 0.0;
    }
    let mut d: Vec<f64> = e
        .windows(4)
        .map(|w| libm::fabs(w[3] - 3.0 * w[2] + 3.0 * w[1] - w[0]))
        .collect();
    let mid = d.len() / 2;
    d.select_nth_unstable_by(mid, f64::total_cmp);
    d[mid] / (0.674_489_75 * libm::sqrt(20.0))
}

/// Fit one raw curve (rising orientation; the first sample is the reversal) by adaptive bins on the input axis:
/// a pilot fit on bins of `pilot` samples estimates the curvature and the sample density, each bin then gets the
/// width that balances its curvature bias against its noise (`w = (144 σ² / (ρ y''²))^(1/5)`: wide where the curve
/// is straight, a few samples where it switches sharply, one sample per bin for noise-free data). Each bin's node
/// is its local linear fit at the bin's mean input (the first bin's at the reversal, the last bin's at the last
/// input); the node outputs then get their weighted least-squares monotone fit. `None` if fewer than 2 samples.
pub fn binned_curve(u: &[f64], y: &[f64], pilot: usize) -> Option<BinnedCurve> {
    let n = u.len().min(y.len());
    if n < 2 {
        return None;
    }
    let start = u[0];
    let back = violation(&u[..n]).amount;
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| u[a].max(start).total_cmp(&u[b].max(start)).then(a.cmp(&b)));
    let xs: Vec<f64> = order.iter().map(|&i| u[i].max(start)).collect();
    let es: Vec<f64> = order.iter().map(|&i| y[i]).collect();
    let noise = sample_noise(&es);
    let x_end = xs[n - 1];

    // Pilot: equal-count bins, their means, curvature and density.
    let k0 = pilot.clamp(3, n.max(3));
    let mut pu: Vec<f64> = Vec::new();
    let mut py: Vec<f64> = Vec::new();
    let mut pdens: Vec<f64> = Vec::new();
    let mut pend: Vec<f64> = Vec::new();
    let mut i = 0;
    while i < n {
        let j = (i + k0).min(n);
        let c = (j - i) as f64;
        pu.push(xs[i..j].iter().sum::<f64>() / c);
        py.push(es[i..j].iter().sum::<f64>() / c);
        let width = (xs[j - 1] - xs[i]).max(0.0);
        pdens.push(if width > 0.0 {
            c / width
        } else {
            f64::INFINITY
        });
        pend.push(xs[j - 1]);
        i = j;
    }
    let nb = pu.len();
    let mut curv = alloc::vec![0.0f64; nb];
    for b in 1..nb.saturating_sub(1) {
        let (h0, h1) = (pu[b] - pu[b - 1], pu[b + 1] - pu[b]);
        if h0 > 0.0 && h1 > 0.0 {
            curv[b] =
                libm::fabs(2.0 * ((py[b + 1] - py[b]) / h1 - (py[b] - py[b - 1]) / h0) / (h0 + h1));
        }
    }
    if nb >= 3 {
        curv[0] = curv[1];
        curv[nb - 1] = curv[nb - 2];
    }
    // Conservative: the largest curvature of the neighbouring pilot bins.
    let curv_max: Vec<f64> = (0..nb)
        .map(|b| {
            let lo = b.saturating_sub(1);
            let hi = (b + 1).min(nb - 1);
            curv[lo..=hi].iter().copied().fold(0.0, f64::max)
        })
        .collect();
    // The pilot curvature passes through zero at a branch's inflection point and is noisy where pilot bins
    // repeat inputs, so the bias-variance width has two guards: the curvature is floored at a tenth of its median
    // over the curve, and no bin is wider than 1/MIN_BINS of the curve's input range (a wide bin's local line
    // would otherwise stand in for a whole sigmoid).
    const MIN_BINS: f64 = 16.0;
    let curv_floor = {
        let mut c: Vec<f64> = curv_max.iter().copied().filter(|v| *v > 0.0).collect();
        if c.is_empty() {
            0.0
        } else {
            let mid = c.len() / 2;
            c.select_nth_unstable_by(mid, f64::total_cmp);
            0.1 * c[mid]
        }
    };
    let max_width = (x_end - start) / MIN_BINS;
    let width_at = |b: usize| -> f64 {
        if noise <= 0.0 || !pdens[b].is_finite() {
            return 0.0;
        }
        let c = curv_max[b].max(curv_floor);
        if c <= 0.0 {
            return max_width;
        }
        libm::pow(144.0 * noise * noise / (pdens[b] * c * c), 0.2).min(max_width)
    };

    // Final bins: walk the sorted samples, each bin as wide as its pilot bin allows (at least one distinct
    // input; equal inputs always share a bin).
    let mut nodes_u: Vec<f64> = Vec::new();
    let mut nodes_y: Vec<f64> = Vec::new();
    let mut counts: Vec<usize> = Vec::new();
    let mut firsts: Vec<usize> = Vec::new();
    let mut pb = 0;
    let mut i = 0;
    while i < n {
        while pb + 1 < nb && pend[pb] < xs[i] {
            pb += 1;
        }
        let w = width_at(pb);
        let mut j = i + 1;
        while j < n && (xs[j] == xs[j - 1] || xs[j] - xs[i] < w) {
            j += 1;
        }
        let first_bin = i == 0;
        let last_bin = j == n;
        let at = if first_bin {
            start
        } else if last_bin {
            x_end
        } else {
            xs[i..j].iter().sum::<f64>() / (j - i) as f64
        };
        nodes_u.push(at);
        nodes_y.push(local_linear(&xs[i..j], &es[i..j], at));
        counts.push(j - i);
        firsts.push(order[i]);
        i = j;
    }
    // A single bin spanning the whole curve: give it its two ends.
    if nodes_u.len() == 1 {
        let (a, b) = (local_linear(&xs, &es, start), local_linear(&xs, &es, x_end));
        nodes_u = alloc::vec![start, x_end];
        nodes_y = alloc::vec![a, b];
        counts = alloc::vec![n - n / 2, n / 2];
        firsts.push(order[n / 2]);
    }
    // Inputs must strictly increase (the last bin's end may equal its mean for a single sample).
    let mut m = 1;
    for k in 1..nodes_u.len() {
        if nodes_u[k] > nodes_u[m - 1] {
            nodes_u[m] = nodes_u[k];
            nodes_y[m] = nodes_y[k];
            counts[m] = counts[k];
            firsts[m] = firsts[k];
            m += 1;
        } else {
            counts[m - 1] += counts[k];
        }
    }
    nodes_u.truncate(m);
    nodes_y.truncate(m);
    counts.truncate(m);
    firsts.truncate(m);
    if nodes_u.len() < 2 {
        return None;
    }
    let viol = violation(&nodes_y);
    let raw = nodes_y.clone();
    let weights: Vec<f64> = counts.iter().map(|&c| c as f64).collect();
    isotonic(&mut nodes_y, &weights);
    let (mut ss, mut wsum) = (0.0, 0.0);
    for ((a, b), w) in raw.iter().zip(&nodes_y).zip(&weights) {
        ss += w * (a - b) * (a - b);
        wsum += w;
    }
    let mut sorted_counts = counts.clone();
    let mid = sorted_counts.len() / 2;
    sorted_counts.select_nth_unstable(mid);
    let node_sigma = noise / libm::sqrt(sorted_counts[mid].max(1) as f64);
    Some(BinnedCurve {
        violation_sample: firsts[viol.index],
        violation: viol,
        reshaped_rms: libm::sqrt(ss / wsum.max(f64::MIN_POSITIVE)),
        input_backtrack: back,
        u: nodes_u,
        y: nodes_y,
        counts,
        noise,
        node_sigma,
    })
}

/// Least-squares line through `(x, e)` evaluated at `at` (the mean when the inputs do not spread).
fn local_linear(x: &[f64], e: &[f64], at: f64) -> f64 {
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let me = e.iter().sum::<f64>() / n;
    let mut sxx = 0.0;
    let mut sxe = 0.0;
    for (&a, &b) in x.iter().zip(e) {
        sxx += (a - mx) * (a - mx);
        sxe += (a - mx) * (b - me);
    }
    let spread = x[x.len() - 1] - x[0];
    if x.len() >= 3 && sxx > 1e-12 * spread * spread * n && sxx > 0.0 {
        me + sxe / sxx * (at - mx)
    } else {
        me
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn isotonic_pools_violators_by_weight() {
        let mut y = [1.0, 3.0, 2.0, 4.0];
        isotonic(&mut y, &[1.0, 1.0, 3.0, 1.0]);
        assert_eq!(y, [1.0, 2.25, 2.25, 4.0]);
        let v = violation(&[0.0, 2.0, 1.5, 0.5, 3.0]);
        assert_eq!((v.amount, v.index), (1.5, 3));
    }

    #[test]
    fn monotone_curve_measures_and_fits_a_dip_after_the_reversal() {
        // The output keeps falling for two samples after the input reversed, then rises.
        let u = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5];
        let y = [0.0, -0.3, -0.4, 0.5, 1.0, 2.0];
        let c = monotone_curve(&u, &y);
        assert!((c.violation.amount - 0.4).abs() < 1e-12);
        assert_eq!(c.violation_sample, 2);
        assert!(c.y.windows(2).all(|w| w[1] >= w[0]));
        assert_eq!(c.u, u);
        assert!(c.reshaped_rms > 0.0);
    }

    #[test]
    fn monotone_curve_averages_equal_inputs_and_clamps_the_start() {
        let u = [0.0, -0.01, 0.2, 0.2, 0.4];
        let y = [0.0, 0.2, 1.0, 3.0, 4.0];
        let c = monotone_curve(&u, &y);
        assert_eq!(c.u, [0.0, 0.2, 0.4]);
        assert_eq!(c.y, [0.1, 2.0, 4.0]);
        assert!((c.input_backtrack - 0.01).abs() < 1e-15);
    }

    #[test]
    fn noise_free_samples_are_kept_one_per_bin() {
        let u: Vec<f64> = (0..50).map(|i| i as f64 * 0.02).collect();
        let y: Vec<f64> = u.iter().map(|x| x * x).collect();
        let b = binned_curve(&u, &y, 16).unwrap();
        assert_eq!(b.u.len(), 50);
        for (a, c) in b.y.iter().zip(&y) {
            assert!((a - c).abs() < 1e-12);
        }
    }

    #[test]
    fn a_straight_stretch_does_not_swallow_the_curved_end() {
        // Repeats of one branch on the same input grid that disagree by a small offset (the scatter of real
        // repeats), straight in the middle and bending towards saturation: the pilot curvature of the straight
        // stretch is zero to round-off, which once made one bin run from there to the end of the curve.
        let truth = |x: f64| {
            let d = (libm::fabs(x) - 0.5).max(0.0);
            if x < 0.0 { x + d * d } else { x - d * d }
        };
        let (mut u, mut y) = (Vec::new(), Vec::new());
        for repeat in 0..6 {
            let offset = if repeat % 2 == 0 { 0.01 } else { -0.01 };
            for i in 0..=250 {
                let x = -1.0 + i as f64 * 0.008;
                u.push(x);
                y.push(truth(x) + offset);
            }
        }
        let b = binned_curve(&u, &y, 16).unwrap();
        assert!(b.u.len() >= 16, "{} bins", b.u.len());
        for (x, v) in b.u.iter().zip(&b.y) {
            assert!(
                (v - truth(*x)).abs() < 0.02,
                "node at {x}: {v} against {}",
                truth(*x)
            );
        }
    }
}
