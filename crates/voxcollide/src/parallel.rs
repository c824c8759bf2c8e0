//! `ParallelCpuCollision`: a multi-threaded CPU backend (rayon) for machines without an adapter,
//! giving the same reports as the reference.
//!
//! What makes it fast, and why it stays exact:
//! - A is binned by a counting sort on hash slots instead of linked lists, and its positions
//!   and voxels are copied into slot order, so a walk reads contiguous memory.
//! - B is probed in parallel; each row of the 3×3×3 block is one contiguous scan (rows sit in
//!   consecutive slots, see [`voxel_hash`]), and under `Search::Neighbours` rows and columns the
//!   radius cannot reach are skipped (only when their nearest face is farther than the radius
//!   plus a rounding margin, so no candidate is lost).
//! - Forces on A are summed in fixed point with atomic 64-bit integers: integer sums do not
//!   depend on their order, so the totals equal the reference's exactly.

use std::sync::atomic::{AtomicI64, Ordering};

use glam::{UVec3, Vec3};
use rayon::prelude::*;

use crate::collision::Collision;
use crate::cpu::{check_body, step_grid};
use crate::eliminate::{pairwise_direction, plane_normal};
use crate::error::{Body, Error};
use crate::grid::VoxelGrid;
use crate::math::dist2;
use crate::params::{ContactParams, Direction, Search};
use crate::report::ContactReport;
use crate::voxel_data::{dense_slots, hashed_slots, voxel_hash};

/// The most B vertices per parallel task: large enough to amortise scheduling.
const CHUNK: usize = 4096;

/// Items per task for `n` items: at most [`CHUNK`], and small enough that every thread gets
/// several tasks (3 tasks on 2 threads would leave one thread idle a third of the time).
fn chunk(n: usize) -> usize {
    (n / (8 * rayon::current_num_threads())).clamp(256, CHUNK)
}

/// The three nearest candidates in `(d2, index)` order.
/// `i`: the A vertex's index (the tie-break of the reference's order); `k`: where it sits in
/// the bins (where its position and its force accumulator are).
#[derive(Clone, Copy, Debug)]
struct Nearest {
    d: [f32; 3],
    i: [u32; 3],
    k: [u32; 3],
    n: usize,
}

impl Nearest {
    const EMPTY: Nearest = Nearest { d: [0.0; 3], i: [0; 3], k: [0; 3], n: 0 };

    #[inline]
    fn insert(&mut self, d: f32, i: u32, slot_k: u32) {
        let before = |k: usize| self.d[k] < d || (self.d[k] == d && self.i[k] < i);
        let mut k = 0;
        while k < self.n && before(k) {
            k += 1;
        }
        if k == 3 {
            return;
        }
        let mut j = self.n.min(2);
        while j > k {
            self.d[j] = self.d[j - 1];
            self.i[j] = self.i[j - 1];
            self.k[j] = self.k[j - 1];
            j -= 1;
        }
        self.d[k] = d;
        self.i[k] = i;
        self.k[k] = slot_k;
        self.n = (self.n + 1).min(3);
    }
}

/// `x.floor()`, inline: without SSE4.1 (the x86-64 baseline) `floor` is a libm call, which
/// was 3 % of a lattice(1M) step. Equal to `floor` for every finite `x` (up to the sign of a
/// zero result, which no caller can see: it only becomes a voxel index).
#[inline]
fn floor(x: f32) -> f32 {
    if x.abs() < 8_388_608.0 {
        let t = x as i32 as f32;
        if t > x { t - 1.0 } else { t }
    } else {
        x // already an integer (or not finite)
    }
}

/// `x.round_ties_even() as i32` for the fixed-point counts, inline (likewise a libm call
/// otherwise): adding and subtracting 1.5 · 2^23 rounds to the nearest even integer in the
/// default rounding mode, exactly, for |x| < 2^22 — counts are at most about 2^16.
#[inline]
fn round_count(x: f32) -> i32 {
    const MAGIC: f32 = 12_582_912.0;
    if x.abs() < 4_194_304.0 { ((x + MAGIC) - MAGIC) as i32 } else { x.round_ties_even() as i32 }
}

