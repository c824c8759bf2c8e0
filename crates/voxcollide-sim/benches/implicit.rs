//! The implicit integrator's step (issue 21, item 5): a block of about 20,000 vertices pressed
//! at its top, as springs and as Neo-Hookean tetrahedra, on one thread and on every core. The
//! step's trajectory is the same on any number of threads (tests/implicit.rs), so the two
//! figures time the same work. And a ball pressed into a block through the default surface
//! contact, whose couplings join the two bodies' solve, on the GPU and the CPU.
//!
//!     cargo bench -p voxcollide-sim --bench implicit

use std::sync::Arc;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use voxcollide::glam::{UVec3, Vec3};
use voxcollide_sim::bodies::box_lattice;
use voxcollide_sim::material::neo_hookean::{Elements, lattice_tets};
use voxcollide_sim::{CpuWorld, ImplicitSettings, Integrator, Material, Mode, StepInputs, World};

/// A block 27 × 27 × 27 vertices (19,683), its base pinned and its top pressed down by 5 % over
/// the first 20 steps; `elements`: Neo-Hookean at ν = 0.45, else the paper's springs.
fn block(elements: bool) -> CpuWorld {
    let mut w = CpuWorld::new(block_world(elements)).unwrap();
    // Into the press, where the solve has work every step.
    for _ in 0..10 {
        w.step().unwrap();
    }
    w
}

fn block_world(elements: bool) -> World {
    let n = 27;
    let material = Material { mass: 1.0, stiffening: 0.0, spring_damping: 0.1, damping: 0.1 };
    let mut body = box_lattice(UVec3::splat(n), 1.0, Vec3::ZERO, 0.4, material, |v| {
        if v.z == 0 {
            Mode::Pinned
        } else if v.z == n - 1 {
            Mode::Driven
        } else {
            Mode::Free
        }
    })
    .unwrap();
    if elements {
        body.elements =
            Some(Elements::new(&body.rest_pos, &lattice_tets(&body.rest_pos, 1.0), 1.0, 0.45).unwrap());
        body.springs.iter_mut().for_each(|s| s.k = 0.0);
    }
    let dt = 10.0 * body.stable_dt(0.1);
    let press = -0.05 * (n - 1) as f32;
    let schedule = Arc::new(move |step: u64| {
        vec![StepInputs {
            drive: Vec3::new(0.0, 0.0, press * (step as f32 / 20.0).min(1.0)),
            ..StepInputs::at_rest(dt)
        }]
    });
    World::new(vec!["block".into()], vec![body], Vec::new(), 1e6, schedule)
        .unwrap()
        .with_integrator(Integrator::Implicit(ImplicitSettings::default()))
}

fn bench(c: &mut Criterion) {
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let mut group = c.benchmark_group("implicit_step_20k");
    group.sample_size(10).measurement_time(Duration::from_secs(15));
    for (name, elements) in [("springs", false), ("neo_hookean", true)] {
        for threads in [1, cores].into_iter().collect::<std::collections::BTreeSet<_>>() {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut w = pool.install(|| block(elements));
            eprintln!("{name}, {threads} thread(s): {} CG iterations a step", w.stats[0].iterations);
            // Each timed step starts from the same state, so that both thread counts time the
            // same solve.
            // The solver's first guess (the last step's answer) is part of that state.
            let (pos, vel, guess) =
                (w.world.bodies[0].pos.clone(), w.world.bodies[0].vel.clone(), w.guess.clone());
            group.bench_function(format!("{name}_{threads}_threads"), |b| {
                b.iter_custom(|iters| {
                    let mut total = Duration::ZERO;
                    for _ in 0..iters {
                        w.world.bodies[0].pos.clone_from(&pos);
                        w.world.bodies[0].vel.clone_from(&vel);
                        w.guess.clone_from(&guess);
                        let start = std::time::Instant::now();
                        pool.install(|| w.step().unwrap());
                        total += start.elapsed();
                    }
                    total
                });
            });
        }
    }
    group.finish();
    paired_ratio(cores);
}

