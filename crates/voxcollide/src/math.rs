//! Vector arithmetic in one fixed `f32` order (docs/design.md §2: "exactly in the order written"), so
//! that the GPU shaders, which spell out the same expressions, give the same bits.
//!
//! No fused multiply-add and no `normalize` or `length` helper whose order is left to a library:
//! every sum here is evaluated left to right.

use glam::Vec3;

/// `u.x * v.x + u.y * v.y + u.z * v.z`, left to right.
#[must_use]
pub fn dot(u: Vec3, v: Vec3) -> f32 {
    u.x * v.x + u.y * v.y + u.z * v.z
}

/// `d2 = dot(b - a, b - a)`, the squared distance that orders candidates.
#[must_use]
pub fn dist2(b: Vec3, a: Vec3) -> f32 {
    let d = b - a;
    dot(d, d)
}

/// `u × v`, each component as `p * q - r * s`.
#[must_use]
pub fn cross(u: Vec3, v: Vec3) -> Vec3 {
    Vec3::new(u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cross_is_right_handed() {
        assert_eq!(cross(Vec3::X, Vec3::Y), Vec3::Z);
        assert_eq!(cross(Vec3::Y, Vec3::Z), Vec3::X);
        assert_eq!(cross(Vec3::Z, Vec3::X), Vec3::Y);
        assert_eq!(dist2(Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 0.0, 1.0)), 8.0);
    }
}
