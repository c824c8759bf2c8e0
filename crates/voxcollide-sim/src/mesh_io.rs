//! Closed triangle surfaces from files: STL (binary and ASCII, with `stl_io`), Wavefront OBJ
//! (`tobj`) and PLY (ASCII and binary, `ply-rs-bw`), checked before a body is made of them.
//!
//! [`read_surface`] reads a file by its extension, welds vertices that are exactly equal (an STL
//! stores every triangle's corners apart), and [`check_closed`] refuses what cannot bound a
//! volume, naming the problem and counting it: degenerate triangles (a repeated corner or no
//! area), edges with only one triangle (the surface is not closed), edges with more than two
//! (not manifold), and triangles whose orientation disagrees with a neighbour's. A closed,
//! consistently oriented surface whose normals point inward (negative enclosed volume) is turned
//! outward, and the report says so.

use std::collections::HashMap;
use std::path::Path;

use glam::{DVec3, Vec3};
use voxcollide::Error;

use crate::mesh::TriangleMesh;

/// A surface read from a file: its vertices and triangles, in the file's units.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Surface {
    /// Vertex positions (exact duplicates welded).
    pub positions: Vec<Vec3>,
    /// Triangles over `positions`.
    pub mesh: TriangleMesh,
}

/// What [`check_closed`] found in a surface that passed.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceReport {
    /// The enclosed volume, in cubic file units (positive: outward normals).
    pub volume: f64,
    /// The surface area, in square file units.
    pub area: f64,
    /// Whether the triangles were flipped because their normals pointed inward.
    pub flipped: bool,
}

fn mesh_error(path: &Path, message: impl Into<String>) -> Error {
    Error::Mesh { path: path.display().to_string(), message: message.into() }
}

/// Reads the closed surface in `path` (`.stl`, `.obj` or `.ply`, in any case) and checks it
/// with [`check_closed`], turning inward normals outward.
///
/// # Errors
/// [`Error::Mesh`] naming the file: it cannot be read, its extension is none of those, it is
/// malformed, it has no triangles or a coordinate that is not finite, or it fails
/// [`check_closed`].
pub fn read_surface(path: &Path) -> Result<(Surface, SurfaceReport), Error> {
    let mut surface = read_sheet(path)?;
    let report = check_closed(&mut surface).map_err(|m| mesh_error(path, m))?;
    Ok((surface, report))
}

/// Reads the triangles in `path` (`.stl`, `.obj` or `.ply`) as they are, open or closed, facing
/// as written: a skin scan (one sheet) or a chest wall (docs/design.md §14).
///
/// # Errors
/// [`Error::Mesh`] naming the file: it cannot be read, its extension is none of those, it is
/// malformed, or it has no triangles or a coordinate that is not finite.
pub fn read_sheet(path: &Path) -> Result<Surface, Error> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let surface = match ext.as_deref() {
        Some("stl") => read_stl(path)?,
        Some("obj") => read_obj(path)?,
        Some("ply") => read_ply(path)?,
        _ => {
            return Err(mesh_error(path, "not a surface file: the extension must be .stl, .obj or .ply"));
        }
    };
    if surface.mesh.triangles.is_empty() {
        return Err(mesh_error(path, "has no triangles"));
    }
    if let Some(i) = surface.positions.iter().position(|p| !p.is_finite()) {
        return Err(mesh_error(path, format!("vertex {i} is not finite: {}", surface.positions[i])));
    }
    Ok(surface)
}

