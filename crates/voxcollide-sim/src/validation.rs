//! Checks of the finite-element material against closed forms (issue 21, item 4;
//! docs/validation.md), each a static answer: the implicit integrator stepped, the loads ramped
//! over a few steps, until the residual force is gone.
//!
//! - [`Cantilever`]: a square beam clamped at its root, its tip carried to the deflection and
//!   the slope that a tip load gives in beam theory. What holds the tip there is that load.
//! - [`LargeStretch`]: a bar stretched by half its length. Its middle is in uniaxial tension,
//!   which for this energy has a closed form.
//!
//! Both are in consistent units (`E = 1`, density 1), with no physical scale.

use std::sync::Arc;

use glam::{Mat3, UVec3, Vec3};

use crate::bodies::box_lattice;
use crate::body::{MassSpring, Material, Mode, StepInputs};
use crate::cpu::CpuWorld;
use crate::integrator::implicit::ImplicitSettings;
use crate::material::neo_hookean::{Elements, lame, lattice_tets};
use crate::world::{Integrator, World};
use voxcollide::error::Error;

/// How the static answers are solved: a tight conjugate gradient, and steps long enough that
/// the beam's slowest mode is quasi-static in a few of them.
const SETTINGS: ImplicitSettings = ImplicitSettings {
    tolerance: 1e-6,
    settle_tolerance: 1e-6,
    max_iterations: 4000,
    max_move: f32::INFINITY,
    split_far: false,
};

/// Where a static solve stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solved {
    /// Steps taken.
    pub steps: u64,
    /// The residual force at the end, relative to the largest load.
    pub residual: f64,
}

/// A body of elements (`E = 1`, `nu`) on a box lattice of `cells` cells of spacing `h` from
/// `origin`, its vertices' modes chosen by `mode`.
fn elements_body(
    cells: UVec3,
    h: f32,
    origin: Vec3,
    nu: f64,
    mode: impl Fn(UVec3) -> Mode,
) -> Result<MassSpring, Error> {
    // Density 1: a vertex carries a cell's mass. The springs keep only their damping.
    let material = Material { mass: h * h * h, stiffening: 0.0, spring_damping: 0.05 * h, damping: 0.0 };
    let mut body = box_lattice(cells + UVec3::ONE, h, origin, 1.0, material, mode)?;
    body.elements = Some(Elements::new(&body.rest_pos, &lattice_tets(&body.rest_pos, h), 1.0, nu)?);
    body.springs.iter_mut().for_each(|s| s.k = 0.0);
    Ok(body)
}

/// Steps `body` under the implicit integrator with `dt`, the drive `drive(ramp)` (`ramp` rising
/// from 0 to 1 over `ramp_steps`, then held), until its residual is below `rest` (at most
/// `max_steps`).
fn solve_static(
    body: MassSpring,
    gravity: Vec3,
    dt: f32,
    ramp_steps: u64,
    max_steps: u64,
    rest: f64,
    drive: impl Fn(f32) -> (Vec3, Mat3) + Send + Sync + 'static,
) -> Result<(MassSpring, Solved), Error> {
    let schedule = Arc::new(move |step: u64| {
        let ramp = ((step + 1) as f32 / ramp_steps as f32).min(1.0);
        let (drive, turn) = drive(ramp);
        vec![StepInputs { drive, turn, gravity: gravity * ramp, ..StepInputs::at_rest(dt) }]
    });
    let world = World::new(vec!["body".into()], vec![body], Vec::new(), f32::MAX, schedule)?
        .with_integrator(Integrator::Implicit(SETTINGS));
    let mut sim = CpuWorld::new(world)?;
    let (mut steps, mut best, mut since) = (0, f64::MAX, 0);
    loop {
        sim.step()?;
        steps += 1;
        let residual = sim.residual.relative();
        // Stalled: the floor of single-precision positions (a strain of 1e-3 is known to
        // about 1e-3 of itself where coordinates are ten spacings from the origin).
        if residual < 0.99 * best {
            (best, since) = (residual, 0);
        } else {
            since += 1;
        }
        if steps > ramp_steps && (residual < rest || steps >= max_steps || since >= 10) {
            break;
        }
    }
    // The residual of the final positions (a step reports the one it started from).
    sim.step()?;
    let residual = sim.residual.relative();
    let body = sim.world.bodies.swap_remove(0);
    Ok((body, Solved { steps: steps + 1, residual }))
}

