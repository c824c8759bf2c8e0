//! The `voxcollide` command as a user runs it.

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod common;
mod sheets;

use std::process::Command;

fn voxcollide() -> Command {
    Command::new(env!("CARGO_BIN_EXE_voxcollide"))
}

/// `run implant` on `backend`, small (a resolution of 8, 40 steps, 2 frames, no pictures),
/// writing to `out`.
fn small_implant(backend: &str, out: &std::path::Path) -> std::process::Output {
    voxcollide()
        .args(["run", "implant", "--backend", backend, "--resolution", "8", "--steps", "40", "--frames", "2"])
        .args(["--no-images", "--out"])
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn run_implant_prints_a_table_and_writes_its_files() {
    let out = std::env::temp_dir().join(format!("voxcollide-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let output = small_implant("cpu", &out);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&output.stderr));
    for line in ["scenario", "backend", "max penetration", "penetrating tissue", "max tissue displacement"] {
        assert!(stdout.contains(line), "no {line:?} in:\n{stdout}");
    }
    assert!(stdout.contains("implant") && stdout.contains("cpu"));
    assert!(out.join("summary.json").is_file() && out.join("tissue.pvd").is_file());
}

#[test]
fn without_an_adapter_the_main_job_runs_on_the_cpu_and_says_why() {
    // No adapter matches the name asked for: `--backend auto` (the default) falls back to the
    // CPU, says so while running, and names the reason in the table and in summary.json.
    let out = std::env::temp_dir().join(format!("voxcollide-noadapter-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let output = voxcollide()
        .args(["run", "implant", "--resolution", "8", "--steps", "30", "--frames", "1", "--out"])
        .arg(&out)
        .env("WGPU_ADAPTER_NAME", "no-such-adapter")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stdout}\n{stderr}");
    assert!(stdout.contains("cpu (no GPU adapter: ") && stdout.contains("no-such-adapter"), "{stdout}");
    assert!(format!("{stdout}{stderr}").contains("running on the CPU"), "{stdout}\n{stderr}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert!(summary["adapter"].as_str().unwrap().contains("no-such-adapter"), "{summary}");
    assert!(!out.join("implant_0000.png").exists());
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

#[test]
fn bench_prints_every_backend_and_writes_json() {
    let json = std::env::temp_dir().join(format!("voxcollide-bench-{}.json", std::process::id()));
    let output = voxcollide()
        .args(["bench", "--sizes", "2k", "--samples", "1", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&output.stderr));
    for backend in ["kdtree_kiddo", "cpu_reference", "parallel_cpu"] {
        assert!(stdout.contains(backend), "no {backend} in:\n{stdout}");
    }
    // Where a GPU is required (CI), its rows are there too, and counted with the others below.
    if common::gpu_required() {
        for backend in ["gpu_step", "gpu_resident"] {
            assert!(stdout.contains(backend), "no {backend} in:\n{stdout}");
        }
        // And the resident step in the order of B its adapter does not use by default.
        assert!(
            stdout.contains("gpu_resident_b_as_given") || stdout.contains("gpu_resident_b_sorted"),
            "no resident step in the other order in:\n{stdout}"
        );
    }
    let rows: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = rows.as_array().unwrap();
    assert!(rows.len() >= 6, "{rows:?}");
    // Every backend finds the same contacts as the reference on the same workload.
    for workload in ["lattice", "z_fastest", "shuffled", "paper", "paper_shuffled"] {
        let counts: Vec<u64> = rows
            .iter()
            .filter(|r| r["workload"] == workload && r["backend"] != "kdtree_kiddo")
            .map(|r| r["colliding"].as_u64().unwrap())
            .collect();
        assert!(counts.windows(2).all(|w| w[0] == w[1]) && counts[0] > 1000, "{workload}: {counts:?}");
    }
    let lattice_kdtree =
        rows.iter().find(|r| r["workload"] == "lattice" && r["backend"] == "kdtree_kiddo").unwrap();
    let lattice_ref =
        rows.iter().find(|r| r["workload"] == "lattice" && r["backend"] == "cpu_reference").unwrap();
    assert_eq!(
        lattice_kdtree["colliding"], lattice_ref["colliding"],
        "the baseline answers the same question"
    );
    // Every order of the lattice finds the same contacts, and the paper's baseline is its own.
    let count = |w: &str, b: &str| {
        rows.iter().find(|r| r["workload"] == w && r["backend"] == b).map(|r| r["colliding"].clone())
    };
    for w in ["z_fastest", "shuffled"] {
        assert_eq!(count(w, "parallel_cpu"), count("lattice", "parallel_cpu"), "{w}");
    }
    assert_eq!(count("paper", "voxel_hashmap"), count("paper", "cpu_reference"));
    assert_eq!(count("paper_shuffled", "voxel_hashmap"), count("paper", "cpu_reference"));
    assert!(rows.iter().all(|r| r["speedup_vs_baseline"].as_f64().is_some_and(|s| s > 0.0)));
    // The backends take turns, one step each: each ratio's spread step by step, the baseline's
    // against itself exactly 1.
    for r in rows.iter() {
        let spread: Vec<f64> =
            r["speedup_spread"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        assert!(spread.len() == 2 && spread[0] > 0.0 && spread[0] <= spread[1], "{r}");
        if r["backend"] == r["baseline"] {
            assert_eq!(spread, [1.0, 1.0], "{r}");
        }
    }

    let output = voxcollide().args(["bench", "--sizes", "0"]).output().unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("is not a size"));
}

#[test]
fn bench_sizes_beyond_the_machine_are_clear_errors_before_allocating() {
    for (sizes, says) in [
        ("99999999999999M", "too large a size"),
        ("5000M", "at most 4294967294 vertices"),
        ("1000M", "GiB available"),
        ("10k,1000M", "GiB available"),
    ] {
        let output = voxcollide().args(["bench", "--sizes", sizes, "--samples", "1"]).output().unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(
            output.status.code(),
            Some(if says == "too large a size" { 2 } else { 1 }),
            "{sizes}: {stderr}"
        );
        assert!(stderr.contains(says), "{sizes}: {stderr}");
        assert!(!stderr.contains("panicked") && !stderr.contains("memory allocation"), "{sizes}: {stderr}");
    }
}

#[test]
fn bench_times_every_gpu_pass_when_asked() {
    // Where the adapter has timestamp queries (lavapipe does): a line of pass times under each
    // gpu_resident row, and the same in the JSON; nothing of it without --passes.
    let Some(ctx) = common::gpu() else { return };
    if !ctx.device().features().contains(voxcollide::wgpu::Features::TIMESTAMP_QUERY) {
        return;
    }
    let json = std::env::temp_dir().join(format!("voxcollide-passes-{}.json", std::process::id()));
    let output = voxcollide()
        .args(["bench", "--sizes", "20k", "--samples", "2", "--no-reference", "--passes", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&output.stderr));
    assert_eq!(
        stdout.matches("passes, ms: bounds").count(),
        voxcollide_cli::bench::WORKLOADS.len(),
        "{stdout}"
    );
    let rows: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for row in rows.as_array().unwrap() {
        let passes = row.get("passes");
        if row["backend"] == "gpu_resident" {
            let passes = passes.and_then(|p| p.as_array()).expect("passes on gpu_resident");
            let names: Vec<&str> = passes.iter().map(|p| p["pass"].as_str().unwrap()).collect();
            assert_eq!(names, voxcollide::gpu::PASSES);
            let probe = passes.iter().find(|p| p["pass"] == "probe").unwrap()["median_ms"].as_f64().unwrap();
            assert!(probe > 0.0, "the probe was not timed: {row}");
        } else {
            assert!(passes.is_none(), "{row}");
        }
    }
}

#[test]
fn run_a_scene_file_writes_every_body_and_the_design_keys() {
    let scenes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let out = std::env::temp_dir().join(format!("voxcollide-cli-file-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let output =
        voxcollide().arg("run").arg(scenes.join("expander.toml")).arg("--out").arg(&out).output().unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stdout}\n{stderr}");
    assert!(!stderr.to_lowercase().contains("error"), "{stderr}");
    for line in ["body skin (soft)", "body expander (shell)", "contact expander – skin", "simulated s per s"]
    {
        assert!(stdout.contains(line), "no {line:?} in:\n{stdout}");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    for key in ["bodies", "contacts", "settled", "simulated_time", "steps", "dt", "files", "units"] {
        assert!(json.get(key).is_some(), "summary.json lacks {key}");
    }
    let bodies = json["bodies"].as_array().unwrap();
    assert_eq!(bodies.len(), 2);
    for b in bodies {
        for key in ["name", "kind", "vertices", "max_displacement"] {
            assert!(b.get(key).is_some(), "a body lacks {key}: {b}");
        }
    }
    assert!(bodies[0]["max_displacement"].as_f64().unwrap() > 0.5, "the skin was lifted: {}", bodies[0]);
    let contact = &json["contacts"][0];
    for key in ["a", "b", "max_penetration", "penetrating_fraction", "contacts_at_end"] {
        assert!(contact.get(key).is_some(), "the contact lacks {key}: {contact}");
    }
    assert_eq!((contact["a"].as_str(), contact["b"].as_str()), (Some("expander"), Some("skin")));
    // A VTK series per body, every frame (4 after the first) of each; pictures with every body
    // where there is an adapter.
    for body in ["skin", "expander"] {
        assert!(out.join(format!("{body}.pvd")).is_file());
        assert!(out.join(format!("{body}_0004.vtp")).is_file());
    }
    if common::gpu_required() {
        assert!(out.join("expander_0004.png").is_file());
    }
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn a_bad_scene_file_is_named_and_nothing_is_written() {
    let dir = std::env::temp_dir().join(format!("voxcollide-cli-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cases = [
        (
            "typo.toml",
            "[[body]]\nname = \"t\"\nkind = \"soft\"\nshape = { box = [1, 1, 1] }\nspacng = 0.5\n",
            "typo.toml:5:1: body[0].spacng",
        ),
        (
            "mesh.toml",
            "[[body]]\nname = \"t\"\nkind = \"soft\"\nmesh = \"nope.stl\"\nspacing = 1\n",
            "body[0].mesh",
        ),
        (
            "contact.toml",
            "[[body]]\nname = \"t\"\nkind = \"soft\"\nshape = { box = [1, 1, 1] }\nspacing = 0.5\n[[contact]]\na = \"x\"\nb = \"t\"\n",
            "no body is named \"x\"",
        ),
    ];
    for (name, text, says) in cases {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        let out = dir.join(format!("out-{name}"));
        let output = voxcollide().arg("run").arg(&path).arg("--out").arg(&out).output().unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{name}");
        assert!(stderr.contains(says), "{name}: {stderr}");
        assert!(!out.exists(), "{name}: something was written");
    }
    let output = voxcollide().args(["run", "no-such-scene"]).output().unwrap();
    assert!(String::from_utf8_lossy(&output.stderr).contains("neither a paper scenario"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An ASCII STL of a UV sphere of `radius` (rings × segments), outward.
fn sphere_stl(radius: f32, rings: u32, segments: u32) -> (String, usize) {
    let pi = std::f32::consts::PI;
    let at = |r: u32, s: u32| {
        let (t, p) = (pi * r as f32 / rings as f32, 2.0 * pi * (s % segments) as f32 / segments as f32);
        match r {
            0 => [0.0, 0.0, radius],
            r if r == rings => [0.0, 0.0, -radius],
            _ => [radius * t.sin() * p.cos(), radius * t.sin() * p.sin(), radius * t.cos()],
        }
    };
    let mut out = String::from("solid sphere\n");
    let mut facet = |a: [f32; 3], b: [f32; 3], c: [f32; 3]| {
        out += "facet normal 0 0 0\nouter loop\n";
        for v in [a, b, c] {
            out += &format!("vertex {:e} {:e} {:e}\n", v[0], v[1], v[2]);
        }
        out += "endloop\nendfacet\n";
    };
    for r in 0..rings {
        for s in 0..segments {
            let (a, b, c, d) = (at(r, s), at(r + 1, s), at(r + 1, s + 1), at(r, s + 1));
            if r > 0 {
                facet(a, b, d);
            }
            if r + 1 < rings {
                facet(b, c, d);
            }
        }
    }
    out += "endsolid sphere\n";
    (out, 2 + (rings as usize - 1) * segments as usize)
}

#[test]
fn a_soft_body_from_the_users_stl_is_shown_and_written_by_its_own_surface() {
    let dir = std::env::temp_dir().join(format!("voxcollide-cli-stl-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (stl, vertices) = sphere_stl(10.0, 12, 24);
    std::fs::write(dir.join("organ.stl"), stl).unwrap();
    std::fs::write(
        dir.join("scene.toml"),
        r#"
[time]
steps = 600
[[body]]
name = "organ"
kind = "soft"
mesh = "organ.stl"
spacing = 2
fixed = [{ below = { z = -8 } }]
[[body]]
name = "probe"
kind = "rigid"
shape = { sphere = 3 }
spacing = 1.5
position = [0, 0, 16]
motion = [{ t = 0.0, position = [0, 0, 16] }, { t = 0.05, position = [0, 0, 12] }]
[[contact]]
a = "probe"
b = "organ"
[output]
frames = 2
"#,
    )
    .unwrap();
    let out = dir.join("out");
    let output = voxcollide().arg("run").arg(dir.join("scene.toml")).arg("--out").arg(&out).output().unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    // The organ's VTK frames carry the user's sphere (its own vertices), not the lattice.
    let vtp = std::fs::read_to_string(out.join("organ_0002.vtp")).unwrap();
    assert!(vtp.contains(&format!("NumberOfPoints=\"{vertices}\"")), "{}", &vtp[..300.min(vtp.len())]);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let organ = &json["bodies"][0];
    assert!(organ["coverage"].as_f64().unwrap() > 0.5, "{organ}");
    assert!(organ["vertices"].as_u64().unwrap() > 200, "{organ}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn settling_goes_on_past_the_schedule_until_the_bodies_rest() {
    // The shipped indentation (a ball held 3 mm into a block, settle = true) comes to rest, and
    // says by how much it moved over its last frame; the same scene without settling stops at
    // its schedule, and with a cap of one frame past it is reported unsettled.
    let scenes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    // Under the explicit integrator, whose rest is judged by motion over a window.
    let text = std::fs::read_to_string(scenes.join("indentation.toml"))
        .unwrap()
        .replace("max_steps = 8000", "max_steps = 8000\nintegrator = \"explicit\"");
    let dir = std::env::temp_dir().join(format!("voxcollide-cli-settle-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let run = |name: &str, text: &str| {
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(
            &path,
            text.replace("[output]\nframes = 8", "[output]\nframes = 8\nimages = false\nvtk = false"),
        )
        .unwrap();
        let out = dir.join(name);
        let output = voxcollide()
            .args(["run", "--backend", "cpu"])
            .arg(&path)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        (json, String::from_utf8_lossy(&output.stdout).into_owned())
    };
    let (settled, stdout) = run("settled", &text);
    assert!(stdout.contains("settled                      true"), "{stdout}");
    assert_eq!(settled["settled"], serde_json::Value::Bool(true));
    let motion = settled["rest_motion"].as_f64().unwrap();
    assert!(motion > 0.0 && motion <= 0.05, "{motion}");
    let (plain, _) = run("plain", &text.replace("settle = true", "settle = false"));
    let schedule = (0.4 / plain["dt"].as_f64().unwrap()).ceil() as u64;
    assert_eq!((plain["settled"].as_bool(), plain["steps"].as_u64()), (Some(false), Some(schedule)));
    let steps = settled["steps"].as_u64().unwrap();
    assert!(steps >= schedule, "{steps} of {schedule}");
    // Capped before a settling window has passed since the schedule: unsettled, and said so.
    let (capped, _) = run(
        "capped",
        &text.replace("duration = 0.4", "duration = 0.05").replace("max_steps = 8000", "max_steps = 500"),
    );
    assert_eq!(capped["settled"].as_bool(), Some(false), "{capped}");
    assert!(capped["rest_window"].as_f64().unwrap() > 0.01, "{capped}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_gpu_run_counts_the_times_a_step_waits_for_the_device() {
    // docs/design.md §5: `host_waits_per_step` in a `--backend gpu` run's summary.json. The
    // explicit step with the voxel model's contacts stays on the device (0), and so does the
    // surface contact, between bodies that show their own surface or with a lattice made from a
    // surface; the implicit solve reads its scalars about once a step, with either contact. A
    // CPU run has no such key.
    let Some(_) = common::gpu() else { return };
    let dir = std::env::temp_dir().join(format!("voxcollide-waits-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let scene = |response: &str, integrator: &str| {
        format!(
            "units = \"mm\"\n[time]\nsteps = 30\nintegrator = \"{integrator}\"\n[[body]]\nname = \"block\"\nkind = \"soft\"\nshape = {{ box = [20, 20, 6] }}\nspacing = 2.5\nmaterial = {{ young_kpa = 3.0, density = 1000.0, damping = 0.5 }}\nfixed = [{{ below = {{ z = -2.9 }} }}]\n[[body]]\nname = \"ball\"\nkind = \"rigid\"\nshape = {{ sphere = 4 }}\nspacing = 2.0\nposition = [0, 0, 7.5]\nmotion = [{{ t = 0.0, position = [0, 0, 7.5] }}, {{ t = 0.02, position = [0, 0, 6] }}]\n[[contact]]\na = \"ball\"\nb = \"block\"\nresponse = \"{response}\"\n[output]\nframes = 3\nimages = false\nvtk = false\n"
        )
    };
    let waits = |name: &str, text: String, backend: &str| -> Option<f64> {
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(&path, text).unwrap();
        let out = dir.join(name);
        let output = voxcollide()
            .arg("run")
            .arg(&path)
            .args(["--backend", backend, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        assert!(output.status.success(), "{name}: {}", String::from_utf8_lossy(&output.stderr));
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        assert_eq!(s["steps"].as_u64(), Some(30), "{name}: {s}");
        s.get("host_waits_per_step").map(|w| w.as_f64().unwrap())
    };
    assert_eq!(waits("penalty", scene("penalty", "explicit"), "gpu"), Some(0.0), "the voxel model's step");
    assert_eq!(waits("surface", scene("surface", "explicit"), "gpu"), Some(0.0), "the surface contact's");
    // Under --backend auto a software adapter (lavapipe in CI) leaves the surface contact to
    // the CPU, which is faster there; the voxel model's steps on the adapter.
    let software = common::gpu().is_some_and(|ctx| {
        ctx.adapter_info().is_some_and(|i| i.device_type == voxcollide::wgpu::DeviceType::Cpu)
    });
    let on = |name: &str| {
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join(name).join("summary.json")).unwrap())
                .unwrap();
        s["backend"].as_str().unwrap().to_string()
    };
    waits("auto-surface", scene("surface", "explicit"), "auto");
    waits("auto-penalty", scene("penalty", "explicit"), "auto");
    let expected = if software { "cpu" } else { "gpu" };
    assert_eq!((on("auto-surface").as_str(), on("auto-penalty").as_str()), (expected, "gpu"));
    // A lattice made from a surface (a soft ball under the rigid one): the device writes the
    // surface it carries each step and searches it there (until 2026-12-07 the host searched
    // it, over the positions read back once a step).
    let carried = scene("surface", "explicit")
        .replace("shape = { box = [20, 20, 6] }", "shape = { sphere = 8 }\nposition = [0, 0, -5]")
        .replace("below = { z = -2.9 }", "below = { z = -11 }");
    assert!(carried.contains("sphere = 8"), "{carried}");
    assert_eq!(waits("carried", carried.clone(), "gpu"), Some(0.0), "a carried surface's contact");
    let implicit = waits("carried-implicit", carried.replace("\"explicit\"", "\"implicit\""), "gpu").unwrap();
    assert!((1.0..1.5).contains(&implicit), "the implicit step of a carried surface's contact: {implicit}");
    // The implicit solve reads its scalars, with its farthest move, about once a step (the
    // first readback after as many iterations as the last solve took).
    let implicit = waits("implicit", scene("penalty", "implicit"), "gpu").unwrap();
    assert!((1.0..1.5).contains(&implicit), "the implicit solve reads its scalars: {implicit}");
    // With the surface contact, too: its search and couplings stay on the device.
    let implicit = waits("implicit-surface", scene("surface", "implicit"), "gpu").unwrap();
    assert!((1.0..1.5).contains(&implicit), "the implicit surface contact's step: {implicit}");
    assert_eq!(
        waits("cpu", scene("penalty", "explicit"), "cpu"),
        None,
        "a CPU run has no device to wait for"
    );
    // The paper's scene, stepped on the device, waits for nothing.
    let out = dir.join("paper");
    let output = small_implant("gpu", &out);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["host_waits_per_step"].as_f64(), Some(0.0), "{s}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `scenes/posture.toml` (docs/gravity.md), small: a breast-like mound given as scanned
/// standing, run lying and standing (docs/design.md §13). `summary.json` says how well its
/// unloaded shape was recovered; lying it moves, standing it stays where it was given; a
/// recovery held to one iteration misses, and the run says it is not a result.
#[test]
fn a_body_scanned_standing_is_recovered_and_run_in_a_posture() {
    let scene =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/posture.toml")).unwrap();
    let scene = scene.replace("spacing = 6", "spacing = 9").replace("frames = 4", "frames = 2");
    let dir = std::env::temp_dir().join(format!("voxcollide-posture-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let run = |name: &str, text: &str| {
        let file = dir.join(format!("{name}.toml"));
        std::fs::write(&file, text).unwrap();
        let out = dir.join(name);
        let output = voxcollide()
            .args(["run"])
            .arg(&file)
            .args(["--backend", "cpu", "--out"])
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        assert!(output.status.success(), "{}\n{stderr}", String::from_utf8_lossy(&output.stdout));
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        (summary, stderr)
    };
    let standing =
        scene.replace("gravity = [0, 0, -9.81]         # lying on her back", "gravity = [0, -9.81, 0]");
    let (lying, said) = run("lying", &scene);
    let (stood, _) = run("standing", &standing);
    for s in [&lying, &stood] {
        let body = &s["bodies"][0];
        let r = &body["reference"];
        assert!(r["iterations"].as_u64().unwrap() >= 1, "{r}");
        assert!(r["residual"].as_f64().unwrap() <= 0.01 * r["spacing"].as_f64().unwrap() + 1e-3, "{r}");
        assert_eq!(r["valid"], true);
        assert_eq!(s["not_a_result"].as_array().unwrap().len(), 0, "{s}");
        assert_eq!(s["settled"], true, "{s}");
    }
    assert!(said.contains("its unloaded shape, recovered"), "{said}");
    // The body as it ends, for any mesh viewer: a closed surface, where it came to rest.
    let (end, report) =
        voxcollide_sim::mesh_io::read_surface(&dir.join("lying").join("breast_end.ply")).unwrap();
    assert!(report.volume > 0.0 && !end.mesh.triangles.is_empty());
    assert!(lying["files"].as_array().unwrap().iter().any(|f| f == "breast_end.ply"), "{lying}");
    let moved = |s: &serde_json::Value| s["bodies"][0]["max_displacement"].as_f64().unwrap();
    assert!(moved(&lying) > 2.0, "lying, it moved {} mm", moved(&lying));
    assert!(moved(&stood) < 0.05, "standing, it moved {} mm from where it was scanned", moved(&stood));
    // A reference gravity far beyond what the tissue holds: the recovery misses (or the shape
    // folds, an error naming the key), and either way no result is shown as one.
    let heavy =
        scene.replace("reference = { gravity = [0, -9.81, 0] }", "reference = { gravity = [0, -300, 0] }");
    let file = dir.join("heavy.toml");
    std::fs::write(&file, &heavy).unwrap();
    let out = dir.join("heavy");
    let output =
        voxcollide().args(["run"]).arg(&file).args(["--backend", "cpu", "--out"]).arg(&out).output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    if output.status.success() {
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        assert_eq!(s["bodies"][0]["reference"]["valid"], false, "{s}");
        assert!(s["not_a_result"][0].as_str().unwrap().contains("breast"), "{s}");
        assert!(stderr.contains("not a result"), "{stderr}");
    } else {
        assert!(stderr.contains("heavy.toml") && stderr.contains("reference"), "{stderr}");
        assert!(!out.exists(), "a run that fails to set up writes nothing");
    }
}

/// A breast between a skin sheet and a chest wall (docs/design.md §14), standing (gravity
/// along −x, the patient's feet): `summary.json` gives its tissue's volume at the start and at
/// the end (the same, to a percent, at ν = 0.45) and its nipple, moved onto the skin and carried
/// down by its weight.
#[test]
fn a_breast_between_its_skin_and_chest_wall_reports_its_landmarks_and_volume() {
    let dir = std::env::temp_dir().join(format!("voxcollide-between-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let skin = |x: f32, y: f32| {
        let r = (x * x + y * y).sqrt() / 60.0;
        15.0 + if r < 1.0 { 40.0 * (0.5 + 0.5 * (std::f32::consts::PI * r).cos()) } else { 0.0 }
    };
    std::fs::write(dir.join("skin.stl"), sheets::sheet_stl(120.0, 48, skin)).unwrap();
    std::fs::write(dir.join("wall.stl"), sheets::sheet_stl(120.0, 4, |_, _| 0.0)).unwrap();
    let scene = r#"
units = "mm"
[time]
duration = 0.5
settle = true
integrator = "implicit"
max_steps = 3000
[world]
gravity = [-9.81, 0, 0]
up = "x"
[[body]]
name = "breast"
kind = "soft"
shape = { between = { outer = "skin.stl", inner = "wall.stl", min = [-90, -90, -10], max = [90, 90, 70] } }
spacing = 9
material = { model = "neo-hookean", young_kpa = 3, poisson = 0.45, density = 1000, damping = 0.5 }
landmarks = { nipple = [0, 0, 55] }
[output]
frames = 2
images = false
vtk = false
"#;
    std::fs::write(dir.join("standing.toml"), scene).unwrap();
    let out = dir.join("out");
    let output = voxcollide()
        .args(["run"])
        .arg(dir.join("standing.toml"))
        .args(["--backend", "cpu", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&output.stderr));
    assert!(stdout.contains("landmark breast.nipple"), "{stdout}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["settled"], true, "{s}");
    let body = &s["bodies"][0];
    let (start, end) = (body["volume_ml"].as_f64().unwrap(), body["volume_ml_end"].as_f64().unwrap());
    // The region holds 620.5 mL (the mound on its 15 mm layer, over the box).
    assert!((start / 620.5 - 1.0).abs() < 0.05, "{start} mL");
    assert!((end / start - 1.0).abs() < 0.01, "{start} mL became {end} mL");
    let l = &s["landmarks"][0];
    assert_eq!((l["body"].as_str(), l["name"].as_str()), (Some("breast"), Some("nipple")));
    let (p, q) = (&l["start"], &l["end"]);
    let get = |v: &serde_json::Value, k: usize| v[k].as_f64().unwrap();
    // On the skin's lattice, under the apex; standing, it comes down (−x) by millimetres.
    assert!(get(p, 0).abs() < 5.0 && get(p, 1).abs() < 5.0 && get(p, 2) > 40.0, "{l}");
    assert!(get(q, 0) < get(p, 0) - 1.0, "the nipple did not come down: {l}");
}
