//! Worlds stepped on the CPU: each contact on the parallel collision backend (the reference's
//! reports, on all cores), then spring forces and integration for every body.

use glam::Vec3;

use crate::body::StepInputs;
use crate::contact::{CpuContacts, SurfaceStats};
use crate::integrator::explicit::Explicit;
use crate::integrator::implicit::{Guess, Implicit, ImplicitSettings, Residual, StepStats};
use crate::integrator::substep::{Parts, Stepper, after_implicit_step};
use crate::integrator::{CpuIntegrator, Loads};
use crate::world::{Integrator, World};
use voxcollide::error::Error;
use voxcollide::report::ContactReport;

/// A world stepping on the CPU.
pub struct CpuWorld {
    /// The world, whose bodies move as it steps.
    pub world: World,
    /// Its contacts, each stepped by its model.
    contacts: CpuContacts,
    /// Per contact: what its surface contact found at the last step.
    pub surface_stats: Vec<SurfaceStats>,
    /// The last step's contact report of each contact.
    pub reports: Vec<ContactReport>,
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

impl CpuWorld {
    /// Starts `world` at step 0.
    ///
    /// # Errors
    /// The contact-parameter errors of [`CpuContacts::new`].
    pub fn new(world: World) -> Result<CpuWorld, Error> {
        let contacts = CpuContacts::new(&world.bodies, &world.contacts)?;
        let quiet = world.quiet_force();
        Ok(CpuWorld {
            surface_stats: vec![SurfaceStats::default(); contacts.len()],
            reports: vec![ContactReport::default(); contacts.len()],
            contacts,
            contact_force: world.bodies.iter().map(|b| vec![Vec3::ZERO; b.len()]).collect(),
            forces: Vec::new(),
            stats: vec![StepStats::default(); world.bodies.len()],
            world,
            step: 0,
            time: 0.0,
            residual: Residual { quiet, ..Residual::default() },
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
        let scale = self.residual.scale();
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
        self.contacts.step(
            &self.world.bodies,
            &self.world.contacts,
            &mut self.reports,
            &mut self.surface_stats,
        )?;
        let w = &mut self.world;
        self.forces.resize_with(w.bodies.len(), Vec::new);
        for k in 0..w.bodies.len() {
            self.contacts.forces_on(k, &self.reports, &mut self.contact_force[k]);
        }
        // A pocket's suction is a load beside the contacts' (crate::pocket), and the implicit
        // solve takes its stiffness.
        let mut rank_one = Vec::new();
        for pocket in &mut w.pockets {
            let suction = pocket.add_forces(&w.bodies, &mut self.contact_force);
            if implicit.is_some() {
                rank_one.push(pocket.linearised(&w.bodies, suction));
            }
        }
        for (k, body) in w.bodies.iter_mut().enumerate() {
            body.hold_fill(&inputs[k]);
            body.forces(&inputs[k], &self.contact_force[k], &mut self.forces[k]);
        }
        let loads = Loads {
            inputs,
            forces: &self.forces,
            contact: &self.contact_force,
            contacts: &self.contacts,
            reports: &self.reports,
            pairs: &w.contacts,
            rank_one: &rank_one,
        };
        let residual = match implicit {
            None => Explicit.integrate(&mut w.bodies, &loads),
            Some(settings) => Implicit { settings, guess: &mut self.guess, stats: &mut self.stats }
                .integrate(&mut w.bodies, &loads),
        };
        Ok(residual)
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
        self.kept.extend(self.world.pockets.iter().map(|p| p.held));
    }

    fn put_back(&mut self) {
        for (body, held) in self.world.bodies.iter_mut().zip(&self.kept) {
            body.held_pressure = *held;
        }
        let n = self.world.bodies.len();
        for (pocket, held) in self.world.pockets.iter_mut().zip(self.kept.iter().skip(n)) {
            pocket.held = *held;
        }
    }

    fn set_solves(&mut self, stats: Vec<StepStats>) {
        self.stats = stats;
    }
}
