//! Every composed shader module parses and validates with naga and default capabilities — no
//! GPU needed, so a shader error shows on any machine.

#[path = "common/wgsl.rs"]
mod wgsl;

use voxcollide::gpu::shaders::SHADERS;

#[test]
fn every_shader_parses_and_validates_with_default_capabilities() {
    for (name, source) in SHADERS {
        wgsl::validate(name, source, &["main"]);
    }
}

#[test]
fn every_pass_starts_from_the_shared_definitions() {
    let common = include_str!("../shaders/common.wgsl");
    let scan_common = include_str!("../shaders/scan_common.wgsl");
    for (name, source) in SHADERS {
        assert!(source.starts_with(common), "{name} is not composed from common.wgsl");
        let mut rest = &source[common.len()..];
        if name.starts_with("scan") && name != "scan_add" {
            assert!(rest.starts_with(scan_common), "{name} is not composed from scan_common.wgsl");
            rest = &rest[scan_common.len()..];
        }
        let path = format!("{}/shaders/{name}.wgsl", env!("CARGO_MANIFEST_DIR"));
        let own = std::fs::read_to_string(&path).unwrap();
        assert_eq!(rest, own, "{path}");
    }
}

#[test]
fn the_workgroup_size_is_the_same_in_rust_and_wgsl() {
    let common = include_str!("../shaders/common.wgsl");
    let line = format!("const WORKGROUP_SIZE: u32 = {}u;", voxcollide::gpu::WORKGROUP_SIZE);
    assert!(common.contains(&line), "common.wgsl lacks `{line}`");
}
