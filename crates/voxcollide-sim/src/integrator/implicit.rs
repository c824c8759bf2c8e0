//! The implicit integrator (docs/design.md §12, `integrator = "implicit"`): backward Euler, linearised
//! once per step (Baraff and Witkin 1998) and solved matrix-free by a block-Jacobi
//! preconditioned conjugate gradient, on every core, each solve starting from the last step's
//! answer ([`Guess`]: a third fewer iterations on the time-to-rest benchmark's scenes).
//!
//! **The step.** With `h` the step, `M` the masses, `K = ∂f/∂x` and `D = ∂f/∂v` at the start of
//! the step, the velocity change `Δv` solves
//!
//! ```text
//! (M − h·D − h²·K) Δv = h·(f + h·K·v)
//! ```
//!
//! and then `v += Δv; x += h·v`. `K` holds, per spring, `k_t·uuᵀ + max(T, 0)/L·(I − uuᵀ)`
//! (its tangent stiffness along the spring and its tension across it, the latter dropped in
//! compression so that `−K` stays positive semi-definite: the "projected" Hessian), the fill's
//! bulk response `−(B/V*)·g·gᵀ` (`g = ∂V/∂x`, a rank-one term over the whole surface, which
//! lets a fill be as incompressible as a liquid), and each contact's penalty stiffness along
//! its force: for a surface contact's push, `−k_c·JᵀJ` with `J = nᵀ[1, −w₀, −w₁, −w₂]` over the
//! pushed vertex and the three corners of the partner's triangle it is pushed from (a
//! [`Coupling`]); for the voxel model's, `−k_c·nnᵀ` on the pushed vertex alone; and for a body
//! of finite elements each tetrahedron's stiffness, projected to be positive semi-definite
//! ([`crate::material::neo_hookean::Tangent`]), its products gathered per vertex. `D` holds the
//! vertex damping, each spring's damping along it and each push's critical damping of the
//! relative speed along it.
//!
//! **Bodies in contact are solved together** ([`integrate_implicit_together`]): one system over
//! every body's vertices, the surface contacts' couplings joining them, so that a body pushing
//! another carries it within the step. Solved each against where the other was at the start of
//! the step, a stiff shell filling under a soft layer pressed into it step after step (5.8–7.4 mm
//! deep against a 4 mm bound, its fill stalled at 93 %, 60 % and 36 % of 200, 400 and 800 mL),
//! because each body saw the other as a wall standing still. The forces themselves (springs, pressure, contacts from the
//! collision library) are the explicit integrator's, bit for bit: only the update differs.
//!
//! The step is not bound by stability, so it is chosen for accuracy; no vertex moves more than
//! [`ImplicitSettings::max_move`] in a step (a contact must see it arrive). A step that would
//! move one farther is refused where [`ImplicitSettings::split_far`] asks it, and
//! [`crate::CpuWorld`] takes it again as shorter steps; otherwise the step's velocity is scaled
//! down.
//!
//! **Determinism.** The products are per vertex, gathered over its springs in adjacency order,
//! and every dot product is summed over fixed chunks in a fixed order: the same answer on any
//! number of threads.

use glam::{Mat3, Vec3};
use rayon::prelude::*;

use super::{CpuIntegrator, Loads, move_held, onto_floor};
use crate::body::{MassSpring, Mode, StepInputs, driven_target};
pub use crate::contact::Coupling;
use crate::contact::{POINT_VERTICES, entries};
use crate::material::Linearised;
use voxcollide::math::cross;

/// Vertices per parallel task; also the chunk of every dot product's fixed-order sum.
const CHUNK: usize = 2048;

/// How the implicit integrator solves each step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImplicitSettings {
    /// The conjugate gradient stops when the residual is this fraction of the right-hand side.
    pub tolerance: f32,
    /// The same once the schedule is over and the step may grow towards rest
    /// ([`crate::CpuWorld::accelerate`]).
    pub settle_tolerance: f32,
    /// The conjugate gradient's iteration cap.
    pub max_iterations: u32,
    /// The farthest a vertex may move in one step (file units); `f32::INFINITY` for no limit.
    pub max_move: f32,
    /// `true`: a step that would move a vertex farther than `max_move` is not taken (the
    /// bodies are left as they were, [`StepStats::taken`] is `false`), for the caller to take
    /// it again as shorter steps: [`crate::CpuWorld`] does while a schedule runs, along the
    /// schedule ([`StepInputs::toward`](crate::StepInputs::toward)), in at most
    /// [`crate::integrator::substep::MAX_SUBSTEPS`] parts, and a scene file's world asks it. `false`:
    /// the step's velocity is scaled down by one factor over all bodies. Scaling keeps the
    /// contacts' promise but not the motion: a 3,000 kPa shell filling to 800 mL under 1 kPa
    /// tissue, at steps where its fill moved it 3–5 times `max_move`, moved at a fifth of its
    /// speed step after step, fell behind its schedule and pushed the tissue through itself
    /// catching up (4.6 mm deep against a 4 mm bound).
    pub split_far: bool,
}

impl Default for ImplicitSettings {
    /// 1e-4 of the right-hand side while the schedule runs, 1e-2 while settling, at most 400
    /// iterations. Each step is one Newton step of a nonlinear problem linearised at its start;
    /// towards rest, solving it finer buys nothing the next step does not redo (an inexact
    /// Newton method's forcing term): a 200 mL implant under a 30 mm layer at a 6 mm spacing
    /// came to rest in 767, 764 and 784 steps at 1e-4, 1e-3 and 1e-2 throughout, in 84, 60 and
    /// 44 s, lifting the layer 20.121, 20.113 and 20.115 mm. While loads change, the motion
    /// is the answer's path, and a contact must hold along it: at 1e-2 throughout, a 3,000 kPa
    /// shell filling to 800 mL under 1 kPa tissue went 4.2 mm into it (bound 4 mm).
    fn default() -> ImplicitSettings {
        ImplicitSettings {
            tolerance: 1e-4,
            settle_tolerance: 1e-2,
            max_iterations: 400,
            max_move: f32::INFINITY,
            split_far: false,
        }
    }
}

impl ImplicitSettings {
    /// The settings of one step: with [`settle_tolerance`](Self::settle_tolerance) in place of
    /// [`tolerance`](Self::tolerance) while `settling` (each solve as far as the step towards
    /// rest needs).
    #[must_use]
    pub fn for_step(self, settling: bool) -> ImplicitSettings {
        if settling { ImplicitSettings { tolerance: self.settle_tolerance, ..self } } else { self }
    }
}

