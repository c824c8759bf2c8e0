//! Property tests of the CPU reference on seeded random inputs: Newton's third law, invariance
//! of `FollowA` under translation by whole voxels, and no contact outside the grid.

mod common;

use common::all_params;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use voxcollide::glam::{IVec3, UVec3, Vec3};
use voxcollide::*;

const SEEDS: std::ops::Range<u64> = 0..12;

/// `n` points in the box `lo..hi`, each coordinate a multiple of 2^-8 (so that whole-voxel
/// translations are exact in f32).
fn cloud(rng: &mut ChaCha8Rng, n: usize, lo: f32, hi: f32) -> Vec<Vec3> {
    let q = |rng: &mut ChaCha8Rng| (rng.random_range(lo..hi) * 256.0).round() / 256.0;
    (0..n).map(|_| Vec3::new(q(rng), q(rng), q(rng))).collect()
}

/// A seeded pair of overlapping bodies with a voxel size and a grid built over A.
fn pair(seed: u64) -> (Vec<Vec3>, Vec<Vec3>, f32, VoxelGrid) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let voxel = [0.5f32, 1.0, 2.0][(seed % 3) as usize];
    let side = voxel * rng.random_range(2.0..6.0);
    let (na, nb) = (rng.random_range(50..300), rng.random_range(50..300));
    let a = cloud(&mut rng, na, 0.0, side);
    let b = cloud(&mut rng, nb, -0.3 * side, 1.2 * side);
    let grid = Initializer::new(voxel).margin((seed % 2) as u32).build(&a).unwrap();
    (a, b, voxel, grid)
}

#[test]
fn forces_obey_newtons_third_law() {
    let mut contacts = 0;
    for seed in SEEDS {
        let (a, b, voxel, grid) = pair(seed);
        let magnitude = [1.0f32, 3.7, 1e-3][(seed % 3) as usize];
        for params in all_params(magnitude, 0.9 * voxel) {
            let r = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
            // Each contact puts at most three fixed-point shares on A, each rounded by at most half
            // a unit m / 65536 per component; the f32 conversions add a little more.
            let shares = 3.0 * r.colliding_b.len() as f32;
            let tolerance = shares * 0.5 * magnitude / 65536.0 * 1.01 + 1e-6 * magnitude;
            let net = r.net_force();
            assert!(
                net.abs().max_element() <= tolerance,
                "seed {seed} {params:?}: net force {net} > {tolerance}"
            );
            // And the law is not satisfied vacuously: B is pushed.
            let pushed_b: f32 = r.force_b.iter().map(|f| f.length()).sum();
            assert!(r.colliding_b.is_empty() || pushed_b > 0.5 * magnitude, "seed {seed} {params:?}");
            contacts += r.colliding_b.len();
        }
    }
    assert!(contacts > 1000, "only {contacts} contacts: the inputs do not exercise the law");
}

#[test]
fn follow_a_is_invariant_under_whole_voxel_translation() {
    let mut compared = 0;
    for seed in SEEDS {
        let (a, b, voxel, grid) = pair(seed);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 1000);
        let k = IVec3::new(rng.random_range(-40..40), rng.random_range(-40..40), rng.random_range(-40..40));
        let shift = k.as_vec3() * voxel;
        let (a2, b2): (Vec<Vec3>, Vec<Vec3>) =
            (a.iter().map(|p| *p + shift).collect(), b.iter().map(|p| *p + shift).collect());
        for params in all_params(1.0, voxel).into_iter().filter(|p| p.anchor == Anchor::FollowA) {
            let r1 = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
            // The same grid as built: only FollowA moves it onto the shifted bodies.
            let r2 = CpuCollision::new(grid, params).unwrap().step(&a2, &b2).unwrap();
            assert_eq!(r2.grid_center, r1.grid_center + shift, "seed {seed}");
            assert_eq!(r2.colliding_b, r1.colliding_b, "seed {seed} {params:?}");
            assert_eq!((r2.binned_a, r2.discarded_a), (r1.binned_a, r1.discarded_a));
            if let Some(i) = (0..a.len()).find(|&i| r1.force_a[i] != r2.force_a[i]) {
                panic!("seed {seed} {params:?}: force_a[{i}] {} != {}", r1.force_a[i], r2.force_a[i]);
            }
            if let Some(j) = (0..b.len()).find(|&j| r1.force_b[j] != r2.force_b[j]) {
                panic!("seed {seed} {params:?}: force_b[{j}] {} != {}", r1.force_b[j], r2.force_b[j]);
            }
            compared += r1.colliding_b.len();
        }
    }
    assert!(compared > 500, "only {compared} contacts compared");
}

#[test]
fn b_outside_the_grid_never_collides() {
    let (mut outside, mut inside_hits) = (0, 0);
    for seed in SEEDS {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let voxel = 1.0;
        // A small grid (dims 3..6) in a cloud that spills far past it on every side.
        let dims = UVec3::splat(rng.random_range(3..6));
        let grid = VoxelGrid::new(Vec3::splat(2.0), voxel, dims).unwrap();
        let a = cloud(&mut rng, 300, -2.0, 6.0);
        let b = cloud(&mut rng, 300, -2.0, 6.0);
        for params in all_params(1.0, voxel) {
            let r = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
            let step_grid = grid.with_center(r.grid_center).unwrap();
            for (j, p) in b.iter().enumerate() {
                let hit = r.colliding_b.binary_search(&(j as u32)).is_ok();
                if step_grid.voxel_of(*p).is_none() {
                    outside += 1;
                    assert!(!hit, "seed {seed} {params:?}: b[{j}] = {p} is outside but collides");
                    assert_eq!(r.force_b[j], Vec3::ZERO);
                } else {
                    inside_hits += usize::from(hit);
                }
            }
        }
    }
    assert!(outside > 1000 && inside_hits > 1000, "outside {outside}, inside hits {inside_hits}");
}

#[test]
fn colliding_b_is_ascending_and_matches_the_forces() {
    for seed in SEEDS {
        let (a, b, voxel, grid) = pair(seed);
        for params in all_params(2.0, voxel) {
            let r = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
            assert!(r.colliding_b.windows(2).all(|w| w[0] < w[1]), "seed {seed}");
            assert_eq!((r.force_a.len(), r.force_b.len()), (a.len(), b.len()));
            for (j, f) in r.force_b.iter().enumerate() {
                let hit = r.colliding_b.binary_search(&(j as u32)).is_ok();
                // Every colliding b gets a force of magnitude m, every other one none.
                if hit {
                    assert!((f.length() - 2.0).abs() < 1e-5, "seed {seed}: |f_b[{j}]| = {}", f.length());
                } else {
                    assert_eq!(*f, Vec3::ZERO);
                }
            }
            assert_eq!(r.binned_a + r.discarded_a, a.len() as u32);
        }
    }
}
