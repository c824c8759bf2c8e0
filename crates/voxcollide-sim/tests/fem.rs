//! The Neo-Hookean tetrahedra (docs/design.md §12, issue 21): they honour the file's Poisson ratio,
//! where the paper's spring lattice has its own 1/4.

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod common;

use std::sync::Arc;

use voxcollide::glam::{Mat3, UVec3, Vec3};
use voxcollide_sim::bodies::box_lattice;
use voxcollide_sim::material::neo_hookean::{Elements, lattice_tets};
use voxcollide_sim::*;

/// A bar `w × w × 4w` cells of spacing 1, pinned at its base, its top driven up by `strain`;
/// `nu`: its elements' Poisson ratio (None: the paper's springs, `k = 0.4 E h`). The lateral
/// and axial strains of its middle, at rest.
fn stretch(w: u32, strain: f32, nu: Option<f64>) -> (f32, f32) {
    let (lateral, axial, _) = stretch_under(w, strain, nu, None);
    (lateral, axial)
}

/// [`stretch`] under the explicit integrator (`implicit` None: 12,000 steps at its bound) or
/// the implicit one (`Some(steps)`: that many steps of 25 times the explicit bound, the stretch
/// ramped over the first third); also the relative residual force at the end.
fn stretch_under(w: u32, strain: f32, nu: Option<f64>, implicit: Option<u64>) -> (f32, f32, f64) {
    let material = Material { mass: 1.0, stiffening: 0.0, spring_damping: 0.3, damping: 0.3 };
    let n = UVec3::new(w + 1, w + 1, 4 * w + 1);
    let top = n.z - 1;
    let mut body = box_lattice(n, 1.0, Vec3::ZERO, 0.4, material, |v| {
        if v.z == 0 {
            Mode::Pinned
        } else if v.z == top {
            Mode::Driven
        } else {
            Mode::Free
        }
    })
    .unwrap();
    if let Some(nu) = nu {
        body.elements =
            Some(Elements::new(&body.rest_pos, &lattice_tets(&body.rest_pos, 1.0), 1.0, nu).unwrap());
        body.springs.iter_mut().for_each(|s| s.k = 0.0);
    }
    let (dt, ramp_steps, steps) = match implicit {
        None => (body.stable_dt(0.1), 2000.0, 12000),
        Some(n) => (25.0 * body.stable_dt(0.1), n as f32 / 3.0, n),
    };
    let length = top as f32;
    let schedule = Arc::new(move |step: u64| {
        let ramp = (step as f32 / ramp_steps).min(1.0);
        vec![StepInputs {
            dt,
            rest_scale: 1.0,
            drive: Vec3::new(0.0, 0.0, ramp * strain * length),
            turn: Mat3::IDENTITY,
            pressure: 0.0,
            fill_volume: 0.0,
            fill_bulk: 0.0,
            fill_hold: 0.0,
            floor: f32::MIN,
            gravity: Vec3::ZERO,
            wall_friction: 0.0,
        }]
    });
    let mut world = World::new(vec!["bar".into()], vec![body], Vec::new(), 1e6, schedule).unwrap();
    if implicit.is_some() {
        world = world.with_integrator(Integrator::Implicit(ImplicitSettings::default()));
    }
    let mut w_ = CpuWorld::new(world).unwrap();
    for _ in 0..steps {
        w_.step().unwrap();
    }
    let residual = w_.residual.relative();
    let b = &w_.world.bodies[0];
    let layer =
        |k: f32| b.rest_pos.iter().zip(&b.pos).filter(move |(r, _)| (r.z - k).abs() < 0.01).map(|(_, p)| *p);
    let mid = 2.0 * w as f32;
    let (lo, hi) = layer(mid).fold((f32::MAX, f32::MIN), |(l, h), p| (l.min(p.x), h.max(p.x)));
    let lateral = (hi - lo) / w as f32 - 1.0;
    let mean_z = |k: f32| {
        let v: Vec<f32> = layer(k).map(|p| p.z).collect();
        v.iter().sum::<f32>() / v.len() as f32
    };
    let span = w as f32;
    let axial = (mean_z(mid + span / 2.0) - mean_z(mid - span / 2.0)) / span - 1.0;
    (lateral, axial, residual)
}

