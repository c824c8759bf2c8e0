//! Implant catalogues (docs/design.md §9): the candidates `voxcollide compare` runs through one scene,
//! read from TOML and checked, with errors that name the file, line, column and key.
//!
//! ```toml
//! [[candidate]]
//! name = "round 300 mL"
//! shape = { implant = { volume_ml = 300, base_mm = 115, projection_mm = 40, style = "round" } }
//!
//! [[candidate]]
//! name = "my shell"
//! mesh = "shell.stl"          # a closed surface, resolved against the catalogue's folder
//!
//! [[candidate]]
//! name = "Mentor MemoryGel Moderate Plus 300 cc"
//! manufacturer = "Mentor"     # optional: who makes it and its product line, as reported
//! line = "MemoryGel Moderate Plus"
//! shape = { implant = { volume_ml = 300, base_mm = 120, projection_mm = 36, style = "round" } }
//! ```

use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;
use voxcollide::Error;

use crate::scene_file::{Geometry, Shape, at, check_shape, missing_mesh, read_text, toml_error};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCatalogue {
    #[serde(default)]
    candidate: Vec<RawCandidate>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCandidate {
    name: Spanned<String>,
    manufacturer: Option<Spanned<String>>,
    line: Option<Spanned<String>>,
    shape: Option<Spanned<Shape>>,
    mesh: Option<Spanned<String>>,
}

/// One candidate: its name and its geometry (a built-in shape, or a mesh resolved against the
/// catalogue's folder).
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// Its unique name.
    pub name: String,
    /// Who makes it, where the catalogue says (`manufacturer = "Mentor"`).
    pub manufacturer: Option<String>,
    /// Its product line, where the catalogue says (`line = "MemoryGel Moderate Plus"`).
    pub line: Option<String>,
    /// Its shape or mesh.
    pub geometry: Geometry,
}

impl Candidate {
    /// A folder name for the candidate's run: its name with every character that is not a
    /// letter, a digit, `-`, `_` or `.` turned into `_`.
    #[must_use]
    pub fn folder(&self) -> String {
        self.name.chars().map(|c| if c.is_alphanumeric() || "-_.".contains(c) { c } else { '_' }).collect()
    }
}

/// A catalogue, read and checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Catalogue {
    /// The file it was read from.
    pub path: PathBuf,
    /// The candidates, in file order (at least one).
    pub candidates: Vec<Candidate>,
}

impl Catalogue {
    /// Reads and checks the catalogue at `path`; meshes must exist.
    ///
    /// # Errors
    /// [`Error::SceneFile`] naming the file, line, column and key: a syntax or type error, an
    /// unknown key, no candidate, a missing, empty or repeated name (or two names that give the
    /// same folder), neither or both of `shape` and `mesh`, a size that is not positive, an
    /// implant volume that its base and projection cannot hold, a mesh that is not a file; or,
    /// at line 0, a file that cannot be read.
    pub fn read(path: impl AsRef<Path>) -> Result<Catalogue, Error> {
        let path = path.as_ref();
        let text = read_text(path, "the catalogue")?;
        let catalogue = Catalogue::parse(path, &text)?;
        let geometries = catalogue.candidates.iter().map(|c| &c.geometry);
        missing_mesh(&path.display().to_string(), &text, "candidate", geometries)?;
        Ok(catalogue)
    }

