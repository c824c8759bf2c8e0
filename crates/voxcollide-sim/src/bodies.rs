//! Builders of the paper's bodies: a tissue layer (box lattice), a cylinder (polar lattice) and
//! an implant (closed ellipsoidal shell), each with its springs and outward-facing surface.

use glam::{DVec3, UVec3, Vec3};

use crate::body::{MassSpring, Material, Mode, Spring};
use crate::mesh::TriangleMesh;
use voxcollide::error::Error;
use voxcollide::math::cross;

/// Adds springs between every pair in `pairs`, with rest lengths from `pos`.
fn springs_from(pos: &[Vec3], pairs: impl IntoIterator<Item = (u32, u32)>, k: f32) -> Vec<Spring> {
    pairs
        .into_iter()
        .map(|(i, j)| Spring { i, j, rest: pos[i as usize].distance(pos[j as usize]), k })
        .collect()
}

/// Adds the quad `a b c d` as two triangles facing `outward` (flipped if they do not).
fn quad(mesh: &mut TriangleMesh, pos: &[Vec3], [a, b, c, d]: [u32; 4], outward: Vec3) {
    tri(mesh, pos, [a, b, c], outward);
    tri(mesh, pos, [a, c, d], outward);
}

/// Adds the triangle `t`, turned to face `outward`.
fn tri(mesh: &mut TriangleMesh, pos: &[Vec3], t: [u32; 3], outward: Vec3) {
    let [a, b, c] = t.map(|i| pos[i as usize]);
    if cross(b - a, c - a).dot(outward) >= 0.0 {
        mesh.triangles.push(t);
    } else {
        mesh.triangles.push([t[0], t[2], t[1]]);
    }
}

/// A box lattice of `n` vertices per axis with spacing `h` from `origin`, joined by structural
/// and face-diagonal springs of stiffness `k`; `mode` says which vertices are held.
///
/// # Errors
/// [`Error::Invalid`] for fewer than 2 vertices on an axis.
pub fn box_lattice(
    n: UVec3,
    h: f32,
    origin: Vec3,
    k: f32,
    material: Material,
    mode: impl Fn(UVec3) -> Mode,
) -> Result<MassSpring, Error> {
    if n.min_element() < 2 {
        return Err(Error::Invalid {
            what: "lattice size",
            value: n.to_string(),
            rule: "needs 2 or more vertices per axis".into(),
        });
    }
    let idx = |x: u32, y: u32, z: u32| x + n.x * (y + n.y * z);
    let mut pos = Vec::with_capacity((n.x * n.y * n.z) as usize);
    let mut modes = Vec::with_capacity(pos.capacity());
    for z in 0..n.z {
        for y in 0..n.y {
            for x in 0..n.x {
                pos.push(origin + h * Vec3::new(x as f32, y as f32, z as f32));
                modes.push(mode(UVec3::new(x, y, z)));
            }
        }
    }
    let mut pairs = Vec::new();
    for z in 0..n.z {
        for y in 0..n.y {
            for x in 0..n.x {
                let i = idx(x, y, z);
                let (nx, ny, nz) = (x + 1 < n.x, y + 1 < n.y, z + 1 < n.z);
                if nx {
                    pairs.push((i, idx(x + 1, y, z)));
                }
                if ny {
                    pairs.push((i, idx(x, y + 1, z)));
                }
                if nz {
                    pairs.push((i, idx(x, y, z + 1)));
                }
                if nx && ny {
                    pairs.extend([(i, idx(x + 1, y + 1, z)), (idx(x + 1, y, z), idx(x, y + 1, z))]);
                }
                if nx && nz {
                    pairs.extend([(i, idx(x + 1, y, z + 1)), (idx(x + 1, y, z), idx(x, y, z + 1))]);
                }
                if ny && nz {
                    pairs.extend([(i, idx(x, y + 1, z + 1)), (idx(x, y + 1, z), idx(x, y, z + 1))]);
                }
            }
        }
    }
    let springs = springs_from(&pos, pairs, k);
    let mut surface = TriangleMesh::default();
    let (mx, my, mz) = (n.x - 1, n.y - 1, n.z - 1);
    for a in 0..mx {
        for b in 0..my {
            for (z, out) in [(0, Vec3::NEG_Z), (mz, Vec3::Z)] {
                quad(
                    &mut surface,
                    &pos,
                    [idx(a, b, z), idx(a + 1, b, z), idx(a + 1, b + 1, z), idx(a, b + 1, z)],
                    out,
                );
            }
        }
    }
    for a in 0..mx {
        for c in 0..mz {
            for (y, out) in [(0, Vec3::NEG_Y), (my, Vec3::Y)] {
                quad(
                    &mut surface,
                    &pos,
                    [idx(a, y, c), idx(a + 1, y, c), idx(a + 1, y, c + 1), idx(a, y, c + 1)],
                    out,
                );
            }
        }
    }
    for b in 0..my {
        for c in 0..mz {
            for (x, out) in [(0, Vec3::NEG_X), (mx, Vec3::X)] {
                quad(
                    &mut surface,
                    &pos,
                    [idx(x, b, c), idx(x, b + 1, c), idx(x, b + 1, c + 1), idx(x, b, c + 1)],
                    out,
                );
            }
        }
    }
    MassSpring::new(pos, modes, springs, surface, material)
}

/// The triangles of the box lattice's plane `y = j` (for a cut-away picture), facing -y.
#[must_use]
pub fn box_slice(n: UVec3, j: u32) -> Vec<[u32; 3]> {
    let idx = |x: u32, z: u32| x + n.x * (j + n.y * z);
    let mut out = Vec::new();
    for x in 0..n.x - 1 {
        for z in 0..n.z - 1 {
            let [a, b, c, d] = [idx(x, z), idx(x + 1, z), idx(x + 1, z + 1), idx(x, z + 1)];
            out.extend([[a, b, c], [a, c, d]]);
        }
    }
    out
}

/// The shape and lattice of a [`cylinder`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CylinderShape {
    /// Center of the bottom face.
    pub base: Vec3,
    /// Radius.
    pub radius: f32,
    /// Height along +z.
    pub height: f32,
    /// Rings of vertices around the center line.
    pub rings: u32,
    /// Vertices per ring.
    pub segments: u32,
    /// Layers of vertices along the axis.
    pub layers: u32,
}

