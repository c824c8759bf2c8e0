//! `ParallelCpuCollision`: a multi-threaded CPU backend (rayon) for machines without an adapter,
//! giving the same reports as the reference.
//!
//! What makes it fast, and why it stays exact:
//! - Both bodies are sorted by the voxel table's slot (a parallel counting sort, `sort`):
//!   A's positions are copied into slot order, so a walk reads contiguous memory, and B is
//!   probed in the same order, so neighbouring probes read neighbouring bins. The caller's
//!   vertex order is touched only when a body is read in and its forces written out, which makes
//!   the speed the same for any order.
//! - A sort is kept from step to step where a new one would come out the same: A's while it
//!   has not moved, bit for bit, and B's while each of its vertices stays in its slot
//!   (`Kept`, `SortedBody::sort_keeping`).
//! - Each vertex's slot is computed four at a time in SIMD lanes (`wide`), exactly as one by
//!   one (`keys_of`), and so is each B vertex's block in the probe (`blocks_in_lanes`).
//! - B is probed in parallel; each row of the 3×3×3 block is one contiguous scan (rows sit in
//!   consecutive slots: a dense table's linear index, or a hashed table's bricks of rows,
//!   `Hashed`), and under `Search::Neighbours` rows and columns the
//!   radius cannot reach are skipped (only when their nearest face is farther than the radius
//!   plus a rounding margin, so no candidate is lost). A pairwise partner is the least
//!   `(d2, index)` kept as one 64-bit key (`Probe::probe`). On x86-64 CPUs with AVX2 the probe
//!   runs a copy of itself compiled for them, chosen at run time: the same operations, the same
//!   bits.
//! - B's forces go back to the caller's order in one pass that also marks its colliding
//!   vertices, a bit each, from which the contact list is made.
//! - Forces on A are summed in fixed point with atomic integers: integer sums do not depend on
//!   their order, so the totals equal the reference's exactly. A run of B adds plainly to the
//!   accumulators that it alone reaches on a dense table; on a hashed table, where none are a
//!   run's alone, the runs list their shares by range of A's bins (`Share`) and one task per
//!   range adds them. 32-bit accumulators while no total
//!   can leave `i32` (no slot of B holds more than 1213 vertices), else 64-bit ones.

mod sort;

use std::hint::select_unpredictable;
use std::sync::atomic::{AtomicI32, AtomicI64, Ordering};

use bytemuck::cast;
use glam::{UVec3, Vec3};
use rayon::prelude::*;
use wide::{f32x4, i32x4, u32x4};

use crate::collision::Collision;
use crate::cpu::{check_body, step_grid};
use crate::eliminate::{ForceLaw, pairwise_direction, pairwise_direction_at, plane_normal};
use crate::error::{Body, Error};
use crate::grid::VoxelGrid;
use crate::math::dist2;
use crate::params::{ContactParams, Direction, Response, Search};
use crate::report::ContactReport;
use crate::voxel_data::{dense_slots, hashed_slots, voxel_hash};
use sort::{Scatter, SortedBody, chunk};

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

/// 1.5 · 2^23: added to and taken from an `f32` below 2^22 in magnitude, it leaves the nearest
/// integer, ties to even ([`round_count`], [`counts`]).
const MAGIC: f32 = 12_582_912.0;

/// `x.round_ties_even() as i32` for the fixed-point counts, inline (likewise a libm call
/// otherwise): adding and subtracting 1.5 · 2^23 rounds to the nearest even integer in the
/// default rounding mode, exactly, for |x| < 2^22 — counts are at most about 2^16.
#[inline]
fn round_count(x: f32) -> i32 {
    if x.abs() < 4_194_304.0 { ((x + MAGIC) - MAGIC) as i32 } else { x.round_ties_even() as i32 }
}

