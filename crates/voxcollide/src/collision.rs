//! The paper's `Collision`: one facade over detection and elimination, whatever the backend.

use glam::Vec3;

use crate::error::Error;
use crate::report::ContactReport;

/// A collision backend: given the current positions of both bodies, finds their contacts and
/// the penalty forces that push them apart.
pub trait Collision {
    /// Runs one step: (re)positions the grid, bins A, probes B and computes the forces.
    ///
    /// # Errors
    /// [`Error::EmptyBody`] or [`Error::TooManyVertices`] for a body of bad size, and
    /// [`Error::ForceOverflow`] when the force on an A vertex leaves the fixed-point range.
    /// Non-finite vertices are not an error: they are discarded and counted.
    fn step(&mut self, a: &[Vec3], b: &[Vec3]) -> Result<ContactReport, Error>;
}
