//! The Rust half of loading a model file: arbitrary curves, initial state, friction coefficients, converter gain,
//! current limit and extension parameters go through the constructors a loaded model goes through (tables, paper
//! inverse, friction, both compensators, effect parameters). Every input gives a model or an error; a model that
//! builds keeps the compensator's safety invariants.
#![no_main]
use bmr::plant::{Effect, EffectKind};
use bmr::{BuildOptions, Compensator, Friction, Hysteresis, InverseKind};
use bmr_fuzz::{Reader, arbitrary_curves, check_command, initial, preisach_curves};
use libfuzzer_sys::fuzz_target;

type Op = Hysteresis<Vec<f64>, 16>;

fuzz_target!(|data: &[u8]| {
    let mut r = Reader::new(data);
    let (asc, desc) = if r.byte() % 3 == 0 {
        (arbitrary_curves(&mut r), arbitrary_curves(&mut r))
    } else {
        preisach_curves(&mut r)
    };
    let start = initial(&mut r);
    let c0 = r.float();
    let a: Vec<f64> = (0..r.count(14)).map(|_| r.float()).collect();
    let b: Vec<f64> = (0..r.count(14)).map(|_| r.float()).collect();
    let gain = r.float();
    let limit = r.float();
    // Extension parameters as a model file names them: a known or unknown effect, known or unknown keys.
    for _ in 0..r.count(3) {
        let kinds = EffectKind::ALL;
        let kind = kinds[r.count(kinds.len() - 1)];
        let specs = kind.params();
        let given: Vec<(&str, f64)> = (0..r.count(3))
            .map(|_| {
                let name = if specs.is_empty() || r.byte() % 5 == 0 {
                    "unknown_parameter"
                } else {
                    specs[r.count(specs.len() - 1)].name
                };
                (name, r.float())
            })
            .collect();
        if let Ok(e) = Effect::from_params(kind, &given) {
            // Accepted parameters are within their documented ranges and round-trip by name.
            let back: Vec<(&str, f64)> = e.params();
            assert_eq!(Effect::from_params(kind, &back).ok(), Some(e));
        }
    }
    let Ok(h) = Op::from_curve_data(&asc, &desc, &BuildOptions::default(), start) else {
        return;
    };
    let friction = Friction::<12>::from_coefficients(c0, &a, &b).unwrap_or(Friction::zero());
    let paper = h.paper_inverse().ok();
    let mut comps = Vec::new();
    if let Ok(c) = Compensator::new(h.clone(), InverseKind::Exact, friction, gain, limit) {
        comps.push(c);
    }
    if let Some(p) = paper
        && let Ok(c) = Compensator::new(h, InverseKind::Paper(p), friction, gain, limit)
    {
        comps.push(c);
    }
    let (y_lo, y_hi) = (asc.iter().chain(&desc)).fold((f64::MAX, f64::MIN), |(lo, hi), (_, y)| {
        y.iter()
            .fold((lo, hi), |(lo, hi), &v| (lo.min(v), hi.max(v)))
    });
    for c in &mut comps {
        for _ in 0..16 {
            let t = if r.byte() % 4 == 0 {
                r.float()
            } else {
                y_lo + (y_hi - y_lo) * r.unit()
            };
            let theta = if r.byte() % 8 == 0 {
                r.float()
            } else {
                7.0 * r.unit()
            };
            let cmd = c.step(t, theta);
            check_command(&cmd, c.limit_a());
        }
    }
});
