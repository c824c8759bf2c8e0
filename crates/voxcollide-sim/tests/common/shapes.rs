//! Closed surfaces that look like anatomy, generated: a concave kidney bean, a drooping
//! breast-like bulge, and a torus (closed without being a sphere).
#![allow(dead_code)]

use voxcollide::glam::{DVec3, Vec3};
use voxcollide_sim::mesh::TriangleMesh;
use voxcollide_sim::mesh_io::Surface;

/// A closed surface of sphere topology: the poles and `rings` rings of `segments`, the point at
/// polar angle θ and azimuth φ given by `f`, triangles counter-clockwise seen from outside.
pub fn sphere_like(rings: u32, segments: u32, f: impl Fn(f64, f64) -> DVec3) -> Surface {
    let pi = std::f64::consts::PI;
    let mut positions = vec![f(0.0, 0.0)];
    for r in 1..=rings {
        let theta = pi * f64::from(r) / f64::from(rings + 1);
        for s in 0..segments {
            positions.push(f(theta, 2.0 * pi * f64::from(s) / f64::from(segments)));
        }
    }
    positions.push(f(pi, 0.0));
    let south = 1 + rings * segments;
    let at = |r: u32, s: u32| 1 + r * segments + s % segments;
    let mut triangles = Vec::new();
    for s in 0..segments {
        triangles.push([0, at(0, s), at(0, s + 1)]);
        triangles.push([south, at(rings - 1, s + 1), at(rings - 1, s)]);
    }
    for r in 0..rings - 1 {
        for s in 0..segments {
            triangles.push([at(r, s), at(r + 1, s), at(r + 1, s + 1)]);
            triangles.push([at(r, s), at(r + 1, s + 1), at(r, s + 1)]);
        }
    }
    Surface { positions: positions.iter().map(|p| p.as_vec3()).collect(), mesh: TriangleMesh { triangles } }
}

/// A kidney bean, 120 × 60 × 50 mm, concave on one side (its hilum).
pub fn kidney() -> Surface {
    kidney_of(24, 48)
}

