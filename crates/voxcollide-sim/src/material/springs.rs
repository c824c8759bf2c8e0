//! The paper's material: a lattice of nonlinear springs that stiffen with strain, as soft
//! tissue does. With length `L`, rest length `L0` and strain `s = (L − L0)/L0`, a spring pulls
//! its ends together with `k·(L − L0)·(1 + stiffening·s²)` along it, plus damping along it,
//! `spring_damping·((v_j − v_i)·u)`. Its constants are the body's
//! [`Material`](crate::body::Material). WGSL twin: `shaders/springs.wgsl`, term for term.

use glam::Vec3;

use super::Material;
use crate::body::{self, MassSpring};
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
}
