//! Builders of the paper's bodies: a tissue layer (box lattice), a cylinder (polar lattice) and
//! an implant (closed ellipsoidal shell), each with its springs and outward-facing surface.

use glam::{UVec3, Vec3};

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
