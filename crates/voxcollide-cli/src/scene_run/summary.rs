//! The run's summary part: what `summary.json` says (docs/design.md §8's keys), started from
//! the built world, measured at each frame, completed at the last one, and written.

use std::path::Path;

use serde::Serialize;

use super::rest::{RESIDUAL_TOLERANCE, mean_spring};
use voxcollide::error::Error;
use voxcollide::report::ContactReport;
use voxcollide_sim::between::volume_between;
use voxcollide_sim::build::{BodyNote, Built};
use voxcollide_sim::scene_file::{BodyKind, SceneFile};
use voxcollide_sim::{Integrator, MassSpring, Simulation, World};

/// A body in `summary.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct BodySummary {
    /// Its name in the file.
    pub name: String,
    /// `soft`, `shell` or `rigid`.
    pub kind: String,
    /// Its vertex count.
    pub vertices: usize,
    /// The largest distance of one of its vertices from where it started, over the run (file
    /// units).
    pub max_displacement: f32,
    /// For a shell: the volume it encloses at the end, in cubic file units (the only volume a
    /// scene in layer units has).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume: Option<f64>,
    /// For a shell in a scene of physical units: the volume it encloses at the end, in mL. For
    /// a body between a skin and a chest wall (docs/design.md §14): the tissue's volume at the
    /// start, in mL.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume_ml: Option<f64>,
    /// For a body between a skin and a chest wall: the tissue's volume at the end, in mL.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume_ml_end: Option<f64>,
    /// For a shell: the volume its `volume` counts more than once, in cubic file units (where
    /// its surface passes through itself, [`voxcollide_sim::mesh::Coverage::excess`]); more
    /// than [`SELF_OVERLAP`] of its volume and the run is not a result (`not_a_result`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub self_overlap: Option<f64>,
    /// For a lattice in a surface: the fraction of the surface's volume it covers.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<f64>,
    /// What building it found worth saying.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub remarks: Vec<String>,
    /// What it is made of, as the run used it (a scene file's soft bodies and shells).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub material: Option<MaterialSummary>,
    /// For a body given as measured under gravity (`reference = { gravity }`, docs/design.md
    /// §13): how well its unloaded shape was recovered.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference: Option<ReferenceSummary>,
    /// For a shell placed on a chest wall (docs/design.md §15): where its base stands.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub placed: Option<PlacedSummary>,
}

/// Where a shell placed on a chest wall stands, in `summary.json` and `compare.json` (file
/// units).
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
#[serde(default)]
pub struct PlacedSummary {
    /// Its base's centre, on the wall.
    pub centre: [f32; 3],
    /// The wall's outward normal there, along which its apex points.
    pub normal: [f32; 3],
    /// How far the centre moved from under its landmark to keep the base within the borders
    /// `place.within` names (`[0, 0, 0]` where it stands under the landmark).
    pub moved: [f32; 3],
    /// Where the borders leave the base too little room, how far it still reaches past one
    /// (0 where it fits).
    pub overreach: f32,
}

/// A landmark in `summary.json` and `compare.json` (docs/design.md §14).
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct LandmarkSummary {
    /// Its body's name.
    pub body: String,
    /// Its name.
    pub name: String,
    /// Where it started: as given, moved onto the body's outer surface.
    pub start: [f32; 3],
    /// Where the body carried it by the end.
    pub end: [f32; 3],
}

/// The recovery of a body's unloaded shape in `summary.json` (docs/design.md §13).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ReferenceSummary {
    /// The largest distance, in the file's units, between the shape given and the unloaded
    /// shape loaded again with the reference gravity.
    pub residual: f32,
    /// The fixed-point iterations taken.
    pub iterations: u32,
    /// The body's spacing (its springs' mean rest length), in the file's units.
    pub spacing: f32,
    /// Whether the residual is within a tenth of the spacing; if not, the run is not a result.
    pub valid: bool,
}

