//! The paper's `CollisionDetector`: bins body A into the voxel data, then finds which B
//! vertices collide and with which A vertices (docs/design.md §2, *Search* and *Partner choice*).

use std::cmp::Ordering;

use glam::{UVec3, Vec3};

use crate::grid::VoxelGrid;
use crate::math::dist2;
use crate::params::Search;
use crate::voxel_data::VoxelData;

/// One collision: B vertex `b` against its partner in A.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// The colliding B vertex.
    pub b: u32,
    /// Its partner: the nearest candidate A vertex (ties: the smaller index).
    pub partner: u32,
    /// The three nearest plane candidates, nearest first, when the detector was asked for them
    /// and found at least three; `None` otherwise.
    pub plane: Option<[u32; 3]>,
}

/// What one detection found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Detection {
    /// The contacts, ascending by `b`; a B vertex appears at most once.
    pub contacts: Vec<Contact>,
    /// A vertices put into voxel lists.
    pub binned_a: u32,
    /// A vertices discarded (not finite, or outside the grid).
    pub discarded_a: u32,
}

/// Finds the contacts between body A and body B in a grid.
pub trait CollisionDetector {
    /// Bins `a` into `grid` and finds the contacts of every vertex of `b`.
    fn detect(&mut self, grid: &VoxelGrid, a: &[Vec3], b: &[Vec3]) -> Detection;
}

/// The reference detector: the voxel lists of [`VoxelData`] searched one B vertex at a time.
#[derive(Clone, Debug)]
pub struct VoxelDetector {
    search: Search,
    with_plane: bool,
    data: VoxelData,
}

impl VoxelDetector {
    /// A detector for `search`. With `with_plane`, each contact also carries the three nearest
    /// plane candidates: under [`Search::Voxel`] taken from the whole 3×3×3 block, under
    /// [`Search::Neighbours`] from the search's own candidates.
    #[must_use]
    pub fn new(search: Search, with_plane: bool) -> VoxelDetector {
        VoxelDetector { search, with_plane, data: VoxelData::new() }
    }

    /// The voxel data as the last detection left it.
    #[must_use]
    pub fn voxel_data(&self) -> &VoxelData {
        &self.data
    }

    /// The candidates `(d2, index)` of `p` in voxel `v`.
    fn voxel_candidates(&self, a: &[Vec3], p: Vec3, v: UVec3) -> Vec<(f32, u32)> {
        self.data.vertices_in(v).map(|i| (dist2(p, a[i as usize]), i)).collect()
    }

    /// The candidates `(d2, index)` of `p` in the 3×3×3 block around `v`, clipped to the grid,
    /// with `d2 < r2` (pass `f32::INFINITY` for all of them).
    fn block_candidates(&self, grid: &VoxelGrid, a: &[Vec3], p: Vec3, v: UVec3, r2: f32) -> Vec<(f32, u32)> {
        let lo = v.saturating_sub(UVec3::ONE);
        let hi = (v + UVec3::ONE).min(grid.dims() - UVec3::ONE);
        let mut out = Vec::new();
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    for i in self.data.vertices_in(UVec3::new(x, y, z)) {
                        let d2 = dist2(p, a[i as usize]);
                        if d2 < r2 {
                            out.push((d2, i));
                        }
                    }
                }
            }
        }
        out
    }
}

/// Candidate order: by `d2`, ties by the smaller index.
fn by_distance(x: &(f32, u32), y: &(f32, u32)) -> Ordering {
    x.0.total_cmp(&y.0).then(x.1.cmp(&y.1))
}

/// The first three in candidate order, if there are three.
fn three_nearest(mut candidates: Vec<(f32, u32)>) -> Option<[u32; 3]> {
    candidates.sort_by(by_distance);
    match candidates[..] {
        [c0, c1, c2, ..] => Some([c0.1, c1.1, c2.1]),
        _ => None,
    }
}

impl CollisionDetector for VoxelDetector {
    fn detect(&mut self, grid: &VoxelGrid, a: &[Vec3], b: &[Vec3]) -> Detection {
        let binned_a = self.data.bin(grid, a);
        let mut contacts = Vec::new();
        for (j, &p) in b.iter().enumerate() {
            let Some(v) = grid.voxel_of(p) else { continue };
            let (candidates, plane) = match self.search {
                Search::Voxel => {
                    let plane = self
                        .with_plane
                        .then(|| three_nearest(self.block_candidates(grid, a, p, v, f32::INFINITY)))
                        .flatten();
                    (self.voxel_candidates(a, p, v), plane)
                }
                Search::Neighbours { radius } => {
                    let candidates = self.block_candidates(grid, a, p, v, radius * radius);
                    let plane = self.with_plane.then(|| three_nearest(candidates.clone())).flatten();
                    (candidates, plane)
                }
            };
            let Some(&(_, partner)) = candidates.iter().min_by(|x, y| by_distance(x, y)) else {
                continue;
            };
            contacts.push(Contact { b: j as u32, partner, plane });
        }
        Detection { contacts, binned_a, discarded_a: a.len() as u32 - binned_a }
    }
}
