//! The paper's two scenes end to end (`voxcollide run implant`, `run cylinder`): their worlds,
//! stepped by the command's one run loop ([`crate::scene_run`]) as any scene file is, with the
//! paper's measures at each frame (penetration by the exact inside test), its pictures (the
//! layer cut open at its middle), and its `summary.json`.

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::Serialize;

use crate::backend::{Backend, context};
use crate::scene_run::{BodySummary, ContactSummary, FileRunConfig, run_scene_on};
use voxcollide::error::Error;
use voxcollide::report::ContactReport;
use voxcollide_render::{Legend, Renderer, Scene as RenderScene, SceneMesh};
use voxcollide_sim::build::{BodyNote, Built, build_world};
use voxcollide_sim::geometry::{ClosedSurface, penetration};
use voxcollide_sim::scene_file::SceneFile;
use voxcollide_sim::{Kind, Scene, SceneConfig, World};

/// Everything a run needs.
#[derive(Clone, Debug)]
pub struct RunConfig {
    /// The scene.
    pub scene: SceneConfig,
    /// Which backend.
    pub backend: Backend,
    /// Where the frames and the summary go (created if missing).
    pub out: PathBuf,
    /// How many frames after the initial one.
    pub frames: u32,
    /// Picture size in pixels; `None`: no pictures.
    pub image: Option<(u32, u32)>,
    /// Whether to write VTK files.
    pub vtk: bool,
}

/// One written frame's measurements.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FrameSummary {
    /// Frame number, 0 = before the first step.
    pub frame: u32,
    /// Steps done.
    pub step: u64,
    /// Simulated time.
    pub time: f64,
    /// Tissue vertices in contact with the foreign body (the voxel model's count).
    pub colliding: usize,
    /// Tissue vertices inside the foreign body's closed surface, over all tissue vertices.
    pub penetrating_fraction: f32,
    /// The deepest such vertex's distance to the surface.
    pub max_penetration: f32,
    /// The largest distance of a tissue vertex from where it started.
    pub max_tissue_displacement: f32,
    /// The largest distance of a foreign-body vertex from where it started.
    pub max_foreign_displacement: f32,
}

/// What a run did, as written to `summary.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Summary {
    /// `cylinder` or `implant`.
    pub scenario: String,
    /// `gpu` or `cpu`.
    pub backend: String,
    /// The adapter that ran it, or why there was none.
    pub adapter: String,
    /// Steps run.
    pub steps: u64,
    /// Vertices of body A (the foreign body).
    pub vertices_a: usize,
    /// Vertices of body B (the tissue).
    pub vertices_b: usize,
    /// Steps per second over the run, frames excluded.
    pub steps_per_second: f64,
    /// On the GPU only: how many times, on average, a step waited for the device to hand data
    /// back to the host, frames excluded (docs/design.md §5). 0: every step stays on the device.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub host_waits_per_step: Option<f64>,
    /// Largest `max_penetration` of the frames after contact is established (the first 10 %
    /// of the run excluded).
    pub max_penetration: f32,
    /// Largest `penetrating_fraction` of those frames.
    pub penetrating_fraction: f32,
    /// Largest tissue displacement over all frames.
    pub max_tissue_displacement: f32,
    /// The tissue layer's thickness.
    pub layer_thickness: f32,
    /// The voxel size of the collision model (the contact's bound, docs/design.md §11).
    pub voxel_size: f32,
    /// Whether the contact held: after first contact, within the voxel size at every frame.
    pub held: bool,
    /// The penalty force per contact.
    pub magnitude: f32,
    /// The tissue's spring stiffness.
    pub stiffness: f32,
    /// The time step.
    pub dt: f32,
    /// Every frame.
    pub frames: Vec<FrameSummary>,
    /// Files written, relative to the output directory.
    pub files: Vec<String>,
    /// docs/design.md §8's per-body figures: the tissue and the foreign body.
    pub bodies: Vec<BodySummary>,
    /// docs/design.md §8's per-contact figures: the one contact.
    pub contacts: Vec<ContactSummary>,
    /// Whether the bodies were found at rest (the paper scenes do not settle: false).
    pub settled: bool,
    /// Simulated seconds.
    pub simulated_time: f64,
    /// The shipped scene file the run followed (`scenes/implant.toml`, `scenes/cylinder.toml`)
    /// at the scenario's defaults; absent when other options made the built-in generator run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scene_file: Option<String>,
}

