//! The contacts' checks (docs/design.md §11): at every frame and between frames, how deep
//! each contact's bodies are in each other by the exact inside test, against the contact's
//! bound; a contact that goes beyond it is said at once and the run is not a result.

use glam::Vec3;

use super::frames::shown_surface;
use super::summary::{ContactSummary, FileSummary};
use voxcollide::error::Error;
use voxcollide::report::ContactReport;
use voxcollide_sim::World;
use voxcollide_sim::geometry::{ClosedSurface, Hierarchy, PenetrationWatch};
use voxcollide_sim::wall::Wall;

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
            let Depths { b_in_a, a_in_b, uncovered } =
                contact_depths(world, pair, &mut self.hierarchies[c], &mut self.watches[c])?;
            let depth = b_in_a.max_depth.max(a_in_b);
            self.last[c] = depth;
            let s = &mut summary.contacts[c];
            if let Some((placed, n)) = uncovered
                && n > 0
            {
                through(s, placed, n, step, frame, note);
            }
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

/// A placed implant through its tissue (docs/design.md §11, §15): its vertices that no tissue
/// covers any more, said at once; the contact did not hold, whatever its depths.
fn through(
    s: &mut ContactSummary,
    placed: usize,
    n: usize,
    step: u64,
    frame: u32,
    note: &mut dyn FnMut(&str),
) {
    let first = s.uncovered == 0;
    s.uncovered = s.uncovered.max(n);
    s.held = false;
    let (name, tissue) = if placed == 0 { (&s.a, &s.b) } else { (&s.b, &s.a) };
    let said = if step == 0 {
        format!(
            "{n} of {name}'s vertices lie in front of {tissue}'s skin before the first step, no tissue covering them along the chest wall's normal: the scene places it outside her"
        )
    } else {
        format!(
            "{n} of {name}'s vertices came through {tissue} at step {step} (frame {frame}): no tissue covers them along the chest wall's normal, the implant shows through her skin (where her tissue is only a spacing or two thick, a coarse lattice can let through an implant that a finer one holds: run it again at a finer `spacing` before ruling it out, docs/patient.md)"
        )
    };
    if first {
        s.worst_step.get_or_insert(step);
        s.worst_frame.get_or_insert(frame);
        note(&format!(
            "warning: contact {} – {} did not hold: {said}; this run's numbers are not a result",
            s.a, s.b
        ));
        s.failure = Some(said);
    }
}

/// What one check of a contact found ([`contact_depths`]).
struct Depths {
    /// `b`'s vertices inside `a`'s closed surface.
    b_in_a: voxcollide_sim::geometry::Penetration,
    /// The deepest of `a`'s shown vertices inside `b`.
    a_in_b: f32,
    /// Where one of the two is placed on the other's chest wall (docs/design.md §15): which
    /// (0 for `a`, 1 for `b`), and how many of its vertices no tissue covers ([`uncovered`]).
    uncovered: Option<(usize, usize)>,
}

/// How deep contact `pair`'s bodies are inside each other: `b`'s vertices inside `a`'s closed
/// surface ([`shown_surface`]: the summary's penetration), and the deepest of `a`'s vertices on it inside
/// `b`'s. Both sides, since the voxel model pushes only `b`'s vertices out of `a`: `a`'s could
/// pass between them. Where one is a placed implant, also how many of its vertices the
/// other's tissue no longer covers.
fn contact_depths(
    world: &World,
    pair: &voxcollide_sim::ContactPair,
    hierarchies: &mut [Option<Hierarchy>; 2],
    watches: &mut [PenetrationWatch; 2],
) -> Result<Depths, Error> {
    let surface_of = |k: usize| shown_surface(&world.bodies[k]);
    let (a_pos, a_mesh) = surface_of(pair.a);
    let (b_pos, b_mesh) = surface_of(pair.b);
    // The walls of the implants placed on the other body's chest wall, whose vertices must stay
    // covered by it (both bodies rest on that wall, but only the implant is in her pocket,
    // whichever of the pair's two the scene names it).
    let placed = |k: usize, on: usize| {
        world
            .pockets
            .iter()
            .any(|p| (p.implant, p.tissue) == (k, on))
            .then(|| world.bodies[k].wall.as_deref())
            .flatten()
    };
    let (wall_a, wall_b) = (placed(pair.a, pair.b), placed(pair.b, pair.a));
    let [ha, hb] = hierarchies;
    let [wa, wb] = watches;
    // The two ways at once, each on every core.
    let (b_in_a, a_in_b) = rayon::join(
        || -> Result<_, Error> {
            let surface = surface_kept(&a_pos, a_mesh, ha.take())?;
            let depth = wa.penetration(&surface, &world.bodies[pair.b].pos);
            let open = wall_b.map(|w| uncovered(&surface, &world.bodies[pair.b].pos, w));
            *ha = Some(surface.into_hierarchy());
            Ok((depth, open))
        },
        || -> Result<_, Error> {
            let surface = surface_kept(&b_pos, b_mesh, hb.take())?;
            let depth = wb.penetration(&surface, &a_pos).max_depth;
            let open = wall_a.map(|w| uncovered(&surface, &a_pos, w));
            *hb = Some(surface.into_hierarchy());
            Ok((depth, open))
        },
    );
    let ((b_in_a, open_b), (a_in_b, open_a)) = (b_in_a?, a_in_b?);
    let uncovered = match (open_a, open_b) {
        (Some(n), _) => Some((0, n)),
        (None, Some(n)) => Some((1, n)),
        (None, None) => None,
    };
    Ok(Depths { b_in_a, a_in_b, uncovered })
}

