//! The structs shared by Rust and WGSL. Keep in sync with `Params` and `State` in
//! `shaders/common.wgsl`.

use bytemuck::{Pod, Zeroable};

use crate::eliminate::ForceLaw;
use crate::grid::VoxelGrid;
use crate::params::{Anchor, ContactParams, Direction, Search};

/// The step's parameters, a uniform. Keep in sync with `Params` in `shaders/common.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub(crate) struct GpuParams {
    pub center: [f32; 4],
    pub half_extent: [f32; 4],
    pub dims: [u32; 4],
    pub inv: f32,
    pub r2: f32,
    pub magnitude: f32,
    pub scale: f32,
    pub unit: f32,
    pub n_a: u32,
    pub n_b: u32,
    pub slot_mask: u32,
    pub search: u32,
    pub direction: u32,
    pub anchor: u32,
    pub dense: u32,
    /// 0: the paper's constant magnitude; 1: a penalty (the four below, as in `ForceLaw`).
    pub response: u32,
    pub stiffness: f32,
    pub gap: f32,
    pub gap_reach: f32,
    pub max_depth: f32,
    pub _pad: [u32; 3],
}
const _: () = assert!(std::mem::size_of::<GpuParams>() == 128);

impl GpuParams {
    /// Everything but the sizes, computed in f32 exactly as the CPU reference does.
    pub fn new(grid: &VoxelGrid, params: &ContactParams, law: &ForceLaw) -> GpuParams {
        let p = law.penalty;
        let half = grid.voxel_size() * 0.5;
        let dims = grid.dims();
        let c = grid.center();
        let m = params.magnitude;
        let (search, r2) = match params.search {
            Search::Voxel => (0, 0.0),
            Search::Neighbours { radius } => (1, radius * radius),
        };
        GpuParams {
            center: [c.x, c.y, c.z, 0.0],
            half_extent: [half * dims.x as f32, half * dims.y as f32, half * dims.z as f32, 0.0],
            dims: [dims.x, dims.y, dims.z, 0],
            inv: grid.inv_voxel_size(),
            r2,
            magnitude: m,
            scale: 65536.0 / m,
            unit: m / 65536.0,
            n_a: 0,
            n_b: 0,
            slot_mask: 0,
            search,
            direction: match params.direction {
                Direction::Pairwise => 0,
                Direction::PlaneNormal => 1,
            },
            anchor: match params.anchor {
                Anchor::Fixed => 0,
                Anchor::FollowA => 1,
            },
            dense: 0,
            response: u32::from(p.is_some()),
            stiffness: p.map_or(0.0, |p| p.stiffness),
            gap: p.map_or(0.0, |p| p.gap),
            gap_reach: p.map_or(0.0, |p| p.gap_reach),
            max_depth: p.map_or(0.0, |p| p.max_depth),
            _pad: [0; 3],
        }
    }
}

/// The step's state on the device. Keep in sync with `State` in `shaders/common.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub(crate) struct GpuState {
    pub center: [f32; 4],
    pub origin: [f32; 4],
    pub min_key: [u32; 4],
    pub max_key: [u32; 4],
    pub binned: u32,
    pub colliding: u32,
    pub overflow: u32,
    pub status: u32,
    pub truncated: u32,
    /// B vertices in the grid, sorted by A's slots for the probe.
    pub binned_b: u32,
    pub _pad: [u32; 2],
}
const _: () = assert!(std::mem::size_of::<GpuState>() == 96);

impl GpuState {
    /// The part of the state cleared at the start of every step: bounds and counters.
    pub const CLEARED: std::ops::Range<u64> = 32..96;
    /// Its size in bytes.
    pub const SIZE: u64 = 96;
    /// `status` bit: the FollowA center was not finite.
    pub const NON_FINITE_CENTER: u32 = 1;

    /// Whether the step ended in an error (a non-finite center, a cut-short walk or a force
    /// overflow), so that its forces are not a report.
    pub fn failed(&self) -> bool {
        self.status & Self::NON_FINITE_CENTER != 0 || self.truncated != 0 || self.overflow != 0
    }
}
