//! Inside tests, winding numbers, distances and penetration on real closed meshes (a cube, a UV
//! sphere, a flattened ellipsoid) against analytic answers and a brute-force winding number.

use std::f64::consts::PI;
use std::time::Instant;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use voxcollide::glam::{DVec3, Vec3};
use voxcollide_sim::geometry::{ClosedSurface, Penetration, PenetrationWatch, penetration};
use voxcollide_sim::mesh::TriangleMesh;

// ---------------------------------------------------------------------------------------------
// Meshes

/// The axis-aligned box `[lo, hi]`: 8 corners (corner `i` has bit 0 = x, 1 = y, 2 = z at `hi`)
/// and 12 triangles, counter-clockwise from outside.
fn cuboid(lo: Vec3, hi: Vec3) -> (Vec<Vec3>, TriangleMesh) {
    let positions = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        })
        .collect();
    // Each face as a quad counter-clockwise from outside: -x, +x, -y, +y, -z, +z.
    let quads = [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]];
    let triangles = quads.iter().flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]]).collect();
    (positions, TriangleMesh { triangles })
}

/// The cube `[-1, 1]³`.
fn cube() -> (Vec<Vec3>, TriangleMesh) {
    cuboid(Vec3::splat(-1.0), Vec3::splat(1.0))
}

/// A UV sphere of radius 1 scaled per axis by `scale`: `rings` latitude bands and `segments`
/// longitudes, vertices on the (scaled) sphere, triangles counter-clockwise from outside. Vertex
/// 0 is the north pole (+z), the last the south pole.
fn uv_sphere(rings: u32, segments: u32, scale: Vec3) -> (Vec<Vec3>, TriangleMesh) {
    let mut positions = vec![Vec3::Z * scale];
    for r in 1..rings {
        let theta = PI * f64::from(r) / f64::from(rings);
        for s in 0..segments {
            let phi = 2.0 * PI * f64::from(s) / f64::from(segments);
            let v = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            positions.push(v.as_vec3() * scale);
        }
    }
    positions.push(-Vec3::Z * scale);
    let south = positions.len() as u32 - 1;
    let ring = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    let mut triangles = Vec::new();
    for s in 0..segments {
        // Seen from outside, longitude increases counter-clockwise around the north pole and
        // clockwise around the south pole.
        triangles.push([0, ring(1, s), ring(1, s + 1)]);
        for r in 1..rings - 1 {
            let (a, b, c, d) = (ring(r, s), ring(r + 1, s), ring(r + 1, s + 1), ring(r, s + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
        triangles.push([south, ring(rings - 1, s + 1), ring(rings - 1, s)]);
    }
    (positions, TriangleMesh { triangles })
}

/// The 16 × 32 unit sphere (960 triangles).
fn sphere() -> (Vec<Vec3>, TriangleMesh) {
    uv_sphere(16, 32, Vec3::ONE)
}

/// A 32 × 32 unit sphere: 1984 triangles, the "~2k" of the speed tests.
fn sphere_2k() -> (Vec<Vec3>, TriangleMesh) {
    uv_sphere(32, 32, Vec3::ONE)
}

/// The same triangles with the opposite orientation.
fn reversed(mesh: &TriangleMesh) -> TriangleMesh {
    TriangleMesh { triangles: mesh.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect() }
}

/// The largest gap between a unit sphere and the inscribed polyhedron: a triangle with
/// circumradius `R` lies in a plane at `√(1 − R²)` from the center, so every surface point is
/// within `1 − √(1 − R²)` of the sphere, and (the polyhedron being star-shaped) every sphere point
/// within that of the surface. That bounds the Hausdorff distance, hence the difference between
/// distances to the two surfaces.
fn tessellation_error(positions: &[Vec3], mesh: &TriangleMesh) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize].as_dvec3());
            let (la, lb, lc) = ((b - c).length(), (c - a).length(), (a - b).length());
            let area2 = (b - a).cross(c - a).length(); // twice the area
            let r = la * lb * lc / (2.0 * area2);
            1.0 - (1.0 - r * r).sqrt()
        })
        .fold(0.0, f64::max)
}

/// The generalized winding number by a plain sum over every triangle (Van Oosterom–Strackee), the
/// reference for the hierarchical one.
fn brute_winding(positions: &[Vec3], mesh: &TriangleMesh, p: Vec3) -> f64 {
    let p = p.as_dvec3();
    let mut sum = 0.0;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| positions[i as usize].as_dvec3() - p);
        let num = a.dot(b.cross(c));
        let den = a.length() * b.length() * c.length()
            + a.dot(b) * c.length()
            + a.dot(c) * b.length()
            + b.dot(c) * a.length();
        sum += 2.0 * num.atan2(den);
    }
    sum / (4.0 * PI)
}

/// Distance from `p` to the surface of the box `[lo, hi]`: to the nearest face inside, to the box
/// outside.
fn box_distance(lo: Vec3, hi: Vec3, p: Vec3) -> f32 {
    let outside = (lo - p).max(p - hi).max(Vec3::ZERO);
    if outside == Vec3::ZERO { (p - lo).min(hi - p).min_element() } else { outside.length() }
}