/// Writes the triangles `mesh` over `positions` to `path` as a binary little-endian PLY file
/// that any mesh viewer opens, with each vertex's `scalar` (for instance how far it moved) as a
/// `quality` property where given, and `comment` in its header.
///
/// # Errors
/// [`Error::Mesh`] naming the file where it cannot be written, or a scalar per vertex is not
/// given.
pub fn write_ply(
    path: &Path,
    positions: &[Vec3],
    mesh: &TriangleMesh,
    scalar: Option<&[f32]>,
    comment: &str,
) -> Result<(), Error> {
    use ply_rs_bw::ply::{
        Addable, DefaultElement, ElementDef, Encoding, Ply, Property, PropertyDef, PropertyType, ScalarType,
    };
    if scalar.is_some_and(|s| s.len() != positions.len()) {
        return Err(mesh_error(path, "needs one scalar per vertex"));
    }
    let mut ply = Ply::<DefaultElement>::new();
    ply.header.encoding = Encoding::BinaryLittleEndian;
    ply.header.comments.push(comment.replace('\n', " "));
    let mut vertex = ElementDef::new("vertex".to_string());
    let float = || PropertyType::Scalar(ScalarType::Float);
    for name in ["x", "y", "z"] {
        vertex.properties.add(PropertyDef::new(name.to_string(), float()));
    }
    if scalar.is_some() {
        vertex.properties.add(PropertyDef::new("quality".to_string(), float()));
    }
    ply.header.elements.add(vertex);
    let mut face = ElementDef::new("face".to_string());
    face.properties.add(PropertyDef::new(
        "vertex_indices".to_string(),
        PropertyType::List(ScalarType::UChar, ScalarType::Int),
    ));
    ply.header.elements.add(face);
    let vertices = positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let mut v = DefaultElement::new();
            for (name, x) in ["x", "y", "z"].into_iter().zip(p.to_array()) {
                v.insert(name.to_string(), Property::Float(x));
            }
            if let Some(s) = scalar {
                v.insert("quality".to_string(), Property::Float(s[i]));
            }
            v
        })
        .collect();
    ply.payload.insert("vertex".to_string(), vertices);
    let faces = mesh
        .triangles
        .iter()
        .map(|t| {
            let mut f = DefaultElement::new();
            f.insert("vertex_indices".to_string(), Property::ListInt(t.iter().map(|&i| i as i32).collect()));
            f
        })
        .collect();
    ply.payload.insert("face".to_string(), faces);
    let file =
        std::fs::File::create(path).map_err(|e| mesh_error(path, format!("cannot be written: {e}")))?;
    let mut out = std::io::BufWriter::new(file);
    ply_rs_bw::writer::Writer::new()
        .write_ply(&mut out, &mut ply)
        .map_err(|e| mesh_error(path, format!("cannot be written: {e}")))?;
    std::io::Write::flush(&mut out).map_err(|e| mesh_error(path, format!("cannot be written: {e}")))?;
    Ok(())
}

fn open(path: &Path) -> Result<std::io::BufReader<std::fs::File>, Error> {
    std::fs::File::open(path)
        .map(std::io::BufReader::new)
        .map_err(|e| mesh_error(path, format!("cannot be read: {e}")))
}

fn read_stl(path: &Path) -> Result<Surface, Error> {
    let mesh = stl_io::read_stl(&mut open(path)?)
        .map_err(|e| mesh_error(path, format!("is not a valid STL file: {e}")))?;
    let positions = mesh.vertices.iter().map(|v| Vec3::from_array(v.0)).collect();
    let triangles = mesh.faces.iter().map(|f| f.vertices.map(|i| i as u32)).collect();
    Ok(weld(Surface { positions, mesh: TriangleMesh { triangles } }))
}

fn read_obj(path: &Path) -> Result<Surface, Error> {
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, _) = tobj::load_obj(path, &options)
        .map_err(|e| mesh_error(path, format!("is not a valid OBJ file: {e}")))?;
    let mut surface = Surface::default();
    for model in models {
        let base = surface.positions.len() as u32;
        let m = model.mesh;
        surface.positions.extend(m.positions.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])));
        surface
            .mesh
            .triangles
            .extend(m.indices.chunks_exact(3).map(|t| [base + t[0], base + t[1], base + t[2]]));
    }
    Ok(weld(surface))
}

#[derive(Debug, Default)]
struct PlyVertex([f32; 3]);

