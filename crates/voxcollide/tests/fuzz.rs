//! Hostile input on every backend (tests/common/hostile.rs): the plain cases the harness reduced
//! its findings to, every seed it ever failed on, and a seeded run of 20k fresh cases. The long
//! run is `cargo run --release --example fuzz -- --cases 1000000`.

mod common;
#[path = "common/hostile.rs"]
mod hostile;

use common::gpu;
use hostile::{Backends, check, generate};
use voxcollide::glam::{UVec3, Vec3};
use voxcollide::*;

/// Every seed the harness has failed on, kept as regressions (see the closing notes of issue 9
/// for what each found).
const FOUND: &[u64] = &[
    // The grid center's sign of zero under FollowA: the reference's f32::min / max picked either
    // zero where the GPU's integer keys order -0 < +0 (fixed: finite_bounds uses that order).
    36531, 50551, 74679, 75668, 111567, 154178, 169586, 206139,
];

fn backends() -> Backends {
    Backends::new(gpu())
}

/// A 20×20×20 lattice of spacing 1, B the same shifted by (0.3, 0.2, 0.1).
fn lattices() -> (Vec<Vec3>, Vec<Vec3>) {
    let a: Vec<Vec3> =
        (0..8000).map(|i| Vec3::new((i % 20) as f32, (i / 20 % 20) as f32, (i / 400) as f32)).collect();
    let b = a.iter().map(|p| *p + Vec3::new(0.3, 0.2, 0.1)).collect();
    (a, b)
}

/// The plain case: big grids, powers of two among them, whose voxel count (d³, up to
/// 2^72) once wrapped to 0 in 64-bit arithmetic and made the parallel backend panic and the GPU
/// find no contact. Every backend finds all 8000, for every search and direction.
#[test]
fn big_grids_find_every_contact_on_every_backend() {
    let (a, b) = lattices();
    let ctx = gpu();
    for d in [1u32 << 21, 1 << 22, (1 << 22) + 1, 3_000_000, 1 << 23, (1 << 24) - 1, 1 << 24] {
        for dims in [UVec3::splat(d), UVec3::new(d, 20, 20), UVec3::new(20, 7, d)] {
            let grid = VoxelGrid::new(Vec3::splat(10.0), 1.0, dims).unwrap();
            for search in [Search::Voxel, Search::Neighbours { radius: 0.9 }] {
                for direction in [Direction::Pairwise, Direction::PlaneNormal] {
                    let params = ContactParams { magnitude: 1.0, search, direction, anchor: Anchor::Fixed };
                    let what = format!("dims {dims} {search:?} {direction:?}");
                    let reference = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
                    // Dims (20, 7, d) leave part of the lattice outside the grid; an odd d puts the voxel faces
                    // at half-integers, where the voxel search pairs fewer.
                    if dims.y != 7 && d % 2 == 0 {
                        assert_eq!(reference.colliding_b.len(), 8000, "{what}");
                    }
                    let parallel = ParallelCpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
                    assert_eq!(parallel, reference, "{what}: parallel");
                    if let Some(ctx) = &ctx {
                        let mut g = GpuCollision::new(ctx, grid, params).unwrap();
                        let report = g.step(&a, &b).unwrap();
                        assert_eq!(report.colliding_b, reference.colliding_b, "{what}: gpu");
                        common::compare(&what, &reference, &report, 1e-5);
                    }
                }
            }
        }
    }
}

/// Where the voxel count is small enough, the tables are dense on both fast backends, and they
/// switch to hashed at the same count.
#[test]
fn the_dense_table_decision_is_exact() {
    use voxcollide::voxel_data::{dense_slots, voxel_count};
    assert_eq!(voxel_count(UVec3::splat(1 << 22)), 1u128 << 66);
    assert_eq!(voxel_count(UVec3::splat(1 << 24)), 1u128 << 72);
    assert_eq!(dense_slots(UVec3::splat(1 << 22), 8000), None);
    assert_eq!(dense_slots(UVec3::splat(1 << 21), usize::MAX), None, "beyond a u32 slot");
    assert_eq!(dense_slots(UVec3::splat(20), 2000), Some(8000));
    assert_eq!(dense_slots(UVec3::splat(20), 1999), None);
    assert_eq!(dense_slots(UVec3::new(1 << 24, 1 << 24, 1), usize::MAX), None);
    if let Some(ctx) = gpu() {
        let (a, b) = lattices();
        let params = ContactParams {
            magnitude: 1.0,
            search: Search::Voxel,
            direction: Direction::Pairwise,
            anchor: Anchor::Fixed,
        };
        for (d, dense) in [(20u32, true), (31, true), (32, false), (1 << 22, false), (1 << 24, false)] {
            let grid = VoxelGrid::new(Vec3::splat(10.0), 1.0, UVec3::splat(d)).unwrap();
            let mut g = GpuCollision::new(&ctx, grid, params).unwrap();
            assert_eq!(g.step(&a, &b).unwrap().colliding_b.len(), 8000, "d {d}");
            assert_eq!(g.dense_table(), Some(dense), "d {d}");
        }
    }
}

/// Every seed the harness ever failed on passes.
#[test]
fn every_case_the_harness_found_stays_fixed() {
    let backends = backends();
    for &seed in FOUND {
        if let Err(e) = check(&generate(seed), &backends) {
            panic!("seed {seed}: {e}");
        }
    }
}

/// 20k fresh seeded cases (`VOXCOLLIDE_FUZZ_CASES` and `VOXCOLLIDE_FUZZ_SEED` change the count
/// and the first seed) on the reference, the parallel backend and the GPU.
#[test]
fn twenty_thousand_hostile_cases_agree_on_every_backend() {
    let env =
        |name: &str, default: u64| std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default);
    let cases = env("VOXCOLLIDE_FUZZ_CASES", 20_000);
    let first = env("VOXCOLLIDE_FUZZ_SEED", 1 << 32);
    let backends = backends();
    let mut failures = Vec::new();
    let (mut ok, mut contacts, mut gpu_ran, mut grid_errors) = (0usize, 0usize, 0usize, 0u64);
    let mut errors = std::collections::BTreeMap::<String, usize>::new();
    for seed in first..first + cases {
        match check(&generate(seed), &backends) {
            Ok(outcome) => {
                gpu_ran += usize::from(outcome.gpu_ran);
                grid_errors += u64::from(outcome.grid_error);
                if outcome.result == "ok" {
                    ok += 1;
                    contacts += usize::from(outcome.contacts > 0);
                } else {
                    *errors.entry(outcome.result).or_default() += 1;
                }
            }
            Err(e) => failures.push(format!("seed {seed}: {e}")),
        }
    }
    eprintln!(
        "{} — {cases} cases: {ok} reports ({contacts} with contacts), errors {errors:?}, {gpu_ran} on the GPU, {} failed",
        backends.gpu.as_ref().map_or_else(|| "no GPU".to_string(), GpuContext::adapter_name),
        failures.len()
    );
    assert!(
        failures.is_empty(),
        "{} of {cases} cases failed:\n{}",
        failures.len(),
        failures[..failures.len().min(20)].join("\n")
    );
    // The generator reaches what it is for: reports with contacts and errors of many kinds.
    assert!(contacts as u64 > cases / 4, "only {contacts} cases with contacts");
    assert!(errors.len() >= 6, "only the errors {errors:?}");
    if backends.gpu.is_some() {
        assert_eq!(gpu_ran as u64, cases - grid_errors, "every case with a grid ran on the GPU");
    }
}
