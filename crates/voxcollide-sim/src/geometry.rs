//! Exact inside tests and distances for points against a closed triangle surface, independent of the
//! voxel model: how deep tissue vertices penetrate a foreign body's current shape.
//!
//! # Orientation and open surfaces
//!
//! Triangles must be counter-clockwise seen from outside (`cross(b - a, c - a)` points out), as
//! [`TriangleMesh`] documents. The inside test is the *generalized winding number* `w(p)`: the sum of
//! the signed solid angles of the triangles seen from `p`, divided by `4π`. For a closed surface
//! with that orientation it is 1 inside and 0 outside (up to rounding); a closed surface with the
//! opposite orientation gives −1 inside, which [`ClosedSurface::contains`] (`w > 0.5`) reports as
//! *outside*: orientation matters. For an open surface (a hole, a missing triangle) `w` is
//! fractional, e.g. 5/6 at the center of a cube with one face missing, and the 0.5 threshold still
//! gives the sensible answer "inside where most of the surface surrounds the point".
//!
//! # Acceleration
//!
//! Both queries walk one bounding-volume hierarchy over the triangles (median splits, a few
//! triangles a leaf):
//!
//! * [`ClosedSurface::distance`] is a nearest-triangle search that skips every node whose box is
//!   farther than the best triangle found so far.
//! * [`ClosedSurface::winding_number`] is the hierarchical evaluation of Jacobson et al. (2013,
//!   "Robust inside-outside segmentation using generalized winding numbers", §3.3). A node's
//!   triangles `N` have a boundary (the edges used by only one of its triangles, with direction);
//!   a fan `C` of triangles from one boundary vertex over those edges has the same boundary, so
//!   `N − C` is closed and lies in the node's box, and for a point outside that box its winding
//!   number is exactly 0: `w_N(p) = w_C(p)`. A compact patch of `k` triangles has a boundary of
//!   about `√k` edges, so a far node costs its (small) fan instead of all its triangles, and a
//!   query costs roughly the triangles near `p` plus the fans of the nodes around them. This is an
//!   identity, not an approximation, and it holds for open surfaces too. Far outside the whole
//!   surface's box, a closed surface has no boundary, an empty fan, and `w = 0` at no cost.

use std::f64::consts::TAU;

use glam::{DVec3, Vec3};

use crate::mesh::TriangleMesh;

/// The most triangles in a leaf of the hierarchy.
const LEAF_SIZE: usize = 4;

/// The margin, relative to the surface's bounding-box diagonal, by which a point must be outside a
/// node's box before the node's fan replaces its triangles: a fan triangle may lie on the box's
/// face, and a point almost on it would see a nearly singular solid angle the real triangles do
/// not have.
const FAR_MARGIN: f64 = 1e-6;

/// No child: the node is a leaf.
const NONE: u32 = u32::MAX;

/// One triangle's corners in `f64`, so that every later difference and product is exact or
/// nearly so (the positions are `f32`).
#[derive(Clone, Copy, Debug)]
struct Triangle {
    a: DVec3,
    b: DVec3,
    c: DVec3,
    /// Zero area: contributes no solid angle (and would give a spurious ±2π for a point on its
    /// line), and its closest point is found on its edges.
    degenerate: bool,
}

impl Triangle {
    fn new(a: DVec3, b: DVec3, c: DVec3) -> Triangle {
        Triangle { a, b, c, degenerate: (b - a).cross(c - a) == DVec3::ZERO }
    }
}

/// How to evaluate a node's winding contribution for a point outside its box, whichever is
/// cheapest: its fan, its own triangles (a leaf), or each child's cheapest way.
#[derive(Clone, Copy, Debug)]
enum Far {
    /// `caps[start..end]`.
    Fan { start: u32, end: u32 },
    /// The node's triangles.
    Triangles,
    /// Both children.
    Children,
}

/// A node of the hierarchy: the box of `triangles[start..end]`, and its two children.
#[derive(Clone, Copy, Debug)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    start: u32,
    end: u32,
    left: u32,
    right: u32,
    far: Far,
}

/// The boundary of a set of triangles as a 1-chain: for each undirected edge `(lo, hi)` with
/// `lo < hi`, how many more times it runs `lo → hi` than `hi → lo`. Edges shared by two
/// consistently oriented triangles cancel; what remains is the boundary.
type Chain = HashMap<(u32, u32), i32>;
/// A hash map with a fixed, quick hash, for keys of small integers (the chains' edges, the
/// contacts' grid cells) where nothing depends on the map's order.
pub(crate) type HashMap<K, V> = std::collections::HashMap<K, V, foldhash::fast::FixedState>;

/// Adds the directed edge `u → v` to a chain, dropping it when it cancels.
fn add_edge(chain: &mut Chain, u: u32, v: u32, times: i32) {
    if u == v {
        return;
    }
    let (key, sign) = if u < v { ((u, v), times) } else { ((v, u), -times) };
    let m = chain.entry(key).or_insert(0);
    *m += sign;
    if *m == 0 {
        chain.remove(&key);
    }
}

