//! The GPU backend against the CPU reference, and its limits. Needs an adapter (Mesa lavapipe
//! in CI): without one each test prints "skipped: no adapter" and passes, unless
//! `VOXCOLLIDE_REQUIRE_GPU=1`.

mod common;

use common::{all_params, bodies, compare, gpu, radius_shell_cases};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use voxcollide::glam::{UVec3, Vec3};
use voxcollide::*;

/// Whether the adapter's `sqrt` is correctly rounded, so that the GPU's forces equal the
/// reference's bit for bit (docs/design.md §2): Mesa's llvmpipe, on Vulkan and on GL.
fn exact_adapter(ctx: &GpuContext) -> bool {
    ctx.adapter_name().contains("llvmpipe")
}

/// Whether the adapter caps a shader's loop nest at 65535 iterations: Mesa's llvmpipe on Vulkan
/// (lavapipe). The same llvmpipe under GL runs the same walks to their end.
fn caps_loops(ctx: &GpuContext) -> bool {
    exact_adapter(ctx) && ctx.adapter_info().is_some_and(|i| i.backend == wgpu::Backend::Vulkan)
}

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
    // docs/design.md §2: exactly equal where the device's sqrt is correctly rounded, as on Mesa's
    // llvmpipe (lavapipe on Vulkan, and on GL); within 1e-5 * m elsewhere (checked above).
    if exact_adapter(&ctx) {
        assert_eq!(inexact, 0, "{}: force components differ in their bits", ctx.adapter_name());
    }
}

#[test]
fn dense_and_hashed_voxel_tables_both_match_the_cpu() {
    // The same bodies in the grid built for them (at most 4 voxels per A vertex: a dense table)
    // and in one 8× wider per axis (512× the voxels: hashed, with aliasing).
    let Some(ctx) = gpu() else { return };
    let (a, b, voxel, built) = bodies(21, 20_000);
    let wide = VoxelGrid::new(built.center(), voxel, built.dims() * 8).unwrap();
    for (grid, dense) in [(built, true), (wide, false)] {
        for params in all_params(1.0, 0.9 * voxel) {
            let cpu = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
            let mut backend = GpuCollision::new(&ctx, grid, params).unwrap();
            assert_eq!(backend.dense_table(), None);
            let gpu = backend.step(&a, &b).unwrap();
            assert_eq!(backend.dense_table(), Some(dense), "{:?}", grid.dims());
            assert!(cpu.colliding_b.len() > 1000, "{params:?}");
            compare(&format!("dense {dense} {params:?}"), &cpu, &gpu, 1e-5);
        }
    }
}

#[test]
fn candidates_at_the_radius_are_never_pruned() {
    // The probe leaves out rows and end voxels the radius cannot reach; candidates within
    // rounding of the radius, in every direction, must still be found exactly as on the CPU.
    let Some(ctx) = gpu() else { return };
    for case in radius_shell_cases() {
        let cpu = CpuCollision::new(case.grid, case.params).unwrap().step(&case.a, &case.b).unwrap();
        let mut backend = GpuCollision::new(&ctx, case.grid, case.params).unwrap();
        let gpu = backend.step(&case.a, &case.b).unwrap();
        assert_eq!(backend.dense_table(), Some(case.dense), "{}", case.what);
        assert!(cpu.colliding_b.len() > 10_000, "{}: {}", case.what, cpu.colliding_b.len());
        compare(&case.what, &cpu, &gpu, 1e-5);
    }
}

#[test]
fn the_benchmark_workloads_match_the_cpu() {
    // docs/design.md §7's lattice and paper at 300k: over 256 scan blocks, so the block totals are
    // summed in more than one round; the parallel backend equals the reference (tests/parallel.rs).
    let Some(ctx) = gpu() else { return };
    for w in [workload::lattice(300_000, 2013).unwrap(), workload::paper(300_000, 2013).unwrap()] {
        let cpu = ParallelCpuCollision::new(w.grid, w.params).unwrap().step(&w.a, &w.b).unwrap();
        let mut backend = GpuCollision::new(&ctx, w.grid, w.params).unwrap();
        let gpu = backend.step(&w.a, &w.b).unwrap();
        let voxels = w.grid.dims().element_product();
        assert!(voxels > 300_000, "{voxels} voxels");
        assert_eq!(backend.dense_table(), Some(true));
        assert!(cpu.colliding_b.len() > 250_000, "{}", cpu.colliding_b.len());
        compare(&format!("{:?}", w.params.search), &cpu, &gpu, 0.0);
    }
}

