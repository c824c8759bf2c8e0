//! From a checked [`SceneFile`] to a [`World`]: bodies from built-in shapes and mesh files,
//! materials in physical units, contacts with their voxel models, and the schedule.
//!
//! # Units
//! The simulation runs in the file's length unit `L` (so that a voxel size given as a power of
//! two in the file stays one), seconds and kilograms. Forces are then in `kg·L/s²`, which is
//! `s` newtons for `s` metres per `L` (`s = 10⁻³` for mm), and stresses in `kg/(L·s²)`, `s`
//! pascals. So:
//! - a lattice of spacing `h` whose axis and face-diagonal springs have stiffness `k` behaves,
//!   for small strains, as a cubic material with `C11 = 3k/h` and `C12 = C44 = k/h`: Young's
//!   modulus `2.5 k/h` and Poisson's ratio 1/4, whatever the file's ν (a body whose file gives
//!   another ν says so in its notes). Hence
//!   `k = 0.4 · E · h`, with `E = young_kpa · 10³ · s` (internal stress units).
//! - a vertex of a lattice carries the mass of its cell, `density · (h·s)³` kg; a tetrahedral
//!   mesh lumps a quarter of each tetrahedron's mass at each corner; a shell vertex carries
//!   `density · area · h` (a wall as thick as its edge length).
//! - `damping` is a damping ratio ζ of a vertex on one spring: the viscous term is
//!   `2ζ√(k m)` and the same along each spring.
//! - pressures: `pressure_kpa · 10³ · s`; penalty magnitudes given in newtons: `N / s`.

use glam::{DVec3, Mat3, UVec3, Vec3};
use voxcollide::{Anchor, ContactParams, Direction, Error, Initializer, Response, Search};

use crate::bodies::{
    CylinderShape, ImplantShape, box_lattice, cylinder, ellipsoid_shell, implant_surface, lattice_in_surface,
    shell_from_surface, tetrahedral_body,
};
use crate::body::{MassSpring, Material, Mode, StepInputs};
use crate::contact::{ContactModel, SurfacePenalty};
use crate::integrator::implicit::ImplicitSettings;
use crate::mesh::TriangleMesh;
use crate::mesh_io::{Surface, read_sheet, read_surface, read_tetrahedra};
use crate::scene_file::{
    Auto, BodyKind, BodySpec, ContactSpec, DirectionSpec, Ease, Fixed, Geometry, ImplantStyle,
    IntegratorSpec, MaterialModel, ResponseSpec, SceneFile, SearchSpec, Shape,
};
use crate::world::{ContactPair, Integrator, World};

/// The implicit integrator's automatic step: the schedule's duration in this many steps…
pub const IMPLICIT_STEPS: f64 = 200.0;
/// … at most this many seconds (and never below the explicit bound).
pub const IMPLICIT_DT: f32 = 5e-3;
/// Under the implicit integrator, a contact's automatic stiffness is at most this many times
/// the springs of the softer of its two bodies.
pub const IMPLICIT_CONTACT: f32 = 100.0;
/// The implicit integrator's fill is this many times stiffer in bulk than the explicit
/// bound allows.
pub const IMPLICIT_BULK: f32 = 100.0;

/// What building a world found worth saying about each body.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyNote {
    /// The body's name.
    pub name: String,
    /// Its vertex count.
    pub vertices: usize,
    /// For a lattice filling a surface: the fraction of the surface's volume its full cells
    /// cover, and the surface vertices it does not reach.
    pub coverage: Option<(f64, usize)>,
    /// Remarks: a surface turned outward, tetrahedra turned, springs left out across a gap.
    pub remarks: Vec<String>,
    /// For a shell that starts flattened ([`BodySpec::flatten`](crate::scene_file::BodySpec)):
    /// its full shape's surface area and enclosed volume (cubic and square file units).
    pub full_shape: Option<(f64, f64)>,
    /// For a body given as measured under gravity (`reference = { gravity }`): what the
    /// recovery of its unloaded shape found ([`crate::reference`]).
    pub reference: Option<crate::reference::Recovered>,
    /// Its landmarks (docs/design.md §14), each on its outer surface.
    pub landmarks: Vec<Landmark>,
    /// For a body between a skin and a chest wall: its surface triangles on the wall
    /// ([`crate::between::volume_between`]).
    pub wall_faces: Option<Vec<u32>>,
    /// For a shell placed on a chest wall (docs/design.md §15): where its base stands.
    pub placed: Option<PlacedNote>,
}

/// Where a shell placed on a chest wall stands (docs/design.md §15), in file units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlacedNote {
    /// Its base's centre, on the wall.
    pub centre: Vec3,
    /// The wall's outward normal there, along which the implant's apex points (unit).
    pub normal: Vec3,
    /// How far the centre moved from under its landmark to keep the base within the borders
    /// `place.within` names (zero without them, or where the base fits).
    pub moved: Vec3,
    /// Where the borders leave the base too little room, how far it still reaches past one.
    pub overreach: f32,
}

impl BodyNote {
    /// Body `name` of `vertices` vertices, about which building found nothing yet.
    #[must_use]
    pub fn new(name: &str, vertices: usize) -> BodyNote {
        BodyNote {
            name: name.to_string(),
            vertices,
            coverage: None,
            remarks: Vec::new(),
            full_shape: None,
            reference: None,
            landmarks: Vec::new(),
            wall_faces: None,
            placed: None,
        }
    }
}

/// A named point on a body's outer surface, carried by it (docs/design.md §14).
#[derive(Clone, Debug, PartialEq)]
pub struct Landmark {
    /// Its name in the file.
    pub name: String,
    /// Where the file put it.
    pub given: Vec3,
    /// The triangle of the surface the body is shown by ([`MassSpring::shown_at`]: the skin as
    /// scanned, for a `between` body) it sits on, and its weights over the corners.
    pub triangle: [u32; 3],
    /// See `triangle`.
    pub weights: [f32; 3],
}

impl Landmark {
    /// Where it is on `body` with its vertices at `pos`.
    #[must_use]
    pub fn at(&self, body: &MassSpring, pos: &[Vec3]) -> Vec3 {
        let (points, _) = body.shown_at(pos);
        self.triangle.iter().zip(&self.weights).map(|(&v, &w)| w * points[v as usize]).sum()
    }
}

