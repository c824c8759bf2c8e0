//! The simulation's shaders parse and validate with naga and default capabilities (no GPU
//! needed), and use the collision kernels' workgroup size.

#[path = "../../voxcollide/tests/common/wgsl.rs"]
mod wgsl;

#[test]
fn every_simulation_shader_validates() {
    for (name, source) in voxcollide_sim::gpu::SHADERS {
        wgsl::validate(name, source, &["main"]);
    }
    // The implicit passes: five stems, each pass an entry point of its own.
    for (name, source, entries) in voxcollide_sim::gpu::implicit::IMPLICIT_STEMS {
        wgsl::validate(name, source, entries);
    }
    wgsl::validate("implicit_contact", voxcollide_sim::gpu::implicit::IMPLICIT_CONTACT, &["main"]);
    wgsl::validate("couple", voxcollide_sim::gpu::implicit::COUPLE, &["main"]);
    wgsl::validate("couple_gather", voxcollide_sim::gpu::implicit::COUPLE_GATHER, &["main"]);
    wgsl::validate("couple_impulse", voxcollide_sim::gpu::implicit::COUPLE_IMPULSE, &["main"]);
    wgsl::validate("couple_build", voxcollide_sim::gpu::implicit::COUPLE_BUILD, &["main"]);
    wgsl::validate("couple_lists", voxcollide_sim::gpu::implicit::COUPLE_LISTS, &["count", "scan", "fill"]);
    // The surface contact's search, after the core's common part.
    let search = [voxcollide::gpu::shaders::COMMON, voxcollide_sim::gpu::surface::SURFACE_SEARCH].concat();
    wgsl::validate("surface_search", &search, &["main"]);
    use voxcollide_sim::gpu::surface::{SURFACE_FORCES, SURFACE_FORCES_ENTRIES, SURFACE_GATHER};
    wgsl::validate("surface_forces", SURFACE_FORCES, &SURFACE_FORCES_ENTRIES);
    wgsl::validate("surface_gather", SURFACE_GATHER, &["main"]);
    wgsl::validate("surface_embed", voxcollide_sim::gpu::surface::SURFACE_EMBED, &["main"]);
}

#[test]
fn the_workgroup_size_is_the_kernels_own() {
    let sim = include_str!("../shaders/sim_common.wgsl");
    let line = format!("const WORKGROUP_SIZE: u32 = {}u;", voxcollide::gpu::WORKGROUP_SIZE);
    assert!(sim.contains(&line), "sim_common.wgsl lacks `{line}`");
}