/// What one implicit step of a body did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepStats {
    /// Conjugate-gradient iterations.
    pub iterations: u32,
    /// The residual reached, relative to the right-hand side.
    pub relative_residual: f32,
    /// The factor the step's velocity was scaled by to keep within `max_move` (1: none); where
    /// the step was refused, the factor it would have been.
    pub scaled: f32,
    /// The farthest a free vertex would have moved in the step, as solved.
    pub farthest: f32,
    /// Whether the step was taken (see [`ImplicitSettings::split_far`]).
    pub taken: bool,
}

/// A body's forces at rest (no damping, no inertia): the residual a static answer drives to 0.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Residual {
    /// `√Σ|f_i|²` over the free vertices: the net force left.
    pub net: f64,
    /// `√Σ(Σ|f_term|)²`: the gross force, the sum of the magnitudes of each vertex's terms.
    pub gross: f64,
    /// The largest gross force seen so far over a run, so that a body coming back to rest
    /// unloaded (net and gross both falling to 0) is judged against a share of the load it had.
    pub peak_gross: f64,
    /// The bodies' [`MassSpring::quiet_force`] (in quadrature): the scale below which a load
    /// is nothing, so that a world with nothing acting is at rest at once.
    pub quiet: f64,
    /// Whether gravity acts: `gross` is then the loads that act ([`MassSpring::residual`]),
    /// never nothing, and `quiet` is no floor (a stiff beam's weight is less than the forces
    /// of its quiet strain, and judged against them its sag was taken for at rest unfinished).
    pub weighed: bool,
}

/// The share of the run's largest gross force below which [`Residual::relative`] no longer
/// scales with the gross force now (a body unloaded at the end).
pub const UNLOADED: f64 = 0.01;

impl Residual {
    /// `net / max(gross, UNLOADED · peak_gross, quiet)` (0 when nothing has pushed): the net
    /// force against the loads the bodies carry now. Against the run's largest load instead, a fill
    /// that had pushed hard while filling was taken for at rest at 1e-3 with its lift 24 %
    /// short of its equilibrium (the net force then 2 % of the gross).
    #[must_use]
    pub fn relative(&self) -> f64 {
        let scale = self.scale();
        if scale > 0.0 { self.net / scale } else { 0.0 }
    }

    /// What [`relative`](Self::relative) divides by: the gross force, or a share of the run's
    /// largest, or (without gravity) the quiet force, whichever is largest.
    #[must_use]
    pub fn scale(&self) -> f64 {
        let scale = self.gross.max(UNLOADED * self.peak_gross);
        if self.weighed { scale } else { scale.max(self.quiet) }
    }

    /// The sum of two bodies' residuals (in quadrature).
    #[must_use]
    pub fn plus(self, other: Residual) -> Residual {
        Residual {
            net: self.net.hypot(other.net),
            gross: self.gross.hypot(other.gross),
            peak_gross: self.peak_gross.max(other.peak_gross),
            quiet: self.quiet.hypot(other.quiet),
            weighed: self.weighed || other.weighed,
        }
    }
}

/// `Σ a_i·b_i` in `f64`, over fixed chunks summed in order.
fn dot(a: &[Vec3], b: &[Vec3]) -> f64 {
    let partial: Vec<f64> = a
        .par_chunks(CHUNK)
        .zip(b.par_chunks(CHUNK))
        .map(|(a, b)| a.iter().zip(b).map(|(x, y)| f64::from(x.dot(*y))).sum::<f64>())
        .collect();
    partial.iter().sum()
}

/// The symmetric blocks of one body's share of one step's linear system.
struct System {
    /// Each of the body's materials' linearisation, in [`MassSpring::materials`] order.
    materials: Vec<Box<dyn Linearised>>,
    /// Per vertex: `m + h·damping`.
    diagonal: Vec<f32>,
    /// Per vertex: the contacts' `k_c·nnᵀ` (their share of `−K`).
    contact: Vec<Mat3>,
    /// Per vertex: the contacts' critical damping along their push, `c = 2√(k_c·m)`.
    contact_damping: Vec<Mat3>,
    /// Per vertex: `h²·k_c·nnᵀ + h·c·nnᵀ`, the contacts' stiffness and their critical damping
    /// along their push (`c = 2√(k_c·m)`) in `A`.
    contact_block: Vec<Mat3>,
    /// The fill's `g = ∂V/∂x` per vertex and `B/V*` (0: no fill).
    fill_g: Vec<Vec3>,
    fill_k: f32,
    /// Per vertex: whether it is free (the others' `Δv` is prescribed).
    free: Vec<bool>,
    /// Per vertex: the block-Jacobi preconditioner's inverse block.
    precondition: Vec<Mat3>,
    /// Each material's scratch of one `apply` (its per-element products), kept from one to the
    /// next (a fresh one every iteration faulted its pages in anew, on one thread).
    scratch: std::sync::Mutex<Vec<Vec<Mat3>>>,
    h: f32,
}

impl System {
    /// `A·u` restricted to `free` (`A = M − h·D − h²·K`), or `−K·u` when `stiff_only`: per
    /// vertex, the diagonal, each material's rows in order, the contacts, then the fill.
    fn apply(&self, body: &MassSpring, u: &[Vec3], out: &mut Vec<Vec3>, stiff_only: bool) {
        let fill = if self.fill_k > 0.0 { self.fill_k * dot(&self.fill_g, u) as f32 } else { 0.0 };
        let h2 = if stiff_only { 1.0 } else { self.h * self.h };
        debug_assert!(self.h > 0.0);
        let mut scratch = self.scratch.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        scratch.resize_with(self.materials.len(), Vec::new);
        for (m, s) in self.materials.iter().zip(scratch.iter_mut()) {
            m.prepare(body, u, s);
        }
        let scratch = &*scratch;
        out.clear();
        out.par_extend((0..body.len()).into_par_iter().with_min_len(CHUNK).map(|i| {
            if !stiff_only && !self.free[i] {
                return Vec3::ZERO;
            }
            let ui = u[i];
            let mut r = if stiff_only { Vec3::ZERO } else { self.diagonal[i] * ui };
            for (m, s) in self.materials.iter().zip(scratch) {
                m.add_product(body, u, s, i, stiff_only, &mut r);
            }
            r += if stiff_only { self.contact[i] * ui } else { self.contact_block[i] * ui };
            if self.fill_k > 0.0 {
                r += (h2 * fill) * self.fill_g[i];
            }
            r
        }));
    }
}

/// The trace of a stiffness block: its stiffness along its push.
fn trace(m: &Mat3) -> f32 {
    m.x_axis.x + m.y_axis.y + m.z_axis.z
}

/// `uuᵀ`.
fn outer(u: Vec3) -> Mat3 {
    Mat3::from_cols(u * u.x, u * u.y, u * u.z)
}

