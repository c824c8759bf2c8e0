//! Running a scene file end to end (`voxcollide run FILE.toml`): its world on the GPU or the
//! CPU, frames (PNG with every body, a VTK series per body), measurements per body and per
//! contact, an optional settling phase, and `summary.json` with docs/design.md §8's keys.
//!
//! Nothing is written when the set-up fails: the file is read, its meshes loaded and its world
//! built before the output folder is touched.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use serde::Serialize;

use crate::backend::{Backend, context, cpu_first};
use crate::output::{BodyFrame, PvdSeries};
use voxcollide::error::Error;
use voxcollide::report::ContactReport;
use voxcollide_render::{Legend, Renderer, Scene as RenderScene, SceneMesh};
use voxcollide_sim::between::volume_between;
use voxcollide_sim::build::{BodyNote, Built, build_world};
use voxcollide_sim::geometry::{ClosedSurface, Hierarchy, PenetrationWatch};
use voxcollide_sim::scene_file::{Axis, BodyKind, SceneFile};
use voxcollide_sim::{Integrator, MassSpring, Simulation, World, simulation};

/// A body in `summary.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct BodySummary {
    /// Its name in the file.
    pub name: String,
    /// `soft`, `shell` or `rigid`.
    pub kind: String,
    /// Its vertex count.
    pub vertices: usize,
    /// The largest distance of one of its vertices from where it started, over the run (file
    /// units).
    pub max_displacement: f32,
    /// For a shell: the volume it encloses at the end, in cubic file units (the only volume a
    /// scene in layer units has).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume: Option<f64>,
    /// For a shell in a scene of physical units: the volume it encloses at the end, in mL. For
    /// a body between a skin and a chest wall (docs/design.md §14): the tissue's volume at the
    /// start, in mL.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume_ml: Option<f64>,
    /// For a body between a skin and a chest wall: the tissue's volume at the end, in mL.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume_ml_end: Option<f64>,
    /// For a lattice in a surface: the fraction of the surface's volume it covers.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<f64>,
    /// What building it found worth saying.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub remarks: Vec<String>,
    /// What it is made of, as the run used it (a scene file's soft bodies and shells).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub material: Option<MaterialSummary>,
    /// For a body given as measured under gravity (`reference = { gravity }`, docs/design.md
    /// §13): how well its unloaded shape was recovered.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference: Option<ReferenceSummary>,
}

/// A landmark in `summary.json` and `compare.json` (docs/design.md §14).
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct LandmarkSummary {
    /// Its body's name.
    pub body: String,
    /// Its name.
    pub name: String,
    /// Where it started: as given, moved onto the body's outer surface.
    pub start: [f32; 3],
    /// Where the body carried it by the end.
    pub end: [f32; 3],
}

/// The recovery of a body's unloaded shape in `summary.json` (docs/design.md §13).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ReferenceSummary {
    /// The largest distance, in the file's units, between the shape given and the unloaded
    /// shape loaded again with the reference gravity.
    pub residual: f32,
    /// The fixed-point iterations taken.
    pub iterations: u32,
    /// The body's spacing (its springs' mean rest length), in the file's units.
    pub spacing: f32,
    /// Whether the residual is within a tenth of the spacing; if not, the run is not a result.
    pub valid: bool,
}

/// A body's material in `summary.json` (docs/design.md §12).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MaterialSummary {
    /// `springs` (the paper's lattice) or `neo-hookean` (tetrahedra).
    pub model: String,
    /// Young's modulus, kPa (the body's; a layer's own is in `remarks`).
    pub young_kpa: f64,
    /// The file's Poisson ratio.
    pub poisson: f64,
    /// Whether the body has that ratio: true for tetrahedra; false for springs, whose lattice
    /// has its own (1/4 for a cubic one).
    pub poisson_honoured: bool,
    /// Its tetrahedra (`neo-hookean`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tetrahedra: Option<usize>,
}

/// A contact in `summary.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ContactSummary {
    /// The indexed body's name.
    pub a: String,
    /// The probing body's name.
    pub b: String,
    /// The deepest vertex of `b` inside `a`'s closed surface, over the frames (file units).
    pub max_penetration: f32,
    /// The largest fraction of `b`'s vertices inside `a`'s surface, over the frames.
    pub penetrating_fraction: f32,
    /// `b`'s vertices in contact (the voxel model's count) at the last frame.
    pub contacts_at_end: usize,
    /// The contact's bound (docs/design.md §11): its voxel size. After first contact no vertex of `b`
    /// may be deeper inside `a` than this at any check (file units).
    pub bound: f32,
    /// The bound at rest: half of `b`'s spacing (a settled run's last frame).
    pub rest_bound: f32,
    /// Whether the contact held: within `bound` at every check after first contact, and within
    /// `rest_bound` at rest.
    pub held: bool,
    /// Where it did not hold, the output frame at (or just before) its deepest check beyond
    /// the bound, and that check's step and depth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worst_frame: Option<u32>,
    /// See `worst_frame`: the step of the deepest check.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worst_step: Option<u64>,
    /// See `worst_frame`: its depth (file units).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worst_depth: Option<f32>,
    /// Where it did not hold, a sentence saying how.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
    /// Checks of the penetration made over the run.
    pub checks: u32,
}

