//! The implicit integrator on the GPU (DESIGN §12): [`crate::GpuWorld`]'s step for a world of
//! spring lattices whose contacts are the voxel model's, in WGSL (`shaders/implicit.wgsl`).
//!
//! Each body's step is the CPU's ([`crate::implicit`]) term by term: the same forces, the same
//! blocks of `A = M − h·D − h²·K` (springs, a fill's rank-one term, each contact's `k·nnᵀ` and
//! its critical damping), the same block-Jacobi preconditioner, the conjugate gradient started
//! from the last step's answer where that leaves less to solve, the floor's rows held, and the
//! same update. The passes run without a readback except where the host must decide: once per
//! batch of [`BATCH`] iterations (has every body's solve converged?) and once at the end (how
//! far would the farthest vertex move?).
//!
//! **One solve over every body**, as on the CPU: each body's passes write its own range of
//! every column of partial sums in one buffer (`red`), and the scalar passes sum every body's,
//! so `α`, `β`, the start from the last answer and the stopping test `|r| ≤ tol·|b|` are the
//! joint system's, and every body reports the joint solve in its [`StepStats`]. A fill's
//! products (`g·v`, `g·p`) and a body's residual at rest are its own.
//!
//! **What differs from the CPU.** The dot products are `f32` trees per workgroup on the device,
//! `f64` chunk sums on the CPU, so the two agree to the solve's tolerance, not bit for bit. A
//! step that would carry a vertex farther than
//! [`ImplicitSettings::max_move`](crate::ImplicitSettings::max_move) is taken in parts, or
//! scaled, as on the CPU ([`crate::Parts`]).

use bytemuck::{Pod, Zeroable};
use wgpu::{Buffer, BufferUsages};

use crate::body::StepInputs;
use crate::implicit::{Residual, StepStats};
use voxcollide::error::Error;
use voxcollide::gpu::kernel::{Kernel, Slot, workgroups};

/// The implicit passes' WGSL, composed with `sim_common.wgsl`.
pub const IMPLICIT: &str = concat!(
    include_str!("../shaders/sim_common.wgsl"),
    include_str!("../shaders/elements.wgsl"),
    include_str!("../shaders/implicit.wgsl")
);
/// The contact stiffness pass's WGSL.
pub const IMPLICIT_CONTACT: &str =
    concat!(include_str!("../shaders/sim_common.wgsl"), include_str!("../shaders/implicit_contact.wgsl"));

/// Conjugate-gradient iterations recorded between two looks at whether the solves converged.
pub const BATCH: u32 = 8;

// The passes (`PASS` in implicit.wgsl).
const PREPARE: usize = 0;
const FLOOR: usize = 1;
const RHS: usize = 2;
const GUESS: usize = 3;
const START: usize = 4;
const GP: usize = 5;
const APPLY: usize = 6;
const UPDATE: usize = 7;
const DIRECTION: usize = 8;
const FARTHEST: usize = 9;
const MOVE: usize = 10;
const SCALARS_A: usize = 11;
const SCALARS_B: usize = 12;
const SCALARS_C: usize = 13;
const SCALARS_GP: usize = 14;
const SCALARS_ALPHA: usize = 15;
const SCALARS_BETA: usize = 16;
const SCALARS_FAR: usize = 17;
const TANGENT: usize = 18;
const PRODUCT_RHS: usize = 19;
const PRODUCT_P: usize = 20;
const PRODUCT_X: usize = 21;
/// Each pass's `PASS` constant, in the order above.
const PASS_IDS: [u32; 22] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 20, 21, 22, 23, 24, 25, 26, 11, 12, 13, 14];
/// Whether each pass is one workgroup (the scalars) rather than one invocation per vertex.
const fn single(pass: usize) -> bool {
    pass >= SCALARS_A && pass <= SCALARS_FAR
}
/// Whether each pass is one invocation per tetrahedron.
const fn per_tetrahedron(pass: usize) -> bool {
    pass >= TANGENT
}
/// `vec4`s per tetrahedron in `tet_work` (`TET_WORK` in implicit.wgsl).
const TET_WORK: u64 = 15;

