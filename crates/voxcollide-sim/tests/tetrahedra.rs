//! Tetrahedral meshes from VTK `.vtu` and Gmsh `.msh` 4.1 files: read, oriented, checked, and
//! made into a soft body with springs along the edges and lumped masses.

mod common;

use std::path::Path;

use common::shapes::volume;
use voxcollide::Error;
use voxcollide::glam::Vec3;
use voxcollide_sim::bodies::tetrahedral_body;
use voxcollide_sim::mesh_io::{Surface, Tetrahedra, check_closed, read_tetrahedra};
use voxcollide_sim::{Material, Mode};

/// A block of `nx × ny × nz` cubes of side `h`, each cut into 6 tetrahedra around its main
/// diagonal (every tetrahedron positive; neighbouring cubes' faces match).
fn block(nx: u32, ny: u32, nz: u32, h: f32) -> (Vec<Vec3>, Vec<[u32; 4]>) {
    let idx = |x: u32, y: u32, z: u32| x + (nx + 1) * (y + (ny + 1) * z);
    let mut pos = Vec::new();
    for z in 0..=nz {
        for y in 0..=ny {
            for x in 0..=nx {
                pos.push(h * Vec3::new(x as f32, y as f32, z as f32));
            }
        }
    }
    let mut tets = Vec::new();
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let c = |dx: u32, dy: u32, dz: u32| idx(x + dx, y + dy, z + dz);
                let (v0, v7) = (c(0, 0, 0), c(1, 1, 1));
                // The six paths from corner 0 to corner 7 along the cube's edges.
                for [a, b] in [
                    [c(1, 0, 0), c(1, 1, 0)],
                    [c(1, 0, 0), c(1, 0, 1)],
                    [c(0, 1, 0), c(1, 1, 0)],
                    [c(0, 1, 0), c(0, 1, 1)],
                    [c(0, 0, 1), c(1, 0, 1)],
                    [c(0, 0, 1), c(0, 1, 1)],
                ] {
                    let t = [v0, a, b, v7];
                    let [p, q, r, s] = t.map(|i| pos[i as usize]);
                    let six_v = (q - p).dot((r - p).cross(s - p));
                    tets.push(if six_v > 0.0 { t } else { [v0, b, a, v7] });
                }
            }
        }
    }
    (pos, tets)
}

fn write_vtu(path: &Path, pos: &[Vec3], tets: &[[u32; 4]]) {
    use vtkio::model::*;
    let vtk = Vtk {
        version: Version::new_xml(1, 0),
        title: String::new(),
        byte_order: ByteOrder::LittleEndian,
        file_path: None,
        data: DataSet::inline(UnstructuredGridPiece {
            points: pos.iter().flat_map(|p| p.to_array()).collect::<Vec<f32>>().into(),
            cells: Cells {
                cell_verts: VertexNumbers::XML {
                    connectivity: tets.iter().flatten().map(|&i| u64::from(i)).collect(),
                    offsets: (1..=tets.len() as u64).map(|k| 4 * k).collect(),
                },
                types: vec![CellType::Tetra; tets.len()],
            },
            data: Attributes::new(),
        }),
    };
    vtk.export(path).unwrap();
}

fn write_msh(path: &Path, pos: &[Vec3], tets: &[[u32; 4]]) {
    let mut s = String::from("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n");
    s += &format!("$Nodes\n1 {} 1 {}\n3 1 0 {}\n", pos.len(), pos.len(), pos.len());
    for i in 0..pos.len() {
        s += &format!("{}\n", i + 1);
    }
    for p in pos {
        s += &format!("{} {} {}\n", p.x, p.y, p.z);
    }
    s += "$EndNodes\n";
    // One block of tetrahedra and one of boundary-ish triangles (ignored).
    s += &format!("$Elements\n2 {} 1 {}\n3 1 4 {}\n", tets.len() + 1, tets.len() + 1, tets.len());
    for (k, t) in tets.iter().enumerate() {
        s += &format!("{} {} {} {} {}\n", k + 1, t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1);
    }
    s += &format!("2 1 2 1\n{} 1 2 3\n$EndElements\n", tets.len() + 1);
    std::fs::write(path, s).unwrap();
}

fn dir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("voxcollide-tets-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn boundary_surface(t: &Tetrahedra) -> Surface {
    Surface { positions: t.positions.clone(), mesh: t.boundary.clone() }
}

