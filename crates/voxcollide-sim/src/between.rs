//! A breast from a scan (docs/design.md §14): the tissue between the skin as scanned (`outer`,
//! an open sheet or a closed surface) and the chest wall (`inner`), inside a box.
//!
//! **Which side.** Both surfaces face outward, away from the patient, as scanners write them.
//! A point is *behind* a surface when a ray from it along the surface's mean facing direction
//! (its area-weighted normal) crosses it an odd number of times: once for a point under a
//! torso scan, none for a point in front of it; for a closed surface, the parity is inside or
//! out whatever the direction. The tissue is the part of the box behind `outer` and in front
//! of `inner`. The rays are cast against the triangles binned on the plane across the
//! direction (slightly tilted, so that a lattice's rows never run along a scan's edges).
//!
//! **The lattice.** A cubic lattice of the spacing from the box's corner `min`; a cell is
//! tissue when its centre is, and the body is its tissue cells: springs along their edges and
//! face diagonals, six tetrahedra each (the Freudenthal split), its surface their faces not
//! shared with another. A corner that lies in front of the skin is moved back onto it, and one
//! behind the chest wall forward onto it, along the surface's facing direction (by at most
//! [`SNAP`] of the spacing, so that no cell turns inside out): the body's outer face is then
//! the scanned skin and its volume the region's, not a staircase a half cell off (kept as
//! cubes, a breast on a 15 mm layer measured 14 % under its volume at a 6 mm spacing and
//! 13 % over at 9 mm). Vertices on the chest wall (behind `inner`, or with a lattice
//! neighbour behind it) and on the box's faces are held.

use glam::{DVec3, UVec3, Vec3};

use crate::body::{MassSpring, Material, Mode, Spring};
use crate::geometry::line_crossing;
use crate::mesh::TriangleMesh;
use crate::mesh_io::Surface;

/// A surface's triangles, for asking which side of it a point lies on.
pub struct Sheet {
    triangles: Vec<[DVec3; 3]>,
    /// The direction rays are cast along: the mean facing direction, tilted a little.
    dir: DVec3,
    /// Two axes across it, and the triangles binned on them.
    u: DVec3,
    v: DVec3,
    lo: [f64; 2],
    cell: f64,
    dims: [usize; 2],
    bins: Vec<Vec<u32>>,
    /// The sheet's open edges (used by one triangle).
    boundary: Vec<[DVec3; 2]>,
}