/// What a scene-file run did, as written to `summary.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FileSummary {
    /// The scene file's name without its extension.
    pub scenario: String,
    /// The file's length unit.
    pub units: String,
    /// `gpu` or `cpu`.
    pub backend: String,
    /// The adapter that ran it, or why there was none.
    pub adapter: String,
    /// Steps run (the schedule's, and the settling ones).
    pub steps: u64,
    /// The time step, in seconds.
    pub dt: f32,
    /// Simulated seconds.
    pub simulated_time: f64,
    /// Steps per second over the run, frames excluded.
    pub steps_per_second: f64,
    /// On the GPU only: how many times, on average, a step waited for the device to hand data
    /// back to the host (a buffer mapped for reading), frames excluded (docs/design.md §5). 0
    /// where a step stays on the device.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub host_waits_per_step: Option<f64>,
    /// Simulated seconds per wall-clock second.
    pub realtime_factor: f64,
    /// Whether the bodies came to rest (`[time] settle`: over a settling window after the
    /// schedule, no vertex that is not held moved more than [`REST_TOLERANCE`] of its body's
    /// spacing); false without settling.
    pub settled: bool,
    /// The farthest a vertex moved over the last settling window (or, without settling, the
    /// last frame), in spacings of its body: what `settled` is judged by (at rest: at most
    /// [`REST_TOLERANCE`]).
    pub rest_motion: f32,
    /// `"explicit"` or `"implicit"` (docs/design.md §12).
    pub integrator: String,
    /// The criterion for rest that `settled` was judged by: `"rest_motion"` under the explicit
    /// integrator ([`rest_motion`](Self::rest_motion) within [`REST_TOLERANCE`] over a settling
    /// window) or `"residual"` under the implicit one (the net force at rest within
    /// [`RESIDUAL_TOLERANCE`] of the gross force, [`residual`](Self::residual)); said whether or
    /// not it was met. `"stalled residual, rest_motion"`: the implicit one's residual stopped
    /// falling above that (contacts chattering at rest), and the shape was judged by motion
    /// from then on.
    pub criterion: String,
    /// The implicit integrator's residual at the end: the net force on the free vertices over
    /// the largest gross force of the run (`√Σ|f|² / max √Σ(Σ|f_term|)²`); absent under the
    /// explicit one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residual: Option<f64>,
    /// How finely the positions resolve that residual (on its scale): half the net force's
    /// change when every coordinate moves to a neighbouring `f32`, a stored position being off
    /// by at most half that (`CpuWorld::residual_floor`). A residual near it is as balanced as single precision
    /// allows, and a criterion below it cannot be met. Absent under the explicit integrator
    /// and on the GPU.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residual_floor: Option<f64>,
    /// The implicit integrator's steps taken in more than one part, because a vertex would
    /// have moved farther in one than a contact may miss (docs/integrator.md, "A step too far
    /// is split"); absent under the explicit one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub split_steps: Option<u64>,
    /// The most parts one of them was taken in.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub most_parts: Option<u32>,
    /// The settling window, in seconds: twice the time an elastic wave takes to cross the
    /// largest deformable body ([`settling_window`]).
    pub rest_window: f64,
    /// Per body.
    pub bodies: Vec<BodySummary>,
    /// Per contact.
    pub contacts: Vec<ContactSummary>,
    /// The bodies' landmarks (docs/design.md §14): where each started, on its body's outer
    /// surface, and where it ended, in the file's units.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub landmarks: Vec<LandmarkSummary>,
    /// Whether every contact held (`contacts[].held`): the run's numbers are a result only then.
    pub held: bool,
    /// Why the run's numbers are not a result, besides a contact that failed (`held`): a
    /// body whose unloaded shape was not recovered to a tenth of its spacing. Empty: nothing.
    pub not_a_result: Vec<String>,
    /// Files written, relative to the output directory.
    pub files: Vec<String>,
}

/// Where to run and what to write.
#[derive(Clone, Debug)]
pub struct FileRunConfig {
    /// The scene file.
    pub path: PathBuf,
    /// Which backend.
    pub backend: Backend,
    /// The output folder (created).
    pub out: PathBuf,
    /// Picture size, when the file asks for images.
    pub image: (u32, u32),
}

/// A world stepping on either backend (a scene file's run, a live view), through the
/// simulator's one seam.
pub(crate) type Run = Box<dyn Simulation + Send>;

/// Simulated seconds after `steps` steps of `dt`: the run's own count where its step varies
/// (the implicit integrator's, grown to settle).
pub(crate) fn simulated_time(run: &dyn Simulation, steps: u64, dt: f32) -> f64 {
    run.time().unwrap_or(steps as f64 * f64::from(dt))
}

fn io(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Io { path: path.display().to_string(), message: e.to_string() }
}

fn kind_name(kind: BodyKind) -> &'static str {
    match kind {
        BodyKind::Soft => "soft",
        BodyKind::Shell => "shell",
        BodyKind::Rigid => "rigid",
    }
}

/// Runs the scene file of `config`, calling `progress(steps_done, steps_planned)` and `note`.
///
/// # Errors
/// The scene file's, meshes' and bodies' errors before anything is written;
/// [`Error::NoAdapter`] for `Backend::Gpu` without one; [`Error::Simulation`] on a blow-up;
/// file errors.
pub fn run_file(
    config: &FileRunConfig,
    progress: &mut dyn FnMut(u64, u64),
    note: &mut dyn FnMut(&str),
) -> Result<FileSummary, Error> {
    let mut file = SceneFile::read(&config.path)?;
    crate::compare::start_placed_deflated(&mut file)?;
    let built = build_world(&file)?;
    run_scene(&file, built, config, progress, note, &mut |_, _, _| Ok(()))
}

/// Where a run is at one of its frames, for [`run_scene`]'s observer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameAt {
    /// Steps done.
    pub step: u64,
    /// Simulated time, in seconds.
    pub time: f64,
    /// Whether this is the run's last frame (the one `summary.json` describes).
    pub last: bool,
}

/// What [`run_scene`] calls at each frame with the world and the frame's contact reports.
pub type Observer<'a> = dyn FnMut(&World, &[ContactReport], FrameAt) -> Result<(), Error> + 'a;

/// [`run_file`] on a scene already read (`config.path` names it) and built from it, calling
/// `observe` with the world and the contact reports at every frame (the scene's `frames` over
/// the schedule, then one a settling window apart while it settles), the last one before
/// `summary.json` is written.
///
/// # Errors
/// As [`run_file`], and `observe`'s.
pub fn run_scene(
    file: &SceneFile,
    built: Built,
    config: &FileRunConfig,
    progress: &mut dyn FnMut(u64, u64),
    note: &mut dyn FnMut(&str),
    observe: &mut Observer<'_>,
) -> Result<FileSummary, Error> {
    let (ctx, without) = context(config.backend, file.output.images, note)?;
    run_scene_on(ctx.as_ref(), &without, file, built, config, progress, note, observe)
}

