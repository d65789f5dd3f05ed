//! Test fixtures shared by the Rust integration tests: the independent Preisach plant of the `preisach-plant`
//! crate (also the workload of the benches in `benches/rust`).
#![allow(unused_imports)]
pub use preisach_plant::*;
