//! The scene stepped on the GPU: the collision passes (through the embedding API) and the
//! simulation passes `forces` and `integrate` for every body, recorded into one encoder per
//! step, with nothing read back until a frame is wanted. Under the implicit integrator the step's solve is [`crate::gpu::implicit`]'s passes
//! instead, which read back a few numbers (has the solve converged, how far would a vertex
//! move) where the host must decide.
//!
//! **A surface contact** (`response = "surface"`, [`SurfaceContact`](crate::contact::SurfaceContact))
//! steps here wholly on the device ([`surface::DeviceSurface`]: each side's search through the
//! voxel model, and the passes after it, to the CPU's bits, nothing read back; a lattice made
//! from a surface shows it the surface it carries). Under the implicit integrator the device
//! builds the couplings ([`crate::integrator::implicit::Coupling`]) that join the two bodies in
//! its one solve from that search too (`implicit::Couplings`, [`crate::gpu::implicit`]), and
//! applies the inelastic impulses after the step (`shaders/couple_impulse.wgsl`, the CPU's
//! rule; docs/contacts.md, "The search on the device").

mod contact;
pub mod implicit;
pub mod surface;

use bytemuck::{Pod, Zeroable};
use glam::Vec4;
use wgpu::{Buffer, BufferUsages};

use crate::body::{MassSpring, StepInputs};
use crate::contact::SurfaceStats;
use crate::integrator::implicit::{ImplicitSettings, Residual, StepStats};
use crate::integrator::substep::{Parts, Stepper, after_implicit_step};
use crate::world::{Integrator, World};
use contact::DeviceContact;
use implicit::{BodyBuffers, CoupledPair, Couplings, ImplicitBody, ImplicitKernels, Setup, Sums};
use voxcollide::error::Error;
use voxcollide::gpu::kernel::{Kernel, Slot};
use voxcollide::gpu::{GpuContext, scoped};
use voxcollide::report::ContactReport;

/// The simulation passes' WGSL, composed with `sim_common.wgsl`.
pub const SHADERS: [(&str, &str); 4] =
    [("accumulate", ACCUMULATE), ("volume", VOLUME), ("forces", FORCES), ("integrate", INTEGRATE)];
/// Pass 1: forces over mass.
pub const FORCES: &str = concat!(
    include_str!("../../shaders/sim_common.wgsl"),
    include_str!("../../shaders/springs.wgsl"),
    include_str!("../../shaders/elements.wgsl"),
    include_str!("../../shaders/forces.wgsl")
);
/// Pass 2: integration.
pub const INTEGRATE: &str = concat!(
    include_str!("../../shaders/sim_common.wgsl"),
    include_str!("../../shaders/held.wgsl"),
    include_str!("../../shaders/integrate.wgsl")
);

/// A body's step parameters. Keep in sync with `SimParams` in `shaders/sim_common.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
struct GpuSimParams {
    drive: [f32; 4],
    /// The columns of `turn`; `turn_x[3]` is 1 where driven vertices are turned, 0 where not.
    turn_x: [f32; 4],
    turn_y: [f32; 4],
    turn_z: [f32; 4],
    dt: f32,
    rest_scale: f32,
    pressure: f32,
    floor: f32,
    damping: f32,
    spring_damping: f32,
    stiffening: f32,
    v_max: f32,
    n: u32,
    tri_base: u32,
    step: u32,
    tri_count: u32,
    fill_volume: f32,
    fill_bulk: f32,
    fill_hold: f32,
    /// The body's tetrahedra (0: springs alone), and their material (`shaders/elements.wgsl`).
    tets: u32,
    mu: f32,
    lambda: f32,
    alpha: f32,
    _pad: u32,
    /// The acceleration of gravity; `gravity[3]` is 1 where there is any.
    gravity: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<GpuSimParams>() == 160);

/// One body's device buffers.
struct GpuBody {
    n: u32,
    /// Tetrahedra (0: springs alone).
    tets: u32,
    tri_base: u32,
    params: Buffer,
    pos: Buffer,
    vel: Buffer,
    info: Buffer,
    offsets: Buffer,
    adjacency: Buffer,
    springs: Buffer,
    triangles: Buffer,
    /// A body of finite elements' tetrahedra and their adjacency, and their rest shapes
    /// (`shaders/elements.wgsl`); 16 bytes each for springs alone.
    tet_index: Buffer,
    tet_rest: Buffer,
    /// Each vertex's share of the body's mass, which gravity pulls ([`MassSpring::mass`]).
    mass: Buffer,
    acc: Buffer,
    status: Buffer,
    /// A fill's pressure and volume, written by the `volume` pass.
    fill: Buffer,
    /// `fill` kept aside while an implicit step may be refused.
    fill_kept: Buffer,
}

