//! The GPU backend: WGSL compute passes on wgpu (docs/design.md §3), checked against the CPU reference.
//!
//! A step is sixteen passes recorded into one command encoder — bounds (FollowA only), frame, a
//! counting sort of A by voxel slot (bin, scan, scan_carry, scan_add, sort, gather), the same of
//! B by A's slots (bin_b … gather_b, so that the probe's speed does not depend on B's order;
//! skipped where B is probed as it comes in, [`GpuCollision::set_sort_b`]), probe, resolve —
//! with every intermediate in device buffers that are created once and reused while the sizes
//! fit. A body keeps its last order while every vertex stays in the slot it was sorted into:
//! `bin` compares each vertex's slot with the one it kept and flags a change; without one the
//! scans and the sort return at once and `gather` brings the new positions into the kept order
//! (no readback: the device decides), which is an order the sort could have made from the same
//! slots. New sizes or a new table sort again. [`GpuCollision::record`] is the embedding API (the app's buffers and
//! encoder, nothing read back); [`Collision::step`] uploads, records, submits and reads back.
//!
//! For an app's (or a crate's) own compute passes beside the collision's, on the same device:
//! [`kernel::Kernel`] (a pass, its layout and its dispatch over any number of items),
//! [`scoped`] (device errors as values), [`read_buffers`] and [`map_read`] (readback, counted
//! per thread by [`host_waits`]).

mod context;
pub mod kernel;
mod layout;
pub mod shaders;

use glam::{Vec3, Vec4};
use wgpu::{Buffer, BufferUsages, CommandEncoder, Device};

pub use context::GpuContext;
use kernel::{Kernel, Slot};
use layout::{GpuParams, GpuState};

use crate::collision::Collision;
use crate::cpu::check_body;
use crate::eliminate::ForceLaw;
use crate::error::{Body, Error};
use crate::grid::VoxelGrid;
use crate::params::{Anchor, ContactParams, Response};
use crate::report::ContactReport;
use crate::voxel_data::{dense_slots, hashed_slots};

/// Invocations per workgroup in every pass but `frame` (64, 128 and 256 measured alike on
/// lavapipe: docs/performance-notes.md). Keep in sync with `WORKGROUP_SIZE` in
/// `shaders/common.wgsl`.
pub const WORKGROUP_SIZE: u32 = 64;
/// Whether a new [`GpuCollision`] on `ctx` sorts B by A's slots before each probe
/// ([`GpuCollision::set_sort_b`]). Not on a software adapter (a CPU device such as Mesa's
/// llvmpipe): there B's sort cost more than it saved in 14 of the 15 workloads and sizes
/// measured (skipping it took 0.68–0.87 of the step's time), all but `shuffled(1M)`, where
/// sorting was 1.15× quicker (docs/performance-notes.md §38). On a hardware GPU, where a
/// warp's scattered reads cost most, it sorts until a real device has been measured.
#[must_use]
pub fn sorts_b_by_default(ctx: &GpuContext) -> bool {
    ctx.adapter_info().is_none_or(|info| info.device_type != wgpu::DeviceType::Cpu)
}

/// Bytes per vertex position and per force: `vec4<f32>`.
const VEC4: u64 = 16;

/// What the kernels of a step are specialised to: the search and the direction.
pub(crate) type KernelKey = (u32, u32);

/// The kernels built on one device, by [`KernelKey`].
pub(crate) type KernelCache = Vec<(KernelKey, std::sync::Arc<Kernels>)>;

/// The bindings of `bin.wgsl`: params, state, positions, counts, kept slots, changed.
const BIN_SLOTS: &[Slot] =
    &[Slot::Uniform, Slot::ReadWrite, Slot::Read, Slot::ReadWrite, Slot::ReadWrite, Slot::ReadWrite];
/// Of `sort.wgsl`: params, state, positions, cursors, sorted, changed.
const SORT_SLOTS: &[Slot] =
    &[Slot::Uniform, Slot::ReadWrite, Slot::Read, Slot::ReadWrite, Slot::ReadWrite, Slot::Read];
/// Of `gather.wgsl`: params, state, positions, sorted, changed.
const GATHER_SLOTS: &[Slot] = &[Slot::Uniform, Slot::ReadWrite, Slot::Read, Slot::ReadWrite, Slot::Read];

/// The kernels of a step.
#[derive(Debug)]
pub(crate) struct Kernels {
    bounds: Kernel,
    frame: Kernel,
    bin: Kernel,
    scan: Kernel,
    scan_carry: Kernel,
    scan_add: Kernel,
    sort: Kernel,
    gather: Kernel,
    bin_b: Kernel,
    sort_b: Kernel,
    gather_b: Kernel,
    probe_hashed: Kernel,
    probe_dense: Kernel,
    /// The probes of B as given (`SORTED_B = false`): [`GpuCollision::set_sort_b`].
    probe_hashed_given: Kernel,
    probe_dense_given: Kernel,
    resolve: Kernel,
}

impl Kernels {
    /// The kernels for `params`: the probe is specialised to its search and direction.
    fn new(device: &Device, params: &GpuParams) -> Kernels {
        use Slot::{Read, ReadWrite, Uniform};
        let probe = |dense: bool, sorted_b: bool| {
            Kernel::with_constants(
                device,
                if dense { "voxcollide probe (dense)" } else { "voxcollide probe (hashed)" },
                shaders::PROBE,
                &[Uniform, ReadWrite, Read, Read, Read, ReadWrite, ReadWrite],
                &[
                    ("SEARCH", f64::from(params.search)),
                    ("DIRECTION", f64::from(params.direction)),
                    ("DENSE", f64::from(u8::from(dense))),
                    ("SORTED_B", f64::from(u8::from(sorted_b))),
                ],
            )
        };
        Kernels {
            bounds: Kernel::new(device, "voxcollide bounds", shaders::BOUNDS, &[Uniform, ReadWrite, Read]),
            frame: Kernel::new(device, "voxcollide frame", shaders::FRAME, &[Uniform, ReadWrite]),
            bin: Kernel::new(device, "voxcollide bin", shaders::BIN, BIN_SLOTS),
            scan: Kernel::new(
                device,
                "voxcollide scan",
                shaders::SCAN,
                &[Uniform, Read, ReadWrite, ReadWrite, Read],
            ),
            scan_carry: Kernel::new(
                device,
                "voxcollide scan_carry",
                shaders::SCAN_CARRY,
                &[Uniform, ReadWrite, Read],
            ),
            scan_add: Kernel::new(
                device,
                "voxcollide scan_add",
                shaders::SCAN_ADD,
                &[Uniform, ReadWrite, Read, ReadWrite, Read],
            ),
            sort: Kernel::new(device, "voxcollide sort", shaders::SORT, SORT_SLOTS),
            gather: Kernel::new(device, "voxcollide gather", shaders::GATHER, GATHER_SLOTS),
            bin_b: Kernel::with_constants(
                device,
                "voxcollide bin_b",
                shaders::BIN,
                BIN_SLOTS,
                &[("BODY", 1.0)],
            ),
            sort_b: Kernel::with_constants(
                device,
                "voxcollide sort_b",
                shaders::SORT,
                SORT_SLOTS,
                &[("BODY", 1.0)],
            ),
            gather_b: Kernel::with_constants(
                device,
                "voxcollide gather_b",
                shaders::GATHER,
                GATHER_SLOTS,
                &[("BODY", 1.0)],
            ),
            probe_hashed: probe(false, true),
            probe_dense: probe(true, true),
            probe_hashed_given: probe(false, false),
            probe_dense_given: probe(true, false),
            resolve: Kernel::new(
                device,
                "voxcollide resolve",
                shaders::RESOLVE,
                &[Uniform, ReadWrite, Read, Read, ReadWrite],
            ),
        }
    }
}

