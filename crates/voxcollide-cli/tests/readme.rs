//! The README's two commands stay true: the test command is the one CI runs, and the main job's
//! example exists.

const README: &str = include_str!("../../../README.md");
const CI: &str = include_str!("../../../.ci/run");

/// The commands in the README's `sh` blocks.
fn readme_commands() -> Vec<&'static str> {
    README
        .split("```sh\n")
        .skip(1)
        .filter_map(|block| block.split("```").next())
        .flat_map(str::lines)
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect()
}

#[test]
fn readme_states_two_commands_and_ci_runs_the_test_one() {
    let commands = readme_commands();
    assert_eq!(commands, ["cargo run --release -- run implant", "cargo test --release"], "{commands:?}");
    let ci_lines: Vec<&str> = CI.lines().map(str::trim).collect();
    assert!(ci_lines.contains(&commands[1]), ".ci/run does not run `{}`", commands[1]);
    assert!(CI.contains("export VOXCOLLIDE_REQUIRE_GPU=1"));
    // Both software adapters: lavapipe (Vulkan) above, llvmpipe on GL for the GPU tests.
    assert!(ci_lines.iter().any(|l| l.starts_with("WGPU_BACKEND=gl cargo test --release --test gpu ")));
}

#[test]
fn the_readme_picture_exists() {
    let picture = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/implant.png");
    assert!(picture.is_file(), "{} is missing", picture.display());
    assert!(README.contains("(docs/implant.png)"));
}
