//! The command's one run loop (`voxcollide run`, the paper scenes, `compare`'s candidates): a
//! scene file's world on the GPU or the CPU, in three parts.
//!
//! - **Set-up**: the build's findings said, the backend placed (`backend::place`), the
//!   summary started (`summary.rs`) and the frame files readied (`frames.rs`).
//! - **Stepping**: frames over the schedule, the contacts checked at and between them
//!   (`checks.rs`), then, where the file settles, frames a settling window apart until the
//!   bodies are at rest (`rest.rs`) or `max_steps`. An observer sees every frame.
//! - **Summary**: the last frame's figures, the totals, and `summary.json` with
//!   docs/design.md §8's keys.
//!
//! Nothing is written when the set-up fails: the file is read, its meshes loaded and its world
//! built before the output folder is touched.

mod checks;
mod frames;
mod rest;
mod summary;

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::backend::{Backend, OnSoftware, Placed, context, place};
use checks::ContactChecks;
use frames::FrameFiles;
use rest::Rest;
use voxcollide::error::Error;
use voxcollide::report::ContactReport;
use voxcollide_sim::build::{Built, build_world};
use voxcollide_sim::scene_file::SceneFile;
use voxcollide_sim::{Simulation, World};

pub use frames::axes;
pub(crate) use frames::{contact_forces, meshes, shown_and_moved, shown_surface};
pub(crate) use rest::mean_spring;
pub use rest::{RESIDUAL_TOLERANCE, REST_TOLERANCE, SETTLE_ACCELERATION, settling_window};
pub use summary::{
    BodySummary, ContactSummary, FileSummary, LandmarkSummary, MaterialSummary, PlacedSummary,
    ReferenceSummary,
};

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

pub(crate) fn io(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Io { path: path.display().to_string(), message: e.to_string() }
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
    // Set-up.
    let not_a_result = say_findings(file, &built, note);
    let Placed { mut run, backend, adapter } =
        place(config.backend, ctx, without, built.world.clone(), OnSoftware::Steps, note)?;
    let scenario =
        config.path.file_stem().map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
    note(&format!("{scenario} on the {backend} backend ({adapter})"));
    let mut frames = FrameFiles::new(ctx, file, &built.world, config, &scenario)?;
    std::fs::create_dir_all(&config.out).map_err(|e| io(&config.out, e))?;
    let mut summary = summary::start(file, &built, &scenario, (backend, adapter), not_a_result);
    let mut rest = Rest::new(&built.world, built.dt, frames.soft().to_vec());
    summary.rest_window = rest.window as f64 * f64::from(built.dt);
    let mut schedule = Schedule::new(file, &built, rest.window);
    if file.time.settle && schedule.planned > file.time.max_steps {
        warn_short(file, &built, note);
    }
    let mut checks = ContactChecks::new(built.world.contacts.len());
    let mut frame = 0u32;

    // Stepping, frame by frame.
    loop {
        let done = schedule.done;
        let (residual, now) = (run.residual().map(|r| r.relative()), simulated_time(&*run, done, built.dt));
        // How finely the positions resolve the residual, past the schedule (two force sums).
        let floor = if residual.is_some() && done >= schedule.planned { run.residual_floor() } else { None };
        let (world, reports) = run.frame().map_err(|e| after_failures(e, &summary, &built.notes))?;
        summary::measure(world, &mut summary);
        checks.check(world, &reports, &mut summary, done, frame, true, note)?;
        let verdict = rest.judge(
            world,
            (done, schedule.planned),
            residual,
            floor,
            (file.time.settle, file.time.max_steps),
            note,
        );
        let last = if file.time.settle {
            (done >= schedule.planned && verdict.at_rest) || done >= file.time.max_steps
        } else {
            done >= schedule.planned
        };
        frames.write(world, &reports, (frame, now), &mut summary)?;
        observe(world, &reports, FrameAt { step: done, time: now, last })?;
        if last {
            // The summary's last frame.
            summary.settled = file.time.settle && verdict.at_rest;
            checks.at_end(&mut summary, done, note);
            frames.write_end(world, &mut summary)?;
            let at =
                summary::Last { residual, floor, stalled_since: rest.stalled_since, motion: verdict.motion };
            let before = summary.not_a_result.len();
            summary::at_end(&mut summary, (world, &reports), file, &built, &at);
            for why in &summary.not_a_result[before..] {
                note(&format!("warning: {why}; the run is not a result"));
            }
            frames.finish(world, &mut summary);
            break;
        }
        let target = schedule.next_frame(frame);
        if file.time.settle && done >= schedule.planned {
            run.accelerate(SETTLE_ACCELERATION);
        }
        frame += 1;
        // Settling, frames may be farther apart than a settling window (as far as on the
        // schedule): the motion is judged over the window before the frame, from where the
        // vertices are kept at its start (checked there too).
        let mark = target.saturating_sub(rest.window);
        if done >= schedule.planned && mark > done {
            let rested = schedule
                .step_to(&mut *run, mark, (&mut checks, &mut summary, frame), progress, note)
                .map_err(|e| after_failures(e, &summary, &built.notes))?;
            if rested {
                // At rest by its residual already: judged at once.
                continue;
            }
            let (world, reports) = run.frame().map_err(|e| after_failures(e, &summary, &built.notes))?;
            checks.check(world, &reports, &mut summary, mark, frame, false, note)?;
            rest.mark(world, mark);
        }
        schedule
            .step_to(&mut *run, target, (&mut checks, &mut summary, frame), progress, note)
            .map_err(|e| after_failures(e, &summary, &built.notes))?;
    }

    // Summary.
    summary::totals(&mut summary, &*run, schedule.done, schedule.seconds);
    summary::write(&config.out, &mut summary)?;
    Ok(summary)
}

