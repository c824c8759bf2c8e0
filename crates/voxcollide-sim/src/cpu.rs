//! The scene stepped on the CPU: the reference collision backend, then spring forces and
//! integration for both bodies.

use glam::Vec3;

use crate::scene::Scene;
use voxcollide::collision::Collision;
use voxcollide::cpu::CpuCollision;
use voxcollide::error::Error;
use voxcollide::report::ContactReport;

/// A scene stepping on the CPU.
pub struct CpuSim {
    /// The scene, whose bodies move as it steps.
    pub scene: Scene,
    collision: CpuCollision,
    force_tissue: Vec<Vec3>,
    force_foreign: Vec<Vec3>,
    /// The last step's contact report.
    pub report: ContactReport,
    step: u64,
}

impl CpuSim {
    /// Starts `scene` at step 0.
    ///
    /// # Errors
    /// The contact-parameter errors of [`CpuCollision::new`].
    pub fn new(scene: Scene) -> Result<CpuSim, Error> {
        let collision = CpuCollision::new(scene.grid, scene.params)?;
        Ok(CpuSim {
            scene,
            collision,
            force_tissue: Vec::new(),
            force_foreign: Vec::new(),
            report: ContactReport::default(),
            step: 0,
        })
    }

    /// Steps taken so far.
    #[must_use]
    pub fn steps_done(&self) -> u64 {
        self.step
    }

    /// One step: collision (A = foreign body, B = tissue) → penalty forces → spring forces →
    /// integration.
    ///
    /// # Errors
    /// Collision errors, and [`Error::Simulation`] when a vertex's position stops being finite
    /// or its speed runs away.
    pub fn step(&mut self) -> Result<(), Error> {
        let s = &mut self.scene;
        self.report = self.collision.step(&s.foreign.pos, &s.tissue.pos)?;
        let (in_t, in_f) = s.inputs(self.step);
        s.tissue.forces(&in_t, &self.report.force_b, &mut self.force_tissue);
        s.foreign.forces(&in_f, &self.report.force_a, &mut self.force_foreign);
        s.tissue.integrate(&in_t, &self.force_tissue);
        s.foreign.integrate(&in_f, &self.force_foreign);
        self.step += 1;
        for (name, body) in [("tissue", &s.tissue), ("foreign body", &s.foreign)] {
            if let Some((_, what)) = body.blow_up(s.v_max) {
                return Err(blow_up(self.step, name, &what, s));
            }
        }
        Ok(())
    }
}

/// The error for a blow-up seen at `step`.
pub(crate) fn blow_up(step: u64, body: &str, what: &str, scene: &Scene) -> Error {
    Error::Simulation {
        step,
        message: format!(
            "{body}: {what}; likely cause: a time step above the integrator's stability bound \
             (dt = {:.3e}) or a penalty magnitude ({}) too large for the stiffness ({})",
            scene.dt, scene.params.magnitude, scene.config.stiffness
        ),
    }
}
