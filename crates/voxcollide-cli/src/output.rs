//! ParaView output: each body at each frame as a VTK XML PolyData file (`.vtp`), and per body a
//! `.pvd` collection that lists those files with their times, so ParaView opens the series as an
//! animation.
//!
//! Format choices:
//! - `.vtp` files are VTK XML PolyData, version 1.0, little-endian, with every array inline in
//!   base64 binary behind a `UInt64` byte count (`header_type="UInt64"`), uncompressed. They are
//!   written through `vtkio` 0.7's XML model (its `export_ascii` would write the legacy format
//!   whatever the extension), and VTK 9's `vtkXMLPolyDataReader`, ParaView's reader, reads them
//!   (tests/output.rs runs it, through Python's `vtk`).
//! - Points are `Float32` × 3; the triangles are `Polys` (`connectivity` and `offsets`, `UInt64`).
//! - Point data: `displacement` (`Float32` × 3, the active vectors), `contact_force`
//!   (`Float32` × 3) and `colliding` (`UInt8`, 0 or 1, the active scalars).
//! - The `.pvd` is written here by hand; it is rewritten whole after every frame, through a
//!   temporary file and a rename, so a run stopped at any point leaves a valid series that lists
//!   only complete `.vtp` files.

use std::io::Write as _;
use std::path::{Component, Path, PathBuf};

use glam::Vec3;
use vtkio::model::{
    Attribute, Attributes, ByteOrder, DataArray, DataSet, ElementType, IOBuffer, PolyDataPiece, Version,
    VertexNumbers, Vtk,
};

use voxcollide::Error;

/// One body at one frame: its surface mesh and per-vertex results.
///
/// Every per-vertex slice must have `positions.len()` entries.
#[derive(Clone, Copy, Debug)]
pub struct BodyFrame<'a> {
    /// Vertex positions.
    pub positions: &'a [Vec3],
    /// Surface triangles, as indices into `positions`.
    pub triangles: &'a [[u32; 3]],
    /// Per-vertex displacement (from the rest or initial position).
    pub displacement: &'a [Vec3],
    /// Per-vertex contact force.
    pub contact_force: &'a [Vec3],
    /// Per-vertex flag: whether the vertex is in contact this frame.
    pub colliding: &'a [bool],
}

/// Writes `body` to `path` as VTK XML PolyData (`.vtp`): all points, the triangles as polys, and
/// the point-data arrays `displacement` (3 components), `contact_force` (3 components) and
/// `colliding` (`UInt8`, 0 or 1).
///
/// The directory of `path` must exist: it is not created. The file is written as `<name>.tmp`
/// beside it and renamed into place, so a stopped run never leaves a half-written `path`.
///
/// # Errors
/// - [`Error::Invalid`] when a per-vertex array's length differs from `positions.len()`, a
///   triangle index is out of range, or a position, displacement or contact force is not finite
///   (the error names the array and the vertex); nothing is written then.
/// - [`Error::Io`] when the file cannot be written (for instance a missing directory).
pub fn write_vtp(path: &Path, body: &BodyFrame) -> Result<(), Error> {
    validate(body)?;
    let mut xml = Vec::new();
    to_vtk(body).write_xml(&mut xml).map_err(|e| io_error(path, format!("cannot encode VTK XML: {e}")))?;
    write_file(path, &xml)
}

/// A ParaView collection (`.pvd`) of one body's frames: the `.pvd` path and, in order, each
/// frame's time and `.vtp` file name (relative to the `.pvd`'s directory).
#[derive(Clone, Debug)]
pub struct PvdSeries {
    path: PathBuf,
    entries: Vec<(f64, String)>,
}

impl PvdSeries {
    /// Starts an empty series whose collection file is `path` (conventionally `<body>.pvd`).
    /// Nothing is written until the first [`write_frame`](Self::write_frame); an existing file
    /// at `path` is then replaced.
    pub fn new(path: impl Into<PathBuf>) -> PvdSeries {
        PvdSeries { path: path.into(), entries: Vec::new() }
    }

