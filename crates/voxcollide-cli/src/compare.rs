//! `voxcollide compare` (docs/design.md §9): one scene run once per candidate of an implant catalogue,
//! the named body's shape (or mesh) replaced by the candidate's, with settling on; the
//! candidates' resting shapes and measurements side by side in `report.html` (self-contained),
//! `compare.json` and `compare.csv`.
//!
//! The compared body is a shell: it starts deflated on its base under the tissue — at the
//! scene's scale, or smaller where the candidate would not fit under the tissue — and fills to
//! the candidate's own volume over the scene's inflation ramp, then the scene settles. Every candidate is built before anything runs, so a
//! bad one is an error naming it and nothing is written.

use std::path::{Path, PathBuf};

use base64::Engine;
use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};
use voxcollide::{ContactReport, Error};
use voxcollide_sim::build::{Recoveries, build_world, build_world_reusing};
use voxcollide_sim::catalogue::{Candidate, Catalogue};
use voxcollide_sim::geometry::ClosedSurface;
use voxcollide_sim::scene_file::{Axis, BodyKind, BodySpec, Ease, Geometry, Inflate, SceneFile, Shape};
use voxcollide_sim::{MassSpring, World};

use crate::backend::Backend;
use crate::plots::{Chart, Series, line_chart_svg};
use crate::scene_run::{
    FileRunConfig, axes, mean_spring, meshes, run_scene_on, shown_and_moved, shown_surface,
};
use plotters::prelude::SeriesLabelPosition;
use voxcollide_render::{Legend, Renderer, Scene as RenderScene};

/// What to compare, and where.
#[derive(Clone, Debug)]
pub struct CompareConfig {
    /// The scene file.
    pub scene: PathBuf,
    /// The name of the scene's shell body that each candidate replaces.
    pub body: String,
    /// The catalogue file.
    pub candidates: PathBuf,
    /// The output folder: `report.html`, `compare.json`, `compare.csv`, and a folder per
    /// candidate with its run.
    pub out: PathBuf,
    /// Which backend runs the scenes.
    pub backend: Backend,
    /// Picture size.
    pub image: (u32, u32),
    /// Candidates run at a time; 0 picks: on the CPU backend one per core (each stepping on
    /// one thread), else one (candidates share the adapter).
    pub jobs: usize,
    /// Choose from the catalogue by her breast's base width (`--fit-base`): only implants
    /// whose base is no wider than it, and at most this many millimetres narrower
    /// ([`fitting`]). `None`: every candidate.
    pub fit_base: Option<f64>,
}

/// One candidate's result, as in `compare.json` (docs/design.md §9's keys first).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CandidateResult {
    /// The candidate's name.
    pub name: String,
    /// Who makes it, where the catalogue says.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub manufacturer: Option<String>,
    /// Its product line, where the catalogue says.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub line: Option<String>,
    /// The volume the compared shell encloses at the end, in mL.
    pub volume_ml: f64,
    /// How far the tissue's outer surface rose at its highest point (scene units).
    pub apex_lift: f32,
    /// The largest distance a tissue vertex moved from its rest position over the run (scene
    /// units).
    pub max_tissue_displacement: f32,
    /// The largest contact pressure on a tissue vertex at the end, in kPa: its penalty force
    /// over the area a surface vertex stands for (its body's spacing squared). The paper's
    /// penalty forces all have one magnitude, so this is that magnitude's pressure wherever a
    /// force acts (0 when none acts at the last step).
    pub peak_contact_pressure_kpa: f64,
    /// The area the tissue touches the shell over at the end, in scene units squared: the
    /// tissue's surface vertices within half a voxel of the shell's surface (or inside it)
    /// times the tissue's spacing squared. Measured on the geometry, not on which penalty forces happen
    /// to act at the last step: at rest, penalty contacts flicker from step to step.
    pub contact_area: f64,
    /// The deepest a tissue vertex got inside the shell over the run (scene units).
    pub max_penetration: f32,
    /// The implant's footprint on the outer surface, in scene units squared: the area (at
    /// rest) of the tissue's up-facing surface whose triangles rose, at all three corners, more
    /// than half the apex lift.
    pub footprint_area: f64,
    /// Whether the scene came to rest before `max_steps`.
    pub settled: bool,
    /// Whether every contact of its run held (docs/design.md §11): only then are its numbers an
    /// answer.
    pub held: bool,
    /// Where it did not hold: why, a sentence.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
    /// Whether its run finished: the shell reached its own volume (within
    /// [`VOLUME_TOLERANCE`]) and the scene came to rest. An unfinished run's numbers are where
    /// it stopped, not an answer.
    pub finished: bool,
    /// Where it did not finish: why, a sentence.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unfinished: Option<String>,
    /// Where its numbers are an answer, but likely not to the question asked: a sentence (the
    /// implant does not touch the tissue at the end, [`untouched`], or its base reaches past
    /// the tissue on a flat chest wall).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub warning: Option<String>,
    /// The voxel size of the compared body's contact (scene units): the model removes
    /// penetrations deeper than that within a few steps.
    pub voxel_size: f32,
    /// The total penalty force at the end over the contact area, in kPa.
    pub mean_contact_pressure_kpa: f64,
    /// The volume the candidate was filled to, in mL: its own.
    pub target_volume_ml: f64,
    /// Steps run.
    pub steps: u64,
    /// Where its run blew up (a vertex not finite, or moving a tenth of the scene in one step):
    /// the step it was seen at. Such a candidate did not hold (`held` false, `failure` says
    /// what blew up), its run stopped there, and its numbers are zero: there is no end to
    /// measure.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub blew_up_at_step: Option<u64>,
    /// Its run's folder, relative to the output folder.
    pub folder: String,
    /// Its pictures (front and side), relative to the output folder; none without an adapter.
    pub pictures: Vec<String>,
    /// The mean distance of the tissue's vertices from their rest positions at the end (scene
    /// units).
    pub mean_tissue_displacement: f32,
    /// The largest strain of a tissue spring at the end: `|length / rest length − 1|`.
    pub max_tissue_strain: f32,
    /// The pressure inside the compared shell at the end, in kPa: its fill's response to the
    /// volume it holds (and any pressure the scene sets). At rest it is what the implant
    /// presses on the tissue with, averaged over its surface — unlike the penalty forces, whose
    /// one magnitude makes the peak contact pressure the same for every candidate.
    pub implant_pressure_kpa: f64,
    /// The tissue's outer surface along the line through its apex parallel to x (on a
    /// patient: across her chest wall, and the rise along its normal), at the end: `[x, rise]`
    /// pairs in x order (scene units), x from the implant's centre, the rise above where that
    /// point of the surface started.
    pub profile: Vec<[f32; 2]>,
    /// On a patient (docs/design.md §15): her landmarks where they started and where the
    /// operated breast carried them, in scene units (`[{ body, name, start, end }]`, as in
    /// `summary.json`).
    pub landmarks: Vec<crate::scene_run::LandmarkSummary>,
    /// On a patient: the distance between each two of her landmarks at the start and at the
    /// end, in scene units (a surgeon's sternal notch to nipple, nipple to fold, where the
    /// scene names them).
    pub landmark_distances: Vec<LandmarkDistance>,
    /// On a patient: the volume the operation added between her skin and chest wall, in mL
    /// (the `between` body's `volume_ml_end` minus its `volume_ml` at the start).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume_gain_ml: Option<f64>,
    /// On a patient: her tissue's Poisson's ratio as its model has it (1/4 for the paper's
    /// springs, `poisson` for finite elements; the least over her tissue bodies). The volume
    /// added is held to the implant's ([`GAIN_TOLERANCE`]) only at
    /// [`INCOMPRESSIBLE_POISSON`] or more: compressible tissue under an implant gives up some of
    /// its own volume.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tissue_poisson: Option<f64>,
    /// On a patient: where the candidate's base stood on her chest wall, and how far it moved
    /// from under the landmark to keep within her borders (`place.within`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub placed: Option<crate::scene_run::PlacedSummary>,
    /// The metrics at each frame of the run.
    pub history: Vec<Sample>,
}

/// The distance between two landmarks, as in `compare.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LandmarkDistance {
    /// One landmark, `body.name`.
    pub a: String,
    /// The other.
    pub b: String,
    /// Their distance at the start and at the end (scene units).
    pub start: f32,
    /// See `start`.
    pub end: f32,
}

/// Each two of `marks`' distance at the start and the end, in their order.
fn distances(marks: &[crate::scene_run::LandmarkSummary]) -> Vec<LandmarkDistance> {
    let at = |p: [f32; 3]| Vec3::from_array(p);
    let mut out = Vec::new();
    for (i, a) in marks.iter().enumerate() {
        for b in &marks[i + 1..] {
            out.push(LandmarkDistance {
                a: format!("{}.{}", a.body, a.name),
                b: format!("{}.{}", b.body, b.name),
                start: at(a.start).distance(at(b.start)),
                end: at(a.end).distance(at(b.end)),
            });
        }
    }
    out
}

/// A candidate's metrics at one frame of its run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Sample {
    /// Simulated time, in seconds.
    pub time: f64,
    /// The apex lift (scene units).
    pub apex_lift: f32,
    /// The compared shell's volume, in mL.
    pub volume_ml: f64,
    /// The largest distance of a tissue vertex from its rest position (scene units).
    pub max_tissue_displacement: f32,
    /// Vertices in contact between the tissue and the compared body: the probing body's (the
    /// contact's `b`), as the detector counts them.
    pub contacts: usize,
}