/// A blow-up `e` with what went wrong before it: the contacts that had already failed (a body
/// come through another is a likely cause of a blow-up, and the first thing to fix), and what
/// building the world warned of (`notes`: tissue too thin for its lattice over an implant's
/// rim, say).
fn after_failures(e: Error, summary: &FileSummary, notes: &[voxcollide_sim::build::BodyNote]) -> Error {
    let mut before: Vec<String> = summary
        .contacts
        .iter()
        .filter_map(|c| c.failure.as_ref().map(|f| format!("contact {} – {} had not held: {f}", c.a, c.b)))
        .collect();
    before.extend(notes.iter().flat_map(|n| {
        n.remarks
            .iter()
            .filter_map(|r| r.strip_prefix("warning: "))
            .map(move |r| format!("the build had warned: {}: {r}", n.name))
    }));
    match e {
        Error::Simulation { step, message } if !before.is_empty() => {
            Error::Simulation { step, message: format!("{message}; before it, {}", before.join("; ")) }
        }
        e => e,
    }
}

/// Says what building the world found (remarks on each body, each unloaded shape recovered),
/// and returns why the run is not a result already, if it is not: an unloaded shape that,
/// loaded again, misses the shape given by more than a tenth of its spacing.
fn say_findings(file: &SceneFile, built: &Built, note: &mut dyn FnMut(&str)) -> Vec<String> {
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
                note(&format!(
                    "warning: {said}; the run is not a result (the recovery could not undo so large a sag: check the body's young_kpa, and the reference gravity's direction and units, docs/gravity.md)"
                ));
                not_a_result.push(why);
            }
        }
    }
    not_a_result
}

/// Warns that a settling run's schedule is longer than its `max_steps`.
fn warn_short(file: &SceneFile, built: &Built, note: &mut dyn FnMut(&str)) {
    // The explicit step is bound by stability (a stiff or nearly incompressible body's is
    // small): the implicit integrator's is not.
    let or_implicit = if built.world.integrator == voxcollide_sim::Integrator::Explicit {
        ", or step with [time] integrator = \"implicit\", whose step is not bound by stability"
    } else {
        ""
    };
    note(&format!(
        "warning: the schedule needs {} steps (dt {:.3e} s), more than max_steps = {}: the run will stop before it ends; raise [time] max_steps or shorten the schedule{or_implicit}",
        built.steps, built.dt, file.time.max_steps
    ));
}

/// The run's steps: the schedule's frames, then settling, and the stepping between frames.
struct Schedule {
    /// Steps of the schedule.
    planned: u64,
    /// Frames over the schedule.
    frames: u64,
    /// Steps between frames on the schedule, at most.
    chunk: u64,
    /// The settling window, in steps: frames past the schedule are at least this far apart.
    window: u64,
    /// Steps between the contacts' checks between frames.
    check_every: u64,
    /// Whether the run settles past its schedule, and where it stops if it does not come to
    /// rest.
    settle: bool,
    max_steps: u64,
    /// Steps done.
    done: u64,
    /// Seconds spent stepping (frames excluded).
    seconds: f64,
}