impl Sheet {
    /// The sheet of `surface`, its bins about `cell` wide; `None` for a surface with no area.
    #[must_use]
    pub fn new(surface: &Surface, cell: f64) -> Option<Sheet> {
        let triangles: Vec<[DVec3; 3]> = surface
            .mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| surface.positions[i as usize].as_dvec3()))
            .collect();
        let normal: DVec3 = triangles.iter().map(|[a, b, c]| (*b - *a).cross(*c - *a)).sum();
        if normal.length().is_nan() || normal.length() <= 0.0 {
            return None;
        }
        // Tilted by irrational fractions of a radian: no lattice row runs along it exactly.
        let n = normal.normalize();
        let any = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        let (a, b) = (n.cross(any).normalize(), n.cross(n.cross(any)).normalize());
        let dir = (n + 1.3e-3 * std::f64::consts::SQRT_2 * a + 0.7e-3 * std::f64::consts::PI * b).normalize();
        let u = dir.cross(any).normalize();
        let v = dir.cross(u);
        let project = |p: DVec3| [p.dot(u), p.dot(v)];
        let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
        for t in &triangles {
            for p in t {
                let q = project(*p);
                for k in 0..2 {
                    lo[k] = lo[k].min(q[k]);
                    hi[k] = hi[k].max(q[k]);
                }
            }
        }
        let cell = cell.max((hi[0] - lo[0]).max(hi[1] - lo[1]) / 2048.0).max(f64::MIN_POSITIVE);
        let dims = [((hi[0] - lo[0]) / cell) as usize + 1, ((hi[1] - lo[1]) / cell) as usize + 1];
        let mut bins = vec![Vec::new(); dims[0] * dims[1]];
        for (k, t) in triangles.iter().enumerate() {
            let q = t.map(project);
            let (mut a, mut b) = ([f64::MAX; 2], [f64::MIN; 2]);
            for p in q {
                for d in 0..2 {
                    a[d] = a[d].min(p[d]);
                    b[d] = b[d].max(p[d]);
                }
            }
            let at = |x: f64, d: usize| (((x - lo[d]) / cell) as usize).min(dims[d] - 1);
            for i in at(a[0], 0)..=at(b[0], 0) {
                for j in at(a[1], 1)..=at(b[1], 1) {
                    bins[i + dims[0] * j].push(k as u32);
                }
            }
        }
        let mut edges: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
        for t in &surface.mesh.triangles {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                *edges.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        let boundary = edges
            .into_iter()
            .filter(|(_, n)| *n == 1)
            .map(|((a, b), _)| [a, b].map(|i| surface.positions[i as usize].as_dvec3()))
            .collect();
        Some(Sheet { triangles, dir, u, v, lo, cell, dims, bins, boundary })
    }

    /// The bin `p` projects into, if the sheet reaches there.
    fn bin(&self, p: DVec3) -> Option<&[u32]> {
        let (x, y) = ((p.dot(self.u) - self.lo[0]) / self.cell, (p.dot(self.v) - self.lo[1]) / self.cell);
        if x < 0.0 || y < 0.0 || x >= self.dims[0] as f64 || y >= self.dims[1] as f64 {
            return None;
        }
        Some(&self.bins[x as usize + self.dims[0] * y as usize])
    }

    /// How many times the ray from `p` along the sheet's facing direction crosses it.
    #[must_use]
    pub fn crossings(&self, p: DVec3) -> usize {
        let Some(bin) = self.bin(p) else { return 0 };
        bin.iter()
            // t > 0; the tilted direction keeps rays off edges.
            .filter(|&&k| {
                line_crossing(p, self.dir, self.triangles[k as usize], 0.0).is_some_and(|t| t > 0.0)
            })
            .count()
    }

    /// Where the line through `p` along the sheet's facing direction meets it nearest to `p`
    /// on the side `sign` (+1: ahead, −1: behind), within `reach`: the point `p` is moved to
    /// when it is snapped onto the sheet.
    #[must_use]
    pub fn along(&self, p: DVec3, sign: f64, reach: f64) -> Option<DVec3> {
        let bin = self.bin(p)?;
        let mut best: Option<f64> = None;
        for &k in bin {
            if let Some(t) = line_crossing(p, self.dir, self.triangles[k as usize], 0.0)
                && t * sign >= 0.0
                && t.abs() <= reach
            {
                best = Some(best.map_or(t, |b: f64| if t.abs() < b.abs() { t } else { b }));
            }
        }
        best.map(|t| p + t * self.dir)
    }

    /// Whether `p` lies behind the sheet (an odd number of crossings).
    #[must_use]
    pub fn behind(&self, p: DVec3) -> bool {
        self.crossings(p) % 2 == 1
    }

    /// Whether the sheet reaches across `p` at all (a triangle projects near it): where it does
    /// not, a sheet with holes or too small leaves the side undecided.
    #[must_use]
    pub fn covers(&self, p: DVec3) -> bool {
        self.bin(p).is_some_and(|b| !b.is_empty())
    }

    /// The nearest point of the sheet to `p`, its distance, and its triangle.
    #[must_use]
    pub fn nearest(&self, p: DVec3) -> (DVec3, f64, usize) {
        let mut best = (p, f64::INFINITY, 0);
        for (k, t) in self.triangles.iter().enumerate() {
            let q = crate::geometry::closest_point(p, t);
            let d = q.distance(p);
            if d < best.1 {
                best = (q, d, k);
            }
        }
        best
    }

    /// Whether `p`, where the sheet's rays do not reach, is in front of it all the same: its
    /// nearest point is inside the sheet (not on its open edge) and `p` lies on the side the
    /// sheet faces there.
    #[must_use]
    pub fn in_front_nearby(&self, p: DVec3) -> bool {
        let (q, _, k) = self.nearest(p);
        let on_edge = self.boundary.iter().any(|[a, b]| {
            let ab = *b - *a;
            let t = ((q - *a).dot(ab) / ab.length_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
            (*a + t * ab).distance(q) <= 1e-9 * (1.0 + q.length())
        });
        let [a, b, c] = self.triangles[k];
        !on_edge && (p - q).dot((b - a).cross(c - a)) >= 0.0
    }
}

/// The farthest a lattice corner is moved onto the skin or the wall, in spacings.
pub const SNAP: f64 = 0.45;