/// A closed triangle surface ready for point queries (built once per frame).
///
/// Construction copies the triangles into a bounding-volume hierarchy (`O(T log T)`); queries do
/// not allocate. The positions must be finite (the answers are unspecified otherwise); every
/// triangle index must be within `positions`.
#[derive(Debug)]
pub struct ClosedSurface<'a> {
    positions: &'a [Vec3],
    mesh: &'a TriangleMesh,
    /// The triangles in hierarchy order: each node covers a contiguous range.
    triangles: Vec<Triangle>,
    /// The fan triangles of the nodes whose [`Far::Fan`] is cheapest.
    caps: Vec<Triangle>,
    /// Their corners, by vertex.
    cap_corners: Vec<[u32; 3]>,
    nodes: Vec<Node>,
    /// Index of the root in `nodes` (none when there are no triangles).
    root: Option<u32>,
    /// How far outside a node's box a point must be for the node to count as far.
    margin: f64,
    /// The triangles' hierarchy order, and the bounding-box diagonal it was built at.
    built: (Vec<u32>, f64),
    /// Whether the triangles have no boundary: the winding number is then an integer away from
    /// the surface, and a point can change sides only by crossing it.
    closed: bool,
}

/// The shape of a [`ClosedSurface`]'s hierarchy, without positions: which triangles each node
/// holds, which fan stands for it from afar, by vertex. Kept from one frame to the next and
/// [refit](ClosedSurface::refit) to the mesh's new positions.
#[derive(Clone, Debug)]
pub struct Hierarchy {
    order: Vec<u32>,
    cap_corners: Vec<[u32; 3]>,
    nodes: Vec<Node>,
    root: Option<u32>,
    /// A hash of the triangles it was built on ([`fingerprint`]).
    fingerprint: u64,
    positions: usize,
    /// The bounding-box diagonal at the build.
    extent: f64,
    /// The bounding-box diagonal at the last refit.
    now: f64,
    /// Whether the triangles have no boundary (every edge used once each way).
    closed: bool,
}

/// A hash of a mesh's triangles, their count included: a hierarchy refits only the triangles
/// it was built on.
fn fingerprint(mesh: &TriangleMesh) -> u64 {
    use std::hash::BuildHasher;
    foldhash::fast::FixedState::default().hash_one(&mesh.triangles)
}

/// [`Error::Invalid`](voxcollide::Error::Invalid) naming the first triangle that indexes
/// outside `positions`.
fn check_indices(positions: &[Vec3], mesh: &TriangleMesh) -> Result<(), voxcollide::Error> {
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&i) = tri.iter().find(|&&i| i as usize >= positions.len()) {
            return Err(voxcollide::Error::Invalid {
                what: "triangle vertex index",
                value: i.to_string(),
                rule: format!("triangle {t} must index one of the {} positions", positions.len()),
            });
        }
    }
    Ok(())
}

impl Hierarchy {
    /// Whether the surface's bounding box has grown or shrunk by more than a quarter since the
    /// hierarchy was built (its boxes then overlap more than a fresh build's, and queries slow
    /// down): time to build anew.
    #[must_use]
    pub fn stale(&self) -> bool {
        !(self.now <= 1.25 * self.extent && self.now >= 0.8 * self.extent)
    }
}

