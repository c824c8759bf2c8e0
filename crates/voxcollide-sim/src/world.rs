//! Any number of bodies and contacts: a [`World`] is bodies, the pairs of them that touch (each
//! with its own voxel model, the paper's one model per pair), the time step and a schedule of
//! each body's inputs. [`crate::cpu::CpuWorld`] and [`crate::gpu::GpuWorld`] step it; the paper's
//! two scenes are worlds of two bodies and one contact ([`crate::Scene::world`]).
//!
//! A body in several contacts gets their forces summed in contact order (the same `f32`
//! additions on the CPU and the GPU, so the two stay bit-identical where the collision is).

use std::sync::Arc;

use voxcollide::Error;

use crate::body::{MassSpring, StepInputs};
use crate::contact::ContactModel;
pub use crate::contact::ContactPair;
pub use crate::integrator::Integrator;

/// A blow-up's likely cause under the explicit integrator.
const EXPLICIT_CAUSE: &str = "a time step above the integrator's stability bound, a penalty magnitude too large for the bodies' stiffness, or a degenerate body";

/// A blow-up's likely cause under the implicit integrator, which has no stability bound.
const IMPLICIT_CAUSE: &str = "a body crushed or turned inside out, past where the step's linearisation holds (as after a contact failed and one body came through another), a penalty magnitude too large for the bodies' stiffness, or a degenerate body";

/// Each body's inputs at a step: `inputs(step)[k]` for body `k`.
pub type Schedule = Arc<dyn Fn(u64) -> Vec<StepInputs> + Send + Sync>;

/// Bodies, their contacts and their schedule.
#[derive(Clone)]
pub struct World {
    /// The bodies' names, for messages and output.
    pub names: Vec<String>,
    /// The bodies; they move as the world steps.
    pub bodies: Vec<MassSpring>,
    /// The pairs in contact, in the order their forces are summed.
    pub contacts: Vec<ContactPair>,
    /// The speed above which a vertex is taken to have blown up.
    pub v_max: f32,
    /// Each body's inputs (time step, drive, pressure, floor) at each step.
    pub schedule: Schedule,
    /// What a blow-up's error names as its likely cause under the explicit integrator (see
    /// [`with_cause`](Self::with_cause)); the implicit one names its own.
    pub likely_cause: String,
    /// How the bodies move from step to step.
    pub integrator: Integrator,
    /// Pockets dissected for implants placed on a patient (docs/design.md §15): their suction
    /// is a load on the CPU backend.
    pub pockets: Vec<crate::pocket::Pocket>,
}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World")
            .field("names", &self.names)
            .field("vertices", &self.bodies.iter().map(MassSpring::len).collect::<Vec<_>>())
            .field("contacts", &self.contacts)
            .field("v_max", &self.v_max)
            .finish_non_exhaustive()
    }
}

impl World {
    /// A world of `bodies` named `names` with `contacts` between them.
    ///
    /// # Errors
    /// [`Error::Invalid`] for a count of names that is not the count of bodies, an empty body,
    /// a contact naming a body that does not exist or the same body twice, or a non-positive
    /// `v_max`.
    pub fn new(
        names: Vec<String>,
        bodies: Vec<MassSpring>,
        contacts: Vec<ContactPair>,
        v_max: f32,
        schedule: Schedule,
    ) -> Result<World, Error> {
        let invalid = |what, value: String, rule: String| Error::Invalid { what, value, rule };
        if names.len() != bodies.len() {
            return Err(invalid(
                "body names",
                names.len().to_string(),
                format!("one per body ({})", bodies.len()),
            ));
        }
        if let Some(k) = bodies.iter().position(MassSpring::is_empty) {
            return Err(invalid("body", names[k].clone(), "has no vertices".into()));
        }
        for (c, pair) in contacts.iter().enumerate() {
            if pair.a >= bodies.len() || pair.b >= bodies.len() || pair.a == pair.b {
                return Err(invalid(
                    "contact",
                    format!("{c}: {} – {}", pair.a, pair.b),
                    format!("needs two different bodies of the {}", bodies.len()),
                ));
            }
            pair.params.validate(&pair.grid)?;
            pair.response().validate(&pair.params, &pair.grid)?;
            if let ContactModel::Surface(surface) = &pair.model {
                surface.validate()?;
            }
        }
        if !(v_max.is_finite() && v_max > 0.0) {
            return Err(invalid("v_max", v_max.to_string(), "must be finite and positive".into()));
        }
        Ok(World {
            names,
            bodies,
            contacts,
            v_max,
            schedule,
            likely_cause: EXPLICIT_CAUSE.into(),
            integrator: Integrator::Explicit,
            pockets: Vec::new(),
        })
    }