/// `grid.voxel_of(p)` with the inline [`floor`]: the same voxel or `None` for every `p`.
#[inline]
fn voxel_of(grid: &VoxelGrid, p: Vec3) -> Option<UVec3> {
    if !p.is_finite() {
        return None;
    }
    let (o, inv, d) = (grid.origin(), grid.inv_voxel_size(), grid.dims());
    let axis = |p: f32, o: f32, dim: u32| {
        let q = floor((p - o) * inv);
        (q >= 0.0 && q < dim as f32).then_some(q as u32)
    };
    Some(UVec3::new(axis(p.x, o.x, d.x)?, axis(p.y, o.y, d.y)?, axis(p.z, o.z, d.z)?))
}

/// The slot of voxel `v`: its linear index in a dense table, else its hash.
#[inline]
fn slot(dense: Option<[u32; 2]>, mask: u32, v: UVec3) -> u32 {
    match dense {
        Some([dx, dy]) => v.x + dx * (v.y + dy * v.z),
        None => voxel_hash(v) & mask,
    }
}

/// A's vertices grouped by hash slot, with copies of their positions and voxels in that order.
#[derive(Debug, Default)]
struct Bins {
    /// `Some([dx, dy])`: one slot per voxel, at `x + dx * (y + dy * z)`.
    dense: Option<[u32; 2]>,
    mask: u32,
    /// Per slot, where its vertices start in `index`/`pos`/`voxel` (`slots + 1` entries).
    start: Vec<u32>,
    /// Binned A vertices in slot order, with their positions and voxels.
    index: Vec<u32>,
    pos: Vec<Vec3>,
    voxel: Vec<UVec3>,
    /// Per A vertex: its slot (`u32::MAX`: discarded) and its voxel.
    slot_of: Vec<u32>,
    voxel_of_a: Vec<UVec3>,
    /// Per A vertex: where it sits in `index`/`pos`/`voxel` (`u32::MAX`: discarded).
    k_of: Vec<u32>,
    /// Scratch of the counting sort.
    cursor: Vec<u32>,
}

/// B's vertices in the order of A's slots, so that consecutive probes read the same bins
/// whatever order B comes in.
#[derive(Debug, Default)]
struct Order {
    /// Per B vertex: its slot (`u32::MAX`: outside the grid or not finite).
    slot_of: Vec<u32>,
    /// B's positions in slot order (those outside the grid last).
    pos: Vec<Vec3>,
    /// Per B vertex: where it sits in `pos`.
    k_of: Vec<u32>,
    /// Per sorted B vertex: its force and whether it collides.
    force: Vec<Vec3>,
    hit: Vec<bool>,
    /// Scratch of the counting sort: per slot, where its B vertices start.
    start: Vec<u32>,
}

/// The multi-threaded CPU backend. Reports equal [`CpuCollision`](crate::CpuCollision)'s.
///
/// Runs on rayon's global thread pool (one thread per core unless `RAYON_NUM_THREADS` says
/// otherwise).
#[derive(Debug)]
pub struct ParallelCpuCollision {
    grid: VoxelGrid,
    params: ContactParams,
    bins: Bins,
    order: Order,
    /// Fixed-point force accumulators of A, three per binned vertex in bin order.
    fixed: Vec<AtomicI64>,
}

impl ParallelCpuCollision {
    /// A parallel backend for the pair of bodies that `grid` was built for.
    ///
    /// # Errors
    /// [`Error::Magnitude`] or [`Error::Radius`] when `params` are invalid for `grid`.
    pub fn new(grid: VoxelGrid, params: ContactParams) -> Result<ParallelCpuCollision, Error> {
        params.validate(&grid)?;
        Ok(ParallelCpuCollision {
            grid,
            params,
            bins: Bins::default(),
            order: Order::default(),
            fixed: Vec::new(),
        })
    }

    /// The grid as built.
    #[must_use]
    pub fn grid(&self) -> &VoxelGrid {
        &self.grid
    }

