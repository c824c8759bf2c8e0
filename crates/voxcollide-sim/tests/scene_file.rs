//! Scene files (docs/design.md §8): every key of the contract is read, defaults are as documented, and
//! every kind of mistake is an error naming the file, the line, the column and the key.

use voxcollide::Error;
use voxcollide_sim::scene_file::*;

/// A file with every key of docs/design.md §8 (one valid body of each kind).
const FULL: &str = r#"
units = "cm"

[time]
duration = 2.0
dt = "auto"
settle = true
max_steps = 5000
integrator = "explicit"

[[body]]
name = "tissue"
kind = "soft"
shape = { box = [8, 8, 1.5] }
spacing = 0.25
position = [0, 0, 1]
rotation = [0, 0, 90]
scale = 1.0
material = { young_kpa = 3.0, poisson = 0.45, density = 1000.0, damping = 0.1 }
fixed = [{ below = { z = 0.3 } }, { rim = 0.5 }, { inside_box = { min = [0, 0, 0], max = [1, 1, 1] } }, { above = { x = 3 } }]

[[body]]
name = "implant"
kind = "shell"
shape = { implant = { volume_ml = 300, base_mm = 111, projection_mm = 45, style = "anatomical" } }
spacing = 0.4
inflate = { volume_ml = 300, ramp = 1.0 }

[[body]]
name = "probe"
kind = "rigid"
shape = { cylinder = { radius = 1, height = 3 } }
spacing = 0.3
motion = [{ t = 0.0, position = [0, 0, 20] }, { t = 1.0, position = [0, 0, 8], rotation = [0, 10, 0] }]

[[contact]]
a = "implant"
b = "tissue"
direction = "plane-normal"
search = "voxel"
radius = "auto"
voxel_size = 0.25
magnitude = 2.5

[[contact]]
a = "probe"
b = "tissue"

[output]
frames = 6
images = false
vtk = true
"#;

#[test]
fn every_key_of_the_contract_is_read() {
    let s = SceneFile::parse("scenes/full.toml", FULL).unwrap();
    assert_eq!(s.units, Units::Cm);
    assert_eq!(s.metres(), 0.01);
    assert_eq!(
        s.time,
        Time {
            duration: Some(2.0),
            steps: None,
            dt: Auto::Auto,
            settle: true,
            max_steps: 5000,
            integrator: IntegratorSpec::Explicit
        }
    );
    assert_eq!(s.bodies.len(), 3);
    let tissue = &s.bodies[0];
    assert_eq!((tissue.name.as_str(), tissue.kind), ("tissue", BodyKind::Soft));
    assert_eq!(tissue.geometry, Geometry::Shape(Shape::Box([8.0, 8.0, 1.5])));
    assert_eq!(
        (tissue.spacing, tissue.position, tissue.rotation),
        (Some(0.25), [0.0, 0.0, 1.0], [0.0, 0.0, 90.0])
    );
    assert_eq!(tissue.fixed.len(), 4);
    assert_eq!(tissue.fixed[0], Fixed::Below(AxisValue { x: None, y: None, z: Some(0.3) }));
    assert_eq!(tissue.fixed[1], Fixed::Rim(0.5));
    let implant = &s.bodies[1];
    assert_eq!(
        implant.geometry,
        Geometry::Shape(Shape::Implant {
            volume_ml: 300.0,
            base_mm: 111.0,
            projection_mm: 45.0,
            style: ImplantStyle::Anatomical
        })
    );
    assert_eq!(
        implant.inflate,
        Some(Inflate {
            pressure_kpa: None,
            volume_ml: Some(300.0),
            schedule: Vec::new(),
            ramp: 1.0,
            ease: Ease::Linear
        })
    );
    let probe = &s.bodies[2];
    assert_eq!(probe.motion.len(), 2);
    assert_eq!(probe.motion[1].rotation, [0.0, 10.0, 0.0]);
    assert_eq!(s.contacts.len(), 2);
    let c = s.contacts[0];
    assert_eq!((c.a, c.b, c.direction, c.search), (1, 0, DirectionSpec::PlaneNormal, SearchSpec::Voxel));
    assert_eq!((c.radius, c.voxel_size, c.magnitude), (Auto::Auto, Auto::Value(0.25), Auto::Value(2.5)));
    // A contact's documented defaults: pairwise, neighbours, everything "auto".
    let d = s.contacts[1];
    assert_eq!((d.a, d.b, d.direction, d.search), (2, 0, DirectionSpec::Pairwise, SearchSpec::Neighbours));
    assert_eq!((d.radius, d.voxel_size, d.magnitude), (Auto::Auto, Auto::Auto, Auto::Auto));
    // ... and the response that holds, measured to the surfaces on both sides, its stiffness and
    // gap chosen (docs/design.md §11).
    assert_eq!((d.response, d.stiffness, d.gap), (ResponseSpec::Surface, Auto::Auto, Auto::Auto));
    assert_eq!(s.output, Output { frames: 6, images: false, vtk: true });
}