/// Slots of per-vertex vectors in `work` (`SLOTS` in implicit.wgsl); the contact stiffness's.
const SLOTS: u64 = 15;
const SLOT_KC0: u32 = 5;
/// Columns of partials, the joint scalars and each body's own in `red`.
const COLUMNS: u64 = 8;
const SCALARS: u64 = 16;
const BODY_SCALARS: u64 = 8;
// The joint scalars read back (`S_*` in implicit.wgsl).
const S_DONE: usize = 7;
const S_ITERATIONS: usize = 8;
const S_RR: usize = 5;
const S_NORM_B2: usize = 9;
const S_FARTHEST: usize = 12;
// A body's own (`B_*`).
const B_NET2: usize = 3;
const B_GROSS2: usize = 4;

/// Keep in sync with `ImplicitParams` in `shaders/implicit.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
struct GpuImplicitParams {
    h: f32,
    fill_k: f32,
    guess_scale: f32,
    tolerance: f32,
    scale: f32,
    max_iterations: f32,
    /// Partials per column over every body; this body's first and its count.
    groups: u32,
    base: u32,
    own: u32,
    /// This body's index, and the bodies'.
    body: u32,
    bodies: u32,
    _pad: u32,
}
const _: () = assert!(std::mem::size_of::<GpuImplicitParams>() == 48);

/// The kernels of the implicit passes, built once per world.
pub(crate) struct ImplicitKernels {
    passes: Vec<Kernel>,
    contact: Kernel,
}

impl ImplicitKernels {
    pub(crate) fn new(device: &wgpu::Device) -> ImplicitKernels {
        use Slot::{Read, ReadWrite, Uniform};
        let slots = [
            Uniform, Uniform, ReadWrite, ReadWrite, Read, Read, Read, Read, Read, Read, Read, ReadWrite,
            ReadWrite, ReadWrite, Read, Read, ReadWrite,
        ];
        let passes = PASS_IDS
            .iter()
            .map(|&id| {
                Kernel::with_constants(
                    device,
                    "voxcollide implicit",
                    IMPLICIT,
                    &slots,
                    &[("PASS", f64::from(id))],
                )
            })
            .collect();
        let contact =
            Kernel::new(device, "voxcollide implicit contact", IMPLICIT_CONTACT, &[Uniform, Read, ReadWrite]);
        ImplicitKernels { passes, contact }
    }
}

/// The world's buffer of partial sums and scalars (`red` in implicit.wgsl), which every body's
/// passes share: one solve over every body.
pub(crate) struct Sums {
    red: Buffer,
    /// Partials per column over every body.
    groups: u32,
    bodies: u32,
}

impl Sums {
    /// The buffer for bodies of `n` vertices each.
    pub(crate) fn new(device: &wgpu::Device, n: &[u32], max_per_dim: u32) -> Sums {
        let groups: u32 = n.iter().map(|&n| own_groups(n, max_per_dim)).sum();
        let bodies = n.len() as u32;
        let size = 4 * (SCALARS + BODY_SCALARS * u64::from(bodies) + COLUMNS * u64::from(groups));
        let red = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("implicit sums"),
            size: size.max(16),
            usage: BufferUsages::STORAGE | BufferUsages::COPY_SRC | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Sums { red, groups, bodies }
    }
}

/// A body's workgroups in a pass over its vertices.
fn own_groups(n: u32, max_per_dim: u32) -> u32 {
    let (x, y) = workgroups(n.max(1), max_per_dim);
    x * y
}

/// One body's device buffers for the implicit passes, and its bind groups.
pub(crate) struct ImplicitBody {
    params: Buffer,
    work: Buffer,
    /// Per tetrahedron: its stiffness and two products (`TET_WORK`).
    _tet_work: Buffer,
    n: u32,
    tets: u32,
    /// Its workgroups, the first of them among every body's, and its index.
    groups: u32,
    base: u32,
    body: u32,
    /// One bind group per pass.
    groups_of: Vec<wgpu::BindGroup>,
    /// Per contact that pushes this body with a penalty: its params and bind group.
    contacts: Vec<(Buffer, wgpu::BindGroup)>,
}

