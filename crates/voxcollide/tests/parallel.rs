//! `ParallelCpuCollision` gives the same reports as the reference on random inputs, for all
//! eight search × direction × anchor combinations, and allocates nothing once warm.

mod common;

use common::{all_params, bodies, radius_shell_cases};
use voxcollide::glam::Vec3;
use voxcollide::*;

#[test]
fn candidates_at_the_radius_are_never_pruned() {
    // The parallel walk leaves out voxels the radius cannot reach; candidates within rounding of
    // the radius, in every direction, must still be found exactly as by the reference.
    for case in radius_shell_cases() {
        let expected = CpuCollision::new(case.grid, case.params).unwrap().step(&case.a, &case.b).unwrap();
        let actual =
            ParallelCpuCollision::new(case.grid, case.params).unwrap().step(&case.a, &case.b).unwrap();
        assert!(expected.colliding_b.len() > 10_000, "{}", case.what);
        assert_eq!(common::compare(&case.what, &expected, &actual, 0.0), 0, "{}", case.what);
    }
}

#[test]
fn parallel_reports_equal_the_reference() {
    let mut contacts = 0;
    for (seed, n) in [(1u64, 1usize), (2, 2), (3, 17), (4, 300), (5, 5_000), (6, 40_000), (8, 120_000)] {
        let (a, b, voxel, grid) = bodies(seed, n);
        for radius in [0.9 * voxel, voxel, 0.31 * voxel] {
            for params in all_params([1.0f32, 3.7, 1e-3][(seed % 3) as usize], radius) {
                let expected = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
                let actual = ParallelCpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
                assert_eq!(expected.colliding_b, actual.colliding_b, "seed {seed} n {n} {params:?}");
                assert_eq!(
                    common::compare(&format!("seed {seed} n {n} {params:?}"), &expected, &actual, 0.0),
                    0
                );
                contacts += expected.colliding_b.len();
            }
        }
    }
    assert!(contacts > 500_000, "{contacts}");
}

#[test]
fn parallel_follows_the_reference_on_the_workloads() {
    let paper_shuffled = |n, seed| {
        let mut w = workload::shuffled(n, seed).unwrap();
        w.params.search = Search::Voxel;
        w
    };
    let mut plane = workload::shuffled(30_000, 9).unwrap();
    plane.params.direction = Direction::PlaneNormal;
    for w in [
        workload::lattice(30_000, 3).unwrap(),
        workload::paper(30_000, 4).unwrap(),
        workload::shuffled(30_000, 5).unwrap(),
        workload::z_fastest(30_000, 6).unwrap(),
        paper_shuffled(30_000, 7),
        plane,
    ] {
        let expected = CpuCollision::new(w.grid, w.params).unwrap().step(&w.a, &w.b).unwrap();
        let actual = ParallelCpuCollision::new(w.grid, w.params).unwrap().step(&w.a, &w.b).unwrap();
        assert!(expected == actual, "{:?}", w.params);
        assert!(expected.colliding_b.len() > 20_000);
    }
    // A shuffled report is the lattice's, permuted: the same contacts and forces per vertex.
    let (w, s) = (workload::lattice(30_000, 3).unwrap(), workload::shuffled(30_000, 3).unwrap());
    let r = ParallelCpuCollision::new(w.grid, w.params).unwrap().step(&w.a, &w.b).unwrap();
    let q = ParallelCpuCollision::new(s.grid, s.params).unwrap().step(&s.a, &s.b).unwrap();
    assert_eq!(r.colliding_b.len(), q.colliding_b.len());
    let key = |v: voxcollide::glam::Vec3| v.to_array().map(f32::to_bits);
    let mut by_position: Vec<_> = w.b.iter().zip(&r.force_b).map(|(p, f)| (key(*p), key(*f))).collect();
    let mut shuffled: Vec<_> = s.b.iter().zip(&q.force_b).map(|(p, f)| (key(*p), key(*f))).collect();
    by_position.sort_unstable();
    shuffled.sort_unstable();
    assert!(by_position == shuffled);
}

