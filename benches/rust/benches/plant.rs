//! Virtual actuator throughput: one `step` of the bmr2013 preset (all stages, sensor noise), and a 100k run.
use bmr::plant::{VirtualActuator, presets::bmr2013};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let mut act = VirtualActuator::new(bmr2013(), 0).unwrap();
    let mut k = 0u64;
    c.bench_function("plant_step_bmr2013", |b| {
        b.iter(|| {
            k += 1;
            let u = 1.25 * ((k as f64) * 1e-3).sin();
            black_box(act.step(black_box(u)))
        })
    });
    let u: Vec<f64> = (0..100_000)
        .map(|k| 1.25 * (k as f64 * 1e-3).sin())
        .collect();
    let mut g = c.benchmark_group("plant_run");
    g.throughput(Throughput::Elements(u.len() as u64));
    g.sample_size(20);
    g.bench_function("bmr2013_100k", |b| {
        b.iter(|| black_box(act.run(black_box(&u))))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