impl<'a> ClosedSurface<'a> {
    /// Builds the query structure for the triangles of `mesh` over `positions`.
    ///
    /// Positions not used by any triangle are ignored (the bounding box is the triangles').
    ///
    /// # Errors
    ///
    /// [`Error::Invalid`](voxcollide::Error::Invalid) if a triangle indexes outside `positions`.
    pub fn new(
        positions: &'a [Vec3],
        mesh: &'a TriangleMesh,
    ) -> Result<ClosedSurface<'a>, voxcollide::Error> {
        check_indices(positions, mesh)?;
        let mut builder = Builder {
            positions,
            indices: &mesh.triangles,
            order: (0..mesh.triangles.len() as u32).collect(),
            centroids: mesh
                .triangles
                .iter()
                .map(|t| t.iter().map(|&i| positions[i as usize].as_dvec3()).sum::<DVec3>() / 3.0)
                .collect(),
            nodes: Vec::new(),
            caps: Vec::new(),
        };
        let (root, closed) = if mesh.triangles.is_empty() {
            (None, true)
        } else {
            let (root, _, chain) = builder.build(0, mesh.triangles.len());
            (Some(root), chain.is_empty())
        };
        let hierarchy = Hierarchy {
            order: builder.order,
            cap_corners: builder.caps,
            nodes: builder.nodes,
            root,
            fingerprint: fingerprint(mesh),
            positions: positions.len(),
            extent: 0.0,
            now: 0.0,
            closed,
        };
        Ok(ClosedSurface::fitted(positions, mesh, hierarchy))
    }

    /// The surface of `mesh` over `positions` on the shape of a hierarchy kept from an earlier
    /// frame of the same mesh ([`ClosedSurface::into_hierarchy`]): its boxes and triangles
    /// refit to the new positions in `O(T)`, where [`ClosedSurface::new`] sorts and merges
    /// boundary chains in `O(T log T)`. The answers are those of any hierarchy over the same
    /// triangles (the fans are an identity, the boxes bound what they hold); at the positions
    /// it was built on, exactly those of [`ClosedSurface::new`]. A mesh that has deformed far
    /// from where the hierarchy was built is answered as correctly, only more slowly: see
    /// [`Hierarchy::stale`].
    ///
    /// # Errors
    ///
    /// [`Error::Invalid`](voxcollide::Error::Invalid) if the hierarchy was built over another
    /// mesh (other triangles, or another count of positions: its fans would stand for
    /// triangles that are not there), or a triangle indexes outside `positions`.
    pub fn refit(
        positions: &'a [Vec3],
        mesh: &'a TriangleMesh,
        hierarchy: Hierarchy,
    ) -> Result<ClosedSurface<'a>, voxcollide::Error> {
        if hierarchy.fingerprint != fingerprint(mesh) || hierarchy.positions != positions.len() {
            return Err(voxcollide::Error::Invalid {
                what: "surface hierarchy",
                value: format!("{} triangles over {} positions", mesh.triangles.len(), positions.len()),
                rule: format!(
                    "a hierarchy refits only the triangles it was built on, over as many positions ({})",
                    hierarchy.positions
                ),
            });
        }
        check_indices(positions, mesh)?;
        Ok(ClosedSurface::fitted(positions, mesh, hierarchy))
    }

    /// The triangles, fans and boxes of `hierarchy` at `positions` (the nodes are stored
    /// children first, so each box is its triangles' or its children's).
    fn fitted(positions: &'a [Vec3], mesh: &'a TriangleMesh, mut hierarchy: Hierarchy) -> ClosedSurface<'a> {
        let at = |i: u32| positions[i as usize].as_dvec3();
        let triangles: Vec<Triangle> = hierarchy
            .order
            .iter()
            .map(|&t| {
                let [a, b, c] = mesh.triangles[t as usize].map(at);
                Triangle::new(a, b, c)
            })
            .collect();
        let caps =
            hierarchy.cap_corners.iter().map(|&[a, b, c]| Triangle::new(at(a), at(b), at(c))).collect();
        for k in 0..hierarchy.nodes.len() {
            let node = hierarchy.nodes[k];
            let (lo, hi) = if node.left == NONE {
                triangles[node.start as usize..node.end as usize]
                    .iter()
                    .fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(lo, hi), t| {
                        (lo.min(t.a).min(t.b).min(t.c), hi.max(t.a).max(t.b).max(t.c))
                    })
            } else {
                let (l, r) = (&hierarchy.nodes[node.left as usize], &hierarchy.nodes[node.right as usize]);
                (l.lo.min(r.lo), l.hi.max(r.hi))
            };
            hierarchy.nodes[k].lo = lo;
            hierarchy.nodes[k].hi = hi;
        }
        let extent = hierarchy.root.map_or(0.0, |r| {
            let n = &hierarchy.nodes[r as usize];
            (n.hi - n.lo).length()
        });
        if hierarchy.extent == 0.0 {
            hierarchy.extent = extent;
        }
        ClosedSurface {
            positions,
            mesh,
            triangles,
            caps,
            cap_corners: hierarchy.cap_corners,
            nodes: hierarchy.nodes,
            root: hierarchy.root,
            margin: FAR_MARGIN * extent.max(f64::MIN_POSITIVE),
            built: (hierarchy.order, hierarchy.extent),
            closed: hierarchy.closed,
        }
    }

    /// The hierarchy's shape, to [`refit`](ClosedSurface::refit) at a later frame.
    #[must_use]
    pub fn into_hierarchy(self) -> Hierarchy {
        let extent = self.root.map_or(0.0, |r| {
            let n = &self.nodes[r as usize];
            (n.hi - n.lo).length()
        });
        Hierarchy {
            order: self.built.0,
            cap_corners: self.cap_corners,
            nodes: self.nodes,
            root: self.root,
            fingerprint: fingerprint(self.mesh),
            positions: self.positions.len(),
            extent: self.built.1,
            now: extent,
            closed: self.closed,
        }
    }

    /// The positions the surface was built on.
    #[must_use]
    pub fn positions(&self) -> &'a [Vec3] {
        self.positions
    }

    /// The triangles the surface was built on.
    #[must_use]
    pub fn mesh(&self) -> &'a TriangleMesh {
        self.mesh
    }

    /// The axis-aligned bounding box `(min, max)` of the triangles' corners; `None` without
    /// triangles.
    #[must_use]
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        self.root.map(|r| {
            let n = &self.nodes[r as usize];
            (n.lo.as_vec3(), n.hi.as_vec3())
        })
    }

    /// The generalized winding number of the surface around p (≈1 inside, ≈0 outside for a closed
    /// CCW surface), by summing signed solid angles (Van Oosterom–Strackee), in f64 for robustness.
    ///
    /// Reversed orientation gives ≈−1 inside; an open surface gives fractional values (see the
    /// module documentation). Zero-area triangles contribute nothing. On the surface itself the
    /// value is finite but not meaningful (about 0.5 on a face). A point with a non-finite
    /// coordinate gets 0: it is never inside.
    #[must_use]
    pub fn winding_number(&self, p: Vec3) -> f64 {
        let Some(root) = self.root else { return 0.0 };
        if !p.is_finite() {
            return 0.0;
        }
        let p = p.as_dvec3();
        // Each term is half the triangle's solid angle Ω/2; w = ΣΩ / 4π = Σ(Ω/2) / 2π.
        let mut sum = 0.0;
        let mut stack = [0u32; 64];
        stack[0] = root;
        let mut len = 1;
        while len > 0 {
            len -= 1;
            let node = &self.nodes[stack[len] as usize];
            let far = self.outside_box(node, p);
            let (start, end) = (node.start as usize, node.end as usize);
            match (far, node.far) {
                (true, Far::Fan { start: fan_start, end: fan_end }) => {
                    sum += self.caps[fan_start as usize..fan_end as usize]
                        .iter()
                        .filter(|t| !t.degenerate)
                        .map(|t| half_solid_angle(t, p))
                        .sum::<f64>();
                }
                (true, Far::Triangles) => sum += self.sum_triangles(start, end, p),
                _ if node.left == NONE => sum += self.sum_triangles(start, end, p),
                // Near (or far and cheapest by children): both children. The depth is about
                // log2(T / LEAF_SIZE) + 1 since splits are at the median, so 64 slots are plenty.
                _ => {
                    stack[len] = node.right;
                    stack[len + 1] = node.left;
                    len += 2;
                }
            }
        }
        sum / TAU
    }

    /// Whether p is inside (winding number > 0.5); false for points outside the bounding box.
    ///
    /// Non-finite points are never inside. The answer for a point on the surface itself (within
    /// rounding) is unspecified.
    #[must_use]
    pub fn contains(&self, p: Vec3) -> bool {
        let Some(root) = self.root else { return false };
        if !p.is_finite() {
            return false;
        }
        let n = &self.nodes[root as usize];
        let q = p.as_dvec3();
        if q.cmplt(n.lo).any() || q.cmpgt(n.hi).any() {
            return false;
        }
        self.winding_number(p) > 0.5
    }

    /// Unsigned distance from p to the nearest point of the surface (closest point on triangle,
    /// Ericson's method).
    ///
    /// Infinite without triangles or for an infinite point; NaN for a point with a NaN
    /// coordinate.
    #[must_use]
    pub fn distance(&self, p: Vec3) -> f32 {
        if p.is_nan() {
            return f32::NAN;
        }
        let Some(root) = self.root else { return f32::INFINITY };
        if !p.is_finite() {
            return f32::INFINITY;
        }
        let p = p.as_dvec3();
        let mut best = f64::INFINITY;
        let mut stack = [0u32; 64];
        stack[0] = root;
        let mut len = 1;
        while len > 0 {
            len -= 1;
            let node = &self.nodes[stack[len] as usize];
            if box_distance2(node, p) >= best {
                continue;
            }
            if node.left == NONE {
                for t in &self.triangles[node.start as usize..node.end as usize] {
                    best = best.min(triangle_distance2(t, p));
                }
            } else {
                // Visit the nearer child first (pushed last), so the farther one is more often
                // skipped.
                let (l, r) = (&self.nodes[node.left as usize], &self.nodes[node.right as usize]);
                let (near, far) = if box_distance2(l, p) <= box_distance2(r, p) {
                    (node.left, node.right)
                } else {
                    (node.right, node.left)
                };
                stack[len] = far;
                stack[len + 1] = near;
                len += 2;
            }
        }
        best.sqrt() as f32
    }

    /// Whether the ray from `p` along `d` (not necessarily unit) meets a triangle of the
    /// surface, on a triangle's edge included; false for a non-finite `p` or `d`, or a zero
    /// `d`. Skips every node whose box the ray misses (slabs).
    #[must_use]
    pub fn ray_hits(&self, p: Vec3, d: Vec3) -> bool {
        let Some(root) = self.root else { return false };
        if !p.is_finite() || !d.is_finite() || d == Vec3::ZERO {
            return false;
        }
        let (p, d) = (p.as_dvec3(), d.as_dvec3());
        let inv = d.recip();
        let mut stack = [0u32; 64];
        stack[0] = root;
        let mut len = 1;
        while len > 0 {
            len -= 1;
            let node = &self.nodes[stack[len] as usize];
            if !ray_meets_box(node, p, inv) {
                continue;
            }
            if node.left == NONE {
                let tris = &self.triangles[node.start as usize..node.end as usize];
                if tris.iter().any(|t| line_crossing(p, d, [t.a, t.b, t.c], 1e-9).is_some_and(|s| s >= 0.0)) {
                    return true;
                }
            } else {
                stack[len] = node.left;
                stack[len + 1] = node.right;
                len += 2;
            }
        }
        false
    }

    /// Whether `p` is outside `node`'s box by more than the margin, so that its fan may stand in
    /// for its triangles.
    fn outside_box(&self, node: &Node, p: DVec3) -> bool {
        let m = self.margin;
        p.x < node.lo.x - m
            || p.y < node.lo.y - m
            || p.z < node.lo.z - m
            || p.x > node.hi.x + m
            || p.y > node.hi.y + m
            || p.z > node.hi.z + m
    }

    /// `Σ Ω/2` over `triangles[start..end]`.
    fn sum_triangles(&self, start: usize, end: usize, p: DVec3) -> f64 {
        self.triangles[start..end].iter().filter(|t| !t.degenerate).map(|t| half_solid_angle(t, p)).sum()
    }
}

