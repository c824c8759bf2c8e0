//! Worlds stepped on the CPU: each contact on the parallel collision backend (the reference's
//! reports, on all cores), then spring forces and integration for every body.

use glam::{Mat3, Vec3};

use crate::body::StepInputs;
use crate::contact::{SurfaceContact, SurfaceForces, SurfaceStats};
use crate::implicit::{
    BodyStep, Coupling, Guess, ImplicitSettings, Residual, StepStats, integrate_implicit_together,
};
use crate::scene::Scene;
use crate::world::{Integrator, World};
use voxcollide::error::Error;
use voxcollide::parallel::ParallelCpuCollision;
use voxcollide::params::Response;
use voxcollide::report::ContactReport;

/// A world stepping on the CPU.
pub struct CpuWorld {
    /// The world, whose bodies move as it steps.
    pub world: World,
    collisions: Vec<ParallelCpuCollision>,
    /// Per contact: its surface contact, where it has one (then its collision is not stepped).
    surfaces: Vec<Option<SurfaceContact>>,
    /// Per contact: the surface contact's last forces and stiffness blocks.
    surface_forces: Vec<SurfaceForces>,
    /// Per contact: what its surface contact found at the last step.
    pub surface_stats: Vec<SurfaceStats>,
    /// The last step's contact report of each contact.
    pub reports: Vec<ContactReport>,
    contacts_of: Vec<Vec<(usize, bool)>>,
    contact_force: Vec<Vec<Vec3>>,
    /// Per body: its forces this step.
    forces: Vec<Vec<Vec3>>,
    step: u64,
    /// Simulated seconds so far.
    pub time: f64,
    /// Implicit only: the last step's residual at rest over all bodies (at its start).
    pub residual: Residual,
    /// Implicit only: the last step's solve, per body.
    pub stats: Vec<StepStats>,
    /// Implicit only: the step is the schedule's times this (see [`accelerate`](Self::accelerate)).
    dt_scale: f32,
    accelerate_to: f32,
    /// Implicit only: the last step's answer, where the next solve starts (part of the
    /// world's state: a step taken again from the same positions and velocities takes it too).
    pub guess: Guess,
    /// Implicit only: the steps taken in parts (see [`ImplicitSettings::split_far`]).
    pub parts: Parts,
    /// The fills' held pressures at the start of a part, put back where it is refused.
    kept: Vec<f32>,
}

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
    *held = Residual { peak_gross: held.peak_gross.max(now.gross), ..now };
    next_dt_scale(dt_scale, accelerate_to, before, now.net, stats, settings)
}

/// The most parts one implicit step is taken in while a schedule runs; the last of them is
/// scaled down if it would still carry a vertex farther than the largest move.
pub const MAX_SUBSTEPS: u32 = 64;

