//! Contacts that hold (DESIGN §11), as a user meets them: a rigid probe driven through 80 % of a
//! block, a stiff soft body pressed into a soft one, a shell filled under tissue lying on it —
//! each checked by the run itself (`summary.json`'s `held`, `bound`, `worst_*`) — and the
//! check seen to fail, with its warning, where the paper's constant response is too weak for
//! the load. A sample of the contact test matrix (`voxcollide matrix`) runs here too.

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use voxcollide_cli::matrix::{Group, run_group, table};
use voxcollide_cli::scenario::Backend;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("voxcollide-contacts-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs `scene` with the command on the CPU; its stdout, stderr and summary.json.
fn run(d: &Path, scene: &str) -> (String, String, serde_json::Value) {
    std::fs::write(d.join("scene.toml"), scene).unwrap();
    let out = d.join("out");
    let output = Command::new(env!("CARGO_BIN_EXE_voxcollide"))
        .args(["run"])
        .arg(d.join("scene.toml"))
        .args(["--backend", "cpu", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let (stdout, stderr) =
        (String::from_utf8_lossy(&output.stdout).into_owned(), String::from_utf8_lossy(&output.stderr).into_owned());
    assert!(output.status.success(), "{stdout}\n{stderr}");
    let summary = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    (stdout, stderr, summary)
}

/// A 10 mm block (3 kPa) held at its base, and a rigid ball driven `depth` mm into it.
fn probe_scene(depth: f64, contact: &str) -> String {
    format!(
        r#"units = "mm"
[time]
duration = 0.3
[[body]]
name = "block"
kind = "soft"
shape = {{ box = [40, 40, 10] }}
spacing = 2.5
material = {{ young_kpa = 3.0, density = 1000.0, damping = 0.5 }}
fixed = [{{ below = {{ z = -4.9 }} }}]
[[body]]
name = "ball"
kind = "rigid"
shape = {{ sphere = 8 }}
spacing = 2.0
position = [0, 0, 13]
motion = [{{ t = 0.0, position = [0, 0, 13] }}, {{ t = 0.25, position = [0, 0, {z}] }}]
[[contact]]
a = "ball"
b = "block"
{contact}
[output]
frames = 3
images = false
vtk = false
"#,
        z = 13.0 - depth
    )
}

fn contact(summary: &serde_json::Value) -> &serde_json::Value {
    &summary["contacts"][0]
}

#[test]
fn a_rigid_probe_driven_through_most_of_a_block_pushes_it_and_does_not_pierce_it() {
    let d = dir("probe");
    // The ball's bottom starts at 5, the block's top; 8 mm down is 80 % of its 10 mm.
    let (stdout, stderr, s) = run(&d, &probe_scene(8.0, ""));
    let c = contact(&s);
    assert_eq!(c["held"], true, "{c}\n{stdout}\n{stderr}");
    assert_eq!(s["held"], true);
    assert!(c["bound"].as_f64().unwrap() > 0.0 && c["checks"].as_u64().unwrap() >= 64, "{c}");
    assert!(c["max_penetration"].as_f64().unwrap() < 0.5 * 2.5, "{c}");
    // The block was pushed, most of the way down.
    let block = &s["bodies"][0];
    assert!(block["max_displacement"].as_f64().unwrap() > 6.0, "{block}");
    assert!(!stderr.contains("warning") && !stdout.contains("warning"), "{stdout}\n{stderr}");
}

#[test]
fn the_papers_constant_response_too_weak_for_the_load_is_caught_and_said() {
    let d = dir("weak");
    // A force of 1 mN a contact cannot hold a block being pressed 8 mm: the ball goes through,
    // and the run says so rather than presenting the numbers.
    let (stdout, stderr, s) = run(&d, &probe_scene(8.0, "response = \"constant\"\nmagnitude = 0.001"));
    let c = contact(&s);
    assert_eq!(c["held"], false, "{c}");
    assert_eq!(s["held"], false);
    let (bound, worst) = (c["bound"].as_f64().unwrap(), c["worst_depth"].as_f64().unwrap());
    assert!(worst > bound, "{c}");
    assert!(c["worst_frame"].is_u64() && c["worst_step"].is_u64() && c["failure"].is_string(), "{c}");
    let said = format!("{stdout}\n{stderr}");
    let warning = said.lines().find(|l| l.contains("warning") && l.contains("ball – block")).unwrap_or_else(|| panic!("{said}"));
    assert!(warning.contains("deep") && warning.contains("bound"), "{warning}");
}

#[test]
fn a_stiff_soft_body_pressed_into_a_soft_one_holds() {
    let d = dir("stiff");
    let scene = r#"units = "mm"
[time]
duration = 0.3
[[body]]
name = "block"
kind = "soft"
shape = { box = [40, 40, 10] }
spacing = 2.5
material = { young_kpa = 3.0, density = 1000.0, damping = 0.5 }
fixed = [{ below = { z = -4.9 } }]
[[body]]
name = "pad"
kind = "soft"
shape = { box = [14, 14, 6] }
spacing = 2.0
position = [0, 0, 8.5]
material = { young_kpa = 300.0, density = 1000.0, damping = 0.5 }
driven = [{ above = { z = 11 } }]
motion = [{ t = 0.0, position = [0, 0, 8.5] }, { t = 0.25, position = [0, 0, 3.5] }]
[[contact]]
a = "pad"
b = "block"
direction = "plane-normal"
[output]
frames = 3
images = false
vtk = false
"#;
    let (stdout, stderr, s) = run(&d, scene);
    let c = contact(&s);
    assert_eq!(c["held"], true, "{c}\n{stdout}\n{stderr}");
    assert!(s["bodies"][0]["max_displacement"].as_f64().unwrap() > 3.0, "{}", s["bodies"][0]);
}

#[test]
fn a_sample_of_the_contact_matrix_passes() {
    // Tissue 10 mm above the chest wall; two volumes on one base. (Gaps of 0 and 2 mm do not
    // pass yet: the implant's vertices pass between the tissue's, which the voxel model does
    // not push, and the matrix says so; see the README's table.)
    let d = dir("matrix");
    let mut cells = Vec::new();
    for gap in [10.0] {
        let g = Group { gap, shell: 30.0, spacing: 6.0, tissue: 3.0 };
        cells.extend(run_group(&g, &[200.0, 400.0], 20000, &d.join(format!("gap{gap}")), Backend::Cpu, &mut |_| {}).unwrap());
    }
    let t = table(&cells);
    eprintln!("{t}");
    for c in &cells {
        assert!(c.failure.is_none(), "{t}");
    }
}
