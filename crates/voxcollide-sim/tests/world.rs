//! Worlds of any number of bodies and contacts: a tissue slab lifted by two implants at once
//! (the slab in two contacts, its forces summed), and a free body in none. The CPU (parallel
//! collision) and the GPU (every pair in one encoder) follow bit-identical trajectories on
//! llvmpipe; bad contact graphs are errors.

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod common;

use std::sync::Arc;

use voxcollide::glam::{UVec3, Vec3};
use voxcollide::*;
use voxcollide_sim::bodies::{box_lattice, ellipsoid_shell};
use voxcollide_sim::*;

fn world() -> World {
    let material = Material { mass: 1.0, stiffening: 10.0, spring_damping: 0.6, damping: 0.2 };
    let n = UVec3::new(13, 7, 3);
    let slab = box_lattice(n, 0.5, Vec3::new(-3.0, -1.5, 0.0), 40.0, material, |v| {
        if v.z == n.z - 1 && (v.x == 0 || v.x == n.x - 1) { Mode::Pinned } else { Mode::Free }
    })
    .unwrap();
    let shell = |x: f32| {
        ellipsoid_shell(Vec3::new(x, 0.0, -0.9), Vec3::new(1.1, 1.1, 1.0), 6, 12, 0.6, 80.0, material)
            .unwrap()
    };
    let (left, right) = (shell(-1.5), shell(1.5));
    let loose =
        box_lattice(UVec3::splat(2), 0.5, Vec3::new(10.0, 10.0, 10.0), 40.0, material, |_| Mode::Free)
            .unwrap();
    let dt = [&slab, &left, &right, &loose].iter().map(|b| b.stable_dt(0.3)).fold(f32::MAX, f32::min);
    let params = ContactParams {
        magnitude: 3.0,
        search: Search::Neighbours { radius: 0.25 },
        direction: Direction::PlaneNormal,
        anchor: Anchor::FollowA,
    };
    // One contact with the paper's constant response, one with a penalty: the GPU world
    // must step both as the CPU does.
    let contact = |a: usize, shell: &MassSpring, response: Response| ContactPair {
        a,
        b: 0,
        grid: Initializer::new(0.25).margin(4).build(&shell.pos).unwrap(),
        params,
        model: ContactModel::Voxel(response),
    };
    let penalty = Response::Penalty { stiffness: 40.0, gap: 0.0 };
    let contacts = vec![contact(1, &left, Response::Constant), contact(2, &right, penalty)];
    let schedule = Arc::new(move |step: u64| {
        let still = StepInputs {
            dt,
            rest_scale: 1.0,
            drive: Vec3::ZERO,
            turn: voxcollide::glam::Mat3::IDENTITY,
            pressure: 0.0,
            fill_volume: 0.0,
            fill_bulk: 0.0,
            fill_hold: 0.0,
            floor: f32::MIN,
            gravity: Vec3::ZERO,
            wall_friction: 0.0,
        };
        let ramp = (step as f32 / 100.0).min(1.0);
        let inflating = StepInputs { pressure: 6.0 * ramp, floor: -1.9, ..still };
        vec![still, inflating, inflating, still]
    });
    World::new(
        ["slab", "left implant", "right implant", "loose"].map(String::from).to_vec(),
        vec![slab, left, right, loose],
        contacts,
        400.0,
        schedule,
    )
    .unwrap()
}