/// The load on vertex `i` that holds it where it is against the elements: minus their force.
fn load_on(body: &MassSpring, i: usize) -> Vec3 {
    body.elements.as_ref().map_or(Vec3::ZERO, |e| -e.force_on(&body.pos, i))
}

/// A square beam of `length` and `width`, `across` cells through its width, clamped at `x = 0`,
/// its tip face (`x = length`) carried down by `deflection`, drawn in by the length its
/// bending takes up and turned by the slope beam theory gives a tip load,
/// `3·deflection / (2·length)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cantilever {
    /// Along x.
    pub length: f32,
    /// Along y and z.
    pub width: f32,
    /// Cells through the width.
    pub across: u32,
    /// Poisson's ratio (`E = 1`).
    pub nu: f64,
    /// The tip's deflection, down.
    pub deflection: f32,
}

/// What a [`Cantilever`] gave.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CantileverResult {
    /// The vertical load that holds the tip, down positive.
    pub load: f64,
    /// The load beam theory gives for the deflection (Timoshenko's, with Cowper's shear factor
    /// for a square section).
    pub theory: f64,
    /// The moment about the tip face's centre that holds the tip (about y).
    pub moment: f64,
    /// Vertices.
    pub vertices: usize,
    /// Steps to rest.
    pub steps: u64,
    /// The residual at the end.
    pub residual: f64,
}

impl Cantilever {
    /// Length 10, width 1, 4 cells across, ν = 0.3, the tip carried down by 5 % of the length.
    #[must_use]
    pub fn standard() -> Cantilever {
        Cantilever { length: 10.0, width: 1.0, across: 4, nu: 0.3, deflection: 0.5 }
    }

    /// Beam theory's tip load for `deflection`: `δ / (L³/3EI + L/κGA)`.
    #[must_use]
    pub fn theory(&self) -> f64 {
        let (l, b, nu) = (f64::from(self.length), f64::from(self.width), self.nu);
        let i = b.powi(4) / 12.0;
        let g = 1.0 / (2.0 * (1.0 + nu));
        let kappa = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu);
        f64::from(self.deflection) / (l.powi(3) / (3.0 * i) + l / (kappa * g * b * b))
    }

    /// Solves it.
    ///
    /// # Errors
    /// The body's and the world's errors.
    pub fn solve(&self) -> Result<CantileverResult, Error> {
        let h = self.width / self.across as f32;
        let along = (self.length / h).round() as u32;
        // Centred on the origin: single-precision positions then resolve its strains best.
        let origin = -0.5 * Vec3::new(along as f32 * h, self.width, self.width);
        let body = elements_body(UVec3::new(along, self.across, self.across), h, origin, self.nu, |v| {
            if v.x == 0 {
                Mode::Pinned
            } else if v.x == along {
                Mode::Driven
            } else {
                Mode::Free
            }
        })?;
        let centre = Vec3::new(origin.x + along as f32 * h, 0.0, 0.0);
        let (deflection, slope, length) = (self.deflection, 1.5 * self.deflection / self.length, self.length);
        // Steps of a tenth of the beam's first period (E = 1, density 1).
        let omega = 3.516 * (self.width * self.width / 12.0).sqrt() / (self.length * self.length);
        let dt = 0.1 * std::f32::consts::TAU / omega;
        let (body, solved) = solve_static(body, Vec3::ZERO, dt, 4, 200, 1e-5, move |ramp| {
            // Turned about y so that +x tips down, about the tip face's centre.
            // and drawn in by the length its bending takes up, `0.6·δ²/L` (else the beam is
            // held stretched, and its tension carries some of the load).
            let turn = Mat3::from_rotation_y(ramp * slope);
            let d = ramp * deflection;
            (centre - turn * centre - Vec3::new(0.6 * d * d / length, 0.0, d), turn)
        })?;
        let tip: Vec<usize> = (0..body.len()).filter(|&i| body.mode[i] == Mode::Driven).collect();
        let centre_now = tip.iter().map(|&i| body.pos[i]).sum::<Vec3>() / tip.len() as f32;
        let (mut load, mut moment) = (0.0f64, 0.0f64);
        for &i in &tip {
            let f = load_on(&body, i);
            load -= f64::from(f.z);
            moment += f64::from((body.pos[i] - centre_now).cross(f).y);
        }
        Ok(CantileverResult {
            load,
            theory: self.theory(),
            moment,
            vertices: body.len(),
            steps: solved.steps,
            residual: solved.residual,
        })
    }
}

