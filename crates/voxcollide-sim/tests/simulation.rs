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
    let text = include_str!("../../../scenes/indentation.toml")
        .replace("[time]", &format!("[time]\nintegrator = \"{integrator}\""))
        .replace("position = [0, 0, 14]", "position = [0, 0, 13.05]")
        .replace("{ t = 0.0, position = [0, 0, 14] }", "{ t = 0.0, position = [0, 0, 13.05] }");
    let built = build_world(&SceneFile::parse("indentation.toml", &text).unwrap()).unwrap();
    assert_eq!(built.world.names, ["block", "ball"]);
    built.world
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
    // Only the GPU waits for a device: here once a step, for the surface contact's search.
    assert_eq!(cpu.host_waits(), None);
    assert_eq!(gpu.host_waits(), Some(n));
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