/// [`run_scene`] on the caller's device (`ctx`; `None`: no adapter, for the reason `without`),
/// so that a command running many scenes (`compare`) opens one. `config.backend` still says
/// where the world steps; `ctx` draws the pictures.
///
/// # Errors
/// As [`run_scene`]; [`Error::NoAdapter`] for `Backend::Gpu` without `ctx`.
#[allow(clippy::too_many_arguments)]
pub fn run_scene_on(
    ctx: Option<&voxcollide::GpuContext>,
    without: &str,
    file: &SceneFile,
    built: Built,
    config: &FileRunConfig,
    progress: &mut dyn FnMut(u64, u64),
    note: &mut dyn FnMut(&str),
    observe: &mut Observer<'_>,
) -> Result<FileSummary, Error> {
    let mut not_a_result = Vec::new();
    for n in &built.notes {
        for r in &n.remarks {
            note(&format!("{}: {r}", n.name));
        }
        if let Some(r) = n.reference {
            let units = file.units.symbol();
            let said = format!(
                "{}: its unloaded shape, recovered from the shape given under the reference gravity in {} iterations ({} solve steps): loaded again, it misses the shape given by {:.3} {units} at most (spacing {:.3} {units})",
                n.name, r.iterations, r.solve_steps, r.residual, r.spacing
            );
            if r.is_valid() {
                note(&said);
            } else {
                let why = format!(
                    "{}: its unloaded shape was not recovered: loaded again it misses the shape given by {:.3} {units}, more than a tenth of its spacing {:.3} {units}",
                    n.name, r.residual, r.spacing
                );
                note(&format!("warning: {said}; the run is not a result"));
                not_a_result.push(why);
            }
        }
    }
    if config.backend == Backend::Gpu && ctx.is_none() {
        return Err(Error::NoAdapter { message: without.to_string() });
    }
    let on_cpu = if config.backend == Backend::Auto { cpu_first(&built.world) } else { None };
    let wants_pictures = file.output.images;
    let without = without.to_string();
    if let (Some(why), Some(_)) = (on_cpu, ctx) {
        note(&format!("{why} steps on the CPU, on every core (the GPU draws the pictures)"));
    }
    let (mut run, backend, adapter) = match (config.backend, ctx) {
        (_, Some(ctx)) if on_cpu.is_some() => {
            (simulation(None, built.world.clone())?, "cpu", format!("pictures on {}", ctx.adapter_name()))
        }
        (Backend::Cpu, _) | (Backend::Auto, None) => (
            simulation(None, built.world.clone())?,
            "cpu",
            ctx.map_or(without, |c| format!("pictures on {}", c.adapter_name())),
        ),
        (_, Some(ctx)) => (simulation(Some(ctx), built.world.clone())?, "gpu", ctx.adapter_name()),
        (Backend::Gpu, None) => unreachable!("Backend::Gpu returned early without an adapter"),
    };
    let scenario =
        config.path.file_stem().map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
    note(&format!("{scenario} on the {backend} backend ({adapter})"));
    let mut renderer = match (ctx, wants_pictures) {
        (Some(ctx), true) => Some(Renderer::new(ctx, config.image.0, config.image.1)?),
        _ => None,
    };
    std::fs::create_dir_all(&config.out).map_err(|e| io(&config.out, e))?;
    let world = &built.world;
    let mut series: Vec<PvdSeries> = if file.output.vtk {
        world.names.iter().map(|n| PvdSeries::new(config.out.join(format!("{n}.pvd")))).collect()
    } else {
        Vec::new()
    };
    let mut summary = FileSummary {
        scenario: scenario.clone(),
        units: file.units.symbol().into(),
        backend: backend.into(),
        adapter,
        dt: built.dt,
        bodies: world
            .names
            .iter()
            .zip(&world.bodies)
            .zip(&file.bodies)
            .zip(&built.notes)
            .map(|(((name, body), spec), n): (((&String, &MassSpring), _), &BodyNote)| BodySummary {
                name: name.clone(),
                kind: kind_name(spec.kind).into(),
                vertices: body.len(),
                coverage: n.coverage.map(|(c, _)| c),
                remarks: n.remarks.clone(),
                material: (spec.kind != BodyKind::Rigid).then(|| MaterialSummary {
                    model: if body.elements.is_some() { "neo-hookean" } else { "springs" }.into(),
                    young_kpa: spec.material.young_kpa,
                    poisson: spec.material.poisson,
                    poisson_honoured: body.elements.is_some(),
                    tetrahedra: body.elements.as_ref().map(|e| e.tets.len()),
                }),
                reference: n.reference.map(|r| ReferenceSummary {
                    residual: r.residual,
                    iterations: r.iterations,
                    spacing: r.spacing,
                    valid: r.is_valid(),
                }),
                ..BodySummary::default()
            })
            .collect(),
        contacts: world
            .contacts
            .iter()
            .map(|c| ContactSummary {
                a: world.names[c.a].clone(),
                b: world.names[c.b].clone(),
                bound: c.grid.voxel_size(),
                rest_bound: 0.5 * mean_spring(&world.bodies[c.b]),
                held: true,
                ..Default::default()
            })
            .collect(),
        held: true,
        not_a_result,
        integrator: if built.world.integrator == Integrator::Explicit { "explicit" } else { "implicit" }
            .into(),
        ..FileSummary::default()
    };
    let size = world
        .bodies
        .iter()
        .flat_map(|b| b.pos.iter())
        .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let size = (size.1 - size.0).max_element();
    let soft: Vec<bool> = file.bodies.iter().map(|b| b.kind == BodyKind::Soft).collect();
    let frames = u64::from(file.output.frames);
    let planned = built.steps;
    let chunk = planned.div_ceil(frames).max(1);
    let mut stepping = 0.0f64;
    let mut done = 0u64;
    let mut frame = 0u32;
    // Where the vertices were at the last frame, and its step.
    let mut before: Option<(u64, Vec<Vec<Vec3>>)> = None;
    let window = settling_window(world, built.dt);
    summary.rest_window = window as f64 * f64::from(built.dt);
    let spacings: Vec<f32> = world.bodies.iter().map(mean_spring).collect();
    // The contacts are checked at every frame and, between frames, at least 64 times over
    // the schedule and 4 times a settling window (docs/design.md §11: a failed contact is never shown
    // as a result).
    let check_every = (planned / 64).min(window / 4).clamp(1, chunk);
    let mut checks = ContactChecks::new(world.contacts.len());
    let mut stall = Stall::default();
    // The step since which the implicit integrator's residual has stalled, once it has.
    let mut stalled_since: Option<u64> = None;
    if file.time.settle && planned > file.time.max_steps {
        // The explicit step is bound by stability (a stiff or nearly incompressible body's is
        // small): the implicit integrator's is not.
        let or_implicit = if built.world.integrator == Integrator::Explicit {
            ", or step with [time] integrator = \"implicit\", whose step is not bound by stability"
        } else {
            ""
        };
        note(&format!(
            "warning: the schedule needs {planned} steps (dt {:.3e} s), more than max_steps = {}: the run will stop before it ends; raise [time] max_steps or shorten the schedule{or_implicit}",
            built.dt, file.time.max_steps
        ));
    }
    loop {
        let (residual, now) = (run.residual().map(|r| r.relative()), simulated_time(&*run, done, built.dt));
        // How finely the positions resolve the residual, past the schedule (two force sums).
        let floor = if residual.is_some() && done >= planned { run.residual_floor() } else { None };
        let (world, reports) = run.frame()?;
        measure(world, &mut summary);
        checks.check(world, &reports, &mut summary, done, frame, true, note)?;
        let motion = before.as_ref().map_or(f32::INFINITY, |(_, was)| frame_motion(world, was, &spacings));
        let long_enough = before.as_ref().is_some_and(|(at, _)| done - at >= window);
        // At rest by motion (the explicit integrator), or by the residual force (the implicit
        // one). Under the implicit integrator motion is not a test of rest: its large steps
        // slow a body still out of balance (a fill judged still at a residual of 3e-3 had its
        // lift 4.5 % short of the equilibrium the residual then reached).
        let still = done >= planned && long_enough && motion <= REST_TOLERANCE && residual.is_none();
        // Balanced: within the tolerance, or as finely as single-precision positions resolve
        // the forces (a column of 6,561 vertices hanging under its own weight stalled at
        // 2.6e-3 of its loads, below its floor of 4.0e-3, its stretch within 0.1 % of the
        // closed form).
        let balanced = done >= planned
            && done > 0
            && residual.is_some_and(|r| r <= RESIDUAL_TOLERANCE || floor.is_some_and(|f| r <= f));
        // Stalled and still: the residual has stopped falling (its chatter is contacts' at
        // rest: on a patient, the pocket's, a vertex of the tissue flipping about a vertex of
        // the implant it rests on, hundreds of times its share of the loads) and no vertex has
        // moved a twentieth of its spacing over a settling window since, but a hundredth of
        // them (the chattering ones, by up to a tenth of a spacing). More steps would not change
        // the shape. Unlike a fill judged still by motion alone, its residual is no longer
        // falling.
        let stalled_still = done >= planned
            && residual.is_some()
            && stalled_since.is_some()
            && long_enough
            && before
                .as_ref()
                .is_some_and(|(_, was)| most_motion(world, was, &spacings, &soft) <= REST_TOLERANCE);
        let at_rest = still || balanced || stalled_still;
        // Settling whose residual has stopped falling is said as soon as it is seen, not only
        // after max_steps.
        if let Some(r) = residual.filter(|_| file.time.settle && done >= planned && !at_rest)
            && let Some(since) = stall.stalled(done, r)
        {
            stalled_since = Some(since);
            let floor = floor.map_or(String::new(), |f| {
                format!(" (single-precision positions resolve it to about {f:.1e})")
            });
            note(&format!(
                "warning: settling has stalled: the residual force has stayed near {r:.2e} of the largest load (at rest: {RESIDUAL_TOLERANCE:.0e}){floor} since step {since}, {} steps; the run goes on until the shape is still (no vertex moving a twentieth of its spacing over a settling window), or to max_steps = {}",
                done - since,
                file.time.max_steps
            ));
        }
        before = Some((done, world.bodies.iter().map(|b| b.pos.clone()).collect()));
        let last = if file.time.settle {
            (done >= planned && at_rest) || done >= file.time.max_steps
        } else {
            done >= planned
        };
        if let Some(r) = renderer.as_mut() {
            let name = format!("{scenario}_{frame:04}.png");
            let shown = shown_and_moved(world);
            let scene = picture(world, &shown, &soft, size, file.world.up);
            let legend = Legend::new(format!("displacement ({})", summary.units), scene.scalar_range)
                .above(scene.largest_scalar());
            r.render_png_with_legend(&scene, Some(&legend), &config.out.join(&name))?;
            summary.files.push(name);
        }
        for (k, pvd) in series.iter_mut().enumerate() {
            let body = &world.bodies[k];
            let force = contact_forces(world, &reports, k);
            let mut colliding = vec![false; body.len()];
            // B's vertices the voxel model found colliding; A's that it pushed.
            for (pair, r) in world.contacts.iter().zip(&reports) {
                if pair.b == k && r.force_b.len() == body.len() {
                    r.colliding_b.iter().for_each(|&j| colliding[j as usize] = true);
                }
                if pair.a == k && r.force_a.len() == body.len() {
                    colliding.iter_mut().zip(&r.force_a).for_each(|(c, f)| *c |= *f != Vec3::ZERO);
                }
            }
            let name = format!("{}_{frame:04}.vtp", world.names[k]);
            let time = now;
            match &body.embedded {
                None => {
                    let displacement: Vec<Vec3> =
                        body.pos.iter().zip(body.start()).map(|(p, r)| *p - *r).collect();
                    pvd.write_frame(
                        time,
                        &name,
                        &BodyFrame {
                            positions: &body.pos,
                            triangles: &body.surface.triangles,
                            displacement: &displacement,
                            contact_force: &force,
                            colliding: &colliding,
                        },
                    )?;
                }
                Some(e) => {
                    // The user's surface, its values interpolated from the lattice.
                    let positions = e.positions(&body.pos, &body.rest_pos);
                    let displacement: Vec<Vec3> =
                        positions.iter().zip(body.shown_start().iter()).map(|(p, r)| *p - *r).collect();
                    let flags: Vec<Vec3> =
                        colliding.iter().map(|c| Vec3::splat(f32::from(u8::from(*c)))).collect();
                    let touching: Vec<bool> = e.interpolate(&flags).iter().map(|f| f.x > 0.0).collect();
                    pvd.write_frame(
                        time,
                        &name,
                        &BodyFrame {
                            positions: &positions,
                            triangles: &e.mesh.triangles,
                            displacement: &displacement,
                            contact_force: &e.interpolate(&force),
                            colliding: &touching,
                        },
                    )?;
                }
            }
            summary.files.push(name);
        }
        observe(world, &reports, FrameAt { step: done, time: now, last })?;
        if last {
            summary.settled = file.time.settle && at_rest;
            checks.at_end(&mut summary, done, note);
            // Each soft body's surface as it ends (the operated skin), for any mesh viewer, with
            // how far each vertex moved as its `quality`.
            if file.output.vtk {
                let shown = shown_and_moved(world);
                for (k, (b, spec)) in world.bodies.iter().zip(&file.bodies).enumerate() {
                    if spec.kind != BodyKind::Soft {
                        continue;
                    }
                    let name = format!("{}_end.ply", world.names[k]);
                    let (_, mesh) = shown_surface(b);
                    voxcollide_sim::mesh_io::write_ply(
                        &config.out.join(&name),
                        &shown[k].0,
                        mesh,
                        Some(&shown[k].1),
                        &format!(
                            "voxcollide: {} at the end of {scenario}, in {}; quality: how far it moved",
                            world.names[k], summary.units
                        ),
                    )?;
                    summary.files.push(name);
                }
            }
            let cubic_ml = file.metres().powi(3) * 1e6;
            for (k, ((b, spec), out)) in
                world.bodies.iter().zip(&file.bodies).zip(summary.bodies.iter_mut()).enumerate()
            {
                if let Some(faces) = &built.notes[k].wall_faces {
                    out.volume_ml = Some(volume_between(b, faces, b.start(), b.start()) * cubic_ml);
                    out.volume_ml_end = Some(volume_between(b, faces, b.start(), &b.pos) * cubic_ml);
                }
                for l in &built.notes[k].landmarks {
                    summary.landmarks.push(LandmarkSummary {
                        body: spec.name.clone(),
                        name: l.name.clone(),
                        start: l.at(b.start()).to_array(),
                        end: l.at(&b.pos).to_array(),
                    });
                }
                if spec.kind == BodyKind::Shell {
                    out.volume = Some(b.enclosed_volume());
                    if file.units.is_physical() {
                        out.volume_ml = Some(b.enclosed_volume() * file.metres().powi(3) * 1e6);
                    }
                }
            }
            summary.rest_motion = if motion.is_finite() { motion } else { 0.0 };
            summary.residual = residual;
            summary.residual_floor = floor;
            (summary.split_steps, summary.most_parts) =
                run.parts().map(|p| (p.split_steps, p.most_parts)).unzip();
            // Each integrator's own test, met or not (the implicit one never judges by motion).
            summary.criterion = match (residual, stalled_since) {
                (Some(r), Some(_)) if r > RESIDUAL_TOLERANCE && !floor.is_some_and(|f| r <= f) => {
                    "stalled residual, rest_motion"
                }
                (Some(_), _) => "residual",
                (None, _) => "rest_motion",
            }
            .into();
            for (c, r) in reports.iter().enumerate() {
                summary.contacts[c].contacts_at_end = r.colliding_b.len();
            }
            break;
        }
        // On the schedule, frame k at step ⌈k · steps / frames⌉ (evenly, the last at its end);
        // past it, frames a settling window apart.
        let next = if done >= planned {
            done + chunk.max(window)
        } else {
            ((u64::from(frame) + 1) * planned).div_ceil(frames).max(done + 1)
        };
        let target = next.min(if file.time.settle { file.time.max_steps } else { planned });
        if file.time.settle && done >= planned {
            run.accelerate(SETTLE_ACCELERATION);
        }
        let mut started = Instant::now();
        while done < target {
            run.step()?;
            done += 1;
            // The implicit integrator at rest needs no more steps to show it.
            if file.time.settle
                && done >= planned
                && run.residual().map(|r| r.relative()).is_some_and(|r| r <= RESIDUAL_TOLERANCE)
            {
                break;
            }
            if done.is_multiple_of(16) || done == target {
                progress(done, planned.max(done));
            }
            if done.is_multiple_of(check_every) && done < target {
                stepping += started.elapsed().as_secs_f64();
                let (world, reports) = run.frame()?;
                checks.check(world, &reports, &mut summary, done, frame + 1, false, note)?;
                started = Instant::now();
            }
        }
        stepping += started.elapsed().as_secs_f64();
        frame += 1;
    }
    if file.output.vtk {
        summary.files.extend(world.names.iter().map(|n| format!("{n}.pvd")));
    }
    summary.steps = done;
    summary.host_waits_per_step = run.host_waits().map(|w| w as f64 / done.max(1) as f64);
    summary.simulated_time = simulated_time(&*run, done, built.dt);
    summary.steps_per_second = if stepping > 0.0 { done as f64 / stepping } else { 0.0 };
    summary.realtime_factor = if stepping > 0.0 { summary.simulated_time / stepping } else { 0.0 };
    let path = config.out.join("summary.json");
    let json = serde_json::to_string_pretty(&summary).map_err(|e| io(&path, e))?;
    std::fs::write(&path, json + "\n").map_err(|e| io(&path, e))?;
    summary.files.push("summary.json".into());
    Ok(summary)
}