fn random_point(rng: &mut ChaCha8Rng, lo: f32, hi: f32) -> Vec3 {
    Vec3::new(rng.random_range(lo..hi), rng.random_range(lo..hi), rng.random_range(lo..hi))
}

// ---------------------------------------------------------------------------------------------
// The meshes themselves

/// Every directed edge once and its reverse once (closed, consistently oriented), and every
/// normal pointing away from the center (outward for these convex shapes).
#[test]
fn test_meshes_are_closed_and_outward() {
    for (name, (positions, mesh)) in [
        ("cube", cube()),
        ("sphere", sphere()),
        ("sphere_2k", sphere_2k()),
        ("ellipsoid", uv_sphere(16, 32, Vec3::new(1.5, 1.0, 0.4))),
    ] {
        let mut edges = std::collections::HashSet::new();
        for &[a, b, c] in &mesh.triangles {
            for e in [(a, b), (b, c), (c, a)] {
                assert!(edges.insert(e), "{name}: edge {e:?} twice");
            }
            let [pa, pb, pc] = [a, b, c].map(|i| positions[i as usize]);
            let n = (pb - pa).cross(pc - pa);
            assert!(n.dot(pa + pb + pc) > 0.0, "{name}: triangle {a} {b} {c} faces inward");
        }
        for &(a, b) in &edges {
            assert!(edges.contains(&(b, a)), "{name}: edge {a}->{b} has no twin");
        }
    }
    assert_eq!(cube().1.triangles.len(), 12);
    assert_eq!(sphere().1.triangles.len(), 960);
    assert_eq!(sphere_2k().1.triangles.len(), 1984);
}

// ---------------------------------------------------------------------------------------------
// Inside tests and winding numbers

#[test]
fn cube_inside_and_outside() {
    let (positions, mesh) = cube();
    let s = ClosedSurface::new(&positions, &mesh).unwrap();
    assert_eq!(s.bounds(), Some((Vec3::splat(-1.0), Vec3::splat(1.0))));
    let inside = [
        Vec3::ZERO,
        Vec3::new(0.5, -0.7, 0.2),
        Vec3::new(1.0 - 1e-3, 0.3, -0.2), // 1e-3 inside each face
        Vec3::new(-1.0 + 1e-3, 0.3, -0.2),
        Vec3::new(0.3, 1.0 - 1e-3, 0.9),
        Vec3::new(0.3, -1.0 + 1e-3, 0.9),
        Vec3::new(0.3, 0.9, 1.0 - 1e-3),
        Vec3::new(0.3, 0.9, -1.0 + 1e-3),
        Vec3::splat(1.0 - 1e-3), // 1e-3 inside a corner, on each axis
        Vec3::new(0.0, 0.0, 0.0 + 1e-3),
    ];
    let outside = [
        Vec3::new(1.0 + 1e-3, 0.3, -0.2), // 1e-3 outside each face
        Vec3::new(-1.0 - 1e-3, 0.3, -0.2),
        Vec3::new(0.3, 1.0 + 1e-3, 0.9),
        Vec3::new(0.3, -1.0 - 1e-3, 0.9),
        Vec3::new(0.3, 0.9, 1.0 + 1e-3),
        Vec3::new(0.3, 0.9, -1.0 - 1e-3),
        Vec3::new(5.0, 0.0, 0.0), // outside the box, on each side
        Vec3::new(0.0, -5.0, 0.0),
        Vec3::new(0.0, 0.0, 100.0),
        Vec3::new(-3.0, 4.0, -5.0),
        Vec3::splat(1.0 + 1e-3),
    ];
    for p in inside {
        assert!(s.contains(p), "{p} should be inside");
        let w = s.winding_number(p);
        assert!((w - 1.0).abs() < 1e-9, "{p}: w = {w}");
    }
    for p in outside {
        assert!(!s.contains(p), "{p} should be outside");
        let w = s.winding_number(p);
        assert!(w.abs() < 1e-9, "{p}: w = {w}");
    }
}

#[test]
fn sphere_inside_and_outside() {
    let (positions, mesh) = sphere();
    let s = ClosedSurface::new(&positions, &mesh).unwrap();
    for p in [Vec3::ZERO, Vec3::new(0.5, 0.5, 0.5), Vec3::new(0.0, 0.0, 0.95), Vec3::new(-0.97, 0.0, 0.0)] {
        assert!(s.contains(p), "{p}");
        assert!((s.winding_number(p) - 1.0).abs() < 1e-9, "{p}");
    }
    for p in
        [Vec3::new(0.6, 0.6, 0.6), Vec3::new(0.0, 0.0, -1.01), Vec3::new(0.0, 7.0, 0.0), Vec3::splat(-0.9)]
    {
        assert!(!s.contains(p), "{p}");
        assert!(s.winding_number(p).abs() < 1e-9, "{p}");
    }
    // 1e-3 either side of every triangle's centroid and of every vertex (inside the box, so the
    // full winding number decides).
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let n = (b - a).cross(c - a).normalize();
        let m = (a + b + c) / 3.0;
        assert!(s.contains(m - 1e-3 * n), "{m} - 1e-3 n");
        assert!(!s.contains(m + 1e-3 * n), "{m} + 1e-3 n");
        assert!((s.winding_number(m - 1e-3 * n) - 1.0).abs() < 1e-9);
        assert!(s.winding_number(m + 1e-3 * n).abs() < 1e-9);
    }
    for &v in &positions {
        assert!(s.contains(v * (1.0 - 1e-3)), "{v}");
        assert!(!s.contains(v * (1.0 + 1e-3)), "{v}");
    }
}

