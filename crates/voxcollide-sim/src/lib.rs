//! Soft-tissue simulation on the voxcollide collision library: mass-spring bodies with nonlinear
//! springs and their builders, closed triangle surfaces (inside tests, distances), and the scenes
//! of the paper — a cylinder pressed into tissue, an implant inflating under it — stepped on the
//! CPU or entirely on the GPU.
#![doc = include_str!("../README.md")]
#![deny(missing_docs)]

pub mod bodies; //   builders: box lattices, cylinders, ellipsoidal shells, lattices in surfaces
pub mod body; //     `MassSpring`: the nonlinear mass-spring body and its integrator
pub mod build; //    a scene file's world: bodies from shapes and meshes, physical units
pub mod catalogue; // implant catalogues (DESIGN §9): the candidates `compare` runs, checked
pub mod contact; //  contacts measured to the partner's surface, both sides (the default response)
pub mod cpu; //      `CpuSim`: a scene stepped on the CPU
pub mod fem; //      finite elements: stable Neo-Hookean tetrahedra (DESIGN §12)
pub mod geometry; // closed triangle surfaces: winding numbers, distances
pub mod gpu; //      `GpuSim`: a scene stepped on the GPU, no per-step readback
pub mod gpu_implicit; // the implicit integrator's WGSL passes, for `GpuWorld`
pub mod implicit; // backward Euler, matrix-free conjugate gradient (DESIGN §12)
pub mod mesh; //     `TriangleMesh`: triangles over a body's vertices
pub mod mesh_io; //  closed surfaces from STL, OBJ and PLY files, checked
pub mod scene; //    `Scene`: the paper's two scenarios, built and scheduled
pub mod scene_file; // scene files (DESIGN §8): TOML read and checked, errors with file, line, key
pub mod validation; // the elements against closed forms: a cantilever, a large stretch
pub mod world; //    `World`: any number of bodies and contacts, each pair its own voxel model

pub use body::{Embedding, MassSpring, Material, Mode, Spring, StepInputs};
pub use contact::{SurfaceContact, SurfacePenalty};
pub use cpu::{CpuSim, CpuWorld, Parts};
pub use gpu::{GpuSim, GpuWorld};
pub use implicit::{Guess, ImplicitSettings, Residual};
pub use scene::{Kind, Scene, SceneConfig};
pub use world::{ContactPair, Integrator, World};
