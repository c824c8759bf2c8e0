//! The paper's two scenes, set up from a few physical parameters: a cylinder pressed into a
//! tissue layer (its Fig. 5) and an implant inflating under one (its Fig. 6).

use glam::{UVec3, Vec3};

use crate::bodies::{CylinderShape, box_lattice, box_slice, cylinder, ellipsoid_shell};
use crate::body::{MassSpring, Material, Mode, StepInputs};
use crate::contact::ContactModel;
use crate::world::{ContactPair, World};
use voxcollide::error::Error;
use voxcollide::grid::VoxelGrid;
use voxcollide::initializer::Initializer;
use voxcollide::params::{Anchor, ContactParams, Direction, Response, Search};

/// Which of the paper's scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A stiff cylinder pressed into a tissue layer whose base is held (Fig. 5).
    Cylinder,
    /// A closed shell inflating on the chest wall under a tissue layer held at its rim (Fig. 6).
    Implant,
}

impl Kind {
    /// The scene's name as the command spells it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Kind::Cylinder => "cylinder",
            Kind::Implant => "implant",
        }
    }
}

/// The knobs of a scene; [`SceneConfig::new`] gives the defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneConfig {
    /// Which scene.
    pub kind: Kind,
    /// Tissue lattice cells across the layer's width (the scene's resolution).
    pub resolution: u32,
    /// Number of time steps of the run.
    pub steps: u64,
    /// Tissue spring stiffness (the foreign body is stiffer by a fixed ratio).
    pub stiffness: f32,
    /// Penalty force per contact; `None`: derived from the stiffness and the lattice spacing.
    pub magnitude: Option<f32>,
    /// Voxel size, a power of two; `None`: the smallest power of two at least the coarser of
    /// the two lattice spacings.
    pub voxel_size: Option<f32>,
    /// The implant's final internal pressure (it inflates by pressure against the tension of
    /// its shell's springs, which keeps the shell taut and stable, unlike growing rest
    /// lengths, which put it in compression and let it buckle).
    pub pressure: f32,
}

impl SceneConfig {
    /// The defaults for `kind`.
    #[must_use]
    pub fn new(kind: Kind) -> SceneConfig {
        SceneConfig {
            kind,
            resolution: 24,
            steps: 1200,
            stiffness: 40.0,
            magnitude: None,
            voxel_size: None,
            pressure: 80.0,
        }
    }
}

/// The tissue layer's width (x and y) and thickness.
pub const LAYER_WIDTH: f32 = 8.0;
/// See [`LAYER_WIDTH`].
pub const LAYER_THICKNESS: f32 = 1.5;
/// How much stiffer the foreign body's springs are than the tissue's.
pub const FOREIGN_STIFFNESS_RATIO: f32 = 4.0;
/// How much the implant's size may grow by inflation (sizes the voxel model's margin).
pub const IMPLANT_GROWTH: f32 = 0.6;
/// The fraction of the run over which the cylinder is pressed down or the implant inflates;
/// the rest of the run holds still and lets the bodies settle.
pub const ACTIVE_FRACTION: f32 = 0.7;

/// A scene ready to run: both bodies, the voxel model, the time step and the schedule.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The scene's configuration.
    pub config: SceneConfig,
    /// Body B of the collision pair: the tissue.
    pub tissue: MassSpring,
    /// Body A of the collision pair: the cylinder or the implant (the voxel model follows it).
    pub foreign: MassSpring,
    /// The voxel model built around the foreign body.
    pub grid: VoxelGrid,
    /// Contact parameters.
    pub params: ContactParams,
    /// The time step (half the integrator's stability bound).
    pub dt: f32,
    /// The speed above which a vertex is taken to have blown up.
    pub v_max: f32,
    /// Triangles of the tissue's middle plane y = 0, for a cut-away picture.
    pub tissue_slice: Vec<[u32; 3]>,
    /// How far the cylinder's top moves down in all.
    pub press_depth: f32,
    /// The implant's final internal pressure.
    pub pressure: f32,
    /// The chest wall under the implant (z).
    pub chest_wall: f32,
}

