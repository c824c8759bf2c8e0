//! A body's vertices sorted by the voxel table's slot, in parallel, in two passes that each
//! write memory in order whatever order the vertices come in:
//! 1. each part of the body (a run of the caller's order, one per task) splits its vertices
//!    into buckets of consecutive slots (at most 1024 buckets, so every bucket's write cursor
//!    stays in cache), with counts of its own;
//! 2. each bucket, a few thousand vertices, is counting-sorted by slot on its own, into its own
//!    range of the sorted array (whose lines it asks for first), and writes its slots' starts.
//!
//! The sort is what makes `ParallelCpuCollision`'s speed independent of the caller's vertex
//! order: every later pass reads the sorted records, whose order depends only on where the
//! vertices are. A single counting sort over all slots did the same with a random access to
//! its counts and one to the sorted array per vertex in any order but the lucky one (2.4× the
//! time shuffled; docs/performance-notes.md). Both passes are stable: within a slot, vertices
//! stay in ascending index order whatever the thread count.

use std::marker::PhantomData;

use glam::Vec3;
use rayon::prelude::*;
use wide::u32x4;

/// A vertex in slot order: its position and its index in the caller's slice.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub(super) struct Rec {
    pub p: Vec3,
    pub i: u32,
}

/// A vertex between the two passes: its slot, index and position.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
struct Tmp {
    s: u32,
    i: u32,
    p: Vec3,
}

/// One body sorted by slot. Buffers are reused from step to step.
#[derive(Debug, Default)]
pub(super) struct SortedBody {
    /// Per vertex: its slot (`u32::MAX`: outside the grid or not finite).
    pub key: Vec<u32>,
    /// The sorted vertices (those outside the grid are left out).
    pub rec: Vec<Rec>,
    /// Per slot: where its vertices start in `rec` (`slots + 1` entries).
    pub start: Vec<u32>,
    /// The vertices in bucket order (between the passes).
    tmp: Vec<Tmp>,
    /// `parts × buckets`: each part's counts per bucket, then its write cursors.
    cursor: Vec<u32>,
    /// Per bucket: where its vertices start in `tmp` and `rec` (`buckets + 1` entries).
    bucket_start: Vec<u32>,
    /// `parts × buckets`: where each part's vertices of each bucket start in `tmp`.
    offset: Vec<u32>,
    /// Per record of `tmp`: its sorted position (within its bucket's range); after one
    /// counting sort, per vertex (`u32::MAX`: left out).
    sorted_at: Vec<u32>,
    /// The most vertices in one slot.
    pub max_per_slot: u32,
    /// Whether the body came nearly in slot order: at most half its vertices in a bucket other
    /// than the last four new ones, as in a body in the grid's own order (x fastest), where
    /// only a few buckets are written at a time. Then the way back reads each value from
    /// its sorted position in the same pass that writes it out, since only those few buckets'
    /// values are read at a time; else it first gathers each bucket's values in the order the
    /// first pass wrote them ([`SortedBody::unsort`]).
    in_order: bool,
    /// The sort's shape, for [`SortedBody::unsort`]: bits of a slot within its bucket,
    /// buckets, and vertices per part (no buckets: one counting sort, `sorted_at` then holding
    /// each vertex's sorted position).
    shape: (u32, usize, usize),
    /// A step's slots, computed before it is known whether the last order can be kept
    /// ([`SortedBody::sort_keeping`]).
    fresh: Vec<u32>,
}

/// The most slots a body sorted in one part is sorted over in one counting sort
/// ([`SortedBody::sort`]): its counts then stay in cache beside the body.
const ONE_PASS_SLOTS: usize = 1 << 17;

/// Tasks for the first pass over `n` vertices: a few per thread, none for small bodies, where
/// the threads would cost more than they save.
fn parts(n: usize) -> usize {
    if n < 32_768 { 1 } else { (4 * rayon::current_num_threads()).min(n / 8192) }
}

/// Items per parallel task for `n` items: every thread gets several tasks.
pub(super) fn chunk(n: usize) -> usize {
    (n / (8 * rayon::current_num_threads())).clamp(1024, 16_384)
}

/// The bits of a slot within its bucket: at most 1024 buckets, at least 256 slots each (or
/// one bucket for a table smaller than that).
fn bucket_bits(slots: usize) -> u32 {
    let bits = usize::BITS - (slots.max(1) - 1).leading_zeros();
    bits.saturating_sub(10).max(bits.min(8))
}

