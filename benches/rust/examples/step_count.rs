//! Runs `N` compensator steps (exact inverse) on a random multi-peak reference: a fixed workload for counting
//! instructions per step with callgrind (`benches/callgrind.sh`). Usage: `step_count N [hysteresis|compensator|
//! extended|controller]` (`extended`: every extension stage on; `controller`: the closed loop around it, measuring
//! 0.95 × the model's torque plus 2 N·mm; `closed_loop`: that controller driving the `rig_preisach` virtual
//! actuator with a coil lag and heating through `bmr::plant::run_closed_loop`, as `bmr.simulate_closed_loop` does).
use bmr_bench as workload;

use bmr::plant::VirtualActuator;
use bmr::plant::effects::{Effect, EffectKind};
use bmr::{Compensator, Controller, ControllerSettings, InverseKind};
use std::hint::black_box;

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(100_000);
    let what = args.next().unwrap_or_else(|| "compensator".into());
    let h = workload::operator();
    let refs = workload::multipeak_reference(200_000, 3);
    let f = workload::friction();
    let mut acc = 0.0;
    match what.as_str() {
        "hysteresis" => {
            let mut op = h;
            for i in 0..n {
                acc += op.step(black_box(refs[i % refs.len()] / 240.0));
            }
        }
        "controller" => {
            let c = Compensator::new(h, InverseKind::Exact, f, 0.125, 1.25)
                .unwrap()
                .with_extensions(&workload::every_stage(), 0.001, 300.0)
                .unwrap();
            let mut c = Controller::new(c, 0.001, ControllerSettings::default()).unwrap();
            let mut y = f64::NAN;
            for i in 0..n {
                acc += c
                    .step(
                        black_box(refs[i % refs.len()]),
                        black_box(i as f64 * 0.002),
                        black_box(y),
                    )
                    .current_a;
                y = 0.95 * c.compensator().model_torque_nmm() + 2.0;
            }
        }
        "closed_loop" => {
            let c = Compensator::new(h, InverseKind::Exact, f, 0.125, 1.25)
                .unwrap()
                .with_extensions(&workload::every_stage(), 0.001, 300.0)
                .unwrap();
            let mut c = Controller::new(c, 0.001, ControllerSettings::default()).unwrap();
            let effects = [
                Effect::from_params(EffectKind::CoilLag, &[("tau_s", 0.02)]).unwrap(),
                Effect::from_params(
                    EffectKind::ThermalDrift,
                    &[("gain_loss", 0.1), ("tau_s", 60.0)],
                )
                .unwrap(),
            ];
            let mut plant =
                VirtualActuator::from_preset("rig_preisach", 1000.0, &effects, 1).unwrap();
            // The reference repeated until `n` samples, each pass one `run_closed_loop` (the plant's own angle).
            let mut left = n;
            while left > 0 {
                let m = left.min(refs.len());
                bmr::plant::run_closed_loop(&mut c, &mut plant, &refs[..m], None, |_, _, s, _| {
                    acc += s.torque_nmm;
                });
                left -= m;
            }
        }
        "compensator" | "extended" => {
            let c = Compensator::new(h, InverseKind::Exact, f, 0.125, 1.25).unwrap();
            let mut c = if what == "extended" {
                c.with_extensions(&workload::every_stage(), 0.001, 300.0)
                    .unwrap()
            } else {
                c
            };
            for i in 0..n {
                acc += c
                    .step(black_box(refs[i % refs.len()]), black_box(i as f64 * 0.002))
                    .current_a;
            }
        }
        other => panic!("unknown workload {other:?}"),
    }
    println!("{acc}");
}