#[test]
fn a_stretched_bar_contracts_by_the_files_poisson_ratio() {
    for nu in [0.3, 0.45, 0.49] {
        let (lateral, axial) = stretch(4, 0.01, Some(nu));
        let measured = -lateral / axial;
        eprintln!("nu {nu}: lateral {lateral:.5} axial {axial:.5} → {measured:.4}");
        assert!((measured - nu as f32).abs() < 0.05 * nu as f32, "ν {measured} for {nu}");
    }
}

#[test]
fn under_the_implicit_integrator_the_elements_rest_at_the_same_ratio_in_a_hundredth_of_the_steps() {
    // The element Hessian (fem::Tangent) in the implicit solve: 120 steps of 25 times the
    // explicit bound where the explicit integrator takes 12,000.
    for nu in [0.3, 0.45, 0.49] {
        let (lateral, axial, residual) = stretch_under(4, 0.01, Some(nu), Some(120));
        let measured = -lateral / axial;
        eprintln!(
            "implicit, nu {nu}: lateral {lateral:.5} axial {axial:.5} → {measured:.4}, residual {residual:.2e}"
        );
        assert!((axial - 0.01).abs() < 0.002, "axial strain {axial} for a 1 % stretch");
        assert!((measured - nu as f32).abs() < 0.05 * nu as f32, "ν {measured} for {nu}");
        assert!(residual < 1e-2, "not at rest: residual {residual}");
    }
}

#[test]
fn the_spring_lattice_keeps_its_own_quarter() {
    // The contrast the elements are for: the paper's lattice gives 1/4 whatever the file says.
    let (lateral, axial) = stretch(4, 0.01, None);
    let measured = -lateral / axial;
    assert!((measured - 0.25).abs() < 0.03, "springs gave ν {measured}");
}

/// How far the first body's farthest vertex moves from rest in 50 steps of `world`.
fn moved_unloaded(world: World) -> f32 {
    let mut w = CpuWorld::new(world).unwrap();
    for _ in 0..50 {
        w.step().unwrap();
    }
    let b = &w.world.bodies[0];
    b.pos.iter().zip(&b.rest_pos).map(|(p, r)| p.distance(*r)).fold(0.0, f32::max)
}

const BLOCK: &str = "units = \"mm\"\n[time]\nintegrator = \"explicit\"\nduration = 0.05\n[[body]]\nname = \"block\"\nkind = \"soft\"\nshape = { box = [20, 20, 10] }\nspacing = 2.5\nmaterial = { model = \"neo-hookean\", young_kpa = 3.0, poisson = 0.45, density = 1000.0, damping = 0.5 }\nfixed = [{ below = { z = -4.9 } }]\n";

#[test]
fn a_scene_files_neo_hookean_block_is_tetrahedra_at_the_files_ratio() {
    use voxcollide_sim::build::build_world;
    use voxcollide_sim::scene_file::SceneFile;
    let file = SceneFile::parse("block.toml", BLOCK).unwrap();
    let built = build_world(&file).unwrap();
    let body = &built.world.bodies[0];
    let e = body.elements.as_ref().expect("elements");
    // 8 × 8 × 4 cubes, six tetrahedra each, filling the block's volume.
    assert_eq!(e.tets.len(), 8 * 8 * 4 * 6);
    let volume: f32 = e.volume.iter().sum();
    assert!((volume - 20.0 * 20.0 * 10.0).abs() < 1.0, "{volume}");
    let (mu, lambda) = voxcollide_sim::material::neo_hookean::lame(3e3 * 1e-3, 0.45);
    assert!((e.mu - mu as f32).abs() < 1e-6 && (e.lambda - (lambda + mu) as f32).abs() < 1e-4);
    assert!(body.springs.iter().all(|s| s.k == 0.0));
    assert!(built.notes[0].remarks.iter().any(|r| r.contains("neo-hookean")), "{:?}", built.notes[0].remarks);
    // Its step is bound by the elements (ν = 0.45 is stiffer in bulk than the lattice).
    let springs = build_world(
        &SceneFile::parse("block.toml", &BLOCK.replace("model = \"neo-hookean\", ", "")).unwrap(),
    )
    .unwrap();
    assert!(built.dt < springs.dt, "{} against the lattice's {}", built.dt, springs.dt);
    // It steps, and stays at rest where nothing loads it.
    let moved = moved_unloaded(built.world);
    assert!(moved < 1e-4, "an unloaded block moved {moved}");
}