    /// Writes `body` to `<pvd dir>/<file_name>` (see [`write_vtp`]) and records it at `time`;
    /// then rewrites the `.pvd` (through a temporary file and a rename), so a run stopped
    /// midway still leaves a valid series of complete frames.
    ///
    /// `file_name` is a plain file name ending in `.vtp` (no directory part); `time` is finite
    /// and later than the previous frame's, and each file name is used once per series.
    ///
    /// # Errors
    /// - [`Error::Invalid`] for a bad `time` or `file_name`, or a bad `body` (as [`write_vtp`]);
    ///   nothing is written and nothing recorded then.
    /// - [`Error::Io`] when the `.vtp` or the `.pvd` cannot be written; the frame is not
    ///   recorded then (a `.vtp` already written stays on disk, unlisted).
    pub fn write_frame(&mut self, time: f64, file_name: &str, body: &BodyFrame) -> Result<(), Error> {
        self.check_time(time)?;
        self.check_file_name(file_name)?;
        write_vtp(&self.dir().join(file_name), body)?;
        self.entries.push((time, file_name.to_owned()));
        if let Err(e) = write_file(&self.path, self.pvd_xml().as_bytes()) {
            self.entries.pop();
            return Err(e);
        }
        Ok(())
    }

    /// The number of frames recorded.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether no frame has been recorded yet.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The path of the `.pvd` file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The directory the `.vtp` files go to: the `.pvd`'s own.
    fn dir(&self) -> &Path {
        self.path.parent().unwrap_or(Path::new(""))
    }

    fn check_time(&self, time: f64) -> Result<(), Error> {
        let invalid = |rule: String| Error::Invalid { what: "frame time", value: format!("{time:?}"), rule };
        if !time.is_finite() {
            return Err(invalid("it must be finite".into()));
        }
        if let Some(&(last, _)) = self.entries.last()
            && time <= last
        {
            return Err(invalid(format!(
                "it must be later than the previous frame's time {last:?} (frame {})",
                self.entries.len() - 1
            )));
        }
        Ok(())
    }

    fn check_file_name(&self, file_name: &str) -> Result<(), Error> {
        let invalid = |rule: &str| Error::Invalid {
            what: "frame file name",
            value: format!("{file_name:?}"),
            rule: rule.into(),
        };
        let mut components = Path::new(file_name).components();
        let plain = matches!((components.next(), components.next()), (Some(Component::Normal(_)), None))
            && !file_name.contains(['/', '\\']);
        if !plain {
            return Err(invalid(
                "it must be a plain file name, without a directory part (it is written beside the .pvd)",
            ));
        }
        if Path::new(file_name).extension().is_none_or(|ext| ext != "vtp") {
            return Err(invalid("it must end in .vtp (ParaView picks the reader by extension)"));
        }
        if self.entries.iter().any(|(_, name)| name == file_name) {
            return Err(invalid("it is already a frame of this series: each frame needs its own file"));
        }
        Ok(())
    }

    /// The whole `.pvd` document for the frames recorded so far.
    fn pvd_xml(&self) -> String {
        let mut xml = String::from(
            "<?xml version=\"1.0\"?>\n\
             <VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n",
        );
        for (time, file) in &self.entries {
            // `{:?}` prints the shortest text that reads back as the same f64, e.g. 0.5 or 1e-7.
            xml.push_str(&format!(
                "    <DataSet timestep=\"{time:?}\" group=\"\" part=\"0\" file=\"{}\"/>\n",
                escape_xml(file)
            ));
        }
        xml.push_str("  </Collection>\n</VTKFile>\n");
        xml
    }
}