impl MassSpring {
    /// The fill's `B/V*` this step (0 without a fill).
    fn fill_stiffness(inputs: &StepInputs) -> f32 {
        if inputs.fill_volume > 0.0 { inputs.fill_bulk / inputs.fill_volume } else { 0.0 }
    }

    /// `∂V/∂x` per vertex: `Σ cross(b − a, c − a) / 6` over its triangles (the pressure force
    /// per unit pressure, exactly as [`MassSpring::forces`] sums it).
    fn volume_gradient(&self) -> Vec<Vec3> {
        (0..self.len())
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|i| {
                let mut g = Vec3::ZERO;
                for &t in &self.tri_adjacency[self.tri_offsets[i] as usize..self.tri_offsets[i + 1] as usize]
                {
                    let [a, b, c] = self.surface.triangles[t as usize].map(|v| self.pos[v as usize]);
                    g += (1.0 / 6.0) * cross(b - a, c - a);
                }
                g
            })
            .collect()
    }

    /// One implicit step of this body alone (see [`integrate_implicit_together`]), with the
    /// forces `f` (from [`MassSpring::forces`], the contact forces `contact` included), and per
    /// vertex the contacts' stiffness `contact_k` (`k_c·nnᵀ` summed over the contacts pushing
    /// it) and the velocity of what pushes it, `contact_vel` (zero for the voxel model's
    /// contacts): a contact damps, and stops, only the vertex's speed relative to it.
    pub fn integrate_implicit(
        &mut self,
        inputs: &StepInputs,
        f: &[Vec3],
        contact: &[Vec3],
        contact_k: &[Mat3],
        contact_vel: &[Vec3],
        settings: &ImplicitSettings,
    ) -> StepStats {
        let step = BodyStep { inputs, forces: f, contact, contact_k, contact_vel };
        integrate_implicit_together(
            std::slice::from_mut(self),
            &[step],
            &[],
            &[],
            settings,
            &mut Guess::default(),
        )[0]
    }

    /// The symmetric blocks of this body's share of one step's system; `extra` adds to the
    /// preconditioner's diagonal blocks (the couplings' own blocks).
    fn system(&self, inputs: &StepInputs, contact_k: &[Mat3], extra: &[Mat3]) -> System {
        let n = self.len();
        let h = inputs.dt;
        let m = self.material;
        let materials: Vec<Box<dyn Linearised>> =
            self.materials().map(|mat| mat.linearise(self, inputs)).collect();
        let fill_k = Self::fill_stiffness(inputs);
        let fill_g = if fill_k > 0.0 { self.volume_gradient() } else { Vec::new() };
        let free: Vec<bool> = self.mode.iter().map(|m| *m == Mode::Free).collect();
        let diagonal: Vec<f32> =
            self.inv_mass.par_iter().with_min_len(CHUNK).map(|w| 1.0 / w + h * m.damping).collect();
        // The contacts' damping: critical along each push, for the vertex's mass.
        let contact_damping: Vec<Mat3> = contact_k
            .par_iter()
            .zip(&self.inv_mass)
            .with_min_len(CHUNK)
            .map(|(kc, w)| {
                let k = trace(kc);
                if k > 0.0 { (2.0 * (1.0 / (w * k)).sqrt()) * *kc } else { Mat3::ZERO }
            })
            .collect();
        let contact_block: Vec<Mat3> = contact_k
            .par_iter()
            .zip(&contact_damping)
            .with_min_len(CHUNK)
            .map(|(kc, c)| h * h * *kc + h * *c)
            .collect();
        let precondition: Vec<Mat3> = (0..n)
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|i| {
                let mut b = Mat3::from_diagonal(Vec3::splat(diagonal[i])) + contact_block[i];
                if let Some(e) = extra.get(i) {
                    b += *e;
                }
                for mat in &materials {
                    mat.add_diagonal(self, i, &mut b);
                }
                if fill_k > 0.0 {
                    b += (h * h * fill_k) * outer(fill_g[i]);
                }
                let inv = b.inverse();
                if inv.is_finite() { inv } else { Mat3::from_diagonal(Vec3::splat(1.0 / diagonal[i])) }
            })
            .collect();
        System {
            materials,
            diagonal,
            contact: contact_k.to_vec(),
            contact_damping,
            contact_block,
            fill_g,
            fill_k,
            free,
            precondition,
            scratch: std::sync::Mutex::new(Vec::new()),
            h,
        }
    }

    /// The body's net and gross force at rest (springs without damping, pressure, weight, `contact`),
    /// over its free vertices: what a static answer drives to zero.
    ///
    /// Under gravity the gross force is the loads that act instead (docs/design.md §13): each
    /// free vertex's weight, contact and pressure, and each held vertex's reaction (the net
    /// force its support takes). A body's internal forces under its own weight are far larger
    /// than its weight, and against them a hanging column was taken for at rest 5 % short of
    /// its stretch (a residual of 1e-3 of them is a smooth error they hardly see).
    #[must_use]
    pub fn residual(&self, inputs: &StepInputs, contact: &[Vec3]) -> Residual {
        let pressure = self.pressure(inputs);
        let loads = inputs.gravity != Vec3::ZERO;
        let prepared = self.prepared(&self.pos);
        let (net, gross) = (0..self.len())
            .into_par_iter()
            .with_min_len(CHUNK)
            .filter(|&i| loads || self.mode[i] == Mode::Free)
            .map(|i| {
                let (f, g, external) = self.force_at_rest(&self.pos, i, &prepared, inputs, contact, pressure);
                match (loads, self.mode[i] == Mode::Free) {
                    (false, _) => (f64::from(f.length_squared()), f64::from(g) * f64::from(g)),
                    (true, true) => {
                        (f64::from(f.length_squared()), f64::from(external) * f64::from(external))
                    }
                    (true, false) => (0.0, f64::from(f.length_squared())),
                }
            })
            .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        Residual { net: net.sqrt(), gross: gross.sqrt(), peak_gross: 0.0, quiet: 0.0, weighed: loads }
    }

    /// How finely the body's positions resolve its net force at rest: half the change of that
    /// force (`√Σ|Δf|²` over the free vertices) when every coordinate moves to a neighbouring
    /// `f32` (times `1 ± 1.2e-7`, the signs scattered by vertex and axis), with the contact
    /// forces, the fill's pressure and which vertices rest on the floor held. A stored position
    /// is off its exact value by at most half a unit in the last place, so no solver balances
    /// the forces much more finely than this. It is an estimate, not a bound: a 50 mL balloon
    /// resting on its floor measured 3.5e-4 of its gross force and went on to a residual of
    /// 4.6e-4; a 500 kPa shell filled to 200 mL under 3 kPa tissue, barely stretched, measured
    /// 3.6e-4 of its own and stalled between 1e-4 and 3e-4 of the world's, the tissue over it
    /// 8e-6 (docs/integrator.md, "The floor of single precision").
    #[must_use]
    pub fn residual_floor(&self, inputs: &StepInputs, contact: &[Vec3]) -> f64 {
        const ULP: f32 = 1.2e-7;
        let pressure = self.pressure(inputs);
        let jittered: Vec<Vec3> = self
            .pos
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let h = (i as u32).wrapping_mul(2_654_435_761);
                let bump = |x: f32, bit: u32| x * if (h >> bit) & 1 == 1 { 1.0 + ULP } else { 1.0 - ULP };
                Vec3::new(bump(p.x, 3), bump(p.y, 7), bump(p.z, 11))
            })
            .collect();
        let (at, near) = (self.prepared(&self.pos), self.prepared(&jittered));
        let change: f64 = (0..self.len())
            .into_par_iter()
            .with_min_len(CHUNK)
            .filter(|&i| self.mode[i] == Mode::Free)
            .map(|i| {
                let (a, ..) = self.force_at_rest(&self.pos, i, &at, inputs, contact, pressure);
                let (b, ..) = self.force_at_rest(&jittered, i, &near, inputs, contact, pressure);
                f64::from((b - a).length_squared())
            })
            .sum();
        0.5 * change.sqrt()
    }

    /// Each material's [`prepare`](crate::material::Material::prepare) at `pos`.
    fn prepared(&self, pos: &[Vec3]) -> Vec<Vec<Mat3>> {
        self.materials().map(|mat| mat.prepare(self, pos)).collect()
    }

    /// Vertex `i`'s net force at rest with the body at `pos` (springs without damping,
    /// elements, `pressure` on its triangles, its weight, `contact`), its gross force (the sum
    /// of the terms' magnitudes), and the part of that gross from outside the body (contact,
    /// pressure, weight). Whether the floor holds it up is judged where the body stands now
    /// (`self.pos`), so that `pos` may differ from it by a rounding without lifting it off.
    fn force_at_rest(
        &self,
        pos: &[Vec3],
        i: usize,
        prepared: &[Vec<Mat3>],
        inputs: &StepInputs,
        contact: &[Vec3],
        pressure: f32,
    ) -> (Vec3, f32, f32) {
        let mut f = contact[i];
        let mut g = contact[i].length();
        let mut external = g;
        for (material, prepared) in self.materials().zip(prepared) {
            material.for_each_term(self, pos, inputs.rest_scale, i, prepared, &mut |t| {
                f += t;
                g += t.length();
            });
        }
        if pressure != 0.0 {
            for &t in &self.tri_adjacency[self.tri_offsets[i] as usize..self.tri_offsets[i + 1] as usize] {
                let [a, b, c] = self.surface.triangles[t as usize].map(|v| pos[v as usize]);
                let p = (pressure / 6.0) * cross(b - a, c - a);
                f += p;
                g += p.length();
                external += p.length();
            }
        }
        if inputs.gravity != Vec3::ZERO {
            let w = self.weight(inputs, i);
            f += w;
            g += w.length();
            external += w.length();
        }
        // A vertex held up by the floor is at rest whatever pushes it down, and its wall's
        // friction takes up to its coefficient times that push off the force along the wall.
        let n = self.floor_normal();
        let into = f.dot(n);
        if into < 0.0 && self.on_floor(self.pos[i], inputs.floor) {
            f -= into * n;
            let along = f.length();
            if inputs.wall_friction > 0.0 && along > 0.0 {
                f *= (along + inputs.wall_friction * into).max(0.0) / along;
            }
        }
        (f, g, external)
    }
}

