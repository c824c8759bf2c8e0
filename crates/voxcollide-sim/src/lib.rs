//! Soft-tissue simulation on the voxcollide collision library: mass-spring bodies with nonlinear
//! springs and their builders, closed triangle surfaces (inside tests, distances), and the scenes
//! of the paper — a cylinder pressed into tissue, an implant inflating under it — stepped on the
//! CPU or entirely on the GPU.
#![doc = include_str!("../README.md")]
#![deny(missing_docs)]

pub mod between; //  a breast from a scan: the tissue between the skin and the chest wall
pub mod bodies; //   builders: box lattices, cylinders, ellipsoidal shells, lattices in surfaces
pub mod body; //     `MassSpring`: the nonlinear mass-spring body and its integrator
pub mod build; //    a scene file's world: bodies from shapes and meshes, physical units
pub mod catalogue; // implant catalogues (docs/design.md §9): the candidates `compare` runs, checked
pub mod contact; //  contacts as one piece: the voxel model's and the surface contact, on the CPU
pub mod cpu; //      `CpuWorld`: a world stepped on the CPU
pub mod geometry; // closed triangle surfaces: winding numbers, distances
pub mod gpu; //      `GpuWorld`: a world stepped on the GPU, and its implicit passes
pub mod integrator; // how bodies move: explicit, implicit (backward Euler), sub-stepping
pub mod material; // materials as energies: springs, Neo-Hookean tetrahedra
pub mod mesh; //     `TriangleMesh`: triangles over a body's vertices
pub mod mesh_io; //  closed surfaces from STL, OBJ and PLY files, checked
pub mod pocket; //   a dissected pocket: the space by the implant drawn shut, as a sealed pocket is
pub mod reference; // the shape as scanned: the unloaded shape a loaded one comes from
pub mod scene; //    `Scene`: the paper's two scenarios, built and scheduled
pub mod scene_file; // scene files (docs/design.md §8): TOML read and checked, errors with file, line, key
pub mod simulation; // `Simulation`: one seam over the CPU and the GPU world
pub mod validation; // the elements against closed forms: a cantilever, a large stretch
pub mod wall; //     a curved chest wall as a floor: heights over its tangent plane, under a placed implant
pub mod world; //    `World`: any number of bodies and contacts, each pair its own voxel model

pub use body::{Embedding, MassSpring, Material, Mode, Spring, StepInputs};
pub use contact::{ContactModel, CpuContacts, SurfaceContact, SurfacePenalty};
pub use cpu::CpuWorld;
pub use gpu::GpuWorld;
pub use integrator::implicit::{Guess, ImplicitSettings, Residual};
pub use integrator::substep::Parts;
pub use integrator::{CpuIntegrator, Integrator};
pub use scene::{Kind, Scene, SceneConfig};
pub use simulation::{Simulation, simulation};
pub use world::{ContactPair, World};
