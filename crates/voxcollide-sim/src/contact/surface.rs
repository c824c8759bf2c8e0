//! Contacts measured to the partner's surface, on both sides (`response = "surface"`, the default
//! of scene files): every vertex of each body is pushed out of the other's closed surface
//! by a penalty that grows with its depth, along the line to the nearest surface point, and the
//! equal and opposite reaction is shared by that point's triangle in its barycentric weights.
//!
//! **Why.** The voxel model's forces ([`voxcollide::Response`]) push `b`'s vertices out of `a`'s
//! and never `a`'s out of `b`, so a soft shell's vertices pass between the tissue's; and its force
//! comes from the nearest vertex or the plane through the three nearest, which jumps when the
//! partner switches, so contacts chatter and an implicit step cannot converge on them. Here the
//! force on a vertex at signed distance `s` from the partner's surface (negative inside) is
//! `k·(gap − s)` along the outward direction while `s < gap`: the gradient of the energy
//! `½·k·(gap − s)²`, continuous wherever the nearest point is (away from the surface's medial
//! axis), so its stiffness `k·nnᵀ` is what an implicit solve needs (docs/semantics.md, "Contacts
//! that hold").
//!
//! **A lattice that carries a surface** (one made from a closed surface, [`Embedding`]) shows
//! the contact that surface, not its own boundary (which lies up to a spacing inside it): the
//! carried surface's vertices are points numbered after the lattice's, each its cell's corners
//! in trilinear weights (a [`Stencil`]), and every force on such a point, or on a triangle
//! of that surface, is shared by those corners in those weights.
//!
//! **Inside or outside.** The nearest point of the partner's surface lies on a face, an edge or
//! a vertex; the sign of `s` is that of `(p − q)·n` with `n` that feature's pseudo-normal: the
//! face's normal, the sum of an edge's two faces' normals, or a vertex's angle-weighted normal
//! (Bærentzen and Aanæs 2005), exact for a closed, outward-oriented surface.
//!
//! **Finding the nearest triangle: the voxel model.** Each side keeps, per probing point, a list
//! of the partner's triangles within the cutoff plus a skin (half the cutoff), made anew only
//! when the bodies have moved more than the skin since (a Verlet list). To make them, the
//! partner's points are binned by voxel, as the core bins a body ([`Binned`]), on a grid that
//! follows them, its voxel the lists' range plus [`STRETCH`] times the surface's longest edge (a
//! power of two), and each probing point walks the block of voxels about its own to the
//! triangles at the points binned there ([`Side::refresh`]). The device's search is the same
//! design in WGSL, walked at every step (`crate::gpu::surface`, docs/contacts.md), and finds the
//! same pushes, bit for bit. A probe farther from every push than the bodies have since moved
//! (its clearance) is not searched. A vertex deeper than `reach` is not pushed (the run's
//! contact check reports it): from beyond the middle of a thin body the nearest point is on its
//! far side.
//!
//! **Determinism.** Each vertex's nearest triangle is found in parallel (ties to the smaller
//! index); the forces are then summed in probe order on one thread, so the result is the same on
//! any number of threads.

use crate::geometry::{HashMap, Region, closest_region};
use std::borrow::Cow;
use voxcollide::VoxelGrid;
use voxcollide::voxel_data::voxel_hash;

use glam::{IVec3, Mat3, UVec3, Vec3};
use rayon::prelude::*;

use crate::body::{Embedding, MassSpring, Mode};
use crate::mesh::TriangleMesh;
use voxcollide::error::Error;

/// The parameters of a surface contact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePenalty {
    /// Force per unit of depth (the body's units: newtons per metre in a scene's world).
    pub stiffness: f32,
    /// How far outside the partner's surface the push begins (0: at the surface).
    pub gap: f32,
    /// The deepest a vertex is pushed from, and how far the search for the nearest triangle
    /// reaches.
    pub reach: f32,
    /// How far outside the gap a vertex is still listed in [`SurfaceForces::pushes`], with no
    /// force (0: not at all): an implicit solve then sees the contact's stiffness before the
    /// vertex arrives, so that a large step does not carry it deep in and out again.
    pub margin: f32,
}

impl SurfacePenalty {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`Error::Invalid`] for a stiffness or reach that is not finite and positive, or a gap
    /// that is not finite, at least 0 and below the reach.
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |what: &'static str, value: f32, rule: &str| {
            Err(Error::Invalid { what, value: value.to_string(), rule: rule.into() })
        };
        if !(self.stiffness.is_finite() && self.stiffness > 0.0) {
            return bad("surface contact stiffness", self.stiffness, "must be finite and positive");
        }
        if !(self.reach.is_finite() && self.reach > 0.0) {
            return bad("surface contact reach", self.reach, "must be finite and positive");
        }
        if !(self.gap.is_finite() && self.gap >= 0.0 && self.gap < self.reach) {
            return bad("surface contact gap", self.gap, "must be finite, at least 0 and below the reach");
        }
        if !(self.margin.is_finite() && self.margin >= 0.0) {
            return bad("surface contact margin", self.margin, "must be finite and at least 0");
        }
        Ok(())
    }
}

/// The most body vertices one point of a surface contact stands for: a lattice's eight cell
/// corners, where the point is on the surface the lattice carries ([`Embedding`]).
pub const POINT_VERTICES: usize = 8;

/// A point of a body as weights of its vertices, `(vertex, weight)`; the unused entries are
/// `(u32::MAX, 0.0)` and come last. A vertex of the body is itself, with weight 1.
pub type Stencil<const N: usize> = [(u32, f32); N];

/// The entries of a stencil in use.
pub fn entries<const N: usize>(s: &Stencil<N>) -> impl Iterator<Item = (u32, f32)> + '_ {
    s.iter().copied().take_while(|(v, _)| *v != u32::MAX)
}

/// The surface a body shows a contact, fixed over a run: its own (`None`), or, for a lattice
/// that carries points ([`MassSpring::carried`]: the surface it was made from, or a patient's
/// scanned skin), the surface over them ([`MassSpring::carried_mesh`]). Its points are
/// numbered after the body's vertices, `len + k` for the carried point `k`.
#[derive(Clone, Debug)]
struct Shown {
    /// The carried surface's triangles over the numbering above.
    mesh: TriangleMesh,
    /// Per point (the body's vertices first, with none), the triangles at it (CSR).
    tri_offsets: Vec<u32>,
    tri_adjacency: Vec<u32>,
}

impl Shown {
    fn of(body: &MassSpring) -> Option<Shown> {
        let (e, mesh) = (body.carried()?, body.carried_mesh()?);
        let (tri_offsets, tri_adjacency) = mesh.triangles_at(body.len() + e.rest.len());
        Some(Shown { mesh, tri_offsets, tri_adjacency })
    }
}

/// A body as one step of a surface contact sees it: its points (its vertices, then the points
/// of the surface it carries, if any) and the surface it shows.
struct View<'a> {
    pos: Cow<'a, [Vec3]>,
    mesh: &'a TriangleMesh,
    tri_offsets: &'a [u32],
    tri_adjacency: &'a [u32],
    /// The body's vertex count: points from here on are the carried surface's.
    vertices: usize,
    embedding: Option<&'a Embedding>,
}

