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

use crate::body::{MassSpring, Mode, StepInputs, driven_target};
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
    /// What an implicit solve takes of the loads whose stiffness joins many vertices (a sealed
    /// pocket's suction); their forces are in `forces`.
    pub rank_one: &'a [implicit::RankOne],
}

/// An integrator on the CPU: moves every body of a world by one step (or part of one).
pub trait CpuIntegrator {
    /// Moves a world's `bodies` under `loads`; returns the residual at rest at the step's
    /// start where the integrator measures one (the implicit integrator's), else zero.
    fn integrate(&mut self, bodies: &mut [MassSpring], loads: &Loads<'_>) -> Residual;
}

/// The end of a step for a vertex that is not free, under either integrator: a pinned one back
/// at `rest` and still; a driven one at its target, at the speed that took it there over `dt`.
/// Nothing for a free one. CPU twin of `shaders/integrate.wgsl`'s and `implicit_move.wgsl`'s.
pub(crate) fn move_held(
    mode: Mode,
    inputs: &StepInputs,
    rest: Vec3,
    pos: &mut Vec3,
    vel: &mut Vec3,
    dt: f32,
) {
    match mode {
        Mode::Free => {}
        Mode::Pinned => {
            *pos = rest;
            *vel = Vec3::ZERO;
        }
        Mode::Driven => {
            let target = driven_target(inputs, rest);
            *vel = (target - *pos) / dt;
            *pos = target;
        }
    }
}

/// A free vertex that ended its step below its floor (the chest wall) is put on it, moving up
/// at most, under either integrator: the plane `z = floor`, or `wall` raised by `floor` along
/// its normal ([`MassSpring::wall`](crate::MassSpring)), its speed along the wall slowed by
/// `friction` ([`Wall::push_out`](crate::wall::Wall::push_out)).
pub(crate) fn onto_floor(
    pos: &mut Vec3,
    vel: &mut Vec3,
    floor: f32,
    wall: Option<&crate::wall::Wall>,
    friction: f32,
) {
    if let Some(w) = wall {
        w.push_out(pos, vel, floor, friction);
    } else if pos.z < floor {
        pos.z = floor;
        vel.z = vel.z.max(0.0);
    }
}