/// `round_count(f[axis] * scale)` for the three axes, in lanes while every product is within
/// `round_count`'s quick range (the same operations, so the same counts).
#[inline(always)]
fn counts(f: Vec3, scale: f32) -> [i32; 3] {
    let x = f32x4::new([f.x, f.y, f.z, 0.0]) * f32x4::splat(scale);
    if x.abs().simd_lt(f32x4::splat(4_194_304.0)).all() {
        // Integers now, which truncation keeps.
        let c = ((x + f32x4::splat(MAGIC)) - f32x4::splat(MAGIC)).trunc_int().to_array();
        [c[0], c[1], c[2]]
    } else {
        let x = x.to_array();
        [round_count(x[0]), round_count(x[1]), round_count(x[2])]
    }
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

/// The slot of voxel `v`: its linear index in a dense table, else its hashed slot.
#[inline]
fn slot(dense: Option<[u32; 2]>, hashed: Hashed, v: UVec3) -> u32 {
    match dense {
        Some([dx, dy]) => v.x + dx * (v.y + dy * v.z),
        None => hashed.slot(v),
    }
}

/// A hashed table's slots: rows `(y, z)` grouped in bricks of 4 × 4 rows, each brick placed by
/// [`voxel_hash`] of its own coordinates, its rows `row` slots apart (the grid's voxels along
/// x, so the rows of a brick do not overlap), and `x` added, masked to the table. A row's
/// voxels sit in consecutive slots, as the walk needs, and most of the rows around a voxel in
/// the same brick, a few kilobytes apart: a block's walk reads one to four places of the
/// table, where a hash of each row read nine unrelated ones (a third of a hashed probe's time
/// at 1M, docs/performance-notes.md §43). Which slot a voxel lands in only affects speed: the
/// walk checks each vertex's own voxel.
#[derive(Clone, Copy, Debug, Default)]
struct Hashed {
    mask: u32,
    row: u32,
}

impl Hashed {
    #[inline(always)]
    fn slot(self, v: UVec3) -> u32 {
        let brick = voxel_hash(UVec3::new(0, v.y >> 2, v.z >> 2));
        let row = ((v.y & 3) + 4 * (v.z & 3)).wrapping_mul(self.row);
        brick.wrapping_add(row).wrapping_add(v.x) & self.mask
    }
}

/// Writes the slot of each of `points` into `keys` (`u32::MAX`: outside the grid or not
/// finite): the same as `voxel_of` and `slot` one by one, four points at a time
/// ([`voxels_in_lanes`], and the table's slot of each voxel in lanes).
fn keys_of(grid: &VoxelGrid, dense: Option<[u32; 2]>, hashed: Hashed, points: &[Vec3], keys: &mut [u32]) {
    let one_by_one = |points: &[Vec3], keys: &mut [u32]| {
        for (k, &p) in keys.iter_mut().zip(points) {
            *k = voxel_of(grid, p).map_or(u32::MAX, |q| slot(dense, hashed, q));
        }
    };
    let slots = |[x, y, z]: [i32x4; 3]| -> i32x4 {
        match dense {
            // `x + dx * (y + dy * z)` in wrapping 32-bit arithmetic: the same bits as in `u32`.
            Some([dx, dy]) => x + i32x4::splat(dx as i32) * (y + i32x4::splat(dy as i32) * z),
            // `Hashed::slot`, the same operations on unsigned lanes.
            None => {
                let (x, y, z): (u32x4, u32x4, u32x4) = (cast(x), cast(y), cast(z));
                let h = ((y >> 2) * u32x4::splat(0x9e37_79b1)) ^ ((z >> 2) * u32x4::splat(0x85eb_ca77));
                let three = u32x4::splat(3);
                let row = ((y & three) + ((z & three) << 2)) * u32x4::splat(hashed.row);
                cast(((h ^ (h >> 16)) + row + x) & u32x4::splat(hashed.mask))
            }
        }
    };
    let whole = points.len() / LANES * LANES;
    for (p, k) in points[..whole].chunks_exact(LANES).zip(keys[..whole].chunks_exact_mut(LANES)) {
        let (q, inside) = voxels_in_lanes(grid, [&p[0], &p[1], &p[2], &p[3]]);
        let s = inside.select(slots(q), i32x4::splat(-1)).to_array();
        for (k, s) in k.iter_mut().zip(s) {
            *k = s as u32;
        }
    }
    one_by_one(&points[whole..], &mut keys[whole..]);
}

/// The voxels of four points, `voxel_of` in lanes: each axis's voxel index, and whether the
/// point is inside (all bits set) — where it is not, the indices mean nothing. A point is
/// inside when every `t = (p - origin) · inv` is in `[0, dim)` (a NaN or an infinity never
/// is), which is `voxel_of`'s test, since `floor(t)` is in `[0, dim)` exactly when `t` is
/// (`dim` is an integer); and there `floor(t)` is `t` truncated.
#[inline(always)]
fn voxels_in_lanes(grid: &VoxelGrid, p: [&Vec3; LANES]) -> ([i32x4; 3], i32x4) {
    let (o, inv, dim) = (grid.origin(), f32x4::splat(grid.inv_voxel_size()), grid.dims().as_vec3());
    let axis = |c: fn(&Vec3) -> f32, o: f32, dim: f32| {
        let t = (f32x4::new([c(p[0]), c(p[1]), c(p[2]), c(p[3])]) - f32x4::splat(o)) * inv;
        (t.trunc_int(), t.simd_ge(f32x4::ZERO) & t.simd_lt(f32x4::splat(dim)))
    };
    let (qx, inx) = axis(|p| p.x, o.x, dim.x);
    let (qy, iny) = axis(|p| p.y, o.y, dim.y);
    let (qz, inz) = axis(|p| p.z, o.z, dim.z);
    ([qx, qy, qz], cast(inx & iny & inz))
}

/// The blocks of [`Probe::block`] in lanes, for four points `p` in voxels `q` (from
/// [`voxels_in_lanes`]): each axis's first and last voxel, with the same operations on the
/// same values, so the same voxels.
#[inline(always)]
fn blocks_in_lanes(
    grid: &VoxelGrid,
    p: [&Vec3; LANES],
    q: [i32x4; 3],
    r: Option<f32>,
) -> ([i32x4; 3], [i32x4; 3]) {
    let (origin, vs, dims) = (grid.origin(), grid.voxel_size(), grid.dims());
    let one = i32x4::splat(1);
    let axis = |axis: usize| {
        let (q, dim) = (q[axis], dims[axis]);
        let mut lo = (q - one).max(i32x4::ZERO);
        let mut hi = (q + one).min(i32x4::splat(dim as i32 - 1));
        if let Some(r) = r {
            let p = f32x4::new(p.map(|p| p[axis]));
            let o = origin[axis];
            // As `Probe::axis_range`, term by term.
            let margin = f32x4::splat(1e-3 * r)
                + f32x4::splat(16.0 * f32::EPSILON)
                    * ((p.abs() + f32x4::splat(o.abs())) + f32x4::splat(vs * dim as f32));
            let reach = f32x4::splat(r) + margin;
            let (o, vs) = (f32x4::splat(o), f32x4::splat(vs));
            let below: i32x4 = cast((p - (o + q.round_float() * vs)).simd_gt(reach));
            let above: i32x4 = cast(((o + (q + one).round_float() * vs) - p).simd_gt(reach));
            lo = below.select(q, lo);
            hi = above.select(q, hi);
        }
        (lo, hi)
    };
    let ((x0, x1), (y0, y1), (z0, z1)) = (axis(0), axis(1), axis(2));
    ([x0, y0, z0], [x1, y1, z1])
}

/// Points whose voxels are computed at once.
const LANES: usize = 4;

/// A's voxel table: its slots, and A sorted by them.
#[derive(Debug, Default)]
struct Bins {
    /// `Some([dx, dy])`: one slot per voxel, at `x + dx * (y + dy * z)`.
    dense: Option<[u32; 2]>,
    /// Otherwise: the hashed table.
    hashed: Hashed,
    /// A in slot order.
    a: SortedBody,
    /// Hashed tables only: the voxel of each sorted A vertex (a walk keeps the row's own).
    voxel: Vec<UVec3>,
}

/// A as the last step sorted it: its positions and how many it binned (the grid follows from
/// them). A step whose A is the same, bit for bit, keeps that order instead of sorting A
/// again: a body
/// held still (a rigid wall, an instrument at rest, `moving(N)`'s A) is sorted once. Keeping
/// it is a parallel copy of A each step that sorts (12 MB at 1M vertices); checking it, a
/// comparison that stops at the first difference (docs/performance.md, "Moving bodies").
#[derive(Debug, Default)]
struct Kept {
    a: Vec<Vec3>,
    binned: Option<u32>,
}

impl Kept {
    fn keep(&mut self, a: &[Vec3], binned: u32) {
        self.a.resize(a.len(), Vec3::ZERO);
        self.a.par_chunks_mut(chunk(a.len())).zip(a.par_chunks(chunk(a.len()))).for_each(|(to, from)| {
            to.copy_from_slice(from);
        });
        self.binned = Some(binned);
    }
}

/// Whether `x` and `y` hold the same bits (so `-0.0` is not `0.0`, and a NaN equals itself).
fn same_bits(x: &[Vec3], y: &[Vec3]) -> bool {
    let (x, y): (&[u32], &[u32]) = (bytemuck::cast_slice(x), bytemuck::cast_slice(y));
    x.len() == y.len()
        && x.par_chunks(4 * chunk(x.len())).zip(y.par_chunks(4 * chunk(y.len()))).all(|(a, b)| a == b)
}

/// The caller's indices of the bits set in `marks`, ascending, into `out`: the words' bits
/// counted (a few thousand `popcnt`s), then each task's words written into its own range.
/// `starts` is reused from step to step, so nothing is allocated once the vectors are grown.
fn marked_indices(marks: &[u64], starts: &mut Vec<usize>, out: &mut Vec<u32>) {
    const WORDS: usize = 1024;
    starts.clear();
    starts.push(0);
    for words in marks.chunks(WORDS) {
        let ones: usize = words.iter().map(|w| w.count_ones() as usize).sum();
        starts.push(starts[starts.len() - 1] + ones);
    }
    out.clear();
    out.resize(starts[starts.len() - 1], 0);
    let to = Scatter::new(out);
    marks.par_chunks(WORDS).zip(starts.par_windows(2)).enumerate().for_each(|(c, (words, range))| {
        let mut at = range[0];
        for (w, &word) in words.iter().enumerate() {
            let base = (64 * (c * WORDS + w)) as u32;
            let mut bits = word;
            while bits != 0 {
                // SAFETY: this task's words have `range[1] - range[0]` bits set, counted above,
                // and the tasks' ranges tile `out`: every index is written once.
                unsafe { to.write(at, base + bits.trailing_zeros()) };
                at += 1;
                bits &= bits - 1;
            }
        }
    });
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
    /// B in the order of A's slots.
    b: SortedBody,
    /// Per sorted B vertex: its force and whether it collides (`w` = 1); scratch for the way
    /// back (`SortedBody::unsort`).
    res_b: Vec<[f32; 4]>,
    scratch_b: Vec<[f32; 4]>,
    /// Per binned A vertex, in bin order: its force; scratch for the way back.
    res_a: Vec<Vec3>,
    scratch_a: Vec<Vec3>,
    /// B's colliding vertices, a bit each in the caller's order; the same for A's way back,
    /// which marks none.
    marks: Vec<u64>,
    marks_a: Vec<u64>,
    /// Where each run of `marks` starts among the colliding vertices (`marked_indices`).
    mark_starts: Vec<usize>,
    /// Fixed-point force accumulators of A, three per binned vertex in bin order: 64-bit, and
    /// 32-bit for steps where no total can leave `i32` (half the memory the probe adds into).
    fixed: Vec<AtomicI64>,
    fixed32: Vec<AtomicI32>,
    /// On a hashed table: A's shares from each run of B's probe, by range of A's bins
    /// ([`Share`]); kept from step to step for their capacity.
    shares: Vec<Vec<Vec<Share>>>,
    /// With profiling on, the last step's phases in milliseconds (see [`PHASES`]).
    phases: Option<[f64; PHASES.len()]>,
    /// A as last sorted ([`Kept`]): a still A keeps its order.
    kept: Kept,
    /// Steps that kept A's order, and B's ([`ParallelCpuCollision::orders_kept`]).
    orders_kept: [u64; 2],
    /// The contacts' response, and its force law.
    response: Response,
    law: ForceLaw,
}

/// The phases of a parallel step, as [`ParallelCpuCollision::phase_times`] names them: A
/// sorted by slot, B sorted by A's slots, the probe (which writes B's results in B's order),
/// B's forces, A's forces back in A's order, and the list of colliding B vertices.
pub const PHASES: [&str; 6] = ["sort_a", "sort_b", "probe", "forces_b", "forces_a", "colliding"];

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
            b: SortedBody::default(),
            res_b: Vec::new(),
            scratch_b: Vec::new(),
            res_a: Vec::new(),
            scratch_a: Vec::new(),
            marks: Vec::new(),
            marks_a: Vec::new(),
            mark_starts: Vec::new(),
            fixed: Vec::new(),
            fixed32: Vec::new(),
            shares: Vec::new(),
            phases: None,
            kept: Kept::default(),
            orders_kept: [0; 2],
            response: Response::Constant,
            law: ForceLaw::new(&params, Response::Constant, grid.voxel_size()),
        })
    }

    /// The same backend with its contacts' force magnitudes given by `response`, as
    /// [`CpuCollision::with_response`](crate::CpuCollision::with_response).
    ///
    /// # Errors
    /// [`Error::Response`] when `response` is invalid for the grid.
    pub fn with_response(self, response: Response) -> Result<ParallelCpuCollision, Error> {
        response.validate(&self.params, &self.grid)?;
        let law = ForceLaw::new(&self.params, response, self.grid.voxel_size());
        Ok(ParallelCpuCollision { response, law, ..self })
    }

    /// How its contacts' force magnitudes are chosen.
    #[must_use]
    pub fn response(&self) -> Response {
        self.response
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

    /// Times each phase of the following steps (a clock read between phases), or stops.
    pub fn set_profiling(&mut self, on: bool) {
        self.phases = on.then_some([0.0; PHASES.len()]);
    }

    /// The last step's phases in milliseconds, in [`PHASES`] order; `None` with profiling off.
    #[must_use]
    pub fn phase_times(&self) -> Option<[(&'static str, f64); PHASES.len()]> {
        self.phases.map(|t| std::array::from_fn(|k| (PHASES[k], t[k])))
    }

    /// How many steps so far kept the order A was last sorted in, and how many B's: A's while
    /// it has not moved, bit for bit; B's while, over A's table as kept, every B vertex stays in
    /// the slot it was sorted into (docs/performance.md, "Moving bodies"). Either way the
    /// reports are the same; a kept order saves the sort.
    #[must_use]
    pub fn orders_kept(&self) -> [u64; 2] {
        self.orders_kept
    }

    /// One step into `report`, reusing its vectors: once they have reached the bodies' sizes a
    /// step allocates nothing.
    ///
    /// # Errors
    /// As [`Collision::step`].
    ///
    /// A step called from outside rayon's pool runs as one job on the pool, so that its dozen
    /// parallel phases are handed out through the workers' own queues: from outside, each would
    /// cross to the pool through its global queue (a wake-up each, and a queue block
    /// allocated every 63 hand-offs).
    pub fn step_into(&mut self, a: &[Vec3], b: &[Vec3], report: &mut ContactReport) -> Result<(), Error> {
        check_body(Body::A, a)?;
        check_body(Body::B, b)?;
        if rayon::current_thread_index().is_some() {
            self.step_in_pool(a, b, report)
        } else {
            rayon::scope(|_| self.step_in_pool(a, b, report))
        }
    }

    /// [`step_into`](Self::step_into) on a thread of the pool.
    fn step_in_pool(&mut self, a: &[Vec3], b: &[Vec3], report: &mut ContactReport) -> Result<(), Error> {
        let mut clock = self.phases.map(|_| (std::time::Instant::now(), 0));
        let mut lap = |phases: &mut Option<[f64; PHASES.len()]>| {
            if let (Some(t), Some((last, k))) = (phases.as_mut(), clock.as_mut()) {
                let now = std::time::Instant::now();
                t[*k] = (now - *last).as_secs_f64() * 1e3;
                (*last, *k) = (now, *k + 1);
            }
        };
        let grid = step_grid(&self.grid, self.params.anchor, a)?;
        // A that has not moved since the last step, bit for bit, is in the order it was
        // sorted in then (docs/design.md §7 lets a backend keep it): the step's grid follows
        // from A and the backend's own, which never changes.
        let (binned, same_table) = match self.kept.binned {
            Some(binned) if same_bits(&self.kept.a, a) => (binned, true),
            _ => {
                let binned = self.bin(&grid, a);
                self.kept.keep(a, binned);
                (binned, false)
            }
        };
        lap(&mut self.phases);
        // B keeps its order while every vertex stays in the slot it was sorted into, over a
        // table that has not changed since (A kept: B was last sorted over A's table as it is).
        let (dense, hashed) = (self.bins.dense, self.bins.hashed);
        let slots = self.bins.a.start.len() - 1;
        let (_, kept_b) =
            self.b.sort_keeping(b, slots, same_table, |p, k| keys_of(&grid, dense, hashed, p, k));
        self.orders_kept[1] += u64::from(kept_b);
        self.orders_kept[0] += u64::from(same_table);
        lap(&mut self.phases);
        // A's totals fit 32-bit accumulators when no total can leave i32: a B vertex adds at
        // most one count to an A vertex, of at most 65537 (|force| ≤ magnitude), and only B's
        // vertices in the 27 voxels around that A vertex's reach it, each at most the fullest
        // slot of B: 27 · 1213 · 65540 < 2^31.
        let narrow = 27 * u64::from(self.b.max_per_slot) * 65_540 < 1 << 31;
        let run = Run { grid: &grid, params: &self.params, law: &self.law, bins: &self.bins, b: &self.b };
        let overflow = if narrow {
            run.probe(&mut self.fixed32, &mut self.shares, &mut self.res_b, &mut self.res_a)
        } else {
            run.probe(&mut self.fixed, &mut self.shares, &mut self.res_b, &mut self.res_a)
        };
        lap(&mut self.phases);
        // B's forces in B's order (those outside the grid collide with nothing), its colliding
        // vertices marked.
        report.force_b.resize(b.len(), Vec3::ZERO);
        self.b.unsort(&self.res_b, &mut self.scratch_b, &mut report.force_b, &mut self.marks, |f, h| {
            let h = h.unwrap_or([0.0; 4]);
            *f = Vec3::new(h[0], h[1], h[2]);
            h[3] != 0.0
        });
        lap(&mut self.phases);
        report.force_a.resize(a.len(), Vec3::ZERO);
        self.bins.a.unsort(
            &self.res_a,
            &mut self.scratch_a,
            &mut report.force_a,
            &mut self.marks_a,
            |o, f| {
                *o = f.unwrap_or(Vec3::ZERO);
                false
            },
        );
        lap(&mut self.phases);
        if let Some((k, count)) = overflow {
            return Err(Error::ForceOverflow { vertex: (k / 3) as u32, axis: (k % 3) as u32, count });
        }
        marked_indices(&self.marks, &mut self.mark_starts, &mut report.colliding_b);
        lap(&mut self.phases);
        report.binned_a = binned;
        report.discarded_a = a.len() as u32 - binned;
        report.grid_center = grid.center();
        Ok(())
    }

    /// Sorts A by the slots of a table for `grid`: one slot per voxel while the grid has at
    /// most four voxels a vertex (no aliasing, and a row is one run of A's vertices in spatial
    /// order), else four hash slots a vertex, which keep aliasing rare
    /// (docs/performance-notes.md). Either way memory is O(|A|).
    fn bin(&mut self, grid: &VoxelGrid, a: &[Vec3]) -> u32 {
        let bins = &mut self.bins;
        let d = grid.dims();
        let dense = dense_slots(d, a.len());
        bins.dense = dense.map(|_| [d.x, d.y]);
        let slots = dense.unwrap_or_else(|| hashed_slots(a.len(), 4)) as usize;
        bins.hashed = Hashed { mask: (slots - 1) as u32, row: d.x };
        let (hashed, dense) = (bins.hashed, bins.dense);
        let binned = bins.a.sort(a, slots, |p, k| keys_of(grid, dense, hashed, p, k));
        if dense.is_none() {
            let rec = &bins.a.rec;
            bins.voxel.resize(rec.len(), UVec3::ZERO);
            bins.voxel.par_chunks_mut(chunk(rec.len())).zip(rec.par_chunks(chunk(rec.len()))).for_each(
                |(v, r)| {
                    // Sorted vertices are in the grid; four at a time, the rest one by one.
                    let whole = r.len() / LANES * LANES;
                    for (v, r) in v[..whole].chunks_exact_mut(LANES).zip(r[..whole].chunks_exact(LANES)) {
                        let ([x, y, z], _) = voxels_in_lanes(grid, [&r[0].p, &r[1].p, &r[2].p, &r[3].p]);
                        let (x, y, z) = (x.to_array(), y.to_array(), z.to_array());
                        for (l, v) in v.iter_mut().enumerate() {
                            *v = UVec3::new(x[l] as u32, y[l] as u32, z[l] as u32);
                        }
                    }
                    for (v, r) in v[whole..].iter_mut().zip(&r[whole..]) {
                        *v = voxel_of(grid, r.p).unwrap_or_default();
                    }
                },
            );
        }
        binned
    }
}

/// A fixed-point force accumulator of A.
trait Accumulator: Send + Sync {
    fn zero() -> Self;
    /// Adds with a plain read and write: for an accumulator only one task adds to.
    fn add_owned(&self, c: i32);
    /// Adds atomically.
    fn add_shared(&self, c: i32);
    /// The total, leaving zero.
    fn take(&mut self) -> i64;
}

impl Accumulator for AtomicI64 {
    fn zero() -> Self {
        AtomicI64::new(0)
    }
    #[inline(always)]
    fn add_owned(&self, c: i32) {
        self.store(self.load(Ordering::Relaxed) + i64::from(c), Ordering::Relaxed);
    }
    #[inline(always)]
    fn add_shared(&self, c: i32) {
        self.fetch_add(i64::from(c), Ordering::Relaxed);
    }
    fn take(&mut self) -> i64 {
        std::mem::replace(self.get_mut(), 0)
    }
}

/// Used only while no partial sum can leave `i32` (see `narrow` in the step), so no add wraps.
impl Accumulator for AtomicI32 {
    fn zero() -> Self {
        AtomicI32::new(0)
    }
    #[inline(always)]
    fn add_owned(&self, c: i32) {
        self.store(self.load(Ordering::Relaxed).wrapping_add(c), Ordering::Relaxed);
    }
    #[inline(always)]
    fn add_shared(&self, c: i32) {
        self.fetch_add(c, Ordering::Relaxed);
    }
    fn take(&mut self) -> i64 {
        i64::from(std::mem::replace(self.get_mut(), 0))
    }
}

/// What a step's probe reads: the grid, the params and both sorted bodies.
struct Run<'a> {
    grid: &'a VoxelGrid,
    params: &'a ContactParams,
    law: &'a ForceLaw,
    bins: &'a Bins,
    b: &'a SortedBody,
}

