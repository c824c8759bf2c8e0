//! Steps one backend on one docs/design.md §7 workload in a loop and prints the median, for profiling
//! (`perf record`, callgrind) and quick before/after checks; `voxcollide bench` is the full table.
//! With `VOXCOLLIDE_PHASES=1` it also prints each phase's median (`set_profiling`).
//!
//! ```text
//! cargo run --release --example steps -- [lattice|z_fastest|shuffled|paper|paper_shuffled|sparse] [N] [steps]
//! ```
//!
//! `sparse` is `lattice` in a grid half the lattice wider on every side, so that A's voxel table
//! is hashed (more than four voxels a vertex), as for a mesh in a roomy grid.

use std::time::Instant;

use voxcollide::workload::{self, DEFAULT_SEED};
use voxcollide::{ContactReport, ParallelCpuCollision};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map_or("lattice", String::as_str);
    let n: usize = args.get(1).map_or(Ok(1_000_000), |s| s.parse())?;
    let steps: usize = args.get(2).map_or(Ok(15), |s| s.parse())?;
    let w = match name {
        "lattice" => workload::lattice(n, DEFAULT_SEED)?,
        "z_fastest" => workload::z_fastest(n, DEFAULT_SEED)?,
        "shuffled" => workload::shuffled(n, DEFAULT_SEED)?,
        "paper" => workload::paper(n, DEFAULT_SEED)?,
        "paper_shuffled" => {
            let mut w = workload::shuffled(n, DEFAULT_SEED)?;
            w.params.search = voxcollide::Search::Voxel;
            w
        }
        "sparse" => {
            let mut w = workload::lattice(n, DEFAULT_SEED)?;
            let k = (w.a.len() as f64).cbrt().round() as u32;
            w.grid = voxcollide::Initializer::new(1.0).margin(k / 2 + 1).build(&w.a)?;
            w
        }
        other => return Err(format!("unknown workload {other}").into()),
    };
    let mut backend = ParallelCpuCollision::new(w.grid, w.params)?;
    let mut report = ContactReport::default();
    let mut times = Vec::with_capacity(steps);
    let mut phases = Vec::with_capacity(steps);
    let profile = std::env::var_os("VOXCOLLIDE_PHASES").is_some();
    for _ in 0..steps {
        backend.set_profiling(profile);
        let t = Instant::now();
        backend.step_into(&w.a, &w.b, &mut report)?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
        phases.extend(backend.phase_times());
    }
    if let Some(first) = phases.first() {
        let each: Vec<String> = (0..first.len())
            .map(|k| {
                let mut v: Vec<f64> = phases.iter().map(|p| p[k].1).collect();
                v.sort_by(f64::total_cmp);
                format!("{} {:.2}", first[k].0, v[v.len() / 2])
            })
            .collect();
        println!("phases (medians, ms): {}", each.join(", "));
    }
    times.sort_by(f64::total_cmp);
    println!(
        "{name}({}) on {} threads: median {:.2} ms, min {:.2} ms, {} colliding",
        w.a.len(),
        rayon::current_num_threads(),
        times[times.len() / 2],
        times[0],
        report.colliding_b.len()
    );
    Ok(())
}
