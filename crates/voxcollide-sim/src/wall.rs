//! A curved chest wall as a floor (docs/design.md §15): the wall under a placed implant,
//! sampled as heights over the plane tangent to it, that the implant's (and the pocket's)
//! free vertices are kept in front of.
//!
//! **The frame.** The implant is placed under a landmark: its base's centre `origin` is the
//! wall's closest point to the landmark, and `normal` the wall's mean outward normal over the
//! base (area-weighted, so that one facet does not tilt it). `u` and `v` span the plane across
//! it. A point's height is how far it lies along `normal` from that plane.
//!
//! **The heights.** On a square grid over the plane, the height of the wall where the line
//! along `normal` through each node meets it (the crossing nearest the plane), bilinear between
//! nodes. A node whose line misses the wall has none, and a point over a cell with a corner of
//! none is not held by the wall: the grid reaches past the pocket, so that is only far from
//! the implant. On a chest curved by a radius `R`, the wall at the rim of a base of radius `r`
//! lies `r²/2R` behind the tangent plane (11 mm for a 115 mm base on a 150 mm radius): a flat
//! floor would hold the implant's rim that far off the wall, and take the space between for
//! the volume it added.

use glam::{DVec3, Vec3};

/// How far in front of the wall, in its grid's cells, a vertex still [rests](Wall::rests) on it.
pub const RESTING: f32 = 0.05;

/// The wall under a placed implant: its heights over the plane tangent to it.
#[derive(Clone, Debug, PartialEq)]
pub struct Wall {
    /// The base's centre, on the wall.
    pub origin: Vec3,
    /// The wall's outward normal there (unit).
    pub normal: Vec3,
    /// Two unit axes across `normal`.
    pub u: Vec3,
    /// See `u`.
    pub v: Vec3,
    /// The grid's spacing, and its nodes along `u` and `v` from `-half` to `half` cells.
    pub cell: f32,
    half: i32,
    heights: Vec<f32>,
}

/// Why a wall could not be sampled.
#[derive(Clone, Debug, PartialEq)]
pub enum WallError {
    /// The surface has no triangle near the point.
    Empty,
    /// The wall does not reach under the whole base: a node within the base's radius (its
    /// distance from the centre, in file units) missed it.
    Short(f32),
}

impl std::fmt::Display for WallError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            WallError::Empty => write!(f, "the chest wall has no triangles"),
            WallError::Short(r) => {
                write!(f, "the chest wall does not reach under the implant's base ({r:.1} from its centre)")
            }
        }
    }
}

impl std::error::Error for WallError {}

