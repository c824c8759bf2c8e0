//! `voxcollide bench`: every backend on docs/design.md §7's workloads — `lattice(N)` (x fastest),
//! `z_fastest(N)`, `shuffled(N)`, `paper(N)`, `paper_shuffled(N)` and `moving(N)` (lattice's
//! bodies stepped 20 times in a row, B moving; its figure the mean step) — each against a
//! baseline that answers its own question, as medians of repeated steps:
//! - `Search::Neighbours` (lattice, z_fastest, shuffled): a k-d tree (`kiddo`: build over A,
//!   then each B vertex's nearest A vertex within the radius, on the same threads);
//! - `Search::Voxel` (paper): a hash map of A's voxels (`std::collections::HashMap`: build
//!   over A, then each B vertex's nearest A vertex in its own voxel, on the same threads).
//!
//! Each figure also gets its distance to this machine's floor: the bytes a step must move
//! ([`step_bytes`]) at the memory bandwidth measured on the same threads ([`cpu_bandwidth`]) or
//! on the device ([`gpu_bandwidth`]).

use std::time::Instant;

use glam::Vec4;
use std::cell::RefCell;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use serde::Serialize;

use voxcollide::collision::Collision;
use voxcollide::cpu::CpuCollision;
use voxcollide::error::Error;
use voxcollide::gpu::{GpuCollision, GpuContext};
use voxcollide::parallel::ParallelCpuCollision;
use voxcollide::params::Search;
use voxcollide::workload::{Workload, lattice, moving, paper, shuffled, z_fastest};

/// One measured case.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BenchRow {
    /// `lattice`, `z_fastest`, `shuffled`, `paper`, `paper_shuffled` or `moving`.
    pub workload: String,
    /// The size asked for (vertices per body, about).
    pub size: usize,
    /// Vertices per body.
    pub vertices: usize,
    /// `cpu_reference`, `parallel_cpu`, `gpu_resident`, `gpu_step`, or the baseline
    /// (`kdtree_kiddo`, `voxel_hashmap`); and the resident step in the order the adapter does
    /// not use by default (`voxcollide::gpu::sorts_b_by_default`): `gpu_resident_b_as_given`
    /// (B's sort skipped) or `gpu_resident_b_sorted`.
    pub backend: String,
    /// Median milliseconds per step (`moving`: of the mean step over its 20 in a row).
    pub median_ms: f64,
    /// Vertices of both bodies per second at the median.
    pub vertices_per_second: f64,
    /// The workload's baseline: `kdtree_kiddo` or `voxel_hashmap`.
    pub baseline: String,
    /// The baseline's median over this one's, on the same workload and size: above 1 is faster
    /// than the baseline.
    pub speedup_vs_baseline: Option<f64>,
    /// The least and the largest of the same ratio step by step: the backends are timed in
    /// turns, one step each, so that each ratio compares steps taken at the same moments.
    pub speedup_spread: Option<[f64; 2]>,
    /// Steps timed.
    pub samples: usize,
    /// The adapter (GPU rows) or `cpu`.
    pub device: String,
    /// Threads used by the CPU rows (1 for the reference).
    pub threads: usize,
    /// Colliding B vertices found (the same for every backend; the baseline's may differ only
    /// on exact ties at the radius).
    pub colliding: usize,
    /// `gpu_resident` with [`BenchConfig::passes`]: each pass's median (timestamp queries), in
    /// the order they run; empty otherwise.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub passes: Vec<PassTime>,
    /// The least time a step can take on this machine: the bytes it must move
    /// ([`step_bytes`]) at the memory bandwidth its device was measured to reach
    /// ([`cpu_bandwidth`], [`gpu_bandwidth`]); `None` where that was not measured.
    pub floor_ms: Option<f64>,
    /// The median over the floor: how far the step is from what memory allows.
    pub times_floor: Option<f64>,
    /// The bandwidth the floor was computed with, in GB/s.
    pub bandwidth_gb_s: Option<f64>,
}

/// The bytes a step must move at the least for bodies of `n_a` and `n_b` vertices with
/// `colliding` contacts: both bodies' positions read and both bodies' forces written (12 bytes
/// a vector each), and the colliding indices written (4 bytes each). Everything else a backend
/// moves — its sorted copies, voxel tables, accumulators — is its own overhead.
#[must_use]
pub fn step_bytes(n_a: usize, n_b: usize, colliding: usize) -> u64 {
    24 * (n_a as u64 + n_b as u64) + 4 * colliding as u64
}