/// The device buffers of a step, sized for `cap_a` A and `cap_b` B vertices and `cap_slots`
/// voxel slots.
#[derive(Debug)]
struct Buffers {
    cap_a: u32,
    cap_b: u32,
    cap_slots: u32,
    params: Buffer,
    state: Buffer,
    /// A's vertices sorted by their slots.
    sort_a: SortBuffers,
    /// B's, sorted by A's slots.
    sort_b: SortBuffers,
    /// Per sorted A vertex 8 words: the low words of the x, y, z fixed-point totals, one
    /// unused, the high words, one unused (biased by 2^31: see `add_fixed` in `shaders/probe.wgsl`).
    fixed: Buffer,
    force_a: Buffer,
    force_b: Buffer,
}

/// One body's counting sort by voxel slot: per-slot counts, their scan (starts, with the
/// scan's block partials), the scatter cursors, and the body's positions in slot order.
#[derive(Debug)]
struct SortBuffers {
    count: Buffer,
    start: Buffer,
    partial: Buffer,
    cursor: Buffer,
    sorted: Buffer,
    /// Per vertex: its slot at the last step (+ 1; 0xFFFFFFFF outside the grid, 0 never
    /// binned), and whether any differs this step (one word): `shaders/bin.wgsl`.
    keys: Buffer,
    changed: Buffer,
}

impl SortBuffers {
    /// For `slots` slots and `vertices` vertices, each buffer made by `make(label, size)`;
    /// labels end in `tag` (`""` for A, `"_b"` for B).
    fn new(make: impl Fn(&str, u64) -> Buffer, slots: u32, vertices: u64, tag: &str) -> SortBuffers {
        let per_slot = 4 * u64::from(scan_slots(slots));
        SortBuffers {
            count: make(&format!("voxcollide count{tag}"), per_slot),
            start: make(&format!("voxcollide start{tag}"), per_slot),
            partial: make(
                &format!("voxcollide partial{tag}"),
                4 * u64::from(scan_blocks(slots).next_multiple_of(4)),
            ),
            cursor: make(&format!("voxcollide cursor{tag}"), per_slot),
            sorted: make(&format!("voxcollide sorted{tag}"), VEC4 * vertices),
            keys: make(&format!("voxcollide keys{tag}"), 4 * vertices),
            changed: make(&format!("voxcollide changed{tag}"), 16),
        }
    }
}

impl Buffers {
    fn new(device: &Device, cap_a: u32, cap_b: u32, cap_slots: u32) -> Buffers {
        let slots = cap_slots;
        let storage = BufferUsages::STORAGE | BufferUsages::COPY_SRC | BufferUsages::COPY_DST;
        let make = |label: &str, size: u64, usage: BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size.max(16),
                usage,
                mapped_at_creation: false,
            })
        };
        let (a, b) = (u64::from(cap_a), u64::from(cap_b));
        Buffers {
            cap_a,
            cap_b,
            cap_slots,
            params: make(
                "voxcollide params",
                std::mem::size_of::<GpuParams>() as u64,
                BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            ),
            state: make("voxcollide state", GpuState::SIZE, storage),
            sort_a: SortBuffers::new(|label, size| make(label, size, storage), slots, a, ""),
            sort_b: SortBuffers::new(|label, size| make(label, size, storage), slots, b, "_b"),
            fixed: make("voxcollide fixed", 32 * a, storage),
            force_a: make("voxcollide force_a", VEC4 * a, storage),
            force_b: make("voxcollide force_b", VEC4 * b, storage),
        }
    }
}

/// Bind groups for one pair of position buffers over the current [`Buffers`].
#[derive(Debug)]
struct Bound {
    a: Buffer,
    b: Buffer,
    bounds: wgpu::BindGroup,
    frame: wgpu::BindGroup,
    bin: wgpu::BindGroup,
    scan: wgpu::BindGroup,
    scan_carry: wgpu::BindGroup,
    scan_add: wgpu::BindGroup,
    sort: wgpu::BindGroup,
    gather: wgpu::BindGroup,
    bin_b: wgpu::BindGroup,
    scan_b: wgpu::BindGroup,
    scan_carry_b: wgpu::BindGroup,
    scan_add_b: wgpu::BindGroup,
    sort_b: wgpu::BindGroup,
    gather_b: wgpu::BindGroup,
    /// Hashed, dense.
    probe: [wgpu::BindGroup; 2],
    /// The probes of B as given, which read B's own positions.
    probe_given: [wgpu::BindGroup; 2],
    resolve: wgpu::BindGroup,
}

/// The passes of a step, in the order they run (`bounds` runs under `Anchor::FollowA` only), as
/// [`GpuCollision::pass_times`] names them.
pub const PASSES: [&str; 16] = [
    "bounds",
    "frame",
    "bin",
    "scan",
    "scan_carry",
    "scan_add",
    "sort",
    "gather",
    "bin_b",
    "scan_b",
    "scan_carry_b",
    "scan_add_b",
    "sort_b",
    "gather_b",
    "probe",
    "resolve",
];

/// One dispatch of a step: its kernel, its bind group, and its items (`None`: one workgroup).
type Pass<'a> = (&'a Kernel, &'a wgpu::BindGroup, Option<u32>);

/// Records `step` into `pass`.
fn dispatch(pass: &mut wgpu::ComputePass<'_>, (kernel, group, items): Pass<'_>, max_per_dim: u32) {
    match items {
        Some(items) => kernel.dispatch(pass, group, items, max_per_dim),
        None => kernel.dispatch_one(pass, group),
    }
}

/// Timestamp queries around each pass, and where they are resolved and read back.
#[derive(Debug)]
struct Profile {
    queries: wgpu::QuerySet,
    resolved: Buffer,
    readback: Buffer,
    /// Nanoseconds per timestamp tick.
    period: f32,
    /// Whether a step has been recorded since profiling was turned on.
    recorded: bool,
}

/// Slots per workgroup (block) of the slot prefix sum: 16 per invocation. Keep in sync with
/// `SCAN_BLOCK` in `shaders/common.wgsl`.
const SCAN_BLOCK: u32 = 16 * WORKGROUP_SIZE;

/// Blocks of the slot prefix sum: `slots` and the end mark after them. Keep in sync with
/// `scan_blocks` in `shaders/common.wgsl`.
fn scan_blocks(slots: u32) -> u32 {
    (slots + 1).div_ceil(SCAN_BLOCK)
}

/// Slots of the count and start buffers: whole scan blocks.
fn scan_slots(slots: u32) -> u32 {
    scan_blocks(slots) * SCAN_BLOCK
}

