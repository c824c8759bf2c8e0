//! Sub-stepping, the bookkeeping both worlds (CPU and GPU) share around their implicit steps:
//! a step that would carry a vertex farther than its largest move taken again in parts
//! ([`Parts`]), and the step grown towards rest as the residual falls (`next_dt_scale`).
//! A world takes part in it by implementing `Stepper`.

use crate::body::StepInputs;
use crate::integrator::implicit::{ImplicitSettings, Residual, StepStats};
use voxcollide::error::Error;

/// How steeply the settling step follows the residual's fall: each step it grows by the fall
/// (the last residual over this one) to this power. Switched evolution relaxation proper (1)
/// makes the step inversely proportional to the residual, so that a residual falling by 0.4 %
/// a step grows it by 0.4 % a step: on benches/rest/compare.toml's 300 mL candidate the step
/// reached 14× the schedule's in 527 settling steps. At 4 it reached the rest criterion in 159
/// (the three candidates: 2,125 steps → 1,056), and a residual that rises shrinks it as fast.
pub const SETTLE_GROWTH: i32 = 4;

/// The implicit step's next scale over the schedule's, after a step at `dt_scale` whose
/// solves gave `stats` and whose residual at rest went from `before` to `now` (net forces):
/// switched evolution relaxation, steepened ([`SETTLE_GROWTH`]). The step grows as the
/// residual falls and shrinks as it rises (a contact chattering), by at most ×1.5 and at
/// least ×0.5 a step, halving where a solve fell short or a vertex was held to the largest
/// move; it stays within `1..=accelerate_to`. (Growing by a fifth each step whatever the
/// residual did was tried: a 30 kPa shell under 30 kPa tissue then stalled 5.6 % short of its
/// volume with the residual at 0.56, moving too little to notice. Growing by at least a tenth
/// while the residual fell was tried too: on benches/rest/compare.toml's 300 mL the step
/// reached 64× in 100 steps, then the residual stalled at a quarter of the schedule's end, and
/// the run took 1,006 steps to 718.) Both worlds, CPU and GPU, step by it.
pub(crate) fn next_dt_scale(
    dt_scale: f32,
    accelerate_to: f32,
    before: f64,
    now: f64,
    stats: &[StepStats],
    settings: &ImplicitSettings,
) -> f32 {
    let calm = stats.iter().all(|s| s.scaled >= 1.0 && s.relative_residual <= settings.tolerance * 10.0);
    let ratio = if now > 0.0 { (before / now) as f32 } else { 1.5 };
    let grown = if calm { dt_scale * ratio.powi(SETTLE_GROWTH).clamp(0.5, 1.5) } else { dt_scale * 0.5 };
    grown.clamp(1.0, accelerate_to)
}

/// After an implicit step whose residual at rest was `now` and whose solves gave `stats`: the
/// world's residual (`held`, its largest gross force kept) updated, and the next step's scale
/// ([`next_dt_scale`]). Both worlds, CPU and GPU, keep their books by it.
pub(crate) fn after_implicit_step(
    held: &mut Residual,
    now: Residual,
    dt_scale: f32,
    accelerate_to: f32,
    stats: &[StepStats],
    settings: &ImplicitSettings,
) -> f32 {
    let before = held.net;
    *held = Residual { peak_gross: held.peak_gross.max(now.gross), quiet: held.quiet, ..now };
    next_dt_scale(dt_scale, accelerate_to, before, now.net, stats, settings)
}

/// The most parts one implicit step is taken in while a schedule runs; the last of them is
/// scaled down if it would still carry a vertex farther than the largest move.
pub const MAX_SUBSTEPS: u32 = 64;

/// What an implicit step taken in parts needs of its world: a step, or part of one, with given
/// inputs, and the state a refused part must leave as it was.
pub(crate) trait Stepper {
    /// One step (or part of one) with `inputs`, explicit or with `implicit`'s settings; the
    /// residual at rest at its start (implicit only). Its solves are then [`Stepper::solves`].
    fn advance(
        &mut self,
        inputs: &[StepInputs],
        implicit: Option<ImplicitSettings>,
    ) -> Result<Residual, Error>;
    /// The last [`advance`](Stepper::advance)'s solve, per body.
    fn solves(&self) -> &[StepStats];
    /// Keeps what a step that is not taken must leave as it was (a fill's integral term).
    fn keep(&mut self);
    /// Puts back what [`keep`](Stepper::keep) kept.
    fn put_back(&mut self);
    /// Sets the step's solves, per body (the parts' merged).
    fn set_solves(&mut self, stats: Vec<StepStats>);
}

/// How a world's implicit steps are taken: whole, or, while a schedule runs, in parts where a
/// step would carry a vertex farther than its largest move (see
/// [`ImplicitSettings::split_far`]). The CPU and the GPU world take them alike.
#[derive(Clone, Debug)]
pub struct Parts {
    /// The parts the last step was taken in (1: whole).
    pub substeps: u32,
    /// The steps so far taken in more than one part.
    pub split_steps: u64,
    /// The most parts a step has been taken in so far.
    pub most_parts: u32,
    /// The last step's inputs, where the next step's parts start from.
    last_inputs: Option<Vec<StepInputs>>,
}

