//! The contacts of a [`GpuWorld`](super::GpuWorld), each by its model: the voxel model's
//! collision passes (through the embedding API, recorded into the step's encoder), or a surface
//! contact stepped wholly on the device ([`DeviceSurface`]; under the implicit integrator its
//! couplings are built from it, [`super::implicit`]). The GPU world's twin of
//! [`crate::contact::CpuContacts`].

use wgpu::Buffer;

use super::surface::DeviceSurface;
use crate::body::MassSpring;
use crate::contact::{ContactModel, ContactPair, SurfaceStats};
use voxcollide::error::Error;
use voxcollide::gpu::{GpuCollision, GpuContext};
use voxcollide::report::ContactReport;

/// A contact as a [`GpuWorld`](super::GpuWorld) steps it.
pub(super) enum DeviceContact {
    /// The voxel model's collision passes (through the embedding API).
    Voxel(Box<GpuCollision>),
    /// A surface contact stepped on the device, nothing read back.
    Device(Box<DeviceSurface>),
}

impl DeviceContact {
    /// The contact `pair` of `bodies` on `ctx`'s device.
    ///
    /// # Errors
    /// The contact errors of [`GpuCollision::new`] and [`DeviceSurface::new`]; [`Error::Gpu`]
    /// when the device refuses a buffer.
    pub(super) fn new(
        ctx: &GpuContext,
        pair: &ContactPair,
        bodies: &[MassSpring],
    ) -> Result<DeviceContact, Error> {
        match pair.model {
            ContactModel::Voxel(response) => GpuCollision::new(ctx, pair.grid, pair.params)
                .and_then(|g| g.with_response(response))
                .map(|g| DeviceContact::Voxel(Box::new(g))),
            ContactModel::Surface(penalty) => {
                DeviceSurface::new(ctx, penalty, &bodies[pair.a], &bodies[pair.b])
                    .map(|d| DeviceContact::Device(Box::new(d)))
            }
        }
    }

    /// Its surface contact, where it is one.
    pub(super) fn device_surface(&self) -> Option<&DeviceSurface> {
        match self {
            DeviceContact::Device(d) => Some(d),
            DeviceContact::Voxel(_) => None,
        }
    }

    /// Records one step of the contact into `encoder` over the bodies' position buffers (`a`,
    /// `b`: buffer and vertex count).
    ///
    /// # Errors
    /// The collision's and the search's recording errors.
    pub(super) fn record(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        queue: &wgpu::Queue,
        (a_pos, a_n): (&Buffer, u32),
        (b_pos, b_n): (&Buffer, u32),
    ) -> Result<(), Error> {
        match self {
            DeviceContact::Voxel(collision) => collision.record(encoder, a_pos, a_n, b_pos, b_n),
            DeviceContact::Device(d) => d.record(encoder, queue, a_pos, b_pos),
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
        }
    }

    /// What its surface contact found at the last read (the default for the voxel model's).
    pub(super) fn surface_stats(&self) -> SurfaceStats {
        match self {
            DeviceContact::Voxel(_) => SurfaceStats::default(),
            DeviceContact::Device(d) => d.stats(),
        }
    }

    /// The last step's report of the contact `pair` (`a_len`: its body `a`'s vertex count),
    /// read back; a surface contact's as the CPU world reports it.
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
        }
    }
}