/// The inscribed polyhedron contains the ellipsoid scaled by `1 − h` and lies inside the ellipsoid
/// (an affine image of the sphere case), so random points agree with the analytic test outside
/// that thin shell.
#[test]
fn flattened_ellipsoid_inside_and_outside() {
    let axes = Vec3::new(1.5, 1.0, 0.4);
    let (positions, mesh) = uv_sphere(16, 32, axes);
    let h = tessellation_error(&uv_sphere(16, 32, Vec3::ONE).0, &mesh) as f32;
    let s = ClosedSurface::new(&positions, &mesh).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (mut inside, mut outside) = (0, 0);
    for _ in 0..5000 {
        let p = random_point(&mut rng, -1.1, 1.1) * axes;
        let r = (p / axes).length(); // < 1 inside the ellipsoid
        if r < 1.0 - h - 1e-4 {
            assert!(s.contains(p), "{p}: r = {r}");
            inside += 1;
        } else if r > 1.0 + 1e-4 {
            assert!(!s.contains(p), "{p}: r = {r}");
            outside += 1;
        }
    }
    assert!(inside > 1500 && outside > 2500, "{inside} {outside}");
    // The thin axis: the center is about 0.4 from the surface, 1e-3 inside the poles is inside.
    let d = s.distance(Vec3::ZERO);
    assert!(d <= 0.4 + 1e-6 && d >= 0.4 * (1.0 - h) - 1e-6, "{d}");
    assert!(s.contains(Vec3::new(0.0, 0.0, 0.4 - 1e-3)));
    assert!(!s.contains(Vec3::new(0.0, 0.0, 0.4 + 1e-3)));
    assert!(s.contains(Vec3::new(1.5 - 1e-3, 0.0, 0.0)));
}

/// Orientation matters: the same triangles clockwise from outside give −1 inside, which is not
/// "inside".
#[test]
fn reversed_orientation_gives_minus_one_and_is_not_inside() {
    for (positions, mesh) in [cube(), sphere()] {
        let rev = reversed(&mesh);
        let s = ClosedSurface::new(&positions, &rev).unwrap();
        for p in [Vec3::ZERO, Vec3::new(0.3, -0.2, 0.5)] {
            let w = s.winding_number(p);
            assert!((w + 1.0).abs() < 1e-9, "{p}: w = {w}");
            assert!(!s.contains(p));
        }
        assert!(s.winding_number(Vec3::new(0.0, 3.0, 0.0)).abs() < 1e-9);
        assert_eq!(penetration(&s, &[Vec3::ZERO]).count, 0);
    }
}

/// An open surface gives fractional winding numbers: from the center of a cube with its +z face
/// removed, the five remaining faces each subtend 4π/6, so w = 5/6, still "inside".
#[test]
fn open_surface_has_fractional_winding() {
    let (positions, mut mesh) = cube();
    mesh.triangles.truncate(10); // drop the two +z triangles
    let s = ClosedSurface::new(&positions, &mesh).unwrap();
    let w = s.winding_number(Vec3::ZERO);
    assert!((w - 5.0 / 6.0).abs() < 1e-9, "{w}");
    assert!(s.contains(Vec3::ZERO));
    // Just above the hole most of the surface is below: small positive, outside.
    let above = Vec3::new(0.0, 0.0, 1.5);
    let w = s.winding_number(above);
    assert!(w > 0.0 && w < 0.5, "{w}");
    assert!(!s.contains(above));
    // 1e-3 below the hole, the hole fills almost half the view: just over 0.5, still inside.
    let w = s.winding_number(Vec3::new(0.0, 0.0, 0.999));
    assert!(w > 0.5 && w < 0.501, "{w}");
    assert!(s.contains(Vec3::new(0.0, 0.0, 0.999)));
}

