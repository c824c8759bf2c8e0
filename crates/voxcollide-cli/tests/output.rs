//! The ParaView output module: `.vtp` files read back with `vtkio`, `.pvd` series parsed back,
//! and every bad input's typed error.

use std::path::{Path, PathBuf};

use voxcollide::Error;
use voxcollide::glam::Vec3;
use voxcollide_cli::output::{BodyFrame, PvdSeries, write_vtp};
use vtkio::Vtk;
use vtkio::model::{Attribute, DataArray, DataSet, IOBuffer, Piece, PolyDataPiece, VertexNumbers};

/// A fresh, empty directory under the system temp dir, one per test; removed when the test
/// passes, kept for a look when it fails.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("voxcollide-output-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A closed unit cube: 8 corners, 12 outward-facing triangles, with per-vertex arrays that
/// differ at every vertex (so a swapped or shifted array shows).
struct Cube {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    displacement: Vec<Vec3>,
    contact_force: Vec<Vec3>,
    colliding: Vec<bool>,
}

impl Cube {
    fn new(shift: f32) -> Cube {
        // Corner i has coordinates (bit 0, bit 1, bit 2) of i.
        let positions: Vec<Vec3> = (0..8u32)
            .map(|i| Vec3::new((i & 1) as f32, (i >> 1 & 1) as f32, (i >> 2 & 1) as f32) + Vec3::splat(shift))
            .collect();
        let triangles = vec![
            [0, 2, 1],
            [1, 2, 3], // z = 0
            [4, 5, 6],
            [5, 7, 6], // z = 1
            [0, 1, 4],
            [1, 5, 4], // y = 0
            [2, 6, 3],
            [3, 6, 7], // y = 1
            [0, 4, 2],
            [2, 4, 6], // x = 0
            [1, 3, 5],
            [3, 7, 5], // x = 1
        ];
        let displacement = (0..8).map(|i| Vec3::new(0.1 * i as f32, -0.25 * i as f32, 1.5 + shift)).collect();
        let contact_force = (0..8)
            .map(|i| if i % 3 == 0 { Vec3::new(0.0, 0.0, -2.0 * i as f32 - 1.0) } else { Vec3::ZERO })
            .collect();
        let colliding = (0..8).map(|i| i % 3 == 0).collect();
        Cube { positions, triangles, displacement, contact_force, colliding }
    }

    fn frame(&self) -> BodyFrame<'_> {
        BodyFrame {
            positions: &self.positions,
            triangles: &self.triangles,
            displacement: &self.displacement,
            contact_force: &self.contact_force,
            colliding: &self.colliding,
        }
    }
}

fn flat(v: &[Vec3]) -> Vec<f32> {
    v.iter().flat_map(|p| p.to_array()).collect()
}

/// Reads a `.vtp` back with `vtkio` and returns its single inline PolyData piece.
fn read_piece(path: &Path) -> PolyDataPiece {
    let vtk = Vtk::import(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let DataSet::PolyData { mut pieces, .. } = vtk.data else { panic!("not PolyData: {:?}", vtk.data) };
    assert_eq!(pieces.len(), 1);
    match pieces.pop().unwrap() {
        Piece::Inline(piece) => *piece,
        other => panic!("not an inline piece: {other:?}"),
    }
}

fn point_array<'a>(piece: &'a PolyDataPiece, name: &str) -> &'a DataArray {
    piece
        .data
        .point
        .iter()
        .find_map(|a| match a {
            Attribute::DataArray(d) if d.name == name => Some(d),
            _ => None,
        })
        .unwrap_or_else(|| panic!("no point array {name:?}"))
}