/// The tetrahedra of a [`cylinder`]'s polar lattice (its vertices numbered as `cylinder`
/// numbers them): each layer's cells are triangles about the center line and quads between
/// rings, each quad cut along its diagonal from `(ring m, segment s)` to `(m + 1, s + 1)`; each
/// triangle with the one above it is a prism, split by [`prism_tets`](crate::material::neo_hookean::prism_tets)
/// so that neighbours share faces.
#[must_use]
pub fn cylinder_tets(shape: &CylinderShape) -> Vec<[u32; 4]> {
    let CylinderShape { rings, segments, layers, .. } = *shape;
    let per_layer = 1 + rings * segments;
    let idx = |l: u32, m: u32, s: u32| {
        l * per_layer + if m == 0 { 0 } else { 1 + (m - 1) * segments + s % segments }
    };
    let mut prisms = Vec::with_capacity(((layers - 1) * segments * (2 * rings - 1)) as usize);
    for l in 0..layers.saturating_sub(1) {
        for s in 0..segments {
            let mut triangles = vec![[(0, 0), (1, s), (1, s + 1)]];
            for m in 1..rings {
                triangles.push([(m, s), (m + 1, s), (m + 1, s + 1)]);
                triangles.push([(m, s), (m + 1, s + 1), (m, s + 1)]);
            }
            for t in triangles {
                let [a, b, c] = t.map(|(m, s)| idx(l, m, s));
                let [d, e, f] = t.map(|(m, s)| idx(l + 1, m, s));
                prisms.push([a, b, c, d, e, f]);
            }
        }
    }
    crate::material::neo_hookean::prism_tets(&prisms)
}

/// A solid cylinder along +z as a polar lattice of `rings` rings of `segments` vertices around a
/// center line, in `layers` layers; springs along rings, radii, layers and the diagonals of every
/// cell. Its top layer is driven, the rest free.
///
/// # Errors
/// [`Error::Invalid`] for fewer than 1 ring, 3 segments or 2 layers.
pub fn cylinder(shape: CylinderShape, k: f32, material: Material) -> Result<MassSpring, Error> {
    let CylinderShape { base, radius, height, rings, segments, layers } = shape;
    if rings < 1 || segments < 3 || layers < 2 {
        return Err(Error::Invalid {
            what: "cylinder lattice",
            value: format!("{rings} rings, {segments} segments, {layers} layers"),
            rule: "needs 1+ rings, 3+ segments and 2+ layers".into(),
        });
    }
    let per_layer = 1 + rings * segments;
    // Vertex (l, m, s): m = 0 is the center line (s ignored), m >= 1 a ring.
    let idx = |l: u32, m: u32, s: u32| {
        l * per_layer + if m == 0 { 0 } else { 1 + (m - 1) * segments + s % segments }
    };
    let mut pos = Vec::new();
    for l in 0..layers {
        let z = base.z + height * l as f32 / (layers - 1) as f32;
        pos.push(Vec3::new(base.x, base.y, z));
        for m in 1..=rings {
            let r = radius * m as f32 / rings as f32;
            for s in 0..segments {
                let t = std::f32::consts::TAU * s as f32 / segments as f32;
                pos.push(Vec3::new(base.x + r * t.cos(), base.y + r * t.sin(), z));
            }
        }
    }
    let mut pairs = Vec::new();
    for l in 0..layers {
        for m in 0..=rings {
            for s in 0..segments {
                if m == 0 && s > 0 {
                    continue;
                }
                let i = idx(l, m, s);
                if m >= 1 {
                    pairs.push((i, idx(l, m, s + 1)));
                }
                if m < rings {
                    let outs: Vec<u32> = if m == 0 { (0..segments).collect() } else { vec![s] };
                    for t in outs {
                        pairs.push((i, idx(l, m + 1, t)));
                        pairs.push((i, idx(l, m + 1, t + 1)));
                        if m >= 1 {
                            pairs.push((idx(l, m, s + 1), idx(l, m + 1, t)));
                        }
                    }
                }
                if l + 1 < layers {
                    pairs.push((i, idx(l + 1, m, s)));
                    if m >= 1 {
                        pairs.push((i, idx(l + 1, m, s + 1)));
                        pairs.push((idx(l, m, s + 1), idx(l + 1, m, s)));
                    }
                    if m < rings {
                        let outs: Vec<u32> = if m == 0 { (0..segments).collect() } else { vec![s] };
                        for t in outs {
                            pairs.push((i, idx(l + 1, m + 1, t)));
                            pairs.push((idx(l, m + 1, t), idx(l + 1, m, s)));
                        }
                    }
                }
            }
        }
    }
    let springs = springs_from(&pos, pairs, k);
    let mut surface = TriangleMesh::default();
    for (l, out) in [(0, Vec3::NEG_Z), (layers - 1, Vec3::Z)] {
        for s in 0..segments {
            tri(&mut surface, &pos, [idx(l, 0, 0), idx(l, 1, s), idx(l, 1, s + 1)], out);
            for m in 1..rings {
                quad(
                    &mut surface,
                    &pos,
                    [idx(l, m, s), idx(l, m + 1, s), idx(l, m + 1, s + 1), idx(l, m, s + 1)],
                    out,
                );
            }
        }
    }
    for l in 0..layers - 1 {
        for s in 0..segments {
            let q = [idx(l, rings, s), idx(l, rings, s + 1), idx(l + 1, rings, s + 1), idx(l + 1, rings, s)];
            let mid = (pos[q[0] as usize] + pos[q[2] as usize]) * 0.5;
            quad(&mut surface, &pos, q, (mid - Vec3::new(base.x, base.y, mid.z)).normalize_or_zero());
        }
    }
    let modes = (0..pos.len() as u32)
        .map(|i| if i / per_layer == layers - 1 { Mode::Driven } else { Mode::Free })
        .collect();
    MassSpring::new(pos, modes, springs, surface, material)
}

