//! The one seam over both worlds: `simulation(ctx, world)` steps a scene file's world through a
//! `Box<dyn Simulation>` on the CPU and on the GPU alike. Under the explicit integrator the two
//! give the same positions and reports, to the bit (on llvmpipe); what varies with the
//! integrator (`time`, `residual`, `parts`) is there only where the step varies; and only the
//! GPU counts the times a step waited for the device: never, for an explicit step with the
//! voxel model's contact.

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod common;

use voxcollide_sim::build::build_world;
use voxcollide_sim::scene_file::SceneFile;
use voxcollide_sim::{Simulation, World, simulation};

/// The shipped indentation scene (a ball pressed into a block, the default surface contact),
/// the ball started just above the block so that they touch within a few dozen steps, under
/// `integrator`.
fn world(integrator: &str) -> World {
    indentation(
        integrator,
        &[
            ("position = [0, 0, 14]", "position = [0, 0, 13.05]"),
            ("{ t = 0.0, position = [0, 0, 14] }", "{ t = 0.0, position = [0, 0, 13.05] }"),
        ],
    )
}

/// The shipped indentation scene under `integrator`, with each `(from, to)` of `edits` made to
/// its text.
fn indentation(integrator: &str, edits: &[(&str, &str)]) -> World {
    let text = edits.iter().fold(
        include_str!("../../../scenes/indentation.toml")
            .replace("[time]", &format!("[time]\nintegrator = \"{integrator}\"")),
        |text, (from, to)| text.replace(from, to),
    );
    let built = build_world(&SceneFile::parse("indentation.toml", &text).unwrap()).unwrap();
    assert_eq!(built.world.names, ["block", "ball"]);
    built.world
}

/// Whether the last step's first contact pushed any vertex of its body `b`.
fn cr_block_forces(sim: &mut dyn Simulation) -> bool {
    let (_, reports) = sim.frame().unwrap();
    reports[0].force_b.iter().any(|f| *f != voxcollide::glam::Vec3::ZERO)
}

fn steps(sim: &mut dyn Simulation, n: u64) {
    for _ in 0..n {
        sim.step().unwrap();
    }
}

#[test]
fn both_backends_step_an_explicit_world_through_one_seam_to_the_same_bits() {
    let Some(ctx) = common::gpu() else { return };
    let w = world("explicit");
    let mut cpu = simulation(None, w.clone()).unwrap();
    let mut gpu = simulation(Some(&ctx), w).unwrap();
    assert_eq!((cpu.backend(), gpu.backend()), ("cpu", "gpu"));
    let n = 60;
    steps(&mut *cpu, n);
    steps(&mut *gpu, n);
    assert_eq!((cpu.steps_done(), gpu.steps_done()), (n, n));
    let (cw, cr) = cpu.frame().unwrap();
    let (cw, cr) = (cw.clone(), cr);
    let (gw, gr) = gpu.frame().unwrap();
    for (k, (c, g)) in cw.bodies.iter().zip(&gw.bodies).enumerate() {
        if let Some(i) = (0..c.len()).find(|&i| c.pos[i] != g.pos[i]) {
            panic!("body {k} vertex {i}: cpu {} gpu {}", c.pos[i], g.pos[i]);
        }
    }
    assert_eq!(cr[0].colliding_b, gr[0].colliding_b);
    assert!(!cr[0].colliding_b.is_empty(), "the ball should touch the block within {n} steps");
    // The explicit step is the schedule's: no time, residual or parts of its own.
    for sim in [&cpu, &gpu] {
        assert_eq!((sim.time(), sim.residual(), sim.parts().is_some()), (None, None, false));
    }
    // Only the GPU could wait for a device, and it does not: the surface contact steps there
    // whole (docs/contacts.md, "The search on the device").
    assert_eq!(cpu.host_waits(), None);
    assert_eq!(gpu.host_waits(), Some(0), "an explicit step read something back");
}

