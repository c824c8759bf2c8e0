//! Worlds stepped on the CPU: each contact on the parallel collision backend (the reference's
//! reports, on all cores), then spring forces and integration for every body.

use glam::Vec3;

use crate::scene::Scene;
use crate::world::World;
use voxcollide::error::Error;
use voxcollide::parallel::ParallelCpuCollision;
use voxcollide::report::ContactReport;

/// A world stepping on the CPU.
pub struct CpuWorld {
    /// The world, whose bodies move as it steps.
    pub world: World,
    collisions: Vec<ParallelCpuCollision>,
    /// The last step's contact report of each contact.
    pub reports: Vec<ContactReport>,
    contacts_of: Vec<Vec<(usize, bool)>>,
    contact_force: Vec<Vec<Vec3>>,
    force: Vec<Vec3>,
    step: u64,
}

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
        Ok(CpuWorld {
            reports: vec![ContactReport::default(); collisions.len()],
            contacts_of: world.contacts_of(),
            contact_force: world.bodies.iter().map(|b| vec![Vec3::ZERO; b.len()]).collect(),
            force: Vec::new(),
            collisions,
            world,
            step: 0,
        })
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
        let w = &mut self.world;
        for (c, pair) in w.contacts.iter().enumerate() {
            let (a, b) = (&w.bodies[pair.a].pos, &w.bodies[pair.b].pos);
            self.collisions[c].step_into(a, b, &mut self.reports[c])?;
        }
        let inputs = w.inputs(self.step)?;
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
            body.forces(&inputs[k], sum, &mut self.force);
            body.integrate(&inputs[k], &self.force);
        }
        self.step += 1;
        for (k, body) in w.bodies.iter().enumerate() {
            if let Some((_, what)) = body.blow_up(w.v_max) {
                return Err(w.blow_up(self.step, k, &what));
            }
        }
        Ok(())
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