/// What `compare` measured, as written to `compare.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Comparison {
    /// The scene file.
    pub scene: String,
    /// The compared body.
    pub body: String,
    /// The scene's length unit.
    pub units: String,
    /// Per candidate, in the catalogue's order.
    pub candidates: Vec<CandidateResult>,
}

fn io(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Io { path: path.display().to_string(), message: e.to_string() }
}

/// The most a candidate is flattened to at the start ([`BodySpec::flatten`]): a twentieth of
/// its height, where the tissue lies on its base (no gap at all).
///
/// [`BodySpec::flatten`]: voxcollide_sim::scene_file::BodySpec
pub const FLATTEST: f64 = 0.05;

/// The scene with `body` replaced by candidate `c` at its full size, filled to `volume_ml`,
/// settling on. With `fit` (its shape's height and the room between its base and the tissue
/// above it, scene units), it starts deflated flat on its base under the tissue: at half its
/// height, or flatter where that would not leave a tenth of the room free (at most
/// [`FLATTEST`]), its rest shape its own.
fn with_candidate(
    scene: &SceneFile,
    body: usize,
    c: &Candidate,
    volume_ml: Option<f64>,
    fit: Option<(f64, f64, f64)>,
) -> SceneFile {
    let mut s = scene.clone();
    s.time.settle = true;
    let b = &mut s.bodies[body];
    b.geometry = c.geometry.clone();
    if let Some((height, room, spacing)) = fit {
        deflate(b, height, room, spacing);
    }
    if let Some(volume_ml) = volume_ml {
        let ramp = b.inflate.as_ref().map_or(0.75 * scene.time.duration.unwrap_or(1.0), |i| i.ramp);
        let ease = b.inflate.as_ref().map_or(Ease::Smooth, |i| i.ease);
        // An expander's schedule keeps its times, its volumes scaled to the candidate's.
        let schedule = match b.inflate.as_ref().and_then(|i| i.schedule.last().map(|l| (l[1], &i.schedule))) {
            Some((last, schedule)) if last > 0.0 => {
                schedule.iter().map(|&[t, ml]| [t, ml * volume_ml / last]).collect()
            }
            _ => Vec::new(),
        };
        b.inflate = Some(Inflate { pressure_kpa: None, volume_ml: Some(volume_ml), schedule, ramp, ease });
    }
    s
}

/// Her breast's base width in millimetres, between the landmarks `medial` and `lateral` of a
/// tissue body (where a surgeon measures it, at the breast's inner and outer borders), and
/// which landmarks those were.
///
/// # Errors
/// [`Error::Invalid`] when no tissue body has both landmarks.
pub fn base_width(scene: &SceneFile, tissue: &[usize]) -> Result<(f64, String), Error> {
    for &t in tissue {
        let b = &scene.bodies[t];
        let at = |name: &str| b.landmarks.iter().find(|(n, _)| n == name).map(|(_, p)| DVec3::from_array(*p));
        if let (Some(m), Some(l)) = (at("medial"), at("lateral")) {
            let mm = m.distance(l) * scene.metres() * 1e3;
            return Ok((mm, format!("{0}.medial – {0}.lateral", b.name)));
        }
    }
    Err(Error::Invalid {
        what: "--fit-base",
        value: scene.path.display().to_string(),
        rule: "needs her breast's borders: give the tissue `landmarks` named `medial` and `lateral` (its inner and outer edges on the skin)".into(),
    })
}

/// The candidates whose implant base is no wider than `width` and at most `margin`
/// millimetres narrower, in their order. A candidate that is not an `implant` shape (a mesh)
/// has no base width to judge, and is kept.
#[must_use]
pub fn fitting(candidates: &[Candidate], width: f64, margin: f64) -> Vec<Candidate> {
    candidates
        .iter()
        .filter(|c| match c.geometry {
            Geometry::Shape(Shape::Implant { base_mm, .. }) => base_mm <= width && base_mm >= width - margin,
            _ => true,
        })
        .cloned()
        .collect()
}

/// Starts shell `b` (its shape `height` high) deflated flat on its base, under tissue `room`
/// above that base whose spacing is `spacing` (scene units). Its top starts a tenth of the
/// room (at least a twentieth of the tissue's spacing) under the tissue, but it is never
/// flatter than its own edge (or [`FLATTEST`]): thinner, the three nearest of its vertices to
/// a tissue vertex mix its top and its base, and their plane stands on edge. Where that start
/// stands higher than the room, it starts that much lower, on a floor as much lower, both
/// rising back as it fills.
fn deflate(b: &mut BodySpec, height: f64, room: f64, spacing: f64) {
    let top = room - (0.1 * room).max(0.05 * spacing);
    let edge = b.spacing.unwrap_or(0.0);
    let f = (top / height).max(FLATTEST).max(edge / height).min(0.5);
    b.scale = 1.0;
    b.flatten = Some(f);
    b.sink = (f * height - top).max(0.0);
}

/// A scene's shells placed on a patient's chest wall and filled (`place` and `inflate`,
/// docs/design.md §15), started as `compare` starts a candidate: deflated flat on the wall,
/// sunk behind it as far as they stand, rising as they fill. Full-sized, they would start
/// inside her tissue. (`voxcollide run` starts a scene so.)
///
/// # Errors
/// A shell that cannot be built alone.
pub fn start_placed_deflated(scene: &mut SceneFile) -> Result<(), Error> {
    for k in 0..scene.bodies.len() {
        let b = &scene.bodies[k];
        let Some(place) = &b.place else { continue };
        if b.inflate.is_none() || b.flatten.is_some() {
            continue;
        }
        let spacing = scene.bodies[place.body].spacing.unwrap_or(1.0);
        let (lo, hi) = alone_extent(scene, k)?;
        if hi > lo {
            deflate(&mut scene.bodies[k], hi - lo, 0.0, spacing);
        }
    }
    Ok(())
}

/// Body `k` of `scene` built alone, standing on its base as its shape gives it (not placed,
/// no gravity): its lowest and highest z (scene units), and the world it is in.
fn alone(scene: &SceneFile, k: usize) -> Result<voxcollide_sim::build::Built, Error> {
    let mut s = scene.clone();
    let mut body = s.bodies[k].clone();
    body.place = None;
    s.bodies = vec![body];
    s.contacts.clear();
    s.world.gravity = None;
    build_world(&s)
}

/// See [`alone`].
fn alone_extent(scene: &SceneFile, k: usize) -> Result<(f64, f64), Error> {
    let built = alone(scene, k)?;
    Ok(built.world.bodies[0]
        .pos
        .iter()
        .fold((f64::MAX, f64::MIN), |(l, h), p| (l.min(p.z.into()), h.max(p.z.into()))))
}

/// The candidate's own volume in mL (an implant's as given; any other shape's or mesh's as its
/// shell encloses it at scale 1), and its lowest and highest z at scale 1 (scene units).
fn own_shape(scene: &SceneFile, body: usize, c: &Candidate) -> Result<(f64, f64, f64), Error> {
    let mut s = with_candidate(scene, body, c, None, None);
    s.bodies[body].scale = 1.0;
    s.bodies[body].inflate = None;
    // Its own shape, standing on its base: alone, not yet placed on a patient.
    let built = alone(&s, body)?;
    let shell = &built.world.bodies[0];
    let (lo, hi) =
        shell.pos.iter().fold((f64::MAX, f64::MIN), |(l, h), p| (l.min(p.z.into()), h.max(p.z.into())));
    let volume = match c.geometry {
        Geometry::Shape(Shape::Implant { volume_ml, .. }) => volume_ml,
        _ => shell.enclosed_volume() * scene.metres().powi(3) * 1e6,
    };
    Ok((volume, lo, hi))
}

/// Where a comparison is, for a progress display.
#[derive(Clone, Copy, Debug)]
pub struct Progress<'a> {
    /// The candidate running, from 0.
    pub index: usize,
    /// Candidates in all.
    pub count: usize,
    /// The candidate's name.
    pub name: &'a str,
    /// Its steps done, and planned (the schedule's; settling may run past it).
    pub done: u64,
    /// Steps planned.
    pub planned: u64,
    /// Whether the candidate's run is over (its last call).
    pub finished: bool,
}