/// The indentation scene under the explicit integrator with the ball driven 3 mm into the
/// block within 0.04 s and held there (the default surface contact, both ways): the device's
/// steps are the CPU's to the bit, and so are the contact's forces on both bodies and the block's
/// vertices it touches, at every frame while the ball goes in and holds; no step waits for the
/// device.
#[test]
fn a_ball_pressed_into_a_block_steps_on_the_device_as_on_the_cpu_without_a_wait() {
    let Some(ctx) = common::gpu() else { return };
    let text = include_str!("../../../scenes/indentation.toml")
        .replace("[time]", "[time]\nintegrator = \"explicit\"")
        .replace("position = [0, 0, 14]", "position = [0, 0, 13.05]")
        .replace("{ t = 0.0, position = [0, 0, 14] }", "{ t = 0.0, position = [0, 0, 13.05] }")
        .replace("{ t = 0.2, position = [0, 0, 10] }", "{ t = 0.04, position = [0, 0, 10] }");
    assert!(text.contains("t = 0.04"), "{text}");
    let built = build_world(&SceneFile::parse("indentation.toml", &text).unwrap()).unwrap();
    assert!(built.world.contacts[0].surface().is_some(), "the surface contact");
    let w = built.world;
    let mut cpu = simulation(None, w.clone()).unwrap();
    let mut gpu = simulation(Some(&ctx), w).unwrap();
    let mut touched = 0;
    for round in 0..5 {
        steps(&mut *cpu, 80);
        steps(&mut *gpu, 80);
        let (cw, cr) = cpu.frame().unwrap();
        let (cw, cr) = (cw.clone(), cr);
        let (gw, gr) = gpu.frame().unwrap();
        for (k, (c, g)) in cw.bodies.iter().zip(&gw.bodies).enumerate() {
            if let Some(i) = (0..c.len()).find(|&i| c.pos[i] != g.pos[i]) {
                panic!("round {round}, body {k} vertex {i}: cpu {} gpu {}", c.pos[i], g.pos[i]);
            }
        }
        assert_eq!(cr[0].colliding_b, gr[0].colliding_b, "round {round}");
        assert_eq!(cr[0].force_a, gr[0].force_a, "round {round}");
        assert_eq!(cr[0].force_b, gr[0].force_b, "round {round}");
        touched = touched.max(cr[0].colliding_b.len());
    }
    assert!(touched > 15, "the ball should press into the block: {touched} of its vertices touched at most");
    // (The ball is driven: the forces on it are zero. The block's are its own pushes out of the
    // ball and the reactions of the ball's pushes out of it, on its triangles' corners.)
    assert!(cr_block_forces(&mut *cpu), "the block should feel the contact");
    assert_eq!(gpu.host_waits(), Some(0), "an explicit step read something back");
}

#[test]
fn an_explicit_step_with_the_voxel_models_contact_never_waits_for_the_device() {
    // docs/design.md §5: a step stays on the device. With the voxel model's penalty the whole
    // explicit step (collision, forces, integration) is recorded and submitted, nothing read
    // back: no wait while it steps, and the contact is found (the reports, read at the frame,
    // after the count, match the CPU's to the bit).
    let Some(ctx) = common::gpu() else { return };
    let text = include_str!("../../../scenes/indentation.toml")
        .replace("[time]", "[time]\nintegrator = \"explicit\"")
        .replace("b = \"block\"", "b = \"block\"\nresponse = \"penalty\"")
        .replace("position = [0, 0, 14]", "position = [0, 0, 13.05]")
        .replace("{ t = 0.0, position = [0, 0, 14] }", "{ t = 0.0, position = [0, 0, 13.05] }");
    let built = build_world(&SceneFile::parse("indentation.toml", &text).unwrap()).unwrap();
    assert!(built.world.contacts[0].surface().is_none(), "the voxel model's penalty");
    let w = built.world;
    let mut cpu = simulation(None, w.clone()).unwrap();
    let mut gpu = simulation(Some(&ctx), w).unwrap();
    let n = 200;
    steps(&mut *cpu, n);
    steps(&mut *gpu, n);
    assert_eq!(gpu.host_waits(), Some(0), "an explicit step read something back");
    let (_, cr) = cpu.frame().unwrap();
    let (_, gr) = gpu.frame().unwrap();
    assert!(!cr[0].colliding_b.is_empty(), "the ball should touch the block within {n} steps");
    assert_eq!(cr[0].colliding_b, gr[0].colliding_b);
}

