//! What a contact costs per step (issue "Contacts that hold"): the surface contact, both sides,
//! with its near-triangle lists kept and made anew, against the voxel model's penalty on the
//! parallel backend, and each inside a whole explicit step of the world. The scene is the
//! contact matrix's (a 20 mm layer of tissue at a 6 mm spacing over a 300 mL implant on a
//! 140 mm base) with the implant's apex 2.5 mm into the tissue: a contact patch, not a pile-up.

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use voxcollide::parallel::ParallelCpuCollision;
use voxcollide::report::ContactReport;
use voxcollide_sim::build::build_world;
use voxcollide_sim::contact::{SurfaceContact, SurfaceForces};
use voxcollide_sim::scene_file::SceneFile;
use voxcollide_sim::{CpuWorld, World};

fn scene(response: &str) -> World {
    let text = format!(
        r#"units = "mm"
[time]
duration = 0.4
[[body]]
name = "tissue"
kind = "soft"
shape = {{ box = [200, 200, 20] }}
spacing = 6
position = [0, 0, 40]
material = {{ young_kpa = 3, density = 950.0, damping = 0.5 }}
fixed = [{{ rim = 1 }}]
[[body]]
name = "implant"
kind = "shell"
shape = {{ implant = {{ volume_ml = 300, base_mm = 140, projection_mm = 32.48, style = "round" }} }}
spacing = 6
material = {{ young_kpa = 500, density = 1000.0, damping = 0.5 }}
floor = 0.0
[[contact]]
a = "implant"
b = "tissue"
direction = "plane-normal"
response = "{response}"
"#
    );
    build_world(&SceneFile::parse("bench.toml", &text).unwrap()).unwrap().world
}

fn bench(c: &mut Criterion) {
    let world = scene("surface");
    let (a, b) = (&world.bodies[1], &world.bodies[0]);
    let penalty_world = scene("penalty");
    let pair = penalty_world.contacts[0];
    let mut group = c.benchmark_group("contact_step");
    group.sample_size(20).measurement_time(Duration::from_secs(5));
    eprintln!(
        "{} tissue and {} implant vertices on {} threads",
        b.len(),
        a.len(),
        rayon::current_num_threads()
    );

    let mut voxel =
        ParallelCpuCollision::new(pair.grid, pair.params).unwrap().with_response(pair.response()).unwrap();
    let mut report = ContactReport::default();
    group.bench_function("voxel_penalty", |bench| {
        bench.iter(|| voxel.step_into(&a.pos, &b.pos, &mut report).unwrap())
    });
    eprintln!("voxel penalty: {} tissue vertices colliding", report.colliding_b.len());

    let penalty = world.contacts[0].surface().unwrap();
    let mut surface = SurfaceContact::new(penalty, a, b).unwrap();
    let mut out = SurfaceForces::default();
    let stats = surface.step(a, b, &mut out);
    eprintln!("surface: {stats:?}");
    group.bench_function("surface_lists_kept", |bench| bench.iter(|| surface.step(a, b, &mut out)));
    group.bench_function("surface_lists_made", |bench| {
        bench.iter(|| SurfaceContact::new(penalty, a, b).unwrap().step(a, b, &mut out))
    });

    // Whole explicit steps of the world, each response (the bodies move as it steps).
    for (name, w) in
        [("world_step_surface", world.clone()), ("world_step_voxel_penalty", penalty_world.clone())]
    {
        let mut cpu = CpuWorld::new(w).unwrap();
        group.bench_function(name, |bench| bench.iter(|| cpu.step().unwrap()));
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
