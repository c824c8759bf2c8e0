//! CPU reference backend on the docs/design.md §7 workloads (one thread): a step is everything from
//! positions to forces for both bodies. Run: `cargo bench --bench cpu`.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use voxcollide::workload::{DEFAULT_SEED, Workload, lattice, paper, shuffled, z_fastest};
use voxcollide::{Collision, CpuCollision};

fn bench_workload(
    c: &mut Criterion,
    name: &str,
    make: fn(usize, u64) -> Result<Workload, voxcollide::Error>,
) {
    let mut group = c.benchmark_group(format!("cpu_reference/{name}"));
    group.sample_size(10);
    for n in [10_000usize, 100_000] {
        let w = make(n, DEFAULT_SEED).expect("workload");
        let mut cpu = CpuCollision::new(w.grid, w.params).expect("params");
        group.throughput(Throughput::Elements((w.a.len() + w.b.len()) as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), &w, |bench, w| {
            bench.iter(|| black_box(cpu.step(&w.a, &w.b).expect("step")));
        });
    }
    group.finish();
}

fn benches(c: &mut Criterion) {
    bench_workload(c, "lattice", lattice);
    bench_workload(c, "z_fastest", z_fastest);
    bench_workload(c, "shuffled", shuffled);
    bench_workload(c, "paper", paper);
}

criterion_group!(cpu, benches);
criterion_main!(cpu);