/// Runs every candidate of `config`'s catalogue through its scene and writes the report,
/// calling `progress` as steps are done and `note` with what is worth saying.
///
/// # Errors
/// The scene's and catalogue's errors; [`Error::Invalid`] for a `--body` the scene lacks;
/// [`Error::SceneFile`] at the body for one that is not a shell; a candidate that cannot be
/// built, named (`candidate[k] "name": …`) — all before anything is written; then the runs'
/// and the files' errors.
pub fn compare(
    config: &CompareConfig,
    progress: &mut dyn FnMut(Progress<'_>),
    note: &mut dyn FnMut(&str),
) -> Result<Comparison, Error> {
    let scene = SceneFile::read(&config.scene)?;
    let mut catalogue = Catalogue::read(&config.candidates)?;
    let names: Vec<&str> = scene.bodies.iter().map(|b| b.name.as_str()).collect();
    let body = names.iter().position(|n| *n == config.body).ok_or_else(|| Error::Invalid {
        what: "--body",
        value: config.body.clone(),
        rule: format!("names a body of {}: {}", config.scene.display(), names.join(", ")),
    })?;
    if scene.bodies[body].kind != BodyKind::Shell {
        return Err(scene.body_error(
            body,
            "kind",
            "the compared body must be a shell (kind = \"shell\"): it is filled to each candidate's volume",
        ));
    }
    if let Some(place) = scene.bodies[body].place.as_ref().filter(|p| p.contact_added) {
        note(&format!(
            "{:?}: no [[contact]] pairs it with {:?}: the default contact between them added",
            config.body, scene.bodies[place.body].name
        ));
    }
    // The tissue: the soft bodies in contact with the compared one.
    let tissue: Vec<usize> = scene
        .contacts
        .iter()
        .filter_map(|c| match (c.a == body, c.b == body) {
            (true, false) => Some(c.b),
            (false, true) => Some(c.a),
            _ => None,
        })
        .filter(|&k| scene.bodies[k].kind == BodyKind::Soft)
        .collect();
    if tissue.is_empty() {
        return Err(scene.body_error(
            body,
            "name",
            "no soft body is in contact with the compared body: add a [[contact]] with the tissue",
        ));
    }
    // A patient's tissue between her skin and chest wall: candidates are not yet placed on its
    // curved wall (docs/design.md §15), and placed as on a flat one they would be no plan.
    let placed = scene.bodies[body].place.is_some();
    if !placed
        && let Some(&t) =
            tissue.iter().find(|&&t| matches!(scene.bodies[t].geometry, Geometry::Shape(Shape::Between(_))))
    {
        return Err(scene.body_error(
            t,
            "shape.between",
            format!(
                "the compared body {:?} is not placed on this patient's chest wall: give it `place = {{ under = \"{}.<landmark>\" }}` (docs/design.md §15)",
                config.body, scene.bodies[t].name
            ),
        ));
    }

    // Chosen by her breast's base width: the candidates that fit it.
    if let Some(margin) = config.fit_base {
        let (width, between) = base_width(&scene, &tissue)?;
        let all = catalogue.candidates.len();
        catalogue.candidates = fitting(&catalogue.candidates, width, margin);
        let names: Vec<&str> = catalogue.candidates.iter().map(|c| c.name.as_str()).collect();
        if names.is_empty() {
            return Err(Error::Invalid {
                what: "--fit-base",
                value: format!("{margin} mm"),
                rule: format!(
                    "no candidate of {} has a base from {:.0} to {width:.0} mm wide, to fit her breast's base of {width:.0} mm ({between})",
                    config.candidates.display(),
                    width - margin
                ),
            });
        }
        note(&format!(
            "her breast's base is {width:.0} mm wide ({between}): {} of {all} candidates have a base from {:.0} to {width:.0} mm: {}",
            names.len(),
            width - margin,
            names.join(", ")
        ));
    }

    // The lowest tissue vertex at rest (the scene as given, its compared body not filled):
    // each candidate starts flat in the room between its base and that. Placed on a
    // patient's chest wall, the tissue lies on the wall: there is no room.
    // Her unloaded shape is recovered once (the first build), and every later build of her
    // reuses it.
    let recoveries = Recoveries::default();
    let floor_of_tissue = if placed {
        0.0
    } else {
        let mut unfilled = scene.clone();
        unfilled.bodies[body].inflate = None;
        let given = build_world_reusing(&unfilled, &recoveries)?;
        tissue
            .iter()
            .flat_map(|&t| given.world.bodies[t].rest_pos.iter().map(|p| f64::from(p.z)))
            .fold(f64::INFINITY, f64::min)
    };
    let tissue_spacing = tissue.iter().map(|&t| scene.bodies[t].spacing.unwrap_or(1.0)).fold(0.0, f64::max);

    // Every candidate is built first: a bad one is named before anything is written.
    let mut runs = Vec::with_capacity(catalogue.candidates.len());
    for (k, c) in catalogue.candidates.iter().enumerate() {
        let named = |e: Error| Error::Invalid {
            what: "candidate",
            value: format!("candidate[{k}] {:?} of {}", c.name, catalogue.path.display()),
            rule: e.to_string(),
        };
        let (volume, lo, hi) = own_shape(&scene, body, c).map_err(named)?;
        let fit = (floor_of_tissue.is_finite() && hi > lo)
            .then(|| (hi - lo, (floor_of_tissue - lo).max(0.0), tissue_spacing));
        let s = with_candidate(&scene, body, c, Some(volume), fit);
        let built = build_world_reusing(&s, &recoveries).map_err(named)?;
        runs.push((c, volume, s, built));
    }

    // Her unoperated shape in the posture asked for, where the scan was taken in another:
    // each tissue body given as measured under another gravity, settled under the scene's
    // (docs/design.md §15: the operated shape beside the unoperated one, in that posture).
    let unoperated = unoperated_in_posture(&scene, body, &tissue, &recoveries, note)?;

    std::fs::create_dir_all(&config.out).map_err(|e| io(&config.out, e))?;
    let (ctx, _) = crate::backend::context(config.backend, true, note)?;
    let units = scene.units.symbol().to_string();
    let count = runs.len();
    // A software adapter steps on the same cores the CPU backend does, slower (about 7 times
    // for the shipped comparison on lavapipe): there the candidates step on the CPU, one per
    // core, and the adapter only draws.
    let backend = match (config.backend, ctx.as_ref().and_then(|c| c.adapter_info())) {
        (Backend::Auto, Some(info)) if info.device_type == wgpu::DeviceType::Cpu => {
            note(&format!(
                "{} is a software adapter: the candidates step on the CPU, which is faster there, and it draws their pictures (--backend gpu steps on it)",
                info.name
            ));
            Backend::Cpu
        }
        // No adapter: the CPU steps (and there are no pictures).
        (Backend::Auto, None) => Backend::Cpu,
        (b, _) => b,
    };
    let jobs = match config.jobs {
        0 if backend == Backend::Cpu => {
            std::thread::available_parallelism().map_or(1, std::num::NonZero::get).min(count)
        }
        0 => 1,
        n => n.min(count),
    };
    let shared = Shared {
        config,
        backend,
        body,
        tissue: &tissue,
        metres: scene.metres(),
        units: &units,
        ctx: ctx.as_ref(),
        count,
        unoperated: &unoperated,
    };
    let mut results: Vec<Option<Result<CandidateResult, Error>>> = (0..count).map(|_| None).collect();
    if jobs <= 1 {
        let mut renderer = None;
        for (k, run) in runs.into_iter().enumerate() {
            let name = run.0.name.clone();
            let mut step = |done, planned| {
                progress(Progress { index: k, count, name: &name, done, planned, finished: false });
            };
            let result = run_candidate(&shared, k, run, &mut renderer, &mut step, note)?;
            let steps = result.steps;
            progress(Progress { index: k, count, name: &name, done: steps, planned: steps, finished: true });
            results[k] = Some(Ok(result));
        }
    } else {
        note(&format!("{jobs} candidates at a time"));
        let names: Vec<String> = runs.iter().map(|r| r.0.name.clone()).collect();
        run_concurrently(&shared, runs, jobs, &mut |message| match message {
            Message::Progress(k, done, planned, finished) => {
                progress(Progress { index: k, count, name: &names[k], done, planned, finished });
            }
            Message::Note(line) => note(&line),
            Message::Done(k, result) => results[k] = Some(result),
        });
    }
    let mut comparison = Comparison {
        scene: config.scene.display().to_string(),
        body: config.body.clone(),
        units: units.clone(),
        candidates: Vec::with_capacity(count),
    };
    for result in results {
        match result {
            Some(r) => comparison.candidates.push(r?),
            // A candidate not run because another failed first: that error was returned above.
            None => {
                return Err(Error::Invalid {
                    what: "compare",
                    value: "candidates".into(),
                    rule: "a candidate was not run".into(),
                });
            }
        }
    }
    write_outputs(&comparison, &config.out)?;
    Ok(comparison)
}

/// One candidate's run as it was built: the candidate, its own volume, its scene and world.
type Run<'a> = (&'a Candidate, f64, SceneFile, voxcollide_sim::build::Built);

/// What every candidate's run shares.
struct Shared<'a> {
    config: &'a CompareConfig,
    /// Where the candidates step.
    backend: Backend,
    body: usize,
    tissue: &'a [usize],
    metres: f64,
    units: &'a str,
    ctx: Option<&'a voxcollide::GpuContext>,
    count: usize,
    /// Per body: her unoperated shape in the scene's posture, where that is not her scan's
    /// ([`unoperated_in_posture`]).
    unoperated: &'a [Option<Vec<Vec3>>],
}

/// What a worker of [`run_concurrently`] tells the thread that called `compare`.
#[allow(clippy::large_enum_variant)] // (a few messages per candidate: not worth a box)
enum Message {
    Progress(usize, u64, u64, bool),
    Note(String),
    Done(usize, Result<CandidateResult, Error>),
}