impl<'a> View<'a> {
    fn new(body: &'a MassSpring, shown: Option<&'a Shown>) -> View<'a> {
        match (shown, body.carried()) {
            (Some(s), Some(e)) => View {
                pos: Cow::Owned(body.with_carried(&body.pos)),
                mesh: &s.mesh,
                tri_offsets: &s.tri_offsets,
                tri_adjacency: &s.tri_adjacency,
                vertices: body.len(),
                embedding: Some(e),
            },
            _ => View {
                pos: Cow::Borrowed(&body.pos),
                mesh: &body.surface,
                tri_offsets: &body.tri_offsets,
                tri_adjacency: &body.tri_adjacency,
                vertices: body.len(),
                embedding: None,
            },
        }
    }

    fn len(&self) -> usize {
        self.pos.len()
    }

    /// Point `i` as the body's vertices and their weights.
    fn stencil(&self, i: u32) -> Stencil<POINT_VERTICES> {
        let mut out = [(u32::MAX, 0.0); POINT_VERTICES];
        match self.embedding {
            Some(e) if i as usize >= self.vertices => {
                let k = i as usize - self.vertices;
                let used = e.corners[k].iter().zip(&e.weights[k]).filter(|(c, _)| **c != u32::MAX);
                for (o, (c, w)) in out.iter_mut().zip(used) {
                    *o = (*c, *w);
                }
            }
            _ => out[0] = (i, 1.0),
        }
        out
    }
}

/// Where on a triangle its nearest point to a vertex lies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Feature {
    Face,
    /// The edge from corner `e` to corner `(e + 1) % 3`.
    Edge(u8),
    Vertex(u8),
}

/// The nearest point of triangle `abc` to `p` ([`closest_region`]): its barycentric weights
/// and the feature it lies on. `None` for a degenerate triangle (its neighbours cover its
/// edges).
fn closest_on_triangle(p: Vec3, [a, b, c]: [Vec3; 3]) -> Option<([f32; 3], Feature)> {
    Some(match closest_region(p, a, b, c) {
        Region::Vertex(0) => ([1.0, 0.0, 0.0], Feature::Vertex(0)),
        Region::Vertex(1) => ([0.0, 1.0, 0.0], Feature::Vertex(1)),
        Region::Vertex(_) => ([0.0, 0.0, 1.0], Feature::Vertex(2)),
        Region::Edge(0, v) => ([1.0 - v, v, 0.0], Feature::Edge(0)),
        Region::Edge(1, w) => ([0.0, 1.0 - w, w], Feature::Edge(1)),
        Region::Edge(_, w) => ([1.0 - w, 0.0, w], Feature::Edge(2)),
        Region::Face { vb, vc, sum } => {
            // (Written so that a NaN sum is refused too.)
            if sum.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || !sum.is_finite() {
                return None;
            }
            let (v, w) = (vb / sum, vc / sum);
            ([1.0 - v - w, v, w], Feature::Face)
        }
    })
}

/// Per triangle, the triangle across each of its edges (edge `e` from corner `e` to `e + 1`);
/// `u32::MAX` where the edge is not shared by exactly two triangles.
pub(crate) fn edge_neighbours(mesh: &TriangleMesh) -> Vec<[u32; 3]> {
    let mut by_edge: HashMap<(u32, u32), Vec<(u32, u8)>> = HashMap::default();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for e in 0..3u8 {
            let (u, v) = (tri[e as usize], tri[(e as usize + 1) % 3]);
            by_edge.entry((u.min(v), u.max(v))).or_default().push((t as u32, e));
        }
    }
    let mut out = vec![[u32::MAX; 3]; mesh.triangles.len()];
    for sides in by_edge.values() {
        if let [(t0, e0), (t1, e1)] = sides[..] {
            out[t0 as usize][e0 as usize] = t1;
            out[t1 as usize][e1 as usize] = t0;
        }
    }
    out
}

/// The unit normal of triangle `t` of `mesh` over `pos` (zero for a degenerate one).
fn face_normal(pos: &[Vec3], tri: [u32; 3]) -> Vec3 {
    let [a, b, c] = tri.map(|v| pos[v as usize]);
    (b - a).cross(c - a).normalize_or_zero()
}

/// One body's vertices probing the other's surface.
#[derive(Clone, Debug, Default)]
struct Side {
    /// The probing body's vertices, ascending.
    probes: Vec<u32>,
    /// The partner's triangles' edge neighbours.
    neighbours: Vec<[u32; 3]>,
    /// The partner's triangles by their first corner (CSR over its points): the walk visits
    /// each triangle once, at that corner.
    first_offsets: Vec<u32>,
    firsts: Vec<u32>,
    /// The grid the partner's points are binned in, following them (`None`: the partner had no
    /// finite point or triangle when the side was made, and nothing is found).
    grid: Option<VoxelGrid>,
    /// The partner's points binned by voxel.
    binned: Binned,
    /// Per probe, the partner's triangles near it (CSR), found through the voxel model.
    offsets: Vec<u32>,
    near: Vec<u32>,
    /// Where the probes and the partner's points were when the lists were made, and how far
    /// they have moved since, at most (the probes' and the partner's largest moves summed).
    probes_then: Vec<Vec3>,
    partner_then: Vec<Vec3>,
    moved_since: f32,
    /// The range the lists were made for (the cutoff plus the skin).
    range: f32,
    built: bool,
    /// Per probe, the last step's nearest triangle (`u32::MAX`: none), which the next search
    /// tries first.
    last: Vec<u32>,
    /// Per probe, how far it and the partner may still move relative to each other before it
    /// could be pushed (a lower bound of its distance beyond the push's reach, less the motion
    /// since it was measured); above 0 it is not searched this step.
    clear: Vec<f32>,
    /// The probes' and the partner's positions at the last step.
    probes_prev: Vec<Vec3>,
    partner_prev: Vec<Vec3>,
    /// Per probe: how far it and the partner moved relative to each other at most since the
    /// last step, and whether it was inside the partner then.
    moved: Vec<f32>,
    inside: Vec<bool>,
    /// Per probe inside the partner at the last step: the way that step pushed it out (its
    /// side of the partner's surface); zero for one outside. See [`Side::hits`].
    entry: Vec<Vec3>,
}

/// The partner's points binned by voxel as the device's binning lays them out (the core's
/// counting sort, `voxcollide::GpuCollision::record_binning`): sorted by the slot of their
/// voxel in the voxel model's hash table ([`voxel_hash`]: the voxels of a row in consecutive
/// slots), in index order within a slot. A slot may hold other voxels' points too (the table
/// has as many slots as the partner has points), so a walk keeps only the voxel's own.
#[derive(Clone, Debug, Default)]
struct Binned {
    /// Per slot, where its points start in `sorted`; then their count.
    starts: Vec<u32>,
    /// The binned points: position, index and voxel.
    sorted: Vec<(Vec3, u32, UVec3)>,
    /// Per point, its voxel (`None`: outside the grid or not finite); and a cursor per slot.
    voxels: Vec<Option<UVec3>>,
    cursor: Vec<u32>,
}