/// The GPU collision backend.
///
/// ```no_run
/// use voxcollide::{glam::Vec3, *};
/// let a = vec![Vec3::ZERO, Vec3::X];
/// let grid = Initializer::new(1.0).margin(1).build(&a)?;
/// let params = ContactParams {
///     magnitude: 1.0,
///     search: Search::Neighbours { radius: 0.5 },
///     direction: Direction::Pairwise,
///     anchor: Anchor::FollowA,
/// };
/// let ctx = GpuContext::new()?;
/// let mut gpu = GpuCollision::new(&ctx, grid, params)?;
/// let report = gpu.step(&a, &[Vec3::new(1.0, 0.25, 0.0)])?;
/// assert_eq!(report.colliding_b, vec![0]);
/// # Ok::<(), voxcollide::Error>(())
/// ```
#[derive(Debug)]
pub struct GpuCollision {
    ctx: GpuContext,
    grid: VoxelGrid,
    params: ContactParams,
    base: GpuParams,
    kernels: std::sync::Arc<Kernels>,
    max_per_dim: u32,
    /// Per body (A, B).
    max_vertices: [u32; 2],
    max_binding: u64,
    /// The device's largest buffer: `step()`'s readback of both bodies' forces must fit one.
    max_buffer: u64,
    buffers: Option<Buffers>,
    bound: Option<Bound>,
    uploaded: GpuParams,
    recorded: Option<(u32, u32)>,
    dense: Option<bool>,
    bind_group_builds: u32,
    profile: Option<Profile>,
    /// Whether B is sorted by A's slots before the probe ([`set_sort_b`](Self::set_sort_b)).
    sort_b: bool,
    /// Per body (A, B): the vertices, slots and kind of table its kept slots (`keys` in
    /// [`SortBuffers`]) were binned for; `None`: not binned since its buffers were made. A body
    /// binned for others is sorted again whatever its slots ([`GpuCollision::force_sort`]).
    sorted_for: [Option<(u32, u32, bool)>; 2],
    // For `step()`: the uploaded positions, the readback buffer and a conversion scratch.
    upload: Option<(Buffer, Buffer)>,
    staging: Option<Buffer>,
    scratch: Vec<Vec4>,
}

impl GpuCollision {
    /// A GPU backend on `ctx` for the pair of bodies that `grid` was built for. Builds the
    /// pipelines; buffers are made on the first step.
    ///
    /// # Errors
    /// [`Error::Magnitude`] or [`Error::Radius`] for invalid `params`, [`Error::Gpu`] when the
    /// device rejects a pipeline.
    pub fn new(ctx: &GpuContext, grid: VoxelGrid, params: ContactParams) -> Result<GpuCollision, Error> {
        params.validate(&grid)?;
        let device = ctx.device();
        let limits = device.limits();
        let base =
            GpuParams::new(&grid, &params, &ForceLaw::new(&params, Response::Constant, grid.voxel_size()));
        let kernels = ctx.kernels((base.search, base.direction), || {
            scoped(device, || Kernels::new(device, &base)).map(std::sync::Arc::new)
        })?;
        let binding = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        Ok(GpuCollision {
            ctx: ctx.clone(),
            grid,
            params,
            base,
            kernels,
            max_per_dim: limits.max_compute_workgroups_per_dimension,
            max_vertices: [Body::A, Body::B]
                .map(|body| (binding / bytes_per_vertex(body)).min(crate::cpu::MAX_VERTICES as u64) as u32),
            max_binding: binding,
            max_buffer: limits.max_buffer_size,
            buffers: None,
            bound: None,
            uploaded: GpuParams::default(),
            recorded: None,
            dense: None,
            bind_group_builds: 0,
            sorted_for: [None; 2],
            profile: None,
            sort_b: sorts_b_by_default(ctx),
            upload: None,
            staging: None,
            scratch: Vec::new(),
        })
    }

    /// Whether B is sorted by A's slots before each probe (`true`) or probed in the order it
    /// comes in (`false`: the five passes of B's counting sort are skipped). The reports are
    /// the same either way, to the bit; only the speed differs. The default is measured per
    /// kind of adapter ([`sorts_b_by_default`]).
    pub fn set_sort_b(&mut self, on: bool) {
        self.sort_b = on;
    }

    /// See [`set_sort_b`](Self::set_sort_b).
    #[must_use]
    pub fn sort_b(&self) -> bool {
        self.sort_b
    }

    /// The most vertices either body may have on this device: the smaller of
    /// [`max_vertices_of`](Self::max_vertices_of) `(Body::A)` and `(Body::B)` (A's, 4M on
    /// lavapipe's 128 MiB storage bindings).
    #[must_use]
    pub fn max_vertices(&self) -> u32 {
        self.max_vertices[0].min(self.max_vertices[1])
    }

    /// The most vertices `body` may have on this device: the storage-binding size over the
    /// bytes a vertex takes in the body's largest buffer — 32 for A (its fixed-point force
    /// accumulators: 2M vertices a 64 MiB binding), 16 for B (its positions and forces). More
    /// is [`Error::DeviceLimit`], before anything is recorded.
    #[must_use]
    pub fn max_vertices_of(&self, body: Body) -> u32 {
        self.max_vertices[body as usize]
    }

    /// How many times the bind groups have been built: once, then again only when the device
    /// buffers grow or the app hands other position buffers to [`record`](Self::record).
    #[must_use]
    pub fn bind_group_builds(&self) -> u32 {
        self.bind_group_builds
    }

    /// Whether the last recorded step used a dense voxel table — a slot per voxel of the grid,
    /// chosen while the grid has at most 4 voxels per A vertex — rather than a hashed one, whose
    /// walks also pass other voxels' vertices; `None` before the first step.
    #[must_use]
    pub fn dense_table(&self) -> Option<bool> {
        self.dense
    }

    /// The grid as built.
    #[must_use]
    pub fn grid(&self) -> &VoxelGrid {
        &self.grid
    }

    /// The contact parameters.
    #[must_use]
    pub fn params(&self) -> &ContactParams {
        &self.params
    }

    /// The same backend with its contacts' force magnitudes given by `response`, as
    /// [`CpuCollision::with_response`](crate::CpuCollision::with_response) (the probe pass reads
    /// them from its uniform: the pipelines are the same).
    ///
    /// # Errors
    /// [`Error::Response`] when `response` is invalid for the grid.
    pub fn with_response(self, response: Response) -> Result<GpuCollision, Error> {
        response.validate(&self.params, &self.grid)?;
        let base = GpuParams::new(
            &self.grid,
            &self.params,
            &ForceLaw::new(&self.params, response, self.grid.voxel_size()),
        );
        Ok(GpuCollision { base, uploaded: GpuParams::default(), recorded: None, ..self })
    }

    /// How its contacts' force magnitudes are chosen.
    #[must_use]
    pub fn response(&self) -> Response {
        if self.base.response == 0 {
            Response::Constant
        } else {
            Response::Penalty { stiffness: self.base.stiffness, gap: self.base.gap }
        }
    }

