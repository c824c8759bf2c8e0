//! The paper's `CollisionEliminator`: turns contacts into equal and opposite penalty forces
//! (docs/design.md §2, *Direction*).

use glam::Vec3;

use crate::detect::Contact;
use crate::fixed_point::ForceAccumulator;
use crate::math::{cross, dist2, dot};
use crate::params::{ContactParams, Direction, Response, Search};

/// Below this squared distance two vertices coincide and have no line of centres; below this
/// cross-product length three points span no plane.
pub const DEGENERATE: f32 = 1e-12;

/// Turns contacts into forces on both bodies.
pub trait CollisionEliminator {
    /// Adds the force of every contact to `forces`: `f_b` on the B vertex, and its opposite,
    /// in shares, on the A vertices it touches. `center` is the grid center of this step.
    fn eliminate(
        &self,
        center: Vec3,
        a: &[Vec3],
        b: &[Vec3],
        contacts: &[Contact],
        forces: &mut ForceAccumulator,
    );
}

/// The eliminator for `direction`, with the magnitude of each contact's force from `law`.
#[must_use]
pub fn eliminator(direction: Direction, law: ForceLaw) -> Box<dyn CollisionEliminator + Send + Sync> {
    match direction {
        Direction::Pairwise => Box::new(PairwiseEliminator { law }),
        Direction::PlaneNormal => Box::new(PlaneNormalEliminator { law }),
    }
}

/// Force along the line of centres of `b` and its partner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairwiseEliminator {
    /// The magnitude of each contact's force.
    pub law: ForceLaw,
}

/// Force along the outward normal of the plane through the three nearest A vertices, split in
/// three among them; pairwise where there is no plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneNormalEliminator {
    /// The magnitude of each contact's force.
    pub law: ForceLaw,
}

/// The magnitude of a contact's force under a [`Response`], its constants computed once (in
/// `f32`, as `shaders/probe.wgsl` receives them): the paper's constant, or a penalty growing
/// with depth. Every backend asks it the same two questions, so that all agree to the bit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceLaw {
    /// `ContactParams::magnitude`: the constant, or the penalty's largest force.
    pub magnitude: f32,
    /// `None`: the paper's constant magnitude.
    pub penalty: Option<Penalty>,
}

/// A penalty response's constants (see [`Response::Penalty`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Penalty {
    /// Force per unit of depth.
    pub stiffness: f32,
    /// How far outside the plane the response begins.
    pub gap: f32,
    /// `gap + reach`: the radius of the sphere around a pairwise partner where it begins.
    pub gap_reach: f32,
    /// `magnitude / stiffness`: the deepest depth counted.
    pub max_depth: f32,
}

impl ForceLaw {
    /// The law of `response` for a contact with `params` on a grid of `voxel_size`.
    #[must_use]
    pub fn new(params: &ContactParams, response: Response, voxel_size: f32) -> ForceLaw {
        let magnitude = params.magnitude;
        let penalty = match response {
            Response::Constant => None,
            Response::Penalty { stiffness, gap } => {
                let reach = match params.search {
                    Search::Neighbours { radius } => radius,
                    Search::Voxel => voxel_size,
                };
                Some(Penalty { stiffness, gap, gap_reach: gap + reach, max_depth: magnitude / stiffness })
            }
        };
        ForceLaw { magnitude, penalty }
    }

    /// The magnitude of the force on `b` along the plane normal `n` of `a0, a1, a2`.
    #[inline(always)]
    #[must_use]
    pub fn plane(&self, b: Vec3, a0: Vec3, a1: Vec3, a2: Vec3, n: Vec3) -> f32 {
        match self.penalty {
            None => self.magnitude,
            Some(p) => p.of_depth(p.gap - dot(b - centroid(a0, a1, a2), n)),
        }
    }

    /// The magnitude of the force on a `b` at squared distance `d2` from its partner.
    #[inline(always)]
    #[must_use]
    pub fn pairwise(&self, d2: f32) -> f32 {
        match self.penalty {
            None => self.magnitude,
            Some(p) => p.of_depth(p.gap_reach - d2.sqrt()),
        }
    }
}

