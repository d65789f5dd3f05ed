//! Per-step latency distribution of `Compensator::step` (exact and paper inverse, and with every extension stage)
//! over 10⁶ steps of a random multi-peak
//! reference: median, p99, p99.9 and max, each step timed alone (timer overhead measured and subtracted).
//! Run: `cargo bench --bench latency`.
use bmr_bench as workload;

use bmr::{Compensator, InverseKind};
use std::hint::black_box;
use std::time::Instant;

fn percentile(sorted: &[u64], p: f64) -> u64 {
    sorted[((sorted.len() as f64 - 1.0) * p).round() as usize]
}

fn main() {
    const N: usize = 1_000_000;
    let h = workload::operator();
    let f = workload::friction();
    let refs = workload::multipeak_reference(N, 7);
    let mut overhead: Vec<u64> = (0..100_000)
        .map(|_| {
            let t = Instant::now();
            black_box(());
            t.elapsed().as_nanos() as u64
        })
        .collect();
    overhead.sort_unstable();
    let timer = percentile(&overhead, 0.5);
    for (name, paper, extended) in [
        ("exact inverse", false, false),
        ("paper inverse", true, false),
        ("exact inverse, every extension stage", false, true),
    ] {
        let inv = if paper {
            InverseKind::Paper(h.paper_inverse().unwrap())
        } else {
            InverseKind::Exact
        };
        let mut c = Compensator::new(h.clone(), inv, f, 0.125, 1.25).unwrap();
        if extended {
            c = c
                .with_extensions(&workload::every_stage(), 0.001, 300.0)
                .unwrap();
        }
        for (i, &r) in refs.iter().take(10_000).enumerate() {
            black_box(c.step(r, i as f64 * 0.002)); // warm up
        }
        let mut ns: Vec<u64> = Vec::with_capacity(N);
        for (i, &r) in refs.iter().enumerate() {
            let th = i as f64 * 0.002;
            let t = Instant::now();
            black_box(c.step(black_box(r), black_box(th)));
            ns.push((t.elapsed().as_nanos() as u64).saturating_sub(timer));
        }
        ns.sort_unstable();
        println!(
            "Compensator::step ({name}), {N} steps, timer overhead {timer} ns subtracted: median {} ns, p99 {} ns, p99.9 {} ns, max {} ns",
            percentile(&ns, 0.5),
            percentile(&ns, 0.99),
            percentile(&ns, 0.999),
            ns[N - 1]
        );
    }
}
