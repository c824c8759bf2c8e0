//! A mass-spring body: vertices with velocities, nonlinear springs, pinned and driven vertices,
//! its surface, and the CPU force and integration steps (the CPU twins of `shaders/forces.wgsl`
//! and `shaders/integrate.wgsl`).

use glam::{Mat3, Vec3};

use crate::integrator::{move_held, onto_floor};
use crate::material::{self, springs::Springs};
use crate::mesh::TriangleMesh;
use voxcollide::error::Error;
use voxcollide::math::{cross, dot};

/// How a vertex moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum Mode {
    /// Integrated from its forces.
    Free = 0,
    /// Held at its rest position.
    Pinned = 1,
    /// Held at its rest position plus the body's drive offset (a kinematic boundary).
    Driven = 2,
}

/// A spring between two vertices with rest length `rest` and stiffness `k`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring {
    /// One end.
    pub i: u32,
    /// The other end.
    pub j: u32,
    /// Rest length at rest scale 1.
    pub rest: f32,
    /// Stiffness (force per unit of extension at small strain).
    pub k: f32,
}

/// The material and integration constants of a body.
///
/// **Spring law** (nonlinear, strain-stiffening, as soft tissue is): with length `L`, rest
/// length `L0 = rest * rest_scale` and strain `s = (L - L0) / L0`, the spring pulls its ends
/// together with `f = k * (L - L0) * (1 + stiffening * s^2)` along the spring, plus damping
/// `spring_damping * dot(v_j - v_i, u)` along it. Every vertex also feels `-damping * v`
/// (a viscous medium) and its contact force.
///
/// **Integrator**: semi-implicit (symplectic) Euler, `v += dt * f / mass; x += dt * v`. It is
/// stable while `dt <= 2 / omega_max` with `omega_max^2 = max over vertices of 4 * (sum of its
/// springs' k) * (1 + 3 * stiffening * s_max^2) / mass_i` (the Gershgorin bound of the
/// stiffness matrix at strain `s_max`); [`MassSpring::stable_dt`] returns half of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Mass of every vertex.
    pub mass: f32,
    /// The `stiffening` factor of the spring law (0: linear springs).
    pub stiffening: f32,
    /// Damping along each spring.
    pub spring_damping: f32,
    /// Viscous damping of every vertex.
    pub damping: f32,
}

