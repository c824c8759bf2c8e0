//! Contacts as one piece: what a contact is ([`ContactModel`]), and the CPU's contacts of a
//! world ([`CpuContacts`]), which every integrator calls through one interface — each step's
//! reports, each body's contact forces summed in contact order, and what an implicit solve
//! takes of them (the voxel model's stiffness blocks, the surface contact's couplings).
//!
//! The two models:
//! - **the voxel model's** ([`ContactModel::Voxel`]): the paper's collision, on the parallel
//!   backend ([`voxcollide::parallel::ParallelCpuCollision`]), its force the paper's constant
//!   magnitude or a penalty growing with depth ([`Response`]);
//! - **the surface contact** ([`ContactModel::Surface`], [`surface`]): both sides pushed out of
//!   each other's closed surface, measured to the partner's triangles.
//!
//! The GPU world's twin of this piece is [`crate::gpu::GpuWorld`]'s `DeviceContact`.

pub mod surface;

pub use surface::{
    POINT_VERTICES, Push, Stencil, SurfaceContact, SurfaceForces, SurfaceHit, SurfacePenalty, SurfaceStats,
    entries, nearest_pushes,
};

use glam::{Mat3, Vec3};

use crate::body::MassSpring;
use voxcollide::error::Error;
use voxcollide::grid::VoxelGrid;
use voxcollide::parallel::ParallelCpuCollision;
use voxcollide::params::ContactParams;
use voxcollide::params::Response;
use voxcollide::report::ContactReport;

/// What a contact is: one of the two models, so that no impossible mix can be written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ContactModel {
    /// The voxel model's report (the paper's): `b`'s vertices pushed from their partners in
    /// `a`, with the paper's constant magnitude or a penalty growing with depth
    /// (docs/semantics.md, "Contacts that hold").
    Voxel(Response),
    /// Forces measured to each other's surface triangles, on both sides ([`SurfaceContact`]);
    /// the pair's grid then gives only the contact's bound (its voxel size). Found on the
    /// host, under the GPU world too.
    Surface(SurfacePenalty),
}

impl ContactModel {
    /// The response as the voxel model names it: a surface contact's penalty is a
    /// [`Response::Penalty`] of the same stiffness and gap.
    #[must_use]
    pub fn response(&self) -> Response {
        match *self {
            ContactModel::Voxel(r) => r,
            ContactModel::Surface(p) => Response::Penalty { stiffness: p.stiffness, gap: p.gap },
        }
    }

    /// The surface contact's parameters, where it is one.
    #[must_use]
    pub fn surface(&self) -> Option<SurfacePenalty> {
        match *self {
            ContactModel::Surface(p) => Some(p),
            ContactModel::Voxel(_) => None,
        }
    }

    /// The stiffness of a voxel-model penalty, which an implicit solve takes as each pushed
    /// vertex's stiffness along its push; `None` for the paper's constant magnitude and for a
    /// surface contact (whose pushes couple the two bodies instead).
    #[must_use]
    pub fn voxel_stiffness(&self) -> Option<f32> {
        match *self {
            ContactModel::Voxel(Response::Penalty { stiffness, .. }) => Some(stiffness),
            ContactModel::Voxel(Response::Constant) | ContactModel::Surface(_) => None,
        }
    }
}

/// One pair of bodies in contact: `a` is binned (its voxel model follows it under
/// [`Anchor::FollowA`](voxcollide::Anchor::FollowA)), `b` probes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactPair {
    /// The indexed body, an index into [`World::bodies`](crate::World::bodies).
    pub a: usize,
    /// The probing body.
    pub b: usize,
    /// The pair's voxel model.
    pub grid: VoxelGrid,
    /// The pair's contact parameters.
    pub params: ContactParams,
    /// How the pair finds its contacts and how strongly they push: the voxel model's report
    /// or the surface contact ([`crate::contact`]).
    pub model: ContactModel,
}

impl ContactPair {
    /// The pair's response as the voxel model names it ([`ContactModel::response`]).
    #[must_use]
    pub fn response(&self) -> Response {
        self.model.response()
    }