impl Binned {
    /// Bins the points of `pos` that lie in `grid`; returns how many.
    fn bin(&mut self, grid: &VoxelGrid, pos: &[Vec3]) -> u32 {
        let slots = pos.len().max(1).next_power_of_two();
        self.voxels.clear();
        self.voxels.extend(pos.iter().map(|p| grid.voxel_of(*p)));
        self.starts.clear();
        self.starts.resize(slots + 1, 0);
        for v in self.voxels.iter().flatten() {
            self.starts[Binned::slot_in(*v, slots) + 1] += 1;
        }
        for s in 0..slots {
            self.starts[s + 1] += self.starts[s];
        }
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.starts[..slots]);
        let n = self.starts[slots];
        self.sorted.clear();
        self.sorted.resize(n as usize, (Vec3::ZERO, 0, UVec3::ZERO));
        for (i, v) in self.voxels.iter().enumerate() {
            if let Some(v) = *v {
                let c = &mut self.cursor[Binned::slot_in(v, slots)];
                self.sorted[*c as usize] = (pos[i], i as u32, v);
                *c += 1;
            }
        }
        n
    }

    fn slot_in(v: UVec3, slots: usize) -> usize {
        voxel_hash(v) as usize & (slots - 1)
    }

    /// The points in the slot of voxel `v` (its own and any other voxel's that shares it).
    fn slot_of(&self, v: UVec3) -> &[(Vec3, u32, UVec3)] {
        let s = Binned::slot_in(v, self.starts.len() - 1);
        &self.sorted[self.starts[s] as usize..self.starts[s + 1] as usize]
    }
}

/// How far the surface's edges may stretch beyond their length as given before a probe walks
/// more than one voxel each way: the binning's voxel is the cutoff plus this times the longest
/// edge ([`search_grid`]).
pub const STRETCH: f32 = 1.5;

/// The squared longest edge of `mesh` over `pos`, each triangle's three edges; one whose square
/// is not finite is passed over (`longest_edge` in `shaders/surface_search.wgsl`).
fn longest_edge2(mesh: &TriangleMesh, pos: &[Vec3]) -> f32 {
    mesh.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| pos[v as usize]);
            b.distance_squared(a).max(c.distance_squared(b)).max(a.distance_squared(c))
        })
        .filter(|e2| e2.is_finite())
        .fold(0.0f32, f32::max)
}

/// The grid a surface contact's search bins the partner's points in, on the CPU and the device
/// alike: its voxel the power of two at or above the cutoff plus [`STRETCH`] times the
/// surface's longest edge now, and room for the partner to grow to twice its widest, every way
/// (a shell deflated flat fills out in its thinnest direction), and a block past each side.
/// The table is hashed, its memory the points', not the voxels'. `voxel` keeps a voxel chosen
/// before (the grid made again for a partner that grew past it). `None` where the partner has
/// no finite point.
pub(crate) fn search_grid(
    cutoff: f32,
    mesh: &TriangleMesh,
    partner: &[Vec3],
    voxel: Option<f32>,
) -> Result<Option<VoxelGrid>, Error> {
    let voxel = voxel.unwrap_or_else(|| {
        let longest = longest_edge2(mesh, partner).sqrt();
        // (The core's grids take a power of two.)
        2f32.powi((cutoff + STRETCH * longest).log2().ceil() as i32)
    });
    let (lo, hi) = partner
        .iter()
        .filter(|p| p.is_finite())
        .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(l, h), p| (l.min(*p), h.max(*p)));
    if lo.cmpgt(hi).any() {
        return Ok(None);
    }
    let across = (2.0 * (hi - lo).max_element() / voxel).ceil() + 4.0;
    let dims = Vec3::splat(across.min(1e6)).as_uvec3();
    VoxelGrid::new(0.5 * (lo + hi), voxel, dims).map(Some)
}

/// What a probe found: the nearest triangle, its weights, the push's direction and its depth
/// beyond the gap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// The partner's nearest triangle within the cutoff.
    pub triangle: u32,
    /// The nearest point's barycentric weights on it.
    pub weights: [f32; 3],
    /// The push's direction: outward from the partner's surface, unit.
    pub normal: Vec3,
    /// `gap − s` for the probe's signed distance `s`: positive where it is pushed, at most 0
    /// within the margin (no force).
    pub depth: f32,
}

impl Side {
    /// A side whose lists reach `range` (the cutoff plus the skin).
    fn new(probing: &View, partner: &View, range: f32) -> Result<Side, Error> {
        // Every point probes, not only the surface's: where a load pushes the surface's
        // vertices aside (a ball pressed deep into a lattice), the ones beneath must not come
        // in between them unseen.
        let probes = (0..probing.len() as u32).collect();
        let grid = if partner.mesh.triangles.is_empty() {
            None
        } else {
            search_grid(range, partner.mesh, &partner.pos, None)?
        };
        let points = partner.mesh.triangles.iter().flatten().map(|&v| v as usize + 1).max().unwrap_or(0);
        let (first_offsets, firsts) = partner.mesh.triangles_by_first_corner(partner.pos.len().max(points));
        Ok(Side {
            probes,
            neighbours: edge_neighbours(partner.mesh),
            first_offsets,
            firsts,
            grid,
            range,
            ..Side::default()
        })
    }