impl SortedBody {
    /// Sorts `points` by their slots among `slots`, which `keys_of(points, keys)` writes for
    /// a run of them (`u32::MAX`: left out), or leaves as `key` already holds them
    /// ([`sort_keeping`](Self::sort_keeping)). Returns how many were sorted.
    pub fn sort(
        &mut self,
        points: &[Vec3],
        slots: usize,
        keys_of: impl Fn(&[Vec3], &mut [u32]) + Sync,
    ) -> u32 {
        let n = points.len();
        // (An empty body too: no part of it to share out.)
        if n == 0 || (parts(n) == 1 && slots <= ONE_PASS_SLOTS) {
            return self.sort_in_one_pass(points, slots, keys_of);
        }
        let shift = bucket_bits(slots);
        let buckets = ((slots.max(1) - 1) >> shift) + 1;
        let parts = parts(n);
        // Whole words of the way back's marks per part (`unsort`).
        let part = n.div_ceil(parts).next_multiple_of(64);
        let parts = n.div_ceil(part); // every part non-empty
        self.key.resize(n, u32::MAX);
        self.cursor.resize(parts * buckets, 0);

        // 1a. Each part's keys and counts per bucket, and how often a vertex's bucket is none
        //     of the last four new ones.
        let misses: usize = self
            .key
            .par_chunks_mut(part)
            .zip(points.par_chunks(part))
            .zip(self.cursor.par_chunks_mut(buckets))
            .map(|((keys, points), counts)| {
                counts.fill(0);
                keys_of(points, keys);
                // The last four new buckets, compared at once: one branch, taken rarely in a
                // body in order and nearly always in another (one per bucket was a coin toss
                // each in a lattice's B, whose vertices alternate between neighbouring rows).
                let (mut misses, mut r) = (0, [u32::MAX; 4]);
                for &s in keys.iter() {
                    if s != u32::MAX {
                        let b = s >> shift;
                        counts[b as usize] += 1;
                        if !u32x4::new(r).simd_eq(u32x4::splat(b)).any() {
                            r = [b, r[0], r[1], r[2]];
                            misses += 1;
                        }
                    }
                }
                misses
            })
            .sum();
        // Offsets in (bucket, part) order: a few thousand numbers.
        self.bucket_start.resize(buckets + 1, 0);
        let mut running = 0u32;
        for b in 0..buckets {
            self.bucket_start[b] = running;
            for p in 0..parts {
                let c = &mut self.cursor[p * buckets + b];
                (*c, running) = (running, running + *c);
            }
        }
        self.bucket_start[buckets] = running;
        let sorted = running as usize;
        self.in_order = 2 * misses <= sorted;
        self.offset.clear();
        self.offset.extend_from_slice(&self.cursor);
        self.shape = (shift, buckets, part);

        // 1b. Each part writes its vertices to its ranges of the buckets, in order.
        self.tmp.resize(sorted, Tmp::default());
        {
            let tmp = Scatter::new(&mut self.tmp);
            self.key
                .par_chunks(part)
                .zip(points.par_chunks(part))
                .zip(self.cursor.par_chunks_mut(buckets))
                .enumerate()
                .for_each(|(p, ((keys, points), cursor))| {
                    for (j, (&s, &q)) in keys.iter().zip(points).enumerate() {
                        if s == u32::MAX {
                            continue;
                        }
                        let at = &mut cursor[(s >> shift) as usize];
                        // SAFETY: part p's cursor of bucket b starts at its own range of `tmp`,
                        // as long as p's count of b; the ranges of all (bucket, part) pairs tile
                        // 0..sorted, and the cursor moves once per vertex that 1a counted from
                        // the same keys. So every index is written once.
                        unsafe { tmp.write(*at as usize, Tmp { s, i: (p * part + j) as u32, p: q }) };
                        tmp.prefetch(*at as usize + PREFETCH_AHEAD);
                        *at += 1;
                    }
                });
        }

        // 2. Each bucket: a counting sort by slot on the bucket's own slice of `start`, which
        //    ends as its slots' starts.
        self.rec.resize(sorted, Rec::default());
        self.sorted_at.resize(sorted, 0);
        self.start.resize(slots + 1, 0);
        {
            let (tmp, bucket_start) = (&self.tmp, &self.bucket_start);
            let rec = Scatter::new(&mut self.rec);
            let sorted_at = Scatter::new(&mut self.sorted_at);
            self.max_per_slot = self.start[..slots]
                .par_chunks_mut(1 << shift)
                .enumerate()
                .map(|(b, start)| {
                    let (lo, hi) = (bucket_start[b] as usize, bucket_start[b + 1] as usize);
                    let first = b << shift;
                    // The bucket's records land anywhere in rec[lo..hi] in any order but the
                    // lucky one, each line's first write a miss that stalls the stores behind
                    // it: ask for every line of the range first, while the counts are made.
                    for at in (lo..hi).step_by(64 / size_of::<Rec>()) {
                        rec.prefetch(at);
                    }
                    start.fill(0);
                    for t in &tmp[lo..hi] {
                        start[t.s as usize - first] += 1;
                    }
                    let most = start.iter().copied().max().unwrap_or(0);
                    let mut running = lo as u32;
                    for c in start.iter_mut() {
                        (*c, running) = (running, running + *c);
                    }
                    for (j, t) in tmp[lo..hi].iter().enumerate() {
                        let at = &mut start[t.s as usize - first];
                        // SAFETY: the bucket's slots' cursors tile its range lo..hi of `rec`
                        // (counted just above from the same vertices), and buckets' ranges are
                        // disjoint: every index is written once. `sorted_at`'s lo..hi is the
                        // bucket's own.
                        unsafe {
                            rec.write(*at as usize, Rec { p: t.p, i: t.i });
                            sorted_at.write(lo + j, *at);
                        }
                        *at += 1;
                    }
                    // Each cursor now holds the next slot's start: shift them back by one.
                    start.copy_within(..start.len() - 1, 1);
                    start[0] = lo as u32;
                    most
                })
                .max()
                .unwrap_or(0);
        }
        self.start[slots] = sorted as u32;
        sorted as u32
    }

