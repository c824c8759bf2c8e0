//! How bodies move from one step to the next: the integrators, each a piece in a file of its
//! own, behind one call.
//!
//! - [`explicit`]: the paper's semi-implicit (symplectic) Euler, its step within the stability
//!   bound;
//! - [`implicit`]: backward Euler, linearised once per step and solved by a preconditioned
//!   conjugate gradient, its step chosen for accuracy;
//! - [`substep`]: what both worlds keep around an implicit step: a step too far taken in
//!   parts, and the step grown towards rest.
//!
//! A world on the CPU ([`crate::CpuWorld`]) sums each body's forces (its material's, its
//! contacts', a fill's pressure) into [`Loads`] and hands them to a [`CpuIntegrator`]; which
//! one is the scene's [`Integrator`]. The GPU world's twins are its `integrate` pass
//! (`shaders/integrate.wgsl`) and [`crate::gpu::implicit`].
//!
//! A new integrator is a new file here that implements [`CpuIntegrator`], and a variant of
//! [`Integrator`] that names it.

pub mod explicit;
pub mod implicit;
pub mod substep;

use glam::Vec3;

use crate::body::{MassSpring, StepInputs};
use crate::contact::ContactPair;
use crate::contact::CpuContacts;
use implicit::{ImplicitSettings, Residual};
use voxcollide::report::ContactReport;

/// How a world's bodies move from one step to the next (docs/design.md §12).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Integrator {
    /// The paper's semi-implicit (symplectic) Euler, its step within the stability bound
    /// ([`explicit`], [`MassSpring::integrate`]), bit for bit on the CPU and the GPU.
    #[default]
    Explicit,
    /// Backward Euler, linearised per step and solved by conjugate gradient
    /// ([`implicit`], [`MassSpring::integrate_implicit`]): a step chosen for accuracy, not stability. The CPU
    /// steps it, and [`crate::GpuWorld`] in WGSL ([`crate::gpu::implicit`]) for spring lattices
    /// whose contacts are the voxel model's.
    Implicit(ImplicitSettings),
}

/// One step's loads on every body of a world, as an integrator takes them (one entry per body).
pub struct Loads<'a> {
    /// Each body's inputs (time step, drive, pressure, floor).
    pub inputs: &'a [StepInputs],
    /// Each body's net force: its material's, its contacts' and its fill's.
    pub forces: &'a [Vec<Vec3>],
    /// Each body's contact forces alone.
    pub contact: &'a [Vec<Vec3>],
    /// The world's contacts, for what an implicit solve takes of them (their stiffness, the
    /// couplings between bodies).
    pub contacts: &'a CpuContacts,
    /// The contacts' reports of this step.
    pub reports: &'a [ContactReport],
    /// The world's pairs in contact, in contact order.
    pub pairs: &'a [ContactPair],
}

/// An integrator on the CPU: moves every body of a world by one step (or part of one).
pub trait CpuIntegrator {
    /// Moves a world's `bodies` under `loads`; returns the residual at rest at the step's
    /// start where the integrator measures one (the implicit integrator's), else zero.
    fn integrate(&mut self, bodies: &mut [MassSpring], loads: &Loads<'_>) -> Residual;
}
