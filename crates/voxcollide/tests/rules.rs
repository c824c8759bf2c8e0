//! Hand-computed cases for each collision rule of docs/design.md §2, with the numbers in the comments,
//! and the bad-input errors of `CpuCollision`.

use voxcollide::fixed_point::ForceAccumulator;
use voxcollide::glam::{UVec3, Vec3};
use voxcollide::*;

/// Grid over `[0, 4)^3` in unit voxels: center (2, 2, 2), origin 0, so a voxel index is
/// `floor(p)`.
fn unit_grid() -> VoxelGrid {
    VoxelGrid::new(Vec3::splat(2.0), 1.0, UVec3::splat(4)).unwrap()
}

fn params(search: Search, direction: Direction, anchor: Anchor) -> ContactParams {
    ContactParams { magnitude: 1.0, search, direction, anchor }
}

fn step(grid: VoxelGrid, params: ContactParams, a: &[Vec3], b: &[Vec3]) -> ContactReport {
    CpuCollision::new(grid, params).unwrap().step(a, b).unwrap()
}

const VOXEL_PAIRWISE: ContactParams = ContactParams {
    magnitude: 1.0,
    search: Search::Voxel,
    direction: Direction::Pairwise,
    anchor: Anchor::Fixed,
};

#[test]
fn discarding_counts_outside_and_non_finite_a_vertices() {
    // Grid [0, 2)^3: center 1, dims 2.
    let grid = VoxelGrid::new(Vec3::ONE, 1.0, UVec3::splat(2)).unwrap();
    let a = [
        Vec3::new(0.5, 0.5, 0.5),           // voxel (0,0,0): binned
        Vec3::new(2.0, 0.5, 0.5),           // x index 2, not < 2: discarded
        Vec3::new(f32::NAN, 0.5, 0.5),      // not finite: discarded
        Vec3::new(0.0, 0.0, 0.0),           // voxel (0,0,0): binned
        Vec3::new(-0.25, 1.5, 1.5),         // x index floor(-0.25) = -1: discarded
        Vec3::new(1.0, f32::INFINITY, 1.0), // not finite: discarded
    ];
    let r = step(grid, VOXEL_PAIRWISE, &a, &[Vec3::new(1.5, 1.5, 1.5)]);
    assert_eq!((r.binned_a, r.discarded_a), (2, 4));
    assert!(r.colliding_b.is_empty());
    assert!(r.force_a.iter().all(|f| *f == Vec3::ZERO));
}

#[test]
fn b_outside_the_grid_never_collides_even_within_the_radius() {
    // Grid [0, 2)^3. A at (1.75, 0.5, 0.5); B at (2.0, 0.5, 0.5) is 0.25 away, well within the
    // radius 0.9, but its x index is 2: outside, so no contact.
    let grid = VoxelGrid::new(Vec3::ONE, 1.0, UVec3::splat(2)).unwrap();
    let a = [Vec3::new(1.75, 0.5, 0.5)];
    let b = [Vec3::new(2.0, 0.5, 0.5), Vec3::new(f32::NAN, 0.5, 0.5), Vec3::new(1.5, 0.5, 0.5)];
    let r =
        step(grid, params(Search::Neighbours { radius: 0.9 }, Direction::Pairwise, Anchor::Fixed), &a, &b);
    assert_eq!(r.colliding_b, vec![2]);
    assert_eq!(r.force_b[0], Vec3::ZERO);
    assert_eq!(r.force_b[1], Vec3::ZERO);
    // b2 - a = (-0.25, 0, 0): unit -x.
    assert_eq!(r.force_b[2], Vec3::NEG_X);
    assert_eq!(r.force_a[0], Vec3::X);
}