/// Runs `runs` on `jobs` threads, each taking the next candidate when it is free, and passes
/// their messages to `on` on this thread as they come. On the CPU backend each worker steps on
/// one thread of its own: the candidates are the parallelism, not each small world's step. A
/// failed candidate stops the others from starting new ones.
fn run_concurrently(shared: &Shared<'_>, runs: Vec<Run<'_>>, jobs: usize, on: &mut dyn FnMut(Message)) {
    use std::sync::atomic::{AtomicBool, Ordering};
    let queue = std::sync::Mutex::new(runs.into_iter().enumerate());
    let failed = AtomicBool::new(false);
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::scope(|scope| {
        for _ in 0..jobs {
            let tx = tx.clone();
            let (queue, failed) = (&queue, &failed);
            scope.spawn(move || {
                let pool = (shared.backend == Backend::Cpu)
                    .then(|| rayon::ThreadPoolBuilder::new().num_threads(1).build().ok())
                    .flatten();
                let mut renderer = None;
                while !failed.load(Ordering::SeqCst) {
                    let Some((k, run)) = queue.lock().ok().and_then(|mut q| q.next()) else { break };
                    let work = || {
                        let mut step = |done, planned| {
                            let _ = tx.send(Message::Progress(k, done, planned, false));
                        };
                        let mut note = |line: &str| {
                            let _ = tx.send(Message::Note(line.to_string()));
                        };
                        run_candidate(shared, k, run, &mut renderer, &mut step, &mut note)
                    };
                    let result = match &pool {
                        Some(pool) => pool.install(work),
                        None => work(),
                    };
                    if let Ok(r) = &result {
                        let _ = tx.send(Message::Progress(k, r.steps, r.steps, true));
                    } else {
                        failed.store(true, Ordering::SeqCst);
                    }
                    let _ = tx.send(Message::Done(k, result));
                }
            });
        }
        drop(tx);
        for message in rx {
            on(message);
        }
    });
}

/// Runs candidate `k` through its scene and measures it, drawing its pictures with `renderer`
/// (made on the shared adapter the first time it is needed).
fn run_candidate(
    shared: &Shared<'_>,
    k: usize,
    (c, volume, mut s, built): Run<'_>,
    renderer: &mut Option<Renderer>,
    progress: &mut dyn FnMut(u64, u64),
    note: &mut dyn FnMut(&str),
) -> Result<CandidateResult, Error> {
    let Shared { config, backend, body, tissue, metres, units, ctx, count, unoperated } = *shared;
    // Frames for the metrics over time; compare draws its own pictures, and writes no
    // ParaView frames (as many as the history's).
    s.output.frames = s.output.frames.max(HISTORY_FRAMES);
    s.output.images = false;
    s.output.vtk = false;
    note(&format!("candidate {}/{count}: {} ({volume:.0} mL)", k + 1, c.name));
    if renderer.is_none()
        && let Some(ctx) = ctx
    {
        *renderer = Some(Renderer::new(ctx, config.image.0, config.image.1)?);
    }
    let folder = c.folder();
    let run_config = FileRunConfig {
        path: config.scene.clone(),
        backend,
        out: config.out.join(&folder),
        image: config.image,
    };
    let mut result = CandidateResult {
        name: c.name.clone(),
        manufacturer: c.manufacturer.clone(),
        line: c.line.clone(),
        target_volume_ml: volume,
        folder: folder.clone(),
        ..CandidateResult::default()
    };
    // On the comparison's one device (opened once, by `compare`) where the candidate steps
    // there; a candidate on the CPU draws nothing itself (compare draws its pictures).
    let (run_ctx, without) = match backend {
        Backend::Cpu => (None, "no adapter used: --backend cpu, no pictures"),
        _ => (ctx, "no adapter"),
    };
    // Measured at the last frame; said after the run, with the rest of its warnings.
    let mut wide = None;
    let ran = run_scene_on(
        run_ctx,
        without,
        &s,
        built,
        &run_config,
        progress,
        &mut |_| {},
        &mut |world, reports, at| {
            result.history.push(sample(world, reports, body, tissue, metres, at.time, Lift::of(world, body)));
            if at.last {
                measure_end(world, reports, body, tissue, metres, &mut result);
                wide = wider_than_tissue(world, body, tissue, units);
                // The pressure of the last step's inputs; internal stress units are pascals times
                // the file's metres per unit.
                let inputs = world.inputs(at.step.saturating_sub(1))?;
                result.implant_pressure_kpa =
                    f64::from(world.bodies[body].pressure(&inputs[body])) / (1e3 * metres);
                if let Some(r) = renderer.as_mut() {
                    let at = Shown { out: &config.out, folder: &folder, units, up: s.world.up, unoperated };
                    result.pictures = pictures(r, world, body, tissue, &at)?;
                }
            }
            Ok(())
        },
    );
    let summary = match ran {
        Ok(summary) => summary,
        // A candidate whose run blew up failed, and the others still run: its error is about
        // this implant in this patient, not about the comparison.
        Err(Error::Simulation { step, message }) => return Ok(blown_up(result, step, &message)),
        Err(e) => return Err(e),
    };
    result.volume_ml = summary.bodies[body].volume_ml.unwrap_or(0.0);
    result.placed.clone_from(&summary.bodies[body].placed);
    result.landmarks.clone_from(&summary.landmarks);
    result.landmark_distances = distances(&result.landmarks);
    result.volume_gain_ml = tissue
        .iter()
        .filter_map(|&t| Some(summary.bodies[t].volume_ml_end? - summary.bodies[t].volume_ml?))
        .reduce(|a, b| a + b);
    result.tissue_poisson = result
        .volume_gain_ml
        .and_then(|_| tissue.iter().map(|&t| s.bodies[t].material.model_poisson()).reduce(f64::min));
    result.max_tissue_displacement =
        tissue.iter().map(|&t| summary.bodies[t].max_displacement).fold(0.0, f32::max);
    result.max_penetration = summary
        .contacts
        .iter()
        .filter(|c| c.a == config.body || c.b == config.body)
        .map(|c| c.max_penetration)
        .fold(0.0, f32::max);
    result.settled = summary.settled;
    result.held = summary.held;
    result.failure = summary
        .contacts
        .iter()
        .filter_map(|c| c.failure.as_ref().map(|f| format!("contact {} – {}: {f}", c.a, c.b)))
        .reduce(|a, b| format!("{a}; {b}"));
    result.steps = summary.steps;
    result.unfinished = unfinished(&result);
    // What the run itself found makes it no result either (an unloaded shape not recovered, a
    // shell through itself).
    let found: Vec<&str> = summary
        .not_a_result
        .iter()
        .map(String::as_str)
        // (What `compare` says itself, the run says of its body: once is enough.)
        .filter(|f| {
            let what = f.split_once(": ").map_or(*f, |(_, what)| what);
            !result.unfinished.as_deref().is_some_and(|u| u.contains(what))
        })
        .collect();
    if !found.is_empty() {
        let found = found.join("; ");
        result.unfinished = Some(result.unfinished.map_or(found.clone(), |u| format!("{u}; {found}")));
    }
    result.finished = result.unfinished.is_none();
    result.warning =
        [untouched(&result, units), wide].into_iter().flatten().reduce(|a, b| format!("{a}; {b}"));
    Ok(result)
}

/// `result` as the candidate whose run blew up at `step`, `message` saying what blew up:
/// failed and unfinished, with nothing measured and no pictures (not even its metrics over
/// time: the frames before a blow-up already show it going).
fn blown_up(result: CandidateResult, step: u64, message: &str) -> CandidateResult {
    CandidateResult {
        name: result.name,
        manufacturer: result.manufacturer,
        line: result.line,
        target_volume_ml: result.target_volume_ml,
        folder: result.folder,
        held: false,
        failure: Some(format!("its run blew up at step {step}: {message}")),
        finished: false,
        unfinished: Some(format!("its run stopped at step {step}, where it blew up")),
        steps: step,
        blew_up_at_step: Some(step),
        ..CandidateResult::default()
    }
}

/// How far from its own volume a candidate's shell may end, relative, and still be finished.
pub const VOLUME_TOLERANCE: f64 = 0.02;

/// On a patient, how far the volume added between her skin and chest wall may be from the
/// implant's, relative, for the operated shape to be an answer.
pub const GAIN_TOLERANCE: f64 = 0.05;

/// The Poisson's ratio from which a patient's tissue is taken for incompressible, and the
/// volume a plan adds between her skin and chest wall is held to the implant's: breast models
/// take 0.49 (docs/patient.md, "Tissue presets"). Softer in bulk, tissue squeezed by an
/// implant gives up some of its own volume: on the paper's springs (ν = 1/4), a 40 mL implant
/// at 30 kPa under a 30 mm flat breast added 36.1 mL.
pub const INCOMPRESSIBLE_POISSON: f64 = 0.49;