    /// The context this backend runs on.
    #[must_use]
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// **Embedding API.** Records one step into the app's `encoder`, reading positions from the
    /// app's buffers: `a` holds `n_a` and `b` holds `n_b` `vec4<f32>` positions (w ignored) and
    /// both need [`BufferUsages::STORAGE`]. Nothing is read back and nothing is submitted: after
    /// the app submits the encoder, [`force_a_buffer`](Self::force_a_buffer) and
    /// [`force_b_buffer`](Self::force_b_buffer) hold the forces (B's `w` is 1 where it collides)
    /// for the app's own passes, and [`read_report`](Self::read_report) can fetch them.
    ///
    /// Parameters that change with the sizes are written with `queue.write_buffer`, which takes
    /// effect at the app's next submit. Buffers grow when sizes grow; while the sizes and the two
    /// position buffers stay the same, a step creates no device buffer, reuses its bind groups
    /// and allocates no memory of its own — only what wgpu allocates to record its commands
    /// (tests/gpu_alloc.rs).
    ///
    /// # Errors
    /// [`Error::EmptyBody`] for a zero count, [`Error::DeviceLimit`] beyond
    /// [`max_vertices`](Self::max_vertices), [`Error::BufferTooSmall`] or
    /// [`Error::BufferUsage`] for a position buffer that cannot hold or bind the count.
    pub fn record(
        &mut self,
        encoder: &mut CommandEncoder,
        a: &Buffer,
        n_a: u32,
        b: &Buffer,
        n_b: u32,
    ) -> Result<(), Error> {
        let (slots, dense) = self.ready(a, n_a, b, n_b)?;
        let Some(bufs) = self.buffers.as_ref() else { unreachable!("buffers were just made") };
        let Some(bound) = self.bound.as_ref() else { unreachable!("bind groups were just made") };
        let cleared = GpuState::CLEARED;
        encoder.clear_buffer(&bufs.state, cleared.start, Some(cleared.end - cleared.start));
        for sort in [&bufs.sort_a, &bufs.sort_b] {
            encoder.clear_buffer(&sort.count, 0, Some(4 * u64::from(scan_slots(slots))));
            encoder.clear_buffer(&sort.changed, 0, None);
        }
        Self::force_sort(&mut self.sorted_for[0], encoder, &bufs.sort_a, (n_a, slots, dense));
        if self.sort_b {
            Self::force_sort(&mut self.sorted_for[1], encoder, &bufs.sort_b, (n_b, slots, dense));
        } else {
            self.sorted_for[1] = None;
        }
        // The probe writes the forces of B's vertices in the grid and the resolve those of A's;
        // the others stay zero.
        encoder.clear_buffer(&bufs.force_b, 0, Some(VEC4 * u64::from(n_b)));
        encoder.clear_buffer(&bufs.force_a, 0, Some(VEC4 * u64::from(n_a)));
        encoder.clear_buffer(&bufs.fixed, 0, Some(32 * u64::from(n_a)));
        let k = &self.kernels;
        let sort_b = self.sort_b;
        let probe = match (dense, sort_b) {
            (true, true) => &k.probe_dense,
            (false, true) => &k.probe_hashed,
            (true, false) => &k.probe_dense_given,
            (false, false) => &k.probe_hashed_given,
        };
        let probe_group =
            if sort_b { &bound.probe[usize::from(dense)] } else { &bound.probe_given[usize::from(dense)] };
        // B's sort, or nothing where B is probed as given.
        let b_items = |items: u32| Some(if sort_b { items } else { 0 });
        // The step's dispatches in order (one invocation per item, or one workgroup): a fixed
        // array, so that recording allocates nothing of its own.
        let [p0, p1, p2, p3, p4, p5, p6, p7] = self.binning_passes(bound, n_a, slots);
        let passes: [Pass<'_>; PASSES.len()] = [
            p0,
            p1,
            p2,
            p3,
            p4,
            p5,
            p6,
            p7,
            (&k.bin_b, &bound.bin_b, b_items(n_b)),
            (&k.scan, &bound.scan_b, b_items(scan_blocks(slots) * WORKGROUP_SIZE)),
            (&k.scan_carry, &bound.scan_carry_b, if sort_b { None } else { Some(0) }),
            (&k.scan_add, &bound.scan_add_b, b_items(scan_slots(slots) / 4)),
            (&k.sort_b, &bound.sort_b, b_items(n_b)),
            (&k.gather_b, &bound.gather_b, b_items(n_b)),
            (probe, probe_group, Some(n_b)),
            (&k.resolve, &bound.resolve, Some(n_a)),
        ];
        let dispatch =
            |pass: &mut wgpu::ComputePass<'_>, step: Pass<'_>| dispatch(pass, step, self.max_per_dim);
        match &self.profile {
            None => {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("voxcollide step"),
                    timestamp_writes: None,
                });
                for step in passes {
                    dispatch(&mut pass, step);
                }
            }
            Some(profile) => {
                // One compute pass per dispatch, timed at its beginning and end.
                for (t, step) in passes.into_iter().enumerate() {
                    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some(PASSES[t]),
                        timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                            query_set: &profile.queries,
                            beginning_of_pass_write_index: Some(2 * t as u32),
                            end_of_pass_write_index: Some(2 * t as u32 + 1),
                        }),
                    });
                    dispatch(&mut pass, step);
                }
                let n = 2 * PASSES.len() as u32;
                encoder.resolve_query_set(&profile.queries, 0..n, &profile.resolved, 0);
                encoder.copy_buffer_to_buffer(&profile.resolved, 0, &profile.readback, 0, 8 * u64::from(n));
            }
        }
        self.recorded = Some((n_a, n_b));
        self.dense = Some(dense);
        if let Some(profile) = self.profile.as_mut() {
            profile.recorded = true;
        }
        Ok(())
    }

    /// Checks a step's inputs and makes its buffers, uniform and bind groups ready for
    /// [`record`](Self::record) or [`record_binning`](Self::record_binning): the voxel table's
    /// slots, and whether it is dense.
    fn ready(&mut self, a: &Buffer, n_a: u32, b: &Buffer, n_b: u32) -> Result<(u32, bool), Error> {
        self.check_input(Body::A, a, n_a)?;
        self.check_input(Body::B, b, n_b)?;
        let device = self.ctx.device().clone();
        let (slots, dense) = self.slots(n_a);
        let grow = self
            .buffers
            .as_ref()
            .is_none_or(|bufs| n_a > bufs.cap_a || n_b > bufs.cap_b || slots > bufs.cap_slots);
        if grow {
            let (cap_a, cap_b, cap_slots) = self
                .buffers
                .as_ref()
                .map_or((n_a, n_b, slots), |x| (x.cap_a.max(n_a), x.cap_b.max(n_b), x.cap_slots.max(slots)));
            self.buffers = Some(scoped(&device, || Buffers::new(&device, cap_a, cap_b, cap_slots))?);
            self.bound = None;
            self.sorted_for = [None; 2];
        }
        let Some(bufs) = self.buffers.as_ref() else { unreachable!("buffers were just made") };

        // Sizes live in the uniform. A slot holds any number of vertices, so the table never
        // fills; in a hashed one, aliasing only lengthens a walk.
        let params = GpuParams { n_a, n_b, slot_mask: slots - 1, dense: u32::from(dense), ..self.base };
        if params != self.uploaded {
            self.ctx.queue().write_buffer(&bufs.params, 0, bytemuck::bytes_of(&params));
            self.uploaded = params;
        }
        let stale = self.bound.as_ref().is_none_or(|bound| bound.a != *a || bound.b != *b);
        if stale {
            let k = &self.kernels;
            let (sa, sb) = (&bufs.sort_a, &bufs.sort_b);
            let bound = scoped(&device, || Bound {
                a: a.clone(),
                b: b.clone(),
                bounds: k.bounds.bind(&device, &[&bufs.params, &bufs.state, a]),
                frame: k.frame.bind(&device, &[&bufs.params, &bufs.state]),
                bin: k.bin.bind(&device, &[&bufs.params, &bufs.state, a, &sa.count, &sa.keys, &sa.changed]),
                scan: k.scan.bind(&device, &[&bufs.params, &sa.count, &sa.start, &sa.partial, &sa.changed]),
                scan_carry: k.scan_carry.bind(&device, &[&bufs.params, &sa.partial, &sa.changed]),
                scan_add: k
                    .scan_add
                    .bind(&device, &[&bufs.params, &sa.start, &sa.partial, &sa.cursor, &sa.changed]),
                sort: k
                    .sort
                    .bind(&device, &[&bufs.params, &bufs.state, a, &sa.cursor, &sa.sorted, &sa.changed]),
                gather: k.gather.bind(&device, &[&bufs.params, &bufs.state, a, &sa.sorted, &sa.changed]),
                bin_b: k
                    .bin_b
                    .bind(&device, &[&bufs.params, &bufs.state, b, &sb.count, &sb.keys, &sb.changed]),
                scan_b: k.scan.bind(&device, &[&bufs.params, &sb.count, &sb.start, &sb.partial, &sb.changed]),
                scan_carry_b: k.scan_carry.bind(&device, &[&bufs.params, &sb.partial, &sb.changed]),
                scan_add_b: k
                    .scan_add
                    .bind(&device, &[&bufs.params, &sb.start, &sb.partial, &sb.cursor, &sb.changed]),
                sort_b: k
                    .sort_b
                    .bind(&device, &[&bufs.params, &bufs.state, b, &sb.cursor, &sb.sorted, &sb.changed]),
                gather_b: k.gather_b.bind(&device, &[&bufs.params, &bufs.state, b, &sb.sorted, &sb.changed]),
                probe: [&k.probe_hashed, &k.probe_dense].map(|probe| {
                    probe.bind(
                        &device,
                        &[
                            &bufs.params,
                            &bufs.state,
                            &sb.sorted,
                            &sa.start,
                            &sa.sorted,
                            &bufs.fixed,
                            &bufs.force_b,
                        ],
                    )
                }),
                probe_given: [&k.probe_hashed_given, &k.probe_dense_given].map(|probe| {
                    probe.bind(
                        &device,
                        &[&bufs.params, &bufs.state, b, &sa.start, &sa.sorted, &bufs.fixed, &bufs.force_b],
                    )
                }),
                resolve: k
                    .resolve
                    .bind(&device, &[&bufs.params, &bufs.state, &bufs.fixed, &sa.sorted, &bufs.force_a]),
            })?;
            self.bound = Some(bound);
            self.bind_group_builds += 1;
        }
        Ok((slots, dense))
    }

    /// **Embedding API.** Records the first half of a step alone into `encoder`: `a`'s `n_a`
    /// positions binned by voxel (the grid following them under [`Anchor::FollowA`]), in the
    /// buffers that the app's own passes may then walk as the probe does: the uniform
    /// ([`params_buffer`](Self::params_buffer), `Params` in `shaders/common.wgsl`), the state
    /// with this step's grid origin ([`state_buffer`](Self::state_buffer)), each slot's first
    /// place ([`slot_starts_buffer`](Self::slot_starts_buffer), `slots + 1` words, the slot of a
    /// voxel as `slot_of` in `shaders/common.wgsl` gives it) and the binned vertices in slot
    /// order ([`sorted_buffer`](Self::sorted_buffer): per place, the position's bits in xyz and
    /// the vertex in w). A slot of a hashed table may hold other voxels' vertices too. Vertices
    /// outside the grid are not binned; the state counts those that are. Nothing is probed,
    /// and the forces are left as they were. The surface contact's search on the device walks
    /// these (`voxcollide-sim`, docs/contacts.md).
    ///
    /// # Errors
    /// Those of [`record`](Self::record) for `a`.
    pub fn record_binning(
        &mut self,
        encoder: &mut CommandEncoder,
        a: &Buffer,
        n_a: u32,
    ) -> Result<(), Error> {
        // (B's buffers are bound to `a` as well, and not used.)
        let (slots, dense) = self.ready(a, n_a, a, n_a)?;
        let Some(bufs) = self.buffers.as_ref() else { unreachable!("buffers were just made") };
        let Some(bound) = self.bound.as_ref() else { unreachable!("bind groups were just made") };
        let cleared = GpuState::CLEARED;
        encoder.clear_buffer(&bufs.state, cleared.start, Some(cleared.end - cleared.start));
        encoder.clear_buffer(&bufs.sort_a.count, 0, Some(4 * u64::from(scan_slots(slots))));
        encoder.clear_buffer(&bufs.sort_a.changed, 0, None);
        Self::force_sort(&mut self.sorted_for[0], encoder, &bufs.sort_a, (n_a, slots, dense));
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("voxcollide binning"),
            timestamp_writes: None,
        });
        for step in self.binning_passes(bound, n_a, slots) {
            dispatch(&mut pass, step, self.max_per_dim);
        }
        drop(pass);
        self.dense = Some(dense);
        Ok(())
    }

    /// A body's kept slots cleared (`0`, which no slot is kept as, so that every vertex reads as
    /// changed and the body is sorted again) where it was last binned for other sizes or another
    /// table than `now` (vertices, slots, dense): a kept order is only one the sort could make
    /// for the same vertices over the same slots.
    fn force_sort(
        sorted_for: &mut Option<(u32, u32, bool)>,
        encoder: &mut CommandEncoder,
        sort: &SortBuffers,
        now: (u32, u32, bool),
    ) {
        if *sorted_for != Some(now) {
            encoder.clear_buffer(&sort.keys, 0, None);
            *sorted_for = Some(now);
        }
    }

    /// The first eight passes of a step, A's binning (the grid following A, A counted, scanned
    /// and sorted by slot, or its kept order brought up to date), as [`record`](Self::record)
    /// and [`record_binning`](Self::record_binning) both dispatch them.
    fn binning_passes<'s>(&'s self, bound: &'s Bound, n_a: u32, slots: u32) -> [Pass<'s>; 8] {
        let k = &self.kernels;
        let follow = self.params.anchor == Anchor::FollowA;
        [
            (&k.bounds, &bound.bounds, Some(if follow { n_a } else { 0 })),
            (&k.frame, &bound.frame, None),
            (&k.bin, &bound.bin, Some(n_a)),
            // One workgroup per scan block, then one invocation per 4 slots.
            (&k.scan, &bound.scan, Some(scan_blocks(slots) * WORKGROUP_SIZE)),
            (&k.scan_carry, &bound.scan_carry, None),
            (&k.scan_add, &bound.scan_add, Some(scan_slots(slots) / 4)),
            (&k.sort, &bound.sort, Some(n_a)),
            (&k.gather, &bound.gather, Some(n_a)),
        ]
    }

    /// The uniform of the recorded steps (`Params` in `shaders/common.wgsl`); `None` before the
    /// first.
    #[must_use]
    pub fn params_buffer(&self) -> Option<&Buffer> {
        self.buffers.as_ref().map(|b| &b.params)
    }

    /// Each voxel slot's first place in [`sorted_buffer`](Self::sorted_buffer) after a recorded
    /// step or binning (`u32`, one more than the slots: slot `s`'s vertices are places
    /// `start[s]..start[s + 1]`); `None` before the first.
    #[must_use]
    pub fn slot_starts_buffer(&self) -> Option<&Buffer> {
        self.buffers.as_ref().map(|b| &b.sort_a.start)
    }

    /// A's binned vertices in slot order after a recorded step or binning (`vec4<u32>`: the
    /// position's bits, then the vertex); `None` before the first.
    #[must_use]
    pub fn sorted_buffer(&self) -> Option<&Buffer> {
        self.buffers.as_ref().map(|b| &b.sort_a.sorted)
    }

    /// Times every pass of the steps recorded from now on (`true`) or stops (`false`). Each pass
    /// then gets a compute pass of its own with timestamp queries, and [`record`](Self::record)
    /// also records their readback; read the times with [`pass_times`](Self::pass_times).
    /// Profiling changes what a step records, so time whole steps with it off.
    ///
    /// # Errors
    /// [`Error::Gpu`] when the device was opened without [`wgpu::Features::TIMESTAMP_QUERY`]
    /// ([`GpuContext::new`] asks for it wherever the adapter has it).
    pub fn set_profiling(&mut self, on: bool) -> Result<(), Error> {
        if !on {
            self.profile = None;
            return Ok(());
        }
        if self.profile.is_some() {
            return Ok(());
        }
        let device = self.ctx.device();
        if !device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            return Err(Error::Gpu {
                message: "profiling needs timestamp queries (wgpu::Features::TIMESTAMP_QUERY), which \
                          this device was not opened with"
                    .into(),
            });
        }
        let count = 2 * PASSES.len() as u32;
        let bytes = 8 * u64::from(count);
        let profile = scoped(device, || Profile {
            queries: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("voxcollide pass times"),
                ty: wgpu::QueryType::Timestamp,
                count,
            }),
            resolved: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("voxcollide pass times"),
                size: bytes,
                usage: BufferUsages::QUERY_RESOLVE | BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            readback: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("voxcollide pass times readback"),
                size: bytes,
                usage: BufferUsages::MAP_READ | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            period: self.ctx.queue().get_timestamp_period(),
            recorded: false,
        })?;
        self.profile = Some(profile);
        Ok(())
    }

    /// The time of each pass of the last step recorded with profiling on, in milliseconds, in
    /// the order of [`PASSES`] (`bounds` is 0 under `Anchor::Fixed`), after the app has
    /// submitted it. Blocks until the device is done.
    ///
    /// # Errors
    /// [`Error::Gpu`] when profiling is off or no step was recorded with it, or the device
    /// fails.
    pub fn pass_times(&mut self) -> Result<[(&'static str, f64); PASSES.len()], Error> {
        let Some(profile) = self.profile.as_ref() else {
            return Err(Error::Gpu { message: "pass_times() with profiling off (see set_profiling)".into() });
        };
        if !profile.recorded {
            return Err(Error::Gpu {
                message: "pass_times() before a step was recorded with profiling on".into(),
            });
        }
        let bytes = map_read(&self.ctx, &profile.readback, profile.readback.size())?;
        let tick = |k: usize| -> u64 { bytemuck::pod_read_unaligned(&bytes[8 * k..8 * k + 8]) };
        let mut out = [("", 0.0); PASSES.len()];
        for (t, name) in PASSES.iter().enumerate() {
            let (start, end) = (tick(2 * t), tick(2 * t + 1));
            out[t] = (*name, end.saturating_sub(start) as f64 * f64::from(profile.period) / 1e6);
        }
        Ok(out)
    }

    /// The forces on A after a recorded step: `n_a` `vec4<f32>` (w = 0).
    ///
    /// # Panics
    /// Never; returns `None` before the first [`record`](Self::record).
    #[must_use]
    pub fn force_a_buffer(&self) -> Option<&Buffer> {
        self.buffers.as_ref().map(|b| &b.force_a)
    }

    /// The forces on B after a recorded step: `n_b` `vec4<f32>`, `w = 1` where B collides.
    #[must_use]
    pub fn force_b_buffer(&self) -> Option<&Buffer> {
        self.buffers.as_ref().map(|b| &b.force_b)
    }

    /// The step's state (96 bytes; see `State` in `shaders/common.wgsl`): grid center and
    /// origin, then at byte 64 the binned-A and colliding-B counts as `u32`.
    #[must_use]
    pub fn state_buffer(&self) -> Option<&Buffer> {
        self.buffers.as_ref().map(|b| &b.state)
    }

    /// Reads back the report of the last recorded step, after the app has submitted it. Blocks
    /// until the device is done.
    ///
    /// # Errors
    /// [`Error::DeviceLimit`] (`max_buffer_size`) when the device's largest buffer cannot hold
    /// both bodies' forces at once,
    /// [`Error::ForceOverflow`] or [`Error::NonFiniteCenter`] as the CPU reference gives them,
    /// [`Error::Gpu`] / [`Error::DeviceLost`] when the device fails, and [`Error::Gpu`] when no
    /// step was recorded.
    pub fn read_report(&mut self) -> Result<ContactReport, Error> {
        let Some((n_a, n_b)) = self.recorded else {
            return Err(Error::Gpu { message: "read_report() before any step was recorded".into() });
        };
        self.check_readback(n_a, n_b)?;
        let device = self.ctx.device().clone();
        let mut encoder = device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("voxcollide readback") });
        let size = readback_size(n_a, n_b);
        let staging = self.staging(size)?;
        let Some(bufs) = self.buffers.as_ref() else { unreachable!("a step was recorded") };
        copy_report(&mut encoder, bufs, &staging, n_a, n_b);
        self.ctx.queue().submit([encoder.finish()]);
        self.finish_report(&staging, n_a, n_b)
    }

    /// The slots of the voxel table for `n_a` vertices, and whether it is dense. Dense — a slot
    /// per voxel of the grid, at its linear index, so no slot holds another voxel's vertices —
    /// while the grid has at most 4 voxels per A vertex (memory stays O(|A|)) and the table
    /// fits a storage binding; hashed otherwise, with `n_a` rounded up to a power of two slots
    /// (at least 4).
    fn slots(&self, n_a: u32) -> (u32, bool) {
        // The same decision as the parallel backend's, in exact arithmetic (voxel_data).
        match dense_slots(self.grid.dims(), n_a as usize) {
            Some(voxels) if 4 * u64::from(scan_slots(voxels)) <= self.max_binding => (voxels, true),
            _ => (hashed_slots(n_a as usize, 1), false),
        }
    }

    fn check_input(&self, body: Body, buffer: &Buffer, n: u32) -> Result<(), Error> {
        if n == 0 {
            return Err(Error::EmptyBody { body });
        }
        if n > self.max_vertices_of(body) {
            return Err(self.limit_error(body, n as usize));
        }
        if !buffer.usage().contains(BufferUsages::STORAGE) {
            return Err(Error::BufferUsage { body });
        }
        let needed = VEC4 * u64::from(n);
        if buffer.size() < needed {
            return Err(Error::BufferTooSmall { body, len: n, size: buffer.size(), needed });
        }
        Ok(())
    }

    /// A report is read back through one buffer holding both bodies' forces and the state; where
    /// the device's largest buffer cannot hold it (a device whose `max_buffer_size` is not above
    /// its binding size, with both bodies near their limits), B's count is the one to shrink.
    fn check_readback(&self, n_a: u32, n_b: u32) -> Result<(), Error> {
        if readback_size(n_a, n_b) <= self.max_buffer {
            return Ok(());
        }
        let room = self.max_buffer.saturating_sub(GpuState::SIZE) / VEC4;
        Err(Error::DeviceLimit {
            body: Body::B,
            len: n_b as usize,
            max: room.saturating_sub(u64::from(n_a)) as usize,
            limit: "max_buffer_size",
            bytes: self.max_buffer,
            per_vertex: VEC4,
        })
    }

    fn limit_error(&self, body: Body, len: usize) -> Error {
        Error::DeviceLimit {
            body,
            len,
            max: self.max_vertices_of(body) as usize,
            limit: "max_storage_buffer_binding_size",
            bytes: self.max_binding,
            per_vertex: bytes_per_vertex(body),
        }
    }

    /// A mappable buffer of at least `size` bytes, reused while it is large enough.
    fn staging(&mut self, size: u64) -> Result<Buffer, Error> {
        if self.staging.as_ref().is_none_or(|s| s.size() < size) {
            let device = self.ctx.device();
            self.staging = Some(scoped(device, || {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("voxcollide staging"),
                    size,
                    usage: BufferUsages::MAP_READ | BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            })?);
        }
        Ok(self.staging.clone().unwrap_or_else(|| unreachable!("staging was just made")))
    }

    /// Maps `staging` (already filled by a submitted copy) and turns it into a report.
    fn finish_report(&mut self, staging: &Buffer, n_a: u32, n_b: u32) -> Result<ContactReport, Error> {
        let (a_end, b_end) = (VEC4 as usize * n_a as usize, VEC4 as usize * (n_a + n_b) as usize);
        // Straight from the mapped bytes into the report's vectors: no intermediate copies.
        let (state, report) = map_read_with(&self.ctx, staging, readback_size(n_a, n_b), |bytes| {
            let state: GpuState =
                bytemuck::pod_read_unaligned(&bytes[b_end..b_end + GpuState::SIZE as usize]);
            if state.failed() {
                return (state, None);
            }
            let forces_a = vec4s(&bytes[..a_end]);
            let forces_b = vec4s(&bytes[a_end..b_end]);
            let report = ContactReport {
                force_a: forces_a.iter().map(|f| Vec3::new(f[0], f[1], f[2])).collect(),
                force_b: forces_b.iter().map(|f| Vec3::new(f[0], f[1], f[2])).collect(),
                colliding_b: (0..n_b).filter(|&j| forces_b[j as usize][3] == 1.0).collect(),
                binned_a: state.binned,
                discarded_a: n_a - state.binned,
                grid_center: Vec3::from_slice(&state.center[..3]),
            };
            (state, Some(report))
        })?;
        let center = Vec3::from_slice(&state.center[..3]);
        if state.status & GpuState::NON_FINITE_CENTER != 0 {
            return Err(Error::NonFiniteCenter { center });
        }
        if state.truncated != 0 {
            return Err(Error::WalkTruncated { b: !state.truncated });
        }
        if state.overflow != 0 {
            return Err(self.overflow_error(!state.overflow));
        }
        report.ok_or_else(|| Error::Gpu { message: "the step's state and report disagree".into() })
    }

    /// The `ForceOverflow` error for accumulator `code = 3 * vertex + axis`, with its exact total.
    fn overflow_error(&mut self, code: u32) -> Error {
        let (vertex, axis) = (code / 3, code % 3);
        let count = self.read_fixed(code).unwrap_or(i64::MIN);
        Error::ForceOverflow { vertex, axis, count }
    }

    fn read_fixed(&mut self, code: u32) -> Result<i64, Error> {
        let device = self.ctx.device().clone();
        let staging = self.staging(8)?;
        let Some(bufs) = self.buffers.as_ref() else { unreachable!("a step was recorded") };
        let mut encoder = device.create_command_encoder(&Default::default());
        // Vertex i's low words are at 8i.., its high words at 8i + 4.. (see `Buffers::fixed`).
        let low = 4 * u64::from(8 * (code / 3) + code % 3);
        encoder.copy_buffer_to_buffer(&bufs.fixed, low, &staging, 0, 4);
        encoder.copy_buffer_to_buffer(&bufs.fixed, low + 16, &staging, 4, 4);
        self.ctx.queue().submit([encoder.finish()]);
        let bytes = map_read(&self.ctx, &staging, 8)?;
        // The total biased by 2^31 (see add_fixed in shaders/probe.wgsl).
        let lo: u32 = bytemuck::pod_read_unaligned(&bytes[0..4]);
        let hi: i32 = bytemuck::pod_read_unaligned(&bytes[4..8]);
        Ok((i64::from(hi) << 32) + i64::from(lo ^ 0x8000_0000) - (1 << 31))
    }

    /// Uploads `points` as `vec4<f32>` into the step's own position buffer for `body`.
    fn upload(&mut self, a: &[Vec3], b: &[Vec3]) -> Result<(), Error> {
        let device = self.ctx.device().clone();
        let fits = |buf: &Buffer, n: usize| buf.size() >= VEC4 * n as u64;
        if self.upload.as_ref().is_none_or(|(ba, bb)| !fits(ba, a.len()) || !fits(bb, b.len())) {
            let make = |label, n: usize| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: VEC4 * n as u64,
                    usage: BufferUsages::STORAGE | BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            let keep = |i: usize, n: usize| {
                self.upload.as_ref().map_or(n, |(ba, bb)| n.max(([ba, bb][i].size() / VEC4) as usize))
            };
            let (na, nb) = (keep(0, a.len()), keep(1, b.len()));
            self.upload = Some(scoped(&device, || (make("voxcollide a", na), make("voxcollide b", nb)))?);
        }
        let Some((ba, bb)) = self.upload.as_ref() else { unreachable!("upload buffers were just made") };
        for (points, buf) in [(a, ba), (b, bb)] {
            self.scratch.clear();
            self.scratch.extend(points.iter().map(|p| p.extend(0.0)));
            self.ctx.queue().write_buffer(buf, 0, bytemuck::cast_slice(&self.scratch));
        }
        Ok(())
    }
}