impl GpuBody {
    fn new(device: &wgpu::Device, body: &MassSpring) -> GpuBody {
        use wgpu::util::DeviceExt as _;
        let init = |label: &str, bytes: &[u8], usage: BufferUsages| {
            // wgpu rejects empty buffers in bindings: pad to 16 bytes.
            let mut data = bytes.to_vec();
            data.resize(data.len().max(16), 0);
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: &data,
                usage,
            })
        };
        let storage = BufferUsages::STORAGE | BufferUsages::COPY_SRC | BufferUsages::COPY_DST;
        let pos: Vec<Vec4> = body.pos.iter().map(|p| p.extend(1.0)).collect();
        let vel: Vec<Vec4> = body.vel.iter().zip(&body.inv_mass).map(|(v, m)| v.extend(*m)).collect();
        let info: Vec<Vec4> =
            body.rest_pos.iter().zip(&body.mode).map(|(p, m)| p.extend(*m as u32 as f32)).collect();
        let offsets: Vec<[u32; 2]> =
            body.offsets.iter().zip(&body.tri_offsets).map(|(s, t)| [*s, *t]).collect();
        let mut adjacency: Vec<u32> = body.adjacency.iter().flatten().copied().collect();
        let tri_base = adjacency.len() as u32;
        adjacency.extend(&body.tri_adjacency);
        let springs: Vec<[f32; 2]> = body.springs.iter().map(|s| [s.rest, s.k]).collect();
        let triangles: Vec<[u32; 4]> = body.surface.triangles.iter().map(|t| [t[0], t[1], t[2], 0]).collect();
        let (tet_index, tet_rest) = body.elements.as_ref().map_or_else(Default::default, |e| {
            let mut index: Vec<u32> = e.tets.iter().flatten().copied().collect();
            index.extend(&e.offsets);
            index.extend(e.adjacency.iter().map(|[k, c]| 4 * k + c));
            // Each tetrahedron's weight (its rest volume times its modulus) where the shaders
            // read its volume.
            let rest: Vec<Vec4> = e
                .dm_inv
                .iter()
                .enumerate()
                .flat_map(|(k, m)| [m.x_axis.extend(e.weight(k)), m.y_axis.extend(0.0), m.z_axis.extend(0.0)])
                .collect();
            (index, rest)
        });
        GpuBody {
            n: body.len() as u32,
            tets: body.elements.as_ref().map_or(0, |e| e.tets.len() as u32),
            tri_base,
            params: init(
                "sim params",
                &[0; std::mem::size_of::<GpuSimParams>()],
                BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            ),
            pos: init("sim pos", bytemuck::cast_slice(&pos), storage | BufferUsages::VERTEX),
            vel: init("sim vel", bytemuck::cast_slice(&vel), storage),
            info: init("sim info", bytemuck::cast_slice(&info), storage),
            offsets: init("sim offsets", bytemuck::cast_slice(&offsets), storage),
            adjacency: init("sim adjacency", bytemuck::cast_slice(&adjacency), storage),
            springs: init("sim springs", bytemuck::cast_slice(&springs), storage),
            triangles: init("sim triangles", bytemuck::cast_slice(&triangles), storage),
            tet_index: init("sim tetrahedra", bytemuck::cast_slice(&tet_index), storage),
            tet_rest: init("sim tetrahedra rest", bytemuck::cast_slice(&tet_rest), storage),
            mass: init("sim mass", bytemuck::cast_slice(&body.mass), storage),
            acc: init("sim acc", &vec![0; 16 * body.len()], storage),
            status: init("sim status", &[0; 8], storage),
            fill: init("sim fill", &[0; 16], storage),
            fill_kept: init("sim fill kept", &[0; 16], storage),
        }
    }

    fn params(&self, body: &MassSpring, inputs: &StepInputs, v_max: f32, step: u64) -> GpuSimParams {
        let m = &body.material;
        GpuSimParams {
            drive: inputs.drive.extend(0.0).to_array(),
            turn_x: inputs
                .turn
                .x_axis
                .extend(f32::from(u8::from(inputs.turn != glam::Mat3::IDENTITY)))
                .to_array(),
            turn_y: inputs.turn.y_axis.extend(0.0).to_array(),
            turn_z: inputs.turn.z_axis.extend(0.0).to_array(),
            dt: inputs.dt,
            rest_scale: inputs.rest_scale,
            pressure: inputs.pressure,
            floor: inputs.floor,
            damping: m.damping,
            spring_damping: m.spring_damping,
            stiffening: m.stiffening,
            v_max,
            n: self.n,
            tri_base: self.tri_base,
            step: step.min(u64::from(u32::MAX - 1)) as u32,
            tri_count: body.surface.triangles.len() as u32,
            fill_volume: inputs.fill_volume,
            fill_bulk: inputs.fill_bulk,
            fill_hold: inputs.fill_hold,
            tets: body.elements.as_ref().map_or(0, |e| e.tets.len() as u32),
            mu: body.elements.as_ref().map_or(0.0, |e| e.mu),
            lambda: body.elements.as_ref().map_or(0.0, |e| e.lambda),
            alpha: body.elements.as_ref().map_or(0.0, crate::material::neo_hookean::Elements::alpha),
            _pad: 0,
            gravity: inputs
                .gravity
                .extend(f32::from(u8::from(inputs.gravity != glam::Vec3::ZERO)))
                .to_array(),
        }
    }
}