/// Places shell `k` on the chest wall of the `between` body `place.body`, under its landmark
/// (docs/design.md §15), and dissects its pocket. The shell as built stands on its lowest point
/// (less its `sink`), centred across: each of its points `(x, y, z)` goes to the wall's frame
/// at `(x, y)` across, `z` in front of the wall there ([`Wall`](crate::wall::Wall)), so its base
/// lies on the curved wall. Both it and the tissue rest on the wall (their free vertices are
/// kept in front of it); the shell with `place.friction`, the tissue sliding freely. The tissue's vertices held on the wall within the base's radius and
/// `place.margin` are let go: the pocket. Where `place.within` names borders, the base moves
/// across the wall until its rim keeps within them ([`Wall::within`](crate::wall::Wall::within)).
fn place_on_wall(
    file: &SceneFile,
    k: usize,
    place: &crate::scene_file::Placement,
    bodies: &mut [MassSpring],
    notes: &[BodyNote],
) -> Result<Placed, Error> {
    let t = place.body;
    let Geometry::Shape(Shape::Between(between)) = &file.bodies[t].geometry else {
        return Err(file.body_error(k, "place.under", "the body it names has no chest wall"));
    };
    let key_error = |m: String| file.body_error(k, "place.under", m);
    let landmark = |name: &str| {
        notes[t]
            .landmarks
            .iter()
            .find(|l| l.name == name)
            .map(|l| l.at(&bodies[t], &bodies[t].pos))
            .ok_or_else(|| key_error(format!("no landmark {name:?}")))
    };
    let mark = landmark(&place.landmark)?;
    let borders = place.within.iter().map(|n| landmark(n)).collect::<Result<Vec<_>, _>>()?;
    let inner = read_sheet(&between.inner)?;
    let triangles: Vec<[Vec3; 3]> =
        inner.mesh.triangles.iter().map(|tri| tri.map(|i| inner.positions[i as usize])).collect();
    let shell = &bodies[k];
    let (lo, hi) = shell
        .pos
        .iter()
        .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(l, h), p| (l.min(*p), h.max(*p)));
    let centre = 0.5 * (lo + hi);
    let radius = shell.pos.iter().map(|p| (p.truncate() - centre.truncate()).length()).fold(0.0f32, f32::max);
    let sink = file.bodies[k].sink as f32;
    let h = file.bodies[t].spacing.unwrap_or(1.0) as f32;
    let margin = place.margin as f32;
    let mut up = Vec3::ZERO;
    up[file.world.up.index()] = 1.0;
    let cell = (0.5 * h).min(radius / 8.0).max(f32::MIN_POSITIVE);
    let sample = |near: Vec3| {
        crate::wall::Wall::sample(&triangles, near, radius, radius + margin + h, cell, up)
            .map_err(|e| key_error(format!("the implant does not fit on the chest wall: {e}")))
    };
    let mut wall = sample(mark)?;
    // A border where her breast ends cannot be where the implant stands.
    for (name, b) in place.within.iter().zip(&borders) {
        // (A distance that does not compare, NaN, is refused as well.)
        if b.distance(mark).partial_cmp(&h).is_none_or(|o| o.is_lt()) {
            return Err(file.body_error(
                k,
                "place.within",
                format!(
                    "border {name:?} lies within a spacing ({h}) of {:?}, the landmark the implant stands under: a border is where her breast ends",
                    place.landmark
                ),
            ));
        }
    }
    // Within her borders: where the base under the landmark would reach past one, it moves
    // across the wall, away from it, and the wall is sampled again there (its frame turns with
    // the wall, so a few rounds settle it).
    let under = wall.origin;
    let mut overreach = 0.0;
    for round in 0..=6 {
        let (shift, over) = wall.within(radius, mark, &borders);
        overreach = over;
        if shift.length() <= 0.05 * h {
            break;
        }
        if round == 6 {
            return Err(key_error(format!(
                "the base does not settle within its borders {:?} on this chest wall: after six moves it would still move {:.2} (the wall turns too much under it)",
                place.within,
                shift.length()
            )));
        }
        // On the wall where the line along its normal across the move meets it: sampled
        // again from a tenth of a spacing in front of it, so that the closest point is about
        // there and the side it faces is known (the grid's bilinear heights may lie a little
        // behind a faceted wall; farther out, the closest point drifts where the wall turns).
        // A wall that turned to face the other way is refused.
        let height = wall.height(shift.x, shift.y).unwrap_or(0.0);
        let before = wall.normal;
        wall = sample(wall.point(shift.extend(height + 0.1 * h)))?;
        if wall.normal.dot(before) <= 0.0 {
            return Err(key_error(format!(
                "the chest wall turns away under the base moved to keep within {:?}",
                place.within
            )));
        }
    }
    let moved = wall.origin - under;
    // The base must stand inside the tissue's box.
    let (bmin, bmax) =
        (Vec3::from_array(between.min.map(|v| v as f32)), Vec3::from_array(between.max.map(|v| v as f32)));
    for a in 0..64 {
        let turn = std::f32::consts::TAU * a as f32 / 64.0;
        let (x, y) = (radius * turn.cos(), radius * turn.sin());
        let rim = wall.point(Vec3::new(x, y, wall.height(x, y).unwrap_or(0.0)));
        if rim.cmplt(bmin - 1e-3 * h).any() || rim.cmpgt(bmax + 1e-3 * h).any() {
            return Err(key_error(format!(
                "the implant does not fit on the chest wall inside the box: its base (radius {radius:.1}) reaches {rim:?}, outside shape.between's min {bmin:?} .. max {bmax:?}"
            )));
        }
    }
    let skin = read_sheet(&between.outer)?;
    let thinnest = thinnest_over_rim(&wall, radius, &skin);
    let drape = |p: Vec3| {
        let (x, y) = (p.x - centre.x, p.y - centre.y);
        wall.point(Vec3::new(x, y, p.z - lo.z - sink + wall.height(x, y).unwrap_or(0.0)))
    };
    let shell = &mut bodies[k];
    for p in shell.pos.iter_mut().chain(shell.rest_pos.iter_mut()) {
        *p = drape(*p);
    }
    // The pocket: the tissue held on the wall over the base and its margin is let go (a vertex
    // held on the wall lies within a cell's diagonal of it); the box's faces stay held.
    let tissue = &mut bodies[t];
    let n = crate::between::spans(bmax - bmin, h).as_vec3();
    let on_face = |p: Vec3| {
        let c = (p - bmin) / h;
        c.cmple(Vec3::splat(1e-4)).any() || (c - n).cmpge(Vec3::splat(-1e-4)).any()
    };
    let mut released = 0;
    for i in 0..tissue.len() {
        let p = tissue.rest_pos[i];
        let l = wall.local(p);
        if tissue.mode[i] == Mode::Pinned
            && l.truncate().length() <= radius + margin
            && wall.height(l.x, l.y).is_some_and(|w| l.z - w <= 1.8 * h)
            && !on_face(p)
        {
            tissue.mode[i] = Mode::Free;
            released += 1;
        }
    }
    let note = PlacedNote { centre: wall.origin, normal: wall.normal, moved, overreach };
    let wall = std::sync::Arc::new(wall);
    bodies[k].wall = Some(wall.clone());
    bodies[t].wall = Some(wall);
    Ok(Placed { released, thinnest, note })
}

/// What placing a shell on a chest wall did ([`place_on_wall`]).
struct Placed {
    /// The tissue's vertices held on the wall that the pocket let go.
    released: usize,
    /// The thinnest her tissue is over the base's rim, and where ([`thinnest_over_rim`]).
    thinnest: Option<(f32, Vec3)>,
    /// Where the base stands, and how far it moved to keep within the borders.
    note: PlacedNote,
}