/// The hierarchical evaluation (fans standing in for far patches) equals the plain sum, on
/// closed, open, non-manifold and degenerate meshes, near and far.
#[test]
fn hierarchical_winding_equals_brute_force() {
    let (sp, sm) = sphere();
    let (cp, cm) = cube();
    // The northern hemisphere (open, with a 32-edge boundary), the cube with one face doubled
    // (edges of multiplicity 2), and the cube with degenerate triangles added.
    let hemisphere = TriangleMesh {
        triangles: sm
            .triangles
            .iter()
            .copied()
            .filter(|t| t.iter().all(|&i| sp[i as usize].z > -1e-6))
            .collect(),
    };
    let mut doubled = cm.clone();
    doubled.triangles.extend_from_slice(&cm.triangles[..2]);
    let (dp, dm) = with_degenerate_triangles();
    let (ep, em) = uv_sphere(16, 32, Vec3::new(1.5, 1.0, 0.4));
    let cases = [
        ("sphere", &sp, &sm, 1.5),
        ("hemisphere", &sp, &hemisphere, 1.5),
        ("sphere_2k", &sphere_2k().0, &sphere_2k().1, 1.5),
        ("ellipsoid", &ep, &em, 1.7),
        ("cube", &cp, &cm, 1.5),
        ("doubled", &cp, &doubled, 1.5),
        ("degenerate", &dp, &dm, 1.5),
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for (name, positions, mesh, extent) in cases {
        let s = ClosedSurface::new(positions, mesh).unwrap();
        let mut points: Vec<Vec3> = (0..500).map(|_| random_point(&mut rng, -extent, extent)).collect();
        // Near the surface: vertices pushed in and out a little.
        points.extend(positions.iter().step_by(3).flat_map(|&v| [v * 0.999, v * 1.001, v * 0.9]));
        points.extend([Vec3::new(0.0, 0.0, 20.0), Vec3::new(-9.0, 4.0, 1.0)]);
        for p in points {
            let (w, b) = (s.winding_number(p), brute_winding(positions, mesh, p));
            assert!((w - b).abs() < 1e-9, "{name} at {p}: {w} vs {b}");
        }
    }
    // The doubled face counts twice at the center.
    let s = ClosedSurface::new(&cp, &doubled).unwrap();
    assert!((s.winding_number(Vec3::ZERO) - 7.0 / 6.0).abs() < 1e-9);
}

// ---------------------------------------------------------------------------------------------
// Distances

#[test]
fn cube_distance_is_analytic() {
    for (lo, hi) in
        [(Vec3::splat(-1.0), Vec3::splat(1.0)), (Vec3::new(0.5, -2.0, 1.0), Vec3::new(3.0, 0.0, 1.5))]
    {
        let (positions, mesh) = cuboid(lo, hi);
        let s = ClosedSurface::new(&positions, &mesh).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let center = (lo + hi) / 2.0;
        let size = (hi - lo).max_element();
        for _ in 0..5000 {
            let p = center + random_point(&mut rng, -size, size);
            let (d, e) = (s.distance(p), box_distance(lo, hi, p));
            assert!((d - e).abs() <= 1e-6 * (1.0 + e), "[{lo}, {hi}] at {p}: {d} vs {e}");
            // The inside test agrees with the box (the random points are never on a face).
            let inside = p.cmpgt(lo).all() && p.cmplt(hi).all();
            assert_eq!(s.contains(p), inside, "{p}");
        }
        // Hand-computed ones.
        if lo == Vec3::splat(-1.0) {
            assert_eq!(s.distance(Vec3::ZERO), 1.0);
            assert!((s.distance(Vec3::new(0.25, 0.5, -0.9)) - 0.1).abs() < 1e-6);
            assert_eq!(s.distance(Vec3::new(3.0, 0.0, 0.0)), 2.0);
            assert!((s.distance(Vec3::new(2.0, 2.0, 0.0)) - 2f32.sqrt()).abs() < 1e-6);
            assert!((s.distance(Vec3::splat(2.0)) - 3f32.sqrt()).abs() < 1e-6);
            assert_eq!(s.distance(Vec3::new(1.0, 0.3, 0.2)), 0.0);
        }
    }
}

#[test]
fn sphere_distance_within_tessellation_error() {
    let (positions, mesh) = sphere();
    let h = tessellation_error(&positions, &mesh);
    // 16 rings × 32 segments: the largest triangles span about 0.28 rad, a sagitta under 0.01.
    assert!(h > 0.005 && h < 0.01, "{h}");
    let s = ClosedSurface::new(&positions, &mesh).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for _ in 0..5000 {
        let p = random_point(&mut rng, -2.0, 2.0);
        let (d, e) = (f64::from(s.distance(p)), (1.0 - f64::from(p.length())).abs());
        assert!((d - e).abs() <= h + 1e-6, "{p}: {d} vs {e} (h = {h})");
    }
    // At the center the nearest points are the flat triangles' centers, 1 - h away at worst.
    let d = f64::from(s.distance(Vec3::ZERO));
    assert!(d < 1.0 && d >= 1.0 - h - 1e-6, "{d}");
    // On a vertex, 0.
    assert_eq!(s.distance(positions[40]), 0.0);
}

// ---------------------------------------------------------------------------------------------
// Penetration

#[test]
fn penetration_hand_computed_on_the_cube() {
    let (positions, mesh) = cube();
    let s = ClosedSurface::new(&positions, &mesh).unwrap();
    let points = [
        Vec3::new(2.0, 0.0, 0.0),      // 0: outside the box
        Vec3::new(0.5, 0.0, 0.0),      // 1: 0.5 from +x
        Vec3::new(f32::NAN, 0.0, 0.0), // 2: never inside
        Vec3::new(0.1, -0.05, 0.02),   // 3: 0.9 from -x... no: from +x, the deepest
        Vec3::new(0.0, 0.0, 1.5),      // 4: outside
        Vec3::new(0.9, 0.2, -0.3),     // 5: 0.1 from +x
        Vec3::new(-0.3, 0.6, 0.0),     // 6: 0.4 from +y
    ];
    let pen = penetration(&s, &points);
    assert_eq!(pen.count, 4);
    assert_eq!(pen.fraction, 4.0 / 7.0);
    assert_eq!(pen.deepest, Some(3));
    assert!((pen.max_depth - 0.9).abs() < 1e-6, "{}", pen.max_depth);

    // No points, and no point inside.
    assert_eq!(penetration(&s, &[]), Penetration::default());
    let none = penetration(&s, &points[..1]);
    assert_eq!(none, Penetration { count: 0, fraction: 0.0, max_depth: 0.0, deepest: None });
    // Every point inside; equal depths keep the first.
    let all = penetration(&s, &[Vec3::new(0.5, 0.0, 0.0), Vec3::new(0.0, -0.5, 0.0), Vec3::ZERO]);
    assert_eq!(all, Penetration { count: 3, fraction: 1.0, max_depth: 1.0, deepest: Some(2) });
    let tie = penetration(&s, &[Vec3::new(0.5, 0.0, 0.0), Vec3::new(0.0, -0.5, 0.0)]);
    assert_eq!(tie.deepest, Some(0));
}

/// 50k random points against the sphere: the polyhedron lies inside the unit ball and contains
/// the ball of radius `1 − h`, so the answer is the analytic one outside that shell (h < 0.01,
/// well within the 0.02 allowed for tessellation).
#[test]
fn random_points_agree_with_the_analytic_sphere() {
    let (positions, mesh) = sphere();
    let h = tessellation_error(&positions, &mesh) as f32;
    assert!(h < 0.02);
    let s = ClosedSurface::new(&positions, &mesh).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let points: Vec<Vec3> = (0..50_000).map(|_| random_point(&mut rng, -1.3, 1.3)).collect();
    let (mut checked, mut shell) = (0, 0);
    let mut inside = 0;
    for &p in &points {
        let r = p.length();
        let c = s.contains(p);
        inside += usize::from(c);
        if r < 1.0 - h - 1e-5 {
            assert!(c, "{p}: |p| = {r}");
            checked += 1;
        } else if r > 1.0 + 1e-5 {
            assert!(!c, "{p}: |p| = {r}");
            checked += 1;
        } else {
            shell += 1;
        }
    }
    assert!(checked > 49_000, "{checked} {shell}");
    // penetration() agrees with contains(), and the deepest point is the one nearest the center.
    let pen = penetration(&s, &points);
    assert_eq!(pen.count, inside);
    assert_eq!(pen.fraction, inside as f32 / 50_000.0);
    let deepest = pen.deepest.unwrap() as usize;
    assert!(points[deepest].length() < 0.05, "{}", points[deepest]);
    assert!(
        (f64::from(pen.max_depth) - (1.0 - f64::from(points[deepest].length()))).abs() <= f64::from(h) + 1e-6
    );
}

// ---------------------------------------------------------------------------------------------
// Bad input

#[test]
fn non_finite_points_are_never_inside() {
    let (positions, mesh) = cube();
    let s = ClosedSurface::new(&positions, &mesh).unwrap();
    let bad = [
        Vec3::new(f32::NAN, 0.0, 0.0),
        Vec3::new(0.0, f32::INFINITY, 0.0),
        Vec3::new(0.0, 0.0, f32::NEG_INFINITY),
        Vec3::splat(f32::NAN),
    ];
    for p in bad {
        assert!(!s.contains(p), "{p}");
        assert_eq!(s.winding_number(p), 0.0, "{p}");
    }
    assert!(s.distance(Vec3::new(f32::NAN, 0.0, 0.0)).is_nan());
    assert_eq!(s.distance(Vec3::new(0.0, f32::INFINITY, 0.0)), f32::INFINITY);
    assert_eq!(penetration(&s, &bad), Penetration::default());
}

/// The cube with degenerate triangles added, all lying in its surface (a degenerate triangle is
/// still a segment of the surface for distances): two with a repeated vertex (a face diagonal,
/// a point), a collinear one (corners 0 and 1 and the middle of their edge, vertex 8) and one
/// across the -z face.
fn with_degenerate_triangles() -> (Vec<Vec3>, TriangleMesh) {
    let (mut positions, mut mesh) = cube();
    positions.push((positions[0] + positions[1]) / 2.0);
    mesh.triangles.extend([[0, 0, 5], [0, 1, 8], [8, 8, 8], [3, 8, 3]]);
    (positions, mesh)
}

#[test]
fn degenerate_triangles_give_no_nan() {
    let (positions, mesh) = with_degenerate_triangles();
    let s = ClosedSurface::new(&positions, &mesh).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let mut points: Vec<Vec3> = (0..2000).map(|_| random_point(&mut rng, -1.5, 1.5)).collect();
    // On the degenerate triangles' lines and points, on and off the cube.
    points.extend([
        Vec3::new(-3.0, -1.0, -1.0),
        Vec3::new(0.5, -1.0, -1.0),
        Vec3::new(0.0, -1.0, -1.0),
        Vec3::splat(-1.0),
        Vec3::splat(0.0),
        Vec3::splat(1.0),
        Vec3::new(2.0, -1.0, -1.0),
    ]);
    for p in points {
        let (w, d) = (s.winding_number(p), s.distance(p));
        assert!(w.is_finite() && d.is_finite(), "{p}: {w} {d}");
        assert!((d - box_distance(Vec3::splat(-1.0), Vec3::splat(1.0), p)).abs() < 1e-6, "{p}: {d}");
        let on_surface = d < 1e-6;
        if !on_surface {
            let inside = p.abs().max_element() < 1.0;
            assert_eq!(s.contains(p), inside, "{p}");
            assert!((w - f64::from(u8::from(inside))).abs() < 1e-9, "{p}: {w}");
        }
    }
    // Nothing but degenerate triangles: no solid angle anywhere, distances to the segments.
    let only = TriangleMesh { triangles: mesh.triangles[12..].to_vec() };
    let s = ClosedSurface::new(&positions, &only).unwrap();
    for p in [Vec3::ZERO, Vec3::new(0.0, -1.0, -1.0), Vec3::new(-3.0, -1.0, -1.0), Vec3::splat(1.0)] {
        assert_eq!(s.winding_number(p), 0.0, "{p}");
        assert!(!s.contains(p));
        assert!(s.distance(p).is_finite());
    }
    // From (0, 1, -1) the nearest is on the segment from corner 3 (1, 1, -1) to (0, -1, -1), at
    // (0.8, 0.6, -1): √0.8 away.
    assert!((s.distance(Vec3::new(0.0, 1.0, -1.0)) - 0.8f32.sqrt()).abs() < 1e-6);
}

#[test]
fn empty_surface() {
    let mesh = TriangleMesh::default();
    let s = ClosedSurface::new(&[], &mesh).unwrap();
    assert_eq!(s.bounds(), None);
    assert_eq!(s.winding_number(Vec3::ZERO), 0.0);
    assert!(!s.contains(Vec3::ZERO));
    assert_eq!(s.distance(Vec3::ZERO), f32::INFINITY);
    assert_eq!(
        penetration(&s, &[Vec3::ZERO]),
        Penetration { count: 0, fraction: 0.0, max_depth: 0.0, deepest: None }
    );
}

#[test]
fn out_of_range_index_is_a_typed_error() {
    let (positions, mut mesh) = cube();
    mesh.triangles.push([0, 1, 8]);
    let err = ClosedSurface::new(&positions, &mesh).err().unwrap();
    assert!(matches!(err, voxcollide::Error::Invalid { .. }), "{err:?}");
    assert!(err.to_string().contains("triangle 12 must index one of the 8 positions"), "{err}");
}

// ---------------------------------------------------------------------------------------------
// Speed

/// 20k points × 1984 triangles must not be quadratic-slow, even in a debug build (a plain sum
/// would be 40M solid angles). Prints the time; asserts only the answers.
#[test]
fn speed_20k_points_2k_triangles() {
    run_points_against_sphere_2k(20_000);
}

/// The 50k × 2k measurement for the report (`cargo test --release --test geometry -- --nocapture
/// fifty`); ignored in ordinary runs to keep debug test time low.
#[test]
#[ignore = "timing only: run with --release --ignored --nocapture"]
fn fifty_k_points_2k_triangles_timing() {
    run_points_against_sphere_2k(50_000);
}

fn run_points_against_sphere_2k(n: usize) {
    let (positions, mesh) = sphere_2k();
    let h = tessellation_error(&positions, &mesh) as f32;
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    // Points in the surface's box, so every one pays for a winding number.
    let points: Vec<Vec3> = (0..n).map(|_| random_point(&mut rng, -1.0, 1.0)).collect();
    let start = Instant::now();
    let s = ClosedSurface::new(&positions, &mesh).unwrap();
    let built = start.elapsed();
    let pen = penetration(&s, &points);
    let total = start.elapsed();
    // The two halves of penetration() apart: the inside test of every point, the distance of the
    // inside ones.
    let start = Instant::now();
    let inside: Vec<Vec3> = points.iter().copied().filter(|&p| s.contains(p)).collect();
    let contains = start.elapsed();
    let start = Instant::now();
    let depth = inside.iter().map(|&p| s.distance(p)).fold(0.0, f32::max);
    let distance = start.elapsed();
    println!(
        "{n} points x {} triangles: build {:.2} ms, build + penetration {:.1} ms ({} inside); \
         contains {:.1} ms, distance {:.1} ms",
        mesh.triangles.len(),
        built.as_secs_f64() * 1e3,
        total.as_secs_f64() * 1e3,
        pen.count,
        contains.as_secs_f64() * 1e3,
        distance.as_secs_f64() * 1e3,
    );
    assert_eq!((inside.len(), depth), (pen.count, pen.max_depth));
    let expected = points.iter().filter(|p| p.length() < 1.0 - h).count();
    let shell = points.iter().filter(|p| (1.0 - h..=1.0).contains(&p.length())).count();
    assert!(pen.count >= expected && pen.count <= expected + shell, "{} vs {expected} + {shell}", pen.count);
}

// ---------------------------------------------------------------------------------------------
// From one frame to the next: a hierarchy refit, and a watch that asks only what may change

/// The sphere's vertices at frame `t` of a squash-and-wobble: flattened by up to 40 %, bulged
/// sideways and shifted, so that the surface sweeps through points that were outside.
fn wobbled(rest: &[Vec3], t: f32) -> Vec<Vec3> {
    let squash = 1.0 - 0.4 * (0.5 - 0.5 * (3.0 * t).cos());
    rest.iter()
        .map(|p| {
            let bulge = 1.0 + 0.3 * (1.0 - squash) * (1.0 - p.z * p.z);
            Vec3::new(p.x * bulge + 0.2 * t, p.y * bulge, p.z * squash + 0.05 * (5.0 * p.x + t).sin())
        })
        .collect()
}

/// A refit hierarchy answers as a fresh one: exactly at the positions it was built on, and at
/// a deformed frame the same inside answers (winding numbers within rounding) and the same
/// distances; a hierarchy of another mesh is refused with a typed error.
#[test]
fn a_refit_hierarchy_answers_as_a_fresh_build() {
    let (rest, mesh) = sphere();
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let points: Vec<Vec3> = (0..2000).map(|_| random_point(&mut rng, -1.6, 1.6)).collect();
    let fresh = ClosedSurface::new(&rest, &mesh).unwrap();
    let same = ClosedSurface::refit(&rest, &mesh, ClosedSurface::new(&rest, &mesh).unwrap().into_hierarchy())
        .unwrap();
    for &p in &points {
        assert_eq!(fresh.winding_number(p).to_bits(), same.winding_number(p).to_bits(), "{p}");
        assert_eq!(fresh.distance(p).to_bits(), same.distance(p).to_bits(), "{p}");
    }
    let mut hierarchy = fresh.into_hierarchy();
    let mut insides = 0;
    for frame in 1..=6 {
        let now = wobbled(&rest, frame as f32 * 0.35);
        let refit = ClosedSurface::refit(&now, &mesh, hierarchy).unwrap();
        let built = ClosedSurface::new(&now, &mesh).unwrap();
        for &p in &points {
            let (a, b) = (refit.winding_number(p), built.winding_number(p));
            assert!((a - b).abs() < 1e-9, "frame {frame}, {p}: {a} vs {b}");
            assert_eq!(refit.contains(p), built.contains(p), "frame {frame}, {p}");
            assert_eq!(refit.distance(p), built.distance(p), "frame {frame}, {p}");
            insides += usize::from(built.contains(p));
        }
        hierarchy = refit.into_hierarchy();
    }
    assert!(insides > 1000, "the test's points should be inside often: {insides}");
    // Another mesh: refused, not answered wrongly. So is the same count of triangles wired
    // otherwise (its fans would stand for triangles that are not there).
    let (cube_positions, cube_mesh) = cube();
    let err = ClosedSurface::refit(&cube_positions, &cube_mesh, hierarchy.clone()).unwrap_err();
    assert!(matches!(err, voxcollide::Error::Invalid { what: "surface hierarchy", .. }), "{err:?}");
    let mut rewired = mesh.clone();
    rewired.triangles[0].swap(1, 2);
    let err = ClosedSurface::refit(&rest, &rewired, hierarchy).unwrap_err();
    assert!(matches!(err, voxcollide::Error::Invalid { what: "surface hierarchy", .. }), "{err:?}");
}

/// A hierarchy goes stale once the surface has grown or shrunk by more than a quarter.
#[test]
fn a_hierarchy_goes_stale_when_the_surface_changes_size() {
    let (rest, mesh) = sphere();
    let h = ClosedSurface::new(&rest, &mesh).unwrap().into_hierarchy();
    assert!(!h.stale());
    let grown: Vec<Vec3> = rest.iter().map(|p| 1.1 * *p).collect();
    let h = ClosedSurface::refit(&grown, &mesh, h).unwrap().into_hierarchy();
    assert!(!h.stale(), "10 % is not stale");
    let doubled: Vec<Vec3> = rest.iter().map(|p| 2.0 * *p).collect();
    let h = ClosedSurface::refit(&doubled, &mesh, h).unwrap().into_hierarchy();
    assert!(h.stale(), "twice the size is");
}

/// The watch gives exactly [`penetration`]'s answer at every frame of a surface sweeping
/// through points (and of points moving through it), while asking fewer points once it has
/// their distances; on a surface with a hole it asks every point every time.
#[test]
fn a_penetration_watch_answers_as_penetration_and_asks_fewer_points() {
    let (rest, mesh) = sphere();
    let mut rng = ChaCha8Rng::seed_from_u64(22);
    let base: Vec<Vec3> = (0..3000).map(|_| random_point(&mut rng, -2.5, 2.5)).collect();
    let mut watch = PenetrationWatch::default();
    let (mut asked, mut seen_inside) = (0, 0);
    for frame in 0..40 {
        let t = frame as f32 * 0.05;
        let now = wobbled(&rest, t);
        // The points drift too, each its own way.
        let points: Vec<Vec3> = base
            .iter()
            .enumerate()
            .map(|(i, p)| *p + 0.02 * t * Vec3::new((i % 7) as f32 - 3.0, 0.0, 1.0))
            .collect();
        let surface = ClosedSurface::new(&now, &mesh).unwrap();
        let expected = penetration(&surface, &points);
        assert_eq!(watch.penetration(&surface, &points), expected, "frame {frame}");
        seen_inside += expected.count;
        if frame > 0 {
            asked += watch.asked;
        }
    }
    assert!(seen_inside > 0);
    assert!(asked < 39 * base.len() / 2, "the watch asked {asked} of {} points", 39 * base.len());
    // A hole: every point, every time.
    let (positions, mut open) = cube();
    open.triangles.truncate(10);
    let surface = ClosedSurface::new(&positions, &open).unwrap();
    let mut watch = PenetrationWatch::default();
    for _ in 0..3 {
        assert_eq!(watch.penetration(&surface, &base), penetration(&surface, &base));
        assert_eq!(watch.asked, base.len());
    }
}

/// Of equally deep points in different parallel chunks, the first is the deepest, as on one
/// thread.
#[test]
fn the_first_of_equally_deep_points_is_the_deepest_across_chunks() {
    let (positions, mesh) = cube();
    let s = ClosedSurface::new(&positions, &mesh).unwrap();
    let mut points = vec![Vec3::splat(5.0); 1000];
    points[700] = Vec3::new(0.5, 0.0, 0.0);
    points[300] = Vec3::new(0.0, -0.5, 0.0);
    let p = penetration(&s, &points);
    assert_eq!((p.count, p.deepest), (2, Some(300)));
    assert_eq!(PenetrationWatch::default().penetration(&s, &points), p);
}

/// A ray meets a surface where the brute force over every triangle says so: on a 2,000-triangle
/// sphere from random points inside and outside it in random directions, and at the corners
/// (along a cube's edge, through its corner, from its face, a zero or non-finite direction).
#[test]
fn rays_meet_the_surface_where_every_triangle_asked_says_so() {
    let (positions, mesh) = sphere_2k();
    let s = ClosedSurface::new(&positions, &mesh).unwrap();
    let brute = |p: Vec3, d: Vec3| {
        mesh.triangles.iter().any(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize].as_dvec3());
            voxcollide_sim::geometry::line_crossing(p.as_dvec3(), d.as_dvec3(), [a, b, c], 1e-9)
                .is_some_and(|t| t >= 0.0)
        })
    };
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (mut met, mut missed) = (0, 0);
    for _ in 0..2000 {
        let p = random_point(&mut rng, -2.0, 2.0);
        let d = random_point(&mut rng, -1.0, 1.0);
        let hit = s.ray_hits(p, d);
        assert_eq!(hit, brute(p, d), "{p} along {d}");
        if hit {
            met += 1
        } else {
            missed += 1
        }
        // From inside, every ray leaves through the surface.
        if s.contains(p) {
            assert!(hit, "{p} along {d} from inside");
        }
    }
    assert!(met > 200 && missed > 200, "{met} met, {missed} missed");
    let (cp, cm) = cube();
    let c = ClosedSurface::new(&cp, &cm).unwrap();
    assert!(c.ray_hits(Vec3::new(1.0, 1.0, -3.0), Vec3::Z), "along an edge");
    assert!(c.ray_hits(Vec3::splat(3.0), Vec3::splat(-1.0)), "through a corner");
    assert!(c.ray_hits(Vec3::new(0.2, 0.3, 1.0), Vec3::Z), "from its face, outward");
    assert!(!c.ray_hits(Vec3::new(0.0, 0.0, 1.5), Vec3::Z), "away from it");
    assert!(!c.ray_hits(Vec3::new(1.01, 0.0, -3.0), Vec3::Z), "beside it");
    assert!(!c.ray_hits(Vec3::ZERO, Vec3::ZERO), "no direction");
    assert!(!c.ray_hits(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::Z), "NaN");
    assert!(!c.ray_hits(Vec3::ZERO, Vec3::new(f32::INFINITY, 0.0, 0.0)), "infinite");
}
