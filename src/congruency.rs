//! Congruency diagnostic: do the ascending and descending families describe the same Everett function?
//!
//! For a Preisach system the rise from reversal `m` to `u` equals the fall from reversal `u` to `m`:
//! `E^a(m, u) = E^d(u, m)`. Measured data that break it are not Preisach (output nonlinearity, rate effects,
//! drift); the mismatch, in output units, is a free diagnostic.
use crate::everett::Family;

/// Mismatch between the two families over every measured reversal and every grid input beyond it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Congruency {
    /// Largest absolute mismatch (output units).
    pub max_abs: f64,
    /// Root-mean-square mismatch (output units).
    pub rms: f64,
    /// Number of `(reversal, input)` pairs compared.
    pub pairs: usize,
}

/// Compare `E^a(m, u)` with `E^d(u, m)` at every measured reversal of both families (descending family in
/// rising orientation, as stored).
pub fn congruency<S: AsRef<[f64]>>(asc: &Family<S>, desc: &Family<S>) -> Congruency {
    let mut sum_sq = 0.0;
    let mut max_abs: f64 = 0.0;
    let mut pairs = 0usize;
    let mut add = |d: f64| {
        sum_sq += d * d;
        max_abs = max_abs.max(d.abs());
        pairs += 1;
    };
    let mut hint = 0;
    // Measured ascending curves against the descending family at off-grid maxima.
    for (j, &m) in asc.reversals().iter().enumerate() {
        for (k, &u) in asc.grid().iter().enumerate() {
            if u > m {
                let s = desc.strip(-u);
                add(asc.row(j)[k] - desc.everett(&s, -m, &mut hint));
            }
        }
    }
    // Measured descending curves against the ascending family at off-grid minima.
    for (j, &v_max) in desc.reversals().iter().enumerate() {
        for (k, &v) in desc.grid().iter().enumerate() {
            if v > v_max {
                let s = asc.strip(-v);
                add(desc.row(j)[k] - asc.everett(&s, -v_max, &mut hint));
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
