//! Errors raised when a curve table is built or validated (never in `step`).
use core::fmt;

use crate::limits::LimitError;

/// Which first-order curve family a table error refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FamilyKind {
    Ascending,
    Descending,
}

impl fmt::Display for FamilyKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FamilyKind::Ascending => "ascending",
            FamilyKind::Descending => "descending",
        })
    }
}

/// What is wrong with a table, with the curve index and sample index it concerns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TableError {
    /// Fewer than two curves in a family.
    TooFewCurves { family: FamilyKind, curves: usize },
    /// A curve with fewer than two samples, or input/output arrays of different lengths.
    BadLength {
        family: FamilyKind,
        curve: usize,
        inputs: usize,
        outputs: usize,
    },
    /// NaN or infinite input or output.
    NonFinite {
        family: FamilyKind,
        curve: usize,
        sample: usize,
    },
    /// Neither family has two curves (one family needs the major branch and one more).
    NotEnoughCurves { ascending: usize, descending: usize },
    /// The input steps back against the curve's direction by more than the limit (not one first-order curve).
    InputBacktrack {
        family: FamilyKind,
        curve: usize,
        sample: usize,
        by: f64,
        limit: f64,
    },
    /// The only curve of a family (used as its major branch to derive the family) does not start at saturation.
    NotAMajorBranch {
        family: FamilyKind,
        start: f64,
        saturation: f64,
    },
    /// Every sample of the curve is at (or behind) its reversal input.
    NoInputSpan { family: FamilyKind, curve: usize },
    /// Output moves against the curve's direction by more than the tolerance.
    OutputNotMonotone {
        family: FamilyKind,
        curve: usize,
        sample: usize,
        drop: f64,
        tolerance: f64,
    },
    /// Two curves start at the same reversal input.
    DuplicateReversal {
        family: FamilyKind,
        curve: usize,
        other: usize,
        input: f64,
    },
    /// Two curves start at reversals closer together than the table's input resolution.
    ReversalsTooClose {
        family: FamilyKind,
        curve: usize,
        input: f64,
        other: usize,
        other_input: f64,
        resolution: f64,
    },
    /// A curve starts within the table's input resolution of the saturation input: it has no room.
    ReversalAtSaturation {
        family: FamilyKind,
        curve: usize,
        input: f64,
        saturation: f64,
    },
    /// An input or output beyond the supported magnitude [`crate::limits::MAX_MAGNITUDE`].
    OutOfRange {
        family: FamilyKind,
        curve: usize,
        sample: usize,
        what: &'static str,
        value: f64,
    },
    /// The table would exceed a documented size limit (see [`crate::limits`]).
    TooLarge {
        family: Option<FamilyKind>,
        limit: LimitError,
    },
    /// A curve does not reach the saturation input of its direction.
    ShortCurve {
        family: FamilyKind,
        curve: usize,
        reaches: f64,
        needed: f64,
    },
    /// A reversal lies outside the input range spanned by the two major branches.
    ReversalOutOfRange {
        family: FamilyKind,
        curve: usize,
        input: f64,
        lo: f64,
        hi: f64,
    },
    /// The major branches do not meet at the saturations (relative mismatch of the output span).
    MajorLoopOpen {
        at_input: f64,
        ascending: f64,
        descending: f64,
    },
    /// The major loop has no height (output at positive saturation not above negative saturation).
    NoOutputSpan { lo: f64, hi: f64 },
    /// A curve's output leaves the major loop by more than the closure tolerance.
    OutsideMajorLoop {
        family: FamilyKind,
        curve: usize,
        output: f64,
        lo: f64,
        hi: f64,
    },
    /// A raw internal table is inconsistent (dimensions, grid, rows).
    BadTable {
        family: FamilyKind,
        what: &'static str,
        index: usize,
    },
    /// Snapshot taken from another table.
    ForeignState,
    /// A serialised state that is damaged or not an operator state.
    BadState { what: &'static str },
    /// A parameter outside its documented range.
    BadParameter { name: &'static str, value: f64 },
}

impl fmt::Display for TableError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            TableError::TooFewCurves { family, curves } => {
                write!(
                    f,
                    "{family} family has {curves} curve(s); at least 2 are needed (the major branch and one more)"
                )
            }
            TableError::BadLength {
                family,
                curve,
                inputs,
                outputs,
            } => write!(
                f,
                "{family} curve {curve}: needs at least 2 samples with as many inputs as outputs (got {inputs} inputs, {outputs} outputs)"
            ),
            TableError::NonFinite {
                family,
                curve,
                sample,
            } => {
                write!(
                    f,
                    "{family} curve {curve}, sample {sample}: value is NaN or infinite"
                )
            }
            TableError::NotEnoughCurves {
                ascending,
                descending,
            } => write!(
                f,
                "{ascending} ascending and {descending} descending curve(s): one family needs at least 2 (its major branch and one more); the other family is then derived from it"
            ),
            TableError::InputBacktrack {
                family,
                curve,
                sample,
                by,
                limit,
            } => {
                let dir = match family {
                    FamilyKind::Ascending => "falls",
                    FamilyKind::Descending => "rises",
                };
                write!(
                    f,
                    "{family} curve {curve}, sample {sample}: input {dir} back by {by:.6} against the curve's direction (limit {limit:.6}); is it cut at the right reversals?"
                )
            }
            TableError::NotAMajorBranch {
                family,
                start,
                saturation,
            } => write!(
                f,
                "the only {family} curve starts at {start}, but the other family's curves reach saturation at {saturation}: a family given as one curve must be its major branch (from saturation), from which the family is derived"
            ),
            TableError::NoInputSpan { family, curve } => write!(
                f,
                "{family} curve {curve}: every sample is at its reversal input; the curve has no span"
            ),
            TableError::OutputNotMonotone {
                family,
                curve,
                sample,
                drop,
                tolerance,
            } => {
                let dir = match family {
                    FamilyKind::Ascending => "falls",
                    FamilyKind::Descending => "rises",
                };
                write!(
                    f,
                    "{family} curve {curve}, sample {sample}: output {dir} by {drop:.6} against the curve's direction (limit {tolerance:.6}); is it a curve of the other family?"
                )
            }
            TableError::DuplicateReversal {
                family,
                curve,
                other,
                input,
            } => {
                write!(
                    f,
                    "{family} curves {other} and {curve} start at the same reversal input {input}"
                )
            }
            TableError::ReversalsTooClose {
                family,
                curve,
                input,
                other,
                other_input,
                resolution,
            } => write!(
                f,
                "{family} curves {other} and {curve} start at reversal inputs {other_input} and {input}, closer than \
                 the table's input resolution {resolution:e}; drop one of them or merge them"
            ),
            TableError::ReversalAtSaturation {
                family,
                curve,
                input,
                saturation,
            } => write!(
                f,
                "{family} curve {curve} starts at {input}, within the table's input resolution of the saturation \
                 input {saturation}: a curve there has no room"
            ),
            TableError::OutOfRange {
                family,
                curve,
                sample,
                what,
                value,
            } => write!(
                f,
                "{family} curve {curve}, sample {sample}: {what} {value:e} is beyond the supported magnitude {:e} \
                 (express the data in other units)",
                crate::limits::MAX_MAGNITUDE
            ),
            TableError::TooLarge {
                family: Some(family),
                limit,
            } => write!(f, "{family} family: {limit}"),
            TableError::TooLarge {
                family: None,
                limit,
            } => write!(f, "{limit}"),
            TableError::ShortCurve {
                family,
                curve,
                reaches,
                needed,
            } => write!(
                f,
                "{family} curve {curve} stops at input {reaches}; it must reach saturation at {needed}"
            ),
            TableError::ReversalOutOfRange {
                family,
                curve,
                input,
                lo,
                hi,
            } => write!(
                f,
                "{family} curve {curve} starts at {input}, outside the major-loop input range [{lo}, {hi}]"
            ),
            TableError::MajorLoopOpen {
                at_input,
                ascending,
                descending,
            } => write!(
                f,
                "major branches do not meet at saturation input {at_input}: ascending ends at {ascending}, descending at {descending}"
            ),
            TableError::OutsideMajorLoop {
                family,
                curve,
                output,
                lo,
                hi,
            } => write!(
                f,
                "{family} curve {curve} reaches output {output}, outside the major loop [{lo}, {hi}] by more than \
                 the closure tolerance: not a first-order curve between these major branches"
            ),
            TableError::NoOutputSpan { lo, hi } => write!(
                f,
                "the major loop has no output span (output {lo} at negative saturation, {hi} at positive)"
            ),
            TableError::BadTable {
                family,
                what,
                index,
            } => {
                write!(f, "{family} table: {what} (at index {index})")
            }
            TableError::ForeignState => {
                f.write_str("snapshot does not belong to this operator's table")
            }
            TableError::BadState { what } => {
                write!(f, "serialised operator state is not valid: {what}")
            }
            TableError::BadParameter { name, value } => {
                write!(f, "parameter {name} = {value} is out of range")
            }
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for TableError {}
