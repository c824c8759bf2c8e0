//! What a contact is and what force it makes: [`ContactParams`] and its three choices.

use crate::error::Error;
use crate::grid::VoxelGrid;

/// Smallest accepted force magnitude: below it the fixed-point scale `65536 / magnitude` would
/// leave `f32`.
pub const MIN_MAGNITUDE: f32 = 1e-30;
/// Largest accepted force magnitude: above it a fixed-point total converted back,
/// `count * (magnitude / 65536)`, could leave `f32`.
pub const MAX_MAGNITUDE: f32 = 1e30;

/// When a B vertex collides, and which A vertices are its candidates (docs/design.md §2, *Search*).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Search {
    /// The paper's rule: `b` collides iff its voxel holds an A vertex; the candidates are the A
    /// vertices of that voxel.
    Voxel,
    /// The candidates are the A vertices of the 3×3×3 block around `b`'s voxel (clipped to the
    /// grid) with `d2 < radius * radius`; `b` collides iff there is one.
    /// `0 < radius <= voxel_size`.
    Neighbours {
        /// The contact distance, at most one voxel.
        radius: f32,
    },
}

/// Which way the penalty force of a contact points (docs/design.md §2, *Direction*).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Along the line of centres of `b` and its partner.
    Pairwise,
    /// Along the normal of the plane through the three nearest A vertices, oriented outward
    /// from A; the force on A is split in three among them (the paper's inflating implant).
    PlaneNormal,
}

/// Where the grid sits from step to step (docs/design.md §2, *Anchor*).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Anchor {
    /// The grid stays where it was built.
    Fixed,
    /// Each step the grid is recentred on the middle of A's bounds, `0.5 * (lo + hi)` over A's
    /// finite vertices (dims and voxel size unchanged; with no finite vertex it stays where it
    /// was built).
    ///
    /// The new center is A's own, so a grid built with
    /// [`Initializer::contact_half`](crate::Initializer::contact_half) loses its offset toward
    /// B: it becomes a half-size box around A's middle. Use `Fixed` with a contact half, or
    /// rebuild the grid when A moves.
    FollowA,
}

/// Everything that decides what a contact is and what force it makes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactParams {
    /// The force per contact, finite, in `[MIN_MAGNITUDE, MAX_MAGNITUDE]`.
    pub magnitude: f32,
    /// When a B vertex collides, and with which A vertices.
    pub search: Search,
    /// Which way the force points.
    pub direction: Direction,
    /// Whether the grid follows body A.
    pub anchor: Anchor,
}

impl ContactParams {
    /// Checks the params against `grid`.
    ///
    /// # Errors
    /// [`Error::Magnitude`] unless the magnitude is finite and in
    /// `[MIN_MAGNITUDE, MAX_MAGNITUDE]`; [`Error::Radius`] unless a neighbour radius is in
    /// `(0, grid.voxel_size()]`.
    pub fn validate(&self, grid: &VoxelGrid) -> Result<(), Error> {
        let m = self.magnitude;
        if !(m.is_finite() && (MIN_MAGNITUDE..=MAX_MAGNITUDE).contains(&m)) {
            return Err(Error::Magnitude { value: m });
        }
        if let Search::Neighbours { radius } = self.search
            && !(radius > 0.0 && radius <= grid.voxel_size())
        {
            return Err(Error::Radius { radius, voxel_size: grid.voxel_size() });
        }
        Ok(())
    }
}

/// How strongly a contact pushes: the magnitude of its force (docs/design.md §2 gives the paper's,
/// [`Response::Constant`]; docs/semantics.md gives both).
///
/// Set on a backend with `with_response` ([`CpuCollision::with_response`](crate::CpuCollision::with_response),
/// and the same on the parallel and GPU backends); a backend made with `new` responds with
/// [`Response::Constant`], the paper's rule, bit for bit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Response {
    /// The paper's rule: every contact pushes with [`ContactParams::magnitude`], however deep.
    #[default]
    Constant,
    /// A penalty that grows with depth, `min(magnitude, stiffness * depth)`, so that a load
    /// that grows is met by a force that grows. `magnitude` is then the most one contact may
    /// push with (and the fixed-point scale of the sums, as before). The depth is, in `f32`:
    /// - along a plane normal `n` through `a0, a1, a2` (centroid `c = (a0 + a1 + a2) / 3`):
    ///   `gap - dot(b - c, n)`, how far `b` is behind the plane moved out by `gap`;
    /// - along the line of centres (pairwise, and the plane's fallback):
    ///   `gap + reach - sqrt(d2)`, with `reach` the search radius (`Search::Neighbours`) or
    ///   the voxel size (`Search::Voxel`): how far `b` is inside the sphere of `gap + reach`
    ///   around its partner;
    ///
    /// clamped to `[0, magnitude / stiffness]` (the quotient computed once, in `f32`, so that
    /// `stiffness * depth` never leaves `f32`). A contact of depth 0 still collides (it is in
    /// `colliding_b`); its force is zero.
    Penalty {
        /// Force per unit of depth, finite and positive.
        stiffness: f32,
        /// How far outside A the response begins, finite, in `[0, voxel_size]`.
        gap: f32,
    },
}

impl Response {
    /// Checks the response against `params` and `grid`.
    ///
    /// # Errors
    /// [`Error::Response`] for a stiffness that is not a positive normal `f32` (no zero,
    /// subnormal, infinity or NaN), or whose `magnitude / stiffness` is not a finite normal
    /// `f32` either; or a gap outside `[0, grid.voxel_size()]`.
    pub fn validate(&self, params: &ContactParams, grid: &VoxelGrid) -> Result<(), Error> {
        if let Response::Penalty { stiffness, gap } = *self {
            if !(stiffness.is_normal() && stiffness > 0.0 && (params.magnitude / stiffness).is_normal()) {
                return Err(Error::Response {
                    what: "stiffness",
                    value: stiffness,
                    rule: format!(
                        "must be a positive normal f32, and so must magnitude / stiffness (magnitude {})",
                        params.magnitude
                    ),
                });
            }
            if !(gap >= 0.0 && gap <= grid.voxel_size()) {
                return Err(Error::Response {
                    what: "gap",
                    value: gap,
                    rule: format!("must be in [0, {}] (the voxel size)", grid.voxel_size()),
                });
            }
        }
        Ok(())
    }
}