    /// Makes the lists anew when the probes and the partner have moved farther than the skin
    /// since they were made (`range` less the cutoff); returns whether it did.
    ///
    /// **Through the voxel model.** The partner's points are binned by voxel ([`Binned`]) in
    /// the grid moved to follow them (a partner that grew past it gets a grid of the same voxel
    /// made anew about it, where the device's search says so and stops). A triangle within
    /// `range` has its first corner within `range` plus its reach there (its longer edge at
    /// that corner: every point of the triangle lies that near it), so each probe walks the
    /// block of voxels about its own that reaches as far as all but the longest fiftieth of
    /// the reaches now allow, to the points binned there that near, and lists the triangles
    /// whose first corner they are and whose box lies within `range`; the longest fiftieth it
    /// measures by their box, every one. Where the block holds
    /// more voxels than the partner has points (a surface stretched past all sense), the
    /// binned points are gone through instead, those in the block kept: the same lists.
    fn refresh(&mut self, probing: &View, partner: &View, skin: f32) -> bool {
        let moved = |now: &[Vec3], then: &[Vec3]| {
            now.iter().zip(then).map(|(p, q)| p.distance_squared(*q)).fold(0.0f32, f32::max).sqrt()
        };
        if self.built {
            // (Every vertex probes, in order: the probes' positions are the body's.)
            self.moved_since =
                moved(&probing.pos, &self.probes_then) + moved(&partner.pos, &self.partner_then);
            if self.moved_since < skin {
                return false;
            }
        }
        self.offsets.clear();
        self.near.clear();
        self.offsets.push(0);
        self.moved_since = 0.0;
        self.probes_then = self.probes.iter().map(|&i| probing.pos[i as usize]).collect();
        self.partner_then.clear();
        self.partner_then.extend_from_slice(&partner.pos);
        self.built = true;
        // (A partner with no finite point when the side was made gets its grid now.)
        if self.grid.is_none() && !partner.mesh.triangles.is_empty() {
            self.grid = search_grid(self.range, partner.mesh, &partner.pos, None).ok().flatten();
        }
        let Some(grid) = self.grid else {
            // No finite point: no triangle can push.
            self.offsets.resize(self.probes.len() + 1, 0);
            return true;
        };
        let grid =
            voxcollide::cpu::step_grid(&grid, voxcollide::Anchor::FollowA, &partner.pos).unwrap_or(grid);
        let finite = partner.pos.iter().filter(|p| p.is_finite()).count() as u32;
        self.grid = Some(grid);
        let mut binned = self.binned.bin(&grid, &partner.pos);
        if binned < finite
            && let Ok(Some(wider)) =
                search_grid(self.range, partner.mesh, &partner.pos, Some(grid.voxel_size()))
        {
            self.grid = Some(wider);
            binned = self.binned.bin(&wider, &partner.pos);
        }
        let grid = self.grid.unwrap_or(grid);
        let (pos, tris) = (&partner.pos, &partner.mesh.triangles);
        let range = self.range;
        if binned < finite {
            // A point past even a grid made anew (a million voxels across: a surface flung
            // apart) is in no voxel: every triangle is measured against every probe instead,
            // slowly but missing none.
            let lists: Vec<Vec<u32>> = self
                .probes
                .par_iter()
                .map(|&i| {
                    let p = probing.pos[i as usize];
                    (0..tris.len() as u32)
                        .filter(|&t| boxed_within(tris[t as usize].map(|c| pos[c as usize]), p, range))
                        .collect()
                })
                .collect();
            self.set_lists(lists);
            return true;
        }
        // Each triangle's reach from its first corner (its longer edge there): every point of
        // the triangle lies that near the corner, so a triangle within the range has its first
        // corner within the range plus its reach. The walk goes as far as all but the longest
        // fiftieth of them reach (`short`); those few (a shell's stretched rim, her tissue
        // stretched over it) are measured against every probe instead, by their box.
        let reach_of: Vec<f32> = tris
            .par_iter()
            .map(|t| {
                let c = t.map(|v| pos[v as usize]);
                c[1].distance(c[0]).max(c[2].distance(c[0]))
            })
            .collect();
        let mut finite: Vec<f32> = reach_of.iter().copied().filter(|e| e.is_finite()).collect();
        let short = match finite.len() {
            0 => 0.0,
            n => *finite.select_nth_unstable_by((n - 1) * 49 / 50, f32::total_cmp).1,
        };
        let long: Vec<u32> = (0..tris.len() as u32).filter(|&t| reach_of[t as usize] > short).collect();
        let near = range + short;
        let near2 = near * near;
        let voxel = grid.voxel_size();
        // (At most the grid across: a surface stretched past all sense is walked whole.)
        let reach = (near / voxel).ceil().max(1.0).min(grid.dims().max_element() as f32) as i32;
        let every_point = (2 * u64::from(reach.unsigned_abs()) + 1).pow(3) > self.binned.sorted.len() as u64;
        let dims = grid.dims().as_ivec3();
        let (binned, first_offsets, firsts) = (&self.binned, &self.first_offsets, &self.firsts);
        // The box around the partner's points: a probe farther than `near` from it has no
        // point that near, and walks nothing (most of a body's vertices, away from the contact).
        let (points_lo, points_hi) = binned
            .sorted
            .iter()
            .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(l, h), r| (l.min(r.0), h.max(r.0)));
        let lists: Vec<Vec<u32>> = self
            .probes
            .par_iter()
            .with_min_len(256)
            .map(|&i| {
                let p = probing.pos[i as usize];
                if !p.is_finite() || box_distance2(points_lo, points_hi, p) > near2 {
                    return Vec::new();
                }
                // The probe's voxel, as the grid counts them (`VoxelGrid::voxel_of`), or where
                // it would be past the grid's faces: a probe just outside the grid walks the
                // part of its block inside it (the points binned near a face may be near it).
                let v = ((p - grid.origin()) * grid.inv_voxel_size())
                    .floor()
                    .clamp(Vec3::splat(-1.0 - reach as f32), dims.as_vec3() + reach as f32)
                    .as_ivec3();
                let (lo, hi) = (v - reach, v + reach);
                if lo.cmpge(dims).any() || hi.cmplt(IVec3::ZERO).any() {
                    return Vec::new();
                }
                let mut list = Vec::new();
                let mut at = |pi: Vec3, j: u32| {
                    if pi.distance_squared(p) > near2 {
                        return;
                    }
                    // Each triangle once: at its first corner (every corner of a triangle
                    // within the range lies that near).
                    let (s, e) = (first_offsets[j as usize] as usize, first_offsets[j as usize + 1] as usize);
                    for &t in &firsts[s..e] {
                        if reach_of[t as usize] > short {
                            continue;
                        }
                        if boxed_within(tris[t as usize].map(|c| pos[c as usize]), p, range) {
                            list.push(t);
                        }
                    }
                };
                if every_point {
                    for &(pi, j, q) in &binned.sorted {
                        if q.as_ivec3().cmpge(lo).all() && q.as_ivec3().cmple(hi).all() {
                            at(pi, j);
                        }
                    }
                } else {
                    // A voxel whose box lies farther than `near` holds no point that near: passed
                    // over, as the device's walk passes over its far voxels (with the same
                    // shave, so that rounding never passes over a point that counts).
                    let origin = grid.origin();
                    let shave = 1e-3 * voxel + 1e-6 * (p.abs().max_element() + origin.abs().max_element());
                    let far = (near + shave) * (near + shave);
                    for z in lo.z.max(0)..=hi.z.min(dims.z - 1) {
                        for y in lo.y.max(0)..=hi.y.min(dims.y - 1) {
                            for x in lo.x.max(0)..=hi.x.min(dims.x - 1) {
                                let q = UVec3::new(x as u32, y as u32, z as u32);
                                let box_lo = origin + q.as_vec3() * voxel;
                                if (box_lo - p).max(p - box_lo - voxel).max(Vec3::ZERO).length_squared() > far
                                {
                                    continue;
                                }
                                for &(pi, j, _) in binned.slot_of(q).iter().filter(|r| r.2 == q) {
                                    at(pi, j);
                                }
                            }
                        }
                    }
                }
                list.extend(
                    long.iter()
                        .copied()
                        .filter(|&t| boxed_within(tris[t as usize].map(|c| pos[c as usize]), p, range)),
                );
                // (In ascending order: the walk's is the hash's, and the longest come last.)
                list.sort_unstable();
                list
            })
            .collect();
        self.set_lists(lists);
        true
    }

    /// Each probe's list, in probe order, into the lists' CSR (`offsets` holds its first 0).
    fn set_lists(&mut self, lists: Vec<Vec<u32>>) {
        for list in lists {
            self.near.extend_from_slice(&list);
            self.offsets.push(self.near.len() as u32);
        }
    }

    /// Each probe's push, if any.
    /// Takes the motion since the last step off every probe's clearance: its own move and the
    /// partner's largest (a point of a triangle moves no farther than its corners).
    fn age(&mut self, probing: &View, partner: &View) {
        let n = self.probes.len();
        if self.clear.len() == n && self.probes_prev.len() == n && self.partner_prev.len() == partner.len() {
            let partner_moved = partner
                .pos
                .iter()
                .zip(&self.partner_prev)
                .map(|(p, q)| p.distance_squared(*q))
                .fold(0.0f32, f32::max)
                .sqrt();
            self.moved.clear();
            for ((c, &i), prev) in self.clear.iter_mut().zip(&self.probes).zip(&self.probes_prev) {
                let moved = probing.pos[i as usize].distance(*prev) + partner_moved;
                *c -= moved;
                self.moved.push(moved);
            }
        } else {
            self.clear = vec![-1.0; n];
            self.moved = vec![0.0; n];
        }
        self.probes_prev.clear();
        self.probes_prev.extend(self.probes.iter().map(|&i| probing.pos[i as usize]));
        self.partner_prev.clear();
        self.partner_prev.extend_from_slice(&partner.pos);
    }

    /// Each probe's push, if any, its nearest triangle within the cutoff (`u32::MAX`: none),
    /// which the next step tries first, and its clearance (see `clear`).
    ///
    /// **Out the way it came in.** A probe inside the partner at the last step is pushed out
    /// through the side it was pushed out through then (`entry`): only the triangles facing
    /// that way (their normal within a right angle of it) are its nearest. In a layer thinner
    /// than twice its depth the nearest triangle is otherwise on the layer's far face once
    /// the probe has passed its middle, and the push would carry it through: a filling
    /// implant came through a patient's 16 mm layer of tissue over her sternum so, at 10 mm
    /// spacing, no vertex ever deeper than 3.6 mm.
    fn hits(
        &self,
        probing: &View,
        partner: &View,
        penalty: &SurfacePenalty,
    ) -> Vec<(Option<SurfaceHit>, u32, f32)> {
        let pos = &partner.pos;
        let tris = &partner.mesh.triangles;
        (0..self.probes.len())
            .into_par_iter()
            .with_min_len(256)
            .map(|k| {
                let last = self.last.get(k).copied().unwrap_or(u32::MAX);
                // Farther from any push than the bodies have moved since it was measured.
                if self.clear[k] > 0.0 {
                    return (None, last, self.clear[k]);
                }
                let p = probing.pos[self.probes[k] as usize];
                let mut best: Option<(f32, u32, [f32; 3], Feature)> = None;
                // A lower bound of the distance to every triangle passed over or measured; and
                // those not listed were farther than the lists' range when they were made, and
                // have come no nearer since than the probes and the partner have moved.
                let unlisted = (self.range - self.moved_since).max(0.0);
                let mut lower = unlisted * unlisted;
                // Nothing beyond the cutoff pushes: a triangle whose box is farther than it, or
                // than the nearest found so far, is passed over before the exact test. The last
                // step's nearest goes first, so that most boxes are passed over (the answer is
                // the same without it: the nearest, ties to the smaller index).
                let cutoff = penalty.reach.max(penalty.gap + penalty.margin);
                let mut bound = cutoff * cutoff;
                let list = &self.near[self.offsets[k] as usize..self.offsets[k + 1] as usize];
                let first = Some(last).filter(|t| list.contains(t));
                let entry = self.entry.get(k).copied().unwrap_or(Vec3::ZERO);
                for &t in first.iter().chain(list) {
                    let corners = tris[t as usize].map(|v| pos[v as usize]);
                    let (lo, hi) = (
                        corners[0].min(corners[1]).min(corners[2]),
                        corners[0].max(corners[1]).max(corners[2]),
                    );
                    let box_d2 = box_distance2(lo, hi, p);
                    if box_d2 > bound {
                        lower = lower.min(box_d2);
                        continue;
                    }
                    // Facing away from the way it came in: the far side (still a bound).
                    if entry != Vec3::ZERO && face_normal(pos, tris[t as usize]).dot(entry) < 0.0 {
                        lower = lower.min(box_d2);
                        continue;
                    }
                    let Some((w, feature)) = closest_on_triangle(p, corners) else { continue };
                    let q = w[0] * corners[0] + w[1] * corners[1] + w[2] * corners[2];
                    let d2 = p.distance_squared(q);
                    lower = lower.min(d2);
                    if d2 <= bound && best.is_none_or(|(b, bt, _, _)| d2 < b || (d2 == b && t < bt)) {
                        best = Some((d2, t, w, feature));
                        bound = d2;
                    }
                }
                // (Clearances are shaved by a thousandth, so that rounding never skips a push.)
                let Some((d2, t, w, feature)) = best else {
                    // Nothing within the cutoff: no push until something comes within it.
                    return (None, u32::MAX, (lower.sqrt() - cutoff) * 0.999);
                };
                let (hit, s) = self.hit(p, partner, penalty, d2, t, w, feature);
                // Outside beyond the gap (and the margin): no push until it comes within it.
                let near = penalty.gap + penalty.margin;
                let clear = if hit.is_none() && s >= near { (s - near) * 0.999 } else { 0.0 };
                (hit, t, clear)
            })
            .collect()
    }

    /// The push on a probe at `p` whose nearest triangle within the cutoff is `t`, at `d2`
    /// squared, its nearest point there `w` on `feature`, and its signed distance (negative
    /// inside).
    #[allow(clippy::too_many_arguments)]
    fn hit(
        &self,
        p: Vec3,
        partner: &View,
        penalty: &SurfacePenalty,
        d2: f32,
        t: u32,
        w: [f32; 3],
        feature: Feature,
    ) -> (Option<SurfaceHit>, f32) {
        let (pos, tris) = (&partner.pos, &partner.mesh.triangles);
        let tri = tris[t as usize];
        let pseudo = match feature {
            Feature::Face => face_normal(pos, tri),
            Feature::Edge(e) => {
                let other = self.neighbours[t as usize][e as usize];
                let n = face_normal(pos, tri);
                if other == u32::MAX { n } else { n + face_normal(pos, tris[other as usize]) }
            }
            Feature::Vertex(c) => vertex_normal(partner, tri[c as usize]),
        };
        let q = w[0] * pos[tri[0] as usize] + w[1] * pos[tri[1] as usize] + w[2] * pos[tri[2] as usize];
        let d = p - q;
        let dist = d2.sqrt();
        let outside = d.dot(pseudo) >= 0.0;
        let s = if outside { dist } else { -dist };
        if s >= penalty.gap + penalty.margin || -s > penalty.reach {
            return (None, s);
        }
        // Along the line to the nearest point (continuous as the vertex moves), or the
        // pseudo-normal where the vertex is on the surface.
        let normal = if dist > 1e-6 * penalty.reach {
            if outside { d / dist } else { -d / dist }
        } else {
            pseudo.normalize_or_zero()
        };
        if normal == Vec3::ZERO {
            return (None, s);
        }
        (Some(SurfaceHit { triangle: t, weights: w, normal, depth: penalty.gap - s }), s)
    }
}

