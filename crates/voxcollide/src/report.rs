//! What one collision step found and the forces it made.

use glam::Vec3;

/// The outcome of one [`Collision::step`](crate::Collision::step).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ContactReport {
    /// The penalty force on each A vertex (`len == |A|`), summed over its contacts.
    pub force_a: Vec<Vec3>,
    /// The penalty force on each B vertex (`len == |B|`); zero where it does not collide.
    pub force_b: Vec<Vec3>,
    /// The colliding B vertices, ascending.
    pub colliding_b: Vec<u32>,
    /// A vertices put into voxel lists this step.
    pub binned_a: u32,
    /// A vertices discarded this step: not finite, or outside the grid.
    pub discarded_a: u32,
    /// The grid center used this step (it moves under [`Anchor::FollowA`](crate::Anchor)).
    pub grid_center: Vec3,
}

impl ContactReport {
    /// The A vertices with a non-zero force, ascending.
    #[must_use]
    pub fn pushed_a(&self) -> Vec<u32> {
        (0..self.force_a.len() as u32).filter(|&i| self.force_a[i as usize] != Vec3::ZERO).collect()
    }

    /// The sum of all forces on both bodies: zero by Newton's third law, up to the fixed-point
    /// rounding of A's forces (half a unit `magnitude / 65536` per component and contribution).
    #[must_use]
    pub fn net_force(&self) -> Vec3 {
        let sum = |v: &[Vec3]| v.iter().fold(glam::DVec3::ZERO, |s, f| s + f.as_dvec3());
        (sum(&self.force_a) + sum(&self.force_b)).as_vec3()
    }
}

impl std::fmt::Display for ContactReport {
    /// A few readable lines: the counts, the grid center and the largest forces.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let max_len = |v: &[Vec3]| v.iter().map(|f| f.length()).fold(0.0f32, f32::max);
        writeln!(
            f,
            "contacts: {} of {} B vertices collide; {} A vertices pushed",
            self.colliding_b.len(),
            self.force_b.len(),
            self.pushed_a().len()
        )?;
        writeln!(
            f,
            "body A: {} binned, {} discarded; grid center {}",
            self.binned_a, self.discarded_a, self.grid_center
        )?;
        write!(
            f,
            "largest force: {:.4} on A, {:.4} on B; net force {}",
            max_len(&self.force_a),
            max_len(&self.force_b),
            self.net_force()
        )
    }
}