/// The buffers of a body that the implicit passes bind besides their own.
pub(crate) struct BodyBuffers<'a> {
    pub sim: &'a Buffer,
    pub pos: &'a Buffer,
    pub vel: &'a Buffer,
    pub info: &'a Buffer,
    pub offsets: &'a Buffer,
    pub adjacency: &'a Buffer,
    pub springs: &'a Buffer,
    pub triangles: &'a Buffer,
    pub contact: &'a Buffer,
    pub fill: &'a Buffer,
    pub status: &'a Buffer,
    pub tet_index: &'a Buffer,
    pub tet_rest: &'a Buffer,
}

impl ImplicitBody {
    /// Body `body` of the world whose sums are `sums`, its partials from `base` on.
    /// `penalties`: the force buffer and stiffness of each of the body's penalty contacts, in
    /// contact order.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        device: &wgpu::Device,
        kernels: &ImplicitKernels,
        n: u32,
        tets: u32,
        max_per_dim: u32,
        b: &BodyBuffers,
        penalties: &[(&Buffer, f32)],
        sums: &Sums,
        (body, base): (u32, u32),
    ) -> ImplicitBody {
        let groups = own_groups(n, max_per_dim);
        let storage = BufferUsages::STORAGE | BufferUsages::COPY_SRC | BufferUsages::COPY_DST;
        let buffer = |label, size: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size.max(16),
                usage,
                mapped_at_creation: false,
            })
        };
        let params = buffer(
            "implicit params",
            std::mem::size_of::<GpuImplicitParams>() as u64,
            BufferUsages::UNIFORM | BufferUsages::COPY_DST,
        );
        let work = buffer("implicit work", 16 * SLOTS * u64::from(n), storage);
        let tet_work = buffer("implicit tetrahedra", 16 * TET_WORK * u64::from(tets), storage);
        let groups_of = kernels
            .passes
            .iter()
            .map(|k| {
                k.bind(
                    device,
                    &[
                        b.sim,
                        &params,
                        b.pos,
                        b.vel,
                        b.info,
                        b.offsets,
                        b.adjacency,
                        b.springs,
                        b.triangles,
                        b.contact,
                        b.fill,
                        &work,
                        &sums.red,
                        b.status,
                        b.tet_index,
                        b.tet_rest,
                        &tet_work,
                    ],
                )
            })
            .collect();
        let contacts = penalties
            .iter()
            .map(|(force, stiffness)| {
                use wgpu::util::DeviceExt as _;
                let words: [u32; 4] = [n, SLOT_KC0 * n, stiffness.to_bits(), 0];
                let p = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("implicit contact params"),
                    contents: bytemuck::cast_slice(&words),
                    usage: BufferUsages::UNIFORM,
                });
                let group = kernels.contact.bind(device, &[&p, force, &work]);
                (p, group)
            })
            .collect();
        ImplicitBody { params, work, _tet_work: tet_work, n, tets, groups, base, body, groups_of, contacts }
    }

    /// Its workgroups in a pass over its vertices (its partials in each column).
    pub(crate) fn groups(&self) -> u32 {
        self.groups
    }

    fn write(&self, queue: &wgpu::Queue, p: &GpuImplicitParams) {
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(p));
    }
}

/// How one step's solve is set up for a body (host side).
pub(crate) struct Setup {
    pub h: f32,
    pub guess_scale: f32,
    pub tolerance: f32,
    pub max_iterations: u32,
}

fn params(inputs: &StepInputs, s: &Setup, body: &ImplicitBody, sums: &Sums, scale: f32) -> GpuImplicitParams {
    GpuImplicitParams {
        h: s.h,
        fill_k: if inputs.fill_volume > 0.0 { inputs.fill_bulk / inputs.fill_volume } else { 0.0 },
        guess_scale: s.guess_scale,
        tolerance: s.tolerance,
        scale,
        max_iterations: s.max_iterations as f32,
        groups: sums.groups,
        base: body.base,
        own: body.groups,
        body: body.body,
        bodies: sums.bodies,
        _pad: 0,
    }
}

