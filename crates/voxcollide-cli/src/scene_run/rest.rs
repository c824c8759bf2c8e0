//! Whether a run has come to rest: the integrators' own tests (motion over a settling window
//! for the explicit one, the residual force for the implicit one), and a settling whose
//! residual has stopped falling.

use glam::Vec3;

use voxcollide_sim::{MassSpring, World};

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

/// Settling windows without the residual falling by a tenth before [`Stall`] says so, over
/// at least two frames. (Eight were tried first: on the MakeHuman patient, six Mentor
/// candidates at 6 mm (docs/patient.md) took 2,917 steps in all; at four, 2,339, each nipple
/// within 0.6 mm and each volume added within 2 mL of the eight's. The residual had stopped
/// falling: the longer wait bought the pocket's suction time to wind up, and the 400 cc ended
/// deep at eight and held at four. Those were counted in frames, which past the schedule are as
/// far apart as on it: there, 50 steps against a window of 18.)
pub(crate) const STALL_WINDOWS: u64 = 4;

impl Stall {
    /// The residual `r` at a settling frame at step `step`, with a settling window of `window`
    /// steps: the step since which it has not fallen by a tenth, the first time that has lasted
    /// [`STALL_WINDOWS`] windows and two frames (once a run).
    pub(crate) fn stalled(&mut self, step: u64, r: f64, window: u64) -> Option<u64> {
        match self.best {
            Some((best, _)) if r.is_nan() || r >= 0.9 * best => self.frames += 1,
            _ => {
                self.best = Some((r, step));
                self.frames = 0;
            }
        }
        let lasted = self.best.is_some_and(|(_, at)| step - at >= STALL_WINDOWS * window);
        if self.frames >= 2 && lasted && !self.said {
            self.said = true;
            return self.best.map(|(_, at)| at);
        }
        None
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
/// fraction of the gross force (see [`FileSummary::residual`](super::FileSummary::residual)).
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

/// A frame's verdict ([`Rest::judge`]).
pub(super) struct Verdict {
    /// Whether the bodies are at rest by their integrator's test.
    pub at_rest: bool,
    /// The farthest a vertex not held moved since the last frame, or since the mark a settling
    /// window before this frame where there is one ([`Rest::mark`]), in spacings of its body
    /// (infinite at the first frame).
    pub motion: f32,
}

/// Whether a run has come to rest, judged at each frame against the last, or against the mark
/// a settling window before it ([`Rest::mark`]).
pub(super) struct Rest {
    /// The settling window, in steps ([`settling_window`]).
    pub window: u64,
    /// Each body's spacing ([`mean_spring`]) and whether it is soft.
    spacings: Vec<f32>,
    soft: Vec<bool>,
    /// Where the vertices were at the last frame, and its step.
    before: Option<(u64, Vec<Vec<Vec3>>)>,
    /// Where they were a settling window before this frame, and its step, where frames are
    /// farther apart than that ([`Rest::mark`]).
    mark: Option<(u64, Vec<Vec<Vec3>>)>,
    stall: Stall,
    /// The step since which the implicit integrator's residual has stalled, once it has.
    pub stalled_since: Option<u64>,
}

impl Rest {
    /// The judge for `world` stepped by `dt`, whose bodies `soft` says are soft.
    pub fn new(world: &World, dt: f32, soft: Vec<bool>) -> Rest {
        Rest {
            window: settling_window(world, dt),
            spacings: world.bodies.iter().map(mean_spring).collect(),
            soft,
            before: None,
            mark: None,
            stall: Stall::default(),
            stalled_since: None,
        }
    }

    /// Keeps where `world`'s vertices are at step `step`, a settling window before the next
    /// frame: the next verdict judges their motion since then, over the window, not since the
    /// last frame (frames past the schedule are as far apart as frames on it, which may be
    /// longer than a window; judged over that, a body was held settling longer than the rule
    /// says, with nothing in its summary saying so).
    pub fn mark(&mut self, world: &World, step: u64) {
        self.mark = Some((step, world.bodies.iter().map(|b| b.pos.clone()).collect()));
    }

    /// The verdict on `world` after `done` of the `planned` steps, with the implicit
    /// integrator's `residual` force and the `floor` positions resolve it to. While the run
    /// `settles`, a residual that has stopped falling is said through `note` once, as soon as
    /// it is seen (`max_steps`: where the run will stop).
    #[allow(clippy::too_many_arguments)]
    pub fn judge(
        &mut self,
        world: &World,
        (done, planned): (u64, u64),
        residual: Option<f64>,
        floor: Option<f64>,
        (settles, max_steps): (bool, u64),
        note: &mut dyn FnMut(&str),
    ) -> Verdict {
        // Judged since the mark, a window before this frame, where there is one; else since
        // the last frame.
        let mark = self.mark.take().filter(|(at, _)| *at < done);
        let since = mark.as_ref().or(self.before.as_ref());
        let motion = since.map_or(f32::INFINITY, |(_, was)| frame_motion(world, was, &self.spacings));
        let long_enough = since.is_some_and(|(at, _)| done - at >= self.window);
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
            && self.stalled_since.is_some()
            && long_enough
            && since.is_some_and(|(_, was)| {
                most_motion(world, was, &self.spacings, &self.soft) <= REST_TOLERANCE
            });
        let at_rest = still || balanced || stalled_still;
        // Settling whose residual has stopped falling is said as soon as it is seen, not only
        // after max_steps.
        if let Some(r) = residual.filter(|_| settles && done >= planned && !at_rest)
            && let Some(since) = self.stall.stalled(done, r, self.window)
        {
            self.stalled_since = Some(since);
            let floor = floor.map_or(String::new(), |f| {
                format!(" (single-precision positions resolve it to about {f:.1e})")
            });
            note(&format!(
                "warning: settling has stalled: the residual force has stayed near {r:.2e} of the largest load (at rest: {RESIDUAL_TOLERANCE:.0e}){floor} since step {since}, {} steps; the run goes on until the shape is still (no vertex moving a twentieth of its spacing over a settling window), or to max_steps = {max_steps}",
                done - since,
            ));
        }
        self.before = Some((done, world.bodies.iter().map(|b| b.pos.clone()).collect()));
        Verdict { at_rest, motion }
    }
}

#[cfg(test)]
mod stall_tests {
    use super::{STALL_WINDOWS, Stall};

    /// A residual falling steadily, even slowly, is not a stall; one that stops falling is said
    /// once, after STALL_WINDOWS settling windows and at least two frames, naming the step it
    /// stopped at; a NaN residual counts as not falling.
    #[test]
    fn settling_is_said_to_stall_once_its_residual_stops_falling() {
        let mut s = Stall::default();
        for k in 0..100u64 {
            assert_eq!(s.stalled(100 * k, 0.85f64.powi(k as i32), 100), None, "frame {k}");
        }
        // Falls to 1e-2 by frame 5, then wanders within a few percent.
        let wandering =
            |k: u64| if k < 5 { 0.5f64.powi(k as i32) } else { 0.0625 * (1.0 + 0.05 * ((k % 3) as f64)) };
        let said = |window: u64| {
            let mut s = Stall::default();
            (0..40u64)
                .filter_map(|k| s.stalled(100 * k, wandering(k), window).map(|since| (k, since)))
                .collect::<Vec<_>>()
        };
        // Frames a window apart: four frames; farther apart, four windows' worth of frames;
        // and never fewer than two frames.
        assert_eq!(said(100), [(4 + STALL_WINDOWS, 400)]);
        assert_eq!(said(60), [(4 + 3, 400)]);
        assert_eq!(said(10), [(4 + 2, 400)]);
        let mut s = Stall::default();
        let said: Vec<u64> =
            (0..20u64).filter_map(|k| s.stalled(k, if k == 0 { 1.0 } else { f64::NAN }, 1)).collect();
        assert_eq!(said, [0]);
    }
}

#[cfg(test)]
mod window_tests {
    use super::Rest;
    use glam::{UVec3, Vec3};
    use voxcollide_sim::bodies::box_lattice;
    use voxcollide_sim::{Material, Mode, StepInputs, World};

    /// Past the schedule, frames farther apart than a settling window: a body that crept a
    /// spacing since the last frame but moved a hundredth of one over the window before this
    /// frame is judged by the hundredth where the window's start was marked, and by the whole
    /// creep where it was not.
    #[test]
    fn settling_motion_is_judged_over_the_window_before_the_frame() {
        let material = Material { mass: 1.0, stiffening: 0.0, spring_damping: 0.0, damping: 0.0 };
        let body = box_lattice(UVec3::new(4, 4, 4), 2.0, Vec3::ZERO, 1.0, material, |_| Mode::Free).unwrap();
        let schedule = std::sync::Arc::new(|_| vec![StepInputs::at_rest(1e-3)]);
        let world = World::new(vec!["slab".into()], vec![body], Vec::new(), 1e3, schedule).unwrap();
        let judged = |mark: bool| {
            let mut world = world.clone();
            let mut rest = Rest::new(&world, 1e-3, vec![true]);
            let window = rest.window;
            let frame = 4 * window;
            let judge = |world: &World, done: u64, rest: &mut Rest| {
                rest.judge(world, (done, 0), None, None, (true, 1_000_000), &mut |_| {})
            };
            judge(&world, 0, &mut rest);
            let shift = |world: &mut World, by: f32| world.bodies[0].pos.iter_mut().for_each(|p| p.x += by);
            shift(&mut world, 2.0);
            if mark {
                rest.mark(&world, frame - window);
            }
            shift(&mut world, 0.02);
            judge(&world, frame, &mut rest)
        };
        // (In spacings of the body: the mean rest length of its springs, diagonals included.)
        let h = super::mean_spring(&world.bodies[0]);
        let (marked, unmarked) = (judged(true), judged(false));
        assert!((marked.motion - 0.02 / h).abs() < 1e-4 && marked.at_rest, "{}", marked.motion);
        assert!((unmarked.motion - 2.02 / h).abs() < 1e-4 && !unmarked.at_rest, "{}", unmarked.motion);
    }
}