/// A load whose stiffness joins many vertices of several bodies in one rank: `−K = k·wwᵀ`
/// over every body's vertices (a sealed pocket's suction, [`crate::pocket::Pocket::linearised`]).
/// Its force is among the bodies' forces already; this is what the solve takes of it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RankOne {
    /// `k` (force per unit length per unit of `w` squared); 0: none.
    pub stiffness: f32,
    /// `w`, per body and vertex; a body it does not touch has none (an empty list).
    pub direction: Vec<Vec<Vec3>>,
}

impl RankOne {
    /// `w·u` over every body it touches, in body order, each body's sum in fixed chunks.
    fn along(&self, u: &[Vec<Vec3>]) -> f64 {
        self.direction.iter().zip(u).filter(|(w, _)| !w.is_empty()).map(|(w, u)| dot(w, u)).sum()
    }
}

/// One body's part in [`integrate_implicit_together`].
#[derive(Clone, Copy, Debug)]
pub struct BodyStep<'a> {
    /// Its inputs this step (every body's `dt` the same).
    pub inputs: &'a StepInputs,
    /// Its forces ([`MassSpring::forces`], the contact forces included).
    pub forces: &'a [Vec3],
    /// Its contact forces alone.
    pub contact: &'a [Vec3],
    /// Per vertex, the stiffness of the contacts that push it alone (`k_c·nnᵀ`: the voxel
    /// model's); a surface contact's pushes are [`Coupling`]s instead.
    pub contact_k: &'a [Mat3],
    /// Per vertex, the velocity of what `contact_k` pushes it against (zero for the voxel model).
    pub contact_vel: &'a [Vec3],
}

impl Coupling {
    /// Whether the vertex is pushed now.
    fn touching(&self) -> bool {
        self.depth > 0.0
    }

    /// Adds a force `f` on the point, and its reaction on the partner's point, to `out`'s free
    /// rows.
    fn exert(&self, f: Vec3, out: &mut [Vec<Vec3>], free: &[Vec<bool>]) {
        let (b, q) = (self.body as usize, self.partner as usize);
        for (v, u) in entries(&self.point) {
            if free[b][v as usize] {
                out[b][v as usize] += u * f;
            }
        }
        for (c, w) in entries(&self.from) {
            if free[q][c as usize] {
                out[q][c as usize] -= w * f;
            }
        }
    }

    /// `n·(Σ uⱼ·u_pointⱼ − Σ wᵢ·u_partnerᵢ)`: the relative motion of `u` along the push.
    fn relative(&self, u: &[Vec<Vec3>]) -> f32 {
        let (b, q) = (self.body as usize, self.partner as usize);
        let mut d = Vec3::ZERO;
        for (v, w) in entries(&self.point) {
            d += w * u[b][v as usize];
        }
        for (c, w) in entries(&self.from) {
            d -= w * u[q][c as usize];
        }
        self.normal.dot(d)
    }

    /// Adds `s·JᵀJ·u`'s rows (those of held vertices too when `all`) to `out`.
    fn add(&self, s: f32, u: &[Vec<Vec3>], out: &mut [Vec<Vec3>], free: &[Vec<bool>], all: bool) {
        let f = (s * self.relative(u)) * self.normal;
        let (b, q) = (self.body as usize, self.partner as usize);
        for (v, w) in entries(&self.point) {
            if all || free[b][v as usize] {
                out[b][v as usize] += w * f;
            }
        }
        for (c, w) in entries(&self.from) {
            if all || free[q][c as usize] {
                out[q][c as usize] -= w * f;
            }
        }
    }
}

