//! Every backend on docs/design.md §7's workloads — lattice(N), z_fastest(N), shuffled(N), paper(N),
//! paper_shuffled(N) and moving(N) (the mean of its 20 steps in a row) — with each one's baseline (a k-d tree, kiddo, for the neighbour
//! search; a hash map of A's voxels for the paper's rule):
//! CPU reference (1 thread), parallel CPU (rayon's threads), GPU resident (positions already on
//! the device, no upload, no readback: the embedded case) and GPU through `step()` (upload and
//! readback included). Run: `cargo bench --bench collide`; the adapter is printed first.
//! `voxcollide bench` measures the same cases and prints a table.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use voxcollide::glam::{Vec3, Vec4};
use voxcollide::workload::DEFAULT_SEED;
use voxcollide::{
    Collision, ContactReport, CpuCollision, GpuCollision, GpuContext, ParallelCpuCollision, wgpu,
};
use voxcollide_cli::bench::{Stepped, WORKLOADS, voxel_hashmap};

const SIZES: [usize; 3] = [10_000, 100_000, 1_000_000];

fn bench(c: &mut Criterion) {
    let ctx = match GpuContext::new() {
        Ok(ctx) => {
            eprintln!("adapter: {}", ctx.adapter_name());
            Some(ctx)
        }
        Err(e) => {
            eprintln!("no adapter, GPU benches skipped: {e}");
            None
        }
    };
    eprintln!("threads: {}", rayon::current_num_threads());
    for (name, make) in WORKLOADS {
        let mut group = c.benchmark_group(name);
        group.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(5));
        for n in SIZES {
            let Stepped { w, steps } = make(n, DEFAULT_SEED).expect("workload");
            group.throughput(Throughput::Elements((w.a.len() + w.b.len()) as u64));
            // Each iteration takes the workload's steps in a row (moving(N)'s twenty, one
            // otherwise); the time reported is the mean step.
            let per_step = |iters: u64, step: &mut dyn FnMut(&[Vec3])| {
                let start = Instant::now();
                for _ in 0..iters {
                    for b in &steps {
                        step(b);
                    }
                }
                start.elapsed() / steps.len() as u32
            };

            let a: Vec<[f32; 3]> = w.a.iter().map(|p| p.to_array()).collect();
            if w.params.search == voxcollide::Search::Voxel {
                group.bench_function(BenchmarkId::new("voxel_hashmap", n), |bench| {
                    bench.iter_custom(|iters| per_step(iters, &mut |b| _ = black_box(voxel_hashmap(&w, b))));
                });
            } else {
                // Kiddo's own layout, made before the timing.
                let bs: Vec<Vec<[f32; 3]>> =
                    steps.iter().map(|b| b.iter().map(|p| p.to_array()).collect()).collect();
                group.bench_function(BenchmarkId::new("kdtree_kiddo", n), |bench| {
                    bench.iter_custom(|iters| {
                        let start = Instant::now();
                        for _ in 0..iters {
                            for b in &bs {
                                let tree =
                                    kiddo::ImmutableKdTree::<f32, 3>::new_from_slice(&a).expect("tree");
                                let nearest = tree
                                    .query_batch(b)
                                    .nearest_one::<kiddo::SquaredEuclidean<f32>>()
                                    .execute();
                                black_box(nearest.iter().filter(|r| r.distance < 0.81).count());
                            }
                        }
                        start.elapsed() / bs.len() as u32
                    });
                });
            }

            let mut par = ParallelCpuCollision::new(w.grid, w.params).expect("params");
            let mut report = ContactReport::default();
            group.bench_function(BenchmarkId::new("parallel_cpu", n), |bench| {
                bench.iter_custom(|iters| {
                    per_step(iters, &mut |b| par.step_into(&w.a, b, &mut report).expect("step"))
                });
            });

            let mut cpu = CpuCollision::new(w.grid, w.params).expect("params");
            group.bench_function(BenchmarkId::new("cpu_reference_1_thread", n), |bench| {
                bench.iter_custom(|iters| {
                    per_step(iters, &mut |b| _ = black_box(cpu.step(&w.a, b).expect("step")))
                });
            });

            let Some(ctx) = &ctx else { continue };
            let mut gpu = GpuCollision::new(ctx, w.grid, w.params).expect("gpu");
            group.bench_function(BenchmarkId::new("gpu_step", n), |bench| {
                bench.iter_custom(|iters| {
                    per_step(iters, &mut |b| _ = black_box(gpu.step(&w.a, b).expect("step")))
                });
            });

            let (device, queue) = (ctx.device(), ctx.queue());
            let upload = |points: &[Vec3]| {
                let data: Vec<Vec4> = points.iter().map(|p| p.extend(1.0)).collect();
                wgpu::util::DeviceExt::create_buffer_init(
                    device,
                    &wgpu::util::BufferInitDescriptor {
                        label: None,
                        contents: bytemuck::cast_slice(&data),
                        usage: wgpu::BufferUsages::STORAGE,
                    },
                )
            };
            let a = upload(&w.a);
            let bs: Vec<_> = steps.iter().map(|b| upload(b)).collect();
            let (n_a, n_b) = (w.a.len() as u32, w.b.len() as u32);
            group.bench_function(BenchmarkId::new("gpu_resident", n), |bench| {
                bench.iter_custom(|iters| {
                    let start = Instant::now();
                    for _ in 0..iters {
                        for b in &bs {
                            let mut encoder = device.create_command_encoder(&Default::default());
                            gpu.record(&mut encoder, &a, n_a, b, n_b).expect("record");
                            queue.submit([encoder.finish()]);
                            device.poll(wgpu::PollType::wait_indefinitely()).expect("poll");
                        }
                    }
                    start.elapsed() / bs.len() as u32
                });
            });
        }
        group.finish();
    }
}

criterion_group!(collide, bench);
criterion_main!(collide);