    /// The contact parameters.
    #[must_use]
    pub fn params(&self) -> &ContactParams {
        &self.params
    }

    /// One step into `report`, reusing its vectors: once they have reached the bodies' sizes a
    /// step allocates nothing.
    ///
    /// # Errors
    /// As [`Collision::step`].
    pub fn step_into(&mut self, a: &[Vec3], b: &[Vec3], report: &mut ContactReport) -> Result<(), Error> {
        check_body(Body::A, a)?;
        check_body(Body::B, b)?;
        let grid = step_grid(&self.grid, self.params.anchor, a)?;
        let binned = self.bin(&grid, a);
        self.sort_b(&grid, b);
        // The accumulators are left at zero by the previous step's resolve.
        self.fixed.truncate(3 * binned as usize);
        self.fixed.resize_with(3 * binned as usize, || AtomicI64::new(0));

        let m = self.params.magnitude;
        let probe = Probe {
            grid: &grid,
            params: &self.params,
            bins: &self.bins,
            fixed: &self.fixed,
            scale: 65536.0 / m,
        };
        // Probe in A's slot order, B's vertices sorted so; the forces go back to B's order after.
        let order = &mut self.order;
        let size = chunk(b.len());
        order.force.resize(b.len(), Vec3::ZERO);
        order.hit.resize(b.len(), false);
        order
            .force
            .par_chunks_mut(size)
            .zip(order.hit.par_chunks_mut(size))
            .zip(order.pos.par_chunks(size))
            .for_each(|((forces, hits), pos)| {
                for ((f, hit), p) in forces.iter_mut().zip(hits.iter_mut()).zip(pos) {
                    let force = probe.probe(*p);
                    *hit = force.is_some();
                    *f = force.unwrap_or(Vec3::ZERO);
                }
            });
        report.force_b.resize(b.len(), Vec3::ZERO);
        let (force, k_of) = (&order.force, &order.k_of);
        report.force_b.par_chunks_mut(size).enumerate().for_each(|(c, out)| {
            for (j, f) in out.iter_mut().enumerate() {
                *f = force[k_of[c * size + j] as usize];
            }
        });

        // Back to f32 in A's order; the first overflow in (vertex, axis) order is the error, as
        // on the CPU. Then every accumulator back to zero for the next step.
        let unit = m / 65536.0;
        report.force_a.resize(a.len(), Vec3::ZERO);
        let size = chunk(a.len());
        let (fixed, k_of) = (&self.fixed, &self.bins.k_of);
        let overflow = report
            .force_a
            .par_chunks_mut(size)
            .enumerate()
            .filter_map(|(c, forces)| {
                let mut first = None;
                for (n, f) in forces.iter_mut().enumerate() {
                    let i = c * size + n;
                    let k = k_of[i];
                    if k == u32::MAX {
                        *f = Vec3::ZERO;
                        continue;
                    }
                    let mut out = [0.0f32; 3];
                    for (axis, o) in out.iter_mut().enumerate() {
                        let count = fixed[3 * k as usize + axis].load(Ordering::Relaxed);
                        match i32::try_from(count) {
                            Ok(c) => *o = c as f32 * unit,
                            Err(_) => first = first.or(Some((3 * i + axis, count))),
                        }
                    }
                    *f = Vec3::from_array(out);
                }
                first
            })
            .min_by_key(|(k, _)| *k);
        self.fixed.par_chunks_mut(CHUNK).for_each(|c| c.iter_mut().for_each(|a| *a.get_mut() = 0));
        if let Some((k, count)) = overflow {
            return Err(Error::ForceOverflow { vertex: (k / 3) as u32, axis: (k % 3) as u32, count });
        }
        report.colliding_b.clear();
        let (hit, k_of) = (&self.order.hit, &self.order.k_of);
        report.colliding_b.extend((0..b.len() as u32).filter(|&j| hit[k_of[j as usize] as usize]));
        report.binned_a = binned;
        report.discarded_a = a.len() as u32 - binned;
        report.grid_center = grid.center();
        Ok(())
    }

