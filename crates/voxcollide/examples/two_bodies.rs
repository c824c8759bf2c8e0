//! A cylinder pressed into a layer of soft tissue (the paper's Fig. 5 set-up): prints the contact
//! report of the first step, then lets the penalty forces push the bodies apart over a few steps,
//! as the paper's iterative method does. Runs on the GPU adapter there is (software ones
//! included) and falls back to the CPU reference, saying so, when there is none.
//!
//! Run: `cargo run --release --example two_bodies` (add `-- --cpu` to force the CPU backend).

use std::time::Instant;

use voxcollide::glam::Vec3;
use voxcollide::{
    Anchor, Collision, ContactParams, CpuCollision, Direction, GpuCollision, GpuContext, Initializer, Search,
};

/// Tissue layer (body A): a lattice of `nx × ny × nz` vertices with spacing `h`, top face at z = 0.
fn tissue(nx: usize, ny: usize, nz: usize, h: f32) -> Vec<Vec3> {
    let mut out = Vec::with_capacity(nx * ny * nz);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                out.push(Vec3::new(i as f32 * h, j as f32 * h, -(k as f32) * h));
            }
        }
    }
    out
}

/// Cylinder (body B): surface rings of radius `r` along x, its axis at height `z`, centred in y.
fn cylinder(length: f32, r: f32, y: f32, z: f32, h: f32) -> Vec<Vec3> {
    let rings = (length / h) as usize + 1;
    let around = ((std::f32::consts::TAU * r) / h).ceil() as usize;
    let mut out = Vec::with_capacity(rings * around);
    for i in 0..rings {
        for k in 0..around {
            let t = k as f32 / around as f32 * std::f32::consts::TAU;
            out.push(Vec3::new(i as f32 * h, y + r * t.cos(), z + r * t.sin()));
        }
    }
    out
}

fn main() -> Result<(), voxcollide::Error> {
    let h = 0.125;
    let a = tissue(64, 64, 8, h);
    // The cylinder (radius 1) sinks 0.3 below the tissue's top face.
    let mut b = cylinder(63.0 * h, 1.0, 32.0 * h, 0.7, h / 2.0);

    // Only the top half of the tissue's bounding cube can meet the cylinder.
    let grid = Initializer::new(h).margin(1).contact_half(Vec3::Z).build(&a)?;
    let params = ContactParams {
        magnitude: 1.0,
        search: Search::Neighbours { radius: h },
        direction: Direction::Pairwise,
        anchor: Anchor::Fixed,
    };
    println!(
        "voxcollide two_bodies: tissue layer (A, {} vertices) and cylinder (B, {} vertices)",
        a.len(),
        b.len()
    );
    println!("grid: center {}, voxel {}, dims {}", grid.center(), grid.voxel_size(), grid.dims());

    let force_cpu = std::env::args().any(|a| a == "--cpu");
    let mut backend: Box<dyn Collision> = match (force_cpu, GpuContext::new()) {
        (false, Ok(ctx)) => {
            println!("backend: GPU on {}\n", ctx.adapter_name());
            Box::new(GpuCollision::new(&ctx, grid, params)?)
        }
        (true, _) => {
            println!("backend: CPU reference (1 thread), as asked with --cpu\n");
            Box::new(CpuCollision::new(grid, params)?)
        }
        (false, Err(e)) => {
            println!("backend: CPU reference (1 thread) — falling back because {e}\n");
            Box::new(CpuCollision::new(grid, params)?)
        }
    };
    let started = Instant::now();
    let report = backend.step(&a, &b)?;
    println!("step 0 ({:.2} ms):\n{report}\n", started.elapsed().as_secs_f64() * 1e3);

    // Without springs (the scenarios add them), let each vertex of both bodies move a quarter
    // voxel per unit of force each step: contacts are removed over several steps, not at once.
    let mut a = a;
    let dt = 0.25 * h;
    for step in 1..=50 {
        let report = backend.step(&a, &b)?;
        if step == 1 || step % 5 == 0 || report.colliding_b.is_empty() {
            println!("step {step}: {} cylinder vertices in contact", report.colliding_b.len());
        }
        if report.colliding_b.is_empty() {
            println!("no contact left");
            return Ok(());
        }
        a.iter_mut().zip(&report.force_a).for_each(|(p, f)| *p += *f * dt);
        b.iter_mut().zip(&report.force_b).for_each(|(p, f)| *p += *f * dt);
    }
    println!("contacts remain after 50 steps");
    Ok(())
}