#[test]
fn vtu_and_msh_blocks_read_back_as_closed_soft_bodies() {
    let d = dir("formats");
    let (pos, tets) = block(4, 3, 2, 2.5);
    let expected = 10.0 * 7.5 * 5.0;
    for name in ["block.vtu", "block.msh"] {
        let path = d.join(name);
        if name.ends_with("vtu") {
            write_vtu(&path, &pos, &tets)
        } else {
            write_msh(&path, &pos, &tets)
        }
        let t = read_tetrahedra(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((t.positions.len(), t.tets.len(), t.turned), (pos.len(), tets.len(), 0), "{name}");
        // The boundary: 2 triangles per outer cube face, closed, outward, enclosing the block.
        assert_eq!(t.boundary.triangles.len(), 2 * 2 * (4 * 3 + 4 * 2 + 3 * 2), "{name}");
        let mut surface = boundary_surface(&t);
        let report = check_closed(&mut surface).unwrap();
        assert!(!report.flipped, "{name}");
        assert!((report.volume - expected).abs() < 1e-3, "{name}: {}", report.volume);

        let material = Material { mass: 1.0, stiffening: 10.0, spring_damping: 0.6, damping: 0.1 };
        let body =
            tetrahedral_body(&t, 2.0, 1e-3, material, |p| if p.z < 0.1 { Mode::Pinned } else { Mode::Free })
                .unwrap();
        // One spring per distinct edge: 6 per cube (4 inner diagonal paths share) — count them.
        let mut edges = std::collections::HashSet::new();
        for t in &t.tets {
            for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                edges.insert((t[i].min(t[j]), t[i].max(t[j])));
            }
        }
        assert_eq!(body.springs.len(), edges.len(), "{name}");
        // Lumped masses add up to density × volume.
        let total: f64 = body.inv_mass.iter().map(|&w| 1.0 / f64::from(w)).sum();
        assert!((total - 1e-3 * expected).abs() < 1e-6, "{name}: total mass {total}");
        assert_eq!(
            body.mode.iter().filter(|m| **m == Mode::Pinned).count(),
            5 * 4,
            "{name}: the z = 0 layer"
        );
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn negatively_ordered_tetrahedra_are_turned_and_counted() {
    let d = dir("turned");
    let (pos, mut tets) = block(2, 2, 2, 1.0);
    for t in tets.iter_mut().step_by(3) {
        t.swap(1, 2);
    }
    let path = d.join("mixed.vtu");
    write_vtu(&path, &pos, &tets);
    let t = read_tetrahedra(&path).unwrap();
    assert_eq!(t.turned, tets.len().div_ceil(3));
    let mut surface = boundary_surface(&t);
    assert!((check_closed(&mut surface).unwrap().volume - 8.0).abs() < 1e-5);
    assert!((volume(&surface) - 8.0).abs() < 1e-5);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn broken_tetrahedral_files_are_named_errors() {
    let d = dir("broken");
    let (pos, tets) = block(1, 1, 1, 1.0);
    let mut flat = pos.clone();
    for p in &mut flat {
        p.z = 0.0;
    }
    type Write = Box<dyn Fn(&Path)>;
    let cases: Vec<(&str, Write, &str)> = vec![
        ("flat.vtu", Box::new(move |p| write_vtu(p, &flat, &tets)), "degenerate tetrahedra"),
        (
            "index.msh",
            Box::new(|p| {
                let (pos, mut tets) = block(1, 1, 1, 1.0);
                tets[0][3] = 99;
                write_msh(p, &pos, &tets)
            }),
            "does not exist",
        ),
        (
            "garbage.msh",
            Box::new(|p| std::fs::write(p, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n").unwrap()),
            "Gmsh 4.1",
        ),
        ("garbage.vtu", Box::new(|p| std::fs::write(p, "<VTKFile").unwrap()), "VTK"),
        (
            "surface.msh",
            Box::new(|p| {
                let s = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 3 1 3\n2 1 0 3\n1\n2\n3\n0 0 0\n1 0 0\n0 1 0\n$EndNodes\n$Elements\n1 1 1 1\n2 1 2 1\n1 1 2 3\n$EndElements\n";
                std::fs::write(p, s).unwrap()
            }),
            "no tetrahedra",
        ),
        ("block.stl", Box::new(|p| std::fs::write(p, "solid x\nendsolid x\n").unwrap()), ".vtu or .msh"),
    ];
    for (name, write, says) in cases {
        let path = d.join(name);
        write(&path);
        let err = read_tetrahedra(&path).unwrap_err();
        let Error::Mesh { path: p, message } = &err else { panic!("{name}: {err:?}") };
        assert!(p.ends_with(name) && message.contains(says), "{name}: {err}");
    }
    let err = read_tetrahedra(&d.join("missing.vtu")).unwrap_err();
    assert!(err.to_string().contains("missing.vtu"), "{err}");
    std::fs::remove_dir_all(&d).unwrap();
}