    /// Counting sort of A's binned vertices by hash slot (stable: ascending index within a slot).
    fn bin(&mut self, grid: &VoxelGrid, a: &[Vec3]) -> u32 {
        let bins = &mut self.bins;
        // A grid with at most four voxels a vertex gets one slot per voxel, in (z, y, x) order:
        // no aliasing, and a row is one run of A's vertices in spatial order. Otherwise four
        // hash slots a vertex keep aliasing rare (docs/performance-notes.md). Either way memory is O(|A|).
        let d = grid.dims();
        let dense = dense_slots(d, a.len());
        bins.dense = dense.map(|_| [d.x, d.y]);
        let slots = dense.unwrap_or_else(|| hashed_slots(a.len(), 4)) as usize;
        bins.mask = (slots - 1) as u32;
        let (mask, dense) = (bins.mask, bins.dense);
        bins.voxel_of_a.clear();
        bins.voxel_of_a.resize(a.len(), UVec3::ZERO);
        bins.slot_of.clear();
        bins.slot_of.resize(a.len(), u32::MAX);
        bins.voxel_of_a.par_iter_mut().zip(bins.slot_of.par_iter_mut()).zip(a.par_iter()).for_each(
            |((v, s), p)| {
                if let Some(q) = voxel_of(grid, *p) {
                    *v = q;
                    *s = slot(dense, mask, q);
                }
            },
        );
        bins.start.clear();
        bins.start.resize(slots + 1, 0);
        let mut binned = 0u32;
        for &s in &bins.slot_of {
            if s != u32::MAX {
                bins.start[s as usize + 1] += 1;
                binned += 1;
            }
        }
        for k in 0..slots {
            bins.start[k + 1] += bins.start[k];
        }
        let n = binned as usize;
        bins.cursor.clear();
        bins.cursor.extend_from_slice(&bins.start[..slots]);
        bins.index.resize(n, 0);
        bins.pos.resize(n, Vec3::ZERO);
        bins.voxel.resize(n, UVec3::ZERO);
        bins.k_of.clear();
        bins.k_of.resize(a.len(), u32::MAX);
        for (i, &s) in bins.slot_of.iter().enumerate() {
            if s != u32::MAX {
                let k = bins.cursor[s as usize] as usize;
                bins.cursor[s as usize] += 1;
                bins.index[k] = i as u32;
                bins.pos[k] = a[i];
                bins.voxel[k] = bins.voxel_of_a[i];
                bins.k_of[i] = k as u32;
            }
        }
        binned
    }

    /// Counting sort of B by the slot of A's table its voxel falls in (stable), those outside
    /// the grid last: probing in this order, neighbouring probes read neighbouring bins.
    fn sort_b(&mut self, grid: &VoxelGrid, b: &[Vec3]) {
        let (dense, mask) = (self.bins.dense, self.bins.mask);
        let slots = self.bins.start.len() - 1;
        let order = &mut self.order;
        order.slot_of.clear();
        order.slot_of.resize(b.len(), u32::MAX);
        order.slot_of.par_iter_mut().zip(b.par_iter()).with_min_len(CHUNK).for_each(|(s, p)| {
            if let Some(q) = voxel_of(grid, *p) {
                *s = slot(dense, mask, q);
            }
        });
        // Slot `slots` holds those outside the grid.
        order.start.clear();
        order.start.resize(slots + 2, 0);
        for &s in &order.slot_of {
            let s = if s == u32::MAX { slots } else { s as usize };
            order.start[s + 1] += 1;
        }
        for k in 0..=slots {
            order.start[k + 1] += order.start[k];
        }
        order.pos.resize(b.len(), Vec3::ZERO);
        order.k_of.resize(b.len(), 0);
        for (j, &s) in order.slot_of.iter().enumerate() {
            let s = if s == u32::MAX { slots } else { s as usize };
            let k = order.start[s] as usize;
            order.start[s] += 1;
            order.pos[k] = b[j];
            order.k_of[j] = k as u32;
        }
    }
}