/// A square beam of `length` and `width` (density 1), `across` cells through its width,
/// clamped at `x = 0`, bending under its own weight: `gravity` down (−z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfWeight {
    /// Along x.
    pub length: f32,
    /// Along y and z.
    pub width: f32,
    /// Cells through the width.
    pub across: u32,
    /// Poisson's ratio (`E = 1`).
    pub nu: f64,
    /// The acceleration of gravity (density 1, so the load per length is `gravity · width²`).
    pub gravity: f32,
}

/// What a [`SelfWeight`] gave.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfWeightResult {
    /// The tip's deflection, down: the mean of the tip face's vertices.
    pub deflection: f64,
    /// How far the tip came back towards the root along the beam (the mean of the tip face's
    /// vertices): 0 in linear theory, the beam's large rotation in the heavy elastica.
    pub shortening: f64,
    /// Beam theory's, Timoshenko's with Cowper's shear factor for a square section.
    pub theory: f64,
    /// The beam's weight over its density, gravity and volume (1: it weighs what it should).
    pub weight: f64,
    /// Vertices.
    pub vertices: usize,
    /// Steps to rest.
    pub steps: u64,
    /// The residual at the end, of the loads that act.
    pub residual: f64,
}

impl SelfWeight {
    /// Length 10, width 1, 4 cells across, ν = 0.3, gravity for a tip deflection of 1 % of the
    /// length.
    #[must_use]
    pub fn standard() -> SelfWeight {
        SelfWeight { length: 10.0, width: 1.0, across: 4, nu: 0.3, gravity: 0.1 / 15_000.0 }
    }

