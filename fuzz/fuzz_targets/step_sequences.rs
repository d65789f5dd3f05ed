//! Random step / inverse / compensator sequences on random valid (Preisach) tables: the real-time invariants
//! (output inside the major loop, exact inverse, never both coils, |I| within the limit, finite output, fault means
//! zero current) and bit-for-bit replay from a snapshot.
#![no_main]
use bmr::{BuildOptions, Compensator, Friction, Hysteresis, InverseKind};
use bmr_fuzz::{
    Reader, check_compensator_replay, check_inverse, check_step, initial, preisach_curves,
};
use libfuzzer_sys::fuzz_target;

type Op = Hysteresis<Vec<f64>, 6>;

fuzz_target!(|data: &[u8]| {
    let mut r = Reader::new(data);
    let (asc, desc) = preisach_curves(&mut r);
    let start = initial(&mut r);
    let Ok(mut h) = Op::from_curve_data(&asc, &desc, &BuildOptions::default(), start) else {
        return;
    };
    let (lo, hi) = h.input_range();
    let (y_lo, y_hi) = h.output_range();
    let span = y_hi - y_lo;
    let limit = 0.1 + 2.0 * r.unit();
    let gain = 0.01 + r.unit();
    let harmonics = r.count(4);
    let a: Vec<f64> = (0..harmonics).map(|_| r.finite(0.1 * span)).collect();
    let b: Vec<f64> = (0..harmonics).map(|_| r.finite(0.1 * span)).collect();
    let friction = Friction::<12>::from_coefficients(r.finite(0.05 * span), &a, &b)
        .expect("bounded coefficients");
    let inverse = if r.byte() % 3 == 0 {
        match h.paper_inverse() {
            Ok(p) => InverseKind::Paper(p),
            Err(_) => InverseKind::Exact,
        }
    } else {
        InverseKind::Exact
    };
    let mut comp =
        Compensator::new(h.clone(), inverse, friction, gain, limit).expect("valid compensator");
    while !r.is_empty() {
        match r.byte() % 8 {
            0 | 1 => {
                let u = lo + (hi - lo) * (1.2 * r.unit() - 0.1);
                check_step(&mut h, u);
            }
            2 => {
                let t = y_lo + span * (1.2 * r.unit() - 0.1);
                check_inverse(&mut h, t);
            }
            3 => {
                // A snapshot of the operator replays bit for bit.
                let s = h.snapshot();
                let us: Vec<f64> = (0..r.count(12))
                    .map(|_| lo + (hi - lo) * r.unit())
                    .collect();
                let first: Vec<u64> = us.iter().map(|&u| h.step(u).to_bits()).collect();
                h.restore(&s).expect("own snapshot");
                let again: Vec<u64> = us.iter().map(|&u| h.step(u).to_bits()).collect();
                assert_eq!(first, again, "operator replay differs");
            }
            4 | 5 => {
                let refs: Vec<(f64, f64)> = (0..1 + r.count(12))
                    .map(|_| {
                        let t = if r.byte() % 16 == 0 {
                            r.float()
                        } else {
                            y_lo + span * (1.4 * r.unit() - 0.2)
                        };
                        let theta = if r.byte() % 16 == 0 {
                            r.float()
                        } else {
                            20.0 * r.unit() - 10.0
                        };
                        (t, theta)
                    })
                    .collect();
                check_compensator_replay(&mut comp, &refs, limit);
            }
            6 => h.reset(initial(&mut r)),
            _ => comp.reset(initial(&mut r)),
        }
    }
});