impl Run<'_> {
    /// Probes sorted B into `res_b` (each vertex's force, `w` = 1 where it collides), adding
    /// A's shares into `fixed` (on a hashed table through `shares`), then turns A's totals into
    /// `res_a` (bin order), leaving the accumulators at zero. Returns the first overflow in
    /// (vertex, axis) order, as on the CPU.
    fn probe<T: Accumulator>(
        &self,
        fixed: &mut Vec<T>,
        shares: &mut Vec<Vec<Vec<Share>>>,
        res_b: &mut Vec<[f32; 4]>,
        res_a: &mut Vec<Vec3>,
    ) -> Option<(usize, i64)> {
        // The accumulators are left at zero by the previous step's resolve.
        let binned = self.bins.a.rec.len();
        fixed.truncate(3 * binned);
        fixed.resize_with(3 * binned, T::zero);
        let m = self.params.magnitude;
        let probe = Probe {
            grid: self.grid,
            params: self.params,
            law: self.law,
            bins: self.bins,
            fixed,
            scale: 65536.0 / m,
        };
        // Probe in A's slot order, in long runs, so that most of A's accumulators are one run's
        // alone (`own_bins`): a quarter of a thread's share each.
        let sorted = self.b.rec.len();
        let size = (sorted / (4 * rayon::current_num_threads())).max(1024);
        let voxel = self.params.search == Search::Voxel;
        let plane = self.params.direction == Direction::PlaneNormal;
        res_b.resize(sorted, [0.0; 4]);
        let (dense, b_start) = (self.bins.dense.is_some(), &self.b.start);
        // A hashed table gives no run of B any of A's accumulators alone (`own_bins`), so
        // instead of an atomic add each (a quarter of the probe) the runs list their shares
        // by range of A's bins, and each range is then added up by one task.
        let runs = sorted.div_ceil(size);
        let ranges = if dense { 0 } else { binned.div_ceil(1 << SHARE_BITS) };
        if shares.len() < runs {
            shares.resize_with(runs, Vec::new);
        }
        for lists in shares.iter_mut() {
            if lists.len() < ranges {
                lists.resize_with(ranges, Vec::new);
            }
            lists.iter_mut().for_each(Vec::clear);
        }
        res_b
            .par_chunks_mut(size)
            .zip(self.b.rec.par_chunks(size))
            .zip(shares[..runs].par_iter_mut())
            .enumerate()
            .for_each(|(c, ((out, recs), lists))| {
                let shares = &mut lists[..ranges];
                match (voxel, plane) {
                    (true, false) if dense => probe.run_own_slots(b_start, c * size, recs, out),
                    (false, false) => probe.run_best::<false, false>(recs, out, shares),
                    (false, true) => probe.run_best::<false, true>(recs, out, shares),
                    (true, false) => probe.run_best::<true, false>(recs, out, shares),
                    (true, true) => probe.run_best::<true, true>(recs, out, shares),
                }
            });
        if ranges > 0 {
            let shares = &shares[..runs];
            fixed.par_chunks_mut(3 << SHARE_BITS).enumerate().for_each(|(r, acc)| {
                let first = (r << SHARE_BITS) as u32;
                for s in shares.iter().flat_map(|lists| &lists[r]) {
                    let at = 3 * (s.k - first) as usize;
                    for (a, c) in acc[at..at + 3].iter().zip(s.c) {
                        a.add_owned(c);
                    }
                }
            });
        }
        // Back to f32, each accumulator back to zero for the next step, in bin order.
        let unit = m / 65536.0;
        res_a.resize(binned, Vec3::ZERO);
        let size = chunk(binned);
        fixed
            .par_chunks_mut(3 * size)
            .zip(self.bins.a.rec.par_chunks(size))
            .zip(res_a.par_chunks_mut(size))
            .filter_map(|((fixed, recs), out)| {
                let mut first: Option<(usize, i64)> = None;
                for ((acc, r), o) in fixed.chunks_exact_mut(3).zip(recs).zip(out) {
                    let mut f = [0.0f32; 3];
                    for (axis, (x, acc)) in f.iter_mut().zip(acc).enumerate() {
                        let count = acc.take();
                        match i32::try_from(count) {
                            Ok(c) => *x = c as f32 * unit,
                            Err(_) => {
                                let at = 3 * r.i as usize + axis;
                                first = Some(
                                    first.map_or((at, count), |e| if e.0 < at { e } else { (at, count) }),
                                );
                            }
                        }
                    }
                    *o = Vec3::from_array(f);
                }
                first
            })
            .min_by_key(|(k, _)| *k)
    }
}