impl Collision for GpuCollision {
    fn step(&mut self, a: &[Vec3], b: &[Vec3]) -> Result<ContactReport, Error> {
        check_body(Body::A, a)?;
        check_body(Body::B, b)?;
        for (body, len) in [(Body::A, a.len()), (Body::B, b.len())] {
            if len > self.max_vertices_of(body) as usize {
                return Err(self.limit_error(body, len));
            }
        }
        if self.ctx.is_lost() {
            return Err(Error::DeviceLost { message: "the device was lost before this step".into() });
        }
        let (n_a, n_b) = (a.len() as u32, b.len() as u32);
        self.check_readback(n_a, n_b)?;
        self.upload(a, b)?;
        let device = self.ctx.device().clone();
        let staging = self.staging(readback_size(n_a, n_b))?;
        let (ba, bb) = self.upload.clone().unwrap_or_else(|| unreachable!("uploaded above"));
        let guard = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("voxcollide step") });
        self.record(&mut encoder, &ba, n_a, &bb, n_b)?;
        let Some(bufs) = self.buffers.as_ref() else { unreachable!("a step was recorded") };
        copy_report(&mut encoder, bufs, &staging, n_a, n_b);
        self.ctx.queue().submit([encoder.finish()]);
        if let Some(e) = pollster::block_on(guard.pop()) {
            return Err(Error::Gpu { message: e.to_string() });
        }
        self.finish_report(&staging, n_a, n_b)
    }
}

