//! A breast from a scan (docs/design.md §14): the tissue between a skin sheet and a chest wall,
//! inside a box, from generated parametric breasts; its held vertices, its landmarks and its
//! volume; and each bad input named.

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod adapter;
mod common;

use common::shapes::{breast_skin, height_sheet, write_stl};
use voxcollide_sim::Mode;
use voxcollide_sim::build::build_world;
use voxcollide_sim::scene_file::SceneFile;

/// A scene of a breast between `skin.stl` and `wall.stl` in `dir`, with `box_` and `extra` keys.
fn scene(dir: &std::path::Path, min: [f64; 3], max: [f64; 3], extra: &str) -> String {
    let _ = dir;
    format!(
        r#"
units = "mm"
[time]
integrator = "implicit"
[[body]]
name = "breast"
kind = "soft"
shape = {{ between = {{ outer = "skin.stl", inner = "wall.stl", min = {min:?}, max = {max:?} }} }}
spacing = 6
material = {{ model = "neo-hookean", young_kpa = 3, poisson = 0.45 }}
{extra}
"#
    )
}

fn folder(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("voxcollide-between-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A skin 15 mm over a flat chest wall, a 40 mm mound of radius 60 mm on it; the wall and skin
/// over a square of `half` a side.
fn write_breast(dir: &std::path::Path, half: f64) {
    write_stl(&dir.join("skin.stl"), &height_sheet(half, 48, breast_skin(15.0, 40.0, 60.0, 0.0)));
    write_stl(&dir.join("wall.stl"), &height_sheet(half, 8, |_, _| 0.0));
}

fn read(dir: &std::path::Path, text: &str) -> Result<voxcollide_sim::build::Built, voxcollide::Error> {
    let path = dir.join("breast.toml");
    std::fs::write(&path, text).unwrap();
    build_world(&SceneFile::read(&path)?)
}

#[test]
fn the_tissue_between_a_skin_and_a_chest_wall_is_held_on_the_wall_and_box() {
    let dir = folder("ok");
    write_breast(&dir, 120.0);
    let built = read(
        &dir,
        &scene(
            &dir,
            [-90.0, -90.0, -10.0],
            [90.0, 90.0, 70.0],
            "landmarks = { nipple = [0, 0, 55], side = [70, 0, 15] }",
        ),
    )
    .unwrap();
    let body = &built.world.bodies[0];
    let h = 6.0f32;
    // Every vertex lies between the wall (z = 0) and the skin, to a cell, inside the box.
    let skin = breast_skin(15.0, 40.0, 60.0, 0.0);
    for p in &body.pos {
        let reach = 2.0 * f64::from(h); // a cell corner, where the skin slopes steeply
        assert!(p.z >= -h && f64::from(p.z) <= skin(f64::from(p.x), f64::from(p.y)) + reach, "{p} outside");
        assert!(p.x.abs() <= 90.05 && p.y.abs() <= 90.05, "{p} outside the box");
    }
    // Held: the layer on the wall, and the box's sides; free: the rest, the mound's top.
    for (p, m) in body.pos.iter().zip(&body.mode) {
        if p.z <= 0.0 || p.x.abs() >= 90.0 - 1e-3 || p.y.abs() >= 90.0 - 1e-3 {
            assert_eq!(*m, Mode::Pinned, "{p} should be held");
        }
    }
    let top = body.pos.iter().enumerate().max_by(|a, b| a.1.z.total_cmp(&b.1.z)).unwrap().0;
    assert_eq!(body.mode[top], Mode::Free);
    // Its volume: the region's, its cells kept by their centres.
    let exact: f64 = {
        let (n, step) = (360, 180.0 / 360.0);
        (0..n * n)
            .map(|k| {
                let (x, y) =
                    (-90.0 + step * (f64::from(k % n) + 0.5), -90.0 + step * (f64::from(k / n) + 0.5));
                skin(x, y) * step * step
            })
            .sum()
    };
    let volume = body.surface.volume(&body.pos);
    eprintln!("volume {volume:.0} mm³ of {exact:.0} ({} vertices)", body.len());
    assert!((volume / exact - 1.0).abs() < 0.03, "volume {volume} of {exact}");
    // At other spacings too: the corners snapped onto the skin and the wall hold the region's
    // volume, not a staircase's.
    for spacing in [4.5, 7.5, 9.0, 11.0] {
        let text = scene(&dir, [-90.0, -90.0, -10.0], [90.0, 90.0, 70.0], "")
            .replace("spacing = 6", &format!("spacing = {spacing}"));
        let b = &read(&dir, &text).unwrap().world.bodies[0];
        let v = b.surface.volume(&b.pos);
        eprintln!("spacing {spacing}: volume {v:.0} mm³ of {exact:.0} ({} vertices)", b.len());
        assert!((v / exact - 1.0).abs() < 0.05, "spacing {spacing}: volume {v} of {exact}");
    }
    // Landmarks, each on the surface near where it was given.
    let marks = &built.notes[0].landmarks;
    assert_eq!(marks.iter().map(|l| l.name.as_str()).collect::<Vec<_>>(), ["nipple", "side"]);
    for l in marks {
        let at = l.at(body, &body.pos);
        assert!(at.distance(l.given) <= 2.0 * h, "{} at {at}, given {}", l.name, l.given);
    }
}

/// The body is shown by the skin as scanned (docs/design.md §14), not its lattice's cells: the
/// scan's triangles inside the box, beside the lattice's faces that are not on the skin side,
/// each of the skin's points carried by its cell; landmarks sit on it.
#[test]
fn the_tissue_is_shown_by_the_scanned_skin_carried_by_its_lattice() {
    use voxcollide::glam::Vec3;
    let dir = folder("skin");
    write_breast(&dir, 120.0);
    let skin_at = breast_skin(15.0, 40.0, 60.0, 0.0);
    // The whole mound, and a box whose side cuts through its flank (where the side's top
    // corners stand in front of the sloping skin).
    for (spacing, low) in [(6.0f32, -90.0f32), (9.0, -90.0), (7.0, -90.0), (6.0, -31.0)] {
        let text = scene(
            &dir,
            [f64::from(low), -90.0, -10.0],
            [90.0, 90.0, 70.0],
            "landmarks = { nipple = [3, -2, 60] }",
        );
        // The lattice's extent: a whole number of cells from the box's corner (175 mm at 7).
        let side = spacing * (180.0 / spacing).floor();
        let across = spacing * ((90.0 - low) / spacing).floor();
        let built = read(&dir, &text.replace("spacing = 6", &format!("spacing = {spacing}"))).unwrap();
        let body = &built.world.bodies[0];
        let skin = body.skin.as_ref().expect("a between body carries its skin");
        let n = body.len() as u32;
        let area = |points: &[Vec3], t: &[u32; 3]| {
            let [a, b, c] = t.map(|k| points[k as usize]);
            0.5 * (b - a).cross(c - a)
        };
        // The sheet: the scan over the lattice, whole (its area seen from the front is the
        // lattice's, 180 × 180 mm at 6 and 9, with no gap and no overlap, and no lip past its
        // side faces), every point on the scan's facets.
        let sheet = &skin.sheet;
        let front: f32 = sheet.mesh.triangles.iter().map(|t| area(&sheet.rest, t).z).sum();
        assert!((front / (side * across) - 1.0).abs() < 1e-4, "{spacing}: the sheet covers {front} mm²");
        for p in &sheet.rest {
            let inside = |v: f32, low: f32, side: f32| (low - 1e-2..=low + side + 1e-2).contains(&v);
            assert!(
                inside(p.x, low, across) && inside(p.y, -90.0, side),
                "{spacing}: {p} outside the lattice"
            );
            // Within the facets' chord of the smooth skin (5 mm facets).
            let z = skin_at(f64::from(p.x), f64::from(p.y)) as f32;
            assert!((p.z - z).abs() < 0.6, "{spacing}: {p} off the skin at {z}");
        }
        // Shown: the sheet, and of the lattice's faces none that faces the front from under the
        // skin (those the sheet replaces): the lattice's faces add no area seen from the front.
        let (points, shown) = body.shown_at(&body.pos);
        let lattice_front: f32 = shown
            .triangles
            .iter()
            .filter(|t| t.iter().all(|&k| k < n))
            .map(|t| area(&points, t).z.max(0.0))
            .sum();
        assert!(
            lattice_front < 0.01 * front,
            "{spacing}: the lattice shows {lattice_front} mm² to the front"
        );
        let carried: Vec<[u32; 3]> = sheet.mesh.triangles.iter().map(|t| t.map(|k| k + n)).collect();
        assert!(carried.iter().all(|t| shown.triangles.contains(t)), "{spacing}: the whole sheet is shown");
        // Watertight, as contacts and the penetration check need: every edge used once each way
        // (the seam between the sheet's rim and the box's sides stitched), enclosing the
        // lattice's own volume.
        let mut edges = std::collections::HashMap::<(u32, u32), u32>::new();
        for t in &shown.triangles {
            for e in 0..3 {
                *edges.entry((t[e], t[(e + 1) % 3])).or_default() += 1;
            }
        }
        let open = edges.iter().filter(|&(&(u, v), &c)| c != 1 || edges.get(&(v, u)) != Some(&1)).count();
        assert_eq!(open, 0, "{spacing}: {open} edges not used once each way");
        let volume = |points: &[Vec3], mesh: &voxcollide_sim::mesh::TriangleMesh| -> f32 {
            mesh.triangles
                .iter()
                .map(|t| t.map(|k| points[k as usize]))
                .map(|[a, b, c]| a.dot(b.cross(c)) / 6.0)
                .sum()
        };
        let (enclosed, lattice) = (volume(&points, shown), volume(&body.pos, &body.surface));
        assert!(
            (enclosed / lattice - 1.0).abs() < 0.02,
            "{spacing}: {enclosed} mm³ against the lattice's {lattice}"
        );
        // No shown point stands in front of her skin (the box's sides end on it).
        for (k, p) in points
            .iter()
            .enumerate()
            .filter(|(k, _)| shown.triangles.iter().flatten().any(|v| *v as usize == *k))
        {
            let z = skin_at(f64::from(p.x), f64::from(p.y)) as f32;
            assert!(
                p.z <= z + 0.6,
                "{spacing}: shown point {k} at {p} stands {} in front of the skin",
                p.z - z
            );
        }
        // Carried: a displacement that varies across the body moves each point of the skin as
        // its cell moves, within what the field changes over a cell.
        let field = |p: Vec3| Vec3::new(0.0, 0.0, 0.05 * p.x) + Vec3::new(0.03 * p.z, 0.0, 0.0);
        let moved: Vec<Vec3> = body.rest_pos.iter().map(|p| *p + field(*p)).collect();
        let (now, _) = body.shown_at(&moved);
        for (k, r) in sheet.rest.iter().enumerate() {
            let error = now[n as usize + k].distance(*r + field(*r));
            assert!(error <= 0.06 * spacing, "{spacing}: skin point {r} off its cells' motion by {error}");
        }
        // The landmark on the scan (on a facet, not a cell's face a snap away).
        let nipple = &built.notes[0].landmarks[0];
        let at = nipple.at(body, body.start());
        let off = sheet
            .mesh
            .triangles
            .iter()
            .map(|t| {
                let corners = t.map(|k| sheet.rest[k as usize].as_dvec3());
                voxcollide_sim::geometry::closest_point(at.as_dvec3(), &corners).distance(at.as_dvec3())
            })
            .fold(f64::INFINITY, f64::min);
        assert!(off < 1e-3, "{spacing}: the nipple at {at}, {off} off the scan");
        assert!(nipple.at(body, &moved).distance(at + field(at)) <= 0.06 * spacing);
    }
}

/// Contacts meet her scanned skin, not her lattice's cells (docs/design.md §14). Over the
/// mound, at a coarse 9 mm, a small ball sunk half a millimetre into the skin is pushed out
/// wherever it is set down, by about that depth, and the reaction lands on her lattice's
/// vertices, equal and opposite. Her lattice's own face, terraced a fraction of a cell either
/// side of the skin, would have missed it in many places (it did, before the skin was shown to
/// contacts), or pushed it by another depth.
#[test]
fn a_contact_meets_her_scanned_skin_not_her_lattices_cells() {
    use voxcollide::glam::Vec3;
    use voxcollide_sim::contact::{SurfaceContact, SurfaceForces};
    use voxcollide_sim::{MassSpring, Material, SurfacePenalty};
    let dir = folder("skin-contact");
    write_breast(&dir, 120.0);
    let text =
        scene(&dir, [-90.0, -90.0, -10.0], [90.0, 90.0, 70.0], "").replace("spacing = 6", "spacing = 9");
    let built = read(&dir, &text).unwrap();
    let body = &built.world.bodies[0];
    let skin = body.skin.as_ref().expect("a between body carries its skin");
    let mut lattice = body.clone();
    lattice.skin = None;
    let material = Material { mass: 1.0, stiffening: 0.0, spring_damping: 0.0, damping: 0.0 };
    let penalty = SurfacePenalty { stiffness: 100.0, gap: 0.0, reach: 2.0, margin: 0.0 };
    let press = |probe: &MassSpring, tissue: &MassSpring| {
        let mut contact = SurfaceContact::new(penalty, probe, tissue).unwrap();
        let mut out = SurfaceForces::default();
        let stats = contact.step(probe, tissue, &mut out);
        (stats, out)
    };
    let (mut tried, mut missed, mut other, mut balanced) = (0, 0, 0, 0);
    // Every fourth point of the sheet away from the box's sides.
    for p in skin.sheet.rest.iter().step_by(4).filter(|p| p.x.abs() < 70.0 && p.y.abs() < 70.0) {
        // Its lowest point half a millimetre under the skin, along the skin's normal there.
        let normal = {
            let skin_at = breast_skin(15.0, 40.0, 60.0, 0.0);
            let (x, y, e) = (f64::from(p.x), f64::from(p.y), 1e-3);
            let dx = (skin_at(x + e, y) - skin_at(x - e, y)) / (2.0 * e);
            let dy = (skin_at(x, y + e) - skin_at(x, y - e)) / (2.0 * e);
            Vec3::new(-dx as f32, -dy as f32, 1.0).normalize()
        };
        let probe = voxcollide_sim::bodies::ellipsoid_shell(
            *p + 1.0 * normal,
            Vec3::splat(1.5),
            6,
            12,
            2.0,
            10.0,
            material,
        )
        .unwrap();
        tried += 1;
        let (with, out) = press(&probe, body);
        assert!(with.a_pushed > 0, "at {p}: the skin did not push the ball sunk into it");
        assert!(
            with.deepest > 0.3 && with.deepest < 0.8,
            "at {p}: pushed by {} for a ball 0.5 under the skin",
            with.deepest
        );
        let (up, down): (Vec3, Vec3) = (out.force_a.iter().sum(), out.force_b.iter().sum());
        assert!(up.dot(normal) > 0.0, "at {p}: pushed {up}, not out");
        // On her vertices, inward, as much as on the ball but for what falls on the ones held
        // on her chest wall (a held vertex feels nothing).
        assert!(
            down.dot(normal) < 0.0 && down.length() <= up.length() * 1.001,
            "at {p}: {up} on the ball, {down} on her"
        );
        if (up + down).length() <= 1e-3 * up.length() {
            balanced += 1;
        }
        let (alone, _) = press(&probe, &lattice);
        if alone.a_pushed == 0 {
            missed += 1;
        } else if (alone.deepest - with.deepest).abs() > 0.25 {
            other += 1;
        }
    }
    eprintln!(
        "{tried} balls ({balanced} over free vertices only): the lattice's face alone missed {missed}, and pushed {other} by another depth"
    );
    // (Off the mound her tissue is 15 mm thick, under two cells: there the skin's cells reach
    // down to the vertices held on the wall.)
    assert!(
        tried > 50 && balanced > tried / 4,
        "{tried} balls, {balanced} with the reaction all on free vertices"
    );
    assert!(missed + other > tried / 10, "the lattice's face lies on the skin: the test shows nothing");
}

/// On the device too: a rigid ball pressed into her skin under the explicit integrator steps
/// the CPU's bits, the skin's points written each step on the device as a carried surface's are,
/// and no step waits for the host.
#[test]
fn on_the_device_a_ball_pressed_into_her_skin_steps_the_cpus_bits() {
    use voxcollide::glam::Vec3;
    let Some(ctx) = adapter::gpu() else { return };
    let dir = folder("skin-gpu");
    write_breast(&dir, 120.0);
    // Over the mound's flank, 36 mm from its apex (the skin at z = 28.4): 2.5 mm into it.
    let ball = r#"
[[body]]
name = "ball"
kind = "rigid"
shape = { sphere = 6 }
spacing = 2
position = [35, 10, 36.4]
motion = [{ t = 0.0, position = [35, 10, 36.4] }, { t = 0.006, position = [35, 10, 31.9] }]
[[contact]]
a = "ball"
b = "breast"
"#;
    let text = scene(&dir, [-90.0, -90.0, -10.0], [90.0, 90.0, 70.0], ball)
        .replace("spacing = 6", "spacing = 9")
        .replace("integrator = \"implicit\"", "integrator = \"explicit\"\nsteps = 300");
    let built = read(&dir, &text).unwrap();
    assert!(built.world.bodies[0].skin.is_some() && built.world.contacts[0].surface().is_some());
    let mut cpu = voxcollide_sim::CpuWorld::new(built.world.clone()).unwrap();
    let mut gpu = voxcollide_sim::GpuWorld::new(&ctx, built.world).unwrap();
    let bits = |v: &[Vec3]| v.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
    let (mut pushed, mut deepest) = (0, 0.0f32);
    for step in 1..=300 {
        cpu.step().unwrap();
        gpu.step().unwrap();
        let c = cpu.surface_stats[0];
        pushed += c.a_pushed + c.b_pushed;
        deepest = deepest.max(c.deepest);
        if step % 50 == 0 {
            assert_eq!(gpu.host_waits(), 0, "step {step} waited");
            gpu.sync().unwrap();
            assert_eq!(voxcollide_sim::contact::SurfaceStats { rebuilt: false, ..c }, gpu.surface_stats()[0]);
            for (k, (c, g)) in cpu.world.bodies.iter().zip(&gpu.world.bodies).enumerate() {
                assert_eq!(bits(&c.pos), bits(&g.pos), "body {k} at step {step}");
                assert_eq!(bits(&c.vel), bits(&g.vel), "body {k} at step {step}");
            }
        }
    }
    assert!(pushed > 100 && deepest > 0.0, "the ball never pressed ({pushed} pushes)");
}

#[test]
fn bad_between_input_is_named_and_nothing_is_built() {
    let dir = folder("bad");
    write_breast(&dir, 120.0);
    let box_ = ([-90.0, -90.0, -10.0], [90.0, 90.0, 70.0]);
    let error = |text: String| read(&dir, &text).map(|_| ()).unwrap_err().to_string();
    // The wall in front of the skin: the files swapped.
    let swapped = scene(&dir, box_.0, box_.1, "")
        .replace("outer = \"skin.stl\", inner = \"wall.stl\"", "outer = \"wall.stl\", inner = \"skin.stl\"");
    let e = error(swapped);
    assert!(
        e.contains("breast.toml") && e.contains("shape.between.inner") && e.contains("in front of"),
        "{e}"
    );
    // A box above the skin holds no tissue.
    let e = error(scene(&dir, [-90.0, -90.0, 60.0], [90.0, 90.0, 90.0], ""));
    assert!(e.contains("shape.between") && e.contains("no tissue"), "{e}");
    // A landmark far from the surface.
    let e = error(scene(&dir, box_.0, box_.1, "landmarks = { nipple = [0, 0, 120] }"));
    assert!(e.contains("landmarks") && e.contains("nipple"), "{e}");
    // A skin that does not reach across the box.
    write_breast(&dir, 60.0);
    std::fs::write(dir.join("wall.stl"), std::fs::read(dir.join("wall.stl")).unwrap()).unwrap();
    write_stl(&dir.join("wall.stl"), &height_sheet(120.0, 8, |_, _| 0.0));
    let e = error(scene(&dir, box_.0, box_.1, ""));
    assert!(e.contains("shape.between.outer") && e.contains("does not cover"), "{e}");
    // A missing file, and a box turned inside out.
    let e = error(scene(&dir, box_.0, box_.1, "").replace("wall.stl", "nowhere.stl"));
    assert!(e.contains("shape.between.inner") && e.contains("nowhere.stl"), "{e}");
    let e = error(scene(&dir, [90.0, -90.0, -10.0], [-90.0, 90.0, 70.0], ""));
    assert!(e.contains("shape.between.max"), "{e}");
    // It lies where its surfaces are: a position, rotation or scale is refused, not ignored.
    for (extra, key) in
        [("position = [0, 0, 5]", "position"), ("rotation = [0, 90, 0]", "rotation"), ("scale = 2", "scale")]
    {
        let e = error(scene(&dir, box_.0, box_.1, extra));
        assert!(e.contains(&format!("body[0].{key}")) && e.contains("does not apply"), "{key}: {e}");
    }
}

/// A skin layer by depth (docs/design.md §14): `layers = [{ region = { depth = d } }]` takes the
/// tetrahedra within `d` of the skin, not of the chest wall or the box's sides; a depth that
/// is not a positive length is named.
#[test]
fn a_skin_layer_by_depth_stiffens_the_tissue_under_the_skin_only() {
    let dir = folder("skin");
    write_breast(&dir, 120.0);
    let layer = "layers = [{ region = { depth = 4 }, young_kpa = 30 }]";
    let built = read(&dir, &scene(&dir, [-90.0, -90.0, -10.0], [90.0, 90.0, 70.0], layer)).unwrap();
    let body = &built.world.bodies[0];
    let e = body.elements.as_ref().unwrap();
    let skin = breast_skin(15.0, 40.0, 60.0, 0.0);
    let (mut stiff, mut deep_stiff, mut total) = (0, 0, 0);
    for (t, m) in e.tets.iter().zip(&e.modulus) {
        let c = t.iter().map(|&v| body.rest_pos[v as usize]).sum::<voxcollide::glam::Vec3>() / 4.0;
        total += 1;
        if *m > 1.0 {
            stiff += 1;
            assert!((m - 10.0).abs() < 1e-4, "modulus ratio {m}");
            // Under the skin: within the depth (and a cell's slope) of it, never at the wall.
            let below = skin(f64::from(c.x), f64::from(c.y)) - f64::from(c.z);
            if below > 4.0 + 6.0 {
                deep_stiff += 1;
            }
        }
    }
    eprintln!("{stiff} of {total} tetrahedra in the skin layer, {deep_stiff} deeper than a cell under it");
    assert!(stiff > total / 20 && stiff < total / 2, "{stiff} of {total}");
    assert!(deep_stiff * 50 < stiff, "{deep_stiff} of {stiff} stiff tetrahedra lie deep");
    let e = read(
        &dir,
        &scene(&dir, [-90.0, -90.0, -10.0], [90.0, 90.0, 70.0], &layer.replace("depth = 4", "depth = -1")),
    )
    .map(|_| ())
    .unwrap_err()
    .to_string();
    assert!(e.contains("depth") && e.contains("positive"), "{e}");
}

/// Tissue presets (docs/patient.md): a body of `preset = "fat"` and a skin layer of
/// `preset = "skin"` take their published moduli and ν = 0.49; a key beside a preset overrides
/// it; an unknown preset and a layer with neither modulus nor preset are named.
#[test]
fn tissue_presets_give_published_parameters() {
    use voxcollide_sim::scene_file::{Fixed, Preset};
    let text = |material: &str, layers: &str| {
        format!(
            "[[body]]\nname = \"b\"\nkind = \"soft\"\nshape = {{ box = [20, 20, 20] }}\nspacing = 5\nmaterial = {material}\n{layers}\n"
        )
    };
    let s = SceneFile::parse(
        "p.toml",
        &text(
            "{ model = \"neo-hookean\", preset = \"fat\" }",
            "layers = [{ region = { depth = 3 }, preset = \"skin\" }, { region = { below = { z = -5 } }, preset = \"muscle\" }]",
        ),
    )
    .unwrap();
    let b = &s.bodies[0];
    assert_eq!((b.material.young_kpa, b.material.poisson, b.material.density), (3.25, 0.49, 1000.0));
    assert_eq!(b.material.preset, Some(Preset::Fat));
    assert_eq!(b.layers[0].young_kpa, 4.0);
    assert_eq!(b.layers[0].region, Fixed::Depth(3.0));
    assert_eq!(b.layers[1].young_kpa, 80.0);
    let s = SceneFile::parse("p.toml", &text("{ preset = \"gland\", poisson = 0.45 }", "")).unwrap();
    assert_eq!((s.bodies[0].material.young_kpa, s.bodies[0].material.poisson), (3.24, 0.45));
    for (material, layers, key) in [
        ("{ preset = \"bone\" }", "", "material"),
        ("{ preset = \"fat\" }", "layers = [{ region = { depth = 3 } }]", "layers"),
    ] {
        let e = SceneFile::parse("p.toml", &text(material, layers)).unwrap_err().to_string();
        assert!(e.contains("p.toml") && e.contains(key), "{key}: {e}");
    }
}

/// A shell placed on a chest wall that gives no `material` is 30 kPa, not a body's 3 kPa (it
/// would crumple under her tissue, docs/patient.md); one that gives a material, or is not
/// placed, keeps it or the body's default.
#[test]
fn a_placed_shell_without_a_material_is_stiffer_than_her_fat() {
    use voxcollide_sim::scene_file::{MaterialSpec, PLACED_SHELL_MATERIAL};
    let text = |implant: &str| {
        format!(
            "units = \"mm\"\n[[body]]\nname = \"breast\"\nkind = \"soft\"\nshape = {{ between = {{ outer = \"skin.stl\", inner = \"wall.stl\", min = [-60, -60, -5], max = [60, 60, 40] }} }}\nspacing = 8\nlandmarks = {{ nipple = [0, 0, 30] }}\n[[body]]\nname = \"implant\"\nkind = \"shell\"\nshape = {{ implant = {{ volume_ml = 40, base_mm = 60, projection_mm = 20 }} }}\nspacing = 8\n{implant}\n"
        )
    };
    let material = |implant: &str| SceneFile::parse("p.toml", &text(implant)).unwrap().bodies[1].material;
    assert_eq!(material("place = { under = \"breast.nipple\" }"), PLACED_SHELL_MATERIAL);
    assert_eq!(PLACED_SHELL_MATERIAL.young_kpa, 30.0);
    assert_eq!(
        PLACED_SHELL_MATERIAL,
        MaterialSpec { young_kpa: 30.0, ..MaterialSpec::default() },
        "a body's default but for its modulus"
    );
    let given = material("place = { under = \"breast.nipple\" }\nmaterial = { young_kpa = 12.0 }");
    assert_eq!(given, MaterialSpec { young_kpa: 12.0, ..MaterialSpec::default() });
    assert_eq!(material(""), MaterialSpec::default());
    assert_eq!(MaterialSpec::default().young_kpa, 3.0);
}

/// docs/design.md §15's example writes no `[[contact]]`: a placed implant that no contact pairs
/// with her tissue gets the default one (the implant binned, her tissue probing), and the run
/// says so; a contact the file gives, in either order, is kept as the only one.
#[test]
fn a_placed_implant_with_no_contact_gets_the_default_one_with_her_tissue() {
    use voxcollide_sim::scene_file::{Auto, ContactSpec, ResponseSpec};
    let dir = folder("implied");
    write_breast(&dir, 120.0);
    let read_file = |text: &str| {
        let path = dir.join("breast.toml");
        std::fs::write(&path, text).unwrap();
        SceneFile::read(&path).unwrap()
    };
    let bare = placed(&dir, "place = { under = \"breast.nipple\" }", "");
    let file = read_file(&bare);
    assert_eq!(file.contacts.len(), 1, "{:?}", file.contacts);
    let ContactSpec { a, b, response, voxel_size, .. } = file.contacts[0];
    assert_eq!((a, b), (1, 0), "the implant indexed, her tissue probing");
    assert_eq!((response, voxel_size), (ResponseSpec::default(), Auto::Auto));
    assert!(file.bodies[1].place.as_ref().unwrap().contact_added);
    let built = build_world(&file).unwrap();
    assert_eq!(built.world.contacts.len(), 1);
    assert!(
        built.notes[1].remarks.iter().any(|r| r.contains("no [[contact]] pairs it with \"breast\"")),
        "{:?}",
        built.notes[1].remarks
    );
    for given in ["a = \"implant\"\nb = \"breast\"", "a = \"breast\"\nb = \"implant\""] {
        let file = read_file(&format!("{bare}\n[[contact]]\n{given}\n"));
        assert_eq!(file.contacts.len(), 1, "{given}: {:?}", file.contacts);
        assert!(!file.bodies[1].place.as_ref().unwrap().contact_added, "{given}");
        let built = build_world(&file).unwrap();
        assert!(!built.notes[1].remarks.iter().any(|r| r.contains("[[contact]]")), "{given}");
    }
    // An unplaced shell beside her is not paired with her by anyone but the file.
    let unplaced = placed(&dir, "position = [0, 0, 200]", "");
    assert!(read_file(&unplaced).contacts.is_empty());
}

/// An implant `extra`-placed on the parametric breast's chest wall (docs/design.md §15).
fn placed(dir: &std::path::Path, place: &str, extra: &str) -> String {
    let box_ = ([-90.0, -90.0, -10.0], [90.0, 90.0, 70.0]);
    scene(dir, box_.0, box_.1, "landmarks = { nipple = [0, 0, 55] }")
        + &format!(
            r#"
[[body]]
name = "implant"
kind = "shell"
shape = {{ implant = {{ volume_ml = 200, base_mm = 100, profile = "moderate" }} }}
spacing = 6
{place}
{extra}
"#
        )
}

/// A 200 mL implant placed under the nipple, filling, in contact with the breast.
fn filling(dir: &std::path::Path) -> String {
    placed(dir, "place = { under = \"breast.nipple\" }", "inflate = { volume_ml = 200, ramp = 0.3 }")
        + "[[contact]]\na = \"implant\"\nb = \"breast\"\n"
}

/// The world of `text`, its implant started as `voxcollide compare` starts it: deflated to a
/// fifth of its height (30 mm: 100 mm × 0.30, moderate), sunk behind the wall by as much,
/// rising as it fills (docs/design.md §15).
fn deflated(dir: &std::path::Path, text: &str) -> voxcollide_sim::build::Built {
    let path = dir.join("breast.toml");
    std::fs::write(&path, text).unwrap();
    let mut file = SceneFile::read(&path).unwrap();
    let height = 30.0;
    file.bodies[1].flatten = Some(0.2);
    file.bodies[1].sink = 0.2 * height + 0.3;
    build_world(&file).unwrap()
}

#[test]
fn an_implant_is_placed_flat_on_a_flat_wall_and_its_pocket_let_go() {
    let dir = folder("placed");
    write_breast(&dir, 120.0);
    let built = read(&dir, &placed(&dir, "place = { under = \"breast.nipple\", margin = 5 }", "")).unwrap();
    let (tissue, shell) = (&built.world.bodies[0], &built.world.bodies[1]);
    let wall = shell.wall.as_ref().unwrap();
    assert!(wall.normal.distance(voxcollide::glam::Vec3::Z) < 1e-4, "{:?}", wall.normal);
    assert!(wall.origin.length() < 1e-3, "{:?}", wall.origin);
    let lowest = shell.pos.iter().map(|p| p.z).fold(f32::MAX, f32::min);
    assert!(lowest.abs() < 1e-4, "the base on the wall: {lowest}");
    // The pocket: held wall vertices within 50 + 5 mm of the axis let go; the rest held.
    for (p, m) in tissue.rest_pos.iter().zip(&tissue.mode) {
        let r = p.truncate().length();
        if p.z < 1.0 && r < 50.0 && p.x.abs() < 89.0 && p.y.abs() < 89.0 {
            assert_eq!(*m, Mode::Free, "{p} under the base is held");
        }
        if p.z < 1.0 && r > 55.0 + 1e-3 {
            assert_eq!(*m, Mode::Pinned, "{p} outside the pocket was let go");
        }
    }
}

#[test]
fn a_base_that_would_reach_past_her_border_moves_across_the_wall_away_from_it() {
    let dir = folder("within");
    write_breast(&dir, 120.0);
    let with = |marks: &str, within: &str| {
        let text = scene(&dir, [-90.0, -90.0, -10.0], [90.0, 90.0, 70.0], marks)
            + &format!(
                "[[body]]\nname = \"implant\"\nkind = \"shell\"\nshape = {{ implant = {{ volume_ml = 200, base_mm = 100, profile = \"moderate\" }} }}\nspacing = 6\nplace = {{ under = \"breast.nipple\", within = {within} }}\n"
            );
        read(&dir, &text).unwrap()
    };
    // Her medial border 30 mm from the nipple: the base (radius 50) moves 20 mm the other way,
    // and the pocket with it; the note says so.
    let built = with("landmarks = { nipple = [0, 0, 55], medial = [-30, 0, 35] }", "[\"breast.medial\"]");
    let wall = built.world.bodies[1].wall.as_ref().unwrap();
    assert!(wall.origin.distance(voxcollide::glam::Vec3::new(20.0, 0.0, 0.0)) < 0.05, "{:?}", wall.origin);
    let (lo, hi) =
        built.world.bodies[1].pos.iter().fold((f32::MAX, f32::MIN), |(l, h), p| (l.min(p.x), h.max(p.x)));
    assert!((lo + 30.0).abs() < 0.5 && (hi - 70.0).abs() < 0.5, "the base spans {lo} .. {hi}");
    let tissue = &built.world.bodies[0];
    for (p, m) in tissue.rest_pos.iter().zip(&tissue.mode) {
        if p.z < 1.0 && (p.x < -41.0 || p.x > 81.0) && p.x.abs() < 89.0 && p.y.abs() < 89.0 {
            assert_eq!(*m, Mode::Pinned, "{p} past the pocket was let go");
        }
    }
    let said = built.notes[1].remarks.join("\n");
    assert!(said.contains("moved 20.0 mm") && said.contains("[\"medial\"]"), "{said}");
    // A border the base does not reach asks nothing.
    let built = with("landmarks = { nipple = [0, 0, 55], medial = [-60, 0, 15] }", "[\"breast.medial\"]");
    assert!(built.world.bodies[1].wall.as_ref().unwrap().origin.length() < 1e-3);
    assert!(!built.notes[1].remarks.join("\n").contains("moved"));
    // Borders 80 mm apart cannot hold a base 100 mm wide: centred between them, with a warning.
    let built = with(
        "landmarks = { nipple = [0, 0, 55], medial = [-30, 0, 35], lateral = [50, 0, 17.68] }",
        "[\"breast.medial\", \"breast.lateral\"]",
    );
    let origin = built.world.bodies[1].wall.as_ref().unwrap().origin;
    // (Her landmarks lie on the lattice's face, within a few tenths of a millimetre of those.)
    let said = built.notes[1].remarks.join("\n");
    assert!(origin.distance(voxcollide::glam::Vec3::new(10.0, 0.0, 0.0)) < 0.3, "{origin:?} {said}");
    let past: f32 = said.split(" mm past").next().unwrap().rsplit(' ').next().unwrap().parse().unwrap();
    assert!(said.contains("warning: its base is too wide") && (past - 10.0).abs() < 0.3, "{said}");
    // A border at the landmark it stands under is no border.
    let text = scene(
        &dir,
        [-90.0, -90.0, -10.0],
        [90.0, 90.0, 70.0],
        "landmarks = { nipple = [0, 0, 55], areola = [2, 0, 54.9] }",
    ) + "[[body]]\nname = \"implant\"\nkind = \"shell\"\nshape = { implant = { volume_ml = 200, base_mm = 100, profile = \"moderate\" } }\nspacing = 6\nplace = { under = \"breast.nipple\", within = [\"breast.areola\"] }\n";
    let e = read(&dir, &text).map(|_| ()).unwrap_err().to_string();
    assert!(
        e.contains("breast.toml") && e.contains("body[1].place.within") && e.contains("within a spacing"),
        "{e}"
    );
}

#[test]
fn a_bad_placement_is_named_by_key() {
    let dir = folder("bad-place");
    write_breast(&dir, 120.0);
    let error = |text: String| match read(&dir, &text) {
        Ok(_) => panic!("built:\n{text}"),
        Err(e) => e.to_string(),
    };
    for (place, extra, says) in [
        ("place = { under = \"nipple\" }", "", "must name a body and its landmark"),
        ("place = { under = \"chest.nipple\" }", "", "no body is named \"chest\""),
        ("place = { under = \"breast.navel\" }", "", "no landmark \"navel\""),
        ("place = { under = \"breast.nipple\", margin = -1 }", "", "0 or more"),
        ("place = { under = \"breast.nipple\", friction = -0.5 }", "", "Coulomb's coefficient"),
        ("place = { under = \"breast.nipple\", friction = nan }", "", "place.friction = NaN"),
        ("place = { under = \"breast.nipple\", side = 1 }", "", "unknown field"),
        ("place = { under = \"breast.nipple\" }", "position = [0, 0, 5]", "give neither"),
        (
            "place = { under = \"breast.nipple\", within = [\"medial\"] }",
            "",
            "must name a landmark of \"breast\"",
        ),
        (
            "place = { under = \"breast.nipple\", within = [\"slab.top\"] }",
            "",
            "must name a landmark of \"breast\"",
        ),
        ("place = { under = \"breast.nipple\", within = [\"breast.medial\"] }", "", "no landmark \"medial\""),
        ("place = { under = \"breast.nipple\", within = [\"breast.nipple\"] }", "", "not a border"),
        ("place = { under = \"breast.nipple\", within = \"breast.nipple\" }", "", "invalid type"),
    ] {
        let e = error(placed(&dir, place, extra));
        assert!(
            e.contains("breast.toml") && e.contains("body[1].place") && e.contains(says),
            "{place} {extra}: {e}"
        );
    }
    // Wider than the box: it does not fit on the wall inside it.
    let wide =
        placed(&dir, "place = { under = \"breast.nipple\" }", "").replace("base_mm = 100", "base_mm = 190");
    let e = error(wide);
    assert!(e.contains("body[1].place.under") && e.contains("does not fit"), "{e}");
    // Only a shell is placed, and only on a body between a skin and a chest wall.
    let e = error(scene(
        &dir,
        [-90.0, -90.0, -10.0],
        [90.0, 90.0, 70.0],
        "place = { under = \"breast.nipple\" }",
    ));
    assert!(e.contains("body[0].place") && e.contains("only a shell"), "{e}");
    let flat = placed(&dir, "place = { under = \"slab.top\" }", "")
        + "[[body]]\nname = \"slab\"\nkind = \"soft\"\nshape = { box = [10, 10, 10] }\nspacing = 5\nlandmarks = { top = [0, 0, 5] }\n";
    let e = error(flat);
    assert!(e.contains("body[1].place") && e.contains("no chest wall"), "{e}");
}

#[test]
fn a_filled_implant_on_the_wall_adds_its_own_volume_and_never_goes_behind_the_wall() {
    use voxcollide::glam::Vec3;
    // As `voxcollide compare` starts it: deflated to a fifth of its height, sunk behind the
    // wall by as much, rising as it fills (docs/design.md §15).
    let dir = folder("filled");
    write_breast(&dir, 120.0);
    let text = filling(&dir);
    let text = text.replace("integrator = \"implicit\"", "integrator = \"implicit\"\nsettle = true");
    let built = deflated(&dir, &text);
    let faces = built.notes[0].wall_faces.clone().unwrap();
    assert_eq!(built.world.pockets.len(), 1, "the pocket is sealed");
    let mut world = voxcollide_sim::CpuWorld::new(built.world).unwrap();
    for step in 0..300 {
        world.step().unwrap();
        if step % 20 != 19 {
            continue;
        }
        let (tissue, implant) = (&world.world.bodies[0], &world.world.bodies[1]);
        let wall = implant.wall.as_ref().unwrap();
        // Past the fill's ramp the wall holds both (before it, the implant rises to it).
        if step > 100 {
            for (b, name) in [(implant, "implant"), (tissue, "tissue")] {
                for (p, m) in b.pos.iter().zip(&b.mode) {
                    if *m == Mode::Free
                        && let Some(a) = wall.above(*p, 0.0)
                    {
                        assert!(a > -1e-3, "step {step}: the {name}'s {p} is {a} behind the wall");
                    }
                }
            }
        }
    }
    let (tissue, implant) = (&world.world.bodies[0], &world.world.bodies[1]);
    let between = |at: &[Vec3]| voxcollide_sim::between::volume_between(tissue, &faces, tissue.start(), at);
    let gain = (between(&tissue.pos) - between(tissue.start())) / 1e3;
    let filled = implant.enclosed_volume() / 1e3;
    eprintln!("{gain:.1} mL added by an implant holding {filled:.1} mL");
    assert!((filled / 200.0 - 1.0).abs() < 0.02, "filled to {filled} mL");
    assert!((gain / filled - 1.0).abs() < 0.05, "{gain} mL added by {filled} mL");
}

#[test]
fn the_gpu_world_refuses_a_curved_wall_by_name() {
    let Some(ctx) = adapter::gpu() else { return };
    let dir = folder("gpu-wall");
    write_breast(&dir, 120.0);
    let built = read(&dir, &placed(&dir, "place = { under = \"breast.nipple\" }", "")).unwrap();
    let e = voxcollide_sim::GpuWorld::new(&ctx, built.world).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("curved chest wall") && e.contains("--backend cpu"), "{e}");
    assert!(e.contains("\"breast\", \"implant\""), "the bodies by their names: {e}");
}

/// A breast on a chest curved like a barrel across her (radius 150 mm), written to `dir`, and
/// `filling`'s scene on it standing, settling, its implant placed with `place`.
fn on_a_barrel_standing(dir: &std::path::Path, place: &str) -> String {
    let chest = |y: f64| 150.0 - (150.0f64 * 150.0 - y * y).sqrt();
    let skin = breast_skin(15.0, 40.0, 60.0, 0.0);
    write_stl(&dir.join("skin.stl"), &height_sheet(120.0, 48, |x, y| skin(x, y) - chest(y)));
    write_stl(&dir.join("wall.stl"), &height_sheet(120.0, 48, |_, y| -chest(y)));
    filling(dir)
        .replace("place = { under = \"breast.nipple\" }", place)
        .replace("integrator = \"implicit\"", "integrator = \"implicit\"\nsettle = true")
        .replace("units = \"mm\"", "units = \"mm\"\n[world]\ngravity = [0, -9.81, 0]\nup = \"y\"")
        .replace("min = [-90.0, -90.0, -10.0]", "min = [-90.0, -90.0, -40.0]")
}

#[test]
fn on_a_curved_wall_standing_the_wall_does_not_cut_the_steps_short() {
    use voxcollide::glam::Vec3;
    // A chest curved like a barrel across her (radius 150 mm), standing: her weight draws the
    // tissue and the implant down and around the curve, sliding on the wall. A vertex that
    // slid a rounding off a curved wall was once taken as in flight, pulled back by its load at
    // full speed, and the whole step split into parts to keep that motion within what a contact
    // sees arrive: five or six parts a step here. Resting on the wall within a twentieth of
    // its grid's cell (`Wall::rests`; docs/patient.md, "Planning on a patient"), it slides on,
    // and a step takes about two.
    let dir = folder("curved");
    let text = on_a_barrel_standing(&dir, "place = { under = \"breast.nipple\" }");
    let built = deflated(&dir, &text);
    let centre = |b: &voxcollide_sim::MassSpring| b.pos.iter().copied().sum::<Vec3>() / b.len() as f32;
    let start = centre(&built.world.bodies[1]);
    let mut world = voxcollide_sim::CpuWorld::new(built.world).unwrap();
    let mut parts = Vec::new();
    for _ in 0..200 {
        world.step().unwrap();
        parts.push(voxcollide_sim::Simulation::parts(&world).map_or(1, |p| p.substeps));
    }
    let (tissue, implant) = (&world.world.bodies[0], &world.world.bodies[1]);
    let wall = implant.wall.as_ref().unwrap();
    for (b, name) in [(implant, "implant"), (tissue, "tissue")] {
        for (p, m) in b.pos.iter().zip(&b.mode) {
            if *m == Mode::Free
                && let Some(a) = wall.above(*p, 0.0)
            {
                assert!(a > -1e-3, "the {name}'s {p} is {a} behind the wall");
            }
        }
    }
    let most = parts[100..].iter().copied().max().unwrap_or(1);
    eprintln!(
        "the implant's centre moved {:?}; parts a step over the last 100: at most {most}",
        centre(implant) - start
    );
    let mean = parts[100..].iter().sum::<u32>() as f32 / 100.0;
    assert!(mean <= 3.0, "a step took {mean} parts: {:?}", &parts[100..]);
}

#[test]
fn standing_the_implant_grips_the_sloping_chest_wall_as_its_friction_says() {
    // A chest curved like a barrel across her (radius 150 mm), standing: the implant's weight
    // lies along the wall, and the fill presses its base into it. Sliding freely (friction 0),
    // the base walks down the wall; at a smooth shell's friction (0.46, the default) the
    // vertices pressed onto the wall stay where they are while the force along it is within
    // the friction's cone (docs/patient.md, "The implant grips the wall"). It grips once it
    // is filled; over the next 120 steps its base moved 1.47 mm sliding freely and 0.05 mm
    // gripping.
    let dir = folder("grip");
    let walk = |friction: &str| {
        let text = on_a_barrel_standing(&dir, &format!("place = {{ under = \"breast.nipple\"{friction} }}"));
        let built = deflated(&dir, &text);
        let mut world = voxcollide_sim::CpuWorld::new(built.world).unwrap();
        // Filled (its ramp is 0.3 s), then 120 steps on: its base spreads freely while it fills.
        while world.time < 0.3 {
            world.step().unwrap();
        }
        let start = world.world.bodies[1].pos.clone();
        for _ in 0..120 {
            world.step().unwrap();
        }
        // The base: the implant's vertices on the wall at the end; how far they went.
        let implant = &world.world.bodies[1];
        let wall = implant.wall.as_ref().unwrap();
        let base: Vec<usize> = (0..implant.len())
            .filter(|&i| wall.above(implant.pos[i], 0.0).is_some_and(|a| a < 1.0))
            .collect();
        assert!(base.len() > 20, "{} vertices on the wall", base.len());
        base.iter().map(|&i| start[i].distance(implant.pos[i])).sum::<f32>() / base.len() as f32
    };
    let (free, gripped) = (walk(", friction = 0"), walk(""));
    eprintln!("filled, the base moved {free} mm sliding freely, {gripped} mm gripping");
    assert!(
        free > 0.3 && gripped < 0.1 * free,
        "gripping, the base moved {gripped} mm; sliding freely {free} mm"
    );
}

#[test]
fn the_pockets_suction_falls_as_it_draws_and_the_solve_takes_its_stiffness() {
    use voxcollide::glam::Vec3;
    // The implicit solve takes a sealed pocket's suction as `−K_s = (K/V)·w·wᵀ`, `w` the force
    // per unit suction on each vertex. That holds if moving the vertices along `w` shuts the
    // pocket's space by `Σ|w|²` per unit: checked here on a filled implant's pocket, its
    // tissue drawn off the implant so that the suction draws.
    let dir = folder("suction");
    write_breast(&dir, 120.0);
    let text = filling(&dir);
    let built = read(&dir, &text).unwrap();
    let mut bodies = built.world.bodies.clone();
    let pocket = built.world.pockets[0].clone();
    // Shrink the implant to an eighth of its volume, and lift the pocket's tissue 5 mm off
    // the wall: a space opens beside it, and the suction draws.
    let c = bodies[1].pos.iter().copied().sum::<Vec3>() / bodies[1].len() as f32;
    for p in &mut bodies[1].pos {
        *p = c + 0.5 * (*p - c);
    }
    for &i in pocket.faces.iter().flatten() {
        bodies[0].pos[i as usize].z += 5.0;
    }
    assert!(pocket.void(&bodies) > 0.0 && pocket.suction(&bodies) > 0.0);
    let r = pocket.linearised(&bodies, pocket.suction(&bodies));
    assert!(r.stiffness > 0.0);
    assert!((r.stiffness - pocket.stiffness / pocket.volume as f32).abs() <= 1e-6 * r.stiffness);
    // Its force is the suction times `w`, on both bodies.
    let mut forces: Vec<Vec<Vec3>> = bodies.iter().map(|b| vec![Vec3::ZERO; b.len()]).collect();
    let mut drawing = pocket.clone();
    drawing.hold = 0.0;
    drawing.add_forces(&bodies, &mut forces);
    let p = drawing.suction(&bodies);
    for (k, f) in forces.iter().enumerate() {
        for (i, f) in f.iter().enumerate() {
            assert!(f.distance(p * r.direction[k][i]) <= 1e-4 * (1.0 + f.length()), "body {k} vertex {i}");
        }
    }
    // Along `w` the space shuts by Σ|w|² per unit.
    let norm2: f64 = r.direction.iter().flatten().map(|w| f64::from(w.length_squared())).sum();
    let step = 1e-3 / norm2.sqrt() as f32; // a thousandth of a millimetre, over all vertices
    let before = pocket.void(&bodies);
    for (b, w) in bodies.iter_mut().zip(&r.direction) {
        for (p, w) in b.pos.iter_mut().zip(w) {
            *p += step * *w;
        }
    }
    let shut = before - pocket.void(&bodies);
    let want = f64::from(step) * norm2;
    eprintln!("shut {shut:.4} mm³ along w, against Σ|w|²·ε = {want:.4}");
    assert!((shut / want - 1.0).abs() < 0.05, "shut {shut} against {want}");
}

#[test]
fn an_implant_nearly_a_cylinder_started_flat_is_warned_of_and_a_rounder_one_is_not() {
    // 200 mL on a 100 mm base at 30 mm (moderate): profile exponent 0.178, rounder than the
    // warning's 0.1; 230 mL on the same base and projection: 0.024, nearly the cylinder
    // (235.6 mL). Both started as `voxcollide compare` starts them, flattened to a fifth.
    let dir = folder("cylinder");
    write_breast(&dir, 120.0);
    let warned = |text: &str| -> Vec<String> {
        let built = deflated(&dir, text);
        built.notes[1].remarks.iter().filter(|r| r.starts_with("warning: ")).cloned().collect()
    };
    let round = filling(&dir);
    assert!(warned(&round).iter().all(|w| !w.contains("cylinder")), "{:?}", warned(&round));
    let full = round.replace("volume_ml = 200", "volume_ml = 230");
    assert_ne!(full, round);
    let w = warned(&full);
    let w = w.iter().find(|w| w.contains("nearly a cylinder")).unwrap_or_else(|| panic!("{w:?}"));
    // It names the exponent, the flattening and what would hold the volume rounder: the base
    // or the projection of a cylinder 1.1 times the volume (2·√(1.1·230e3 / (π·30)) = 103.9 mm;
    // 1.1·230e3 / (π·50²) = 32.2 mm).
    for said in ["profile exponent 0.024", "flattened to 20 %", "a base of 104 mm", "a projection of 32 mm"] {
        assert!(w.contains(said), "{said:?} not in {w}");
    }
    // Not flattened (as `voxcollide run` builds a scene not placed), nothing is said.
    let path = dir.join("breast.toml");
    std::fs::write(&path, &full).unwrap();
    let built = build_world(&SceneFile::read(&path).unwrap()).unwrap();
    assert!(built.notes[1].remarks.iter().all(|r| !r.contains("cylinder")), "{:?}", built.notes[1].remarks);
}

/// A plan written in centimetres is the plan written in millimetres (docs/patient.md, "The same
/// plan in other units and axes"): the same breast, wall, box, landmark and spacings, every
/// length in the file and its meshes a tenth, the implant's catalogue sizes still in mm and mL.
/// Built, the two are the same to a rounding: the same lattice, held and let go alike (in cm
/// the box's 18 / 0.6 rounded to 29.999998 and, floored, the lattice lost its far faces: 3,515
/// vertices against 3,698). Stepped, they part: the contact's voxel is a power of two in file
/// units (8 mm against 1 cm), and its reach and the solve's margin follow it; 40 steps later
/// the fill is the same to 0.3 % (145.8 mL against 146.2; to a thousandth with the shell at a
/// body's 3 kPa, before a placed shell's default was 30 kPa).
#[test]
fn a_plan_in_centimetres_is_the_plan_in_millimetres() {
    use voxcollide_sim::mesh_io::Surface;
    let dir = folder("units");
    write_breast(&dir, 120.0);
    let cm = dir.join("cm");
    std::fs::create_dir_all(&cm).unwrap();
    let tenth =
        |s: Surface| Surface { positions: s.positions.iter().map(|p| *p * 0.1).collect(), mesh: s.mesh };
    write_stl(&cm.join("skin.stl"), &tenth(height_sheet(120.0, 48, breast_skin(15.0, 40.0, 60.0, 0.0))));
    write_stl(&cm.join("wall.stl"), &tenth(height_sheet(120.0, 8, |_, _| 0.0)));
    let mm_text = filling(&dir);
    let cm_text = mm_text
        .replace("units = \"mm\"", "units = \"cm\"")
        .replace(
            "min = [-90.0, -90.0, -10.0], max = [90.0, 90.0, 70.0]",
            "min = [-9.0, -9.0, -1.0], max = [9.0, 9.0, 7.0]",
        )
        .replace("nipple = [0, 0, 55]", "nipple = [0, 0, 5.5]")
        .replace("spacing = 6\n", "spacing = 0.6\n");
    assert_eq!(cm_text.matches("0.6\n").count(), 2, "{cm_text}");
    assert!(cm_text.contains("[-9.0, -9.0, -1.0]") && cm_text.contains("5.5]"), "{cm_text}");
    // Started as `voxcollide compare` starts it ([`deflated`]: a fifth of its 30 mm, sunk 6.3 mm).
    let start = |folder: &std::path::Path, text: &str, unit: f64| {
        let path = folder.join("breast.toml");
        std::fs::write(&path, text).unwrap();
        let mut file = SceneFile::read(&path).unwrap();
        file.bodies[1].flatten = Some(0.2);
        file.bodies[1].sink = 6.3 / unit;
        voxcollide_sim::CpuWorld::new(build_world(&file).unwrap().world).unwrap()
    };
    let (mut mm, mut cm) = (start(&dir, &mm_text, 1.0), start(&cm, &cm_text, 10.0));
    let mut far = 0.0f32;
    for (a, b) in mm.world.bodies.iter().zip(&cm.world.bodies) {
        assert_eq!(a.pos.len(), b.pos.len(), "the same lattice");
        assert_eq!(a.mode, b.mode, "the same vertices held and let go");
        for (p, q) in a.pos.iter().zip(&b.pos) {
            far = far.max(p.distance(*q * 10.0));
        }
    }
    assert!(far < 1e-3, "built {far} mm apart");
    assert_eq!(mm.world.pockets[0].faces, cm.world.pockets[0].faces, "the same pocket");
    let voxels = [&mm, &cm].map(|w| w.world.contacts[0].grid.voxel_size());
    assert_eq!(voxels, [8.0, 1.0], "powers of two in file units");
    for _ in 0..40 {
        mm.step().unwrap();
        cm.step().unwrap();
    }
    let filled = [&mm, &cm].map(|w| w.world.bodies[1].enclosed_volume());
    assert!((filled[0] - filled[1] * 1e3).abs() < 5e-3 * filled[0], "{filled:?}");
}