/// A's bins per range of [`Share`]s (2^14: a range's accumulators are 192 KiB or less).
const SHARE_BITS: u32 = 14;

/// An A vertex's share of a B vertex's force on a hashed table: its bin position and
/// fixed-point counts, added after the probe by the one task that owns the bin's range.
#[derive(Clone, Copy, Debug)]
struct Share {
    k: u32,
    c: [i32; 3],
}

/// Where a run of B's probes adds A's shares: into the accumulators, plainly for the bins in
/// `own` (see [`Probe::own_bins`]) and atomically for the others, or, on a hashed table, to
/// `shares`, one list per range of `1 << SHARE_BITS` bins (empty on a dense table).
struct Sink<'s> {
    own: (u32, u32),
    shares: &'s mut [Vec<Share>],
}

/// What a B vertex needs to probe.
struct Probe<'a, T> {
    grid: &'a VoxelGrid,
    params: &'a ContactParams,
    law: &'a ForceLaw,
    bins: &'a Bins,
    fixed: &'a [T],
    scale: f32,
}

impl<T: Accumulator> Probe<'_, T> {
    /// [`run`](Self::run), compiled for AVX2 where the CPU has it (detected at run time): the
    /// same operations, so the same results to the bit, in VEX encoding with three operands
    /// and blends for the selects (about 1.5 ms less of a 35 ms probe on lattice(1M)).
    fn run_best<const VOXEL: bool, const PLANE: bool>(
        &self,
        recs: &[sort::Rec],
        out: &mut [[f32; 4]],
        shares: &mut [Vec<Share>],
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && !baseline_only() {
            // SAFETY: the CPU has AVX2.
            return unsafe { self.run_avx2::<VOXEL, PLANE>(recs, out, shares) };
        }
        self.run::<VOXEL, PLANE>(recs, out, shares);
    }

    /// [`run`](Self::run) for CPUs with AVX2.
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2<const VOXEL: bool, const PLANE: bool>(
        &self,
        recs: &[sort::Rec],
        out: &mut [[f32; 4]],
        shares: &mut [Vec<Share>],
    ) {
        self.run::<VOXEL, PLANE>(recs, out, shares);
    }

    /// Probes a run of sorted B vertices; A's shares go to `shares` (by range of A's bins) on a
    /// hashed table, where it has one list per range, else into the accumulators.
    /// Sorted B is inside the grid, so each vertex has its voxel, computed four at a time.
    #[inline(always)]
    fn run<const VOXEL: bool, const PLANE: bool>(
        &self,
        recs: &[sort::Rec],
        out: &mut [[f32; 4]],
        shares: &mut [Vec<Share>],
    ) {
        let to = &mut Sink { own: self.own_bins(recs), shares };
        let force = |f: Option<Vec3>| f.map_or([0.0; 4], |f| [f.x, f.y, f.z, 1.0]);
        let whole = recs.len() / LANES * LANES;
        let radius = self.radius::<VOXEL, PLANE>();
        for (o, r) in out[..whole].chunks_exact_mut(LANES).zip(recs[..whole].chunks_exact(LANES)) {
            let p = [&r[0].p, &r[1].p, &r[2].p, &r[3].p];
            let (q, inside) = voxels_in_lanes(self.grid, p);
            // The blocks in lanes too: one vertex at a time, LLVM packs a voxel's three indices
            // into a vector through the stack, and the load waits for the stores (a third of
            // the probe in `perf`).
            let (lo, hi) = if VOXEL && !PLANE { (q, q) } else { blocks_in_lanes(self.grid, p, q, radius) };
            let at = |v: [i32x4; 3]| v.map(i32x4::to_array);
            let (q, lo, hi, inside) = (at(q), at(lo), at(hi), inside.to_array());
            for l in 0..LANES {
                let u = |v: [[i32; 4]; 3]| UVec3::new(v[0][l] as u32, v[1][l] as u32, v[2][l] as u32);
                o[l] = if inside[l] != 0 {
                    force(self.probe::<VOXEL, PLANE>(r[l].p, u(q), (u(lo), u(hi)), to))
                } else {
                    [0.0; 4]
                };
            }
        }
        for (o, r) in out[whole..].iter_mut().zip(&recs[whole..]) {
            *o = force(voxel_of(self.grid, r.p).and_then(|q| {
                let block = if VOXEL && !PLANE { (q, q) } else { self.block(r.p, q, radius) };
                self.probe::<VOXEL, PLANE>(r.p, q, block, to)
            }));
        }
    }

    /// [`run`](Self::run) for the paper's rule with pairwise forces on a dense table, as a
    /// merge of the two sorted bodies: B's vertices of each slot against A's of the same slot
    /// (its voxel's), with no voxel computed and no block walked. `first` is the position of
    /// `recs[0]` in sorted B.
    fn run_own_slots(&self, b_start: &[u32], first: usize, recs: &[sort::Rec], out: &mut [[f32; 4]]) {
        let (Some([dx, dy]), Some(r0)) = (self.bins.dense, recs.first()) else {
            return;
        };
        let Some(q) = voxel_of(self.grid, r0.p) else {
            return; // sorted B is in the grid
        };
        let to = &mut Sink { own: self.own_bins(recs), shares: &mut [] };
        let (a_start, a_rec) = (&self.bins.a.start, &self.bins.a.rec);
        let mut s = (q.x + dx * (q.y + dy * q.z)) as usize;
        let (mut k, end) = (first, first + recs.len());
        while k < end {
            while b_start[s + 1] as usize <= k {
                s += 1;
            }
            let hi = (b_start[s + 1] as usize).min(end);
            let (a0, a1) = (a_start[s] as usize, a_start[s + 1] as usize);
            for (o, r) in out[k - first..hi - first].iter_mut().zip(&recs[k - first..hi - first]) {
                let (mut best_d, mut best_i, mut best_k) = (f32::INFINITY, u32::MAX, 0);
                for (j, a) in a_rec[a0..a1].iter().enumerate() {
                    let d = dist2(r.p, a.p);
                    let better = (d < best_d) | ((d == best_d) & (a.i < best_i));
                    best_d = if d < best_d { d } else { best_d };
                    best_i = select_unpredictable(better, a.i, best_i);
                    best_k = select_unpredictable(better, (a0 + j) as u32, best_k);
                }
                *o = if best_i == u32::MAX {
                    [0.0; 4]
                } else {
                    let f = self.pair_force(r.p, best_k, to);
                    [f.x, f.y, f.z, 1.0]
                };
            }
            k = hi;
        }
    }

    /// The pairwise force on B vertex `p` from its partner at bin position `k` of A; adds A's
    /// share.
    #[inline(always)]
    fn pair_force(&self, p: Vec3, k: u32, to: &mut Sink<'_>) -> Vec3 {
        let partner = self.bins.a.rec[k as usize].p;
        let f_b = self.law.pairwise(dist2(p, partner)) * pairwise_direction(self.grid.center(), partner, p);
        self.add(k, -f_b, to);
        f_b
    }

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
            lo = select_unpredictable(below, q, lo);
            hi = select_unpredictable(above, q, hi);
        }
        (lo, hi)
    }

    /// Walks voxels `lo..=hi`, offering every A vertex of each (and whether it is in `own`) to
    /// `visit(d2, index, bin position, in_own)`. A row's voxels sit in consecutive slots (see
    /// [`Hashed`]), so each row of the block is one contiguous scan.
    /// `OWN`: whether `visit` looks at `in_own` (when not, it is always `false`).
    #[inline(always)]
    fn walk<const OWN: bool>(
        &self,
        p: Vec3,
        lo: UVec3,
        hi: UVec3,
        own: UVec3,
        mut visit: impl FnMut(f32, u32, u32, bool),
    ) {
        let bins = self.bins;
        let (start, rec) = (&bins.a.start, &bins.a.rec);
        if let Some([dx, dy]) = bins.dense {
            // Every entry of the run is in this row and in lo.x..=hi.x: no checks. The own
            // voxel's vertices are its slot's run.
            let (own_lo, own_hi) = if OWN {
                let s = (own.x + dx * (own.y + dy * own.z)) as usize;
                (start[s] as usize, start[s + 1] as usize)
            } else {
                (0, 0)
            };
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    let row = (dx * (y + dy * z)) as usize;
                    let (k0, k1) =
                        (start[row + lo.x as usize] as usize, start[row + hi.x as usize + 1] as usize);
                    for (k, r) in rec[k0..k1].iter().enumerate() {
                        let k = k0 + k;
                        visit(dist2(p, r.p), r.i, k as u32, OWN && k >= own_lo && k < own_hi);
                    }
                }
            }
            return;
        }
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                let s0 = bins.hashed.slot(UVec3::new(lo.x, y, z));
                let s1 = bins.hashed.slot(UVec3::new(hi.x, y, z));
                let mut scan = |from: u32, to: u32| {
                    let (k0, k1) = (start[from as usize] as usize, start[to as usize + 1] as usize);
                    for (k, (r, &v)) in rec[k0..k1].iter().zip(&bins.voxel[k0..k1]).enumerate() {
                        if v.y == y && v.z == z && v.x >= lo.x && v.x <= hi.x {
                            visit(dist2(p, r.p), r.i, (k0 + k) as u32, OWN && v == own);
                        }
                    }
                };
                if s0 <= s1 {
                    scan(s0, s1);
                } else {
                    // The row wraps around the end of the table.
                    scan(s0, bins.hashed.mask);
                    scan(0, s1);
                }
            }
        }
    }

    /// The reach of a probe's block: the radius under `Search::Neighbours`, `None` (the whole
    /// 3×3×3 block) for the plane normal under `Search::Voxel`; the paper's pairwise rule has
    /// no block but the own voxel.
    fn radius<const VOXEL: bool, const PLANE: bool>(&self) -> Option<f32> {
        match self.params.search {
            Search::Neighbours { radius } if !VOXEL => Some(radius),
            _ => None,
        }
    }

    /// The force on B vertex `p` in voxel `q`, with the voxels `block` that it searches (see
    /// [`Probe::radius`]), or `None` when it does not collide; adds A's shares.
    /// Specialised by search (`VOXEL`: `Search::Voxel`) and direction (`PLANE`:
    /// `Direction::PlaneNormal`), so each configuration runs code without the others' branches.
    #[inline(always)]
    fn probe<const VOXEL: bool, const PLANE: bool>(
        &self,
        p: Vec3,
        q: UVec3,
        (lo, hi): (UVec3, UVec3),
        to: &mut Sink<'_>,
    ) -> Option<Vec3> {
        let law = self.law;
        let center = self.grid.center();
        let pos = |k: u32| self.bins.a.rec[k as usize].p;
        let radius = match self.params.search {
            Search::Neighbours { radius } => radius,
            Search::Voxel => f32::INFINITY,
        };
        if !PLANE {
            // Pairwise: only the partner is needed, the least (d2, index) in the own voxel or
            // within the radius; no top-3 bookkeeping. Without branches: whether a candidate
            // wins is data, not a pattern.
            let r2 = radius * radius;
            // The least `(d2, index)` as one 64-bit key, `d2`'s bits above the index: squared
            // distances are never negative, so their bits order as they do (a NaN's above
            // every number, as it never wins). Under `Search::Neighbours` the start is `(r2, 0)`,
            // which a candidate at `r2` or beyond never undercuts; under `Search::Voxel`
            // `(inf, none)`. One compare and two selects a candidate, where the pair took a
            // dozen instructions in a chain.
            let key = |d: f32, i: u32| (u64::from(d.to_bits()) << 32) | u64::from(i);
            let start = if VOXEL { key(f32::INFINITY, u32::MAX) } else { key(r2, 0) };
            let (mut best, mut best_k) = (start, 0);
            self.walk::<false>(p, lo, hi, q, |d, i, k, _| {
                let candidate = key(d, i);
                // `select_unpredictable`: LLVM turns plain selects back into a branch here,
                // mispredicted on a third of the candidates.
                let better = candidate < best;
                best = select_unpredictable(better, candidate, best);
                best_k = select_unpredictable(better, k, best_k);
            });
            if best == start {
                return None;
            }
            let best_d = f32::from_bits((best >> 32) as u32);
            // `best_d` is `dist2(p, partner)`, which the direction would compute again.
            let f_b = law.pairwise(best_d) * pairwise_direction_at(center, pos(best_k), p, best_d);
            self.add(best_k, -f_b, to);
            return Some(f_b);
        }
        // Plane normal: the three nearest of the block (the own voxel's nearest is the
        // fallback partner under the paper's rule).
        let mut own = Nearest::EMPTY;
        let mut block = Nearest::EMPTY;
        if VOXEL {
            self.walk::<true>(p, lo, hi, q, |d, i, k, is_own| {
                block.insert(d, i, k);
                if is_own {
                    own.insert(d, i, k);
                }
            });
        } else {
            let r2 = radius * radius;
            self.walk::<false>(p, lo, hi, q, |d, i, k, _| {
                if d < r2 {
                    block.insert(d, i, k);
                }
            });
            own = block;
        }
        if own.n == 0 {
            return None;
        }
        if block.n == 3 {
            let [k0, k1, k2] = block.k;
            if let Some(n) = plane_normal(center, pos(k0), pos(k1), pos(k2)) {
                let f_b = law.plane(p, pos(k0), pos(k1), pos(k2), n) * n;
                let share = -f_b / 3.0;
                for k in block.k {
                    self.add(k, share, to);
                }
                return Some(f_b);
            }
        }
        let partner = own.k[0];
        let f_b = law.pairwise(own.d[0]) * pairwise_direction(center, pos(partner), p);
        self.add(partner, -f_b, to);
        Some(f_b)
    }

    /// The block around voxel `q` that a sphere of radius `r` around `p` can reach (the whole
    /// 3×3×3 block when `r` is `None`), clipped to the grid.
    #[inline(always)]
    fn block(&self, p: Vec3, q: UVec3, r: Option<f32>) -> (UVec3, UVec3) {
        let a = |k: usize| self.axis_range(k, p[k], q[k], r);
        let ((x0, x1), (y0, y1), (z0, z1)) = (a(0), a(1), a(2));
        (UVec3::new(x0, y0, z0), UVec3::new(x1, y1, z1))
    }

    /// Adds `f` to the accumulator of the A vertex at bin position `k`, as `to` says (see
    /// [`Sink`]): on a hashed table by a [`Share`] in its range's list, else directly. `to.own`:
    /// the bin positions that only this task's B vertices can reach (see
    /// [`Probe::own_bins`]); their accumulators take a plain read and write, the others an
    /// atomic add (an atomic add waits for the stores before it: a quarter of a lattice probe).
    #[inline(always)]
    fn add(&self, k: u32, f: Vec3, to: &mut Sink<'_>) {
        let counts = counts(f, self.scale);
        if !to.shares.is_empty() {
            if counts != [0; 3] {
                to.shares[(k >> SHARE_BITS) as usize].push(Share { k, c: counts });
            }
            return;
        }
        let own = to.own;
        let mine = k >= own.0 && k < own.1;
        for (axis, c) in counts.into_iter().enumerate() {
            let acc = &self.fixed[3 * k as usize + axis];
            if mine {
                acc.add_owned(c);
            } else if c != 0 {
                acc.add_shared(c);
            }
        }
    }

    /// The bin positions of A that no B vertex outside `recs` (a run of sorted B) can reach.
    ///
    /// In a dense table a B vertex in slot `t` reaches only A vertices in the slots of its
    /// 3×3×3 block, `t - reach ..= t + reach` with `reach = 1 + dx + dx·dy`. B is sorted by
    /// slot, so every other task's B vertices lie in slots `≤ t0` or `≥ t1` (the first and last
    /// of the run: a slot may be split between two runs), and A's slots strictly between
    /// `t0 + reach` and `t1 - reach` are this run's alone. A hashed table has no such bound:
    /// nothing is private there.
    fn own_bins(&self, recs: &[sort::Rec]) -> (u32, u32) {
        let (Some([dx, dy]), Some(first), Some(last)) = (self.bins.dense, recs.first(), recs.last()) else {
            return (0, 0);
        };
        let (Some(t0), Some(t1)) = (voxel_of(self.grid, first.p), voxel_of(self.grid, last.p)) else {
            return (0, 0);
        };
        let (dx, dy) = (dx as u64, dy as u64);
        let lin = |v: UVec3| v.x as u64 + dx * (v.y as u64 + dy * v.z as u64);
        let reach = 1 + dx + dx * dy;
        let (lo, hi) = (lin(t0) + reach + 1, lin(t1).saturating_sub(reach));
        if lo >= hi {
            return (0, 0);
        }
        let start = &self.bins.a.start;
        (start[lo as usize], start[hi as usize])
    }
}

