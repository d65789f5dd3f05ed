//! Identification from measured runs (least squares with faer): seal friction harmonics and Everett tables.
pub mod error;
pub mod everett_fit;
pub mod everett_folds;
pub mod everett_large;
pub mod everett_regressors;
pub mod friction_fit;
pub mod nnls;

pub use error::{IdentificationError, RunError};
pub use everett_fit::{
    EverettFit, EverettFitOptions, EverettInput, EverettModel, EverettRegression, EverettRun,
    fit_everett,
};
pub use everett_folds::{EverettFoldRun, EverettFolds, FoldScore};
pub use everett_large::{EverettRows, solve_bounded};
pub use everett_regressors::{EverettGrid, NormalEquations, PreisachMemory, simulate_everett};
pub use friction_fit::{FrictionFit, fit_friction};
pub use nnls::{NnlsSolution, nnls_gram, nnls_gram_warm};
