//! Test fixtures shared by the Rust integration tests: the independent Preisach plant of the `preisach-plant`
//! crate (also the workload of the benches in `benches/rust`).
#![allow(unused_imports)]
pub use preisach_plant::*;

/// Values of one effect parameter at and around the edges of its range: its min, max, middle and default, then
/// just above its minimum (subnormals, `next_up`, the smallest nonzero value of a parameter whose 0 means
/// automatic). Some are outside the range: the caller expects those refused.
#[allow(dead_code)]
pub fn edge_values(spec: &bmr::vocabulary::ParamSpec) -> [f64; 9] {
    [
        spec.min,
        spec.max,
        0.5 * (spec.min + spec.max),
        spec.default,
        5e-324,
        1e-300,
        spec.min.next_up(),
        spec.min * (1.0 + 1e-15),
        spec.smallest_nonzero,
    ]
}