#[test]
fn what_the_elements_do_not_take_yet_is_refused_by_key() {
    use voxcollide_sim::build::build_world;
    use voxcollide_sim::scene_file::SceneFile;
    let cases = [
        (
            BLOCK.replace(
                "kind = \"soft\"\nshape = { box = [20, 20, 10] }",
                "kind = \"shell\"\nshape = { sphere = 10 }",
            ),
            "material",
            "soft body",
        ),
        (
            // The top cell's tetrahedra have their centres at most 4.375 mm up: none is in it.
            BLOCK.replace(
                "fixed =",
                "layers = [{ region = { above = { z = 4.5 } }, young_kpa = 30.0 }]\nfixed =",
            ),
            "layers[0]",
            "no tetrahedron's centre",
        ),
    ];
    for (text, key, words) in cases {
        let file = SceneFile::parse("block.toml", &text).unwrap();
        let e = build_world(&file).unwrap_err().to_string();
        assert!(e.contains("block.toml") && e.contains(key) && e.contains(words), "{e}");
    }
}

#[test]
fn a_neo_hookean_layer_scales_its_tetrahedra_by_its_modulus() {
    use voxcollide_sim::build::build_world;
    use voxcollide_sim::scene_file::SceneFile;
    let build = |text: &str| build_world(&SceneFile::parse("block.toml", text).unwrap()).unwrap();
    let layered = |region: &str, kpa: f64| {
        BLOCK.replace("fixed =", &format!("layers = [{{ region = {region}, young_kpa = {kpa} }}]\nfixed ="))
    };
    // A layer over the whole block at twice its modulus is the block at twice its modulus:
    // the same forces at any deformation, the same step.
    let whole = build(&layered("{ above = { z = -10 } }", 6.0));
    let stiff = build(&BLOCK.replace("young_kpa = 3.0", "young_kpa = 6.0"));
    assert_eq!(whole.dt, stiff.dt);
    let (a, b) = (&whole.world.bodies[0], &stiff.world.bodies[0]);
    let (ea, eb) = (a.elements.as_ref().unwrap(), b.elements.as_ref().unwrap());
    assert!(ea.modulus.iter().all(|m| *m == 2.0) && eb.modulus.iter().all(|m| *m == 1.0));
    let bent: Vec<Vec3> = a
        .rest_pos
        .iter()
        .map(|p| *p + Vec3::new(0.05 * p.z * p.z, 0.02 * p.x, -0.03 * p.x * p.y.sin()))
        .collect();
    let mut largest = 0.0f32;
    for i in 0..a.len() {
        let (fa, fb) = (ea.force_on(&bent, i), eb.force_on(&bent, i));
        largest = largest.max(fb.length());
        assert!((fa - fb).length() <= 1e-5 * fb.length().max(1e-3), "vertex {i}: {fa} against {fb}");
    }
    assert!(largest > 1e-3, "the deformation loads the block ({largest})");
    // The top half at 30 kPa: the tetrahedra whose centres are above z = 0, half of them,
    // ten times as stiff, and said so.
    let half = build(&layered("{ above = { z = 0 } }", 30.0));
    let e = half.world.bodies[0].elements.as_ref().unwrap();
    let (rest, top) = (&half.world.bodies[0].rest_pos, e.modulus.iter().filter(|m| **m == 10.0).count());
    assert_eq!(top, e.tets.len() / 2);
    for (k, t) in e.tets.iter().enumerate() {
        let centre = t.iter().map(|&v| rest[v as usize]).sum::<Vec3>() / 4.0;
        assert_eq!(e.modulus[k], if centre.z > 0.0 { 10.0 } else { 1.0 }, "{centre}");
    }
    let remarks = &half.notes[0].remarks;
    assert!(
        remarks.iter().any(|r| r.contains("a layer of 30 kPa") && r.contains("tetrahedra")),
        "{remarks:?}"
    );
    assert!(half.dt < stiff.dt, "a stiffer layer shortens the explicit step");
    // Pulled by the same stretch, the layered block pushes back harder than the plain one.
    let plain = build(BLOCK);
    let e0 = plain.world.bodies[0].elements.as_ref().unwrap();
    let stretched: Vec<Vec3> = rest.iter().map(|p| *p * Vec3::new(1.0, 1.0, 1.05)).collect();
    let top_vertex = (0..rest.len()).max_by(|&i, &j| rest[i].z.total_cmp(&rest[j].z)).unwrap();
    let (f_layered, f_plain) = (e.force_on(&stretched, top_vertex).z, e0.force_on(&stretched, top_vertex).z);
    assert!(f_plain < 0.0 && f_layered < 5.0 * f_plain, "{f_layered} against {f_plain}");
}

