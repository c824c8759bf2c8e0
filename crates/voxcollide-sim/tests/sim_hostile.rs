//! Hostile input one layer up: the simulator meets NaN or huge positions appearing mid-run, and
//! bodies without volume. Each is a named error or a run that stays finite, on the CPU and on
//! the GPU, never a panic and never a NaN handed on.

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod common;

use voxcollide::glam::{UVec3, Vec3};
use voxcollide::*;
use voxcollide_sim::*;

fn scene(kind: Kind) -> Scene {
    Scene::new(SceneConfig { resolution: 8, steps: 200, ..SceneConfig::new(kind) }).unwrap()
}

/// The scene after `steps` CPU steps: a run in progress, with the bodies in contact.
fn mid_run(kind: Kind, steps: u32) -> Scene {
    let mut scene = scene(kind);
    let mut cpu = CpuWorld::new(scene.world().unwrap()).unwrap();
    for _ in 0..steps {
        cpu.step().unwrap();
    }
    scene.follow(&cpu.world);
    scene
}

/// What may become of a poisoned vertex: a blow-up named by its body and vertex, or a run that
/// stays finite.
fn assert_named_or_finite(what: &str, result: Result<(), Error>, world: &World) {
    match result {
        Err(Error::Simulation { step, message }) => {
            assert!(step >= 1, "{what}: step {step}");
            assert!(message.contains("vertex") && message.contains("likely cause"), "{what}: {message}");
        }
        Err(e) => panic!("{what}: not a simulation error: {e:?}"),
        Ok(()) => {
            for body in &world.bodies {
                assert!(
                    body.pos.iter().chain(&body.vel).all(|v| v.is_finite()),
                    "{what}: a NaN was handed on"
                );
            }
        }
    }
}

/// The poisons: a NaN, an infinity, and positions far beyond the scene (1e30, f32::MAX).
const POISONS: [f32; 4] = [f32::NAN, f32::INFINITY, 1e30, f32::MAX];

fn poison(scene: &mut Scene, tissue: bool, value: f32) {
    let body = if tissue { &mut scene.tissue } else { &mut scene.foreign };
    let i = body.len() / 2;
    body.pos[i] = Vec3::new(body.pos[i].x, value, body.pos[i].z);
}

#[test]
fn nan_or_huge_positions_mid_run_stop_the_cpu_run_with_a_named_error() {
    for kind in [Kind::Cylinder, Kind::Implant] {
        for tissue in [true, false] {
            for value in POISONS {
                let what = format!("{kind:?} tissue {tissue} value {value}");
                let mut scene = mid_run(kind, 30);
                poison(&mut scene, tissue, value);
                let mut cpu = CpuWorld::new(scene.world().unwrap()).unwrap();
                let mut result = Ok(());
                for _ in 0..20 {
                    result = cpu.step();
                    if result.is_err() {
                        break;
                    }
                }
                if !value.is_finite() {
                    // A position that is not finite is seen at the very next step.
                    let Err(Error::Simulation { step, .. }) = &result else { panic!("{what}: {result:?}") };
                    assert_eq!(*step, 1, "{what}");
                }
                assert_named_or_finite(&what, result, &cpu.world);
            }
        }
    }
}

#[test]
fn a_blow_up_names_the_cause_its_integrator_makes_likely() {
    // The implicit integrator has no stability bound: its blow-up does not blame the time step.
    for implicit in [false, true] {
        let mut scene = mid_run(Kind::Implant, 30);
        poison(&mut scene, true, f32::NAN);
        let mut world = scene.world().unwrap();
        if implicit {
            world = world.with_integrator(Integrator::Implicit(ImplicitSettings::default()));
        }
        let Err(Error::Simulation { message, .. }) = CpuWorld::new(world).unwrap().step() else {
            panic!("implicit {implicit}: a NaN went unseen")
        };
        assert_eq!(message.contains("stability bound"), !implicit, "{message}");
        assert_eq!(message.contains("turned inside out"), implicit, "{message}");
    }
}

