//! The benchmark workloads of docs/design.md §7, seeded and reproducible, so that every figure (and
//! every example) runs on the same bodies.

use glam::Vec3;

use crate::error::Error;
use crate::grid::VoxelGrid;
use crate::initializer::Initializer;
use crate::params::{Anchor, ContactParams, Direction, Search};

/// The seed every benchmark uses unless told otherwise.
pub const DEFAULT_SEED: u64 = 2013;

/// A pair of bodies to collide, with the grid and params of a workload.
#[derive(Clone, Debug)]
pub struct Workload {
    /// Body A, the indexed body.
    pub a: Vec<Vec3>,
    /// Body B, the probing body.
    pub b: Vec<Vec3>,
    /// `Initializer::new(1.0).margin(1).build(&a)`.
    pub grid: VoxelGrid,
    /// The workload's contact params.
    pub params: ContactParams,
}

/// **lattice(N)**: A is a cubic lattice of `k^3` vertices, `k = round(cbrt(n))` (at least 1),
/// spacing 1, each vertex jittered uniformly within ±0.1 per axis; B is the same lattice shifted
/// by (0.5, 0.5, 0.5) and jittered independently. Params: magnitude 1,
/// `Search::Neighbours { radius: 0.9 }`, `Direction::Pairwise`, `Anchor::Fixed`.
///
/// Vertices are laid out x fastest, then y, then z; A's jitter is drawn first, then B's, from one
/// [`SplitMix64`] stream seeded with `seed`.
///
/// # Errors
/// Only if the lattice is too large for a grid (over `2^24` voxels per axis).
pub fn lattice(n: usize, seed: u64) -> Result<Workload, Error> {
    let k = ((n as f64).cbrt().round() as usize).max(1);
    let mut rng = SplitMix64::new(seed);
    let mut body = |offset: f32| -> Vec<Vec3> {
        let mut out = Vec::with_capacity(k * k * k);
        for z in 0..k {
            for y in 0..k {
                for x in 0..k {
                    let jitter = Vec3::new(rng.jitter(0.1), rng.jitter(0.1), rng.jitter(0.1));
                    out.push(Vec3::new(x as f32, y as f32, z as f32) + Vec3::splat(offset) + jitter);
                }
            }
        }
        out
    };
    let a = body(0.0);
    let b = body(0.5);
    let grid = Initializer::new(1.0).margin(1).build(&a)?;
    let params = ContactParams {
        magnitude: 1.0,
        search: Search::Neighbours { radius: 0.9 },
        direction: Direction::Pairwise,
        anchor: Anchor::Fixed,
    };
    Ok(Workload { a, b, grid, params })
}

/// **paper(N)**: the bodies of [`lattice`] with the paper's own rule, `Search::Voxel`.
///
/// # Errors
/// As [`lattice`].
pub fn paper(n: usize, seed: u64) -> Result<Workload, Error> {
    let mut w = lattice(n, seed)?;
    w.params.search = Search::Voxel;
    Ok(w)
}

/// **shuffled(N)**: the bodies of [`lattice`] with each body's vertices in a seeded random
/// order (a Fisher–Yates shuffle of A, then of B, from one [`SplitMix64`] stream seeded with
/// `seed ^ SHUFFLE_SEED`), as a real mesh's vertices come. The grid is the same (built over
/// the same A); a report is the lattice's, permuted.
///
/// # Errors
/// As [`lattice`].
pub fn shuffled(n: usize, seed: u64) -> Result<Workload, Error> {
    let mut w = lattice(n, seed)?;
    let mut rng = SplitMix64::new(seed ^ SHUFFLE_SEED);
    for body in [&mut w.a, &mut w.b] {
        for i in (1..body.len()).rev() {
            body.swap(i, rng.below(i as u64 + 1) as usize);
        }
    }
    Ok(w)
}

/// Mixed into the seed of [`shuffled`]'s order, so that it is not the jitter's stream.
pub const SHUFFLE_SEED: u64 = 0x0bad_5eed_0f0d_e5e5;

/// **z_fastest(N)**: the bodies of [`lattice`] listed z fastest, then y, then x (the lattice
/// transposed: the order of a mesher that sweeps the other way).
///
/// # Errors
/// As [`lattice`].
pub fn z_fastest(n: usize, seed: u64) -> Result<Workload, Error> {
    let mut w = lattice(n, seed)?;
    let k = ((w.a.len() as f64).cbrt().round() as usize).max(1);
    for body in [&mut w.a, &mut w.b] {
        let xyz = std::mem::take(body);
        body.extend(
            (0..k)
                .flat_map(|x| (0..k).flat_map(move |y| (0..k).map(move |z| (x, y, z))))
                .map(|(x, y, z)| xyz[x + k * (y + k * z)]),
        );
    }
    Ok(w)
}