/// Bytes a vertex of `body` takes in the body's largest device buffer: A's fixed-point
/// accumulators hold 8 words a vertex (see `Buffers::fixed`), B's positions and forces a
/// `vec4<f32>`.
fn bytes_per_vertex(body: Body) -> u64 {
    match body {
        Body::A => 32,
        Body::B => VEC4,
    }
}

/// `bytes` as `[f32; 4]`s: borrowed where they are aligned for it (a mapped buffer is), copied
/// otherwise.
fn vec4s(bytes: &[u8]) -> std::borrow::Cow<'_, [[f32; 4]]> {
    match bytemuck::try_cast_slice(bytes) {
        Ok(v) => std::borrow::Cow::Borrowed(v),
        Err(_) => std::borrow::Cow::Owned(bytemuck::pod_collect_to_vec(bytes)),
    }
}

fn readback_size(n_a: u32, n_b: u32) -> u64 {
    VEC4 * (u64::from(n_a) + u64::from(n_b)) + GpuState::SIZE
}

/// Copies force_a, force_b and the state, back to back, into `staging`.
fn copy_report(encoder: &mut CommandEncoder, bufs: &Buffers, staging: &Buffer, n_a: u32, n_b: u32) {
    let (a, b) = (VEC4 * u64::from(n_a), VEC4 * u64::from(n_b));
    encoder.copy_buffer_to_buffer(&bufs.force_a, 0, staging, 0, a);
    encoder.copy_buffer_to_buffer(&bufs.force_b, 0, staging, a, b);
    encoder.copy_buffer_to_buffer(&bufs.state, 0, staging, a + b, GpuState::SIZE);
}

