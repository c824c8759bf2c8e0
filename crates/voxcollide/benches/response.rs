//! What the penalty response costs a step against the paper's constant one (docs/design.md §7's
//! lattice workload, plane-normal and pairwise), on the reference (one thread) and the
//! parallel backend, with the two responses interleaved in one group so that their ratio comes
//! from the same moments. Run: `cargo bench --bench response`.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use voxcollide::workload::{DEFAULT_SEED, lattice};
use voxcollide::{Collision, CpuCollision, Direction, ParallelCpuCollision, Response};

fn benches(c: &mut Criterion) {
    let n = 100_000;
    for direction in [Direction::Pairwise, Direction::PlaneNormal] {
        let mut w = lattice(n, DEFAULT_SEED).expect("workload");
        w.params.direction = direction;
        let penalty = Response::Penalty { stiffness: 4.0, gap: 0.0 };
        let mut group = c.benchmark_group(format!("response/{direction:?}"));
        group.sample_size(10);
        group.throughput(Throughput::Elements((w.a.len() + w.b.len()) as u64));
        for (name, response) in [("constant", Response::Constant), ("penalty", penalty)] {
            let mut cpu =
                CpuCollision::new(w.grid, w.params).and_then(|c| c.with_response(response)).expect("params");
            group.bench_with_input(BenchmarkId::new("reference", name), &w, |bench, w| {
                bench.iter(|| black_box(cpu.step(&w.a, &w.b).expect("step")));
            });
            let mut par = ParallelCpuCollision::new(w.grid, w.params)
                .and_then(|c| c.with_response(response))
                .expect("params");
            let mut report = voxcollide::ContactReport::default();
            group.bench_with_input(BenchmarkId::new("parallel", name), &w, |bench, w| {
                bench.iter(|| {
                    par.step_into(&w.a, &w.b, &mut report).expect("step");
                    black_box(report.colliding_b.len())
                });
            });
        }
        group.finish();
    }
}

criterion_group!(response, benches);
criterion_main!(response);
