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
//! a bound on its stiffness (the explicit integrator's stable step), and its linearisation for
//! the implicit solve ([`Linearised`]: its share of `−K`, with its own damping its share of
//! `A = M − h·D − h²·K`, and its diagonal blocks for the preconditioner), which
//! [`crate::integrator::implicit`] sums over the body's materials in their order. The GPU's twin
//! of the linearisation is in `shaders/implicit_solve.wgsl` (`apply_row`),
//! `implicit_system.wgsl` and `implicit_tetrahedra.wgsl`.
//!
//! A new material is a new file here that implements [`Material`], its WGSL twin, and a place in
//! [`MassSpring::materials`].

pub mod neo_hookean;
pub mod springs;

use glam::{Mat3, Vec3};

use crate::body::{MassSpring, StepInputs};

/// A body's material: the forces its deformation gives each vertex.
///
/// Sums are per vertex, over the material's terms in a fixed order, so that the result does
/// not depend on the thread count and the GPU's twin gives the same bits.
pub trait Material: Sync {
    /// What its forces at `pos` share between vertices, computed once over the body before
    /// [`add_force`](Self::add_force) or [`for_each_term`](Self::for_each_term) gathers each
    /// vertex's from it (a tetrahedron's forces on its four corners: one deformation gradient
    /// instead of four). Empty where each vertex's terms are its own.
    fn prepare(&self, _body: &MassSpring, _pos: &[Vec3]) -> Vec<Mat3> {
        Vec::new()
    }

    /// Adds the material's force on vertex `i` of `body`, at positions `pos` and velocities
    /// `vel` (its damping), to `f`, in the order its WGSL twin adds it; `prepared` is
    /// [`prepare`](Self::prepare)'s at `pos`.
    #[allow(clippy::too_many_arguments)]
    fn add_force(
        &self,
        body: &MassSpring,
        pos: &[Vec3],
        vel: &[Vec3],
        rest_scale: f32,
        i: usize,
        prepared: &[Mat3],
        f: &mut Vec3,
    );

    /// Calls `term` with each of the material's forces on vertex `i` at rest (no damping), the
    /// body at `pos`, in the same order: a static answer drives their sum to zero, and their
    /// magnitudes are the scale it is judged against; `prepared` is [`prepare`](Self::prepare)'s
    /// at `pos`.
    fn for_each_term(
        &self,
        body: &MassSpring,
        pos: &[Vec3],
        rest_scale: f32,
        i: usize,
        prepared: &[Mat3],
        term: &mut dyn FnMut(Vec3),
    );

    /// Per vertex, a bound on its stiffness (`ω²·mass`, Gershgorin) for strains up to `s_max`:
    /// the explicit integrator's stable step follows the largest over the vertices.
    fn stiffness_bounds(&self, body: &MassSpring, s_max: f32) -> Vec<f32>;

    /// The material's linearisation at the body's positions, at the start of an implicit step of
    /// `inputs.dt`.
    fn linearise(&self, body: &MassSpring, inputs: &StepInputs) -> Box<dyn Linearised>;
}

/// A material's share of one implicit step's linear system, taken at the step's start: its part
/// of `−K` (`K = ∂f/∂x`, projected to be positive semi-definite) and, with its own damping `D`,
/// of `A = M − h·D − h²·K`.
///
/// A product is made in two stages, so that a material whose terms span several vertices (a
/// tetrahedron) computes each term once: [`prepare`](Self::prepare) over the whole body, then
/// [`add_product`](Self::add_product) per vertex, which gathers in a fixed order (the same on
/// any number of threads).
pub trait Linearised: Send + Sync {
    /// Work done once per product before the per-vertex sums, into `scratch` (which it may
    /// leave empty): for `u`, and `stiff_only` as in [`add_product`](Self::add_product).
    fn prepare(&self, body: &MassSpring, u: &[Vec3], scratch: &mut Vec<Mat3>) {
        let _ = (body, u);
        scratch.clear();
    }

    /// Adds the material's row `i` of `A·u`, or of `−K·u` when `stiff_only`, to `r`; `scratch`
    /// is what [`prepare`](Self::prepare) left.
    fn add_product(
        &self,
        body: &MassSpring,
        u: &[Vec3],
        scratch: &[Mat3],
        i: usize,
        stiff_only: bool,
        r: &mut Vec3,
    );

    /// Adds the material's diagonal block of `A` at vertex `i` (the preconditioner's) to `b`.
    fn add_diagonal(&self, body: &MassSpring, i: usize, b: &mut Mat3);
}
