//! Triangle surfaces over a body's vertices: what is rendered, written to VTK, and used to tell
//! whether a point is inside a closed body.

/// Triangles indexing a body's vertex positions, counter-clockwise seen from outside (so
/// `cross(b - a, c - a)` points out). A closed surface has every edge in exactly two triangles.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TriangleMesh {
    /// The triangles, as indices into the body's positions.
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleMesh {
    /// The volume the triangles enclose over `positions`, summed in `f64` (positive when they
    /// face outward).
    #[must_use]
    pub fn volume(&self, positions: &[glam::Vec3]) -> f64 {
        self.corners(positions).map(|[a, b, c]| a.dot(b.cross(c)) / 6.0).sum()
    }

    /// The triangles' total area over `positions`, summed in `f64`.
    #[must_use]
    pub fn area(&self, positions: &[glam::Vec3]) -> f64 {
        self.corners(positions).map(|[a, b, c]| 0.5 * (b - a).cross(c - a).length()).sum()
    }

    /// Per vertex of `n`, the triangles at it, as offsets into a flat list (CSR): vertex `v`'s
    /// are `list[offsets[v]..offsets[v + 1]]`, ascending.
    #[must_use]
    pub fn triangles_at(&self, n: usize) -> (Vec<u32>, Vec<u32>) {
        self.triangles_by(n, |t| &t[..])
    }

    /// The triangles by their first corner, as [`triangles_at`](Self::triangles_at) lays them
    /// out: each triangle once.
    #[must_use]
    pub fn triangles_by_first_corner(&self, n: usize) -> (Vec<u32>, Vec<u32>) {
        self.triangles_by(n, |t| &t[..1])
    }

    /// Per vertex (of `n`), the triangles that `corners` names it a corner of, in order (CSR).
    fn triangles_by(&self, n: usize, corners: impl Fn(&[u32; 3]) -> &[u32]) -> (Vec<u32>, Vec<u32>) {
        let mut offsets = vec![0u32; n + 1];
        for t in &self.triangles {
            for &v in corners(t) {
                offsets[v as usize + 1] += 1;
            }
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut list = vec![0u32; offsets[n] as usize];
        for (k, t) in self.triangles.iter().enumerate() {
            for &v in corners(t) {
                list[fill[v as usize] as usize] = k as u32;
                fill[v as usize] += 1;
            }
        }
        (offsets, list)
    }

    fn corners<'a>(&'a self, positions: &'a [glam::Vec3]) -> impl Iterator<Item = [glam::DVec3; 3]> + 'a {
        self.triangles.iter().map(|t| t.map(|v| positions[v as usize].as_dvec3()))
    }
}
