//! The renderer's shader parses and validates with naga and default capabilities (no GPU
//! needed).

#[path = "../../voxcollide/tests/common/wgsl.rs"]
mod wgsl;

#[test]
fn the_render_shader_validates() {
    wgsl::validate("render", voxcollide_render::SHADER, &["vs_main", "fs_main"]);
}

#[test]
fn the_device_paths_shader_validates() {
    wgsl::validate("render_device", voxcollide_render::DEVICE_SHADER, &["vs_device", "fs_main"]);
}