#[test]
fn the_moving_workload_matches_the_cpu_at_every_step() {
    // docs/design.md §7's moving(N): one GPU backend stepped 20 times in a row, B moving; every
    // step's report equals the CPU's for that step's positions.
    let Some(ctx) = gpu() else { return };
    let m = workload::moving(40_000, 22).unwrap();
    let w = &m.start;
    let mut cpu = ParallelCpuCollision::new(w.grid, w.params).unwrap();
    let mut backend = GpuCollision::new(&ctx, w.grid, w.params).unwrap();
    for k in 0..workload::MOVING_STEPS {
        let b = m.b_at(k);
        let expected = cpu.step(&w.a, &b).unwrap();
        let got = backend.step(&w.a, &b).unwrap();
        assert!(expected.colliding_b.len() > 20_000, "step {k}");
        compare(&format!("moving step {k}"), &expected, &got, 0.0);
    }
}

#[test]
fn a_kept_order_on_the_device_holds_only_while_every_vertex_keeps_its_slot() {
    // Each body keeps its order on the device while every vertex stays in the slot it was
    // sorted into (shaders/bin.wgsl), its new positions gathered into it (gather.wgsl). B moves
    // within its voxels (kept), one vertex crosses a face, leaves the grid, becomes NaN and
    // comes back; B gains a vertex (sorted again whatever its slots); A moves within its
    // voxels, then loses a vertex; the grid follows A. Every step equals the CPU's. (With the
    // gather left out, the second step differs where B is sorted, and the ninth where not.)
    let Some(ctx) = gpu() else { return };
    let w = workload::lattice(30_000, 31).unwrap();
    let mut follow = w.params;
    follow.anchor = Anchor::FollowA;
    // B sorted (as on a hardware GPU) and probed as given (a software adapter's default).
    for (params, sort_b) in [(w.params, true), (follow, true), (w.params, false)] {
        let grid = w.grid;
        let mut cpu = CpuCollision::new(grid, params).unwrap();
        let mut backend = GpuCollision::new(&ctx, grid, params).unwrap();
        backend.set_sort_b(sort_b);
        let (mut a, mut b) = (w.a.clone(), w.b.clone());
        let within = |p: &mut Vec3, d: Vec3| {
            if grid.voxel_of(*p + d) == grid.voxel_of(*p) {
                *p += d;
            }
        };
        let mid = b.len() / 2 + 5;
        for k in 0..12 {
            match k {
                1 | 2 => b.iter_mut().for_each(|p| within(p, Vec3::new(0.01, -0.01, 0.005))),
                3 => b[mid].x += 1.0,
                4 => b[mid].x = 1e9,
                5 => b[mid].x = f32::NAN,
                6 => b[mid] = w.b[mid],
                7 => b.push(w.b[0] + Vec3::splat(0.05)),
                8 | 9 => a.iter_mut().for_each(|p| within(p, Vec3::new(-0.01, 0.0, 0.01))),
                10 => {
                    a.pop();
                }
                _ => {}
            }
            let expected = cpu.step(&a, &b).unwrap();
            let got = backend.step(&a, &b).unwrap();
            assert!(expected.colliding_b.len() > 10_000, "step {k}");
            compare(&format!("step {k} {:?}, B sorted: {sort_b}", params.anchor), &expected, &got, 0.0);
        }
    }
}