/// The bind groups of a world's passes (made after the first collision step, whose force
/// buffers they read).
struct Bound {
    /// Per body with two or more contacts: one `accumulate` group per contact, in order.
    accumulate: Vec<Vec<wgpu::BindGroup>>,
    volume: Vec<wgpu::BindGroup>,
    forces: Vec<wgpu::BindGroup>,
    integrate: Vec<wgpu::BindGroup>,
}

/// Where a body's contact forces come from on the device.
enum ContactSource {
    /// No contact: a buffer of zeros.
    Zeros(Buffer),
    /// One contact: its force buffer, as it is (`(contact, as_a)`).
    One(usize, bool),
    /// Several: summed in contact order into this buffer, with one uniform per contact
    /// (`(contact, as_a, params)`).
    Sum(Buffer, Vec<(usize, bool, Buffer)>),
}

/// A world stepping on the GPU: every contact's collision passes (through the embedding API),
/// each body's contact forces summed where it has several, then `forces` and `integrate` for
/// every body — one command encoder and one submit a step, nothing read back until
/// [`sync`](Self::sync) but, where a surface contact is found on the host, its bodies'
/// positions each step (and under the implicit integrator the solve's few numbers and the
/// coupled bodies' velocities).
pub struct GpuWorld {
    /// The world. Its bodies' positions and velocities are brought up to date by
    /// [`sync`](Self::sync).
    pub world: World,
    ctx: GpuContext,
    /// Per contact, in the world's order.
    collisions: Vec<DeviceContact>,
    forces: Kernel,
    integrate: Kernel,
    accumulate: Kernel,
    volume: Kernel,
    bodies: Vec<GpuBody>,
    sources: Vec<ContactSource>,
    bound: Option<Bound>,
    max_per_dim: u32,
    step: u64,
    /// How many times the steps so far waited for the device to hand data back (mapped a
    /// buffer), frames ([`sync`](Self::sync)) excluded: docs/design.md §5's
    /// `host_waits_per_step`.
    host_waits: u64,
    /// Implicit only: the passes, and what they carry from step to step.
    implicit: Option<Implicit>,
}

/// What a [`GpuWorld`] stepping the implicit integrator keeps.
struct Implicit {
    settings: ImplicitSettings,
    kernels: ImplicitKernels,
    /// Per body, made with the bind groups (after the first collision step), and the world's
    /// sums, which make their solves one.
    bodies: Vec<ImplicitBody>,
    sums: Option<Sums>,
    /// The surface contacts' couplings (`None`: the world has none).
    couplings: Option<Couplings>,
    /// The last step's `h` (0: none yet), whose answer the next solve starts from.
    guess_h: f32,
    /// The iterations the last solve's first round took (0: none yet), which the next one's
    /// first readback waits for ([`Setup::expect`](crate::gpu::implicit::Setup)).
    last_iterations: u32,
    dt_scale: f32,
    accelerate_to: f32,
    residual: Residual,
    stats: Vec<StepStats>,
    time: f64,
    /// The steps taken in parts.
    parts: Parts,
}

/// The `accumulate` pass: one body's contact forces from several contacts.
pub const ACCUMULATE: &str =
    concat!(include_str!("../../shaders/sim_common.wgsl"), include_str!("../../shaders/accumulate.wgsl"));
/// The `volume` pass: a filled body's enclosed volume and the fill's pressure.
pub const VOLUME: &str =
    concat!(include_str!("../../shaders/sim_common.wgsl"), include_str!("../../shaders/volume.wgsl"));

