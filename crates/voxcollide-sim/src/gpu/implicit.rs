//! The implicit integrator on the GPU (docs/design.md §12): [`crate::GpuWorld`]'s step for a world of
//! spring lattices and Neo-Hookean tetrahedra, with the voxel model's contacts or the surface
//! contact's couplings, in WGSL (`shaders/implicit_solve.wgsl` and its stems `implicit_*.wgsl`, `elements.wgsl`, `couple.wgsl`).
//!
//! Each body's step is the CPU's ([`crate::integrator::implicit`]) term by term: the same forces, the same
//! blocks of `A = M − h·D − h²·K` (springs, tetrahedra, a fill's rank-one term, each contact's
//! `k·nnᵀ` and its critical damping), the same block-Jacobi preconditioner, the conjugate
//! gradient started from the last step's answer where that leaves less to solve, the floor's
//! rows held, and the same update. The passes run without a readback except where the host
//! must decide: once per batch of [`BATCH`] iterations (has the solve converged?; the first
//! readback only after as many iterations as the last solve took, `Setup::expect`), once at the
//! end (how far would the farthest vertex move? read with the solve's last scalars), and with a
//! surface contact once per round of its active set (did the set of couplings in the gap
//! change? read with the scalars too).
//!
//! **One solve over every body**, as on the CPU: each body's passes write its own range of
//! every column of partial sums in one buffer (`red`), and the scalar passes sum every body's,
//! so `α`, `β`, the start from the last answer and the stopping test `|r| ≤ tol·|b|` are the
//! joint system's, and every body reports the joint solve in its [`StepStats`]. A fill's
//! products (`g·v`, `g·p`) and a body's residual at rest are its own.
//!
//! **A surface contact's couplings** ([`crate::integrator::implicit::Coupling`]) are built on the
//! device from its own search each step (`shaders/couple_build.wgsl`, one a probe, and
//! `shaders/couple_lists.wgsl`, each vertex's list and blocks; `Couplings::record_built`), as
//! the CPU builds them from its pushes; `shaders/couple.wgsl` takes each one's
//! `n·(Σ w·u_point − Σ w·u_partner)` of `p`, `x`, or `v` and the held `Δv`, and gathers its terms
//! per vertex into a slot that `A·p`, `b − A·x` and the right-hand side add. The solve is taken
//! again from its answer while the set of couplings it ends within the gap changes (at most four
//! rounds), and the inelastic impulses after the step run on the device in coupling order
//! (`shaders/couple_impulse.wgsl`), by the CPU's rule.
//!
//! **What differs from the CPU.** The dot products are `f32` trees per workgroup on the device,
//! `f64` chunk sums on the CPU, so the two agree to the solve's tolerance, not bit for bit. A
//! step that would carry a vertex farther than
//! [`ImplicitSettings::max_move`](crate::ImplicitSettings::max_move) is taken in parts, or
//! scaled, as on the CPU ([`crate::Parts`]).

use bytemuck::{Pod, Zeroable};
use wgpu::{Buffer, BufferUsages};

use crate::body::StepInputs;
use crate::integrator::implicit::{Residual, StepStats};
use voxcollide::error::Error;
use voxcollide::gpu::kernel::{Kernel, Slot, workgroups};
use voxcollide::gpu::scoped;