    /// [`sort`](Self::sort), keeping the last sort's order where it would come out the same:
    /// when `same_table` (the last sort was over the same table) and every vertex's slot is
    /// the one it had then. The sort's order follows from the slots alone (it is stable, and
    /// its parts depend only on the body's size and the thread count), so the kept order is
    /// the one a new sort would make, record for record: only the positions are new, gathered
    /// into it. A body at rest, or moving within its voxels, is then sorted once; the first
    /// vertex that changes slot sorts it again, with the slots already computed. Returns how
    /// many were sorted, and whether the order was kept.
    pub fn sort_keeping(
        &mut self,
        points: &[Vec3],
        slots: usize,
        same_table: bool,
        keys_of: impl Fn(&[Vec3], &mut [u32]) + Sync,
    ) -> (u32, bool) {
        let n = points.len();
        if !same_table || self.key.len() != n || self.start.len() != slots + 1 {
            return (self.sort(points, slots, keys_of), false);
        }
        let mut fresh = std::mem::take(&mut self.fresh);
        fresh.resize(n, u32::MAX);
        let size = chunk(n);
        // Every part computes its slots (no stop at the first difference: the sort below
        // takes them all).
        let changed: usize = fresh
            .par_chunks_mut(size)
            .zip(points.par_chunks(size))
            .zip(self.key.par_chunks(size))
            .map(|((fresh, points), key)| {
                keys_of(points, fresh);
                usize::from(fresh != key)
            })
            .sum();
        let same = changed == 0;
        let sorted = if same {
            let size = chunk(self.rec.len());
            self.rec.par_chunks_mut(size).for_each(|rec| {
                for r in rec {
                    r.p = points[r.i as usize];
                }
            });
            self.rec.len() as u32
        } else {
            // The slots are known: they become the body's, and the sort takes them as they are.
            std::mem::swap(&mut self.key, &mut fresh);
            self.sort(points, slots, |_, _| {})
        };
        self.fresh = fresh;
        (sorted, same)
    }