/// Hits that cannot be trusted are confirmed by the exact inside test (the generalized winding
/// number, [`crate::geometry::ClosedSurface`]), and dropped where it says outside. Where a shell
/// has folded over itself (a flattened implant springing back, a crumpled membrane), the
/// nearest feature's pseudo-normal can point inward, and a vertex outside would be taken as
/// inside and thrown. So a hit is checked when it is deeper than a quarter of the reach, or
/// when its vertex was outside at the last step and is now deeper inside than it and the
/// partner have moved since (`moved`): it cannot have crossed the surface, and a vertex that
/// truly comes in does so gradually. A holding contact's hits pass neither test, so the
/// hierarchy is rarely built. Returns, per probe, whether it is now inside.
fn confirm(
    hits: &mut [Option<SurfaceHit>],
    probes: &[u32],
    was_inside: &[bool],
    moved: &[f32],
    probing: &View,
    partner: &View,
    penalty: &SurfacePenalty,
) -> Vec<bool> {
    let deep = penalty.gap + 0.25 * penalty.reach;
    let slack = 1e-4 * penalty.reach;
    let suspect = |k: usize, h: &SurfaceHit| {
        let inside = h.depth - penalty.gap;
        h.depth > deep
            || (inside > 0.0
                && !was_inside.get(k).copied().unwrap_or(false)
                && inside > moved.get(k).copied().unwrap_or(0.0) * 1.001 + slack)
    };
    if hits.iter().enumerate().any(|(k, h)| h.as_ref().is_some_and(|h| suspect(k, h)))
        && let Ok(surface) = crate::geometry::ClosedSurface::new(&partner.pos, partner.mesh)
    {
        hits.par_iter_mut().zip(probes.par_iter()).enumerate().for_each(|(k, (hit, &i))| {
            if hit.as_ref().is_some_and(|h| suspect(k, h)) && !surface.contains(probing.pos[i as usize]) {
                *hit = None;
            }
        });
    }
    hits.iter().map(|h| h.as_ref().is_some_and(|h| h.depth > penalty.gap)).collect()
}

