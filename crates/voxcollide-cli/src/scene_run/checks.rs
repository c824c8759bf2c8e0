//! The contacts' checks (docs/design.md §11): at every frame and between frames, how deep
//! each contact's bodies are in each other by the exact inside test, against the contact's
//! bound; a contact that goes beyond it is said at once and the run is not a result.

use glam::Vec3;

use super::frames::shown_surface;
use super::summary::FileSummary;
use voxcollide::error::Error;
use voxcollide::report::ContactReport;
use voxcollide_sim::World;
use voxcollide_sim::geometry::{ClosedSurface, Hierarchy, PenetrationWatch};

/// The contacts' checks against their bounds (docs/design.md §11), over a run.
pub(super) struct ContactChecks {
    /// Per contact: whether it has touched yet (a contact is bound after first contact).
    touched: Vec<bool>,
    /// Per contact: the depth of the last check (at the end, the last frame's).
    last: Vec<f32>,
    /// Per contact: the hierarchies of its two bodies' surfaces, kept from one check to the
    /// next and refit (a check builds none anew until one has gone stale).
    hierarchies: Vec<[Option<Hierarchy>; 2]>,
    /// Per contact: b's vertices in a, a's surface in b, from one check to the next (each
    /// asks only the points that may have changed sides).
    watches: Vec<[PenetrationWatch; 2]>,
}

impl ContactChecks {
    pub(super) fn new(contacts: usize) -> ContactChecks {
        ContactChecks {
            touched: vec![false; contacts],
            last: vec![0.0; contacts],
            hierarchies: vec![[None, None]; contacts],
            watches: vec![Default::default(); contacts],
        }
    }

    /// Checks every contact's penetration now (`step`, in output frame `frame`) against its
    /// bound, recording the worst and warning the first time one goes beyond. At a frame
    /// (`at_frame`) the summary's penetration maxima take the same measurement.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn check(
        &mut self,
        world: &World,
        reports: &[ContactReport],
        summary: &mut FileSummary,
        step: u64,
        frame: u32,
        at_frame: bool,
        note: &mut dyn FnMut(&str),
    ) -> Result<(), Error> {
        for (c, pair) in world.contacts.iter().enumerate() {
            let (b_in_a, a_in_b) =
                contact_depths(world, pair, &mut self.hierarchies[c], &mut self.watches[c])?;
            let depth = b_in_a.max_depth.max(a_in_b);
            self.last[c] = depth;
            let s = &mut summary.contacts[c];
            if at_frame {
                s.max_penetration = s.max_penetration.max(b_in_a.max_depth);
                s.penetrating_fraction = s.penetrating_fraction.max(b_in_a.fraction);
            }
            s.checks += 1;
            self.touched[c] |= depth > 0.0 || reports.get(c).is_some_and(|r| !r.colliding_b.is_empty());
            if !self.touched[c] || depth <= s.bound {
                continue;
            }
            // The first time beyond the bound is the time to warn.
            let first = s.held;
            s.held = false;
            // Before the first step the scene itself placed them so: no push of the contact's
            // made it, and none may undo it (a push starts at the partner's surface).
            let placed = step == 0;
            if s.worst_depth.is_none_or(|w| depth > w) {
                s.worst_depth = Some(depth);
                s.worst_frame = Some(frame);
                s.worst_step = Some(step);
                s.failure = Some(if placed {
                    format!(
                        "the scene places {} and {} {depth:.3} {u} deep in each other before the first step, beyond the contact's bound of {:.3} {u} (its voxel size): move them apart",
                        s.a,
                        s.b,
                        s.bound,
                        u = summary.units
                    )
                } else {
                    format!(
                        "{} and {} went {depth:.3} {u} deep into each other at step {step} (frame {frame}), beyond the contact's bound of {:.3} {u} (its voxel size)",
                        s.a,
                        s.b,
                        s.bound,
                        u = summary.units
                    )
                });
            }
            if first && placed {
                note(&format!(
                    "warning: contact {} – {} did not hold: the scene places them {depth:.3} {u} deep in each other before the first step, beyond the bound of {:.3} {u}; move them apart (their `position`s) and run again: this run's numbers are not a result",
                    s.a,
                    s.b,
                    s.bound,
                    u = summary.units
                ));
            } else if first {
                note(&format!(
                    "warning: contact {} – {} did not hold: {depth:.3} {u} deep at step {step} (frame {frame}), beyond the bound of {:.3} {u}; this run's numbers are not a result",
                    s.a,
                    s.b,
                    s.bound,
                    u = summary.units
                ));
            }
        }
        summary.held = summary.contacts.iter().all(|c| c.held);
        Ok(())
    }

    /// At the last frame: a settled run's contacts are held to their bound at rest, and each
    /// contact that did not hold is said once more.
    pub(super) fn at_end(&self, summary: &mut FileSummary, step: u64, note: &mut dyn FnMut(&str)) {
        for (s, &depth) in summary.contacts.iter_mut().zip(&self.last) {
            if summary.settled && depth > s.rest_bound {
                s.held = false;
                if s.worst_depth.is_none() {
                    s.worst_depth = Some(depth);
                    s.worst_step = Some(step);
                }
                s.failure.get_or_insert_with(|| {
                    format!(
                        "at rest {} and {} are {depth:.3} {u} deep in each other, beyond the resting bound of {:.3} {u} (half of {}'s spacing)",
                        s.a,
                        s.b,
                        s.rest_bound,
                        s.b,
                        u = summary.units
                    )
                });
            }
            if let Some(f) = &s.failure {
                note(&format!("warning: contact {} – {} did not hold: {f}", s.a, s.b));
            }
        }
        summary.held = summary.contacts.iter().all(|c| c.held);
    }
}