/// An implicit stem composed after what the solve's passes share (`implicit_solve.wgsl`, and the
/// laws and modes it calls).
macro_rules! implicit_stem {
    ($stem:literal) => {
        concat!(
            include_str!("../../shaders/sim_common.wgsl"),
            include_str!("../../shaders/implicit_slots.wgsl"),
            include_str!("../../shaders/springs.wgsl"),
            include_str!("../../shaders/held.wgsl"),
            include_str!("../../shaders/elements.wgsl"),
            include_str!("../../shaders/implicit_solve.wgsl"),
            include_str!(concat!("../../shaders/", $stem))
        )
    };
}
/// The per-tetrahedron passes: each tetrahedron's stiffness and products.
pub const IMPLICIT_TETRAHEDRA: &str = implicit_stem!("implicit_tetrahedra.wgsl");
/// The system's passes: forces, the floor's rows, the right-hand side and preconditioner.
pub const IMPLICIT_SYSTEM: &str = implicit_stem!("implicit_system.wgsl");
/// The conjugate gradient's per-vertex passes.
pub const IMPLICIT_CG: &str = implicit_stem!("implicit_cg.wgsl");
/// The new velocity, the farthest move and the update.
pub const IMPLICIT_MOVE: &str = implicit_stem!("implicit_move.wgsl");
/// The single-workgroup passes that sum the partials into the solve's scalars.
pub const IMPLICIT_SCALARS: &str = implicit_stem!("implicit_scalars.wgsl");
/// Each implicit stem's name, its WGSL and its entry points (the passes).
pub const IMPLICIT_STEMS: [(&str, &str, &[&str]); 5] = [
    ("implicit_tetrahedra", IMPLICIT_TETRAHEDRA, &["tangent", "product_rhs", "product_p", "product_x"]),
    ("implicit_system", IMPLICIT_SYSTEM, &["prepare", "floor_rows", "rhs"]),
    ("implicit_cg", IMPLICIT_CG, &["guess", "start", "gp", "apply", "update", "direction"]),
    ("implicit_move", IMPLICIT_MOVE, &["farthest", "advance"]),
    (
        "implicit_scalars",
        IMPLICIT_SCALARS,
        &[
            "scalars_a",
            "scalars_b",
            "scalars_c",
            "scalars_gp",
            "scalars_alpha",
            "scalars_beta",
            "scalars_far",
        ],
    ),
];
/// The couplings' passes' WGSL (a surface contact in the implicit solve).
pub const COUPLE: &str = concat!(
    include_str!("../../shaders/sim_common.wgsl"),
    include_str!("../../shaders/implicit_slots.wgsl"),
    include_str!("../../shaders/coupling.wgsl"),
    include_str!("../../shaders/couple.wgsl")
);
/// The couplings' inelastic impulses' WGSL, after the step's update.
pub const COUPLE_IMPULSE: &str = concat!(
    include_str!("../../shaders/sim_common.wgsl"),
    include_str!("../../shaders/coupling.wgsl"),
    include_str!("../../shaders/couple_impulse.wgsl")
);
/// The couplings' gather pass's WGSL.
pub const COUPLE_GATHER: &str = concat!(
    include_str!("../../shaders/sim_common.wgsl"),
    include_str!("../../shaders/implicit_slots.wgsl"),
    include_str!("../../shaders/couple_gather.wgsl")
);
/// The pass that builds a surface contact's couplings from its search on the device.
pub const COUPLE_BUILD: &str = concat!(
    include_str!("../../shaders/sim_common.wgsl"),
    include_str!("../../shaders/surface_hit.wgsl"),
    include_str!("../../shaders/carried.wgsl"),
    include_str!("../../shaders/coupling.wgsl"),
    include_str!("../../shaders/couple_build.wgsl")
);
/// The pass that lists a coupled body's couplings per vertex on the device, with their blocks.
pub const COUPLE_LISTS: &str = concat!(
    include_str!("../../shaders/sim_common.wgsl"),
    include_str!("../../shaders/implicit_slots.wgsl"),
    include_str!("../../shaders/surface_hit.wgsl"),
    include_str!("../../shaders/coupling.wgsl"),
    include_str!("../../shaders/couple_lists.wgsl")
);
/// The contact stiffness pass's WGSL.
pub const IMPLICIT_CONTACT: &str = concat!(
    include_str!("../../shaders/sim_common.wgsl"),
    include_str!("../../shaders/implicit_contact.wgsl")
);

/// Conjugate-gradient iterations recorded between two looks at whether the solves converged.
pub const BATCH: u32 = 8;

// The passes, in `PASSES`' order.
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
/// Each pass's stem and entry point, in the order above.
const PASSES: [(&str, &str); 22] = [
    (IMPLICIT_SYSTEM, "prepare"),
    (IMPLICIT_SYSTEM, "floor_rows"),
    (IMPLICIT_SYSTEM, "rhs"),
    (IMPLICIT_CG, "guess"),
    (IMPLICIT_CG, "start"),
    (IMPLICIT_CG, "gp"),
    (IMPLICIT_CG, "apply"),
    (IMPLICIT_CG, "update"),
    (IMPLICIT_CG, "direction"),
    (IMPLICIT_MOVE, "farthest"),
    (IMPLICIT_MOVE, "advance"),
    (IMPLICIT_SCALARS, "scalars_a"),
    (IMPLICIT_SCALARS, "scalars_b"),
    (IMPLICIT_SCALARS, "scalars_c"),
    (IMPLICIT_SCALARS, "scalars_gp"),
    (IMPLICIT_SCALARS, "scalars_alpha"),
    (IMPLICIT_SCALARS, "scalars_beta"),
    (IMPLICIT_SCALARS, "scalars_far"),
    (IMPLICIT_TETRAHEDRA, "tangent"),
    (IMPLICIT_TETRAHEDRA, "product_rhs"),
    (IMPLICIT_TETRAHEDRA, "product_p"),
    (IMPLICIT_TETRAHEDRA, "product_x"),
];
/// Whether each pass is one workgroup (the scalars) rather than one invocation per vertex.
const fn single(pass: usize) -> bool {
    pass >= SCALARS_A && pass <= SCALARS_FAR
}
/// Whether each pass is one invocation per tetrahedron.
const fn per_tetrahedron(pass: usize) -> bool {
    pass >= TANGENT
}
/// `vec4`s per tetrahedron in `tet_work` (`TET_WORK` in implicit_solve.wgsl).
const TET_WORK: u64 = 15;