/// The kidney bean with `rings` × `segments` (about `2 · rings · segments` triangles).
pub fn kidney_of(rings: u32, segments: u32) -> Surface {
    sphere_like(rings, segments, |t, p| {
        let (x, y, z) = (t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
        DVec3::new(60.0 * x, 30.0 * (y + 0.55 * (1.0 - x * x)), 25.0 * z)
    })
}

/// A breast-like bulge: wide and flat at the chest wall (z low), projecting and drooping.
pub fn breast() -> Surface {
    sphere_like(20, 40, |t, p| {
        let (x, y, z) = (t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
        let droop = 0.35 * (1.0 - z) * (1.0 - z);
        DVec3::new(70.0 * x, 65.0 * y - 20.0 * droop, 40.0 * z.max(-0.3) + 8.0 * (x * x + y * y))
    })
}

/// A torus (genus 1): closed without being a sphere.
pub fn torus() -> Surface {
    let (big, small, n, m) = (40.0f64, 12.0f64, 48u32, 16u32);
    let pi = std::f64::consts::PI;
    let mut positions = Vec::new();
    for i in 0..n {
        for j in 0..m {
            let (u, v) = (2.0 * pi * f64::from(i) / f64::from(n), 2.0 * pi * f64::from(j) / f64::from(m));
            let r = big + small * v.cos();
            positions.push(Vec3::new((r * u.cos()) as f32, (r * u.sin()) as f32, (small * v.sin()) as f32));
        }
    }
    let at = |i: u32, j: u32| (i % n) * m + j % m;
    let mut triangles = Vec::new();
    for i in 0..n {
        for j in 0..m {
            triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    Surface { positions, mesh: TriangleMesh { triangles } }
}

pub fn volume(s: &Surface) -> f64 {
    s.mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| s.positions[i as usize].as_dvec3());
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// The closed surface of a union of axis-aligned cubes of side `size` at integer `cells`: each
/// face between a cell and an empty neighbour, outward, vertices shared.
pub fn cubes(cells: &[[i32; 3]], size: f32) -> Surface {
    use std::collections::{HashMap, HashSet};
    let set: HashSet<[i32; 3]> = cells.iter().copied().collect();
    let mut index: HashMap<[i32; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut vertex = |c: [i32; 3], positions: &mut Vec<Vec3>| {
        *index.entry(c).or_insert_with(|| {
            positions.push(Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) * size);
            (positions.len() - 1) as u32
        })
    };
    let mut triangles = Vec::new();
    for &[x, y, z] in cells {
        // (neighbour offset, the face's four corners counter-clockwise seen from outside)
        let faces: [([i32; 3], [[i32; 3]; 4]); 6] = [
            ([-1, 0, 0], [[0, 0, 0], [0, 0, 1], [0, 1, 1], [0, 1, 0]]),
            ([1, 0, 0], [[1, 0, 0], [1, 1, 0], [1, 1, 1], [1, 0, 1]]),
            ([0, -1, 0], [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]]),
            ([0, 1, 0], [[0, 1, 0], [0, 1, 1], [1, 1, 1], [1, 1, 0]]),
            ([0, 0, -1], [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]]),
            ([0, 0, 1], [[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]]),
        ];
        for (d, quad) in faces {
            if set.contains(&[x + d[0], y + d[1], z + d[2]]) {
                continue;
            }
            let v = quad.map(|o| vertex([x + o[0], y + o[1], z + o[2]], &mut positions));
            triangles.push([v[0], v[1], v[2]]);
            triangles.push([v[0], v[2], v[3]]);
        }
    }
    Surface { positions, mesh: TriangleMesh { triangles } }
}

/// A U of cubes: a base `base` cells thick, two arms `arm` cells thick and `length` long, a gap
/// of `gap` cells between them, `depth` cells deep.
pub fn u_shape(base: i32, arm: i32, gap: i32, length: i32, depth: i32) -> Vec<[i32; 3]> {
    let width = 2 * arm + gap;
    let mut cells = Vec::new();
    for z in 0..depth {
        for x in 0..width {
            for y in 0..base + length {
                let in_arm = x < arm || x >= arm + gap;
                if y < base || in_arm {
                    cells.push([x, y, z]);
                }
            }
        }
    }
    cells
}

/// Writes `s` as a binary STL file (every triangle's corners apart, as STL stores them).
pub fn write_stl(path: &std::path::Path, s: &Surface) {
    let triangles: Vec<stl_io::Triangle> = s
        .mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| s.positions[i as usize]);
            stl_io::Triangle {
                normal: stl_io::Normal::new((b - a).cross(c - a).normalize_or_zero().to_array()),
                vertices: [a, b, c].map(|p| stl_io::Vertex::new(p.to_array())),
            }
        })
        .collect();
    let mut file = std::fs::File::create(path).unwrap();
    stl_io::write_stl(&mut file, triangles.iter()).unwrap();
}

/// An open sheet over the square `[-half, half]²` of the (x, y) plane at height `z(x, y)`,
/// `cells` squares a side, each two triangles facing +z: a torso scan or a chest wall lying
/// on its back, facing up (away from the patient).
pub fn height_sheet(half: f64, cells: u32, z: impl Fn(f64, f64) -> f64) -> Surface {
    let n = cells + 1;
    let mut positions = Vec::with_capacity((n * n) as usize);
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (
                -half + 2.0 * half * f64::from(i) / f64::from(cells),
                -half + 2.0 * half * f64::from(j) / f64::from(cells),
            );
            positions.push(DVec3::new(x, y, z(x, y)).as_vec3());
        }
    }
    let mut mesh = TriangleMesh::default();
    for j in 0..cells {
        for i in 0..cells {
            let v = |a: u32, b: u32| (i + a) + n * (j + b);
            mesh.triangles.push([v(0, 0), v(1, 0), v(1, 1)]);
            mesh.triangles.push([v(0, 0), v(1, 1), v(0, 1)]);
        }
    }
    Surface { positions, mesh }
}

/// A breast lying on its back: the skin `base` above the chest wall (z = 0), rising by a mound
/// of `height` over a disc of `radius` about the origin (a cos² profile), its apex at `apex_shift`
/// along +x (ptosis, standing).
pub fn breast_skin(base: f64, height: f64, radius: f64, apex_shift: f64) -> impl Fn(f64, f64) -> f64 {
    move |x, y| {
        let r = ((x - apex_shift).powi(2) + y * y).sqrt() / radius;
        base + if r < 1.0 { height * (0.5 + 0.5 * (std::f64::consts::PI * r).cos()) } else { 0.0 }
    }
}