/// What a body's solve reached, read back.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Solved {
    pub iterations: u32,
    pub relative_residual: f32,
    pub farthest: f32,
    pub residual: Residual,
}

/// The joint scalars, and each body's own.
fn read_scalars(ctx: &voxcollide::GpuContext, sums: &Sums) -> Result<([f32; 16], Vec<[f32; 8]>), Error> {
    let size = 4 * (SCALARS + BODY_SCALARS * u64::from(sums.bodies));
    let bytes = voxcollide::gpu::read_buffers(ctx, &[(&sums.red, size)])?;
    let words: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes[0]);
    let joint: [f32; 16] = words[..16].try_into().unwrap_or([0.0; 16]);
    let own = words[16..].chunks_exact(8).map(|c| c.try_into().unwrap_or([0.0; 8])).collect();
    Ok((joint, own))
}

/// Records `items`, each a pass of one body (`(body, pass)`), in order, in one compute pass.
/// A pass over the joint scalars is recorded once, with any body's bindings.
fn record(
    encoder: &mut wgpu::CommandEncoder,
    kernels: &ImplicitKernels,
    bodies: &[ImplicitBody],
    items: &[(usize, usize)],
    max_per_dim: u32,
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some("voxcollide implicit"),
        timestamp_writes: None,
    });
    for &(k, p) in items {
        let body = &bodies[k];
        if single(p) {
            kernels.passes[p].dispatch_one(&mut pass, &body.groups_of[p]);
        } else if per_tetrahedron(p) {
            kernels.passes[p].dispatch(&mut pass, &body.groups_of[p], body.tets, max_per_dim);
        } else {
            kernels.passes[p].dispatch(&mut pass, &body.groups_of[p], body.n, max_per_dim);
        }
    }
}

/// `passes` for every body in turn, as `(body, pass)` items.
fn each(bodies: usize, passes: impl Fn(usize) -> Vec<usize>) -> Vec<(usize, usize)> {
    (0..bodies).flat_map(|k| passes(k).into_iter().map(move |p| (k, p))).collect()
}

