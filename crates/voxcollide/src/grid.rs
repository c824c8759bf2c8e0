//! The voxel grid: where the voxel model sits in space and how a point finds its voxel.

use glam::{UVec3, Vec3};

use crate::error::Error;

/// Smallest allowed voxel-size exponent: `voxel_size >= 2^-24`.
pub const MIN_VOXEL_EXP: i32 = -24;
/// Largest allowed voxel-size exponent: `voxel_size <= 2^24`.
pub const MAX_VOXEL_EXP: i32 = 24;
/// Largest number of voxels per axis, `2^24`: every dim and every voxel index is then exact in
/// `f32`, so the inside test `0 <= q < dims` means the same on the CPU and the GPU.
pub const MAX_DIM: u32 = 1 << 24;

/// An axis-aligned grid of cubic voxels: `dims` voxels of side `voxel_size` per axis, centred on
/// `center`.
///
/// The grid is only a description; the voxels themselves are never allocated (see
/// [`VoxelData`](crate::voxel_data::VoxelData)), so `dims` may be as large as [`MAX_DIM`] per
/// axis at no cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelGrid {
    center: Vec3,
    voxel_size: f32,
    dims: UVec3,
    origin: Vec3,
    inv: f32,
}

impl VoxelGrid {
    /// Makes a grid of `dims` voxels of side `voxel_size`, centred on `center`.
    ///
    /// # Errors
    /// - [`Error::VoxelSize`] unless `voxel_size` is an exact power of two `2^k`,
    ///   `-24 <= k <= 24` (so finite and positive);
    /// - [`Error::Dims`] unless each of `dims` is in `1..=2^24`;
    /// - [`Error::NonFiniteCenter`] unless `center` is finite.
    pub fn new(center: Vec3, voxel_size: f32, dims: UVec3) -> Result<VoxelGrid, Error> {
        check_voxel_size(voxel_size)?;
        if dims.min_element() == 0 || dims.max_element() > MAX_DIM {
            return Err(Error::Dims { dims });
        }
        if !center.is_finite() {
            return Err(Error::NonFiniteCenter { center });
        }
        // docs/design.md §2, in f32 and in this order: `voxel_size * 0.5` first.
        let half = voxel_size * 0.5;
        let origin = center - Vec3::new(half * dims.x as f32, half * dims.y as f32, half * dims.z as f32);
        Ok(VoxelGrid { center, voxel_size, dims, origin, inv: 1.0 / voxel_size })
    }

    /// The same grid moved to `center` (voxel size and dims unchanged).
    ///
    /// # Errors
    /// [`Error::NonFiniteCenter`] unless `center` is finite.
    pub fn with_center(&self, center: Vec3) -> Result<VoxelGrid, Error> {
        VoxelGrid::new(center, self.voxel_size, self.dims)
    }

    /// The grid's center.
    #[must_use]
    pub fn center(&self) -> Vec3 {
        self.center
    }

    /// The side of one voxel, a power of two.
    #[must_use]
    pub fn voxel_size(&self) -> f32 {
        self.voxel_size
    }

    /// The number of voxels per axis.
    #[must_use]
    pub fn dims(&self) -> UVec3 {
        self.dims
    }

    /// The grid's minimum corner, `center - voxel_size * 0.5 * dims`.
    #[must_use]
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// `1 / voxel_size`, exact since the voxel size is a power of two.
    #[must_use]
    pub fn inv_voxel_size(&self) -> f32 {
        self.inv
    }

    /// The voxel holding `p`: `floor((p - origin) * inv)` per axis, or `None` when `p` is not
    /// finite or its voxel is outside `0 <= q < dims` on some axis (the vertex is discarded).
    #[must_use]
    pub fn voxel_of(&self, p: Vec3) -> Option<UVec3> {
        if !p.is_finite() {
            return None;
        }
        let x = self.axis_index(p.x, self.origin.x, self.dims.x)?;
        let y = self.axis_index(p.y, self.origin.y, self.dims.y)?;
        let z = self.axis_index(p.z, self.origin.z, self.dims.z)?;
        Some(UVec3::new(x, y, z))
    }

    fn axis_index(&self, p: f32, origin: f32, dim: u32) -> Option<u32> {
        let q = ((p - origin) * self.inv).floor();
        // `dim <= 2^24` is exact in f32; a NaN or infinite `q` fails both comparisons.
        (q >= 0.0 && q < dim as f32).then_some(q as u32)
    }
}

/// Checks that `voxel_size` is `2^k` with `MIN_VOXEL_EXP <= k <= MAX_VOXEL_EXP`.
pub(crate) fn check_voxel_size(voxel_size: f32) -> Result<(), Error> {
    let bits = voxel_size.to_bits();
    let mantissa = bits & 0x007f_ffff;
    let biased = ((bits >> 23) & 0xff) as i32;
    let sign = bits >> 31;
    // A normal float with a zero mantissa is a power of two; the exponent range keeps it normal.
    let exp = biased - 127;
    if sign == 0 && mantissa == 0 && (MIN_VOXEL_EXP..=MAX_VOXEL_EXP).contains(&exp) {
        Ok(())
    } else {
        Err(Error::VoxelSize { value: voxel_size })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn powers_of_two_in_range_are_accepted() {
        for k in MIN_VOXEL_EXP..=MAX_VOXEL_EXP {
            assert!(check_voxel_size(2f32.powi(k)).is_ok(), "2^{k}");
        }
        for bad in [0.0, -0.0, -1.0, 0.75, 3.0, 2f32.powi(25), 2f32.powi(-25), f32::NAN, f32::INFINITY] {
            assert!(check_voxel_size(bad).is_err(), "{bad}");
        }
    }
}
