//! Which backend steps a run, and the device it runs on: `--backend auto|gpu|cpu`, the one
//! GPU context a command opens (and passes to every run it makes), where a world steps on it
//! (`place`, for `run` and `view` alike), and why `auto` chooses the CPU for a
//! world that could step on the GPU.

use voxcollide::error::Error;
use voxcollide::gpu::GpuContext;
use voxcollide_sim::{Integrator, Simulation, World, simulation};

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
/// does: the implicit integrator, whose solve waits on the device about once a round of its
/// active set, and which no hardware GPU has yet been measured stepping (on lavapipe
/// `scenes/breast-implant.toml` stepped at 8.3 steps/s against the CPU's 92, docs/integrator.md,
/// "The surface contact on the device"); and always for a curved chest wall (an implant placed
/// on a patient), which only the CPU holds. (The explicit step's surface contact runs wholly on
/// the device, docs/contacts.md.)
/// (On a software adapter any surface contact steps on the CPU too: [`place`].)
/// `--backend gpu` steps every world on the device: both integrators, springs or
/// `"neo-hookean"` tetrahedra, and every contact response.
pub(crate) fn cpu_first(world: &World) -> Option<&'static str> {
    if world.bodies.iter().any(|b| b.wall.is_some()) {
        Some(
            "an implant placed on a patient's chest wall (only the CPU backend holds a curved wall and seals the pocket)",
        )
    } else if world.integrator != Integrator::Explicit {
        Some(
            "[time] integrator = \"implicit\" (its WGSL solve waits on the device about once a step, and steps an eleventh as fast as the CPU on lavapipe: --backend gpu runs it)",
        )
    } else {
        None
    }
}

/// Why a surface contact steps on the CPU under `--backend auto` where the adapter is a
/// software one, though its explicit step runs wholly on the device: there its two dozen
/// dispatches a step cost more than the CPU's whole step (docs/performance.md, "The surface
/// contact on a software adapter").
const SURFACE_ON_SOFTWARE: &str = "on which the surface contact steps slower than on the CPU (lavapipe stepped scenes/breast-implant.toml, made explicit, at 52 steps/s against the CPU's 1,130)";

/// What a software adapter (lavapipe, WARP) does for a command under `--backend auto`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum OnSoftware {
    /// It steps the world, as a GPU would (`run`: the paper's GPU path, shown on any adapter).
    Steps,
    /// It only draws, and the CPU steps: a software adapter draws on the cores the CPU backend
    /// steps on, and steps slower than it (`view`, whose frames compete with the steps, and
    /// `compare`, whose candidates step one per core).
    Draws,
}

/// A world placed on a backend: the simulation, which backend steps it (`"gpu"` or `"cpu"`),
/// and the adapter in words (or, when none is used, why).
pub(crate) struct Placed {
    /// The simulation.
    pub run: Box<dyn Simulation + Send>,
    /// `"gpu"` or `"cpu"`.
    pub backend: &'static str,
    /// The adapter that steps it, `pictures on …` where it only draws, or why there is none.
    pub adapter: String,
}

/// Where `world` steps for `backend`, on `ctx` (`None`: no adapter, for the reason `without`),
/// saying through `note` why `auto` keeps it on the CPU where it does.
///
/// # Errors
/// [`Error::NoAdapter`] for [`Backend::Gpu`] without an adapter, or on one without compute
/// shaders; the world's errors on the backend it steps on.
pub(crate) fn place(
    backend: Backend,
    ctx: Option<&GpuContext>,
    without: &str,
    world: World,
    software: OnSoftware,
    note: &mut dyn FnMut(&str),
) -> Result<Placed, Error> {
    let name = ctx.map(GpuContext::adapter_name);
    let computes = ctx
        .and_then(GpuContext::downlevel_flags)
        .is_none_or(|f| f.contains(wgpu::DownlevelFlags::COMPUTE_SHADERS));
    let is_software =
        ctx.and_then(GpuContext::adapter_info).is_some_and(|i| i.device_type == wgpu::DeviceType::Cpu);
    let on_gpu = match (backend, &name) {
        (Backend::Cpu, _) | (Backend::Auto, None) => false,
        (Backend::Gpu, None) => return Err(Error::NoAdapter { message: without.to_string() }),
        (Backend::Gpu, Some(name)) if !computes => {
            return Err(Error::NoAdapter { message: format!("{name} has no compute shaders to step on") });
        }
        (Backend::Gpu, Some(_)) => true,
        (Backend::Auto, Some(name)) if !computes => {
            note(&format!("{name} has no compute shaders: stepping on the CPU"));
            false
        }
        (Backend::Auto, Some(name)) if is_software && software == OnSoftware::Draws => {
            note(&format!(
                "{name} is a software adapter: stepping on the CPU, which is faster there, and drawing on it (--backend gpu steps on it)"
            ));
            false
        }
        (Backend::Auto, Some(name)) => match cpu_first(&world) {
            Some(why) => {
                note(&format!("{why} steps on the CPU, on every core (the GPU draws the pictures)"));
                false
            }
            None if is_software && world.contacts.iter().any(|c| c.surface().is_some()) => {
                note(&format!(
                    "{name} is a software adapter, {SURFACE_ON_SOFTWARE}: stepping on the CPU (--backend gpu steps on it)"
                ));
                false
            }
            None => true,
        },
    };
    Ok(if on_gpu {
        Placed { run: simulation(ctx, world)?, backend: "gpu", adapter: name.unwrap_or_default() }
    } else {
        Placed {
            run: simulation(None, world)?,
            backend: "cpu",
            adapter: name.map_or_else(|| without.to_string(), |n| format!("pictures on {n}")),
        }
    })
}