/// A lattice of vertices joined by springs.
#[derive(Clone, Debug)]
pub struct MassSpring {
    /// Where each vertex starts (and where pinned and driven vertices are anchored).
    pub rest_pos: Vec<Vec3>,
    /// Current positions.
    pub pos: Vec<Vec3>,
    /// Current velocities.
    pub vel: Vec<Vec3>,
    /// How each vertex moves.
    pub mode: Vec<Mode>,
    /// The springs.
    pub springs: Vec<Spring>,
    /// The outer surface, for pictures, files and the inside test.
    pub surface: TriangleMesh,
    /// Material constants.
    pub material: Material,
    /// Per vertex, its springs as `(other vertex, spring index)`, in CSR form: the entries of
    /// vertex `i` are `adjacency[offsets[i]..offsets[i + 1]]`. Forces are summed in this order
    /// on the CPU and the GPU alike.
    pub offsets: Vec<u32>,
    /// See `offsets`.
    pub adjacency: Vec<[u32; 2]>,
    /// Per vertex, its share of the body's mass in kilograms: what gravity pulls
    /// ([`StepInputs::gravity`]). A lattice's vertex carries an eighth of each cell it is a
    /// corner of (a quarter of each tetrahedron), so that the body weighs its density times
    /// its volume; its inertia is the lumped [`inv_mass`](Self::inv_mass), which weighs
    /// boundary vertices as whole cells for the springs' stable step.
    pub mass: Vec<f32>,
    /// Per vertex, `1 / mass`: the material's mass scaled by the vertex's spring count over
    /// [`REFERENCE_DEGREE`] (at least 1), so that hubs (poles, axes) are not the stiffest
    /// oscillators and do not dictate the time step.
    pub inv_mass: Vec<f32>,
    /// Per vertex, the surface triangles around it, in CSR form like `offsets`/`adjacency`
    /// (for the pressure force).
    pub tri_offsets: Vec<u32>,
    /// See `tri_offsets`.
    pub tri_adjacency: Vec<u32>,
    /// The user's own surface carried by the body (a lattice filling a closed surface): what
    /// pictures, VTK files and penetration use instead of [`surface`](Self::surface); `None`
    /// for a body whose own surface is the user's.
    pub embedded: Option<Embedding>,
    /// The pressure a fill has built up to hold its volume (see [`StepInputs::fill_hold`]); 0
    /// at the start.
    pub held_pressure: f32,
    /// Finite elements (docs/design.md §12's `"neo-hookean"`): their forces add to the springs' (a
    /// body of elements keeps its springs for its damping only, their stiffness 0); `None`
    /// for the paper's spring lattice.
    pub elements: Option<crate::material::neo_hookean::Elements>,
    /// Where the body started, where that is not its rest shape: a body given as measured
    /// under gravity starts loaded, at the shape given (docs/design.md §13). `None`: it started
    /// at rest. What moved is measured from here ([`start`](Self::start)).
    pub started: Option<Vec<Vec3>>,
    /// A curved chest wall as its floor (docs/design.md §15): its free vertices are kept in
    /// front of it, raised by [`StepInputs::floor`] along its normal, with the step's
    /// [`StepInputs::wall_friction`]. `None`: the floor is the plane `z = floor`.
    pub wall: Option<std::sync::Arc<crate::wall::Wall>>,
    /// The skin as scanned, carried by a patient's tissue (a `between` body, docs/design.md
    /// §14): what pictures, surface files, landmarks, the lift and contacts see in place of
    /// the lattice's faces on the skin side ([`shown_at`](Self::shown_at),
    /// [`carried`](Self::carried)). The volumes keep the lattice's own
    /// [`surface`](Self::surface). `None` for other bodies.
    pub skin: Option<CarriedSkin>,
}

/// The scanned skin a `between` body carries (docs/design.md §14), and the surface it is shown
/// by: the lattice's own faces but those on the skin side (the box's faces and the chest
/// wall's), and the scan's triangles inside the box.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CarriedSkin {
    /// The scan's triangles inside the body's box, each vertex following its lattice cell.
    pub sheet: Embedding,
    /// The surface shown, over the body's vertices and then the sheet's (`len + k` for the
    /// sheet's vertex `k`).
    pub shown: TriangleMesh,
}

/// A surface carried by a lattice: each of its vertices follows the displacement of the cell it
/// lies in (trilinear weights over the cell's kept corners), so the user's surface moves with
/// the body while the lattice does the physics.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Embedding {
    /// The surface's vertices at rest.
    pub rest: Vec<Vec3>,
    /// Its triangles, over `rest`.
    pub mesh: TriangleMesh,
    /// Per surface vertex, up to 8 body vertices (`u32::MAX`: none) and their weights (summing
    /// to 1).
    pub corners: Vec<[u32; 8]>,
    /// The weights of `corners`.
    pub weights: Vec<[f32; 8]>,
}

impl Embedding {
    /// `values` of the body's vertices interpolated at every surface vertex.
    #[must_use]
    pub fn interpolate(&self, values: &[Vec3]) -> Vec<Vec3> {
        self.corners
            .iter()
            .zip(&self.weights)
            .map(|(c, w)| {
                c.iter().zip(w).filter(|(c, _)| **c != u32::MAX).map(|(c, w)| *w * values[*c as usize]).sum()
            })
            .collect()
    }

