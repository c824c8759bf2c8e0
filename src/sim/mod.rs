//! Soft-tissue simulation for the paper's scenarios: mass-spring bodies with nonlinear springs,
//! their builders, and the scenes that press a cylinder into tissue or inflate an implant under
//! it, on the CPU or entirely on the GPU.

pub mod bodies;
pub mod body;

pub use body::{MassSpring, Material, Mode, Spring, StepInputs};
pub mod scene;

pub use scene::{Kind, Scene, SceneConfig};
pub mod cpu;
pub mod gpu;

pub use cpu::CpuSim;
pub use gpu::GpuSim;