#[test]
fn profiling_times_every_pass_and_changes_no_result() {
    let Some(ctx) = gpu() else { return };
    let w = workload::lattice(50_000, 4).unwrap();
    let mut backend = GpuCollision::new(&ctx, w.grid, w.params).unwrap();
    if !ctx.device().features().contains(wgpu::Features::TIMESTAMP_QUERY) {
        assert!(matches!(backend.set_profiling(true), Err(Error::Gpu { .. })));
        return;
    }
    assert!(matches!(backend.pass_times(), Err(Error::Gpu { .. })), "profiling is off");
    backend.set_profiling(true).unwrap();
    assert!(matches!(backend.pass_times(), Err(Error::Gpu { .. })), "nothing recorded yet");
    for anchor in [Anchor::Fixed, Anchor::FollowA] {
        let params = ContactParams { anchor, ..w.params };
        let mut backend = GpuCollision::new(&ctx, w.grid, params).unwrap();
        backend.set_profiling(true).unwrap();
        let cpu = CpuCollision::new(w.grid, params).unwrap().step(&w.a, &w.b).unwrap();
        let gpu = backend.step(&w.a, &w.b).unwrap();
        compare(&format!("{anchor:?} profiled"), &cpu, &gpu, 0.0);
        let times = backend.pass_times().unwrap();
        let names: Vec<&str> = times.iter().map(|(name, _)| *name).collect();
        assert_eq!(names, gpu::PASSES);
        // Timestamps were written and resolved around the passes that do work (a pass that
        // was not timed reads 0). How long each takes is the benchmark's business.
        let ms = |name: &str| times.iter().find(|(n, _)| *n == name).unwrap().1;
        assert!(ms("probe") > 0.0 && ms("bin") > 0.0, "{times:?}");
        backend.set_profiling(false).unwrap();
        assert!(matches!(backend.pass_times(), Err(Error::Gpu { .. })));
        compare(&format!("{anchor:?} after profiling"), &cpu, &backend.step(&w.a, &w.b).unwrap(), 0.0);
    }
}

#[test]
fn tiny_hashed_tables_whose_rows_wrap_match_the_cpu() {
    // Five A vertices in a 1024³ grid: 8 hash slots, so most block rows (3 slots) wrap past the
    // last slot to the first; the plane normal needs three candidates from such rows.
    let Some(ctx) = gpu() else { return };
    let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(1024)).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for round in 0..12 {
        let corner = Vec3::new(
            rng.random_range(-50.0..50.0f32).floor(),
            rng.random_range(-50.0..50.0f32).floor(),
            rng.random_range(-50.0..50.0f32).floor(),
        );
        let mut jitter = || Vec3::new(rng.random(), rng.random(), rng.random());
        let a: Vec<Vec3> =
            (0..5).map(|i| corner + Vec3::new((i % 3) as f32, (i / 3) as f32, 0.0) + jitter()).collect();
        let b: Vec<Vec3> = (0..20).map(|_| corner + 3.0 * jitter() - Vec3::splat(0.5)).collect();
        for params in all_params(1.0, 1.0) {
            let cpu = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
            let mut backend = GpuCollision::new(&ctx, grid, params).unwrap();
            let gpu = backend.step(&a, &b).unwrap();
            assert_eq!(backend.dense_table(), Some(false));
            compare(&format!("round {round} {params:?}"), &cpu, &gpu, 1e-5);
        }
    }
}

#[test]
fn gpu_reports_are_bit_identical_run_after_run() {
    let Some(ctx) = gpu() else { return };
    let (a, b, voxel, grid) = bodies(11, 60_000);
    for params in all_params(1.0, voxel) {
        let mut backend = GpuCollision::new(&ctx, grid, params).unwrap();
        let first = backend.step(&a, &b).unwrap();
        let again = backend.step(&a, &b).unwrap();
        let fresh = GpuCollision::new(&ctx, grid, params).unwrap().step(&a, &b).unwrap();
        assert!(first.colliding_b.len() > 1000, "{params:?}");
        for other in [&again, &fresh] {
            assert_eq!(
                compare(&format!("{params:?}"), &first, other, 0.0),
                0,
                "{params:?}: not bit-identical"
            );
        }
    }
}

#[test]
fn one_long_voxel_list_is_walked_whole() {
    // Every A vertex in one voxel: one list of 5000 entries, no capacity to run out of (lists
    // chain through `next`), and every entry is a candidate.
    let Some(ctx) = gpu() else { return };
    let a: Vec<Vec3> = (0..5000)
        .map(|i| Vec3::new(0.1 + (i % 97) as f32 * 0.008, 0.5, 0.1 + (i / 97) as f32 * 0.01))
        .collect();
    let b: Vec<Vec3> =
        (0..3000).map(|i| Vec3::new(0.05 + (i % 89) as f32 * 0.01, 0.6, (i / 89) as f32 * 0.0125)).collect();
    let grid = VoxelGrid::new(Vec3::splat(2.0), 1.0, UVec3::splat(4)).unwrap();
    for params in all_params(1.0, 1.0) {
        let cpu = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
        let gpu = GpuCollision::new(&ctx, grid, params).unwrap().step(&a, &b).unwrap();
        assert_eq!(cpu.binned_a, 5000);
        assert!(cpu.colliding_b.len() > 2500, "{params:?}");
        compare(&format!("{params:?}"), &cpu, &gpu, 1e-5);
    }
}