#[test]
fn voxel_search_collides_within_the_voxel_only() {
    // a = (0.125, 0.5, 0.0625) in voxel (0,0,0).
    // b0 = (0.5, 0.5, 0.5625): same voxel; b0 - a = (0.375, 0, 0.5), d2 = 0.390625, sqrt = 0.625,
    //   d = (0.6, 0, 0.8): f_b0 = (0.6, 0, 0.8).
    // b1 = (1.0, 0.5, 0.0625): voxel (1,0,0), only 0.875 away, but another voxel: no contact.
    let a = [Vec3::new(0.125, 0.5, 0.0625)];
    let b = [Vec3::new(0.5, 0.5, 0.5625), Vec3::new(1.0, 0.5, 0.0625)];
    let r = step(unit_grid(), VOXEL_PAIRWISE, &a, &b);
    assert_eq!(r.colliding_b, vec![0]);
    assert_eq!(r.force_b[0], Vec3::new(0.6, 0.0, 0.8));
    assert_eq!(r.force_b[1], Vec3::ZERO);
    // Fixed point, m = 1: x: round(-0.6f32 * 65536) = round(-39321.6) = -39322 -> -39322/65536;
    // z: round(-0.8f32 * 65536) = round(-52428.8) = -52429 -> -52429/65536.
    assert_eq!(r.force_a[0], Vec3::new(-39322.0 / 65536.0, 0.0, -52429.0 / 65536.0));
}

#[test]
fn neighbour_search_uses_the_block_and_a_strict_radius() {
    // radius 0.5 (r2 = 0.25).
    // a0 = (0.875, 0.5, 0.5), voxel (0,0,0); a1 = (1.625, 0.5, 0.5), voxel (1,0,0).
    // b0 = (1.125, 0.5, 0.5), voxel (1,0,0): a0 at d2 = 0.0625 (neighbouring voxel) and a1 at
    //   d2 = 0.25, not < 0.25: partner a0, f = (0.25, 0, 0) / 0.25 = +x.
    // b1 = (2.125, 0.5, 0.5): a1 at d2 = 0.25 exactly: no candidate, no contact.
    let a = [Vec3::new(0.875, 0.5, 0.5), Vec3::new(1.625, 0.5, 0.5)];
    let b = [Vec3::new(1.125, 0.5, 0.5), Vec3::new(2.125, 0.5, 0.5)];
    let r = step(
        unit_grid(),
        params(Search::Neighbours { radius: 0.5 }, Direction::Pairwise, Anchor::Fixed),
        &a,
        &b,
    );
    assert_eq!(r.colliding_b, vec![0]);
    assert_eq!(r.force_b, vec![Vec3::X, Vec3::ZERO]);
    assert_eq!(r.force_a, vec![Vec3::NEG_X, Vec3::ZERO]);
}

#[test]
fn neighbour_block_is_clipped_at_the_grid_faces() {
    // b = (0.1, 0.1, 0.1) in corner voxel (0,0,0): its block is clipped to [0,1]^3. a = (0.0, 0.0,
    // 0.0) in the same voxel at d2 = 0.03: collides, and nothing out of range is touched.
    let a = [Vec3::ZERO];
    let r = step(
        unit_grid(),
        params(Search::Neighbours { radius: 1.0 }, Direction::Pairwise, Anchor::Fixed),
        &a,
        &[Vec3::splat(0.125)],
    );
    assert_eq!(r.colliding_b, vec![0]);
    let d = 1.0 / 3f32.sqrt();
    assert!(r.force_b[0].abs_diff_eq(Vec3::splat(d), 1e-6), "{}", r.force_b[0]);
}

#[test]
fn partner_is_nearest_and_ties_go_to_the_smaller_index() {
    // b = (0.5, 0.5, 0.5). a0 = (0.0625, 0.5, 0.5) at d2 = 0.19140625;
    // a1 = (0.75, 0.5, 0.5) and a2 = (0.25, 0.5, 0.5) both at d2 = 0.0625: a tie, a1 wins.
    // f_b = (0.5 - 0.75, 0, 0) / 0.25 = -x; a1 gets +x.
    let a = [Vec3::new(0.0625, 0.5, 0.5), Vec3::new(0.75, 0.5, 0.5), Vec3::new(0.25, 0.5, 0.5)];
    let b = [Vec3::splat(0.5)];
    let r = step(unit_grid(), VOXEL_PAIRWISE, &a, &b);
    assert_eq!(r.force_b[0], Vec3::NEG_X);
    assert_eq!(r.force_a, vec![Vec3::ZERO, Vec3::X, Vec3::ZERO]);

    // Reversing the order of A changes which index wins the tie, but not the geometry: now
    // a1 = (0.25, ...) has the smaller index and wins: f_b = (0.25, 0, 0) / 0.25 = +x.
    let a = [a[0], a[2], a[1]];
    let r = step(unit_grid(), VOXEL_PAIRWISE, &a, &b);
    assert_eq!(r.force_b[0], Vec3::X);
    assert_eq!(r.force_a, vec![Vec3::ZERO, Vec3::NEG_X, Vec3::ZERO]);
}