#[test]
fn an_implicit_world_keeps_its_own_time_residual_and_parts_on_either_backend() {
    let ctx = common::gpu();
    let w = world("implicit");
    let mut sims = vec![simulation(None, w.clone()).unwrap()];
    if let Some(ctx) = &ctx {
        sims.push(simulation(Some(ctx), w).unwrap());
    }
    for sim in &mut sims {
        steps(&mut **sim, 5);
        let time = sim.time().unwrap_or_else(|| panic!("{}: no time of its own", sim.backend()));
        assert!(time > 0.0, "{}: {time}", sim.backend());
        assert!(sim.residual().is_some() && sim.parts().is_some(), "{}", sim.backend());
        sim.accelerate(4.0);
        steps(&mut **sim, 2);
        assert!(sim.time().unwrap() > time, "{}", sim.backend());
        let (world, reports) = sim.frame().unwrap();
        assert_eq!(reports.len(), world.contacts.len());
        assert!(world.bodies.iter().all(|b| b.pos.iter().all(|p| p.is_finite())));
    }
}

#[test]
fn an_implicit_step_before_its_surface_contact_touches_waits_for_its_solve_once() {
    // The ball held 20 mm over the block: the surface contact has no coupling yet, so the
    // farthest move rides with the solve's readback. The contact's search and couplings are the
    // device's (`shaders/couple_build.wgsl`): a step waits for its solve alone, once.
    let Some(ctx) = common::gpu() else { return };
    let held = indentation(
        "implicit",
        &[
            ("position = [0, 0, 14]", "position = [0, 0, 34]"),
            ("{ t = 0.2, position = [0, 0, 10] }", "{ t = 0.2, position = [0, 0, 34] }"),
        ],
    );
    let mut gpu = voxcollide_sim::GpuWorld::new(&ctx, held.clone()).unwrap();
    let mut cpu = voxcollide_sim::CpuWorld::new(held).unwrap();
    let before = gpu.host_waits();
    for _ in 0..20 {
        gpu.step().unwrap();
        cpu.step().unwrap();
    }
    let waits = gpu.host_waits() - before;
    assert!(waits <= 20, "{waits} waits in 20 steps");
    // The same answer as the CPU's, to the solve's tolerance.
    let (gw, _) = Simulation::frame(&mut gpu).unwrap();
    let block = &gw.bodies[0];
    let moved = block.pos.iter().zip(block.start()).map(|(p, r)| p.distance(*r)).fold(0.0, f32::max);
    let apart =
        block.pos.iter().zip(&cpu.world.bodies[0].pos).map(|(g, c)| g.distance(*c)).fold(0.0, f32::max);
    assert!(apart <= 1e-2 * moved.max(1e-3), "gpu and cpu {apart} apart, moved {moved}");
}

#[test]
fn an_implicit_solve_reads_back_about_once_whatever_its_iterations() {
    // The device stops a solve itself, and the host records as many iterations as the last
    // solve took before its first readback (`Setup::expect` in src/gpu/implicit.rs): a step
    // waits for its solve (its farthest move and the contact's arrival test read with it), but
    // not once per batch of 8 iterations, nor for the positions (the contact's search and
    // couplings are built on the device, `shaders/couple_build.wgsl`), nor for the impulses
    // (applied there too, `shaders/couple_impulse.wgsl`).
    let Some(ctx) = common::gpu() else { return };
    let mut gpu = voxcollide_sim::GpuWorld::new(&ctx, world("implicit")).unwrap();
    let mut rows = Vec::new();
    for _ in 0..60 {
        let before = gpu.host_waits();
        gpu.step().unwrap();
        let iterations = gpu.stats().map_or(0, |s| s[0].iterations);
        rows.push((iterations, gpu.host_waits() - before));
    }
    // Steps of 24 to 40 iterations (mostly one round of the contact's active set; a second
    // round reads once more): 1 wait (the solve with its farthest move and arrival test), 2
    // with a second round, 3 where the solve also runs past its predecessor's iterations. Read
    // batch by batch, each would wait 3 to 5 times for its solve alone; with the positions read
    // for a search on the host, once more a step (2 to 4, as before the device built the
    // couplings).
    let steady: Vec<_> = rows.iter().filter(|(i, _)| (24..=40).contains(i)).collect();
    let few = steady.iter().filter(|(_, w)| *w <= 1).count();
    assert!(steady.len() >= 20 && few * 10 >= steady.len() * 8, "(iterations, waits) per step: {rows:?}");
    assert!(steady.iter().all(|(_, w)| *w <= 3), "(iterations, waits) per step: {rows:?}");
}