#[test]
fn every_one_of_eight_million_b_vertices_is_probed() {
    // More than 65535 × 64 items: the probe dispatch wraps into rows. B vertex j collides iff
    // j % 4099 == 0 or it is the last one; the others sit outside the grid.
    let Some(ctx) = gpu() else { return };
    let a: Vec<Vec3> =
        (0..1000).map(|i| Vec3::new((i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32)).collect();
    let grid = Initializer::new(1.0).margin(1).build(&a).unwrap();
    let params = ContactParams {
        magnitude: 1.0,
        search: Search::Neighbours { radius: 0.5 },
        direction: Direction::Pairwise,
        anchor: Anchor::Fixed,
    };
    let mut gpu = GpuCollision::new(&ctx, grid, params).unwrap();
    let n = gpu.max_vertices_of(Body::B).min(8 << 20) as usize;
    assert!(n >= 8 << 20 || !exact_adapter(&ctx), "llvmpipe allows B only {n}");
    let hit = |j: usize| j.is_multiple_of(4099) || j == n - 1;
    let b: Vec<Vec3> = (0..n)
        .map(|j| if hit(j) { a[j % 1000] + Vec3::new(0.0, 0.0, 0.25) } else { Vec3::splat(100.0) })
        .collect();
    let report = gpu.step(&a, &b).unwrap();
    let expected: Vec<u32> = (0..n).filter(|&j| hit(j)).map(|j| j as u32).collect();
    assert_eq!(report.colliding_b.len(), expected.len());
    assert_eq!(report.colliding_b, expected);
    assert_eq!(report.force_b[n - 1], Vec3::Z, "the last B vertex");
    assert_eq!(report.force_b[n - 2], Vec3::ZERO);
}

#[test]
fn more_vertices_than_the_device_binds_is_an_error_and_the_limit_itself_works() {
    // A's largest buffer takes 32 bytes a vertex (its fixed-point accumulators), B's 16: each
    // body's limit is its own, a body at its limit steps, one vertex more is DeviceLimit —
    // before anything is recorded, never a validation error.
    let Some(ctx) = gpu() else { return };
    let a = [Vec3::ZERO];
    let grid = Initializer::new(1.0).build(&a).unwrap();
    let params = all_params(1.0, 1.0)[0];
    let mut gpu = GpuCollision::new(&ctx, grid, params).unwrap();
    let (max_a, max_b) = (gpu.max_vertices_of(Body::A) as usize, gpu.max_vertices_of(Body::B) as usize);
    let limits = ctx.device().limits();
    eprintln!(
        "{}: A {max_a}, B {max_b} vertices (binding {} bytes, buffer {} bytes)",
        ctx.adapter_name(),
        limits.max_storage_buffer_binding_size,
        limits.max_buffer_size
    );
    assert_eq!(gpu.max_vertices() as usize, max_a.min(max_b));
    assert!(max_a <= max_b);
    let far = Vec3::splat(100.0); // outside the grid: no contact, no force to sum
    for (body, max) in [(Body::A, max_a), (Body::B, max_b)] {
        let big = vec![far; max + 1];
        let err = match body {
            Body::A => gpu.step(&big, &a),
            Body::B => gpu.step(&a, &big),
        }
        .unwrap_err();
        assert!(
            matches!(err, Error::DeviceLimit { body: b, len, max: m, .. } if b == body && len == max + 1 && m == max),
            "{err:?}"
        );
        assert!(err.to_string().contains("max_storage_buffer_binding_size"), "{err}");
    }
    // Body A at its limit (4M on lavapipe) with one contact: it works.
    let mut big_a = vec![far; max_a.min(16 << 20)];
    big_a[max_a.min(16 << 20) - 1] = Vec3::ZERO;
    let report = gpu.step(&big_a, &[Vec3::new(0.25, 0.0, 0.0)]).unwrap();
    assert_eq!(report.colliding_b, vec![0]);
    assert_eq!(report.force_a[big_a.len() - 1], -Vec3::X);
}

#[test]
fn force_overflow_is_reported_by_the_gpu_too() {
    let Some(ctx) = gpu() else { return };
    let grid = VoxelGrid::new(Vec3::splat(2.0), 1.0, UVec3::splat(4)).unwrap();
    let params = all_params(1.0, 1.0)[0];
    let a = [Vec3::splat(0.5)];
    let mut gpu = GpuCollision::new(&ctx, grid, params).unwrap();
    // 32768 pushes of -65536 each: exactly i32::MIN, which fits.
    let report = gpu.step(&a, &vec![Vec3::new(0.75, 0.5, 0.5); 32768]).unwrap();
    assert_eq!(report.force_a[0], Vec3::new(-32768.0, 0.0, 0.0));
    // One more leaves i32: the same error as the CPU reference, with the exact total.
    let b = vec![Vec3::new(0.75, 0.5, 0.5); 32769];
    let expected = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap_err();
    assert_eq!(gpu.step(&a, &b).unwrap_err(), expected);
    assert_eq!(expected, Error::ForceOverflow { vertex: 0, axis: 0, count: -2_147_549_184 });
    // And the backend is still usable afterwards.
    assert_eq!(gpu.step(&a, &[Vec3::new(0.75, 0.5, 0.5)]).unwrap().colliding_b, vec![0]);
}

#[test]
fn a_follow_a_center_beyond_f32_is_the_same_error_as_on_the_cpu() {
    let Some(ctx) = gpu() else { return };
    let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(4)).unwrap();
    let params = ContactParams { anchor: Anchor::FollowA, ..all_params(1.0, 1.0)[0] };
    let a = [Vec3::new(3e38, 0.0, 0.0), Vec3::new(3.2e38, 0.0, 0.0)];
    let expected = CpuCollision::new(grid, params).unwrap().step(&a, &[Vec3::ZERO]).unwrap_err();
    assert!(matches!(expected, Error::NonFiniteCenter { .. }));
    assert_eq!(GpuCollision::new(&ctx, grid, params).unwrap().step(&a, &[Vec3::ZERO]).unwrap_err(), expected);
}

