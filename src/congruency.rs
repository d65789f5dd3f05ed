//! Congruency diagnostic: do the ascending and descending families describe the same Everett function?
//!
//! For a Preisach system the rise from reversal `m` to `u` equals the fall from reversal `u` to `m`:
//! `E^a(m, u) = E^d(u, m)`. Measured data that break it are not Preisach (output nonlinearity, rate effects,
//! drift); the mismatch, in output units, is a free diagnostic.
use crate::everett::Family;

/// Mismatch between the two families over every pair of measured reversals (minimum below maximum).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Congruency {
    /// Largest absolute mismatch (output units).
    pub max_abs: f64,
    /// Root-mean-square mismatch (output units).
    pub rms: f64,
    /// Number of `(reversal, input)` pairs compared.
    pub pairs: usize,
}

/// Compare `E^a(m, M)` with `E^d(M, m)` for every measured minimum `m` and measured maximum `M > m` (descending
/// family in rising orientation, as stored).
pub fn congruency<S: AsRef<[f64]>>(asc: &Family<S>, desc: &Family<S>) -> Congruency {
    let mut sum_sq = 0.0;
    let mut max_abs: f64 = 0.0;
    let mut pairs = 0usize;
    let mut add = |d: f64| {
        sum_sq += d * d;
        max_abs = max_abs.max(d.abs());
        pairs += 1;
    };
    // Pairs of measured reversals: minimum m (ascending family) below maximum M (descending family). Both sides
    // are then read on measured curves (no off-grid interpolation across reversals).
    let mut hint = 0;
    for &m in asc.reversals() {
        let sa = asc.strip(m);
        for &v in desc.reversals() {
            let big_m = -v;
            if big_m > m {
                let sd = desc.strip(v);
                add(asc.everett(&sa, big_m, &mut hint) - desc.everett(&sd, -m, &mut hint));
            }
        }
    }
    let rms = if pairs > 0 {
        libm::sqrt(sum_sq / pairs as f64)
    } else {
        0.0
    };
    Congruency {
        max_abs,
        rms,
        pairs,
    }
}