#[test]
fn an_implant_profile_name_gives_its_projection() {
    for (name, ratio) in [("low", 0.22), ("moderate", 0.30), ("high", 0.40), ("extra-high", 0.48)] {
        let text = format!(
            "[[body]]\nname = \"i\"\nkind = \"shell\"\nshape = {{ implant = {{ volume_ml = 200, base_mm = 110, profile = \"{name}\" }} }}\nspacing = 5\n"
        );
        let s = SceneFile::parse("p.toml", &text).unwrap();
        let Geometry::Shape(Shape::Implant { base_mm, projection_mm, style, .. }) = s.bodies[0].geometry
        else {
            panic!("{:?}", s.bodies[0].geometry)
        };
        assert_eq!((base_mm, style), (110.0, ImplantStyle::Round));
        assert!((projection_mm - ratio * 110.0).abs() < 1e-9, "{name}: {projection_mm}");
    }
    // The issue's example: 300 mL high profile ≈ 11.1 cm base and 4.5 cm projection, low
    // ≈ 13.5 cm and 3.0 cm.
    assert!((Profile::High.ratio() * 111.0 - 45.0).abs() < 1.0);
    assert!((Profile::Low.ratio() * 135.0 - 30.0).abs() < 1.0);
}

#[test]
fn defaults_are_as_documented() {
    let s = SceneFile::parse(
        "a/b/min.toml",
        "[[body]]\nname = \"t\"\nkind = \"soft\"\nmesh = \"t.stl\"\nspacing = 2\n",
    )
    .unwrap();
    assert_eq!(s.units, Units::Mm);
    assert_eq!(
        s.time,
        Time {
            duration: Some(1.0),
            steps: None,
            dt: Auto::Auto,
            settle: false,
            max_steps: 200_000,
            // A scene in millimetres with no voxel-model contact: the integrator that comes to
            // rest (docs/scene-files.md, "Which integrator").
            integrator: IntegratorSpec::Implicit
        }
    );
    assert_eq!(s.output, Output { frames: 12, images: true, vtk: true });
    let b = &s.bodies[0];
    assert_eq!(b.geometry, Geometry::Mesh("a/b/t.stl".into()), "relative to the file");
    assert_eq!((b.position, b.rotation, b.scale), ([0.0; 3], [0.0; 3], 1.0));
    assert_eq!(
        b.material,
        MaterialSpec {
            young_kpa: 3.0,
            poisson: 0.45,
            density: 1000.0,
            damping: 0.1,
            spring_damping: None,
            model: MaterialModel::Springs,
            preset: None,
        }
    );
    assert!(s.contacts.is_empty());
}

