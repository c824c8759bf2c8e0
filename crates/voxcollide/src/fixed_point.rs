//! Order-independent accumulation of the forces on body A in fixed point (docs/design.md §2,
//! *Accumulation*): each component becomes an integer count of `magnitude / 65536`, counts are
//! summed exactly, and a total outside `i32` is an error instead of a wrapped value.

use glam::Vec3;

use crate::error::Error;

/// The forces of one step while they are being summed.
#[derive(Clone, Debug)]
pub struct ForceAccumulator {
    /// `65536 / magnitude`, in f32, computed once.
    scale: f32,
    /// `magnitude / 65536`, in f32, computed once.
    unit: f32,
    /// Per A vertex, the exact sum of its counts (`i64` cannot overflow: at most `2^32`
    /// contributions of at most `2^17` each).
    counts_a: Vec<[i64; 3]>,
    /// Per B vertex, its force (written once: a B vertex collides at most once).
    force_b: Vec<Vec3>,
}

impl ForceAccumulator {
    /// Zero forces for `len_a` A vertices and `len_b` B vertices, with contact force `magnitude`.
    #[must_use]
    pub fn new(len_a: usize, len_b: usize, magnitude: f32) -> ForceAccumulator {
        ForceAccumulator {
            scale: 65536.0 / magnitude,
            unit: magnitude / 65536.0,
            counts_a: vec![[0; 3]; len_a],
            force_b: vec![Vec3::ZERO; len_b],
        }
    }

    /// The fixed-point count of one force component: `round_ties_even(f * (65536 / m))`.
    #[must_use]
    pub fn count(&self, f: f32) -> i32 {
        // |f| <= ~m, so |f * scale| <= ~2^17: the cast never saturates.
        (f * self.scale).round_ties_even() as i32
    }

    /// Adds force `f` to A vertex `i`, in fixed point.
    pub fn add_a(&mut self, i: u32, f: Vec3) {
        let counts = [self.count(f.x), self.count(f.y), self.count(f.z)];
        for (total, c) in self.counts_a[i as usize].iter_mut().zip(counts) {
            *total += i64::from(c);
        }
    }

    /// Sets the force on B vertex `j`.
    pub fn set_b(&mut self, j: u32, f: Vec3) {
        self.force_b[j as usize] = f;
    }

    /// The forces on A and on B: each A total back in f32 as `f32(count) * (m / 65536)`.
    ///
    /// # Errors
    /// [`Error::ForceOverflow`] for the first A total (by vertex, then axis) outside `i32`.
    pub fn finish(self) -> Result<(Vec<Vec3>, Vec<Vec3>), Error> {
        let unit = self.unit;
        let force_a = self
            .counts_a
            .iter()
            .enumerate()
            .map(|(i, counts)| {
                let mut f = [0.0f32; 3];
                for (axis, &count) in counts.iter().enumerate() {
                    let c = i32::try_from(count).map_err(|_| Error::ForceOverflow {
                        vertex: i as u32,
                        axis: axis as u32,
                        count,
                    })?;
                    f[axis] = c as f32 * unit;
                }
                Ok(Vec3::from_array(f))
            })
            .collect::<Result<Vec<_>, Error>>()?;
        Ok((force_a, self.force_b))
    }
}