/// Why a candidate's run is not finished, if it is not: its shell short of (or past) its own
/// volume by more than [`VOLUME_TOLERANCE`], the scene not at rest when `max_steps` ran out, or
/// on a patient the volume added not the implant's within [`GAIN_TOLERANCE`].
#[must_use]
pub fn unfinished(r: &CandidateResult) -> Option<String> {
    let mut why = Vec::new();
    // (A NaN volume is off too.)
    let within = (r.volume_ml - r.target_volume_ml).abs() <= VOLUME_TOLERANCE * r.target_volume_ml;
    if !within {
        why.push(format!(
            "the implant holds {:.1} mL of its {:.1} mL (more than {:.0} % off)",
            r.volume_ml,
            r.target_volume_ml,
            100.0 * VOLUME_TOLERANCE
        ));
    }
    if !r.settled {
        why.push(format!("the scene had not come to rest after {} steps ([time] max_steps)", r.steps));
    }
    // On a patient: what the operation added between her skin and chest wall is the implant,
    // or the breast did not follow it (a space left open, or tissue stretched or squeezed).
    if let (Some(gain), Some(nu)) = (r.volume_gain_ml, r.tissue_poisson) {
        why.extend(gain_off(gain, r.volume_ml, nu));
    }
    (!why.is_empty()).then(|| why.join("; "))
}

/// Why a plan that added `gain` mL between her skin and chest wall around an implant of
/// `implant` mL is not an answer, if it is not: in tissue of Poisson's ratio `tissue_poisson`
/// at [`INCOMPRESSIBLE_POISSON`] or more, the two more than [`GAIN_TOLERANCE`] apart (or either
/// not a number). `run` and `compare` say it alike.
#[must_use]
pub fn gain_off(gain: f64, implant: f64, tissue_poisson: f64) -> Option<String> {
    if tissue_poisson < INCOMPRESSIBLE_POISSON || (gain - implant).abs() <= GAIN_TOLERANCE * implant {
        return None;
    }
    Some(format!(
        "the volume added between her skin and chest wall, {gain:.1} mL, is not the implant's {implant:.1} mL to {:.0} % (docs/patient.md, \"Planning\")",
        100.0 * GAIN_TOLERANCE
    ))
}

/// A warning for a candidate that does not touch the tissue at the end (no tissue surface
/// vertex within half a voxel of it, [`CandidateResult::contact_area`] 0, and no contact force
/// on the tissue at the last step): the gap it was
/// placed under is wider than it stands, and its lift (0 without gravity) says nothing of it.
/// A failed or blown-up run says its own reason instead.
#[must_use]
pub fn untouched(r: &CandidateResult, units: &str) -> Option<String> {
    (r.held && r.blew_up_at_step.is_none() && r.contact_area == 0.0 && r.peak_contact_pressure_kpa == 0.0)
        .then(|| {
        format!(
            "it does not touch the tissue at the end, so the tissue's shape is none of its doing (a lift of {:.2} {units}): it stands lower than the gap it was placed under",
            r.apex_lift
        )
    })
}

/// A warning for an implant on a flat chest wall (no curved wall) whose base reaches past the
/// tissue over it, across the wall, at the end: the tissue's edge, held or not, then shapes
/// the answer along with the implant. (On a curved wall, placement
/// refuses an implant that does not fit inside the patient's box: docs/patient.md.)
fn wider_than_tissue(world: &World, body: usize, tissue: &[usize], units: &str) -> Option<String> {
    let implant = &world.bodies[body];
    if implant.wall.is_some() || tissue.is_empty() {
        return None;
    }
    let extent = |points: &mut dyn Iterator<Item = Vec3>| {
        let (lo, hi) = points.fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(p), hi.max(p)));
        (hi - lo).truncate()
    };
    let across = extent(&mut implant.pos.iter().copied());
    let under = extent(&mut tissue.iter().flat_map(|&t| world.bodies[t].pos.iter().copied()));
    (across.x > under.x || across.y > under.y).then(|| {
        format!(
            "its base reaches past the tissue over it ({:.0} × {:.0} {units} across the chest wall, the tissue {:.0} × {:.0} {units}): the tissue's edge, not the implant alone, shapes the answer",
            across.x, across.y, under.x, under.y
        )
    })
}

impl CandidateResult {
    /// Whether its numbers are an answer: every contact held and the run finished.
    #[must_use]
    pub fn is_result(&self) -> bool {
        self.held && self.finished
    }

    /// Why its numbers are not an answer, if they are not: the failed contact's reason and the
    /// unfinished run's, in that order.
    #[must_use]
    pub fn not_a_result(&self) -> Option<String> {
        match (self.held, &self.failure, &self.unfinished) {
            (true, _, None) => None,
            (true, _, Some(u)) => Some(format!("unfinished: {u}")),
            (false, f, u) => Some(
                [Some(f.clone().unwrap_or_else(|| "a contact did not hold".into())), u.clone()]
                    .into_iter()
                    .flatten()
                    .collect::<Vec<_>>()
                    .join("; "),
            ),
        }
    }
}

/// Frames at least, over the schedule, for the metrics over time.
const HISTORY_FRAMES: u32 = 40;

/// Which way "up" is for the measures: the way an implant lifts the tissue (+z over a flat
/// chest wall; the wall's outward normal under a placed one), and the way across it that the
/// profile runs along (+x; the wall's `u`).
#[derive(Clone, Copy, Debug)]
struct Lift {
    dir: Vec3,
    across: Vec3,
}

impl Lift {
    /// The lift of the compared body `body` of `world`.
    fn of(world: &World, body: usize) -> Lift {
        world.bodies[body]
            .wall
            .as_ref()
            .map_or(Lift { dir: Vec3::Z, across: Vec3::X }, |w| Lift { dir: w.normal, across: w.u })
    }
}

/// How far the tissue's outer surface rose at its highest point (along `lift`): the highest of
/// the points its shown surface's triangles use ([`shown_surface`]: a patient's scanned skin,
/// not the lattice vertices under it).
fn apex_lift(world: &World, tissue: &[usize], lift: Lift) -> f32 {
    tissue
        .iter()
        .map(|&t| {
            let b = &world.bodies[t];
            let (now, mesh) = shown_surface(b);
            let used = used_points(&mesh.triangles);
            let top = |p: &[Vec3]| used.iter().map(|&i| p[i].dot(lift.dir)).fold(f32::MIN, f32::max);
            top(&now) - top(&b.shown_start())
        })
        .fold(f32::MIN, f32::max)
}

/// The points `triangles` use, ascending.
fn used_points(triangles: &[[u32; 3]]) -> Vec<usize> {
    let mut used: Vec<usize> = triangles.iter().flatten().map(|&i| i as usize).collect();
    used.sort_unstable();
    used.dedup();
    used
}

/// The metrics of one frame.
fn sample(
    world: &World,
    reports: &[ContactReport],
    body: usize,
    tissue: &[usize],
    metres: f64,
    time: f64,
    lift: Lift,
) -> Sample {
    let moved = |t: usize| {
        let b = &world.bodies[t];
        b.pos.iter().zip(b.start()).map(|(p, r)| p.distance(*r))
    };
    Sample {
        time,
        apex_lift: apex_lift(world, tissue, lift),
        volume_ml: world.bodies[body].enclosed_volume() * metres.powi(3) * 1e6,
        max_tissue_displacement: tissue.iter().flat_map(|&t| moved(t)).fold(0.0, f32::max),
        contacts: world
            .contacts
            .iter()
            .zip(reports)
            .filter(|(p, _)| (p.a == body && tissue.contains(&p.b)) || (p.b == body && tissue.contains(&p.a)))
            .map(|(_, r)| r.colliding_b.len())
            .sum(),
    }
}

/// The tissue's outer surface ([`outer`]) along the line through its highest point parallel
/// to `lift.across` (x over a flat wall): `[x − centre.x, rise]` in x order.
fn profile(world: &World, tissue: &[usize], centre: Vec3, lift: Lift) -> Vec<[f32; 2]> {
    let third = lift.dir.cross(lift.across);
    let mut points = Vec::new();
    for &t in tissue {
        let b = &world.bodies[t];
        let h = mean_spring(b);
        let s = ShownTissue::of(b);
        let on_top = used_points(&outer(&s, lift));
        let Some(&apex) =
            on_top.iter().max_by(|&&i, &&j| s.now[i].dot(lift.dir).total_cmp(&s.now[j].dot(lift.dir)))
        else {
            continue;
        };
        let y = s.rest[apex].dot(third);
        points.extend(
            on_top
                .iter()
                .filter(|&&i| (s.rest[i].dot(third) - y).abs() <= 0.5 * h)
                .map(|&i| [(s.rest[i] - centre).dot(lift.across), (s.now[i] - s.start[i]).dot(lift.dir)]),
        );
    }
    points.sort_by(|a, b| a[0].total_cmp(&b[0]));
    points
}

/// A tissue body's surface as it is shown ([`shown_surface`]: a patient's scanned skin beside
/// her lattice's other faces, a surface the lattice carries, or its own), at rest, where it
/// started and now.
struct ShownTissue<'a> {
    rest: std::borrow::Cow<'a, [Vec3]>,
    start: std::borrow::Cow<'a, [Vec3]>,
    now: std::borrow::Cow<'a, [Vec3]>,
    mesh: &'a voxcollide_sim::mesh::TriangleMesh,
}