    /// The surface's vertices for the body at `pos` (rest `rest_pos`): each moves by its cell's
    /// interpolated displacement.
    #[must_use]
    pub fn positions(&self, pos: &[Vec3], rest_pos: &[Vec3]) -> Vec<Vec3> {
        let displacement: Vec<Vec3> = pos.iter().zip(rest_pos).map(|(p, r)| *p - *r).collect();
        self.interpolate(&displacement).iter().zip(&self.rest).map(|(d, r)| *r + *d).collect()
    }
}

/// The spring count of an interior vertex of the tissue lattice; vertices with more springs
/// get proportionally more mass.
pub const REFERENCE_DEGREE: f32 = 18.0;

/// The strain whose forces set a body's [`MassSpring::quiet_force`]: a load that strains it
/// less is judged against these forces, so that with nothing acting the body is at rest at once.
pub const REST_STRAIN: f64 = 1e-5;

/// Vertices per parallel task of the force and integration loops: below this a body runs on
/// one thread.
pub(crate) const PAR_CHUNK: usize = 2048;

/// The lanes of the volume sum (the `volume` pass's workgroup size).
pub const VOLUME_LANES: usize = 256;

/// What changes from step to step: the time step, the growth of rest lengths and the drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepInputs {
    /// Time step.
    pub dt: f32,
    /// Rest lengths are `rest * rest_scale` (an inflating implant grows it).
    pub rest_scale: f32,
    /// Driven vertices sit at `rest_pos + drive`, or `turn · rest_pos + drive` when `turn` is
    /// not the identity.
    pub drive: Vec3,
    /// The rotation of driven vertices ([`Mat3::IDENTITY`] for none: a pure translation).
    pub turn: Mat3,
    /// Pressure inside the closed surface, pushing every surface triangle outward (an
    /// inflating implant); 0 for none.
    pub pressure: f32,
    /// A fill of this volume inside the closed surface (a shell filled to a volume; 0 for
    /// none): the pressure becomes `pressure + fill_bulk · (fill_volume − V) / fill_volume`
    /// for the volume `V` the surface encloses at the start of the step
    /// ([`MassSpring::fill_volume_now`]), so that the fill holds its volume against a load as a
    /// nearly incompressible liquid would, with the bulk modulus `fill_bulk`.
    pub fill_volume: f32,
    /// The fill's bulk modulus (pressure units); used only with `fill_volume`.
    pub fill_bulk: f32,
    /// Once a fill has reached its final volume: each step its held pressure
    /// ([`MassSpring::held_pressure`]) grows by `fill_hold · fill_bulk · (fill_volume − V) /
    /// fill_volume`, an integral term, so that at rest the fill holds its volume exactly, however
    /// hard the tissue presses, while the bulk modulus stays within the step's stability bound.
    /// `dt / τ` for an integral time `τ`; 0 for none.
    pub fill_hold: f32,
    /// Free vertices are kept at `z >= floor` (the chest wall); `f32::MIN` for none.
    pub floor: f32,
    /// The acceleration of gravity, in file units per second squared (docs/design.md §13):
    /// each free vertex is pulled by its share of the body's mass ([`MassSpring::mass`]) times
    /// it. Zero for none (the paper's scenes).
    pub gravity: Vec3,
    /// Coulomb's coefficient of friction on the body's curved wall ([`MassSpring::wall`]; 0:
    /// it slides freely): a vertex pressed onto the wall holds where the force along the wall
    /// is at most this times the force into it, and one that lands on it loses that times its
    /// speed into it of its speed along it. A placed implant's `place.friction` once its fill
    /// is done (while it fills, its base spreads on the wall freely).
    pub wall_friction: f32,
}

impl StepInputs {
    /// Steps of `dt` with nothing scheduled: no drive or turn, rest lengths as built, no
    /// pressure or fill, and no floor.
    #[must_use]
    pub fn at_rest(dt: f32) -> StepInputs {
        StepInputs {
            dt,
            rest_scale: 1.0,
            drive: Vec3::ZERO,
            turn: Mat3::IDENTITY,
            pressure: 0.0,
            fill_volume: 0.0,
            fill_bulk: 0.0,
            fill_hold: 0.0,
            floor: f32::MIN,
            gravity: Vec3::ZERO,
            wall_friction: 0.0,
        }
    }