/// The bytes each bandwidth measurement copies: large enough to leave every cache.
const COPY_BYTES: usize = 256 << 20;

/// The memory bandwidth the CPU threads reach, in bytes per second: the best of five parallel
/// copies of a 256 MiB buffer (the bytes read and the bytes written both counted), on rayon's
/// threads as the parallel backend runs.
#[must_use]
pub fn cpu_bandwidth() -> f64 {
    use rayon::prelude::*;
    let words = COPY_BYTES / 8;
    let src: Vec<u64> = (0..words as u64).collect();
    let mut dst = vec![0u64; words];
    let chunk = (words / (8 * rayon::current_num_threads())).max(1 << 16);
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        dst.par_chunks_mut(chunk).zip(src.par_chunks(chunk)).for_each(|(d, s)| d.copy_from_slice(s));
        best = best.min(t.elapsed().as_secs_f64());
        std::hint::black_box(&dst);
    }
    (2 * COPY_BYTES) as f64 / best
}

/// The memory bandwidth of `ctx`'s device, in bytes per second: the best of five copies of a
/// buffer of up to 256 MiB into another on the device (read and written bytes counted), timed
/// from submission to completion. `None` when the device cannot make the buffers.
#[must_use]
pub fn gpu_bandwidth(ctx: &GpuContext) -> Option<f64> {
    let device = ctx.device();
    let size = (COPY_BYTES as u64).min(device.limits().max_buffer_size) & !255;
    if size == 0 {
        return None;
    }
    let buffer = |usage| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bandwidth"),
            size,
            usage,
            mapped_at_creation: false,
        })
    };
    let (src, dst) = (buffer(wgpu::BufferUsages::COPY_SRC), buffer(wgpu::BufferUsages::COPY_DST));
    let mut best = f64::INFINITY;
    for k in 0..6 {
        let t = Instant::now();
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&src, 0, &dst, 0, size);
        ctx.queue().submit([encoder.finish()]);
        device.poll(wgpu::PollType::wait_indefinitely()).ok()?;
        if k > 0 {
            best = best.min(t.elapsed().as_secs_f64());
        }
    }
    Some((2 * size) as f64 / best)
}

/// One GPU pass's median time.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PassTime {
    /// The pass, as in [`voxcollide::gpu::PASSES`].
    pub pass: String,
    /// Median milliseconds per step.
    pub median_ms: f64,
}

/// What to measure.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchConfig {
    /// Vertices per body.
    pub sizes: Vec<usize>,
    /// Timed steps per case (after one warm-up step); the median is reported.
    pub samples: usize,
    /// Whether to measure the GPU too (when there is an adapter).
    pub gpu: bool,
    /// Whether to measure the single-threaded reference (slow at 1M).
    pub reference: bool,
    /// Whether to time each GPU pass of the resident step too (timestamp queries, where the
    /// adapter has them), in extra steps after the whole-step timing.
    pub passes: bool,
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        xs[n / 2]
    } else {
        0.5 * (xs[n / 2 - 1] + xs[n / 2])
    }
}

/// Times `f` once to warm up, then `samples` times; returns the median in milliseconds.
fn time(samples: usize, mut f: impl FnMut() -> Result<usize, Error>) -> Result<(f64, usize), Error> {
    let colliding = f()?;
    let mut ms = Vec::with_capacity(samples);
    for _ in 0..samples {
        let t = Instant::now();
        f()?;
        ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    Ok((median(ms), colliding))
}

/// One backend's step in [`interleaved`]: its name, device and threads, and the step, which
/// returns the colliding B vertices it found.
struct Contender<'s> {
    backend: String,
    device: String,
    threads: usize,
    step: Box<dyn FnMut() -> Result<usize, Error> + 's>,
}

impl<'s> Contender<'s> {
    fn new(
        backend: &str,
        device: &str,
        threads: usize,
        step: impl FnMut() -> Result<usize, Error> + 's,
    ) -> Contender<'s> {
        Contender { backend: backend.into(), device: device.into(), threads, step: Box::new(step) }
    }
}

/// What [`interleaved`] measured of one backend: each turn's milliseconds, in turn order.
struct Measured {
    backend: String,
    samples: Vec<f64>,
    device: String,
    threads: usize,
    colliding: usize,
}