#[test]
fn coincident_vertices_push_away_from_the_grid_center() {
    // Grid center (2, 2, 2). a = b = (0.5, 2, 2): d2 = 0 < 1e-12, so d = unit(b - center) =
    // unit(-1.5, 0, 0) = -x.
    let a = [Vec3::new(0.5, 2.0, 2.0)];
    let r = step(unit_grid(), VOXEL_PAIRWISE, &a, &a);
    assert_eq!(r.force_b[0], Vec3::NEG_X);
    assert_eq!(r.force_a[0], Vec3::X);

    // b = a + 1 ulp in x (0.5 + 2^-24 = 0.50000006): d2 = 3.6e-15 < 1e-12, still
    // coincident: the same direction.
    let b = [Vec3::new(f32::from_bits(0.5f32.to_bits() + 1), 2.0, 2.0)];
    let r = step(unit_grid(), VOXEL_PAIRWISE, &a, &b);
    assert!(r.force_b[0].abs_diff_eq(Vec3::NEG_X, 1e-6), "{}", r.force_b[0]);

    // a = b = the grid center: the direction from the center is degenerate too: +z.
    let a = [Vec3::splat(2.0)];
    let r = step(unit_grid(), VOXEL_PAIRWISE, &a, &a);
    assert_eq!(r.force_b[0], Vec3::Z);
    assert_eq!(r.force_a[0], Vec3::NEG_Z);
}

/// a0 = (1.5, 1.5, z) in voxel (1,1,⌊z⌋), a1 = a0 + x, a2 = a0 + y in neighbouring voxels.
fn right_angle(z: f32) -> [Vec3; 3] {
    [Vec3::new(1.5, 1.5, z), Vec3::new(2.5, 1.5, z), Vec3::new(1.5, 2.5, z)]
}

#[test]
fn plane_normal_points_outward_from_the_grid_center() {
    let plane = params(Search::Voxel, Direction::PlaneNormal, Anchor::Fixed);
    // Plane z = 1, below the center (2,2,2). b = (1.5, 1.5, 1.25) in a0's voxel: collides. The
    // plane candidates are the whole 3×3×3 block: a0 (d2 0.0625), a1 and a2 (d2 1.0625, tie by
    // index). cross(a1 - a0, a2 - a0) = cross(x, y) = +z; centroid - center has z = 1 - 2 = -1,
    // so n flips to -z. f_b = -z; each A vertex gets +z / 3: round(65536 / 3) = 21845 ->
    // 21845 / 65536 = 0.3333282470703125.
    let a = right_angle(1.0);
    let r = step(unit_grid(), plane, &a, &[Vec3::new(1.5, 1.5, 1.25)]);
    assert_eq!(r.force_b[0], Vec3::NEG_Z);
    assert_eq!(r.force_a, vec![Vec3::new(0.0, 0.0, 21845.0 / 65536.0); 3]);

    // Plane z = 2.5, above the center: centroid - center has z = +0.5, n stays +z.
    let a = right_angle(2.5);
    let r = step(unit_grid(), plane, &a, &[Vec3::new(1.5, 1.5, 2.75)]);
    assert_eq!(r.force_b[0], Vec3::Z);
    assert_eq!(r.force_a, vec![Vec3::new(0.0, 0.0, -21845.0 / 65536.0); 3]);
}

