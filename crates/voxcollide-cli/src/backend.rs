//! Which backend steps a run, and the device it runs on: `--backend auto|gpu|cpu`, the one
//! GPU context a command opens (and passes to every run it makes), and why `auto` chooses the
//! CPU for a world that could step on the GPU.

use voxcollide::error::Error;
use voxcollide::gpu::GpuContext;
use voxcollide_sim::{Integrator, World};

/// Which backend runs the simulation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// The GPU when an adapter (software ones included) is found, else the CPU.
    Auto,
    /// The GPU; an error without an adapter.
    Gpu,
    /// The CPU reference path.
    Cpu,
}

/// The adapter a run uses — for `backend` and whether pictures are wanted — and, when there is
/// none, why (for the summary). A fallback to the CPU is said through `note`.
///
/// # Errors
/// [`Error::NoAdapter`] for [`Backend::Gpu`] without an adapter.
pub fn context(
    backend: Backend,
    pictures: bool,
    note: &mut dyn FnMut(&str),
) -> Result<(Option<GpuContext>, String), Error> {
    let mut without = String::from("no adapter used: --backend cpu, no pictures");
    let ctx = match backend {
        Backend::Cpu if !pictures => None,
        Backend::Gpu => Some(GpuContext::new()?),
        _ => match GpuContext::new() {
            Ok(ctx) => Some(ctx),
            Err(e) => {
                note(&format!("{e}; running on the CPU and writing no pictures"));
                without = e.to_string();
                None
            }
        },
    };
    Ok((ctx, without))
}

/// Why `world` steps on the CPU under `--backend auto` though it could step on the GPU, if it
/// does: the implicit integrator, whose solve waits on the device every few iterations (on
/// lavapipe a 1,000-vertex press stepped at 59 steps/s against the CPU's 1,121), or a surface
/// contact, whose search runs on the host and makes each GPU step wait for the positions; and
/// always for a curved chest wall (an implant placed on a patient), which only the CPU holds.
/// `--backend gpu` steps every world on the device: both integrators, springs or
/// `"neo-hookean"` tetrahedra, and every contact response.
pub(crate) fn cpu_first(world: &World) -> Option<&'static str> {
    if world.bodies.iter().any(|b| b.wall.is_some()) {
        Some(
            "an implant placed on a patient's chest wall (only the CPU backend holds a curved wall and seals the pocket)",
        )
    } else if world.integrator != Integrator::Explicit {
        Some(
            "[time] integrator = \"implicit\" (its WGSL passes wait on the device every 8 iterations: --backend gpu runs them)",
        )
    } else if world.contacts.iter().any(|c| c.surface().is_some()) {
        Some(
            "contact response = \"surface\" (the default: its search runs on the host, each GPU step waiting for the positions; --backend gpu runs it)",
        )
    } else {
        None
    }
}