/// Why a `between` body could not be made (docs/design.md §14); each names the key at fault.
#[derive(Clone, Debug, PartialEq)]
pub enum BetweenError {
    /// A surface with no area: which (`"outer"` or `"inner"`).
    Flat(&'static str),
    /// The skin does not reach across the box where the tissue would be: the points it leaves
    /// undecided, and one of them.
    Uncovered(usize, Vec3),
    /// The chest wall lies in front of the skin: no point of the box is both behind the skin
    /// and in front of the wall, though each alone holds some.
    WallInFront,
    /// The box holds no tissue: no lattice cell is wholly behind the skin and in front of the
    /// wall.
    Empty,
}

impl std::fmt::Display for BetweenError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BetweenError::Flat(which) => write!(f, "`{which}` has no area: its triangles face nowhere"),
            BetweenError::Uncovered(n, p) => write!(
                f,
                "`outer` does not cover the box: {n} lattice points in front of the chest wall lie where the skin does not reach (one at {p}); give a scan that spans the box, or a smaller box"
            ),
            BetweenError::WallInFront => write!(
                f,
                "`inner` lies in front of `outer`: no point of the box is behind the skin and in front of the chest wall (both face outward, away from the patient)"
            ),
            BetweenError::Empty => write!(
                f,
                "the box holds no tissue: no lattice cell is wholly behind `outer` and in front of `inner`; widen the box or use a finer spacing"
            ),
        }
    }
}

/// What [`between_body`] made.
#[derive(Clone, Debug, PartialEq)]
pub struct BetweenReport {
    /// Tissue cells.
    pub cells: usize,
    /// Vertices held on the chest wall.
    pub on_wall: usize,
    /// Vertices held on the box's faces.
    pub on_box: usize,
    /// Vertices left on the lattice because snapping them would have flattened a tetrahedron.
    pub unsnapped: usize,
    /// The body's surface triangles on the chest wall (all three corners held there), as
    /// indices into its surface: the side [`volume_between`] keeps where it started.
    pub wall_faces: Vec<u32>,
}

