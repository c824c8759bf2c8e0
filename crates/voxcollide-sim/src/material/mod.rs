//! Materials as energies: what a body's vertices feel from its own deformation, each law in a
//! file named after it, its WGSL twin beside it in `shaders/`.
//!
//! - [`springs`]: the paper's lattice of nonlinear, strain-stiffening springs
//!   (`shaders/springs.wgsl`);
//! - [`neo_hookean`]: linear tetrahedra of a stable Neo-Hookean material, which honour
//!   Poisson's ratio (`shaders/elements.wgsl`).
//!
//! A body's materials ([`MassSpring::materials`]) are its springs, then its elements if it has
//! any (a body of elements keeps its springs for their damping, their stiffness 0). Each
//! [`Material`] gives its force on a vertex, its undamped terms (what a static answer balances),
//! and a bound on its stiffness (the explicit integrator's stable step). The implicit solve's
//! linearisation of each is in [`crate::integrator::implicit`] (`MassSpring::system`), and the
//! GPU's in `shaders/implicit_system.wgsl`, `implicit_solve.wgsl` and `implicit_tetrahedra.wgsl`.
//!
//! A new material is a new file here that implements [`Material`], its WGSL twin, and a place in
//! [`MassSpring::materials`].

pub mod neo_hookean;
pub mod springs;

use glam::Vec3;

use crate::body::MassSpring;

/// A body's material: the forces its deformation gives each vertex.
///
/// Sums are per vertex, over the material's terms in a fixed order, so that the result does
/// not depend on the thread count and the GPU's twin gives the same bits.
pub trait Material: Sync {
    /// Adds the material's force on vertex `i` of `body`, at positions `pos` and velocities
    /// `vel` (its damping), to `f`, in the order its WGSL twin adds it.
    fn add_force(
        &self,
        body: &MassSpring,
        pos: &[Vec3],
        vel: &[Vec3],
        rest_scale: f32,
        i: usize,
        f: &mut Vec3,
    );

    /// Calls `term` with each of the material's forces on vertex `i` at rest (no damping), the
    /// body at `pos`, in the same order: a static answer drives their sum to zero, and their
    /// magnitudes are the scale it is judged against.
    fn for_each_term(
        &self,
        body: &MassSpring,
        pos: &[Vec3],
        rest_scale: f32,
        i: usize,
        term: &mut dyn FnMut(Vec3),
    );

    /// Per vertex, a bound on its stiffness (`ω²·mass`, Gershgorin) for strains up to `s_max`:
    /// the explicit integrator's stable step follows the largest over the vertices.
    fn stiffness_bounds(&self, body: &MassSpring, s_max: f32) -> Vec<f32>;
}