/// A closed ellipsoidal shell (an implant or expander) with radii `radii` around `center`: a UV
/// sphere of `rings` latitudes and `segments` meridians, springs along every edge, across every
/// quad and to the second neighbour along rings and meridians (bending). Vertices below
/// `center.z - pin_below * radii.z` rest on the chest wall and are pinned.
///
/// # Errors
/// [`Error::Invalid`] for fewer than 2 rings or 3 segments.
pub fn ellipsoid_shell(
    center: Vec3,
    radii: Vec3,
    rings: u32,
    segments: u32,
    pin_below: f32,
    k: f32,
    material: Material,
) -> Result<MassSpring, Error> {
    if rings < 2 || segments < 3 {
        return Err(Error::Invalid {
            what: "shell lattice",
            value: format!("{rings} rings, {segments} segments"),
            rule: "needs 2+ rings and 3+ segments".into(),
        });
    }
    // 0: north pole, then rings top to bottom, then the south pole.
    let ring = |r: u32, s: u32| 1 + r * segments + s % segments;
    let south = 1 + rings * segments;
    let mut pos = vec![center + Vec3::new(0.0, 0.0, radii.z)];
    for r in 0..rings {
        let phi = std::f32::consts::PI * (r + 1) as f32 / (rings + 1) as f32;
        for s in 0..segments {
            let t = std::f32::consts::TAU * s as f32 / segments as f32;
            pos.push(center + radii * Vec3::new(phi.sin() * t.cos(), phi.sin() * t.sin(), phi.cos()));
        }
    }
    pos.push(center - Vec3::new(0.0, 0.0, radii.z));
    let mut pairs = Vec::new();
    let mut surface = TriangleMesh::default();
    let out = |p: Vec3| (p - center) / (radii * radii);
    for s in 0..segments {
        pairs.push((0, ring(0, s)));
        pairs.push((south, ring(rings - 1, s)));
        pairs.push((0, ring(1, s)));
        pairs.push((south, ring(rings - 2, s)));
        tri(&mut surface, &pos, [0, ring(0, s), ring(0, s + 1)], out(pos[ring(0, s) as usize]));
        let (a, b) = (ring(rings - 1, s), ring(rings - 1, s + 1));
        tri(&mut surface, &pos, [south, a, b], out(pos[a as usize]));
        for r in 0..rings {
            pairs.push((ring(r, s), ring(r, s + 1)));
            pairs.push((ring(r, s), ring(r, s + 2)));
            if r + 1 < rings {
                pairs.extend([
                    (ring(r, s), ring(r + 1, s)),
                    (ring(r, s), ring(r + 1, s + 1)),
                    (ring(r, s + 1), ring(r + 1, s)),
                ]);
                let q = [ring(r, s), ring(r + 1, s), ring(r + 1, s + 1), ring(r, s + 1)];
                quad(&mut surface, &pos, q, out(pos[q[0] as usize]));
            }
            if r + 2 < rings {
                pairs.push((ring(r, s), ring(r + 2, s)));
            }
        }
    }
    let springs = springs_from(&pos, pairs, k);
    let floor = center.z - pin_below * radii.z;
    let modes = pos.iter().map(|p| if p.z < floor { Mode::Pinned } else { Mode::Free }).collect();
    MassSpring::new(pos, modes, springs, surface, material)
}

/// Where rays along +x through the rows of a lattice's half-spacing grid cross a closed surface:
/// the inside test of every lattice node and every spring's middle, by parity, at the cost of
/// the triangles each row meets instead of a winding number a point. Each row is probed by four
/// rays a millionth of the spacing off it (±y, ±z), and a point is inside when one of them says
/// so — or when a crossing is within the tolerance of it — so that points on a face parallel to
/// the rays count as on the surface.
struct RowCrossings {
    /// Per ray (4) per half-grid row (`(2n.y - 1) × (2n.z - 1)`): crossing x's, sorted; `None`
    /// where the crossings were odd in number (the ray met an edge or a vertex exactly).
    rows: Vec<Option<Vec<f64>>>,
    ny2: u32,
    nz2: u32,
}

impl RowCrossings {
    fn new(positions: &[Vec3], mesh: &TriangleMesh, origin: Vec3, h: f32, n: UVec3) -> RowCrossings {
        use rayon::prelude::*;
        let (ny2, nz2) = (2 * n.y - 1, 2 * n.z - 1);
        let half = f64::from(h) / 2.0;
        let (oy, oz) = (f64::from(origin.y), f64::from(origin.z));
        let delta = 1e-6 * f64::from(h);
        let offsets =
            [(delta, 0.7 * delta), (-0.8 * delta, delta), (0.9 * delta, -delta), (-delta, -0.6 * delta)];
        // Which rows each triangle's (y, z) box spans, and its crossing there.
        let mut lists: Vec<Vec<f64>> = vec![Vec::new(); 4 * (ny2 * nz2) as usize];
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| positions[i as usize].as_dvec3());
            let (ylo, yhi) = (a.y.min(b.y).min(c.y), a.y.max(b.y).max(c.y));
            let (zlo, zhi) = (a.z.min(b.z).min(c.z), a.z.max(b.z).max(c.z));
            let r0 =
                |lo: f64, o: f64, m: u32| (((lo - o - 2.0 * delta) / half).ceil().max(0.0) as u32).min(m);
            let r1 = |hi: f64, o: f64, m: u32| {
                let r = ((hi - o + 2.0 * delta) / half).floor();
                if r < 0.0 { None } else { Some((r as u32).min(m - 1)) }
            };
            let (Some(y1), Some(z1)) = (r1(yhi, oy, ny2), r1(zhi, oz, nz2)) else { continue };
            for yr in r0(ylo, oy, ny2)..=y1 {
                for zr in r0(zlo, oz, nz2)..=z1 {
                    for (k, (dy, dz)) in offsets.iter().enumerate() {
                        let (py, pz) = (oy + f64::from(yr) * half + dy, oz + f64::from(zr) * half + dz);
                        if let Some(x) = ray_x(a, b, c, py, pz) {
                            lists[(k as u32 * ny2 * nz2 + zr * ny2 + yr) as usize].push(x);
                        }
                    }
                }
            }
        }
        let rows = lists
            .into_par_iter()
            .map(|mut xs| {
                xs.sort_by(f64::total_cmp);
                xs.len().is_multiple_of(2).then_some(xs)
            })
            .collect();
        RowCrossings { rows, ny2, nz2 }
    }

    /// Whether x on half-grid row (y2, z2) is inside (or within `on` of a crossing); `None` when
    /// a ray of that row met an edge or a vertex exactly.
    fn inside(&self, x: f32, y2: u32, z2: u32, on: f32) -> Option<bool> {
        let x = f64::from(x);
        let mut any = false;
        for k in 0..4 {
            let xs = self.rows[(k * self.ny2 * self.nz2 + z2 * self.ny2 + y2) as usize].as_ref()?;
            let before = xs.partition_point(|&c| c < x);
            let near = [before.checked_sub(1), Some(before)]
                .into_iter()
                .flatten()
                .filter_map(|i| xs.get(i))
                .any(|&c| (c - x).abs() <= f64::from(on));
            any |= before % 2 == 1 || near;
        }
        Some(any)
    }
}

