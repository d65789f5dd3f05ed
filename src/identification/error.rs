//! What can go wrong when identifying friction or an Everett table from data.
use core::fmt;

use crate::limits::LimitError;

/// A problem with one run of training data passed to the Everett fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RunError {
    /// Input, output and weight arrays of different lengths.
    Lengths {
        inputs: usize,
        outputs: usize,
        weights: usize,
    },
    /// The run's offset column does not exist.
    OffsetColumn { column: usize, columns: usize },
    /// A NaN or infinite input (every input drives the memory) or output of a weighted sample.
    NonFinite {
        what: &'static str,
        sample: usize,
        value: f64,
    },
    /// A run gain that is not positive and finite.
    BadGain { gain: f64 },
    /// The run's regressors would pass a documented size limit (see [`crate::limits`]).
    Limit(LimitError),
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            RunError::Lengths {
                inputs,
                outputs,
                weights,
            } => write!(
                f,
                "input has {inputs} samples, output {outputs}, weights {weights}"
            ),
            RunError::OffsetColumn { column, columns } => {
                write!(f, "offset column {column} out of range ({columns} offsets)")
            }
            RunError::NonFinite {
                what,
                sample,
                value,
            } => write!(f, "{what} sample {sample} is not finite ({value})"),
            RunError::BadGain { gain } => {
                write!(f, "run gain must be positive and finite, got {gain}")
            }
            RunError::Limit(e) => write!(f, "{e}"),
        }
    }
}

/// Why an identification failed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum IdentificationError {
    /// A requested size above its documented limit (see [`crate::limits`]).
    Limit(LimitError),
    /// Two arrays that must match in length do not.
    LengthMismatch {
        first: &'static str,
        first_len: usize,
        second: &'static str,
        second_len: usize,
    },
    /// A NaN or infinite value.
    NonFinite {
        what: &'static str,
        index: usize,
        value: f64,
    },
    /// Not enough samples for the number of coefficients of a friction fit.
    TooFewSamples {
        order: usize,
        needed: usize,
        got: usize,
    },
    /// The angle samples leave a friction coefficient undetermined (rank deficiency).
    Undetermined { order: usize, coefficient: usize },
    /// An Everett grid with fewer than two nodes.
    GridTooShort { nodes: usize },
    /// Everett grid nodes that do not strictly increase.
    GridNotIncreasing {
        index: usize,
        value: f64,
        previous: f64,
    },
    /// A uniform grid request without finite `lo < hi` and at least one interval.
    BadUniformGrid { lo: f64, hi: f64, intervals: usize },
    /// Wrong number of cell masses for the grid.
    MassCount {
        intervals: usize,
        expected: usize,
        got: usize,
    },
    /// A negative (or non-finite) cell mass.
    NegativeMass { index: usize, value: f64 },
    /// A table with a negative cell mass asked for what needs monotone branches (its CBH operator, an inverse).
    SignedTable { index: usize, value: f64 },
    /// A regularisation weight that is negative or NaN.
    BadParameter { name: &'static str, value: f64 },
    /// An Everett fit without offset columns.
    NoOffsets,
    /// Cross-validation with fewer than two folds.
    TooFewFolds { folds: usize },
    /// A problem in one training run.
    Run { run: usize, error: RunError },
    /// No sample had a positive weight.
    NoSamples,
    /// An offset column that no weighted sample uses.
    EmptyOffset { column: usize },
    /// The regularised normal equations are not positive definite.
    NotPositiveDefinite,
    /// Internal dimension mismatch of the nonnegative least-squares solver.
    SolverDimensions { q: usize, c: usize, mask: usize },
    /// The identified table's first-order curves were rejected by the CBH table builder.
    Table(crate::error::TableError),
}

impl From<crate::error::TableError> for IdentificationError {
    fn from(e: crate::error::TableError) -> Self {
        IdentificationError::Table(e)
    }
}

impl From<LimitError> for IdentificationError {
    fn from(e: LimitError) -> Self {
        IdentificationError::Limit(e)
    }
}

fn coefficient_name(f: &mut fmt::Formatter<'_>, j: usize) -> fmt::Result {
    if j == 0 {
        return f.write_str("c0");
    }
    let k = j.div_ceil(2);
    if j % 2 == 1 {
        write!(f, "a_{k}")
    } else {
        write!(f, "b_{k}")
    }
}

impl fmt::Display for IdentificationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use IdentificationError as E;
        match *self {
            E::Limit(l) => write!(f, "{l}"),
            E::Table(ref t) => write!(f, "{t}"),
            E::LengthMismatch {
                first,
                first_len,
                second,
                second_len,
            } => write!(
                f,
                "{first} has {first_len} samples but {second} has {second_len}"
            ),
            E::NonFinite { what, index, value } => {
                write!(f, "{what} {index} is not finite ({value})")
            }
            E::TooFewSamples { order, needed, got } => write!(
                f,
                "friction order {order} needs more than {needed} samples, got {got}"
            ),
            E::Undetermined { order, coefficient } => {
                write!(
                    f,
                    "friction order {order}: the angle samples do not determine coefficient "
                )?;
                coefficient_name(f, coefficient)?;
                f.write_str(
                    " (too little angle coverage); lower the order or use a run covering full revolutions",
                )
            }
            E::GridTooShort { nodes } => {
                write!(f, "Everett grid needs at least 2 nodes, got {nodes}")
            }
            E::GridNotIncreasing {
                index,
                value,
                previous,
            } => write!(
                f,
                "Everett grid must strictly increase; node {index} ({value}) follows {previous}"
            ),
            E::BadUniformGrid { lo, hi, intervals } => write!(
                f,
                "uniform Everett grid needs finite lo < hi and at least one interval (lo={lo}, hi={hi}, n={intervals})"
            ),
            E::MassCount {
                intervals,
                expected,
                got,
            } => write!(
                f,
                "Everett model on {intervals} intervals needs {expected} cell masses, got {got}"
            ),
            E::NegativeMass { index, value } => write!(
                f,
                "cell mass {index} must be finite and nonnegative, got {value}"
            ),
            E::SignedTable { index, value } => write!(
                f,
                "the table is signed (cell mass {index} is {value}): its branches need not be monotone, so it \
                 has no CBH operator and no exact inverse; it only predicts"
            ),
            E::BadParameter { name, value } => {
                write!(f, "{name} must be finite and nonnegative, got {value}")
            }
            E::NoOffsets => f.write_str("at least one offset column is needed"),
            E::TooFewFolds { folds } => {
                write!(f, "cross-validation needs at least 2 folds, got {folds}")
            }
            E::Run { run, error } => write!(f, "run {run}: {error}"),
            E::NoSamples => f.write_str("no samples with positive weight to fit"),
            E::EmptyOffset { column } => write!(f, "offset column {column} has no samples"),
            E::NotPositiveDefinite => {
                f.write_str("normal equations are not positive definite; increase the ridge")
            }
            E::SolverDimensions { q, c, mask } => write!(
                f,
                "NNLS dimension mismatch: Q has {q} entries, c {c} and the constraint mask {mask}"
            ),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for IdentificationError {}