impl<'a> ShownTissue<'a> {
    fn of(b: &'a MassSpring) -> ShownTissue<'a> {
        let (now, mesh) = shown_surface(b);
        ShownTissue { rest: b.shown_at(&b.rest_pos).0, start: b.shown_start(), now, mesh }
    }
}

/// A tissue body's outer surface: its shown surface's triangles that face up at rest (their
/// normal within 60° of `lift`), the skin over a chest-wall pocket whatever the tissue's shape.
fn outer(s: &ShownTissue<'_>, lift: Lift) -> Vec<[u32; 3]> {
    s.mesh
        .triangles
        .iter()
        .copied()
        .filter(|t| {
            let [p, q, r] = t.map(|i| s.rest[i as usize]);
            let n = (q - p).cross(r - p);
            n.dot(lift.dir) > 0.5 * n.length()
        })
        .collect()
}

/// The area (at rest) of the tissue's outer surface that rose more than half of `lift`: its
/// outer triangles whose three corners did.
fn footprint(world: &World, tissue: &[usize], rise: f32, lift: Lift) -> f64 {
    let mut area = 0.0;
    for &t in tissue {
        let s = ShownTissue::of(&world.bodies[t]);
        let rose = |i: u32| (s.now[i as usize] - s.start[i as usize]).dot(lift.dir) > 0.5 * rise;
        for tri in outer(&s, lift).iter().filter(|tri| tri.iter().all(|&i| rose(i))) {
            let [p, q, r] = tri.map(|i| s.rest[i as usize].as_dvec3());
            area += 0.5 * (q - p).cross(r - p).length();
        }
    }
    area
}

/// The end-of-run measurements that need the world: the apex lift, the tissue's mean
/// displacement, strain and profile, the contact area and pressures, and the footprint.
fn measure_end(
    world: &World,
    reports: &[ContactReport],
    body: usize,
    tissue: &[usize],
    metres: f64,
    out: &mut CandidateResult,
) {
    let lift = Lift::of(world, body);
    out.apex_lift = apex_lift(world, tissue, lift);
    let (mut moved, mut vertices) = (0.0f64, 0usize);
    let mut strain = 0.0f32;
    for &t in tissue {
        let b = &world.bodies[t];
        moved += b.pos.iter().zip(b.start()).map(|(p, r)| f64::from(p.distance(*r))).sum::<f64>();
        vertices += b.len();
        for s in &b.springs {
            let length = b.pos[s.i as usize].distance(b.pos[s.j as usize]);
            strain = strain.max((length / s.rest - 1.0).abs());
        }
    }
    out.mean_tissue_displacement = if vertices > 0 { (moved / vertices as f64) as f32 } else { 0.0 };
    out.max_tissue_strain = strain;
    let centre = {
        let p = &world.bodies[body].pos;
        p.iter().copied().sum::<Vec3>() / p.len().max(1) as f32
    };
    out.profile = profile(world, tissue, centre, lift);
    let (mut peak, mut total, mut area) = (0.0f64, 0.0f64, 0.0f64);
    out.voxel_size = world
        .contacts
        .iter()
        .filter(|p| p.a == body || p.b == body)
        .map(|p| p.grid.voxel_size())
        .fold(0.0, f32::max);
    // The contact area, from the geometry.
    let (shell_positions, shell_mesh) = shown_surface(&world.bodies[body]);
    if let Ok(surface) = ClosedSurface::new(&shell_positions, shell_mesh) {
        let voxel = out.voxel_size;
        for &t in tissue {
            let b = &world.bodies[t];
            let h = f64::from(mean_spring(b));
            let mut on_surface = vec![false; b.len()];
            b.surface.triangles.iter().flatten().for_each(|&i| on_surface[i as usize] = true);
            let touching = b
                .pos
                .iter()
                .zip(&on_surface)
                .filter(|(p, on)| **on && (surface.distance(**p) <= 0.5 * voxel || surface.contains(**p)))
                .count();
            area += touching as f64 * h * h;
        }
    }
    out.contact_area = area;
    // The footprint; no lift, no footprint (what rose would be noise).
    out.footprint_area =
        if out.apex_lift <= 0.0 { 0.0 } else { footprint(world, tissue, out.apex_lift, lift) };
    for (pair, r) in world.contacts.iter().zip(reports) {
        // The tissue's side of a contact with the compared body.
        let (t, forces) = if pair.a == body && tissue.contains(&pair.b) {
            (pair.b, &r.force_b)
        } else if pair.b == body && tissue.contains(&pair.a) {
            (pair.a, &r.force_a)
        } else {
            continue;
        };
        let h = f64::from(mean_spring(&world.bodies[t]));
        let vertex_area = h * h;
        for f in forces.iter().filter(|f| **f != Vec3::ZERO) {
            // Internal force units are `metres` newtons; an area of h² scene units is
            // h² · metres² m².
            let newtons = f64::from(f.length()) * metres;
            let kpa = newtons / (vertex_area * metres * metres) / 1e3;
            peak = peak.max(kpa);
            total += newtons;
        }
    }
    out.peak_contact_pressure_kpa = peak;
    out.mean_contact_pressure_kpa = if area > 0.0 { total / (area * metres * metres) / 1e3 } else { 0.0 };
}

/// The candidate's resting shape from the front (looking along +y where z is up) and the side
/// (along +x), `up` drawn upward ([`axes`]), cut open through the compared body's centre, the
/// tissue coloured by displacement on one scale for every candidate (a tenth of the tissue's
/// extent); returns the files written.
///
/// On a patient (an implant placed on her chest wall, docs/design.md §15) the front shows her
/// skin whole, as she would be seen, and the side is cut through the implant (her profile);
/// each beside the same view of her unoperated, as scanned (`before-front.png`,
/// `before-side.png`), on one scale.
fn pictures(
    renderer: &mut Renderer,
    world: &World,
    body: usize,
    tissue: &[usize],
    at: &Shown<'_>,
) -> Result<Vec<String>, Error> {
    let Shown { out, folder, units, up, unoperated } = *at;
    let [side, forward, up] = axes(up);
    let shown = shown_and_moved(world);
    let extent = tissue
        .iter()
        .flat_map(|&t| world.bodies[t].rest_pos.iter())
        .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let range = (0.0, 0.1 * (extent.1 - extent.0).max_element());
    let centre = {
        let p = &world.bodies[body].pos;
        p.iter().copied().sum::<Vec3>() / p.len().max(1) as f32
    };
    let patient = world.bodies[body].wall.is_some();
    // Her unoperated shape: the tissue as scanned, or settled in the posture asked for where
    // the scan was taken in another; no implant.
    let before: Vec<(Vec<Vec3>, Vec<f32>)> = world
        .bodies
        .iter()
        .enumerate()
        .map(|(k, b)| {
            let start = match unoperated.get(k).and_then(Option::as_ref) {
                Some(settled) => {
                    let mut posed = b.clone();
                    posed.pos.clone_from(settled);
                    shown_surface(&posed).0.into_owned()
                }
                None => b.shown_start().into_owned(),
            };
            let n = if k == body { 0 } else { start.len() };
            (start, vec![0.0; n])
        })
        .collect();
    // (name, looking along, cut open, unoperated)
    let views: Vec<(&str, Vec3, bool, bool)> = if patient {
        vec![
            ("front", forward, false, false),
            ("before-front", forward, false, true),
            ("side", side, true, false),
            ("before-side", side, true, true),
        ]
    } else {
        vec![("front", forward, true, false), ("side", side, true, false)]
    };
    let mut files = Vec::new();
    // From a little above, so the tissue's surface shows its colours beside the cut.
    for (view, across, cut, unoperated) in views {
        let dir = across - 0.35 * up;
        let positions = if unoperated { &before } else { &shown };
        let mut meshes = meshes(
            world,
            positions,
            |k| tissue.contains(&k),
            |k| if k == body { [0.95, 0.6, 0.25] } else { [0.6, 0.6, 0.65] },
        );
        if unoperated {
            meshes.remove(body);
        }
        let scene = RenderScene {
            meshes,
            scalar_range: range,
            clip: cut.then_some((centre, across)),
            view_dir: dir,
            up,
        };
        let name = format!("{folder}/{view}.png");
        let legend =
            Legend::new(format!("tissue displacement ({units})"), range).above(scene.largest_scalar());
        renderer.render_png_with_legend(&scene, Some(&legend), &out.join(&name))?;
        files.push(name);
    }
    Ok(files)
}

/// Where a candidate's pictures go and how they are drawn.
#[derive(Clone, Copy)]
struct Shown<'a> {
    out: &'a Path,
    folder: &'a str,
    units: &'a str,
    up: Axis,
    /// Per body: her unoperated shape in the posture, where it is not her scan.
    unoperated: &'a [Option<Vec<Vec3>>],
}

/// Per body of `scene`: for a tissue body given as measured under another gravity than the
/// scene's (`reference = { gravity }` not `[world] gravity`), its unoperated shape in the
/// scene's posture: the body as built without the compared one, settled under the scene's
/// gravity ([`voxcollide_sim::reference::settle`]). `None` elsewhere: there her scan is her
/// unoperated shape.
fn unoperated_in_posture(
    scene: &SceneFile,
    body: usize,
    tissue: &[usize],
    recoveries: &Recoveries,
    note: &mut dyn FnMut(&str),
) -> Result<Vec<Option<Vec<Vec3>>>, Error> {
    let mut out = vec![None; scene.bodies.len()];
    let gravity = scene.world.gravity.unwrap_or([0.0; 3]);
    let posed: Vec<usize> =
        tissue.iter().copied().filter(|&t| scene.bodies[t].reference.is_some_and(|g| g != gravity)).collect();
    if posed.is_empty() {
        return Ok(out);
    }
    // Without the implant: not placed, so no pocket is let go.
    let mut s = scene.clone();
    s.bodies[body].place = None;
    s.bodies[body].inflate = None;
    s.contacts.retain(|c| c.a != body && c.b != body);
    let built = build_world_reusing(&s, recoveries)?;
    let g = voxcollide_sim::build::gravity(&s);
    for t in posed {
        let mut b = built.world.bodies[t].clone();
        let steps = voxcollide_sim::reference::settle(&mut b, g)?;
        note(&format!(
            "{}: her unoperated shape in this posture, settled from her scan in {steps} steps (the pictures' \"unoperated\")",
            scene.bodies[t].name
        ));
        out[t] = Some(b.pos);
    }
    Ok(out)
}