/// The volume between the body's outer surface at `pos` and the chest wall, inside its box
/// (cubic file units; docs/design.md §14): its surface's enclosed volume with the triangles of
/// `wall_faces` ([`BetweenReport::wall_faces`]) where they started (`start`). Where the tissue
/// stays on the wall it is the tissue's own volume; where a pocket lifts it off, it counts the
/// space between it and the wall (the implant's) too.
#[must_use]
pub fn volume_between(body: &MassSpring, wall_faces: &[u32], start: &[Vec3], pos: &[Vec3]) -> f64 {
    let mut on_wall = vec![false; body.surface.triangles.len()];
    for &f in wall_faces {
        on_wall[f as usize] = true;
    }
    body.surface
        .triangles
        .iter()
        .zip(&on_wall)
        .map(|(t, &wall)| {
            let at = if wall { start } else { pos };
            let [a, b, c] = t.map(|i| at[i as usize].as_dvec3());
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// The whole spacings `h` a box of `size` spans along each axis, from its `min` corner. A side
/// a whole number of spacings long, to a ten-thousandth of one, spans that many, so that its
/// far face carries lattice points however `size / h` rounds: a 180 mm side at 6 mm spans 30,
/// and so must 18 cm at 0.6 cm, which single precision makes 29.999998 (floored, the lattice
/// lost the box's far faces and the plan changed with the units).
#[must_use]
pub fn spans(size: Vec3, h: f32) -> UVec3 {
    (size.as_dvec3() / f64::from(h) + 1e-4).floor().as_uvec3()
}

/// What [`between_body`] makes: the body, what it found, and its tetrahedra (six per cell).
pub type Made = (MassSpring, BetweenReport, Vec<[u32; 4]>);

/// The tissue between `outer` and `inner` inside the box `min`..`max`, a lattice of spacing `h`
/// (springs of stiffness `k`, `material`), held on the chest wall and the box's faces.
///
/// # Errors
/// [`BetweenError`] for surfaces that do not bound tissue in the box; a lattice error
/// ([`voxcollide::Error::Invalid`]) as a message.
pub fn between_body(
    outer: &Surface,
    inner: &Surface,
    min: Vec3,
    max: Vec3,
    h: f32,
    k: f32,
    material: Material,
) -> Result<Made, Result<BetweenError, voxcollide::Error>> {
    let skin = Sheet::new(outer, f64::from(h)).ok_or(Ok(BetweenError::Flat("outer")))?;
    let wall = Sheet::new(inner, f64::from(h)).ok_or(Ok(BetweenError::Flat("inner")))?;
    let n = spans(max - min, h) + UVec3::ONE;
    let count = (n.x * n.y * n.z) as usize;
    if n.min_element() < 2 || count as u64 > crate::bodies::MAX_LATTICE_VERTICES {
        return Err(Err(voxcollide::Error::Invalid {
            what: "lattice spacing",
            value: h.to_string(),
            rule: format!(
                "gives {n} lattice points in the box: at least 2 and at most {} in all",
                crate::bodies::MAX_LATTICE_VERTICES
            ),
        }));
    }
    let idx = |x: u32, y: u32, z: u32| (x + n.x * (y + n.y * z)) as usize;
    let at = |i: usize| {
        let i = i as u32;
        UVec3::new(i % n.x, i / n.x % n.y, i / (n.x * n.y))
    };
    let node = |c: UVec3| min + h * c.as_vec3();
    use rayon::prelude::*;
    // Per node: behind the skin, in front of the wall, and whether the skin reaches across it.
    let sides: Vec<(bool, bool, bool)> = (0..count)
        .into_par_iter()
        .map(|i| {
            let p = node(at(i)).as_dvec3();
            (skin.behind(p), !wall.behind(p), skin.covers(p))
        })
        .collect();
    let uncovered: Vec<usize> = (0..count).filter(|&i| sides[i].1 && !sides[i].2).collect();
    // A cell is tissue when its centre is: the lattice then holds the region's volume to a
    // half cell either way at its surface, not a whole cell short of it (cells wholly inside
    // kept 116 of 620 mL of a breast on a 15 mm layer at a 9 mm spacing).
    // Per cell, by its centre: in front of the skin (whose faces beside a tissue cell are on
    // the skin side, shown by the scan's own triangles), or tissue.
    let m = n - UVec3::ONE;
    let cell_index = |c: UVec3| (c.x + m.x * (c.y + m.y * c.z)) as usize;
    let (in_front, tissue): (Vec<bool>, Vec<bool>) = (0..m.x * m.y * m.z)
        .into_par_iter()
        .map(|i| {
            let c = UVec3::new(i % m.x, i / m.x % m.y, i / (m.x * m.y));
            let p = (node(c) + 0.5 * h).as_dvec3();
            let behind_skin = skin.behind(p);
            (!behind_skin, behind_skin && !wall.behind(p))
        })
        .unzip();
    let cells: Vec<UVec3> = (0..m.x * m.y * m.z)
        .filter(|&i| tissue[i as usize])
        .map(|i| UVec3::new(i % m.x, i / m.x % m.y, i / (m.x * m.y)))
        .collect();
    if cells.is_empty() {
        let behind = sides.iter().any(|s| s.0);
        let front = sides.iter().any(|s| s.1);
        return Err(Ok(if behind && front { BetweenError::WallInFront } else { BetweenError::Empty }));
    }
    // Where the tissue needs skin and the scan does not reach: undecided.
    // (Only where tissue cells are near, and where the skin's nearest point does not say the
    // point is in front of it: a point in the air beside the torso, which the skin's tilted
    // rays pass by, is in front of it.)
    let undecided: Vec<usize> = uncovered
        .par_iter()
        .copied()
        .filter(|&i| {
            let c = at(i);
            cells.iter().any(|cell| (cell.as_ivec3() - c.as_ivec3()).abs().max_element() <= 1)
                && !skin.in_front_nearby(node(c).as_dvec3())
        })
        .collect();
    if let Some(&i) = undecided.first() {
        return Err(Ok(BetweenError::Uncovered(undecided.len(), node(at(i)))));
    }
    // The vertices of tissue cells, the springs along their edges and face diagonals, and the
    // faces not shared with another tissue cell.
    let mut vertex = vec![u32::MAX; count];
    let mut pos = Vec::new();
    let reach = SNAP * f64::from(h);
    let mut moved = Vec::new();
    // Each vertex's lattice position, before it is snapped.
    let mut lattice = Vec::new();
    for c in &cells {
        for k in 0..8u32 {
            let i = idx(c.x + (k & 1), c.y + (k >> 1 & 1), c.z + (k >> 2 & 1));
            if vertex[i] == u32::MAX {
                vertex[i] = pos.len() as u32;
                let p = node(at(i)).as_dvec3();
                // Onto the skin (back along its facing direction) or onto the wall (forward).
                let snapped = match sides[i] {
                    (false, ..) => skin.along(p, -1.0, reach),
                    (true, false, _) => wall.along(p, 1.0, reach),
                    (true, true, _) => None,
                };
                moved.push(snapped.is_some());
                lattice.push(p.as_vec3());
                pos.push(snapped.unwrap_or(p).as_vec3());
            }
        }
    }
    // Six tetrahedra per cell, along its main diagonal (as `lattice_tets` cuts a lattice).
    let mut tets = Vec::with_capacity(6 * cells.len());
    for c in &cells {
        let corner = |d: UVec3| vertex[idx(c.x + d.x, c.y + d.y, c.z + d.z)];
        let axes = [UVec3::X, UVec3::Y, UVec3::Z];
        for path in [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]] {
            let a = axes[path[0]];
            let b = a + axes[path[1]];
            tets.push([UVec3::ZERO, a, b, UVec3::ONE].map(corner));
        }
    }
    let is_full: std::collections::HashSet<UVec3> = cells.iter().copied().collect();
    let mut pairs: Vec<(u32, u32)> = Vec::new();
    let mut mesh = TriangleMesh::default();
    // Per surface triangle: whether it faces a cell in front of the skin.
    let mut skin_side = Vec::new();
    for c in &cells {
        let v = |dx: u32, dy: u32, dz: u32| vertex[idx(c.x + dx, c.y + dy, c.z + dz)];
        // 12 edges, 12 face diagonals.
        let corners: [u32; 8] =
            std::array::from_fn(|k| v(k as u32 & 1, k as u32 >> 1 & 1, k as u32 >> 2 & 1));
        for (a, b) in [
            (0, 1),
            (2, 3),
            (4, 5),
            (6, 7),
            (0, 2),
            (1, 3),
            (4, 6),
            (5, 7),
            (0, 4),
            (1, 5),
            (2, 6),
            (3, 7),
            (0, 3),
            (1, 2),
            (4, 7),
            (5, 6),
            (0, 5),
            (1, 4),
            (2, 7),
            (3, 6),
            (0, 6),
            (2, 4),
            (1, 7),
            (3, 5),
        ] {
            let (i, j) = (corners[a], corners[b]);
            pairs.push((i.min(j), i.max(j)));
        }
        let neighbour = |d: [i32; 3]| {
            let q = c.as_ivec3() + glam::IVec3::from_array(d);
            q.min_element() >= 0 && is_full.contains(&q.as_uvec3())
        };
        let before_skin = |d: [i32; 3]| {
            let q = c.as_ivec3() + glam::IVec3::from_array(d);
            q.min_element() >= 0 && q.cmplt(m.as_ivec3()).all() && in_front[cell_index(q.as_uvec3())]
        };
        for (d, quad, out) in [
            ([-1, 0, 0], [v(0, 0, 0), v(0, 1, 0), v(0, 1, 1), v(0, 0, 1)], Vec3::NEG_X),
            ([1, 0, 0], [v(1, 0, 0), v(1, 1, 0), v(1, 1, 1), v(1, 0, 1)], Vec3::X),
            ([0, -1, 0], [v(0, 0, 0), v(1, 0, 0), v(1, 0, 1), v(0, 0, 1)], Vec3::NEG_Y),
            ([0, 1, 0], [v(0, 1, 0), v(1, 1, 0), v(1, 1, 1), v(0, 1, 1)], Vec3::Y),
            ([0, 0, -1], [v(0, 0, 0), v(1, 0, 0), v(1, 1, 0), v(0, 1, 0)], Vec3::NEG_Z),
            ([0, 0, 1], [v(0, 0, 1), v(1, 0, 1), v(1, 1, 1), v(0, 1, 1)], Vec3::Z),
        ] {
            if !neighbour(d) {
                let on_skin = before_skin(d);
                for t in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                    skin_side.push(on_skin);
                    let [a, b, c] = t.map(|i| pos[i as usize]);
                    mesh.triangles.push(if (b - a).cross(c - a).dot(out) >= 0.0 {
                        t
                    } else {
                        [t[0], t[2], t[1]]
                    });
                }
            }
        }
    }
    // The body's other surface vertices, inside the region: onto the skin or the wall where
    // either is within reach along its facing direction (the lattice's lowest layer a little in
    // front of the wall comes down onto it).
    let mut on_surface = vec![false; pos.len()];
    mesh.triangles.iter().flatten().for_each(|&v| on_surface[v as usize] = true);
    for (v, p) in pos.iter_mut().enumerate() {
        if moved[v] || !on_surface[v] {
            continue;
        }
        let q = p.as_dvec3();
        let nearer = |a: Option<DVec3>, b: Option<DVec3>| match (a, b) {
            (Some(a), Some(b)) => Some(if a.distance(q) <= b.distance(q) { a } else { b }),
            (a, b) => a.or(b),
        };
        let to_skin = nearer(skin.along(q, 1.0, reach), skin.along(q, -1.0, reach));
        let to_wall = nearer(wall.along(q, 1.0, reach), wall.along(q, -1.0, reach));
        if let Some(s) = nearer(to_skin, to_wall) {
            *p = s.as_vec3();
        }
    }
    // A cell whose corners were snapped onto one flat piece of a coarse scan can fold or flatten
    // a tetrahedron: its corners go back to the lattice until none is thinner than a twentieth
    // of a regular one's.
    let mut unsnapped = 0usize;
    for _ in 0..4 {
        let thin: Vec<[u32; 4]> = tets
            .iter()
            .copied()
            .filter(|t| {
                let det = |p: &[Vec3]| {
                    let [a, b, c, d] = t.map(|v| p[v as usize]);
                    (b - a).dot((c - a).cross(d - a))
                };
                // Half the cuts are turned the other way round: the lattice's sign says which.
                det(&pos) * det(&lattice).signum() < 0.05 * h * h * h
            })
            .collect();
        if thin.is_empty() {
            break;
        }
        for t in thin {
            for v in t {
                if pos[v as usize] != lattice[v as usize] {
                    pos[v as usize] = lattice[v as usize];
                    unsnapped += 1;
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    let springs = pairs
        .into_iter()
        .map(|(i, j)| Spring { i, j, rest: pos[i as usize].distance(pos[j as usize]), k })
        .collect();
    // Held: on the chest wall (a lattice neighbour behind it) and on the box's faces.
    let (mut on_wall, mut on_box) = (0, 0);
    let mut modes = vec![Mode::Free; pos.len()];
    let mut held_on_wall = vec![false; pos.len()];
    for i in 0..count {
        let v = vertex[i];
        if v == u32::MAX {
            continue;
        }
        let c = at(i);
        let face = c.x == 0 || c.y == 0 || c.z == 0 || c.x + 1 == n.x || c.y + 1 == n.y || c.z + 1 == n.z;
        let mut wallward = !sides[i].1;
        for d in 0..27i32 {
            let o = glam::IVec3::new(d % 3 - 1, d / 3 % 3 - 1, d / 9 - 1);
            let q = c.as_ivec3() + o;
            if q.min_element() >= 0 && q.x < n.x as i32 && q.y < n.y as i32 && q.z < n.z as i32 {
                wallward |= !sides[idx(q.x as u32, q.y as u32, q.z as u32)].1;
            }
        }
        if wallward {
            on_wall += 1;
            held_on_wall[v as usize] = true;
            modes[v as usize] = Mode::Pinned;
        } else if face {
            on_box += 1;
            modes[v as usize] = Mode::Pinned;
        }
    }
    let wall_faces = (0..mesh.triangles.len() as u32)
        .filter(|&f| mesh.triangles[f as usize].iter().all(|&i| held_on_wall[i as usize]))
        .collect();
    let carried = carried_skin(outer, [&skin, &wall], (min, h, n), &vertex, (&pos, &mesh, &skin_side));
    let mut body = MassSpring::new(pos, modes, springs, mesh, material).map_err(Err)?;
    body.skin = carried;
    Ok((body, BetweenReport { cells: cells.len(), on_wall, on_box, unsnapped, wall_faces }, tets))
}

/// The scanned skin a `between` body carries ([`crate::body::CarriedSkin`]): `outer`'s triangles
/// inside the lattice's extent (the grid from `min`, spacing `h`, `n` nodes a side, `vertex`
/// the body's vertex at each node) and in front of the `wall`, each vertex following its cell;
/// shown beside the body's faces (`mesh`, its vertices at `pos`) that `skin_side` does not mark,
/// their corners in front of the `skin` moved back onto it. `None` where none of the scan is
/// kept.
fn carried_skin(
    outer: &Surface,
    [skin, wall]: [&Sheet; 2],
    (min, h, n): (Vec3, f32, UVec3),
    vertex: &[u32],
    (pos, mesh, skin_side): (&[Vec3], &TriangleMesh, &[bool]),
) -> Option<crate::body::CarriedSkin> {
    // The scanned skin, carried: the scan's triangles inside the lattice's box (the box given,
    // less what a whole number of cells does not reach) and in front of the wall, each vertex
    // following its lattice cell; shown beside the lattice's faces but those on the skin side.
    let (points, triangles) = clip_to_box(outer, min, min + h * (n - UVec3::ONE).as_vec3());
    let (corners, weights) = crate::bodies::carried(&points, min, h, n, vertex);
    let carried = |k: u32| corners[k as usize].iter().any(|&c| c != u32::MAX);
    let kept: Vec<[u32; 3]> = triangles
        .into_iter()
        .filter(|t| {
            let centre = t.iter().map(|&k| points[k as usize].as_dvec3()).sum::<DVec3>() / 3.0;
            t.iter().all(|&k| carried(k)) && !wall.behind(centre)
        })
        .collect();
    let mut renumber = vec![u32::MAX; points.len()];
    let mut sheet = crate::body::Embedding::default();
    for t in &kept {
        let t = t.map(|k| {
            if renumber[k as usize] == u32::MAX {
                renumber[k as usize] = sheet.rest.len() as u32;
                sheet.rest.push(points[k as usize]);
                sheet.corners.push(corners[k as usize]);
                sheet.weights.push(weights[k as usize]);
            }
            renumber[k as usize]
        });
        sheet.mesh.triangles.push(t);
    }
    let count = pos.len() as u32;
    // The lattice's faces shown beside the skin (the box's sides) end where the skin does: a
    // corner of one that lies in front of the skin (left on the lattice, or more than a snap
    // away) is shown moved back onto it, a point of the sheet carried as the others are; it
    // would otherwise stand out past her skin as a fin.
    let mut sides: Vec<[u32; 3]> =
        mesh.triangles.iter().zip(skin_side).filter(|(_, on_skin)| !**on_skin).map(|(t, _)| *t).collect();
    if !sheet.mesh.triangles.is_empty() {
        let mut onto = vec![u32::MAX; pos.len()];
        let mut moved_back = Vec::new();
        for &v in sides.iter().flatten() {
            let p = pos[v as usize].as_dvec3();
            if onto[v as usize] == u32::MAX
                && !skin.behind(p)
                && let Some(q) = skin.along(p, -1.0, 2.0 * f64::from(h))
            {
                onto[v as usize] = count + (sheet.rest.len() + moved_back.len()) as u32;
                moved_back.push(q.as_vec3());
            }
        }
        let (corners, weights) = crate::bodies::carried(&moved_back, min, h, n, vertex);
        sheet.rest.extend(moved_back);
        sheet.corners.extend(corners);
        sheet.weights.extend(weights);
        for v in sides.iter_mut().flatten() {
            if onto[*v as usize] != u32::MAX {
                *v = onto[*v as usize];
            }
        }
    }
    let skin_tris: Vec<[u32; 3]> = sheet.mesh.triangles.iter().map(|t| t.map(|k| k + count)).collect();
    let at = |k: u32| if k < count { pos[k as usize] } else { sheet.rest[(k - count) as usize] };
    let seam = stitch(&skin_tris, &sides, at);
    let shown = TriangleMesh { triangles: sides.into_iter().chain(skin_tris).chain(seam).collect() };
    (!sheet.mesh.triangles.is_empty()).then_some(crate::body::CarriedSkin { sheet, shown })
}

/// The triangles that close the seam between the skin's sheet `skin` and the lattice's faces
/// shown beside it, `sides` (points at `at`): where the rim of each is one loop, a strip
/// between the two loops, walked together (each step the shorter of the two diagonals, as
/// contours are tiled), each rim's edges used the other way round, so that with them the
/// surface has no boundary. None where either rim is not one loop (left open: see
/// docs/patient.md, "The body").
fn stitch(skin: &[[u32; 3]], sides: &[[u32; 3]], at: impl Fn(u32) -> Vec3) -> Vec<[u32; 3]> {
    use std::collections::{HashMap, HashSet};
    let all: HashSet<(u32, u32)> =
        skin.iter().chain(sides).flat_map(|t| (0..3).map(move |e| (t[e], t[(e + 1) % 3]))).collect();
    // A part's rim: its edges whose reverse no triangle of either part uses, as one loop in
    // their own direction (`None` where they are not one simple loop).
    let rim = |part: &[[u32; 3]]| -> Option<Vec<u32>> {
        let mut next: HashMap<u32, u32> = HashMap::new();
        for t in part {
            for e in 0..3 {
                let (u, v) = (t[e], t[(e + 1) % 3]);
                if !all.contains(&(v, u)) && next.insert(u, v).is_some() {
                    return None;
                }
            }
        }
        let &start = next.keys().min()?;
        let mut looped = vec![start];
        let mut v = *next.get(&start)?;
        while v != start {
            if looped.len() > next.len() {
                return None;
            }
            looped.push(v);
            v = *next.get(&v)?;
        }
        (looped.len() == next.len() && looped.len() >= 3).then_some(looped)
    };
    let (Some(a), Some(b)) = (rim(skin), rim(sides)) else { return Vec::new() };
    // The two rims run opposite ways round the seam: `a` forward, `b` backward, from the point
    // of `b` nearest `a`'s first.
    let j0 =
        (0..b.len()).min_by(|&x, &y| at(b[x]).distance(at(a[0])).total_cmp(&at(b[y]).distance(at(a[0]))));
    let Some(j0) = j0 else { return Vec::new() };
    let (na, nb) = (a.len(), b.len());
    let a_at = |i: usize| a[i % na];
    let b_at = |j: usize| b[(j0 + nb - j % nb) % nb];
    let (mut i, mut j) = (0, 0);
    let mut out = Vec::with_capacity(na + nb);
    while i < na || j < nb {
        let advance_a = j >= nb
            || (i < na && at(a_at(i + 1)).distance(at(b_at(j))) <= at(a_at(i)).distance(at(b_at(j + 1))));
        if advance_a {
            out.push([a_at(i + 1), a_at(i), b_at(j)]);
            i += 1;
        } else {
            out.push([b_at(j), b_at(j + 1), a_at(i)]);
            j += 1;
        }
    }
    out
}

/// The triangles of `surface` clipped to the box `min`..`max`: its points (the surface's own
/// inside the box, then where its edges cross the box's faces) and triangles over them, each
/// facing as the surface's did. A crossing is computed from its edge's two ends in one order
/// whichever triangle asks, so neighbours share it.
fn clip_to_box(surface: &Surface, min: Vec3, max: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (lo, hi) = (min.as_dvec3(), max.as_dvec3());
    let mut points: Vec<Vec3> = Vec::new();
    let mut index: std::collections::HashMap<[u32; 3], u32> = std::collections::HashMap::new();
    let mut add = |p: DVec3, points: &mut Vec<Vec3>| {
        let p = p.as_vec3();
        *index.entry(p.to_array().map(f32::to_bits)).or_insert_with(|| {
            points.push(p);
            points.len() as u32 - 1
        })
    };
    let mut triangles = Vec::new();
    for t in &surface.mesh.triangles {
        let mut polygon: Vec<DVec3> = t.iter().map(|&k| surface.positions[k as usize].as_dvec3()).collect();
        for axis in 0..3 {
            for (bound, sign) in [(lo[axis], 1.0), (hi[axis], -1.0)] {
                let inside = |p: &DVec3| sign * (p[axis] - bound) >= 0.0;
                let mut out = Vec::with_capacity(polygon.len() + 2);
                for (k, p) in polygon.iter().enumerate() {
                    let q = polygon[(k + 1) % polygon.len()];
                    if inside(p) {
                        out.push(*p);
                    }
                    if inside(p) != inside(&q) {
                        // The same crossing from either triangle: its ends in one order.
                        let (a, b) = if p.to_array() < q.to_array() { (*p, q) } else { (q, *p) };
                        let s = (bound - a[axis]) / (b[axis] - a[axis]);
                        let mut x = a + s * (b - a);
                        x[axis] = bound;
                        out.push(x);
                    }
                }
                polygon = out;
                if polygon.len() < 3 {
                    break;
                }
            }
            if polygon.len() < 3 {
                break;
            }
        }
        if polygon.len() < 3 {
            continue;
        }
        let ids: Vec<u32> = polygon.iter().map(|p| add(*p, &mut points)).collect();
        for k in 1..ids.len() - 1 {
            let tri = [ids[0], ids[k], ids[k + 1]];
            if tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2] {
                triangles.push(tri);
            }
        }
    }
    (points, triangles)
}