/// Slots of per-vertex vectors in `work` (`SLOTS` in implicit_solve.wgsl); the contact stiffness's,
/// and the couplings' own blocks (`SLOT_E0`, `SLOT_E1`, written by `shaders/couple_lists.wgsl`).
const SLOTS: u64 = 18;
const SLOT_KC0: u32 = 5;
/// Columns of partials, the joint scalars and each body's own in `red`.
const COLUMNS: u64 = 8;
const SCALARS: u64 = 16;
const BODY_SCALARS: u64 = 8;
// The joint scalars read back (`S_*` in implicit_solve.wgsl).
const S_DONE: usize = 7;
const S_ITERATIONS: usize = 8;
const S_RR: usize = 5;
const S_NORM_B2: usize = 9;
const S_FARTHEST: usize = 12;
// A body's own (`B_*`).
const B_NET2: usize = 3;
const B_GROSS2: usize = 4;

/// Keep in sync with `ImplicitParams` in `shaders/implicit_solve.wgsl`.
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
    /// 1 where a surface contact couples this body.
    coupled: u32,
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
            ReadWrite, ReadWrite, Read, Read, ReadWrite, Read,
        ];
        let passes = PASSES
            .iter()
            .map(|&(stem, entry)| Kernel::entry(device, "voxcollide implicit", stem, &slots, entry))
            .collect();
        let contact =
            Kernel::new(device, "voxcollide implicit contact", IMPLICIT_CONTACT, &[Uniform, Read, ReadWrite]);
        ImplicitKernels { passes, contact }
    }
}

/// The world's buffer of partial sums and scalars (`red` in implicit_solve.wgsl), which every body's
/// passes share: one solve over every body.
pub(crate) struct Sums {
    red: Buffer,
    /// Partials per column over every body.
    groups: u32,
    bodies: u32,
}

impl Sums {
    /// The buffer of the joint and per-body scalars (and the partials).
    pub(crate) fn red(&self) -> &Buffer {
        &self.red
    }

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
    /// Whether a surface contact couples it.
    coupled: bool,
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
    pub mass: &'a Buffer,
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
        coupled: bool,
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
                        b.mass,
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
        ImplicitBody {
            params,
            work,
            _tet_work: tet_work,
            n,
            tets,
            groups,
            base,
            body,
            coupled,
            groups_of,
            contacts,
        }
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
#[derive(Clone, Copy, Debug)]
pub(crate) struct Setup {
    pub h: f32,
    pub guess_scale: f32,
    pub tolerance: f32,
    pub max_iterations: u32,
    /// The iterations the last solve's first round took (0: none yet). The first readback
    /// comes after as many, in whole batches (at least one): a solve started from the last
    /// answer takes about as many, and the iterations recorded past its end change nothing
    /// (the device stops the solve itself, `S_DONE`), so fewer readbacks give the same answer,
    /// bit for bit. A solve shorter than the last records a few iterations that do nothing
    /// but their products; on the indentation scene the waits fell from 7.2 to 4.6 a step
    /// and lavapipe stepped 1.12× faster (docs/integrator.md).
    pub expect: u32,
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
        coupled: u32::from(body.coupled),
    }
}

/// What a body's solve reached, read back.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Solved {
    pub iterations: u32,
    /// Of those, the first round's ([`Setup::expect`]).
    pub first_round: u32,
    pub relative_residual: f32,
    pub farthest: f32,
    pub residual: Residual,
}

/// What [`read_scalars`] reads: the joint scalars, each body's own, and whether the couplings'
/// `changed` flag is set.
type Scalars = ([f32; 16], Vec<[f32; 8]>, bool);

/// The joint scalars, each body's own, and, in the same readback, whether the couplings'
/// `changed` flag (when given) is set.
fn read_scalars(
    ctx: &voxcollide::GpuContext,
    sums: &Sums,
    changed: Option<&Buffer>,
) -> Result<Scalars, Error> {
    let size = 4 * (SCALARS + BODY_SCALARS * u64::from(sums.bodies));
    let mut parts = vec![(&sums.red, size)];
    parts.extend(changed.map(|c| (c, 4)));
    let bytes = voxcollide::gpu::read_buffers(ctx, &parts)?;
    let words: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes[0]);
    let joint: [f32; 16] = words[..16].try_into().unwrap_or([0.0; 16]);
    let own = words[16..].chunks_exact(8).map(|c| c.try_into().unwrap_or([0.0; 8])).collect();
    let changed = bytes.get(1).is_some_and(|b| bytemuck::pod_read_unaligned::<u32>(&b[..4]) != 0);
    Ok((joint, own, changed))
}

