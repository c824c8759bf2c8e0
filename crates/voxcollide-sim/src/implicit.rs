//! The implicit integrator (DESIGN §12, `integrator = "implicit"`): backward Euler, linearised
//! once per step (Baraff and Witkin 1998) and solved matrix-free by a block-Jacobi
//! preconditioned conjugate gradient, on every core.
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
//! its force, `−k_c·nnᵀ` on every vertex it pushes. `D` holds the vertex damping and each
//! spring's damping along it. The forces themselves (springs, pressure, contacts from the
//! collision library) are the explicit integrator's, bit for bit: only the update differs.
//!
//! The step is not bound by stability, so it is chosen for accuracy; no vertex moves more than
//! [`ImplicitSettings::max_move`] in a step (a contact must see it arrive), the step's velocity
//! scaled down where it would.
//!
//! **Determinism.** The products are per vertex, gathered over its springs in adjacency order,
//! and every dot product is summed over fixed chunks in a fixed order: the same answer on any
//! number of threads.

use glam::{Mat3, Vec3};
use rayon::prelude::*;

use crate::body::{MassSpring, Mode, StepInputs, driven_target, spring_force};
use voxcollide::math::cross;

/// Vertices per parallel task; also the chunk of every dot product's fixed-order sum.
const CHUNK: usize = 2048;

/// How the implicit integrator solves each step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImplicitSettings {
    /// The conjugate gradient stops when the residual is this fraction of the right-hand side.
    pub tolerance: f32,
    /// The conjugate gradient's iteration cap.
    pub max_iterations: u32,
    /// The farthest a vertex may move in one step (file units); `f32::INFINITY` for no limit.
    pub max_move: f32,
}

impl Default for ImplicitSettings {
    fn default() -> ImplicitSettings {
        ImplicitSettings { tolerance: 1e-4, max_iterations: 400, max_move: f32::INFINITY }
    }
}

/// What one implicit step of a body did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepStats {
    /// Conjugate-gradient iterations.
    pub iterations: u32,
    /// The residual reached, relative to the right-hand side.
    pub relative_residual: f32,
    /// The factor the step's velocity was scaled by to keep within `max_move` (1: none).
    pub scaled: f32,
}

/// A body's forces at rest (no damping, no inertia): the residual a static answer drives to 0.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Residual {
    /// `√Σ|f_i|²` over the free vertices: the net force left.
    pub net: f64,
    /// `√Σ(Σ|f_term|)²`: the gross force, the sum of the magnitudes of each vertex's terms.
    pub gross: f64,
    /// The largest gross force seen so far over a run: the scale of its loads, so that a body
    /// coming back to rest unloaded (net and gross both falling to 0) is judged against the
    /// load it had.
    pub peak_gross: f64,
}

impl Residual {
    /// `net / peak_gross` (0 when nothing has pushed).
    #[must_use]
    pub fn relative(&self) -> f64 {
        let scale = self.peak_gross.max(self.gross);
        if scale > 0.0 { self.net / scale } else { 0.0 }
    }