#[test]
fn nan_or_huge_positions_mid_run_stop_the_gpu_run_with_a_named_error() {
    let Some(ctx) = common::gpu() else { return };
    for kind in [Kind::Cylinder, Kind::Implant] {
        for tissue in [true, false] {
            for value in POISONS {
                let what = format!("{kind:?} tissue {tissue} value {value}");
                let mut scene = mid_run(kind, 30);
                poison(&mut scene, tissue, value);
                let mut gpu = GpuWorld::new(&ctx, scene.world().unwrap()).unwrap();
                let mut result = Ok(());
                for _ in 0..20 {
                    result = gpu.step();
                    assert!(result.is_ok(), "{what}: recording failed: {result:?}");
                }
                // The GPU checks at each readback: the blow-up is named there, with its step.
                let synced = gpu.sync().map(|_| ());
                if !value.is_finite() {
                    assert!(matches!(synced, Err(Error::Simulation { step: 1, .. })), "{what}: {synced:?}");
                }
                assert_named_or_finite(&what, synced.and(result), &gpu.world);
            }
        }
    }
}

#[test]
fn bodies_without_volume_are_errors_or_finite_runs() {
    let material = Material { mass: 1.0, stiffening: 10.0, spring_damping: 0.6, damping: 0.3 };
    // A lattice or a shell of no size has springs of rest length 0: refused, by name.
    let flat_box = bodies::box_lattice(UVec3::splat(3), 0.0, Vec3::ZERO, 1.0, material, |_| Mode::Free);
    assert!(matches!(&flat_box, Err(Error::Invalid { what: "spring rest/k", .. })), "{flat_box:?}");
    let point = bodies::ellipsoid_shell(Vec3::ZERO, Vec3::ZERO, 6, 12, 0.6, 1.0, material);
    assert!(matches!(&point, Err(Error::Invalid { what: "spring rest/k", .. })), "{point:?}");
    let nan = bodies::ellipsoid_shell(Vec3::ZERO, Vec3::new(1.0, f32::NAN, 1.0), 6, 12, 0.6, 1.0, material);
    assert!(matches!(&nan, Err(Error::Invalid { .. })), "{nan:?}");

    // A shell flattened to a disc (no volume) inflating under the tissue: it runs, or stops
    // with a named blow-up, on both backends.
    let base = scene(Kind::Implant);
    let center = base.foreign.pos.iter().copied().sum::<Vec3>() / base.foreign.len() as f32;
    let extent = base.foreign.pos.iter().fold(Vec3::ZERO, |e, p| e.max((*p - center).abs()));
    // Flattened exactly, its rings fall onto one another: springs of rest length 0, refused.
    let disc = bodies::ellipsoid_shell(center, Vec3::new(extent.x, extent.y, 0.0), 6, 12, 0.6, 4.0, material);
    assert!(matches!(&disc, Err(Error::Invalid { what: "spring rest/k", .. })), "{disc:?}");
    // Flattened to 1e-5 of its width, it has (almost) no volume, and runs.
    let disc = bodies::ellipsoid_shell(
        center,
        Vec3::new(extent.x, extent.y, 1e-5 * extent.x),
        6,
        12,
        0.6,
        4.0,
        material,
    )
    .unwrap();
    let mut scene = base.clone();
    scene.foreign = disc;
    let mut cpu = CpuWorld::new(scene.world().unwrap()).unwrap();
    let result = (0..100).try_for_each(|_| cpu.step());
    eprintln!("flat shell on the CPU: {result:?}");
    assert_named_or_finite("flat shell, cpu", result, &cpu.world);
    if let Some(ctx) = common::gpu() {
        let mut gpu = GpuWorld::new(&ctx, scene.world().unwrap()).unwrap();
        for _ in 0..100 {
            gpu.step().unwrap();
        }
        let synced = gpu.sync().map(|_| ());
        assert_named_or_finite("flat shell, gpu", synced, &gpu.world);
    }
}

