//! bmr: congruency-based hysteresis (CBH) for bi-directional magneto-rheological actuators.
//!
//! The real-time core (curve tables, extrema memory, CBH operator, friction) is `no_std` and never allocates in a
//! `step`; building tables from measured curves needs `alloc`; identification (faer least squares) needs
//! `lstsq`; the Python module needs `python`.
#![cfg_attr(not(feature = "std"), no_std)]

#[cfg(feature = "alloc")]
extern crate alloc;

pub mod accommodation;
pub mod cbh;
pub mod compensator;
pub mod congruency;
pub mod controller;
pub mod creep;
#[cfg(feature = "alloc")]
pub mod curve_fit;
#[cfg(feature = "alloc")]
pub mod derived_family;
#[cfg(feature = "alloc")]
pub mod discrepancy;
pub mod error;
pub mod everett;
#[cfg(feature = "alloc")]
pub mod export;
#[cfg(feature = "ffi")]
pub mod ffi;
pub mod filters;
pub mod friction;
#[cfg(feature = "alloc")]
pub mod from_curves;
pub mod history;
pub mod inverse;
pub mod limits;
pub mod model_data;
#[cfg(feature = "alloc")]
pub mod node_selection;
#[cfg(feature = "alloc")]
pub mod paper_inverse;
#[cfg(feature = "std")]
pub mod plant;
pub mod rate_dependence;
pub mod reversals;
pub mod simulation;
pub mod stages;
#[cfg(feature = "alloc")]
pub mod table_builder;
pub mod trig;
pub mod viscous;
pub mod vocabulary;

pub use cbh::{Hysteresis, Initial, State};
pub use compensator::{Command, Compensator, CompensatorError, CompensatorState, InverseKind};
pub use congruency::{Congruency, congruency};
pub use controller::{
    Controller, ControllerDesign, ControllerError, ControllerSettings, ControllerState,
};
pub use error::{FamilyKind, TableError};
pub use everett::{Family, Strip};
pub use friction::{Friction, FrictionError};
pub use inverse::InverseInput;
pub use limits::LimitError;
pub use reversals::{ReversalFinder, ReversalOrder, ReversalPoint};
#[cfg(feature = "alloc")]
pub use table_builder::{BuildOptions, BuildReport, MeasuredCurve, build_tables};

#[cfg(feature = "python")]
mod python;

#[cfg(feature = "lstsq")]
pub mod identification;