/// `compare.json`, `compare.csv` and `report.html` in `out`.
fn write_outputs(comparison: &Comparison, out: &Path) -> Result<(), Error> {
    let path = out.join("compare.json");
    let json = serde_json::to_string_pretty(comparison).map_err(|e| io(&path, e))?;
    std::fs::write(&path, json + "\n").map_err(|e| io(&path, e))?;

    let path = out.join("compare.csv");
    let mut csv = csv::Writer::from_path(&path).map_err(|e| io(&path, e))?;
    let u = &comparison.units;
    csv.write_record([
        "name".to_string(),
        "volume_ml".into(),
        format!("apex_lift_{u}"),
        format!("max_tissue_displacement_{u}"),
        format!("mean_tissue_displacement_{u}"),
        "max_tissue_strain".into(),
        "implant_pressure_kpa".into(),
        "peak_contact_pressure_kpa".into(),
        "mean_contact_pressure_kpa".into(),
        format!("contact_area_{u}2"),
        format!("max_penetration_{u}"),
        format!("footprint_area_{u}2"),
        "settled".into(),
        "steps".into(),
        "held".into(),
        "failure".into(),
        "finished".into(),
        "unfinished".into(),
        "volume_gain_ml".into(),
    ])
    .map_err(|e| io(&path, e))?;
    for c in &comparison.candidates {
        // A run that blew up measured nothing: its measures' cells are empty, not zero.
        let m = |cell: String| if c.blew_up_at_step.is_none() { cell } else { String::new() };
        csv.write_record([
            c.name.clone(),
            m(format!("{:.1}", c.volume_ml)),
            m(format!("{:.3}", c.apex_lift)),
            m(format!("{:.3}", c.max_tissue_displacement)),
            m(format!("{:.3}", c.mean_tissue_displacement)),
            m(format!("{:.4}", c.max_tissue_strain)),
            m(format!("{:.3}", c.implant_pressure_kpa)),
            m(format!("{:.3}", c.peak_contact_pressure_kpa)),
            m(format!("{:.3}", c.mean_contact_pressure_kpa)),
            m(format!("{:.1}", c.contact_area)),
            m(format!("{:.3}", c.max_penetration)),
            m(format!("{:.1}", c.footprint_area)),
            c.settled.to_string(),
            c.steps.to_string(),
            c.held.to_string(),
            c.failure.clone().unwrap_or_default(),
            c.finished.to_string(),
            c.unfinished.clone().unwrap_or_default(),
            c.volume_gain_ml.map_or_else(String::new, |g| format!("{g:.1}")),
        ])
        .map_err(|e| io(&path, e))?;
    }
    csv.flush().map_err(|e| io(&path, e))?;

    let path = out.join("report.html");
    let html = report_html(comparison, out)?;
    std::fs::write(&path, html).map_err(|e| io(&path, e))
}

/// The report's charts, inline SVG in `<figure>`s: the outer surface's profile through the
/// apex, one curve per candidate, and the metrics over time.
fn plots(comparison: &Comparison) -> Result<String, Error> {
    let u = &comparison.units;
    let each = |f: &dyn Fn(&CandidateResult) -> Vec<(f64, f64)>| -> Vec<Series> {
        comparison
            .candidates
            .iter()
            .map(|c| Series {
                label: if !c.held {
                    format!("{} (FAILED, not a result)", c.name)
                } else if !c.finished {
                    format!("{} (UNFINISHED, not a result)", c.name)
                } else {
                    c.name.clone()
                },
                points: f(c),
            })
            .collect()
    };
    let over_time = |f: fn(&Sample) -> f64| {
        each(&|c: &CandidateResult| c.history.iter().map(|s| (s.time, f(s))).collect())
    };
    let profile =
        each(&|c: &CandidateResult| c.profile.iter().map(|p| (f64::from(p[0]), f64::from(p[1]))).collect());
    let charts = [
        (
            "profile",
            if comparison.candidates.iter().all(|c| c.finished) {
                "The outer surface through the apex, at rest"
            } else {
                "The outer surface through the apex, at the end of each run (not all at rest)"
            },
            format!("x from the implant's centre ({u})"),
            format!("rise of the surface ({u})"),
            profile,
        ),
        (
            "lift",
            "Apex lift over time",
            "time (s)".into(),
            format!("apex lift ({u})"),
            over_time(|s| f64::from(s.apex_lift)),
        ),
        (
            "volume",
            "Implant volume over time",
            "time (s)".into(),
            "volume (mL)".into(),
            over_time(|s| s.volume_ml),
        ),
        (
            "displacement",
            "Max tissue displacement over time",
            "time (s)".into(),
            format!("max tissue displacement ({u})"),
            over_time(|s| f64::from(s.max_tissue_displacement)),
        ),
    ];
    let mut html = String::new();
    for (id, title, x, y, series) in &charts {
        // The profile peaks in the middle; the metrics over time rise to the upper right.
        let legend =
            if *id == "profile" { SeriesLabelPosition::UpperRight } else { SeriesLabelPosition::LowerRight };
        let svg = line_chart_svg(&Chart { title, x, y, series, legend }, 640, 400)?;
        // Inline in HTML the parser puts <svg> in its namespace: the page names no URL at all.
        let svg = svg.replacen(" xmlns=\"http://www.w3.org/2000/svg\"", "", 1);
        html += &format!("<figure class=\"plot\" id=\"plot-{id}\">{svg}</figure>\n");
    }
    Ok(html)
}

/// `items` without repeats, in the order first seen.
fn first_seen<T: PartialEq>(items: impl Iterator<Item = T>) -> Vec<T> {
    let mut out = Vec::new();
    for m in items {
        if !out.contains(&m) {
            out.push(m);
        }
    }
    out
}

