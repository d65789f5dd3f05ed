//! Documented bounds on every size and magnitude a caller can ask for.
//!
//! Each size that comes from a user (curve counts and grid nodes of a table, harmonic orders, grid intervals and
//! offsets of a least-squares fit, sample counts of generated signals) is checked against one of these limits
//! *before* anything is allocated, so that a hostile or mistaken request gives a clear error instead of an
//! allocation failure that aborts the process. The limits are far above what the physics needs (tens of curves,
//! about a thousand nodes, 12 harmonics, 50 intervals) and keep every allocation below about 1 GiB.
use core::fmt;

/// Most first-order curves in one family of a table.
pub const MAX_CURVES: usize = 4096;
/// Largest `max_nodes` a table may be resampled to.
pub const MAX_NODES: usize = 1 << 16;
/// Most stored values (curves × grid nodes) in one family of a table: 128 MiB of `f64`.
pub const MAX_TABLE_VALUES: usize = 1 << 24;
/// Largest magnitude of a table input or output, and of a friction model's largest torque
/// (`|c0| + Σ |a_k| + |b_k|`). Products of two input differences must stay finite (`(2e150)² < f64::MAX`) and a
/// friction torque subtracted from any finite reference stays finite; data beyond it belong in other units.
pub const MAX_MAGNITUDE: f64 = 1e150;
/// Most samples one call may generate (angle previews, simulated runs): 128 MiB per `f64` column.
pub const MAX_GENERATED_SAMPLES: usize = 1 << 24;
/// Highest harmonic order of a friction fit.
pub const MAX_FIT_ORDER: usize = 64;
/// Most grid intervals of an Everett (Preisach) table.
pub const MAX_EVERETT_INTERVALS: usize = 2048;
/// Most unknowns (cell masses plus output offsets) of one least-squares Everett fit solved on its dense normal
/// equations, which hold the square of this many values (128 MiB); larger fits take the matrix-free path.
pub const MAX_EVERETT_UNKNOWNS: usize = 4096;
/// Most unknowns of one least-squares Everett fit on the matrix-free path (about 510 grid intervals): it holds a
/// dozen vectors of this many values (13 MiB) besides the regressor entries.
pub const MAX_EVERETT_LARGE_UNKNOWNS: usize = 1 << 17;
/// Most regressor entries the matrix-free Everett fit stores (12 bytes each: 384 MiB).
pub const MAX_EVERETT_ENTRIES: usize = 1 << 25;
/// Most cross-validation folds of one Everett fit: each holds its own normal equations (up to 128 MiB).
pub const MAX_CV_FOLDS: usize = 10;
/// Most pivoting iterations of the nonnegative least-squares solver.
pub const MAX_SOLVER_ITERATIONS: usize = 100_000;
/// Most `(input, output)` points in the first-order curves generated from an Everett table (both families).
pub const MAX_CURVE_POINTS: usize = 1 << 24;

/// A requested size above its documented limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LimitError {
    /// What was asked for, in the caller's terms (e.g. "grid nodes × curves of the table").
    pub what: &'static str,
    /// The size asked for (`usize::MAX` when it does not even fit in a `usize`).
    pub requested: usize,
    /// The limit (one of the constants of this module).
    pub limit: usize,
}

impl fmt::Display for LimitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.requested == usize::MAX {
            write!(
                f,
                "{} is beyond the limit of {} (too large to count)",
                self.what, self.limit
            )
        } else {
            write!(
                f,
                "{} is {}, above the limit of {}",
                self.what, self.requested, self.limit
            )
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for LimitError {}

/// `Ok(requested)` if `requested <= limit`, else the error naming `what`.
pub fn check(what: &'static str, requested: usize, limit: usize) -> Result<usize, LimitError> {
    if requested <= limit {
        Ok(requested)
    } else {
        Err(LimitError {
            what,
            requested,
            limit,
        })
    }
}

/// Product of sizes, saturating at `usize::MAX` (which is above every limit).
pub const fn product(a: usize, b: usize) -> usize {
    match a.checked_mul(b) {
        Some(p) => p,
        None => usize::MAX,
    }
}

/// Sum of sizes, saturating at `usize::MAX`.
pub const fn sum(a: usize, b: usize) -> usize {
    match a.checked_add(b) {
        Some(s) => s,
        None => usize::MAX,
    }
}