/// The last step's answer, where the next step's solve starts ([`integrate_implicit_together`]):
/// the velocity change per body and vertex, and the step it was taken over.
#[derive(Clone, Debug, Default)]
pub struct Guess {
    /// The step, in seconds (0: none yet).
    pub h: f32,
    /// Per body, per vertex: the velocity change solved for.
    pub dv: Vec<Vec<Vec3>>,
}

/// The system of one step over every body, and its couplings.
struct Joint<'a> {
    bodies: &'a [MassSpring],
    systems: Vec<System>,
    couplings: &'a [Coupling],
    /// Per coupling: whether it is in the system (the touching ones always).
    active: Vec<bool>,
    /// Per coupling: its critical damping `2√(k·m)` (`m` the reduced mass of the vertex and the
    /// triangle's point).
    damping: Vec<f32>,
    free: Vec<Vec<bool>>,
    /// Per body: the vertices resting on its floor, pushed into it: their velocity along its
    /// normal is held at 0 within the solve (the solve's `Δv` is filtered, Baraff and Witkin
    /// 1998), not only projected after it.
    on_floor: Vec<Vec<u32>>,
    /// Per body: those of `on_floor` that its wall's friction holds where they are (the force
    /// along the wall within [`StepInputs::wall_friction`] times the force into it): their
    /// whole velocity is held at 0 within the solve.
    gripped: Vec<Vec<u32>>,
    /// Per body: its floor's normal ([`MassSpring::floor_normal`]).
    normals: Vec<Vec3>,
    /// The loads of rank one across bodies.
    rank_one: &'a [RankOne],
    h: f32,
}

impl Joint<'_> {
    /// Zeroes the rows along the floor's normal of the vertices resting on the floor, and the
    /// whole rows of those its friction grips.
    fn filter(&self, u: &mut [Vec<Vec3>]) {
        for (((u, held), gripped), n) in
            u.iter_mut().zip(&self.on_floor).zip(&self.gripped).zip(&self.normals)
        {
            for &i in held {
                let u = &mut u[i as usize];
                *u -= u.dot(*n) * *n;
            }
            for &i in gripped {
                u[i as usize] = Vec3::ZERO;
            }
        }
    }

    /// `A·u` on the free vertices, or `−K·u` (every vertex) when `stiff_only`.
    fn apply(&self, u: &[Vec<Vec3>], out: &mut [Vec<Vec3>], stiff_only: bool) {
        for (k, system) in self.systems.iter().enumerate() {
            system.apply(&self.bodies[k], &u[k], &mut out[k], stiff_only);
        }
        // In order, on one thread: the same sums on any number of threads.
        let h = self.h;
        for ((c, d), _) in self.couplings.iter().zip(&self.damping).zip(&self.active).filter(|(_, a)| **a) {
            let s = if stiff_only { c.stiffness } else { h * h * c.stiffness + h * d };
            c.add(s, u, out, &self.free, stiff_only);
        }
        for r in self.rank_one.iter().filter(|r| r.stiffness > 0.0) {
            let s = (if stiff_only { 1.0 } else { h * h }) * r.stiffness * r.along(u) as f32;
            for ((w, out), free) in r.direction.iter().zip(out.iter_mut()).zip(&self.free) {
                out.par_iter_mut().zip(w).zip(free).with_min_len(CHUNK).for_each(|((o, w), f)| {
                    if stiff_only || *f {
                        *o += s * *w;
                    }
                });
            }
        }
    }

    fn precondition(&self, r: &[Vec<Vec3>]) -> Vec<Vec<Vec3>> {
        self.systems
            .iter()
            .zip(r)
            .map(|(s, r)| {
                r.par_iter().zip(&s.precondition).with_min_len(CHUNK).map(|(r, p)| *p * *r).collect()
            })
            .collect()
    }
}

/// `Σ_k a_k·b_k` over bodies, in order.
fn dot_all(a: &[Vec<Vec3>], b: &[Vec<Vec3>]) -> f64 {
    a.iter().zip(b).map(|(a, b)| dot(a, b)).sum()
}

