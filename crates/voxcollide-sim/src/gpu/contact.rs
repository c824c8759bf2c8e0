//! The contacts of a [`GpuWorld`](super::GpuWorld), each by its model: the voxel model's
//! collision passes (through the embedding API, recorded into the step's encoder); a surface
//! contact stepped wholly on the device ([`DeviceSurface`]: under the implicit integrator only
//! where no body is in two surface contacts); or
//! else a surface contact found on the host, its forces (and couplings) uploaded. The GPU
//! world's twin of
//! [`crate::contact::CpuContacts`].

use glam::Vec4;
use wgpu::{Buffer, BufferUsages};

use super::surface::DeviceSurface;
use crate::body::MassSpring;
use crate::contact::{ContactModel, ContactPair, Coupling, SurfaceContact, SurfaceForces, SurfaceStats};
use voxcollide::error::Error;
use voxcollide::gpu::{GpuCollision, GpuContext, scoped};
use voxcollide::report::ContactReport;

/// A contact as a [`GpuWorld`] steps it.
pub(super) enum DeviceContact {
    /// The voxel model's collision passes (through the embedding API).
    Voxel(Box<GpuCollision>),
    /// A surface contact stepped on the device, nothing read back.
    Device(Box<DeviceSurface>),
    /// A surface contact, found on the host.
    Surface(Box<HostSurface>),
}

/// A surface contact's host side in a [`GpuWorld`]: its search over the positions read back
/// each step, and the device buffers its forces are uploaded to.
pub(super) struct HostSurface {
    contact: SurfaceContact,
    forces: SurfaceForces,
    stats: SurfaceStats,
    /// The forces on `a`'s and `b`'s vertices, as the `forces` pass reads a collision's.
    force_a: Buffer,
    force_b: Buffer,
}

impl DeviceContact {
    /// The contact `pair` of `bodies` on `ctx`'s device; a surface contact steps there whole
    /// where `on_device` (the caller's choice: always under the explicit integrator, and under
    /// the implicit one where the device builds the couplings).
    ///
    /// # Errors
    /// The contact errors of [`GpuCollision::new`] and [`SurfaceContact::new`]; [`Error::Gpu`]
    /// when the device refuses a buffer.
    pub(super) fn new(
        ctx: &GpuContext,
        pair: &ContactPair,
        bodies: &[MassSpring],
        on_device: bool,
    ) -> Result<DeviceContact, Error> {
        let device = ctx.device();
        match pair.model {
            ContactModel::Voxel(response) => GpuCollision::new(ctx, pair.grid, pair.params)
                .and_then(|g| g.with_response(response))
                .map(|g| DeviceContact::Voxel(Box::new(g))),
            ContactModel::Surface(penalty) if on_device => {
                DeviceSurface::new(ctx, penalty, &bodies[pair.a], &bodies[pair.b])
                    .map(|d| DeviceContact::Device(Box::new(d)))
            }
            ContactModel::Surface(penalty) => {
                let (a, b) = (&bodies[pair.a], &bodies[pair.b]);
                let contact = SurfaceContact::new(penalty, a, b)?;
                let buffer = |n: usize| {
                    scoped(device, || {
                        device.create_buffer(&wgpu::BufferDescriptor {
                            label: Some("sim surface contact forces"),
                            size: 16 * n.max(1) as u64,
                            usage: BufferUsages::STORAGE | BufferUsages::COPY_DST,
                            mapped_at_creation: false,
                        })
                    })
                };
                Ok(DeviceContact::Surface(Box::new(HostSurface {
                    contact,
                    forces: SurfaceForces::default(),
                    stats: SurfaceStats::default(),
                    force_a: buffer(a.len())?,
                    force_b: buffer(b.len())?,
                })))
            }
        }
    }

    /// Its surface contact stepped on the device, where it is one.
    pub(super) fn device_surface(&self) -> Option<&DeviceSurface> {
        match self {
            DeviceContact::Device(d) => Some(d),
            DeviceContact::Voxel(_) | DeviceContact::Surface(_) => None,
        }
    }

    /// Whether its search runs on the host, over the two bodies' positions read back.
    pub(super) fn on_host(&self) -> bool {
        matches!(self, DeviceContact::Surface(_))
    }