/// Steps each contender once to warm up, then `samples` turns in which each steps once, in
/// order: the machine's slow and quick moments fall on every backend alike, and each turn's
/// ratio compares steps taken within moments of each other.
fn interleaved(samples: usize, contenders: Vec<Contender>) -> Result<Vec<Measured>, Error> {
    let mut out = Vec::with_capacity(contenders.len());
    let mut steps = Vec::with_capacity(contenders.len());
    for mut c in contenders {
        let colliding = (c.step)()?;
        out.push(Measured {
            backend: c.backend,
            samples: Vec::with_capacity(samples),
            device: c.device,
            threads: c.threads,
            colliding,
        });
        steps.push(c.step);
    }
    for _ in 0..samples {
        for (m, step) in out.iter_mut().zip(steps.iter_mut()) {
            let t = Instant::now();
            step()?;
            m.samples.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    Ok(out)
}

/// Bytes a benchmark case holds per vertex of each body, generously: the two bodies and the
/// k-d tree's copies, the reference's lists, the parallel backend's sorted copies, slots,
/// accumulators and kept copy of A, the reports and the GPU upload's scratch.
const BYTES_PER_VERTEX: u64 = 336;

/// What `moving(N)` holds per vertex of each body beyond that: B at each of its 20 steps, on
/// the host twice (for the backends and the k-d tree) and once on the device.
const MOVING_BYTES_PER_VERTEX: u64 = 20 * (12 + 12 + 16);

/// Refuses a size beyond a body's vertex limit or beyond this machine's available memory, before
/// anything is allocated.
fn check_size(size: usize) -> Result<(), Error> {
    let invalid = |rule: String| Error::Invalid { what: "bench size", value: size.to_string(), rule };
    if size > voxcollide::cpu::MAX_VERTICES {
        return Err(invalid(format!("a body has at most {} vertices", voxcollide::cpu::MAX_VERTICES)));
    }
    let needed = (size as u64).saturating_mul(BYTES_PER_VERTEX + MOVING_BYTES_PER_VERTEX);
    if let Some(available) = available_memory()
        && needed > available
    {
        let gib = |b: u64| b as f64 / f64::from(1u32 << 30);
        return Err(invalid(format!(
            "needs about {:.1} GiB and this machine has {:.1} GiB available",
            gib(needed),
            gib(available)
        )));
    }
    Ok(())
}

/// The memory available to a new allocation (Linux: `MemAvailable` of /proc/meminfo), or `None`
/// where it cannot be told.
fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Runs the benchmark, calling `note` with each row as it is measured.
///
/// # Errors
/// [`Error::Invalid`] for no sizes, a size of 0 or zero samples; errors of the backends.
pub fn run(config: &BenchConfig, note: &mut dyn FnMut(&BenchRow)) -> Result<Vec<BenchRow>, Error> {
    if config.sizes.is_empty() || config.sizes.contains(&0) || config.samples == 0 {
        return Err(Error::Invalid {
            what: "bench sizes/samples",
            value: format!("{:?} / {}", config.sizes, config.samples),
            rule: "needs at least one size, every size and the samples above 0".into(),
        });
    }
    for &size in &config.sizes {
        check_size(size)?;
    }
    let ctx = if config.gpu { GpuContext::new().ok() } else { None };
    let threads = rayon::current_num_threads();
    let cpu_bw = cpu_bandwidth();
    let gpu_bw = ctx.as_ref().and_then(gpu_bandwidth);
    let mut rows = Vec::new();
    for &size in &config.sizes {
        for (name, make) in WORKLOADS {
            let Stepped { w, steps } = make(size, voxcollide::workload::DEFAULT_SEED)?;
            let n = w.a.len();
            let mut passes = Vec::new();
            let a: Vec<[f32; 3]> = w.a.iter().map(|p| p.to_array()).collect();
            let bs: Vec<Vec<[f32; 3]>> =
                steps.iter().map(|b| b.iter().map(|p| p.to_array()).collect()).collect();
            // The GPU's two ways share one backend (the resident step's report is read back
            // after the timing).
            let gpu = match &ctx {
                Some(ctx) => Some((RefCell::new(GpuCollision::new(ctx, w.grid, w.params)?), ctx)),
                None => None,
            };
            let upload = |device: &wgpu::Device, points: &[glam::Vec3]| {
                let data: Vec<Vec4> = points.iter().map(|p| p.extend(1.0)).collect();
                wgpu::util::DeviceExt::create_buffer_init(
                    device,
                    &wgpu::util::BufferInitDescriptor {
                        label: Some("bench positions"),
                        contents: bytemuck::cast_slice(&data),
                        usage: wgpu::BufferUsages::STORAGE,
                    },
                )
            };
            let resident = gpu.as_ref().map(|(_, ctx)| {
                (
                    upload(ctx.device(), &w.a),
                    steps.iter().map(|b| upload(ctx.device(), b)).collect::<Vec<_>>(),
                )
            });
            // Every backend of the workload, as one step each; timed in turns below.
            let mut contenders: Vec<Contender> = Vec::new();
            let baseline = match w.params.search {
                // The same answer as the workload: nearest A within the radius.
                // (Each contender takes every step of the workload in a row, once a turn, and
                // returns the last step's count.)
                Search::Neighbours { radius } => {
                    let (a, bs) = (&a, &bs);
                    contenders.push(Contender::new("kdtree_kiddo", "cpu", threads, move || {
                        let mut found = 0;
                        for b in bs {
                            let tree =
                                ImmutableKdTree::<f32, 3>::new_from_slice(a).map_err(|e| Error::Invalid {
                                    what: "k-d tree",
                                    value: format!("{e:?}"),
                                    rule: "kiddo could not build it".into(),
                                })?;
                            let nearest =
                                tree.query_batch(b).nearest_one::<SquaredEuclidean<f32>>().execute();
                            found = nearest.iter().filter(|r| r.distance < radius * radius).count();
                        }
                        Ok(found)
                    }));
                    "kdtree_kiddo"
                }
                // The same answer as the workload: nearest A in B's own voxel.
                Search::Voxel => {
                    let (w, steps) = (&w, &steps);
                    contenders.push(Contender::new("voxel_hashmap", "cpu", threads, move || {
                        let mut found = 0;
                        for b in steps {
                            found = voxel_hashmap(w, b);
                        }
                        Ok(found)
                    }));
                    "voxel_hashmap"
                }
            };
            let (wr, steps) = (&w, &steps);
            if config.reference {
                let mut cpu = CpuCollision::new(w.grid, w.params)?;
                contenders.push(Contender::new("cpu_reference", "cpu", 1, move || {
                    let mut found = 0;
                    for b in steps {
                        found = cpu.step(&wr.a, b)?.colliding_b.len();
                    }
                    Ok(found)
                }));
            }
            let mut par = ParallelCpuCollision::new(w.grid, w.params)?;
            let mut report = Default::default();
            contenders.push(Contender::new("parallel_cpu", "cpu", threads, move || {
                for b in steps {
                    par.step_into(&wr.a, b, &mut report)?;
                }
                Ok(report.colliding_b.len())
            }));
            if let (Some((gpu, ctx)), Some((ba, bbs))) = (&gpu, &resident) {
                contenders.push(Contender::new("gpu_step", &ctx.adapter_name(), 0, move || {
                    let mut found = 0;
                    for b in steps {
                        found = gpu.borrow_mut().step(&wr.a, b)?.colliding_b.len();
                    }
                    Ok(found)
                }));
                let nb = w.b.len() as u32;
                // The resident step as it runs on this adapter, and in the other order: B sorted
                // by A's slots, or probed as it comes in (whether the sort pays for itself).
                let default = voxcollide::gpu::sorts_b_by_default(ctx);
                let other = if default { "gpu_resident_b_as_given" } else { "gpu_resident_b_sorted" };
                for (backend, sort_b) in [("gpu_resident", default), (other, !default)] {
                    contenders.push(Contender::new(backend, &ctx.adapter_name(), 0, move || {
                        let (device, queue) = (ctx.device(), ctx.queue());
                        // One step a submission, each waited for, as an app steps.
                        for bb in bbs {
                            let mut encoder = device.create_command_encoder(&Default::default());
                            let mut gpu = gpu.borrow_mut();
                            gpu.set_sort_b(sort_b);
                            let recorded = gpu.record(&mut encoder, ba, n as u32, bb, nb);
                            gpu.set_sort_b(default);
                            recorded?;
                            queue.submit([encoder.finish()]);
                            device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| Error::Gpu {
                                message: format!("waiting for the device: {e}"),
                            })?;
                        }
                        Ok(0)
                    }));
                }
            }
            let mut measured = interleaved(config.samples, contenders)?;
            // The mean step of a turn's steps in a row.
            for m in &mut measured {
                m.samples.iter_mut().for_each(|ms| *ms /= steps.len() as f64);
            }
            if let Some((gpu, ctx)) = &gpu {
                let gpu = &mut *gpu.borrow_mut();
                // The resident steps' own contacts: one more step in each order, read back after
                // the timing.
                if let Some((ba, bbs)) = &resident
                    && let Some(bb) = bbs.last()
                {
                    let default = voxcollide::gpu::sorts_b_by_default(ctx);
                    for m in measured.iter_mut().filter(|m| m.backend.starts_with("gpu_resident")) {
                        gpu.set_sort_b(if m.backend == "gpu_resident" { default } else { !default });
                        let mut encoder = ctx.device().create_command_encoder(&Default::default());
                        gpu.record(&mut encoder, ba, n as u32, bb, w.b.len() as u32)?;
                        ctx.queue().submit([encoder.finish()]);
                        m.colliding = gpu.read_report()?.colliding_b.len();
                    }
                    gpu.set_sort_b(default);
                }
                // Per pass, in steps of their own: profiling splits the step into timed passes.
                if let (true, Some((ba, bbs))) = (config.passes, &resident)
                    && let Some(bb) = bbs.last()
                    && gpu.set_profiling(true).is_ok()
                {
                    let (device, queue) = (ctx.device(), ctx.queue());
                    let mut times: Vec<Vec<f64>> = vec![Vec::new(); voxcollide::gpu::PASSES.len()];
                    time(config.samples, || {
                        let mut encoder = device.create_command_encoder(&Default::default());
                        gpu.record(&mut encoder, ba, n as u32, bb, w.b.len() as u32)?;
                        queue.submit([encoder.finish()]);
                        for (k, (_, ms)) in gpu.pass_times()?.into_iter().enumerate() {
                            times[k].push(ms);
                        }
                        Ok(0)
                    })?;
                    gpu.set_profiling(false)?;
                    passes = voxcollide::gpu::PASSES
                        .iter()
                        .zip(times)
                        .map(|(pass, ms)| PassTime { pass: (*pass).into(), median_ms: median(ms) })
                        .collect();
                }
            }
            let base = measured[0].samples.clone();
            for Measured { backend, samples, device, threads, colliding } in measured {
                let ms = median(samples.clone());
                // Per turn, the baseline's step over this one's: the ratio's spread.
                let ratios: Vec<f64> = base.iter().zip(&samples).map(|(b, s)| b / s).collect();
                let spread = [
                    ratios.iter().copied().fold(f64::INFINITY, f64::min),
                    ratios.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                ];
                let backend_is_resident = backend == "gpu_resident";
                let bandwidth = if backend.starts_with("gpu") { gpu_bw } else { Some(cpu_bw) };
                let floor_ms = bandwidth.map(|bw| step_bytes(n, w.b.len(), colliding) as f64 / bw * 1e3);
                let row = BenchRow {
                    workload: name.into(),
                    size,
                    vertices: n,
                    baseline: baseline.into(),
                    speedup_vs_baseline: Some(median(base.clone()) / ms),
                    speedup_spread: Some(spread),
                    vertices_per_second: (2 * n) as f64 / (ms / 1e3),
                    median_ms: ms,
                    backend,
                    samples: config.samples,
                    device,
                    threads,
                    colliding,
                    passes: if backend_is_resident { std::mem::take(&mut passes) } else { Vec::new() },
                    floor_ms,
                    times_floor: floor_ms.map(|f| ms / f),
                    bandwidth_gb_s: bandwidth.map(|bw| bw / 1e9),
                };
                note(&row);
                rows.push(row);
            }
        }
    }
    Ok(rows)
}

/// A workload's constructor: `(vertices per body, seed)`.
pub type MakeWorkload = fn(usize, u64) -> Result<Stepped, Error>;

/// A workload as it is stepped: its bodies, grid and params, and B at each step it takes in a
/// row (one for the still workloads, twenty for `moving(N)`).
#[derive(Clone, Debug)]
pub struct Stepped {
    /// The bodies, grid and params (B as at the first step).
    pub w: Workload,
    /// B at each step, in order.
    pub steps: Vec<Vec<glam::Vec3>>,
}

impl Stepped {
    fn still(w: Workload) -> Stepped {
        let steps = vec![w.b.clone()];
        Stepped { w, steps }
    }
}

/// The workloads, by name: docs/design.md §7's in three orders, the paper's rule in two, and
/// lattice's bodies moving.
pub const WORKLOADS: [(&str, MakeWorkload); 6] = [
    ("lattice", |n, seed| Ok(Stepped::still(lattice(n, seed)?))),
    ("z_fastest", |n, seed| Ok(Stepped::still(z_fastest(n, seed)?))),
    ("shuffled", |n, seed| Ok(Stepped::still(shuffled(n, seed)?))),
    ("paper", |n, seed| Ok(Stepped::still(paper(n, seed)?))),
    ("paper_shuffled", |n, seed| Ok(Stepped::still(paper_shuffled(n, seed)?))),
    ("moving", moving_steps),
];

/// `paper(N)`'s rule on `shuffled(N)`'s order.
fn paper_shuffled(n: usize, seed: u64) -> Result<Workload, Error> {
    let mut w = shuffled(n, seed)?;
    w.params.search = Search::Voxel;
    Ok(w)
}

/// `moving(N)`: lattice's bodies, B at each of its [`MOVING_STEPS`](voxcollide::workload::MOVING_STEPS).
fn moving_steps(n: usize, seed: u64) -> Result<Stepped, Error> {
    let m = moving(n, seed)?;
    let steps = (0..voxcollide::workload::MOVING_STEPS).map(|k| m.b_at(k)).collect();
    Ok(Stepped { w: m.start, steps })
}

/// The paper workloads' baseline: a hash map from voxel to A's vertices, built over A, then per
/// B vertex (in parallel) the nearest A vertex of its own voxel, ties to the lower index — what
/// `Search::Voxel` asks, for B at `b` (`w.b`, or a moving workload's B at a step). Returns the
/// B vertices that found one.
#[must_use]
pub fn voxel_hashmap(w: &Workload, b: &[glam::Vec3]) -> usize {
    use rayon::prelude::*;
    use std::collections::HashMap;
    let grid = &w.grid;
    let mut voxels: HashMap<glam::UVec3, Vec<u32>> = HashMap::with_capacity(w.a.len());
    for (i, p) in w.a.iter().enumerate() {
        if let Some(v) = grid.voxel_of(*p) {
            voxels.entry(v).or_default().push(i as u32);
        }
    }
    b.par_iter()
        .filter_map(|p| {
            let list = voxels.get(&grid.voxel_of(*p)?)?;
            let nearest = list
                .iter()
                .map(|&i| (w.a[i as usize].distance_squared(*p), i))
                .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            // The partner is the answer: keep the search from being optimised away.
            std::hint::black_box(nearest)
        })
        .count()
}

/// The rows as a plain-text table.
#[must_use]
pub fn table(rows: &[BenchRow]) -> String {
    let mut out = format!(
        "{:<14} {:>9} {:<23} {:>11} {:>12} {:>11} {:>13} {:>9} {:>8} {:>8}  {}\n",
        "workload",
        "vertices",
        "backend",
        "median ms",
        "vertices/s",
        "vs baseline",
        "step by step",
        "floor ms",
        "x floor",
        "threads",
        "device"
    );
    for r in rows {
        let threads = if r.threads == 0 { "-".to_string() } else { r.threads.to_string() };
        out += &format!(
            "{:<14} {:>9} {:<23} {:>11.3} {:>12.3e} {:>10.2}x {:>13} {:>9} {:>8} {:>8}  {}\n",
            r.workload,
            r.vertices,
            r.backend,
            r.median_ms,
            r.vertices_per_second,
            r.speedup_vs_baseline.unwrap_or(f64::NAN),
            r.speedup_spread.map_or("-".into(), |[lo, hi]| format!("{lo:.2}–{hi:.2}x")),
            r.floor_ms.map_or("-".into(), |f| format!("{f:.3}")),
            r.times_floor.map_or("-".into(), |x| format!("{x:.0}x")),
            threads,
            r.device
        );
        if !r.passes.is_empty() {
            let each: Vec<String> =
                r.passes.iter().map(|p| format!("{} {:.2}", p.pass, p.median_ms)).collect();
            out += &format!("{:>19} passes, ms: {}\n", "", each.join(", "));
        }
    }
    out
}