/// Checks a piece read back against the body it was written from.
fn assert_piece_is(piece: &PolyDataPiece, cube: &Cube) {
    assert_eq!(piece.num_points(), cube.positions.len());
    assert_eq!(piece.points, IOBuffer::F32(flat(&cube.positions)));

    let Some(VertexNumbers::XML { connectivity, offsets }) = piece.polys.clone() else {
        panic!("polys missing or not in XML form: {:?}", piece.polys)
    };
    let expected: Vec<u64> = cube.triangles.iter().flatten().map(|&i| i as u64).collect();
    assert_eq!(connectivity, expected);
    assert_eq!(offsets, (1..=12).map(|t| 3 * t).collect::<Vec<u64>>());
    assert_eq!(piece.num_verts() + piece.num_lines() + piece.num_strips(), 0);

    assert_eq!(piece.data.point.len(), 3, "{:?}", piece.data.point);
    assert!(piece.data.cell.is_empty());
    let displacement = point_array(piece, "displacement");
    assert_eq!(displacement.num_comp(), 3);
    assert_eq!(displacement.data, IOBuffer::F32(flat(&cube.displacement)));
    let force = point_array(piece, "contact_force");
    assert_eq!(force.num_comp(), 3);
    assert_eq!(force.data, IOBuffer::F32(flat(&cube.contact_force)));
    let colliding = point_array(piece, "colliding");
    assert_eq!(colliding.num_comp(), 1);
    assert_eq!(colliding.data, IOBuffer::U8(cube.colliding.iter().map(|&c| c as u8).collect()));
}