impl Collision for ParallelCpuCollision {
    fn step(&mut self, a: &[Vec3], b: &[Vec3]) -> Result<ContactReport, Error> {
        let mut report = ContactReport::default();
        self.step_into(a, b, &mut report)?;
        Ok(report)
    }
}

/// Whether the probe runs its baseline code even on a CPU with AVX2: never, but in the unit
/// test that compares both.
#[cfg(not(test))]
#[inline(always)]
fn baseline_only() -> bool {
    false
}

#[cfg(test)]
static BASELINE_ONLY: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

#[cfg(test)]
fn baseline_only() -> bool {
    BASELINE_ONLY.load(Ordering::Relaxed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_baseline_probe_and_the_avx2_probe_give_the_references_reports() {
        use crate::CpuCollision;
        use crate::workload;
        // Dense and hashed tables, both directions and searches, more than one run per thread.
        let mut cases = Vec::new();
        for n in [3_000, 40_000] {
            let w = workload::shuffled(n, 22).unwrap();
            for search in [Search::Neighbours { radius: 0.9 }, Search::Voxel] {
                for direction in [Direction::Pairwise, Direction::PlaneNormal] {
                    let params = ContactParams { search, direction, ..w.params };
                    cases.push((w.a.clone(), w.b.clone(), w.grid, params));
                    let roomy = crate::Initializer::new(1.0).margin(20).build(&w.a).unwrap();
                    cases.push((w.a.clone(), w.b.clone(), roomy, params));
                }
            }
        }
        for (a, b, grid, params) in cases {
            let what = format!("{} vertices, {params:?}, {grid:?}", a.len());
            let reference = CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
            for baseline in [true, false] {
                BASELINE_ONLY.store(baseline, Ordering::Relaxed);
                let report = ParallelCpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap();
                BASELINE_ONLY.store(false, Ordering::Relaxed);
                assert_eq!(report, reference, "{what}, baseline only: {baseline}");
            }
        }
    }

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

    /// Grids for the tests of work in lanes against work one by one (center, voxel size,
    /// dims): small and flat ones, far from the origin, and a long one of `long` voxels.
    fn lane_test_grids(long: UVec3) -> [(Vec3, f32, UVec3); 4] {
        [
            (Vec3::ZERO, 1.0, UVec3::new(7, 5, 3)),
            (Vec3::new(-3.25, 1e3, 0.5), 0.25, UVec3::new(40, 1, 9)),
            (Vec3::new(1e6, -1e6, 0.0), 2.0, UVec3::new(1, 300, 2)),
            (Vec3::new(3.0, 0.0, 0.0), 1.0, long),
        ]
    }

    #[test]
    fn keys_in_lanes_equal_voxel_and_slot_one_by_one() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(22);
        // The longest axis reaching t = 2^24.
        for (center, size, dims) in lane_test_grids(UVec3::new(1 << 24, 1, 1)) {
            let grid = VoxelGrid::new(center, size, dims).unwrap();
            let (o, d) = (grid.origin(), grid.dims().as_vec3());
            let top = o + d * size;
            let mut points = vec![
                o,
                top,
                o - Vec3::splat(1e-3),
                Vec3::new(top.x - 1e-3 * size, o.y, o.z),
                Vec3::new(-0.0, -0.0, -0.0),
                Vec3::new(f32::NAN, o.y, o.z),
                Vec3::new(o.x, f32::INFINITY, o.z),
                Vec3::new(o.x, o.y, f32::NEG_INFINITY),
                Vec3::splat(f32::MAX),
                Vec3::splat(-f32::MAX),
            ];
            for _ in 0..2000 {
                // Within the grid and a voxel or two around it, and on voxel faces.
                let t = Vec3::new(rng.random(), rng.random(), rng.random()) * (d + 4.0) - 2.0;
                points.push(o + t * size);
                points.push(o + t.floor() * size);
            }
            for n in [points.len(), points.len() - 1, points.len() - 2, 3, 0] {
                let hashed = |mask| Hashed { mask, row: dims.x };
                for (dense, hashed) in
                    [(Some([dims.x, dims.y]), hashed(0)), (None, hashed(255)), (None, hashed((1 << 22) - 1))]
                {
                    let mut keys = vec![7; n];
                    keys_of(&grid, dense, hashed, &points[..n], &mut keys);
                    for (p, k) in points[..n].iter().zip(&keys) {
                        let one = voxel_of(&grid, *p).map_or(u32::MAX, |q| slot(dense, hashed, q));
                        assert_eq!(*k, one, "{p} in {grid:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn blocks_in_lanes_equal_the_block_one_by_one() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
        let w = crate::workload::lattice(27, 1).unwrap();
        let bins = Bins::default();
        for (center, size, dims) in lane_test_grids(UVec3::new(1 << 20, 2, 1)) {
            let grid = VoxelGrid::new(center, size, dims).unwrap();
            let law = ForceLaw::new(&w.params, Response::default(), size);
            let probe = Probe {
                grid: &grid,
                params: &w.params,
                law: &law,
                bins: &bins,
                fixed: &[] as &[AtomicI32],
                scale: 1.0,
            };
            let (o, d) = (grid.origin(), grid.dims().as_vec3());
            let mut points = vec![o, o + (d - 1e-3) * size];
            for _ in 0..2000 {
                // Inside the grid, on voxel faces and a few ulps either side of them.
                let t = Vec3::new(rng.random(), rng.random(), rng.random()) * d;
                let face = o + t.floor() * size;
                let n = rng.random_range(-8..=8);
                points.push(o + t * size);
                points.push(face);
                points.push(face.to_array().map(|v| f32::from_bits((v.to_bits() as i32 + n) as u32)).into());
            }
            for r in [Some(0.9 * size), Some(0.5 * size), Some(1e-6), Some(3.0 * size), None] {
                // And about a reach from a face, either side of the margin's edge.
                let mut points = points.clone();
                for _ in 0..4000 {
                    let Some(r) = r else { break };
                    let t = (Vec3::new(rng.random(), rng.random(), rng.random()) * d).floor();
                    let side = Vec3::new(rng.random(), rng.random(), rng.random()).round() * 2.0 - 1.0;
                    let jitter = Vec3::new(rng.random(), rng.random(), rng.random()) * 2.0 - 1.0;
                    let reach = r * (1.0 + 1e-3) + jitter * (2e-4 * r + 1e-5 * (o.abs() + d * size));
                    points.push(o + t * size + side * reach);
                }
                points.retain(|p| voxel_of(&grid, *p).is_some());
                for p in points.chunks_exact(LANES) {
                    let p = [&p[0], &p[1], &p[2], &p[3]];
                    let (q, inside) = voxels_in_lanes(&grid, p);
                    assert_eq!(inside.to_array(), [-1; 4]);
                    let (lo, hi) = blocks_in_lanes(&grid, p, q, r);
                    for (l, p) in p.into_iter().enumerate() {
                        let lane = |v: [i32x4; 3]| UVec3::from_array(v.map(|v| v.to_array()[l] as u32));
                        let one = probe.block(*p, lane(q), r);
                        assert_eq!((lane(lo), lane(hi)), one, "{p} with reach {r:?} in {grid:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn counts_in_lanes_equal_round_count() {
        let scale = 65536.0 / 0.75;
        let mut values = vec![0.0, -0.0, 0.5, -0.5, 1.5, -2.5, 4_194_303.5, 4_194_304.0, -4_194_305.0, 1e9];
        values.extend([f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, f32::MIN_POSITIVE]);
        let mut x = -70.0f32;
        while x < 70.0 {
            values.extend([x, f32::from_bits(x.to_bits() + 1), x / scale, (x + 0.5) / scale]);
            x += 0.0371;
        }
        for w in values.windows(3) {
            let f = Vec3::new(w[0], w[1], w[2]);
            let one = [0, 1, 2].map(|a| round_count(f[a] * scale));
            assert_eq!(counts(f, scale), one, "{f}");
        }
    }
}
