//! Running a scene end to end: the backend (GPU when there is an adapter, else the CPU), the
//! frames (PNG pictures, VTK files for ParaView, measurements), and the run's summary.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use serde::Serialize;

use crate::backend::{Backend, context};
use crate::output::{BodyFrame, PvdSeries};
use voxcollide::error::Error;
use voxcollide::report::ContactReport;
use voxcollide_render::{Legend, Renderer, Scene as RenderScene, SceneMesh};
use voxcollide_sim::build::build_world;
use voxcollide_sim::geometry::{ClosedSurface, penetration};
use voxcollide_sim::scene_file::SceneFile;
use voxcollide_sim::{CpuSim, GpuSim, Kind, Scene, SceneConfig};

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
    pub bodies: Vec<crate::scene_run::BodySummary>,
    /// docs/design.md §8's per-contact figures: the one contact.
    pub contacts: Vec<crate::scene_run::ContactSummary>,
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

/// A simulation on one of the two backends.
enum Sim {
    Cpu(Box<CpuSim>),
    Gpu(Box<GpuSim>),
}

impl Sim {
    fn step(&mut self) -> Result<(), Error> {
        match self {
            Sim::Cpu(s) => s.step(),
            Sim::Gpu(s) => s.step(),
        }
    }

    /// The scene with up-to-date positions and the last contact report.
    fn frame(&mut self) -> Result<(&Scene, ContactReport), Error> {
        match self {
            Sim::Cpu(s) => Ok((&s.scene, s.report.clone())),
            Sim::Gpu(s) => {
                let report = s.sync()?;
                Ok((&s.scene, report))
            }
        }
    }
}

/// The report's forces for a body of `n` vertices, borrowed; zeros before the first step, when
/// the report is still empty.
fn forces_or_zero(v: &[Vec3], n: usize) -> std::borrow::Cow<'_, [Vec3]> {
    if v.len() == n { v.into() } else { vec![Vec3::ZERO; n].into() }
}

fn io(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Io { path: path.display().to_string(), message: e.to_string() }
}