#[test]
fn vtp_reads_back_points_polys_and_arrays() {
    let dir = TempDir::new("vtp");
    let cube = Cube::new(0.0);
    let path = dir.join("cube.vtp");
    write_vtp(&path, &cube.frame()).unwrap();
    assert_piece_is(&read_piece(&path), &cube);

    // The header ParaView's reader dispatches on, and the array declarations.
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.contains(
            r#"<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64""#
        ),
        "{text}"
    );
    assert!(text.contains(r#"NumberOfPoints="8""#) && text.contains(r#"NumberOfPolys="12""#));
    // Each array as VTK declares it (attribute order is the writer's; NumberOfComponents
    // defaults to 1).
    for (name, ty, components) in
        [("displacement", "Float32", "3"), ("contact_force", "Float32", "3"), ("colliding", "UInt8", "1")]
    {
        let array = data_array(&text, name).unwrap_or_else(|| panic!("no DataArray {name}: {text}"));
        let attr = |key: &str| array.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str());
        assert_eq!(attr("type"), Some(ty), "{name}");
        assert_eq!(attr("format"), Some("binary"), "{name}");
        assert_eq!(attr("NumberOfComponents").unwrap_or("1"), components, "{name}");
    }
    assert!(text.contains(r#"Scalars="colliding""#) && text.contains(r#"Vectors="displacement""#));
    assert!(!text.contains("compressor="), "written uncompressed: {text}");
    // No temporary file is left behind.
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
}

/// The attributes of the `<DataArray ... Name="name" ...>` element of `text`.
fn data_array(text: &str, name: &str) -> Option<Vec<(String, String)>> {
    text.split("<DataArray ")
        .skip(1)
        .filter_map(|rest| rest.find('>').map(|end| parse_attributes(&rest[..end])))
        .find(|attrs| attrs.iter().any(|(k, v)| k == "Name" && v == name))
}

#[test]
fn vtp_overwrites_an_existing_file() {
    let dir = TempDir::new("overwrite");
    let path = dir.join("body.vtp");
    write_vtp(&path, &Cube::new(0.0).frame()).unwrap();
    let moved = Cube::new(2.5);
    write_vtp(&path, &moved.frame()).unwrap();
    assert_piece_is(&read_piece(&path), &moved);
}

#[test]
fn vtp_of_a_point_cloud_has_no_polys() {
    let dir = TempDir::new("cloud");
    let cube = Cube::new(0.0);
    let body = BodyFrame { triangles: &[], ..cube.frame() };
    let path = dir.join("cloud.vtp");
    write_vtp(&path, &body).unwrap();
    let piece = read_piece(&path);
    assert_eq!(piece.points, IOBuffer::F32(flat(&cube.positions)));
    assert_eq!(piece.num_polys(), 0);
    assert_eq!(point_array(&piece, "displacement").data, IOBuffer::F32(flat(&cube.displacement)));
}

/// One `<DataSet>` entry of a `.pvd`.
#[derive(Debug, PartialEq)]
struct Entry {
    timestep: f64,
    file: String,
}

/// Parses a `.pvd` strictly enough to catch a malformed one: the XML declaration, balanced tags
/// with only whitespace between them, quoted attributes with only the five predefined entities,
/// the `VTKFile type="Collection"` root holding one `Collection` of `DataSet` elements.
fn parse_pvd(text: &str) -> Vec<Entry> {
    let body = text.strip_prefix("<?xml version=\"1.0\"?>").expect("XML declaration first");
    let mut stack: Vec<String> = Vec::new();
    let mut entries = Vec::new();
    let mut rest = body;
    let mut closed_root = false;
    while let Some(open) = rest.find('<') {
        assert!(rest[..open].trim().is_empty(), "text outside tags: {:?}", &rest[..open]);
        let close = rest[open..].find('>').expect("unterminated tag") + open;
        let tag = &rest[open + 1..close];
        rest = &rest[close + 1..];
        assert!(!closed_root, "content after the root element");
        if let Some(name) = tag.strip_prefix('/') {
            assert_eq!(stack.pop().as_deref(), Some(name), "unbalanced </{name}>");
            closed_root = stack.is_empty();
            continue;
        }
        let (tag, self_closing) = match tag.strip_suffix('/') {
            Some(t) => (t, true),
            None => (tag, false),
        };
        let (name, attrs) = tag.split_once(' ').unwrap_or((tag, ""));
        let attrs = parse_attributes(attrs);
        let attr = |key: &str| attrs.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str());
        match (stack.len(), name) {
            (0, "VTKFile") => {
                assert_eq!(attr("type"), Some("Collection"));
                assert_eq!(attr("version"), Some("0.1"));
                assert_eq!(attr("byte_order"), Some("LittleEndian"));
            }
            (1, "Collection") => {}
            (2, "DataSet") => {
                assert!(self_closing);
                assert_eq!((attr("group"), attr("part")), (Some(""), Some("0")));
                let timestep = attr("timestep").expect("timestep").parse().expect("timestep is a number");
                entries.push(Entry { timestep, file: attr("file").expect("file").to_owned() });
            }
            (depth, name) => panic!("unexpected <{name}> at depth {depth}"),
        }
        if !self_closing {
            stack.push(name.to_owned());
        }
    }
    assert!(closed_root && stack.is_empty() && rest.trim().is_empty(), "unclosed elements {stack:?}");
    entries
}

fn parse_attributes(mut text: &str) -> Vec<(String, String)> {
    let mut attrs = Vec::new();
    loop {
        text = text.trim_start();
        if text.is_empty() {
            return attrs;
        }
        let (key, after) = text.split_once("=\"").expect("attribute as key=\"value\"");
        let (raw, after) = after.split_once('"').expect("closing quote");
        assert!(!raw.contains('<'), "raw < in an attribute: {raw:?}");
        let mut value = String::new();
        let mut parts = raw.split('&');
        value.push_str(parts.next().unwrap());
        for part in parts {
            let (entity, tail) = part.split_once(';').expect("entity ends with ;");
            value.push(match entity {
                "amp" => '&',
                "lt" => '<',
                "gt" => '>',
                "quot" => '"',
                "apos" => '\'',
                other => panic!("unknown entity &{other};"),
            });
            value.push_str(tail);
        }
        attrs.push((key.trim().to_owned(), value));
        text = after;
    }
}

#[test]
fn series_of_three_frames_lists_them_in_order() {
    let dir = TempDir::new("series");
    let pvd = dir.join("tissue.pvd");
    let mut series = PvdSeries::new(&pvd);
    assert!(series.is_empty());
    assert_eq!(series.len(), 0);
    assert_eq!(series.path(), pvd);
    assert!(!pvd.exists(), "nothing is written before the first frame");

    let times = [0.0, 0.5, 1.25];
    let cubes: Vec<Cube> = (0..3).map(|k| Cube::new(0.1 * k as f32)).collect();
    for (k, (time, cube)) in times.iter().zip(&cubes).enumerate() {
        let name = format!("tissue_{k:04}.vtp");
        series.write_frame(*time, &name, &cube.frame()).unwrap();
        assert_eq!(series.len(), k + 1);
        assert!(!series.is_empty());
        // After every frame the .pvd on disk is a complete series of the frames so far.
        let entries = parse_pvd(&std::fs::read_to_string(&pvd).unwrap());
        assert_eq!(entries.len(), k + 1);
        assert_eq!(entries[k], Entry { timestep: *time, file: name });
    }

    let entries = parse_pvd(&std::fs::read_to_string(&pvd).unwrap());
    let expected: Vec<Entry> =
        (0..3).map(|k| Entry { timestep: times[k], file: format!("tissue_{k:04}.vtp") }).collect();
    assert_eq!(entries, expected);
    // Each listed file lies beside the .pvd and holds its own frame.
    for (entry, cube) in entries.iter().zip(&cubes) {
        assert_piece_is(&read_piece(&dir.join(&entry.file)), cube);
    }
    // The .pvd, three .vtp files, and no temporary file.
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 4);
}

