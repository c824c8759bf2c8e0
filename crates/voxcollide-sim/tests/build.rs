//! Scene files built into worlds and run: a rigid sphere indenting a soft block (mm, kPa), an
//! inflating shell lifting a layer, a soft body filling an STL surface; the physical units give
//! the block the Young's modulus the file asks for.

mod common;

use voxcollide::Error;
use voxcollide::glam::Vec3;
use voxcollide_sim::build::build_world;
use voxcollide_sim::scene_file::SceneFile;
use voxcollide_sim::{CpuWorld, Mode};

const INDENT: &str = r#"
units = "mm"
[time]
integrator = "explicit"
duration = 0.4
[[body]]
name = "block"
kind = "soft"
shape = { box = [40, 40, 10] }
spacing = 2.5
material = { young_kpa = 3.0, poisson = 0.45, density = 1000, damping = 0.5 }
fixed = [{ below = { z = -4.9 } }]
[[body]]
name = "ball"
kind = "rigid"
shape = { sphere = 8 }
spacing = 2.0
position = [0, 0, 14]
motion = [{ t = 0.0, position = [0, 0, 14] }, { t = 0.3, position = [0, 0, 11] }]
[[contact]]
a = "ball"
b = "block"
"#;

#[test]
fn a_rigid_sphere_indents_a_soft_block() {
    let file = SceneFile::parse("indent.toml", INDENT).unwrap();
    let built = build_world(&file).unwrap();
    let w = &built.world;
    assert_eq!(w.names, ["block", "ball"]);
    assert_eq!(w.bodies[0].len(), 17 * 17 * 5, "a 40 × 40 × 10 box at 2.5 mm");
    assert!(w.bodies[0].mode.iter().filter(|m| **m == Mode::Pinned).count() == 17 * 17, "the bottom layer");
    assert!(w.bodies[1].mode.iter().all(|m| *m == Mode::Driven), "a rigid body is driven");
    assert!(built.dt > 0.0 && built.steps == (0.4 / f64::from(built.dt)).ceil() as u64);
    let mut cpu = CpuWorld::new(built.world.clone()).unwrap();
    let top = |b: &voxcollide_sim::MassSpring| {
        b.pos
            .iter()
            .zip(&b.rest_pos)
            .filter(|(_, r)| r.z > 4.9 && r.x.abs() < 1.0 && r.y.abs() < 1.0)
            .map(|(p, r)| p.z - r.z)
            .fold(0.0, f32::min)
    };
    let mut contacts = 0;
    for _ in 0..built.steps {
        cpu.step().unwrap();
        contacts += cpu.reports[0].colliding_b.len();
    }
    // The ball's bottom went from 6 mm to 3 mm, 2 mm into the block's top at 5 mm, and the
    // contact holds the block's vertices about the contact radius (0.75 × 2.5 mm) off the ball.
    let depth = -top(&cpu.world.bodies[0]);
    eprintln!(
        "dt {:.3e}, {} steps, {contacts} contacts, the block's top went down {depth:.3} mm",
        built.dt, built.steps
    );
    assert!(contacts > 0);
    assert!(depth > 2.0 && depth < 2.0 + 1.875 + 0.5, "{depth}");
}

#[test]
fn an_inflating_shell_lifts_a_layer() {
    let text = r#"
units = "mm"
[time]
steps = 1500
[[body]]
name = "skin"
kind = "soft"
shape = { box = [60, 60, 6] }
spacing = 3
fixed = [{ rim = 1 }]
[[body]]
name = "expander"
kind = "shell"
shape = { ellipsoid = [15, 15, 6] }
spacing = 4
position = [0, 0, -9.5]
inflate = { pressure_kpa = 0.5, ramp = 0.1 }
material = { young_kpa = 30 }
fixed = [{ below = { z = -14 } }]
[[contact]]
a = "expander"
b = "skin"
direction = "plane-normal"
"#;
    let file = SceneFile::parse("expander.toml", text).unwrap();
    let built = build_world(&file).unwrap();
    let mut cpu = CpuWorld::new(built.world).unwrap();
    for _ in 0..built.steps {
        cpu.step().unwrap();
    }
    let skin = &cpu.world.bodies[0];
    let lift = skin.pos.iter().zip(&skin.rest_pos).map(|(p, r)| p.z - r.z).fold(f32::MIN, f32::max);
    eprintln!("the skin rose {lift:.3} mm over {} steps of {:.2e} s", built.steps, built.dt);
    assert!(lift > 0.5, "{lift}");
}