/// Half the signed solid angle of a triangle seen from `p` (Van Oosterom & Strackee 1983):
/// `tan(Ω/2) = a·(b×c) / (|a||b||c| + (a·b)|c| + (a·c)|b| + (b·c)|a|)` with `a, b, c` the corners
/// relative to `p`. Positive when `p` is on the inner side of a counter-clockwise triangle.
/// `atan2` keeps the quadrant (Ω up to ±2π) and never gives NaN for finite arguments, even `0 / 0`.
fn half_solid_angle(t: &Triangle, p: DVec3) -> f64 {
    let (a, b, c) = (t.a - p, t.b - p, t.c - p);
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let num = a.dot(b.cross(c));
    let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    num.atan2(den)
}

/// Squared distance from `p` to `node`'s box (0 inside).
fn box_distance2(node: &Node, p: DVec3) -> f64 {
    let d = (node.lo - p).max(p - node.hi).max(DVec3::ZERO);
    d.dot(d)
}

/// Whether the ray `p + t·d`, `t ≥ 0` (`inv` = `1 / d` componentwise, infinite along an axis
/// it does not move on), meets `node`'s box, its faces included (slabs; NaN comparisons of a
/// ray along a face count as meeting).
fn ray_meets_box(node: &Node, p: DVec3, inv: DVec3) -> bool {
    let (a, b) = ((node.lo - p) * inv, (node.hi - p) * inv);
    let (near, far) = (a.min(b), a.max(b));
    let enter = near.max_element().max(0.0);
    let leave = far.min_element();
    // (`min_element`/`max_element` skip a NaN: a ray along a face is judged by the others.)
    enter <= leave
}