/// A body's material in `summary.json` (docs/design.md §12).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MaterialSummary {
    /// `springs` (the paper's lattice) or `neo-hookean` (tetrahedra).
    pub model: String,
    /// Young's modulus, kPa (the body's; a layer's own is in `remarks`).
    pub young_kpa: f64,
    /// The file's Poisson ratio.
    pub poisson: f64,
    /// Whether the body has that ratio: true for tetrahedra; false for springs, whose lattice
    /// has its own (1/4 for a cubic one).
    pub poisson_honoured: bool,
    /// Its tetrahedra (`neo-hookean`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tetrahedra: Option<usize>,
}

/// A contact in `summary.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ContactSummary {
    /// The indexed body's name.
    pub a: String,
    /// The probing body's name.
    pub b: String,
    /// The deepest vertex of `b` inside `a`'s closed surface, over the frames (file units).
    pub max_penetration: f32,
    /// The largest fraction of `b`'s vertices inside `a`'s surface, over the frames.
    pub penetrating_fraction: f32,
    /// `b`'s vertices in contact (the voxel model's count) at the last frame.
    pub contacts_at_end: usize,
    /// The contact's bound (docs/design.md §11): its voxel size. After first contact no vertex of `b`
    /// may be deeper inside `a` than this at any check (file units).
    pub bound: f32,
    /// The bound at rest: half of `b`'s spacing (a settled run's last frame).
    pub rest_bound: f32,
    /// Whether the contact held: within `bound` at every check after first contact, and within
    /// `rest_bound` at rest.
    pub held: bool,
    /// Where it did not hold, the output frame at (or just before) its deepest check beyond
    /// the bound, and that check's step and depth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worst_frame: Option<u32>,
    /// See `worst_frame`: the step of the deepest check.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worst_step: Option<u64>,
    /// See `worst_frame`: its depth (file units).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worst_depth: Option<f32>,
    /// Where it did not hold, a sentence saying how.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
    /// Checks of the penetration made over the run.
    pub checks: u32,
    /// Where one body is an implant placed on the other's chest wall (docs/design.md §15):
    /// the most of its vertices that, at one check, no tissue covered along the wall's normal
    /// (it had come through her skin; the contact did not hold). 0 elsewhere.
    pub uncovered: usize,
}

