//! The paper's integrator: semi-implicit (symplectic) Euler, `v += dt·f/m`, then `x += dt·v`,
//! each body on its own, its step within the stability bound. Its vertex update is
//! [`MassSpring::integrate`]; its WGSL twin is `shaders/integrate.wgsl`, bit for bit.

use super::implicit::Residual;
use super::{CpuIntegrator, Loads};
use crate::body::MassSpring;

/// The explicit step: each body's vertices moved by its own net force.
#[derive(Clone, Copy, Debug, Default)]
pub struct Explicit;

impl CpuIntegrator for Explicit {
    fn integrate(&mut self, bodies: &mut [MassSpring], loads: &Loads<'_>) -> Residual {
        for (k, body) in bodies.iter_mut().enumerate() {
            body.integrate(&loads.inputs[k], &loads.forces[k]);
        }
        Residual::default()
    }
}