/// The ratio of one thread's step to every core's, measured in pairs: the same step from the
/// same state on one thread and then on every core (or the other way round, every other pair),
/// so that both halves of a pair see the same moment of a shared machine. Criterion's two
/// figures above come from runs a minute apart, and this machine's speed moves by more than
/// the ratio's margin over that time. Prints the median of the pairs' ratios and its quartiles.
fn paired_ratio(cores: usize) {
    if cores < 2 {
        return;
    }
    let pairs = std::env::var("VOXCOLLIDE_PAIRS").ok().and_then(|s| s.parse().ok()).unwrap_or(41);
    for (name, elements) in [("springs", false), ("neo_hookean", true)] {
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let all = rayon::ThreadPoolBuilder::new().num_threads(cores).build().unwrap();
        let mut w = all.install(|| block(elements));
        let (pos, vel, guess) =
            (w.world.bodies[0].pos.clone(), w.world.bodies[0].vel.clone(), w.guess.clone());
        let mut time = |pool: &rayon::ThreadPool| {
            w.world.bodies[0].pos.clone_from(&pos);
            w.world.bodies[0].vel.clone_from(&vel);
            w.guess.clone_from(&guess);
            let start = std::time::Instant::now();
            pool.install(|| w.step().unwrap());
            start.elapsed().as_secs_f64()
        };
        // Warm both pools and the pages.
        time(&one);
        time(&all);
        let mut ratios = Vec::with_capacity(pairs);
        let (mut t1, mut tn) = (Vec::with_capacity(pairs), Vec::with_capacity(pairs));
        for k in 0..pairs {
            let (a, b) = if k % 2 == 0 {
                let a = time(&one);
                (a, time(&all))
            } else {
                let b = time(&all);
                (time(&one), b)
            };
            ratios.push(a / b);
            t1.push(a);
            tn.push(b);
        }
        let median = |v: &mut Vec<f64>, q: f64| {
            v.sort_by(f64::total_cmp);
            v[((v.len() - 1) as f64 * q).round() as usize]
        };
        eprintln!(
            "implicit_step_20k/{name}: {cores} threads against 1, {pairs} interleaved pairs: \
             median {:.2}× (quartiles {:.2}–{:.2}×); medians {:.1} / {:.1} ms",
            median(&mut ratios, 0.5),
            median(&mut ratios, 0.25),
            median(&mut ratios, 0.75),
            median(&mut t1, 0.5) * 1e3,
            median(&mut tn, 0.5) * 1e3,
        );
    }
}

/// The springs' block and the Neo-Hookean one stepped on the GPU's implicit passes (`GpuWorld`)
/// and on the CPU on every core, each from step 10 of the press on, step after step: a device's state cannot be set
/// back cheaply, so each figure is a run of consecutive steps of the same trajectory (the two
/// agree to the solve's tolerance, tests/implicit.rs), not the same step again and again.
fn gpu(c: &mut Criterion) {
    let ctx = match voxcollide::GpuContext::new() {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("implicit_steps_20k_gpu skipped: no adapter ({e})");
            return;
        }
    };
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let mut group = c.benchmark_group("implicit_steps_20k");
    group.sample_size(10).measurement_time(Duration::from_secs(20));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(cores).build().unwrap();
    for (name, elements) in [("springs", false), ("neo_hookean", true)] {
        let mut on_gpu = voxcollide_sim::GpuWorld::new(&ctx, block_world(elements)).unwrap();
        for _ in 0..10 {
            on_gpu.step().unwrap();
        }
        eprintln!(
            "{name} on {}: {} CG iterations a step",
            ctx.adapter_name(),
            on_gpu.stats().map_or(0, |s| s[0].iterations)
        );
        group.bench_function(format!("{name}_gpu"), |b| b.iter(|| on_gpu.step().unwrap()));
        let mut on_cpu = pool.install(|| block(elements));
        group.bench_function(format!("{name}_cpu_{cores}_threads"), |b| {
            b.iter(|| pool.install(|| on_cpu.step().unwrap()))
        });
    }
    group.finish();
}