/// What a scene-file run did, as written to `summary.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FileSummary {
    /// The scene file's name without its extension.
    pub scenario: String,
    /// The file's length unit.
    pub units: String,
    /// `gpu` or `cpu`.
    pub backend: String,
    /// The adapter that ran it, or why there was none.
    pub adapter: String,
    /// Steps run (the schedule's, and the settling ones).
    pub steps: u64,
    /// The time step, in seconds.
    pub dt: f32,
    /// Simulated seconds.
    pub simulated_time: f64,
    /// Steps per second over the run, frames excluded.
    pub steps_per_second: f64,
    /// On the GPU only: how many times, on average, a step waited for the device to hand data
    /// back to the host (a buffer mapped for reading), frames excluded (docs/design.md §5). 0
    /// where a step stays on the device.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub host_waits_per_step: Option<f64>,
    /// Simulated seconds per wall-clock second.
    pub realtime_factor: f64,
    /// Whether the bodies came to rest (`[time] settle`: over a settling window after the
    /// schedule, no vertex that is not held moved more than [`REST_TOLERANCE`](super::REST_TOLERANCE) of its body's
    /// spacing); false without settling.
    pub settled: bool,
    /// The farthest a vertex moved over the last settling window (or, without settling, the
    /// last frame), in spacings of its body: what `settled` is judged by (at rest: at most
    /// [`REST_TOLERANCE`](super::REST_TOLERANCE)).
    pub rest_motion: f32,
    /// `"explicit"` or `"implicit"` (docs/design.md §12).
    pub integrator: String,
    /// The criterion for rest that `settled` was judged by: `"rest_motion"` under the explicit
    /// integrator ([`rest_motion`](Self::rest_motion) within [`REST_TOLERANCE`](super::REST_TOLERANCE) over a settling
    /// window) or `"residual"` under the implicit one (the net force at rest within
    /// [`RESIDUAL_TOLERANCE`] of the gross force, [`residual`](Self::residual)); said whether or
    /// not it was met. `"stalled residual, rest_motion"`: the implicit one's residual stopped
    /// falling above that (contacts chattering at rest), and the shape was judged by motion
    /// from then on.
    pub criterion: String,
    /// The implicit integrator's residual at the end: the net force on the free vertices over
    /// the largest gross force of the run (`√Σ|f|² / max √Σ(Σ|f_term|)²`); absent under the
    /// explicit one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residual: Option<f64>,
    /// How finely the positions resolve that residual (on its scale): half the net force's
    /// change when every coordinate moves to a neighbouring `f32`, a stored position being off
    /// by at most half that (`CpuWorld::residual_floor`). A residual near it is as balanced as single precision
    /// allows, and a criterion below it cannot be met. Absent under the explicit integrator
    /// and on the GPU.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residual_floor: Option<f64>,
    /// The implicit integrator's steps taken in more than one part, because a vertex would
    /// have moved farther in one than a contact may miss (docs/integrator.md, "A step too far
    /// is split"); absent under the explicit one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub split_steps: Option<u64>,
    /// The most parts one of them was taken in.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub most_parts: Option<u32>,
    /// The settling window, in seconds: twice the time an elastic wave takes to cross the
    /// largest deformable body ([`settling_window`](super::settling_window)).
    pub rest_window: f64,
    /// Per body.
    pub bodies: Vec<BodySummary>,
    /// Per contact.
    pub contacts: Vec<ContactSummary>,
    /// The bodies' landmarks (docs/design.md §14): where each started, on its body's outer
    /// surface, and where it ended, in the file's units.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub landmarks: Vec<LandmarkSummary>,
    /// Whether every contact held (`contacts[].held`): the run's numbers are a result only then.
    pub held: bool,
    /// Why the run's numbers are not a result, besides a contact that failed (`held`): a
    /// body whose unloaded shape was not recovered to a tenth of its spacing. Empty: nothing.
    pub not_a_result: Vec<String>,
    /// Files written, relative to the output directory.
    pub files: Vec<String>,
}

fn kind_name(kind: BodyKind) -> &'static str {
    match kind {
        BodyKind::Soft => "soft",
        BodyKind::Shell => "shell",
        BodyKind::Rigid => "rigid",
    }
}

/// The summary of `file`'s run named `scenario`, before its first step: its bodies, their
/// materials and recovered shapes, its contacts (held until a check finds otherwise), the
/// backend and adapter it steps on, and why it is `not_a_result` already (set-up findings).
pub(super) fn start(
    file: &SceneFile,
    built: &Built,
    scenario: &str,
    (backend, adapter): (&str, String),
    not_a_result: Vec<String>,
) -> FileSummary {
    let world = &built.world;
    FileSummary {
        scenario: scenario.to_string(),
        units: file.units.symbol().into(),
        backend: backend.into(),
        adapter,
        dt: built.dt,
        bodies: world
            .names
            .iter()
            .zip(&world.bodies)
            .zip(&file.bodies)
            .zip(&built.notes)
            .map(|(((name, body), spec), n): (((&String, &MassSpring), _), &BodyNote)| BodySummary {
                name: name.clone(),
                kind: kind_name(spec.kind).into(),
                vertices: body.len(),
                coverage: n.coverage.map(|(c, _)| c),
                remarks: n.remarks.clone(),
                material: (spec.kind != BodyKind::Rigid).then(|| MaterialSummary {
                    model: if body.elements.is_some() { "neo-hookean" } else { "springs" }.into(),
                    young_kpa: spec.material.young_kpa,
                    poisson: spec.material.poisson,
                    poisson_honoured: body.elements.is_some(),
                    tetrahedra: body.elements.as_ref().map(|e| e.tets.len()),
                }),
                reference: n.reference.map(|r| ReferenceSummary {
                    residual: r.residual,
                    iterations: r.iterations,
                    spacing: r.spacing,
                    valid: r.is_valid(),
                }),
                placed: n.placed.map(|p| PlacedSummary {
                    centre: p.centre.to_array(),
                    normal: p.normal.to_array(),
                    moved: p.moved.to_array(),
                    overreach: p.overreach,
                }),
                ..BodySummary::default()
            })
            .collect(),
        contacts: world
            .contacts
            .iter()
            .map(|c| ContactSummary {
                a: world.names[c.a].clone(),
                b: world.names[c.b].clone(),
                bound: c.grid.voxel_size(),
                rest_bound: 0.5 * mean_spring(&world.bodies[c.b]),
                held: true,
                ..Default::default()
            })
            .collect(),
        held: true,
        not_a_result,
        integrator: if world.integrator == Integrator::Explicit { "explicit" } else { "implicit" }.into(),
        ..FileSummary::default()
    }
}