impl Penalty {
    /// `stiffness * depth`, the depth clamped to `[0, max_depth]` (NaN counts as 0), with the
    /// comparisons written as `shaders/probe.wgsl` writes them.
    #[inline(always)]
    #[must_use]
    pub fn of_depth(&self, depth: f32) -> f32 {
        let d = if depth > 0.0 { depth } else { 0.0 };
        let d = if d < self.max_depth { d } else { self.max_depth };
        self.stiffness * d
    }
}

/// The unit direction from `a` to `b`, `(b - a) / sqrt(d2)`; for coincident vertices
/// (`d2 < 1e-12`) the unit vector from `center` to `b`, or `+z` when that is degenerate too.
#[must_use]
pub fn pairwise_direction(center: Vec3, a: Vec3, b: Vec3) -> Vec3 {
    pairwise_direction_at(center, a, b, dist2(b, a))
}

/// [`pairwise_direction`] for a caller that has `d2 = dist2(b, a)` already (the same bits, so
/// the same direction).
#[inline(always)]
#[must_use]
pub fn pairwise_direction_at(center: Vec3, a: Vec3, b: Vec3, d2: f32) -> Vec3 {
    if d2 >= DEGENERATE {
        return (b - a) / d2.sqrt();
    }
    let e2 = dist2(b, center);
    if e2 >= DEGENERATE { (b - center) / e2.sqrt() } else { Vec3::Z }
}

/// The unit normal of the plane through `a0, a1, a2`, `c / sqrt(dot(c, c))` with
/// `c = cross(a1 - a0, a2 - a0)`, turned so that `dot(n, centroid - center) >= 0`; `None` when
/// `|c| < 1e-12`.
#[must_use]
pub fn plane_normal(center: Vec3, a0: Vec3, a1: Vec3, a2: Vec3) -> Option<Vec3> {
    let c = cross(a1 - a0, a2 - a0);
    let len = dot(c, c).sqrt();
    if len < DEGENERATE {
        return None;
    }
    let n = c / len;
    Some(if dot(n, centroid(a0, a1, a2) - center) >= 0.0 { n } else { -n })
}

/// The centroid of three points, `(a0 + a1 + a2) / 3`, as the plane's orientation and the
/// penalty's depth (and `shaders/probe.wgsl`) compute it.
#[inline(always)]
#[must_use]
pub fn centroid(a0: Vec3, a1: Vec3, a2: Vec3) -> Vec3 {
    (a0 + a1 + a2) / 3.0
}

fn pairwise(
    law: &ForceLaw,
    center: Vec3,
    a: &[Vec3],
    b: &[Vec3],
    contact: &Contact,
    forces: &mut ForceAccumulator,
) {
    let (pa, pb) = (a[contact.partner as usize], b[contact.b as usize]);
    let d = pairwise_direction(center, pa, pb);
    let f_b = law.pairwise(dist2(pb, pa)) * d;
    forces.set_b(contact.b, f_b);
    forces.add_a(contact.partner, -f_b);
}

impl CollisionEliminator for PairwiseEliminator {
    fn eliminate(
        &self,
        center: Vec3,
        a: &[Vec3],
        b: &[Vec3],
        contacts: &[Contact],
        forces: &mut ForceAccumulator,
    ) {
        for contact in contacts {
            pairwise(&self.law, center, a, b, contact, forces);
        }
    }
}

impl CollisionEliminator for PlaneNormalEliminator {
    fn eliminate(
        &self,
        center: Vec3,
        a: &[Vec3],
        b: &[Vec3],
        contacts: &[Contact],
        forces: &mut ForceAccumulator,
    ) {
        for contact in contacts {
            let plane = contact.plane.and_then(|[i0, i1, i2]| {
                let n = plane_normal(center, a[i0 as usize], a[i1 as usize], a[i2 as usize])?;
                Some(([i0, i1, i2], n))
            });
            let Some((three, n)) = plane else {
                pairwise(&self.law, center, a, b, contact, forces);
                continue;
            };
            let [a0, a1, a2] = three.map(|i| a[i as usize]);
            let f_b = self.law.plane(b[contact.b as usize], a0, a1, a2, n) * n;
            forces.set_b(contact.b, f_b);
            let share = -f_b / 3.0;
            for i in three {
                forces.add_a(i, share);
            }
        }
    }
}
