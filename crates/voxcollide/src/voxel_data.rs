//! The paper's `VoxelData`: a sparse voxel hash whose slots hold the heads of per-voxel lists of
//! body-A vertex indices, linked through a `next` array indexed by vertex.
//!
//! Memory is `O(|A|)` whatever the grid's dims: only voxels that hold a vertex exist, as list
//! entries. Several voxels may share a slot (aliasing); a walk resolves it exactly by keeping only
//! the vertices whose own voxel is the one asked for.

use glam::{UVec3, Vec3};

use crate::grid::VoxelGrid;

/// Marks the end of a list, and a discarded vertex.
pub const EMPTY: u32 = u32::MAX;

/// The slot-independent hash of a voxel: a scrambled hash of its row `(y, z)` plus `x`, so that
/// the voxels of a row land in consecutive slots. Which slot a voxel lands in only affects
/// speed, never a result (walks check every vertex's own voxel); keeping rows contiguous makes a
/// 3×3×3 walk touch 9 runs of adjacent slots instead of 27 scattered ones, and neighbouring B
/// vertices reuse them (see `docs/performance-notes.md`). Keep in sync with `voxel_hash` in
/// `shaders/common.wgsl`.
#[must_use]
pub fn voxel_hash(v: UVec3) -> u32 {
    // Large odd multipliers (golden ratio, murmur3's finaliser) spread y and z across the word;
    // the xor-shift folds the high bits into the masked low ones.
    let h = v.y.wrapping_mul(0x9e37_79b1) ^ v.z.wrapping_mul(0x85eb_ca77);
    (h ^ (h >> 16)).wrapping_add(v.x)
}

/// The voxels of a grid of `dims`, exactly: up to `2^72` for dims of `2^24`, so the product is
/// taken in `u128` (in `u64` a grid of `2^22` per axis has `2^66` voxels, which wraps to 0).
#[must_use]
pub fn voxel_count(dims: UVec3) -> u128 {
    u128::from(dims.x) * u128::from(dims.y) * u128::from(dims.z)
}

/// Largest number of slots a voxel table may have: a slot is a `u32`, and the table's prefix
/// sum needs one entry more than the slots.
pub const MAX_SLOTS: u32 = 1 << 31;

/// The slots of a dense voxel table — one slot per voxel, at its linear index
/// `x + dims.x * (y + dims.y * z)` — for `dims` and `n_a` vertices of A, when the parallel and
/// GPU backends use one: while the grid has at most 4 voxels per A vertex, so memory stays
/// `O(|A|)`, and the linear index fits a slot. `None`: the table is hashed.
///
/// One decision for both backends, made in exact arithmetic: no product of dims wraps.
#[must_use]
pub fn dense_slots(dims: UVec3, n_a: usize) -> Option<u32> {
    let voxels = voxel_count(dims);
    (voxels <= 4 * n_a as u128 && voxels <= u128::from(MAX_SLOTS)).then_some(voxels as u32)
}

/// The slots of a hashed voxel table for `n_a` vertices of A: `per_vertex * n_a` rounded up to
/// a power of two, at least 4 (a block row, 3 slots, then never meets itself when it wraps
/// around the table's end) and at most [`MAX_SLOTS`] (the hash is masked to it; aliasing only
/// lengthens a walk).
#[must_use]
pub fn hashed_slots(n_a: usize, per_vertex: usize) -> u32 {
    let wanted = n_a.saturating_mul(per_vertex).clamp(4, MAX_SLOTS as usize);
    wanted.next_power_of_two() as u32
}

/// Per-voxel lists of body-A vertices in a sparse hash, rebuilt by [`bin`](Self::bin) every step.
#[derive(Clone, Debug, Default)]
pub struct VoxelData {
    /// Per slot: the most recently binned vertex of a voxel hashed there, or [`EMPTY`].
    head: Vec<u32>,
    /// Per A vertex: the next vertex of the same slot, or [`EMPTY`].
    next: Vec<u32>,
    /// Per A vertex: its own voxel, valid where `inside[i]`.
    voxel: Vec<UVec3>,
    inside: Vec<bool>,
    binned: u32,
}

impl VoxelData {
    /// Empty voxel data; buffers grow on the first [`bin`](Self::bin) and are reused after.
    #[must_use]
    pub fn new() -> VoxelData {
        VoxelData::default()
    }