    /// Parses and checks catalogue `text` as if read from `path` (mesh paths are resolved
    /// against its folder, and not looked for).
    ///
    /// # Errors
    /// As [`read`](Self::read), but for the mesh files.
    pub fn parse(path: impl AsRef<Path>, text: &str) -> Result<Catalogue, Error> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let raw: RawCatalogue = toml::from_str(text).map_err(|e| toml_error(&file, text, &e))?;
        if raw.candidate.is_empty() {
            return Err(at(
                &file,
                text,
                0..0,
                Some("candidate"),
                "no [[candidate]]: a catalogue lists at least one",
            ));
        }
        let dir = path.parent().unwrap_or(Path::new(""));
        let mut candidates: Vec<Candidate> = Vec::with_capacity(raw.candidate.len());
        for (k, c) in raw.candidate.into_iter().enumerate() {
            let key = |what: &str| format!("candidate[{k}].{what}");
            let name_span = c.name.span();
            let name = c.name.into_inner();
            if name.trim().is_empty() {
                return Err(at(&file, text, name_span, Some(&key("name")), "a candidate needs a name"));
            }
            let geometry = match (c.shape, c.mesh) {
                (Some(shape), None) => {
                    let span = shape.span();
                    let shape = shape.into_inner();
                    check_shape(&shape).map_err(|(what, m)| at(&file, text, span, Some(&key(what)), m))?;
                    Geometry::Shape(shape)
                }
                (None, Some(mesh)) => Geometry::Mesh(dir.join(mesh.into_inner())),
                (Some(_), Some(mesh)) => {
                    return Err(at(
                        &file,
                        text,
                        mesh.span(),
                        Some(&key("mesh")),
                        format!("candidate {name:?} has both `shape` and `mesh`; give one"),
                    ));
                }
                (None, None) => {
                    return Err(at(
                        &file,
                        text,
                        name_span,
                        Some(&key("shape")),
                        format!("candidate {name:?} needs a `shape` or a `mesh`"),
                    ));
                }
            };
            let label = |v: Option<Spanned<String>>, what: &str| match v {
                Some(v) if v.get_ref().trim().is_empty() => Err(at(
                    &file,
                    text,
                    v.span(),
                    Some(&key(what)),
                    format!("candidate {name:?} has an empty `{what}`: name it or leave the key out"),
                )),
                v => Ok(v.map(Spanned::into_inner)),
            };
            let manufacturer = label(c.manufacturer, "manufacturer")?;
            let line = label(c.line, "line")?;
            let candidate = Candidate { name, manufacturer, line, geometry };
            if let Some(first) =
                candidates.iter().position(|o| o.name == candidate.name || o.folder() == candidate.folder())
            {
                return Err(at(
                    &file,
                    text,
                    name_span,
                    Some(&key("name")),
                    format!(
                        "{:?} repeats candidate[{first}] {:?} (names are unique, and so are the folders they give)",
                        candidate.name, candidates[first].name
                    ),
                ));
            }
            candidates.push(candidate);
        }
        Ok(Catalogue { path: path.to_path_buf(), candidates })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene_file::ImplantStyle;