/// Where the ray `(t, py, pz)`, `t` along +x, crosses triangle `a b c`, if it does (the
/// triangle's projection on the (y, z) plane holds the point; edges count on one side only
/// where the signs say so, and an exact hit on an edge is treated as a crossing of both
/// triangles, which the parity check of the row then refuses).
fn ray_x(a: DVec3, b: DVec3, c: DVec3, py: f64, pz: f64) -> Option<f64> {
    let e = |p: DVec3, q: DVec3| (q.y - p.y) * (pz - p.z) - (q.z - p.z) * (py - p.y);
    let (w0, w1, w2) = (e(b, c), e(c, a), e(a, b));
    let inside = (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0) || (w0 <= 0.0 && w1 <= 0.0 && w2 <= 0.0);
    let sum = w0 + w1 + w2;
    if !inside || sum == 0.0 {
        return None;
    }
    Some((w0 * a.x + w1 * b.x + w2 * c.x) / sum)
}

/// The most vertices a lattice may have: a body of more does not fit the GPU's storage
/// bindings on common adapters, and the CPU would need gigabytes.
pub const MAX_LATTICE_VERTICES: u64 = 16 << 20;

/// What [`lattice_in_surface`] made, and what it could not keep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LatticeReport {
    /// Lattice vertices inside the surface (those with at least one spring).
    pub vertices: usize,
    /// Springs kept.
    pub springs: usize,
    /// Springs between two inside vertices whose middle is outside the surface (across a fold
    /// or a gap narrower than the spacing): left out, so that the lattice does not leak.
    pub springs_outside: usize,
    /// Inside vertices without any spring left (slivers thinner than the spacing): left out.
    pub isolated: usize,
    /// The volume of the lattice's full cells (those with all 8 corners kept: the solid the
    /// lattice holds) over the surface's enclosed volume. Below 1 by about a cell layer at the
    /// surface; much below where parts are thinner than the spacing.
    pub coverage: f64,
    /// Surface vertices farther than a cell's diagonal (`√3 · spacing`) from every lattice
    /// vertex: parts of the surface thinner than the spacing, which the lattice does not hold.
    pub uncovered: usize,
    /// All surface vertices, for the fraction.
    pub surface_vertices: usize,
}