/// `(file text, line, column, key, a fragment of the message)`.
fn bad_cases() -> Vec<(&'static str, usize, usize, &'static str, &'static str)> {
    const T: &str = "[[body]]\nname = \"t\"\nkind = \"soft\"\nshape = { box = [1, 1, 1] }\nspacing = 0.5\n";
    let with = |extra: &'static str| -> &'static str { Box::leak(format!("{T}{extra}").into_boxed_str()) };
    vec![
        // Syntax and types.
        ("units = mm\n", 1, 9, "units", "string"),
        ("units = \"inch\"\n", 1, 9, "units", "unknown variant"),
        ("unit = \"mm\"\n", 1, 1, "unit", "unknown field"),
        ("[time]\nduration = 2\nsetle = true\n", 3, 1, "time.setle", "unknown field"),
        (with("spacingg = 1\n"), 6, 1, "body[0].spacingg", "unknown field"),
        (with("material = { young = 3 }\n"), 6, 14, "body[0].material.young", "unknown field"),
        (with("[[contact]]\na = \"t\"\nb = \"t\"\nfoo = 1\n"), 9, 1, "contact[0].foo", "unknown field"),
        ("[[body]]\nname = \"t\"\nkind = \"jelly\"\n", 3, 8, "body[0].kind", "unknown variant"),
        ("[[body]]\nkind = \"soft\"\n", 1, 1, "body[0]", "missing field `name`"),
        (
            "[[body]]\nname = \"t\"\nkind = \"soft\"\nshape = { cube = 1 }\n",
            4,
            11,
            "body[0].shape.cube",
            "unknown variant `cube`",
        ),
        (with("fixed = [{ below = { z = 1, x = 2 } }]\n"), 6, 10, "body[0].fixed", "exactly one of x, y, z"),
        (with("fixed = [{ near = 1 }]\n"), 6, 12, "body[0].fixed.near", "unknown variant `near`"),
        ("[time]\ndt = \"fast\"\n", 2, 6, "time.dt", "\"auto\" or a number"),
        // Values out of range.
        (with("material = { poisson = 0.5 }\n"), 6, 12, "body[0].material.poisson", "[0, 0.5)"),
        (with("material = { young_kpa = -1 }\n"), 6, 12, "body[0].material.young_kpa", "positive modulus"),
        (
            "[[body]]\nname = \"t\"\nkind = \"soft\"\nshape = { sphere = 1 }\nspacing = 0\n",
            5,
            11,
            "body[0].spacing",
            "positive length",
        ),
        (
            "[[body]]\nname = \"t\"\nkind = \"soft\"\nshape = { box = [1, 0, 1] }\nspacing = 1\n",
            4,
            9,
            "body[0].shape",
            "every size must be positive",
        ),
        (with("scale = -2\n"), 6, 9, "body[0].scale", "must be positive"),
        // An implant's projection: a length or a profile name, one of them.
        (
            "[[body]]\nname = \"i\"\nkind = \"shell\"\nshape = { implant = { volume_ml = 300, base_mm = 111, profile = \"tall\" } }\n",
            4,
            65,
            "body[0].shape.implant.profile",
            "expected one of `low`, `moderate`, `high`, `extra-high`",
        ),
        (
            "[[body]]\nname = \"i\"\nkind = \"shell\"\nshape = { implant = { volume_ml = 300, base_mm = 111, projection_mm = 40, profile = \"low\" } }\n",
            4,
            9,
            "body[0].shape",
            "not both",
        ),
        (
            "[[body]]\nname = \"i\"\nkind = \"shell\"\nshape = { implant = { volume_ml = 300, base_mm = 111 } }\n",
            4,
            9,
            "body[0].shape",
            "missing `projection_mm` (mm) or `profile`",
        ),
        ("[time]\nduration = 1\nsteps = 10\n", 3, 1, "time.steps", "not both"),
        ("[time]\nduration = -1\n", 2, 1, "time.duration", "positive seconds"),
        ("[time]\nmax_steps = 0\n", 2, 1, "time.max_steps", "at least 1"),
        ("[output]\nframes = 0\n", 2, 1, "output.frames", "at least 1 frame"),
        // A body's required keys for its kind.
        ("[[body]]\nname = \"t\"\nkind = \"soft\"\nspacing = 1\n", 2, 8, "body[0]", "needs `mesh`"),
        (
            "[[body]]\nname = \"t\"\nkind = \"soft\"\nmesh = \"t.stl\"\n",
            2,
            8,
            "body[0].spacing",
            "needs `spacing`",
        ),
        (
            "[[body]]\nname = \"s\"\nkind = \"shell\"\nshape = { sphere = 1 }\n",
            2,
            8,
            "body[0].spacing",
            "surface edge length",
        ),
        (with("mesh = \"t.stl\"\n"), 6, 8, "body[0].mesh", "both `mesh` and `shape`"),
        (with("motion = [{ t = 0, position = [0, 0, 0] }]\n"), 6, 10, "body[0].motion", "only a rigid body"),
        (with("inflate = { pressure_kpa = 1 }\n"), 6, 11, "body[0].inflate", "only a shell inflates"),
        (
            "[[body]]\nname = \"r\"\nkind = \"rigid\"\nshape = { sphere = 1 }\nspacing = 0.5\nmotion = [{ t = 1, position = [0, 0, 0] }, { t = 1, position = [0, 0, 1] }]\n",
            6,
            10,
            "body[0].motion",
            "must increase",
        ),
        (
            "[[body]]\nname = \"s\"\nkind = \"shell\"\nshape = { sphere = 1 }\nspacing = 0.5\ninflate = { pressure_kpa = 1, volume_ml = 2 }\n",
            6,
            11,
            "body[0].inflate",
            "one of them",
        ),
        // Names and contacts.
        (
            with("[[body]]\nname = \"t\"\nkind = \"rigid\"\nshape = { sphere = 1 }\nspacing = 1\n"),
            7,
            8,
            "body[1].name",
            "already the name of body[0]",
        ),
        (
            with("[[contact]]\na = \"implant\"\nb = \"t\"\n"),
            7,
            5,
            "contact[0].a",
            "no body is named \"implant\"",
        ),
        (with("[[contact]]\na = \"t\"\nb = \"t\"\n"), 8, 5, "contact[0].b", "two different bodies"),
        (
            with(
                "[[body]]\nname = \"u\"\nkind = \"rigid\"\nshape = { sphere = 1 }\nspacing = 1\n[[contact]]\na = \"u\"\nb = \"t\"\nvoxel_size = 0.3\n",
            ),
            14,
            14,
            "contact[0].voxel_size",
            "not a power of two",
        ),
        (
            with(
                "[[body]]\nname = \"u\"\nkind = \"rigid\"\nshape = { sphere = 1 }\nspacing = 1\n[[contact]]\na = \"u\"\nb = \"t\"\nmagnitude = 0\n",
            ),
            14,
            13,
            "contact[0].magnitude",
            "positive",
        ),
        (
            with(
                "[[body]]\nname = \"u\"\nkind = \"rigid\"\nshape = { sphere = 1 }\nspacing = 1\n[[contact]]\na = \"u\"\nb = \"t\"\ndirection = \"normal\"\n",
            ),
            14,
            13,
            "contact[0].direction",
            "unknown variant",
        ),
        // docs/design.md §12's keys are read; what is not built yet is refused by its key.
        ("[time]\nintegrator = \"leapfrog\"\n", 2, 14, "time.integrator", "unknown variant"),
        (with("material = { model = \"foam\" }\n"), 6, 22, "body[0].material.model", "unknown variant"),
        (
            with(
                "[[body]]\nname = \"u\"\nkind = \"rigid\"\nshape = { sphere = 1 }\nspacing = 1\n[[contact]]\na = \"u\"\nb = \"t\"\nresponse = \"soft\"\n",
            ),
            14,
            12,
            "contact[0].response",
            "unknown variant",
        ),
        (
            with(
                "[[body]]\nname = \"u\"\nkind = \"rigid\"\nshape = { sphere = 1 }\nspacing = 1\n[[contact]]\na = \"u\"\nb = \"t\"\ngap = -1\n",
            ),
            14,
            7,
            "contact[0].gap",
            "0 or more",
        ),
        (
            with(
                "[[body]]\nname = \"u\"\nkind = \"rigid\"\nshape = { sphere = 1 }\nspacing = 1\n[[contact]]\na = \"u\"\nb = \"t\"\nstiffness = 0\n",
            ),
            14,
            13,
            "contact[0].stiffness",
            "positive",
        ),
        (
            with(
                "[[body]]\nname = \"u\"\nkind = \"rigid\"\nshape = { sphere = 1 }\nspacing = 1\n[[contact]]\na = \"u\"\nb = \"t\"\nresponse = \"constant\"\nstiffness = 5\n",
            ),
            15,
            13,
            "contact[0].stiffness",
            "a penalty's",
        ),
    ]
}

