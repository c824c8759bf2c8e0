//! `CpuCollision`: the single-threaded reference backend, written to follow docs/design.md §2 plainly.
//! Every other backend is checked against it.

use glam::Vec3;

use crate::collision::Collision;
use crate::detect::{CollisionDetector, VoxelDetector};
use crate::eliminate::{CollisionEliminator, ForceLaw, eliminator};
use crate::error::{Body, Error};
use crate::fixed_point::ForceAccumulator;
use crate::grid::VoxelGrid;
use crate::initializer::finite_bounds;
use crate::params::{Anchor, ContactParams, Direction, Response};
use crate::report::ContactReport;

/// The most vertices a body may have: indices are `u32`, with `u32::MAX` kept as the end of a
/// voxel list.
pub const MAX_VERTICES: usize = u32::MAX as usize - 1;

/// The reference collision backend on the CPU.
///
/// ```
/// use voxcollide::{glam::Vec3, *};
/// let a = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0)];
/// let grid = Initializer::new(1.0).margin(1).build(&a)?;
/// let params = ContactParams {
///     magnitude: 1.0,
///     search: Search::Neighbours { radius: 0.5 },
///     direction: Direction::Pairwise,
///     anchor: Anchor::Fixed,
/// };
/// let mut cpu = CpuCollision::new(grid, params)?;
/// let report = cpu.step(&a, &[Vec3::new(2.0, 0.25, 0.0)])?;
/// assert_eq!(report.colliding_b, vec![0]);
/// assert_eq!(report.force_b[0], Vec3::Y); // pushed along the line of centres
/// assert_eq!(report.force_a[1], -Vec3::Y);
/// # Ok::<(), voxcollide::Error>(())
/// ```
pub struct CpuCollision {
    grid: VoxelGrid,
    params: ContactParams,
    response: Response,
    detector: VoxelDetector,
    eliminator: Box<dyn CollisionEliminator + Send + Sync>,
}

impl CpuCollision {
    /// A reference backend for the pair of bodies that `grid` was built for.
    ///
    /// # Errors
    /// [`Error::Magnitude`] or [`Error::Radius`] when `params` are invalid for `grid`.
    pub fn new(grid: VoxelGrid, params: ContactParams) -> Result<CpuCollision, Error> {
        params.validate(&grid)?;
        Ok(CpuCollision {
            grid,
            params,
            response: Response::Constant,
            detector: VoxelDetector::new(params.search, params.direction == Direction::PlaneNormal),
            eliminator: eliminator(
                params.direction,
                ForceLaw::new(&params, Response::Constant, grid.voxel_size()),
            ),
        })
    }

    /// The same backend with its contacts' force magnitudes given by `response` (made by
    /// [`new`](Self::new), it is [`Response::Constant`], the paper's rule).
    ///
    /// ```
    /// use voxcollide::{glam::Vec3, *};
    /// let a = [Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0)];
    /// let grid = Initializer::new(1.0).margin(1).build(&a)?;
    /// let params = ContactParams {
    ///     magnitude: 10.0,
    ///     search: Search::Neighbours { radius: 0.5 },
    ///     direction: Direction::Pairwise,
    ///     anchor: Anchor::Fixed,
    /// };
    /// let penalty = Response::Penalty { stiffness: 4.0, gap: 0.0 };
    /// let mut cpu = CpuCollision::new(grid, params)?.with_response(penalty)?;
    /// // 0.25 from its partner, 0.25 inside the radius: a force of 4 * 0.25 = 1.
    /// let report = cpu.step(&a, &[Vec3::new(2.0, 0.25, 0.0)])?;
    /// assert_eq!(report.force_b[0], Vec3::Y);
    /// # Ok::<(), voxcollide::Error>(())
    /// ```
    ///
    /// # Errors
    /// [`Error::Response`] when `response` is invalid for the grid ([`Response::validate`]).
    pub fn with_response(self, response: Response) -> Result<CpuCollision, Error> {
        response.validate(&self.params, &self.grid)?;
        let law = ForceLaw::new(&self.params, response, self.grid.voxel_size());
        Ok(CpuCollision { response, eliminator: eliminator(self.params.direction, law), ..self })
    }

    /// How its contacts' force magnitudes are chosen.
    #[must_use]
    pub fn response(&self) -> Response {
        self.response
    }

    /// The grid as built (under [`Anchor::FollowA`] each step recentres a copy of it).
    #[must_use]
    pub fn grid(&self) -> &VoxelGrid {
        &self.grid
    }

    /// The contact parameters.
    #[must_use]
    pub fn params(&self) -> &ContactParams {
        &self.params
    }
}

/// Checks that a body is non-empty and indexable by `u32`.
pub(crate) fn check_body(body: Body, points: &[Vec3]) -> Result<(), Error> {
    if points.is_empty() {
        return Err(Error::EmptyBody { body });
    }
    if points.len() > MAX_VERTICES {
        return Err(Error::TooManyVertices { body, len: points.len(), max: MAX_VERTICES });
    }
    Ok(())
}

/// The grid of one step: `grid` itself under [`Anchor::Fixed`]; under [`Anchor::FollowA`],
/// `grid` recentred on `0.5 * (lo + hi)` of A's finite vertices (unmoved when A has none, as
/// then every A vertex is discarded anyway).
///
/// # Errors
/// [`Error::NonFiniteCenter`] when `lo + hi` overflows `f32`.
pub fn step_grid(grid: &VoxelGrid, anchor: Anchor, a: &[Vec3]) -> Result<VoxelGrid, Error> {
    // Only a grid that follows A needs A's bounds (a pass over A: 2–5 % of a parallel step).
    match anchor {
        Anchor::FollowA => match finite_bounds(a) {
            Some((lo, hi)) => grid.with_center(0.5 * (lo + hi)),
            None => Ok(*grid),
        },
        Anchor::Fixed => Ok(*grid),
    }
}

impl Collision for CpuCollision {
    fn step(&mut self, a: &[Vec3], b: &[Vec3]) -> Result<ContactReport, Error> {
        check_body(Body::A, a)?;
        check_body(Body::B, b)?;
        let grid = step_grid(&self.grid, self.params.anchor, a)?;
        let detection = self.detector.detect(&grid, a, b);
        let mut forces = ForceAccumulator::new(a.len(), b.len(), self.params.magnitude);
        self.eliminator.eliminate(grid.center(), a, b, &detection.contacts, &mut forces);
        let (force_a, force_b) = forces.finish()?;
        Ok(ContactReport {
            force_a,
            force_b,
            colliding_b: detection.contacts.iter().map(|c| c.b).collect(),
            binned_a: detection.binned_a,
            discarded_a: detection.discarded_a,
            grid_center: grid.center(),
        })
    }
}