/// Checks every rule of [`write_vtp`] on `body` before anything is written.
fn validate(body: &BodyFrame) -> Result<(), Error> {
    let n = body.positions.len();
    if u32::try_from(n).is_err() {
        return Err(Error::Invalid {
            what: "positions length",
            value: n.to_string(),
            rule: format!("a VTK piece holds at most {} points", u32::MAX),
        });
    }
    if u32::try_from(body.triangles.len()).is_err() {
        return Err(Error::Invalid {
            what: "triangles length",
            value: body.triangles.len().to_string(),
            rule: format!("a VTK piece holds at most {} polys", u32::MAX),
        });
    }
    let lengths: [(&'static str, usize); 3] = [
        ("displacement length", body.displacement.len()),
        ("contact_force length", body.contact_force.len()),
        ("colliding length", body.colliding.len()),
    ];
    for (what, len) in lengths {
        if len != n {
            return Err(Error::Invalid {
                what,
                value: len.to_string(),
                rule: format!("it must equal positions.len() = {n} (one value per vertex)"),
            });
        }
    }
    for (t, tri) in body.triangles.iter().enumerate() {
        for (corner, &index) in tri.iter().enumerate() {
            if index as usize >= n {
                return Err(Error::Invalid {
                    what: "triangle vertex index",
                    value: index.to_string(),
                    rule: format!(
                        "triangle {t} (corner {corner}) must index one of the {n} positions (0..{n})"
                    ),
                });
            }
        }
    }
    let vectors: [(&'static str, &[Vec3]); 3] = [
        ("position", body.positions),
        ("displacement", body.displacement),
        ("contact_force", body.contact_force),
    ];
    for (what, values) in vectors {
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(Error::Invalid {
                what,
                value: values[i].to_string(),
                rule: format!("vertex {i} must have three finite components"),
            });
        }
    }
    Ok(())
}

/// The `vtkio` model of a validated body: one inline PolyData piece.
fn to_vtk(body: &BodyFrame) -> Vtk {
    let flat = |v: &[Vec3]| -> IOBuffer { v.iter().flat_map(|p| p.to_array()).collect::<Vec<f32>>().into() };
    let polys = (!body.triangles.is_empty()).then(|| VertexNumbers::XML {
        connectivity: body.triangles.iter().flatten().map(|&i| u64::from(i)).collect(),
        offsets: (1..=body.triangles.len() as u64).map(|t| 3 * t).collect(),
    });
    let point = vec![
        Attribute::DataArray(DataArray::vectors("displacement").with_buf(flat(body.displacement))),
        Attribute::DataArray(DataArray {
            name: "contact_force".into(),
            elem: ElementType::Generic(3),
            data: flat(body.contact_force),
        }),
        Attribute::DataArray(
            DataArray::scalars("colliding", 1)
                .with_buf(body.colliding.iter().map(|&c| u8::from(c)).collect::<Vec<u8>>().into()),
        ),
    ];
    Vtk {
        version: Version::new_xml(1, 0),
        title: String::new(),
        byte_order: ByteOrder::LittleEndian,
        file_path: None,
        data: DataSet::inline(PolyDataPiece {
            points: flat(body.positions),
            polys,
            data: Attributes { point, cell: Vec::new() },
            ..Default::default()
        }),
    }
}

/// Writes `bytes` to `path` through a temporary file beside it (`<name>.tmp`) and a rename, so
/// that a process stopped midway leaves `path` either as it was or whole with the new content.
fn write_file(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        let problem = if dir.exists() { "is not a directory" } else { "does not exist" };
        return Err(io_error(
            path,
            format!("the directory {} {problem} (the caller creates the output directory)", dir.display()),
        ));
    }
    let Some(name) = path.file_name() else {
        return Err(io_error(path, "the path has no file name".into()));
    };
    let mut tmp_name = name.to_os_string();
    tmp_name.push(".tmp");
    let tmp = path.with_file_name(tmp_name);
    let write = || -> std::io::Result<()> {
        let mut file = std::fs::File::create(&tmp)?;
        file.write_all(bytes)?;
        std::fs::rename(&tmp, path)
    };
    write().map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io_error(path, e.to_string())
    })
}

fn io_error(path: &Path, message: String) -> Error {
    Error::Io { path: path.display().to_string(), message }
}

/// Escapes the five XML special characters for an attribute value.
fn escape_xml(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}