/// Whether settling under the implicit integrator still gets anywhere: its residual force at
/// each frame past the schedule against the least it has reached.
#[derive(Debug, Default)]
pub(crate) struct Stall {
    /// The least residual so far, and the step it was reached at (a new least counts only
    /// when it is a tenth below the last).
    best: Option<(f64, u64)>,
    /// Frames since the least.
    frames: u32,
    said: bool,
}

/// Settling frames without the residual falling by a tenth before [`Stall`] says so.
pub(crate) const STALL_FRAMES: u32 = 8;

impl Stall {
    /// The residual `r` at a settling frame at step `step`: the step since which it has not
    /// fallen by a tenth, the first time that has lasted [`STALL_FRAMES`] frames (once a run).
    pub(crate) fn stalled(&mut self, step: u64, r: f64) -> Option<u64> {
        match self.best {
            Some((best, _)) if r.is_nan() || r >= 0.9 * best => self.frames += 1,
            _ => {
                self.best = Some((r, step));
                self.frames = 0;
            }
        }
        if self.frames >= STALL_FRAMES && !self.said {
            self.said = true;
            return self.best.map(|(_, at)| at);
        }
        None
    }
}

/// The contacts' checks against their bounds (docs/design.md §11), over a run.
struct ContactChecks {
    /// Per contact: whether it has touched yet (a contact is bound after first contact).
    touched: Vec<bool>,
    /// Per contact: the depth of the last check (at the end, the last frame's).
    last: Vec<f32>,
    /// Per contact: the hierarchies of its two bodies' surfaces, kept from one check to the
    /// next and refit (a check builds none anew until one has gone stale).
    hierarchies: Vec<[Option<Hierarchy>; 2]>,
    /// Per contact: b's vertices in a, a's surface in b, from one check to the next (each
    /// asks only the points that may have changed sides).
    watches: Vec<[PenetrationWatch; 2]>,
}

