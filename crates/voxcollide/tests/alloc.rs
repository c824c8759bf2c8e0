//! `ParallelCpuCollision::step_into` allocates nothing once warm: a counting global allocator
//! sees no allocation during warm steps (this test binary has only this test, so nothing else
//! allocates meanwhile).

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
    for w in [workload::lattice(50_000, 1).unwrap(), workload::paper(50_000, 2).unwrap()] {
        for direction in [Direction::Pairwise, Direction::PlaneNormal] {
            for anchor in [Anchor::Fixed, Anchor::FollowA] {
                let params = ContactParams { direction, anchor, ..w.params };
                let mut backend = ParallelCpuCollision::new(w.grid, params).unwrap();
                let mut report = ContactReport::default();
                backend.step_into(&w.a, &w.b, &mut report).unwrap();
                backend.step_into(&w.a, &w.b, &mut report).unwrap();
                let before = ALLOCATIONS.load(Ordering::SeqCst);
                for _ in 0..3 {
                    backend.step_into(&w.a, &w.b, &mut report).unwrap();
                }
                let during = ALLOCATIONS.load(Ordering::SeqCst) - before;
                assert_eq!(during, 0, "{params:?}: {during} allocations in 3 warm steps");
                assert!(report.colliding_b.len() > 10_000);
            }
        }
    }
}