    fn error(text: &str) -> (usize, String, String) {
        match Catalogue::parse("cat.toml", text).unwrap_err() {
            Error::SceneFile { file, line, key, message, .. } => {
                assert_eq!(file, "cat.toml");
                (line, key, message)
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn candidates_are_read_in_order() {
        let c = Catalogue::parse(
            "dir/cat.toml",
            r#"
[[candidate]]
name = "round 300"
shape = { implant = { volume_ml = 300, base_mm = 115, projection_mm = 40 } }

[[candidate]]
name = "teardrop 250"
manufacturer = "Acme"
line = "Teardrop Tall"
shape = { implant = { volume_ml = 250, base_mm = 110, projection_mm = 38, style = "anatomical" } }

[[candidate]]
name = "own / shell"
mesh = "shell.stl"
"#,
        )
        .unwrap();
        assert_eq!(c.candidates.len(), 3);
        assert_eq!(
            c.candidates[1].geometry,
            Geometry::Shape(Shape::Implant {
                volume_ml: 250.0,
                base_mm: 110.0,
                projection_mm: 38.0,
                style: ImplantStyle::Anatomical
            })
        );
        assert_eq!(
            (c.candidates[1].manufacturer.as_deref(), c.candidates[1].line.as_deref()),
            (Some("Acme"), Some("Teardrop Tall"))
        );
        assert_eq!((c.candidates[0].manufacturer.as_deref(), c.candidates[0].line.as_deref()), (None, None));
        assert_eq!(c.candidates[2].geometry, Geometry::Mesh(PathBuf::from("dir/shell.stl")));
        assert_eq!(c.candidates[2].folder(), "own___shell");
    }

    #[test]
    fn bad_candidates_are_named_by_line_and_key() {
        let implant = |v: &str| {
            format!(
                "[[candidate]]\nname = \"a\"\nshape = {{ implant = {{ volume_ml = {v}, base_mm = 115, projection_mm = 40 }} }}\n"
            )
        };
        let (line, key, message) = error(&implant("900"));
        assert_eq!((line, key.as_str()), (3, "candidate[0].shape.implant.volume_ml"), "{message}");
        assert!(message.contains("holds more than"), "{message}");
        let (line, key, _) = error(&implant("-5"));
        assert_eq!((line, key.as_str()), (3, "candidate[0].shape"));
        let (_, key, _) = error("[[candidate]]\nname = \"a\"\n");
        assert_eq!(key, "candidate[0].shape");
        let (line, key, _) = error("[[candidate]]\nname = \"\"\nshape = { sphere = 3 }\n");
        assert_eq!((line, key.as_str()), (2, "candidate[0].name"));
        let (line, key, message) = error(
            "[[candidate]]\nname = \"a b\"\nshape = { sphere = 3 }\n[[candidate]]\nname = \"a_b\"\nshape = { sphere = 4 }\n",
        );
        assert_eq!((line, key.as_str()), (5, "candidate[1].name"), "{message}");
        let (line, key, _) = error("[[candidate]]\nname = \"a\"\nshape = { sphere = 3 }\nmesh = \"x.stl\"\n");
        assert_eq!((line, key.as_str()), (4, "candidate[0].mesh"));
        let (line, key, _) = error("[[candidate]]\nname = \"a\"\nshape = { sphere = 3 }\ncolour = 1\n");
        assert_eq!((line, key.as_str()), (4, "candidate[0].colour"));
        let (line, key, _) =
            error("[[candidate]]\nname = \"a\"\nmanufacturer = \" \"\nshape = { sphere = 3 }\n");
        assert_eq!((line, key.as_str()), (3, "candidate[0].manufacturer"));
        let (line, key, _) = error("[[candidate]]\nname = \"a\"\nshape = { sphere = 3 }\nline = \"\"\n");
        assert_eq!((line, key.as_str()), (4, "candidate[0].line"));
        let (_, key, _) = error("# nothing\n");
        assert_eq!(key, "candidate");
        let (line, _, _) = error("[[candidate]]\nname = 3\n");
        assert_eq!(line, 2);
    }

    /// The shipped product line (`scenes/catalogues/mentor-memorygel-round.toml`) reads whole:
    /// every size an implant its base and projection can hold, each profile wider and more
    /// projecting as it holds more, its sizes as the catalogue prints them.
    #[test]
    fn the_shipped_product_line_reads_whole_and_in_order() {
        let path =
            concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/catalogues/mentor-memorygel-round.toml");
        let c = Catalogue::read(path).unwrap();
        assert_eq!(c.candidates.len(), 25 + 25 + 22 + 20);
        // Per line, its sizes: (volume, base, projection).
        type Sizes = Vec<(f64, f64, f64)>;
        let mut lines: Vec<(String, Sizes)> = Vec::new();
        for k in &c.candidates {
            assert_eq!(k.manufacturer.as_deref(), Some("Mentor"), "{}", k.name);
            let Geometry::Shape(Shape::Implant { volume_ml, base_mm, projection_mm, style }) = k.geometry
            else {
                panic!("{}: {:?}", k.name, k.geometry)
            };
            assert_eq!(style, ImplantStyle::Round, "{}", k.name);
            let line = k.line.clone().unwrap();
            match lines.last_mut() {
                Some((l, sizes)) if *l == line => sizes.push((volume_ml, base_mm, projection_mm)),
                _ => lines.push((line, vec![(volume_ml, base_mm, projection_mm)])),
            }
        }
        assert_eq!(lines.len(), 4, "{:?}", lines.iter().map(|l| &l.0).collect::<Vec<_>>());
        for (line, sizes) in &lines {
            for w in sizes.windows(2) {
                let ((v0, b0, p0), (v1, b1, p1)) = (w[0], w[1]);
                assert!(v1 > v0 && b1 > b0 && p1 >= p0, "{line}: {:?} then {:?}", w[0], w[1]);
            }
        }
        // At about 350 cc the profiles narrow and project more, as their names say.
        let at350: Vec<(f64, f64)> = lines
            .iter()
            .map(|(_, s)| {
                s.iter().find(|&&(v, ..)| (340.0..=360.0).contains(&v)).map(|&(_, b, p)| (b, p)).unwrap()
            })
            .collect();
        assert_eq!(at350, [(134.0, 32.0), (125.0, 39.0), (117.0, 48.0), (101.0, 52.0)]);
        // The patient's six are sizes of it, as it lists them.
        let six = Catalogue::read(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/patient-implants.toml"))
            .unwrap();
        assert_eq!(six.candidates.len(), 6);
        for k in &six.candidates {
            assert!(c.candidates.contains(k), "{} is not in the product line as listed", k.name);
        }
    }

    #[test]
    fn a_missing_mesh_is_named() {
        let dir = std::env::temp_dir().join(format!("voxcollide-catalogue-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cat.toml");
        std::fs::write(&path, "[[candidate]]\nname = \"a\"\nmesh = \"missing.stl\"\n").unwrap();
        match Catalogue::read(&path).unwrap_err() {
            Error::SceneFile { line, key, message, .. } => {
                assert_eq!((line, key.as_str()), (3, "candidate[0].mesh"));
                assert!(message.contains("missing.stl"), "{message}");
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            Catalogue::read(dir.join("nope.toml")).unwrap_err(),
            Error::SceneFile { line: 0, .. }
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