/// A soft body filling the closed surface `positions` / `mesh` (outward-oriented, as
/// [`crate::mesh_io::read_surface`] gives it), in the manner of SOFA's `SparseGridTopology`: a
/// cubic lattice of spacing `h` centred on the surface's bounding box, keeping the nodes inside
/// (generalized winding number above ½, or on the surface within `1e-4 · h`), joined by
/// structural and face-diagonal springs of
/// stiffness `k` as in [`box_lattice`] — but only springs whose middle is inside too, so that
/// no spring bridges a concave gap. The body's own surface is the outer faces of the lattice's
/// full cells; `mode` decides from a vertex's position whether it is held.
///
/// # Errors
/// [`Error::Invalid`] for a spacing that is not a positive length, a surface without triangles,
/// a lattice of more than [`MAX_LATTICE_VERTICES`] vertices (estimated from the box and the
/// enclosed volume before anything is allocated, and named with its count), and a spacing so
/// coarse that no lattice cell lies wholly inside (no interior).
pub fn lattice_in_surface(
    positions: &[Vec3],
    mesh: &TriangleMesh,
    h: f32,
    k: f32,
    material: Material,
    mode: impl Fn(Vec3) -> Mode,
) -> Result<(MassSpring, LatticeReport), Error> {
    use rayon::prelude::*;

    let invalid = |what, value: String, rule: String| Error::Invalid { what, value, rule };
    if !(h.is_finite() && h > 0.0) {
        return Err(invalid("lattice spacing", h.to_string(), "must be a positive length".into()));
    }
    let surface = crate::geometry::ClosedSurface::new(positions, mesh)?;
    let Some((lo, hi)) = surface.bounds() else {
        return Err(invalid("surface", "no triangles".into(), "a lattice needs a closed surface".into()));
    };
    let volume: f64 = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize].as_dvec3());
            a.dot(b.cross(c)) / 6.0
        })
        .sum();
    let extent = (hi - lo).as_dvec3();
    let hd = f64::from(h);
    let n = (extent / hd).floor() + glam::DVec3::ONE;
    let grid = n.x * n.y * n.z;
    let estimate = (volume.abs() / (hd * hd * hd)).max(1.0);
    if grid > 4.0 * MAX_LATTICE_VERTICES as f64 || estimate > MAX_LATTICE_VERTICES as f64 {
        return Err(invalid(
            "lattice spacing",
            h.to_string(),
            format!(
                "gives about {estimate:.0} lattice vertices ({grid:.0} lattice nodes in the box); at most {MAX_LATTICE_VERTICES} are allowed"
            ),
        ));
    }
    let n = UVec3::new(n.x as u32, n.y as u32, n.z as u32);
    let origin = 0.5 * (lo + hi) - 0.5 * h * (n - UVec3::ONE).as_vec3();
    let node = |x: u32, y: u32, z: u32| origin + h * Vec3::new(x as f32, y as f32, z as f32);
    let count = (n.x * n.y * n.z) as usize;
    let idx = |x: u32, y: u32, z: u32| (x + n.x * (y + n.y * z)) as usize;
    // Inside, or on the surface within a ten-thousandth of the spacing (a node or a spring's
    // middle exactly on a face, as where a box's faces fall on the lattice, is not outside).
    // Inside, or on the surface within a ten-thousandth of the spacing (a node or a spring's
    // middle exactly on a face, as where a box's faces fall on the lattice, is not outside).
    let rays = RowCrossings::new(positions, mesh, origin, h, n);
    let on = 1e-4 * h;
    let keeps = |p: Vec3, y2: u32, z2: u32| match rays.inside(p.x, y2, z2, on) {
        Some(inside) => inside,
        // A row whose rays met an edge or a vertex exactly: the winding number decides.
        None => surface.contains(p) || surface.distance(p) <= on,
    };
    // A node's lattice coordinates and position, from its linear index.
    let coords = |i: usize| {
        let i = i as u32;
        (i % n.x, i / n.x % n.y, i / (n.x * n.y))
    };
    let grid_pos = |i: usize| {
        let (x, y, z) = coords(i);
        node(x, y, z)
    };
    // Which nodes are inside, from the crossings of the rows' rays with the surface.
    let inside: Vec<bool> = (0..count)
        .into_par_iter()
        .map(|i| {
            let (_, y, z) = coords(i);
            keeps(grid_pos(i), 2 * y, 2 * z)
        })
        .collect();

    // Springs between inside nodes whose middle is inside too.
    let steps: [[i32; 3]; 9] = [
        [1, 0, 0],
        [0, 1, 0],
        [0, 0, 1],
        [1, 1, 0],
        [1, -1, 0],
        [1, 0, 1],
        [1, 0, -1],
        [0, 1, 1],
        [0, 1, -1],
    ];
    let at = |x: u32, y: u32, z: u32, d: [i32; 3]| -> Option<usize> {
        let (x, y, z) = (x as i64 + i64::from(d[0]), y as i64 + i64::from(d[1]), z as i64 + i64::from(d[2]));
        let inb = |v: i64, m: u32| v >= 0 && v < i64::from(m);
        (inb(x, n.x) && inb(y, n.y) && inb(z, n.z)).then(|| idx(x as u32, y as u32, z as u32))
    };
    let candidates: Vec<(usize, usize)> = (0..count)
        .filter(|&i| inside[i])
        .flat_map(|i| {
            let (x, y, z) = coords(i);
            steps.iter().filter_map(move |&d| at(x, y, z, d).map(|j| (i, j)))
        })
        .filter(|&(_, j)| inside[j])
        .collect();
    // A spring's middle lies on a row of the half-spacing grid: (y_i + y_j, z_i + z_j) in
    // half-spacings.
    let kept: Vec<bool> = candidates
        .par_iter()
        .map(|&(i, j)| {
            let ((_, yi, zi), (_, yj, zj)) = (coords(i), coords(j));
            keeps(0.5 * (grid_pos(i) + grid_pos(j)), yi + yj, zi + zj)
        })
        .collect();
    let springs_outside = kept.iter().filter(|k| !**k).count();
    let mut has_spring = vec![false; count];
    // Per node, which of the three axis springs forward from it were kept (bits x, y, z).
    let mut axis_kept = vec![0u8; count];
    for (&(i, j), &keep) in candidates.iter().zip(&kept) {
        if keep {
            has_spring[i] = true;
            has_spring[j] = true;
            let d = j - i;
            let bit = if d == 1 {
                1
            } else if d == n.x as usize {
                2
            } else if d == (n.x * n.y) as usize {
                4
            } else {
                0
            };
            axis_kept[i] |= bit;
        }
    }
    let isolated = (0..count).filter(|&i| inside[i] && !has_spring[i]).count();
    let mut vertex = vec![u32::MAX; count];
    let mut pos = Vec::new();
    for i in 0..count {
        if has_spring[i] {
            vertex[i] = pos.len() as u32;
            pos.push(grid_pos(i));
        }
    }
    // The outer faces of the full cells: all 8 corners and all 12 edges kept, so that a cell
    // never spans a gap whose springs were left out.
    let full = |x: u32, y: u32, z: u32| {
        if !(x + 1 < n.x && y + 1 < n.y && z + 1 < n.z) {
            return false;
        }
        let corner = |c: u32| idx(x + (c & 1), y + (c >> 1 & 1), z + (c >> 2 & 1));
        // Edges along x start at the corners with x = 0, along y at y = 0, along z at z = 0.
        (0..8).all(|c| vertex[corner(c)] != u32::MAX)
            && [0u32, 2, 4, 6].iter().all(|&c| axis_kept[corner(c)] & 1 != 0)
            && [0u32, 1, 4, 5].iter().all(|&c| axis_kept[corner(c)] & 2 != 0)
            && [0u32, 1, 2, 3].iter().all(|&c| axis_kept[corner(c)] & 4 != 0)
    };
    let mut cells = 0usize;
    let mut surface_mesh = TriangleMesh::default();
    for z in 0..n.z.saturating_sub(1) {
        for y in 0..n.y.saturating_sub(1) {
            for x in 0..n.x.saturating_sub(1) {
                if !full(x, y, z) {
                    continue;
                }
                cells += 1;
                let v = |dx: u32, dy: u32, dz: u32| vertex[idx(x + dx, y + dy, z + dz)];
                let neighbour_full = |dx: i32, dy: i32, dz: i32| {
                    let (a, b, c) =
                        (x as i64 + i64::from(dx), y as i64 + i64::from(dy), z as i64 + i64::from(dz));
                    a >= 0 && b >= 0 && c >= 0 && full(a as u32, b as u32, c as u32)
                };
                let faces = [
                    ((-1, 0, 0), [v(0, 0, 0), v(0, 1, 0), v(0, 1, 1), v(0, 0, 1)], Vec3::NEG_X),
                    ((1, 0, 0), [v(1, 0, 0), v(1, 1, 0), v(1, 1, 1), v(1, 0, 1)], Vec3::X),
                    ((0, -1, 0), [v(0, 0, 0), v(1, 0, 0), v(1, 0, 1), v(0, 0, 1)], Vec3::NEG_Y),
                    ((0, 1, 0), [v(0, 1, 0), v(1, 1, 0), v(1, 1, 1), v(0, 1, 1)], Vec3::Y),
                    ((0, 0, -1), [v(0, 0, 0), v(1, 0, 0), v(1, 1, 0), v(0, 1, 0)], Vec3::NEG_Z),
                    ((0, 0, 1), [v(0, 0, 1), v(1, 0, 1), v(1, 1, 1), v(0, 1, 1)], Vec3::Z),
                ];
                for ((dx, dy, dz), corners, out) in faces {
                    if !neighbour_full(dx, dy, dz) {
                        quad(&mut surface_mesh, &pos, corners, out);
                    }
                }
            }
        }
    }
    if cells == 0 {
        return Err(invalid(
            "lattice spacing",
            h.to_string(),
            format!(
                "leaves no lattice cell wholly inside the surface (its box is {:.4} × {:.4} × {:.4}); use a finer spacing",
                extent.x, extent.y, extent.z
            ),
        ));
    }
    // Surface vertices the lattice does not reach: no kept node within a cell's diagonal.
    let reach2 = 3.0 * h * h * 1.0001;
    let uncovered = positions
        .par_iter()
        .filter(|p| {
            let q = ((**p - origin) / h).round();
            let mut near = false;
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let c = q + Vec3::new(dx as f32, dy as f32, dz as f32);
                        if c.cmplt(Vec3::ZERO).any() || c.cmpge(n.as_vec3()).any() {
                            continue;
                        }
                        let i = idx(c.x as u32, c.y as u32, c.z as u32);
                        near |= vertex[i] != u32::MAX && grid_pos(i).distance_squared(**p) <= reach2;
                    }
                }
            }
            !near
        })
        .count();
    let pairs: Vec<(u32, u32)> = candidates
        .iter()
        .zip(&kept)
        .filter(|(_, keep)| **keep)
        .map(|(&(i, j), _)| (vertex[i], vertex[j]))
        .collect();
    let springs = springs_from(&pos, pairs, k);
    let report = LatticeReport {
        vertices: pos.len(),
        springs: springs.len(),
        springs_outside,
        isolated,
        coverage: cells as f64 * hd * hd * hd / volume.abs().max(f64::MIN_POSITIVE),
        uncovered,
        surface_vertices: positions.len(),
    };
    // The user's surface, carried by the lattice.
    let (corners, weights) = carried(positions, origin, h, n, &vertex);
    let modes = pos.iter().map(|p| mode(*p)).collect();
    let mut body = MassSpring::new(pos, modes, springs, surface_mesh, material)?;
    body.embedded =
        Some(crate::body::Embedding { rest: positions.to_vec(), mesh: mesh.clone(), corners, weights });
    Ok((body, report))
}