#[test]
fn bad_params_and_empty_bodies_are_errors_on_the_gpu() {
    let Some(ctx) = gpu() else { return };
    let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(4)).unwrap();
    let good = all_params(1.0, 1.0)[0];
    let err = GpuCollision::new(&ctx, grid, ContactParams { magnitude: f32::NAN, ..good }).unwrap_err();
    assert!(matches!(err, Error::Magnitude { .. }));
    let err =
        GpuCollision::new(&ctx, grid, ContactParams { search: Search::Neighbours { radius: 2.0 }, ..good })
            .unwrap_err();
    assert!(matches!(err, Error::Radius { .. }));
    let mut gpu = GpuCollision::new(&ctx, grid, good).unwrap();
    assert_eq!(gpu.step(&[], &[Vec3::ZERO]).unwrap_err(), Error::EmptyBody { body: Body::A });
    assert_eq!(gpu.step(&[Vec3::ZERO], &[]).unwrap_err(), Error::EmptyBody { body: Body::B });
}

#[test]
fn bodies_that_grow_and_shrink_between_steps_stay_correct() {
    let Some(ctx) = gpu() else { return };
    let params = all_params(1.0, 0.45)[6]; // Neighbours, PlaneNormal, Fixed (voxel 0.5)
    let (a, b, _, grid) = bodies(21, 20_000);
    let mut gpu = GpuCollision::new(&ctx, grid, params).unwrap();
    let mut cpu = CpuCollision::new(grid, params).unwrap();
    for (na, nb) in [(100, 50), (20_000, 20_000), (300, 19_000), (20_000, 10), (5_000, 5_000)] {
        let (a, b) = (&a[..na], &b[..nb]);
        compare(&format!("sizes {na} {nb}"), &cpu.step(a, b).unwrap(), &gpu.step(a, b).unwrap(), 1e-5);
    }
}

