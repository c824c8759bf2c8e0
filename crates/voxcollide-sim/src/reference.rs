//! The shape as scanned (docs/design.md §13): a body imaged under gravity is a loaded shape.
//! [`unload`] finds the unloaded shape whose equilibrium under the reference gravity, with the
//! body's held vertices held, is the shape given, so that a run can then load it in another
//! posture.
//!
//! **Method**: the backward-displacement fixed point (Sellier 2011; Eiben et al. 2016 for
//! breasts from prone MRI). From the scan `x̂` as the first guess of the unloaded shape `X`,
//! each iteration loads `X` to its equilibrium `φ(X)` under the reference gravity (a static
//! solve: the implicit integrator, its step grown towards rest) and moves `X` by the miss,
//! `X ← X + (x̂ − φ(X))`, until the largest miss is below [`TOLERANCE`] of the body's spacing.
//! Each static solve starts from the scan (where the loaded shape ends), so that late
//! iterations take few steps. The miss of the last iteration is the recovery's residual.

use glam::Vec3;
use voxcollide::error::Error;

use crate::body::{MassSpring, Mode, StepInputs};
use crate::cpu::CpuWorld;
use crate::integrator::Integrator;
use crate::integrator::implicit::ImplicitSettings;
use crate::world::World;

/// The recovery stops when the largest miss is this share of the body's spacing.
pub const TOLERANCE: f32 = 0.01;
/// A recovery whose residual is above this share of the spacing is a warning, and the run
/// is not a result (docs/design.md §13).
pub const WARN: f32 = 0.1;
/// The most fixed-point iterations.
pub const MAX_ITERATIONS: u32 = 40;
/// A recovery judges its pace over this many iterations, and stops with the best shape found
/// where at that pace the iterations left would not bring its miss within [`WARN`] of the
/// spacing (a body too soft for the sag of its scan: docs/gravity.md, "Soft bodies").
pub const PACE: usize = 6;
/// Each static solve: its first step (seconds), and how many times the step may grow towards rest.
const SOLVE_DT: f32 = 5e-3;
const SOLVE_ACCELERATION: f32 = 256.0;
/// Each static solve's steps at most, and the residual at rest it solves to (of the loads).
const SOLVE_STEPS: u32 = 4000;
const SOLVE_RESIDUAL: f64 = 1e-4;

/// What the recovery of an unloaded shape found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Recovered {
    /// The largest distance between the shape given and the unloaded shape loaded again with
    /// the reference gravity (the body's length unit).
    pub residual: f32,
    /// The fixed-point iterations taken.
    pub iterations: u32,
    /// The body's mean spacing (its springs' mean rest length), which the residual is judged
    /// against.
    pub spacing: f32,
    /// The static solves' steps, all iterations together.
    pub solve_steps: u64,
}

impl Recovered {
    /// Whether the residual is within [`WARN`] of the spacing: the recovered shape may be run.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        self.residual.is_finite() && self.residual <= WARN * self.spacing
    }
}

/// Replaces `body`'s rest shape, the shape it is unloaded in, by `rest`: its springs' rest
/// lengths and its elements' rest shapes follow; its held vertices are held at `rest`, and a
/// surface embedded in it (or a skin it carries) moves with its lattice.
///
/// # Errors
/// [`Error::Invalid`] for a length that does not match, a non-finite position, or a
/// tetrahedron that `rest` turns inside out or flattens.
pub fn set_rest_shape(body: &mut MassSpring, rest: &[Vec3]) -> Result<(), Error> {
    if rest.len() != body.len() || !rest.iter().all(|p| p.is_finite()) {
        return Err(Error::Invalid {
            what: "rest shape",
            value: format!("{} positions", rest.len()),
            rule: format!("needs {} finite positions, one per vertex", body.len()),
        });
    }
    if let Some(elements) = &mut body.elements {
        for (k, t) in elements.tets.iter().enumerate() {
            let p = t.map(|v| rest[v as usize]);
            let dm = glam::Mat3::from_cols(p[1] - p[0], p[2] - p[0], p[3] - p[0]);
            let det = dm.determinant();
            if !(det > 0.0 && det.is_finite()) {
                return Err(Error::Invalid {
                    what: "unloaded shape",
                    value: format!("tetrahedron {k} {t:?}"),
                    rule: "is turned inside out or flat: no body rests in such a shape".into(),
                });
            }
            elements.dm_inv[k] = dm.inverse();
            elements.volume[k] = det / 6.0;
        }
    }
    for s in &mut body.springs {
        s.rest = rest[s.i as usize].distance(rest[s.j as usize]);
    }
    let moved: Vec<Vec3> = rest.iter().zip(&body.rest_pos).map(|(r, old)| *r - *old).collect();
    for e in body.embedded.iter_mut().chain(body.skin.iter_mut().map(|s| &mut s.sheet)) {
        let by = e.interpolate(&moved);
        e.rest.iter_mut().zip(by).for_each(|(p, d)| *p += d);
    }
    body.rest_pos = rest.to_vec();
    Ok(())
}