impl GpuWorld {
    /// Uploads `world` to the device of `ctx`.
    ///
    /// # Errors
    /// [`Error::Gpu`] when the device rejects a pipeline or a buffer; the contact errors of
    /// [`GpuCollision::new`](voxcollide::GpuCollision::new) and [`SurfaceContact::new`](crate::contact::SurfaceContact::new); [`Error::Invalid`] for a body
    /// resting on a curved wall ([`MassSpring::wall`](crate::MassSpring)), held on the CPU only. Both integrators step here (the
    /// implicit one in [`crate::gpu::implicit`]'s passes), with every contact response.
    pub fn new(ctx: &GpuContext, world: World) -> Result<GpuWorld, Error> {
        use wgpu::util::DeviceExt as _;
        // A curved chest wall as a floor (an implant placed on a patient) is held on the CPU
        // only, so far: refused here rather than stepped through the wall.
        let on_walls: Vec<String> = (0..world.bodies.len())
            .filter(|&k| world.bodies[k].wall.is_some())
            .map(|k| world.names.get(k).map_or_else(|| k.to_string(), |n| format!("{n:?}")))
            .collect();
        if !on_walls.is_empty() {
            let (what, rest) = if on_walls.len() == 1 { ("body", "rests") } else { ("bodies", "rest") };
            return Err(Error::Invalid {
                what,
                value: on_walls.join(", "),
                rule: format!(
                    "{rest} on a curved chest wall (an implant placed on a patient, docs/design.md §15), which only the CPU backend holds so far: run it with --backend cpu"
                ),
            });
        }
        let device = ctx.device();
        // A surface contact steps on the device under either integrator; under the implicit
        // one the device builds the solve's couplings from its search too.
        let collisions = world
            .contacts
            .iter()
            .map(|c| DeviceContact::new(ctx, c, &world.bodies))
            .collect::<Result<Vec<_>, _>>()?;
        use Slot::{Read, ReadWrite, Uniform};
        let contacts_of = world.contacts_of();
        let (forces, integrate, accumulate, volume, bodies, sources) = scoped(device, || {
            let bodies: Vec<GpuBody> = world.bodies.iter().map(|b| GpuBody::new(device, b)).collect();
            let sources = contacts_of
                .iter()
                .zip(&bodies)
                .map(|(of, body)| {
                    let forces_buffer = |label| {
                        device.create_buffer(&wgpu::BufferDescriptor {
                            label: Some(label),
                            size: 16 * u64::from(body.n.max(1)),
                            usage: BufferUsages::STORAGE | BufferUsages::COPY_DST,
                            mapped_at_creation: false,
                        })
                    };
                    match of.as_slice() {
                        [] => ContactSource::Zeros(forces_buffer("sim no contact")),
                        [(c, as_a)] => ContactSource::One(*c, *as_a),
                        many => ContactSource::Sum(
                            forces_buffer("sim contact sum"),
                            many.iter()
                                .enumerate()
                                .map(|(k, &(c, as_a))| {
                                    let params =
                                        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                                            label: Some("sim accumulate params"),
                                            contents: bytemuck::cast_slice(&[
                                                body.n,
                                                u32::from(k == 0),
                                                0,
                                                0,
                                            ]),
                                            usage: BufferUsages::UNIFORM,
                                        });
                                    (c, as_a, params)
                                })
                                .collect(),
                        ),
                    }
                })
                .collect::<Vec<_>>();
            (
                Kernel::new(
                    device,
                    "voxcollide forces",
                    FORCES,
                    &[Uniform, Read, Read, Read, Read, Read, Read, Read, ReadWrite, Read, Read, Read, Read],
                ),
                Kernel::new(
                    device,
                    "voxcollide integrate",
                    INTEGRATE,
                    &[Uniform, ReadWrite, ReadWrite, Read, Read, ReadWrite],
                ),
                Kernel::new(device, "voxcollide accumulate", ACCUMULATE, &[Uniform, Read, ReadWrite]),
                Kernel::new(device, "voxcollide volume", VOLUME, &[Uniform, Read, Read, ReadWrite]),
                bodies,
                sources,
            )
        })?;
        let implicit = match world.integrator {
            Integrator::Explicit => None,
            Integrator::Implicit(settings) => Some(Implicit {
                settings,
                kernels: scoped(device, || ImplicitKernels::new(device))?,
                bodies: Vec::new(),
                sums: None,
                couplings: {
                    let pairs: Vec<CoupledPair> = world
                        .contacts
                        .iter()
                        .filter(|c| c.surface().is_some())
                        .map(|c| CoupledPair { a: c.a, b: c.b })
                        .collect();
                    let n: Vec<u32> = world.bodies.iter().map(|b| b.len() as u32).collect();
                    (!pairs.is_empty()).then(|| Couplings::new(device, pairs, &n))
                },
                guess_h: 0.0,
                last_iterations: 0,
                dt_scale: 1.0,
                accelerate_to: 1.0,
                residual: Residual { quiet: world.quiet_force(), ..Residual::default() },
                stats: vec![StepStats::default(); world.bodies.len()],
                time: 0.0,
                parts: Parts::default(),
            }),
        };
        Ok(GpuWorld {
            max_per_dim: device.limits().max_compute_workgroups_per_dimension,
            ctx: ctx.clone(),
            collisions,
            forces,
            integrate,
            accumulate,
            volume,
            bodies,
            sources,
            bound: None,
            world,
            step: 0,
            host_waits: 0,
            implicit,
        })
    }

    /// Steps taken so far.
    #[must_use]
    pub fn steps_done(&self) -> u64 {
        self.step
    }

    /// One step, recorded into one encoder and submitted: every contact's collision → contact
    /// sums → forces → integration, for every body. Nothing is read back but a surface
    /// contact's positions (and, implicit, the solve's few numbers: [`crate::gpu::implicit`]).
    ///
    /// # Errors
    /// The collisions' recording errors, and [`Error::Gpu`] for a validation or out-of-memory
    /// error while recording or submitting (the whole step runs inside error scopes, so such an
    /// error becomes this value instead of reaching wgpu's default handler).
    pub fn step(&mut self) -> Result<(), Error> {
        let device = self.ctx.device().clone();
        let before = voxcollide::gpu::host_waits();
        let result = scoped(&device, || {
            if self.implicit.is_some() {
                self.implicit_step()
            } else {
                let inputs = self.world.inputs(self.step)?;
                let encoder = self.record(&inputs)?;
                self.ctx.queue().submit([encoder.finish()]);
                self.step += 1;
                Ok(())
            }
        });
        self.host_waits += voxcollide::gpu::host_waits() - before;
        result?
    }

    /// How many times the steps so far waited for the device to hand data back to the host
    /// (a buffer mapped for reading), frames ([`sync`](Self::sync)) excluded. 0 where every
    /// step stays on the device: the explicit integrator, with any contact. The implicit solve
    /// reads its few scalars about once a round of its active set.
    #[must_use]
    pub fn host_waits(&self) -> u64 {
        self.host_waits
    }

    /// Body `body`'s positions as the device holds them: one `vec4<f32>` per vertex (xyz, in
    /// the world's lengths, the scene file's units; w 1), in a `STORAGE` buffer that every step updates in place. An app draws
    /// from it without reading it back (`voxcollide_render::DeviceMesh`, after the step's
    /// commands on the same queue); [`sync`](Self::sync) copies it into `world`. `None` past
    /// the last body.
    #[must_use]
    pub fn positions(&self, body: usize) -> Option<&wgpu::Buffer> {
        self.bodies.get(body).map(|b| &b.pos)
    }

    /// Records one step's collisions and, for every body, its contact sums, its fill's pressure
    /// and (explicit) its forces and integration; the encoder, not yet submitted.
    fn record(&mut self, inputs: &[StepInputs]) -> Result<wgpu::CommandEncoder, Error> {
        let device = self.ctx.device().clone();
        let ctx = self.ctx.clone();
        let queue = ctx.queue();
        for ((gpu, body), inputs) in self.bodies.iter().zip(&self.world.bodies).zip(inputs) {
            queue.write_buffer(
                &gpu.params,
                0,
                bytemuck::bytes_of(&gpu.params(body, inputs, self.world.v_max, self.step)),
            );
        }
        let mut encoder = device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("voxcollide sim step") });
        for (collision, pair) in self.collisions.iter_mut().zip(&self.world.contacts) {
            let (a, b) = (&self.bodies[pair.a], &self.bodies[pair.b]);
            collision.record(&mut encoder, queue, (&a.pos, a.n), (&b.pos, b.n))?;
        }
        if self.bound.is_none() {
            let (bound, implicit_bodies, sums) = self.bind(&device)?;
            self.bound = Some(bound);
            if let Some(imp) = self.implicit.as_mut() {
                imp.bodies = implicit_bodies;
                imp.sums = sums;
            }
        }
        let Some(bound) = self.bound.as_ref() else { unreachable!("bound above") };
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("voxcollide sim"),
            timestamp_writes: None,
        });
        for (groups, body) in bound.accumulate.iter().zip(&self.bodies) {
            for group in groups {
                self.accumulate.dispatch(&mut pass, group, body.n, self.max_per_dim);
            }
        }
        for (group, inputs) in bound.volume.iter().zip(inputs) {
            if inputs.fill_volume > 0.0 {
                self.volume.dispatch_one(&mut pass, group);
            }
        }
        if self.implicit.is_none() {
            for (group, body) in bound.forces.iter().zip(&self.bodies) {
                self.forces.dispatch(&mut pass, group, body.n, self.max_per_dim);
            }
            for (group, body) in bound.integrate.iter().zip(&self.bodies) {
                self.integrate.dispatch(&mut pass, group, body.n, self.max_per_dim);
            }
        }
        drop(pass);
        Ok(encoder)
    }

    /// One implicit step, whole or in parts as the CPU world takes it ([`Parts`]), and the
    /// step's growth towards rest ([`CpuWorld::accelerate`](crate::CpuWorld::accelerate)).
    fn implicit_step(&mut self) -> Result<(), Error> {
        let mut inputs = self.world.inputs(self.step)?;
        let Some(imp) = self.implicit.as_mut() else { unreachable!("implicit only") };
        inputs.iter_mut().for_each(|i| i.dt *= imp.dt_scale);
        let settling = imp.accelerate_to > 1.0;
        let settings = imp.settings.for_step(settling);
        let mut parts = std::mem::take(&mut imp.parts);
        let residual = parts.step(self, &inputs, Some(settings), settling);
        let Some(imp) = self.implicit.as_mut() else { unreachable!("implicit only") };
        imp.parts = parts;
        let residual = residual?;
        imp.dt_scale = after_implicit_step(
            &mut imp.residual,
            residual,
            imp.dt_scale,
            imp.accelerate_to,
            &imp.stats,
            &settings,
        );
        imp.time += f64::from(inputs.first().map_or(0.0, |i| i.dt));
        self.step += 1;
        Ok(())
    }

    /// Implicit only: from now on, let the step grow towards rest by up to `factor` times the
    /// schedule's (see [`CpuWorld::accelerate`](crate::CpuWorld::accelerate)); 1 returns to it.
    pub fn accelerate(&mut self, factor: f32) {
        if let Some(imp) = self.implicit.as_mut() {
            imp.accelerate_to = factor.max(1.0);
            if factor <= 1.0 {
                imp.dt_scale = 1.0;
            }
        }
    }

    /// Implicit only: the last step's residual at rest over all bodies (at its start).
    #[must_use]
    pub fn residual(&self) -> Option<Residual> {
        self.implicit.as_ref().map(|i| i.residual)
    }

    /// Implicit only: the steps taken in parts so far.
    #[must_use]
    pub fn parts(&self) -> Option<&Parts> {
        self.implicit.as_ref().map(|i| &i.parts)
    }

    /// Implicit only: the last step's solve, per body.
    #[must_use]
    pub fn stats(&self) -> Option<&[StepStats]> {
        self.implicit.as_ref().map(|i| i.stats.as_slice())
    }

    /// Simulated seconds so far under the implicit integrator, whose step grows to settle
    /// (`None`: explicit, where it is steps × the schedule's step).
    #[must_use]
    pub fn time(&self) -> Option<f64> {
        self.implicit.as_ref().map(|i| i.time)
    }

    /// The step the last step took, relative to the schedule's (1 under the explicit
    /// integrator).
    #[must_use]
    pub fn dt_scale(&self) -> f32 {
        self.implicit.as_ref().map_or(1.0, |i| i.dt_scale)
    }

    /// The bind groups, once the collisions have their force buffers.
    fn bind(&self, device: &wgpu::Device) -> Result<(Bound, Vec<ImplicitBody>, Option<Sums>), Error> {
        let force_buffer = |c: usize, as_a: bool| self.collisions[c].force_buffer(as_a);
        let mut accumulate = Vec::with_capacity(self.bodies.len());
        let mut forces = Vec::with_capacity(self.bodies.len());
        let mut integrate = Vec::with_capacity(self.bodies.len());
        let mut volume = Vec::with_capacity(self.bodies.len());
        let mut implicit_bodies = Vec::new();
        let sums = self.implicit.as_ref().map(|_| {
            let n: Vec<u32> = self.bodies.iter().map(|b| b.n).collect();
            Sums::new(device, &n, self.max_per_dim)
        });
        let mut base = 0;
        let contacts_of = self.world.contacts_of();
        for (k, b) in self.bodies.iter().enumerate() {
            let mut groups = Vec::new();
            let contact = match &self.sources[k] {
                ContactSource::Zeros(zeros) => zeros,
                ContactSource::One(c, as_a) => force_buffer(*c, *as_a)?,
                ContactSource::Sum(sum, parts) => {
                    for (c, as_a, params) in parts {
                        groups.push(self.accumulate.bind(device, &[params, force_buffer(*c, *as_a)?, sum]));
                    }
                    sum
                }
            };
            accumulate.push(groups);
            forces.push(self.forces.bind(
                device,
                &[
                    &b.params,
                    &b.pos,
                    &b.vel,
                    contact,
                    &b.offsets,
                    &b.adjacency,
                    &b.springs,
                    &b.triangles,
                    &b.acc,
                    &b.fill,
                    &b.tet_index,
                    &b.tet_rest,
                    &b.mass,
                ],
            ));
            volume.push(self.volume.bind(device, &[&b.params, &b.pos, &b.triangles, &b.fill]));
            integrate
                .push(self.integrate.bind(device, &[&b.params, &b.pos, &b.vel, &b.info, &b.acc, &b.status]));
            if let (Some(imp), Some(sums)) = (self.implicit.as_ref(), sums.as_ref()) {
                // Each penalty contact's force on this body, and its stiffness.
                let mut penalties = Vec::new();
                for &(c, as_a) in &contacts_of[k] {
                    // (A surface contact's pushes are couplings instead.)
                    if let Some(stiffness) = self.world.contacts[c].model.voxel_stiffness() {
                        penalties.push((force_buffer(c, as_a)?, stiffness));
                    }
                }
                let buffers = BodyBuffers {
                    sim: &b.params,
                    pos: &b.pos,
                    vel: &b.vel,
                    info: &b.info,
                    offsets: &b.offsets,
                    adjacency: &b.adjacency,
                    springs: &b.springs,
                    triangles: &b.triangles,
                    contact,
                    fill: &b.fill,
                    status: &b.status,
                    tet_index: &b.tet_index,
                    tet_rest: &b.tet_rest,
                    mass: &b.mass,
                };
                let body = ImplicitBody::new(
                    device,
                    &imp.kernels,
                    b.n,
                    b.tets,
                    self.max_per_dim,
                    &buffers,
                    &penalties,
                    sums,
                    (k as u32, base),
                    imp.couplings.as_ref().is_some_and(|c| c.couples(k)),
                );
                base += body.groups();
                implicit_bodies.push(body);
            }
        }
        Ok((Bound { accumulate, volume, forces, integrate }, implicit_bodies, sums))
    }

    /// Per contact, what its surface contact found at the last step (the default for a contact
    /// of the voxel model), as [`CpuWorld::surface_stats`](crate::CpuWorld::surface_stats).
    #[must_use]
    pub fn surface_stats(&self) -> Vec<SurfaceStats> {
        self.collisions.iter().map(DeviceContact::surface_stats).collect()
    }

    /// Reads every body's positions, velocities and held fill pressure back into
    /// [`world`](Self::world), checks
    /// for a blow-up, and returns the last step's report of every contact.
    ///
    /// # Errors
    /// [`Error::Simulation`] when a vertex blew up (naming the first step it was seen at, the
    /// body and the vertex), and the readback's device errors.
    pub fn sync(&mut self) -> Result<Vec<ContactReport>, Error> {
        // The bodies first: a blow-up is named by its vertex before a contact says what it did
        // to the contact (a surface stretched past its search's reach, say).
        for (k, gpu) in self.bodies.iter().enumerate() {
            let n = u64::from(gpu.n);
            let bytes = voxcollide::gpu::read_buffers(
                &self.ctx,
                &[(&gpu.pos, 16 * n), (&gpu.vel, 16 * n), (&gpu.status, 8), (&gpu.fill, 16)],
            )?;
            let status: [u32; 2] = bytemuck::pod_read_unaligned(&bytes[2]);
            if status[0] != 0 {
                let what = format!("vertex {} has a non-finite position or a runaway speed", !status[1]);
                return Err(self.world.blow_up(u64::from(!status[0]) + 1, k, &what));
            }
            let body = &mut self.world.bodies[k];
            let pos: Vec<Vec4> = bytemuck::pod_collect_to_vec(&bytes[0]);
            let vel: Vec<Vec4> = bytemuck::pod_collect_to_vec(&bytes[1]);
            body.pos = pos.iter().map(|p| p.truncate()).collect();
            body.vel = vel.iter().map(|v| v.truncate()).collect();
            // The fill's held pressure (the volume pass's `fill[2]`), so that the body's
            // pressure reads on the CPU as it stands on the device.
            let fill: [f32; 4] = bytemuck::pod_read_unaligned(&bytes[3]);
            body.held_pressure = fill[2];
        }
        if self.step == 0 {
            return Ok(vec![ContactReport::default(); self.collisions.len()]);
        }
        self.collisions
            .iter_mut()
            .zip(&self.world.contacts)
            .map(|(c, pair)| c.read_report(pair, self.world.bodies[pair.a].len()))
            .collect()
    }
}

