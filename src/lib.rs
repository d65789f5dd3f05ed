//! bmr: congruency-based hysteresis (CBH) for bi-directional magneto-rheological actuators.
#![cfg_attr(not(feature = "std"), no_std)]

#[cfg(feature = "alloc")]
extern crate alloc;

#[cfg(feature = "std")]
pub mod plant;

#[cfg(feature = "python")]
mod python;