fn bits(v: &[Vec3]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

#[test]
fn two_implants_lift_one_slab_the_same_on_cpu_and_gpu() {
    let mut cpu = CpuWorld::new(world()).unwrap();
    let gpu_ctx = common::gpu();
    let mut gpu = gpu_ctx.as_ref().map(|ctx| GpuWorld::new(ctx, world()).unwrap());
    let exact = gpu_ctx.as_ref().is_some_and(|c| c.adapter_name().contains("llvmpipe"));
    let start = cpu.world.bodies[0].pos.clone();
    let mut touched = [0usize; 2];
    for step in 1..=150 {
        cpu.step().unwrap();
        for (c, t) in touched.iter_mut().enumerate() {
            *t += cpu.reports[c].colliding_b.len();
        }
        let Some(gpu) = gpu.as_mut() else { continue };
        gpu.step().unwrap();
        if step % 50 == 0 {
            let reports = gpu.sync().unwrap();
            for k in 0..4 {
                let (c, g) = (&cpu.world.bodies[k], &gpu.world.bodies[k]);
                let name = &cpu.world.names[k];
                if exact {
                    assert_eq!(bits(&c.pos), bits(&g.pos), "step {step}: {name} positions");
                    assert_eq!(bits(&c.vel), bits(&g.vel), "step {step}: {name} velocities");
                } else {
                    let d = c.pos.iter().zip(&g.pos).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
                    assert!(d < 1e-3, "step {step}: {name} differs by {d}");
                }
            }
            for (c, r) in reports.iter().enumerate() {
                assert_eq!(r.colliding_b, cpu.reports[c].colliding_b, "step {step}: contact {c}");
            }
        }
    }
    // Both implants pushed the slab, which rose over both of them, and the loose body, in no
    // contact, fell (no floor) without any contact force.
    assert!(touched[0] > 0 && touched[1] > 0, "{touched:?}");
    let slab = &cpu.world.bodies[0];
    let lift = |x0: f32, x1: f32| {
        slab.pos
            .iter()
            .zip(&start)
            .filter(|(_, s)| s.x > x0 && s.x < x1 && s.z < 0.1)
            .map(|(p, s)| p.z - s.z)
            .fold(f32::MIN, f32::max)
    };
    let (l, r) = (lift(-2.0, -1.0), lift(1.0, 2.0));
    assert!(l > 0.02 && r > 0.02 && (l - r).abs() < 0.1 * l, "lift over the implants: {l} {r}");
    assert!(cpu.world.bodies[3].pos.iter().all(|p| p.is_finite()));
}

#[test]
fn bad_contact_graphs_are_errors() {
    let w = world();
    let schedule = w.schedule.clone();
    let bad = |contacts: Vec<ContactPair>| {
        World::new(w.names.clone(), w.bodies.clone(), contacts, 400.0, schedule.clone()).unwrap_err()
    };
    let pair = w.contacts[0];
    for (contacts, says) in [
        (vec![ContactPair { a: 0, b: 0, ..pair }], "two different bodies"),
        (vec![ContactPair { a: 9, ..pair }], "two different bodies"),
        (vec![ContactPair { params: ContactParams { magnitude: -1.0, ..pair.params }, ..pair }], "magnitude"),
    ] {
        let err = bad(contacts);
        assert!(err.to_string().contains(says), "{err}");
    }
    let err = World::new(vec!["one".into()], w.bodies.clone(), vec![], 400.0, schedule.clone()).unwrap_err();
    assert!(err.to_string().contains("one per body"), "{err}");
    // A schedule that forgets a body is an error at the step, not a panic.
    let short =
        World::new(w.names.clone(), w.bodies.clone(), w.contacts.clone(), 400.0, Arc::new(|_| vec![]));
    let err = CpuWorld::new(short.unwrap()).unwrap().step().unwrap_err();
    assert!(err.to_string().contains("schedule"), "{err}");
}

#[test]
fn a_turning_paddle_sweeps_a_block_the_same_on_cpu_and_gpu() {
    // A scene file's rigid paddle lowered onto a soft block while it turns a quarter about z
    // (keyframe rotations, about the body's position): the driven vertices follow the turn,
    // the block is pushed, and both backends agree to the bit on llvmpipe.
    let text = r#"
[time]
integrator = "explicit"
steps = 240
[[body]]
name = "block"
kind = "soft"
shape = { box = [40, 40, 10] }
spacing = 2.5
material = { young_kpa = 3.0, damping = 0.5 }
fixed = [{ below = { z = -4.9 } }]
[[body]]
name = "paddle"
kind = "rigid"
shape = { box = [30, 4, 6] }
spacing = 2
position = [0, 0, 8.5]
motion = [{ t = 0.0, position = [0, 0, 8.5] }, { t = 0.02, position = [0, 0, 7], rotation = [0, 0, 90] }]
[[contact]]
a = "paddle"
b = "block"
response = "penalty"
"#;
    let world = || {
        let file = voxcollide_sim::scene_file::SceneFile::parse("paddle.toml", text).unwrap();
        voxcollide_sim::build::build_world(&file).unwrap()
    };
    let built = world();
    eprintln!("dt {:.3e} s: 240 steps = {:.3} s", built.dt, 240.0 * built.dt);
    assert!(240.0 * built.dt > 0.02, "the turn ends within the run");
    let mut cpu = CpuWorld::new(built.world).unwrap();
    let gpu_ctx = common::gpu();
    let mut gpu = gpu_ctx.as_ref().map(|ctx| GpuWorld::new(ctx, world().world).unwrap());
    let exact = gpu_ctx.as_ref().is_some_and(|c| c.adapter_name().contains("llvmpipe"));
    let mut touched = 0;
    for step in 1..=240u64 {
        cpu.step().unwrap();
        touched += cpu.reports[0].colliding_b.len();
        let Some(gpu) = gpu.as_mut() else { continue };
        gpu.step().unwrap();
        if step % 80 == 0 {
            gpu.sync().unwrap();
            for k in 0..2 {
                let (c, g) = (&cpu.world.bodies[k], &gpu.world.bodies[k]);
                if exact {
                    assert_eq!(bits(&c.pos), bits(&g.pos), "step {step}: body {k} positions");
                } else {
                    let d = c.pos.iter().zip(&g.pos).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
                    assert!(d < 1e-3, "step {step}: body {k} differs by {d}");
                }
            }
        }
    }
    // Turned a quarter: long along y now, 1.5 mm lower, still centred.
    let paddle = &cpu.world.bodies[1];
    let (lo, hi) = paddle.pos.iter().fold((Vec3::MAX, Vec3::MIN), |(l, h), p| (l.min(*p), h.max(*p)));
    eprintln!("paddle {lo} .. {hi}; {touched} contacts");
    assert!((hi.y - lo.y - 30.0).abs() < 0.01 && (hi.x - lo.x - 4.0).abs() < 0.01, "{lo} {hi}");
    assert!((lo.z - 4.0).abs() < 0.01 && (lo.x + hi.x).abs() < 0.01, "{lo} {hi}");
    assert!(touched > 0);
    let block = &cpu.world.bodies[0];
    let pushed = block.pos.iter().zip(&block.rest_pos).map(|(p, r)| r.z - p.z).fold(f32::MIN, f32::max);
    assert!(pushed > 0.3, "the block was pushed down by {pushed}");
}

#[test]
fn a_shell_filled_to_a_volume_lifts_a_layer_the_same_on_cpu_and_gpu() {
    // A scene file's shell filled from 3.8 to 6 mL under a held layer: the fill's pressure
    // comes from the volume pass (a fixed-order sum on the GPU, its twin on the CPU), so the
    // trajectories agree to the bit on llvmpipe; the fill reaches its volume against the load.
    let text = r#"
[time]
integrator = "explicit"
steps = 300
[[body]]
name = "skin"
kind = "soft"
shape = { box = [40, 40, 6] }
spacing = 3
material = { young_kpa = 3.0, damping = 0.5 }
fixed = [{ rim = 1 }]
[[body]]
name = "expander"
kind = "shell"
shape = { ellipsoid = [12, 12, 6] }
spacing = 3
position = [0, 0, -9.5]
material = { young_kpa = 30, damping = 0.5 }
floor = -15.5
inflate = { volume_ml = 6, ramp = 0.01 }
[[contact]]
a = "expander"
b = "skin"
direction = "plane-normal"
response = "penalty"
"#;
    let world = || {
        let file = voxcollide_sim::scene_file::SceneFile::parse("fill.toml", text).unwrap();
        voxcollide_sim::build::build_world(&file).unwrap()
    };
    let built = world();
    let start = built.world.bodies[1].enclosed_volume() * 1e-3;
    eprintln!("dt {:.3e} s: 300 steps = {:.4} s; {start:.2} mL at first", built.dt, 300.0 * built.dt);
    let mut cpu = CpuWorld::new(built.world).unwrap();
    let gpu_ctx = common::gpu();
    let mut gpu = gpu_ctx.as_ref().map(|ctx| GpuWorld::new(ctx, world().world).unwrap());
    let exact = gpu_ctx.as_ref().is_some_and(|c| c.adapter_name().contains("llvmpipe"));
    let mut touched = 0;
    for step in 1..=300u64 {
        cpu.step().unwrap();
        touched += cpu.reports[0].colliding_b.len();
        let Some(gpu) = gpu.as_mut() else { continue };
        gpu.step().unwrap();
        if step % 100 == 0 {
            gpu.sync().unwrap();
            for k in 0..2 {
                let (c, g) = (&cpu.world.bodies[k], &gpu.world.bodies[k]);
                if exact {
                    assert_eq!(bits(&c.pos), bits(&g.pos), "step {step}: body {k} positions");
                    assert_eq!(bits(&c.vel), bits(&g.vel), "step {step}: body {k} velocities");
                } else {
                    let d = c.pos.iter().zip(&g.pos).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
                    assert!(d < 1e-3, "step {step}: body {k} differs by {d}");
                }
            }
        }
    }
    let end = cpu.world.bodies[1].enclosed_volume() * 1e-3;
    let skin = &cpu.world.bodies[0];
    let lift = skin.pos.iter().zip(&skin.rest_pos).map(|(p, r)| p.z - r.z).fold(f32::MIN, f32::max);
    eprintln!("{start:.2} → {end:.2} mL, the skin rose {lift:.2} mm, {touched} contacts");
    assert!(touched > 0 && lift > 1.0, "{lift}");
    assert!((end - 6.0).abs() < 0.05 * 6.0, "{end} mL");
}

#[test]
fn four_bodies_step_the_implicit_integrator_alike_on_cpu_and_gpu() {
    // Several bodies free to move, solved in one system on both (the voxel model's contacts
    // couple nothing): the same motion to the solve's tolerance.
    let implicit = || world().with_integrator(Integrator::Implicit(ImplicitSettings::default()));
    let Some(ctx) = common::gpu() else { return };
    let mut cpu = CpuWorld::new(implicit()).unwrap();
    let mut gpu = GpuWorld::new(&ctx, implicit()).unwrap();
    let start = cpu.world.bodies[0].pos.clone();
    for step in 1..=150 {
        cpu.step().unwrap();
        gpu.step().unwrap();
        if step % 50 == 0 {
            gpu.sync().unwrap();
            for k in 0..4 {
                let (c, g) = (&cpu.world.bodies[k], &gpu.world.bodies[k]);
                let d = c.pos.iter().zip(&g.pos).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
                assert!(d < 1e-3, "step {step}: {} differs by {d}", cpu.world.names[k]);
            }
        }
    }
    // One solve over every body, to its tolerance, in as many iterations as the CPU's (its dot
    // products in f64, the device's in f32) give or take two; the slab rose over both implants.
    let stats = gpu.stats().unwrap();
    assert!(stats.iter().all(|s| *s == stats[0]), "{stats:?}");
    assert!(stats[0].relative_residual <= ImplicitSettings::default().tolerance, "{stats:?}");
    let (c, g) = (cpu.stats[0].iterations, stats[0].iterations);
    assert!(g > 0 && c.abs_diff(g) <= 2, "{g} iterations on the GPU, {c} on the CPU");
    let rise = cpu.world.bodies[0].pos.iter().zip(&start).map(|(p, s)| p.z - s.z).fold(f32::MIN, f32::max);
    assert!(rise > 0.02, "the slab rose {rise}");
}
