//! Helpers shared by the GPU tests: an adapter or a skip, seeded bodies, and report comparison.
#![allow(dead_code)]

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use voxcollide::glam::Vec3;
use voxcollide::*;

mod adapter;
#[allow(unused_imports)]
pub use adapter::{gpu, gpu_required};

/// All eight search × direction × anchor combinations.
pub fn all_params(magnitude: f32, radius: f32) -> Vec<ContactParams> {
    let mut out = Vec::new();
    for search in [Search::Voxel, Search::Neighbours { radius }] {
        for direction in [Direction::Pairwise, Direction::PlaneNormal] {
            for anchor in [Anchor::Fixed, Anchor::FollowA] {
                out.push(ContactParams { magnitude, search, direction, anchor });
            }
        }
    }
    out
}

/// Seeded overlapping bodies of about `n` vertices each, about two vertices per voxel, with a
/// few non-finite and coincident vertices, and a grid built over (most of) A.
pub fn bodies(seed: u64, n: usize) -> (Vec<Vec3>, Vec<Vec3>, f32, VoxelGrid) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let voxel = [0.5f32, 1.0, 2.0][(seed % 3) as usize];
    let side = voxel * ((n as f32 / 2.0).cbrt()).max(1.0);
    let mut point = |lo: f32, hi: f32| {
        Vec3::new(rng.random_range(lo..hi), rng.random_range(lo..hi), rng.random_range(lo..hi))
            - Vec3::splat(7.0)
    };
    let mut a: Vec<Vec3> = (0..n).map(|_| point(0.0, side)).collect();
    let mut b: Vec<Vec3> = (0..n).map(|_| point(-0.1 * side, 1.1 * side)).collect();
    let grid = Initializer::new(voxel).build(&a[..(n * 9 / 10).max(1)]).unwrap();
    if n >= 8 {
        a[1] = Vec3::NAN;
        b[2] = Vec3::new(0.0, f32::INFINITY, 0.0);
        b[3] = a[4];
        b[5] = a[6];
    }
    (a, b, voxel, grid)
}

/// Compares two reports: `colliding_b`, counts and center exactly, forces within `tolerance`;
/// returns the number of force components that differ in their bits.
pub fn compare(what: &str, expected: &ContactReport, actual: &ContactReport, tolerance: f32) -> usize {
    assert_eq!(expected.colliding_b.len(), actual.colliding_b.len(), "{what}: colliding count");
    if let Some(k) =
        (0..expected.colliding_b.len()).find(|&k| expected.colliding_b[k] != actual.colliding_b[k])
    {
        panic!("{what}: colliding_b[{k}] {} != {}", expected.colliding_b[k], actual.colliding_b[k]);
    }
    assert_eq!(
        (expected.binned_a, expected.discarded_a),
        (actual.binned_a, actual.discarded_a),
        "{what}: binned"
    );
    assert_eq!(expected.grid_center, actual.grid_center, "{what}: grid center");
    let mut inexact = 0;
    for (name, e, g) in
        [("force_a", &expected.force_a, &actual.force_a), ("force_b", &expected.force_b, &actual.force_b)]
    {
        assert_eq!(e.len(), g.len(), "{what}: {name} length");
        for i in 0..e.len() {
            let d = (e[i] - g[i]).abs().max_element();
            assert!(
                d <= tolerance,
                "{what}: {name}[{i}] cpu {} gpu {} differ by {d} > {tolerance}",
                e[i],
                g[i]
            );
            inexact += (0..3).filter(|&k| e[i][k].to_bits() != g[i][k].to_bits()).count();
        }
    }
    inexact
}

/// Pairs that test the radius to the last bit: B vertices on a jittered lattice `spacing` apart,
/// and for each an A vertex in a random direction at `radius` × (1 ± up to 1e-5), so that many
/// candidates lie within rounding of the radius, in every direction across voxel faces and
/// edges; the grid is built over A with a margin of one voxel. A spacing of one voxel gives a
/// dense voxel table, a wider one a hashed table.
pub fn radius_shell(
    seed: u64,
    pairs: usize,
    voxel: f32,
    radius: f32,
    spacing: f32,
) -> (Vec<Vec3>, Vec<Vec3>, VoxelGrid) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let side = (pairs as f32).cbrt().ceil() as usize;
    let mut a = Vec::with_capacity(pairs);
    let mut b = Vec::with_capacity(pairs);
    for k in 0..pairs {
        let cell = Vec3::new((k % side) as f32, (k / side % side) as f32, (k / side / side) as f32);
        let p = cell * spacing * voxel
            + Vec3::new(
                rng.random_range(0.0..voxel),
                rng.random_range(0.0..voxel),
                rng.random_range(0.0..voxel),
            );
        let dir = loop {
            let d = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if d.length_squared() > 0.01 && d.length_squared() <= 1.0 {
                break d.normalize();
            }
        };
        let stretch = 1.0 + rng.random_range(-1e-5..1e-5f32);
        b.push(p);
        a.push(p + dir * (radius * stretch));
    }
    let grid = Initializer::new(voxel).margin(1).build(&a).unwrap();
    (a, b, grid)
}

/// One case of [`radius_shell_cases`].
pub struct ShellCase {
    pub what: String,
    pub a: Vec<Vec3>,
    pub b: Vec<Vec3>,
    pub grid: VoxelGrid,
    pub params: ContactParams,
    /// Whether the grid has at most 4 voxels per A vertex (a dense voxel table).
    pub dense: bool,
}

/// [`radius_shell`] pairs (30k) under the neighbour search for three voxel sizes, dense and
/// hashed tables, radii of 0.9, 1 and 0.31 voxel, both directions: the cases that catch a
/// candidate lost to pruning.
pub fn radius_shell_cases() -> Vec<ShellCase> {
    let mut out = Vec::new();
    for (seed, voxel, spacing, dense) in
        [(1u64, 1.0f32, 1.0f32, true), (2, 0.5, 3.0, false), (3, 2.0, 1.0, true)]
    {
        for radius in [0.9 * voxel, voxel, 0.31 * voxel] {
            let (a, b, grid) = radius_shell(seed, 30_000, voxel, radius, spacing);
            for direction in [Direction::Pairwise, Direction::PlaneNormal] {
                let params = ContactParams {
                    magnitude: 1.0,
                    search: Search::Neighbours { radius },
                    direction,
                    anchor: Anchor::Fixed,
                };
                let what = format!("seed {seed} radius {radius} {direction:?}");
                out.push(ShellCase { what, a: a.clone(), b: b.clone(), grid, params, dense });
            }
        }
    }
    out
}
