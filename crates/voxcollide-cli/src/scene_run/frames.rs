//! The run's frames on disk: a picture of every body (PNG), a VTK series per body for
//! ParaView, and at the end each soft body's surface as PLY; and how a body is shown (the
//! user's own surface where the lattice carries one).

use std::path::PathBuf;

use glam::Vec3;

use super::FileRunConfig;
use super::summary::FileSummary;
use crate::output::{BodyFrame, PvdSeries};
use voxcollide::error::Error;
use voxcollide::gpu::GpuContext;
use voxcollide::report::ContactReport;
use voxcollide_render::{Legend, Renderer, Scene as RenderScene, SceneMesh};
use voxcollide_sim::scene_file::{Axis, BodyKind, SceneFile};
use voxcollide_sim::{MassSpring, World};

/// What a run writes at its frames, and where.
pub(super) struct FrameFiles {
    /// Draws the pictures, where the file asks for them and there is an adapter.
    renderer: Option<Renderer>,
    /// A series per body, where the file asks for VTK.
    series: Vec<PvdSeries>,
    out: PathBuf,
    scenario: String,
    units: String,
    /// Per body: whether it is soft (coloured by how far it moved, and written as PLY).
    soft: Vec<bool>,
    /// The scene's size, the largest side of the box around every body at the start.
    size: f32,
    up: Axis,
}

impl FrameFiles {
    /// The frames of `file`'s run named `scenario` (its world as built: `world`), drawn on
    /// `ctx`.
    ///
    /// # Errors
    /// The renderer's errors.
    pub fn new(
        ctx: Option<&GpuContext>,
        file: &SceneFile,
        world: &World,
        config: &FileRunConfig,
        scenario: &str,
    ) -> Result<FrameFiles, Error> {
        let renderer = match (ctx, file.output.images) {
            (Some(ctx), true) => Some(Renderer::new(ctx, config.image.0, config.image.1)?),
            _ => None,
        };
        let series = if file.output.vtk {
            world.names.iter().map(|n| PvdSeries::new(config.out.join(format!("{n}.pvd")))).collect()
        } else {
            Vec::new()
        };
        let (lo, hi) = world
            .bodies
            .iter()
            .flat_map(|b| b.pos.iter())
            .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        Ok(FrameFiles {
            renderer,
            series,
            out: config.out.clone(),
            scenario: scenario.to_string(),
            units: file.units.symbol().into(),
            soft: file.bodies.iter().map(|b| b.kind == BodyKind::Soft).collect(),
            size: (hi - lo).max_element(),
            up: file.world.up,
        })
    }

    /// Per body, whether it is soft.
    pub fn soft(&self) -> &[bool] {
        &self.soft
    }

    /// Writes frame `frame` (simulated `time` seconds) of `world` with its contact `reports`,
    /// listing the files in `summary`.
    ///
    /// # Errors
    /// The renderer's and [`Error::Io`] for the files.
    pub fn write(
        &mut self,
        world: &World,
        reports: &[ContactReport],
        (frame, time): (u32, f64),
        summary: &mut FileSummary,
    ) -> Result<(), Error> {
        if let Some(r) = self.renderer.as_mut() {
            let name = format!("{}_{frame:04}.png", self.scenario);
            let shown = shown_and_moved(world);
            let scene = picture(world, &shown, &self.soft, self.size, self.up);
            let legend = Legend::new(format!("displacement ({})", self.units), scene.scalar_range)
                .above(scene.largest_scalar());
            r.render_png_with_legend(&scene, Some(&legend), &self.out.join(&name))?;
            summary.files.push(name);
        }
        for (k, pvd) in self.series.iter_mut().enumerate() {
            let body = &world.bodies[k];
            let force = contact_forces(world, reports, k);
            let mut colliding = vec![false; body.len()];
            // B's vertices the voxel model found colliding; A's that it pushed.
            for (pair, r) in world.contacts.iter().zip(reports) {
                if pair.b == k && r.force_b.len() == body.len() {
                    r.colliding_b.iter().for_each(|&j| colliding[j as usize] = true);
                }
                if pair.a == k && r.force_a.len() == body.len() {
                    colliding.iter_mut().zip(&r.force_a).for_each(|(c, f)| *c |= *f != Vec3::ZERO);
                }
            }
            let name = format!("{}_{frame:04}.vtp", world.names[k]);
            // The surface it is shown by (the user's own it carries, her scanned skin, or its
            // own), its values interpolated there from the lattice.
            let (positions, mesh) = body.shown_at(&body.pos);
            let displacement: Vec<Vec3> =
                positions.iter().zip(body.shown_start().iter()).map(|(p, r)| *p - *r).collect();
            let flags: Vec<Vec3> = colliding.iter().map(|c| Vec3::splat(f32::from(u8::from(*c)))).collect();
            let touching: Vec<bool> = body.shown_values(&flags).iter().map(|f| f.x > 0.0).collect();
            pvd.write_frame(
                time,
                &name,
                &BodyFrame {
                    positions: &positions,
                    triangles: &mesh.triangles,
                    displacement: &displacement,
                    contact_force: &body.shown_values(&force),
                    colliding: &touching,
                },
            )?;
            summary.files.push(name);
        }
        Ok(())
    }