/// Copies `(buffer, size)` pairs into one staging buffer, submits, and returns each one's bytes.
///
/// # Errors
/// [`Error::Gpu`] or [`Error::DeviceLost`] when the device fails.
pub fn read_buffers(ctx: &GpuContext, parts: &[(&Buffer, u64)]) -> Result<Vec<Vec<u8>>, Error> {
    let device = ctx.device();
    let total: u64 = parts.iter().map(|(_, n)| n.div_ceil(4) * 4).sum();
    let staging = scoped(device, || {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("voxcollide readback"),
            size: total.max(4),
            usage: BufferUsages::MAP_READ | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    })?;
    let mut encoder = device.create_command_encoder(&Default::default());
    let mut offset = 0;
    for (buffer, size) in parts {
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, offset, *size);
        offset += size.div_ceil(4) * 4;
    }
    ctx.queue().submit([encoder.finish()]);
    let bytes = map_read(ctx, &staging, total.max(4))?;
    let mut out = Vec::with_capacity(parts.len());
    let mut offset = 0usize;
    for (_, size) in parts {
        out.push(bytes[offset..offset + *size as usize].to_vec());
        offset += (size.div_ceil(4) * 4) as usize;
    }
    Ok(out)
}

thread_local! {
    /// This thread's count of waits for the device to hand data back ([`host_waits`]).
    static HOST_WAITS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// How many times this thread has waited for the device to hand data back to the host: every
/// buffer mapped for reading through [`map_read`] or [`read_buffers`] (which is how every
/// readback of this workspace waits). A caller measures a piece of work by the count before
/// and after it, on the thread that does it: the simulator's `host_waits_per_step`
/// (docs/design.md §5). Per thread, so that work on other threads does not count.
#[must_use]
pub fn host_waits() -> u64 {
    HOST_WAITS.with(std::cell::Cell::get)
}

/// Maps the first `size` bytes of `buffer` for reading, waits, and copies them out.
///
/// # Errors
/// [`Error::Gpu`] or [`Error::DeviceLost`] when the device fails.
pub fn map_read(ctx: &GpuContext, buffer: &Buffer, size: u64) -> Result<Vec<u8>, Error> {
    map_read_with(ctx, buffer, size, <[u8]>::to_vec)
}

/// Maps the first `size` bytes of `buffer` (already filled by a submitted copy), waits for the
/// device, and hands them to `f` in place, without copying them first.
pub(crate) fn map_read_with<T>(
    ctx: &GpuContext,
    buffer: &Buffer,
    size: u64,
    f: impl FnOnce(&[u8]) -> T,
) -> Result<T, Error> {
    HOST_WAITS.with(|w| w.set(w.get() + 1));
    let slice = buffer.slice(..size);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    let lost = |what: String| {
        if ctx.is_lost() { Error::DeviceLost { message: what } } else { Error::Gpu { message: what } }
    };
    ctx.device()
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| lost(format!("waiting for the device: {e}")))?;
    match rx.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(lost(format!("reading the results back: {e}"))),
        Err(_) => return Err(lost("reading the results back: the map callback never ran".into())),
    }
    let out = {
        let view = slice.get_mapped_range().map_err(|e| lost(format!("reading the results back: {e}")))?;
        f(&view)
    };
    buffer.unmap();
    Ok(out)
}

/// Runs `f` inside validation and out-of-memory error scopes, turning a captured error into
/// [`Error::Gpu`].
///
/// For recording or creating anything on a device that should fail as a value: wgpu reports
/// validation errors to an uncaptured-error handler (which panics by default) unless a scope
/// catches them.
///
/// # Errors
/// [`Error::Gpu`] with wgpu's message.
pub fn scoped<T>(device: &Device, f: impl FnOnce() -> T) -> Result<T, Error> {
    let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let value = f();
    let errors = [pollster::block_on(validation.pop()), pollster::block_on(oom.pop())];
    match errors.into_iter().flatten().next() {
        Some(e) => Err(Error::Gpu { message: e.to_string() }),
        None => Ok(value),
    }
}