#[test]
fn every_mistake_names_the_file_line_column_and_key() {
    let mut wrong = Vec::new();
    for (text, line, column, key, says) in bad_cases() {
        match SceneFile::parse("scenes/bad.toml", text) {
            Err(Error::SceneFile { line: l, column: c, key: k, message, .. })
                if (l, c, k.as_str()) == (line, column, key) && message.contains(says) => {}
            other => {
                wrong.push(format!("{text:?}\n  expected {line}:{column} {key} {says:?}\n  got {other:?}"))
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    for (text, line, column, key, says) in bad_cases() {
        let err = SceneFile::parse("scenes/bad.toml", text).unwrap_err();
        let Error::SceneFile { file, line: l, column: c, key: k, message } = &err else {
            panic!("{text}\n→ not a scene-file error: {err:?}")
        };
        assert_eq!(file, "scenes/bad.toml");
        assert_eq!((*l, *c, k.as_str()), (line, column, key), "{text}\n→ {err}");
        assert!(message.contains(says), "{text}\n→ {err}\n(expected it to say {says:?})");
        assert!(err.to_string().starts_with(&format!("scenes/bad.toml:{line}:{column}: {key}: ")), "{err}");
    }
}

#[test]
fn a_missing_mesh_or_file_is_named() {
    let dir = std::env::temp_dir().join(format!("voxcollide-scene-file-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("scene.toml");
    std::fs::write(
        &path,
        "[[body]]\nname = \"t\"\nkind = \"soft\"\nmesh = \"meshes/tissue.stl\"\nspacing = 1\n",
    )
    .unwrap();
    let err = SceneFile::read(&path).unwrap_err();
    let Error::SceneFile { line, key, message, .. } = &err else { panic!("{err:?}") };
    assert_eq!((*line, key.as_str()), (4, "body[0].mesh"), "{err}");
    assert!(message.contains("meshes/tissue.stl") && message.contains("does not exist"), "{err}");
    std::fs::create_dir_all(dir.join("meshes")).unwrap();
    std::fs::write(dir.join("meshes/tissue.stl"), "solid t\nendsolid t\n").unwrap();
    assert_eq!(
        SceneFile::read(&path).unwrap().bodies[0].geometry,
        Geometry::Mesh(dir.join("meshes/tissue.stl"))
    );

    let err = SceneFile::read(dir.join("nope.toml")).unwrap_err();
    assert!(err.to_string().contains("nope.toml") && err.to_string().contains("cannot read"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_papers_integrator_and_material_are_read_by_name() {
    // docs/design.md §12: the explicit integrator and the spring lattice, named as the contract names them.
    let s = SceneFile::parse(
        "p.toml",
        "[time]\nintegrator = \"explicit\"\n[[body]]\nname = \"t\"\nkind = \"soft\"\nshape = { box = [1, 1, 1] }\nspacing = 0.5\nmaterial = { model = \"springs\", young_kpa = 3.0, poisson = 0.45, density = 1000.0, damping = 0.1 }\n",
    )
    .unwrap();
    assert_eq!(s.time.integrator, IntegratorSpec::Explicit);
    assert_eq!(s.bodies[0].material.model, MaterialModel::Springs);
}

#[test]
fn the_implicit_integrator_is_read_by_name_and_built() {
    let s = SceneFile::parse(
        "p.toml",
        "[time]\nintegrator = \"implicit\"\nduration = 0.4\n[[body]]\nname = \"t\"\nkind = \"soft\"\nshape = { box = [10, 10, 10] }\nspacing = 2.5\n",
    )
    .unwrap();
    assert_eq!(s.time.integrator, IntegratorSpec::Implicit);
    let built = voxcollide_sim::build::build_world(&s).unwrap();
    assert!(matches!(built.world.integrator, voxcollide_sim::Integrator::Implicit(_)));
    // The step is chosen for accuracy: the schedule in IMPLICIT_STEPS steps, far above the bound.
    let stable = built.world.bodies[0].stable_dt(0.3);
    assert!(built.dt > 10.0 * stable, "dt {} against the bound {stable}", built.dt);
    assert_eq!(built.steps, voxcollide_sim::build::IMPLICIT_STEPS as u64);
}

#[test]
fn a_scene_in_layer_units_has_no_millilitres() {
    let text = "units = \"layer\"\n[[body]]\nname = \"s\"\nkind = \"shell\"\nshape = { sphere = 1 }\nspacing = 0.3\ninflate = { volume_ml = 5, ramp = 0.1 }\n";
    let e = SceneFile::parse("layer.toml", text).unwrap_err().to_string();
    assert!(e.contains("layer.toml") && e.contains("inflate") && e.contains("no millilitres"), "{e}");
    let ok = text.replace("volume_ml = 5", "pressure_kpa = 0.1");
    let s = SceneFile::parse("layer.toml", &ok).unwrap();
    assert_eq!(s.units.symbol(), "layer units");
    assert!(!s.units.is_physical());
    assert_eq!(s.metres(), 1.0);
}

#[test]
fn a_scene_that_names_no_integrator_gets_the_one_that_comes_to_rest_unless_the_paper_needs_its_own() {
    // docs/scene-files.md, "Which integrator": implicit in physical units with surface contacts
    // (or none); explicit in the paper's layer units, with a voxel-model response, or by name.
    let body = "[[body]]\nname = \"t\"\nkind = \"soft\"\nshape = { box = [10, 10, 10] }\nspacing = 2.5\n\
                [[body]]\nname = \"b\"\nkind = \"rigid\"\nshape = { sphere = 3 }\nspacing = 1\nposition = [0, 0, 9]\n";
    let contact = |response: &str| format!("[[contact]]\na = \"b\"\nb = \"t\"\n{response}");
    for (units, time, response, expected) in [
        ("", "", "", IntegratorSpec::Implicit),
        ("units = \"cm\"\n", "", "response = \"surface\"\n", IntegratorSpec::Implicit),
        ("units = \"m\"\n", "[time]\nsettle = true\n", "", IntegratorSpec::Implicit),
        ("", "", "response = \"penalty\"\n", IntegratorSpec::Explicit),
        ("", "", "response = \"constant\"\n", IntegratorSpec::Explicit),
        ("units = \"layer\"\n", "", "", IntegratorSpec::Explicit),
        ("", "[time]\nintegrator = \"explicit\"\n", "", IntegratorSpec::Explicit),
        ("units = \"layer\"\n", "[time]\nintegrator = \"implicit\"\n", "", IntegratorSpec::Implicit),
        ("", "[time]\nintegrator = \"implicit\"\n", "response = \"penalty\"\n", IntegratorSpec::Implicit),
    ] {
        let text = format!("{units}{time}{body}{}", contact(response));
        let s = SceneFile::parse("p.toml", &text).unwrap();
        assert_eq!(s.time.integrator, expected, "{text}");
    }
}