/// A paper scene's shipped scene file, relative to the repository's root.
#[must_use]
pub fn shipped_path(kind: Kind) -> &'static str {
    match kind {
        Kind::Implant => "scenes/implant.toml",
        Kind::Cylinder => "scenes/cylinder.toml",
    }
}

/// The text of a paper scene's shipped scene file ([`shipped_path`]), built into the command
/// so that `run implant` runs anywhere, as `run scenes/implant.toml` does from the root.
#[must_use]
pub fn shipped(kind: Kind) -> &'static str {
    match kind {
        Kind::Implant => include_str!("../../../scenes/implant.toml"),
        Kind::Cylinder => include_str!("../../../scenes/cylinder.toml"),
    }
}

fn io(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Io { path: path.display().to_string(), message: e.to_string() }
}

/// Runs `config`, calling `progress(steps_done)` as it goes and `note(line)` for anything the
/// user should read (the backend chosen, a fallback to the CPU, pictures skipped).
///
/// A paper scene runs through the command's one run loop ([`run_scene_on`]), as a scene file
/// does: at its defaults from its shipped file, with other options as the built-in generator
/// builds it (the same world to the bit at the defaults). The loop steps it and writes its
/// ParaView files; this adds the paper's measures and pictures at each frame.
///
/// # Errors
/// Set-up errors of the scene, [`Error::NoAdapter`] for `Backend::Gpu` without an adapter,
/// [`Error::Simulation`] on a blow-up, and file errors.
pub fn run(
    config: &RunConfig,
    progress: &mut dyn FnMut(u64),
    note: &mut dyn FnMut(&str),
) -> Result<Summary, Error> {
    if config.frames == 0 {
        return Err(Error::Invalid { what: "frames", value: "0".into(), rule: "must be at least 1".into() });
    }
    let scene = Scene::new(config.scene)?;
    let kind = config.scene.kind;
    let name = kind.name();
    let path = shipped_path(kind);
    let mut file = SceneFile::parse(path, shipped(kind))?;
    // At its defaults, a paper scene runs as its shipped scene file describes it (proven the
    // same to the bit by voxcollide-sim's tests/shipped_scenes.rs); other options have only the
    // built-in generator, whose world takes the file's names.
    let at_defaults = config.scene == SceneConfig::new(kind);
    let built = if at_defaults {
        note(&format!("{name} from the shipped {path}"));
        build_world(&file)?
    } else {
        note(&format!("{name} from the built-in generator, for options other than {path}'s"));
        let mut world = scene.world()?;
        world.names = file.bodies.iter().map(|b| b.name.clone()).collect();
        let notes = world.names.iter().zip(&world.bodies).map(|(n, b)| BodyNote::new(n, b.len())).collect();
        Built { world, dt: scene.dt, steps: config.scene.steps, notes }
    };
    scene.check_world(&built.world)?;
    // The loop writes the ParaView files; the pictures are the paper's own (below).
    file.output.frames = config.frames;
    file.output.images = false;
    file.output.vtk = config.vtk;
    std::fs::create_dir_all(&config.out).map_err(|e| io(&config.out, e))?;
    let (ctx, without) = context(config.backend, config.image.is_some(), note)?;
    let mut renderer = match (&ctx, config.image) {
        (Some(ctx), Some((w, h))) => Some(Renderer::new(ctx, w, h)?),
        _ => None,
    };
    let mut frames = Vec::new();
    let mut pictures = Vec::new();
    let run_config = FileRunConfig {
        path: path.into(),
        backend: config.backend,
        out: config.out.clone(),
        image: config.image.unwrap_or((1, 1)),
    };
    let ran = run_scene_on(
        ctx.as_ref(),
        &without,
        &file,
        built,
        &run_config,
        &mut |done, _| progress(done),
        note,
        &mut |world, reports, at| {
            let frame = frames.len() as u32;
            let f = measure(frame, at.step, &scene, world, reports.first())?;
            if let Some(r) = renderer.as_mut() {
                let png = format!("{name}_{frame:04}.png");
                let tissue = &world.bodies[0];
                let moved: Vec<f32> =
                    tissue.pos.iter().zip(&tissue.rest_pos).map(|(p, r)| p.distance(*r)).collect();
                let shown = picture(&scene, world, &moved);
                let legend = Legend::new("tissue displacement (layer units)", shown.scalar_range);
                r.render_png_with_legend(&shown, Some(&legend), &config.out.join(&png))?;
                pictures.push(png);
            }
            frames.push(f);
            Ok(())
        },
    )?;
    let steps = ran.steps;
    let mut summary = Summary {
        scenario: name.into(),
        backend: ran.backend.clone(),
        adapter: ran.adapter.clone(),
        steps,
        vertices_a: scene.foreign.len(),
        vertices_b: scene.tissue.len(),
        steps_per_second: ran.steps_per_second,
        host_waits_per_step: ran.host_waits_per_step,
        layer_thickness: scene.layer_thickness(),
        voxel_size: scene.grid.voxel_size(),
        magnitude: scene.params.magnitude,
        stiffness: config.scene.stiffness,
        dt: scene.dt,
        frames,
        files: pictures,
        scene_file: at_defaults.then(|| path.to_string()),
        simulated_time: steps as f64 * f64::from(scene.dt),
        ..Summary::default()
    };
    summary.files.extend(ran.files.into_iter().filter(|f| f != "summary.json"));
    let settle = steps / 10;
    for f in summary.frames.iter().filter(|f| f.step > settle) {
        summary.max_penetration = summary.max_penetration.max(f.max_penetration);
        summary.penetrating_fraction = summary.penetrating_fraction.max(f.penetrating_fraction);
    }
    summary.max_tissue_displacement =
        summary.frames.iter().map(|f| f.max_tissue_displacement).fold(0.0, f32::max);
    let max_foreign = summary.frames.iter().map(|f| f.max_foreign_displacement).fold(0.0, f32::max);
    summary.bodies = vec![
        BodySummary {
            name: "tissue".into(),
            kind: "soft".into(),
            vertices: summary.vertices_b,
            max_displacement: summary.max_tissue_displacement,
            ..Default::default()
        },
        BodySummary {
            name: name.into(),
            kind: match kind {
                Kind::Cylinder => "soft",
                Kind::Implant => "shell",
            }
            .into(),
            vertices: summary.vertices_a,
            max_displacement: max_foreign,
            ..Default::default()
        },
    ];
    // docs/design.md §11: after first contact, every frame within the voxel size.
    let bound = summary.voxel_size;
    let touched = summary.frames.iter().position(|f| f.colliding > 0 || f.max_penetration > 0.0);
    let worst = touched
        .map(|t| &summary.frames[t..])
        .unwrap_or_default()
        .iter()
        .filter(|f| f.max_penetration > bound)
        .max_by(|x, y| x.max_penetration.total_cmp(&y.max_penetration));
    let failure = worst.map(|f| {
        format!(
            "the tissue went {:.3} deep into the {name} at step {} (frame {}), beyond the contact's bound of {bound} (its voxel size)",
            f.max_penetration, f.step, f.frame
        )
    });
    summary.contacts = vec![ContactSummary {
        a: name.into(),
        b: "tissue".into(),
        max_penetration: summary.frames.iter().map(|f| f.max_penetration).fold(0.0, f32::max),
        penetrating_fraction: summary.frames.iter().map(|f| f.penetrating_fraction).fold(0.0, f32::max),
        contacts_at_end: summary.frames.last().map_or(0, |f| f.colliding),
        bound,
        rest_bound: 0.5 * scene.tissue_spacing(),
        held: worst.is_none(),
        worst_frame: worst.map(|f| f.frame),
        worst_step: worst.map(|f| f.step),
        worst_depth: worst.map(|f| f.max_penetration),
        failure,
        checks: summary.frames.len() as u32,
        uncovered: 0,
    }];
    summary.held = worst.is_none();
    let path = config.out.join("summary.json");
    let json = serde_json::to_string_pretty(&summary).map_err(|e| io(&path, e))?;
    std::fs::write(&path, json + "\n").map_err(|e| io(&path, e))?;
    summary.files.push("summary.json".into());
    Ok(summary)
}

