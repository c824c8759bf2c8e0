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
    build_world(&SceneFile::read(breast_file(skin, nipple, min, max, turn, spacing, "")).unwrap())
        .unwrap_or_else(|e| panic!("{skin}: {e}"))
}

/// The scene file of [`breast`], with `more` after its body, and its path.
fn breast_file(
    skin: &str,
    nipple: [f32; 3],
    min: [f32; 3],
    max: [f32; 3],
    turn: Mat3,
    spacing: f32,
    more: &str,
) -> PathBuf {
    // A folder of its own per call: the tests run at once, and two writing one skin file
    // while a third reads it built a body of nothing.
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("voxcollide-patient-{skin}-{call}-{}", std::process::id()));
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
{more}
"#,
        lo.to_array(),
        hi.to_array(),
        nipple.to_array()
    );
    let path = dir.join("breast.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// An implant placed under the nipple (docs/design.md §15), `base` mm wide.
fn implant(base: u32) -> String {
    format!(
        r#"
[[body]]
name = "implant"
kind = "shell"
shape = {{ implant = {{ volume_ml = 250, base_mm = {base}, profile = "moderate" }} }}
spacing = 6
place = {{ under = "breast.nipple" }}
[[contact]]
a = "implant"
b = "breast"
"#
    )
}

#[test]
fn an_implant_placed_under_the_nipple_stands_on_the_curved_chest_wall_in_either_posture() {
    let (min, max, skins) = landmarks();
    let lying = Mat3::from_rotation_x(std::f32::consts::FRAC_PI_2);
    for (skin, nipple) in skins.iter().filter(|(s, _)| s.starts_with("maxcup")) {
        let mut normals = Vec::new();
        for (posture, turn) in [("standing", Mat3::IDENTITY), ("lying", lying)] {
            let plain = breast(skin, *nipple, min, max, turn, 8.0);
            let path = breast_file(skin, *nipple, min, max, turn, 8.0, &implant(110));
            let built =
                build_world(&SceneFile::read(&path).unwrap()).unwrap_or_else(|e| panic!("{skin}: {e}"));
            let (tissue, shell) = (&built.world.bodies[0], &built.world.bodies[1]);
            let wall = shell.wall.as_ref().expect("a placed implant rests on the wall");
            assert!(
                tissue.wall.as_ref().is_some_and(|w| std::sync::Arc::ptr_eq(w, wall)),
                "the pocket rests on the same wall"
            );
            // Its base on the wall, nowhere behind it, and the wall's normal toward the nipple.
            let above: Vec<f32> = shell.pos.iter().map(|p| wall.above(*p, 0.0).unwrap()).collect();
            let lowest = above.iter().copied().fold(f32::MAX, f32::min);
            let highest = above.iter().copied().fold(f32::MIN, f32::max);
            let mark = built.notes[0].landmarks[0].at(tissue, &tissue.pos);
            assert!(lowest.abs() < 0.05, "{skin} {posture}: base {lowest} from the wall");
            assert!(
                (highest - 33.0).abs() < 1.0,
                "{skin} {posture}: apex {highest} in front (110 mm × 0.30)"
            );
            assert!(wall.normal.dot((mark - wall.origin).normalize()) > 0.8, "{skin} {posture}: {wall:?}");
            // The base lies across the wall, centred under the nipple's foot.
            let centre = shell.pos.iter().copied().sum::<Vec3>() / shell.len() as f32;
            let across = wall.local(centre).truncate().length();
            assert!(across < 2.0, "{skin} {posture}: the implant's centre is {across} mm off its foot");
            // The pocket: vertices held on the wall under the base are let go, the rest stay.
            let held = |b: &voxcollide_sim::MassSpring| {
                b.mode.iter().filter(|m| **m == voxcollide_sim::Mode::Pinned).count()
            };
            let released = held(&plain.world.bodies[0]) - held(tissue);
            eprintln!(
                "{skin} {posture}: normal {:?}, {released} let go of {} held, base {lowest:.3} apex {highest:.2} mm",
                wall.normal,
                held(&plain.world.bodies[0])
            );
            assert!(released > 60 && held(tissue) > released, "{skin} {posture}: {released} let go");
            for (i, p) in tissue.rest_pos.iter().enumerate() {
                if tissue.mode[i] == voxcollide_sim::Mode::Free
                    && plain.world.bodies[0].mode[i] != voxcollide_sim::Mode::Free
                {
                    assert!(
                        wall.local(*p).truncate().length() <= 55.0 + 10.0 + 1e-3,
                        "{p} let go outside the pocket"
                    );
                }
            }
            normals.push(turn.transpose() * wall.normal);
        }
        // The same place on her whichever way she lies (to a degree: the nipple is moved onto
        // each posture's lattice).
        assert!(normals[0].distance(normals[1]) < 0.02, "{skin}: {normals:?}");
    }
}

#[test]
fn an_implant_that_does_not_fit_on_the_wall_inside_the_box_is_refused_by_key() {
    let (min, max, skins) = landmarks();
    let (skin, nipple) = skins.iter().find(|(s, _)| s == "maxcup-averagefirmness").unwrap();
    let path = breast_file(skin, *nipple, min, max, Mat3::IDENTITY, 10.0, &implant(190));
    let e = build_world(&SceneFile::read(&path).unwrap()).unwrap_err().to_string();
    assert!(e.contains("body[1].place.under") && e.contains("does not fit"), "{e}");
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
            let on = mark.at(body, &body.pos);
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
    let before = built.notes[0].landmarks[0].at(&body, &body.pos);
    let steps = reference::settle(&mut body, Vec3::new(0.0, -9810.0, 0.0)).unwrap();
    let after = built.notes[0].landmarks[0].at(&body, &body.pos);
    eprintln!("nipple {before} → {after} ({steps} steps)");
    assert!(after.y < before.y - 1.0, "standing, the nipple did not come down: {before} → {after}");
    assert!(after.is_finite());
}

/// The shipped plan (`scenes/patient-plan.toml`) keeps its implant's base within her breast's
/// `medial` and `lateral` borders (`place.within`): under her nipple alone, her leaning chest
/// wall puts the base's centre 17 mm medial of the nipple and its rim past her midline (x = 0),
/// over her sternum where her tissue is thin; within her borders it moves laterally, off it.
#[test]
fn the_shipped_plan_keeps_her_implant_off_her_sternum() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let text = std::fs::read_to_string(scenes.join("patient-plan.toml")).unwrap();
    let within = ", within = [\"breast.medial\", \"breast.lateral\"]";
    assert!(text.contains(within), "the shipped plan keeps within her borders");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("patient-within");
    std::fs::create_dir_all(&dir).unwrap();
    let place = |text: &str| {
        let text = text.replace("\"makehuman/", &format!("\"{}/makehuman/", scenes.display()));
        let path = dir.join("plan.toml");
        std::fs::write(&path, text).unwrap();
        let built = build_world(&SceneFile::read(&path).unwrap()).unwrap();
        let shell = &built.world.bodies[1];
        let medial_most = shell.pos.iter().map(|p| p.x).fold(f32::MAX, f32::min);
        (medial_most, built.notes[1].remarks.join("\n"))
    };
    let (alone, said) = place(&text.replace(within, ""));
    assert!(alone < 0.0, "under the nipple alone its rim reaches {alone} mm, past her midline: {said}");
    assert!(!said.contains("moved"), "{said}");
    let (kept, said) = place(&text);
    eprintln!("the base's medial rim: {alone:.1} mm under the nipple alone, {kept:.1} mm within her borders");
    // Her medial border, seen along the wall's normal, is at about 16 mm: the rim stops near it.
    assert!(
        (5.0..25.0).contains(&kept) && kept > alone + 15.0,
        "within her borders its rim is at {kept} mm: {said}"
    );
    assert!(said.contains("its base's centre moved") && !said.contains("too wide"), "{said}");
}