/// `n / d` for a denominator that is mathematically positive but may round to 0 on a
/// degenerate edge; 0 then (the edge is a point, any parameter gives it).
fn ratio(n: f64, d: f64) -> f64 {
    if d > 0.0 { n / d } else { 0.0 }
}

/// Squared distance from `p` to the segment `a b` (a point when `a == b`).
fn segment_distance2(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let t = ratio((p - a).dot(ab), ab.dot(ab)).clamp(0.0, 1.0);
    (a + ab * t).distance_squared(p)
}

/// Coordinates that [`closest_region`] works in: `f32` ([`Vec3`], the surface contact's) or
/// `f64` ([`DVec3`], the penetration measure's), with the same operations in the same order.
pub(crate) trait Coords: Copy + std::ops::Sub<Output = Self> {
    /// The scalar.
    type S: Copy
        + PartialOrd
        + std::ops::Add<Output = Self::S>
        + std::ops::Sub<Output = Self::S>
        + std::ops::Mul<Output = Self::S>
        + std::ops::Div<Output = Self::S>;
    /// Zero.
    const ZERO: Self::S;
    /// The dot product.
    fn dot(self, other: Self) -> Self::S;
}

impl Coords for Vec3 {
    type S = f32;
    const ZERO: f32 = 0.0;
    fn dot(self, other: Vec3) -> f32 {
        Vec3::dot(self, other)
    }
}

impl Coords for DVec3 {
    type S = f64;
    const ZERO: f64 = 0.0;
    fn dot(self, other: DVec3) -> f64 {
        DVec3::dot(self, other)
    }
}

/// Where on triangle `abc` the point nearest to `p` lies ([`closest_region`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Region<S> {
    /// Corner 0, 1 or 2.
    Vertex(u8),
    /// Edge `ab` at `a + t·(b − a)` (0), `bc` at `b + t·(c − b)` (1), or `ca` at `a + t·(c − a)` (2).
    Edge(u8, S),
    /// Inside the face: `a + (vb/sum)·(b − a) + (vc/sum)·(c − a)`, where `sum` (`|ab × ac|²` up
    /// to rounding) is positive; a sliver can round it to 0 or below, which the caller handles.
    Face {
        /// The weight of `b`, times `sum`.
        vb: S,
        /// The weight of `c`, times `sum`.
        vc: S,
        /// `va + vb + vc`.
        sum: S,
    },
}