    /// Beam theory's tip deflection under a uniform load `q`: `qL⁴/(8EI) + qL²/(2κGA)`.
    #[must_use]
    pub fn theory(&self) -> f64 {
        let (l, b, nu) = (f64::from(self.length), f64::from(self.width), self.nu);
        let q = f64::from(self.gravity) * b * b;
        let i = b.powi(4) / 12.0;
        let g = 1.0 / (2.0 * (1.0 + nu));
        let kappa = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu);
        q * l.powi(4) / (8.0 * i) + q * l * l / (2.0 * kappa * g * b * b)
    }

    /// Solves it.
    ///
    /// # Errors
    /// The body's and the world's errors.
    pub fn solve(&self) -> Result<SelfWeightResult, Error> {
        let h = self.width / self.across as f32;
        let along = (self.length / h).round() as u32;
        let origin = -0.5 * Vec3::new(along as f32 * h, self.width, self.width);
        let mut body = elements_body(UVec3::new(along, self.across, self.across), h, origin, self.nu, |v| {
            if v.x == 0 { Mode::Pinned } else { Mode::Free }
        })?;
        // What gravity pulls: a quarter of each tetrahedron at each corner (density 1).
        let tets = body.elements.as_ref().map_or(&[][..], |e| &e.tets);
        body.mass =
            crate::bodies::tet_masses(&body.rest_pos, tets, 1.0).into_iter().map(|m| m as f32).collect();
        let weight = body.total_mass() / f64::from(self.length * self.width * self.width);
        let omega = 3.516 * (self.width * self.width / 12.0).sqrt() / (self.length * self.length);
        let dt = 0.1 * std::f32::consts::TAU / omega;
        let gravity = Vec3::new(0.0, 0.0, -self.gravity);
        let (body, solved) =
            solve_static(body, gravity, dt, 4, 200, 1e-5, move |_| (Vec3::ZERO, Mat3::IDENTITY))?;
        let tip: Vec<usize> = (0..body.len())
            .filter(|&i| (body.rest_pos[i].x - (origin.x + along as f32 * h)).abs() < 1e-3 * h)
            .collect();
        let mean =
            |d: &dyn Fn(usize) -> f32| tip.iter().map(|&i| f64::from(d(i))).sum::<f64>() / tip.len() as f64;
        let deflection = mean(&|i| body.rest_pos[i].z - body.pos[i].z);
        let shortening = mean(&|i| body.rest_pos[i].x - body.pos[i].x);
        Ok(SelfWeightResult {
            deflection,
            shortening,
            theory: self.theory(),
            weight,
            vertices: body.len(),
            steps: solved.steps,
            residual: solved.residual,
        })
    }
}

/// The heavy elastica: an inextensible, unshearable cantilever clamped level and bending under
/// its own weight through large deflections: Euler's elastica under a uniform load that keeps
/// its direction, as M. Dado and S. Al-Sadder solve it for cantilevers under uniform loads ("A
/// new technique for large deflection analysis of non-prismatic cantilever beams", Mechanics
/// Research Communications 32 (2005) 692–703). With `s` the arc length over the length `L` and
/// `θ` the slope below level,
/// `θ'' = −α (1 − s) cos θ`, `θ(0) = 0`, `θ'(1) = 0`, where `α = qL³/(EI)` is the load's
/// measure. It is solved here by shooting on the root's curvature (bisection, each try a
/// fourth-order Runge–Kutta sweep of 4,000 steps), independently of any finite element.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeavyElastica {
    /// The tip's drop below the root, over `L` (`α/8` for a small load).
    pub drop: f64,
    /// The tip's reach from the root along the level, over `L` (1 for a small load).
    pub reach: f64,
    /// The tip's slope below level, in radians (`α/6` for a small load).
    pub tip_slope: f64,
}

impl HeavyElastica {
    /// The elastica of load measure `alpha = qL³/(EI)` (at least 0).
    #[must_use]
    pub fn solve(alpha: f64) -> HeavyElastica {
        const STEPS: usize = 4000;
        // (θ, θ', drop, reach) swept from the root with root curvature `k0`.
        let sweep = |k0: f64| {
            let h = 1.0 / STEPS as f64;
            let f = |s: f64, y: [f64; 4]| [y[1], -alpha * (1.0 - s) * y[0].cos(), y[0].sin(), y[0].cos()];
            let mut y = [0.0, k0, 0.0, 0.0];
            for k in 0..STEPS {
                let s = k as f64 * h;
                let add = |y: [f64; 4], d: [f64; 4], t: f64| std::array::from_fn(|i| y[i] + t * d[i]);
                let k1 = f(s, y);
                let k2 = f(s + 0.5 * h, add(y, k1, 0.5 * h));
                let k3 = f(s + 0.5 * h, add(y, k2, 0.5 * h));
                let k4 = f(s + h, add(y, k3, h));
                y = std::array::from_fn(|i| y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
            }
            y
        };
        // The free tip carries no moment: θ'(1) = 0. The root's moment is at most the small
        // load's, qL²/2 (α/2 in these units), and at least 0.
        let (mut lo, mut hi) = (0.0, 0.5 * alpha);
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if sweep(mid)[1] > 0.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let y = sweep(0.5 * (lo + hi));
        HeavyElastica { drop: y[2], reach: y[3], tip_slope: y[0] }
    }
}

/// A bar `width × width × 4·width` (spacing 1) pinned at its base, its top carried up until the
/// bar is `stretch` times its length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LargeStretch {
    /// Cells across.
    pub width: u32,
    /// Poisson's ratio (`E = 1`).
    pub nu: f64,
    /// The stretch of the whole bar.
    pub stretch: f32,
}

