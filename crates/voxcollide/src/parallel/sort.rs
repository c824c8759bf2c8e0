//! A body's vertices sorted by the voxel table's slot, in parallel: a counting sort in a few
//! parts, each with its own counts, so no pass needs an atomic read-modify-write and the order
//! is stable (ascending index within a slot) whatever the thread count.
//!
//! The sort is what makes `ParallelCpuCollision`'s speed independent of the caller's vertex
//! order: every later pass reads the sorted records, whose order depends only on where the
//! vertices are. Only the passes that read a body in and write its forces out touch the
//! caller's order, once each.

use std::marker::PhantomData;
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

use glam::Vec3;
use rayon::prelude::*;

/// A vertex in slot order: its position and its index in the caller's slice.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub(super) struct Rec {
    pub p: Vec3,
    pub i: u32,
}

/// One body sorted by slot. Buffers are reused from step to step.
#[derive(Debug, Default)]
pub(super) struct SortedBody {
    /// Per vertex: its slot (`u32::MAX`: outside the grid or not finite).
    pub key: Vec<u32>,
    /// Per vertex: where it sits in `rec` (`u32::MAX`: not sorted, outside the grid).
    pub k_of: Vec<u32>,
    /// The sorted vertices (those outside the grid are left out).
    pub rec: Vec<Rec>,
    /// Per slot: where its vertices start in `rec` (`slots + 1` entries).
    pub start: Vec<u32>,
    /// `parts × slots` counts, then running offsets (scratch).
    counts: Vec<AtomicU32>,
    /// Per range of slots: its total, then where it starts (scratch).
    totals: Vec<u32>,
}

/// How many parts to count in: one per thread, while the parts' counts stay within about 16
/// words per vertex (a hashed table has up to 8 slots a vertex), and one for small bodies,
/// where the threads would cost more than they save.
fn parts(n: usize, slots: usize) -> usize {
    if n < 32_768 {
        return 1;
    }
    (16 * n / slots.max(1)).clamp(1, rayon::current_num_threads())
}

/// Items per parallel task for `n` items: every thread gets several tasks.
pub(super) fn chunk(n: usize) -> usize {
    (n / (8 * rayon::current_num_threads())).clamp(1024, 16_384)
}

impl SortedBody {
    /// Sorts `points` by `slot_of` (`None`: left out) into `slots` slots. Returns how many
    /// were sorted.
    pub fn sort(
        &mut self,
        points: &[Vec3],
        slots: usize,
        slot_of: impl Fn(Vec3) -> Option<u32> + Sync,
    ) -> u32 {
        let n = points.len();
        let parts = parts(n, slots);
        let part = n.div_ceil(parts);
        self.key.resize(n, u32::MAX);
        self.k_of.resize(n, u32::MAX);
        if self.counts.len() < parts * slots {
            self.counts.resize_with(parts * slots, || AtomicU32::new(0));
        }
        let counts = &self.counts[..parts * slots];

        // 1. Each part's keys and counts (the counts are zero: see the end of 3).
        let sorted: usize = self
            .key
            .par_chunks_mut(part)
            .zip(points.par_chunks(part))
            .enumerate()
            .map(|(p, (keys, points))| {
                let counts = &counts[p * slots..(p + 1) * slots];
                let mut sorted = 0;
                for (key, &q) in keys.iter_mut().zip(points) {
                    *key = match slot_of(q) {
                        Some(s) => {
                            let c = &counts[s as usize];
                            c.store(c.load(Relaxed) + 1, Relaxed);
                            sorted += 1;
                            s
                        }
                        None => u32::MAX,
                    };
                }
                sorted
            })
            .sum();

        // 2. Exclusive prefix sum in (slot, part) order: a range's total, the ranges' running
        //    sum, then each range's offsets.
        self.start.resize(slots + 1, 0);
        let range = chunk(slots).max(4096);
        let ranges = slots.div_ceil(range);
        self.totals.resize(ranges, 0);
        self.totals.par_iter_mut().enumerate().for_each(|(r, t)| {
            let (lo, hi) = (r * range, ((r + 1) * range).min(slots));
            *t = (0..parts)
                .map(|p| counts[p * slots + lo..p * slots + hi].iter().map(|c| c.load(Relaxed)).sum::<u32>())
                .sum();
        });
        let mut running = 0u32;
        for t in &mut self.totals {
            let c = *t;
            *t = running;
            running += c;
        }
        self.start[..slots].par_chunks_mut(range).zip(self.totals.par_iter()).enumerate().for_each(
            |(r, (start, &base))| {
                let mut running = base;
                for (j, st) in start.iter_mut().enumerate() {
                    let s = r * range + j;
                    *st = running;
                    for p in 0..parts {
                        let c = &counts[p * slots + s];
                        let n = c.load(Relaxed);
                        c.store(running, Relaxed);
                        running += n;
                    }
                }
            },
        );
        self.start[slots] = sorted as u32;

        // 3. Each part places its vertices in order (stable), reading them in the caller's order
        //    and writing each record once; then the counts go back to zero.
        self.rec.resize(sorted, Rec::default());
        let rec = Scatter::new(&mut self.rec);
        self.k_of.par_chunks_mut(part).zip(self.key.par_chunks(part)).enumerate().for_each(
            |(p, (k_of, keys))| {
                let counts = &counts[p * slots..(p + 1) * slots];
                let first = p * part;
                for (j, (k, &s)) in k_of.iter_mut().zip(keys).enumerate() {
                    if s == u32::MAX {
                        *k = u32::MAX;
                        continue;
                    }
                    let c = &counts[s as usize];
                    let at = c.load(Relaxed);
                    c.store(at + 1, Relaxed);
                    let i = first + j;
                    // SAFETY: after step 2, part p's cursor of slot s starts at its own range of
                    // `rec`, as long as p's count of s; the ranges of all (slot, part) pairs tile
                    // 0..sorted without overlap, and each cursor moves once per vertex of p in s,
                    // which step 1 counted from the same keys. So every `at` is written once.
                    unsafe { rec.write(at as usize, Rec { p: points[i], i: i as u32 }) };
                    *k = at;
                }
            },
        );
        // Back to zero for the next step (a pass over the counts, sequential in memory).
        counts.par_chunks(range).for_each(|c| c.iter().for_each(|c| c.store(0, Relaxed)));
        sorted as u32
    }
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
