//! The GPU backend against the CPU reference, and its limits. Needs an adapter (Mesa lavapipe
//! in CI): without one each test prints "skipped: no adapter" and passes, unless
//! `VOXCOLLIDE_REQUIRE_GPU=1`.

mod common;

use common::{all_params, bodies, compare, gpu};
use voxcollide::*;

#[test]
fn gpu_matches_cpu_for_all_combinations() {
    let Some(ctx) = gpu() else { return };
    eprintln!("adapter: {}", ctx.adapter_name());
    let mut inexact = 0;
    let mut contacts = 0;
    for (seed, n) in [(1u64, 1usize), (2, 2), (3, 17), (4, 300), (5, 5_000), (6, 40_000), (7, 100_000)] {
        let (a, b, voxel, grid) = bodies(seed, n);
        let magnitude = [1.0f32, 3.7, 1e-3][(seed % 3) as usize];
        for params in all_params(magnitude, 0.9 * voxel) {
            let cpu = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
            let gpu = GpuCollision::new(&ctx, grid, params).unwrap().step(&a, &b).unwrap();
            inexact += compare(&format!("seed {seed} n {n} {params:?}"), &cpu, &gpu, 1e-5 * magnitude);
            contacts += cpu.colliding_b.len();
        }
    }
    eprintln!("{contacts} contacts compared; {inexact} force components not bit-identical");
    assert!(contacts > 100_000, "only {contacts} contacts");
}