/// `body` at its equilibrium under `gravity` (file units per second squared), from where it
/// stands, its held vertices held: a static solve by the implicit integrator, its step grown
/// towards rest. Returns the steps taken.
///
/// # Errors
/// The simulation's errors (a vertex that blows up).
pub fn settle(body: &mut MassSpring, gravity: Vec3) -> Result<u64, Error> {
    body.vel.iter_mut().for_each(|v| *v = Vec3::ZERO);
    let schedule =
        std::sync::Arc::new(move |_| vec![StepInputs { gravity, ..StepInputs::at_rest(SOLVE_DT) }]);
    let extent = body.pos.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let size = (extent.1 - extent.0).max_element().max(f32::MIN_POSITIVE);
    let world =
        World::new(vec!["body".into()], vec![body.clone()], Vec::new(), 1e3 * size / SOLVE_DT, schedule)?
            .with_integrator(Integrator::Implicit(ImplicitSettings::default()));
    let mut w = CpuWorld::new(world)?;
    w.accelerate(SOLVE_ACCELERATION);
    let mut steps = 0u64;
    loop {
        w.step()?;
        steps += 1;
        let r = w.residual.relative();
        let floor = if steps.is_multiple_of(8) { w.residual_floor() } else { None };
        if steps >= 3 && (r <= SOLVE_RESIDUAL || floor.is_some_and(|f| r <= f))
            || steps >= u64::from(SOLVE_STEPS)
        {
            break;
        }
    }
    let settled = w.world.bodies.swap_remove(0);
    body.pos = settled.pos;
    body.vel = settled.vel;
    Ok(steps)
}

/// Finds the unloaded shape of `body`, whose equilibrium under `gravity` (file units per second
/// squared), its held vertices held, is the shape it has now; leaves it resting in that shape
/// and standing where that equilibrium puts it (the shape given, to the residual), still.
///
/// # Errors
/// Those of [`settle`] where the shape given, as its own unloaded shape, blows up under
/// `gravity`, and of [`set_rest_shape`] where the shape given is not a valid one. A shape not
/// recovered within [`WARN`] of the spacing is no error: its [`Recovered::is_valid`] is false.
pub fn unload(body: &mut MassSpring, gravity: Vec3) -> Result<Recovered, Error> {
    let scan = body.pos.clone();
    let spacing = if body.springs.is_empty() {
        1.0
    } else {
        body.springs.iter().map(|s| s.rest).sum::<f32>() / body.springs.len() as f32
    };
    let free: Vec<bool> = body.mode.iter().map(|m| *m == Mode::Free).collect();
    let mut rest = scan.clone();
    let mut recovered = Recovered { residual: f32::INFINITY, iterations: 0, spacing, solve_steps: 0 };
    let mut best = (f32::INFINITY, rest.clone(), scan.clone());
    // The share of the miss each iteration moves by: all of it, halved where that would turn a
    // tetrahedron of the unloaded shape inside out, or make its static solve blow up (a soft
    // body's scan sagged far: its first misses overshoot), down to 1/64.
    let mut share = 1.0f32;
    // The last shape whose solve came through, and its miss: where a smaller move starts.
    let mut base: Option<(Vec<Vec3>, Vec<Vec3>)> = None;
    // The misses of the solves that came through, in order: how fast the recovery goes.
    let mut misses: Vec<f32> = Vec::new();
    set_rest_shape(body, &rest)?;
    'iterate: for iteration in 1..=MAX_ITERATIONS {
        recovered.iterations = iteration;
        body.pos.clone_from(&scan);
        let solved = settle(body, gravity).map(|steps| {
            recovered.solve_steps += steps;
            let miss: Vec<Vec3> = scan.iter().zip(&body.pos).map(|(s, p)| *s - *p).collect();
            let residual =
                miss.iter().zip(&free).filter(|(_, f)| **f).map(|(m, _)| m.length()).fold(0.0, f32::max);
            (miss, residual)
        });
        // The last move went too far (its solve blew up, or its miss more than doubled): half
        // as far from where it started.
        let too_far = solved.as_ref().map_or(true, |(_, residual)| *residual > 2.0 * best.0);
        let miss = match (solved, &base) {
            (_, Some((from, miss))) if too_far => {
                share *= 0.5;
                rest.clone_from(from);
                miss.clone()
            }
            // The scan itself as the unloaded shape blew up: nothing to go back to.
            (Err(e), _) => return Err(e),
            (Ok((miss, residual)), _) => {
                if residual < best.0 {
                    best = (residual, rest.clone(), body.pos.clone());
                }
                if residual <= TOLERANCE * spacing {
                    break;
                }
                // Too slow to be a result: at the pace of its last PACE solves, the iterations
                // left would not bring the miss within WARN of the spacing.
                misses.push(residual);
                if let Some(&then) = misses.len().checked_sub(PACE + 1).map(|k| &misses[k]) {
                    let pace = (residual / then).powf(1.0 / PACE as f32);
                    let needed = (WARN * spacing / residual).ln() / pace.ln();
                    if pace >= 1.0 || needed > (MAX_ITERATIONS - iteration) as f32 {
                        break;
                    }
                }
                base = Some((rest.clone(), miss.clone()));
                miss
            }
        };
        loop {
            if share < 1.0 / 64.0 {
                break 'iterate;
            }
            let next: Vec<Vec3> = rest
                .iter()
                .zip(&miss)
                .zip(&free)
                .map(|((r, m), f)| if *f { *r + share * *m } else { *r })
                .collect();
            if set_rest_shape(body, &next).is_ok() {
                rest = next;
                break;
            }
            share *= 0.5;
        }
    }
    let (residual, rest, loaded) = best;
    set_rest_shape(body, &rest)?;
    body.started = Some(loaded.clone());
    body.pos = loaded;
    body.vel.iter_mut().for_each(|v| *v = Vec3::ZERO);
    recovered.residual = residual;
    Ok(recovered)
}