impl ply_rs_bw::ply::PropertyAccess for PlyVertex {
    fn new() -> Self {
        PlyVertex::default()
    }
    fn set_float(&mut self, name: &str, v: f32) -> ply_rs_bw::ply::PropertyAccessResult {
        self.set(name, v)
    }
    fn set_double(&mut self, name: &str, v: f64) -> ply_rs_bw::ply::PropertyAccessResult {
        self.set(name, v as f32)
    }
}

impl PlyVertex {
    fn set(&mut self, name: &str, v: f32) -> ply_rs_bw::ply::PropertyAccessResult {
        match name {
            "x" => self.0[0] = v,
            "y" => self.0[1] = v,
            "z" => self.0[2] = v,
            _ => return ply_rs_bw::ply::PropertyAccessResult::Ignored,
        }
        ply_rs_bw::ply::PropertyAccessResult::Set
    }
}

#[derive(Debug, Default)]
struct PlyFace(Vec<i64>);

impl ply_rs_bw::ply::PropertyAccess for PlyFace {
    fn new() -> Self {
        PlyFace::default()
    }
    fn set_list_int(&mut self, name: &str, v: Vec<i32>) -> ply_rs_bw::ply::PropertyAccessResult {
        self.set(name, v.into_iter().map(i64::from).collect())
    }
    fn set_list_uint(&mut self, name: &str, v: Vec<u32>) -> ply_rs_bw::ply::PropertyAccessResult {
        self.set(name, v.into_iter().map(i64::from).collect())
    }
}

impl PlyFace {
    fn set(&mut self, name: &str, v: Vec<i64>) -> ply_rs_bw::ply::PropertyAccessResult {
        if name == "vertex_indices" || name == "vertex_index" {
            self.0 = v;
            ply_rs_bw::ply::PropertyAccessResult::Set
        } else {
            ply_rs_bw::ply::PropertyAccessResult::Ignored
        }
    }
}

fn read_ply(path: &Path) -> Result<Surface, Error> {
    use ply_rs_bw::parser::{Parser, Reader};
    fn bad<E: std::fmt::Display>(path: &Path) -> impl Fn(E) -> Error + '_ {
        move |e| mesh_error(path, format!("is not a valid PLY file: {e}"))
    }
    let mut reader = Reader::new(open(path)?);
    let vertex_parser = Parser::<PlyVertex>::new();
    let header = vertex_parser.read_header(&mut reader).map_err(bad(path))?;
    let (Some(vertex), Some(face)) = (header.elements.get("vertex"), header.elements.get("face")) else {
        return Err(mesh_error(path, "has no `vertex` or no `face` element"));
    };
    let vertices = vertex_parser.read_payload_for_element(&mut reader, vertex, &header).map_err(bad(path))?;
    let faces =
        Parser::<PlyFace>::new().read_payload_for_element(&mut reader, face, &header).map_err(bad(path))?;
    let n = vertices.len() as i64;
    let mut triangles = Vec::with_capacity(faces.len());
    for (k, f) in faces.iter().enumerate() {
        if f.0.len() < 3 || f.0.iter().any(|&i| i < 0 || i >= n) {
            return Err(mesh_error(path, format!("face {k} has indices {:?} for {n} vertices", f.0)));
        }
        // A polygon as a fan of triangles.
        for j in 1..f.0.len() - 1 {
            triangles.push([f.0[0] as u32, f.0[j] as u32, f.0[j + 1] as u32]);
        }
    }
    let positions = vertices.into_iter().map(|v| Vec3::from_array(v.0)).collect();
    Ok(weld(Surface { positions, mesh: TriangleMesh { triangles } }))
}

