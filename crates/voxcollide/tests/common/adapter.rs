//! The adapter for a GPU test: a context, or a skip saying so — unless
//! `VOXCOLLIDE_REQUIRE_GPU=1` (CI), when a missing adapter fails the test. Shared by the tests of
//! every crate of the workspace (the others include this file by path).
#![allow(dead_code)]

use voxcollide::GpuContext;

/// A GPU context, or `None` with "skipped: no adapter" — unless `VOXCOLLIDE_REQUIRE_GPU=1`, when
/// a missing adapter fails the test.
pub fn gpu() -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(ctx) => Some(ctx),
        Err(e) if gpu_required() => {
            panic!("VOXCOLLIDE_REQUIRE_GPU=1 but there is no adapter: {e}")
        }
        Err(e) => {
            eprintln!("skipped: no adapter ({e})");
            None
        }
    }
}

/// Whether GPU checks must run (`VOXCOLLIDE_REQUIRE_GPU=1`, as CI sets it) rather than skip.
pub fn gpu_required() -> bool {
    std::env::var("VOXCOLLIDE_REQUIRE_GPU").as_deref() == Ok("1")
}
