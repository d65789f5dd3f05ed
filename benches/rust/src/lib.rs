//! The fixed workload of the step benches and of the callgrind instruction count: tables measured from a
//! 200-threshold Preisach plant (the tests' independent `preisach-plant`, 21 curves per family, ±1.25 A,
//! ±300 N·mm) and a random multi-peak torque reference.
use preisach_plant as common;

use bmr::{BuildOptions, Friction, Hysteresis, Initial};

pub fn operator() -> Hysteresis<Vec<f64>, 64> {
    let (a, d) = common::measure_first_order(200, 21);
    let scale = |c: &Vec<common::Curve>| -> Vec<common::Curve> {
        c.iter()
            .map(|(u, y)| (u.iter().map(|x| 1.25 * x).collect(), y.clone()))
            .collect()
    };
    let (a, d) = (scale(&a), scale(&d));
    Hysteresis::from_curve_data(&a, &d, &BuildOptions::default(), Initial::Negative).unwrap()
}

/// Random multi-peak torque reference (N·mm) sampled at 1 kHz: peaks every 0.2-2 s, ±280 N·mm.
pub fn multipeak_reference(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = common::Rng(seed);
    let mut out = Vec::with_capacity(n);
    let (mut from, mut to, mut len, mut i) = (0.0, 0.0, 1usize, 0usize);
    while out.len() < n {
        if i == len {
            from = to;
            to = 560.0 * (rng.uniform() - 0.5);
            len = 200 + (rng.uniform() * 1800.0) as usize;
            i = 0;
        }
        let t = i as f64 / len as f64;
        out.push(from + (to - from) * 0.5 * (1.0 - (std::f64::consts::PI * t).cos()));
        i += 1;
    }
    out
}

/// The paper's 3-harmonic friction (N·mm).
pub fn friction() -> Friction<{ bmr::friction::MAX_ORDER }> {
    Friction::from_amplitude_phase(12.0, &[25.0, 8.0, 4.0], &[0.3, 1.1, -0.7]).unwrap()
}

/// Every extension stage the compensator has, at sizes the diagnosis finds on the virtual actuator (1 kHz).
pub fn every_stage() -> Vec<bmr::vocabulary::Params> {
    use bmr::vocabulary::{EffectKind, Params};
    let p = |k: EffectKind, v: &[(&'static str, f64)]| Params::new(k.spec(), v).unwrap();
    vec![
        p(EffectKind::TimeDelay, &[("delay_s", 0.01)]),
        p(EffectKind::CoilLag, &[("tau_s", 0.02)]),
        p(EffectKind::NonCongruent, &[("curvature", 1.5)]),
        p(
            EffectKind::ThermalDrift,
            &[("gain_loss", 0.1), ("tau_s", 60.0)],
        ),
        p(
            EffectKind::TorqueRipple,
            &[("eps", 0.05), ("phase_rad", 0.4)],
        ),
        p(
            EffectKind::FrictionHarmonics,
            &[("order", 6.0), ("amplitude_nmm", 5.0)],
        ),
        p(EffectKind::FrictionCurrent, &[("gain_per_a", 0.5)]),
    ]
}