    /// The pair's surface contact, where it is one ([`ContactModel::surface`]).
    #[must_use]
    pub fn surface(&self) -> Option<SurfacePenalty> {
        self.model.surface()
    }
}

/// One push of a surface contact, as the implicit solve couples the two bodies: a spring of
/// stiffness `stiffness` along `normal` between vertex `vertex` of body `body` and the point of
/// body `partner`'s triangle `triangle` at barycentric `weights`. Its Hessian `k·JᵀJ`, with
/// `J = nᵀ[1, −w₀, −w₁, −w₂]`, joins the two bodies' unknowns in one system, so that a body
/// pushing another carries it within the step instead of pressing into where it was.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coupling {
    /// The pushed point's body.
    pub body: u32,
    /// The pushed point, as its body's vertices and weights (a vertex: itself, weight 1; a
    /// point of the surface a lattice carries: its cell's corners).
    pub point: Stencil<POINT_VERTICES>,
    /// The body whose surface pushes it.
    pub partner: u32,
    /// The nearest point of that surface, as the partner's vertices and weights (a triangle's
    /// corners in its barycentric weights, each corner's own stencil scaled by its weight).
    pub from: Stencil<{ 3 * POINT_VERTICES }>,
    /// The push's direction (unit).
    pub normal: Vec3,
    /// The push's stiffness (force per unit depth).
    pub stiffness: f32,
    /// `gap − s` at the start of the step: positive where the vertex is pushed (its force is
    /// in [`BodyStep::forces`](crate::integrator::implicit::BodyStep::forces)), at most 0 where it is only within the contact's margin. A pair
    /// is in the solve where the solve ends it within the gap, with the force
    /// `k·(gap − s − Δs)` it meets there: one within the margin joins where the solve carries it
    /// in, one pushed now leaves where the solve carries it away (found by solving again, at
    /// most four times; after the first solve pairs only join, so that the set cannot cycle).
    pub depth: f32,
}

impl Coupling {
    /// The coupling of push `p` of the surface contact `pair`, whose stiffness is `stiffness`.
    pub(crate) fn of_push(p: &Push, pair: &ContactPair, stiffness: f32) -> Coupling {
        let (body, partner) = if p.of_a { (pair.a, pair.b) } else { (pair.b, pair.a) };
        Coupling {
            body: body as u32,
            point: p.point,
            partner: partner as u32,
            from: p.from,
            normal: p.normal,
            stiffness,
            depth: p.depth,
        }
    }
}

/// For each of `bodies` bodies, the contacts of `pairs` that push it, in contact order:
/// `(contact, as_a)`. A body's contact forces are summed in this order on the CPU and the GPU.
#[must_use]
pub fn contacts_of(bodies: usize, pairs: &[ContactPair]) -> Vec<Vec<(usize, bool)>> {
    let mut of = vec![Vec::new(); bodies];
    for (c, pair) in pairs.iter().enumerate() {
        of[pair.a].push((c, true));
        of[pair.b].push((c, false));
    }
    of
}

/// One contact's state on the CPU, by its model.
// (A world holds a handful: their sizes do not matter.)
#[allow(clippy::large_enum_variant)]
enum CpuContact {
    Voxel(ParallelCpuCollision),
    Surface { contact: SurfaceContact, forces: SurfaceForces },
}

/// A world's contacts on the CPU: each stepped by its model, and what the integrators take of
/// them. Only the model a contact has is built.
pub struct CpuContacts {
    contacts: Vec<CpuContact>,
    /// For each body, the contacts that push it, in contact order: `(contact, as_a)`.
    contacts_of: Vec<Vec<(usize, bool)>>,
}