impl ContactChecks {
    fn new(contacts: usize) -> ContactChecks {
        ContactChecks {
            touched: vec![false; contacts],
            last: vec![0.0; contacts],
            hierarchies: vec![[None, None]; contacts],
            watches: vec![Default::default(); contacts],
        }
    }

    /// Checks every contact's penetration now (`step`, in output frame `frame`) against its
    /// bound, recording the worst and warning the first time one goes beyond. At a frame
    /// (`at_frame`) the summary's penetration maxima take the same measurement.
    #[allow(clippy::too_many_arguments)]
    fn check(
        &mut self,
        world: &World,
        reports: &[ContactReport],
        summary: &mut FileSummary,
        step: u64,
        frame: u32,
        at_frame: bool,
        note: &mut dyn FnMut(&str),
    ) -> Result<(), Error> {
        for (c, pair) in world.contacts.iter().enumerate() {
            let (b_in_a, a_in_b) =
                contact_depths(world, pair, &mut self.hierarchies[c], &mut self.watches[c])?;
            let depth = b_in_a.max_depth.max(a_in_b);
            self.last[c] = depth;
            let s = &mut summary.contacts[c];
            if at_frame {
                s.max_penetration = s.max_penetration.max(b_in_a.max_depth);
                s.penetrating_fraction = s.penetrating_fraction.max(b_in_a.fraction);
            }
            s.checks += 1;
            self.touched[c] |= depth > 0.0 || reports.get(c).is_some_and(|r| !r.colliding_b.is_empty());
            if !self.touched[c] || depth <= s.bound {
                continue;
            }
            // The first time beyond the bound is the time to warn.
            let first = s.held;
            s.held = false;
            // Before the first step the scene itself placed them so: no push of the contact's
            // made it, and none may undo it (a push starts at the partner's surface).
            let placed = step == 0;
            if s.worst_depth.is_none_or(|w| depth > w) {
                s.worst_depth = Some(depth);
                s.worst_frame = Some(frame);
                s.worst_step = Some(step);
                s.failure = Some(if placed {
                    format!(
                        "the scene places {} and {} {depth:.3} {u} deep in each other before the first step, beyond the contact's bound of {:.3} {u} (its voxel size): move them apart",
                        s.a,
                        s.b,
                        s.bound,
                        u = summary.units
                    )
                } else {
                    format!(
                        "{} and {} went {depth:.3} {u} deep into each other at step {step} (frame {frame}), beyond the contact's bound of {:.3} {u} (its voxel size)",
                        s.a,
                        s.b,
                        s.bound,
                        u = summary.units
                    )
                });
            }
            if first && placed {
                note(&format!(
                    "warning: contact {} – {} did not hold: the scene places them {depth:.3} {u} deep in each other before the first step, beyond the bound of {:.3} {u}; move them apart (their `position`s) and run again: this run's numbers are not a result",
                    s.a,
                    s.b,
                    s.bound,
                    u = summary.units
                ));
            } else if first {
                note(&format!(
                    "warning: contact {} – {} did not hold: {depth:.3} {u} deep at step {step} (frame {frame}), beyond the bound of {:.3} {u}; this run's numbers are not a result",
                    s.a,
                    s.b,
                    s.bound,
                    u = summary.units
                ));
            }
        }
        summary.held = summary.contacts.iter().all(|c| c.held);
        Ok(())
    }