/// `s` with `&`, `<`, `>` and `"` escaped for HTML.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The report: one self-contained page (pictures as data URIs, no script, no link) with the
/// table of measurements and each candidate's resting shape from the front and the side.
fn report_html(comparison: &Comparison, out: &Path) -> Result<String, Error> {
    let u = escape(&comparison.units);
    let mut rows = String::new();
    for c in &comparison.candidates {
        if !c.held {
            rows += &format!(
                "<tr class=\"failed\"><th scope=\"row\">{}</th><td colspan=\"13\"><strong>FAILED — not a result.</strong> {}</td></tr>\n",
                escape(&c.name),
                escape(c.failure.as_deref().unwrap_or("a contact did not hold"))
            );
            continue;
        }
        rows += &format!(
            "<tr><th scope=\"row\">{}</th><td>{:.1}</td><td>{:.2}</td><td>{:.2}</td><td>{:.2}</td><td>{:.1} %</td><td>{:.2}</td><td>{:.2}</td><td>{:.2}</td><td>{:.0}</td><td>{:.2}</td><td>{:.0}</td><td>{}</td><td>{}</td></tr>\n",
            escape(&c.name),
            c.volume_ml,
            c.apex_lift,
            c.max_tissue_displacement,
            c.mean_tissue_displacement,
            100.0 * c.max_tissue_strain,
            c.implant_pressure_kpa,
            c.peak_contact_pressure_kpa,
            c.mean_contact_pressure_kpa,
            c.contact_area,
            c.max_penetration,
            c.footprint_area,
            if c.settled { "yes" } else { "no (max_steps)" },
            "yes"
        );
        if let Some(why) = &c.unfinished {
            rows += &format!(
                "<tr class=\"unfinished\"><td colspan=\"14\"><strong>UNFINISHED — {} is not a result:</strong> {}.</td></tr>\n",
                escape(&c.name),
                escape(why)
            );
        }
        if let Some(why) = &c.warning {
            rows += &format!(
                "<tr class=\"warning\"><td colspan=\"14\"><strong>Warning — {}:</strong> {}.</td></tr>\n",
                escape(&c.name),
                escape(why)
            );
        }
    }
    // On a patient: what the operation added between her skin and chest wall, and where it
    // carried her landmarks (docs/design.md §15).
    let mut patient = String::new();
    if comparison.candidates.iter().any(|c| c.volume_gain_ml.is_some() || !c.landmarks.is_empty()) {
        let marks = first_seen(
            comparison
                .candidates
                .iter()
                .flat_map(|c| c.landmarks.iter().map(|l| (l.body.clone(), l.name.clone()))),
        );
        let placed = comparison.candidates.iter().any(|c| c.placed.is_some());
        patient += "<h2>On the patient</h2>\n<table id=\"patient\">\n<thead><tr><th>candidate</th><th>volume added (mL)</th><th>added / implant</th>";
        if placed {
            patient += &format!("<th>base moved from under the landmark ({u})</th>");
        }
        for (body, name) in &marks {
            patient += &format!(
                "<th>{}.{} moved ({u})</th><th>{}.{} at the end ({u})</th>",
                escape(body),
                escape(name),
                escape(body),
                escape(name)
            );
        }
        patient += "</tr></thead>\n<tbody>\n";
        for c in &comparison.candidates {
            let valid = if c.is_result() { "" } else { " class=\"unfinished\"" };
            patient += &format!("<tr{valid}><th scope=\"row\">{}</th>", escape(&c.name));
            match c.volume_gain_ml {
                Some(g) if c.target_volume_ml > 0.0 => {
                    let mark =
                        if c.tissue_poisson.is_some_and(|nu| nu < INCOMPRESSIBLE_POISSON) { "*" } else { "" };
                    patient += &format!(
                        "<td>{g:.1}{mark}</td><td>{:.1} %{mark}</td>",
                        100.0 * g / c.target_volume_ml
                    );
                }
                _ => patient += "<td>–</td><td>–</td>",
            }
            if placed {
                patient += &match &c.placed {
                    Some(p) if p.overreach > 0.0 => format!(
                        "<td>{:.1}, <strong>too wide for her borders by {:.1}</strong></td>",
                        Vec3::from_array(p.moved).length(),
                        p.overreach
                    ),
                    Some(p) => format!("<td>{:.1}</td>", Vec3::from_array(p.moved).length()),
                    None => "<td>–</td>".into(),
                };
            }
            for (body, name) in &marks {
                match c.landmarks.iter().find(|l| &l.body == body && &l.name == name) {
                    Some(l) => {
                        let moved = Vec3::from_array(l.end).distance(Vec3::from_array(l.start));
                        patient += &format!(
                            "<td>{moved:.1}</td><td>{:.1}, {:.1}, {:.1}</td>",
                            l.end[0], l.end[1], l.end[2]
                        );
                    }
                    None => patient += "<td>–</td><td>–</td>",
                }
            }
            patient += "</tr>\n";
        }
        patient += "</tbody></table>\n<p>Volume added: the volume between the skin and the chest wall at the end less at the start. A row not marked as a result (a failed or unfinished run) is where its run stopped.";
        if let Some(nu) = comparison
            .candidates
            .iter()
            .filter_map(|c| c.tissue_poisson)
            .find(|nu| *nu < INCOMPRESSIBLE_POISSON)
        {
            patient += &format!(
                " *&nbsp;Her tissue is compressible in this scene (Poisson's ratio {nu:.2} as its model has it; the paper's springs have 1/4): squeezed by the implant, it gives up some of its own volume, so the volume added is not held to the implant's. Give it <code>model = \"neo-hookean\"</code> at <code>poisson = 0.49</code> (or a tissue <code>preset</code>) for a plan whose volume added is checked."
            );
        }
        if placed {
            patient += " Base moved: how far each base's centre stood across her chest wall from under the landmark it was placed under, to keep its rim within the borders the scene names (<code>place.within</code>); 0 where it stands under the landmark.";
        }
        patient += "</p>\n";
        let pairs = first_seen(
            comparison
                .candidates
                .iter()
                .flat_map(|c| c.landmark_distances.iter().map(|d| (d.a.clone(), d.b.clone()))),
        );
        if !pairs.is_empty() {
            patient += "<table id=\"distances\">\n<thead><tr><th>candidate</th>";
            for (a, b) in &pairs {
                patient += &format!("<th>{} – {} ({u}): before → after</th>", escape(a), escape(b));
            }
            patient += "</tr></thead>\n<tbody>\n";
            for c in &comparison.candidates {
                patient += &format!("<tr><th scope=\"row\">{}</th>", escape(&c.name));
                for (a, b) in &pairs {
                    match c.landmark_distances.iter().find(|d| &d.a == a && &d.b == b) {
                        Some(d) => patient += &format!("<td>{:.1} → {:.1}</td>", d.start, d.end),
                        None => patient += "<td>–</td>",
                    }
                }
                patient += "</tr>\n";
            }
            patient += "</tbody></table>\n";
        }
    }
    let mut figures = String::new();
    for c in &comparison.candidates {
        figures += &format!("<section><h3>{}</h3>\n", escape(&c.name));
        let made: Vec<&str> = [&c.manufacturer, &c.line].into_iter().flatten().map(String::as_str).collect();
        if !made.is_empty() {
            figures += &format!("<p class=\"made\">{}</p>\n", escape(&made.join(", ")));
        }
        if c.blew_up_at_step.is_some() {
            figures += &format!(
                "<p class=\"failed\"><strong>FAILED — not a result:</strong> {}. Its run stopped there: there is no shape to show.</p>\n",
                escape(c.failure.as_deref().unwrap_or("its run blew up"))
            );
        } else if !c.held {
            figures += &format!(
                "<p class=\"failed\"><strong>FAILED — not a result:</strong> {}. Its pictures show where the run went wrong.</p>\n",
                escape(c.failure.as_deref().unwrap_or("a contact did not hold"))
            );
        } else if let Some(why) = &c.unfinished {
            figures += &format!(
                "<p class=\"unfinished\"><strong>UNFINISHED — not a result:</strong> {}. Its pictures show where the run stopped.</p>\n",
                escape(why)
            );
        } else if let Some(why) = &c.warning {
            figures += &format!("<p class=\"warning\"><strong>Warning:</strong> {}.</p>\n", escape(why));
        }
        if c.pictures.is_empty() && c.blew_up_at_step.is_none() {
            figures += "<p>No pictures: no adapter to draw them on.</p>\n";
        }
        for p in &c.pictures {
            let bytes = std::fs::read(out.join(p)).map_err(|e| io(&out.join(p), e))?;
            let data = base64::engine::general_purpose::STANDARD.encode(bytes);
            let view = match p.rsplit('/').next() {
                Some("before-front.png") => "front, unoperated",
                Some("before-side.png") => "side, unoperated",
                Some("front.png") => "front",
                _ => "side",
            };
            figures += &format!(
                "<figure><img alt=\"{} from the {view}\" src=\"data:image/png;base64,{data}\"><figcaption>{view}</figcaption></figure>\n",
                escape(&c.name)
            );
        }
        figures += "</section>\n";
    }
    Ok(format!(
        r#"<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Implant comparison: {scene}</title>
<style>
body {{ font-family: sans-serif; margin: 2em; color: #222; }}
table {{ border-collapse: collapse; font-size: 0.85em; }} th, td {{ border: 1px solid #bbb; padding: 0.25em 0.45em; text-align: right; }}
th[scope=row] {{ text-align: left; }} .failed {{ background: #fdd; color: #900; }} tr.failed td {{ text-align: left; }} .unfinished {{ background: #fec; color: #850; }} tr.unfinished td {{ text-align: left; }} .warning {{ background: #ffd; color: #660; }} tr.warning td {{ text-align: left; }} figure {{ display: inline-block; margin: 0.5em; vertical-align: top; }} img {{ max-width: 480px; }}
</style></head>
<body>
<h1>Implant comparison</h1>
<p>Scene <code>{scene}</code>, compared body <code>{body}</code>: each candidate filled toward its own volume under the tissue, then settled (a candidate that did not get there is marked unfinished). Lengths in {u}.</p>
{failed}{unfinished}<h2>Measurements</h2>
<table id="measurements">
<thead><tr><th>candidate</th><th>volume (mL)</th><th>apex lift ({u})</th><th>max tissue displacement ({u})</th><th>mean tissue displacement ({u})</th><th>max tissue strain</th><th>implant pressure (kPa)</th><th>peak contact pressure (kPa)</th><th>mean contact pressure (kPa)</th><th>contact area ({u}²)</th><th>max penetration ({u})</th><th>footprint ({u}²)</th><th>settled</th><th>held</th></tr></thead>
<tbody>
{rows}</tbody></table>
{patient}<h2>Plots</h2>
{plots}
<h2>Resting shapes</h2>
<p>Cut open through the implant's centre; the tissue coloured by how far it moved, on one scale for every candidate.</p>
{figures}</body></html>
"#,
        scene = escape(&comparison.scene),
        body = escape(&comparison.body),
        plots = plots(comparison)?,
        failed = {
            let failed: Vec<String> =
                comparison.candidates.iter().filter(|c| !c.held).map(|c| escape(&c.name)).collect();
            if failed.is_empty() {
                String::new()
            } else {
                format!(
                    "<p class=\"failed\" id=\"failed\"><strong>{} of {} candidates FAILED</strong> ({}): a contact did not hold or a run blew up, so their numbers are not an answer. Their rows say why.</p>\n",
                    failed.len(),
                    comparison.candidates.len(),
                    failed.join(", ")
                )
            }
        },
        unfinished = {
            let unfinished: Vec<String> = comparison
                .candidates
                .iter()
                .filter(|c| c.held && !c.finished)
                .map(|c| escape(&c.name))
                .collect();
            if unfinished.is_empty() {
                String::new()
            } else {
                format!(
                    "<p class=\"unfinished\" id=\"unfinished\"><strong>{} of {} candidates UNFINISHED</strong> ({}): short of their volume or not at rest when the run ended, so their numbers are not an answer. Their rows say why.</p>\n",
                    unfinished.len(),
                    comparison.candidates.len(),
                    unfinished.join(", ")
                )
            }
        },
    ))
}