#[test]
fn plane_normal_falls_back_to_pairwise_without_a_plane() {
    let plane = params(Search::Voxel, Direction::PlaneNormal, Anchor::Fixed);
    let b = [Vec3::new(1.5, 1.5, 1.25)];
    // Two candidates only: pairwise with the partner a0: (0, 0, 0.25) / 0.25 = +z (not the
    // plane's -z).
    let a = &right_angle(1.0)[..2];
    let r = step(unit_grid(), plane, a, &b);
    assert_eq!(r.force_b[0], Vec3::Z);
    assert_eq!(r.force_a, vec![Vec3::NEG_Z, Vec3::ZERO]);

    // Three collinear candidates: |cross| = 0 < 1e-12: pairwise with a0 again.
    let a = [Vec3::new(1.5, 1.5, 1.0), Vec3::new(2.5, 1.5, 1.0), Vec3::new(1.25, 1.5, 1.0)];
    let r = step(unit_grid(), plane, &a, &b);
    assert_eq!(r.force_b[0], Vec3::Z);
    assert_eq!(r.force_a, vec![Vec3::NEG_Z, Vec3::ZERO, Vec3::ZERO]);
}

#[test]
fn plane_candidates_under_neighbours_are_the_search_candidates() {
    // a0 = (1.5, 1.5, 1) (d2 0.0625), a1 = (1.75, 1.5, 1) (d2 0.125), a2 = (1.5, 2.5, 1)
    // (d2 1.0625). Voxel search: all three span the plane z = 1, normal flipped to -z.
    // Neighbours with radius 0.5: a2 is out of range, two candidates: pairwise +z with a0.
    let a = [Vec3::new(1.5, 1.5, 1.0), Vec3::new(1.75, 1.5, 1.0), Vec3::new(1.5, 2.5, 1.0)];
    let b = [Vec3::new(1.5, 1.5, 1.25)];
    let r = step(unit_grid(), params(Search::Voxel, Direction::PlaneNormal, Anchor::Fixed), &a, &b);
    assert_eq!(r.force_b[0], Vec3::NEG_Z);
    assert_eq!(r.force_a[1], Vec3::new(0.0, 0.0, 21845.0 / 65536.0));
    let near = Search::Neighbours { radius: 0.5 };
    let r = step(unit_grid(), params(near, Direction::PlaneNormal, Anchor::Fixed), &a, &b);
    assert_eq!(r.force_b[0], Vec3::Z);
    assert_eq!(r.force_a, vec![Vec3::NEG_Z, Vec3::ZERO, Vec3::ZERO]);
}

#[test]
fn forces_on_a_are_summed_in_fixed_point() {
    // a = (1, 1, 1); b0 = (1.375, 1, 1.5), b1 = (1.375, 1, 0.5), both 0.625 away:
    // f_b0 = (0.6, 0, 0.8), f_b1 = (0.6, 0, -0.8).
    // A's x: 2 * round(-0.6f32 * 65536) = 2 * -39322 = -78644 -> -78644 / 65536 =
    // -1.20001220703125 (an f32 sum would give -1.2000000476837158); z: -52429 + 52429 = 0.
    let a = [Vec3::ONE];
    let b = [Vec3::new(1.375, 1.0, 1.5), Vec3::new(1.375, 1.0, 0.5)];
    let r = step(
        unit_grid(),
        params(Search::Neighbours { radius: 1.0 }, Direction::Pairwise, Anchor::Fixed),
        &a,
        &b,
    );
    assert_eq!(r.force_b, vec![Vec3::new(0.6, 0.0, 0.8), Vec3::new(0.6, 0.0, -0.8)]);
    assert_eq!(r.force_a[0], Vec3::new(-78644.0 / 65536.0, 0.0, 0.0));
}

#[test]
fn fixed_point_counts_round_ties_to_even_and_scale_by_magnitude() {
    // m = 1: scale 65536. 0.5 / 65536 -> 0.5 -> 0; 1.5 -> 2; -2.5 -> -2; 2.5 -> 2.
    let acc = ForceAccumulator::new(1, 1, 1.0);
    let unit = 1.0 / 65536.0;
    assert_eq!([0.5, 1.5, -2.5, 2.5, 2.4999].map(|k| acc.count(k * unit)), [0, 2, -2, 2, 2]);
    // m = 4: scale 16384. A contribution of -4 * 0.6 = -2.4 counts round(-39321.6) = -39322,
    // back to -39322 * (4 / 65536) = -2.400024414.
    let mut acc = ForceAccumulator::new(1, 1, 4.0);
    acc.add_a(0, Vec3::new(-2.4, 0.0, 0.0));
    let (force_a, _) = acc.finish().unwrap();
    assert_eq!(force_a[0].x, -39322.0 * (4.0 / 65536.0));
}