/// The Voronoi region of triangle `abc` that holds the point nearest to `p` (Ericson,
/// *Real-Time Collision Detection*, §5.1.5), in `f32` or `f64` alike: the one closest-point
/// routine of the crate, which the surface contact ([`crate::contact::surface`]) and the
/// penetration measure ([`ClosedSurface`]) both build on. An edge's parameter is 0 where its
/// ratio's denominator is not positive (an edge of no length).
pub(crate) fn closest_region<V: Coords>(p: V, a: V, b: V, c: V) -> Region<V::S> {
    let zero = V::ZERO;
    let ratio = |n: V::S, d: V::S| if d > zero { n / d } else { zero };
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= zero && d2 <= zero {
        return Region::Vertex(0);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= zero && d4 <= d3 {
        return Region::Vertex(1);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= zero && d1 >= zero && d3 <= zero {
        return Region::Edge(0, ratio(d1, d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= zero && d5 <= d6 {
        return Region::Vertex(2);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= zero && d2 >= zero && d6 <= zero {
        return Region::Edge(2, ratio(d2, d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= zero && d4 - d3 >= zero && d5 - d6 >= zero {
        return Region::Edge(1, ratio(d4 - d3, (d4 - d3) + (d5 - d6)));
    }
    Region::Face { vb, vc, sum: va + vb + vc }
}

/// Where the line `p + t·d` meets triangle `[a, b, c]` (Möller and Trumbore 1997): `t`,
/// where the meeting point's barycentric weights are each at least `-eps`; `None` elsewhere,
/// or for a line along the triangle's plane.
#[must_use]
pub fn line_crossing(p: DVec3, d: DVec3, [a, b, c]: [DVec3; 3], eps: f64) -> Option<f64> {
    let (e1, e2) = (b - a, c - a);
    let h = d.cross(e2);
    let det = e1.dot(h);
    if det.abs() < 1e-300 {
        return None;
    }
    let s = p - a;
    let w1 = s.dot(h) / det;
    let q = s.cross(e1);
    let w2 = d.dot(q) / det;
    (w1 >= -eps && w2 >= -eps && w1 + w2 <= 1.0 + eps).then(|| e2.dot(q) / det)
}

/// The point of triangle `abc` nearest to `p` (`closest_region`, which the surface contact
/// shares); a sliver whose face weights round to nothing is measured on its edges.
#[must_use]
pub fn closest_point(p: DVec3, [a, b, c]: &[DVec3; 3]) -> DVec3 {
    let on_edge = |a: DVec3, b: DVec3| {
        let ab = b - a;
        a + ab * ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
    };
    let (ab, ac) = (*b - *a, *c - *a);
    match closest_region(p, *a, *b, *c) {
        Region::Vertex(0) => *a,
        Region::Vertex(1) => *b,
        Region::Vertex(_) => *c,
        Region::Edge(0, t) => *a + ab * t,
        Region::Edge(1, t) => *b + (*c - *b) * t,
        Region::Edge(_, t) => *a + ac * t,
        Region::Face { sum, .. } if sum.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) => {
            [on_edge(*a, *b), on_edge(*b, *c), on_edge(*c, *a)]
                .into_iter()
                .filter(|q| q.is_finite())
                .min_by(|q, r| q.distance_squared(p).total_cmp(&r.distance_squared(p)))
                .unwrap_or(*a)
        }
        Region::Face { vb, vc, sum } => *a + ab * (vb / sum) + ac * (vc / sum),
    }
}

/// Squared distance from `p` to the triangle, through its closest point ([`closest_region`]).
/// Zero-area triangles, for which the face region's barycentric denominator vanishes, are
/// measured on their three edges instead.
fn triangle_distance2(t: &Triangle, p: DVec3) -> f64 {
    let edges = || {
        segment_distance2(p, t.a, t.b).min(segment_distance2(p, t.b, t.c)).min(segment_distance2(p, t.c, t.a))
    };
    if t.degenerate {
        return edges();
    }
    let (a, b, c) = (t.a, t.b, t.c);
    let (ab, ac) = (b - a, c - a);
    match closest_region(p, a, b, c) {
        Region::Vertex(0) => a.distance_squared(p),
        Region::Vertex(1) => b.distance_squared(p),
        Region::Vertex(_) => c.distance_squared(p),
        Region::Edge(0, t) => (a + ab * t).distance_squared(p),
        Region::Edge(1, t) => (b + (c - b) * t).distance_squared(p),
        Region::Edge(_, t) => (a + ac * t).distance_squared(p),
        // A sliver whose denominator rounds to 0 (or below) is measured on its edges.
        Region::Face { sum, .. } if sum <= 0.0 => edges(),
        Region::Face { vb, vc, sum } => (a + ab * (vb / sum) + ac * (vc / sum)).distance_squared(p),
    }
}

/// Builds the hierarchy and the fans, bottom-up.
struct Builder<'b> {
    positions: &'b [Vec3],
    indices: &'b [[u32; 3]],
    /// Triangle indices, permuted so that each node's are contiguous.
    order: Vec<u32>,
    centroids: Vec<DVec3>,
    nodes: Vec<Node>,
    caps: Vec<[u32; 3]>,
}

impl Builder<'_> {
    /// Builds the node over `order[start..end]`; returns its index, the cost (triangles summed)
    /// of its cheapest far evaluation, and its boundary chain.
    fn build(&mut self, start: usize, end: usize) -> (u32, usize, Chain) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        let mut clo = lo;
        let mut chi = hi;
        for &t in &self.order[start..end] {
            for i in self.indices[t as usize] {
                let v = self.positions[i as usize].as_dvec3();
                lo = lo.min(v);
                hi = hi.max(v);
            }
            let c = self.centroids[t as usize];
            clo = clo.min(c);
            chi = chi.max(c);
        }
        let count = end - start;
        let (left, right, chain, below) = if count <= LEAF_SIZE {
            let mut chain = Chain::default();
            for &t in &self.order[start..end] {
                let [a, b, c] = self.indices[t as usize];
                add_edge(&mut chain, a, b, 1);
                add_edge(&mut chain, b, c, 1);
                add_edge(&mut chain, c, a, 1);
            }
            (NONE, NONE, chain, count)
        } else {
            // Median split along the longest axis of the centroids' box: balanced, so the depth
            // stays about log2(T), and spatially compact, so the patches have short boundaries.
            let e = chi - clo;
            let axis = if e.x >= e.y && e.x >= e.z {
                0
            } else if e.y >= e.z {
                1
            } else {
                2
            };
            let mid = start + count / 2;
            let centroids = &self.centroids;
            self.order[start..end].select_nth_unstable_by(count / 2, |&s, &t| {
                centroids[s as usize][axis].total_cmp(&centroids[t as usize][axis]).then(s.cmp(&t))
            });
            let (l, lcost, lchain) = self.build(start, mid);
            let (r, rcost, rchain) = self.build(mid, end);
            // The boundary of the union is the sum of the boundaries: add the smaller chain into
            // the larger.
            let (mut chain, other) =
                if lchain.len() >= rchain.len() { (lchain, rchain) } else { (rchain, lchain) };
            for ((u, v), m) in other {
                add_edge(&mut chain, u, v, m);
            }
            (l, r, chain, lcost + rcost)
        };
        let fan = self.fan(&chain);
        let (far, cost) = if fan.len() <= below {
            let s = self.caps.len() as u32;
            self.caps.extend(fan);
            (Far::Fan { start: s, end: self.caps.len() as u32 }, self.caps.len() - s as usize)
        } else if left == NONE {
            (Far::Triangles, below)
        } else {
            (Far::Children, below)
        };
        self.nodes.push(Node { lo, hi, start: start as u32, end: end as u32, left, right, far });
        ((self.nodes.len() - 1) as u32, cost, chain)
    }

    /// The fan over a boundary chain from one of its vertices: triangles `(v0, u, w)` for each
    /// boundary edge `u → w`, repeated by multiplicity. Its boundary equals the chain, because the
    /// spokes `v0 → u` cancel around a cycle. Triangles through `v0` are left out (no solid
    /// angle); those of zero area now are kept, by vertex, for a refit may give them one.
    fn fan(&self, chain: &Chain) -> Vec<[u32; 3]> {
        if chain.is_empty() {
            return Vec::new();
        }
        // Sorted so the fan, and so the rounding of the sums, does not depend on hash order.
        let mut edges: Vec<(u32, u32, i32)> = chain.iter().map(|(&(u, v), &m)| (u, v, m)).collect();
        edges.sort_unstable();
        // The hub touching the most boundary edges leaves out the most triangles.
        let mut touches: HashMap<u32, usize> = HashMap::default();
        for &(u, v, m) in &edges {
            *touches.entry(u).or_default() += m.unsigned_abs() as usize;
            *touches.entry(v).or_default() += m.unsigned_abs() as usize;
        }
        let hub = touches.iter().max_by(|x, y| x.1.cmp(y.1).then(y.0.cmp(x.0))).map(|(&v, _)| v).unwrap();
        let mut fan = Vec::new();
        for (u, v, m) in edges {
            let (u, w) = if m > 0 { (u, v) } else { (v, u) };
            if u == hub || w == hub {
                continue;
            }
            fan.extend(std::iter::repeat_n([hub, u, w], m.unsigned_abs() as usize));
        }
        fan
    }
}

/// How deep a set of points is inside a closed surface.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Penetration {
    /// How many points are inside ([`ClosedSurface::contains`]).
    pub count: usize,
    /// `count / points.len()` (0 for no points).
    pub fraction: f32,
    /// The largest distance of an inside point to the surface; 0 when none is inside.
    pub max_depth: f32,
    /// The index of the deepest point (the first of equals); `None` when none is inside.
    pub deepest: Option<u32>,
}

/// The points of `points` inside the closed surface, and the deepest one's distance to it.
///
/// Non-finite points are never inside. Only inside points pay for a distance query. The
/// points are taken in chunks on every core and the chunks' answers combined in order: the
/// same answer, the first of equally deep points included, on any number of threads.
#[must_use]
pub fn penetration(surface: &ClosedSurface, points: &[Vec3]) -> Penetration {
    use rayon::prelude::*;
    let parts: Vec<Penetration> = points
        .par_chunks(PENETRATION_CHUNK)
        .enumerate()
        .map(|(c, chunk)| {
            let mut out = Penetration::default();
            for (k, &p) in chunk.iter().enumerate() {
                if surface.contains(p) {
                    out.inside(c * PENETRATION_CHUNK + k, surface.distance(p));
                }
            }
            out
        })
        .collect();
    Penetration::combined(parts, points.len())
}

/// Points per parallel task of [`penetration`] and [`PenetrationWatch::penetration`].
const PENETRATION_CHUNK: usize = 256;

impl Penetration {
    /// Counts point `i`, inside at `depth`: the deepest where deeper than all before it.
    fn inside(&mut self, i: usize, depth: f32) {
        self.count += 1;
        if self.deepest.is_none() || depth > self.max_depth {
            self.max_depth = depth;
            self.deepest = Some(i as u32);
        }
    }

    /// The chunks' answers combined in order (the first of equally deep points stays the
    /// deepest), over `points` points.
    fn combined(parts: Vec<Penetration>, points: usize) -> Penetration {
        let mut out = Penetration::default();
        for part in parts {
            out.count += part.count;
            if part.deepest.is_some() && (out.deepest.is_none() || part.max_depth > out.max_depth) {
                out.max_depth = part.max_depth;
                out.deepest = part.deepest;
            }
        }
        if points > 0 {
            out.fraction = out.count as f32 / points as f32;
        }
        out
    }
}

/// [`penetration`] from one frame to the next: the same answer, asking only the points that
/// may have changed sides.
///
/// A point found outside a closed surface at distance `d` cannot be inside it later unless it
/// and the surface have moved, together, `d` towards each other: its winding number is an
/// integer away from the surface and changes only as the point crosses it (along the straight
/// paths from then to now, it stays farther than `d − |Δp| − max|Δv|` from the surface, each of
/// whose points moves no farther than its farthest vertex). So each point keeps a lower bound
/// on its distance, lowered by its own move and the surface's largest vertex move at each call,
/// and is asked again only when the bound runs out. Points inside are asked every time (their
/// depth is the answer). Where the surface has a boundary (its winding number is not an
/// integer), or the points or the surface change in number, every point is asked.
#[derive(Clone, Debug, Default)]
pub struct PenetrationWatch {
    /// The surface's positions at the last call.
    surface: Vec<Vec3>,
    /// Per point: where it was at the last call, and a lower bound on its distance then to the
    /// surface: positive outside, negative inside (0: to be asked).
    at: Vec<(Vec3, f32)>,
    /// How many points the last call asked.
    pub asked: usize,
}

impl PenetrationWatch {
    /// [`penetration`] of `points` in `surface` now, asking only the points that may have
    /// changed sides since the last call.
    pub fn penetration(&mut self, surface: &ClosedSurface, points: &[Vec3]) -> Penetration {
        use rayon::prelude::*;
        let positions = surface.positions();
        let fresh = !surface.closed || self.surface.len() != positions.len() || self.at.len() != points.len();
        if fresh {
            self.surface = positions.to_vec();
            self.at = points.iter().map(|&p| (p, 0.0)).collect();
        }
        // The surface's largest vertex move (NaN or ∞ where a position is not finite: every
        // point is asked).
        let moved = positions
            .iter()
            .zip(&self.surface)
            .map(|(p, q)| p.distance(*q))
            .fold(0.0f32, |m, d| if d.is_nan() || m.is_nan() { f32::NAN } else { m.max(d) });
        let root = surface.root.map(|r| surface.nodes[r as usize]);
        let parts: Vec<(Penetration, usize)> = points
            .par_chunks(PENETRATION_CHUNK)
            .zip(self.at.par_chunks_mut(PENETRATION_CHUNK))
            .enumerate()
            .map(|(c, (chunk, at))| {
                let mut out = Penetration::default();
                let mut asked = 0;
                for (k, (&p, (then, clear))) in chunk.iter().zip(at.iter_mut()).enumerate() {
                    let gone = p.distance(*then) + moved;
                    *then = p;
                    // Slack for the rounding of the bound's sums.
                    if *clear > 0.0 && gone * 1.001 < *clear {
                        *clear -= gone * 1.001;
                        continue;
                    }
                    // Inside by more than it and the surface have moved since: inside still,
                    // and its depth now is the answer.
                    if *clear < 0.0 && gone * 1.001 < -*clear {
                        let d = surface.distance(p);
                        out.inside(c * PENETRATION_CHUNK + k, d);
                        *clear = if d.is_finite() { -0.999 * d } else { 0.0 };
                        continue;
                    }
                    asked += 1;
                    if surface.contains(p) {
                        let d = surface.distance(p);
                        out.inside(c * PENETRATION_CHUNK + k, d);
                        *clear = if d.is_finite() { -0.999 * d } else { 0.0 };
                        continue;
                    }
                    // Outside: outside the surface's box, the distance to the box bounds it.
                    let d = match root {
                        Some(n) if p.is_finite() => {
                            let outside_box = box_distance2(&n, p.as_dvec3()).sqrt();
                            if outside_box > 0.0 { outside_box as f32 } else { surface.distance(p) }
                        }
                        _ => 0.0,
                    };
                    *clear = if d.is_finite() { 0.999 * d } else { 0.0 };
                }
                (out, asked)
            })
            .collect();
        self.surface.copy_from_slice(positions);
        self.asked = parts.iter().map(|p| p.1).sum();
        Penetration::combined(parts.into_iter().map(|p| p.0).collect(), points.len())
    }
}