/// The measurements of one frame (`world`: the tissue and the foreign body; `report`: their
/// contact's); penetration by the exact inside test on the foreign body's current closed
/// surface, independent of the voxel model.
fn measure(
    frame: u32,
    step: u64,
    scene: &Scene,
    world: &World,
    report: Option<&ContactReport>,
) -> Result<FrameSummary, Error> {
    let [tissue, foreign] = &world.bodies[..] else {
        return Err(scene.check_world(world).err().unwrap_or(Error::Invalid {
            what: "scene world",
            value: format!("{} bodies", world.bodies.len()),
            rule: "a paper scene has two".into(),
        }));
    };
    let surface = ClosedSurface::new(&foreign.pos, &foreign.surface)?;
    let p = penetration(&surface, &tissue.pos);
    let max_disp =
        |pos: &[Vec3], rest: &[Vec3]| pos.iter().zip(rest).map(|(p, r)| p.distance(*r)).fold(0.0, f32::max);
    Ok(FrameSummary {
        frame,
        step,
        time: step as f64 * f64::from(scene.dt),
        colliding: report.map_or(0, |r| r.colliding_b.len()),
        penetrating_fraction: p.fraction,
        max_penetration: p.max_depth,
        max_tissue_displacement: max_disp(&tissue.pos, &tissue.rest_pos),
        max_foreign_displacement: max_disp(&foreign.pos, &foreign.rest_pos),
    })
}

