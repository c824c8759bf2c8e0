//! The paper's `CollisionEliminator`: turns contacts into equal and opposite penalty forces
//! (DESIGN §2, *Direction*).

use glam::Vec3;

use crate::detect::Contact;
use crate::fixed_point::ForceAccumulator;
use crate::math::{cross, dist2, dot};
use crate::params::Direction;

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

/// The eliminator for `direction`, with contact force `magnitude`.
#[must_use]
pub fn eliminator(direction: Direction, magnitude: f32) -> Box<dyn CollisionEliminator + Send + Sync> {
    match direction {
        Direction::Pairwise => Box::new(PairwiseEliminator { magnitude }),
        Direction::PlaneNormal => Box::new(PlaneNormalEliminator { magnitude }),
    }
}

/// Force along the line of centres of `b` and its partner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairwiseEliminator {
    /// The force per contact.
    pub magnitude: f32,
}

/// Force along the outward normal of the plane through the three nearest A vertices, split in
/// three among them; pairwise where there is no plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneNormalEliminator {
    /// The force per contact.
    pub magnitude: f32,
}

/// The unit direction from `a` to `b`, `(b - a) / sqrt(d2)`; for coincident vertices
/// (`d2 < 1e-12`) the unit vector from `center` to `b`, or `+z` when that is degenerate too.
#[must_use]
pub fn pairwise_direction(center: Vec3, a: Vec3, b: Vec3) -> Vec3 {
    let d2 = dist2(b, a);
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
    let centroid = (a0 + a1 + a2) / 3.0;
    Some(if dot(n, centroid - center) >= 0.0 { n } else { -n })
}

fn pairwise(
    magnitude: f32,
    center: Vec3,
    a: &[Vec3],
    b: &[Vec3],
    contact: &Contact,
    forces: &mut ForceAccumulator,
) {
    let d = pairwise_direction(center, a[contact.partner as usize], b[contact.b as usize]);
    let f_b = magnitude * d;
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
            pairwise(self.magnitude, center, a, b, contact, forces);
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
                pairwise(self.magnitude, center, a, b, contact, forces);
                continue;
            };
            let f_b = self.magnitude * n;
            forces.set_b(contact.b, f_b);
            let share = -f_b / 3.0;
            for i in three {
                forces.add_a(i, share);
            }
        }
    }
}
