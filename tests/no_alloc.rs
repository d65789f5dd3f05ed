//! `step` never allocates: a counting global allocator watches a long random run.
mod common;

use bmr::{BuildOptions, Hysteresis, Initial};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;
static ALLOCS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn hysteresis_step_does_not_allocate() {
    let (asc, desc) = common::measure_first_order(60, 13);
    let a: Vec<_> = asc
        .iter()
        .map(|(u, y)| (u.as_slice(), y.as_slice()))
        .collect();
    let d: Vec<_> = desc
        .iter()
        .map(|(u, y)| (u.as_slice(), y.as_slice()))
        .collect();
    let mut h =
        Hysteresis::<Vec<f64>, 8>::from_curves(&a, &d, &BuildOptions::default(), Initial::Negative)
            .unwrap();
    let inputs = common::random_history(&mut common::Rng(3), 2000, 9);
    let before = ALLOCS.load(Ordering::SeqCst);
    let mut acc = 0.0;
    for &u in &inputs {
        acc += h.step(u); // overflows the 8-point memory: merges must not allocate either
    }
    let snap = h.snapshot();
    h.restore(&snap).unwrap();
    let after = ALLOCS.load(Ordering::SeqCst);
    assert!(acc.is_finite());
    assert_eq!(after - before, 0, "step allocated {} times", after - before);
}
