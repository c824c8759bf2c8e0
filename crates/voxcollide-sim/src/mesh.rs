//! Triangle surfaces over a body's vertices: what is rendered, written to VTK, and used to tell
//! whether a point is inside a closed body.

/// Triangles indexing a body's vertex positions, counter-clockwise seen from outside (so
/// `cross(b - a, c - a)` points out). A closed surface has every edge in exactly two triangles.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TriangleMesh {
    /// The triangles, as indices into the body's positions.
    pub triangles: Vec<[u32; 3]>,
}

/// The volume a surface encloses, counted two ways ([`TriangleMesh::coverage`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coverage {
    /// Each point counted by its winding number (what [`TriangleMesh::volume`] sums): twice
    /// where the surface wraps it twice, negatively where it is turned inside out.
    pub signed: f64,
    /// The space inside the surface (winding number at least one), each point once.
    pub covered: f64,
}

impl Coverage {
    /// What the signed count makes of space that is not inside the surface once: the volume
    /// of a surface that passes through itself counted a second time (or, negative, a
    /// surface turned inside out). Zero for a surface that does neither.
    #[must_use]
    pub fn excess(&self) -> f64 {
        self.signed - self.covered
    }
}

impl TriangleMesh {
    /// The volume the triangles enclose over `positions`, summed in `f64` (positive when they
    /// face outward).
    #[must_use]
    pub fn volume(&self, positions: &[glam::Vec3]) -> f64 {
        self.corners(positions).map(|[a, b, c]| a.dot(b.cross(c)) / 6.0).sum()
    }

    /// How the volume the triangles enclose over `positions` is made up ([`Coverage`]): the
    /// space inside them counted once, against [`volume`](Self::volume)'s count, which counts
    /// a space the surface wraps twice (where it passes through itself) twice. Measured along
    /// `columns × columns` vertical lines over the surface's bounds, each crossing of a
    /// triangle turning the winding number along the line by one; exact along each line, so
    /// the error is the columns' cells across the surface's outline.
    #[must_use]
    pub fn coverage(&self, positions: &[glam::Vec3], columns: usize) -> Coverage {
        let n = columns.max(1);
        let Some((lo, hi)) =
            self.corners(positions).flatten().fold(None, |b: Option<(glam::DVec3, glam::DVec3)>, p| {
                Some(b.map_or((p, p), |(l, h)| (l.min(p), h.max(p))))
            })
        else {
            return Coverage { signed: 0.0, covered: 0.0 };
        };
        let cell = (hi - lo).truncate() / n as f64;
        if !(cell.x > 0.0 && cell.y > 0.0 && cell.is_finite()) {
            return Coverage { signed: self.volume(positions), covered: 0.0 };
        }
        // Lines a little off the cells' centres (by fractions no lattice shares), so that
        // they pass between the corners and edges of a mesh laid on a grid.
        let line = |i: usize, j: usize| {
            glam::DVec2::new(lo.x + (i as f64 + 0.5137) * cell.x, lo.y + (j as f64 + 0.4729) * cell.y)
        };
        let cross = |a: glam::DVec2, b: glam::DVec2| a.x * b.y - a.y * b.x;
        // Per crossing: its line, its height, and how it turns the winding number above it.
        let mut crossings: Vec<(usize, f64, i32)> = Vec::new();
        for [a, b, c] in self.corners(positions) {
            let (a2, b2, c2) = (a.truncate(), b.truncate(), c.truncate());
            let area = cross(b2 - a2, c2 - a2);
            if area == 0.0 || !area.is_finite() {
                continue;
            }
            // Facing up (area > 0) the line leaves the inside going up: one less above.
            let turn = if area > 0.0 { -1 } else { 1 };
            let (l, h) = (a2.min(b2).min(c2), a2.max(b2).max(c2));
            let first =
                |v: f64, lo: f64, cell: f64| (((v - lo) / cell - 0.6).ceil().max(0.0) as usize).min(n);
            let last =
                |v: f64, lo: f64, cell: f64| (((v - lo) / cell - 0.4).floor().max(-1.0) + 1.0) as usize;
            for i in first(l.x, lo.x, cell.x)..last(h.x, lo.x, cell.x).min(n) {
                for j in first(l.y, lo.y, cell.y)..last(h.y, lo.y, cell.y).min(n) {
                    let p = line(i, j);
                    let (u, v) = (cross(b2 - p, c2 - p) / area, cross(c2 - p, a2 - p) / area);
                    let w = 1.0 - u - v;
                    if u >= 0.0 && v >= 0.0 && w >= 0.0 {
                        crossings.push((i + n * j, u * a.z + v * b.z + w * c.z, turn));
                    }
                }
            }
        }
        crossings.sort_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)));
        let (mut signed, mut covered) = (0.0, 0.0);
        for along in crossings.chunk_by(|x, y| x.0 == y.0) {
            let mut winding = 0;
            for pair in along.windows(2) {
                winding += pair[0].2;
                let length = pair[1].1 - pair[0].1;
                signed += f64::from(winding) * length;
                if winding >= 1 {
                    covered += length;
                }
            }
        }
        let area = cell.x * cell.y;
        Coverage { signed: signed * area, covered: covered * area }
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// A cube from `lo` to `lo + size`, its triangles facing out, as 8 positions after `base`.
    fn cube(lo: Vec3, size: f32, base: u32, pos: &mut Vec<Vec3>, tris: &mut Vec<[u32; 3]>) {
        for k in 0..8 {
            pos.push(lo + size * Vec3::new((k & 1) as f32, ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32));
        }
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        for [a, b, c, d] in quads {
            tris.push([base + a, base + b, base + c]);
            tris.push([base + a, base + c, base + d]);
        }
    }

    #[test]
    fn a_surface_through_itself_counts_its_overlap_twice_and_coverage_says_how_much() {
        let (mut pos, mut tris) = (Vec::new(), Vec::new());
        cube(Vec3::ZERO, 2.0, 0, &mut pos, &mut tris);
        let one = TriangleMesh { triangles: tris.clone() };
        assert!((one.volume(&pos) - 8.0).abs() < 1e-9);
        let c = one.coverage(&pos, 64);
        assert!((c.signed - 8.0).abs() < 1e-6 && (c.covered - 8.0).abs() < 1e-6, "{c:?}");
        assert!(c.excess().abs() < 1e-6);
        // A second cube through the first, one unit across each way: 8 + 8 counted, 15
        // covered, the unit cube they share counted twice.
        cube(Vec3::ONE, 2.0, 8, &mut pos, &mut tris);
        let two = TriangleMesh { triangles: tris.clone() };
        assert!((two.volume(&pos) - 16.0).abs() < 1e-9);
        let c = two.coverage(&pos, 300);
        assert!((c.signed - 16.0).abs() < 0.1 && (c.covered - 15.0).abs() < 0.1, "{c:?}");
        assert!((c.excess() - 1.0).abs() < 0.1, "{c:?}");
        // Turned inside out: nothing covered, all of it counted negatively.
        let inside_out =
            TriangleMesh { triangles: one.triangles.iter().map(|[a, b, c]| [*a, *c, *b]).collect() };
        let c = inside_out.coverage(&pos, 64);
        assert!((c.signed + 8.0).abs() < 1e-6 && c.covered.abs() < 1e-9, "{c:?}");
        // No triangles, or a flat sheet: nothing.
        assert_eq!(TriangleMesh::default().coverage(&pos, 8), Coverage { signed: 0.0, covered: 0.0 });
    }
}