#[test]
fn nan_or_huge_positions_under_the_implicit_integrator_are_named_on_the_cpu_and_the_gpu() {
    let ctx = common::gpu();
    let implicit = Integrator::Implicit(ImplicitSettings::default());
    for kind in [Kind::Cylinder, Kind::Implant] {
        for tissue in [true, false] {
            for value in POISONS {
                let what = format!("implicit {kind:?} tissue {tissue} value {value}");
                let mut scene = mid_run(kind, 30);
                poison(&mut scene, tissue, value);
                let world = scene.world().unwrap().with_integrator(implicit);
                let mut cpu = CpuWorld::new(world.clone()).unwrap();
                let mut result = Ok(());
                for _ in 0..10 {
                    result = cpu.step();
                    if result.is_err() {
                        break;
                    }
                }
                let finite =
                    |w: &World| w.bodies.iter().all(|b| b.pos.iter().chain(&b.vel).all(|v| v.is_finite()));
                match &result {
                    Err(Error::Simulation { step, message }) => {
                        assert!(*step >= 1 && message.contains("vertex"), "{what}: {message}");
                    }
                    Err(e) => panic!("{what}: not a simulation error: {e:?}"),
                    Ok(()) => assert!(finite(&cpu.world), "{what}: a NaN was handed on (CPU)"),
                }
                if !value.is_finite() {
                    assert!(matches!(result, Err(Error::Simulation { step: 1, .. })), "{what}: {result:?}");
                }
                // The GPU's passes run on (a NaN ends each solve at once), and the readback
                // names the blow-up with its step.
                let Some(ctx) = ctx.as_ref() else { continue };
                let mut gpu = GpuWorld::new(ctx, world).unwrap();
                for _ in 0..10 {
                    gpu.step().unwrap_or_else(|e| panic!("{what}: recording failed: {e:?}"));
                }
                match gpu.sync() {
                    Err(Error::Simulation { step, message }) => {
                        assert!(message.contains("vertex"), "{what}: {message}");
                        assert!(value.is_finite() || step == 1, "{what}: step {step}");
                    }
                    Err(e) => panic!("{what}: not a simulation error: {e:?}"),
                    Ok(_) => {
                        assert!(value.is_finite(), "{what}: the GPU did not name it");
                        assert!(finite(&gpu.world), "{what}: a NaN was handed on (GPU)");
                    }
                }
            }
        }
    }
}

/// A ball pressed into a block, explicit, the default surface contact: between a lattice's own
/// surface and a rigid ball it steps wholly on the device (docs/contacts.md, "The search on the
/// device").
const PRESS: &str = include_str!("common/press.toml");
/// A rigid ball pressed into a lattice that carries a sphere's surface, which the contact meets
/// (`shaders/surface_embed.wgsl` writes its points each step).
const DOME: &str = include_str!("common/dome.toml");

#[test]
fn the_devices_surface_contact_meets_poisons_mid_run_with_a_named_error_or_a_finite_run() {
    let Some(ctx) = common::gpu() else { return };
    for (name, text) in [("press.toml", PRESS), ("dome.toml", DOME)] {
        poisons_on_the_device(&ctx, name, text);
    }
}