    /// At the last frame: a settled run's contacts are held to their bound at rest, and each
    /// contact that did not hold is said once more.
    fn at_end(&self, summary: &mut FileSummary, step: u64, note: &mut dyn FnMut(&str)) {
        for (s, &depth) in summary.contacts.iter_mut().zip(&self.last) {
            if summary.settled && depth > s.rest_bound {
                s.held = false;
                if s.worst_depth.is_none() {
                    s.worst_depth = Some(depth);
                    s.worst_step = Some(step);
                }
                s.failure.get_or_insert_with(|| {
                    format!(
                        "at rest {} and {} are {depth:.3} {u} deep in each other, beyond the resting bound of {:.3} {u} (half of {}'s spacing)",
                        s.a,
                        s.b,
                        s.rest_bound,
                        s.b,
                        u = summary.units
                    )
                });
            }
            if let Some(f) = &s.failure {
                note(&format!("warning: contact {} – {} did not hold: {f}", s.a, s.b));
            }
        }
        summary.held = summary.contacts.iter().all(|c| c.held);
    }
}

/// How deep contact `pair`'s bodies are inside each other: `b`'s vertices inside `a`'s closed
/// (shown) surface (the summary's penetration), and the deepest of `a`'s shown vertices inside
/// `b`'s. Both sides, since the voxel model pushes only `b`'s vertices out of `a`: `a`'s could
/// pass between them.
fn contact_depths(
    world: &World,
    pair: &voxcollide_sim::ContactPair,
    hierarchies: &mut [Option<Hierarchy>; 2],
    watches: &mut [PenetrationWatch; 2],
) -> Result<(voxcollide_sim::geometry::Penetration, f32), Error> {
    let surface_of = |k: usize| shown_surface(&world.bodies[k]);
    let (a_pos, a_mesh) = surface_of(pair.a);
    let (b_pos, b_mesh) = surface_of(pair.b);
    let [ha, hb] = hierarchies;
    let [wa, wb] = watches;
    // The two ways at once, each on every core.
    let (b_in_a, a_in_b) = rayon::join(
        || -> Result<_, Error> {
            let surface = surface_kept(&a_pos, a_mesh, ha.take())?;
            let depth = wa.penetration(&surface, &world.bodies[pair.b].pos);
            *ha = Some(surface.into_hierarchy());
            Ok(depth)
        },
        || -> Result<_, Error> {
            let surface = surface_kept(&b_pos, b_mesh, hb.take())?;
            let depth = wb.penetration(&surface, &a_pos).max_depth;
            *hb = Some(surface.into_hierarchy());
            Ok(depth)
        },
    );
    Ok((b_in_a?, a_in_b?))
}