impl CpuContacts {
    /// The contacts `pairs` of a world's `bodies` as they are now.
    ///
    /// # Errors
    /// The contact-parameter errors of [`ParallelCpuCollision::new`] and
    /// [`SurfaceContact::new`].
    pub fn new(bodies: &[MassSpring], pairs: &[ContactPair]) -> Result<CpuContacts, Error> {
        let contacts = pairs
            .iter()
            .map(|c| match c.model {
                ContactModel::Voxel(response) => ParallelCpuCollision::new(c.grid, c.params)
                    .and_then(|p| p.with_response(response))
                    .map(CpuContact::Voxel),
                ContactModel::Surface(penalty) => SurfaceContact::new(penalty, &bodies[c.a], &bodies[c.b])
                    .map(|contact| CpuContact::Surface { contact, forces: SurfaceForces::default() }),
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(CpuContacts { contacts, contacts_of: contacts_of(bodies.len(), pairs) })
    }

    /// How many contacts there are.
    #[must_use]
    pub fn len(&self) -> usize {
        self.contacts.len()
    }

    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.contacts.is_empty()
    }

    /// Steps every contact (`pairs`) at the `bodies`' positions: each one's report into
    /// `reports`, and a surface contact's findings into `stats` (one each per contact).
    ///
    /// # Errors
    /// The collision's errors ([`ParallelCpuCollision::step_into`]).
    pub fn step(
        &mut self,
        bodies: &[MassSpring],
        pairs: &[ContactPair],
        reports: &mut [ContactReport],
        stats: &mut [SurfaceStats],
    ) -> Result<(), Error> {
        for (c, pair) in pairs.iter().enumerate() {
            let (a, b) = (&bodies[pair.a], &bodies[pair.b]);
            let r = &mut reports[c];
            match &mut self.contacts[c] {
                CpuContact::Voxel(collision) => collision.step_into(&a.pos, &b.pos, r)?,
                CpuContact::Surface { contact, forces } => {
                    stats[c] = contact.step(a, b, forces);
                    r.force_a.clone_from(&forces.force_a);
                    r.force_b.clone_from(&forces.force_b);
                    r.colliding_b.clone_from(&forces.touching_b);
                    r.binned_a = a.len() as u32;
                    r.discarded_a = 0;
                    r.grid_center = pair.grid.center();
                }
            }
        }
        Ok(())
    }

    /// Body `k`'s contact forces of the last step, summed in contact order into `sum` (its
    /// length the body's; the same `f32` additions as the GPU's `accumulate` pass).
    pub fn forces_on(&self, k: usize, reports: &[ContactReport], sum: &mut [Vec3]) {
        for (n, &(c, as_a)) in self.contacts_of[k].iter().enumerate() {
            let f = if as_a { &reports[c].force_a } else { &reports[c].force_b };
            if n == 0 {
                sum.copy_from_slice(f);
            } else {
                sum.iter_mut().zip(f).for_each(|(s, f)| *s += *f);
            }
        }
    }

    /// Body `k`'s contact stiffness blocks (`len`: its vertex count) for an implicit solve: each voxel-model penalty's
    /// stiffness along the force it gave each vertex it pushed (it pushes from a surface standing
    /// still). A surface contact's pushes couple the two bodies instead ([`couplings`]).
    ///
    /// [`couplings`]: Self::couplings
    #[must_use]
    pub fn stiffness_on(
        &self,
        k: usize,
        len: usize,
        pairs: &[ContactPair],
        reports: &[ContactReport],
    ) -> Vec<Mat3> {
        let mut contact_k = vec![Mat3::ZERO; len];
        for &(c, as_a) in &self.contacts_of[k] {
            let Some(stiffness) = pairs[c].model.voxel_stiffness() else { continue };
            let f = if as_a { &reports[c].force_a } else { &reports[c].force_b };
            for (kc, f) in contact_k.iter_mut().zip(f) {
                let len = f.length();
                if len > 0.0 {
                    let n = *f / len;
                    *kc += stiffness * Mat3::from_cols(n * n.x, n * n.y, n * n.z);
                }
            }
        }
        contact_k
    }

    /// The surface contacts' pushes of the last step as couplings of an implicit solve, in
    /// contact order.
    #[must_use]
    pub fn couplings(&self, pairs: &[ContactPair]) -> Vec<Coupling> {
        let mut couplings = Vec::new();
        for (contact, pair) in self.contacts.iter().zip(pairs) {
            let CpuContact::Surface { contact, forces } = contact else { continue };
            let stiffness = contact.penalty.stiffness;
            couplings.extend(forces.pushes.iter().map(|p| Coupling::of_push(p, pair, stiffness)));
        }
        couplings
    }
}