/// Records `items`, each a pass of one body (`(body, pass)`), in order, in one compute pass.
/// A pass over the joint scalars is recorded once, with any body's bindings; `(_, COUPLINGS +
/// mode)` records the couplings' `mode` ([`Couplings::record`]).
fn record(
    encoder: &mut wgpu::CommandEncoder,
    kernels: &ImplicitKernels,
    bodies: &[ImplicitBody],
    couplings: Option<&Couplings>,
    items: &[(usize, usize)],
    max_per_dim: u32,
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some("voxcollide implicit"),
        timestamp_writes: None,
    });
    for &(k, p) in items {
        if p >= COUPLINGS {
            if let Some(c) = couplings {
                c.record(&mut pass, p - COUPLINGS, max_per_dim);
            }
            continue;
        }
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
/// gradient over every body to the joint tolerance, and the farthest move. With `couplings`
/// (a surface contact's, built for this step), their terms join the system, and the solve is
/// repeated from its last answer while the set of couplings it ends within the gap changes, at
/// most four times, as on the CPU. Returns each body's solve (the joint one's figures, with its
/// own residual at rest); the update is [`finish`]'s.
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve(
    ctx: &voxcollide::GpuContext,
    mut encoder: wgpu::CommandEncoder,
    kernels: &ImplicitKernels,
    bodies: &[ImplicitBody],
    sums: &Sums,
    couplings: Option<&Couplings>,
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
    // (With no coupling this step the gathers still run: they clear each coupled body's slot.)
    let coupled = couplings.is_some();
    let couple = |mode: usize| -> Vec<(usize, usize)> {
        if coupled { vec![(0, COUPLINGS + mode)] } else { Vec::new() }
    };
    let fill = |k: usize| inputs[k].fill_volume > 0.0;
    let elements = |k: usize| bodies[k].tets > 0;
    // Each body's forces and start (once a step), then its right-hand side and the joint
    // start (again in each round).
    let mut start = each(count, |k| {
        let mut passes = vec![PREPARE, FLOOR, SCALARS_A];
        if elements(k) {
            passes.push(TANGENT);
        }
        passes
    });
    let round_start = |guessing: bool| -> Vec<(usize, usize)> {
        let mut items = each(count, |k| if elements(k) { vec![PRODUCT_RHS] } else { Vec::new() });
        items.extend(couple(MODE_RHS));
        items.extend(each(count, |k| {
            let mut passes = vec![RHS];
            if guessing {
                if fill(k) {
                    passes.extend([GP, SCALARS_GP]);
                }
                if elements(k) {
                    passes.push(PRODUCT_X);
                }
            }
            passes
        }));
        if guessing {
            items.extend(couple(MODE_X));
            items.extend(each(count, |_| vec![GUESS]));
        }
        items.push((0, SCALARS_B));
        items.extend(each(count, |_| vec![START]));
        items.push((0, SCALARS_C));
        items
    };
    start.extend(round_start(setup.guess_scale > 0.0));
    record(&mut encoder, kernels, bodies, couplings, &start, max_per_dim);
    // One iteration: each body's `A·p` (the couplings' terms gathered first), the joint `α`,
    // each body's update, the joint `β`, each body's new direction.
    let mut iteration = each(count, |k| {
        let mut p = Vec::with_capacity(3);
        if fill(k) {
            p.extend([GP, SCALARS_GP]);
        }
        if elements(k) {
            p.push(PRODUCT_P);
        }
        p
    });
    iteration.extend(couple(MODE_P));
    iteration.extend(each(count, |_| vec![APPLY]));
    iteration.push((0, SCALARS_ALPHA));
    iteration.extend(each(count, |_| vec![UPDATE]));
    iteration.push((0, SCALARS_BETA));
    iteration.extend(each(count, |_| vec![DIRECTION]));
    let batch: Vec<(usize, usize)> = (0..BATCH).flat_map(|_| iteration.iter().copied()).collect();
    let mut far = each(count, |_| vec![FARTHEST]);
    far.push((0, SCALARS_FAR));
    far.extend(couple(MODE_ARRIVE));
    let new_encoder = || {
        ctx.device().create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("voxcollide implicit solve"),
        })
    };
    let (mut iterations, mut round, mut first_round) = (0, 1, 0);
    let (joint, own) = loop {
        let mut recorded = 0;
        // Batches before the first readback: in the first round, as many as the last solve
        // suggests ([`Setup::expect`]).
        let mut ahead = if round == 1 { setup.expect.div_ceil(BATCH).max(1) } else { 1 };
        // The couplings the solve ends within the gap are in it, and no others: solved again,
        // from its answer, while that set changes (after the first round pairs only join).
        let recheck = couplings.filter(|_| round < 4);
        // The farthest move, and the couplings' arrival test, ride along with each readback of
        // the solve: the first reads the solve's answer and writes only its own scratch, and
        // the second waits on the device for the solve to be done (`couple.wgsl`), so that a
        // round waits once for all three.
        let (joint, own, changed) = loop {
            for _ in 0..ahead {
                record(&mut encoder, kernels, bodies, couplings, &batch, max_per_dim);
                recorded += BATCH;
            }
            ahead = 1;
            record(&mut encoder, kernels, bodies, couplings, &far, max_per_dim);
            queue.submit([encoder.finish()]);
            let scalars = read_scalars(ctx, sums, recheck.map(|c| &c.changed))?;
            encoder = new_encoder();
            // (The cap is the solve's own, checked on the device; this only stops the host.)
            if scalars.0[S_DONE] != 0.0 || recorded > setup.max_iterations + BATCH {
                break scalars;
            }
        };
        iterations += joint[S_ITERATIONS] as u32;
        if round == 1 {
            first_round = joint[S_ITERATIONS] as u32;
        }
        let Some(c) = recheck.filter(|_| changed) else { break (joint, own) };
        round += 1;
        c.set_round(queue, round);
        // `gp` reads x while S_DONE is negative (the guess's g·x), as at the start.
        queue.write_buffer(&sums.red, 4 * S_DONE as u64, bytemuck::bytes_of(&-1.0f32));
        let again = Setup { guess_scale: 1.0, ..*setup };
        for (b, inputs) in bodies.iter().zip(inputs) {
            b.write(queue, &params(inputs, &again, b, sums, 1.0));
        }
        record(&mut encoder, kernels, bodies, couplings, &round_start(true), max_per_dim);
    };
    let relative = if joint[S_NORM_B2] > 0.0 { (joint[S_RR] / joint[S_NORM_B2]).sqrt() } else { 0.0 };
    Ok(own
        .iter()
        .zip(inputs)
        .map(|(o, i)| (o, i.gravity != glam::Vec3::ZERO))
        .map(|(o, weighed)| Solved {
            iterations,
            first_round,
            relative_residual: relative,
            farthest: joint[S_FARTHEST],
            residual: Residual {
                net: f64::from(o[B_NET2]).sqrt(),
                gross: f64::from(o[B_GROSS2]).sqrt(),
                peak_gross: 0.0,
                quiet: 0.0,
                weighed,
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
    record(&mut encoder, kernels, bodies, None, &each(bodies.len(), |_| vec![MOVE]), max_per_dim);
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

/// Keep in sync with `RelativeParams` in `shaders/coupling.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
struct RelativeParams {
    h: f32,
    round: u32,
    first: u32,
    count: u32,
    n_a: u32,
    n_b: u32,
    _pad: [u32; 2],
}

// The couplings' modes (`MODE_*` in couple.wgsl). A solve's item `(_, COUPLINGS + mode)` records
// the mode's pass over every surface contact, then the gather over every coupled body.
const MODE_P: usize = 0;
const MODE_X: usize = 1;
const MODE_RHS: usize = 2;
const MODE_ARRIVE: usize = 3;
const COUPLINGS: usize = 100;

/// A surface contact's bodies, `a` and `b`, as the couplings' passes see them.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CoupledPair {
    pub a: usize,
    pub b: usize,
}

/// `Build` in `shaders/couple_build.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct GpuBuild {
    n_probes: u32,
    first: u32,
    of_a: u32,
    stiffness: f32,
    stride: u32,
    probe_n: u32,
    partner_n: u32,
    carries: u32,
}

/// `Lists` in `shaders/couple_lists.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct GpuLists {
    n: u32,
    own_first: u32,
    own: u32,
    other: u32,
    starts_at: u32,
    keys_at: u32,
    h: f32,
    carried: u32,
    after: u32,
    _pad: [u32; 3],
}

/// Couplings built on the device from its own search of the surface contacts
/// ([`Couplings::record_built`]): per contact its two sides' build passes, per coupled body
/// its lists passes (`count`, `scan`, `fill`), bound once.
struct OnDevice {
    build: Kernel,
    lists: [Kernel; 3],
    /// Per contact and side (`b` probing `a`, then `a` probing `b`): the build's group.
    build_groups: Vec<([GpuBuild; 2], [wgpu::BindGroup; 2])>,
    /// Per coupled body (as `gathers`) and per surface contact of it, in contact order: the
    /// lists' uniform, its values and its groups.
    lists_groups: Vec<Vec<(Buffer, GpuLists, [wgpu::BindGroup; 3])>>,
}

/// Entries a coupling built on the device: a vertex and a triangle's three corners, or, where
/// a body carries a surface, a point's up to 8 corners and three points' up to 24.
const STRIDE_OWN: u32 = 4;
const STRIDE_CARRIED: u32 = 32;

/// One coupled body's gather: its lists of (coupling, ±weight) per vertex.
struct Gather {
    body: usize,
    n: u32,
    params: Buffer,
    offsets: Buffer,
    items: Buffer,
    items_capacity: u64,
}

/// The surface contacts' couplings in the device's implicit solve (`shaders/couple.wgsl`): the
/// device builds them each step from the contacts' search there
/// ([`record_built`](Self::record_built); [`crate::integrator::implicit::Coupling`], as the CPU
/// builds them from its pushes); the passes add their terms to `A·p`, `A·x` and the right-hand
/// side, and mark which the solve ends within the gap.
pub(crate) struct Couplings {
    relative: Vec<Kernel>,
    gather: Kernel,
    /// The inelastic impulses after the update, and per contact its bind group.
    impulse: Kernel,
    impulse_groups: Vec<wgpu::BindGroup>,
    pairs: Vec<CoupledPair>,
    /// Per contact: its parameters, and per mode its bind group.
    params: Vec<Buffer>,
    relative_groups: Vec<Vec<wgpu::BindGroup>>,
    gathers: Vec<Gather>,
    gather_groups: Vec<wgpu::BindGroup>,
    couplings: Buffer,
    entries: Buffer,
    push: Buffer,
    active: Buffer,
    changed: Buffer,
    /// This step's: per contact its first coupling and count, and the couplings.
    ranges: Vec<(u32, u32)>,
    h: f32,
    bound: bool,
    /// Its build's passes, once bound.
    on_device: Option<OnDevice>,
}

fn storage_buffer(device: &wgpu::Device, label: &'static str, size: u64) -> Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size.max(16),
        usage: BufferUsages::STORAGE | BufferUsages::COPY_SRC | BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

impl Couplings {
    /// The couplings of the surface contacts `pairs` over bodies of `n` vertices each, built on
    /// the device from its own search ([`record_built`](Self::record_built)).
    pub(crate) fn new(device: &wgpu::Device, pairs: Vec<CoupledPair>, n: &[u32]) -> Couplings {
        use Slot::{Read, ReadWrite, Uniform};
        let relative = (0..4)
            .map(|mode| {
                Kernel::with_constants(
                    device,
                    "voxcollide couplings",
                    COUPLE,
                    &[Uniform, Read, Read, Read, Read, Read, Read, ReadWrite, ReadWrite, ReadWrite, Read],
                    &[("MODE", f64::from(mode))],
                )
            })
            .collect();
        let gather = Kernel::new(
            device,
            "voxcollide coupling gather",
            COUPLE_GATHER,
            &[Uniform, Read, Read, Read, ReadWrite],
        );
        let uniform = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 32,
                usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let params = pairs.iter().map(|_| uniform("coupling params")).collect();
        let mut coupled: Vec<usize> = pairs.iter().flat_map(|p| [p.a, p.b]).collect();
        coupled.sort_unstable();
        coupled.dedup();
        let gathers = coupled
            .into_iter()
            .map(|body| {
                use wgpu::util::DeviceExt as _;
                let n = n[body];
                Gather {
                    body,
                    n,
                    params: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("coupling gather params"),
                        contents: bytemuck::cast_slice(&[n, 0, 0, 0]),
                        usage: BufferUsages::UNIFORM,
                    }),
                    offsets: storage_buffer(device, "coupling gather offsets", 4 * (u64::from(n) + 1)),
                    items: storage_buffer(device, "coupling gather items", 16),
                    items_capacity: 2,
                }
            })
            .collect();
        let impulse = Kernel::new(
            device,
            "voxcollide coupling impulses",
            COUPLE_IMPULSE,
            &[Uniform, Read, Read, Read, Read, Read, ReadWrite, ReadWrite],
        );
        Couplings {
            relative,
            gather,
            impulse,
            impulse_groups: Vec::new(),
            pairs,
            params,
            relative_groups: Vec::new(),
            gathers,
            gather_groups: Vec::new(),
            couplings: storage_buffer(device, "couplings", 48),
            entries: storage_buffer(device, "coupling entries", 8),
            push: storage_buffer(device, "coupling pushes", 16),
            active: storage_buffer(device, "coupling flags", 4),
            changed: storage_buffer(device, "couplings changed", 4),
            ranges: Vec::new(),
            h: 0.0,
            bound: false,
            on_device: None,
        }
    }

    /// Records this step's couplings built on the device into `encoder`, after the contacts'
    /// searches (`surfaces`, one per pair, [`DeviceSurface`](crate::gpu::surface::DeviceSurface)):
    /// each probe's coupling (`shaders/couple_build.wgsl`), then each coupled body's lists of
    /// them and their blocks (`shaders/couple_lists.wgsl`, a body's contacts in order), at step
    /// `h`. Nothing is uploaded but the step's `h`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn record_built(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        surfaces: &[&crate::gpu::surface::DeviceSurface],
        implicit: &[ImplicitBody],
        (vel, info, red): (&[&Buffer], &[&Buffer], &Buffer),
        h: f32,
    ) -> Result<(), Error> {
        self.h = h;
        if self.on_device.is_none() {
            // (A device that refuses the room is an error, not a panic.)
            let made =
                scoped(device, || self.make_on_device(device, surfaces, implicit, (vel, info, red), h))?;
            self.on_device = Some(made);
        }
        let Some(d) = self.on_device.as_ref() else { unreachable!("made above") };
        for (params, values, _) in d.lists_groups.iter().flatten() {
            queue.write_buffer(params, 0, bytemuck::bytes_of(&GpuLists { h, ..*values }));
        }
        self.set_round(queue, 1);
        let max_per_dim = device.limits().max_compute_workgroups_per_dimension;
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("voxcollide coupling build"),
            timestamp_writes: None,
        });
        for (params, groups) in &d.build_groups {
            for (p, group) in params.iter().zip(groups) {
                d.build.dispatch(&mut pass, group, p.n_probes, max_per_dim);
            }
        }
        // Per coupled body: each of its contacts' counts, one scan, each contact's lists.
        for contacts in &d.lists_groups {
            for (_, values, [count, _, _]) in contacts {
                d.lists[0].dispatch(&mut pass, count, values.n, max_per_dim);
            }
            if let Some((_, _, [_, scan, _])) = contacts.first() {
                d.lists[1].dispatch_one(&mut pass, scan);
            }
            for (_, values, [_, _, fill]) in contacts {
                d.lists[2].dispatch(&mut pass, fill, values.n, max_per_dim);
            }
        }
        Ok(())
    }

    /// The room for every probe's coupling and each coupled body's lists, and the build's and
    /// the lists' passes bound over it ([`record_built`](Self::record_built), once).
    fn make_on_device(
        &mut self,
        device: &wgpu::Device,
        surfaces: &[&crate::gpu::surface::DeviceSurface],
        implicit: &[ImplicitBody],
        (vel, info, red): (&[&Buffer], &[&Buffer], &Buffer),
        h: f32,
    ) -> OnDevice {
        use Slot::{Read, ReadWrite, Uniform};
        // Every probe's coupling, every step: the room is known once. Side 0 is b's points
        // probing a's surface, side 1 a's probing b's.
        let sides: Vec<[crate::gpu::surface::SideLists<'_>; 2]> =
            surfaces.iter().map(|s| [s.side_lists(0), s.side_lists(1)]).collect();
        let carries = sides.iter().flatten().any(|s| s.probe.1.is_some() || s.partner.1.is_some());
        let stride = if carries { STRIDE_CARRIED } else { STRIDE_OWN };
        self.ranges.clear();
        let mut first = 0u32;
        for [s0, s1] in &sides {
            let count = s0.n_probes + s1.n_probes;
            self.ranges.push((first, count));
            first += count;
        }
        let total = u64::from(first).max(1);
        self.couplings = storage_buffer(device, "couplings", 48 * total);
        self.entries = storage_buffer(device, "coupling entries", 8 * u64::from(stride) * total);
        self.push = storage_buffer(device, "coupling pushes", 16 * total);
        self.active = storage_buffer(device, "coupling flags", 4 * total);
        // A body's items: one a point of its points per vertex (at most 8 a carried point),
        // and up to 3 a probe of its partner (each over up to 8 vertices where it carries).
        let spread = if carries { 8 } else { 1 };
        let room: Vec<u64> = self
            .gathers
            .iter()
            .map(|g| {
                self.pairs
                    .iter()
                    .zip(&sides)
                    .filter(|(p, _)| p.a == g.body || p.b == g.body)
                    .map(|(p, sides)| {
                        // The side where this body probes, and the other.
                        let (own, other) =
                            if p.b == g.body { (&sides[0], &sides[1]) } else { (&sides[1], &sides[0]) };
                        spread * (u64::from(own.n_probes) + 3 * u64::from(other.n_probes))
                    })
                    .sum::<u64>()
            })
            .collect();
        for (g, room) in self.gathers.iter_mut().zip(room) {
            g.items_capacity = room.max(1);
            g.items = storage_buffer(device, "coupling gather items", 8 * g.items_capacity);
        }
        self.bind(device, implicit, (vel, info, red));
        let build = Kernel::new(
            device,
            "voxcollide coupling build",
            COUPLE_BUILD,
            &[Uniform, Read, Read, Read, Read, ReadWrite, ReadWrite, ReadWrite, Read, Read],
        );
        let list_slots = [Uniform, Read, Read, Read, ReadWrite, ReadWrite, ReadWrite, Read, ReadWrite];
        let lists = ["count", "scan", "fill"].map(|entry| {
            Kernel::entry(device, "voxcollide coupling lists", COUPLE_LISTS, &list_slots, entry)
        });
        let uniform = |label: &str, bytes: &[u8]| {
            use wgpu::util::DeviceExt as _;
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            })
        };
        // Where a body carries no surface, its carried points' binding is a placeholder.
        let none = storage_buffer(device, "no carried points", 80);
        let build_groups = self
            .pairs
            .iter()
            .zip(&self.ranges)
            .zip(&sides)
            .map(|((p, &(first, _)), sides)| {
                let firsts = [first, first + sides[0].n_probes];
                let (probes, partners) = ([p.b, p.a], [p.a, p.b]);
                let params: [GpuBuild; 2] = std::array::from_fn(|s| {
                    let side = &sides[s];
                    GpuBuild {
                        n_probes: side.n_probes,
                        first: firsts[s],
                        of_a: s as u32,
                        stiffness: side.stiffness,
                        stride,
                        probe_n: side.probe.0,
                        partner_n: side.partner.0,
                        carries: u32::from(side.probe.1.is_some())
                            | (u32::from(side.partner.1.is_some()) << 1),
                    }
                });
                let groups = std::array::from_fn(|s| {
                    let side = &sides[s];
                    let params = uniform("coupling build", bytemuck::bytes_of(&params[s]));
                    build.bind(
                        device,
                        &[
                            &params,
                            side.hits,
                            side.topology,
                            vel[probes[s]],
                            vel[partners[s]],
                            &self.couplings,
                            &self.entries,
                            &self.active,
                            side.probe.1.unwrap_or(&none),
                            side.partner.1.unwrap_or(&none),
                        ],
                    )
                });
                (params, groups)
            })
            .collect();
        let lists_groups = self
            .gathers
            .iter()
            .map(|g| {
                // Per vertex, how far the contacts before have filled its list.
                let cursor = storage_buffer(device, "coupling lists cursor", 4 * u64::from(g.n));
                self.pairs
                    .iter()
                    .enumerate()
                    .filter(|(_, p)| p.a == g.body || p.b == g.body)
                    .enumerate()
                    .map(|(nth, (c, p))| {
                        let first = self.ranges[c].0;
                        let is_b = p.b == g.body;
                        // Its partner's probes on its surface: the side where it is the
                        // partner (side 0 for a, side 1 for b).
                        let other = &sides[c][usize::from(is_b)];
                        let values = GpuLists {
                            n: g.n,
                            own_first: u32::from(is_b),
                            own: if is_b { first } else { first + sides[c][0].n_probes },
                            other: if is_b { first + sides[c][0].n_probes } else { first },
                            starts_at: other.starts_at,
                            keys_at: other.keys_at,
                            h,
                            carried: u32::from(other.partner.1.is_some()),
                            after: u32::from(nth > 0),
                            _pad: [0; 3],
                        };
                        let params = uniform("coupling lists", bytemuck::bytes_of(&values));
                        let buffers = [
                            &params,
                            other.hits,
                            other.scratch,
                            &self.couplings,
                            &g.offsets,
                            &g.items,
                            &implicit[g.body].work,
                            other.partner_points,
                            &cursor,
                        ];
                        let groups = lists.each_ref().map(|k| k.bind(device, &buffers));
                        (params, values, groups)
                    })
                    .collect()
            })
            .collect();
        OnDevice { build, lists, build_groups, lists_groups }
    }

    /// Whether `body` is coupled.
    pub(crate) fn couples(&self, body: usize) -> bool {
        self.gathers.iter().any(|g| g.body == body)
    }

    fn bind(
        &mut self,
        device: &wgpu::Device,
        implicit: &[ImplicitBody],
        (vel, info, red): (&[&Buffer], &[&Buffer], &Buffer),
    ) {
        self.relative_groups = self
            .pairs
            .iter()
            .zip(&self.params)
            .map(|(p, params)| {
                self.relative
                    .iter()
                    .map(|k| {
                        k.bind(
                            device,
                            &[
                                params,
                                &self.couplings,
                                &self.entries,
                                &implicit[p.a].work,
                                &implicit[p.b].work,
                                vel[p.a],
                                vel[p.b],
                                &self.push,
                                &self.active,
                                &self.changed,
                                red,
                            ],
                        )
                    })
                    .collect()
            })
            .collect();
        self.impulse_groups = self
            .pairs
            .iter()
            .zip(&self.params)
            .map(|(p, params)| {
                self.impulse.bind(
                    device,
                    &[
                        params,
                        &self.couplings,
                        &self.entries,
                        info[p.a],
                        info[p.b],
                        &self.active,
                        vel[p.a],
                        vel[p.b],
                    ],
                )
            })
            .collect();
        self.gather_groups = self
            .gathers
            .iter()
            .map(|g| {
                self.gather
                    .bind(device, &[&g.params, &self.push, &g.offsets, &g.items, &implicit[g.body].work])
            })
            .collect();
        self.bound = true;
    }

    /// Sets the solve's round for the arrival test (and clears the "changed" word).
    fn set_round(&self, queue: &wgpu::Queue, round: u32) {
        for ((p, &(first, count)), params) in self.pairs.iter().zip(&self.ranges).zip(&self.params) {
            let n = |k: usize| self.gathers.iter().find(|g| g.body == k).map_or(0, |g| g.n);
            let r = RelativeParams { h: self.h, round, first, count, n_a: n(p.a), n_b: n(p.b), _pad: [0; 2] };
            queue.write_buffer(params, 0, bytemuck::bytes_of(&r));
        }
        queue.write_buffer(&self.changed, 0, bytemuck::bytes_of(&0u32));
    }

    /// Records `mode`'s pass over every contact's couplings, then (but for the arrival test)
    /// the gather over every coupled body.
    fn record(&self, pass: &mut wgpu::ComputePass<'_>, mode: usize, max_per_dim: u32) {
        for (groups, &(_, count)) in self.relative_groups.iter().zip(&self.ranges) {
            self.relative[mode].dispatch(pass, &groups[mode], count, max_per_dim);
        }
        if mode != MODE_ARRIVE {
            for (g, group) in self.gathers.iter().zip(&self.gather_groups) {
                self.gather.dispatch(pass, group, g.n, max_per_dim);
            }
        }
    }

    /// Records the inelastic impulses of the couplings pushed now that the solve kept
    /// (`shaders/couple_impulse.wgsl`, the CPU's `inelastic_impulses`): each contact's in one
    /// invocation, in coupling order, the contacts in order. Nothing is read back.
    pub(crate) fn record_impulses(&self, pass: &mut wgpu::ComputePass<'_>) {
        for (group, &(_, count)) in self.impulse_groups.iter().zip(&self.ranges) {
            if count > 0 {
                self.impulse.dispatch_one(pass, group);
            }
        }
    }
}
