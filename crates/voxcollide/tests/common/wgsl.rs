//! WGSL validation with naga and default capabilities, no GPU needed. Shared by the tests of
//! every crate of the workspace that has shaders (the others include this file by path).
#![allow(dead_code)]

/// Parses and validates `source` and checks that it has the `entries`; panics naming `name`.
pub fn validate(name: &str, source: &str, entries: &[&str]) {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("{name}.wgsl: {}", e.emit_to_string(source)));
    let mut validator = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    );
    if let Err(e) = validator.validate(&module) {
        panic!("{name}.wgsl does not validate: {}", e.emit_to_string(source));
    }
    for entry in entries {
        assert!(module.entry_points.iter().any(|e| e.name == *entry), "{name}.wgsl has no `{entry}`");
    }
}
