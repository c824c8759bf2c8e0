//! Building a soft body from a closed surface (issue 11's goal: about 100k lattice vertices from
//! a surface of 20k triangles in at most 1 s on the 2-core development machine).

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use voxcollide_sim::bodies::lattice_in_surface;
use voxcollide_sim::{Material, Mode};

#[path = "../tests/common/shapes.rs"]
mod shapes;

fn bench(c: &mut Criterion) {
    let kidney = shapes::kidney_of(70, 142);
    let (pos, mesh) = (kidney.positions, kidney.mesh);
    let material = Material { mass: 1.0, stiffening: 10.0, spring_damping: 0.6, damping: 0.1 };
    let (_, report) = lattice_in_surface(&pos, &mesh, 1.3, 1.0, material, |_| Mode::Free).unwrap();
    eprintln!("{} triangles → {report:?}", mesh.triangles.len());
    let mut group = c.benchmark_group("lattice_in_surface");
    group.sample_size(10).measurement_time(Duration::from_secs(20));
    group.bench_function("kidney_20k_triangles", |b| {
        b.iter(|| lattice_in_surface(&pos, &mesh, 1.3, 1.0, material, |_| Mode::Free).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