fn poisons_on_the_device(ctx: &GpuContext, name: &str, text: &str) {
    let built = voxcollide_sim::build::build_world(
        &voxcollide_sim::scene_file::SceneFile::parse(name, text).unwrap(),
    )
    .unwrap();
    let mut cpu = CpuWorld::new(built.world).unwrap();
    for _ in 0..150 {
        cpu.step().unwrap();
    }
    let s = cpu.surface_stats[0];
    assert!(s.a_pushed + s.b_pushed > 0, "{name}: the two should be in contact: {s:?}");
    // Under the implicit integrator too, where the device builds the solve's couplings from its
    // search (`shaders/couple_build.wgsl`): a NaN ends each solve at once, and the readback
    // names it.
    for implicit in [false, true] {
        for body in [0, 1] {
            for value in POISONS {
                let what = format!("{name}: implicit {implicit} body {body} value {value}");
                let mut world = cpu.world.clone();
                let b = &mut world.bodies[body];
                let i = b.len() / 2;
                b.pos[i].y = value;
                if implicit {
                    world = world.with_integrator(Integrator::Implicit(ImplicitSettings::default()));
                }
                let mut gpu = GpuWorld::new(ctx, world).unwrap();
                let mut result = Ok(());
                for _ in 0..20 {
                    result = gpu.step();
                    assert!(result.is_ok(), "{what}: recording failed: {result:?}");
                }
                if !implicit {
                    assert_eq!(gpu.host_waits(), 0, "{what}");
                }
                let synced = gpu.sync().map(|_| ());
                if !value.is_finite() {
                    assert!(matches!(synced, Err(Error::Simulation { step: 1, .. })), "{what}: {synced:?}");
                }
                // A vertex thrown far off that the implicit step holds finite is named by the
                // search instead: the surface it belongs to no longer fits the grid its search
                // bins it in, where a contact could be missed.
                let result = synced.and(result);
                if let Err(Error::Simulation { step, message }) = &result
                    && implicit
                    && message.contains("grew past the grid")
                {
                    assert!(*step >= 1 && value.is_finite(), "{what}: {message}");
                    continue;
                }
                assert_named_or_finite(&what, result, &gpu.world);
            }
        }
    }
}

#[test]
fn the_devices_surface_contact_with_nothing_to_find_steps_as_the_cpu_and_pushes_nothing() {
    // The ball far above the block all along: every search comes back empty, and the bodies
    // step to the CPU's bits, no force from the contact.
    let Some(ctx) = common::gpu() else { return };
    let far = PRESS.replace("[0, 0, 11]", "[0, 0, 80]").replace("[0, 0, 8]", "[0, 0, 70]");
    assert_eq!(far.matches("[0, 0, 80]").count(), 2, "{far}");
    let built = voxcollide_sim::build::build_world(
        &voxcollide_sim::scene_file::SceneFile::parse("far.toml", &far).unwrap(),
    )
    .unwrap();
    let mut cpu = CpuWorld::new(built.world.clone()).unwrap();
    let mut gpu = GpuWorld::new(&ctx, built.world.clone()).unwrap();
    for _ in 0..50 {
        cpu.step().unwrap();
        gpu.step().unwrap();
    }
    let reports = gpu.sync().unwrap();
    assert!(reports[0].force_a.iter().chain(&reports[0].force_b).all(|f| *f == Vec3::ZERO));
    assert!(reports[0].colliding_b.is_empty());
    for (c, g) in cpu.world.bodies.iter().zip(&gpu.world.bodies) {
        assert_eq!(c.pos, g.pos);
    }
    assert_eq!(gpu.host_waits(), 0);
    // Under the implicit integrator every coupling the device builds is empty: the bodies step
    // as on the CPU, to the solve's tolerance, and no force is reported.
    let world = built.world.with_integrator(Integrator::Implicit(ImplicitSettings::default()));
    let mut cpu = CpuWorld::new(world.clone()).unwrap();
    let mut gpu = GpuWorld::new(&ctx, world).unwrap();
    for _ in 0..50 {
        cpu.step().unwrap();
        gpu.step().unwrap();
    }
    let reports = gpu.sync().unwrap();
    assert!(reports[0].force_a.iter().chain(&reports[0].force_b).all(|f| *f == Vec3::ZERO));
    for (c, g) in cpu.world.bodies.iter().zip(&gpu.world.bodies) {
        let apart = c.pos.iter().zip(&g.pos).map(|(c, g)| c.distance(*g)).fold(0.0, f32::max);
        assert!(apart < 1e-3, "the implicit worlds are {apart} apart");
    }
}