    /// A body small enough to sort on one thread, over a table small enough that its counts stay
    /// in cache: one counting sort over every slot (the two passes' buckets cost more than
    /// they save here). The same result as the two passes: stable, the same `rec`, `start` and
    /// `key`.
    fn sort_in_one_pass(
        &mut self,
        points: &[Vec3],
        slots: usize,
        keys_of: impl Fn(&[Vec3], &mut [u32]),
    ) -> u32 {
        let n = points.len();
        self.key.resize(n, u32::MAX);
        self.start.clear();
        self.start.resize(slots + 1, 0);
        keys_of(points, &mut self.key);
        for &s in &self.key {
            if s != u32::MAX {
                self.start[s as usize] += 1;
            }
        }
        self.max_per_slot = self.start.iter().copied().max().unwrap_or(0);
        let mut running = 0u32;
        for c in &mut self.start {
            (*c, running) = (running, running + *c);
        }
        let sorted = self.start[slots] as usize;
        self.rec.resize(sorted, Rec::default());
        self.sorted_at.resize(n, 0);
        // Each slot's cursor, from its start; `sorted_at[i]`: where vertex i went.
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.start[..slots]);
        for (i, (&s, &q)) in self.key.iter().zip(points).enumerate() {
            if s != u32::MAX {
                let at = &mut self.cursor[s as usize];
                self.rec[*at as usize] = Rec { p: q, i: i as u32 };
                self.sorted_at[i] = *at;
                *at += 1;
            }
        }
        self.shape = (0, 0, n);
        sorted as u32
    }

    /// Takes values in sorted order (`by_rec[k]` for `rec[k]`) back to the caller's order,
    /// calling `write(out[i], value)` for each vertex `i` (`None`: left out of the sort), and
    /// sets bit `i % 64` of `marks[i / 64]` where `write` returns `true` (`marks` is resized to
    /// `out.len().div_ceil(64)` words).
    ///
    /// The sort's passes run backwards, so that every access stays in memory order, follows
    /// one of the bucket cursors or stays within a bucket whatever order the vertices came in
    /// (a plain scatter by `rec[k].i` is a random write per vertex in a shuffled body: about
    /// 20 ms of a paper(1M) step): the second pass's as a gather of each record's value from
    /// its sorted position (`sorted_at`, within the bucket's few kilobytes of `by_rec`) into
    /// `scratch`, then the first pass's, each part following its buckets' cursors as it wrote
    /// them. A body that came nearly in slot order (`in_order`) skips `scratch`: its parts
    /// follow a few buckets at a time, so the first pass backwards reads each value from its
    /// sorted position directly, within those buckets' ranges of `by_rec`; a body in another
    /// order follows hundreds of buckets at once, and read so its values would come from
    /// all over `by_rec` (z fastest: 5 -> 8.8 ms a body at 1M).
    pub fn unsort<T: Copy + Default + Send + Sync, O: Send>(
        &mut self,
        by_rec: &[T],
        scratch: &mut Vec<T>,
        out: &mut [O],
        marks: &mut Vec<u64>,
        write: impl Fn(&mut O, Option<T>) -> bool + Sync,
    ) {
        let (shift, buckets, part) = self.shape;
        // Every word is written below (`write_marked`): no need to clear them first.
        marks.resize(out.len().div_ceil(64), 0);
        if buckets == 0 {
            // One counting sort: each vertex's value is where it went.
            let (sorted_at, key) = (&self.sorted_at, &self.key);
            write_marked(out, marks, &write, |i| (key[i] != u32::MAX).then(|| by_rec[sorted_at[i] as usize]));
            return;
        }
        let sorted_at = &self.sorted_at[..self.rec.len()];
        let from = if self.in_order {
            None
        } else {
            scratch.resize(sorted_at.len(), T::default());
            let size = chunk(sorted_at.len());
            scratch.par_chunks_mut(size).zip(sorted_at.par_chunks(size)).for_each(|(s, at)| {
                for (s, &at) in s.iter_mut().zip(at) {
                    *s = by_rec[at as usize];
                }
            });
            Some(&scratch[..])
        };
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.offset);
        out.par_chunks_mut(part)
            .zip(marks.par_chunks_mut(part / 64))
            .zip(self.key.par_chunks(part))
            .zip(self.cursor.par_chunks_mut(buckets))
            .for_each(|(((out, marks), keys), cursor)| {
                write_marked(out, marks, &write, |j| {
                    let s = keys[j];
                    (s != u32::MAX).then(|| {
                        let at = &mut cursor[(s >> shift) as usize];
                        let t = *at as usize;
                        *at += 1;
                        match from {
                            Some(scratch) => {
                                prefetch(scratch, t + PREFETCH_AHEAD);
                                scratch[t]
                            }
                            None => by_rec[sorted_at[t] as usize],
                        }
                    })
                });
            });
    }
}