impl CpuWorld {
    /// Starts `world` at step 0.
    ///
    /// # Errors
    /// The contact-parameter errors of [`ParallelCpuCollision::new`].
    pub fn new(world: World) -> Result<CpuWorld, Error> {
        let collisions = world
            .contacts
            .iter()
            .map(|c| ParallelCpuCollision::new(c.grid, c.params).and_then(|p| p.with_response(c.response)))
            .collect::<Result<Vec<_>, _>>()?;
        let surfaces = world
            .contacts
            .iter()
            .map(|c| {
                c.surface.map(|p| SurfaceContact::new(p, &world.bodies[c.a], &world.bodies[c.b])).transpose()
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(CpuWorld {
            surface_forces: vec![SurfaceForces::default(); surfaces.len()],
            surface_stats: vec![SurfaceStats::default(); surfaces.len()],
            surfaces,
            reports: vec![ContactReport::default(); collisions.len()],
            contacts_of: world.contacts_of(),
            contact_force: world.bodies.iter().map(|b| vec![Vec3::ZERO; b.len()]).collect(),
            forces: Vec::new(),
            stats: vec![StepStats::default(); world.bodies.len()],
            collisions,
            world,
            step: 0,
            time: 0.0,
            residual: Residual::default(),
            dt_scale: 1.0,
            accelerate_to: 1.0,
            guess: Guess::default(),
            parts: Parts::default(),
            kept: Vec::new(),
        })
    }

    /// Implicit only: from now on, let the step grow up to `factor` times the schedule's while
    /// every solve converges and no vertex is held to the step's largest move, halving it when
    /// one is (pseudo-transient continuation: towards rest, with the loads at their final
    /// values, the equilibrium does not depend on the step). 1 returns to the schedule's step.
    pub fn accelerate(&mut self, factor: f32) {
        self.accelerate_to = factor.max(1.0);
        if factor <= 1.0 {
            self.dt_scale = 1.0;
        }
    }

    /// The step the last step took, in seconds, relative to the schedule's.
    #[must_use]
    pub fn dt_scale(&self) -> f32 {
        self.dt_scale
    }

    /// Implicit only: how finely the positions resolve the residual at rest, on the same scale
    /// as [`residual`](Self::residual)'s [`Residual::relative`]: each body's
    /// [`MassSpring::residual_floor`](crate::MassSpring::residual_floor) (in quadrature) over
    /// the residual's gross force. A residual near it is as balanced as `f32` positions can
    /// be. `None` under the explicit integrator, before the first step, or where nothing has
    /// pushed yet.
    #[must_use]
    pub fn residual_floor(&self) -> Option<f64> {
        if self.world.integrator == Integrator::Explicit || self.step == 0 {
            return None;
        }
        let inputs = self.world.inputs(self.step - 1).ok()?;
        let net = self
            .world
            .bodies
            .iter()
            .zip(&inputs)
            .zip(&self.contact_force)
            .map(|((b, i), c)| b.residual_floor(i, c).powi(2))
            .sum::<f64>()
            .sqrt();
        let scale = self.residual.gross.max(crate::implicit::UNLOADED * self.residual.peak_gross);
        (scale > 0.0).then(|| net / scale)
    }

    /// Steps taken so far.
    #[must_use]
    pub fn steps_done(&self) -> u64 {
        self.step
    }

    /// One step: every contact's collision → each body's contact forces, summed in contact
    /// order → spring forces → integration.
    ///
    /// # Errors
    /// Collision errors, and [`Error::Simulation`] when a vertex's position stops being finite
    /// or its speed runs away (naming the step, the body and the vertex).
    pub fn step(&mut self) -> Result<(), Error> {
        // On one of the pool's threads: each parallel loop within is then a fork on a worker,
        // not a job sent to the pool from outside it and waited for asleep.
        rayon::scope(|_| self.step_on_pool())
    }

    fn step_on_pool(&mut self) -> Result<(), Error> {
        let w = &self.world;
        let mut inputs = w.inputs(self.step)?;
        let implicit = match w.integrator {
            Integrator::Explicit => None,
            // Settling: each solve as far as the step towards rest needs.
            Integrator::Implicit(s) => Some(s.for_step(self.accelerate_to > 1.0)),
        };
        if implicit.is_some() {
            inputs.iter_mut().for_each(|i| i.dt *= self.dt_scale);
        }
        let mut parts = std::mem::take(&mut self.parts);
        let residual = parts.step(self, &inputs, implicit, self.accelerate_to > 1.0);
        self.parts = parts;
        let residual = residual?;
        let w = &self.world;
        if let Some(settings) = implicit {
            self.dt_scale = after_implicit_step(
                &mut self.residual,
                residual,
                self.dt_scale,
                self.accelerate_to,
                &self.stats,
                &settings,
            );
        }
        self.time += f64::from(inputs.first().map_or(0.0, |i| i.dt));
        self.step += 1;
        for (k, body) in w.bodies.iter().enumerate() {
            if let Some((_, what)) = body.blow_up(w.v_max) {
                return Err(w.blow_up(self.step, k, &what));
            }
        }
        Ok(())
    }

    /// One step (or part of one) with `inputs`: every contact's collision, each body's contact
    /// forces summed in contact order, spring forces, and integration, explicit or with
    /// `implicit`'s settings. Returns the residual at rest at its start (implicit only).
    fn advance(
        &mut self,
        inputs: &[StepInputs],
        implicit: Option<ImplicitSettings>,
    ) -> Result<Residual, Error> {
        let w = &mut self.world;
        for (c, pair) in w.contacts.iter().enumerate() {
            let (a, b) = (&w.bodies[pair.a], &w.bodies[pair.b]);
            match &mut self.surfaces[c] {
                Some(surface) => {
                    let out = &mut self.surface_forces[c];
                    self.surface_stats[c] = surface.step(a, b, out);
                    let r = &mut self.reports[c];
                    r.force_a.clone_from(&out.force_a);
                    r.force_b.clone_from(&out.force_b);
                    r.colliding_b.clone_from(&out.touching_b);
                    r.binned_a = a.len() as u32;
                    r.discarded_a = 0;
                    r.grid_center = pair.grid.center();
                }
                None => self.collisions[c].step_into(&a.pos, &b.pos, &mut self.reports[c])?,
            }
        }
        let mut residual = Residual::default();
        // Implicit: per body, the voxel model's contact stiffness and what it pushes against.
        let mut voxel_k: Vec<Vec<Mat3>> = Vec::new();
        let mut voxel_vel: Vec<Vec<Vec3>> = Vec::new();
        self.forces.resize_with(w.bodies.len(), Vec::new);
        for (k, body) in w.bodies.iter_mut().enumerate() {
            let sum = &mut self.contact_force[k];
            for (n, &(c, as_a)) in self.contacts_of[k].iter().enumerate() {
                let f = if as_a { &self.reports[c].force_a } else { &self.reports[c].force_b };
                if n == 0 {
                    sum.copy_from_slice(f);
                } else {
                    sum.iter_mut().zip(f).for_each(|(s, f)| *s += *f);
                }
            }
            body.hold_fill(&inputs[k]);
            let force = &mut self.forces[k];
            body.forces(&inputs[k], sum, force);
            if implicit.is_none() {
                body.integrate(&inputs[k], force);
                continue;
            }
            // Each voxel-model penalty's stiffness along the force it gives each vertex it
            // pushes (it pushes from a surface standing still). A surface contact's pushes
            // couple the two bodies in the solve instead.
            let mut contact_k = vec![Mat3::ZERO; body.len()];
            for &(c, as_a) in &self.contacts_of[k] {
                if self.surfaces[c].is_some() {
                    continue;
                }
                let Response::Penalty { stiffness, .. } = w.contacts[c].response else { continue };
                let f = if as_a { &self.reports[c].force_a } else { &self.reports[c].force_b };
                for (kc, f) in contact_k.iter_mut().zip(f) {
                    let len = f.length();
                    if len > 0.0 {
                        let n = *f / len;
                        *kc += stiffness * Mat3::from_cols(n * n.x, n * n.y, n * n.z);
                    }
                }
            }
            voxel_vel.push(vec![Vec3::ZERO; body.len()]);
            voxel_k.push(contact_k);
            residual = residual.plus(body.residual(&inputs[k], sum));
        }
        if let Some(settings) = implicit {
            let mut couplings = Vec::new();
            for (c, pair) in w.contacts.iter().enumerate() {
                let Some(surface) = &self.surfaces[c] else { continue };
                let stiffness = surface.penalty.stiffness;
                couplings.extend(
                    self.surface_forces[c].pushes.iter().map(|p| Coupling::of_push(p, pair, stiffness)),
                );
            }
            let steps: Vec<BodyStep> = (0..w.bodies.len())
                .map(|k| BodyStep {
                    inputs: &inputs[k],
                    forces: &self.forces[k],
                    contact: &self.contact_force[k],
                    contact_k: &voxel_k[k],
                    contact_vel: &voxel_vel[k],
                })
                .collect();
            self.stats =
                integrate_implicit_together(&mut w.bodies, &steps, &couplings, &settings, &mut self.guess);
        }
        Ok(residual)
    }
}

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

impl Stepper for CpuWorld {
    fn advance(
        &mut self,
        inputs: &[StepInputs],
        implicit: Option<ImplicitSettings>,
    ) -> Result<Residual, Error> {
        CpuWorld::advance(self, inputs, implicit)
    }

    fn solves(&self) -> &[StepStats] {
        &self.stats
    }

    fn keep(&mut self) {
        self.kept = self.world.bodies.iter().map(|b| b.held_pressure).collect();
    }

    fn put_back(&mut self) {
        for (body, held) in self.world.bodies.iter_mut().zip(&self.kept) {
            body.held_pressure = *held;
        }
    }

    fn set_solves(&mut self, stats: Vec<StepStats>) {
        self.stats = stats;
    }
}

/// A paper scene stepping on the CPU: the scene's world of two bodies (tissue, foreign body)
/// and one contact.
pub struct CpuSim {
    /// The scene, whose bodies move as it steps.
    pub scene: Scene,
    world: CpuWorld,
    /// The last step's contact report.
    pub report: ContactReport,
}

impl CpuSim {
    /// Starts `scene` at step 0.
    ///
    /// # Errors
    /// The contact-parameter errors of [`ParallelCpuCollision::new`].
    pub fn new(scene: Scene) -> Result<CpuSim, Error> {
        let world = CpuWorld::new(scene.world()?)?;
        Ok(CpuSim { scene, world, report: ContactReport::default() })
    }

    /// Starts `scene` as `world` steps it: the world of a scene file that stands for it
    /// ([`Scene::check_world`]), such as the shipped `scenes/implant.toml`.
    ///
    /// # Errors
    /// Those of [`Scene::check_world`] and of [`CpuWorld::new`].
    pub fn with_world(scene: Scene, world: World) -> Result<CpuSim, Error> {
        scene.check_world(&world)?;
        let world = CpuWorld::new(world)?;
        Ok(CpuSim { scene, world, report: ContactReport::default() })
    }

    /// Steps taken so far.
    #[must_use]
    pub fn steps_done(&self) -> u64 {
        self.world.steps_done()
    }

    /// One step: collision (A = foreign body, B = tissue) → penalty forces → spring forces →
    /// integration.
    ///
    /// # Errors
    /// Collision errors, and [`Error::Simulation`] when a vertex's position stops being finite
    /// or its speed runs away.
    pub fn step(&mut self) -> Result<(), Error> {
        let result = self.world.step();
        self.scene.follow(&self.world.world);
        self.report.clone_from(&self.world.reports[0]);
        result
    }
}