/// The closed surface of `mesh` at `positions` on the hierarchy kept from the last check, or
/// on a new one where there is none or it has gone stale.
fn surface_kept<'a>(
    positions: &'a [Vec3],
    mesh: &'a voxcollide_sim::mesh::TriangleMesh,
    kept: Option<Hierarchy>,
) -> Result<ClosedSurface<'a>, Error> {
    match kept.filter(|h| !h.stale()).map(|h| ClosedSurface::refit(positions, mesh, h)) {
        Some(Ok(surface)) => Ok(surface),
        _ => ClosedSurface::new(positions, mesh),
    }
}

/// The contact force on each vertex of body `k`: its side's forces of every contact it is in,
/// summed in contact order.
pub(crate) fn contact_forces(world: &World, reports: &[ContactReport], k: usize) -> Vec<Vec3> {
    let n = world.bodies[k].len();
    let mut force = vec![Vec3::ZERO; n];
    for (pair, r) in world.contacts.iter().zip(reports) {
        if pair.a == k && r.force_a.len() == n {
            force.iter_mut().zip(&r.force_a).for_each(|(f, a)| *f += *a);
        }
        if pair.b == k && r.force_b.len() == n {
            force.iter_mut().zip(&r.force_b).for_each(|(f, b)| *f += *b);
        }
    }
    force
}

/// Every body's shown surface ([`shown_surface`]) and how far each of its vertices is from
/// where it started.
pub(crate) fn shown_and_moved(world: &World) -> Vec<(Vec<Vec3>, Vec<f32>)> {
    world
        .bodies
        .iter()
        .map(|b| {
            let (p, _) = shown_surface(b);
            let moved = p.iter().zip(b.shown_start().iter()).map(|(p, r)| p.distance(*r)).collect();
            (p.into_owned(), moved)
        })
        .collect()
}

/// The surface a body is shown and measured by: the user's own where the lattice carries one
/// (its vertices following their cells), else the body's.
pub(crate) fn shown_surface(
    body: &MassSpring,
) -> (std::borrow::Cow<'_, [Vec3]>, &voxcollide_sim::mesh::TriangleMesh) {
    match &body.embedded {
        Some(e) => (e.positions(&body.pos, &body.rest_pos).into(), &e.mesh),
        None => (body.pos.as_slice().into(), &body.surface),
    }
}

/// The settling criterion's tolerance: the bodies are at rest when, over a settling window
/// after the schedule ([`settling_window`]), no vertex that is not held (free, or driven by
/// keyframes) moved farther than this fraction of its body's spacing (the mean rest length of
/// its springs). That is finer than the model resolves a contact — a penalty contact's
/// vertices chatter by a few hundredths of a spacing from step to step, however long the run,
/// which is why speeds at an instant cannot be the test — and a shape that changes by less
/// over the time its body needs to respond is the final one for planning.
pub const REST_TOLERANCE: f32 = 0.05;

/// The implicit integrator is at rest when the net force on its free vertices is at most this
/// fraction of the gross force (see [`FileSummary::residual`]).
pub const RESIDUAL_TOLERANCE: f64 = 1e-3;

/// Past the schedule, the implicit step may grow to this many times the schedule's while it
/// settles (see `CpuWorld::accelerate`).
pub const SETTLE_ACCELERATION: f32 = 64.0;

/// The settling window in steps: twice the time an elastic wave takes to cross the largest
/// deformable body, `2 · extent / c` with the lattice's wave speed `c = h · √(k/m)` (its mean
/// spring length, stiffness and vertex mass) — the time over which a body still adjusting to
/// its load must show it (for a body of finite elements, its P-wave speed). At least one step.
pub fn settling_window(world: &World, dt: f32) -> u64 {
    ((voxcollide_sim::world::response_time(&world.bodies) / f64::from(dt)).ceil() as u64).max(1)
}

/// A body's spacing: the mean rest length of its springs (1 without springs).
pub(crate) fn mean_spring(b: &MassSpring) -> f32 {
    if b.springs.is_empty() {
        1.0
    } else {
        (b.springs.iter().map(|s| f64::from(s.rest)).sum::<f64>() / b.springs.len() as f64) as f32
    }
}

/// The farthest any vertex that is not pinned is from where it was at the last frame, in
/// spacings of its body.
fn frame_motion(world: &World, before: &[Vec<Vec3>], spacings: &[f32]) -> f32 {
    motions(world, before, spacings).fold(0.0, f32::max)
}

