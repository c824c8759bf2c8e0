//! Building a soft body from a closed surface (issue 11's goal: about 100k lattice vertices from
//! a surface of 20k triangles in at most 1 s on the 2-core development machine).

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use voxcollide::glam::{DVec3, Vec3};
use voxcollide_sim::bodies::lattice_in_surface;
use voxcollide_sim::mesh::TriangleMesh;
use voxcollide_sim::{Material, Mode};

/// A kidney bean of about 20k triangles, 120 × 60 × 50 mm.
fn kidney(rings: u32, segments: u32) -> (Vec<Vec3>, TriangleMesh) {
    let pi = std::f64::consts::PI;
    let f = |t: f64, p: f64| {
        let (x, y, z) = (t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
        DVec3::new(60.0 * x, 30.0 * (y + 0.55 * (1.0 - x * x)), 25.0 * z).as_vec3()
    };
    let mut pos = vec![f(0.0, 0.0)];
    for r in 1..=rings {
        for s in 0..segments {
            pos.push(f(
                pi * f64::from(r) / f64::from(rings + 1),
                2.0 * pi * f64::from(s) / f64::from(segments),
            ));
        }
    }
    pos.push(f(pi, 0.0));
    let south = 1 + rings * segments;
    let at = |r: u32, s: u32| 1 + r * segments + s % segments;
    let mut triangles = Vec::new();
    for s in 0..segments {
        triangles.push([0, at(0, s), at(0, s + 1)]);
        triangles.push([south, at(rings - 1, s + 1), at(rings - 1, s)]);
    }
    for r in 0..rings - 1 {
        for s in 0..segments {
            triangles.push([at(r, s), at(r + 1, s), at(r + 1, s + 1)]);
            triangles.push([at(r, s), at(r + 1, s + 1), at(r, s + 1)]);
        }
    }
    (pos, TriangleMesh { triangles })
}

fn bench(c: &mut Criterion) {
    let (pos, mesh) = kidney(70, 142);
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
