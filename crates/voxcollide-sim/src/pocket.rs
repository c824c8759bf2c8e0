//! A dissected pocket (docs/design.md §15): the closed space between the tissue let go from the
//! chest wall and the wall, which holds nothing but its implant.
//!
//! **Why.** A surgical pocket is sealed: no air enters it, so the tissue stays on the implant
//! and the wall wherever the implant does not hold it off. A lattice left to itself does not
//! know that. Where the implant's rim meets the wall, and where a standing breast hangs forward
//! off the implant's lower pole, the tissue stood off and left a space open: at a 10 mm
//! spacing, 110 mL of space beside a 200 mL implant on the MakeHuman patient, and 11 mL beside
//! a 40 mL one on a flat wall with a 10 mm margin.
//!
//! **How.** The pocket's volume is the space its let-go faces swept from where they started
//! on the wall (the wall does not move). What it holds beyond the implant's volume is drawn
//! shut by a suction on those faces and on the implant, as a fluid's pressure would be: `K ·
//! void / V` now, plus what that has added up to over the steps (`hold` of it each step, as a
//! fill holds its volume), never a push (an implant pressed into the tissue is the contact's
//! work). `K` is ten times the tissue's Young's modulus; fifty times closed the space on a flat
//! wall but blew the patient up, when the implicit solve did not see the suction coming. It
//! acts with the contacts' forces, on the CPU backend, and the implicit solve takes its
//! stiffness, `(K/V)·w·wᵀ` over both bodies ([`Pocket::linearised`]): the one-candidate plan of
//! docs/patient.md at 10 mm came to rest in 503 steps instead of 664 with it.
//!
//! **Tried and left.** Drawing only the faces no contact pushes (where the tissue rests on the
//! implant there is no space): the space at the implant's rim stayed open (6.6 mL beside a
//! 40 mL implant), its faces touching the implant at a corner. Drawing each face by the share
//! of its corners no contact pushes: the suction then switched with the contacts, and the
//! patient blew up at 10 mm.

use glam::Vec3;

use crate::body::MassSpring;
use crate::integrator::implicit::RankOne;

/// The suction's stiffness, in multiples of the tissue's Young's modulus: a space open by 1 %
/// of the implant's volume draws at a tenth of the modulus.
pub const SUCTION: f64 = 10.0;

/// A pocket between a tissue's faces let go from its chest wall and the wall, holding an
/// implant.
#[derive(Clone, Debug, PartialEq)]
pub struct Pocket {
    /// The tissue body.
    pub tissue: usize,
    /// The implant's body.
    pub implant: usize,
    /// The tissue's surface triangles on the wall with a corner let go, as corners.
    pub faces: Vec<[u32; 3]>,
    /// `K` of `p = K · void / V`, in the world's pressure units (pascals times metres per
    /// file unit).
    pub stiffness: f32,
    /// `V`: the implant's full volume (cubic file units), not what it holds as it fills
    /// (a tenth of it at first, which made the suction ten times as stiff and blew a patient
    /// up at a 10 mm spacing).
    pub volume: f64,
    /// The share of `K · void / V` added to the suction each step.
    pub hold: f32,
    /// The suction added up over the steps (pressure units).
    pub held: f32,
}

impl Pocket {
    /// The space the pocket holds beyond its implant, in cubic file units (negative: less
    /// than the implant, which the contact settles).
    #[must_use]
    pub fn void(&self, bodies: &[MassSpring]) -> f64 {
        let (t, implant) = (&bodies[self.tissue], &bodies[self.implant]);
        let (start, pos) = (t.start(), &t.pos);
        let det = |at: &[Vec3], f: &[u32; 3]| {
            let [a, b, c] = f.map(|i| at[i as usize].as_dvec3());
            a.dot(b.cross(c)) / 6.0
        };
        let space: f64 = self.faces.iter().map(|f| det(start, f) - det(pos, f)).sum();
        space - implant.enclosed_volume()
    }

    /// `K · void / V` now (pressure units).
    fn drawn(&self, bodies: &[MassSpring]) -> f32 {
        if self.volume > 0.0 {
            (f64::from(self.stiffness) * self.void(bodies) / self.volume) as f32
        } else {
            0.0
        }
    }

    /// The suction drawing the pocket shut (pressure units; never below 0).
    #[must_use]
    pub fn suction(&self, bodies: &[MassSpring]) -> f32 {
        (self.drawn(bodies) + self.held).max(0.0)
    }

    /// The suction's stiffness as the implicit solve takes it: `−K_s = (K/V)·w·wᵀ` over both
    /// bodies' vertices, `w` the force per unit suction on each vertex (the tissue's let-go
    /// faces, toward the wall, and the implant's surface, outward), where the suction draws
    /// (`suction`, as [`add_forces`](Self::add_forces) returned it; none where it is 0). Moving
    /// a vertex along its force shuts the space by as much, so the suction falls as it draws:
    /// an explicit load, it overshot and blew a patient up where the wall let her tissue slide.
    #[must_use]
    pub fn linearised(&self, bodies: &[MassSpring], suction: f32) -> RankOne {
        let mut direction: Vec<Vec<Vec3>> = bodies.iter().map(|_| Vec::new()).collect();
        if self.volume <= 0.0 || suction <= 0.0 {
            return RankOne { stiffness: 0.0, direction };
        }
        for k in [self.tissue, self.implant] {
            direction[k].resize(bodies[k].len(), Vec3::ZERO);
        }
        self.each_share(bodies, 1.0, &mut |k, i, share| direction[k][i] += share);
        RankOne { stiffness: (f64::from(self.stiffness) / self.volume) as f32, direction }
    }

    /// Adds this step's share to what the suction holds, and its forces to `forces` (per body,
    /// per vertex): on the tissue's let-go faces toward the wall, and on the implant's surface
    /// outward. Returns the suction it applied.
    pub fn add_forces(&mut self, bodies: &[MassSpring], forces: &mut [Vec<Vec3>]) -> f32 {
        let drawn = self.drawn(bodies);
        self.held = (self.held + self.hold * drawn).max(0.0);
        let p = (drawn + self.held).max(0.0);
        if p > 0.0 {
            self.each_share(bodies, p, &mut |k, i, share| forces[k][i] += share);
        }
        p
    }

    /// Calls `add(body, vertex, share)` with each corner's share of a suction `p` on its
    /// triangle, `(p/6)·(b − a)×(c − a)`: the tissue's let-go faces, then the implant's surface.
    fn each_share(&self, bodies: &[MassSpring], p: f32, add: &mut dyn FnMut(usize, usize, Vec3)) {
        let mut on = |k: usize, triangles: &mut dyn Iterator<Item = [u32; 3]>| {
            let pos = &bodies[k].pos;
            for t in triangles {
                let [a, b, c] = t.map(|i| pos[i as usize]);
                let share = (p / 6.0) * (b - a).cross(c - a);
                for i in t {
                    add(k, i as usize, share);
                }
            }
        };
        on(self.tissue, &mut self.faces.iter().copied());
        on(self.implant, &mut bodies[self.implant].surface.triangles.iter().copied());
    }
}