/// The motion that all but a hundredth of the soft bodies' vertices not held stay within (of
/// [`frame_motion`]'s): the tissue's shape, still but for its few chattering contact
/// vertices. (A shell's are left out: an implant's rim squeezed between the tissue and the
/// chest wall chatters by a twentieth of a spacing from step to step on the patient at rest;
/// its volume is judged on its own.)
fn most_motion(world: &World, before: &[Vec<Vec3>], spacings: &[f32], soft: &[bool]) -> f32 {
    let mut all: Vec<f32> = motions(world, before, spacings)
        .zip(world.bodies.iter().enumerate().flat_map(|(k, b)| {
            b.mode.iter().filter(|m| **m != voxcollide_sim::Mode::Pinned).map(move |_| soft[k])
        }))
        .filter_map(|(m, soft)| soft.then_some(m))
        .collect();
    if all.is_empty() {
        return 0.0;
    }
    let k = ((all.len() as f64 * 0.99).floor() as usize).min(all.len() - 1);
    *all.select_nth_unstable_by(k, f32::total_cmp).1
}

/// Each vertex not held: how far it moved since `before`, in its body's spacings.
fn motions<'a>(
    world: &'a World,
    before: &'a [Vec<Vec3>],
    spacings: &'a [f32],
) -> impl Iterator<Item = f32> + 'a {
    world.bodies.iter().zip(before).zip(spacings).flat_map(|((b, was), h)| {
        b.pos
            .iter()
            .zip(was)
            .zip(&b.mode)
            .filter(|(_, m)| **m != voxcollide_sim::Mode::Pinned)
            .map(move |((p, q), _)| p.distance(*q) / h)
    })
}

/// Updates the summary's displacement maxima with this frame (the contacts' penetration is
/// [`ContactChecks::check`]'s, independent of the voxel model).
fn measure(world: &World, summary: &mut FileSummary) {
    for (body, s) in world.bodies.iter().zip(summary.bodies.iter_mut()) {
        let d = body.pos.iter().zip(body.start()).map(|(p, r)| p.distance(*r)).fold(0.0, f32::max);
        s.max_displacement = s.max_displacement.max(d);
    }
}

/// Every body's mesh for a picture, by its shown surface (`shown`: positions and how far each
/// moved): the bodies for which `coloured` says so coloured by that distance, the others in
/// `colour(body)`.
pub(crate) fn meshes<'a>(
    world: &'a World,
    shown: &'a [(Vec<Vec3>, Vec<f32>)],
    coloured: impl Fn(usize) -> bool,
    colour: impl Fn(usize) -> [f32; 3],
) -> Vec<SceneMesh<'a>> {
    world
        .bodies
        .iter()
        .enumerate()
        .map(|(k, b)| SceneMesh {
            positions: &shown[k].0,
            triangles: &b.embedded.as_ref().map_or(&b.surface, |e| &e.mesh).triangles,
            scalars: coloured(k).then(|| shown[k].1.as_slice()),
            base_color: colour(k),
        })
        .collect()
}

/// The scene's axes as pictures see them (`[world] up`, docs/design.md §13): `[side,
/// forward, up]`, `up` drawn upward and a picture from the front looking along `forward`, a
/// right-handed turn of x, y, z. Z up: looking along +y (the paper's scenes). Y up: looking
/// along −z, at a patient who faces +z as surface scanners and MakeHuman write her. X up:
/// looking along +z.
#[must_use]
pub fn axes(up: Axis) -> [Vec3; 3] {
    match up {
        Axis::Z => [Vec3::X, Vec3::Y, Vec3::Z],
        Axis::Y => [Vec3::X, Vec3::NEG_Z, Vec3::Y],
        Axis::X => [Vec3::Y, Vec3::Z, Vec3::X],
    }
}

/// Every body by its shown surface (`shown`: positions and how far each moved), the soft ones
/// coloured by that distance (up to a tenth of the scene), the others in plain colours, seen
/// from the front and a little above, `up` drawn upward.
fn picture<'a>(
    world: &'a World,
    shown: &'a [(Vec<Vec3>, Vec<f32>)],
    soft: &[bool],
    size: f32,
    up: Axis,
) -> RenderScene<'a> {
    let [side, forward, up] = axes(up);
    const COLOURS: [[f32; 3]; 4] = [[0.95, 0.6, 0.25], [0.45, 0.55, 0.7], [0.6, 0.8, 0.5], [0.8, 0.5, 0.7]];
    RenderScene {
        meshes: meshes(world, shown, |k| soft[k], |k| COLOURS[k % COLOURS.len()]),
        scalar_range: (0.0, 0.1 * size),
        clip: None,
        view_dir: (0.3 * side + forward - 0.35 * up).normalize(),
        up,
    }
}

#[cfg(test)]
mod stall_tests {
    use super::{STALL_FRAMES, Stall};

    /// A residual falling steadily, even slowly, is not a stall; one that stops falling is said
    /// once, after STALL_FRAMES frames, naming the step it stopped at; a NaN residual counts
    /// as not falling.
    #[test]
    fn settling_is_said_to_stall_once_its_residual_stops_falling() {
        let mut s = Stall::default();
        for k in 0..100u64 {
            assert_eq!(s.stalled(100 * k, 0.85f64.powi(k as i32)), None, "frame {k}");
        }
        let mut s = Stall::default();
        let mut said = Vec::new();
        for k in 0..40u64 {
            // Falls to 1e-2 by frame 5, then wanders within a few percent.
            let r = if k < 5 { 0.5f64.powi(k as i32) } else { 0.0625 * (1.0 + 0.05 * ((k % 3) as f64)) };
            if let Some(since) = s.stalled(100 * k, r) {
                said.push((k, since));
            }
        }
        assert_eq!(said, [(4 + u64::from(STALL_FRAMES), 400)]);
        let mut s = Stall::default();
        let said: Vec<u64> =
            (0..20u64).filter_map(|k| s.stalled(k, if k == 0 { 1.0 } else { f64::NAN })).collect();
        assert_eq!(said, [0]);
    }
}