/// A rigid ball pressed 3 mm into a soft block of 10,571 vertices through the default surface
/// contact, implicit (a scene file).
const PRESS: &str = r#"
units = "mm"
[time]
integrator = "implicit"
max_steps = 100000
[[body]]
name = "block"
kind = "soft"
shape = { box = [30, 30, 10] }
spacing = 1
material = { young_kpa = 10 }
fixed = [{ below = { z = -4.5 } }]
[[body]]
name = "ball"
kind = "rigid"
shape = { sphere = 6 }
spacing = 1.5
position = [0, 0, 11]
motion = [{ t = 0.0, position = [0, 0, 11] }, { t = 0.05, position = [0, 0, 8] }]
[[contact]]
a = "ball"
b = "block"
"#;

/// The press's world, and the steps until the ball pushes the block.
fn press_world() -> (World, u64) {
    let file = voxcollide_sim::scene_file::SceneFile::parse("press.toml", PRESS).unwrap();
    let world = voxcollide_sim::build::build_world(&file).unwrap().world;
    let mut cpu = CpuWorld::new(world.clone()).unwrap();
    let mut steps = 0;
    while cpu.surface_stats[0].a_pushed + cpu.surface_stats[0].b_pushed == 0 && steps < 2000 {
        cpu.step().unwrap();
        steps += 1;
    }
    (world, steps + 5)
}

/// The press stepped on the GPU (the host's search, the couplings in the device's solve) and on
/// the CPU on every core, consecutive steps from five after the first push on.
fn surface_press(c: &mut Criterion) {
    let ctx = match voxcollide::GpuContext::new() {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("implicit_surface_press skipped: no adapter ({e})");
            return;
        }
    };
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let mut group = c.benchmark_group("implicit_surface_press");
    group.sample_size(10).measurement_time(Duration::from_secs(20));
    let (world, into) = press_world();
    let mut on_gpu = voxcollide_sim::GpuWorld::new(&ctx, world.clone()).unwrap();
    let mut on_cpu = CpuWorld::new(world).unwrap();
    for _ in 0..into {
        on_gpu.step().unwrap();
        on_cpu.step().unwrap();
    }
    eprintln!(
        "press on {}, step {into}: {} and {} CG iterations a step (GPU, CPU), {} pushes",
        ctx.adapter_name(),
        on_gpu.stats().map_or(0, |s| s[0].iterations),
        on_cpu.stats[0].iterations,
        on_cpu.surface_stats[0].a_pushed + on_cpu.surface_stats[0].b_pushed
    );
    // The same 8 steps on each, timed one by one (criterion's figures below run each for as
    // many steps as fit its time, so the CPU's reach the press's cheaper, later steps).
    let median_of = |step: &mut dyn FnMut() -> u32| {
        let (mut ms, mut iterations) = (Vec::new(), 0);
        for _ in 0..8 {
            let t = std::time::Instant::now();
            iterations += step();
            ms.push(t.elapsed().as_secs_f64() * 1e3);
        }
        ms.sort_by(f64::total_cmp);
        (ms[ms.len() / 2], iterations)
    };
    let (gpu_ms, gpu_its) = median_of(&mut || {
        on_gpu.step().unwrap();
        on_gpu.stats().map_or(0, |s| s[0].iterations)
    });
    let (cpu_ms, cpu_its) = median_of(&mut || {
        on_cpu.step().unwrap();
        on_cpu.stats[0].iterations
    });
    eprintln!(
        "implicit_surface_press: steps {into}..{}: median {gpu_ms:.1} ms a step on the GPU ({gpu_its} CG iterations in all), {cpu_ms:.1} ms on the CPU, {cores} threads ({cpu_its}); {:.1}×",
        into + 8,
        gpu_ms / cpu_ms
    );
    group.bench_function("gpu", |b| b.iter(|| on_gpu.step().unwrap()));
    group.bench_function(format!("cpu_{cores}_threads"), |b| b.iter(|| on_cpu.step().unwrap()));
    group.finish();
}

criterion_group!(benches, bench, gpu, surface_press);
criterion_main!(benches);