    /// Part of a step: the inputs a fraction `t` (0 to 1) of the way from `self` (the last
    /// step's, where its time ends) to `to` (this step's), for a step of `dt` that is `share`
    /// of `to`'s. Rest lengths, drive, pressure, fill and floor are interpolated linearly (a
    /// value the two share is kept exactly, and at `t = 1` they are `to`'s exactly), the turn
    /// along the shortest arc, and the fill's integral term is `share` of `to`'s (it is a rate
    /// per step).
    #[must_use]
    pub fn toward(&self, to: &StepInputs, t: f32, dt: f32, share: f32) -> StepInputs {
        let mix = |a: f32, b: f32| if a == b || t >= 1.0 { b } else { a + (b - a) * t };
        let turn = if self.turn == to.turn || t >= 1.0 {
            to.turn
        } else {
            let (a, b) = (glam::Quat::from_mat3(&self.turn), glam::Quat::from_mat3(&to.turn));
            Mat3::from_quat(a.slerp(b, t))
        };
        StepInputs {
            dt,
            rest_scale: mix(self.rest_scale, to.rest_scale),
            drive: if self.drive == to.drive || t >= 1.0 { to.drive } else { self.drive.lerp(to.drive, t) },
            turn,
            pressure: mix(self.pressure, to.pressure),
            fill_volume: mix(self.fill_volume, to.fill_volume),
            fill_bulk: mix(self.fill_bulk, to.fill_bulk),
            fill_hold: to.fill_hold * share,
            floor: mix(self.floor, to.floor),
            gravity: if self.gravity == to.gravity || t >= 1.0 {
                to.gravity
            } else {
                self.gravity.lerp(to.gravity, t)
            },
            wall_friction: to.wall_friction,
        }
    }
}