#[test]
fn parallel_follows_the_reference_step_by_step_on_the_moving_workload() {
    // docs/design.md §7's moving(N): one backend stepped 20 times in a row, B moving a
    // twentieth of the spacing each step; every step's report is the reference's for that
    // step's positions, whatever the backend keeps from step to step.
    let m = workload::moving(30_000, 21).unwrap();
    let w = &m.start;
    let mut reference = CpuCollision::new(w.grid, w.params).unwrap();
    let mut parallel = ParallelCpuCollision::new(w.grid, w.params).unwrap();
    let mut report = ContactReport::default();
    let mut counts = Vec::new();
    for k in 0..workload::MOVING_STEPS {
        let b = m.b_at(k);
        assert_eq!(b[7], w.b[7] + workload::MOVING_STEP * k as f32);
        let expected = reference.step(&w.a, &b).unwrap();
        parallel.step_into(&w.a, &b, &mut report).unwrap();
        assert!(expected == report, "step {k}");
        counts.push(expected.colliding_b.len());
    }
    // The contacts change as B moves (a third of a voxel's worth of B leaves A's reach).
    assert!(counts.iter().all(|c| *c > 20_000), "{counts:?}");
    assert!(counts.first() != counts.last(), "{counts:?}");
    // A still kept its order after the first step; B kept its own at the steps where none of
    // its vertices crossed into another voxel (its jitter spreads the crossings over a few).
    let [kept_a, kept_b] = parallel.orders_kept();
    assert_eq!(kept_a, workload::MOVING_STEPS as u64 - 1);
    assert!((5..kept_a).contains(&kept_b), "B kept its order at {kept_b} steps");
}

#[test]
fn a_kept_order_of_a_moving_body_holds_only_while_its_vertices_keep_their_voxels() {
    // B moves by less than its vertices' distance to a voxel's face: its order is kept, with
    // its new positions. Then one vertex crosses into the next voxel, leaves the grid, becomes
    // NaN and comes back, B gains a vertex, A moves: each but NaN sorts B again. Every step's
    // report equals the reference's (with the positions left unrefreshed in the kept order,
    // the second step differs).
    let w = workload::lattice(20_000, 29).unwrap();
    let (grid, params) = (w.grid, w.params);
    let mut reference = CpuCollision::new(grid, params).unwrap();
    let mut parallel = ParallelCpuCollision::new(grid, params).unwrap();
    let mut report = ContactReport::default();
    let (mut a, mut b) = (w.a.clone(), w.b.clone());
    let mid = b.len() / 2 + 5;
    let mut kept = Vec::new();
    for k in 0..10 {
        match k {
            // Each vertex that stays within its voxel so (most of them, checked below).
            1 | 2 => b.iter_mut().for_each(|p| {
                let q = *p + Vec3::new(0.01, -0.01, 0.005);
                if grid.voxel_of(q) == grid.voxel_of(*p) {
                    *p = q;
                }
            }),
            3 => b[mid].x += 1.0,
            4 => b[mid].x = 1e9,
            5 => b[mid].x = f32::NAN,
            6 => b[mid] = w.b[mid],
            7 => b.push(w.b[0] + Vec3::splat(0.05)),
            8 => a[3].y += 0.01,
            _ => {}
        }
        if k == 2 {
            let moved = b.iter().zip(&w.b).filter(|(p, q)| p != q).count();
            assert!(moved > b.len() * 3 / 4, "{moved}");
        }
        let expected = reference.step(&a, &b).unwrap();
        let before = parallel.orders_kept()[1];
        parallel.step_into(&a, &b, &mut report).unwrap();
        assert!(expected == report, "step {k}");
        kept.push(parallel.orders_kept()[1] > before);
    }
    // Steps 0, 3, 4 and 6 to 8 sort B again; 1, 2, 9 keep its order, and so does 5: a vertex
    // outside the grid and then NaN is left out of the sort either way.
    let expected = [false, true, true, false, false, true, false, false, false, true];
    assert_eq!(kept, expected);
}

#[test]
fn a_kept_order_of_a_still_body_is_let_go_the_moment_it_moves() {
    // A still A keeps the order it was sorted in; one vertex moved (by a third of the spacing,
    // or by one unit in the last place), a sign of zero flipped, a vertex more or a grid that
    // follows A sorts it again.
    // Every step's report equals the reference's, stepped the same way.
    let m = workload::moving(20_000, 23).unwrap();
    let (grid, params) = (m.start.grid, m.start.params);
    let mut a = m.start.a.clone();
    let mut follow = params;
    follow.anchor = Anchor::FollowA;
    for params in [params, follow] {
        let mut reference = CpuCollision::new(grid, params).unwrap();
        let mut parallel = ParallelCpuCollision::new(grid, params).unwrap();
        let mut report = ContactReport::default();
        for k in 0..8 {
            let b = m.b_at(k);
            let mid = a.len() / 2 + 13;
            match k {
                2 => a[mid].x += 0.3,
                3 => a[mid].x = f32::from_bits(a[mid].x.to_bits() + 1),
                5 => a[5] = Vec3::new(0.0, a[5].y, a[5].z),
                // The same place as -0.0: other bits, so sorted again (the reports are the
                // same either way; this step shows only that nothing breaks).
                6 => a[5].x = -0.0,
                7 => a.push(a[0] + Vec3::splat(0.3)),
                _ => {}
            }
            let expected = reference.step(&a, &b).unwrap();
            parallel.step_into(&a, &b, &mut report).unwrap();
            assert!(expected == report, "step {k} {:?}", params.anchor);
        }
    }
}