/// Merges vertices with exactly equal coordinates (bitwise, `-0.0` as `+0.0`), keeping the first
/// of each; drops vertices no triangle uses.
fn weld(surface: Surface) -> Surface {
    let mut index: HashMap<[u32; 3], u32> = HashMap::with_capacity(surface.positions.len());
    let mut positions = Vec::with_capacity(surface.positions.len());
    let mut remap = vec![u32::MAX; surface.positions.len()];
    for t in &surface.mesh.triangles {
        for &v in t {
            let v = v as usize;
            if v < remap.len() && remap[v] == u32::MAX {
                let p = surface.positions[v];
                let key = (p + Vec3::ZERO).to_array().map(f32::to_bits);
                remap[v] = *index.entry(key).or_insert_with(|| {
                    positions.push(p);
                    (positions.len() - 1) as u32
                });
            }
        }
    }
    let triangles = surface.mesh.triangles.iter().map(|t| t.map(|v| remap[v as usize])).collect();
    Surface { positions, mesh: TriangleMesh { triangles } }
}

/// Checks that `surface` bounds a volume, and turns it outward if it is inside out.
///
/// # Errors
/// A message naming the problem, its count and the first instance: degenerate triangles, edges
/// of one triangle (the count of boundary edges), edges of more than two, inconsistent
/// orientation.
pub fn check_closed(surface: &mut Surface) -> Result<SurfaceReport, String> {
    let p = &surface.positions;
    let tris = &surface.mesh.triangles;
    let mut degenerate = 0usize;
    let mut first_degenerate = None;
    for (k, t) in tris.iter().enumerate() {
        let area2 = {
            let [a, b, c] = t.map(|i| p[i as usize].as_dvec3());
            (b - a).cross(c - a).length()
        };
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || area2 == 0.0 {
            degenerate += 1;
            first_degenerate.get_or_insert(k);
        }
    }
    if let Some(k) = first_degenerate {
        return Err(format!(
            "{degenerate} degenerate triangle(s) (a repeated corner or no area), the first triangle {k}: {:?}",
            tris[k]
        ));
    }
    // Every directed edge, and how many triangles use each undirected one.
    let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * tris.len());
    for t in tris {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *directed.entry((a, b)).or_default() += 1;
        }
    }
    let (mut boundary, mut shared, mut flipped_edges) = (0usize, 0usize, 0usize);
    let mut first = (None, None, None);
    for (&(a, b), &n) in &directed {
        let back = directed.get(&(b, a)).copied().unwrap_or(0);
        if a < b || back == 0 {
            let total = n + back;
            if total == 1 {
                boundary += 1;
                first.0.get_or_insert((a, b));
            } else if total > 2 {
                shared += 1;
                first.1.get_or_insert((a, b));
            }
        }
        if n > 1 && n + back == 2 {
            flipped_edges += 1;
            first.2.get_or_insert((a, b));
        }
    }
    if boundary > 0 {
        let (a, b) = first.0.unwrap_or_default();
        return Err(format!(
            "is not closed: {boundary} boundary edge(s) belong to one triangle only (e.g. vertices {a}–{b} at {} and {})",
            p[a as usize], p[b as usize]
        ));
    }
    if shared > 0 {
        let (a, b) = first.1.unwrap_or_default();
        return Err(format!(
            "is not manifold: {shared} edge(s) belong to more than two triangles (e.g. vertices {a}–{b})"
        ));
    }
    if flipped_edges > 0 {
        let (a, b) = first.2.unwrap_or_default();
        return Err(format!(
            "is not consistently oriented: {flipped_edges} edge(s) run the same way in both of their triangles (e.g. vertices {a}–{b})"
        ));
    }
    let (mut volume, area) = (surface.mesh.volume(p), surface.mesh.area(p));
    let flipped = volume < 0.0;
    if flipped {
        for t in &mut surface.mesh.triangles {
            t.swap(1, 2);
        }
        volume = -volume;
    }
    Ok(SurfaceReport { volume, area, flipped })
}