    /// Records one step of the contact into `encoder`: the voxel model's passes over the bodies'
    /// position buffers, or the surface contact's search over their positions on the host
    /// (`a`, `b`: buffer, vertex count and the body as last read back) and its forces uploaded.
    ///
    /// # Errors
    /// The collision's recording errors.
    pub(super) fn record(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        queue: &wgpu::Queue,
        (a_pos, a_n, a): (&Buffer, u32, &MassSpring),
        (b_pos, b_n, b): (&Buffer, u32, &MassSpring),
    ) -> Result<(), Error> {
        match self {
            DeviceContact::Voxel(collision) => collision.record(encoder, a_pos, a_n, b_pos, b_n),
            DeviceContact::Device(d) => d.record(encoder, queue, a_pos, b_pos),
            DeviceContact::Surface(s) => {
                s.stats = s.contact.step(a, b, &mut s.forces);
                let padded = |f: &[glam::Vec3]| -> Vec<Vec4> { f.iter().map(|f| f.extend(0.0)).collect() };
                queue.write_buffer(&s.force_a, 0, bytemuck::cast_slice(&padded(&s.forces.force_a)));
                queue.write_buffer(&s.force_b, 0, bytemuck::cast_slice(&padded(&s.forces.force_b)));
                Ok(())
            }
        }
    }

    /// The buffer of its forces on `a` (`as_a`) or on `b`, as the `forces` pass reads it.
    ///
    /// # Errors
    /// [`Error::Gpu`] where a collision has not been recorded yet.
    pub(super) fn force_buffer(&self, as_a: bool) -> Result<&Buffer, Error> {
        match self {
            DeviceContact::Voxel(collision) => {
                if as_a { collision.force_a_buffer() } else { collision.force_b_buffer() }.ok_or_else(|| {
                    Error::Gpu { message: "collision force buffers missing after a recorded step".into() }
                })
            }
            DeviceContact::Device(d) => Ok(d.force_buffer(as_a)),
            DeviceContact::Surface(s) => Ok(if as_a { &s.force_a } else { &s.force_b }),
        }
    }

    /// What its surface contact found at the last step (the default for the voxel model's).
    pub(super) fn surface_stats(&self) -> SurfaceStats {
        match self {
            DeviceContact::Voxel(_) => SurfaceStats::default(),
            DeviceContact::Device(d) => d.stats(),
            DeviceContact::Surface(s) => s.stats,
        }
    }

    /// The last step's report of the contact `pair` (`a_len`: its body `a`'s vertex count),
    /// read back for the voxel model, and as the CPU world reports it for a surface contact.
    ///
    /// # Errors
    /// The readback's device errors.
    pub(super) fn read_report(&mut self, pair: &ContactPair, a_len: usize) -> Result<ContactReport, Error> {
        match self {
            DeviceContact::Voxel(collision) => collision.read_report(),
            DeviceContact::Device(d) => {
                let (force_a, force_b, colliding_b) = d.read()?;
                Ok(ContactReport {
                    force_a,
                    force_b,
                    colliding_b,
                    binned_a: a_len as u32,
                    discarded_a: 0,
                    grid_center: pair.grid.center(),
                })
            }
            DeviceContact::Surface(s) => Ok(ContactReport {
                force_a: s.forces.force_a.clone(),
                force_b: s.forces.force_b.clone(),
                colliding_b: s.forces.touching_b.clone(),
                binned_a: a_len as u32,
                discarded_a: 0,
                grid_center: pair.grid.center(),
            }),
        }
    }

    /// A surface contact's pushes of the last step as couplings of the implicit solve (`None`
    /// for the voxel model's, whose stiffness enters per vertex).
    pub(super) fn couplings(&self, pair: &ContactPair) -> Option<Vec<Coupling>> {
        match self {
            DeviceContact::Surface(s) => Some(
                s.forces
                    .pushes
                    .iter()
                    .map(|p| Coupling::of_push(p, pair, s.contact.penalty.stiffness))
                    .collect(),
            ),
            DeviceContact::Voxel(_) | DeviceContact::Device(_) => None,
        }
    }
}