#[test]
fn series_times_round_trip_exactly() {
    let dir = TempDir::new("times");
    let mut series = PvdSeries::new(dir.join("implant.pvd"));
    let cube = Cube::new(0.0);
    let times = [-1e-7, 0.1, 1.0 / 3.0, 2.5e12];
    for (k, &t) in times.iter().enumerate() {
        series.write_frame(t, &format!("implant_{k}.vtp"), &cube.frame()).unwrap();
    }
    let entries = parse_pvd(&std::fs::read_to_string(dir.join("implant.pvd")).unwrap());
    assert_eq!(entries.iter().map(|e| e.timestep).collect::<Vec<_>>(), times);
}

#[test]
fn series_escapes_file_names() {
    let dir = TempDir::new("escape");
    let pvd = dir.join("odd.pvd");
    let name = "a&b <\"c\"> 'd'.vtp";
    let cube = Cube::new(0.0);
    PvdSeries::new(&pvd).write_frame(0.5, name, &cube.frame()).unwrap();
    let text = std::fs::read_to_string(&pvd).unwrap();
    assert!(text.contains(r#"file="a&amp;b &lt;&quot;c&quot;&gt; &apos;d&apos;.vtp""#), "{text}");
    let entries = parse_pvd(&text);
    assert_eq!(entries, vec![Entry { timestep: 0.5, file: name.to_owned() }]);
    assert_piece_is(&read_piece(&dir.join(name)), &cube);
}

fn invalid(err: Error) -> (&'static str, String, String) {
    match err {
        Error::Invalid { what, value, rule } => (what, value, rule),
        other => panic!("expected Error::Invalid, got {other:?}"),
    }
}

#[test]
fn mismatched_lengths_name_the_array_and_both_lengths() {
    let dir = TempDir::new("lengths");
    let path = dir.join("bad.vtp");
    let cube = Cube::new(0.0);
    let short = &cube.displacement[..7];
    let long = [cube.contact_force.clone(), vec![Vec3::ZERO]].concat();
    let flags = &cube.colliding[..3];
    let cases = [
        (BodyFrame { displacement: short, ..cube.frame() }, "displacement length", "7"),
        (BodyFrame { contact_force: &long, ..cube.frame() }, "contact_force length", "9"),
        (BodyFrame { colliding: flags, ..cube.frame() }, "colliding length", "3"),
    ];
    for (body, what, len) in cases {
        let (w, value, rule) = invalid(write_vtp(&path, &body).unwrap_err());
        assert_eq!((w, value.as_str()), (what, len));
        assert!(rule.contains("positions.len() = 8"), "{rule}");
        let message = Error::Invalid { what: w, value, rule }.to_string();
        assert!(message.starts_with(&format!("{what} = {len} is invalid")), "{message}");
        assert!(!path.exists(), "nothing is written for a bad body");
    }
}

#[test]
fn triangle_index_out_of_range_names_the_triangle() {
    let dir = TempDir::new("index");
    let path = dir.join("bad.vtp");
    let cube = Cube::new(0.0);
    let mut triangles = cube.triangles.clone();
    triangles[5] = [1, 8, 4];
    let body = BodyFrame { triangles: &triangles, ..cube.frame() };
    let (what, value, rule) = invalid(write_vtp(&path, &body).unwrap_err());
    assert_eq!((what, value.as_str()), ("triangle vertex index", "8"));
    assert!(
        rule.contains("triangle 5") && rule.contains("corner 1") && rule.contains("8 positions"),
        "{rule}"
    );
    assert!(!path.exists());
}

#[test]
fn non_finite_values_name_the_array_and_vertex() {
    let dir = TempDir::new("nonfinite");
    let path = dir.join("bad.vtp");
    let cube = Cube::new(0.0);
    let mut positions = cube.positions.clone();
    positions[6].y = f32::NAN;
    let mut displacement = cube.displacement.clone();
    displacement[2].z = f32::INFINITY;
    let mut force = cube.contact_force.clone();
    force[7].x = f32::NEG_INFINITY;
    let cases = [
        (BodyFrame { positions: &positions, ..cube.frame() }, "position", "vertex 6"),
        (BodyFrame { displacement: &displacement, ..cube.frame() }, "displacement", "vertex 2"),
        (BodyFrame { contact_force: &force, ..cube.frame() }, "contact_force", "vertex 7"),
    ];
    for (body, what, vertex) in cases {
        let (w, _, rule) = invalid(write_vtp(&path, &body).unwrap_err());
        assert_eq!(w, what);
        assert!(rule.contains(vertex), "{rule}");
        assert!(!path.exists());
    }
}

#[test]
fn missing_directory_is_an_io_error_naming_it() {
    let dir = TempDir::new("missing");
    let gone = dir.join("not_created");
    let cube = Cube::new(0.0);
    let path = gone.join("body.vtp");
    match write_vtp(&path, &cube.frame()).unwrap_err() {
        Error::Io { path: p, message } => {
            assert_eq!(p, path.display().to_string());
            assert!(message.contains("does not exist") && message.contains("not_created"), "{message}");
        }
        other => panic!("expected Error::Io, got {other:?}"),
    }
    // A regular file where the directory should be.
    let file = dir.join("a_file");
    std::fs::write(&file, "").unwrap();
    match write_vtp(&file.join("body.vtp"), &cube.frame()).unwrap_err() {
        Error::Io { message, .. } => assert!(message.contains("is not a directory"), "{message}"),
        other => panic!("expected Error::Io, got {other:?}"),
    }
    let mut series = PvdSeries::new(gone.join("body.pvd"));
    assert!(matches!(series.write_frame(0.0, "body_0.vtp", &cube.frame()), Err(Error::Io { .. })));
    assert!(series.is_empty(), "a failed frame is not recorded");
    assert!(!gone.exists(), "the writer does not create directories");
}

#[test]
fn series_rejects_bad_frames_and_keeps_its_file_valid() {
    let dir = TempDir::new("bad-series");
    let pvd = dir.join("tissue.pvd");
    let cube = Cube::new(0.0);
    let mut series = PvdSeries::new(&pvd);
    series.write_frame(1.0, "t_0.vtp", &cube.frame()).unwrap();
    let before = std::fs::read_to_string(&pvd).unwrap();

    let bad_body = BodyFrame { colliding: &[], ..cube.frame() };
    let cases: [(f64, &str, BodyFrame, &str); 10] = [
        (1.0, "t_1.vtp", cube.frame(), "frame time"), // not later
        (0.5, "t_1.vtp", cube.frame(), "frame time"),
        (f64::NAN, "t_1.vtp", cube.frame(), "frame time"),
        (f64::INFINITY, "t_1.vtp", cube.frame(), "frame time"),
        (2.0, "sub/t_1.vtp", cube.frame(), "frame file name"),
        (2.0, "../t_1.vtp", cube.frame(), "frame file name"),
        (2.0, "", cube.frame(), "frame file name"),
        (2.0, "t_1.vtk", cube.frame(), "frame file name"),
        (2.0, "t_0.vtp", cube.frame(), "frame file name"), // already used
        (2.0, "t_1.vtp", bad_body, "colliding length"),
    ];
    for (time, name, body, what) in cases {
        let (w, _, rule) = invalid(series.write_frame(time, name, &body).unwrap_err());
        assert_eq!(w, what, "time {time}, name {name:?}: {rule}");
        assert_eq!(series.len(), 1);
        assert_eq!(std::fs::read_to_string(&pvd).unwrap(), before, "the .pvd is unchanged");
    }
    assert!(!dir.join("t_1.vtp").exists());

    // The series goes on after rejected frames.
    series.write_frame(2.0, "t_1.vtp", &cube.frame()).unwrap();
    let entries = parse_pvd(&std::fs::read_to_string(&pvd).unwrap());
    assert_eq!(
        entries.iter().map(|e| (e.timestep, e.file.as_str())).collect::<Vec<_>>(),
        [(1.0, "t_0.vtp"), (2.0, "t_1.vtp")]
    );
}

/// Whether VTK's own readers must run (`VOXCOLLIDE_REQUIRE_VTK=1`, as CI sets it after installing
/// Python's `vtk`) rather than skip where Python has no `vtk`.
fn vtk_required() -> bool {
    std::env::var("VOXCOLLIDE_REQUIRE_VTK").as_deref() == Ok("1")
}

/// Reads `.vtp` files with VTK 9's own `vtkXMLPolyDataReader` (ParaView's reader for them, via
/// Python's `vtk`) and prints, per file, the points, polys, each point array's name, components
/// and range; `None` when Python has no `vtk` module.
fn read_with_vtk(paths: &[PathBuf]) -> Option<String> {
    let script = r#"
import sys, vtk
print("vtk", vtk.vtkVersion.GetVTKVersion())
for path in sys.argv[1:]:
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(path)
    reader.Update()
    if reader.GetErrorCode() != 0:
        sys.exit("vtk could not read " + path)
    data = reader.GetOutput()
    pd = data.GetPointData()
    arrays = []
    for i in range(pd.GetNumberOfArrays()):
        a = pd.GetArray(i)
        lo, hi = a.GetRange(-1) if a.GetNumberOfComponents() > 1 else a.GetRange(0)
        arrays.append("%s/%d/%g/%g" % (a.GetName(), a.GetNumberOfComponents(), lo, hi))
    p = data.GetPoint(data.GetNumberOfPoints() - 1)
    print(path, data.GetNumberOfPoints(), data.GetNumberOfPolys(), pd.GetScalars().GetName(),
          pd.GetVectors().GetName(), " ".join(arrays), "%g,%g,%g" % p)
"#;
    let output = std::process::Command::new("python3").arg("-c").arg(script).args(paths).output();
    match output {
        Ok(o) if o.status.success() => Some(String::from_utf8_lossy(&o.stdout).into_owned()),
        Ok(o) if String::from_utf8_lossy(&o.stderr).contains("No module named 'vtk'") && !vtk_required() => {
            eprintln!("skipped: Python has no vtk module (pip install vtk)");
            None
        }
        Ok(o) => panic!("python3 with vtk failed: {}", String::from_utf8_lossy(&o.stderr)),
        Err(e) if !vtk_required() => {
            eprintln!("skipped: no python3 ({e})");
            None
        }
        Err(e) => panic!("VOXCOLLIDE_REQUIRE_VTK=1 but python3 does not start: {e}"),
    }
}

#[test]
fn vtk_9_reads_every_file_of_a_series() {
    let dir = TempDir::new("vtk9");
    let cubes = [Cube::new(0.0), Cube::new(0.5), Cube::new(1.25)];
    let mut series = PvdSeries::new(dir.join("cube.pvd"));
    let mut paths = Vec::new();
    for (k, cube) in cubes.iter().enumerate() {
        let name = format!("cube_{k:04}.vtp");
        series.write_frame(k as f64 * 0.5, &name, &cube.frame()).unwrap();
        paths.push(dir.join(&name));
    }
    let Some(out) = read_with_vtk(&paths) else { return };
    eprintln!("{out}");
    let lines: Vec<&str> = out.lines().collect();
    assert!(lines[0].starts_with("vtk 9."), "{out}");
    for (k, cube) in cubes.iter().enumerate() {
        let line = lines[k + 1];
        let fields: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(&fields[1..5], ["8", "12", "colliding", "displacement"], "{line}");
        let arrays = &fields[5..8];
        for (name, components) in [("displacement", 3), ("contact_force", 3), ("colliding", 1)] {
            assert!(
                arrays.iter().any(|a| a.starts_with(&format!("{name}/{components}/"))),
                "{name} × {components} in {line}"
            );
        }
        let last = cube.positions[7];
        assert_eq!(fields[8], format!("{},{},{}", last.x, last.y, last.z), "{line}");
    }
}