    /// The sum of two bodies' residuals (in quadrature).
    #[must_use]
    pub fn plus(self, other: Residual) -> Residual {
        Residual {
            net: self.net.hypot(other.net),
            gross: self.gross.hypot(other.gross),
            peak_gross: self.peak_gross.max(other.peak_gross),
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

/// The symmetric blocks of one step's linear system.
struct System {
    /// Per spring: `h²·H + h·c·uuᵀ`, the coupling of its two ends.
    coupling: Vec<Mat3>,
    /// Per spring: `H`, its share of `−K`.
    stiffness: Vec<Mat3>,
    /// Per vertex: `m + h·damping`.
    diagonal: Vec<f32>,
    /// Per vertex: the contacts' `k_c·nnᵀ` (their share of `−K`).
    contact: Vec<Mat3>,
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
    h: f32,
}

impl System {
    /// `A·u` restricted to `free` (`A = M − h·D − h²·K`), or `−K·u` when `stiff_only`.
    fn apply(&self, body: &MassSpring, u: &[Vec3], out: &mut Vec<Vec3>, stiff_only: bool) {
        let fill = if self.fill_k > 0.0 { self.fill_k * dot(&self.fill_g, u) as f32 } else { 0.0 };
        let h2 = if stiff_only { 1.0 } else { self.h * self.h };
        debug_assert!(self.h > 0.0);
        out.clear();
        out.par_extend((0..body.len()).into_par_iter().with_min_len(CHUNK).map(|i| {
            if !stiff_only && !self.free[i] {
                return Vec3::ZERO;
            }
            let ui = u[i];
            let mut r = if stiff_only { Vec3::ZERO } else { self.diagonal[i] * ui };
            let blocks = if stiff_only { &self.stiffness } else { &self.coupling };
            for &[j, s] in &body.adjacency[body.offsets[i] as usize..body.offsets[i + 1] as usize] {
                r += blocks[s as usize] * (ui - u[j as usize]);
            }
            r += if stiff_only { self.contact[i] * ui } else { self.contact_block[i] * ui };
            if self.fill_k > 0.0 {
                r += (h2 * fill) * self.fill_g[i];
            }
            r
        }));
    }
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

    /// One implicit step (see the [module](self)) with the forces `f` (from
    /// [`MassSpring::forces`], the contact forces included) and, per vertex, the contacts'
    /// stiffness `contact_k` (`k_c·nnᵀ` summed over the contacts pushing it) and the velocity
    /// of what pushes it, `contact_vel` (the partner's surface there; zero for the voxel model's
    /// contacts): a contact damps, and stops, only the vertex's speed relative to it, so that a
    /// body lifting another carries it along instead of dragging against it.
    pub fn integrate_implicit(
        &mut self,
        inputs: &StepInputs,
        f: &[Vec3],
        contact: &[Vec3],
        contact_k: &[Mat3],
        contact_vel: &[Vec3],
        settings: &ImplicitSettings,
    ) -> StepStats {
        let n = self.len();
        let h = inputs.dt;
        let m = self.material;
        let rest_scale = inputs.rest_scale;
        // Per spring: the tangent stiffness along it and the tension across it.
        let (stiffness, coupling): (Vec<Mat3>, Vec<Mat3>) = self
            .springs
            .par_iter()
            .with_min_len(CHUNK)
            .map(|s| {
                let d = self.pos[s.j as usize] - self.pos[s.i as usize];
                let len = d.length();
                if len < 1e-12 {
                    return (Mat3::ZERO, Mat3::ZERO);
                }
                let u = d / len;
                let rest = s.rest * rest_scale;
                let strain = (len - rest) / rest;
                let tension = s.k * (len - rest) * (1.0 + m.stiffening * strain * strain);
                let tangent = s.k * (1.0 + 3.0 * m.stiffening * strain * strain);
                let uu = outer(u);
                let across = (tension.max(0.0) / len) * (Mat3::IDENTITY - uu);
                let stiff = tangent * uu + across;
                (stiff, h * h * stiff + (h * m.spring_damping) * uu)
            })
            .unzip();
        let fill_k = Self::fill_stiffness(inputs);
        let fill_g = if fill_k > 0.0 { self.volume_gradient() } else { Vec::new() };
        let free: Vec<bool> = self.mode.iter().map(|m| *m == Mode::Free).collect();
        let diagonal: Vec<f32> = self.inv_mass.iter().map(|w| 1.0 / w + h * m.damping).collect();
        // The contacts' damping: critical along each push, for the vertex's mass.
        let contact_damping: Vec<Mat3> = contact_k
            .iter()
            .zip(&self.inv_mass)
            .map(|(kc, w)| {
                let k = kc.x_axis.x + kc.y_axis.y + kc.z_axis.z;
                if k > 0.0 { (2.0 * (1.0 / (w * k)).sqrt()) * *kc } else { Mat3::ZERO }
            })
            .collect();
        let contact_block: Vec<Mat3> =
            contact_k.iter().zip(&contact_damping).map(|(kc, c)| h * h * *kc + h * *c).collect();
        let precondition: Vec<Mat3> = (0..n)
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|i| {
                let mut b = Mat3::from_diagonal(Vec3::splat(diagonal[i])) + contact_block[i];
                for &[_, s] in &self.adjacency[self.offsets[i] as usize..self.offsets[i + 1] as usize] {
                    b += coupling[s as usize];
                }
                if fill_k > 0.0 {
                    b += (h * h * fill_k) * outer(fill_g[i]);
                }
                let inv = b.inverse();
                if inv.is_finite() { inv } else { Mat3::from_diagonal(Vec3::splat(1.0 / diagonal[i])) }
            })
            .collect();
        let system = System {
            coupling,
            stiffness,
            diagonal,
            contact: contact_k.to_vec(),
            contact_block,
            fill_g,
            fill_k,
            free,
            precondition,
            h,
        };
        // The prescribed Δv of held vertices: to rest, or to the drive's target.
        let prescribed: Vec<Vec3> = (0..n)
            .map(|i| match self.mode[i] {
                Mode::Free => Vec3::ZERO,
                Mode::Pinned => -self.vel[i],
                Mode::Driven => (driven_target(inputs, self.rest_pos[i]) - self.pos[i]) / h - self.vel[i],
            })
            .collect();
        // b = h·(f + h·K·v) − A·Δv_prescribed, on the free vertices.
        let mut kv = Vec::with_capacity(n);
        system.apply(self, &self.vel, &mut kv, true);
        let mut a_fixed = Vec::with_capacity(n);
        let any_held = prescribed.iter().any(|p| *p != Vec3::ZERO);
        if any_held {
            system.apply(self, &prescribed, &mut a_fixed, false);
        } else {
            a_fixed.resize(n, Vec3::ZERO);
        }
        let rhs: Vec<Vec3> = (0..n)
            .map(|i| {
                if system.free[i] {
                    h * (f[i] - contact_damping[i] * (self.vel[i] - contact_vel[i]) - h * kv[i]) - a_fixed[i]
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        let (dv, iterations, relative_residual) = conjugate_gradient(self, &system, &rhs, settings);
        // The update, scaled where a vertex would move farther than `max_move`.
        let new_vel: Vec<Vec3> =
            (0..n).map(|i| self.vel[i] + if system.free[i] { dv[i] } else { prescribed[i] }).collect();
        let farthest =
            (0..n).filter(|&i| system.free[i]).map(|i| h * new_vel[i].length()).fold(0.0f32, f32::max);
        let scaled = if farthest > settings.max_move { settings.max_move / farthest } else { 1.0 };
        for i in 0..n {
            match self.mode[i] {
                Mode::Free => {
                    self.vel[i] = scaled * new_vel[i];
                    self.pos[i] += h * self.vel[i];
                    // A contact's push is inelastic: it moves the vertex out, and leaves it no
                    // speed away from the contact (which would carry it on once free of it).
                    let push = contact[i].length();
                    if push > 0.0 {
                        let n = contact[i] / push;
                        let away = (self.vel[i] - contact_vel[i]).dot(n);
                        if away > 0.0 {
                            self.vel[i] -= away * n;
                        }
                    }
                    if self.pos[i].z < inputs.floor {
                        self.pos[i].z = inputs.floor;
                        self.vel[i].z = self.vel[i].z.max(0.0);
                    }
                }
                Mode::Pinned => {
                    self.pos[i] = self.rest_pos[i];
                    self.vel[i] = Vec3::ZERO;
                }
                Mode::Driven => {
                    let target = driven_target(inputs, self.rest_pos[i]);
                    self.vel[i] = (target - self.pos[i]) / h;
                    self.pos[i] = target;
                }
            }
        }
        StepStats { iterations, relative_residual, scaled }
    }

    /// The body's net and gross force at rest (springs without damping, pressure, `contact`),
    /// over its free vertices: what a static answer drives to zero.
    #[must_use]
    pub fn residual(&self, inputs: &StepInputs, contact: &[Vec3]) -> Residual {
        let m = &self.material;
        let pressure = self.pressure(inputs);
        let (net, gross) = (0..self.len())
            .into_par_iter()
            .with_min_len(CHUNK)
            .filter(|&i| self.mode[i] == Mode::Free)
            .map(|i| {
                let x = self.pos[i];
                let mut f = contact[i];
                let mut g = contact[i].length();
                for &[j, k] in &self.adjacency[self.offsets[i] as usize..self.offsets[i + 1] as usize] {
                    let s = self.springs[k as usize];
                    let t = spring_force(
                        x,
                        Vec3::ZERO,
                        self.pos[j as usize],
                        Vec3::ZERO,
                        s.rest * inputs.rest_scale,
                        s.k,
                        m,
                    );
                    f += t;
                    g += t.length();
                }
                if pressure != 0.0 {
                    for &t in
                        &self.tri_adjacency[self.tri_offsets[i] as usize..self.tri_offsets[i + 1] as usize]
                    {
                        let [a, b, c] = self.surface.triangles[t as usize].map(|v| self.pos[v as usize]);
                        let p = (pressure / 6.0) * cross(b - a, c - a);
                        f += p;
                        g += p.length();
                    }
                }
                // A vertex held up by the floor is at rest whatever pushes it down.
                if x.z <= inputs.floor && f.z < 0.0 {
                    f.z = 0.0;
                }
                (f64::from(f.length_squared()), f64::from(g) * f64::from(g))
            })
            .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        Residual { net: net.sqrt(), gross: gross.sqrt(), peak_gross: 0.0 }
    }
}

/// Solves `A·x = b` on the free vertices by preconditioned conjugate gradient; returns `x`,
/// the iterations and the relative residual reached.
fn conjugate_gradient(
    body: &MassSpring,
    system: &System,
    b: &[Vec3],
    settings: &ImplicitSettings,
) -> (Vec<Vec3>, u32, f32) {
    let n = b.len();
    let mut x = vec![Vec3::ZERO; n];
    let norm_b = dot(b, b).sqrt();
    if norm_b == 0.0 {
        return (x, 0, 0.0);
    }
    let precondition = |r: &[Vec3]| -> Vec<Vec3> {
        r.par_iter().zip(&system.precondition).with_min_len(CHUNK).map(|(r, p)| *p * *r).collect()
    };
    let mut r = b.to_vec();
    let mut z = precondition(&r);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let mut ap = Vec::with_capacity(n);
    let target = f64::from(settings.tolerance) * norm_b;
    let mut residual = norm_b;
    let mut iterations = 0;
    while iterations < settings.max_iterations && residual > target {
        system.apply(body, &p, &mut ap, false);
        let pap = dot(&p, &ap);
        if !(pap > 0.0) {
            break;
        }
        let alpha = (rz / pap) as f32;
        x.par_iter_mut().zip(&p).with_min_len(CHUNK).for_each(|(x, p)| *x += alpha * *p);
        r.par_iter_mut().zip(&ap).with_min_len(CHUNK).for_each(|(r, ap)| *r -= alpha * *ap);
        residual = dot(&r, &r).sqrt();
        z = precondition(&r);
        let rz_next = dot(&r, &z);
        let beta = (rz_next / rz) as f32;
        rz = rz_next;
        p.par_iter_mut().zip(&z).with_min_len(CHUNK).for_each(|(p, z)| *p = *z + beta * *p);
        iterations += 1;
    }
    (x, iterations, (residual / norm_b) as f32)
}
