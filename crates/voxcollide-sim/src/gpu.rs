//! The scene stepped entirely on the GPU: the collision passes (through the embedding API) and
//! the simulation passes `forces` and `integrate` for both bodies, recorded into one encoder per
//! step, with nothing read back until a frame is wanted.

use bytemuck::{Pod, Zeroable};
use glam::Vec4;
use wgpu::{Buffer, BufferUsages};

use crate::body::{MassSpring, StepInputs};
use crate::scene::Scene;
use voxcollide::error::Error;
use voxcollide::gpu::kernel::{Kernel, Slot};
use voxcollide::gpu::{GpuCollision, GpuContext, scoped};
use voxcollide::report::ContactReport;

/// The simulation passes' WGSL, composed with `sim_common.wgsl`.
pub const SHADERS: [(&str, &str); 2] = [("forces", FORCES), ("integrate", INTEGRATE)];
/// Pass 1: forces over mass.
pub const FORCES: &str =
    concat!(include_str!("../shaders/sim_common.wgsl"), include_str!("../shaders/forces.wgsl"));
/// Pass 2: integration.
pub const INTEGRATE: &str =
    concat!(include_str!("../shaders/sim_common.wgsl"), include_str!("../shaders/integrate.wgsl"));

/// A body's step parameters. Keep in sync with `SimParams` in `shaders/sim_common.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
struct GpuSimParams {
    drive: [f32; 4],
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
    _pad: u32,
}
const _: () = assert!(std::mem::size_of::<GpuSimParams>() == 64);

/// One body's device buffers.
struct GpuBody {
    n: u32,
    tri_base: u32,
    params: Buffer,
    pos: Buffer,
    vel: Buffer,
    info: Buffer,
    offsets: Buffer,
    adjacency: Buffer,
    springs: Buffer,
    triangles: Buffer,
    acc: Buffer,
    status: Buffer,
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
        GpuBody {
            n: body.len() as u32,
            tri_base,
            params: init("sim params", &[0; 64], BufferUsages::UNIFORM | BufferUsages::COPY_DST),
            pos: init("sim pos", bytemuck::cast_slice(&pos), storage | BufferUsages::VERTEX),
            vel: init("sim vel", bytemuck::cast_slice(&vel), storage),
            info: init("sim info", bytemuck::cast_slice(&info), storage),
            offsets: init("sim offsets", bytemuck::cast_slice(&offsets), storage),
            adjacency: init("sim adjacency", bytemuck::cast_slice(&adjacency), storage),
            springs: init("sim springs", bytemuck::cast_slice(&springs), storage),
            triangles: init("sim triangles", bytemuck::cast_slice(&triangles), storage),
            acc: init("sim acc", &vec![0; 16 * body.len()], storage),
            status: init("sim status", &[0; 8], storage),
        }
    }

    fn params(&self, body: &MassSpring, inputs: &StepInputs, v_max: f32, step: u64) -> GpuSimParams {
        let m = &body.material;
        GpuSimParams {
            drive: inputs.drive.extend(0.0).to_array(),
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
            _pad: 0,
        }
    }
}

/// Bind groups of both bodies' passes (made after the first collision step, whose force buffers
/// they read).
struct Bound {
    forces: [wgpu::BindGroup; 2],
    integrate: [wgpu::BindGroup; 2],
}

/// A scene stepping on the GPU.
pub struct GpuSim {
    /// The scene. Its bodies' positions and velocities are only brought up to date by
    /// [`sync`](Self::sync).
    pub scene: Scene,
    ctx: GpuContext,
    collision: GpuCollision,
    forces: Kernel,
    integrate: Kernel,
    tissue: GpuBody,
    foreign: GpuBody,
    bound: Option<Bound>,
    max_per_dim: u32,
    step: u64,
}

impl GpuSim {
    /// Uploads `scene` to the device of `ctx`.
    ///
    /// # Errors
    /// [`Error::Gpu`] when the device rejects a pipeline or a buffer; the contact errors of
    /// [`GpuCollision::new`].
    pub fn new(ctx: &GpuContext, scene: Scene) -> Result<GpuSim, Error> {
        let device = ctx.device();
        let collision = GpuCollision::new(ctx, scene.grid, scene.params)?;
        use Slot::{Read, ReadWrite, Uniform};
        let (forces, integrate, tissue, foreign) = scoped(device, || {
            (
                Kernel::new(
                    device,
                    "voxcollide forces",
                    FORCES,
                    &[Uniform, Read, Read, Read, Read, Read, Read, Read, ReadWrite],
                ),
                Kernel::new(
                    device,
                    "voxcollide integrate",
                    INTEGRATE,
                    &[Uniform, ReadWrite, ReadWrite, Read, Read, ReadWrite],
                ),
                GpuBody::new(device, &scene.tissue),
                GpuBody::new(device, &scene.foreign),
            )
        })?;
        Ok(GpuSim {
            max_per_dim: device.limits().max_compute_workgroups_per_dimension,
            ctx: ctx.clone(),
            collision,
            forces,
            integrate,
            tissue,
            foreign,
            bound: None,
            scene,
            step: 0,
        })
    }