    /// Rebuilds the lists for the vertices of `a` in `grid`: each vertex whose voxel is inside
    /// the grid is pushed onto its voxel's list (`next[i] = head[slot]; head[slot] = i`, the
    /// sequential form of the GPU's `atomicExchange`); the others are discarded.
    /// Returns the number binned.
    pub fn bin(&mut self, grid: &VoxelGrid, a: &[Vec3]) -> u32 {
        let slots = a.len().max(1).next_power_of_two();
        self.head.clear();
        self.head.resize(slots, EMPTY);
        self.next.clear();
        self.next.resize(a.len(), EMPTY);
        self.voxel.clear();
        self.voxel.resize(a.len(), UVec3::ZERO);
        self.inside.clear();
        self.inside.resize(a.len(), false);
        self.binned = 0;
        for (i, &p) in a.iter().enumerate() {
            let Some(v) = grid.voxel_of(p) else { continue };
            let slot = self.slot(v);
            self.voxel[i] = v;
            self.inside[i] = true;
            self.next[i] = self.head[slot];
            self.head[slot] = i as u32;
            self.binned += 1;
        }
        self.binned
    }

    /// How many A vertices the last [`bin`](Self::bin) put into lists.
    #[must_use]
    pub fn binned(&self) -> u32 {
        self.binned
    }

    /// The number of hash slots: the smallest power of two `>= |A|`, so memory follows the
    /// vertex count and never the grid's dims.
    #[must_use]
    pub fn slot_count(&self) -> usize {
        self.head.len()
    }

    /// The voxel of A vertex `i` if it was binned.
    #[must_use]
    pub fn voxel_of_vertex(&self, i: u32) -> Option<UVec3> {
        let i = i as usize;
        self.inside.get(i).copied().unwrap_or(false).then(|| self.voxel[i])
    }

    /// The A vertices binned in voxel `v`, in list order (most recently binned first).
    pub fn vertices_in(&self, v: UVec3) -> impl Iterator<Item = u32> + '_ {
        let start = if self.head.is_empty() { EMPTY } else { self.head[self.slot(v)] };
        std::iter::successors((start != EMPTY).then_some(start), |&i| {
            let n = self.next[i as usize];
            (n != EMPTY).then_some(n)
        })
        .filter(move |&i| self.voxel[i as usize] == v)
    }

    fn slot(&self, v: UVec3) -> usize {
        (voxel_hash(v) as usize) & (self.head.len() - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aliased_voxels_are_told_apart() {
        // One slot for two vertices in two different voxels: both lists share the slot, and a
        // walk must return only the vertex of the voxel asked for.
        let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(8)).unwrap();
        let a = [Vec3::new(-3.5, -3.5, -3.5)];
        let mut data = VoxelData::new();
        data.bin(&grid, &a);
        assert_eq!(data.slot_count(), 1);
        assert_eq!(data.vertices_in(UVec3::ZERO).collect::<Vec<_>>(), vec![0]);
        assert_eq!(data.vertices_in(UVec3::new(1, 0, 0)).count(), 0);

        let a = [Vec3::new(-3.5, -3.5, -3.5), Vec3::new(3.5, 3.5, 3.5), Vec3::new(-3.4, -3.4, -3.4)];
        data.bin(&grid, &a);
        assert_eq!(data.slot_count(), 4);
        let mut in0: Vec<u32> = data.vertices_in(UVec3::ZERO).collect();
        in0.sort_unstable();
        assert_eq!(in0, vec![0, 2]);
        assert_eq!(data.vertices_in(UVec3::splat(7)).collect::<Vec<_>>(), vec![1]);
    }

    #[test]
    fn memory_follows_vertices_not_dims() {
        let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(1 << 24)).unwrap();
        let a: Vec<Vec3> = (0..100).map(|i| Vec3::splat(i as f32 * 1000.0)).collect();
        let mut data = VoxelData::new();
        assert_eq!(data.bin(&grid, &a), 100);
        assert_eq!(data.slot_count(), 128);
        for (i, &p) in a.iter().enumerate() {
            let v = grid.voxel_of(p).unwrap();
            assert!(data.vertices_in(v).any(|j| j == i as u32));
        }
    }
}