/// A tetrahedral mesh read from a file: its vertices, its tetrahedra (positively oriented:
/// `dot(b - a, cross(c - a, d - a)) > 0`) and its boundary, outward.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Tetrahedra {
    /// Vertex positions (those no tetrahedron uses are dropped).
    pub positions: Vec<Vec3>,
    /// The tetrahedra, as indices into `positions`.
    pub tets: Vec<[u32; 4]>,
    /// The boundary: faces of one tetrahedron only, counter-clockwise seen from outside.
    pub boundary: TriangleMesh,
    /// Tetrahedra whose vertices were given in the negative order and were turned.
    pub turned: usize,
}

/// Reads the tetrahedral mesh in `path`: VTK XML unstructured grid (`.vtu`, cells of type
/// `VTK_TETRA`, with `vtkio`) or Gmsh `.msh` 4.1 (ASCII or binary, elements of type 4, with
/// `mshio`). Other cells (triangles, lines, points of a Gmsh file's lower-dimensional entities)
/// are ignored; tetrahedra of negative orientation are turned and counted.
///
/// # Errors
/// [`Error::Mesh`] naming the file: unreadable or malformed, no tetrahedra, a vertex index out
/// of range, a coordinate that is not finite, or a degenerate tetrahedron (no volume).
pub fn read_tetrahedra(path: &Path) -> Result<Tetrahedra, Error> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let (positions, tets) = match ext.as_deref() {
        Some("vtu") => read_vtu(path)?,
        Some("msh") => read_msh(path)?,
        _ => return Err(mesh_error(path, "not a tetrahedral mesh: the extension must be .vtu or .msh")),
    };
    tetrahedra(positions, tets).map_err(|m| mesh_error(path, m))
}

fn read_vtu(path: &Path) -> Result<(Vec<Vec3>, Vec<[u64; 4]>), Error> {
    use vtkio::model::{CellType, DataSet, VertexNumbers};
    let bad = |m: String| mesh_error(path, m);
    let vtk = vtkio::Vtk::import(path).map_err(|e| bad(format!("is not a readable VTK file: {e}")))?;
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        return Err(bad("is not an unstructured grid".into()));
    };
    let (mut positions, mut tets) = (Vec::new(), Vec::new());
    for piece in pieces {
        let piece = piece.load_piece_data(None).map_err(|e| bad(format!("cannot load a piece: {e}")))?;
        let base = positions.len() as u64;
        let points: Vec<f64> =
            piece.points.cast_into().ok_or_else(|| bad("points are not numbers".into()))?;
        positions.extend(points.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2]).as_vec3()));
        let (connectivity, offsets) = match piece.cells.cell_verts {
            VertexNumbers::XML { connectivity, offsets } => (connectivity, offsets),
            legacy => legacy.into_xml(),
        };
        let mut start = 0u64;
        for (k, (&end, ty)) in offsets.iter().zip(&piece.cells.types).enumerate() {
            if *ty == CellType::Tetra {
                let v = connectivity
                    .get(start as usize..end as usize)
                    .filter(|v| v.len() == 4)
                    .ok_or_else(|| bad(format!("cell {k} is a tetrahedron without 4 vertices")))?;
                tets.push([v[0] + base, v[1] + base, v[2] + base, v[3] + base]);
            }
            start = end;
        }
    }
    Ok((positions, tets))
}