/// How thick her tissue is over the rim of a base of `radius` on `wall`, at its thinnest: from
/// the wall out along its normal to her `skin`, at 64 points around the rim; and where. `None`
/// where no ray from the rim meets the skin.
fn thinnest_over_rim(wall: &crate::wall::Wall, radius: f32, skin: &Surface) -> Option<(f32, Vec3)> {
    let corners: Vec<[DVec3; 3]> =
        skin.mesh.triangles.iter().map(|t| t.map(|i| skin.positions[i as usize].as_dvec3())).collect();
    let n = wall.normal.as_dvec3();
    (0..64)
        .filter_map(|a| {
            let turn = std::f32::consts::TAU * a as f32 / 64.0;
            let (x, y) = (radius * turn.cos(), radius * turn.sin());
            let rim = wall.point(Vec3::new(x, y, wall.height(x, y)?));
            let o = rim.as_dvec3();
            let t = corners
                .iter()
                .filter_map(|&c| crate::geometry::line_crossing(o, n, c, 0.0).filter(|t| *t >= 0.0))
                .fold(f64::INFINITY, f64::min);
            t.is_finite().then_some((t as f32, rim))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

/// A world built from a scene file, with its run length.
#[derive(Clone, Debug)]
pub struct Built {
    /// The world.
    pub world: World,
    /// The time step, in seconds.
    pub dt: f32,
    /// Steps of the schedule (`time.steps`, or `time.duration / dt`).
    pub steps: u64,
    /// Per body, what building it found.
    pub notes: Vec<BodyNote>,
}

/// Newtons per internal force unit and pascals per internal stress unit: `s`, the metres per
/// file unit.
fn spring_k(young_kpa: f64, h: f64, s: f64) -> f32 {
    (0.4 * young_kpa * 1e3 * s * h) as f32
}

/// The rotation of `degrees` about x, then y, then z.
fn rotation(degrees: [f64; 3]) -> Mat3 {
    let [x, y, z] = degrees.map(|d| (d as f32).to_radians());
    Mat3::from_rotation_z(z) * Mat3::from_rotation_y(y) * Mat3::from_rotation_x(x)
}

/// A closed surface of an ellipsoid with edges of about `edge`, outward.
fn ellipsoid_surface(radii: Vec3, edge: f32) -> Result<Surface, Error> {
    let r = radii.max_element();
    let segments = ((std::f32::consts::TAU * r / edge).round() as u32).max(8);
    let rings = (segments / 2).max(3);
    let shell = ellipsoid_shell(Vec3::ZERO, radii, rings, segments, 2.0, 1.0, unit_material())?;
    Ok(Surface { positions: shell.pos, mesh: shell.surface })
}

/// A closed surface of a cylinder (axis z, base at z = 0), edges of about `edge`.
fn cylinder_surface(radius: f32, height: f32, edge: f32) -> Surface {
    let segments = ((std::f32::consts::TAU * radius / edge).round() as u32).max(8);
    let layers = ((height / edge).round() as u32).max(1) + 1;
    let mut positions = vec![Vec3::ZERO, Vec3::new(0.0, 0.0, height)];
    for l in 0..layers {
        let z = height * l as f32 / (layers - 1) as f32;
        for s in 0..segments {
            let a = std::f32::consts::TAU * s as f32 / segments as f32;
            positions.push(Vec3::new(radius * a.cos(), radius * a.sin(), z));
        }
    }
    let at = |l: u32, s: u32| 2 + l * segments + s % segments;
    let mut triangles = Vec::new();
    for s in 0..segments {
        triangles.push([0, at(0, s + 1), at(0, s)]);
        triangles.push([1, at(layers - 1, s), at(layers - 1, s + 1)]);
        for l in 0..layers - 1 {
            triangles.push([at(l, s), at(l, s + 1), at(l + 1, s + 1)]);
            triangles.push([at(l, s), at(l + 1, s + 1), at(l + 1, s)]);
        }
    }
    Surface { positions, mesh: TriangleMesh { triangles } }
}

fn unit_material() -> Material {
    Material { mass: 1.0, stiffening: 10.0, spring_damping: 0.0, damping: 0.0 }
}

/// Whether `fixed` holds a vertex at `p` of a body whose lateral bounds are `lo`..`hi`.
/// What region rules need of their body: its bounding box and, for `depth`, its outer surface
/// at rest (its surface triangles with every corner free).
struct Frame {
    lo: Vec3,
    hi: Vec3,
    outer: Vec<[DVec3; 3]>,
}

impl Frame {
    fn of(body: &MassSpring) -> Frame {
        let lo = body.pos.iter().fold(Vec3::splat(f32::MAX), |a, p| a.min(*p));
        let hi = body.pos.iter().fold(Vec3::splat(f32::MIN), |a, p| a.max(*p));
        let outer = body
            .surface
            .triangles
            .iter()
            .filter(|t| t.iter().all(|&v| body.mode[v as usize] == Mode::Free))
            .map(|t| t.map(|v| body.rest_pos[v as usize].as_dvec3()))
            .collect();
        Frame { lo, hi, outer }
    }

    /// How far `p` lies from the outer surface.
    fn depth(&self, p: Vec3) -> f64 {
        let q = p.as_dvec3();
        self.outer
            .iter()
            .map(|t| crate::geometry::closest_point(q, t).distance(q))
            .fold(f64::INFINITY, f64::min)
    }
}

fn held(fixed: &[Fixed], p: Vec3, frame: &Frame) -> bool {
    let (lo, hi) = (frame.lo, frame.hi);
    fixed.iter().any(|f| match *f {
        Fixed::Below(a) => a.get().is_some_and(|(axis, v)| f64::from(p[axis]) < v),
        Fixed::Above(a) => a.get().is_some_and(|(axis, v)| f64::from(p[axis]) > v),
        Fixed::InsideBox { min, max } => {
            (0..3).all(|k| f64::from(p[k]) >= min[k] && f64::from(p[k]) <= max[k])
        }
        Fixed::Rim(w) => {
            let w = w as f32;
            p.x <= lo.x + w || p.x >= hi.x - w || p.y <= lo.y + w || p.y >= hi.y - w
        }
        Fixed::Depth(d) => frame.depth(p) <= d,
    })
}

/// The body of `spec`, in file units, with its material's spring constant for spacing `h`.
fn body(file: &SceneFile, spec: &BodySpec) -> Result<(MassSpring, BodyNote, f32), Error> {
    let s = file.metres();
    let m = &spec.material;
    let rot = rotation(spec.rotation);
    let scale = spec.scale as f32;
    let offset = Vec3::from_array(spec.position.map(|v| v as f32));
    let place = |p: Vec3| rot * (scale * p) + offset;
    let h = spec.spacing.map(|h| h as f32);
    let mut note = BodyNote::new(&spec.name, 0);
    let material_for = |h: f32, mass: f64| {
        let kspring = f64::from(spring_k(m.young_kpa, f64::from(h), s));
        let critical = 2.0 * (kspring * mass).sqrt();
        let (c, c_spring) = (m.damping * critical, m.spring_damping.unwrap_or(m.damping) * critical);
        (
            Material {
                mass: mass as f32,
                stiffening: 10.0,
                spring_damping: c_spring as f32,
                damping: c as f32,
            },
            kspring as f32,
        )
    };
    let cell_mass = |h: f32| m.density * (f64::from(h) * s).powi(3);
    // A closed surface of the body, placed, for lattices, shells and rigid bodies.
    let surface = |edge: f32| -> Result<(Surface, Option<String>), Error> {
        let mut remark = None;
        let mut surface = match &spec.geometry {
            Geometry::Shape(Shape::Sphere(r)) => ellipsoid_surface(Vec3::splat(*r as f32), edge / scale)?,
            Geometry::Shape(Shape::Ellipsoid(r)) => {
                ellipsoid_surface(Vec3::from_array(r.map(|v| v as f32)), edge / scale)?
            }
            Geometry::Shape(Shape::Cylinder { radius, height }) => {
                let mut c = cylinder_surface(*radius as f32, *height as f32, edge / scale);
                c.positions.iter_mut().for_each(|p| p.z -= 0.5 * *height as f32);
                c
            }
            Geometry::Shape(Shape::Box(size)) => {
                let size = Vec3::from_array(size.map(|v| v as f32));
                let n = (size / (edge / scale)).round().max(Vec3::ONE).as_uvec3() + UVec3::ONE;
                let b = box_lattice(n, 1.0, Vec3::ZERO, 1.0, unit_material(), |_| Mode::Free)?;
                let cells = (n - UVec3::ONE).as_vec3();
                Surface {
                    positions: b.pos.iter().map(|p| (*p / cells - 0.5) * size).collect(),
                    mesh: b.surface,
                }
            }
            Geometry::Shape(Shape::Implant { volume_ml, base_mm, projection_mm, style }) => {
                // mm and mL into file units.
                let mm = 1e-3 / s;
                let shape = ImplantShape {
                    volume: volume_ml * 1e-6 / s.powi(3),
                    base: base_mm * mm,
                    projection: projection_mm * mm,
                    anatomical: *style == ImplantStyle::Anatomical,
                };
                let (positions, mesh) = implant_surface(shape, f64::from(edge / scale))?;
                // docs/design.md §9: it stands on its base in the plane z = 0 of its position, apex up
                // (the outline's base is at z = −projection/2).
                let lift = Vec3::new(0.0, 0.0, (0.5 * shape.projection) as f32);
                let made = Surface { positions: positions.into_iter().map(|p| p + lift).collect(), mesh };
                let volume = made.mesh.volume(&made.positions);
                remark = Some(format!(
                    "a {} implant of {volume_ml} mL, base {base_mm} mm, projection {projection_mm} mm (profile exponent {:.3}): its {} triangles enclose {:.1} mL",
                    if shape.anatomical { "anatomical" } else { "round" },
                    shape.exponent()?,
                    made.mesh.triangles.len(),
                    volume * s.powi(3) * 1e6
                ));
                made
            }
            Geometry::Shape(Shape::Between(_)) => {
                return Err(Error::Invalid {
                    what: "shape",
                    value: "between".into(),
                    rule: "is a soft body's tissue between two surfaces, not a closed surface".into(),
                });
            }
            Geometry::Mesh(path) => {
                let (surface, report) = read_surface(path)?;
                if report.flipped {
                    remark = Some(format!("{}: its normals pointed inward; turned outward", path.display()));
                }
                surface
            }
        };
        surface.positions.iter_mut().for_each(|p| *p = place(*p));
        if rot.determinant() < 0.0 || scale < 0.0 {
            surface.mesh.triangles.iter_mut().for_each(|t| t.swap(1, 2));
        }
        Ok((surface, remark))
    };
    let neo_hookean = spec.material.model == MaterialModel::NeoHookean;
    let index = file.bodies.iter().position(|b| b.name == spec.name).unwrap_or(0);
    if neo_hookean && spec.kind != BodyKind::Soft {
        return Err(file.body_error(
            index,
            "material.model",
            format!(
                "\"neo-hookean\" is a soft body's material (tetrahedra); {:?} is a {:?}: use \"springs\"",
                spec.name, spec.kind
            ),
        ));
    }
    // A mesh's own tetrahedra, for the elements.
    let mut mesh_tets: Option<Vec<[u32; 4]>> = None;
    let (mut body, kspring) = match spec.kind {
        BodyKind::Soft => {
            let h = h.unwrap_or(1.0);
            let (material, kspring) = material_for(h, cell_mass(h));
            match &spec.geometry {
                Geometry::Shape(Shape::Box(size)) if spec.rotation == [0.0; 3] => {
                    let size = Vec3::from_array(size.map(|v| v as f32)) * scale;
                    let n = (size / h).round().max(Vec3::ONE).as_uvec3() + UVec3::ONE;
                    let origin = offset - 0.5 * h * (n - UVec3::ONE).as_vec3();
                    (box_lattice(n, h, origin, kspring, material, |_| Mode::Free)?, kspring)
                }
                // A solid cylinder is a polar lattice: rings about `spacing` apart.
                Geometry::Shape(Shape::Cylinder { radius, height }) if spec.rotation == [0.0; 3] => {
                    let (radius, height) = (*radius as f32 * scale, *height as f32 * scale);
                    let rings = ((radius / h).round() as u32).max(2);
                    // The base below the centre, rounded once (from f64).
                    let base_z = (f64::from(offset.z) - 0.5 * f64::from(height)) as f32;
                    let shape = CylinderShape {
                        base: Vec3::new(offset.x, offset.y, base_z),
                        radius,
                        height,
                        rings,
                        segments: (6 * rings).max(12),
                        layers: ((height / h).round() as u32).max(2) + 1,
                    };
                    // Its tetrahedra: the elements' (neo-hookean), and its mass's shares.
                    mesh_tets = Some(crate::bodies::cylinder_tets(&shape));
                    (cylinder(shape, kspring, material)?, kspring)
                }
                Geometry::Shape(Shape::Between(b)) => {
                    let outer = read_sheet(&b.outer)?;
                    let inner = read_sheet(&b.inner)?;
                    let corner = |c: [f64; 3]| Vec3::from_array(c.map(|v| v as f32));
                    let made = crate::between::between_body(
                        &outer,
                        &inner,
                        corner(b.min),
                        corner(b.max),
                        h,
                        kspring,
                        material,
                    );
                    let (body, report, tets) = made.map_err(|e| match e {
                        Ok(e) => {
                            let key = match e {
                                crate::between::BetweenError::Flat(which) => format!("shape.between.{which}"),
                                crate::between::BetweenError::Uncovered(..) => "shape.between.outer".into(),
                                crate::between::BetweenError::WallInFront => "shape.between.inner".into(),
                                crate::between::BetweenError::Empty => "shape.between.min".into(),
                            };
                            file.body_error(index, &key, e.to_string())
                        }
                        Err(e) => e,
                    })?;
                    note.remarks.push(format!(
                        "between the skin and the chest wall: {} cells of {h}, {} vertices held on the wall and {} on the box's faces",
                        report.cells, report.on_wall, report.on_box
                    ));
                    mesh_tets = Some(tets);
                    note.wall_faces = Some(report.wall_faces);
                    (body, kspring)
                }
                Geometry::Mesh(path)
                    if path
                        .extension()
                        .is_some_and(|e| e.eq_ignore_ascii_case("vtu") || e.eq_ignore_ascii_case("msh")) =>
                {
                    let mut tets = read_tetrahedra(path)?;
                    tets.positions.iter_mut().for_each(|p| *p = place(*p));
                    if tets.turned > 0 {
                        note.remarks.push(format!(
                            "{} tetrahedra were given in the negative order and turned",
                            tets.turned
                        ));
                    }
                    let edge = tets
                        .tets
                        .iter()
                        .map(|t| tets.positions[t[0] as usize].distance(tets.positions[t[1] as usize]))
                        .sum::<f32>()
                        / tets.tets.len() as f32;
                    let (material, kspring) = material_for(edge, cell_mass(edge));
                    let density = (m.density * s.powi(3)) as f32; // kg per cubic file unit
                    mesh_tets = Some(tets.tets.clone());
                    (tetrahedral_body(&tets, kspring, density, material, |_| Mode::Free)?, kspring)
                }
                _ => {
                    let (surface, remark) = surface(h)?;
                    note.remarks.extend(remark);
                    let (body, report) =
                        lattice_in_surface(&surface.positions, &surface.mesh, h, kspring, material, |_| {
                            Mode::Free
                        })?;
                    note.coverage = Some((report.coverage, report.uncovered));
                    if report.springs_outside > 0 {
                        note.remarks.push(format!(
                            "{} springs across gaps narrower than the spacing were left out",
                            report.springs_outside
                        ));
                    }
                    if report.uncovered > 0 {
                        note.remarks.push(format!(
                            "{} of {} surface vertices are more than a cell from the lattice: parts thinner than the spacing {h} are not held",
                            report.uncovered, report.surface_vertices
                        ));
                    }
                    (body, kspring)
                }
            }
        }
        BodyKind::Shell => {
            let edge = h.unwrap_or(1.0);
            let (material, kspring) = material_for(edge, cell_mass(edge));
            let (mut shell, kspring) = match &spec.geometry {
                Geometry::Shape(Shape::Sphere(_) | Shape::Ellipsoid(_)) => {
                    let radii = match &spec.geometry {
                        Geometry::Shape(Shape::Sphere(r)) => Vec3::splat(*r as f32),
                        Geometry::Shape(Shape::Ellipsoid(r)) => Vec3::from_array(r.map(|v| v as f32)),
                        _ => unreachable!("matched above"),
                    } * scale;
                    let segments =
                        ((std::f32::consts::TAU * radii.max_element() / edge).round() as u32).max(8);
                    let rings = (segments / 2).max(3);
                    let shell = if spec.rotation == [0.0; 3] {
                        ellipsoid_shell(offset, radii, rings, segments, 2.0, kspring, material)?
                    } else {
                        let mut shell =
                            ellipsoid_shell(Vec3::ZERO, radii, rings, segments, 2.0, kspring, material)?;
                        for p in shell.pos.iter_mut().chain(shell.rest_pos.iter_mut()) {
                            *p = rot * *p + offset;
                        }
                        shell
                    };
                    (shell, kspring)
                }
                _ => {
                    // Any other shape or a surface file: a shell of its surface.
                    let (surface, remark) = surface(edge)?;
                    note.remarks.extend(remark);
                    (shell_from_surface(&surface.positions, &surface.mesh, kspring, material)?, kspring)
                }
            };
            if let Some(f) = spec.flatten {
                // Flattened onto its lowest point (an implant's base): its heights above it
                // times f, its springs still the full shape's.
                note.full_shape = Some((shell.surface.area(&shell.pos), shell.enclosed_volume()));
                let base = shell.pos.iter().map(|p| p.z).fold(f32::MAX, f32::min);
                for p in shell.pos.iter_mut().chain(shell.rest_pos.iter_mut()) {
                    p.z = base + (p.z - base) * f as f32;
                }
                note.remarks.extend(flat_start_warning(&spec.geometry, f));
            }
            if spec.sink > 0.0 {
                for p in shell.pos.iter_mut().chain(shell.rest_pos.iter_mut()) {
                    p.z -= spec.sink as f32;
                }
            }
            (shell, kspring)
        }
        BodyKind::Rigid => {
            let edge = h.unwrap_or(1.0);
            let (material, kspring) = material_for(edge, cell_mass(edge));
            match &spec.geometry {
                Geometry::Shape(Shape::Cylinder { radius, height }) if spec.rotation == [0.0; 3] => {
                    let (radius, height) = (*radius as f32 * scale, *height as f32 * scale);
                    let rings = ((radius / edge).round() as u32).max(1);
                    let shape = CylinderShape {
                        base: offset - Vec3::new(0.0, 0.0, 0.5 * height),
                        radius,
                        height,
                        rings,
                        segments: (6 * rings).max(12),
                        layers: ((height / edge).round() as u32).max(1) + 1,
                    };
                    (cylinder(shape, kspring, material)?, kspring)
                }
                _ => {
                    let (surface, remark) = surface(edge)?;
                    note.remarks.extend(remark);
                    let mut edges: Vec<(u32, u32)> = surface
                        .mesh
                        .triangles
                        .iter()
                        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
                        .map(|(a, b)| (a.min(b), a.max(b)))
                        .collect();
                    edges.sort_unstable();
                    edges.dedup();
                    let springs = edges
                        .into_iter()
                        .map(|(i, j)| crate::body::Spring {
                            i,
                            j,
                            rest: surface.positions[i as usize].distance(surface.positions[j as usize]),
                            k: kspring,
                        })
                        .collect();
                    let n = surface.positions.len();
                    (
                        MassSpring::new(
                            surface.positions,
                            vec![Mode::Free; n],
                            springs,
                            surface.mesh,
                            material,
                        )?,
                        kspring,
                    )
                }
            }
        }
    };
    // Held vertices, and a rigid body's are all driven.
    let frame = Frame::of(&body);
    // A body between two surfaces is held on its chest wall and box unless `fixed` says otherwise.
    let between = matches!(spec.geometry, Geometry::Shape(Shape::Between(_)));
    for (i, p) in body.rest_pos.iter().enumerate() {
        if between && spec.fixed.is_empty() && spec.driven.is_empty() {
            break;
        }
        body.mode[i] = if spec.kind == BodyKind::Rigid || held(&spec.driven, *p, &frame) {
            Mode::Driven
        } else if held(&spec.fixed, *p, &frame) {
            Mode::Pinned
        } else {
            Mode::Free
        };
    }
    // Layers: a spring with both ends in a layer's region takes its stiffness, in proportion
    // to the one the body's material gave it (the elements' layers are below). A skin layer
    // (`depth`) is measured from the outer surface where the body is not held.
    let frame = if spec.layers.is_empty() { frame } else { Frame::of(&body) };
    let given: Vec<f32> = body.springs.iter().map(|s| s.k).collect();
    for layer in spec.layers.iter().filter(|_| !neo_hookean) {
        let ratio = (layer.young_kpa / m.young_kpa) as f32;
        let region = [layer.region];
        let inside: Vec<bool> = body.rest_pos.iter().map(|p| held(&region, *p, &frame)).collect();
        let mut springs = 0usize;
        for (s, k) in
            body.springs.iter_mut().zip(&given).filter(|(s, _)| inside[s.i as usize] && inside[s.j as usize])
        {
            s.k = k * ratio;
            springs += 1;
        }
        note.remarks.push(format!(
            "a layer of {} kPa: {springs} of {} springs",
            layer.young_kpa,
            body.springs.len()
        ));
    }
    note.vertices = body.len();
    // A soft body's tetrahedra: a mesh's own, or six per cell of its lattice.
    let tets = (spec.kind == BodyKind::Soft).then(|| {
        mesh_tets
            .unwrap_or_else(|| crate::material::neo_hookean::lattice_tets(&body.rest_pos, h.unwrap_or(1.0)))
    });
    // What gravity pulls: each vertex a quarter of each of its tetrahedra's mass, so that the
    // body weighs its density times its volume (a shell's vertex its wall's, as it was built).
    if let Some(tets) = &tets {
        body.mass = crate::bodies::tet_masses(&body.rest_pos, tets, m.density * s.powi(3))
            .into_iter()
            .map(|m| m as f32)
            .collect();
    }
    if neo_hookean {
        let tets = tets.unwrap_or_default();
        let young = m.young_kpa * 1e3 * s;
        let mut elements =
            crate::material::neo_hookean::Elements::new(&body.rest_pos, &tets, young, m.poisson)
                .map_err(|e| file.body_error(index, "material.model", e.to_string()))?;
        note.remarks.push(format!(
            "neo-hookean: {} tetrahedra, poisson = {} (the springs keep only their damping)",
            elements.tets.len(),
            m.poisson
        ));
        // Layers: a tetrahedron whose centre is in a layer's region takes its modulus (at the
        // body's Poisson ratio), as a finite-element code assigns a material to an element set.
        let centres: Vec<Vec3> = if spec.layers.is_empty() {
            Vec::new()
        } else {
            elements
                .tets
                .iter()
                .map(|t| t.iter().map(|&v| body.rest_pos[v as usize]).sum::<Vec3>() / 4.0)
                .collect()
        };
        for (l, layer) in spec.layers.iter().enumerate() {
            let region = [layer.region];
            let ratio = (layer.young_kpa / m.young_kpa) as f32;
            let mut count = 0usize;
            for (k, &centre) in centres.iter().enumerate() {
                if held(&region, centre, &frame) {
                    elements.modulus[k] = ratio;
                    count += 1;
                }
            }
            if count == 0 {
                return Err(file.body_error(
                    index,
                    &format!("layers[{l}]"),
                    "the layer's region holds no tetrahedron's centre: a \"neo-hookean\" body's layer takes the tetrahedra whose centres are in it, so it must be about as deep as they are; widen the region",
                ));
            }
            note.remarks.push(format!(
                "a layer of {} kPa: {count} of {} tetrahedra (by their centres)",
                layer.young_kpa,
                elements.tets.len()
            ));
        }
        body.elements = Some(elements);
        body.springs.iter_mut().for_each(|s| s.k = 0.0);
    } else if spec.kind != BodyKind::Rigid && (m.poisson - 0.25).abs() > 1e-9 {
        note.remarks.push(format!(
            "poisson = {}: a spring network has its own Poisson ratio (1/4 for a cubic lattice); Young's modulus is matched, the ratio is not",
            m.poisson
        ));
    }
    Ok((body, note, kspring))
}

/// A body's schedule: keyframes (time, offset from the first, rotation in degrees, ease) about
/// its pivot, final pressure or volume ratio, ramp and its ease, and floor.
struct BodySchedule {
    keys: Vec<(f64, Vec3, DVec3, Ease)>,
    pivot: Vec3,
    pressure: f32,
    /// The final volume over the first, for a shell inflated to a volume.
    growth: Option<f64>,
    /// And its fill: the first volume, the final one, and the fill's bulk modulus.
    fill: Option<(f64, f64, f32)>,
    /// An expander's schedule: (time, fraction of the way from the first volume to the last).
    steps: Vec<(f64, f64)>,
    ramp: f64,
    ease: Ease,
    floor: f32,
    /// How far below `floor` the floor starts, rising to it over the ramp.
    sink: f32,
    /// A fill's integral gain per step once it is full ([`StepInputs::fill_hold`]).
    hold: f32,
    /// Gravity, in file units per second squared (zero for none, and for a rigid body).
    gravity: Vec3,
    /// A placed implant's friction on the chest wall (0 for any other body), from the end of
    /// its ramp ([`StepInputs::wall_friction`]).
    friction: f32,
}

impl BodySchedule {
    /// The translation and rotation (degrees) of the keyframes at `t`: linear (or eased)
    /// between them, each Euler angle on its own, held after the last.
    fn pose(&self, t: f64) -> (Vec3, DVec3) {
        match self.keys.iter().position(|(kt, ..)| *kt >= t) {
            None => self.keys.last().map_or((Vec3::ZERO, DVec3::ZERO), |(_, p, r, _)| (*p, *r)),
            Some(0) => (self.keys[0].1, self.keys[0].2),
            Some(i) => {
                let ((t0, p0, r0, _), (t1, p1, r1, ease)) = (self.keys[i - 1], self.keys[i]);
                let u = ease.at(((t - t0) / (t1 - t0)) as f32);
                (p0.lerp(p1, u), r0.lerp(r1, f64::from(u)))
            }
        }
    }

    fn inputs(&self, t: f64, dt: f32) -> StepInputs {
        let (offset, degrees) = self.pose(t);
        let first = self.keys.first().map_or(DVec3::ZERO, |k| k.2);
        // Driven vertices rest where the first keyframe has them; they turn about the body's
        // position by the rotation since then.
        let (drive, turn) = if degrees == first {
            (offset, Mat3::IDENTITY)
        } else {
            let turn = rotation(degrees.to_array()) * rotation(first.to_array()).transpose();
            (offset + self.pivot - turn * self.pivot, turn)
        };
        let ramped = if !self.steps.is_empty() {
            along(&self.steps, t) as f32
        } else if self.ramp > 0.0 {
            self.ease.at((t / self.ramp) as f32)
        } else {
            1.0
        };
        // To a volume: rest lengths grow by the cube root of the volume reached so far.
        let rest_scale = self.growth.map_or(1.0, |g| (1.0 + (g - 1.0) * f64::from(ramped)).cbrt() as f32);
        // The fill's bulk modulus follows the volume it holds (see `fill_bulk`).
        let (fill_volume, fill_bulk) = self.fill.map_or((0.0, 0.0), |(start, end, bulk)| {
            let v = start + (end - start) * f64::from(ramped);
            (v as f32, (f64::from(bulk) * v / end) as f32)
        });
        StepInputs {
            dt,
            rest_scale,
            drive,
            turn,
            pressure: self.pressure * ramped,
            fill_volume,
            fill_bulk,
            // The integral term holds the final volume only: integrating the lag of a fill
            // still under way would overshoot it.
            fill_hold: if ramped >= 1.0 { self.hold } else { 0.0 },
            floor: if self.sink > 0.0 { self.floor - self.sink * (1.0 - ramped) } else { self.floor },
            gravity: self.gravity,
            // Filling, the base spreads on the wall; once in place, it grips it.
            wall_friction: if ramped >= 1.0 { self.friction } else { 0.0 },
        }
    }
}

/// `points` (time, value), from (0, 0), linearly at `t`, held after the last.
fn along(points: &[(f64, f64)], t: f64) -> f64 {
    let mut before = (0.0, 0.0);
    for &(pt, v) in points {
        if t < pt {
            return before.1 + (v - before.1) * (t - before.0) / (pt - before.0);
        }
        before = (pt, v);
    }
    before.1
}

/// The bulk modulus of a shell's fill: stiff enough to hold the volume against the tissue (a
/// 1 % deficit raises the pressure by 1 % of it), soft enough that the pressure's response to
/// the shell swelling as a whole, `bulk · A · a / V` per vertex for a surface of area `A`,
/// vertex area `a = A / N` and volume `V`, stays at half the stiffness `k` of its springs, so
/// that the springs' stability bound still holds: `bulk = k V N / (2 A²)`.
///
/// The bulk modulus at the end, for the shell's largest surface (its full shape's, or the
/// first grown by the fill): [`BodySchedule::inputs`] scales it with the volume the fill holds
/// at each step, so that the bound holds from the first (small) volume to the last.
fn fill_bulk(shell: &MassSpring, k: f32, target: f64, full: Option<(f64, f64)>) -> f32 {
    let start = shell.surface.area(&shell.pos);
    let grown = start * (target / shell.enclosed_volume()).cbrt().powi(2).max(1.0);
    let area = full.map_or(grown, |(a, _)| a.max(start));
    (0.5 * f64::from(k) * target * shell.len() as f64 / (area * area)) as f32
}

/// The scene's gravity (`[world] gravity`, m/s²) in file units per second squared.
#[must_use]
pub fn gravity(file: &SceneFile) -> Vec3 {
    file.world.gravity.map_or(Vec3::ZERO, |g| (DVec3::from_array(g) / file.metres()).as_vec3())
}

/// Landmark `name`, given at `p` on body `k` of `file` (built as `b`): moved onto the body's
/// outer surface, its nearest point, and carried by that triangle's corners from then on.
///
/// # Errors
/// [`Error::Invalid`] naming the file and the body's `landmarks` key for a landmark farther
/// than twice the body's spacing from its surface.
fn landmark_on(
    file: &SceneFile,
    k: usize,
    name: &str,
    p: [f64; 3],
    b: &MassSpring,
) -> Result<Landmark, Error> {
    let spec = &file.bodies[k];
    let given = Vec3::from_array(p.map(|v| v as f32));
    let q = given.as_dvec3();
    let mut best = (f64::INFINITY, [0u32; 3], DVec3::ZERO);
    let (points, shown) = b.shown_at(&b.pos);
    for t in &shown.triangles {
        let corners = t.map(|i| points[i as usize].as_dvec3());
        let c = crate::geometry::closest_point(q, &corners);
        let d = c.distance(q);
        if d < best.0 {
            best = (d, *t, c);
        }
    }
    let reach = 2.0 * f64::from(spec.spacing.unwrap_or(1.0) as f32);
    if best.0.is_nan() || best.0 > reach {
        return Err(file.body_error(
            k,
            "landmarks",
            format!(
                "landmark {name:?} at {p:?} is {:.3} {} from the body's surface, more than twice its spacing: put it on the skin",
                best.0,
                file.units.symbol()
            ),
        ));
    }
    let [a, b2, c] = best.1.map(|i| points[i as usize].as_dvec3());
    // Barycentric weights of the closest point.
    let (v0, v1, v2) = (b2 - a, c - a, best.2 - a);
    let (d00, d01, d11, d20, d21) = (v0.dot(v0), v0.dot(v1), v1.dot(v1), v2.dot(v0), v2.dot(v1));
    let den = d00 * d11 - d01 * d01;
    let (wb, wc) =
        if den > 0.0 { ((d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den) } else { (0.0, 0.0) };
    Ok(Landmark {
        name: name.to_string(),
        given,
        triangle: best.1,
        weights: [(1.0 - wb - wc) as f32, wb as f32, wc as f32],
    })
}

/// What body `k` of `file` (built as `bodies[k]`, with the bodies' spring `stiffness`, their
/// `fills` and build `notes`) is given at each step: its keyframes (time, offset from the
/// first, rotation), its final pressure or volume and its ramp, its floor and its gravity
/// (`hold`: a fill's integral pace under the explicit integrator).
fn body_schedule(
    file: &SceneFile,
    k: usize,
    (bodies, stiffness, fills, notes): (&[MassSpring], &[f32], &[Fill], &[BodyNote]),
    (implicit, hold): (bool, f32),
) -> BodySchedule {
    let s = file.metres();
    let b = &file.bodies[k];
    let base = b.motion.first().map_or(DVec3::ZERO, |m| DVec3::from_array(m.position));
    let keys = b
        .motion
        .iter()
        .map(|m| {
            (m.t, (DVec3::from_array(m.position) - base).as_vec3(), DVec3::from_array(m.rotation), m.ease)
        })
        .collect();
    let (mut pressure, mut growth, mut fill, mut ramp, mut ease) = (0.0, None, None, 0.0, Ease::Linear);
    let mut steps = Vec::new();
    if let Some(i) = &b.inflate {
        (ramp, ease) = (i.ramp, i.ease);
        pressure = (i.pressure_kpa.unwrap_or(0.0) * 1e3 * s) as f32;
        if let Some((start, target)) = fills[k] {
            growth = b.flatten.is_none().then_some(target / start);
            let bulk = fill_bulk(&bodies[k], stiffness[k], target, notes[k].full_shape);
            // The implicit solve takes the fill's bulk response whole: a fill as
            // incompressible as the liquid it stands for.
            let bulk = if implicit { IMPLICIT_BULK * bulk } else { bulk };
            fill = Some((start, target, bulk));
            // The schedule's volumes as fractions of the way from the first to the last.
            let span = target - start;
            steps = i
                .schedule
                .iter()
                .map(|&[t, ml]| {
                    let v = ml * 1e-6 / s.powi(3);
                    (t, if span.abs() > 0.0 { (v - start) / span } else { 1.0 })
                })
                .collect();
        }
    }
    BodySchedule {
        keys,
        pivot: Vec3::from_array(b.position.map(|v| v as f32)),
        pressure,
        growth,
        fill,
        steps,
        ramp,
        ease,
        // On a curved wall the floor is the wall itself, raised by `floor` along its normal.
        floor: match (bodies[k].wall.is_some(), b.floor) {
            (true, f) => f.unwrap_or(0.0) as f32,
            (false, f) => f.map_or(f32::MIN, |f| f as f32),
        },
        sink: b.sink as f32,
        hold: if fill.is_some() && !implicit { hold } else { 0.0 },
        gravity: if b.kind == BodyKind::Rigid { Vec3::ZERO } else { gravity(file) },
        friction: b.place.as_ref().map_or(0.0, |p| p.friction as f32),
    }
}

/// The pocket of body `k` of `file` where it is an implant placed on a patient and in contact
/// with her tissue (`bodies` as built, with their `fills` and build `notes`): closed around it
/// (crate::pocket), its suction adding up at the pace `hold` a fill's does. `None` for any
/// other body.
fn pocket(
    file: &SceneFile,
    k: usize,
    (bodies, fills, notes): (&[MassSpring], &[Fill], &[BodyNote]),
    hold: f32,
) -> Option<crate::pocket::Pocket> {
    let s = file.metres();
    let place = file.bodies[k].place.as_ref()?;
    let t = place.body;
    let touching = file.contacts.iter().any(|c| (c.a, c.b) == (k, t) || (c.a, c.b) == (t, k));
    let wall_faces = notes[t].wall_faces.as_ref().filter(|_| touching)?;
    let tissue = &bodies[t];
    let faces = wall_faces
        .iter()
        .map(|&f| tissue.surface.triangles[f as usize])
        .filter(|f| f.iter().any(|&i| tissue.mode[i as usize] == Mode::Free))
        .collect();
    let young = file.bodies[t].material.young_kpa * 1e3;
    let stiffness = (crate::pocket::SUCTION * young * s) as f32;
    let volume = fills[k].map_or_else(|| bodies[k].enclosed_volume(), |(_, target)| target);
    Some(crate::pocket::Pocket { tissue: t, implant: k, faces, stiffness, volume, hold, held: 0.0 })
}

/// The warning for an implant started flattened to `f` of its height whose outline is nearly a
/// cylinder ([`crate::bodies::FLAT_START_EXPONENT`]); `None` for any other shell.
fn flat_start_warning(geometry: &Geometry, f: f64) -> Option<String> {
    let Geometry::Shape(Shape::Implant { volume_ml, base_mm, projection_mm, .. }) = geometry else {
        return None;
    };
    // (mm and mm³: the exponent has no units.)
    let shape = ImplantShape {
        volume: volume_ml * 1e3,
        base: *base_mm,
        projection: *projection_mm,
        anatomical: false,
    };
    let alpha = shape.exponent().ok()?;
    (alpha < crate::bodies::FLAT_START_EXPONENT).then(|| {
        // The base and projection that would hold the volume at the fullest exponent not warned of.
        let cylinder = |base: f64, projection: f64| std::f64::consts::PI * (0.5 * base).powi(2) * projection;
        let fits = 1e3 * volume_ml * (1.0 + crate::bodies::FLAT_START_EXPONENT);
        format!(
            "warning: {volume_ml} mL on a {base_mm} mm base at {projection_mm} mm is nearly a cylinder (profile exponent {alpha:.3}; a manufacturer's round implants are 0.19 to 0.51): started flattened to {:.0} % of its height, its upright rim springs open in the first steps, fast enough that the run may stop as a blow-up; a base of {:.0} mm, or a projection of {:.0} mm, gives it a rounder outline",
            100.0 * f,
            2.0 * (fits / (std::f64::consts::PI * projection_mm)).sqrt(),
            fits / cylinder(*base_mm, 1.0),
        )
    })
}

/// A shell filled to a volume: the volume it encloses at first and its target, in cubic file
/// units; `None` for any other body.
type Fill = Option<(f64, f64)>;

/// The step a world's contacts are sized for: the time step, the bodies' stability bound, and
/// whether the implicit integrator steps them.
#[derive(Clone, Copy)]
struct Timing {
    dt: f32,
    stable: f32,
    implicit: bool,
}

/// Contact `c` of `file` between its built `bodies` (with each body's spring `stiffness` and
/// each filled shell's start and target volumes, `fills`): its reach, voxel, stiffness and
/// response where the file leaves them to be worked out, its grid, and its model.
///
/// # Errors
/// [`Error::Invalid`] naming the pair for parameters the response or the surface contact
/// refuses; the grid's errors.
fn contact_pair(
    file: &SceneFile,
    c: &ContactSpec,
    (bodies, stiffness, fills): (&[MassSpring], &[f32], &[Fill]),
    Timing { dt, stable, implicit }: Timing,
) -> Result<ContactPair, Error> {
    let s = file.metres();
    let spacing = |k: usize| file.bodies[k].spacing.unwrap_or(1.0) as f32;
    // A shell filled or inflated grows its edges with it: the plane of the three nearest
    // needs them within the radius wherever b meets a face (a face's centre is 1/√3 of an
    // edge from its corners), so the radius and the voxel follow the grown edge.
    let edge_growth = |k: usize| -> f32 {
        match (file.bodies[k].inflate.as_ref(), fills[k]) {
            (None, _) => 1.0,
            _ if file.bodies[k].flatten.is_some() => 1.0,
            (Some(_), Some((start, target))) => (target / start).cbrt().max(1.0) as f32,
            (Some(_), None) => 1.6,
        }
    };
    let grown = |k: usize| spacing(k) * edge_growth(k);
    let h = spacing(c.a).max(spacing(c.b));
    // (The paper's constant response keeps the rules it was shipped with: 0.75 h.)
    let reach = match c.response {
        ResponseSpec::Penalty | ResponseSpec::Surface => {
            (0.75 * h).max(0.65 * grown(c.a)).max(0.65 * grown(c.b))
        }
        ResponseSpec::Constant => 0.75 * h,
    };
    let voxel = match c.voxel_size {
        Auto::Value(v) => v as f32,
        Auto::Auto => 2f32.powi(h.max(reach).log2().ceil() as i32),
    };
    let radius = match c.radius {
        Auto::Value(r) => r as f32,
        Auto::Auto => reach.min(voxel),
    };
    // The penalty's stiffness: half of what the step allows the lightest free vertex of the
    // pair, `0.5 m / dt²` (a contact spring adds `k/m` to the `omega²` whose bound is
    // `4/dt²`, of which the bodies' springs take a quarter at the automatic step), so that
    // a depth is pushed out within a few steps, whatever the load.
    let lightest = [c.a, c.b]
        .iter()
        .flat_map(|&k| {
            let b = &bodies[k];
            b.inv_mass.iter().zip(&b.mode).filter(|(_, m)| **m == Mode::Free).map(|(im, _)| 1.0 / *im)
        })
        .fold(f32::MAX, f32::min);
    let lightest = if lightest == f32::MAX { 1.0 / bodies[c.b].inv_mass[0] } else { lightest };
    // Under the implicit integrator the contact's stiffness enters the solve, so it keeps
    // the explicit bound's (a property of the bodies, not of the step), but at most
    // IMPLICIT_CONTACT times the softer body's springs: the bound follows the stiffer body
    // (a 3,000 kPa shell's bound is a thousand times a 1 kPa tissue's springs), and a
    // contact far stiffer than what it pushes only makes the solve ill-conditioned and its
    // residual at rest noise (a hundredth of a millimetre of depth is then a force no
    // spring of the tissue can balance). A hundred times the softer springs still keeps the
    // depth under load within a hundredth of its spacing times its strain.
    let material_dt = if implicit { stable.min(dt) } else { dt };
    let softer = [c.a, c.b]
        .iter()
        .filter(|&&k| bodies[k].mode.contains(&Mode::Free))
        .map(|&k| stiffness[k])
        .fold(f32::MAX, f32::min);
    let contact_k = match c.stiffness {
        Auto::Value(n_per_m) => n_per_m as f32,
        Auto::Auto if implicit && softer < f32::MAX => {
            (0.5 * lightest / (material_dt * material_dt)).min(IMPLICIT_CONTACT * softer)
        }
        Auto::Auto => 0.5 * lightest / (material_dt * material_dt),
    };
    let gap = match c.gap {
        Auto::Value(g) => g as f32,
        Auto::Auto => 0.0,
    };
    let response = match c.response {
        ResponseSpec::Constant => Response::Constant,
        ResponseSpec::Penalty | ResponseSpec::Surface => Response::Penalty { stiffness: contact_k, gap },
    };
    // The surface contact pushes from as deep as the contact's bound (its voxel size): a
    // vertex beyond it has failed the contact, and from farther than half a thin body's
    // thickness its nearest surface point is on the far side.
    let surface = (c.response == ResponseSpec::Surface).then_some(SurfacePenalty {
        stiffness: contact_k,
        gap,
        reach: voxel.max(2.0 * gap),
        // The implicit solve sees a contact a quarter of the reach before it arrives.
        margin: if implicit { 0.25 * voxel.max(2.0 * gap) } else { 0.0 },
    });
    let magnitude = match (c.magnitude, c.response) {
        (Auto::Value(newtons), _) => (newtons / s) as f32,
        (Auto::Auto, ResponseSpec::Constant) => 4.0 * stiffness[c.b] * spacing(c.b),
        // The penalty's largest force: at a depth of two voxels, twice the contact's bound,
        // so that it never caps a contact that holds.
        (Auto::Auto, ResponseSpec::Penalty | ResponseSpec::Surface) => contact_k * 2.0 * voxel,
    };
    let params = ContactParams {
        magnitude,
        search: match c.search {
            SearchSpec::Neighbours => Search::Neighbours { radius },
            SearchSpec::Voxel => Search::Voxel,
        },
        direction: match c.direction {
            DirectionSpec::Pairwise => Direction::Pairwise,
            DirectionSpec::PlaneNormal => Direction::PlaneNormal,
        },
        anchor: Anchor::FollowA,
    };
    // Two voxels of margin, and room for an inflating shell to grow by 60 % of its size (the
    // grid keeps its dims as it follows A; what leaves it is discarded).
    let a = &bodies[c.a].pos;
    let growth = match (file.bodies[c.a].inflate.as_ref(), fills[c.a]) {
        (None, _) => 0.0,
        // Flattened: it rises to its full height.
        (Some(_), Some(_)) if file.bodies[c.a].flatten.is_some() => {
            (1.0 / file.bodies[c.a].flatten.unwrap_or(1.0)).min(10.0) as f32 - 0.8
        }
        // To a volume: its linear growth, and a fifth of its size more.
        (Some(_), Some((start, target))) => (target / start).cbrt().clamp(1.0, 10.0) as f32 - 0.8,
        (Some(_), None) => 0.6,
    };
    let margin = if growth > 0.0 {
        let (lo, hi) = a.iter().fold((Vec3::MAX, Vec3::MIN), |(l, h), p| (l.min(*p), h.max(*p)));
        (growth * (hi - lo).max_element() / voxel).ceil() as u32 + 2
    } else {
        2
    };
    let grid = Initializer::new(voxel).margin(margin).build(a)?;
    response.validate(&params, &grid).map_err(|e| Error::Invalid {
        what: "contact",
        value: format!("{} – {}", file.bodies[c.a].name, file.bodies[c.b].name),
        rule: e.to_string(),
    })?;
    let model = match surface {
        Some(surface) => {
            surface.validate().map_err(|e| Error::Invalid {
                what: "contact",
                value: format!("{} – {}", file.bodies[c.a].name, file.bodies[c.b].name),
                rule: e.to_string(),
            })?;
            ContactModel::Surface(surface)
        }
        None => ContactModel::Voxel(response),
    };
    Ok(ContactPair { a: c.a, b: c.b, grid, params, model })
}

/// Builds the world of `file`.
///
/// # Errors
/// The errors of reading its meshes ([`Error::Mesh`]), of making its bodies
/// ([`Error::Invalid`] naming the body), and [`Error::SceneFile`] for a shape not built yet.
pub fn build_world(file: &SceneFile) -> Result<Built, Error> {
    build_world_reusing(file, &Recoveries::default())
}

/// The unloaded shapes that builds have recovered ([`crate::reference::unload`]), for later
/// builds of the same bodies to reuse ([`build_world_reusing`]): `voxcollide compare` builds
/// one world per candidate implant around the same patient, whose recovery is the same each
/// time and took the most of each build (a body as scanned at a 6 mm spacing: several static
/// solves).
#[derive(Debug, Default)]
pub struct Recoveries {
    found: std::sync::Mutex<Vec<Recovery>>,
}

/// A body as its unloaded shape was recovered: what it was built from, and the body after.
#[derive(Debug)]
struct Recovery {
    path: std::path::PathBuf,
    units: crate::scene_file::Units,
    spec: BodySpec,
    body: MassSpring,
    recovered: crate::reference::Recovered,
}

impl Recoveries {
    /// How many bodies' unloaded shapes are kept.
    #[must_use]
    pub fn len(&self) -> usize {
        self.found.lock().map_or(0, |f| f.len())
    }

    /// Whether none is.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// [`build_world`], taking each body's unloaded shape from `recoveries` where an earlier build
/// recovered it for the same body (the same [`BodySpec`], in a file at the same path in the
/// same units: a body is built from those alone, and its recovery is deterministic, so the
/// world is the one [`build_world`] builds, bit for bit), and keeping there the ones it
/// recovers itself.
///
/// # Errors
/// As [`build_world`].
pub fn build_world_reusing(file: &SceneFile, recoveries: &Recoveries) -> Result<Built, Error> {
    let s = file.metres();
    let mut bodies = Vec::with_capacity(file.bodies.len());
    let mut notes = Vec::with_capacity(file.bodies.len());
    let mut stiffness = Vec::with_capacity(file.bodies.len());
    for spec in &file.bodies {
        let (body, note, kspring) = body(file, spec).map_err(|e| match e {
            Error::Invalid { what, value, rule } => {
                Error::Invalid { what, value: format!("{value} (body {:?})", spec.name), rule }
            }
            e => e,
        })?;
        bodies.push(body);
        notes.push(note);
        stiffness.push(kspring);
    }
    // A body given as measured under gravity: its unloaded shape, found before anything else
    // is sized from it (docs/design.md §13).
    for (k, spec) in file.bodies.iter().enumerate() {
        let Some(g) = spec.reference else { continue };
        let same = |r: &Recovery| r.path == file.path && r.units == file.units && r.spec == *spec;
        let found = recoveries
            .found
            .lock()
            .ok()
            .and_then(|f| f.iter().find(|r| same(r)).map(|r| (r.body.clone(), r.recovered)));
        let recovered = match found {
            Some((body, recovered)) => {
                bodies[k] = body;
                recovered
            }
            None => {
                let g = (DVec3::from_array(g) / s).as_vec3();
                let recovered = crate::reference::unload(&mut bodies[k], g).map_err(|e| {
                    file.body_error(k, "reference", format!("recovering the unloaded shape failed: {e}"))
                })?;
                if let Ok(mut f) = recoveries.found.lock() {
                    f.push(Recovery {
                        path: file.path.clone(),
                        units: file.units,
                        spec: spec.clone(),
                        body: bodies[k].clone(),
                        recovered,
                    });
                }
                recovered
            }
        };
        notes[k].reference = Some(recovered);
    }
    // Landmarks: each moved onto its body's outer surface, no farther than twice its spacing.
    for (k, spec) in file.bodies.iter().enumerate() {
        for (name, p) in &spec.landmarks {
            let landmark = landmark_on(file, k, name, *p, &bodies[k])?;
            notes[k].landmarks.push(landmark);
        }
    }
    // Shells placed on a patient's chest wall under a landmark (docs/design.md §15).
    for k in 0..file.bodies.len() {
        if let Some(place) = &file.bodies[k].place {
            let Placed { released, thinnest, note } = place_on_wall(file, k, place, &mut bodies, &notes)?;
            let PlacedNote { moved, overreach, .. } = note;
            notes[k].placed = Some(note);
            let tissue = &file.bodies[place.body].name;
            let u = file.units.symbol();
            notes[k].remarks.push(format!(
                "placed on {tissue:?}'s chest wall under {:?}: the pocket lets go {released} of {tissue:?}'s vertices held on the wall, over the base and a margin of {} {u}; friction on the wall {}",
                place.landmark, place.margin, place.friction
            ));
            if place.contact_added {
                notes[k].remarks.push(format!(
                    "no [[contact]] pairs it with {tissue:?}: the default contact between them added (a = {:?}, b = {tissue:?})",
                    file.bodies[k].name
                ));
            }
            if moved.length() > 0.0 {
                notes[k].remarks.push(format!(
                    "its base's centre moved {:.1} {u} along the wall, by [{:.1}, {:.1}, {:.1}], from under {:?} to keep its rim within {:?}",
                    moved.length(),
                    moved.x,
                    moved.y,
                    moved.z,
                    place.landmark,
                    place.within
                ));
            }
            if overreach > 0.0 {
                notes[k].remarks.push(format!(
                    "warning: its base is too wide for {tissue:?}'s borders {:?}: centred between them, it still reaches {overreach:.1} {u} past one; a narrower base fits her",
                    place.within
                ));
            }
            // Tissue under one and a half cells thick over the rim: a lattice that coarse may
            // not hold the implant under it (docs/patient.md; a rule of thumb from the MakeHuman
            // patient, where 12 mm held at 7 mm and not at 10).
            let h = file.bodies[place.body].spacing.unwrap_or(1.0) as f32;
            if let Some((thick, at)) = thinnest
                && thick < 1.5 * h
            {
                notes[k].remarks.push(format!(
                    "warning: {tissue:?} is {thick:.1} {u} thick over the implant's rim at [{:.1}, {:.1}, {:.1}], under one and a half of its cells ({h} {u}): a lattice that coarse may let the implant come through it, which the run checks and says; a spacing of {:.1} {u} or finer holds more",
                    at.x,
                    at.y,
                    at.z,
                    thick / 1.5
                ));
            }
        }
    }
    // Per shell filled to a volume: the volume it encloses at first and its target, in cubic
    // file units (the voxel model's margin and the schedule both follow from them).
    let mut fills: Vec<Fill> = Vec::with_capacity(file.bodies.len());
    for (k, b) in file.bodies.iter().enumerate() {
        let Some(ml) = b.inflate.as_ref().and_then(|i| i.volume_ml) else {
            fills.push(None);
            continue;
        };
        let start = bodies[k].enclosed_volume();
        let target = ml * 1e-6 / s.powi(3);
        if !(start > 0.0 && target > 0.0) {
            return Err(file.body_error(k,
                "inflate.volume_ml",
                format!(
                    "the shell encloses {start:.4e} cubic {}; inflating to a volume needs a closed, outward shell and a positive volume",
                    file.units.symbol()
                ),
            ));
        }
        // The rest shape grows by the cube root of the ratio: beyond a thousandfold (ten times
        // the size) the springs and the voxel model's margin cannot follow.
        let ratio = target / start;
        // A flattened shell's rest shape does not grow: it fills to its own shape's volume.
        let flattened = b.flatten.is_some();
        if !flattened && !(1e-3..=1e3).contains(&ratio) {
            let ml_of = |v: f64| v * s.powi(3) * 1e6;
            return Err(file.body_error(k,
                "inflate.volume_ml",
                format!(
                    "{ml} mL is {ratio:.3e} times the {:.4} mL the shell encloses; a shell filled to a volume can change it at most a thousandfold either way",
                    ml_of(start)
                ),
            ));
        }
        // An expander's schedule only fills: from what the shell holds at first, upwards.
        if let Some(&[t, first]) = b.inflate.as_ref().and_then(|i| i.schedule.first())
            && first * 1e-6 / s.powi(3) < start * (1.0 - 1e-6)
        {
            return Err(file.body_error(
                k,
                "inflate.schedule",
                format!(
                    "its first fill, {first} mL at {t} s, is below the {:.4} mL the shell holds at the start: an expander's schedule only fills",
                    start * s.powi(3) * 1e6
                ),
            ));
        }
        fills.push(Some((start, target)));
    }
    // A shell filled to a volume weighs its fill: the fill's mass (the body's density times the
    // volume it is filled to) shared over the shell's vertices by the area about each, which is
    // where a liquid's weight presses on its wall. Its wall's own weight is left out: the
    // lattice's wall is as thick as its edge for the step's sake (a 6 mm wall would weigh as
    // much as a 300 mL fill), an implant's shell is a millimetre of silicone. (Its inertia is
    // the wall's: the step's bound does not change.)
    for (k, fill) in fills.iter().enumerate() {
        let Some((_, target)) = fill else { continue };
        let b = &mut bodies[k];
        let fill_mass = file.bodies[k].material.density * target * s.powi(3);
        let mut area = vec![0.0f64; b.len()];
        for t in &b.surface.triangles {
            let [p, q, r] = t.map(|i| b.pos[i as usize].as_dvec3());
            let third = (q - p).cross(r - p).length() / 6.0;
            t.iter().for_each(|&i| area[i as usize] += third);
        }
        let total: f64 = area.iter().sum();
        if total > 0.0 {
            for (m, a) in b.mass.iter_mut().zip(&area) {
                *m = (fill_mass * a / total) as f32;
            }
        }
    }
    // Only bodies that move by their springs bound the step: a rigid body's vertices are all
    // driven, and its material is only nominal.
    let stable = bodies
        .iter()
        .filter(|b| b.mode.contains(&Mode::Free))
        .map(|b| b.stable_dt(0.3))
        .fold(f32::MAX, f32::min);
    let implicit = file.time.integrator == IntegratorSpec::Implicit;
    let dt = match file.time.dt {
        Auto::Value(dt) => dt as f32,
        // The implicit step is chosen for accuracy: the schedule in IMPLICIT_STEPS steps, at
        // most IMPLICIT_DT, never below the explicit bound.
        Auto::Auto if implicit => match (file.time.steps, file.time.duration) {
            (None, Some(d)) => ((d / IMPLICIT_STEPS) as f32).min(IMPLICIT_DT).max(stable),
            _ => stable,
        },
        Auto::Auto => stable,
    };
    if !(dt.is_finite() && dt > 0.0) {
        return Err(Error::Invalid {
            what: "time step",
            value: dt.to_string(),
            rule: "the bodies give no finite stability bound; give [time] dt".into(),
        });
    }
    let timing = Timing { dt, stable, implicit };
    let contacts = file
        .contacts
        .iter()
        .map(|c| contact_pair(file, c, (&bodies, &stiffness, &fills), timing))
        .collect::<Result<Vec<_>, Error>>()?;
    let steps = match (file.time.steps, file.time.duration) {
        (Some(n), _) => n,
        (None, Some(d)) => ((d / f64::from(dt)).ceil() as u64).max(1),
        (None, None) => 1,
    };
    // An expander's schedule runs within the run: a settling run would stop at a pause.
    let end = steps as f64 * f64::from(dt);
    for (k, b) in file.bodies.iter().enumerate() {
        if let Some(&[t, _]) = b.inflate.as_ref().and_then(|i| i.schedule.last())
            && t > end * (1.0 + 1e-9)
        {
            return Err(file.body_error(
                k,
                "inflate.schedule",
                format!("its last fill is at {t} s, after the run's {end} s: lengthen the run ([time] duration or steps)"),
            ));
        }
    }
    let extent = bodies
        .iter()
        .flat_map(|b| b.pos.iter())
        .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let size = (extent.1 - extent.0).max_element().max(f32::MIN_POSITIVE);
    let names: Vec<String> = file.bodies.iter().map(|b| b.name.clone()).collect();
    // Per body: its keyframes (time, offset from the first, rotation), its final pressure or
    // volume and its ramp.
    let mut schedule_specs = Vec::with_capacity(file.bodies.len());
    // A fill's integral time is twice the bodies' response time, so that the integral term is
    // slower than the mechanics it steers (a faster one rings); the implicit solve holds a fill
    // through its bulk term alone.
    let hold = (f64::from(dt) / (2.0 * crate::world::response_time(&bodies)).max(f64::from(dt))) as f32;
    for k in 0..file.bodies.len() {
        schedule_specs.push(body_schedule(file, k, (&bodies, &stiffness, &fills, &notes), (implicit, hold)));
    }
    let schedule = std::sync::Arc::new(move |step: u64| {
        let t = (step + 1) as f64 * f64::from(dt);
        schedule_specs.iter().map(|b| b.inputs(t, dt)).collect()
    });
    // Each placed implant's pocket, closed around it (crate::pocket), where it touches its
    // tissue; its suction adds up at the pace a fill's does.
    let pockets =
        (0..file.bodies.len()).filter_map(|k| pocket(file, k, (&bodies, &fills, &notes), hold)).collect();
    // A vertex that moves a tenth of the scene in one step has blown up.
    let mut world = World::new(names, bodies, contacts, 0.1 * size / dt, schedule)?;
    world.pockets = pockets;
    if implicit {
        // No vertex moves more than a quarter of the finest contact's reach in a step, so that
        // every contact sees it arrive; a step that would move one farther is taken as shorter
        // parts.
        let max_move = world
            .contacts
            .iter()
            .map(|c| match c.params.search {
                Search::Neighbours { radius } => radius.min(c.grid.voxel_size()),
                Search::Voxel => c.grid.voxel_size(),
            })
            .fold(f32::INFINITY, f32::min)
            * 0.25;
        world = world.with_integrator(Integrator::Implicit(ImplicitSettings {
            max_move,
            split_far: true,
            ..ImplicitSettings::default()
        }));
    }
    Ok(Built { world, dt, steps, notes })
}