/// How a lattice carries `points` (an [`Embedding`](crate::body::Embedding)'s corners and
/// weights): each point in its cell of the grid from `origin` (spacing `h`, `n` nodes a side,
/// `vertex` the body's vertex at each node or `u32::MAX`), weighted trilinearly over the
/// cell's kept corners (renormalized); one whose cell keeps none follows its nearest kept node
/// within the 3 × 3 × 3 block around it, and one with none there is carried by nothing (all
/// corners `u32::MAX`: it stays where it is).
pub(crate) fn carried(
    points: &[Vec3],
    origin: Vec3,
    h: f32,
    n: UVec3,
    vertex: &[u32],
) -> (Vec<[u32; 8]>, Vec<[f32; 8]>) {
    let idx = |x: u32, y: u32, z: u32| (x + n.x * (y + n.y * z)) as usize;
    let mut corners = Vec::with_capacity(points.len());
    let mut weights = Vec::with_capacity(points.len());
    for p in points {
        let q = (*p - origin) / h;
        let c = q.floor().clamp(Vec3::ZERO, (n - UVec3::ONE).as_vec3());
        let f = (q - c).clamp(Vec3::ZERO, Vec3::ONE);
        let (cx, cy, cz) = (c.x as u32, c.y as u32, c.z as u32);
        let mut corner = [u32::MAX; 8];
        let mut weight = [0.0f32; 8];
        let mut total = 0.0;
        for k in 0..8u32 {
            let (dx, dy, dz) = (k & 1, k >> 1 & 1, k >> 2 & 1);
            let (x, y, z) = (cx + dx, cy + dy, cz + dz);
            if x >= n.x || y >= n.y || z >= n.z {
                continue;
            }
            let v = vertex[idx(x, y, z)];
            if v == u32::MAX {
                continue;
            }
            let w = (if dx == 1 { f.x } else { 1.0 - f.x })
                * (if dy == 1 { f.y } else { 1.0 - f.y })
                * (if dz == 1 { f.z } else { 1.0 - f.z });
            corner[k as usize] = v;
            weight[k as usize] = w;
            total += w;
        }
        if total > 1e-6 {
            weight.iter_mut().for_each(|w| *w /= total);
        } else {
            // No kept corner carries it: the nearest kept node around.
            let r = q.round();
            let mut best = (f32::MAX, u32::MAX);
            for d in 0..27i32 {
                let o = Vec3::new((d % 3 - 1) as f32, (d / 3 % 3 - 1) as f32, (d / 9 - 1) as f32);
                let g = r + o;
                if g.cmplt(Vec3::ZERO).any() || g.cmpge(n.as_vec3()).any() {
                    continue;
                }
                let v = vertex[idx(g.x as u32, g.y as u32, g.z as u32)];
                let dist = (origin + h * g).distance_squared(*p);
                if v != u32::MAX && dist < best.0 {
                    best = (dist, v);
                }
            }
            corner = [u32::MAX; 8];
            weight = [0.0; 8];
            if best.1 != u32::MAX {
                corner[0] = best.1;
                weight[0] = 1.0;
            }
        }
        corners.push(corner);
        weights.push(weight);
    }
    (corners, weights)
}

/// Each vertex's share of the mass of the tetrahedra `tets` over `rest`: a quarter of each
/// one's volume times `density` (kg per cubic unit), so that the body weighs its density
/// times its volume. (A body's lumped masses, and what gravity pulls: [`MassSpring::mass`].)
#[must_use]
pub fn tet_masses(rest: &[Vec3], tets: &[[u32; 4]], density: f64) -> Vec<f64> {
    let mut mass = vec![0.0f64; rest.len()];
    for t in tets {
        let [a, b, c, d] = t.map(|i| rest[i as usize].as_dvec3());
        let volume = ((b - a).dot((c - a).cross(d - a)) / 6.0).abs();
        for &v in t {
            mass[v as usize] += density * volume / 4.0;
        }
    }
    mass
}