fn smoothstep(t: f32) -> f32 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl Scene {
    /// Builds the scene of `config`.
    ///
    /// # Errors
    /// [`Error::Invalid`] for a resolution outside 4..=200, a step count of 0, or a
    /// non-finite or non-positive stiffness or magnitude; [`Error::VoxelSize`] for a bad voxel
    /// size; the contact errors of [`ContactParams::validate`].
    pub fn new(config: SceneConfig) -> Result<Scene, Error> {
        let invalid = |what, value: String, rule: &str| Error::Invalid { what, value, rule: rule.into() };
        if !(4..=200).contains(&config.resolution) {
            return Err(invalid(
                "resolution",
                config.resolution.to_string(),
                "must be between 4 and 200 cells",
            ));
        }
        if config.steps == 0 {
            return Err(invalid("steps", "0".into(), "must be at least 1"));
        }
        if !(config.pressure.is_finite() && config.pressure >= 0.0) {
            return Err(invalid("pressure", config.pressure.to_string(), "must be finite and not negative"));
        }
        if !(config.stiffness.is_finite() && config.stiffness > 0.0) {
            return Err(invalid("stiffness", config.stiffness.to_string(), "must be finite and positive"));
        }
        let n = config.resolution;
        let h = LAYER_WIDTH / n as f32;
        let nz = ((LAYER_THICKNESS / h).round() as u32).max(2) + 1;
        let thickness = h * (nz - 1) as f32;
        let dims = UVec3::new(n + 1, n + 1, nz);
        let origin = Vec3::new(-LAYER_WIDTH / 2.0, -LAYER_WIDTH / 2.0, 0.0);
        let k = config.stiffness;
        let tissue_material = Material { mass: 1.0, stiffening: 10.0, spring_damping: 0.6, damping: 0.15 };
        let foreign_material = Material { mass: 1.0, stiffening: 10.0, spring_damping: 0.6, damping: 0.3 };
        let k_foreign = k * FOREIGN_STIFFNESS_RATIO;
        let (tissue, foreign, press_depth, foreign_spacing, growth, chest_wall) = match config.kind {
            Kind::Cylinder => {
                let tissue = box_lattice(dims, h, origin, k, tissue_material, |v| {
                    if v.z == 0 { Mode::Pinned } else { Mode::Free }
                })?;
                let radius = 0.15 * LAYER_WIDTH;
                let rings = ((radius / h).round() as u32).max(2);
                let segments = (6 * rings).max(12);
                let height = 0.6 * thickness;
                let layers = ((height / h).round() as u32).max(2) + 1;
                let base = Vec3::new(0.0, 0.0, thickness + 1.0 * h);
                let shape = CylinderShape { base, radius, height, rings, segments, layers };
                let foreign = cylinder(shape, k_foreign, foreign_material)?;
                (tissue, foreign, 1.0 * h + 0.3 * thickness, radius / rings as f32, 0.0, f32::MIN)
            }
            Kind::Implant => {
                let rim = |v: UVec3| v.x == 0 || v.y == 0 || v.x == n || v.y == n;
                let tissue = box_lattice(dims, h, origin, k, tissue_material, |v| {
                    if rim(v) { Mode::Pinned } else { Mode::Free }
                })?;
                let radii = Vec3::new(0.25 * LAYER_WIDTH, 0.25 * LAYER_WIDTH, 0.4 * thickness);
                let center = Vec3::new(0.0, 0.0, -radii.z - 1.0 * h);
                let segments = ((std::f32::consts::TAU * radii.x / h).round() as u32).max(12);
                let rings = (segments / 2).max(4);
                let foreign =
                    ellipsoid_shell(center, radii, rings, segments, 0.6, k_foreign, foreign_material)?;
                (
                    tissue,
                    foreign,
                    0.0,
                    std::f32::consts::TAU * radii.x / segments as f32,
                    IMPLANT_GROWTH,
                    center.z - radii.z,
                )
            }
        };
        let spacing = h.max(foreign_spacing);
        let voxel_size = match config.voxel_size {
            Some(v) => v,
            None => 2f32.powi(spacing.log2().ceil() as i32),
        };
        // The grid follows the foreign body; its dims are set once, so leave room for growth.
        let extent = foreign.pos.iter().fold(Vec3::splat(f32::MIN), |m, p| m.max(*p))
            - foreign.pos.iter().fold(Vec3::splat(f32::MAX), |m, p| m.min(*p));
        let margin = (growth * extent.max_element() / voxel_size).ceil() as u32 + 2;
        let grid = Initializer::new(voxel_size).margin(margin).build(&foreign.pos)?;
        let magnitude = config.magnitude.unwrap_or(4.0 * k * h);
        let params = ContactParams {
            magnitude,
            // Contact within three quarters of the coarser lattice spacing: the foreign body's
            // vertices then leave no gap a tissue vertex could slip through, and the bodies
            // start out of contact.
            search: Search::Neighbours { radius: (0.75 * spacing).min(voxel_size) },
            direction: match config.kind {
                Kind::Cylinder => Direction::Pairwise,
                Kind::Implant => Direction::PlaneNormal,
            },
            anchor: Anchor::FollowA,
        };
        params.validate(&grid)?;
        let dt = tissue.stable_dt(0.3).min(foreign.stable_dt(0.3));
        Ok(Scene {
            config,
            tissue_slice: box_slice(dims, n / 2),
            pressure: config.pressure,
            chest_wall,
            tissue,
            foreign,
            grid,
            params,
            dt,
            v_max: 50.0 * LAYER_WIDTH,
            press_depth,
        })
    }

    /// The tissue lattice's spacing.
    #[must_use]
    pub fn tissue_spacing(&self) -> f32 {
        LAYER_WIDTH / self.config.resolution as f32
    }

    /// The layer's thickness.
    #[must_use]
    pub fn layer_thickness(&self) -> f32 {
        self.tissue.rest_pos.iter().map(|p| p.z).fold(0.0, f32::max)
    }

    /// What step `step` (0-based) applies to the tissue and to the foreign body.
    #[must_use]
    pub fn inputs(&self, step: u64) -> (StepInputs, StepInputs) {
        self.schedule().at(step)
    }

    /// What the schedule of [`inputs`](Self::inputs) depends on, apart from the bodies.
    fn schedule(&self) -> SceneSchedule {
        SceneSchedule {
            kind: self.config.kind,
            steps: self.config.steps,
            dt: self.dt,
            press_depth: self.press_depth,
            pressure: self.pressure,
            chest_wall: self.chest_wall,
        }
    }

    /// Takes the positions and velocities of the scene's world (see [`world`](Self::world)) as
    /// its own.
    pub fn follow(&mut self, world: &World) {
        if let [tissue, foreign] = &world.bodies[..] {
            self.tissue.pos.clone_from(&tissue.pos);
            self.tissue.vel.clone_from(&tissue.vel);
            self.foreign.pos.clone_from(&foreign.pos);
            self.foreign.vel.clone_from(&foreign.vel);
        }
    }

    /// Checks that `world` can stand for this scene: two bodies, the tissue and the foreign
    /// body in that order, with their vertex counts, and one contact of the foreign body (A)
    /// against the tissue (B) — as the shipped `scenes/implant.toml` and `scenes/cylinder.toml`
    /// build. Only the shapes are checked; the springs, materials and schedule are the world's.
    ///
    /// # Errors
    /// [`Error::Invalid`] naming what differs.
    pub fn check_world(&self, world: &World) -> Result<(), Error> {
        let counts: Vec<usize> = world.bodies.iter().map(MassSpring::len).collect();
        let pairs: Vec<(usize, usize)> = world.contacts.iter().map(|c| (c.a, c.b)).collect();
        if counts != [self.tissue.len(), self.foreign.len()] || pairs != [(1, 0)] {
            return Err(Error::Invalid {
                what: "scene world",
                value: format!("bodies of {counts:?} vertices, contacts (a, b) {pairs:?}"),
                rule: format!(
                    "the {} scene has a tissue of {} and a foreign body of {} vertices, in contact (1, 0)",
                    self.config.kind.name(),
                    self.tissue.len(),
                    self.foreign.len()
                ),
            });
        }
        Ok(())
    }

    /// The scene as a [`World`]: bodies `tissue` (0) and `foreign body` (1), one contact with
    /// the foreign body as A.
    ///
    /// # Errors
    /// The contact errors of [`World::new`].
    pub fn world(&self) -> Result<World, Error> {
        let schedule = self.schedule();
        World::new(
            vec!["tissue".into(), "foreign body".into()],
            vec![self.tissue.clone(), self.foreign.clone()],
            vec![ContactPair {
                a: 1,
                b: 0,
                grid: self.grid,
                params: self.params,
                model: ContactModel::Voxel(Response::Constant),
            }],
            self.v_max,
            std::sync::Arc::new(move |step| {
                let (t, f) = schedule.at(step);
                vec![t, f]
            }),
        )
        .map(|w| {
            w.with_cause(format!(
                "a time step above the integrator's stability bound (dt = {:.3e}) or a penalty \
                 magnitude ({}) too large for the stiffness ({})",
                self.dt, self.params.magnitude, self.config.stiffness
            ))
        })
    }
}