/// One implicit step (see the [module](self)) of every body of `bodies` at once, with each
/// one's [`BodyStep`] and the surface contacts' pushes as `couplings` between them: one linear
/// system over all their vertices, so that bodies in contact move together within the step.
/// Where a vertex would move farther than `max_move`, the step is refused or its velocity
/// scaled by one factor over all bodies ([`ImplicitSettings::split_far`]). Returns each body's [`StepStats`] (the same solve for all).
///
/// # Panics
/// When `steps` and `bodies` differ in length, or a coupling names a body or vertex out of
/// range.
pub fn integrate_implicit_together(
    bodies: &mut [MassSpring],
    steps: &[BodyStep],
    couplings: &[Coupling],
    rank_one: &[RankOne],
    settings: &ImplicitSettings,
    guess: &mut Guess,
) -> Vec<StepStats> {
    assert_eq!(bodies.len(), steps.len(), "one step per body");
    let Some(h) = steps.first().map(|s| s.inputs.dt) else { return Vec::new() };
    // The couplings' damping and their diagonal blocks (for the preconditioner), and the
    // loads of rank one's.
    let damping = coupling_damping(bodies, couplings);
    let mut extra = coupling_blocks(bodies, couplings, &damping, h);
    for r in rank_one.iter().filter(|r| r.stiffness > 0.0) {
        for (k, w) in r.direction.iter().enumerate().filter(|(_, w)| !w.is_empty()) {
            let blocks = &mut extra[k];
            blocks.resize(w.len(), Mat3::ZERO);
            for (b, w) in blocks.iter_mut().zip(w) {
                *b += (h * h * r.stiffness) * outer(*w);
            }
        }
    }
    // The vertices resting on their floor and pushed into it: still vertically, in the solve;
    // and of those, the ones its friction grips (Coulomb: the force along the wall within the
    // friction's cone about the force into it), still altogether.
    let mut on_floor: Vec<Vec<u32>> = Vec::with_capacity(bodies.len());
    let mut gripped: Vec<Vec<u32>> = Vec::with_capacity(bodies.len());
    let normals: Vec<Vec3> = bodies.iter().map(MassSpring::floor_normal).collect();
    for ((body, s), n) in bodies.iter_mut().zip(steps).zip(&normals) {
        let held: Vec<u32> = (0..body.len())
            .filter(|&i| {
                body.mode[i] == Mode::Free
                    && s.forces[i].dot(*n) < 0.0
                    && body.on_floor(body.pos[i], s.inputs.floor)
            })
            .map(|i| i as u32)
            .collect();
        for &i in &held {
            let v = &mut body.vel[i as usize];
            *v -= v.dot(*n) * *n;
        }
        // Coulomb over the step: it sticks where the friction's impulse, `h·μ` times the push
        // into the wall, can stop both its momentum along the wall and the step's force along
        // it. One still sliding faster slides on (gripped at once, a 1.5 kPa breast blew up
        // at the step its implant's base stopped dead).
        let mu = s.inputs.wall_friction;
        let grips: Vec<u32> = held
            .iter()
            .copied()
            .filter(|&i| {
                let (f, v) = (s.forces[i as usize], body.vel[i as usize]);
                let into = f.dot(*n);
                let along = body.mass[i as usize] * v.length() + h * (f - into * *n).length();
                mu > 0.0 && along <= -h * mu * into
            })
            .collect();
        for &i in &grips {
            body.vel[i as usize] = Vec3::ZERO;
        }
        on_floor.push(held);
        gripped.push(grips);
    }
    let systems: Vec<System> =
        bodies.iter().zip(steps).zip(&extra).map(|((b, s), e)| b.system(s.inputs, s.contact_k, e)).collect();
    let free: Vec<Vec<bool>> = systems.iter().map(|s| s.free.clone()).collect();
    // The prescribed Δv of held vertices: to rest, or to the drive's target.
    let prescribed: Vec<Vec<Vec3>> = bodies
        .iter()
        .zip(steps)
        .map(|(body, s)| {
            (0..body.len())
                .into_par_iter()
                .with_min_len(CHUNK)
                .map(|i| match body.mode[i] {
                    Mode::Free => Vec3::ZERO,
                    Mode::Pinned => -body.vel[i],
                    Mode::Driven => {
                        (driven_target(s.inputs, body.rest_pos[i]) - body.pos[i]) / h - body.vel[i]
                    }
                })
                .collect()
        })
        .collect();
    let vel: Vec<Vec<Vec3>> = bodies.iter().map(|b| b.vel.clone()).collect();
    let active = couplings.iter().map(Coupling::touching).collect();
    let mut joint = Joint {
        bodies: &*bodies,
        systems,
        couplings,
        active,
        damping,
        free,
        on_floor,
        gripped,
        normals,
        rank_one,
        h,
    };
    let zeros = || -> Vec<Vec<Vec3>> { bodies.iter().map(|b| vec![Vec3::ZERO; b.len()]).collect() };
    let any_held = prescribed.iter().flatten().any(|p| *p != Vec3::ZERO);
    // b = h·(f − C_c·v_rel + h·K·v) − A·Δv_prescribed, on the free vertices, over the couplings
    // in the system (an arriving vertex's `k·(gap − s)` included: a pull until it arrives).
    let rhs_of = |joint: &Joint| -> Vec<Vec<Vec3>> {
        let mut kv = zeros();
        joint.apply(&vel, &mut kv, true);
        let mut a_fixed = zeros();
        if any_held {
            joint.apply(&prescribed, &mut a_fixed, false);
        }
        let mut rhs: Vec<Vec<Vec3>> = (0..joint.bodies.len())
            .map(|k| {
                let (body, s, system) = (&joint.bodies[k], &steps[k], &joint.systems[k]);
                (0..body.len())
                    .into_par_iter()
                    .with_min_len(CHUNK)
                    .map(|i| {
                        if system.free[i] {
                            h * (s.forces[i]
                                - system.contact_damping[i] * (body.vel[i] - s.contact_vel[i])
                                - h * kv[k][i])
                                - a_fixed[k][i]
                        } else {
                            Vec3::ZERO
                        }
                    })
                    .collect()
            })
            .collect();
        if joint.couplings.is_empty() {
            return rhs;
        }
        // The couplings' damping of the relative velocity, and the arriving ones' force.
        let mut extra = zeros();
        for ((c, d), active) in joint.couplings.iter().zip(&joint.damping).zip(&joint.active) {
            match (*active, c.touching()) {
                (true, touching) => {
                    c.add(-*d, &vel, &mut extra, &joint.free, false);
                    if !touching {
                        c.exert((c.stiffness * c.depth) * c.normal, &mut extra, &joint.free);
                    }
                }
                // Pushed now, but leaving within the step: its push is taken out of the forces.
                (false, true) => c.exert(-(c.stiffness * c.depth) * c.normal, &mut extra, &joint.free),
                (false, false) => {}
            }
        }
        rhs.iter_mut().zip(&extra).for_each(|(r, e)| r.iter_mut().zip(e).for_each(|(r, e)| *r += h * *e));
        rhs
    };
    let velocity_after = |joint: &Joint, dv: &[Vec<Vec3>]| -> Vec<Vec<Vec3>> {
        (0..joint.bodies.len())
            .map(|k| {
                let (body, free) = (&joint.bodies[k], &joint.free[k]);
                (0..body.len())
                    .into_par_iter()
                    .with_min_len(CHUNK)
                    .map(|i| body.vel[i] + if free[i] { dv[k][i] } else { prescribed[k][i] })
                    .collect()
            })
            .collect()
    };
    let (mut iterations, mut rounds) = (0, 0);
    // The first solve starts from the last step's answer, scaled to this step (`Δv` is about
    // `h` times an acceleration that changes little from step to step); a solve again, from
    // the one before it.
    let mut start: Option<Vec<Vec<Vec3>>> = (guess.h > 0.0
        && guess.dv.len() == bodies.len()
        && guess.dv.iter().zip(bodies.iter()).all(|(g, b)| g.len() == b.len()))
    .then(|| {
        let scale = h / guess.h;
        guess.dv.iter().map(|g| g.iter().map(|v| scale * *v).collect()).collect()
    });
    let (dv, relative_residual) = loop {
        rounds += 1;
        let (dv, its, relative) = conjugate_gradient(&joint, &rhs_of(&joint), settings, start.as_deref());
        iterations += its;
        // The pairs this solve ends within the gap are in it, and no others: a vertex within the
        // margin that it carries past the gap joins it, and one pushed now that it carries
        // away leaves it (a penalty spring linearised both ways would pull it back). Solved
        // again until none changes, at most four times.
        let after = velocity_after(&joint, &dv);
        let mut changed = false;
        for (c, a) in couplings.iter().zip(joint.active.iter_mut()) {
            let arrives = h * c.relative(&after) < c.depth;
            // After the first solve pairs only join, so that the set cannot cycle (a pair at
            // the edge, left by one solve and carried in by the next, stays in).
            if arrives != *a && (rounds == 1 || arrives) {
                changed = true;
                *a = arrives;
            }
        }
        if !changed || rounds == 4 {
            break (dv, relative);
        }
        start = Some(dv);
    };
    guess.h = h;
    guess.dv.clone_from(&dv);
    // The update, scaled where a vertex would move farther than `max_move`.
    let new_vel = velocity_after(&joint, &dv);
    // (A maximum: the same on any number of threads.)
    let farthest = new_vel
        .iter()
        .zip(&joint.free)
        .zip(joint.bodies.iter().zip(steps))
        .map(|((v, free), (body, step))| {
            let wall = body.wall.as_deref();
            v.par_iter()
                .zip(free)
                .enumerate()
                .with_min_len(CHUNK)
                .filter(|(_, (_, f))| **f)
                .map(|(i, (v, _))| {
                    // A curved wall stops what would carry a vertex into it: the vertex moves
                    // only as far as the wall lets it, and keeps the speed the wall leaves it,
                    // which carries it on in the next step. (A flat floor's vertices are held
                    // in the solve exactly, and the GPU's twin measures the solved motion.)
                    if wall.is_none() {
                        return h * v.length();
                    }
                    let (mut p, mut w) = (body.pos[i] + h * *v, *v);
                    onto_floor(&mut p, &mut w, step.inputs.floor, wall, step.inputs.wall_friction);
                    p.distance(body.pos[i]).max(h * w.length())
                })
                .reduce(|| 0.0f32, f32::max)
        })
        .fold(0.0f32, f32::max);
    let scaled = if farthest > settings.max_move { settings.max_move / farthest } else { 1.0 };
    if settings.split_far && scaled < 1.0 {
        return vec![
            StepStats { iterations, relative_residual, scaled, farthest, taken: false };
            bodies.len()
        ];
    }
    let active = joint.active;
    for (k, body) in bodies.iter_mut().enumerate() {
        let (inputs, step, new_vel) = (steps[k].inputs, &steps[k], &new_vel[k]);
        let MassSpring { mode, rest_pos, pos, vel, wall, .. } = body;
        let (wall, friction) = (wall.as_deref(), inputs.wall_friction);
        // Each vertex on its own, on every core.
        (pos.par_iter_mut(), vel.par_iter_mut(), mode.par_iter(), rest_pos.par_iter())
            .into_par_iter()
            .enumerate()
            .with_min_len(CHUNK)
            .for_each(|(i, (pos, vel, mode, rest))| match mode {
                Mode::Free => {
                    *vel = scaled * new_vel[i];
                    *pos += h * *vel;
                    // A voxel-model contact's push is inelastic: it moves the vertex out, and
                    // leaves it no speed away from what pushes it (which would carry it on once
                    // free of it).
                    let push = step.contact[i].length();
                    if push > 0.0 && trace(&step.contact_k[i]) > 0.0 {
                        let n = step.contact[i] / push;
                        let away = (*vel - step.contact_vel[i]).dot(n);
                        if away > 0.0 {
                            *vel -= away * n;
                        }
                    }
                    onto_floor(pos, vel, inputs.floor, wall, friction);
                }
                held => move_held(*held, inputs, *rest, pos, vel, h),
            });
    }
    inelastic_impulses(bodies, couplings, &active);
    vec![StepStats { iterations, relative_residual, scaled, farthest, taken: true }; bodies.len()]
}

