//! The paper's `Initializer`: builds the voxel model (a [`VoxelGrid`]) around body A.

use glam::{UVec3, Vec3};

use crate::error::{Body, Error};
use crate::grid::{MAX_DIM, VoxelGrid, check_voxel_size};

/// Builds the [`VoxelGrid`] of a pair of bodies from body A: the bounding cube of A's finite
/// vertices, plus `margin` voxels on every side, optionally halved toward B.
///
/// ```
/// use voxcollide::{Initializer, glam::{UVec3, Vec3}};
/// let a = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(3.0, 1.0, 2.0)];
/// let grid = Initializer::new(1.0).margin(1).build(&a)?;
/// assert_eq!(grid.center(), Vec3::new(1.5, 0.5, 1.0));
/// assert_eq!(grid.dims(), UVec3::splat(5)); // ceil(3 / 1) + 2 * 1
/// # Ok::<(), voxcollide::Error>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[must_use]
pub struct Initializer {
    voxel_size: f32,
    margin: u32,
    toward: Option<Vec3>,
}

impl Initializer {
    /// An initializer for voxels of side `voxel_size` (checked by [`build`](Self::build)), with
    /// no margin and the whole cube.
    pub fn new(voxel_size: f32) -> Initializer {
        Initializer { voxel_size, margin: 0, toward: None }
    }

    /// Adds `margin` voxels on every side of the bounding cube.
    pub fn margin(self, margin: u32) -> Initializer {
        Initializer { margin, ..self }
    }

    /// Keeps only the half of the cube that faces the direction `toward`, along that
    /// direction's dominant axis (ties: x before y before z). The half starts at the cube's
    /// center. `toward` is a direction (for instance B's centroid minus A's), not a point.
    ///
    /// The half-box is placed for this A; [`Anchor::FollowA`](crate::Anchor::FollowA) recentres
    /// the grid on A's middle and so undoes the offset.
    pub fn contact_half(self, toward: Vec3) -> Initializer {
        Initializer { toward: Some(toward), ..self }
    }

    /// Builds the grid over the finite vertices of `a` (docs/design.md §2, *Initializer*):
    /// `center = 0.5 * (lo + hi)`, `side = max(hi - lo)`,
    /// `n = max(ceil(side / voxel_size) + 2 * margin, 1)` voxels per axis.
    ///
    /// # Errors
    /// [`Error::VoxelSize`] for a bad voxel size, [`Error::Toward`] for a non-finite or zero
    /// `contact_half` direction, [`Error::EmptyBody`] for an empty `a`,
    /// [`Error::NoFiniteVertex`] when no vertex of `a` is finite, [`Error::BoundsTooLarge`]
    /// when the cube needs more than `2^24` voxels per axis, and [`Error::NonFiniteCenter`] when
    /// `lo + hi` overflows `f32`.
    pub fn build(&self, a: &[Vec3]) -> Result<VoxelGrid, Error> {
        check_voxel_size(self.voxel_size)?;
        if let Some(toward) = self.toward
            && (!toward.is_finite() || toward == Vec3::ZERO)
        {
            return Err(Error::Toward { toward });
        }
        if a.is_empty() {
            return Err(Error::EmptyBody { body: Body::A });
        }
        let (lo, hi) = finite_bounds(a).ok_or(Error::NoFiniteVertex { len: a.len() })?;
        let mut center = 0.5 * (lo + hi);
        let side = (hi - lo).max_element();

        // `ceil` of a huge or infinite quotient saturates in the cast and is rejected below.
        let cube = (side / self.voxel_size).ceil() as u64;
        let n = cube.saturating_add(2 * u64::from(self.margin)).max(1);
        if n > u64::from(MAX_DIM) {
            return Err(Error::BoundsTooLarge {
                side,
                voxel_size: self.voxel_size,
                margin: self.margin,
                needed: n,
            });
        }
        let n = n as u32;
        let mut dims = UVec3::splat(n);

        if let Some(toward) = self.toward {
            let axis = dominant_axis(toward);
            let h = n.div_ceil(2);
            dims[axis] = h;
            let shift = 0.5 * h as f32 * self.voxel_size;
            if toward[axis] > 0.0 {
                center[axis] += shift;
            } else {
                center[axis] -= shift;
            }
        }
        VoxelGrid::new(center, self.voxel_size, dims)
    }
}

/// Per-axis min and max over the finite vertices (all three components finite), or `None`
/// when there is none.
///
/// In the order of [`f32::total_cmp`], where `-0.0 < +0.0`: a body with both zeros on an axis
/// has `lo = -0.0` and `hi = +0.0` there, as the GPU's bounds pass orders them (integer keys of
/// the bits), so the grid center's sign of zero is the same on every backend. (`f32::min`
/// may return either zero.)
pub(crate) fn finite_bounds(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let mut finite = points.iter().filter(|p| p.is_finite());
    let first = *finite.next()?;
    let (mut lo, mut hi) = (first, first);
    for p in finite {
        for k in 0..3 {
            if p[k].total_cmp(&lo[k]).is_lt() {
                lo[k] = p[k];
            }
            if p[k].total_cmp(&hi[k]).is_gt() {
                hi[k] = p[k];
            }
        }
    }
    Some((lo, hi))
}

/// The axis of the largest `|v_i|`; ties go to the earlier axis.
fn dominant_axis(v: Vec3) -> usize {
    let a = v.abs();
    let mut axis = 0;
    for i in 1..3 {
        if a[i] > a[axis] {
            axis = i;
        }
    }
    axis
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dominant_axis_prefers_earlier_axis_on_ties() {
        assert_eq!(dominant_axis(Vec3::new(1.0, -1.0, 1.0)), 0);
        assert_eq!(dominant_axis(Vec3::new(0.5, -1.0, 1.0)), 1);
        assert_eq!(dominant_axis(Vec3::new(0.0, 0.0, -2.0)), 2);
    }
}