impl Wall {
    /// The wall of `triangles` (corners, facing outward) under `near`: its frame at the closest
    /// point to `near`, its normal averaged over `radius` about it, and heights on a grid of
    /// `cell` out to `reach` (at least `radius`). Every node within `radius` must meet the
    /// wall. `up` (any vector) turns `u` and `v`: `v` is `up` across the normal where it can be.
    ///
    /// # Errors
    /// [`WallError`] for a wall with no triangles, or one that does not reach under `radius`.
    pub fn sample(
        triangles: &[[Vec3; 3]],
        near: Vec3,
        radius: f32,
        reach: f32,
        cell: f32,
        up: Vec3,
    ) -> Result<Wall, WallError> {
        let tris: Vec<[DVec3; 3]> = triangles.iter().map(|t| t.map(Vec3::as_dvec3)).collect();
        let q = near.as_dvec3();
        let origin = tris
            .iter()
            .map(|t| crate::geometry::closest_point(q, t))
            .filter(|c| c.is_finite())
            .min_by(|a, b| a.distance_squared(q).total_cmp(&b.distance_squared(q)))
            .ok_or(WallError::Empty)?;
        let r = f64::from(radius);
        let mut normal = DVec3::ZERO;
        for t @ [a, b, c] in &tris {
            let centre = (*a + *b + *c) / 3.0;
            if centre.distance(origin) <= r
                || crate::geometry::closest_point(origin, t).distance(origin) < 1e-9
            {
                normal += (*b - *a).cross(*c - *a);
            }
        }
        let mut normal = normal.try_normalize().ok_or(WallError::Empty)?;
        // The wall faces the skin: a point in front of it (the landmark) says which way.
        if normal.dot(q - origin) < 0.0 {
            normal = -normal;
        }
        let up = up.as_dvec3();
        let across = up - up.dot(normal) * normal;
        let v = across.try_normalize().unwrap_or_else(|| normal.any_orthonormal_vector());
        let u = v.cross(normal);
        let half = (reach.max(radius) / cell).ceil() as i32 + 1;
        let side = (2 * half + 1) as usize;
        // Only triangles that come near the grid's prism can meet its lines.
        let span = f64::from(cell) * f64::from(half) * std::f64::consts::SQRT_2 + 1e-6;
        let near_tris: Vec<[DVec3; 3]> = tris
            .iter()
            .filter(|t| {
                t.iter().any(|p| {
                    let d = *p - origin;
                    (d - d.dot(normal) * normal).length() <= span
                }) || {
                    let d = (t[0] + t[1] + t[2]) / 3.0 - origin;
                    (d - d.dot(normal) * normal).length()
                        <= span + t[0].distance(t[1]).max(t[0].distance(t[2]))
                }
            })
            .copied()
            .collect();
        use rayon::prelude::*;
        let heights: Vec<f32> = (0..side * side)
            .into_par_iter()
            .map(|k| {
                let (i, j) = ((k % side) as i32 - half, (k / side) as i32 - half);
                let p = origin + f64::from(cell) * (f64::from(i) * u + f64::from(j) * v);
                near_tris
                    .iter()
                    .filter_map(|t| crate::geometry::line_crossing(p, normal, *t, 1e-9))
                    .min_by(|a, b| a.abs().total_cmp(&b.abs()))
                    .map_or(f32::NAN, |t| t as f32)
            })
            .collect();
        let wall = Wall {
            origin: origin.as_vec3(),
            normal: normal.as_vec3(),
            u: u.as_vec3(),
            v: v.as_vec3(),
            cell,
            half,
            heights,
        };
        // Every node under the base (and the cells about it) meets the wall.
        for k in 0..side * side {
            let (i, j) = ((k % side) as i32 - half, (k / side) as i32 - half);
            let d = cell * ((i * i + j * j) as f32).sqrt();
            if wall.heights[k].is_nan() && d <= radius + cell * std::f32::consts::SQRT_2 {
                return Err(WallError::Short(d));
            }
        }
        Ok(wall)
    }

    /// `p` in the wall's frame: across (`u`, `v`) and its height along the normal.
    #[must_use]
    pub fn local(&self, p: Vec3) -> Vec3 {
        let d = p - self.origin;
        Vec3::new(d.dot(self.u), d.dot(self.v), d.dot(self.normal))
    }

    /// The point of local coordinates `l` ([`local`](Self::local)).
    #[must_use]
    pub fn point(&self, l: Vec3) -> Vec3 {
        self.origin + l.x * self.u + l.y * self.v + l.z * self.normal
    }

    /// The wall's height across `(x, y)` (local), bilinear; `None` off the grid or where a
    /// corner of the cell missed the wall.
    #[must_use]
    pub fn height(&self, x: f32, y: f32) -> Option<f32> {
        let side = 2 * self.half + 1;
        let gx = x / self.cell + self.half as f32;
        let gy = y / self.cell + self.half as f32;
        if !(gx >= 0.0 && gy >= 0.0 && gx <= (side - 1) as f32 && gy <= (side - 1) as f32) {
            return None;
        }
        let (i, j) = ((gx as i32).min(side - 2), (gy as i32).min(side - 2));
        let (fx, fy) = (gx - i as f32, gy - j as f32);
        let at = |a: i32, b: i32| self.heights[(a + side * b) as usize];
        let (h00, h10, h01, h11) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
        let h = (1.0 - fy) * ((1.0 - fx) * h00 + fx * h10) + fy * ((1.0 - fx) * h01 + fx * h11);
        h.is_finite().then_some(h)
    }