/// The solve of one implicit step over every body, after the collisions and the fills'
/// pressures are recorded in `encoder`: the contact stiffness, the system, one conjugate
/// gradient over every body to the joint tolerance, and the farthest move. Returns each body's
/// solve (the joint one's figures, with its own residual at rest); the update is [`finish`]'s.
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve(
    ctx: &voxcollide::GpuContext,
    mut encoder: wgpu::CommandEncoder,
    kernels: &ImplicitKernels,
    bodies: &[ImplicitBody],
    sums: &Sums,
    inputs: &[StepInputs],
    setup: &Setup,
    max_per_dim: u32,
) -> Result<Vec<Solved>, Error> {
    let queue = ctx.queue();
    for (b, inputs) in bodies.iter().zip(inputs) {
        b.write(queue, &params(inputs, setup, b, sums, 1.0));
        encoder.clear_buffer(&b.work, 16 * u64::from(SLOT_KC0) * u64::from(b.n), Some(32 * u64::from(b.n)));
    }
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("voxcollide implicit contacts"),
            timestamp_writes: None,
        });
        for b in bodies {
            for (_, group) in &b.contacts {
                kernels.contact.dispatch(&mut pass, group, b.n, max_per_dim);
            }
        }
    }
    let count = bodies.len();
    let fill = |k: usize| inputs[k].fill_volume > 0.0;
    let elements = |k: usize| bodies[k].tets > 0;
    let guessing = setup.guess_scale > 0.0;
    // Each body's system and right-hand side, then the joint start.
    let mut start = each(count, |k| {
        let mut passes = vec![PREPARE, FLOOR, SCALARS_A];
        if elements(k) {
            passes.extend([TANGENT, PRODUCT_RHS]);
        }
        passes.push(RHS);
        if guessing {
            if fill(k) {
                passes.extend([GP, SCALARS_GP]);
            }
            if elements(k) {
                passes.push(PRODUCT_X);
            }
            passes.push(GUESS);
        }
        passes
    });
    start.push((0, SCALARS_B));
    start.extend(each(count, |_| vec![START]));
    start.push((0, SCALARS_C));
    record(&mut encoder, kernels, bodies, &start, max_per_dim);
    // One iteration: each body's `A·p`, the joint `α`, each body's update, the joint `β`, each
    // body's new direction.
    let mut iteration = each(count, |k| {
        let mut p = Vec::with_capacity(4);
        if fill(k) {
            p.extend([GP, SCALARS_GP]);
        }
        if elements(k) {
            p.push(PRODUCT_P);
        }
        p.push(APPLY);
        p
    });
    iteration.push((0, SCALARS_ALPHA));
    iteration.extend(each(count, |_| vec![UPDATE]));
    iteration.push((0, SCALARS_BETA));
    iteration.extend(each(count, |_| vec![DIRECTION]));
    let batch: Vec<(usize, usize)> = (0..BATCH).flat_map(|_| iteration.iter().copied()).collect();
    let mut recorded = 0;
    loop {
        record(&mut encoder, kernels, bodies, &batch, max_per_dim);
        recorded += BATCH;
        queue.submit([encoder.finish()]);
        let (joint, _) = read_scalars(ctx, sums)?;
        encoder = ctx.device().create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("voxcollide implicit solve"),
        });
        // (The cap is the solve's own, checked on the device; this only stops the host.)
        if joint[S_DONE] != 0.0 || recorded > setup.max_iterations + BATCH {
            break;
        }
    }
    let mut far = each(count, |_| vec![FARTHEST]);
    far.push((0, SCALARS_FAR));
    record(&mut encoder, kernels, bodies, &far, max_per_dim);
    queue.submit([encoder.finish()]);
    let (joint, own) = read_scalars(ctx, sums)?;
    let relative = if joint[S_NORM_B2] > 0.0 { (joint[S_RR] / joint[S_NORM_B2]).sqrt() } else { 0.0 };
    Ok(own
        .iter()
        .map(|o| Solved {
            iterations: joint[S_ITERATIONS] as u32,
            relative_residual: relative,
            farthest: joint[S_FARTHEST],
            residual: Residual {
                net: f64::from(o[B_NET2]).sqrt(),
                gross: f64::from(o[B_GROSS2]).sqrt(),
                peak_gross: 0.0,
            },
        })
        .collect())
}

/// The update after [`solve`]: every body's velocity scaled by `scale`, then its positions,
/// modes, floor and contacts' inelastic push, in one submit.
#[allow(clippy::too_many_arguments)]
pub(crate) fn finish(
    ctx: &voxcollide::GpuContext,
    kernels: &ImplicitKernels,
    bodies: &[ImplicitBody],
    sums: &Sums,
    inputs: &[StepInputs],
    setup: &Setup,
    scale: f32,
    max_per_dim: u32,
) {
    let queue = ctx.queue();
    for (b, inputs) in bodies.iter().zip(inputs) {
        b.write(queue, &params(inputs, setup, b, sums, scale));
    }
    let mut encoder = ctx
        .device()
        .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("voxcollide implicit move") });
    record(&mut encoder, kernels, bodies, &each(bodies.len(), |_| vec![MOVE]), max_per_dim);
    queue.submit([encoder.finish()]);
}

/// Each body's [`StepStats`] from its solve, the common scale, and whether the step was taken.
pub(crate) fn stats(solved: &[Solved], scale: f32, taken: bool) -> Vec<StepStats> {
    let farthest = solved.iter().map(|s| s.farthest).fold(0.0, f32::max);
    solved
        .iter()
        .map(|s| StepStats {
            iterations: s.iterations,
            relative_residual: s.relative_residual,
            scaled: scale,
            farthest,
            taken,
        })
        .collect()
}
