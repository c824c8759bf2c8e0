//! Hand-computed cases for the voxel grid and the initializer (docs/design.md §2, *Grid* and
//! *Initializer*), and their bad-input errors.

use voxcollide::glam::{UVec3, Vec3};
use voxcollide::{Error, Initializer, VoxelGrid};

#[test]
fn origin_is_center_minus_half_extent() {
    // half = 0.5 * 0.5 = 0.25; origin = (1 - 0.25*3, 2 - 0.25*4, 3 - 0.25*5) = (0.25, 1, 1.75).
    let grid = VoxelGrid::new(Vec3::new(1.0, 2.0, 3.0), 0.5, UVec3::new(3, 4, 5)).unwrap();
    assert_eq!(grid.origin(), Vec3::new(0.25, 1.0, 1.75));
    assert_eq!(grid.center(), Vec3::new(1.0, 2.0, 3.0));
    assert_eq!(grid.voxel_size(), 0.5);
    assert_eq!(grid.dims(), UVec3::new(3, 4, 5));
}

#[test]
fn voxel_of_floors_negative_coordinates() {
    // center -3, voxel 2, dims 2: origin = -3 - 1 * 2 = -5, inv = 0.5.
    let grid = VoxelGrid::new(Vec3::splat(-3.0), 2.0, UVec3::splat(2)).unwrap();
    // x: (-4.5 + 5) * 0.5 = 0.25 -> 0; y: (-3 + 5) * 0.5 = 1 -> 1; z: (-1.0001 + 5) * 0.5 = 1.99995 -> 1.
    assert_eq!(grid.voxel_of(Vec3::new(-4.5, -3.0, -1.0001)), Some(UVec3::new(0, 1, 1)));
    // x: (-5.5 + 5) * 0.5 = -0.25: floor gives -1 (outside); truncation would wrongly give 0.
    assert_eq!(grid.voxel_of(Vec3::new(-5.5, -3.0, -3.0)), None);
    // The far face is outside: (-1 + 5) * 0.5 = 2, not < 2.
    assert_eq!(grid.voxel_of(Vec3::new(-3.0, -1.0, -3.0)), None);
    // The near face is inside: (-5 + 5) * 0.5 = 0.
    assert_eq!(grid.voxel_of(Vec3::new(-5.0, -5.0, -5.0)), Some(UVec3::ZERO));
}

#[test]
fn voxel_of_rejects_non_finite_points() {
    let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(4)).unwrap();
    for p in
        [Vec3::new(f32::NAN, 0.0, 0.0), Vec3::new(0.0, f32::INFINITY, 0.0), Vec3::splat(f32::NEG_INFINITY)]
    {
        assert_eq!(grid.voxel_of(p), None, "{p}");
    }
}

#[test]
fn grid_allows_two_to_the_twenty_four_voxels_per_axis() {
    // origin = -0.5 * 2^24 = -2^23, so 0.0 lands in voxel 2^23 on every axis.
    let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(1 << 24)).unwrap();
    assert_eq!(grid.voxel_of(Vec3::ZERO), Some(UVec3::splat(1 << 23)));
    assert_eq!(grid.voxel_of(Vec3::splat(8388607.0)), Some(UVec3::splat((1 << 24) - 1)));
    assert_eq!(grid.voxel_of(Vec3::splat(8388608.0)), None);
}

#[test]
fn bad_voxel_sizes_are_typed_errors() {
    for value in [0.0, -0.0, -1.0, 0.3, 3.0, f32::NAN, f32::INFINITY, 2f32.powi(25), 2f32.powi(-25), 1e-40] {
        let err = VoxelGrid::new(Vec3::ZERO, value, UVec3::ONE).unwrap_err();
        assert!(
            matches!(err, Error::VoxelSize { value: v } if v.to_bits() == value.to_bits()),
            "{value}: {err:?}"
        );
        let msg = err.to_string();
        assert!(msg.contains("power of two") && msg.contains("-24 <= k <= 24"), "{msg}");
        let err = Initializer::new(value).build(&[Vec3::ZERO]).unwrap_err();
        assert!(matches!(err, Error::VoxelSize { .. }), "{value}: {err:?}");
    }
    assert!(VoxelGrid::new(Vec3::ZERO, 2f32.powi(-24), UVec3::ONE).is_ok());
    assert!(VoxelGrid::new(Vec3::ZERO, 2f32.powi(24), UVec3::ONE).is_ok());
    assert!(
        VoxelGrid::new(Vec3::ZERO, 0.75, UVec3::ONE)
            .unwrap_err()
            .to_string()
            .contains("voxel size 0.75 is invalid")
    );
}

#[test]
fn bad_dims_are_typed_errors() {
    for dims in
        [UVec3::new(0, 1, 1), UVec3::new(1, 0, 1), UVec3::new(1, 1, 0), UVec3::new(1, (1 << 24) + 1, 1)]
    {
        let err = VoxelGrid::new(Vec3::ZERO, 1.0, dims).unwrap_err();
        assert_eq!(err, Error::Dims { dims });
        assert!(err.to_string().contains("16777216"), "{err}");
    }
}

#[test]
fn non_finite_center_is_a_typed_error() {
    let center = Vec3::new(0.0, f32::NAN, 0.0);
    let err = VoxelGrid::new(center, 1.0, UVec3::ONE).unwrap_err();
    assert!(matches!(err, Error::NonFiniteCenter { .. }), "{err:?}");
    assert!(err.to_string().contains("NaN"), "{err}");
}

