//! Anatomy nobody here made (docs/patient.md): torso regions of the MakeHuman body model (its
//! base mesh and breast targets as MPFB 2 ships them, CC0; made by tools/makehuman_torso.py
//! into scenes/makehuman) at two breast sizes and two firmnesses, each a breast between its
//! skin and an estimated chest wall (docs/design.md §14), standing as scanned and turned to
//! lie on her back: built, its volume growing with the cup and the same in either orientation,
//! its nipple on the skin, and under its own weight the nipple comes down.

mod common;

use std::path::{Path, PathBuf};

use common::shapes::write_stl;

use voxcollide::glam::{Mat3, Vec3};
use voxcollide_sim::build::{Built, build_world};
use voxcollide_sim::mesh_io::read_sheet;
use voxcollide_sim::reference;
use voxcollide_sim::scene_file::SceneFile;

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/makehuman")
}

/// A box's corners, and each skin's name and nipple.
type Landmarks = ([f32; 3], [f32; 3], Vec<(String, [f32; 3])>);

/// The box and each skin's nipple, from landmarks.txt.
fn landmarks() -> Landmarks {
    let text = std::fs::read_to_string(data().join("landmarks.txt")).unwrap();
    let mut lines = text.lines();
    let head = lines.next().unwrap();
    let numbers: Vec<f32> = head
        .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
        .filter_map(|t| t.parse().ok())
        .collect();
    let (min, max) = ([numbers[0], numbers[1], numbers[2]], [numbers[3], numbers[4], numbers[5]]);
    let skins = lines
        .map(|l| {
            let mut t = l.split_whitespace();
            let name = t.next().unwrap().to_string();
            let p: Vec<f32> = t.map(|v| v.parse().unwrap()).collect();
            (name, [p[0], p[1], p[2]])
        })
        .collect();
    (min, max, skins)
}

/// The breast of `skin` between it and the wall, in a folder of its own, its surfaces and box
/// turned by `turn` (the identity: standing as scanned, y up).
fn breast(skin: &str, nipple: [f32; 3], min: [f32; 3], max: [f32; 3], turn: Mat3, spacing: f32) -> Built {
    let dir = std::env::temp_dir().join(format!(
        "voxcollide-patient-{skin}-{}-{}",
        turn.z_axis.y,
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    for (from, to) in [(format!("skin-{skin}.stl"), "skin.stl"), ("wall.stl".into(), "wall.stl")] {
        let mut s = read_sheet(&data().join(from)).unwrap();
        s.positions.iter_mut().for_each(|p| *p = turn * *p);
        write_stl(&dir.join(to), &s);
    }
    let (a, b) = (turn * Vec3::from_array(min), turn * Vec3::from_array(max));
    let (lo, hi) = (a.min(b), a.max(b));
    let nipple = turn * Vec3::from_array(nipple);
    let text = format!(
        r#"
units = "mm"
[time]
integrator = "implicit"
[[body]]
name = "breast"
kind = "soft"
shape = {{ between = {{ outer = "skin.stl", inner = "wall.stl", min = {:?}, max = {:?} }} }}
spacing = {spacing}
material = {{ model = "neo-hookean", young_kpa = 3, poisson = 0.45, density = 1000, damping = 0.5 }}
landmarks = {{ nipple = {:?} }}
"#,
        lo.to_array(),
        hi.to_array(),
        nipple.to_array()
    );
    let path = dir.join("breast.toml");
    std::fs::write(&path, text).unwrap();
    build_world(&SceneFile::read(&path).unwrap()).unwrap_or_else(|e| panic!("{skin}: {e}"))
}

#[test]
fn makehuman_breasts_are_built_between_their_skin_and_chest_wall_in_either_posture() {
    let (min, max, skins) = landmarks();
    // Lying on her back: y (up, standing) becomes z; z (forward) becomes −y.
    let lying = Mat3::from_rotation_x(std::f32::consts::FRAC_PI_2);
    let mut volumes = Vec::new();
    for (skin, nipple) in &skins {
        let mut per_posture = Vec::new();
        for (posture, turn) in [("standing", Mat3::IDENTITY), ("lying", lying)] {
            let built = breast(skin, *nipple, min, max, turn, 8.0);
            let body = &built.world.bodies[0];
            let volume = body.surface.volume(&body.pos) / 1e3;
            let mark = &built.notes[0].landmarks[0];
            let on = mark.at(&body.pos);
            eprintln!(
                "{skin} {posture}: {} vertices, {volume:.0} mL, nipple {:.1} mm from where it was given",
                body.len(),
                on.distance(mark.given)
            );
            assert!(on.distance(mark.given) <= 8.0, "{skin} {posture}: nipple {on} far from {}", mark.given);
            assert!(body.mode.contains(&voxcollide_sim::Mode::Free));
            per_posture.push(volume);
        }
        // The same tissue whichever way it lies (the lattice is the box's, turned).
        assert!((per_posture[1] / per_posture[0] - 1.0).abs() < 0.05, "{skin}: {per_posture:?} mL");
        volumes.push((skin.clone(), per_posture[0]));
    }
    // A bigger cup holds more.
    let of = |name: &str| volumes.iter().find(|(s, _)| s == name).unwrap().1;
    assert!(of("maxcup-averagefirmness") > of("averagecup-averagefirmness") + 50.0, "{volumes:?}");
    assert!(volumes.iter().all(|(_, v)| *v > 100.0 && *v < 3000.0), "{volumes:?}");
}

#[test]
fn a_makehuman_breast_standing_sags_under_its_own_weight() {
    let (min, max, skins) = landmarks();
    let (skin, nipple) = skins.iter().find(|(s, _)| s == "maxcup-averagefirmness").unwrap();
    let built = breast(skin, *nipple, min, max, Mat3::IDENTITY, 10.0);
    let mut body = built.world.bodies[0].clone();
    let before = built.notes[0].landmarks[0].at(&body.pos);
    let steps = reference::settle(&mut body, Vec3::new(0.0, -9810.0, 0.0)).unwrap();
    let after = built.notes[0].landmarks[0].at(&body.pos);
    eprintln!("nipple {before} → {after} ({steps} steps)");
    assert!(after.y < before.y - 1.0, "standing, the nipple did not come down: {before} → {after}");
    assert!(after.is_finite());
}