    /// At the last frame, where the file asks for VTK: each soft body's surface as it ends (the
    /// operated skin), for any mesh viewer, with how far each vertex moved as its `quality`.
    ///
    /// # Errors
    /// [`Error::Io`] for the files.
    pub fn write_end(&self, world: &World, summary: &mut FileSummary) -> Result<(), Error> {
        if self.series.is_empty() {
            return Ok(());
        }
        let shown = shown_and_moved(world);
        for (k, b) in world.bodies.iter().enumerate() {
            if !self.soft[k] {
                continue;
            }
            let name = format!("{}_end.ply", world.names[k]);
            let (_, mesh) = shown_surface(b);
            voxcollide_sim::mesh_io::write_ply(
                &self.out.join(&name),
                &shown[k].0,
                mesh,
                Some(&shown[k].1),
                &format!(
                    "voxcollide: {} at the end of {}, in {}; quality: how far it moved",
                    world.names[k], self.scenario, self.units
                ),
            )?;
            summary.files.push(name);
        }
        Ok(())
    }

    /// After the last frame: the series' `.pvd` files, listed in `summary`.
    pub fn finish(&self, world: &World, summary: &mut FileSummary) {
        if !self.series.is_empty() {
            summary.files.extend(world.names.iter().map(|n| format!("{n}.pvd")));
        }
    }
}

/// The contact force on each vertex of body `k`: its side's forces of every contact it is in,
/// summed in contact order.
pub(crate) fn contact_forces(world: &World, reports: &[ContactReport], k: usize) -> Vec<Vec3> {
    let n = world.bodies[k].len();
    let mut force = vec![Vec3::ZERO; n];
    for (pair, r) in world.contacts.iter().zip(reports) {
        if pair.a == k && r.force_a.len() == n {
            force.iter_mut().zip(&r.force_a).for_each(|(f, a)| *f += *a);
        }
        if pair.b == k && r.force_b.len() == n {
            force.iter_mut().zip(&r.force_b).for_each(|(f, b)| *f += *b);
        }
    }
    force
}

/// Every body's shown surface ([`shown_surface`]) and how far each of its vertices is from
/// where it started.
pub(crate) fn shown_and_moved(world: &World) -> Vec<(Vec<Vec3>, Vec<f32>)> {
    world
        .bodies
        .iter()
        .map(|b| {
            let (p, _) = shown_surface(b);
            let moved = p.iter().zip(b.shown_start().iter()).map(|(p, r)| p.distance(*r)).collect();
            (p.into_owned(), moved)
        })
        .collect()
}

/// The surface a body is shown and measured by, and that its contacts meet
/// ([`MassSpring::shown_at`]): the user's own where the lattice carries one (its vertices
/// following their cells), a patient's scanned skin beside her lattice's other faces, else the
/// body's.
pub(crate) fn shown_surface(
    body: &MassSpring,
) -> (std::borrow::Cow<'_, [Vec3]>, &voxcollide_sim::mesh::TriangleMesh) {
    body.shown_at(&body.pos)
}

/// Every body's mesh for a picture, by its shown surface (`shown`: positions and how far each
/// moved): the bodies for which `coloured` says so coloured by that distance, the others in
/// `colour(body)`.
pub(crate) fn meshes<'a>(
    world: &'a World,
    shown: &'a [(Vec<Vec3>, Vec<f32>)],
    coloured: impl Fn(usize) -> bool,
    colour: impl Fn(usize) -> [f32; 3],
) -> Vec<SceneMesh<'a>> {
    world
        .bodies
        .iter()
        .enumerate()
        .map(|(k, b)| SceneMesh {
            positions: &shown[k].0,
            triangles: &b.shown_at(&b.pos).1.triangles,
            scalars: coloured(k).then(|| shown[k].1.as_slice()),
            base_color: colour(k),
        })
        .collect()
}

/// The scene's axes as pictures see them (`[world] up`, docs/design.md §13): `[side,
/// forward, up]`, `up` drawn upward and a picture from the front looking along `forward`, a
/// right-handed turn of x, y, z. Z up: looking along +y (the paper's scenes). Y up: looking
/// along −z, at a patient who faces +z as surface scanners and MakeHuman write her. X up:
/// looking along +z.
#[must_use]
pub fn axes(up: Axis) -> [Vec3; 3] {
    match up {
        Axis::Z => [Vec3::X, Vec3::Y, Vec3::Z],
        Axis::Y => [Vec3::X, Vec3::NEG_Z, Vec3::Y],
        Axis::X => [Vec3::Y, Vec3::Z, Vec3::X],
    }
}

/// Every body by its shown surface (`shown`: positions and how far each moved), the soft ones
/// coloured by that distance (up to a tenth of the scene), the others in plain colours, seen
/// from the front and a little above, `up` drawn upward.
fn picture<'a>(
    world: &'a World,
    shown: &'a [(Vec<Vec3>, Vec<f32>)],
    soft: &[bool],
    size: f32,
    up: Axis,
) -> RenderScene<'a> {
    let [side, forward, up] = axes(up);
    const COLOURS: [[f32; 3]; 4] = [[0.95, 0.6, 0.25], [0.45, 0.55, 0.7], [0.6, 0.8, 0.5], [0.8, 0.5, 0.7]];
    RenderScene {
        meshes: meshes(world, shown, |k| soft[k], |k| COLOURS[k % COLOURS.len()]),
        scalar_range: (0.0, 0.1 * size),
        clip: None,
        view_dir: (0.3 * side + forward - 0.35 * up).normalize(),
        up,
    }
}
