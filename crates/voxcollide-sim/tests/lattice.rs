//! Soft bodies filling closed surfaces that look like anatomy: the lattice stays inside (no
//! vertex and no spring outside, even across the kidney's concave side), fills most of the
//! volume, says which thin parts it cannot hold, and refuses spacings that give no interior or
//! too many vertices — before allocating them.

mod common;

use common::shapes::{breast, cubes, kidney, sphere_like, torus, u_shape, volume};
use voxcollide::Error;
use voxcollide::glam::{DVec3, Vec3};
use voxcollide_sim::bodies::{LatticeReport, MAX_LATTICE_VERTICES, lattice_in_surface};
use voxcollide_sim::geometry::ClosedSurface;
use voxcollide_sim::mesh_io::{Surface, check_closed};
use voxcollide_sim::{MassSpring, Material, Mode};

const MATERIAL: Material = Material { mass: 1.0, stiffening: 10.0, spring_damping: 0.6, damping: 0.1 };

fn fill(s: &Surface, h: f32) -> Result<(MassSpring, LatticeReport), Error> {
    lattice_in_surface(&s.positions, &s.mesh, h, 1.0, MATERIAL, |_| Mode::Free)
}

/// Every vertex and every point along every spring is inside the surface (or on it, to
/// rounding: a lattice node may fall exactly on a face).
fn assert_inside(what: &str, s: &Surface, body: &MassSpring) {
    let surface = ClosedSurface::new(&s.positions, &s.mesh).unwrap();
    let inside = |p: Vec3| surface.contains(p) || surface.distance(p) <= 1e-3;
    for (i, p) in body.pos.iter().enumerate() {
        assert!(inside(*p), "{what}: vertex {i} at {p} is outside");
    }
    for spring in &body.springs {
        let (a, b) = (body.pos[spring.i as usize], body.pos[spring.j as usize]);
        for t in [0.25f32, 0.5, 0.75] {
            let p = a.lerp(b, t);
            assert!(inside(p), "{what}: spring {}-{} leaves the surface at {p}", spring.i, spring.j);
        }
    }
}

#[test]
fn anatomy_like_surfaces_are_filled_from_the_inside() {
    for (shape, mut s, h) in
        [("kidney", kidney(), 4.0f32), ("breast", breast(), 5.0), ("torus", torus(), 3.0)]
    {
        check_closed(&mut s).unwrap();
        let (body, report) = fill(&s, h).unwrap();
        eprintln!("{shape}: {report:?}");
        assert!(report.vertices > 500, "{shape}: {report:?}");
        assert_eq!(report.vertices, body.len());
        assert_eq!(report.springs, body.springs.len());
        assert_inside(shape, &s, &body);
        // The full cells fill the volume but for about a cell layer at the surface.
        assert!((0.6..=1.0).contains(&report.coverage), "{shape}: coverage {}", report.coverage);
        // The body's own surface (the full cells' outer faces) is closed and encloses most of it.
        let mut own = Surface { positions: body.pos.clone(), mesh: body.surface.clone() };
        let own_report = check_closed(&mut own);
        // A union of cubes may touch along an edge (non-manifold there), but it bounds a volume.
        let enclosed = volume(&own).abs();
        assert!(enclosed > 0.5 * volume(&s), "{shape}: {enclosed} of {} ({own_report:?})", volume(&s));
        // Every spring is one of the lattice's: along an axis or a face diagonal of the cell.
        for spring in &body.springs {
            let l = spring.rest / h;
            assert!(
                (l - 1.0).abs() < 1e-4 || (l - 2f32.sqrt()).abs() < 1e-4,
                "{shape}: rest {}",
                spring.rest
            );
        }
    }
}

#[test]
fn springs_across_a_concave_gap_are_left_out_and_counted() {
    // A U whose arms (3 cells of 1 mm thick) are half a spacing apart (a gap of 1 cell, spacing
    // 2 mm): lattice nodes on both sides of the gap are one spacing apart, and a spring between
    // them would leak through it. The lattice stays inside, and the report counts what it left
    // out.
    let mut u = cubes(&u_shape(4, 3, 1, 12, 6), 1.0);
    check_closed(&mut u).unwrap();
    let (body, report) = fill(&u, 2.0).unwrap();
    eprintln!("U: {report:?}");
    assert_inside("U", &u, &body);
    assert!(report.springs_outside > 0, "{report:?}");
    // The body's own surface (its full cells) does not close over the gap either.
    let own = ClosedSurface::new(&body.pos, &body.surface).unwrap();
    let gap = Vec3::new(3.5, 10.0, 3.0); // between the arms, halfway up, mid-depth
    assert!(!ClosedSurface::new(&u.positions, &u.mesh).unwrap().contains(gap));
    assert!(!own.contains(gap), "the lattice's solid spans the gap");
}