/// What a B vertex needs to probe.
struct Probe<'a> {
    grid: &'a VoxelGrid,
    params: &'a ContactParams,
    bins: &'a Bins,
    fixed: &'a [AtomicI64],
    scale: f32,
}

impl Probe<'_> {
    /// The voxels of the block around `q` along one axis that a sphere of radius `r` around
    /// `p` can reach (all three when `r` is `None`), clipped to the grid.
    fn axis_range(&self, axis: usize, p: f32, q: u32, r: Option<f32>) -> (u32, u32) {
        let dim = self.grid.dims()[axis];
        let (mut lo, mut hi) = (q.saturating_sub(1), (q + 1).min(dim - 1));
        if let Some(r) = r {
            let vs = self.grid.voxel_size();
            let origin = self.grid.origin()[axis];
            // Generous for the f32 rounding of positions, voxel indices, faces and d2: a few
            // ulps of the largest magnitude involved, and 1e-3 of the radius.
            let margin = 1e-3 * r + 16.0 * f32::EPSILON * (p.abs() + origin.abs() + vs * dim as f32);
            let reach = r + margin;
            // Selects, not branches: which faces are out of reach is data, not a pattern.
            let below = p - (origin + q as f32 * vs) > reach;
            let above = (origin + (q + 1) as f32 * vs) - p > reach;
            lo = if below { q } else { lo };
            hi = if above { q } else { hi };
        }
        (lo, hi)
    }

    /// Walks voxels `lo..=hi`, offering every A vertex of each (and whether it is in `own`) to
    /// `visit(d2, index, bin position, in_own)`. A row's voxels sit in consecutive slots (see
    /// [`voxel_hash`]), so each row of the block is one contiguous scan.
    #[inline]
    fn walk(&self, p: Vec3, lo: UVec3, hi: UVec3, own: UVec3, mut visit: impl FnMut(f32, u32, u32, bool)) {
        let bins = self.bins;
        if bins.dense.is_some() {
            // Every entry of the run is in this row and in lo.x..=hi.x: no checks.
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    let s0 = slot(bins.dense, bins.mask, UVec3::new(lo.x, y, z)) as usize;
                    let s1 = slot(bins.dense, bins.mask, UVec3::new(hi.x, y, z)) as usize;
                    for k in bins.start[s0] as usize..bins.start[s1 + 1] as usize {
                        visit(dist2(p, bins.pos[k]), bins.index[k], k as u32, bins.voxel[k] == own);
                    }
                }
            }
            return;
        }
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                let s0 = voxel_hash(UVec3::new(lo.x, y, z)) & bins.mask;
                let s1 = voxel_hash(UVec3::new(hi.x, y, z)) & bins.mask;
                let mut scan = |from: u32, to: u32| {
                    for k in bins.start[from as usize] as usize..bins.start[to as usize + 1] as usize {
                        let v = bins.voxel[k];
                        if v.y == y && v.z == z && v.x >= lo.x && v.x <= hi.x {
                            visit(dist2(p, bins.pos[k]), bins.index[k], k as u32, v == own);
                        }
                    }
                };
                if s0 <= s1 {
                    scan(s0, s1);
                } else {
                    // The row wraps around the end of the table.
                    scan(s0, bins.mask);
                    scan(0, s1);
                }
            }
        }
    }

    /// The force on B vertex `p`, or `None` when it does not collide; adds A's shares.
    fn probe(&self, p: Vec3) -> Option<Vec3> {
        let q = voxel_of(self.grid, p)?;
        let plane = self.params.direction == Direction::PlaneNormal;
        let (own, block) = match self.params.search {
            Search::Voxel => {
                let mut own = Nearest::EMPTY;
                let mut block = Nearest::EMPTY;
                if plane {
                    let r = |k: usize| self.axis_range(k, p[k], q[k], None);
                    let ((x0, x1), (y0, y1), (z0, z1)) = (r(0), r(1), r(2));
                    self.walk(p, UVec3::new(x0, y0, z0), UVec3::new(x1, y1, z1), q, |d, i, k, is_own| {
                        block.insert(d, i, k);
                        if is_own {
                            own.insert(d, i, k);
                        }
                    });
                } else {
                    self.walk(p, q, q, q, |d, i, k, _| own.insert(d, i, k));
                }
                (own, block)
            }
            Search::Neighbours { radius } => {
                let r2 = radius * radius;
                let r = |k: usize| self.axis_range(k, p[k], q[k], Some(radius));
                let ((x0, x1), (y0, y1), (z0, z1)) = (r(0), r(1), r(2));
                let mut block = Nearest::EMPTY;
                let (lo, hi) = (UVec3::new(x0, y0, z0), UVec3::new(x1, y1, z1));
                if plane {
                    self.walk(p, lo, hi, q, |d, i, k, _| {
                        if d < r2 {
                            block.insert(d, i, k);
                        }
                    });
                } else {
                    // Only the partner is needed: keep the best, no top-3 bookkeeping.
                    let (mut best_d, mut best_i, mut best_k) = (r2, u32::MAX, 0);
                    self.walk(p, lo, hi, q, |d, i, k, _| {
                        // Without branches: whether a candidate wins is data, not a pattern.
                        let better = (d < best_d) | ((d == best_d) & (d < r2) & (i < best_i));
                        best_d = if better { d } else { best_d };
                        best_i = if better { i } else { best_i };
                        best_k = if better { k } else { best_k };
                    });
                    if best_i != u32::MAX {
                        block = Nearest { d: [best_d, 0.0, 0.0], i: [best_i, 0, 0], k: [best_k, 0, 0], n: 1 };
                    }
                }
                (block, block)
            }
        };
        if own.n == 0 {
            return None;
        }
        let m = self.params.magnitude;
        let center = self.grid.center();
        let pos = &self.bins.pos;
        if plane && block.n == 3 {
            let [k0, k1, k2] = block.k;
            if let Some(n) = plane_normal(center, pos[k0 as usize], pos[k1 as usize], pos[k2 as usize]) {
                let f_b = m * n;
                let share = -f_b / 3.0;
                for k in block.k {
                    self.add(k, share);
                }
                return Some(f_b);
            }
        }
        let partner = own.k[0];
        let f_b = m * pairwise_direction(center, pos[partner as usize], p);
        self.add(partner, -f_b);
        Some(f_b)
    }

    /// Adds `f` to the accumulator of the A vertex at bin position `k`.
    fn add(&self, k: u32, f: Vec3) {
        for axis in 0..3 {
            let c = round_count(f[axis] * self.scale);
            if c != 0 {
                self.fixed[3 * k as usize + axis].fetch_add(i64::from(c), Ordering::Relaxed);
            }
        }
    }
}