#[test]
fn parallel_errors_match_the_reference() {
    let grid =
        VoxelGrid::new(voxcollide::glam::Vec3::splat(2.0), 1.0, voxcollide::glam::UVec3::splat(4)).unwrap();
    let params = all_params(1.0, 1.0)[0];
    let a = [voxcollide::glam::Vec3::splat(0.5)];
    let b = vec![voxcollide::glam::Vec3::new(0.75, 0.5, 0.5); 32769];
    let mut par = ParallelCpuCollision::new(grid, params).unwrap();
    assert_eq!(
        par.step(&a, &b).unwrap_err(),
        CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap_err()
    );
    assert_eq!(par.step(&[], &b).unwrap_err(), Error::EmptyBody { body: Body::A });
    let bad = ContactParams { magnitude: -1.0, ..params };
    assert!(matches!(ParallelCpuCollision::new(grid, bad).unwrap_err(), Error::Magnitude { .. }));
}

#[test]
fn parallel_reports_do_not_depend_on_the_thread_count() {
    // Long runs of sorted B own most of A's accumulators and add to them without atomics
    // (`own_bins`); the runs' boundaries move with the thread count, so every count must give
    // the reference's report, in x-fastest and shuffled order, for every search and direction.
    for (w, order) in [
        (workload::lattice(150_000, 11).unwrap(), "lattice"),
        (workload::shuffled(150_000, 12).unwrap(), "shuffled"),
    ] {
        for (search, direction) in [
            (w.params.search, Direction::Pairwise),
            (w.params.search, Direction::PlaneNormal),
            (Search::Voxel, Direction::Pairwise),
            (Search::Voxel, Direction::PlaneNormal),
        ] {
            let params = ContactParams { search, direction, ..w.params };
            let expected = CpuCollision::new(w.grid, params).unwrap().step(&w.a, &w.b).unwrap();
            assert!(expected.colliding_b.len() > 100_000);
            for threads in [1, 2, 3, 7] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let mut backend = ParallelCpuCollision::new(w.grid, params).unwrap();
                let actual = pool.install(|| {
                    backend.step(&w.a, &w.b).unwrap();
                    backend.step(&w.a, &w.b).unwrap()
                });
                assert!(expected == actual, "{order} {params:?} on {threads} threads");
            }
        }
    }
}

#[test]
fn piles_on_either_side_of_the_32_bit_accumulators_match_the_reference() {
    // A's totals are summed in 32 bits while no slot of B holds more than 1213 vertices, in 64
    // bits beyond. Piles of B around an A vertex, just under and just over that, from every
    // direction, must give the reference's report either way (and the 64-bit path the
    // reference's overflow where the total leaves i32: 32769 pushes of 65536).
    use voxcollide::glam::Vec3;
    let grid = VoxelGrid::new(Vec3::splat(2.0), 1.0, voxcollide::glam::UVec3::splat(4)).unwrap();
    let a = [Vec3::splat(1.5), Vec3::new(1.6, 1.5, 1.5)];
    for per_voxel in [1, 1213, 1214, 5000] {
        let mut b = Vec::new();
        for (k, d) in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z].into_iter().enumerate() {
            for j in 0..per_voxel {
                b.push(Vec3::splat(1.5) + d * (0.6 + 0.0001 * (j % 7) as f32) + Vec3::splat(0.01 * k as f32));
            }
        }
        for params in all_params(1.0, 1.0) {
            let expected = CpuCollision::new(grid, params).unwrap().step(&a, &b);
            let actual = ParallelCpuCollision::new(grid, params).unwrap().step(&a, &b);
            assert!(expected == actual, "{per_voxel} a voxel, {params:?}");
        }
    }
}