/// How many of a placed implant's vertices `points` its tissue's closed surface `tissue` does
/// not cover: the ray from the vertex out along the chest wall's normal meets none of the
/// tissue's triangles, nor do two rays tilted a fifth of the way from it (a ray along a
/// lattice's edge may slip between its triangles). In the pocket an implant lies between the
/// wall and the tissue, so each such ray meets the tissue's face over the pocket; one that
/// meets nothing starts in front of her skin: the implant has come through the tissue.
fn uncovered(tissue: &ClosedSurface<'_>, points: &[Vec3], wall: &Wall) -> usize {
    let rays = [wall.normal, wall.normal + 0.2 * wall.u, wall.normal - 0.2 * wall.v];
    points.iter().filter(|&&p| !rays.iter().any(|&d| tissue.ray_hits(p, d))).count()
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::UVec3;
    use voxcollide_sim::bodies::box_lattice;
    use voxcollide_sim::{Material, Mode};

    /// Over a flat wall at z = 0 a slab of tissue lifted off it from z = 5 to 15 (its pocket
    /// below): points in the pocket, in the tissue, and on its lattice's edges are covered;
    /// points in front of its skin, or beside it past its box, are not.
    #[test]
    fn an_implants_vertex_in_front_of_her_skin_is_uncovered_and_one_in_the_pocket_is_not() {
        let floor = [
            [Vec3::new(-100.0, -100.0, 0.0), Vec3::new(100.0, -100.0, 0.0), Vec3::new(100.0, 100.0, 0.0)],
            [Vec3::new(-100.0, -100.0, 0.0), Vec3::new(100.0, 100.0, 0.0), Vec3::new(-100.0, 100.0, 0.0)],
        ];
        let wall = Wall::sample(&floor, Vec3::new(0.0, 0.0, 1.0), 20.0, 30.0, 5.0, Vec3::Y).unwrap();
        assert!((wall.normal - Vec3::Z).length() < 1e-6, "{}", wall.normal);
        let material = Material { mass: 1.0, stiffening: 0.0, spring_damping: 0.0, damping: 0.0 };
        let slab =
            box_lattice(UVec3::new(11, 11, 2), 10.0, Vec3::new(-50.0, -50.0, 5.0), 1.0, material, |_| {
                Mode::Free
            })
            .unwrap();
        let tissue = ClosedSurface::new(&slab.pos, &slab.surface).unwrap();
        let covered =
            [Vec3::new(0.0, 0.0, 2.0), Vec3::new(10.0, -20.0, 8.0), Vec3::new(50.0, 0.0, 2.0), Vec3::ZERO];
        assert_eq!(uncovered(&tissue, &covered, &wall), 0);
        let through = [Vec3::new(0.0, 0.0, 16.0), Vec3::new(-30.0, 40.0, 15.5), Vec3::new(70.0, 0.0, 2.0)];
        assert_eq!(uncovered(&tissue, &through, &wall), 3);
        assert_eq!(uncovered(&tissue, &[covered[0], through[0], covered[1]], &wall), 1);
    }
}