#[test]
fn a_soft_body_fills_an_stl_surface() {
    let dir = std::env::temp_dir().join(format!("voxcollide-build-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let kidney = common::shapes::kidney();
    common::shapes::write_stl(&dir.join("kidney.stl"), &kidney);
    let path = dir.join("scene.toml");
    std::fs::write(
        &path,
        "[[body]]\nname = \"kidney\"\nkind = \"soft\"\nmesh = \"kidney.stl\"\nspacing = 5\nrotation = [0, 0, 90]\nposition = [0, 0, 100]\n",
    )
    .unwrap();
    let file = SceneFile::read(&path).unwrap();
    let built = build_world(&file).unwrap();
    let body = &built.world.bodies[0];
    let (coverage, uncovered) = built.notes[0].coverage.unwrap();
    eprintln!("{:?}", built.notes[0]);
    assert!(body.len() > 500 && (0.5..1.0).contains(&coverage) && uncovered == 0);
    // Rotated a quarter turn about z and lifted: long along y now, around z = 100.
    let (lo, hi) = body.pos.iter().fold((Vec3::MAX, Vec3::MIN), |(l, h), p| (l.min(*p), h.max(*p)));
    assert!(hi.y - lo.y > 1.5 * (hi.x - lo.x), "{lo} {hi}");
    assert!((0.5 * (lo.z + hi.z) - 100.0).abs() < 5.0, "{lo} {hi}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn implants_have_their_catalogue_volume_base_and_projection() {
    // Round and anatomical implants of three sizes, each as a shell (its surface) at 2 mm
    // edges, and one as a soft lattice and a rigid body: the surface encloses the catalogue's
    // volume, spans the base and the projection, and an
    // anatomical one's apex sits below the centre (−y).
    for (ml, base, projection) in [(300.0, 115.0, 40.0), (250.0, 110.0, 35.0), (450.0, 130.0, 52.0)] {
        for style in ["round", "anatomical"] {
            let text = format!(
                "[[body]]\nname = \"i\"\nkind = \"shell\"\nshape = {{ implant = {{ volume_ml = {ml}, base_mm = {base}, projection_mm = {projection}, style = \"{style}\" }} }}\nspacing = 2\nposition = [0, 0, 100]\n"
            );
            let built = build_world(&SceneFile::parse("implant.toml", &text).unwrap()).unwrap();
            let shell = &built.world.bodies[0];
            let volume_ml = shell.enclosed_volume() * 1e-3;
            let (lo, hi) = shell.pos.iter().fold((Vec3::MAX, Vec3::MIN), |(l, h), p| (l.min(*p), h.max(*p)));
            let apex = shell.pos.iter().max_by(|a, b| a.z.total_cmp(&b.z)).unwrap();
            eprintln!(
                "{style} {ml} mL: {volume_ml:.1} mL, {lo} .. {hi}, apex {apex}: {:?}",
                built.notes[0].remarks
            );
            // The issue asks for 2 %; the fitted facets hold it to a thousandth.
            assert!((volume_ml - ml).abs() < 1e-3 * ml, "{volume_ml} mL for {ml}");
            assert!(((hi.x - lo.x) - base as f32).abs() < 0.01 * base as f32, "base {}", hi.x - lo.x);
            assert!(
                ((hi.z - lo.z) - projection as f32).abs() < 0.01 * projection as f32,
                "projection {}",
                hi.z - lo.z
            );
            assert!(
                (lo.z - 100.0).abs() < 0.01,
                "its base in the plane z = 0 of its position (docs/design.md §9): {lo}"
            );
            let r = 0.5 * base as f32;
            if style == "round" {
                assert!(apex.y.abs() < 0.05 * r, "{apex}");
            } else {
                assert!((apex.y + 0.25 * r).abs() < 0.05 * r, "{apex}");
            }
            assert!(built.notes[0].remarks.iter().any(|m| m.contains("mL")), "{:?}", built.notes[0].remarks);
        }
    }
    // Coarse facets (10 mm edges on a 115 mm base) hold the volume too, by the profile names'
    // projections as by lengths.
    for profile in ["low", "moderate", "high", "extra-high"] {
        let text = format!(
            "[[body]]\nname = \"i\"\nkind = \"shell\"\nshape = {{ implant = {{ volume_ml = 250, base_mm = 125, profile = \"{profile}\" }} }}\nspacing = 10\n"
        );
        let built = build_world(&SceneFile::parse("implant.toml", &text).unwrap()).unwrap();
        let volume_ml = built.world.bodies[0].enclosed_volume() * 1e-3;
        assert!((volume_ml - 250.0).abs() < 0.25, "{profile}: {volume_ml} mL");
    }
    for kind in ["soft", "rigid"] {
        let text = format!(
            "[[body]]\nname = \"i\"\nkind = \"{kind}\"\nshape = {{ implant = {{ volume_ml = 300, base_mm = 115, projection_mm = 40 }} }}\nspacing = 4\n"
        );
        let built = build_world(&SceneFile::parse("implant.toml", &text).unwrap()).unwrap();
        assert!(built.world.bodies[0].len() > 200, "{kind}: {}", built.world.bodies[0].len());
    }
}

#[test]
fn an_implant_no_dome_can_hold_is_refused_by_its_key() {
    // A 100 mm base and 30 mm projection hold at most its cylinder, 235.6 mL.
    for (ml, says) in [(400.0, "less than 235.6 mL"), (10.0, "more than 21.4 mL")] {
        let text = format!(
            "[[body]]\nname = \"i\"\nkind = \"shell\"\nshape = {{ implant = {{ volume_ml = {ml}, base_mm = 100, projection_mm = 30 }} }}\nspacing = 2\n"
        );
        let err = SceneFile::parse("implant.toml", &text).unwrap_err();
        let Error::SceneFile { line, key, message, .. } = &err else { panic!("{err}") };
        assert_eq!((*line, key.as_str()), (4, "body[0].shape.implant.volume_ml"), "{err}");
        assert!(message.contains(says), "{err}");
    }
}

#[test]
fn a_shell_inflates_to_its_target_volume() {
    // A free sphere of 20 mm radius (33.5 mL, 32.9 mL as its polygon) filled to 60 mL over
    // 0.2 s, then held there: its rest lengths grow by the cube root, so it settles at 60 mL,
    // within the polygon's shortfall; and a pressure-free shell with no inflate stays put.
    let text = "[time]\nduration = 0.5\n[[body]]\nname = \"balloon\"\nkind = \"shell\"\nshape = { sphere = 20 }\nspacing = 3\nmaterial = { young_kpa = 50, damping = 0.3 }\ninflate = { volume_ml = 60, ramp = 0.2 }\n";
    let built = build_world(&SceneFile::parse("balloon.toml", text).unwrap()).unwrap();
    let start = built.world.bodies[0].enclosed_volume() * 1e-3;
    let mut cpu = CpuWorld::new(built.world).unwrap();
    let mut half = 0.0;
    for step in 0..built.steps {
        cpu.step().unwrap();
        if step == (0.1 / f64::from(built.dt)) as u64 {
            half = cpu.world.bodies[0].enclosed_volume() * 1e-3;
        }
    }
    let end = cpu.world.bodies[0].enclosed_volume() * 1e-3;
    eprintln!("{start:.2} mL → {half:.2} mL at 0.1 s → {end:.2} mL after {} steps", built.steps);
    assert!((start - 32.9).abs() < 0.5, "{start}");
    assert!(half > start + 5.0 && half < 55.0, "half way: {half}");
    assert!((end - 60.0).abs() < 0.02 * 60.0, "{end} mL");
}

#[test]
fn an_expander_follows_its_fill_schedule() {
    // A free 20 mm sphere (32.9 mL) filled like a tissue expander: to 45 mL by 0.1 s, held
    // until 0.2 s, then to 60 mL by 0.3 s, held after. At each sample it holds the schedule's
    // volume (linear between the fills) within 3 %.
    let text = "[time]\nintegrator = \"explicit\"\nduration = 0.45\n[[body]]\nname = \"expander\"\nkind = \"shell\"\nshape = { sphere = 20 }\nspacing = 3\nmaterial = { young_kpa = 50, damping = 0.3 }\ninflate = { schedule = [[0.1, 45], [0.2, 45], [0.3, 60]] }\n";
    let built = build_world(&SceneFile::parse("expander.toml", text).unwrap()).unwrap();
    let start = built.world.bodies[0].enclosed_volume() * 1e-3;
    let expected = |t: f64| match t {
        t if t < 0.1 => start + (45.0 - start) * t / 0.1,
        t if t < 0.2 => 45.0,
        t if t < 0.3 => 45.0 + 15.0 * (t - 0.2) / 0.1,
        _ => 60.0,
    };
    let mut cpu = CpuWorld::new(built.world).unwrap();
    let dt = f64::from(built.dt);
    let mut checked = 0;
    for step in 1..=built.steps {
        cpu.step().unwrap();
        let t = step as f64 * dt;
        // Away from the schedule's corners, where the shell lags a little behind.
        let near_corner = [0.1, 0.2, 0.3].iter().any(|c| (t - c).abs() < 0.02);
        if step % 200 == 0 && t > 0.02 && !near_corner {
            let v = cpu.world.bodies[0].enclosed_volume() * 1e-3;
            assert!(
                (v - expected(t)).abs() < 0.03 * expected(t),
                "at {t:.3} s: {v:.2} mL, not {:.2}",
                expected(t)
            );
            checked += 1;
        }
    }
    assert!(checked >= 6, "{checked} samples");
    // A schedule that falls, starts at 0, or ends after the run is refused by its key.
    for (schedule, says) in [
        ("[[0.1, 45], [0.2, 40]]", "do not decrease"),
        ("[[0.0, 45]]", "from above 0"),
        ("[[0.2, 45], [0.1, 50]]", "increase"),
        ("[[0.1, 0], [0.2, 45]]", "positive volumes"),
    ] {
        let bad = text.replace("[[0.1, 45], [0.2, 45], [0.3, 60]]", schedule);
        let err = SceneFile::parse("expander.toml", &bad).unwrap_err();
        assert!(
            matches!(&err, Error::SceneFile { key, message, .. } if key == "body[0].inflate" && message.contains(says)),
            "{err}"
        );
    }
    // The first fill below what the shell holds at the start (32.9 mL) would deflate it.
    let shrinking = text.replace("[[0.1, 45], [0.2, 45], [0.3, 60]]", "[[0.1, 20], [0.2, 45]]");
    let err = build_world(&SceneFile::parse("expander.toml", &shrinking).unwrap()).unwrap_err();
    assert!(
        matches!(&err, Error::SceneFile { key, message, .. } if key == "body[0].inflate.schedule" && message.contains("only fills")),
        "{err}"
    );
    let late = text.replace("[0.3, 60]", "[0.6, 60]");
    let err = build_world(&SceneFile::parse("expander.toml", &late).unwrap()).unwrap_err();
    assert!(
        matches!(&err, Error::SceneFile { key, message, .. } if key == "body[0].inflate.schedule" && message.contains("lengthen")),
        "{err}"
    );
}

#[test]
fn a_skin_layer_stiffens_the_springs_within_it_and_no_others() {
    // Fat (2 kPa) 20 mm thick at a 5 mm spacing, z from 0 to 20; skin (30 kPa): the springs
    // with both ends above z = 17, the top surface's. A later layer overrides an earlier one.
    let text = "[time]\nintegrator = \"explicit\"\n[[body]]\nname = \"t\"\nkind = \"soft\"\nshape = { box = [40, 40, 20] }\nspacing = 5\nposition = [0, 0, 10]\nmaterial = { young_kpa = 2 }\nlayers = [{ region = { above = { z = 17 } }, young_kpa = 30 }, { region = { inside_box = { min = [-30, -30, 17], max = [0, 30, 30] } }, young_kpa = 10 }]\n";
    let built = build_world(&SceneFile::parse("skin.toml", text).unwrap()).unwrap();
    let b = &built.world.bodies[0];
    let fat = b.springs.iter().map(|s| s.k).fold(f32::MAX, f32::min);
    let (mut skin, mut half, mut rest) = (0, 0, 0);
    for s in &b.springs {
        let (p, q) = (b.rest_pos[s.i as usize], b.rest_pos[s.j as usize]);
        let ratio = s.k / fat;
        if p.z > 17.0 && q.z > 17.0 && p.x <= 0.0 && q.x <= 0.0 {
            assert!((ratio - 5.0).abs() < 1e-4, "{p} {q}: {ratio}");
            half += 1;
        } else if p.z > 17.0 && q.z > 17.0 {
            assert!((ratio - 15.0).abs() < 1e-4, "{p} {q}: {ratio}");
            skin += 1;
        } else {
            assert!((ratio - 1.0).abs() < 1e-6, "{p} {q}: {ratio}");
            rest += 1;
        }
    }
    assert!(skin > 20 && half > 20 && rest > 10 * skin, "{skin} {half} {rest}");
    assert!(
        built.notes[0].remarks.iter().any(|r| r.contains("a layer of 30 kPa")),
        "{:?}",
        built.notes[0].remarks
    );
    // The step follows the stiffest spring: a stiffer skin makes it shorter.
    let soft =
        build_world(&SceneFile::parse("fat.toml", &text.replace("layers", "# layers")).unwrap()).unwrap();
    assert!(built.dt < 0.5 * soft.dt, "{} vs {}", built.dt, soft.dt);
    // Layers are a soft body's, with a positive modulus, named by their key.
    for (bad, says) in [
        (text.replace("young_kpa = 30", "young_kpa = -1"), "positive modulus"),
        (text.replace("kind = \"soft\"", "kind = \"shell\""), "only a soft body has layers"),
        (text.replace("{ above = { z = 17 } }", "{ above = { z = 17, x = 1 } }"), "exactly one of x, y, z"),
    ] {
        let err = SceneFile::parse("skin.toml", &bad).unwrap_err();
        assert!(
            matches!(&err, Error::SceneFile { key, message, .. } if key.starts_with("body[0].layers") && message.contains(says)),
            "{err}"
        );
    }
}

#[test]
fn a_fill_beyond_a_thousandfold_is_refused_by_its_key() {
    // A 20 mm sphere (32.9 mL as its polygon) cannot be filled to 1e40 mL, nor emptied to a
    // millionth: a set-up error naming the key, before any step.
    for ml in ["1e40", "1e-5"] {
        let text = format!(
            "[[body]]\nname = \"balloon\"\nkind = \"shell\"\nshape = {{ sphere = 20 }}\nspacing = 3\ninflate = {{ volume_ml = {ml} }}\n"
        );
        let err = build_world(&SceneFile::parse("balloon.toml", &text).unwrap()).unwrap_err();
        let Error::SceneFile { line, column, key, message, .. } = &err else { panic!("{err}") };
        assert_eq!((*line, *column, key.as_str()), (6, 1, "body[0].inflate.volume_ml"), "{err}");
        assert!(message.contains("thousandfold"), "{err}");
    }
}

#[test]
fn a_block_has_the_young_modulus_the_file_gives() {
    // A 20 mm cube of E = 3 kPa at spacing 2 mm, stretched uniformly by 0.5 % along z (and
    // shrunk by a quarter of that across, the lattice's own Poisson ratio): the stress its
    // springs put on an inner vertex of the top face is E × strain, in the simulation's units
    // (stresses in pascals × metres per mm).
    let text = "[[body]]\nname = \"cube\"\nkind = \"soft\"\nshape = { box = [20, 20, 20] }\nspacing = 2\nmaterial = { young_kpa = 3.0 }\n";
    let built = build_world(&SceneFile::parse("cube.toml", text).unwrap()).unwrap();
    let mut cube = built.world.bodies[0].clone();
    let strain = 0.005f32;
    for (p, r) in cube.pos.iter_mut().zip(&cube.rest_pos) {
        *p = Vec3::new(r.x * (1.0 - strain / 4.0), r.y * (1.0 - strain / 4.0), r.z * (1.0 + strain));
    }
    let inputs = (built.world.schedule)(0)[0];
    let mut force = Vec::new();
    cube.forces(&inputs, &vec![Vec3::ZERO; cube.len()], &mut force);
    let top = cube.rest_pos.iter().position(|r| r.z > 9.9 && r.x.abs() < 0.1 && r.y.abs() < 0.1).unwrap();
    let f_z = force[top].z;
    let e_measured = -f_z / (2.0 * 2.0 * strain); // stress on the vertex's h² of face
    let e_expected = 3.0e3 * 1e-3; // 3 kPa in pascals × (metres per mm)
    eprintln!("E measured {e_measured} vs {e_expected} (internal units)");
    assert!((e_measured - e_expected).abs() < 0.03 * e_expected, "{e_measured} vs {e_expected}");
}

#[test]
fn a_shell_from_an_stl_surface_inflates() {
    let dir = std::env::temp_dir().join(format!("voxcollide-build-shell-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let kidney = common::shapes::kidney();
    common::shapes::write_stl(&dir.join("sac.stl"), &kidney);
    std::fs::write(
        dir.join("scene.toml"),
        "[time]\nsteps = 400\n[[body]]\nname = \"sac\"\nkind = \"shell\"\nmesh = \"sac.stl\"\nmaterial = { young_kpa = 50, damping = 0.5 }\ninflate = { pressure_kpa = 0.5, ramp = 0.005 }\n",
    )
    .unwrap();
    let built = build_world(&SceneFile::read(dir.join("scene.toml")).unwrap()).unwrap();
    let shell = &built.world.bodies[0];
    assert_eq!(shell.len(), kidney.positions.len(), "the shell is the user's surface");
    assert!(shell.surface.triangles.len() == kidney.mesh.triangles.len(), "its triangles are the file's");
    let mesh = shell.surface.clone();
    // Edges and bending springs: every edge once, and one across each edge.
    let edges = 3 * kidney.mesh.triangles.len() / 2;
    assert!(shell.springs.len() > edges && shell.springs.len() <= 2 * edges, "{}", shell.springs.len());
    let enclosed = |pos: &[Vec3]| {
        common::shapes::volume(&voxcollide_sim::mesh_io::Surface {
            positions: pos.to_vec(),
            mesh: mesh.clone(),
        })
    };
    let v0 = enclosed(&shell.pos);
    let mut cpu = CpuWorld::new(built.world).unwrap();
    for _ in 0..built.steps {
        cpu.step().unwrap();
    }
    let v1 = enclosed(&cpu.world.bodies[0].pos);
    eprintln!("volume {v0:.0} → {v1:.0} mm³");
    assert!(v1 > 1.01 * v0, "{v0} → {v1}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_contact_responds_with_a_penalty_stiff_for_the_step_unless_told_otherwise() {
    use voxcollide::Response;
    let built = build_world(&SceneFile::parse("indent.toml", INDENT).unwrap()).unwrap();
    let pair = &built.world.contacts[0];
    let Response::Penalty { stiffness, gap } = pair.response() else {
        panic!("{:?}", pair.response());
    };
    // Half of what the step allows the block's lightest free vertex: 0.5 m / dt².
    let block = &built.world.bodies[0];
    let lightest = block
        .inv_mass
        .iter()
        .zip(&block.mode)
        .filter(|(_, m)| **m == Mode::Free)
        .map(|(w, _)| 1.0 / *w)
        .fold(f32::MAX, f32::min);
    let expected = 0.5 * lightest / (built.dt * built.dt);
    assert!((stiffness / expected - 1.0).abs() < 1e-5, "{stiffness} vs {expected}");
    assert_eq!(gap, 0.0);
    // Its largest force is that of two voxels' depth.
    let voxel = pair.grid.voxel_size();
    assert!((pair.params.magnitude / (stiffness * 2.0 * voxel) - 1.0).abs() < 1e-6);

    // Given: the stiffness in N/m as it is (internal force per length is N/m in any unit), the
    // gap in file units; and the paper's constant response with its own magnitude rule.
    let given = INDENT.replace("[[contact]]", "[[contact]]\nstiffness = 250\ngap = 0.5");
    let built = build_world(&SceneFile::parse("indent.toml", &given).unwrap()).unwrap();
    assert_eq!(built.world.contacts[0].response(), Response::Penalty { stiffness: 250.0, gap: 0.5 });
    let constant = INDENT.replace("[[contact]]", "[[contact]]\nresponse = \"constant\"");
    let built = build_world(&SceneFile::parse("indent.toml", &constant).unwrap()).unwrap();
    assert_eq!(built.world.contacts[0].response(), Response::Constant);
}