fn read_msh(path: &Path) -> Result<(Vec<Vec3>, Vec<[u64; 4]>), Error> {
    let bytes = std::fs::read(path).map_err(|e| mesh_error(path, format!("cannot be read: {e}")))?;
    let msh = mshio::parse_msh_bytes(&bytes)
        .map_err(|e| mesh_error(path, format!("is not a valid Gmsh 4.1 file: {e}")))?;
    let mut positions = Vec::new();
    let mut index: HashMap<u64, u64> = HashMap::new();
    if let Some(nodes) = &msh.data.nodes {
        for block in &nodes.node_blocks {
            // Tags run consecutively from the block's first unless the block lists them.
            let mut tags: Vec<(u64, usize)> = match &block.node_tags {
                Some(t) => t.iter().map(|(&tag, &i)| (tag, i)).collect(),
                None => (0..block.nodes.len()).map(|i| (nodes.min_node_tag + i as u64, i)).collect(),
            };
            tags.sort_unstable();
            let base = positions.len() as u64;
            positions.extend(block.nodes.iter().map(|n| DVec3::new(n.x, n.y, n.z).as_vec3()));
            for (tag, i) in tags {
                index.insert(tag, base + i as u64);
            }
        }
    }
    let mut tets = Vec::new();
    if let Some(elements) = &msh.data.elements {
        for block in elements.element_blocks.iter().filter(|b| b.element_type == mshio::ElementType::Tet4) {
            for e in &block.elements {
                let v: Option<Vec<u64>> = e.nodes.iter().map(|tag| index.get(tag).copied()).collect();
                let v = v.filter(|v| v.len() == 4).ok_or_else(|| {
                    mesh_error(path, format!("element {} names a node that does not exist", e.element_tag))
                })?;
                tets.push([v[0], v[1], v[2], v[3]]);
            }
        }
    }
    Ok((positions, tets))
}

/// Checks and orients tetrahedra, drops unused vertices, and finds the boundary.
fn tetrahedra(positions: Vec<Vec3>, tets: Vec<[u64; 4]>) -> Result<Tetrahedra, String> {
    if tets.is_empty() {
        return Err("has no tetrahedra".into());
    }
    let n = positions.len() as u64;
    if let Some((k, t)) = tets.iter().enumerate().find(|(_, t)| t.iter().any(|&v| v >= n)) {
        return Err(format!("tetrahedron {k} has indices {t:?} for {n} vertices"));
    }
    let mut remap = vec![u32::MAX; positions.len()];
    let mut kept = Vec::new();
    let mut out = Vec::with_capacity(tets.len());
    let mut turned = 0;
    let mut degenerate = (0usize, None);
    for (k, t) in tets.iter().enumerate() {
        let t = t.map(|v| {
            let v = v as usize;
            if remap[v] == u32::MAX {
                remap[v] = kept.len() as u32;
                kept.push(positions[v]);
            }
            remap[v]
        });
        let [a, b, c, d] = t.map(|i| kept[i as usize].as_dvec3());
        let six_v = (b - a).dot((c - a).cross(d - a));
        let scale = (b - a).length().max((c - a).length()).max((d - a).length());
        // Not above the threshold: zero volume, or NaN from a non-finite corner.
        if six_v.abs().partial_cmp(&(1e-12 * scale * scale * scale)) != Some(std::cmp::Ordering::Greater) {
            degenerate.0 += 1;
            degenerate.1.get_or_insert(k);
            continue;
        }
        if six_v < 0.0 {
            turned += 1;
            out.push([t[0], t[2], t[1], t[3]]);
        } else {
            out.push(t);
        }
    }
    if let (count, Some(k)) = degenerate {
        return Err(format!(
            "{count} degenerate tetrahedra (no volume), the first tetrahedron {k}: {:?}",
            tets[k]
        ));
    }
    if let Some(i) = kept.iter().position(|p| !p.is_finite()) {
        return Err(format!("vertex {i} is not finite: {}", kept[i]));
    }
    // Faces of one tetrahedron are the boundary; a positive tet's faces, seen from outside,
    // are (a c b), (a b d), (a d c), (b c d).
    let mut faces: HashMap<[u32; 3], (u32, [u32; 3])> = HashMap::new();
    for t in &out {
        let [a, b, c, d] = *t;
        for f in [[a, c, b], [a, b, d], [a, d, c], [b, c, d]] {
            let mut key = f;
            key.sort_unstable();
            faces.entry(key).and_modify(|e| e.0 += 1).or_insert((1, f));
        }
    }
    let mut boundary: Vec<[u32; 3]> = faces.into_values().filter(|(n, _)| *n == 1).map(|(_, f)| f).collect();
    boundary.sort_unstable();
    Ok(Tetrahedra { positions: kept, tets: out, boundary: TriangleMesh { triangles: boundary }, turned })
}