/// The angle-weighted normal of `partner`'s surface at vertex `v` (over its triangles).
fn vertex_normal(partner: &View, v: u32) -> Vec3 {
    let pos = &partner.pos;
    let (s, e) = (partner.tri_offsets[v as usize] as usize, partner.tri_offsets[v as usize + 1] as usize);
    partner.tri_adjacency[s..e]
        .iter()
        .map(|&t| {
            let tri = partner.mesh.triangles[t as usize];
            let c = tri.iter().position(|&u| u == v).unwrap_or(0);
            let o = pos[v as usize];
            let (u, w) = (pos[tri[(c + 1) % 3] as usize] - o, pos[tri[(c + 2) % 3] as usize] - o);
            face_normal(pos, tri) * u.angle_between(w)
        })
        .sum()
}

/// One side of a surface contact's search alone, from nothing kept: each of the points
/// `probes` against the surface `mesh` over the points `partner`, with the way each was pushed
/// out at the last step (`entry`, zero or missing: none), as [`SurfaceContact::step`] finds its
/// pushes before the inside test confirms doubtful ones. The reference that the search on the
/// device (`crate::gpu::surface`) is held to, bit for bit.
#[must_use]
pub fn nearest_pushes(
    penalty: &SurfacePenalty,
    probes: &[Vec3],
    partner: &[Vec3],
    mesh: &TriangleMesh,
    entry: &[Vec3],
) -> Vec<Option<SurfaceHit>> {
    let (tri_offsets, tri_adjacency) = mesh.triangles_at(partner.len());
    let view = |pos: &[Vec3]| View {
        pos: Cow::Owned(pos.to_vec()),
        mesh,
        tri_offsets: &tri_offsets,
        tri_adjacency: &tri_adjacency,
        vertices: pos.len(),
        embedding: None,
    };
    let (probing, partner) = (view(probes), view(partner));
    let cutoff = penalty.reach.max(penalty.gap + penalty.margin);
    let Ok(mut side) = Side::new(&probing, &partner, 1.5 * cutoff) else { return vec![None; probes.len()] };
    side.refresh(&probing, &partner, 0.5 * cutoff);
    side.age(&probing, &partner);
    side.entry = (0..probes.len()).map(|k| entry.get(k).copied().unwrap_or(Vec3::ZERO)).collect();
    side.hits(&probing, &partner, penalty).into_iter().map(|(hit, _, _)| hit).collect()
}

/// What one step of a surface contact found.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SurfaceStats {
    /// Points of `b` pushed out of `a` (its vertices, and those of a surface it carries).
    pub b_pushed: u32,
    /// Points of `a` pushed out of `b`.
    pub a_pushed: u32,
    /// The deepest push beyond the gap, either side.
    pub deepest: f32,
    /// Whether the near-triangle lists were made anew this step.
    pub rebuilt: bool,
}

/// The forces of one surface contact: on each body's vertices, and each vertex's contact
/// stiffness (`Σ k·w²·nnᵀ`, the diagonal blocks of the penalty's Gauss–Newton Hessian) for an
/// implicit solve.
#[derive(Clone, Debug, Default)]
pub struct SurfaceForces {
    /// On `a`'s vertices.
    pub force_a: Vec<Vec3>,
    /// On `b`'s vertices.
    pub force_b: Vec<Vec3>,
    /// `a`'s vertices' stiffness blocks.
    pub stiffness_a: Vec<Mat3>,
    /// `b`'s vertices' stiffness blocks.
    pub stiffness_b: Vec<Mat3>,
    /// `b`'s vertices in contact this step, ascending: those pushed out of `a`, and the corners
    /// of `b`'s triangles that `a`'s vertices push (with a weight above 0).
    pub touching_b: Vec<u32>,
    /// Every push, in the order its force was summed, and every vertex within the margin: what
    /// an implicit solve needs to couple the two bodies (each is a spring of the contact's
    /// stiffness between the vertex and its nearest point on the partner's surface, along
    /// `normal`).
    pub pushes: Vec<Push>,
}

/// One point pushed out of the partner's surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Push {
    /// Whether the pushed point is `a`'s (the triangle then `b`'s), or `b`'s.
    pub of_a: bool,
    /// The pushed point: a vertex of its body, or (numbered after them) a vertex of the surface
    /// its lattice carries.
    pub vertex: u32,
    /// The pushed point as its body's vertices and weights.
    pub point: Stencil<POINT_VERTICES>,
    /// The partner's nearest point as the partner's vertices and weights: the triangle's
    /// corners' stencils, each scaled by its barycentric weight, in corner order.
    pub from: Stencil<{ 3 * POINT_VERTICES }>,
    /// The push's direction (unit, outward from the partner's surface).
    pub normal: Vec3,
    /// `gap − s` for the vertex's signed distance `s` from the partner's surface: positive where
    /// it is pushed, at most 0 within the margin (no force).
    pub depth: f32,
}

/// A surface contact between bodies `a` and `b`: both sides' near-triangle lists.
#[derive(Clone, Debug)]
pub struct SurfaceContact {
    /// Its parameters.
    pub penalty: SurfacePenalty,
    /// `b`'s vertices against `a`'s surface, and `a`'s against `b`'s.
    sides: [Side; 2],
    /// The surfaces `a` and `b` show the contact, where not their own.
    shown: [Option<Shown>; 2],
}

impl SurfaceContact {
    /// A contact between `a` and `b` as they are now.
    ///
    /// # Errors
    /// Those of [`SurfacePenalty::validate`].
    pub fn new(penalty: SurfacePenalty, a: &MassSpring, b: &MassSpring) -> Result<SurfaceContact, Error> {
        penalty.validate()?;
        let shown = [Shown::of(a), Shown::of(b)];
        let (va, vb) = (View::new(a, shown[0].as_ref()), View::new(b, shown[1].as_ref()));
        let range = 1.5 * penalty.reach.max(penalty.gap + penalty.margin);
        let sides = [Side::new(&vb, &va, range)?, Side::new(&va, &vb, range)?];
        Ok(SurfaceContact { penalty, sides, shown })
    }

