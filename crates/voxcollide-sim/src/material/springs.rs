//! The paper's material: a lattice of nonlinear springs that stiffen with strain, as soft
//! tissue does. With length `L`, rest length `L0` and strain `s = (L − L0)/L0`, a spring pulls
//! its ends together with `k·(L − L0)·(1 + stiffening·s²)` along it, plus damping along it,
//! `spring_damping·((v_j − v_i)·u)`. Its constants are the body's
//! [`Material`](crate::body::Material). WGSL twin: `shaders/springs.wgsl`, term for term.

use glam::{Mat3, Vec3};
use rayon::prelude::*;

use super::{Linearised, Material};
use crate::body::{self, MassSpring, PAR_CHUNK, StepInputs};
use voxcollide::math::dot;

/// The tension of a spring of stiffness `k` and rest length `rest` at length `len`:
/// `k·(L − L0)·(1 + stiffening·s²)`.
#[must_use]
pub fn tension(len: f32, rest: f32, k: f32, stiffening: f32) -> f32 {
    let strain = (len - rest) / rest;
    k * (len - rest) * (1.0 + stiffening * strain * strain)
}

/// Its tangent stiffness, `d tension / dL = k·(1 + 3·stiffening·s²)`.
#[must_use]
pub fn tangent(len: f32, rest: f32, k: f32, stiffening: f32) -> f32 {
    let strain = (len - rest) / rest;
    k * (1.0 + 3.0 * stiffening * strain * strain)
}

/// The force of one spring on its end `x` (velocity `v`) from the other end `y` (velocity `w`):
/// the nonlinear spring law plus damping along the spring. Written term by term as in
/// `shaders/springs.wgsl`.
#[must_use]
pub fn spring_force(x: Vec3, v: Vec3, y: Vec3, w: Vec3, rest: f32, k: f32, m: &body::Material) -> Vec3 {
    let d = y - x;
    let len = dot(d, d).sqrt();
    if len < 1e-12 {
        return Vec3::ZERO;
    }
    let u = d / len;
    let tension = tension(len, rest, k, m.stiffening);
    let damping = m.spring_damping * dot(w - v, u);
    (tension + damping) * u
}

/// The body's springs as a [`Material`]: its [`springs`](MassSpring::springs), gathered per
/// vertex in [`adjacency`](MassSpring::adjacency) order.
#[derive(Clone, Copy, Debug, Default)]
pub struct Springs;

impl Material for Springs {
    fn add_force(
        &self,
        body: &MassSpring,
        pos: &[Vec3],
        vel: &[Vec3],
        rest_scale: f32,
        i: usize,
        _prepared: &[Mat3],
        f: &mut Vec3,
    ) {
        let (x, v) = (pos[i], vel[i]);
        for &[j, k] in &body.adjacency[body.offsets[i] as usize..body.offsets[i + 1] as usize] {
            let s = body.springs[k as usize];
            *f += spring_force(
                x,
                v,
                pos[j as usize],
                vel[j as usize],
                s.rest * rest_scale,
                s.k,
                &body.material,
            );
        }
    }

    fn for_each_term(
        &self,
        body: &MassSpring,
        pos: &[Vec3],
        rest_scale: f32,
        i: usize,
        _prepared: &[Mat3],
        term: &mut dyn FnMut(Vec3),
    ) {
        let x = pos[i];
        for &[j, k] in &body.adjacency[body.offsets[i] as usize..body.offsets[i + 1] as usize] {
            let s = body.springs[k as usize];
            term(spring_force(
                x,
                Vec3::ZERO,
                pos[j as usize],
                Vec3::ZERO,
                s.rest * rest_scale,
                s.k,
                &body.material,
            ));
        }
    }

    fn stiffness_bounds(&self, body: &MassSpring, s_max: f32) -> Vec<f32> {
        let stiffen = 1.0 + 3.0 * body.material.stiffening * s_max * s_max;
        (0..body.len())
            .map(|i| {
                let adj = &body.adjacency[body.offsets[i] as usize..body.offsets[i + 1] as usize];
                4.0 * adj.iter().map(|&[_, k]| body.springs[k as usize].k).sum::<f32>() * stiffen
            })
            .collect()
    }