/// `write(out[j], value(j))` for each `j`, setting bit `j % 64` of `marks[j / 64]` where it
/// returns `true`: each word built in a register and stored once.
#[inline(always)]
fn write_marked<T, O>(
    out: &mut [O],
    marks: &mut [u64],
    write: &impl Fn(&mut O, Option<T>) -> bool,
    mut value: impl FnMut(usize) -> Option<T>,
) {
    let mut word = 0u64;
    for (j, o) in out.iter_mut().enumerate() {
        word |= u64::from(write(o, value(j))) << (j % 64);
        if j % 64 == 63 {
            marks[j / 64] = word;
            word = 0;
        }
    }
    if !out.len().is_multiple_of(64) {
        marks[out.len() / 64] = word;
    }
}

/// How far ahead of a bucket's cursor [`prefetch`] asks, in elements: two or three lines of
/// the sort's records.
const PREFETCH_AHEAD: usize = 8;

/// Asks for the cache line holding `slice[i]` (nothing when `i` is past the end): a hint for
/// the passes that follow a bucket's cursor through memory, one of hundreds at a time when the
/// caller's order is not the slots' (z fastest: the bucket pass 5-6 -> 4-4.5 ms a body at 1M),
/// which the hardware's prefetchers do not follow.
#[inline(always)]
fn prefetch<T>(slice: &[T], i: usize) {
    prefetch_at(slice.as_ptr(), slice.len(), i);
}

#[inline(always)]
fn prefetch_at<T>(ptr: *const T, len: usize, i: usize) {
    #[cfg(target_arch = "x86_64")]
    if i < len {
        // SAFETY: a prefetch never faults, and the address is inside the slice.
        unsafe {
            core::arch::x86_64::_mm_prefetch::<{ core::arch::x86_64::_MM_HINT_T0 }>(ptr.add(i).cast::<i8>())
        };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (ptr, len, i);
}

/// A slice that parallel tasks write at indices that no two writes share: the scatter of a
/// permutation, which safe Rust can only express as a gather from the other side (a second
/// random pass over the caller's order).
pub(super) struct Scatter<'a, T> {
    ptr: *mut T,
    len: usize,
    _slice: PhantomData<&'a mut [T]>,
}

// SAFETY: a `Scatter` is a `&mut [T]` handed to tasks that write disjoint elements (the contract
// of `write`); sending `T`s between threads is all that needs.
unsafe impl<T: Send> Sync for Scatter<'_, T> {}