#[test]
fn a_neo_hookean_cylinder_is_tetrahedra_that_fill_it_and_share_whole_faces() {
    use std::collections::HashMap;
    use voxcollide_sim::build::build_world;
    use voxcollide_sim::scene_file::SceneFile;
    let text = BLOCK
        .replace("shape = { box = [20, 20, 10] }", "shape = { cylinder = { radius = 10, height = 10 } }");
    let built = build_world(&SceneFile::parse("cylinder.toml", &text).unwrap()).unwrap();
    let body = &built.world.bodies[0];
    let e = body.elements.as_ref().expect("elements");
    let rest = &body.rest_pos;
    // Its polar lattice: 4 rings of 24 segments, 5 layers (a 2.5 mm spacing), as prisms of
    // three tetrahedra each, 7 triangles a segment (one at the centre, two a quad).
    let (rings, segments, layers) = (4usize, 24usize, 5usize);
    assert_eq!(rest.len(), layers * (1 + rings * segments));
    assert_eq!(e.tets.len(), 3 * (layers - 1) * segments * (2 * rings - 1));
    // They fill the lattice's prism: a 24-gon of radius 10, 10 high.
    let polygon = 0.5 * segments as f32 * 100.0 * (std::f32::consts::TAU / segments as f32).sin();
    let volume: f32 = e.volume.iter().sum();
    assert!((volume - 10.0 * polygon).abs() < 1e-4 * volume, "{volume} against {}", 10.0 * polygon);
    // Every face is shared by two of them, or is on the boundary, whose area is the prism's.
    let mut faces: HashMap<[u32; 3], u32> = HashMap::new();
    for t in &e.tets {
        for skip in 0..4 {
            let mut f: Vec<u32> = (0..4).filter(|&c| c != skip).map(|c| t[c]).collect();
            f.sort_unstable();
            *faces.entry([f[0], f[1], f[2]]).or_default() += 1;
        }
    }
    assert!(faces.values().all(|&n| n <= 2), "a face of more than two tetrahedra");
    let boundary: f32 = faces
        .iter()
        .filter(|(_, n)| **n == 1)
        .map(|(f, _)| {
            let [a, b, c] = f.map(|v| rest[v as usize]);
            0.5 * (b - a).cross(c - a).length()
        })
        .sum();
    let perimeter = segments as f32 * 20.0 * (std::f32::consts::PI / segments as f32).sin();
    let want = 2.0 * polygon + 10.0 * perimeter;
    assert!((boundary - want).abs() < 1e-4 * want, "boundary {boundary} against {want}");
    // It steps, and stays at rest where nothing loads it.
    let moved = moved_unloaded(built.world);
    assert!(moved < 1e-4, "an unloaded cylinder moved {moved}");
}