#[test]
fn thin_parts_are_reported_not_lost_silently() {
    // A U with a base 2.4 mm thick and arms 0.2 mm thick, 6 mm long, spacing 2 mm: the arms are
    // thinner than the spacing and hold no lattice node; the lattice holds the base, and the
    // report counts the arms' surface it cannot reach.
    let mut u = cubes(&u_shape(12, 1, 21, 30, 12), 0.2);
    check_closed(&mut u).unwrap();
    let (body, report) = fill(&u, 2.0).unwrap();
    eprintln!("thin U: {report:?}");
    assert_inside("thin U", &u, &body);
    assert!(report.uncovered > 0 && report.uncovered < report.surface_vertices, "{report:?}");
    assert!(report.coverage < 0.9, "{report:?}");
    // A fine spacing reaches it all.
    let fine = fill(&u, 0.1).unwrap().1;
    assert_eq!(fine.uncovered, 0, "{fine:?}");
    // A plate far thinner than the spacing has no interior at all.
    let mut plate = sphere_like(12, 24, |t, p| {
        DVec3::new(40.0 * t.sin() * p.cos(), 40.0 * t.sin() * p.sin(), 0.5 * t.cos())
    });
    check_closed(&mut plate).unwrap();
    let err = fill(&plate, 2.0).unwrap_err();
    assert!(
        matches!(&err, Error::Invalid { what: "lattice spacing", rule, .. } if rule.contains("no lattice cell")),
        "{err}"
    );
}

#[test]
fn spacings_that_give_no_body_or_too_large_a_body_are_refused_up_front() {
    let mut s = kidney();
    check_closed(&mut s).unwrap();
    let err = fill(&s, 200.0).unwrap_err();
    assert!(err.to_string().contains("no lattice cell"), "{err}");
    // 1e-3 mm over a 120 mm kidney: ~10^14 vertices. Refused at once, naming the count.
    let t = std::time::Instant::now();
    let err = fill(&s, 1e-3).unwrap_err();
    let Error::Invalid { rule, .. } = &err else { panic!("{err:?}") };
    assert!(rule.contains("lattice vertices") && rule.contains(&MAX_LATTICE_VERTICES.to_string()), "{err}");
    assert!(t.elapsed().as_secs() < 5, "it allocated first");
    for bad in [0.0f32, -1.0, f32::NAN, f32::INFINITY] {
        assert!(matches!(fill(&s, bad), Err(Error::Invalid { .. })), "{bad}");
    }
}

#[test]
fn held_vertices_follow_the_rule_on_positions() {
    let mut s = breast();
    check_closed(&mut s).unwrap();
    let (body, _) = lattice_in_surface(&s.positions, &s.mesh, 5.0, 1.0, MATERIAL, |p| {
        if p.z < -5.0 { Mode::Pinned } else { Mode::Free }
    })
    .unwrap();
    let pinned: Vec<Vec3> =
        body.pos.iter().zip(&body.mode).filter(|(_, m)| **m == Mode::Pinned).map(|(p, _)| *p).collect();
    assert!(!pinned.is_empty() && pinned.len() < body.len());
    assert!(pinned.iter().all(|p| p.z < -5.0));
}

#[test]
fn the_users_surface_is_carried_by_the_lattice() {
    for (shape, mut s, h) in [("kidney", kidney(), 4.0f32), ("breast", breast(), 5.0)] {
        check_closed(&mut s).unwrap();
        let (mut body, _) = fill(&s, h).unwrap();
        let e = body.embedded.clone().expect("a lattice in a surface carries it");
        assert_eq!(e.rest, s.positions, "{shape}");
        assert_eq!(e.mesh, s.mesh, "{shape}");
        // At rest the surface is where the user put it; moved with the lattice, it follows.
        assert_eq!(e.positions(&body.pos, &body.rest_pos), s.positions, "{shape}");
        let shift = Vec3::new(3.0, -2.0, 7.5);
        body.pos.iter_mut().for_each(|p| *p += shift);
        for (p, r) in e.positions(&body.pos, &body.rest_pos).iter().zip(&s.positions) {
            assert!((*p - (*r + shift)).length() < 1e-4, "{shape}: {p} vs {}", *r + shift);
        }
        // A uniform stretch of the lattice stretches the surface with it (to within a cell at the
        // boundary, where a cell's missing corners are left out of the weights).
        let stretch = |p: Vec3| Vec3::new(1.1 * p.x, p.y, p.z);
        body.pos = body.rest_pos.iter().map(|p| stretch(*p)).collect();
        let worst = e
            .positions(&body.pos, &body.rest_pos)
            .iter()
            .zip(&s.positions)
            .map(|(p, r)| p.distance(stretch(*r)))
            .fold(0.0, f32::max);
        assert!(worst < 0.1 * h, "{shape}: {worst}");
    }
}