/// Updates the summary's displacement maxima with this frame (the contacts' penetration is
/// the checks', independent of the voxel model).
pub(super) fn measure(world: &World, summary: &mut FileSummary) {
    for (body, s) in world.bodies.iter().zip(summary.bodies.iter_mut()) {
        let d = body.pos.iter().zip(body.start()).map(|(p, r)| p.distance(*r)).fold(0.0, f32::max);
        s.max_displacement = s.max_displacement.max(d);
    }
}

/// How the last frame found the run: its residual force and the floor positions resolve it to
/// (the implicit integrator's), the step its residual stalled at (if it did), and the farthest
/// a vertex moved since the frame before (or the mark a settling window before it,
/// `Rest::mark`), in spacings.
pub(super) struct Last {
    pub residual: Option<f64>,
    pub floor: Option<f64>,
    pub stalled_since: Option<u64>,
    pub motion: f32,
}

/// The summary's figures at the last frame: volumes (between the skin and the chest wall, and
/// each shell's), landmarks, the rest test met, and the contacts at the end.
pub(super) fn at_end(
    summary: &mut FileSummary,
    (world, reports): (&World, &[ContactReport]),
    file: &SceneFile,
    built: &Built,
    last: &Last,
) {
    let cubic_ml = file.metres().powi(3) * 1e6;
    for (k, ((b, spec), out)) in
        world.bodies.iter().zip(&file.bodies).zip(summary.bodies.iter_mut()).enumerate()
    {
        if let Some(faces) = &built.notes[k].wall_faces {
            out.volume_ml = Some(volume_between(b, faces, b.start(), b.start()) * cubic_ml);
            out.volume_ml_end = Some(volume_between(b, faces, b.start(), &b.pos) * cubic_ml);
        }
        for l in &built.notes[k].landmarks {
            summary.landmarks.push(LandmarkSummary {
                body: spec.name.clone(),
                name: l.name.clone(),
                start: l.at(b, b.start()).to_array(),
                end: l.at(b, &b.pos).to_array(),
            });
        }
        if spec.kind == BodyKind::Shell {
            out.volume = Some(b.enclosed_volume());
            let coverage = b.surface.coverage(&b.pos, COVERAGE_COLUMNS);
            out.self_overlap = Some(coverage.excess());
            if coverage.excess().abs() > SELF_OVERLAP * coverage.signed.abs() {
                summary.not_a_result.push(through_itself(&spec.name, coverage, file));
            }
            if file.units.is_physical() {
                out.volume_ml = Some(b.enclosed_volume() * file.metres().powi(3) * 1e6);
            }
        }
    }
    // A placed implant's plan: in tissue taken for incompressible, the volume added between
    // her skin and chest wall is the implant's, as `compare` asks of a candidate, or the run is
    // not a result.
    for p in &world.pockets {
        let (tissue, implant) = (&summary.bodies[p.tissue], &summary.bodies[p.implant]);
        if let (Some(start), Some(end), Some(volume)) =
            (tissue.volume_ml, tissue.volume_ml_end, implant.volume_ml)
            && let Some(why) =
                crate::compare::gain_off(end - start, volume, file.bodies[p.tissue].material.model_poisson())
        {
            let why = format!("{}: {why}", tissue.name);
            summary.not_a_result.push(why);
        }
    }
    summary.rest_motion = if last.motion.is_finite() { last.motion } else { 0.0 };
    summary.residual = last.residual;
    summary.residual_floor = last.floor;
    // Each integrator's own test, met or not (the implicit one never judges by motion).
    summary.criterion = match (last.residual, last.stalled_since) {
        (Some(r), Some(_)) if r > RESIDUAL_TOLERANCE && !last.floor.is_some_and(|f| r <= f) => {
            "stalled residual, rest_motion"
        }
        (Some(_), _) => "residual",
        (None, _) => "rest_motion",
    }
    .into();
    for (c, r) in reports.iter().enumerate() {
        summary.contacts[c].contacts_at_end = r.colliding_b.len();
    }
}