    /// One step's forces into `out` (resized to the bodies), and what it found.
    pub fn step(&mut self, a: &MassSpring, b: &MassSpring, out: &mut SurfaceForces) -> SurfaceStats {
        let p = self.penalty;
        let cutoff = p.reach.max(p.gap + p.margin);
        let skin = 0.5 * cutoff;
        let mut stats = SurfaceStats::default();
        let reset = |f: &mut Vec<Vec3>, k: &mut Vec<Mat3>, n: usize| {
            f.clear();
            f.resize(n, Vec3::ZERO);
            k.clear();
            k.resize(n, Mat3::ZERO);
        };
        reset(&mut out.force_a, &mut out.stiffness_a, a.len());
        reset(&mut out.force_b, &mut out.stiffness_b, b.len());
        out.touching_b.clear();
        out.pushes.clear();
        let views = [View::new(a, self.shown[0].as_ref()), View::new(b, self.shown[1].as_ref())];
        for (s, side) in self.sides.iter_mut().enumerate() {
            let (probing, partner) = if s == 0 { (&views[1], &views[0]) } else { (&views[0], &views[1]) };
            stats.rebuilt |= side.refresh(probing, partner, skin);
            side.age(probing, partner);
            let found = side.hits(probing, partner, &p);
            let mut hits = Vec::with_capacity(found.len());
            (side.last, side.clear) = found
                .into_iter()
                .map(|(hit, last, clear)| {
                    hits.push(hit);
                    (last, clear)
                })
                .unzip();
            side.inside = confirm(&mut hits, &side.probes, &side.inside, &side.moved, probing, partner, &p);
            side.entry.clear();
            side.entry.extend(hits.iter().zip(&side.inside).map(|(h, &inside)| match h {
                Some(h) if inside => h.normal,
                _ => Vec3::ZERO,
            }));
            let (f_probe, k_probe, f_partner, k_partner) = if s == 0 {
                (&mut out.force_b, &mut out.stiffness_b, &mut out.force_a, &mut out.stiffness_a)
            } else {
                (&mut out.force_a, &mut out.stiffness_a, &mut out.force_b, &mut out.stiffness_b)
            };
            for (&i, hit) in side.probes.iter().zip(&hits) {
                let Some(h) = hit else { continue };
                let tri = partner.mesh.triangles[h.triangle as usize];
                // The nearest point's stencil: each corner's, scaled by its weight.
                let mut from = [(u32::MAX, 0.0); 3 * POINT_VERTICES];
                let mut n = 0;
                for (c, w) in tri.iter().zip(h.weights) {
                    for (v, u) in entries(&partner.stencil(*c)) {
                        from[n] = (v, w * u);
                        n += 1;
                    }
                }
                let point = probing.stencil(i);
                let push = Push { of_a: s == 1, vertex: i, point, from, normal: h.normal, depth: h.depth };
                out.pushes.push(push);
                if h.depth <= 0.0 {
                    // Within the margin, outside the gap: listed, no force.
                    continue;
                }
                let f = p.stiffness * h.depth * h.normal;
                let nn = Mat3::from_cols(h.normal * h.normal.x, h.normal * h.normal.y, h.normal * h.normal.z);
                for (v, u) in entries(&point) {
                    f_probe[v as usize] += u * f;
                    k_probe[v as usize] += (p.stiffness * u * u) * nn;
                }
                for (v, w) in entries(&from) {
                    f_partner[v as usize] -= w * f;
                    k_partner[v as usize] += (p.stiffness * w * w) * nn;
                }
                stats.deepest = stats.deepest.max(h.depth);
                if s == 0 {
                    stats.b_pushed += 1;
                    out.touching_b.extend(entries(&point).filter(|(_, u)| *u > 0.0).map(|(v, _)| v));
                } else {
                    stats.a_pushed += 1;
                    out.touching_b.extend(entries(&from).filter(|(_, w)| *w > 0.0).map(|(v, _)| v));
                }
            }
        }
        out.touching_b.sort_unstable();
        out.touching_b.dedup();
        // A held vertex feels nothing: it is where its drive puts it.
        for (body, f, k) in
            [(a, &mut out.force_a, &mut out.stiffness_a), (b, &mut out.force_b, &mut out.stiffness_b)]
        {
            for ((m, f), k) in body.mode.iter().zip(f.iter_mut()).zip(k.iter_mut()) {
                if *m != Mode::Free {
                    *f = Vec3::ZERO;
                    *k = Mat3::ZERO;
                }
            }
        }
        stats
    }
}

/// The squared distance from `p` to the box `lo`..`hi` (0 inside it).
fn box_distance2(lo: Vec3, hi: Vec3, p: Vec3) -> f32 {
    (lo - p).max(p - hi).max(Vec3::ZERO).length_squared()
}