    /// Steps taken so far.
    #[must_use]
    pub fn steps_done(&self) -> u64 {
        self.step
    }

    /// One step, recorded into one encoder and submitted: collision (A = foreign body, B =
    /// tissue) → forces → integration. Nothing is read back.
    ///
    /// # Errors
    /// The collision's recording errors, and [`Error::Gpu`] for a validation or out-of-memory
    /// error while recording or submitting (the whole step runs inside error scopes, so such an
    /// error becomes this value instead of reaching wgpu's default handler).
    pub fn step(&mut self) -> Result<(), Error> {
        let device = self.ctx.device().clone();
        scoped(&device, || self.record_and_submit())?
    }

    fn record_and_submit(&mut self) -> Result<(), Error> {
        let device = self.ctx.device().clone();
        let queue = self.ctx.queue();
        let (in_t, in_f) = self.scene.inputs(self.step);
        let s = &self.scene;
        queue.write_buffer(
            &self.tissue.params,
            0,
            bytemuck::bytes_of(&self.tissue.params(&s.tissue, &in_t, s.v_max, self.step)),
        );
        queue.write_buffer(
            &self.foreign.params,
            0,
            bytemuck::bytes_of(&self.foreign.params(&s.foreign, &in_f, s.v_max, self.step)),
        );
        let mut encoder = device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("voxcollide sim step") });
        self.collision.record(
            &mut encoder,
            &self.foreign.pos,
            self.foreign.n,
            &self.tissue.pos,
            self.tissue.n,
        )?;
        if self.bound.is_none() {
            let (Some(force_a), Some(force_b)) =
                (self.collision.force_a_buffer(), self.collision.force_b_buffer())
            else {
                return Err(Error::Gpu {
                    message: "collision force buffers missing after a recorded step".into(),
                });
            };
            let forces = |b: &GpuBody, contact: &Buffer| {
                self.forces.bind(
                    &device,
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
                    ],
                )
            };
            let integrate = |b: &GpuBody| {
                self.integrate.bind(&device, &[&b.params, &b.pos, &b.vel, &b.info, &b.acc, &b.status])
            };
            self.bound = Some(scoped(&device, || Bound {
                forces: [forces(&self.tissue, force_b), forces(&self.foreign, force_a)],
                integrate: [integrate(&self.tissue), integrate(&self.foreign)],
            })?);
        }
        let Some(bound) = self.bound.as_ref() else { unreachable!("bound above") };
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("voxcollide sim"),
                timestamp_writes: None,
            });
            for (k, body) in [&self.tissue, &self.foreign].into_iter().enumerate() {
                self.forces.dispatch(&mut pass, &bound.forces[k], body.n, self.max_per_dim);
            }
            for (k, body) in [&self.tissue, &self.foreign].into_iter().enumerate() {
                self.integrate.dispatch(&mut pass, &bound.integrate[k], body.n, self.max_per_dim);
            }
        }
        queue.submit([encoder.finish()]);
        self.step += 1;
        Ok(())
    }

    /// Reads both bodies' positions and velocities back into [`scene`](Self::scene), checks
    /// for a blow-up, and returns the last step's contact report.
    ///
    /// # Errors
    /// [`Error::Simulation`] when a vertex blew up (naming the first step it was seen at),
    /// and the readback's device errors.
    pub fn sync(&mut self) -> Result<ContactReport, Error> {
        let report = if self.step > 0 { self.collision.read_report()? } else { ContactReport::default() };
        for (name, tissue) in [("tissue", true), ("foreign body", false)] {
            let gpu = if tissue { &self.tissue } else { &self.foreign };
            let n = gpu.n as u64;
            let bytes = voxcollide::gpu::read_buffers(
                &self.ctx,
                &[(&gpu.pos, 16 * n), (&gpu.vel, 16 * n), (&gpu.status, 8)],
            )?;
            let status: [u32; 2] = bytemuck::pod_read_unaligned(&bytes[2]);
            if status[0] != 0 {
                let what = format!("vertex {} has a non-finite position or a runaway speed", !status[1]);
                return Err(crate::cpu::blow_up(u64::from(!status[0]) + 1, name, &what, &self.scene));
            }
            let body = if tissue { &mut self.scene.tissue } else { &mut self.scene.foreign };
            let pos: Vec<Vec4> = bytemuck::pod_collect_to_vec(&bytes[0]);
            let vel: Vec<Vec4> = bytemuck::pod_collect_to_vec(&bytes[1]);
            body.pos = pos.iter().map(|p| p.truncate()).collect();
            body.vel = vel.iter().map(|v| v.truncate()).collect();
        }
        Ok(report)
    }
}