#[test]
fn crowded_voxels_and_ties_probed_in_lanes_match_the_reference() {
    // The neighbour search probes B in groups of lanes along a row of voxels: groups that end
    // mid-voxel, at a row's end and at a vertex outside the grid, crowds of B in one voxel,
    // and A vertices at the same distance from a B vertex (the lower index wins in every lane).
    use voxcollide::glam::Vec3;
    let mut a = Vec::new();
    for z in 0..6 {
        for y in 0..6 {
            for x in 0..12 {
                let p = Vec3::new(x as f32, y as f32, z as f32) * 1.0;
                a.push(p);
                a.push(p); // a twin: every distance ties
            }
        }
    }
    let grid = Initializer::new(1.0).build(&a).unwrap();
    let mut b = Vec::new();
    // A crowd of 30 in one voxel, on its faces and corners too.
    for k in 0..30 {
        let t = k as f32 / 29.0;
        b.push(Vec3::new(3.0 + t, 2.0 + (1.0 - t) * 0.999, 2.5));
    }
    // Every voxel of a few rows, with some left empty and one vertex outside the grid.
    for z in [0.5f32, 2.5, 5.5] {
        for y in [0.5f32, 3.5, 5.5] {
            for x in 0..12 {
                if x % 5 == 3 {
                    continue;
                }
                b.push(Vec3::new(x as f32 + 0.5, y, z));
            }
            b.push(Vec3::new(40.0, y, z));
        }
    }
    // Halfway between two A vertices along each axis (exact ties across voxels).
    b.extend([Vec3::new(4.5, 1.0, 1.0), Vec3::new(4.0, 1.5, 1.0), Vec3::new(4.0, 1.0, 1.5)]);
    for radius in [0.72f32, 0.9, 1.0] {
        for magnitude in [1.0f32, 1e-3] {
            let params = ContactParams {
                magnitude,
                search: Search::Neighbours { radius },
                direction: Direction::Pairwise,
                anchor: Anchor::Fixed,
            };
            let expected = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
            let actual = ParallelCpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
            let what = format!("radius {radius}, magnitude {magnitude}");
            assert!(expected.colliding_b.len() > 20, "{what}: {} colliding", expected.colliding_b.len());
            assert_eq!(common::compare(&what, &expected, &actual, 0.0), 0, "{what}");
        }
    }
}

#[test]
fn hashed_tables_match_the_reference() {
    // Grids of more than four voxels per A vertex hash A's voxel table (rows grouped in
    // bricks): random bodies in a roomy grid, a sphere's shell in its bounding grid (a surface
    // mesh's case), a slab long along x (rows far apart within a brick), and a handful of
    // vertices in a table of sixteen slots (rows aliased).
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
    let mut cases: Vec<(&str, Vec<Vec3>, Vec<Vec3>, VoxelGrid)> = Vec::new();
    let (a, b, _, _) = bodies(11, 20_000);
    let grid = Initializer::new(1.0).margin(20).build(&a[..18_000]).unwrap();
    cases.push(("roomy", a, b, grid));
    let mut shell = |r: f32, n: usize| -> Vec<Vec3> {
        (0..n)
            .map(|_| {
                let d = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                d.normalize_or(Vec3::X) * (r + rng.random_range(-0.3..0.3))
            })
            .collect()
    };
    let (a, b) = (shell(30.0, 30_000), shell(29.5, 30_000));
    let grid = Initializer::new(1.0).margin(2).build(&a).unwrap();
    cases.push(("shell", a, b, grid));
    let slab = |rng: &mut rand_chacha::ChaCha8Rng, n: usize| -> Vec<Vec3> {
        (0..n)
            .map(|_| {
                Vec3::new(
                    rng.random_range(0.0..3000.0),
                    rng.random_range(0.0..6.0),
                    rng.random_range(0.0..2.0),
                )
            })
            .collect()
    };
    let (a, b) = (slab(&mut rng, 8_000), slab(&mut rng, 8_000));
    let grid = Initializer::new(1.0).margin(3).build(&a).unwrap();
    cases.push(("slab", a, b, grid));
    let a = vec![Vec3::ZERO, Vec3::new(0.3, 9.0, 4.0), Vec3::new(17.0, 2.0, 1.0)];
    let b =
        vec![Vec3::new(0.2, 0.1, 0.0), Vec3::new(0.5, 8.8, 4.1), Vec3::new(16.6, 2.2, 1.3), Vec3::splat(5.0)];
    let grid = Initializer::new(0.5).margin(1).build(&a).unwrap();
    cases.push(("few", a, b, grid));
    for (name, a, b, grid) in &cases {
        let voxels = u64::from(grid.dims().x) * u64::from(grid.dims().y) * u64::from(grid.dims().z);
        assert!(voxels > 4 * a.len() as u64, "{name}: {voxels} voxels is a dense table");
        let mut contacts = 0;
        for radius in [0.9 * grid.voxel_size(), 0.4 * grid.voxel_size()] {
            for params in all_params(1.0, radius) {
                let expected = CpuCollision::new(*grid, params).unwrap().step(a, b).unwrap();
                let actual = ParallelCpuCollision::new(*grid, params).unwrap().step(a, b).unwrap();
                let what = format!("{name} {params:?}");
                assert_eq!(expected.colliding_b, actual.colliding_b, "{what}");
                assert_eq!(common::compare(&what, &expected, &actual, 0.0), 0);
                contacts += expected.colliding_b.len();
            }
        }
        assert!(contacts > 0, "{name}: no contact");
    }
}