impl<'a, T: Copy> Scatter<'a, T> {
    pub fn new(slice: &'a mut [T]) -> Scatter<'a, T> {
        Scatter { ptr: slice.as_mut_ptr(), len: slice.len(), _slice: PhantomData }
    }

    /// Asks for the line holding element `i` ahead of a write (see [`prefetch`]).
    #[inline(always)]
    pub fn prefetch(&self, i: usize) {
        prefetch_at(self.ptr, self.len, i);
    }

    /// Writes `value` at `i` (out of range: a panic, never a stray write).
    ///
    /// # Safety
    /// No other `write` through this `Scatter` uses the same `i`.
    #[inline(always)]
    pub unsafe fn write(&self, i: usize, value: T) {
        assert!(i < self.len, "scatter index {i} out of {}", self.len);
        // SAFETY: in bounds, and by the caller's contract no other thread touches element i.
        unsafe { self.ptr.add(i).write(value) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::workload::SplitMix64;

    #[test]
    fn a_kept_order_is_the_order_a_new_sort_makes() {
        // In one part and in several: the body moved within its slots keeps its order with its
        // new positions; one vertex changed slot (or the table changed) sorts it again, from
        // the slots already computed. Either way the result is a new sort's, record for record.
        for (n, slots) in [(20_000, 5_000), (150_000, 1 << 20), (100_000, 3_000)] {
            let slot_of = |p: &Vec3| (SplitMix64::new(p.y as u64).next_u64() % slots as u64) as u32;
            let keys = |p: &[Vec3], k: &mut [u32]| {
                for (p, k) in p.iter().zip(k) {
                    *k = slot_of(p);
                }
            };
            let mut points: Vec<Vec3> = (0..n).map(|i| Vec3::new(0.0, i as f32, 0.0)).collect();
            let mut kept = SortedBody::default();
            assert_eq!(kept.sort_keeping(&points, slots, true, keys), (n as u32, false));
            for (step, same_table, keeps) in
                [(1, true, true), (2, true, false), (3, false, false), (4, true, true)]
            {
                // The slot follows y alone: x moves within it.
                points.iter_mut().for_each(|p| p.x += 0.5);
                if step == 2 {
                    points[n * 2 / 3].y = (n + 7) as f32;
                }
                assert_eq!(kept.sort_keeping(&points, slots, same_table, keys), (n as u32, keeps), "n {n}");
                let mut new = SortedBody::default();
                new.sort(&points, slots, keys);
                assert!(
                    kept.rec == new.rec && kept.start == new.start && kept.key == new.key,
                    "n {n} step {step}"
                );
                assert_eq!(
                    (kept.sorted_at.as_slice(), kept.max_per_slot, kept.shape, kept.in_order),
                    (new.sorted_at.as_slice(), new.max_per_slot, new.shape, new.in_order)
                );
            }
        }
    }

    #[test]
    fn sorts_stably_and_unsorts_back() {
        // One body reused across sizes, as from step to step; some vertices left out; a table
        // of one slot, tables smaller and larger than the body, a pile in three slots, and
        // bodies that come in slot order (whose way back skips the gather).
        #[derive(Clone, Copy, PartialEq)]
        enum Order {
            Random,
            Pile,
            Ascending,
        }
        use Order::{Ascending, Pile, Random};
        let mut body = SortedBody::default();
        for (n, slots, order) in [
            (1, 1, Random),
            (0, 1 << 20, Random),
            (10, 3, Random),
            (40_000, 5_000, Random),
            (100_000, 1 << 20, Random),
            (100_000, 1 << 20, Ascending),
            (70_000, 300_000, Pile),
            (33, 7, Random),
            (50_001, 3_000, Ascending),
            // Sorted in one pass (one part, a table of at most ONE_PASS_SLOTS).
            (20_000, 100_000, Random),
            (5_000, 5_000, Pile),
            (30_000, 1 << 17, Random),
            (30_000, 1 << 17, Ascending),
            // One part, but a table too large for one pass.
            (20_000, (1 << 17) + 1, Random),
            (20_000, (1 << 17) + 1, Ascending),
        ] {
            let points: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
            let slot_of = |p: Vec3| {
                let h = SplitMix64::new(p.x as u64).next_u64();
                match (h % 7, order) {
                    (0, _) => None,
                    (_, Pile) => Some((h % 3) as u32 * 1000),
                    (_, Random) => Some((h % slots as u64) as u32),
                    // Ascending, with neighbours swapped here and there.
                    (_, Ascending) => Some(((p.x as u64 + h % 3) * slots as u64 / (n as u64 + 2)) as u32),
                }
            };
            let sorted = body.sort(&points, slots, |p, k| {
                for (p, k) in p.iter().zip(k) {
                    *k = slot_of(*p).unwrap_or(u32::MAX);
                }
            });
            let mut expected: Vec<(u32, u32)> =
                (0..n).filter_map(|i| slot_of(points[i]).map(|s| (s, i as u32))).collect();
            expected.sort_unstable();
            assert_eq!(sorted as usize, expected.len(), "n {n}");
            if body.shape.1 != 0 {
                // A pile's three slots are in at most three buckets: as good as in order.
                assert_eq!(body.in_order, order != Random, "n {n}: in order");
            }
            assert_eq!(body.start.len(), slots + 1);
            assert_eq!(body.start[slots], sorted);
            for (k, &(s, i)) in expected.iter().enumerate() {
                assert_eq!(body.rec[k].i, i, "n {n} position {k}");
                assert_eq!(body.rec[k].p, points[i as usize]);
                assert!(
                    (body.start[s as usize]..body.start[s as usize + 1]).contains(&(k as u32)),
                    "n {n} slot {s}"
                );
            }
            // Back in the caller's order, marked where the index is a multiple of 3.
            let by_rec: Vec<u32> = body.rec.iter().map(|r| 2 * r.i + 1).collect();
            let (mut out, mut marks, mut scratch) = (vec![7u32; n], vec![u64::MAX; 3], Vec::new());
            body.unsort(&by_rec, &mut scratch, &mut out, &mut marks, |o, v| {
                *o = v.unwrap_or(0);
                v.is_some_and(|v| v % 3 == 1)
            });
            assert_eq!(marks.len(), n.div_ceil(64));
            for (i, &o) in out.iter().enumerate() {
                let inside = slot_of(points[i]).is_some();
                assert_eq!(o, if inside { 2 * i as u32 + 1 } else { 0 }, "n {n} vertex {i}");
                let marked = marks[i / 64] >> (i % 64) & 1 == 1;
                assert_eq!(marked, inside && i % 3 == 0, "n {n} vertex {i}");
            }
            assert!(n % 64 == 0 || marks[n / 64] >> (n % 64) == 0, "n {n}: marks past the end");
        }
    }
}
