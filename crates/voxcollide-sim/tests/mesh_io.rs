//! Closed surfaces from STL (binary and ASCII), OBJ and PLY (ASCII and binary): shapes that look
//! like anatomy (a concave kidney bean, a drooping breast-like bulge, a torus), written in every
//! format, read back, welded and checked; and every way a surface can fail to bound a volume is a
//! named error with its count.

use std::io::Write as _;
use std::path::{Path, PathBuf};

mod common;

use common::shapes::{breast, kidney, torus, volume, write_stl};
use voxcollide::Error;
use voxcollide::glam::Vec3;
use voxcollide_sim::mesh_io::{Surface, read_surface};

struct Dir(PathBuf);

impl Dir {
    fn new(name: &str) -> Dir {
        let dir = std::env::temp_dir().join(format!("voxcollide-mesh-io-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        Dir(dir)
    }
}

impl Drop for Dir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn corners(s: &Surface, t: &[u32; 3]) -> [Vec3; 3] {
    t.map(|i| s.positions[i as usize])
}

fn write_ascii_stl(path: &Path, s: &Surface) {
    let mut out = String::from("solid test\n");
    for t in &s.mesh.triangles {
        let [a, b, c] = corners(s, t);
        let n = (b - a).cross(c - a).normalize_or_zero();
        out += &format!("  facet normal {} {} {}\n    outer loop\n", n.x, n.y, n.z);
        for p in [a, b, c] {
            out += &format!("      vertex {:e} {:e} {:e}\n", p.x, p.y, p.z);
        }
        out += "    endloop\n  endfacet\n";
    }
    out += "endsolid test\n";
    std::fs::write(path, out).unwrap();
}

fn write_obj(path: &Path, s: &Surface) {
    let mut out = String::from("# test\no shape\n");
    for p in &s.positions {
        out += &format!("v {:e} {:e} {:e}\n", p.x, p.y, p.z);
    }
    for t in &s.mesh.triangles {
        out += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, out).unwrap();
}

fn write_ply(path: &Path, s: &Surface, binary: bool) {
    let format = if binary { "binary_little_endian" } else { "ascii" };
    let header = format!(
        "ply\nformat {format} 1.0\ncomment test\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        s.positions.len(),
        s.mesh.triangles.len()
    );
    let mut file = std::fs::File::create(path).unwrap();
    file.write_all(header.as_bytes()).unwrap();
    if binary {
        for p in &s.positions {
            for v in p.to_array() {
                file.write_all(&v.to_le_bytes()).unwrap();
            }
        }
        for t in &s.mesh.triangles {
            file.write_all(&[3]).unwrap();
            for v in t {
                file.write_all(&(*v as i32).to_le_bytes()).unwrap();
            }
        }
    } else {
        let mut out = String::new();
        for p in &s.positions {
            out += &format!("{:e} {:e} {:e}\n", p.x, p.y, p.z);
        }
        for t in &s.mesh.triangles {
            out += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
        }
        file.write_all(out.as_bytes()).unwrap();
    }
}

/// Every format: `(file name, writer)`.
type Writer = fn(&Path, &Surface);

fn formats() -> Vec<(&'static str, Writer)> {
    vec![
        ("binary.stl", write_stl),
        ("ascii.stl", write_ascii_stl),
        ("shape.OBJ", write_obj),
        ("ascii.ply", |p, s| write_ply(p, s, false)),
        ("binary.ply", |p, s| write_ply(p, s, true)),
    ]
}

#[test]
fn anatomy_like_surfaces_read_back_from_every_format() {
    let dir = Dir::new("formats");
    for (shape, surface) in [("kidney", kidney()), ("breast", breast()), ("torus", torus())] {
        let expected = volume(&surface);
        assert!(expected > 0.0, "{shape}: the generator winds outward");
        for (name, write) in formats() {
            let path = dir.0.join(format!("{shape}-{name}"));
            write(&path, &surface);
            let (read, report) = read_surface(&path).unwrap_or_else(|e| panic!("{shape} {name}: {e}"));
            assert_eq!(read.positions.len(), surface.positions.len(), "{shape} {name}: welded vertices");
            assert_eq!(read.mesh.triangles.len(), surface.mesh.triangles.len(), "{shape} {name}");
            assert!(!report.flipped, "{shape} {name}");
            // ASCII writes round-trip f32 exactly ({:e} prints the shortest exact form).
            assert!(
                (report.volume - expected).abs() <= 1e-9 * expected,
                "{shape} {name}: {} vs {expected}",
                report.volume
            );
            assert!(report.area > 0.0);
        }
    }
}

#[test]
fn an_inside_out_surface_is_turned_outward_and_says_so() {
    let dir = Dir::new("flipped");
    let mut surface = kidney();
    for t in &mut surface.mesh.triangles {
        t.swap(0, 1);
    }
    assert!(volume(&surface) < 0.0);
    let path = dir.0.join("inside-out.stl");
    write_stl(&path, &surface);
    let (read, report) = read_surface(&path).unwrap();
    assert!(report.flipped);
    assert!((report.volume - volume(&kidney())).abs() <= 1e-9 * report.volume);
    assert!(volume(&read) > 0.0, "the triangles themselves now wind outward");
}

/// Writes `surface` as OBJ (which keeps the triangles as given) and returns the error.
fn error_of(dir: &Dir, name: &str, surface: &Surface) -> String {
    let path = dir.0.join(name);
    write_obj(&path, surface);
    let err = read_surface(&path).unwrap_err();
    let Error::Mesh { path: p, message } = &err else { panic!("{err:?}") };
    assert!(p.ends_with(name), "{err}");
    message.clone()
}

#[test]
fn a_surface_that_cannot_bound_a_volume_is_refused_with_its_count() {
    let dir = Dir::new("broken");

    let mut open = breast();
    open.mesh.triangles.remove(7);
    let m = error_of(&dir, "open.obj", &open);
    assert!(m.contains("not closed: 3 boundary edge(s)"), "{m}");

    let mut holes = torus();
    holes.mesh.triangles.retain(|t| t[0] % 97 != 5);
    let m = error_of(&dir, "holes.obj", &holes);
    assert!(m.contains("not closed") && m.contains("boundary edge"), "{m}");

    let mut fin = kidney();
    let extra = fin.positions.len() as u32;
    fin.positions.push(Vec3::new(0.0, 0.0, 100.0));
    let t = fin.mesh.triangles[0];
    fin.mesh.triangles.push([t[0], t[1], extra]);
    let m = error_of(&dir, "fin.obj", &fin);
    assert!(m.contains("not"), "{m}");

    let mut doubled = kidney();
    let t = doubled.mesh.triangles[3];
    doubled.mesh.triangles.push([t[0], t[2], t[1]]);
    doubled.mesh.triangles.push(t);
    let m = error_of(&dir, "doubled.obj", &doubled);
    assert!(m.contains("not manifold: 3 edge(s) belong to more than two triangles"), "{m}");

    let mut degenerate = kidney();
    let t = degenerate.mesh.triangles[10];
    degenerate.mesh.triangles[10] = [t[0], t[1], t[1]];
    let m = error_of(&dir, "degenerate.obj", &degenerate);
    assert!(m.contains("1 degenerate triangle(s)") && m.contains("the first triangle 10"), "{m}");

    let mut flat = kidney();
    let t = flat.mesh.triangles[20];
    let (a, b) = (flat.positions[t[0] as usize], flat.positions[t[1] as usize]);
    flat.positions[t[2] as usize] = a + 2.0 * (b - a); // on the line through a and b: no area
    let m = error_of(&dir, "flat.obj", &flat);
    assert!(m.contains("degenerate"), "{m}");

    let mut twisted = breast();
    twisted.mesh.triangles[5].swap(1, 2);
    let m = error_of(&dir, "twisted.obj", &twisted);
    assert!(m.contains("not consistently oriented: 3 edge(s)"), "{m}");
}

#[test]
fn unreadable_and_malformed_files_are_named() {
    let dir = Dir::new("files");
    let missing = dir.0.join("missing.stl");
    let err = read_surface(&missing).unwrap_err();
    assert!(err.to_string().contains("missing.stl") && err.to_string().contains("cannot be read"), "{err}");

    let odd = dir.0.join("tissue.step");
    std::fs::write(&odd, "ISO-10303-21;").unwrap();
    let err = read_surface(&odd).unwrap_err();
    assert!(err.to_string().contains(".stl, .obj or .ply"), "{err}");

    for (name, bytes) in [
        ("garbage.stl", &b"\x00\x01\x02 not an stl"[..]),
        ("garbage.ply", &b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nend_header\n1\n"[..]),
        ("noface.ply", &b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n"[..]),
        ("badindex.obj", &b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"[..]),
        ("empty.obj", &b"# nothing\n"[..]),
    ] {
        let path = dir.0.join(name);
        std::fs::write(&path, bytes).unwrap();
        let err = read_surface(&path).unwrap_err();
        let Error::Mesh { path: p, message } = &err else { panic!("{name}: {err:?}") };
        assert!(p.ends_with(name) && !message.is_empty(), "{name}: {err}");
        eprintln!("{err}");
    }

    let mut nan = kidney();
    nan.positions[3] = Vec3::new(f32::NAN, 0.0, 0.0);
    let path = dir.0.join("nan.obj");
    write_obj(&path, &nan);
    let err = read_surface(&path).unwrap_err();
    assert!(err.to_string().contains("not finite"), "{err}");
}