/// How deep contact `pair`'s bodies are inside each other: `b`'s vertices inside `a`'s closed
/// (shown) surface (the summary's penetration), and the deepest of `a`'s shown vertices inside
/// `b`'s. Both sides, since the voxel model pushes only `b`'s vertices out of `a`: `a`'s could
/// pass between them.
fn contact_depths(
    world: &World,
    pair: &voxcollide_sim::ContactPair,
    hierarchies: &mut [Option<Hierarchy>; 2],
    watches: &mut [PenetrationWatch; 2],
) -> Result<(voxcollide_sim::geometry::Penetration, f32), Error> {
    let surface_of = |k: usize| shown_surface(&world.bodies[k]);
    let (a_pos, a_mesh) = surface_of(pair.a);
    let (b_pos, b_mesh) = surface_of(pair.b);
    let [ha, hb] = hierarchies;
    let [wa, wb] = watches;
    // The two ways at once, each on every core.
    let (b_in_a, a_in_b) = rayon::join(
        || -> Result<_, Error> {
            let surface = surface_kept(&a_pos, a_mesh, ha.take())?;
            let depth = wa.penetration(&surface, &world.bodies[pair.b].pos);
            *ha = Some(surface.into_hierarchy());
            Ok(depth)
        },
        || -> Result<_, Error> {
            let surface = surface_kept(&b_pos, b_mesh, hb.take())?;
            let depth = wb.penetration(&surface, &a_pos).max_depth;
            *hb = Some(surface.into_hierarchy());
            Ok(depth)
        },
    );
    Ok((b_in_a?, a_in_b?))
}

/// The closed surface of `mesh` at `positions` on the hierarchy kept from the last check, or
/// on a new one where there is none or it has gone stale.
fn surface_kept<'a>(
    positions: &'a [Vec3],
    mesh: &'a voxcollide_sim::mesh::TriangleMesh,
    kept: Option<Hierarchy>,
) -> Result<ClosedSurface<'a>, Error> {
    match kept.filter(|h| !h.stale()).map(|h| ClosedSurface::refit(positions, mesh, h)) {
        Some(Ok(surface)) => Ok(surface),
        _ => ClosedSurface::new(positions, mesh),
    }
}