impl Schedule {
    fn new(file: &SceneFile, built: &Built, window: u64) -> Schedule {
        let frames = u64::from(file.output.frames);
        let planned = built.steps;
        let chunk = planned.div_ceil(frames).max(1);
        Schedule {
            planned,
            frames,
            chunk,
            window,
            // The contacts are checked at every frame and, between frames, at least 64 times
            // over the schedule and 4 times a settling window (docs/design.md §11: a failed
            // contact is never shown as a result).
            check_every: (planned / 64).min(window / 4).clamp(1, chunk),
            settle: file.time.settle,
            max_steps: file.time.max_steps,
            done: 0,
            seconds: 0.0,
        }
    }

    /// The step of the frame after `frame`: on the schedule, frame k at step
    /// ⌈k · steps / frames⌉ (evenly, the last at its end); past it, frames a settling window
    /// apart.
    fn next_frame(&self, frame: u32) -> u64 {
        let next = if self.done >= self.planned {
            self.done + self.chunk.max(self.window)
        } else {
            ((u64::from(frame) + 1) * self.planned).div_ceil(self.frames).max(self.done + 1)
        };
        next.min(if self.settle { self.max_steps } else { self.planned })
    }

    /// Steps `run` to `target` (sooner where the implicit integrator comes to rest while
    /// settling), checking the contacts every `check_every` steps on the way (as part of
    /// `frame`, the frame being stepped to), calling `progress(done, planned)`. Returns whether
    /// it stopped because the run came to rest (at `target` or before it).
    fn step_to(
        &mut self,
        run: &mut dyn Simulation,
        target: u64,
        (checks, summary, frame): (&mut ContactChecks, &mut FileSummary, u32),
        progress: &mut dyn FnMut(u64, u64),
        note: &mut dyn FnMut(&str),
    ) -> Result<bool, Error> {
        let mut started = Instant::now();
        let mut rested = false;
        while self.done < target {
            run.step()?;
            self.done += 1;
            let done = self.done;
            // The implicit integrator at rest needs no more steps to show it.
            if self.settle
                && done >= self.planned
                && run.residual().map(|r| r.relative()).is_some_and(|r| r <= RESIDUAL_TOLERANCE)
            {
                rested = true;
                break;
            }
            if done.is_multiple_of(16) || done == target {
                progress(done, self.planned.max(done));
            }
            if done.is_multiple_of(self.check_every) && done < target {
                self.seconds += started.elapsed().as_secs_f64();
                let (world, reports) = run.frame()?;
                checks.check(world, &reports, summary, done, frame, false, note)?;
                started = Instant::now();
            }
        }
        self.seconds += started.elapsed().as_secs_f64();
        Ok(rested)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_blow_up_after_a_failed_contact_names_that_failure() {
        let blow_up = || Error::Simulation { step: 124, message: "breast: vertex 944 moves at 7.9e3".into() };
        let mut summary = FileSummary::default();
        summary.contacts.push(summary::ContactSummary {
            a: "implant".into(),
            b: "breast".into(),
            ..Default::default()
        });
        let mut notes = vec![voxcollide_sim::build::BodyNote::new("implant", 100)];
        notes[0].remarks.push("its base moved 12 mm".into());
        // While every contact held, and the build warned of nothing, the blow-up is as it was.
        assert_eq!(after_failures(blow_up(), &summary, &notes), blow_up());
        summary.contacts[0].failure = Some("1 of implant's vertices came through breast at step 99".into());
        notes[0].remarks.push("warning: \"breast\" is 5.3 mm thick over the implant's rim".into());
        let Error::Simulation { step, message } = after_failures(blow_up(), &summary, &notes) else {
            panic!()
        };
        assert_eq!(step, 124);
        assert_eq!(
            message,
            "breast: vertex 944 moves at 7.9e3; before it, contact implant – breast had not held: 1 of implant's vertices came through breast at step 99; the build had warned: implant: \"breast\" is 5.3 mm thick over the implant's rim"
        );
        // Other errors are left alone.
        let io = Error::Io { path: "x".into(), message: "y".into() };
        assert_eq!(after_failures(io.clone(), &summary, &notes), io);
    }
}