    /// Where across the wall (`(x, y)` local) a base of `radius` centred at the origin would
    /// stand to keep its rim within each of `borders` (points, for example her breast's medial
    /// and lateral borders on the skin), seen from `from` (the landmark it stands under). All
    /// are seen along the normal on the plane across, and each border bounds the base by the
    /// line through it square to its direction from `from`. A border that leaves the base room
    /// asks nothing, so the answer is the origin where all do. Returns a move that keeps within
    /// them all (the least for one border, or for two across each other; for two at an angle,
    /// averaged projections onto each, which may move a little more than the least), and where
    /// they leave less room than the base needs, how much the base overreaches at most (`0`
    /// where it fits); then the move shares that overreach between them, the least it can at
    /// the most overreached (centred between two across each other).
    #[must_use]
    pub fn within(&self, radius: f32, from: Vec3, borders: &[Vec3]) -> (glam::Vec2, f32) {
        let from = self.local(from).truncate();
        // Each border as a half-plane: s · d ≤ b · d − radius.
        let planes: Vec<(glam::Vec2, f32)> = borders
            .iter()
            .filter_map(|p| {
                let b = self.local(*p).truncate();
                let d = (b - from).try_normalize()?;
                Some((d, b.dot(d) - radius))
            })
            .collect();
        let over = |s: glam::Vec2| planes.iter().map(|(d, c)| s.dot(*d) - c).fold(0.0f32, f32::max);
        // Into the half-planes each loosened by `slack`, from the origin: Cimmino's
        // projections, averaged (each step moves along the borders' directions only, so
        // nothing moves the base along a line no border asks about).
        let into = |slack: f32| {
            let mut s = glam::Vec2::ZERO;
            for _ in 0..400 {
                let step: glam::Vec2 =
                    planes.iter().map(|(d, c)| (s.dot(*d) - c - slack).max(0.0) * *d).sum();
                s -= step / planes.len() as f32;
                if step.length() <= 1e-6 * radius {
                    break;
                }
            }
            s
        };
        if planes.is_empty() {
            return (glam::Vec2::ZERO, 0.0);
        }
        let tolerance = 1e-3 * radius;
        let s = into(0.0);
        if over(s) <= tolerance {
            return (s, 0.0);
        }
        // Too little room: the least overreach that leaves some, by bisection (the origin
        // overreaches by `over(0)`, so that much always does).
        let (mut lo, mut hi) = (0.0f32, over(glam::Vec2::ZERO));
        for _ in 0..64 {
            if hi - lo <= 1e-4 * radius {
                break;
            }
            let mid = 0.5 * (lo + hi);
            if over(into(mid)) <= mid + tolerance {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let s = into(hi);
        let left = over(s);
        (s, if left > tolerance { left } else { 0.0 })
    }

    /// How far `p` lies in front of the wall raised by `offset` along the normal (negative:
    /// behind it); `None` where the wall is not sampled.
    #[must_use]
    pub fn above(&self, p: Vec3, offset: f32) -> Option<f32> {
        let l = self.local(p);
        self.height(l.x, l.y).map(|h| l.z - h - offset)
    }

    /// Whether a vertex at `p` rests on the wall raised by `offset`, for a step's solve and its
    /// residual: on it, behind it, or within [`RESTING`] of its cell in front of it. A vertex
    /// that slid a rounding off the wall is still on it (taken as in flight, the solve pulled
    /// it back at the speed its load gives in one step, and the whole step was cut short to
    /// keep that motion within what a contact sees arrive).
    #[must_use]
    pub fn rests(&self, p: Vec3, offset: f32) -> bool {
        self.above(p, offset).is_some_and(|a| a <= RESTING * self.cell)
    }

    /// Whether `p` is on or behind the wall raised by `offset`: within a thousandth of the
    /// grid's cell of it (a point [`push_out`](Self::push_out) put on the wall is there to a
    /// rounding of its coordinates, either side).
    #[must_use]
    pub fn holds(&self, p: Vec3, offset: f32) -> bool {
        self.above(p, offset).is_some_and(|a| a <= 1e-3 * self.cell)
    }

    /// Puts a point behind the wall raised by `offset` onto it, along the normal, and takes
    /// away its speed into the wall, and with `friction` (Coulomb's coefficient) that times
    /// the speed taken of its speed along the wall (an impulse within the friction cone).
    pub fn push_out(&self, pos: &mut Vec3, vel: &mut Vec3, offset: f32, friction: f32) {
        if let Some(a) = self.above(*pos, offset)
            && a < 0.0
        {
            *pos -= a * self.normal;
            let into = vel.dot(self.normal);
            if into < 0.0 {
                *vel -= into * self.normal;
                let along = vel.length();
                if friction > 0.0 && along > 0.0 {
                    *vel *= (along + friction * into).max(0.0) / along;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cylinder's wall of radius `big` about the y axis, its outside facing out, as triangles.
    fn barrel(big: f32) -> Vec<[Vec3; 3]> {
        let mut t = Vec::new();
        let (n, m) = (96, 40);
        let at = |i: i32, j: i32| {
            let a = std::f32::consts::PI * (i as f32 / n as f32 - 0.5);
            Vec3::new(big * a.sin(), -100.0 + 200.0 * j as f32 / m as f32, big * a.cos())
        };
        for i in 0..n {
            for j in 0..m {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                // Outward (+radial): counter-clockwise seen from outside.
                t.push([a, b, c]);
                t.push([a, c, d]);
            }
        }
        t
    }

    #[test]
    fn a_barrel_is_sampled_to_its_sagitta() {
        let big = 150.0;
        let tris = barrel(big);
        let wall = Wall::sample(&tris, Vec3::new(0.0, 0.0, 200.0), 57.5, 70.0, 2.5, Vec3::Y).unwrap();
        assert!(wall.origin.distance(Vec3::new(0.0, 0.0, big)) < 0.5, "{:?}", wall.origin);
        assert!(wall.normal.distance(Vec3::Z) < 1e-3, "{:?}", wall.normal);
        assert!(wall.v.distance(Vec3::Y) < 1e-3);
        // Across the barrel the wall falls away by R − √(R² − x²); along it, it stays.
        for x in [0.0f32, 20.0, 40.0, 57.5] {
            let want = -(big - (big * big - x * x).sqrt());
            let got = wall.height(x, 0.0).unwrap();
            assert!((got - want).abs() < 0.15, "at {x}: {got} against {want}");
            assert!(wall.height(0.0, x).unwrap().abs() < 0.15);
        }
        // A point behind it is pushed out along the normal and loses its speed into it.
        let mut p = wall.point(Vec3::new(40.0, 0.0, -10.0));
        let mut vel = Vec3::new(1.0, 0.0, -3.0);
        wall.push_out(&mut p, &mut vel, 0.0, 0.0);
        assert!(wall.above(p, 0.0).unwrap().abs() < 1e-3);
        assert!(vel.dot(wall.normal) >= 0.0 && (vel.x - 1.0).abs() < 1e-6);
        // With friction it also loses that times the speed taken of its speed along the wall
        // (Coulomb's impulse), down to none.
        for (friction, along) in [(0.2f32, 0.4f32), (0.5, 0.0)] {
            let mut p = wall.point(Vec3::new(0.0, 0.0, -10.0));
            let mut vel = Vec3::new(1.0, 0.0, -3.0);
            wall.push_out(&mut p, &mut vel, 0.0, friction);
            assert!(vel.distance(Vec3::new(along, 0.0, 0.0)) < 1e-5, "{friction}: {vel}");
        }
        // Raised by an offset, it holds that far in front.
        assert!(wall.holds(wall.point(Vec3::new(0.0, 0.0, 1.0)), 2.0));
        assert!(!wall.holds(wall.point(Vec3::new(0.0, 0.0, 1.0)), 0.0));
        // A vertex a rounding in front of it rests on it; one a fraction of a cell off does not.
        let on = |x: f32, gap: f32| wall.point(Vec3::new(x, 0.0, wall.height(x, 0.0).unwrap() + gap));
        assert!(wall.rests(on(40.0, 0.5 * RESTING * 2.5), 0.0));
        assert!(!wall.rests(on(40.0, 2.0 * RESTING * 2.5), 0.0));
        // Off the grid it holds nothing.
        assert_eq!(wall.height(500.0, 0.0), None);
    }

    #[test]
    fn a_base_keeps_within_the_borders_it_is_given() {
        let tris = barrel(150.0);
        let wall = Wall::sample(&tris, Vec3::new(0.0, 0.0, 200.0), 50.0, 70.0, 2.5, Vec3::Y).unwrap();
        // On the skin 40 in front of the wall, straight out from it.
        let skin = |x: f32, y: f32| wall.point(Vec3::new(x, y, 40.0));
        // None given, or one farther than the radius: it stays.
        assert_eq!(wall.within(50.0, skin(0.0, 0.0), &[]), (glam::Vec2::ZERO, 0.0));
        assert_eq!(wall.within(50.0, skin(0.0, 0.0), &[skin(-60.0, 0.0)]).0, glam::Vec2::ZERO);
        // A border 30 to one side moves it 20 the other way, and its rim stands at the border.
        let (s, over) = wall.within(50.0, skin(0.0, 0.0), &[skin(-30.0, 0.0)]);
        assert!(s.distance(glam::Vec2::new(20.0, 0.0)) < 1e-3 && over == 0.0, "{s} {over}");
        // Two across each other with room between: it moves only as far as the nearer asks.
        let (s, over) = wall.within(50.0, skin(0.0, 0.0), &[skin(-30.0, 0.0), skin(80.0, 0.0)]);
        assert!(s.distance(glam::Vec2::new(20.0, 0.0)) < 1e-3 && over == 0.0, "{s} {over}");
        // Borders 80 apart cannot hold a base 100 wide: it is centred between them and
        // overreaches each by 10.
        let (s, over) = wall.within(50.0, skin(0.0, 0.0), &[skin(-30.0, 0.0), skin(50.0, 0.0)]);
        assert!(s.distance(glam::Vec2::new(10.0, 0.0)) < 1e-2 && (over - 10.0).abs() < 1e-2, "{s} {over}");
        // Across two sides at once (medial and below): it moves away from both.
        let (s, over) = wall.within(50.0, skin(0.0, 0.0), &[skin(-30.0, 0.0), skin(0.0, -40.0)]);
        assert!(s.distance(glam::Vec2::new(20.0, 10.0)) < 1e-2 && over == 0.0, "{s} {over}");
    }

    #[test]
    fn a_wall_short_of_the_base_is_refused() {
        let tris = barrel(150.0);
        // Near the barrel's end (y = 100): the base's far side is off it.
        let e = Wall::sample(&tris, Vec3::new(0.0, 80.0, 200.0), 57.5, 70.0, 2.5, Vec3::Y).unwrap_err();
        assert!(matches!(e, WallError::Short(_)), "{e:?}");
        assert_eq!(Wall::sample(&[], Vec3::ZERO, 1.0, 1.0, 0.5, Vec3::Y).unwrap_err(), WallError::Empty);
    }
}