/// What a [`LargeStretch`] gave, at the bar's middle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LargeStretchResult {
    /// The axial stretch of the middle.
    pub stretch: f64,
    /// Its lateral stretch (width over width at rest).
    pub lateral: f64,
    /// The axial load over the area at rest: the nominal stress.
    pub stress: f64,
    /// The residual at the end.
    pub residual: f64,
}

impl LargeStretch {
    /// 4 cells across, ν = 0.45, stretched by half.
    #[must_use]
    pub fn standard() -> LargeStretch {
        LargeStretch { width: 4, nu: 0.45, stretch: 1.5 }
    }

    /// The energy's uniaxial tension at an axial stretch `l`: the lateral stretch `s` where the
    /// lateral stress is 0, `s² = (α − μ/(λ'l))/l`, and the nominal stress
    /// `P = μl + λ'(l·s² − α)·s²`.
    #[must_use]
    pub fn closed_form(&self, l: f64) -> (f64, f64) {
        let (mu, lambda) = lame(1.0, self.nu);
        let lambda = lambda + mu;
        let alpha = 1.0 + mu / lambda;
        let s2 = (alpha - mu / (lambda * l)) / l;
        (s2.sqrt(), mu * l + lambda * (l * s2 - alpha) * s2)
    }

    /// Solves it.
    ///
    /// # Errors
    /// The body's and the world's errors.
    pub fn solve(&self) -> Result<LargeStretchResult, Error> {
        let w = self.width;
        let top = 4 * w;
        let body = elements_body(UVec3::new(w, w, top), 1.0, Vec3::ZERO, self.nu, |v| {
            if v.z == 0 {
                Mode::Pinned
            } else if v.z == top {
                Mode::Driven
            } else {
                Mode::Free
            }
        })?;
        let lift = (self.stretch - 1.0) * top as f32;
        // A P-wave crosses the bar in about `top / √(λ + 2μ)`; steps of a few such times.
        let dt = 4.0 * top as f32;
        let (body, solved) = solve_static(body, Vec3::ZERO, dt, 20, 400, 1e-5, move |ramp| {
            (Vec3::Z * (ramp * lift), Mat3::IDENTITY)
        })?;
        let layer = |k: f32| {
            body.rest_pos.iter().zip(&body.pos).filter(move |(r, _)| (r.z - k).abs() < 0.01).map(|(_, p)| *p)
        };
        let mean_z = |k: f32| {
            let z: Vec<f64> = layer(k).map(|p| f64::from(p.z)).collect();
            z.iter().sum::<f64>() / z.len() as f64
        };
        let (mid, span) = (2.0 * w as f32, w as f32);
        let stretch = (mean_z(mid + span / 2.0) - mean_z(mid - span / 2.0)) / f64::from(span);
        let (lo, hi) = layer(mid).fold((f32::MAX, f32::MIN), |(l, h), p| (l.min(p.x), h.max(p.x)));
        let lateral = f64::from(hi - lo) / f64::from(w);
        let load: f64 = (0..body.len())
            .filter(|&i| body.mode[i] == Mode::Driven)
            .map(|i| f64::from(load_on(&body, i).z))
            .sum();
        Ok(LargeStretchResult {
            stretch,
            lateral,
            stress: load / f64::from(w * w),
            residual: solved.residual,
        })
    }
}