/// A soft body of a tetrahedral mesh: a spring of stiffness `k` along every edge (once, however
/// many tetrahedra share it) and **lumped masses** — each tetrahedron's mass, `density` times
/// its volume, split equally among its four vertices. Its surface is the mesh's boundary.
///
/// # Errors
/// [`Error::Invalid`] for a density that is not positive, and the errors of
/// [`MassSpring::new`].
pub fn tetrahedral_body(
    mesh: &crate::mesh_io::Tetrahedra,
    k: f32,
    density: f32,
    material: Material,
    mode: impl Fn(Vec3) -> Mode,
) -> Result<MassSpring, Error> {
    if !(density.is_finite() && density > 0.0) {
        return Err(Error::Invalid {
            what: "density",
            value: density.to_string(),
            rule: "must be finite and positive".into(),
        });
    }
    let p = &mesh.positions;
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(6 * mesh.tets.len());
    for t in &mesh.tets {
        for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
            edges.push((t[i].min(t[j]), t[i].max(t[j])));
        }
    }
    let mass = tet_masses(p, &mesh.tets, f64::from(density));
    edges.sort_unstable();
    edges.dedup();
    let springs = springs_from(p, edges, k);
    let modes = p.iter().map(|q| mode(*q)).collect();
    let mut body = MassSpring::new(p.clone(), modes, springs, mesh.boundary.clone(), material)?;
    body.inv_mass = mass.iter().map(|&m| (1.0 / m) as f32).collect();
    body.mass = mass.iter().map(|&m| m as f32).collect();
    Ok(body)
}

/// A closed shell of the surface `positions` / `mesh` (outward, as
/// [`crate::mesh_io::read_surface`] gives it): a spring of stiffness `k` along every edge, and
/// a bending spring of the same stiffness across every edge, between the two corners opposite
/// it, so that the shell keeps its shape where a flat edge would fold freely. Pressure acts on
/// its triangles (an implant or an expander). Its surface is the mesh itself.
///
/// # Errors
/// [`Error::Invalid`] for an edge not shared by exactly two triangles (the surface is not closed
/// and manifold; `read_surface` refuses such files first), and the errors of
/// [`MassSpring::new`].
pub fn shell_from_surface(
    positions: &[Vec3],
    mesh: &TriangleMesh,
    k: f32,
    material: Material,
) -> Result<MassSpring, Error> {
    use std::collections::HashMap;
    // Each undirected edge and the corners opposite it.
    let mut opposite: HashMap<(u32, u32), Vec<u32>> = HashMap::with_capacity(3 * mesh.triangles.len() / 2);
    for t in &mesh.triangles {
        for (a, b, c) in [(t[0], t[1], t[2]), (t[1], t[2], t[0]), (t[2], t[0], t[1])] {
            opposite.entry((a.min(b), a.max(b))).or_default().push(c);
        }
    }
    let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(2 * opposite.len());
    for (&(a, b), across) in &opposite {
        let [c, d] = across[..] else {
            return Err(Error::Invalid {
                what: "shell surface",
                value: format!("edge {a}–{b} in {} triangles", across.len()),
                rule: "every edge of a shell must belong to exactly two triangles".into(),
            });
        };
        pairs.push((a, b));
        if c != d {
            pairs.push((c.min(d), c.max(d)));
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    let springs = springs_from(positions, pairs, k);
    let modes = vec![Mode::Free; positions.len()];
    MassSpring::new(positions.to_vec(), modes, springs, mesh.clone(), material)
}

/// A breast implant's outline by the numbers a catalogue gives: volume, base width and
/// projection, round or anatomical. All lengths in one unit, the volume in its cube.
///
/// The base is a disc of diameter `base` in the plane `z = −projection/2`, centred on the z
/// axis; the dome rises to `z = +projection/2`. Its height over the base at a point a fraction
/// `ρ` of the way from the apex's foot to the rim is `projection · (1 − ρ²)^α`, so that the
/// volume is `π (base/2)² · projection / (α + 1)`: the exponent `α` follows from the three
/// numbers ([`ImplantShape::exponent`]). `α = 1/2` is a half ellipsoid, a small `α` a full disc
/// with a rounded edge, a large one a steep cone. A round implant's apex is over the centre; an
/// anatomical (teardrop) one's is a quarter of the radius below it (towards −y, the lower pole),
/// so the lower pole is full and the upper one slopes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImplantShape {
    /// The enclosed volume.
    pub volume: f64,
    /// The base's diameter.
    pub base: f64,
    /// The height of the dome over the base.
    pub projection: f64,
    /// Teardrop instead of round.
    pub anatomical: bool,
}

/// The largest profile exponent [`ImplantShape::exponent`] accepts: a dome of `1/(α+1)` of its
/// cylinder, beyond which the outline is a spike rather than an implant.
pub const MAX_IMPLANT_EXPONENT: f64 = 10.0;

/// The profile exponent below which an implant started deflated flat is warned of: its outline
/// is then nearly a cylinder (a manufacturer's round implants lie between 0.19 and 0.51,
/// `scenes/catalogues/mentor-memorygel-round.toml`), its rim standing almost upright. Flattened
/// onto its base, that whole rim is pressed into its springs, which throw it open in the first
/// steps: on the MakeHuman patient at a 9 mm spacing, 400 mL on a 120 mm base at 36 mm
/// (exponent 0.018) moved at 7.6·10³ mm/s in its first step, over the blow-up limit (a tenth of
/// the scene a step, there 7.57·10³), where exponent 0.13 moved at 5.1·10³ and the catalogue's
/// at about 2.9·10³ (docs/patient.md, "A nearly cylindrical implant").
pub const FLAT_START_EXPONENT: f64 = 0.1;

impl ImplantShape {
    /// The profile exponent `α = π (base/2)² · projection / volume − 1`.
    ///
    /// # Errors
    /// [`Error::Invalid`] when the sizes are not positive and finite, when the volume is not
    /// less than the cylinder of that base and projection (no dome holds it), or when it is
    /// less than `1/(MAX_IMPLANT_EXPONENT + 1)` of it.
    pub fn exponent(&self) -> Result<f64, Error> {
        let sizes = [self.volume, self.base, self.projection];
        if !sizes.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(Error::Invalid {
                what: "implant",
                value: format!("{self:?}"),
                rule: "volume, base and projection must be positive".into(),
            });
        }
        let cylinder = std::f64::consts::PI * (0.5 * self.base).powi(2) * self.projection;
        let alpha = cylinder / self.volume - 1.0;
        if alpha <= 0.0 || alpha > MAX_IMPLANT_EXPONENT {
            return Err(Error::Invalid {
                what: "implant volume",
                value: format!("{}", self.volume),
                rule: format!(
                    "a dome of base {} and projection {} holds between {:.4} and {:.4} (less than its cylinder, more than 1/{} of it)",
                    self.base,
                    self.projection,
                    cylinder / (MAX_IMPLANT_EXPONENT + 1.0),
                    cylinder,
                    MAX_IMPLANT_EXPONENT + 1.0
                ),
            });
        }
        Ok(alpha)
    }
}