impl MassSpring {
    /// A body at rest at `positions`.
    ///
    /// # Errors
    /// [`Error::Invalid`] for a spring or triangle index out of range, a non-finite position,
    /// or a non-positive rest length, stiffness or mass.
    pub fn new(
        positions: Vec<Vec3>,
        mode: Vec<Mode>,
        springs: Vec<Spring>,
        surface: TriangleMesh,
        material: Material,
    ) -> Result<MassSpring, Error> {
        let n = positions.len();
        let invalid = |what, value: String, rule: &str| Error::Invalid { what, value, rule: rule.into() };
        if mode.len() != n {
            return Err(invalid(
                "mode length",
                mode.len().to_string(),
                &format!("must equal the {n} vertices"),
            ));
        }
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(invalid(
                "vertex position",
                format!("{} (vertex {i})", positions[i]),
                "must be finite",
            ));
        }
        for s in &springs {
            if s.i as usize >= n || s.j as usize >= n || s.i == s.j {
                return Err(invalid(
                    "spring",
                    format!("{}-{}", s.i, s.j),
                    &format!("needs two distinct vertices below {n}"),
                ));
            }
            if !(s.rest > 0.0 && s.k > 0.0 && s.rest.is_finite() && s.k.is_finite()) {
                return Err(invalid(
                    "spring rest/k",
                    format!("{}/{}", s.rest, s.k),
                    "must be finite and positive",
                ));
            }
        }
        if let Some(t) = surface.triangles.iter().find(|t| t.iter().any(|&v| v as usize >= n)) {
            return Err(invalid("triangle", format!("{t:?}"), &format!("indices must be below {n}")));
        }
        if !(material.mass > 0.0 && material.mass.is_finite()) {
            return Err(invalid("mass", material.mass.to_string(), "must be finite and positive"));
        }
        let mut degree = vec![0u32; n];
        for s in &springs {
            degree[s.i as usize] += 1;
            degree[s.j as usize] += 1;
        }
        let mut offsets = vec![0u32; n + 1];
        for i in 0..n {
            offsets[i + 1] = offsets[i] + degree[i];
        }
        let mut fill = offsets.clone();
        let mut adjacency = vec![[0u32; 2]; offsets[n] as usize];
        for (k, s) in springs.iter().enumerate() {
            for (a, b) in [(s.i, s.j), (s.j, s.i)] {
                adjacency[fill[a as usize] as usize] = [b, k as u32];
                fill[a as usize] += 1;
            }
        }
        let inv_mass: Vec<f32> =
            degree.iter().map(|&d| 1.0 / (material.mass * (d as f32 / REFERENCE_DEGREE).max(1.0))).collect();
        let (tri_offsets, tri_adjacency) = surface.triangles_at(n);
        Ok(MassSpring {
            mass: inv_mass.iter().map(|w| 1.0 / w).collect(),
            inv_mass,
            tri_offsets,
            tri_adjacency,
            vel: vec![Vec3::ZERO; n],
            pos: positions.clone(),
            rest_pos: positions,
            mode,
            springs,
            surface,
            material,
            offsets,
            adjacency,
            embedded: None,
            elements: None,
            held_pressure: 0.0,
            started: None,
            wall: None,
            skin: None,
        })
    }

    /// Number of vertices.
    #[must_use]
    pub fn len(&self) -> usize {
        self.pos.len()
    }

    /// Whether the body has no vertex.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.pos.is_empty()
    }

    /// The pressure on its surface this step: `inputs.pressure`, plus a fill's response to the
    /// volume now (see [`StepInputs::fill_volume`]). CPU twin of `shaders/volume.wgsl`.
    #[must_use]
    pub fn pressure(&self, inputs: &StepInputs) -> f32 {
        if inputs.fill_volume > 0.0 {
            let v = self.fill_volume_now();
            inputs.pressure
                + inputs.fill_bulk * (inputs.fill_volume - v) / inputs.fill_volume
                + self.held_pressure
        } else {
            inputs.pressure
        }
    }

    /// A fill's integral term, once a step before its forces: the held pressure grows by
    /// `fill_hold · fill_bulk` times the relative deficit of the volume now (see
    /// [`StepInputs::fill_hold`]). CPU twin of `shaders/volume.wgsl`'s `fill[2]`.
    pub fn hold_fill(&mut self, inputs: &StepInputs) {
        if inputs.fill_volume > 0.0 && inputs.fill_hold > 0.0 {
            let v = self.fill_volume_now();
            self.held_pressure +=
                inputs.fill_hold * inputs.fill_bulk * ((inputs.fill_volume - v) / inputs.fill_volume);
        }
    }

    /// The volume its surface encloses, summed in `f32` exactly as `shaders/volume.wgsl` does
    /// it: each triangle's `dot(a, cross(b, c)) / 6` added, in order, to the partial sum of its
    /// index modulo [`VOLUME_LANES`], and the partial sums then added pairwise (lane `i` and
    /// `i + half`, halving).
    #[must_use]
    pub fn fill_volume_now(&self) -> f32 {
        let mut partial = [0.0f32; VOLUME_LANES];
        for (j, t) in self.surface.triangles.iter().enumerate() {
            let [a, b, c] = t.map(|v| self.pos[v as usize]);
            partial[j % VOLUME_LANES] += dot(a, cross(b, c)) / 6.0;
        }
        let mut half = VOLUME_LANES / 2;
        while half > 0 {
            for i in 0..half {
                partial[i] += partial[i + half];
            }
            half /= 2;
        }
        partial[0]
    }

    /// The volume its surface encloses at its current positions (positive for outward
    /// triangles), in cubic length units, summed in `f64`.
    #[must_use]
    pub fn enclosed_volume(&self) -> f64 {
        self.surface.volume(&self.pos)
    }

    /// Half the stability bound of the integrator (see [`Material`]) for strains up to `s_max`
    /// (with a body's elements, their Gershgorin bound added: [`crate::material::neo_hookean::Elements::stiffness_bound`]).
    #[must_use]
    pub fn stable_dt(&self, s_max: f32) -> f32 {
        let bounds: Vec<Vec<f32>> = self.materials().map(|m| m.stiffness_bounds(self, s_max)).collect();
        let omega2 = (0..self.len())
            .map(|i| bounds.iter().map(|b| b[i]).sum::<f32>() * self.inv_mass[i])
            .fold(0.0f32, f32::max);
        if omega2 > 0.0 { 0.5 * 2.0 / omega2.sqrt() } else { f32::INFINITY }
    }

    /// The net force at rest below which the body is at rest whatever acts on it
    /// (docs/design.md §13): over its free vertices (in quadrature), the force its materials
    /// answer a move of [`REST_STRAIN`] of its mean spring's length with. A body that carries
    /// less than that has nothing acting on it worth the name, and its residual is judged
    /// against this instead of against rounding noise.
    #[must_use]
    pub fn quiet_force(&self) -> f64 {
        let bounds: Vec<Vec<f32>> = self.materials().map(|m| m.stiffness_bounds(self, 0.0)).collect();
        let h = if self.springs.is_empty() {
            0.0
        } else {
            self.springs.iter().map(|s| f64::from(s.rest)).sum::<f64>() / self.springs.len() as f64
        };
        let sum: f64 = (0..self.len())
            .filter(|&i| self.mode[i] == Mode::Free)
            .map(|i| (f64::from(bounds.iter().map(|b| b[i]).sum::<f32>()) * h * REST_STRAIN).powi(2))
            .sum();
        sum.sqrt()
    }

    /// The body's materials, in the order their forces are summed: its springs, then its
    /// elements if it has them.
    pub fn materials(&self) -> impl Iterator<Item = &dyn material::Material> {
        std::iter::once(&Springs as &dyn material::Material)
            .chain(self.elements.as_ref().map(|e| e as &dyn material::Material))
    }

    /// The force on every vertex (its materials', viscous damping, the fill's pressure, its
    /// weight and `contact`), summed per vertex in the materials' order. CPU twin of `shaders/forces.wgsl`.
    pub fn forces(&self, inputs: &StepInputs, contact: &[Vec3], out: &mut Vec<Vec3>) {
        use rayon::prelude::*;
        out.clear();
        let m = &self.material;
        let pressure = self.pressure(inputs);
        // What each material's forces share between vertices, once (a tetrahedron's).
        let prepared: Vec<Vec<Mat3>> = self.materials().map(|mat| mat.prepare(self, &self.pos)).collect();
        // Each vertex's sum is its own, in its own order: the same on any number of threads.
        out.par_extend((0..self.len()).into_par_iter().with_min_len(PAR_CHUNK).map(|i| {
            let mut f = contact[i] - m.damping * self.vel[i];
            for (material, prepared) in self.materials().zip(&prepared) {
                material.add_force(self, &self.pos, &self.vel, inputs.rest_scale, i, prepared, &mut f);
            }
            if pressure != 0.0 {
                // Each triangle's force p * area * normal = p * cross / 2, a third to each corner.
                for &t in &self.tri_adjacency[self.tri_offsets[i] as usize..self.tri_offsets[i + 1] as usize]
                {
                    let [a, b, c] = self.surface.triangles[t as usize].map(|v| self.pos[v as usize]);
                    f += (pressure / 6.0) * cross(b - a, c - a);
                }
            }
            if inputs.gravity != Vec3::ZERO {
                f += self.weight(inputs, i);
            }
            f
        }));
    }

    /// Where each vertex started: [`started`](Self::started), or its rest position.
    #[must_use]
    pub fn start(&self) -> &[Vec3] {
        self.started.as_deref().unwrap_or(&self.rest_pos)
    }

    /// Where the surface the body is shown by started ([`shown_at`](Self::shown_at) its
    /// [`start`](Self::start)).
    #[must_use]
    pub fn shown_start(&self) -> std::borrow::Cow<'_, [Vec3]> {
        self.shown_at(self.start()).0
    }

    /// The surface the body is shown by (pictures, surface files, landmarks) and that contacts
    /// meet and penetration is measured against, with its vertices at `pos`: the user's own
    /// that it carries ([`embedded`](Self::embedded)); the scanned skin beside the lattice's
    /// other faces ([`skin`](Self::skin)), its points the body's vertices and then the sheet's;
    /// or its own [`surface`](Self::surface).
    #[must_use]
    pub fn shown_at<'a>(&'a self, pos: &'a [Vec3]) -> (std::borrow::Cow<'a, [Vec3]>, &'a TriangleMesh) {
        match (&self.embedded, &self.skin) {
            (Some(e), _) => (e.positions(pos, &self.rest_pos).into(), &e.mesh),
            (None, Some(s)) => (self.with_carried(pos).into(), &s.shown),
            (None, None) => (pos.into(), &self.surface),
        }
    }

    /// The body's vertices at `pos`, then the points it carries ([`carried`](Self::carried))
    /// where they follow them: the points [`carried_mesh`](Self::carried_mesh) is over.
    #[must_use]
    pub fn with_carried(&self, pos: &[Vec3]) -> Vec<Vec3> {
        let mut points = pos.to_vec();
        if let Some(e) = self.carried() {
            points.extend(e.positions(pos, &self.rest_pos));
        }
        points
    }

    /// `values` of the body's vertices at the points of the surface it is shown by
    /// ([`shown_at`](Self::shown_at)): interpolated onto a surface it carries, and, beside its
    /// vertices' own, onto a scanned skin's points.
    #[must_use]
    pub fn shown_values<'a>(&self, values: &'a [Vec3]) -> std::borrow::Cow<'a, [Vec3]> {
        match (&self.embedded, &self.skin) {
            (Some(e), _) => e.interpolate(values).into(),
            (None, Some(s)) => {
                values.iter().copied().chain(s.sheet.interpolate(values)).collect::<Vec<_>>().into()
            }
            (None, None) => values.into(),
        }
    }

    /// The points the body carries that a contact meets, each following its cells: the user's
    /// surface ([`embedded`](Self::embedded)) or the scanned skin's sheet ([`skin`](Self::skin));
    /// `None` where the body shows its own surface.
    #[must_use]
    pub fn carried(&self) -> Option<&Embedding> {
        self.embedded.as_ref().or(self.skin.as_ref().map(|s| &s.sheet))
    }

    /// The surface a contact meets where the body carries points ([`carried`](Self::carried)),
    /// over its vertices and then those points (`len + k` for the carried point `k`): the
    /// carried surface's triangles, or the skin beside the lattice's other faces; the same
    /// triangles as [`shown_at`](Self::shown_at)'s. `None` where the body shows its own surface.
    #[must_use]
    pub fn carried_mesh(&self) -> Option<TriangleMesh> {
        let n = self.len() as u32;
        match (&self.embedded, &self.skin) {
            (Some(e), _) => {
                Some(TriangleMesh { triangles: e.mesh.triangles.iter().map(|t| t.map(|v| v + n)).collect() })
            }
            (None, Some(s)) => Some(s.shown.clone()),
            (None, None) => None,
        }
    }

    /// Vertex `i`'s weight under `inputs`' gravity: its [`mass`](Self::mass) times it.
    #[must_use]
    pub fn weight(&self, inputs: &StepInputs, i: usize) -> Vec3 {
        self.mass[i] * inputs.gravity
    }

    /// Its floor's outward normal: its [`wall`](Self::wall)'s, or +z.
    #[must_use]
    pub fn floor_normal(&self) -> Vec3 {
        self.wall.as_ref().map_or(Vec3::Z, |w| w.normal)
    }

    /// Whether a vertex at `p` rests on the body's floor raised to `floor`
    /// ([`StepInputs::floor`]): on or behind it, or, on a curved wall, a rounding in front of it
    /// ([`Wall::rests`](crate::wall::Wall::rests)).
    #[must_use]
    pub fn on_floor(&self, p: Vec3, floor: f32) -> bool {
        match &self.wall {
            Some(w) => w.rests(p, floor),
            None => p.z <= floor,
        }
    }

    /// The body's mass in kilograms: the sum of its vertices' shares ([`mass`](Self::mass)).
    #[must_use]
    pub fn total_mass(&self) -> f64 {
        self.mass.iter().map(|&m| f64::from(m)).sum()
    }

    /// One integration step with the forces `f`. CPU twin of `shaders/integrate.wgsl`; each
    /// vertex on its own, so on every core.
    pub fn integrate(&mut self, inputs: &StepInputs, f: &[Vec3]) {
        use rayon::prelude::*;
        let (mode, rest_pos, inv_mass) = (&self.mode, &self.rest_pos, &self.inv_mass);
        let (wall, friction) = (self.wall.as_deref(), inputs.wall_friction);
        self.pos.par_iter_mut().zip(self.vel.par_iter_mut()).enumerate().with_min_len(PAR_CHUNK).for_each(
            |(i, (pos, vel))| match mode[i] {
                Mode::Free => {
                    *vel += inputs.dt * (f[i] * inv_mass[i]);
                    *pos += inputs.dt * *vel;
                    onto_floor(pos, vel, inputs.floor, wall, friction);
                }
                held => move_held(held, inputs, rest_pos[i], pos, vel, inputs.dt),
            },
        );
    }

    /// The first vertex whose position is not finite or whose speed exceeds `v_max`.
    #[must_use]
    pub fn blow_up(&self, v_max: f32) -> Option<(usize, String)> {
        use rayon::prelude::*;
        self.pos.par_iter().zip(&self.vel).enumerate().with_min_len(PAR_CHUNK).find_map_first(
            |(i, (p, v))| {
                if !p.is_finite() || !v.is_finite() {
                    Some((i, format!("vertex {i} has a non-finite position or velocity")))
                } else if v.length() > v_max {
                    Some((i, format!("vertex {i} moves at {:.3e}, above the limit {v_max:.3e}", v.length())))
                } else {
                    None
                }
            },
        )
    }
}