/// **moving(N)**: the bodies of [`lattice`] stepped [`MOVING_STEPS`] times in a row, A still and
/// B moving by [`MOVING_STEP`] (a twentieth of the spacing along x) from each step to the next.
/// The figure is the mean step; a backend may keep state from step to step (an order, a sort)
/// as long as every step's report equals the reference's for that step's positions. Step `k`'s
/// B is [`Moving::b_at`]`(k)`: the lattice's B at step 0, moved `k` times.
///
/// # Errors
/// As [`lattice`].
pub fn moving(n: usize, seed: u64) -> Result<Moving, Error> {
    Ok(Moving { start: lattice(n, seed)? })
}

/// Steps in a row of [`moving`].
pub const MOVING_STEPS: usize = 20;

/// How far B moves from each step of [`moving`] to the next: a twentieth of the spacing, along x.
pub const MOVING_STEP: Vec3 = Vec3::new(0.05, 0.0, 0.0);

/// The bodies of [`moving`]: its first step's, and B at each later one.
#[derive(Clone, Debug)]
pub struct Moving {
    /// Step 0: [`lattice`]'s bodies, grid and params (the grid stays the one built over A).
    pub start: Workload,
}

impl Moving {
    /// B at step `k` (0 to [`MOVING_STEPS`]` − 1`): the lattice's B moved `k` times by
    /// [`MOVING_STEP`], each coordinate computed once from the start (`b + k·step`, so that
    /// no rounding accumulates and any backend is handed the same bits).
    #[must_use]
    pub fn b_at(&self, k: usize) -> Vec<Vec3> {
        let shift = MOVING_STEP * k as f32;
        self.start.b.iter().map(|p| *p + shift).collect()
    }
}

/// The workloads' random numbers: SplitMix64 (Steele, Lea and Flood, 2014), a 64-bit state
/// stepped by the golden-ratio increment and scrambled. Small and the same on every platform,
/// so a workload is a pure function of its seed; it is not for anything that needs
/// unpredictability.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A stream seeded with `seed`.
    #[must_use]
    pub fn new(seed: u64) -> SplitMix64 {
        SplitMix64(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`, with 24 random bits (every value exact in `f32`).
    pub fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / 16_777_216.0)
    }

    /// Uniform in `[-r, r)`.
    pub fn jitter(&mut self, r: f32) -> f32 {
        r * (2.0 * self.unit() - 1.0)
    }

    /// Uniform in `0..n` (`n > 0`; the modulo bias is below `n / 2^64`).
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lattice_is_reproducible_and_shaped_as_specified() {
        let w = lattice(1000, 7).unwrap();
        assert_eq!((w.a.len(), w.b.len()), (1000, 1000));
        assert_eq!(w.a, lattice(1000, 7).unwrap().a);
        assert_ne!(w.a, lattice(1000, 8).unwrap().a);
        for (i, (a, b)) in w.a.iter().zip(&w.b).enumerate() {
            let ideal = Vec3::new((i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32);
            assert!((*a - ideal).abs().max_element() <= 0.1 + 1e-6, "a[{i}] = {a}");
            assert!((*b - ideal - Vec3::splat(0.5)).abs().max_element() <= 0.1 + 1e-6, "b[{i}] = {b}");
        }
        assert_eq!(w.grid.voxel_size(), 1.0);
        assert_eq!(paper(1000, 7).unwrap().params.search, Search::Voxel);
    }

    #[test]
    fn shuffled_and_z_fastest_hold_the_lattices_vertices_in_other_orders() {
        let w = lattice(1000, 7).unwrap();
        let key = |v: &Vec3| v.to_array().map(f32::to_bits);
        let sorted = |mut v: Vec<Vec3>| {
            v.sort_by_key(key);
            v
        };
        for other in [shuffled(1000, 7).unwrap(), z_fastest(1000, 7).unwrap()] {
            assert_ne!(other.a, w.a);
            assert_eq!(sorted(other.a.clone()), sorted(w.a.clone()));
            assert_eq!(sorted(other.b.clone()), sorted(w.b.clone()));
            assert_eq!(other.grid, w.grid);
        }
        let z = z_fastest(1000, 7).unwrap();
        assert_eq!((z.a[1], z.a[10]), (w.a[100], w.a[10]));
        assert_eq!(shuffled(1000, 7).unwrap().a, shuffled(1000, 7).unwrap().a);
    }
}
