//! `ParallelCpuCollision::step_into` allocates nothing once warm: a counting global allocator
//! sees no allocation during warm steps (this test binary has only this test, so nothing else
//! allocates meanwhile).
//!
//! The steps run on a thread of rayon's pool, as in an app whose simulation runs there. From
//! outside the pool every step hands one job to the pool's global queue, and that queue
//! (crossbeam's `Injector`) allocates a block of 63 slots every 63 jobs: rayon's, not the
//! backend's.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use voxcollide::*;

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator, only counting.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn warm_parallel_steps_allocate_nothing() {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
    // The lattice in a grid roomy enough for a hashed table too (whose probe lists A's shares).
    let mut roomy = workload::lattice(50_000, 3).unwrap();
    roomy.grid = voxcollide::Initializer::new(1.0).margin(20).build(&roomy.a).unwrap();
    for w in [workload::lattice(50_000, 1).unwrap(), workload::paper(50_000, 2).unwrap(), roomy] {
        for direction in [Direction::Pairwise, Direction::PlaneNormal] {
            for anchor in [Anchor::Fixed, Anchor::FollowA] {
                let params = ContactParams { direction, anchor, ..w.params };
                let mut backend = ParallelCpuCollision::new(w.grid, params).unwrap();
                let mut report = ContactReport::default();
                let during = pool.install(|| {
                    backend.step_into(&w.a, &w.b, &mut report).unwrap();
                    backend.step_into(&w.a, &w.b, &mut report).unwrap();
                    let before = ALLOCATIONS.load(Ordering::SeqCst);
                    for _ in 0..5 {
                        backend.step_into(&w.a, &w.b, &mut report).unwrap();
                    }
                    ALLOCATIONS.load(Ordering::SeqCst) - before
                });
                assert_eq!(during, 0, "{params:?}: {during} allocations in 5 warm steps");
                assert!(report.colliding_b.len() > 10_000);
            }
        }
    }
}
