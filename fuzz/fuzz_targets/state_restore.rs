//! Damaged or forged state words (what a pickle carries): an operator and the virtual actuator either refuse them
//! or continue with finite outputs; never a panic, an index outside the tables or an allocation beyond the input.
#![no_main]
use bmr::plant::{VirtualActuator, preset};
use bmr::{BuildOptions, Hysteresis, Initial};
use bmr_fuzz::{Reader, check_step, preisach_curves};
use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

type Op = Hysteresis<Vec<f64>, 8>;

fn actuator() -> &'static VirtualActuator {
    static A: OnceLock<VirtualActuator> = OnceLock::new();
    A.get_or_init(|| {
        let mut config = preset("bmr2013").expect("preset");
        config
            .effects
            .insert(bmr::plant::Effect::parse("time_delay:delay_s=0.003").expect("effect"));
        VirtualActuator::new(config, 1).expect("actuator")
    })
}

fuzz_target!(|data: &[u8]| {
    let mut r = Reader::new(data);
    match r.byte() % 2 {
        0 => {
            let (asc, desc) = preisach_curves(&mut r);
            let Ok(mut h) =
                Op::from_curve_data(&asc, &desc, &BuildOptions::default(), Initial::Negative)
            else {
                return;
            };
            let (lo, hi) = h.input_range();
            for _ in 0..r.count(20) {
                h.step(lo + (hi - lo) * r.unit());
            }
            // Start from the operator's own words, then damage some of them.
            let mut words = h.snapshot().to_words();
            for _ in 0..r.count(4) {
                let i = r.count(words.len().saturating_sub(1));
                if let Some(w) = words.get_mut(i) {
                    *w = if r.byte() % 2 == 0 {
                        r.u64()
                    } else {
                        r.float().to_bits()
                    };
                }
            }
            if r.byte() % 8 == 0 {
                words.truncate(r.count(words.len()));
            }
            if let Ok(st) = h.state_from_words(&words) {
                h.restore(&st).expect("checked state restores");
                for _ in 0..8 {
                    check_step(&mut h, lo + (hi - lo) * r.unit());
                }
            }
        }
        _ => {
            let mut a = actuator().clone();
            let cmd: Vec<f64> = (0..r.count(30))
                .map(|_| 1.5 * (2.0 * r.unit() - 1.0))
                .collect();
            a.run(&cmd);
            let mut words = a.save_state();
            for _ in 0..r.count(4) {
                let i = r.count(words.len().saturating_sub(1));
                if let Some(w) = words.get_mut(i) {
                    *w = if r.byte() % 2 == 0 {
                        r.u64()
                    } else {
                        r.float().to_bits()
                    };
                }
            }
            if r.byte() % 8 == 0 {
                words.truncate(r.count(words.len()));
            }
            if a.load_state(&words).is_ok() {
                for s in a.run(&[0.5, -0.7, 1.0, 0.0]).torque_nmm {
                    assert!(s.is_finite(), "torque {s} after a restored state");
                }
            }
        }
    }
});