/// Per coupling, its critical damping `2√(k·m)`, `m` the reduced mass of the vertex and the
/// triangle's point.
pub(crate) fn coupling_damping(bodies: &[MassSpring], couplings: &[Coupling]) -> Vec<f32> {
    let mass = |b: u32, v: u32| 1.0 / bodies[b as usize].inv_mass[v as usize];
    couplings
        .iter()
        .map(|c| {
            let m: f32 = entries(&c.point).map(|(v, w)| w * mass(c.body, v)).sum();
            let point: f32 = entries(&c.from).map(|(v, w)| w * mass(c.partner, v)).sum();
            let reduced = if point > 0.0 { m * point / (m + point) } else { m };
            2.0 * (c.stiffness * reduced).sqrt()
        })
        .collect()
}

/// Per body and vertex, the couplings' own blocks `Σ (h²k + h·d)·w²·nnᵀ` (for the
/// preconditioner); empty per body where there are no couplings.
pub(crate) fn coupling_blocks(
    bodies: &[MassSpring],
    couplings: &[Coupling],
    damping: &[f32],
    h: f32,
) -> Vec<Vec<Mat3>> {
    let mut extra: Vec<Vec<Mat3>> = if couplings.is_empty() {
        vec![Vec::new(); bodies.len()]
    } else {
        bodies.iter().map(|b| vec![Mat3::ZERO; b.len()]).collect()
    };
    for (c, d) in couplings.iter().zip(damping) {
        let nn = (h * h * c.stiffness + h * d) * outer(c.normal);
        for (v, w) in entries(&c.point) {
            extra[c.body as usize][v as usize] += (w * w) * nn;
        }
        for (v, w) in entries(&c.from) {
            extra[c.partner as usize][v as usize] += (w * w) * nn;
        }
    }
    extra
}

/// A surface contact's push is inelastic, between the two bodies: where a vertex and its point
/// on the partner's surface separate along the push, an impulse between them (in their reduced
/// mass, momentum kept) leaves them none of that speed. Over the couplings pushed now and
/// `active` in the solve, in order, on one thread, after the step's update.
pub(crate) fn inelastic_impulses(bodies: &mut [MassSpring], couplings: &[Coupling], active: &[bool]) {
    for (c, _) in couplings.iter().zip(active).filter(|(c, a)| c.touching() && **a) {
        let (b, q) = (c.body as usize, c.partner as usize);
        let inverse =
            |k: usize, i: usize| if bodies[k].mode[i] == Mode::Free { bodies[k].inv_mass[i] } else { 0.0 };
        let (mut away, mut compliance) = (0.0, 0.0);
        for (v, w) in entries(&c.point) {
            away += w * c.normal.dot(bodies[b].vel[v as usize]);
            compliance += w * w * inverse(b, v as usize);
        }
        for (t, w) in entries(&c.from) {
            away -= w * c.normal.dot(bodies[q].vel[t as usize]);
            compliance += w * w * inverse(q, t as usize);
        }
        if away <= 0.0 || compliance <= 0.0 {
            continue;
        }
        let impulse = (away / compliance) * c.normal;
        let mut kicks = [Vec3::ZERO; 4 * POINT_VERTICES];
        for ((v, w), kick) in entries(&c.point).zip(kicks.iter_mut()) {
            *kick = -(w * inverse(b, v as usize)) * impulse;
        }
        for ((t, w), kick) in entries(&c.from).zip(kicks[POINT_VERTICES..].iter_mut()) {
            *kick = (w * inverse(q, t as usize)) * impulse;
        }
        for ((v, _), kick) in entries(&c.point).zip(&kicks) {
            bodies[b].vel[v as usize] += *kick;
        }
        for ((t, _), kick) in entries(&c.from).zip(&kicks[POINT_VERTICES..]) {
            bodies[q].vel[t as usize] += *kick;
        }
    }
}