/// The closed, outward surface of `shape` with edges of about `edge`: a fan of rings from the
/// apex down the dome to the rim and across the flat base to its centre. The rings are spaced
/// evenly in `asin ρ` on the dome, closer near the rim where it turns down.
///
/// The facets lie inside the smooth dome, so its profile exponent is fitted (by bisection) so
/// that the facets themselves enclose `shape.volume`, to a millionth where the base and
/// projection allow it; a volume so close to the cylinder's that even the fullest faceted dome
/// falls short gets that fullest dome.
///
/// # Errors
/// Those of [`ImplantShape::exponent`], and [`Error::Invalid`] for an edge that is not positive
/// or gives over 4 million vertices.
pub fn implant_surface(shape: ImplantShape, edge: f64) -> Result<(Vec<Vec3>, TriangleMesh), Error> {
    let alpha = shape.exponent()?;
    let r = 0.5 * shape.base;
    let p = shape.projection;
    let rings_for = |length: f64| (length / edge).round().clamp(1.0, 1e6) as u32;
    if !(edge.is_finite() && edge > 0.0) {
        return Err(Error::Invalid {
            what: "implant edge",
            value: edge.to_string(),
            rule: "must be positive".into(),
        });
    }
    let segments = rings_for(std::f64::consts::TAU * r).max(12);
    let dome = rings_for(0.5 * std::f64::consts::PI * r.max(p)).max(3);
    let flat = rings_for(r).max(2);
    let count = u64::from(segments) * u64::from(dome + flat) + 2;
    if count > 4_000_000 {
        return Err(Error::Invalid {
            what: "implant edge",
            value: edge.to_string(),
            rule: format!("gives {count} vertices; at most 4,000,000"),
        });
    }
    let build = |alpha: f64| implant_facets(shape, alpha, segments, dome, flat);
    // Fewer facets enclose less: the volume falls as the exponent grows.
    let enclosed = |alpha: f64| {
        let (pos, mesh) = build(alpha);
        mesh.volume(&pos)
    };
    let (mut lo, mut hi) = (1e-6, alpha.max(1e-6));
    while enclosed(hi) > shape.volume && hi < MAX_IMPLANT_EXPONENT {
        hi = (2.0 * hi).min(MAX_IMPLANT_EXPONENT);
    }
    let fitted = if enclosed(lo) <= shape.volume {
        lo
    } else {
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if enclosed(mid) > shape.volume {
                lo = mid
            } else {
                hi = mid
            }
            if hi - lo < 1e-9 * hi {
                break;
            }
        }
        0.5 * (lo + hi)
    };
    Ok(build(fitted))
}

/// [`implant_surface`]'s facets for the profile exponent `alpha`.
fn implant_facets(
    shape: ImplantShape,
    alpha: f64,
    segments: u32,
    dome: u32,
    flat: u32,
) -> (Vec<Vec3>, TriangleMesh) {
    let r = 0.5 * shape.base;
    let p = shape.projection;
    // The foot of the apex, and the distance from it to the rim along direction θ.
    let foot = if shape.anatomical { DVec3::new(0.0, -0.25 * r, 0.0) } else { DVec3::ZERO };
    let reach = |dir: DVec3| {
        // |foot + t dir| = r, t > 0.
        let b = foot.dot(dir);
        -b + (b * b - foot.length_squared() + r * r).sqrt()
    };
    let at = |rho: f64, theta: f64, z: f64| {
        let dir = DVec3::new(theta.cos(), theta.sin(), 0.0);
        let xy = foot + rho * reach(dir) * dir;
        DVec3::new(xy.x, xy.y, z - 0.5 * p).as_vec3()
    };
    // Rings from the apex: the dome's (ρ = sin φ), the rim, the base's inward.
    let mut rings: Vec<(f64, f64)> = (1..dome)
        .map(|i| {
            let rho = (0.5 * std::f64::consts::PI * f64::from(i) / f64::from(dome)).sin();
            (rho, p * (1.0 - rho * rho).max(0.0).powf(alpha))
        })
        .collect();
    rings.push((1.0, 0.0));
    rings.extend((1..flat).rev().map(|j| (f64::from(j) / f64::from(flat), 0.0)));
    let mut pos = vec![at(0.0, 0.0, p)];
    for &(rho, z) in &rings {
        for s in 0..segments {
            pos.push(at(rho, std::f64::consts::TAU * f64::from(s) / f64::from(segments), z));
        }
    }
    let bottom = pos.len() as u32;
    pos.push(at(0.0, 0.0, 0.0));
    let ring = |k: u32, s: u32| 1 + k * segments + s % segments;
    let last = rings.len() as u32 - 1;
    let rim = dome - 1; // the index of the rim ring
    // Outward: up and away from the apex's axis on the dome, down on the base.
    let up = Vec3::new(0.0, 0.0, p as f32);
    let foot32 = foot.as_vec3();
    let dome_out = |q: Vec3| Vec3::new(q.x - foot32.x, q.y - foot32.y, 0.0) + up;
    let down = Vec3::NEG_Z;
    let mut mesh = TriangleMesh::default();
    for s in 0..segments {
        let (a, b) = (ring(0, s), ring(0, s + 1));
        tri(&mut mesh, &pos, [0, a, b], dome_out(pos[a as usize]));
        for k in 0..last {
            let q = [ring(k, s), ring(k + 1, s), ring(k + 1, s + 1), ring(k, s + 1)];
            let outward = if k < rim { dome_out(pos[q[0] as usize]) } else { down };
            quad(&mut mesh, &pos, q, outward);
        }
        tri(&mut mesh, &pos, [bottom, ring(last, s + 1), ring(last, s)], down);
    }
    (pos, mesh)
}
