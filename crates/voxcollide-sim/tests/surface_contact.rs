//! Contacts measured to the partner's surface (`response = "surface"`, `SurfaceContact`): both
//! sides pushed, where the voxel model pushes only one; the force continuous across the
//! partner's edges and equal to the penalty's depth law; Newton's third law; the same bits on
//! any number of threads; the same bits on the GPU world under the explicit integrator (wholly on
//! the device between bodies that show their own surface, the search on the host for a surface a
//! lattice carries), and its refusal under the implicit one by name.

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod common;

use voxcollide::glam::{UVec3, Vec3};
use voxcollide::parallel::ParallelCpuCollision;
use voxcollide::{Anchor, ContactParams, Direction, Initializer, Response, Search};
use voxcollide_sim::bodies::{box_lattice, ellipsoid_shell, lattice_in_surface};
use voxcollide_sim::build::build_world;
use voxcollide_sim::contact::SurfaceForces;
use voxcollide_sim::scene_file::SceneFile;
use voxcollide_sim::*;

const K: f32 = 100.0;

fn material() -> Material {
    Material { mass: 1.0, stiffening: 0.0, spring_damping: 0.0, damping: 0.0 }
}

/// A 5×5×3 lattice of spacing 6: the box (0, 0, 0)–(24, 24, 12).
fn block() -> MassSpring {
    box_lattice(UVec3::new(5, 5, 3), 6.0, Vec3::ZERO, 10.0, material(), |_| Mode::Free).unwrap()
}

/// A small closed shell of radius `r` around `center`, nothing pinned.
fn ball(center: Vec3, r: f32) -> MassSpring {
    ellipsoid_shell(center, Vec3::splat(r), 4, 8, 2.0, 10.0, material()).unwrap()
}

fn penalty() -> SurfacePenalty {
    SurfacePenalty { stiffness: K, gap: 0.0, reach: 4.0, margin: 0.0 }
}

#[test]
fn a_shell_between_the_lattice_vertices_is_pushed_out_where_the_voxel_model_sees_nothing() {
    // The ball's lower half is 1.5 deep in the block's top face, between its vertices: the
    // nearest block vertex is over 3 away from every ball vertex.
    let (block, ball) = (block(), ball(Vec3::new(9.0, 9.0, 11.5), 1.0));
    let nearest =
        ball.pos.iter().flat_map(|p| block.pos.iter().map(move |q| p.distance(*q))).fold(f32::MAX, f32::min);
    assert!(nearest > 3.0, "{nearest}");

    // The voxel model, ball as A, block probing within 0.75 of a spacing: no contact at all.
    let grid = Initializer::new(4.0).margin(2).build(&ball.pos).unwrap();
    let params = ContactParams {
        magnitude: 1e3,
        search: Search::Neighbours { radius: 3.0 },
        direction: Direction::PlaneNormal,
        anchor: Anchor::FollowA,
    };
    let mut voxel = ParallelCpuCollision::new(grid, params)
        .unwrap()
        .with_response(Response::Penalty { stiffness: K, gap: 0.0 })
        .unwrap();
    let report = voxcollide::Collision::step(&mut voxel, &ball.pos, &block.pos).unwrap();
    assert!(report.colliding_b.is_empty(), "the voxel model found {:?}", report.colliding_b);

    // The surface contact pushes the ball's sunk vertices up, each by K times its depth, and the
    // block's top down as much.
    let mut contact = SurfaceContact::new(penalty(), &ball, &block).unwrap();
    let mut out = SurfaceForces::default();
    let stats = contact.step(&ball, &block, &mut out);
    assert!(stats.a_pushed > 0, "{stats:?}");
    assert!((stats.deepest - 1.5).abs() < 1e-4, "{stats:?}");
    for (p, f) in ball.pos.iter().zip(&out.force_a) {
        let depth = (12.0 - p.z).max(0.0);
        let want = Vec3::new(0.0, 0.0, K * depth);
        assert!((*f - want).length() < 1e-3 * K, "ball vertex at {p}: {f} against {want}");
    }
    let total: Vec3 = out.force_a.iter().chain(&out.force_b).copied().sum();
    let gross: f32 = out.force_a.iter().map(|f| f.length()).sum();
    assert!(gross > 0.0 && total.length() < 1e-5 * gross, "net {total} of {gross}");
    assert!(out.force_b.iter().all(|f| f.z <= 0.0));
    // Its stiffness along the push, for the implicit solve.
    let i = ball.pos.iter().position(|p| p.z < 10.51).unwrap();
    assert!((out.stiffness_a[i].z_axis.z - K).abs() < 1e-3, "{}", out.stiffness_a[i]);
}

