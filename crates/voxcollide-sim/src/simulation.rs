//! One seam over the CPU and the GPU: [`Simulation`], what a caller needs of a world that
//! steps, whichever backend steps it. [`crate::CpuWorld`] and [`crate::GpuWorld`] implement
//! it, so that a run loop, a live view or an app holds a `Box<dyn Simulation>` and never
//! matches on the backend.

use voxcollide::error::Error;
use voxcollide::gpu::GpuContext;
use voxcollide::report::ContactReport;

use crate::cpu::CpuWorld;
use crate::gpu::GpuWorld;
use crate::integrator::implicit::Residual;
use crate::integrator::substep::Parts;
use crate::world::{Integrator, World};

/// A world that steps, on the CPU or a GPU.
pub trait Simulation {
    /// One step of every body and contact.
    ///
    /// # Errors
    /// The collisions' errors, [`Error::Simulation`] when a vertex blows up, and (on a GPU)
    /// [`Error::Gpu`] for a device error.
    fn step(&mut self) -> Result<(), Error>;

    /// Steps taken so far.
    fn steps_done(&self) -> u64;

    /// The world as it was built, or as the last [`frame`](Self::frame) left it: on the CPU
    /// its bodies are always current; on a GPU they are current only after a frame.
    fn world(&self) -> &World;

    /// The world as it is now (read back from the device where it lives there), and the last
    /// step's report of every contact.
    ///
    /// # Errors
    /// On a GPU, [`Error::Simulation`] when a vertex blew up, and the readback's device errors.
    fn frame(&mut self) -> Result<(&World, Vec<ContactReport>), Error>;

    /// Simulated seconds so far where the step varies (the implicit integrator, whose step
    /// grows to settle); `None` where every step is the schedule's (explicit).
    fn time(&self) -> Option<f64>;

    /// Implicit only: from now on, let the step grow towards rest by up to `factor` times the
    /// schedule's; 1 returns to it. Nothing under the explicit integrator.
    fn accelerate(&mut self, factor: f32);

    /// Implicit only: the last step's residual at rest over all bodies (at its start).
    fn residual(&self) -> Option<Residual>;

    /// Implicit only, where the backend measures it: how finely the positions resolve the
    /// residual at rest ([`CpuWorld::residual_floor`]).
    fn residual_floor(&self) -> Option<f64>;

    /// Implicit only: the steps taken in parts so far.
    fn parts(&self) -> Option<&Parts>;

    /// How many times the steps so far waited for the device to hand data back to the host,
    /// frames excluded (docs/design.md §5); `None` on the CPU, where nothing lives on a device.
    fn host_waits(&self) -> Option<u64>;

    /// Which backend steps it, in words (for summaries and messages).
    fn backend(&self) -> &'static str;

    /// On a GPU: body `body`'s positions where they live, the buffer each step updates in place
    /// ([`GpuWorld::positions`]), for drawing without reading them back; `None` on the CPU
    /// (where `world()` holds them) and past the last body.
    fn positions_buffer(&self, body: usize) -> Option<wgpu::Buffer> {
        let _ = body;
        None
    }
}

/// `world` on `ctx`'s device, or on the CPU without one.
///
/// # Errors
/// Those of [`GpuWorld::new`] and [`CpuWorld::new`].
pub fn simulation(ctx: Option<&GpuContext>, world: World) -> Result<Box<dyn Simulation + Send>, Error> {
    Ok(match ctx {
        Some(ctx) => Box::new(GpuWorld::new(ctx, world)?),
        None => Box::new(CpuWorld::new(world)?),
    })
}

impl Simulation for CpuWorld {
    fn step(&mut self) -> Result<(), Error> {
        CpuWorld::step(self)
    }

    fn steps_done(&self) -> u64 {
        CpuWorld::steps_done(self)
    }

    fn world(&self) -> &World {
        &self.world
    }

    fn frame(&mut self) -> Result<(&World, Vec<ContactReport>), Error> {
        Ok((&self.world, self.reports.clone()))
    }

    fn time(&self) -> Option<f64> {
        (self.world.integrator != Integrator::Explicit).then_some(self.time)
    }

    fn accelerate(&mut self, factor: f32) {
        CpuWorld::accelerate(self, factor);
    }

    fn residual(&self) -> Option<Residual> {
        (self.world.integrator != Integrator::Explicit).then_some(self.residual)
    }

    fn residual_floor(&self) -> Option<f64> {
        CpuWorld::residual_floor(self)
    }

    fn parts(&self) -> Option<&Parts> {
        (self.world.integrator != Integrator::Explicit).then_some(&self.parts)
    }

    fn host_waits(&self) -> Option<u64> {
        None
    }

    fn backend(&self) -> &'static str {
        "cpu"
    }
}

impl Simulation for GpuWorld {
    fn step(&mut self) -> Result<(), Error> {
        GpuWorld::step(self)
    }

    fn steps_done(&self) -> u64 {
        GpuWorld::steps_done(self)
    }

    fn world(&self) -> &World {
        &self.world
    }

    fn frame(&mut self) -> Result<(&World, Vec<ContactReport>), Error> {
        let reports = self.sync()?;
        Ok((&self.world, reports))
    }

    fn time(&self) -> Option<f64> {
        GpuWorld::time(self)
    }

    fn accelerate(&mut self, factor: f32) {
        GpuWorld::accelerate(self, factor);
    }

    fn residual(&self) -> Option<Residual> {
        GpuWorld::residual(self)
    }

    fn residual_floor(&self) -> Option<f64> {
        None
    }

    fn parts(&self) -> Option<&Parts> {
        GpuWorld::parts(self)
    }

    fn host_waits(&self) -> Option<u64> {
        Some(GpuWorld::host_waits(self))
    }

    fn backend(&self) -> &'static str {
        "gpu"
    }

    fn positions_buffer(&self, body: usize) -> Option<wgpu::Buffer> {
        self.positions(body).cloned()
    }
}