/// Solves `A·x = b` on the free vertices of every body by preconditioned conjugate gradient;
/// returns `x`, the iterations and the relative residual reached.
fn conjugate_gradient(
    joint: &Joint,
    b: &[Vec<Vec3>],
    settings: &ImplicitSettings,
    guess: Option<&[Vec<Vec3>]>,
) -> (Vec<Vec<Vec3>>, u32, f32) {
    let mut x: Vec<Vec<Vec3>> = b.iter().map(|b| vec![Vec3::ZERO; b.len()]).collect();
    // The floor's rows are not solved for: the tolerance is of what is.
    let mut r = b.to_vec();
    joint.filter(&mut r);
    let norm_b = dot_all(&r, &r).sqrt();
    if norm_b == 0.0 {
        return (x, 0, 0.0);
    }
    // From the guess, on the free rows, where it leaves less to solve than 0 does.
    if let Some(g) = guess {
        for ((x, g), free) in x.iter_mut().zip(g).zip(&joint.free) {
            for ((x, g), free) in x.iter_mut().zip(g).zip(free) {
                if *free {
                    *x = *g;
                }
            }
        }
        joint.filter(&mut x);
        let mut ax: Vec<Vec<Vec3>> = b.iter().map(|b| Vec::with_capacity(b.len())).collect();
        joint.apply(&x, &mut ax, false);
        joint.filter(&mut ax);
        let mut left = r.clone();
        left.iter_mut().zip(&ax).for_each(|(r, ax)| r.iter_mut().zip(ax).for_each(|(r, ax)| *r -= *ax));
        if dot_all(&left, &left).sqrt() < norm_b {
            r = left;
        } else {
            x.iter_mut().for_each(|x| x.fill(Vec3::ZERO));
        }
    }
    let mut z = joint.precondition(&r);
    joint.filter(&mut z);
    let mut p = z.clone();
    let mut rz = dot_all(&r, &z);
    let mut ap: Vec<Vec<Vec3>> = b.iter().map(|b| Vec::with_capacity(b.len())).collect();
    let target = f64::from(settings.tolerance) * norm_b;
    let mut residual = norm_b;
    let mut iterations = 0;
    while iterations < settings.max_iterations && residual > target {
        joint.apply(&p, &mut ap, false);
        joint.filter(&mut ap);
        let pap = dot_all(&p, &ap);
        // (A NaN curvature stops it too.)
        if pap.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            break;
        }
        let alpha = (rz / pap) as f32;
        // x += α·p, r −= α·Ap, z = P·r, and the chunks' r·r and r·z, in one pass.
        let (mut rr_sum, mut rz_sum) = (Vec::with_capacity(x.len()), Vec::with_capacity(x.len()));
        for k in 0..x.len() {
            let partial: Vec<(f64, f64)> = x[k]
                .par_chunks_mut(CHUNK)
                .zip(r[k].par_chunks_mut(CHUNK))
                .zip(z[k].par_chunks_mut(CHUNK))
                .zip(p[k].par_chunks(CHUNK).zip(ap[k].par_chunks(CHUNK)))
                .zip(joint.systems[k].precondition.par_chunks(CHUNK))
                .map(|((((x, r), z), (p, ap)), pc)| {
                    for (x, p) in x.iter_mut().zip(p) {
                        *x += alpha * *p;
                    }
                    for (r, ap) in r.iter_mut().zip(ap) {
                        *r -= alpha * *ap;
                    }
                    for ((z, r), pc) in z.iter_mut().zip(&*r).zip(pc) {
                        *z = *pc * *r;
                    }
                    // r's rows on the floor are 0, so z's (zeroed below) add nothing.
                    let rr = r.iter().map(|r| f64::from(r.dot(*r))).sum::<f64>();
                    let rz = r.iter().zip(&*z).map(|(r, z)| f64::from(r.dot(*z))).sum::<f64>();
                    (rr, rz)
                })
                .collect();
            rr_sum.push(partial.iter().map(|p| p.0).sum::<f64>());
            rz_sum.push(partial.iter().map(|p| p.1).sum::<f64>());
        }
        joint.filter(&mut z);
        residual = rr_sum.iter().sum::<f64>().sqrt();
        let rz_next = rz_sum.iter().sum::<f64>();
        let beta = (rz_next / rz) as f32;
        rz = rz_next;
        for k in 0..p.len() {
            p[k].par_iter_mut().zip(&z[k]).with_min_len(CHUNK).for_each(|(p, z)| *p = *z + beta * *p);
        }
        iterations += 1;
    }
    (x, iterations, (residual / norm_b) as f32)
}

/// The implicit step on the CPU, as a [`CpuIntegrator`]: every body's residual at rest, the
/// voxel model's contact stiffness and the surface contacts' couplings, then one solve over
/// every body ([`integrate_implicit_together`]). It keeps nothing of its own: the last answer
/// (`guess`) and the solves (`stats`) are the world's.
pub struct Implicit<'a> {
    /// This step's settings.
    pub settings: ImplicitSettings,
    /// Where the solve starts, and where its answer is kept for the next step.
    pub guess: &'a mut Guess,
    /// The solves, per body.
    pub stats: &'a mut Vec<StepStats>,
}

impl CpuIntegrator for Implicit<'_> {
    fn integrate(&mut self, bodies: &mut [MassSpring], loads: &Loads<'_>) -> Residual {
        let mut residual = Residual::default();
        let mut contact_k = Vec::with_capacity(bodies.len());
        let mut contact_vel = Vec::with_capacity(bodies.len());
        for (k, body) in bodies.iter().enumerate() {
            residual = residual.plus(body.residual(&loads.inputs[k], &loads.contact[k]));
            // What the voxel model's penalties push against stands still.
            contact_vel.push(vec![Vec3::ZERO; body.len()]);
            contact_k.push(loads.contacts.stiffness_on(k, body.len(), loads.pairs, loads.reports));
        }
        let couplings = loads.contacts.couplings(loads.pairs);
        let steps: Vec<BodyStep> = (0..bodies.len())
            .map(|k| BodyStep {
                inputs: &loads.inputs[k],
                forces: &loads.forces[k],
                contact: &loads.contact[k],
                contact_k: &contact_k[k],
                contact_vel: &contact_vel[k],
            })
            .collect();
        *self.stats = integrate_implicit_together(
            bodies,
            &steps,
            &couplings,
            loads.rank_one,
            &self.settings,
            self.guess,
        );
        residual
    }
}