/// Runs `config`, calling `progress(steps_done)` as it goes and `note(line)` for anything the
/// user should read (the backend chosen, a fallback to the CPU, pictures skipped).
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
    // At its defaults, a paper scene runs as its shipped scene file describes it (proven the
    // same to the bit by voxcollide-sim's tests/shipped_scenes.rs); other options have only the
    // built-in generator.
    let shipped = if config.scene == SceneConfig::new(config.scene.kind) {
        let (path, text) = (shipped_path(config.scene.kind), shipped(config.scene.kind));
        let built = build_world(&SceneFile::parse(path, text)?)?;
        Some((path, built.world))
    } else {
        None
    };
    std::fs::create_dir_all(&config.out).map_err(|e| io(&config.out, e))?;
    let (ctx, without) = context(config.backend, config.image.is_some(), note)?;
    let (mut sim, backend, adapter) = match (config.backend, &ctx) {
        (Backend::Cpu, _) | (Backend::Auto, None) => (
            Sim::Cpu(Box::new(match &shipped {
                Some((_, world)) => CpuSim::with_world(scene.clone(), world.clone())?,
                None => CpuSim::new(scene.clone())?,
            })),
            "cpu",
            ctx.as_ref().map_or(without, |c| format!("pictures on {}", c.adapter_name())),
        ),
        (_, Some(ctx)) => (
            Sim::Gpu(Box::new(match &shipped {
                Some((_, world)) => GpuSim::with_world(ctx, scene.clone(), world.clone())?,
                None => GpuSim::new(ctx, scene.clone())?,
            })),
            "gpu",
            ctx.adapter_name(),
        ),
        (Backend::Gpu, None) => unreachable!("Backend::Gpu returned early without an adapter"),
    };
    let source = match &shipped {
        Some((path, _)) => format!("the shipped {path}"),
        None => {
            format!("the built-in generator, for options other than {}'s", shipped_path(config.scene.kind))
        }
    };
    note(&format!("{} on the {backend} backend ({adapter}), from {source}", config.scene.kind.name()));
    let mut renderer = match (&ctx, config.image) {
        (Some(ctx), Some((w, h))) => Some(Renderer::new(ctx, w, h)?),
        _ => None,
    };
    let name = config.scene.kind.name();
    let mut series = config.vtk.then(|| {
        (
            PvdSeries::new(config.out.join("tissue.pvd")),
            PvdSeries::new(config.out.join(format!("{name}.pvd"))),
        )
    });

    let steps = config.scene.steps;
    let mut summary = Summary {
        scenario: name.into(),
        backend: backend.into(),
        adapter,
        steps,
        vertices_a: scene.foreign.len(),
        vertices_b: scene.tissue.len(),
        layer_thickness: scene.layer_thickness(),
        voxel_size: scene.grid.voxel_size(),
        magnitude: scene.params.magnitude,
        stiffness: config.scene.stiffness,
        dt: scene.dt,
        scene_file: shipped.as_ref().map(|(path, _)| (*path).to_string()),
        ..Summary::default()
    };
    let mut stepping = 0.0f64;
    let mut done = 0u64;
    for frame in 0..=config.frames {
        let target = (u64::from(frame) * steps).div_ceil(u64::from(config.frames));
        let started = Instant::now();
        while done < target {
            sim.step()?;
            done += 1;
            if done.is_multiple_of(16) || done == target {
                progress(done);
            }
        }
        let (scene, report) = sim.frame()?;
        stepping += started.elapsed().as_secs_f64();
        let f = measure(frame, done, scene, &report)?;
        if let Some(r) = renderer.as_mut() {
            let file = format!("{name}_{frame:04}.png");
            let moved: Vec<f32> =
                scene.tissue.pos.iter().zip(&scene.tissue.rest_pos).map(|(p, r)| p.distance(*r)).collect();
            let shown = picture(scene, &moved);
            let legend = Legend::new("tissue displacement (layer units)", shown.scalar_range);
            r.render_png_with_legend(&shown, Some(&legend), &config.out.join(&file))?;
            summary.files.push(file);
        }
        if let Some((tissue, foreign)) = series.as_mut() {
            let time = f.time;
            let colliding: Vec<bool> = {
                let mut c = vec![false; scene.tissue.len()];
                report.colliding_b.iter().for_each(|&j| c[j as usize] = true);
                c
            };
            let (ft, ff) = (
                forces_or_zero(&report.force_b, scene.tissue.len()),
                forces_or_zero(&report.force_a, scene.foreign.len()),
            );
            for (pvd, body, forces, flags, prefix) in [
                (tissue, &scene.tissue, &ft, colliding, "tissue"),
                (foreign, &scene.foreign, &ff, ff.iter().map(|f| *f != Vec3::ZERO).collect(), name),
            ] {
                let displacement: Vec<Vec3> =
                    body.pos.iter().zip(&body.rest_pos).map(|(p, r)| *p - *r).collect();
                let file = format!("{prefix}_{frame:04}.vtp");
                pvd.write_frame(
                    time,
                    &file,
                    &BodyFrame {
                        positions: &body.pos,
                        triangles: &body.surface.triangles,
                        displacement: &displacement,
                        contact_force: forces,
                        colliding: &flags,
                    },
                )?;
                summary.files.push(file);
            }
        }
        summary.frames.push(f);
    }
    if series.is_some() {
        summary.files.extend(["tissue.pvd".to_string(), format!("{name}.pvd")]);
    }
    summary.steps_per_second = if stepping > 0.0 { steps as f64 / stepping } else { 0.0 };
    summary.host_waits_per_step = match &sim {
        Sim::Gpu(s) => Some(s.host_waits() as f64 / steps.max(1) as f64),
        Sim::Cpu(_) => None,
    };
    let settle = steps / 10;
    for f in summary.frames.iter().filter(|f| f.step > settle) {
        summary.max_penetration = summary.max_penetration.max(f.max_penetration);
        summary.penetrating_fraction = summary.penetrating_fraction.max(f.penetrating_fraction);
    }
    summary.max_tissue_displacement =
        summary.frames.iter().map(|f| f.max_tissue_displacement).fold(0.0, f32::max);
    let max_foreign = summary.frames.iter().map(|f| f.max_foreign_displacement).fold(0.0, f32::max);
    summary.bodies = vec![
        crate::scene_run::BodySummary {
            name: "tissue".into(),
            kind: "soft".into(),
            vertices: summary.vertices_b,
            max_displacement: summary.max_tissue_displacement,
            ..Default::default()
        },
        crate::scene_run::BodySummary {
            name: name.into(),
            kind: match config.scene.kind {
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
    summary.contacts = vec![crate::scene_run::ContactSummary {
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
    }];
    summary.held = worst.is_none();
    summary.simulated_time = steps as f64 * f64::from(scene.dt);
    let path = config.out.join("summary.json");
    let json = serde_json::to_string_pretty(&summary).map_err(|e| io(&path, e))?;
    std::fs::write(&path, json + "\n").map_err(|e| io(&path, e))?;
    summary.files.push("summary.json".into());
    Ok(summary)
}

/// The measurements of one frame; penetration by the exact inside test on the foreign body's
/// current closed surface, independent of the voxel model.
fn measure(frame: u32, step: u64, scene: &Scene, report: &ContactReport) -> Result<FrameSummary, Error> {
    let surface = ClosedSurface::new(&scene.foreign.pos, &scene.foreign.surface)?;
    let p = penetration(&surface, &scene.tissue.pos);
    let max_disp =
        |pos: &[Vec3], rest: &[Vec3]| pos.iter().zip(rest).map(|(p, r)| p.distance(*r)).fold(0.0, f32::max);
    Ok(FrameSummary {
        frame,
        step,
        time: step as f64 * f64::from(scene.dt),
        colliding: report.colliding_b.len(),
        penetrating_fraction: p.fraction,
        max_penetration: p.max_depth,
        max_tissue_displacement: max_disp(&scene.tissue.pos, &scene.tissue.rest_pos),
        max_foreign_displacement: max_disp(&scene.foreign.pos, &scene.foreign.rest_pos),
    })
}

/// The picture of a frame: seen from the front and a little above, the front half cut away at
/// y = 0, the tissue coloured by how far it moved (the cut face is the tissue's middle plane),
/// the foreign body in a plain colour.
fn picture<'a>(scene: &'a Scene, tissue_scalars: &'a [f32]) -> RenderScene<'a> {
    let colour = match scene.config.kind {
        Kind::Cylinder => [0.45, 0.55, 0.7],
        Kind::Implant => [0.95, 0.6, 0.25],
    };
    RenderScene {
        meshes: vec![
            SceneMesh {
                positions: &scene.tissue.pos,
                triangles: &scene.tissue.surface.triangles,
                scalars: Some(tissue_scalars),
                base_color: [0.8; 3],
            },
            SceneMesh {
                positions: &scene.tissue.pos,
                triangles: &scene.tissue_slice,
                scalars: Some(tissue_scalars),
                base_color: [0.8; 3],
            },
            SceneMesh {
                positions: &scene.foreign.pos,
                triangles: &scene.foreign.surface.triangles,
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
