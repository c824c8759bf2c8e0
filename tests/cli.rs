//! The `voxcollide` command as a user runs it.

use std::process::Command;

fn voxcollide() -> Command {
    Command::new(env!("CARGO_BIN_EXE_voxcollide"))
}

#[test]
fn run_implant_prints_a_table_and_writes_its_files() {
    let out = std::env::temp_dir().join(format!("voxcollide-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let output = voxcollide()
        .args([
            "run",
            "implant",
            "--backend",
            "cpu",
            "--resolution",
            "8",
            "--steps",
            "40",
            "--frames",
            "2",
            "--no-images",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&output.stderr));
    for line in ["scenario", "backend", "max penetration", "penetrating tissue", "max tissue displacement"] {
        assert!(stdout.contains(line), "no {line:?} in:\n{stdout}");
    }
    assert!(stdout.contains("implant") && stdout.contains("cpu"));
    assert!(out.join("summary.json").is_file() && out.join("tissue.pvd").is_file());
}

#[test]
fn bad_arguments_fail_with_a_clear_message() {
    let output = voxcollide().args(["run", "implant", "--image", "big"]).output().unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("WIDTHxHEIGHT"));

    let output = voxcollide()
        .args(["run", "implant", "--backend", "cpu", "--resolution", "1", "--no-images"])
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("resolution = 1 is invalid"), "{stderr}");

    let output = voxcollide().args(["run", "kidney"]).output().unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("cylinder"));
}