    fn linearise(&self, body: &MassSpring, inputs: &StepInputs) -> Box<dyn Linearised> {
        let h = inputs.dt;
        let m = &body.material;
        // Per spring: its direction, its share of `−K` (the tension across it and the tangent
        // stiffness along it) and its share of `A` (`h²·` those, and `h·spring_damping` along it).
        type Blocks = ((Vec<Vec3>, Vec<[f32; 2]>), Vec<[f32; 2]>);
        let ((direction, stiffness), system): Blocks = body
            .springs
            .par_iter()
            .with_min_len(PAR_CHUNK)
            .map(|s| {
                let d = body.pos[s.j as usize] - body.pos[s.i as usize];
                let len = d.length();
                if len < 1e-12 {
                    return ((Vec3::ZERO, [0.0; 2]), [0.0; 2]);
                }
                let u = d / len;
                let rest = s.rest * inputs.rest_scale;
                // tangent·uuᵀ + across·(I − uuᵀ) = across·I + (tangent − across)·uuᵀ.
                let across = tension(len, rest, s.k, m.stiffening).max(0.0) / len;
                let along = tangent(len, rest, s.k, m.stiffening) - across;
                ((u, [across, along]), [h * h * across, h * h * along + h * m.spring_damping])
            })
            .unzip();
        // `A`'s rows as the products read them: each vertex's springs in adjacency order, with
        // the neighbour, the spring's share and its direction side by side.
        // Springs that keep only their damping (under finite elements, `k = 0`) have `a = 0`
        // and the one `b = h·spring_damping`: their rows need only the direction and the
        // neighbour, two thirds of the memory a product streams through.
        let damping = h * m.spring_damping;
        let damping_only = body.springs.iter().all(|s| s.k == 0.0);
        let (rows, damping_rows) = if damping_only {
            let rows = body
                .adjacency
                .par_iter()
                .with_min_len(PAR_CHUNK)
                .map(|&[j, s]| DampingRow { n: direction[s as usize].to_array(), j })
                .collect();
            (Vec::new(), Some((damping, rows)))
        } else {
            let rows = body
                .adjacency
                .par_iter()
                .with_min_len(PAR_CHUNK)
                .map(|&[j, s]| {
                    let ([a, b], n) = (system[s as usize], direction[s as usize]);
                    Row { n: n.to_array(), a, b, j }
                })
                .collect();
            (rows, None)
        };
        Box::new(LinearSprings { direction, stiffness, system, rows, damping_rows })
    }
}

/// A spring in a vertex's row of `A`: the block `a·I + b·nnᵀ` coupling it to vertex `j`.
#[derive(Clone, Copy, Debug)]
struct Row {
    n: [f32; 3],
    a: f32,
    b: f32,
    j: u32,
}

/// A spring that keeps only its damping, in a vertex's row of `A`: the block `b·nnᵀ` coupling
/// it to vertex `j`, `b` the body's one `h·spring_damping`.
#[derive(Clone, Copy, Debug)]
struct DampingRow {
    n: [f32; 3],
    j: u32,
}

/// The springs' linearisation. Each spring's block is `a·I + b·uuᵀ` with `u` its direction,
/// kept as `[a, b]`: a fifth of the nine numbers' memory, which the products stream through. A
/// vertex's row couples it to its neighbours, in adjacency order.
struct LinearSprings {
    /// Per spring: its direction `u`.
    direction: Vec<Vec3>,
    /// Per spring: its share of `−K`.
    stiffness: Vec<[f32; 2]>,
    /// Per spring: its share of `A`, `h²·H + h·c·uuᵀ`.
    system: Vec<[f32; 2]>,
    /// `system` and `direction` per entry of the body's adjacency: the rows of `A` in the
    /// order a product reads them (a product streams through them, rather than look up each
    /// spring; 2026-12-06).
    rows: Vec<Row>,
    /// In place of `rows` where every spring keeps only its damping: the one `b`, and each
    /// entry's direction and neighbour.
    damping_rows: Option<(f32, Vec<DampingRow>)>,
}

impl Linearised for LinearSprings {
    fn add_product(
        &self,
        body: &MassSpring,
        u: &[Vec3],
        _: &[Mat3],
        i: usize,
        stiff_only: bool,
        r: &mut Vec3,
    ) {
        let ui = u[i];
        let row = body.offsets[i] as usize..body.offsets[i + 1] as usize;
        if stiff_only {
            for &[j, s] in &body.adjacency[row] {
                let d = ui - u[j as usize];
                let ([a, b], n) = (self.stiffness[s as usize], self.direction[s as usize]);
                *r += a * d + (b * n.dot(d)) * n;
            }
        } else if let Some((b, rows)) = &self.damping_rows {
            // (`a = 0`: the same sum as below, less its zeros.)
            for &DampingRow { n, j } in &rows[row] {
                let (d, n) = (ui - u[j as usize], Vec3::from_array(n));
                *r += (b * n.dot(d)) * n;
            }
        } else {
            for &Row { n, a, b, j } in &self.rows[row] {
                let (d, n) = (ui - u[j as usize], Vec3::from_array(n));
                *r += a * d + (b * n.dot(d)) * n;
            }
        }
    }

    fn add_diagonal(&self, body: &MassSpring, i: usize, b: &mut Mat3) {
        for &[_, s] in &body.adjacency[body.offsets[i] as usize..body.offsets[i + 1] as usize] {
            let [a, c] = self.system[s as usize];
            *b += Mat3::from_diagonal(Vec3::splat(a)) + c * outer(self.direction[s as usize]);
        }
    }
}

/// `uuᵀ`.
fn outer(u: Vec3) -> Mat3 {
    Mat3::from_cols(u * u.x, u * u.y, u * u.z)
}