/// The schedule of a paper scene: the drive or the pressure ramped over the active part of
/// the run.
#[derive(Clone, Copy, Debug)]
struct SceneSchedule {
    kind: Kind,
    steps: u64,
    dt: f32,
    press_depth: f32,
    pressure: f32,
    chest_wall: f32,
}

impl SceneSchedule {
    fn at(&self, step: u64) -> (StepInputs, StepInputs) {
        let progress = smoothstep((step + 1) as f32 / (ACTIVE_FRACTION * self.steps as f32));
        let tissue = StepInputs {
            gravity: Vec3::ZERO,
            dt: self.dt,
            rest_scale: 1.0,
            drive: Vec3::ZERO,
            turn: glam::Mat3::IDENTITY,
            pressure: 0.0,
            fill_volume: 0.0,
            fill_bulk: 0.0,
            fill_hold: 0.0,
            floor: f32::MIN,
            wall_friction: 0.0,
        };
        let foreign = match self.kind {
            Kind::Cylinder => {
                StepInputs { drive: Vec3::new(0.0, 0.0, -self.press_depth * progress), ..tissue }
            }
            Kind::Implant => {
                StepInputs { pressure: self.pressure * progress, floor: self.chest_wall, ..tissue }
            }
        };
        (tissue, foreign)
    }
}