impl Default for Parts {
    fn default() -> Parts {
        Parts { substeps: 1, split_steps: 0, most_parts: 1, last_inputs: None }
    }
}

impl Parts {
    /// One step of `world` with `inputs` (explicit where `implicit` is `None`). While a
    /// schedule runs (not `settling`), a step that would carry a vertex farther than its
    /// largest move is taken again as shorter steps along the schedule (a fill outrunning the
    /// step); the last step's count is where the next starts, halved. Settling (or without a
    /// largest move), a step too far is scaled down, never refused, and the step shrinks.
    pub(crate) fn step<S: Stepper>(
        &mut self,
        world: &mut S,
        inputs: &[StepInputs],
        implicit: Option<ImplicitSettings>,
        settling: bool,
    ) -> Result<Residual, Error> {
        let residual = match implicit {
            Some(settings) if settings.split_far && !settling && settings.max_move.is_finite() => {
                let from = self.last_inputs.take().unwrap_or_else(|| inputs.to_vec());
                let parts = (self.substeps / 2).max(1);
                self.substeps = 0;
                let mut stats: Vec<StepStats> = Vec::new();
                let residual = self.in_parts(world, &from, inputs, (0.0, 1.0), parts, settings, &mut stats);
                world.set_solves(stats);
                residual?
            }
            _ => {
                let r =
                    world.advance(inputs, implicit.map(|s| ImplicitSettings { split_far: false, ..s }))?;
                self.substeps = 1;
                r
            }
        };
        self.last_inputs = Some(inputs.to_vec());
        if self.substeps > 1 {
            self.split_steps += 1;
        }
        self.most_parts = self.most_parts.max(self.substeps);
        Ok(residual)
    }

    /// Splits the part `(t0, t1)` of the step from `from` to `to`: taken in one where no vertex
    /// would move farther than the largest move, else as shorter parts (at most
    /// [`MAX_SUBSTEPS`] in all, the last of them scaled). Adds each part's solve to `stats`
    /// and returns the first part's residual.
    #[allow(clippy::too_many_arguments)]
    fn split<S: Stepper>(
        &mut self,
        world: &mut S,
        from: &[StepInputs],
        to: &[StepInputs],
        (t0, t1): (f32, f32),
        settings: ImplicitSettings,
        stats: &mut Vec<StepStats>,
    ) -> Result<Residual, Error> {
        let share = t1 - t0;
        let part: Vec<StepInputs> =
            from.iter().zip(to).map(|(a, b)| a.toward(b, t1, b.dt * share, share)).collect();
        let deepest = (share * MAX_SUBSTEPS as f32) < 2.0;
        // A part not taken leaves the world as it was: its fill's integral term too. (Not the
        // vertical speed of vertices pressed into their floor, which the solve zeroes before it
        // is refused, on the CPU and the GPU alike; the next part, from the same positions,
        // zeroes it again where they are still pressed.)
        world.keep();
        let residual = world.advance(&part, Some(ImplicitSettings { split_far: !deepest, ..settings }))?;
        let solves = world.solves();
        let taken = solves.iter().all(|s| s.taken);
        if stats.is_empty() {
            stats.extend_from_slice(solves);
        } else {
            for (s, n) in stats.iter_mut().zip(solves) {
                s.iterations += n.iterations;
                s.relative_residual = s.relative_residual.max(n.relative_residual);
                s.scaled = s.scaled.min(n.scaled);
                s.farthest = s.farthest.max(n.farthest);
            }
        }
        if taken {
            self.substeps += 1;
            return Ok(residual);
        }
        // Parts short enough that each moves within the largest move, with a quarter to spare.
        let farthest = solves.iter().map(|s| s.farthest).fold(0.0, f32::max);
        world.put_back();
        let wanted = (1.25 * farthest / settings.max_move).ceil().clamp(2.0, 16.0) as u32;
        let parts = wanted.min(((share * MAX_SUBSTEPS as f32) as u32).max(2));
        self.in_parts(world, from, to, (t0, t1), parts, settings, stats)
    }

    /// The part `(t0, t1)` of the step from `from` to `to` as `parts` equal parts, each
    /// [`split`](Self::split) as it needs (the last ends at `t1` exactly); the first part's
    /// residual.
    #[allow(clippy::too_many_arguments)]
    fn in_parts<S: Stepper>(
        &mut self,
        world: &mut S,
        from: &[StepInputs],
        to: &[StepInputs],
        (t0, t1): (f32, f32),
        parts: u32,
        settings: ImplicitSettings,
        stats: &mut Vec<StepStats>,
    ) -> Result<Residual, Error> {
        let share = t1 - t0;
        let mut first = None;
        for j in 0..parts {
            let (a, b) = (t0 + share * j as f32 / parts as f32, t0 + share * (j + 1) as f32 / parts as f32);
            let r = self.split(world, from, to, (a, if j + 1 == parts { t1 } else { b }), settings, stats)?;
            first.get_or_insert(r);
        }
        Ok(first.unwrap_or_default())
    }
}