#[test]
fn force_overflow_is_an_error_not_a_wrap() {
    // Each b at (0.75, 0.5, 0.5) pushes a = (0.5, 0.5, 0.5) by -x: count -65536 each.
    // 32768 of them total -2^31 = i32::MIN, which fits: -2^31 / 65536 = -32768.
    let a = [Vec3::splat(0.5)];
    let b = vec![Vec3::new(0.75, 0.5, 0.5); 32768];
    let r = step(unit_grid(), VOXEL_PAIRWISE, &a, &b);
    assert_eq!(r.force_a[0], Vec3::new(-32768.0, 0.0, 0.0));
    // One more: -2^31 - 65536 = -2147549184 leaves i32.
    let b = vec![Vec3::new(0.75, 0.5, 0.5); 32769];
    let err = CpuCollision::new(unit_grid(), VOXEL_PAIRWISE).unwrap().step(&a, &b).unwrap_err();
    assert_eq!(err, Error::ForceOverflow { vertex: 0, axis: 0, count: -2_147_549_184 });
    assert!(err.to_string().contains("-2147549184") && err.to_string().contains("i32"), "{err}");
}

#[test]
fn follow_a_recentres_the_grid_each_step() {
    // Built on A = {(0,0,0), (2,0,0)}: center (1,0,0), n = 2 + 2 * 1 = 4.
    let a0 = [Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0)];
    let grid = Initializer::new(1.0).margin(1).build(&a0).unwrap();
    // A moved by +10 in x (plus two non-finite vertices, ignored by the bounds and discarded):
    // the FollowA center is 0.5 * (10 + 12) = 11; origin = 11 - 0.5 * 4 = 9 in x, -2 in y, z.
    // b = (12.25, 0, 0): voxel (3, 2, 2), the same as a1 = (12, 0, 0): f_b = +x.
    let a =
        [Vec3::new(10.0, 0.0, 0.0), Vec3::new(12.0, 0.0, 0.0), Vec3::NAN, Vec3::new(0.0, f32::INFINITY, 0.0)];
    let b = [Vec3::new(12.25, 0.0, 0.0)];
    let follow = step(grid, params(Search::Voxel, Direction::Pairwise, Anchor::FollowA), &a, &b);
    assert_eq!(follow.grid_center, Vec3::new(11.0, 0.0, 0.0));
    assert_eq!((follow.binned_a, follow.discarded_a), (2, 2));
    assert_eq!(follow.force_b[0], Vec3::X);
    assert_eq!(follow.force_a[1], Vec3::NEG_X);

    // Fixed: the grid stays at (1,0,0) and covers x in [-1, 3): everything is outside.
    let fixed = step(grid, VOXEL_PAIRWISE, &a, &b);
    assert_eq!(fixed.grid_center, Vec3::new(1.0, 0.0, 0.0));
    assert_eq!((fixed.binned_a, fixed.discarded_a), (0, 4));
    assert!(fixed.colliding_b.is_empty());

    // With no finite A vertex, FollowA keeps the built grid (and every A vertex is discarded).
    let none = step(grid, params(Search::Voxel, Direction::Pairwise, Anchor::FollowA), &[Vec3::NAN], &b);
    assert_eq!(none.grid_center, grid.center());
    assert_eq!((none.binned_a, none.discarded_a), (0, 1));
}

#[test]
fn non_finite_vertices_never_reach_the_output() {
    let a = [Vec3::splat(0.5), Vec3::NAN, Vec3::new(f32::NEG_INFINITY, 0.5, 0.5)];
    let b = [Vec3::splat(0.75), Vec3::new(0.5, f32::NAN, 0.5), Vec3::INFINITY];
    for direction in [Direction::Pairwise, Direction::PlaneNormal] {
        for anchor in [Anchor::Fixed, Anchor::FollowA] {
            let r = step(unit_grid(), params(Search::Neighbours { radius: 1.0 }, direction, anchor), &a, &b);
            assert_eq!(r.colliding_b, vec![0]);
            assert_eq!(r.discarded_a, 2);
            assert!(r.force_a.iter().chain(&r.force_b).all(|f| f.is_finite()), "{r:?}");
            assert!(r.grid_center.is_finite());
        }
    }
}