#[test]
fn a_walk_the_driver_cuts_short_is_an_error_not_a_missed_contact() {
    // 70000 A vertices in one voxel: lavapipe (llvmpipe on Vulkan) caps a shader's loop nest at
    // 65535 iterations, so there the walk cannot finish and the step must fail with
    // WalkTruncated; llvmpipe on GL, and every other adapter seen, walks them all, and then the
    // step must match the CPU. Either way, never a missed contact.
    let Some(ctx) = gpu() else { return };
    let a: Vec<Vec3> = (0..70_000)
        .map(|i| Vec3::new(0.1 + (i % 97) as f32 * 0.008, 0.5, 0.1 + (i / 97) as f32 * 0.0001))
        .collect();
    let b: Vec<Vec3> = (0..10).map(|i| Vec3::new(0.05 + i as f32 * 0.01, 0.6, 0.0)).collect();
    let grid = VoxelGrid::new(Vec3::splat(2.0), 1.0, UVec3::splat(4)).unwrap();
    // Every search and direction (the voxel search with a pairwise partner walks one slot, the
    // others the block's ranges); the grid stays where it was built, around the one voxel.
    for params in all_params(1.0, 1.0).into_iter().filter(|p| p.anchor == Anchor::Fixed) {
        let cpu = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
        match GpuCollision::new(&ctx, grid, params).unwrap().step(&a, &b) {
            Ok(gpu) => {
                assert!(!caps_loops(&ctx), "{params:?}: lavapipe walked 70000");
                assert_eq!(compare("70000 in one voxel", &cpu, &gpu, 1e-5), 0);
            }
            Err(err) => {
                assert!(caps_loops(&ctx), "unexpected on {}: {err}", ctx.adapter_name());
                assert_eq!(err, Error::WalkTruncated { b: 0 }, "{params:?}");
                assert!(err.to_string().contains("65535"), "{err}");
            }
        }
    }
}

#[test]
fn b_probed_as_given_matches_the_cpu_in_every_order_and_table() {
    // `set_sort_b(false)` skips B's counting sort and probes B in its own order: the same
    // reports, for every search and direction, dense and hashed tables, the workloads' three
    // orders, and bodies with vertices off the grid and not finite; and back again.
    let Some(ctx) = gpu() else { return };
    let default = GpuCollision::new(
        &ctx,
        workload::lattice(8, 1).unwrap().grid,
        workload::lattice(8, 1).unwrap().params,
    )
    .unwrap()
    .sort_b();
    assert_eq!(default, gpu::sorts_b_by_default(&ctx));
    // A software adapter probes B as given (docs/performance-notes.md §38).
    assert_eq!(default, !exact_adapter(&ctx), "{}", ctx.adapter_name());
    let (a, b, voxel, built) = bodies(22, 20_000);
    let wide = VoxelGrid::new(built.center(), voxel, built.dims() * 8).unwrap();
    type Case = (String, Vec<Vec3>, Vec<Vec3>, VoxelGrid, ContactParams);
    let mut cases: Vec<Case> = Vec::new();
    for (grid, what) in [(built, "dense"), (wide, "hashed")] {
        for params in all_params(1.0, 0.9 * voxel) {
            cases.push((format!("{what} {params:?}"), a.clone(), b.clone(), grid, params));
        }
    }
    for w in [
        workload::lattice(40_000, 5).unwrap(),
        workload::z_fastest(40_000, 6).unwrap(),
        workload::shuffled(40_000, 7).unwrap(),
        workload::paper(40_000, 8).unwrap(),
    ] {
        cases.push((format!("workload {:?}", w.params), w.a, w.b, w.grid, w.params));
    }
    let mut inexact = 0;
    for (what, a, b, grid, params) in cases {
        let cpu = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
        let mut backend = GpuCollision::new(&ctx, grid, params).unwrap();
        backend.set_sort_b(false);
        assert!(!backend.sort_b());
        let given = backend.step(&a, &b).unwrap();
        assert!(cpu.colliding_b.len() > 1000, "{what}: {}", cpu.colliding_b.len());
        inexact += compare(&format!("{what}, B as given"), &cpu, &given, 1e-5 * params.magnitude);
        backend.set_sort_b(true);
        let sorted = backend.step(&a, &b).unwrap();
        inexact += compare(&format!("{what}, B sorted"), &cpu, &sorted, 1e-5 * params.magnitude);
    }
    if exact_adapter(&ctx) {
        assert_eq!(inexact, 0, "{}: force components differ in their bits", ctx.adapter_name());
    }
}