#[test]
fn initializer_bounds_the_finite_vertices_in_a_cube() {
    // lo = (0,0,0), hi = (3,1,2) (the NaN vertex is ignored); center = 0.5 * (lo + hi) =
    // (1.5, 0.5, 1); side = 3; n = ceil(3 / 1) + 2 * 1 = 5.
    let a = [Vec3::ZERO, Vec3::new(3.0, 1.0, 2.0), Vec3::new(f32::NAN, 100.0, 100.0)];
    let grid = Initializer::new(1.0).margin(1).build(&a).unwrap();
    assert_eq!(grid.center(), Vec3::new(1.5, 0.5, 1.0));
    assert_eq!(grid.dims(), UVec3::splat(5));
    assert_eq!(grid.voxel_size(), 1.0);
    // No margin: n = 3. Voxel 2: n = ceil(1.5) = 2.
    assert_eq!(Initializer::new(1.0).build(&a).unwrap().dims(), UVec3::splat(3));
    assert_eq!(Initializer::new(2.0).build(&a).unwrap().dims(), UVec3::splat(2));
    // One vertex: side 0, n = max(0, 1) = 1.
    let one = Initializer::new(0.25).build(&[Vec3::new(-7.0, 2.0, 1.0)]).unwrap();
    assert_eq!((one.center(), one.dims()), (Vec3::new(-7.0, 2.0, 1.0), UVec3::ONE));
}

#[test]
fn contact_half_keeps_the_half_facing_the_direction() {
    // The cube above: center (1.5, 0.5, 1), n = 5, so h = ceil(5 / 2) = 3 and the center moves
    // by 0.5 * 3 * 1 = 1.5 along the dominant axis.
    let a = [Vec3::ZERO, Vec3::new(3.0, 1.0, 2.0)];
    let init = Initializer::new(1.0).margin(1);
    let cases = [
        (Vec3::new(2.0, 1.0, -1.0), Vec3::new(3.0, 0.5, 1.0), UVec3::new(3, 5, 5)),
        // x and y tie: x wins; negative, so the center moves down.
        (Vec3::new(-1.0, 1.0, 0.5), Vec3::new(0.0, 0.5, 1.0), UVec3::new(3, 5, 5)),
        (Vec3::new(0.0, -2.0, 1.0), Vec3::new(1.5, -1.0, 1.0), UVec3::new(5, 3, 5)),
        // y and z tie: y wins.
        (Vec3::new(0.0, 3.0, -3.0), Vec3::new(1.5, 2.0, 1.0), UVec3::new(5, 3, 5)),
        (Vec3::new(0.1, 0.0, -3.0), Vec3::new(1.5, 0.5, -0.5), UVec3::new(5, 5, 3)),
    ];
    for (toward, center, dims) in cases {
        let grid = init.contact_half(toward).build(&a).unwrap();
        assert_eq!((grid.center(), grid.dims()), (center, dims), "toward {toward}");
    }
    // The half-box starts at the cube's center: origin.x = 3 - 0.5 * 3 = 1.5.
    let grid = init.contact_half(Vec3::X).build(&a).unwrap();
    assert_eq!(grid.origin().x, 1.5);
}

#[test]
fn initializer_errors_are_typed() {
    assert_eq!(Initializer::new(1.0).build(&[]), Err(Error::EmptyBody { body: voxcollide::Body::A }));

    let nan = [Vec3::new(f32::NAN, 0.0, 0.0), Vec3::new(0.0, f32::INFINITY, 0.0)];
    let err = Initializer::new(1.0).build(&nan).unwrap_err();
    assert_eq!(err, Error::NoFiniteVertex { len: 2 });
    assert!(err.to_string().contains("2 vertices and none is finite"), "{err}");

    for toward in [Vec3::ZERO, Vec3::new(f32::NAN, 1.0, 0.0), Vec3::new(0.0, f32::INFINITY, 0.0)] {
        let err = Initializer::new(1.0).contact_half(toward).build(&[Vec3::ZERO]).unwrap_err();
        assert!(matches!(err, Error::Toward { .. }), "{toward}: {err:?}");
        assert!(err.to_string().contains("finite and non-zero"), "{err}");
    }

    // side 1e9 in voxels of 2^-24: ~1.7e16 voxels per axis, far over 2^24.
    let err = Initializer::new(2f32.powi(-24)).build(&[Vec3::ZERO, Vec3::new(1e9, 0.0, 0.0)]).unwrap_err();
    assert!(matches!(err, Error::BoundsTooLarge { margin: 0, .. }), "{err:?}");
    // n = 2^24 - 2 + 2 * 1 is the largest allowed; one more margin voxel is too many.
    let a = [Vec3::ZERO, Vec3::new(16777214.0, 0.0, 0.0)];
    assert_eq!(Initializer::new(1.0).margin(1).build(&a).unwrap().dims().x, 1 << 24);
    let err = Initializer::new(1.0).margin(2).build(&a).unwrap_err();
    assert!(matches!(err, Error::BoundsTooLarge { needed: 16777218, .. }), "{err:?}");
    assert!(err.to_string().contains("needs 16777218 voxels"), "{err}");

    // lo + hi = 6e38 overflows f32.
    let err = Initializer::new(1.0).build(&[Vec3::new(3e38, 0.0, 0.0)]).unwrap_err();
    assert!(matches!(err, Error::NonFiniteCenter { .. }), "{err:?}");
}