/// Whether the triangle of corners `c` belongs in the list of a probe at `p`: its corners
/// finite (a triangle with one that is not is never listed) and its box within `range` of `p`.
fn boxed_within(c: [Vec3; 3], p: Vec3, range: f32) -> bool {
    c.iter().all(|c| c.is_finite())
        && box_distance2(c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]), p) <= range * range
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_point_features() {
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let (w, f) = closest_on_triangle(Vec3::new(0.2, 0.2, 1.0), t).unwrap();
        assert_eq!(f, Feature::Face);
        assert!((w[1] - 0.2).abs() < 1e-6 && (w[2] - 0.2).abs() < 1e-6);
        assert_eq!(closest_on_triangle(Vec3::new(-1.0, -1.0, 0.0), t).unwrap().1, Feature::Vertex(0));
        assert_eq!(closest_on_triangle(Vec3::new(0.5, -1.0, 0.0), t).unwrap().1, Feature::Edge(0));
        assert_eq!(closest_on_triangle(Vec3::new(1.0, 1.0, 0.0), t).unwrap().1, Feature::Edge(1));
        assert_eq!(closest_on_triangle(Vec3::new(-1.0, 0.5, 0.0), t).unwrap().1, Feature::Edge(2));
        assert_eq!(
            closest_on_triangle(Vec3::ZERO, [Vec3::X, Vec3::X, Vec3::X]).map(|x| x.1),
            Some(Feature::Vertex(0))
        );
        assert!(
            closest_on_triangle(Vec3::Z, [Vec3::ZERO, Vec3::X, 2.0 * Vec3::X])
                .is_some_and(|(_, f)| f != Feature::Face)
        );
    }

    /// A side over `partner` and `mesh` probed by one point, stepped as
    /// [`SurfaceContact::step`] steps it (lists, aging, the search, the clearance kept).
    struct OneSide {
        side: Side,
        mesh: TriangleMesh,
        offsets: Vec<u32>,
        adjacency: Vec<u32>,
        partner: Vec<Vec3>,
    }

    impl OneSide {
        fn new(mesh: TriangleMesh, partner: Vec<Vec3>, probe: Vec3, cutoff: f32) -> OneSide {
            let (offsets, adjacency) = mesh.triangles_at(partner.len());
            let mut one = OneSide { side: Side::default(), mesh, offsets, adjacency, partner };
            let (probing, view) = one.views(probe);
            let side = Side::new(&probing, &view, 1.5 * cutoff).unwrap();
            one.side = side;
            one
        }

        fn views(&self, probe: Vec3) -> (View<'_>, View<'_>) {
            let view = |pos: &[Vec3]| View {
                pos: Cow::Owned(pos.to_vec()),
                mesh: &self.mesh,
                tri_offsets: &self.offsets,
                tri_adjacency: &self.adjacency,
                vertices: pos.len(),
                embedding: None,
            };
            (view(&[probe]), view(&self.partner))
        }

        fn step(&mut self, probe: Vec3, penalty: &SurfacePenalty) -> Option<SurfaceHit> {
            let cutoff = penalty.reach.max(penalty.gap + penalty.margin);
            let mut side = std::mem::take(&mut self.side);
            let (probing, partner) = self.views(probe);
            side.refresh(&probing, &partner, 0.5 * cutoff);
            side.age(&probing, &partner);
            let (hit, last, clear) = side.hits(&probing, &partner, penalty)[0];
            (side.last, side.clear) = (vec![last], vec![clear]);
            self.side = side;
            hit
        }
    }

    #[test]
    fn a_probe_is_searched_again_before_a_triangle_its_lists_left_out_could_push_it() {
        // A large slanted triangle whose box holds the probe, its plane 2.9 away, and a small
        // one facing the probe 1.6 away: beyond the lists' range (1.5), so not listed. The
        // probe then walks toward the small one, 0.2 a step. Its clearance from the listed
        // triangle alone would be 1.9, and would skip it past the step (the sixth) where the
        // small one first pushes it: the clearance must also bound what the lists left out.
        let penalty = SurfacePenalty { stiffness: 1.0, gap: 0.5, reach: 1.0, margin: 0.0 };
        let partner = vec![
            Vec3::new(5.0, -5.0, -5.0),
            Vec3::new(-5.0, 5.0, -5.0),
            Vec3::new(-5.0, -5.0, 5.0),
            Vec3::new(1.6, -0.5, -0.5),
            Vec3::new(1.6, 0.0, 0.5),
            Vec3::new(1.6, 0.5, -0.5),
        ];
        let mesh = TriangleMesh { triangles: vec![[0, 1, 2], [3, 4, 5]] };
        let mut one = OneSide::new(mesh.clone(), partner.clone(), Vec3::ZERO, 1.0);
        let mut pushed = 0;
        for step in 0..8 {
            let probe = Vec3::new(0.2 * step as f32, 0.0, 0.0);
            let kept = one.step(probe, &penalty);
            let fresh = nearest_pushes(&penalty, &[probe], &partner, &mesh, &[])[0];
            assert_eq!(kept, fresh, "step {step}, the probe at {probe}");
            pushed += usize::from(kept.is_some());
        }
        // (x = 1.2 and 1.4: within the gap of the small triangle.)
        assert_eq!(pushed, 2);
    }

    /// The nearest triangle within the cutoff of every probe, over every triangle.
    fn nearest_by_every_triangle(
        probe: Vec3,
        partner: &[Vec3],
        mesh: &TriangleMesh,
        cutoff: f32,
    ) -> Option<(u32, f32)> {
        let mut best: Option<(f32, u32)> = None;
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let c = tri.map(|v| partner[v as usize]);
            let Some((w, _)) = closest_on_triangle(probe, c) else { continue };
            let d2 = probe.distance_squared(w[0] * c[0] + w[1] * c[1] + w[2] * c[2]);
            if d2 <= cutoff * cutoff && best.is_none_or(|(b, bt)| d2 < b || (d2 == b && (t as u32) < bt)) {
                best = Some((d2, t as u32));
            }
        }
        best.map(|(d2, t)| (t, d2))
    }

    #[test]
    fn the_voxel_walk_lists_every_triangle_within_reach_on_a_surface_stretched_and_grown() {
        // A wavy sheet (a grid of 24 × 24 points, two triangles a cell), probed from points
        // scattered about it: as given; stretched along x to ten times its length (edges far
        // past the voxel its search was set up for: a probe walks two voxels each way), and to
        // thirty (the block holds more voxels than the sheet has points, which are gone
        // through instead); moved 400 away (out of the grid its points were binned in); and
        // grown 3.45 times along x about its middle, still inside its grid but a third of a
        // unit from the grid's faces, probed from past them too (a probe just outside the grid
        // walks the part of its block inside it). The nearest triangle within the cutoff is
        // every triangle's nearest, each time.
        let n = 24;
        let sheet = |stretch: f32, shift: f32| -> Vec<Vec3> {
            (0..n * n)
                .map(|k| {
                    let (i, j) = ((k % n) as f32, (k / n) as f32);
                    Vec3::new(stretch * i + shift, j, 0.6 * (0.7 * i).sin() * (0.5 * j).cos())
                })
                .collect()
        };
        let mut triangles = Vec::new();
        for j in 0..n as u32 - 1 {
            for i in 0..n as u32 - 1 {
                let (a, b, c, d) = (
                    i + n as u32 * j,
                    i + 1 + n as u32 * j,
                    i + 1 + n as u32 * (j + 1),
                    i + n as u32 * (j + 1),
                );
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            }
        }
        let mesh = TriangleMesh { triangles };
        let penalty = SurfacePenalty { stiffness: 1.0, gap: 0.2, reach: 1.5, margin: 0.3 };
        let cutoff = penalty.reach.max(penalty.gap + penalty.margin);
        let given = sheet(1.0, 0.0);
        // (Three more: one point flung a billion away, past any grid, which leaves the lists to
        // every triangle; the side set up on a sheet with no finite point, which gets its grid
        // at the first list made; and one point at infinity.)
        let cases = [
            (1.0, 0.0, ""),
            (10.0, 0.0, ""),
            (30.0, 0.0, ""),
            (1.0, 400.0, ""),
            (3.45, -28.175, ""),
            (1.0, 0.0, "flung"),
            (1.0, 0.0, "set up on NaN"),
            (1.0, 0.0, "infinite"),
        ];
        for (stretch, shift, case) in cases {
            let mut partner = sheet(stretch, shift);
            if case == "flung" {
                partner[n * n - 1] = Vec3::new(1e9, 0.0, 0.0);
            }
            if case == "infinite" {
                // (Its triangles reach infinitely far from their first corner: the longest,
                // measured by their box, and never listed.)
                partner[n * n - 2] = Vec3::new(f32::INFINITY, 0.0, 0.0);
            }
            let given = if case == "set up on NaN" { vec![Vec3::NAN; given.len()] } else { given.clone() };
            let probes: Vec<Vec3> = (0..2000)
                .map(|k| {
                    let h = (k as u32).wrapping_mul(2_654_435_761);
                    let f = |s: u32| ((h >> s) & 1023) as f32 / 1023.0;
                    Vec3::new(shift + f(0) * stretch * n as f32, f(10) * n as f32, 4.0 * f(20) - 2.0)
                })
                .collect();
            // The side set up on the sheet as given, then searching the sheet as it is now.
            let (offsets, adjacency) = mesh.triangles_at(given.len());
            let view = |pos: &[Vec3]| View {
                pos: Cow::Owned(pos.to_vec()),
                mesh: &mesh,
                tri_offsets: &offsets,
                tri_adjacency: &adjacency,
                vertices: pos.len(),
                embedding: None,
            };
            let mut side = Side::new(&view(&probes), &view(&given), 1.5 * cutoff).unwrap();
            side.refresh(&view(&probes), &view(&partner), 0.5 * cutoff);
            // Each probe's list holds every triangle within the lists' range, and only
            // triangles whose box lies within it.
            let range = 1.5 * cutoff;
            for (k, probe) in probes.iter().enumerate() {
                let listed = &side.near[side.offsets[k] as usize..side.offsets[k + 1] as usize];
                for (t, tri) in mesh.triangles.iter().enumerate() {
                    let c = tri.map(|c| partner[c as usize]);
                    let (lo, hi) = (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]));
                    let boxed =
                        c.iter().all(|c| c.is_finite()) && box_distance2(lo, hi, *probe) <= range * range;
                    let within = closest_on_triangle(*probe, c).is_some_and(|(w, _)| {
                        probe.distance_squared(w[0] * c[0] + w[1] * c[1] + w[2] * c[2]) <= range * range
                    });
                    let is_listed = listed.contains(&(t as u32));
                    assert!(
                        (!within || is_listed) && (!is_listed || boxed),
                        "stretched {stretch}, moved {shift} {case}: probe {k} at {probe}, triangle {t}: within {within}, box within {boxed}, listed {is_listed}"
                    );
                }
            }
            side.age(&view(&probes), &view(&partner));
            side.entry = vec![Vec3::ZERO; probes.len()];
            let hits = side.hits(&view(&probes), &view(&partner), &penalty);
            let mut found = 0;
            for (k, (probe, (_, t, _))) in probes.iter().zip(&hits).enumerate() {
                let want = nearest_by_every_triangle(*probe, &partner, &mesh, cutoff).map(|(t, _)| t);
                let got = (*t != u32::MAX).then_some(*t);
                assert_eq!(got, want, "stretched {stretch}, moved {shift} {case}: probe {k} at {probe}");
                found += usize::from(got.is_some());
            }
            assert!(
                found > 300,
                "stretched {stretch}, moved {shift} {case}: only {found} probes near the sheet"
            );
        }
    }
}
