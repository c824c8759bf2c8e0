//! The contact responses (`Response`): the paper's constant magnitude, and the penalty that grows
//! with depth, by hand-computed cases, on every backend.

mod common;

use voxcollide::glam::Vec3;
use voxcollide::*;

fn params(direction: Direction, magnitude: f32) -> ContactParams {
    ContactParams { magnitude, search: Search::Neighbours { radius: 1.0 }, direction, anchor: Anchor::Fixed }
}

/// Steps `a`, `b` on the reference, the parallel backend and (where there is one) the GPU, checks
/// that they agree to the bit, and returns the reference's report.
fn step_all(a: &[Vec3], b: &[Vec3], params: ContactParams, response: Response) -> ContactReport {
    let grid = Initializer::new(1.0).margin(2).build(a).unwrap();
    let reference =
        CpuCollision::new(grid, params).unwrap().with_response(response).unwrap().step(a, b).unwrap();
    let parallel =
        ParallelCpuCollision::new(grid, params).unwrap().with_response(response).unwrap().step(a, b).unwrap();
    assert_eq!(reference, parallel, "parallel backend");
    if let Some(ctx) = common::gpu() {
        let mut gpu = GpuCollision::new(&ctx, grid, params).unwrap().with_response(response).unwrap();
        assert_eq!(gpu.response(), response);
        let report = gpu.step(a, b).unwrap();
        assert_eq!(report.colliding_b, reference.colliding_b, "GPU colliding");
        for (g, r) in report.force_b.iter().zip(&reference.force_b) {
            assert!((*g - *r).abs().max_element() <= 1e-5 * params.magnitude, "GPU force_b {g} vs {r}");
        }
    }
    reference
}

/// A triangle of A in the plane z = 0 (outward +z from the grid centre below it) and one more A
/// vertex deep below, so that the grid centre lies under the plane.
fn floor_a() -> Vec<Vec3> {
    vec![
        Vec3::new(-0.5, -0.4, 0.0),
        Vec3::new(0.5, -0.4, 0.0),
        Vec3::new(0.0, 0.6, 0.0),
        Vec3::new(0.0, 0.0, -3.0),
    ]
}

#[test]
fn the_penalty_grows_with_depth_behind_the_plane() {
    let a = floor_a();
    let centroid_z = 0.0;
    let penalty = Response::Penalty { stiffness: 8.0, gap: 0.0 };
    // b 0.125 below the plane at the centroid: depth 0.125, force 1 along +z.
    let depth = 0.125;
    let b = [Vec3::new(0.0, -0.4 / 3.0 + 0.6 / 3.0, centroid_z - depth)];
    let r = step_all(&a, &b, params(Direction::PlaneNormal, 100.0), penalty);
    assert_eq!(r.colliding_b, vec![0]);
    assert!((r.force_b[0] - Vec3::new(0.0, 0.0, 8.0 * depth)).length() < 1e-5, "{}", r.force_b[0]);
    // Newton's third law, in three shares.
    assert!((r.force_a[0] + r.force_a[1] + r.force_a[2] + r.force_b[0]).length() < 1e-2);
    // Twice as deep, twice the force.
    let b2 = [b[0] - Vec3::Z * depth];
    let r2 = step_all(&a, &b2, params(Direction::PlaneNormal, 100.0), penalty);
    assert!((r2.force_b[0].z - 2.0 * r.force_b[0].z).abs() < 1e-5);
    // In front of the plane (but within the radius): it collides, with no force.
    let front = [b[0] + Vec3::Z * 0.5];
    let r3 = step_all(&a, &front, params(Direction::PlaneNormal, 100.0), penalty);
    assert_eq!(r3.colliding_b, vec![0]);
    assert_eq!(r3.force_b[0], Vec3::ZERO);
    // A gap moves the plane out: 0.375 in front with a gap of 0.75 is 0.375 deep.
    let gapped = Response::Penalty { stiffness: 8.0, gap: 0.75 };
    let r4 = step_all(&a, &front, params(Direction::PlaneNormal, 100.0), gapped);
    assert!((r4.force_b[0].z - 3.0).abs() < 1e-5, "{}", r4.force_b[0]);
}

#[test]
fn the_penalty_never_pushes_harder_than_the_magnitude() {
    let a = floor_a();
    let b = [Vec3::new(0.0, 0.0, -0.5)];
    let r =
        step_all(&a, &b, params(Direction::PlaneNormal, 2.0), Response::Penalty { stiffness: 1e6, gap: 0.0 });
    assert!((r.force_b[0].length() - 2.0).abs() < 1e-5, "{}", r.force_b[0]);
}

#[test]
fn a_pairwise_penalty_grows_inside_the_sphere_of_gap_and_radius() {
    let a = [Vec3::ZERO, Vec3::new(3.0, 0.0, 0.0)];
    // 0.25 from its partner, radius 1, gap 0.5: depth 1.25, force 2.5 along +y.
    let b = [Vec3::new(3.0, 0.25, 0.0)];
    let r =
        step_all(&a, &b, params(Direction::Pairwise, 10.0), Response::Penalty { stiffness: 2.0, gap: 0.5 });
    assert!((r.force_b[0] - Vec3::new(0.0, 2.5, 0.0)).length() < 1e-6, "{}", r.force_b[0]);
    assert!((r.force_a[1] + r.force_b[0]).length() < 1e-3);
}

#[test]
fn the_constant_response_is_the_papers_to_the_bit() {
    let (a, b, _, grid) = common::bodies(7, 3000);
    for params in common::all_params(0.75, 0.6) {
        let plain = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
        let constant = CpuCollision::new(grid, params)
            .unwrap()
            .with_response(Response::Constant)
            .unwrap()
            .step(&a, &b)
            .unwrap();
        assert_eq!(plain, constant, "{params:?}");
        let parallel = ParallelCpuCollision::new(grid, params)
            .unwrap()
            .with_response(Response::Constant)
            .unwrap()
            .step(&a, &b)
            .unwrap();
        assert_eq!(plain, parallel, "{params:?}");
    }
}

#[test]
fn bad_penalties_are_refused_by_name() {
    let a = floor_a();
    let grid = Initializer::new(1.0).margin(2).build(&a).unwrap();
    let p = params(Direction::PlaneNormal, 1.0);
    for (stiffness, gap, what) in [
        (0.0, 0.0, "stiffness"),
        (-1.0, 0.0, "stiffness"),
        (f32::NAN, 0.0, "stiffness"),
        (f32::INFINITY, 0.0, "stiffness"),
        (1e-40, 0.0, "stiffness"),
        (1e-38, 0.0, "stiffness"), // magnitude / stiffness leaves f32
        (1.0, -0.1, "gap"),
        (1.0, 1.5, "gap"),
        (1.0, f32::NAN, "gap"),
    ] {
        let response = Response::Penalty { stiffness, gap };
        let err = CpuCollision::new(grid, p).unwrap().with_response(response).err();
        assert!(matches!(err, Some(Error::Response { what: w, .. }) if w == what), "{response:?}: {err:?}");
        let err = ParallelCpuCollision::new(grid, p).unwrap().with_response(response).err();
        assert!(matches!(err, Some(Error::Response { .. })), "{response:?}: {err:?}");
    }
}