/// A shell whose volume counts more than this share of itself twice passes through itself: its
/// fill holds a volume its surface does not enclose. The tolerance on the volume a plan adds
/// (`compare`'s 5 %): a shell as soft as fat, 3 kPa, planned on the MakeHuman patient
/// standing, crumpled until 165.3 mL of its 298.9 were counted twice (55 %); at 30 kPa its rim,
/// pressed between her tissue and the wall, folds over a few millilitres (4.2 mL of 299.7, and
/// 10.4 mL of the 350 cc ultra-high's 349.4: 3.0 %; docs/patient.md).
pub const SELF_OVERLAP: f64 = 0.05;

/// The lines [`TriangleMesh::coverage`](voxcollide_sim::mesh::TriangleMesh::coverage) measures
/// a shell along, per side of its bounds.
const COVERAGE_COLUMNS: usize = 128;

/// Why a shell whose surface passes through itself (`coverage`) is not a result.
fn through_itself(name: &str, coverage: voxcollide_sim::mesh::Coverage, file: &SceneFile) -> String {
    let (scale, unit) = if file.units.is_physical() {
        (file.metres().powi(3) * 1e6, " mL".to_string())
    } else {
        (1.0, format!(" cubic {}", file.units.symbol()))
    };
    format!(
        "{name}: its shell passes through itself: of the {:.1}{unit} its volume counts, {:.1}{unit} is counted more than once, and its surface encloses {:.1}{unit} (a shell too soft for its load crumples: give it a stiffer material, docs/patient.md)",
        coverage.signed * scale,
        coverage.excess() * scale,
        coverage.covered * scale
    )
}

/// The run's totals: `steps` done in `seconds` of stepping (frames excluded), the simulated
/// time, how often a step waited for the device, and how far a step was split.
pub(super) fn totals(summary: &mut FileSummary, run: &dyn Simulation, steps: u64, seconds: f64) {
    (summary.split_steps, summary.most_parts) = run.parts().map(|p| (p.split_steps, p.most_parts)).unzip();
    summary.steps = steps;
    summary.host_waits_per_step = run.host_waits().map(|w| w as f64 / steps.max(1) as f64);
    summary.simulated_time = super::simulated_time(run, steps, summary.dt);
    summary.steps_per_second = if seconds > 0.0 { steps as f64 / seconds } else { 0.0 };
    summary.realtime_factor = if seconds > 0.0 { summary.simulated_time / seconds } else { 0.0 };
}

/// Writes `summary` as `summary.json` in `out`, and lists it among its files.
///
/// # Errors
/// [`Error::Io`] naming the file.
pub(super) fn write(out: &Path, summary: &mut FileSummary) -> Result<(), Error> {
    let path = out.join("summary.json");
    let json = serde_json::to_string_pretty(&*summary).map_err(|e| super::io(&path, e))?;
    std::fs::write(&path, json + "\n").map_err(|e| super::io(&path, e))?;
    summary.files.push("summary.json".into());
    Ok(())
}