impl Stepper for GpuWorld {
    /// The collisions and fills recorded, the solves ([`crate::gpu::implicit`]), and the update
    /// with one scale over every body where a vertex would move farther than the largest move,
    /// or none where [`ImplicitSettings::split_far`] refuses such a step.
    fn advance(
        &mut self,
        inputs: &[StepInputs],
        implicit: Option<ImplicitSettings>,
    ) -> Result<Residual, Error> {
        let mut encoder = self.record(inputs)?;
        let (Some(settings), Some(imp)) = (implicit, self.implicit.as_mut()) else {
            self.ctx.queue().submit([encoder.finish()]);
            return Ok(Residual::default());
        };
        let h = inputs.first().map_or(0.0, |i| i.dt);
        let setup = Setup {
            h,
            guess_scale: if imp.guess_h > 0.0 { h / imp.guess_h } else { 0.0 },
            tolerance: settings.tolerance,
            max_iterations: settings.max_iterations,
            expect: imp.last_iterations,
        };
        let Some(sums) = imp.sums.as_ref() else { unreachable!("bound by record") };
        // The surface contacts' couplings: built on the device from its search, recorded after
        // it.
        let vel: Vec<&Buffer> = self.bodies.iter().map(|b| &b.vel).collect();
        let info: Vec<&Buffer> = self.bodies.iter().map(|b| &b.info).collect();
        if let Some(couplings) = imp.couplings.as_mut() {
            let surfaces: Vec<&surface::DeviceSurface> =
                self.collisions.iter().filter_map(DeviceContact::device_surface).collect();
            couplings.record_built(
                self.ctx.device(),
                self.ctx.queue(),
                &mut encoder,
                &surfaces,
                &imp.bodies,
                (&vel, &info, sums.red()),
                h,
            )?;
        }
        let solved = crate::gpu::implicit::solve(
            &self.ctx,
            encoder,
            &imp.kernels,
            &imp.bodies,
            sums,
            imp.couplings.as_ref(),
            inputs,
            &setup,
            self.max_per_dim,
        )?;
        imp.guess_h = h;
        imp.last_iterations = solved.first().map_or(0, |s| s.first_round);
        let farthest = solved.iter().map(|s| s.farthest).fold(0.0, f32::max);
        let scale = if farthest > settings.max_move { settings.max_move / farthest } else { 1.0 };
        let taken = !(settings.split_far && scale < 1.0);
        if taken {
            crate::gpu::implicit::finish(
                &self.ctx,
                &imp.kernels,
                &imp.bodies,
                sums,
                inputs,
                &setup,
                scale,
                self.max_per_dim,
            );
            // A surface contact's push is inelastic: the impulses between the pairs the solve
            // kept that separate, in coupling order, on the device (the CPU's own rule,
            // `shaders/couple_impulse.wgsl`), after the update. Only a coupling pushed now
            // can take one.
            if let Some(c) = imp.couplings.as_ref() {
                let mut encoder = self.ctx.device().create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("voxcollide implicit impulses"),
                });
                {
                    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("voxcollide implicit impulses"),
                        timestamp_writes: None,
                    });
                    c.record_impulses(&mut pass);
                }
                self.ctx.queue().submit([encoder.finish()]);
            }
        }
        imp.stats = crate::gpu::implicit::stats(&solved, scale, taken);
        Ok(solved.iter().fold(Residual::default(), |r, s| r.plus(s.residual)))
    }

    fn solves(&self) -> &[StepStats] {
        self.implicit.as_ref().map_or(&[], |i| i.stats.as_slice())
    }

    /// The fills' held pressures stay on the device: copied aside.
    fn keep(&mut self) {
        let mut encoder = self.ctx.device().create_command_encoder(&Default::default());
        for b in &self.bodies {
            encoder.copy_buffer_to_buffer(&b.fill, 0, &b.fill_kept, 0, 16);
        }
        self.ctx.queue().submit([encoder.finish()]);
    }

    fn put_back(&mut self) {
        let mut encoder = self.ctx.device().create_command_encoder(&Default::default());
        for b in &self.bodies {
            encoder.copy_buffer_to_buffer(&b.fill_kept, 0, &b.fill, 0, 16);
        }
        self.ctx.queue().submit([encoder.finish()]);
    }

    fn set_solves(&mut self, stats: Vec<StepStats>) {
        if let Some(imp) = self.implicit.as_mut() {
            imp.stats = stats;
        }
    }
}