#[test]
fn the_push_is_continuous_across_the_partners_edges() {
    // A probe sliding 1 deep under the block's top face, across its triangles' edges and
    // vertices: the same push everywhere, straight up (the voxel model's plane of the three
    // nearest turns as they change).
    let block = block();
    let mut depth_seen = Vec::new();
    for i in 0..=48 {
        let x = 3.0 + 18.0 * i as f32 / 48.0;
        let probe = ball(Vec3::new(x, 11.0, 11.5), 0.5);
        let mut contact = SurfaceContact::new(penalty(), &block, &probe).unwrap();
        let mut out = SurfaceForces::default();
        contact.step(&block, &probe, &mut out);
        let (k, bottom) = probe.pos.iter().enumerate().min_by(|a, b| a.1.z.total_cmp(&b.1.z)).unwrap();
        let f = out.force_b[k];
        let want = K * (12.0 - bottom.z);
        assert!((f - Vec3::new(0.0, 0.0, want)).length() < 1e-4 * want, "at x = {x}: {f} against {want} up");
        depth_seen.push(f.z);
    }
    assert!(depth_seen.iter().all(|z| (z - depth_seen[0]).abs() < 1e-3));
}

/// A rigid ball pressed 3 mm into a soft block (a scene file, the default response).
const PRESS: &str = include_str!("common/press.toml");

#[test]
fn a_world_of_surface_contacts_steps_the_same_on_one_and_two_threads() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let file = SceneFile::parse("press.toml", PRESS).unwrap();
            let built = build_world(&file).unwrap();
            assert!(built.world.contacts[0].surface().is_some(), "the default response is the surface one");
            let mut cpu = CpuWorld::new(built.world).unwrap();
            let mut pushed = 0;
            for _ in 0..400 {
                cpu.step().unwrap();
                pushed += cpu.surface_stats[0].a_pushed + cpu.surface_stats[0].b_pushed;
            }
            (cpu.world.bodies.iter().map(|b| b.pos.clone()).collect::<Vec<_>>(), pushed)
        })
    };
    let (one, pushed) = run(1);
    assert!(pushed > 0, "the ball never touched the block");
    let (two, _) = run(2);
    for (k, (a, b)) in one.iter().zip(&two).enumerate() {
        for (i, (p, q)) in a.iter().zip(b).enumerate() {
            assert_eq!(p.to_array().map(f32::to_bits), q.to_array().map(f32::to_bits), "body {k} vertex {i}");
        }
    }
}

/// A rigid ball pressed 2 mm into a soft sphere: a lattice that carries the sphere's surface,
/// which the contact meets (its points' forces shared by their cells' corners).
const DOME: &str = include_str!("common/dome.toml");