impl Collision for ParallelCpuCollision {
    fn step(&mut self, a: &[Vec3], b: &[Vec3]) -> Result<ContactReport, Error> {
        let mut report = ContactReport::default();
        self.step_into(a, b, &mut report)?;
        Ok(report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inline_floor_and_round_equal_the_library_ones() {
        let mut x = -70_000_000.0f32;
        let specials =
            [0.0, -0.0, 0.5, -0.5, 1.5, 2.5, -2.5, -1.0, 8_388_607.5, -8_388_607.5, 4_194_303.5, 1e30, -1e30];
        for v in specials {
            assert_eq!(floor(v), v.floor(), "{v}");
            assert_eq!(round_count(v), v.round_ties_even() as i32, "{v}");
        }
        while x < 70_000_000.0 {
            for v in [x, x + 0.25, x + 0.5, x + 0.75, f32::from_bits(x.to_bits() + 1)] {
                assert_eq!(floor(v), v.floor(), "{v}");
                if v.abs() < 1e9 {
                    assert_eq!(round_count(v), v.round_ties_even() as i32, "{v}");
                }
            }
            x += 997.3;
        }
        for k in -300_000..300_000 {
            let v = k as f32 * 0.5;
            assert_eq!(round_count(v), v.round_ties_even() as i32, "{v}");
            assert_eq!(floor(v), v.floor(), "{v}");
        }
    }
}
