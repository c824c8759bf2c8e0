//! Collision detection and elimination between soft tissue and foreign bodies with the paper's
//! modified voxel model.
#![doc = include_str!("../README.md")]
#![deny(missing_docs)]

// The paper's architecture (docs/design.md §1, its Fig. 4), one module a box:
pub mod collision; //    `Collision`: the facade trait every backend implements
pub mod cpu; //          `CpuCollision`: the reference backend
pub mod detect; //       `CollisionDetector`: binning and search
pub mod eliminate; //    `CollisionEliminator`: contacts into penalty forces
pub mod gpu; //          `GpuCollision`, `GpuContext`: the wgpu backend
pub mod grid; //         the voxel grid and voxel indexing
pub mod initializer; //  `Initializer`: the grid around body A
pub mod voxel_data; //   `VoxelData`: the sparse voxel hash of per-voxel vertex lists

// Supporting pieces.
pub mod error;
pub mod fixed_point;
pub mod math;
#[cfg(feature = "parallel")]
pub mod parallel; //     `ParallelCpuCollision`: the multi-threaded CPU backend (rayon)
pub mod params;
pub mod report;
pub mod workload; //     the benchmark workloads of docs/design.md §7

pub use collision::Collision;
pub use cpu::CpuCollision;
pub use error::{Body, Error};
pub use gpu::{GpuCollision, GpuContext};
pub use grid::VoxelGrid;
pub use initializer::Initializer;
#[cfg(feature = "parallel")]
pub use parallel::ParallelCpuCollision;
pub use params::{Anchor, ContactParams, Direction, Response, Search};
pub use report::ContactReport;

pub use glam;
pub use wgpu;