fn bits(v: &[Vec3]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

#[test]
fn under_the_explicit_integrator_a_surface_contact_steps_the_same_bits_on_cpu_and_gpu() {
    // Between a lattice's own surface and a ball (the block), and between the surface a
    // lattice carries and a ball (the dome: its points written each step by
    // `shaders/surface_embed.wgsl`, their forces shared by their cells' corners), the whole
    // contact steps on the device, the CPU's arithmetic in WGSL, and no step waits. The
    // device's forces and integration give the CPU's bits. (What the contact found is read back
    // with the positions: compared at those frames, all but whether the CPU's near-triangle
    // lists were rebuilt, which the device keeps none of.)
    let Some(ctx) = common::gpu() else { return };
    for (name, text, steps) in [("press.toml", PRESS, 400), ("dome.toml", DOME, 300)] {
        let built = build_world(&SceneFile::parse(name, text).unwrap()).unwrap();
        assert!(
            built.world.contacts[0].surface().is_some(),
            "{name}: the default response is the surface one"
        );
        if name == "dome.toml" {
            assert!(built.world.bodies[0].embedded.is_some(), "the dome carries its sphere");
        }
        let mut cpu = CpuWorld::new(built.world.clone()).unwrap();
        let mut gpu = GpuWorld::new(&ctx, built.world).unwrap();
        let (mut pushed, mut deepest) = (0, 0.0f32);
        for step in 1..=steps {
            cpu.step().unwrap();
            gpu.step().unwrap();
            let c = cpu.surface_stats[0];
            pushed += c.a_pushed + c.b_pushed;
            deepest = deepest.max(c.deepest);
            if step % 25 == 0 || step == steps {
                assert_eq!(gpu.host_waits(), 0, "{name}: a step waited");
                let reports = gpu.sync().unwrap();
                let g = gpu.surface_stats()[0];
                assert_eq!(
                    voxcollide_sim::contact::SurfaceStats { rebuilt: false, ..c },
                    g,
                    "{name}: step {step}"
                );
                for (k, (c, g)) in cpu.world.bodies.iter().zip(&gpu.world.bodies).enumerate() {
                    assert_eq!(bits(&c.pos), bits(&g.pos), "{name}: body {k} at step {step}");
                    assert_eq!(bits(&c.vel), bits(&g.vel), "{name}: body {k} at step {step}");
                }
                let (c, g) = (&cpu.reports[0], &reports[0]);
                assert_eq!(
                    (bits(&c.force_a), bits(&c.force_b)),
                    (bits(&g.force_a), bits(&g.force_b)),
                    "{name}"
                );
                assert_eq!(c.colliding_b, g.colliding_b, "{name}: step {step}");
            }
        }
        assert!(pushed > 100 && deepest > 0.0, "{name}: the ball never pressed ({pushed} pushes)");
        // The dome was pressed down where the ball came in.
        let lowered = gpu.world.bodies[0]
            .pos
            .iter()
            .zip(&gpu.world.bodies[0].rest_pos)
            .map(|(p, r)| r.z - p.z)
            .fold(0.0f32, f32::max);
        assert!(lowered > 0.5, "{name}: the soft body moved down at most {lowered}");
    }
}

#[test]
fn under_the_implicit_integrator_the_gpu_world_couples_a_surface_contact_as_the_cpu_does() {
    // The couplings in the device's solve, built there from its own search, pressed into a
    // block and into a lattice that carries a sphere's surface: the two backends agree to the
    // solve's tolerance while the ball is driven, and on the dent it leaves.
    let Some(ctx) = common::gpu() else { return };
    for (name, text, steps) in [("press.toml", PRESS, 60), ("dome.toml", DOME, 60)] {
        let implicit = text.replace("integrator = \"explicit\"", "integrator = \"implicit\"");
        let built = build_world(&SceneFile::parse(name, &implicit).unwrap()).unwrap();
        assert_ne!(built.world.integrator, Integrator::Explicit);
        let mut cpu = CpuWorld::new(built.world.clone()).unwrap();
        let mut gpu = GpuWorld::new(&ctx, built.world).unwrap();
        let (mut pushed, mut worst) = (0, 0.0f32);
        for step in 1..=steps {
            cpu.step().unwrap();
            gpu.step().unwrap();
            pushed += gpu.surface_stats()[0].a_pushed + gpu.surface_stats()[0].b_pushed;
            gpu.sync().unwrap();
            for (c, g) in cpu.world.bodies.iter().zip(&gpu.world.bodies) {
                let d = c.pos.iter().zip(&g.pos).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
                worst = worst.max(d);
            }
            let (c, g) = (cpu.stats[0], gpu.stats().unwrap()[0]);
            assert!(
                g.relative_residual <= ImplicitSettings::default().tolerance,
                "{name}: step {step}: {g:?}"
            );
            assert!(c.iterations.abs_diff(g.iterations) <= 2, "{name}: step {step}: {c:?} on the CPU, {g:?}");
        }
        assert!(worst < 1e-3, "{name}: the bodies differ by up to {worst} mm");
        // The contact searches and builds its couplings on the device, the dome's over the
        // surface its lattice carries (each coupling's points as their cells' corners): a step
        // waits for its solve alone, about once (a second round of the active set, once more).
        let waits = gpu.host_waits() as f64 / f64::from(steps);
        assert!((1.0..1.5).contains(&waits), "{name}: {waits} waits a step");
        let dent = |w: &World| {
            w.bodies[0].pos.iter().zip(&w.bodies[0].rest_pos).map(|(p, r)| r.z - p.z).fold(0.0f32, f32::max)
        };
        let (c, g) = (dent(&cpu.world), dent(&gpu.world));
        assert!(pushed > 0 && c > 0.5, "{name}: the ball never pressed ({pushed} pushes, dent {c})");
        assert!((c - g).abs() < 0.02 * c, "{name}: dent {c} on the CPU, {g} on the GPU");
    }
}

#[test]
fn bad_surface_parameters_are_refused_by_name() {
    let (a, b) = (block(), ball(Vec3::new(6.0, 6.0, 9.0), 1.0));
    for (p, what) in [
        (SurfacePenalty { stiffness: 0.0, ..penalty() }, "stiffness"),
        (SurfacePenalty { stiffness: f32::NAN, ..penalty() }, "stiffness"),
        (SurfacePenalty { reach: -1.0, ..penalty() }, "reach"),
        (SurfacePenalty { gap: 4.0, ..penalty() }, "gap"),
        (SurfacePenalty { gap: -0.1, ..penalty() }, "gap"),
        (SurfacePenalty { margin: -1.0, ..penalty() }, "margin"),
        (SurfacePenalty { margin: f32::INFINITY, ..penalty() }, "margin"),
    ] {
        let Err(e) = SurfaceContact::new(p, &a, &b) else { panic!("{p:?} was taken") };
        assert!(e.to_string().contains(what), "{e}");
    }
}

#[test]
fn a_vertex_outside_a_folded_shell_is_not_taken_for_inside() {
    // A shell with one triangle turned inside out (as where a flattened implant folds over
    // itself): just above that triangle its pseudo-normal says "inside". The vertex did not
    // cross the surface to get there, so the exact inside test is asked, and says outside.
    let mut shell = ball(Vec3::new(0.0, 0.0, 0.0), 4.0);
    let top = shell.surface.triangles.iter().position(|t| t.contains(&0)).unwrap();
    shell.surface.triangles[top].swap(1, 2);
    let [a, b, c] = shell.surface.triangles[top].map(|v| shell.pos[v as usize]);
    let centre = (a + b + c) / 3.0;
    let outward = centre.normalize();
    // (Not so close that the turned triangle alone makes the winding number pass ½.)
    let probe = ball(centre + 1.2 * outward, 0.2);
    // A reach of 8: every false depth here is under a quarter of it, the depth beyond which a
    // hit is always confirmed.
    let reach8 = SurfacePenalty { reach: 8.0, ..penalty() };
    let mut contact = SurfaceContact::new(reach8, &shell, &probe).unwrap();
    let mut out = SurfaceForces::default();
    let stats = contact.step(&shell, &probe, &mut out);
    assert_eq!(stats.b_pushed, 0, "{stats:?}");
    assert!(out.force_b.iter().all(|f| *f == Vec3::ZERO));
    // The same probe truly inside, 0.6 below the (intact) surface elsewhere, is pushed out.
    let side = shell.surface.triangles.iter().position(|t| !t.contains(&0)).unwrap();
    let [a, b, c] = shell.surface.triangles[side].map(|v| shell.pos[v as usize]);
    let centre = (a + b + c) / 3.0;
    let inside = ball(centre - 0.6 * centre.normalize(), 0.1);
    let mut contact = SurfaceContact::new(reach8, &shell, &inside).unwrap();
    let stats = contact.step(&shell, &inside, &mut out);
    assert!(stats.b_pushed > 0, "{stats:?}");
}

/// The device's twin of the folded shell above (`gpu::surface::DeviceSurface`, its winding
/// number summed in WGSL): the vertex outside is not pushed, the one inside is.
#[test]
fn on_the_device_too_a_vertex_outside_a_folded_shell_is_not_taken_for_inside() {
    use voxcollide::wgpu::util::DeviceExt as _;
    use voxcollide_sim::gpu::surface::DeviceSurface;
    let Some(ctx) = common::gpu() else { return };
    let mut shell = ball(Vec3::new(0.0, 0.0, 0.0), 4.0);
    let top = shell.surface.triangles.iter().position(|t| t.contains(&0)).unwrap();
    shell.surface.triangles[top].swap(1, 2);
    let [a, b, c] = shell.surface.triangles[top].map(|v| shell.pos[v as usize]);
    let centre = (a + b + c) / 3.0;
    let reach8 = SurfacePenalty { reach: 8.0, ..penalty() };
    let device = ctx.device();
    let upload = |points: &[Vec3]| {
        let padded: Vec<[f32; 4]> = points.iter().map(|p| p.extend(1.0).to_array()).collect();
        device.create_buffer_init(&voxcollide::wgpu::util::BufferInitDescriptor {
            label: Some("test points"),
            contents: bytemuck::cast_slice(&padded),
            usage: voxcollide::wgpu::BufferUsages::STORAGE,
        })
    };
    // Each probe against the shell, one step: the forces on the probe, and the stats.
    let step = |probe: &MassSpring| {
        let mut contact = DeviceSurface::new(&ctx, reach8, &shell, probe).unwrap();
        let (pa, pb) = (upload(&shell.pos), upload(&probe.pos));
        let mut encoder = device.create_command_encoder(&Default::default());
        contact.record(&mut encoder, ctx.queue(), &pa, &pb).unwrap();
        ctx.queue().submit([encoder.finish()]);
        let (_, on_probe, _) = contact.read().unwrap();
        (on_probe, contact.stats())
    };
    let (on_probe, stats) = step(&ball(centre + 1.2 * centre.normalize(), 0.2));
    assert_eq!(stats.b_pushed, 0, "{stats:?}");
    assert!(on_probe.iter().all(|f| *f == Vec3::ZERO));
    let side = shell.surface.triangles.iter().position(|t| !t.contains(&0)).unwrap();
    let [a, b, c] = shell.surface.triangles[side].map(|v| shell.pos[v as usize]);
    let centre = (a + b + c) / 3.0;
    let (on_probe, stats) = step(&ball(centre - 0.6 * centre.normalize(), 0.1));
    assert!(stats.b_pushed > 0 && on_probe.iter().any(|f| *f != Vec3::ZERO), "{stats:?}");
}

/// A ball moving down at 1 unit/s, just touching a free block, and the world of the two with a
/// stiff surface contact under the implicit integrator at a step ten times the contact's
/// period over 2π (the bodies' springs as stiff as the contact).
fn moving_ball_on_block() -> World {
    let block = box_lattice(UVec3::new(5, 5, 3), 6.0, Vec3::ZERO, 1e4, material(), |_| Mode::Free).unwrap();
    let mut ball =
        ellipsoid_shell(Vec3::new(12.0, 12.0, 15.9), Vec3::splat(4.0), 4, 8, 2.0, 1e4, material()).unwrap();
    ball.vel.iter_mut().for_each(|v| *v = Vec3::new(0.0, 0.0, -1.0));
    let grid = Initializer::new(4.0).margin(2).build(&ball.pos).unwrap();
    let params = ContactParams {
        magnitude: 1e6,
        search: Search::Neighbours { radius: 3.0 },
        direction: Direction::PlaneNormal,
        anchor: Anchor::FollowA,
    };
    let stiffness = 1e4;
    let contact = ContactPair {
        a: 0,
        b: 1,
        grid,
        params,
        model: ContactModel::Surface(SurfacePenalty { stiffness, gap: 0.0, reach: 4.0, margin: 1.0 }),
    };
    let schedule = std::sync::Arc::new(|_| vec![StepInputs::at_rest(0.1); 2]);
    World::new(vec!["ball".into(), "block".into()], vec![ball, block], vec![contact], 1e6, schedule)
        .unwrap()
        .with_integrator(Integrator::Implicit(ImplicitSettings {
            tolerance: 1e-6,
            settle_tolerance: 1e-6,
            ..Default::default()
        }))
}

fn momentum(body: &MassSpring) -> Vec3 {
    body.vel.iter().zip(&body.inv_mass).map(|(v, w)| *v / *w).sum()
}

#[test]
fn under_the_implicit_integrator_a_body_pushing_another_carries_it_within_the_step() {
    // The contact's pushes join the two bodies in one solve: the block takes up the ball's
    // momentum in the step it is struck, momentum kept as between any two bodies. (Solved each
    // against the other's start, the ball would stop at where the block was and the block be
    // pushed out of where the ball was: momentum made and lost.)
    let mut cpu = CpuWorld::new(moving_ball_on_block()).unwrap();
    let before = momentum(&cpu.world.bodies[0]) + momentum(&cpu.world.bodies[1]);
    cpu.step().unwrap();
    assert!(cpu.surface_stats[0].a_pushed > 0, "{:?}", cpu.surface_stats[0]);
    let (ball, block) = (momentum(&cpu.world.bodies[0]), momentum(&cpu.world.bodies[1]));
    let after = ball + block;
    assert!((after - before).length() < 1e-3 * before.length(), "momentum {before} → {after}");
    assert!(block.z < -0.2 * before.length(), "the block took up {block} of {before}");
    // And the two stay out of each other as they go on.
    for _ in 0..20 {
        cpu.step().unwrap();
        assert!(cpu.surface_stats[0].deepest < 0.2, "{:?}", cpu.surface_stats[0]);
    }
}

#[test]
fn on_the_gpu_a_block_released_by_the_ball_springs_back_as_on_the_cpu() {
    // The ball pressed into the block and lifted far clear again, under the implicit
    // integrator: the couplings arrive, push, leave through the margin and are gone, and the
    // block springs back as on the CPU.
    let Some(ctx) = common::gpu() else { return };
    let implicit = PRESS.replace("integrator = \"explicit\"", "integrator = \"implicit\"");
    let dt =
        build_world(&SceneFile::parse("press.toml", &implicit).unwrap()).unwrap().world.inputs(0).unwrap()[0]
            .dt;
    // In over 40 steps, out again over the next 20, far above the block.
    let (t_in, t_out) = (40.0 * dt, 60.0 * dt);
    let release = implicit.replace(
        "{ t = 0.01, position = [0, 0, 8] }]",
        &format!("{{ t = {t_in}, position = [0, 0, 8] }}, {{ t = {t_out}, position = [0, 0, 40] }}]"),
    );
    assert_ne!(release, implicit);
    let built = build_world(&SceneFile::parse("release.toml", &release).unwrap()).unwrap();
    let mut cpu = CpuWorld::new(built.world.clone()).unwrap();
    let mut gpu = GpuWorld::new(&ctx, built.world).unwrap();
    let (mut pushed, mut free_after) = (0, 0);
    for step in 1..=120 {
        cpu.step().unwrap();
        gpu.step().unwrap();
        let g = gpu.surface_stats()[0];
        pushed += g.a_pushed + g.b_pushed;
        if pushed > 0 && g.a_pushed + g.b_pushed == 0 {
            free_after += 1;
        }
        if step % 20 == 0 {
            gpu.sync().unwrap();
            for (k, (c, g)) in cpu.world.bodies.iter().zip(&gpu.world.bodies).enumerate() {
                let d = c.pos.iter().zip(&g.pos).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
                assert!(d < 1e-3, "step {step}: body {k} differs by {d} mm");
            }
        }
    }
    assert!(pushed > 50 && free_after > 20, "{pushed} pushes, {free_after} steps clear after them");
}

#[test]
fn on_the_gpu_too_a_body_pushing_another_carries_it_within_the_step() {
    // The couplings join the two free bodies' unknowns in the device's one solve: the block
    // takes up the ball's momentum in the step it is struck, momentum kept, as on the CPU; the
    // two stay out of each other (the pairs the solve carries away leave it, and the inelastic
    // impulses take away their speed apart).
    let Some(ctx) = common::gpu() else { return };
    let mut cpu = CpuWorld::new(moving_ball_on_block()).unwrap();
    let mut gpu = GpuWorld::new(&ctx, moving_ball_on_block()).unwrap();
    let before = momentum(&cpu.world.bodies[0]) + momentum(&cpu.world.bodies[1]);
    cpu.step().unwrap();
    gpu.step().unwrap();
    gpu.sync().unwrap();
    assert!(gpu.surface_stats()[0].a_pushed > 0, "{:?}", gpu.surface_stats()[0]);
    let (ball, block) = (momentum(&gpu.world.bodies[0]), momentum(&gpu.world.bodies[1]));
    let after = ball + block;
    assert!((after - before).length() < 1e-3 * before.length(), "momentum {before} → {after}");
    assert!(block.z < -0.2 * before.length(), "the block took up {block} of {before}");
    let cpu_block = momentum(&cpu.world.bodies[1]);
    assert!(
        (block - cpu_block).length() < 1e-3 * before.length(),
        "{block} on the GPU, {cpu_block} on the CPU"
    );
    for step in 0..20 {
        cpu.step().unwrap();
        gpu.step().unwrap();
        assert!(gpu.surface_stats()[0].deepest < 0.2, "{:?}", gpu.surface_stats()[0]);
        gpu.sync().unwrap();
        for k in 0..2 {
            let (c, g) = (&cpu.world.bodies[k], &gpu.world.bodies[k]);
            let d = c.pos.iter().zip(&g.pos).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
            assert!(d < 1e-3, "step {step}: body {k} differs by {d}");
        }
    }
}

#[test]
fn on_the_gpu_two_contacts_naming_the_same_bodies_in_either_order_step_as_on_the_cpu() {
    // The struck block with a second surface contact, its bodies named the other way round:
    // each coupling is read from its own contact's bodies (a = ball in one, block in the
    // other), not from the first contact that names the same two.
    let Some(ctx) = common::gpu() else { return };
    let both = || {
        let mut w = moving_ball_on_block();
        let mut swapped = w.contacts[0];
        (swapped.a, swapped.b) = (1, 0);
        w.contacts.push(swapped);
        w
    };
    let mut cpu = CpuWorld::new(both()).unwrap();
    let mut gpu = GpuWorld::new(&ctx, both()).unwrap();
    let mut pushed = [0; 2];
    for step in 0..6 {
        cpu.step().unwrap();
        gpu.step().unwrap();
        for (p, s) in pushed.iter_mut().zip(gpu.surface_stats()) {
            *p += s.a_pushed + s.b_pushed;
        }
        gpu.sync().unwrap();
        for k in 0..2 {
            let (c, g) = (&cpu.world.bodies[k], &gpu.world.bodies[k]);
            let d = c.pos.iter().zip(&g.pos).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
            assert!(d < 1e-3, "step {step}: body {k} differs by {d}");
        }
    }
    assert!(pushed.iter().all(|p| *p > 0), "pushes per contact: {pushed:?}");
}

#[test]
fn a_lattice_made_from_a_surface_meets_a_contact_at_that_surface_and_its_cells_carry_the_reaction() {
    // A lattice of spacing 5 in an ellipsoid 12 tall carries the ellipsoid (what is shown and
    // measured); its own vertices stop more than a millimetre below the top.
    let skin =
        ellipsoid_shell(Vec3::ZERO, Vec3::new(20.0, 20.0, 12.0), 12, 24, f32::MIN, 10.0, material()).unwrap();
    let (dome, _) =
        lattice_in_surface(&skin.pos, &skin.surface, 5.0, 10.0, material(), |_| Mode::Free).unwrap();
    let carried = dome.embedded.as_ref().expect("a lattice made from a surface carries it");
    let top = carried.rest.iter().map(|p| p.z).fold(f32::MIN, f32::max);
    let own_top = dome.pos.iter().map(|p| p.z).fold(f32::MIN, f32::max);
    assert!(top - own_top > 1.0, "carried top {top}, lattice top {own_top}");
    // A small ball sunk 0.5 into the carried surface's top, clear of the lattice's vertices and
    // of its own surface.
    let probe = ball(Vec3::new(0.0, 0.0, top + 0.5), 1.0);
    assert!(probe.pos.iter().all(|p| p.z > own_top + 0.2));
    let mut contact = SurfaceContact::new(penalty(), &probe, &dome).unwrap();
    let mut out = SurfaceForces::default();
    let stats = contact.step(&probe, &dome, &mut out);
    assert!(stats.a_pushed > 0, "the carried surface did not push: {stats:?}");
    assert!(stats.deepest > 0.3 && stats.deepest < 0.6, "{stats:?}");
    // Up on the ball, down on the dome's cells, equal and opposite.
    let up: f32 = out.force_a.iter().map(|f| f.z).sum();
    let down: f32 = out.force_b.iter().map(|f| f.z).sum();
    assert!(up > 0.0 && (up + down).abs() < 1e-4 * up, "{up} up, {down} down");
    let total: Vec3 = out.force_a.iter().chain(&out.force_b).copied().sum();
    assert!(total.length() < 1e-4 * up, "net {total}");
    // The reaction lands on the lattice's top vertices under the ball, nowhere else.
    for (p, f) in dome.pos.iter().zip(&out.force_b) {
        if *f != Vec3::ZERO {
            assert!(p.z > own_top - 5.01 && p.x.abs() < 10.01 && p.y.abs() < 10.01, "{p}: {f}");
        }
    }
    // Each push is listed with its stencils, for the implicit solve: the ball's vertex itself,
    // the carried surface's point as up to eight cell corners whose weights sum to 1.
    let push = out.pushes.iter().find(|p| p.of_a && p.depth > 0.0).unwrap();
    assert_eq!(push.point[0].1, 1.0);
    assert!(push.point[1..].iter().all(|e| e.0 == u32::MAX));
    let weight: f32 = voxcollide_sim::contact::entries(&push.from).map(|(_, w)| w).sum();
    assert!((weight - 1.0).abs() < 1e-5, "{weight}");
    assert!(voxcollide_sim::contact::entries(&push.from).all(|(v, _)| (v as usize) < dome.len()));
}

/// A probe driven down through a plate one cell thick is pushed back out of its top face, the
/// way it came in, all the way through, though past the plate's middle its nearest face is the
/// bottom one: a fresh contact, which has not seen it come in, pushes it on out of the bottom.
/// (A filling implant came through a patient's thin tissue over her sternum so.)
#[test]
fn a_probe_past_the_middle_of_a_thin_plate_is_pushed_out_the_way_it_came_in() {
    let plate = box_lattice(UVec3::new(5, 5, 2), 6.0, Vec3::ZERO, 10.0, material(), |_| Mode::Free).unwrap();
    let penalty = SurfacePenalty { stiffness: K, gap: 0.0, reach: 5.0, margin: 0.0 };
    let at = |z: f32| ball(Vec3::new(11.0, 10.0, z), 0.5);
    let mut contact = SurfaceContact::new(penalty, &plate, &at(7.0)).unwrap();
    let mut out = SurfaceForces::default();
    let (mut past_middle, mut z) = (0, 7.0);
    while z > 1.5 {
        let probe = at(z);
        contact.step(&plate, &probe, &mut out);
        let (k, bottom) = probe.pos.iter().enumerate().min_by(|a, b| a.1.z.total_cmp(&b.1.z)).unwrap();
        if bottom.z < 6.0 {
            let f = out.force_b[k];
            assert!(f.z > 0.0 && f.x.abs() + f.y.abs() < 1e-3 * f.z, "at {}: pushed {f}", bottom.z);
            // As deep as it is under the top face.
            assert!((f.z - K * (6.0 - bottom.z)).abs() < 1e-3 * f.z, "at {}: {f}", bottom.z);
            if bottom.z < 3.0 {
                past_middle += 1;
                let mut fresh = SurfaceContact::new(penalty, &plate, &probe).unwrap();
                let mut seen = SurfaceForces::default();
                fresh.step(&plate, &probe, &mut seen);
                assert!(seen.force_b[k].z < 0.0, "a fresh contact at {}: {}", bottom.z, seen.force_b[k]);
            }
        }
        z -= 0.25;
    }
    assert!(past_middle >= 4, "{past_middle}");
}

/// A block pressed by two rigid balls, a contact each, the block `b` of one and `a` of the
/// other: each of its vertices has couplings of both contacts.
const TWO_BALLS: &str = r#"
units = "mm"
[time]
integrator = "implicit"
steps = 60
[[body]]
name = "block"
kind = "soft"
shape = { box = [36, 24, 10] }
spacing = 3
material = { young_kpa = 10 }
fixed = [{ below = { z = -4 } }]
[[body]]
name = "left"
kind = "rigid"
shape = { sphere = 5 }
spacing = 2.5
position = [-9, 0, 10]
motion = [{ t = 0.0, position = [-9, 0, 10] }, { t = 0.01, position = [-9, 0, 8] }]
[[body]]
name = "right"
kind = "rigid"
shape = { sphere = 5 }
spacing = 2.5
position = [9, 1, 10]
motion = [{ t = 0.0, position = [9, 1, 10] }, { t = 0.01, position = [9, 1, 8.5] }]
[[contact]]
a = "left"
b = "block"
[[contact]]
a = "block"
b = "right"
"#;

#[test]
fn a_body_in_two_surface_contacts_is_coupled_on_the_device_as_on_the_cpu() {
    // The device lists each vertex's couplings of both contacts, the first contact's before the
    // second's, and sums their blocks on (`shaders/couple_lists.wgsl`): the two backends agree
    // to the solve's tolerance, and a step waits for its solve alone.
    let Some(ctx) = common::gpu() else { return };
    let built = build_world(&SceneFile::parse("two.toml", TWO_BALLS).unwrap()).unwrap();
    assert_ne!(built.world.integrator, Integrator::Explicit);
    let mut cpu = CpuWorld::new(built.world.clone()).unwrap();
    let mut gpu = GpuWorld::new(&ctx, built.world).unwrap();
    let (mut pushed, mut worst) = ([0; 2], 0.0f32);
    for step in 1..=60 {
        cpu.step().unwrap();
        gpu.step().unwrap();
        for (c, s) in pushed.iter_mut().zip(gpu.surface_stats()) {
            *c += s.a_pushed + s.b_pushed;
        }
        gpu.sync().unwrap();
        for (c, g) in cpu.world.bodies.iter().zip(&gpu.world.bodies) {
            let d = c.pos.iter().zip(&g.pos).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
            worst = worst.max(d);
        }
        let (c, g) = (cpu.stats[0], gpu.stats().unwrap()[0]);
        assert!(g.relative_residual <= ImplicitSettings::default().tolerance, "step {step}: {g:?}");
        assert!(c.iterations.abs_diff(g.iterations) <= 2, "step {step}: {c:?} on the CPU, {g:?}");
    }
    assert!(pushed.iter().all(|p| *p > 0), "a ball never pressed: {pushed:?}");
    assert!(worst < 1e-3, "the bodies differ by up to {worst} mm");
    // Each ball left its dent.
    let block = &gpu.world.bodies[0];
    for x in [-9.0f32, 9.0] {
        let dent = block
            .pos
            .iter()
            .zip(&block.rest_pos)
            .filter(|(_, r)| (r.x - x).abs() < 4.0)
            .map(|(p, r)| r.z - p.z)
            .fold(0.0f32, f32::max);
        assert!(dent > 0.2, "the dent at x = {x} is {dent} mm");
    }
    let waits = gpu.host_waits() as f64 / 60.0;
    assert!((1.0..1.5).contains(&waits), "{waits} waits a step");
}