/// The picture of a frame: seen from the front and a little above, the front half cut away at
/// y = 0, the tissue coloured by how far it moved (the cut face is the tissue's middle plane),
/// the foreign body in a plain colour.
fn picture<'a>(scene: &'a Scene, world: &'a World, tissue_scalars: &'a [f32]) -> RenderScene<'a> {
    let colour = match scene.config.kind {
        Kind::Cylinder => [0.45, 0.55, 0.7],
        Kind::Implant => [0.95, 0.6, 0.25],
    };
    let (tissue, foreign) = (&world.bodies[0], &world.bodies[1]);
    RenderScene {
        meshes: vec![
            SceneMesh {
                positions: &tissue.pos,
                triangles: &tissue.surface.triangles,
                scalars: Some(tissue_scalars),
                base_color: [0.8; 3],
            },
            SceneMesh {
                positions: &tissue.pos,
                triangles: &scene.tissue_slice,
                scalars: Some(tissue_scalars),
                base_color: [0.8; 3],
            },
            SceneMesh {
                positions: &foreign.pos,
                triangles: &foreign.surface.triangles,
                scalars: None,
                base_color: colour,
            },
        ],
        scalar_range: (0.0, 0.5 * scene.layer_thickness()),
        clip: Some((Vec3::new(0.0, -0.5 * scene.tissue_spacing(), 0.0), Vec3::Y)),
        view_dir: Vec3::new(0.3, 1.0, -0.25).normalize(),
        up: Vec3::Z,
    }
}