/// Where a driven vertex resting at `rest` is put by `inputs`: `rest + drive`, or
/// `turn · rest + drive` (column by column, left to right, as `shaders/integrate.wgsl` does).
#[must_use]
pub fn driven_target(inputs: &StepInputs, rest: Vec3) -> Vec3 {
    if inputs.turn == Mat3::IDENTITY {
        rest + inputs.drive
    } else {
        let m = inputs.turn;
        m.x_axis * rest.x + m.y_axis * rest.y + m.z_axis * rest.z + inputs.drive
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn part_of_a_step_lies_between_the_two_steps_inputs() {
        let from = StepInputs { fill_volume: 10.0, ..StepInputs::at_rest(0.2) };
        let to = StepInputs {
            rest_scale: 1.5,
            drive: Vec3::new(2.0, 0.0, 0.0),
            turn: Mat3::from_rotation_z(0.5),
            pressure: 4.0,
            fill_volume: 20.0,
            fill_bulk: 8.0,
            fill_hold: 0.4,
            ..from
        };
        let half = from.toward(&to, 0.5, 0.1, 0.5);
        assert_eq!(half.dt, 0.1);
        assert_eq!(
            (half.rest_scale, half.pressure, half.fill_volume, half.fill_bulk),
            (1.25, 2.0, 15.0, 4.0)
        );
        assert_eq!(half.drive, Vec3::new(1.0, 0.0, 0.0));
        assert!(half.turn.abs_diff_eq(Mat3::from_rotation_z(0.25), 1e-6), "{:?}", half.turn);
        assert_eq!(half.fill_hold, 0.2);
        // A value the two share is kept exactly (no floor stays no floor).
        assert_eq!(half.floor, f32::MIN);
        assert_eq!(from.toward(&to, 1.0, 0.2, 1.0), to);
    }
}