    /// The same world moved by `integrator`.
    #[must_use]
    pub fn with_integrator(self, integrator: Integrator) -> World {
        World { integrator, ..self }
    }

    /// The same world whose blow-up errors name `cause` as the likely one.
    #[must_use]
    pub fn with_cause(self, cause: String) -> World {
        World { likely_cause: cause, ..self }
    }

    /// The error for a blow-up of body `k` seen at `step`: `what` happened, and the likely cause.
    #[must_use]
    pub fn blow_up(&self, step: u64, k: usize, what: &str) -> Error {
        // The implicit integrator has no stability bound to blame.
        let cause = match self.integrator {
            Integrator::Implicit(_) => IMPLICIT_CAUSE,
            Integrator::Explicit => &self.likely_cause,
        };
        Error::Simulation { step, message: format!("{}: {what}; likely cause: {cause}", self.names[k]) }
    }

    /// The inputs of every body at `step`.
    ///
    /// # Errors
    /// [`Error::Invalid`] when the schedule gives a count other than the bodies'.
    pub fn inputs(&self, step: u64) -> Result<Vec<StepInputs>, Error> {
        let inputs = (self.schedule)(step);
        if inputs.len() != self.bodies.len() {
            return Err(Error::Invalid {
                what: "schedule",
                value: inputs.len().to_string(),
                rule: format!("must give inputs for each of the {} bodies", self.bodies.len()),
            });
        }
        Ok(inputs)
    }

    /// The world's quiet force: its bodies' [`MassSpring::quiet_force`] in quadrature (the
    /// implicit integrator's residual at rest is judged against no less).
    #[must_use]
    pub fn quiet_force(&self) -> f64 {
        self.bodies.iter().map(|b| b.quiet_force().powi(2)).sum::<f64>().sqrt()
    }

    /// For each body, the contacts that push it, in contact order: `(contact, as_a)`.
    #[must_use]
    pub fn contacts_of(&self) -> Vec<Vec<(usize, bool)>> {
        crate::contact::contacts_of(self.bodies.len(), &self.contacts)
    }
}

/// How long the bodies take to respond to a load: twice the time an elastic wave takes to cross
/// the largest deformable body, `2 · extent / c`, with the lattice's wave speed `c = h · √(k/m)`
/// (its mean spring length, stiffness and vertex mass), or for a body of finite elements its
/// P-wave speed `√((λ + 2μ)/ρ)`; in seconds, 0 without a deformable body. A run's settling
/// window and a fill's integral time follow it.
#[must_use]
pub fn response_time(bodies: &[MassSpring]) -> f64 {
    bodies
        .iter()
        .filter(|b| b.mode.contains(&crate::body::Mode::Free) && !b.springs.is_empty())
        .map(|b| {
            let h = b.springs.iter().map(|s| f64::from(s.rest)).sum::<f64>() / b.springs.len() as f64;
            let k = b.springs.iter().map(|s| f64::from(s.k)).sum::<f64>() / b.springs.len() as f64;
            let m = b.inv_mass.iter().map(|w| 1.0 / f64::from(*w)).sum::<f64>() / b.len() as f64;
            let (lo, hi) = b
                .rest_pos
                .iter()
                .fold((glam::Vec3::MAX, glam::Vec3::MIN), |(l, h), p| (l.min(*p), h.max(*p)));
            let speed = match &b.elements {
                Some(e) => (f64::from(e.lambda + e.mu) * h * h * h / m).sqrt(),
                None => h * (k / m).sqrt(),
            };
            2.0 * f64::from((hi - lo).max_element()) / speed
        })
        .filter(|t| t.is_finite())
        .fold(0.0, f64::max)
}
