//! Criterion benches: `Hysteresis::step` and `Compensator::step` (exact and paper inverse) on a random
//! multi-peak input, tables measured from a 200-threshold Preisach plant (21 curves per family).
use bmr_bench as workload;

use bmr::{Compensator, InverseKind};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use workload::{friction, multipeak_reference, operator};

fn benches(c: &mut Criterion) {
    let h = operator();
    let f = friction();
    let refs = multipeak_reference(100_000, 1);
    let currents: Vec<f64> = refs.iter().map(|r| r / 240.0).collect();
    let mut g = c.benchmark_group("step");
    let mut op = h.clone();
    let mut i = 0;
    g.bench_function("Hysteresis::step", |b| {
        b.iter(|| {
            i = (i + 1) % currents.len();
            black_box(op.step(black_box(currents[i])))
        })
    });
    for paper in [false, true] {
        let inv = if paper {
            InverseKind::Paper(h.paper_inverse().unwrap())
        } else {
            InverseKind::Exact
        };
        let mut comp = Compensator::new(h.clone(), inv, f, 0.125, 1.25).unwrap();
        let mut i = 0;
        let name = if paper {
            "Compensator::step (paper inverse)"
        } else {
            "Compensator::step (exact inverse)"
        };
        g.bench_function(name, |b| {
            b.iter(|| {
                i = (i + 1) % refs.len();
                black_box(comp.step(black_box(refs[i]), black_box(i as f64 * 0.002)))
            })
        });
    }
    g.finish();
}

criterion_group!(step, benches);
criterion_main!(step);
