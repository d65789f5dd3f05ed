//! Table building from curves: arbitrary and Preisach-like (valid, noisy, resampled) families with arbitrary build
//! options. Every input gives a table or an error, never a panic or an allocation beyond the limits; a table that
//! builds steps inside its major loop, inverts exactly, replays from a snapshot, round-trips its state words and
//! rebuilds from its own curves (what a saved model holds).
#![no_main]
use bmr::{BuildOptions, Hysteresis, Initial};
use bmr_fuzz::{Reader, arbitrary_curves, check_inverse, check_step, initial, preisach_curves};
use libfuzzer_sys::fuzz_target;

type Op = Hysteresis<Vec<f64>, 8>;

fuzz_target!(|data: &[u8]| {
    let mut r = Reader::new(data);
    let (asc, desc) = if r.byte() % 4 == 0 {
        (arbitrary_curves(&mut r), arbitrary_curves(&mut r))
    } else {
        preisach_curves(&mut r)
    };
    let mut opts = BuildOptions::default();
    let custom = r.byte() % 3 == 0;
    if custom {
        opts.monotone_tolerance = r.float();
        opts.reach_tolerance = r.float();
        opts.closure_tolerance = r.float();
        opts.max_nodes = match r.byte() % 4 {
            0 => r.u64() as usize,
            _ => r.count(2000),
        };
    }
    let start = initial(&mut r);
    let Ok(mut h) = Op::from_curve_data(&asc, &desc, &opts, start) else {
        return;
    };
    let (lo, hi) = h.input_range();
    let (y_lo, y_hi) = h.output_range();
    let s = h.snapshot();
    let mut twin = h.clone();
    // Decode the operations first so that they can be replayed on the twin from the snapshot.
    let mut ops: Vec<(u8, f64)> = Vec::new();
    while !r.is_empty() {
        let op = r.byte() % 4;
        let v = match op {
            0 => lo + (hi - lo) * (1.2 * r.unit() - 0.1),
            1 => r.float(),
            2 => y_lo + (y_hi - y_lo) * (1.2 * r.unit() - 0.1),
            _ => 0.0,
        };
        ops.push((op, v));
    }
    let apply = |h: &mut Op, checked: bool| -> Vec<u64> {
        let mut out = Vec::new();
        for &(op, v) in &ops {
            match op {
                0 | 1 if checked => out.push(check_step(h, v).to_bits()),
                0 | 1 => out.push(h.step(v).to_bits()),
                2 if checked => {
                    check_inverse(h, v);
                    out.push(h.output().to_bits());
                }
                2 => {
                    h.step_inverse(v);
                    out.push(h.output().to_bits());
                }
                _ => {
                    let words = h.snapshot().to_words();
                    let back = h.state_from_words(&words).expect("own state words");
                    assert_eq!(back.to_words(), words, "state words round trip");
                }
            }
        }
        out
    };
    let first = apply(&mut h, true);
    twin.restore(&s).expect("own snapshot");
    assert_eq!(
        apply(&mut twin, false),
        first,
        "replay from a snapshot differs"
    );
    // A model file may store the operator's curves and rebuilds them with the default options: an operator built
    // with those rebuilds from its own curves. (With custom tolerances a table at a tolerance's edge may not:
    // the stored rows are running maxima of the measured increments.)
    if !custom {
        let (a, d) = h.curves();
        if let Err(e) = Op::from_curve_data(&a, &d, &opts, Initial::Negative) {
            panic!("the operator's own curves do not rebuild it: {e}");
        }
    }
});