#[test]
fn bad_magnitudes_are_typed_errors() {
    for magnitude in [0.0, -0.0, -1.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e-31, 1e31, 1e-40] {
        let p = ContactParams { magnitude, ..VOXEL_PAIRWISE };
        let err = CpuCollision::new(unit_grid(), p).err().unwrap();
        assert!(
            matches!(err, Error::Magnitude { value } if value.to_bits() == magnitude.to_bits()),
            "{err:?}"
        );
        assert!(err.to_string().contains(&format!("magnitude {magnitude:?} is invalid")), "{err}");
    }
    for magnitude in [1e-30, 1e30, 1.0, 3.7] {
        assert!(CpuCollision::new(unit_grid(), ContactParams { magnitude, ..VOXEL_PAIRWISE }).is_ok());
    }
}

#[test]
fn radius_outside_zero_to_voxel_size_is_a_typed_error() {
    for radius in [0.0, -0.5, 1.0000001, 2.0, f32::NAN, f32::INFINITY] {
        let p = params(Search::Neighbours { radius }, Direction::Pairwise, Anchor::Fixed);
        let err = CpuCollision::new(unit_grid(), p).err().unwrap();
        assert!(matches!(err, Error::Radius { voxel_size: 1.0, .. }), "{radius}: {err:?}");
        assert!(err.to_string().contains("0 < radius <= voxel size (1.0)"), "{err}");
    }
    for radius in [1.0, 0.5, 1e-6] {
        let p = params(Search::Neighbours { radius }, Direction::Pairwise, Anchor::Fixed);
        assert!(CpuCollision::new(unit_grid(), p).is_ok());
    }
}

#[test]
fn empty_bodies_are_typed_errors() {
    let mut cpu = CpuCollision::new(unit_grid(), VOXEL_PAIRWISE).unwrap();
    let err = cpu.step(&[], &[Vec3::ONE]).unwrap_err();
    assert_eq!(err, Error::EmptyBody { body: Body::A });
    assert!(err.to_string().contains("body A is empty"), "{err}");
    assert_eq!(cpu.step(&[Vec3::ONE], &[]).unwrap_err(), Error::EmptyBody { body: Body::B });
}

#[test]
fn lonely_voxel_in_a_huge_sparse_grid() {
    // 2^24 voxels per axis: memory follows |A|, not dims. center 0, voxel 2^-4:
    // origin = -0.5 * 2^-4 * 2^24 = -2^19. a = (1000, -1000, 0.03125), b 0.03125 above in z, same
    // voxel: (0.0625 - 0.03125) / 0.03125 -> +z.
    let grid = VoxelGrid::new(Vec3::ZERO, 0.0625, UVec3::splat(1 << 24)).unwrap();
    let a = [Vec3::new(1000.0, -1000.0, 0.0)];
    let b = [Vec3::new(1000.0, -1000.0, 0.03125), Vec3::new(-1000.0, 1000.0, 0.0)];
    let r = step(grid, VOXEL_PAIRWISE, &a, &b);
    assert_eq!(r.colliding_b, vec![0]);
    assert_eq!(r.force_b[0], Vec3::Z);
}

#[test]
fn steps_are_deterministic_and_reuse_state_safely() {
    let a = right_angle(1.0);
    let b = [Vec3::new(1.5, 1.5, 1.25), Vec3::new(2.4, 1.6, 1.1)];
    let mut cpu =
        CpuCollision::new(unit_grid(), params(Search::Voxel, Direction::PlaneNormal, Anchor::FollowA))
            .unwrap();
    let first = cpu.step(&a, &b).unwrap();
    let _other = cpu.step(&[Vec3::ONE; 5], &[Vec3::ONE]).unwrap();
    assert_eq!(cpu.step(&a, &b).unwrap(), first);
}
