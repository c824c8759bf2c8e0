//! The paper's scenarios end to end at a small resolution, on the CPU and on the GPU: the
//! quality bar of the issue (penetration, deformation, finiteness), the files written, and the
//! errors for bad set-ups and blow-ups.

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod common;

use std::path::PathBuf;

use voxcollide::Error;
use voxcollide::glam::Vec3;
use voxcollide_cli::backend::Backend;
use voxcollide_cli::scenario::{RunConfig, Summary, run};
use voxcollide_sim::{CpuWorld, Kind, Scene, SceneConfig};

fn out_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("voxcollide-test-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn small(kind: Kind, backend: Backend, name: &str) -> RunConfig {
    RunConfig {
        scene: SceneConfig { resolution: 12, steps: 600, ..SceneConfig::new(kind) },
        backend,
        out: out_dir(name),
        frames: 10,
        image: None,
        vtk: false,
    }
}

/// The bar, frame by frame after contact is established (the first 10 % of the run).
fn assert_quality(s: &Summary) {
    for f in s.frames.iter().filter(|f| f.step > s.steps / 10) {
        assert!(
            f.max_penetration <= s.voxel_size,
            "{}: frame {} penetrates {} > voxel {}",
            s.scenario,
            f.frame,
            f.max_penetration,
            s.voxel_size
        );
        assert!(
            f.penetrating_fraction <= 0.01,
            "{}: frame {}: {} % penetrate",
            s.scenario,
            f.frame,
            100.0 * f.penetrating_fraction
        );
        assert!(f.max_tissue_displacement.is_finite() && f.max_foreign_displacement.is_finite());
    }
    assert!(
        s.max_tissue_displacement >= 0.2 * s.layer_thickness,
        "{}: tissue moved {} < 20 % of {}",
        s.scenario,
        s.max_tissue_displacement,
        s.layer_thickness
    );
    assert!(s.frames.iter().any(|f| f.colliding > 0), "{}: never in contact", s.scenario);
}

#[test]
fn both_scenarios_meet_the_quality_bar_on_the_cpu() {
    for kind in [Kind::Cylinder, Kind::Implant] {
        let s = run(&small(kind, Backend::Cpu, &format!("cpu-{}", kind.name())), &mut |_| {}, &mut |_| {})
            .unwrap();
        assert_eq!(s.backend, "cpu");
        assert_quality(&s);
    }
}

#[test]
fn both_scenarios_meet_the_quality_bar_on_the_gpu() {
    if common::gpu().is_none() {
        return;
    }
    for kind in [Kind::Cylinder, Kind::Implant] {
        let s = run(&small(kind, Backend::Gpu, &format!("gpu-{}", kind.name())), &mut |_| {}, &mut |_| {})
            .unwrap();
        assert_eq!(s.backend, "gpu");
        assert_quality(&s);
    }
}

#[test]
fn the_implant_shell_is_deformed_by_the_layer_it_lifts() {
    // The same shell inflated with and without the tissue on top: the load flattens it.
    let config = SceneConfig { resolution: 12, steps: 600, ..SceneConfig::new(Kind::Implant) };
    let mut loaded = CpuWorld::new(Scene::new(config).unwrap().world().unwrap()).unwrap();
    let mut free = Scene::new(config).unwrap();
    let mut f = Vec::new();
    for step in 0..config.steps {
        loaded.step().unwrap();
        let (_, inputs) = free.inputs(step);
        let zero = vec![Vec3::ZERO; free.foreign.len()];
        free.foreign.forces(&inputs, &zero, &mut f);
        free.foreign.integrate(&inputs, &f.clone());
    }
    let top = |pos: &[Vec3]| pos.iter().map(|p| p.z).fold(f32::MIN, f32::max);
    let loaded_foreign = &loaded.world.bodies[1];
    let (top_loaded, top_free) = (top(&loaded_foreign.pos), top(&free.foreign.pos));
    let rise = top_free - free.foreign.rest_pos.iter().map(|p| p.z).fold(f32::MIN, f32::max);
    assert!(rise > 0.3, "the free shell rose only {rise}");
    let deviation =
        loaded_foreign.pos.iter().zip(&free.foreign.pos).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
    eprintln!("rise {rise}, loaded top {top_loaded}, free top {top_free}, largest deviation {deviation}");
    assert!(
        top_loaded < top_free,
        "loaded top {top_loaded} vs free {top_free}: the layer did not push the shell down"
    );
    assert!(
        deviation > 0.05 * rise,
        "the shell's shape differs by at most {deviation} from its free inflation (rise {rise})"
    );
}

#[test]
fn a_run_writes_pictures_paraview_files_and_a_summary() {
    let mut config = small(Kind::Implant, Backend::Auto, "files");
    config.scene.steps = 60;
    config.frames = 2;
    config.vtk = true;
    config.image = Some((160, 100));
    let mut notes = Vec::new();
    let s = run(&config, &mut |_| {}, &mut |line| notes.push(line.to_string())).unwrap();
    assert!(notes.iter().any(|n| n.contains("implant on the")), "{notes:?}");
    let dir = &config.out;
    for f in [
        "tissue_0000.vtp",
        "tissue_0002.vtp",
        "implant_0001.vtp",
        "tissue.pvd",
        "implant.pvd",
        "summary.json",
    ] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    let pvd = std::fs::read_to_string(dir.join("tissue.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 3);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    for key in [
        "scenario",
        "backend",
        "adapter",
        "steps",
        "vertices_a",
        "vertices_b",
        "steps_per_second",
        "max_penetration",
        "penetrating_fraction",
        "max_tissue_displacement",
        "layer_thickness",
        "voxel_size",
        "frames",
        // docs/design.md §8's keys, added to these.
        "bodies",
        "contacts",
        "settled",
        "simulated_time",
    ] {
        assert!(json.get(key).is_some(), "summary.json lacks {key}");
    }
    assert_eq!(json["frames"].as_array().unwrap().len(), 3);
    assert_eq!(json["bodies"][0]["name"], "tissue");
    assert_eq!(json["bodies"][1]["kind"], "shell");
    assert_eq!(
        (json["contacts"][0]["a"].as_str(), json["contacts"][0]["b"].as_str()),
        (Some("implant"), Some("tissue"))
    );
    assert!(json["simulated_time"].as_f64().unwrap() > 0.0);
    assert_eq!(json["frames"][2]["step"], 60);
    // Pictures need an adapter; where one is required (CI), the run must have used it.
    if common::gpu_required() {
        assert_eq!(s.backend, "gpu", "VOXCOLLIDE_REQUIRE_GPU=1 but the run fell back to the CPU");
    }
    if s.backend == "gpu" {
        let png = std::fs::File::open(dir.join("implant_0002.png")).unwrap();
        let reader = png::Decoder::new(std::io::BufReader::new(png)).read_info().unwrap();
        assert_eq!((reader.info().width, reader.info().height), (160, 100));
    }
}

#[test]
fn bad_set_ups_are_typed_errors() {
    let base = small(Kind::Cylinder, Backend::Cpu, "bad");
    let cases: Vec<(RunConfig, &str)> = vec![
        (RunConfig { frames: 0, ..base.clone() }, "frames"),
        (RunConfig { scene: SceneConfig { resolution: 2, ..base.scene }, ..base.clone() }, "resolution"),
        (RunConfig { scene: SceneConfig { steps: 0, ..base.scene }, ..base.clone() }, "steps"),
        (RunConfig { scene: SceneConfig { stiffness: f32::NAN, ..base.scene }, ..base.clone() }, "stiffness"),
        (RunConfig { scene: SceneConfig { pressure: -1.0, ..base.scene }, ..base.clone() }, "pressure"),
    ];
    for (config, what) in cases {
        let err = run(&config, &mut |_| {}, &mut |_| {}).unwrap_err();
        assert!(matches!(&err, Error::Invalid { what: w, .. } if *w == what), "{what}: {err:?}");
    }
    let err = run(
        &RunConfig { scene: SceneConfig { voxel_size: Some(0.3), ..base.scene }, ..base.clone() },
        &mut |_| {},
        &mut |_| {},
    )
    .unwrap_err();
    assert!(matches!(err, Error::VoxelSize { .. }), "{err:?}");
    let err = run(
        &RunConfig { scene: SceneConfig { magnitude: Some(f32::INFINITY), ..base.scene }, ..base },
        &mut |_| {},
        &mut |_| {},
    )
    .unwrap_err();
    assert!(matches!(err, Error::Magnitude { .. }), "{err:?}");
}

#[test]
fn a_blow_up_stops_the_run_naming_the_step() {
    // A penalty force a million times too large flings the first touching vertices away.
    for backend in [Backend::Cpu, Backend::Gpu] {
        if backend == Backend::Gpu && common::gpu().is_none() {
            continue;
        }
        let mut config = small(Kind::Cylinder, backend, "blowup");
        config.scene.magnitude = Some(1e9);
        let err = run(&config, &mut |_| {}, &mut |_| {}).unwrap_err();
        let Error::Simulation { step, message } = &err else { panic!("{backend:?}: {err:?}") };
        assert!(*step > 0 && *step <= 600, "{step}");
        assert!(message.contains("likely cause"), "{message}");
        let summary = config.out.join("summary.json");
        assert!(!summary.exists(), "a blown-up run must not leave a summary of NaN");
    }
}

#[test]
fn at_their_defaults_the_paper_scenes_run_their_shipped_files() {
    // `run implant` and `run cylinder` at their defaults follow scenes/implant.toml and
    // scenes/cylinder.toml, and give the built-in generator's figures to the bit (100 steps of
    // the 1200-step schedule here: the same world, so the same frames); other options run the
    // built-in generator and say so by leaving `scene_file` out.
    for kind in [Kind::Implant, Kind::Cylinder] {
        let config = RunConfig {
            scene: SceneConfig::new(kind),
            backend: Backend::Cpu,
            out: out_dir(&format!("shipped-{}", kind.name())),
            frames: 12,
            image: None,
            vtk: false,
        };
        let mut notes = Vec::new();
        let mut steps = 0;
        let shipped = run(&config, &mut |done| steps = done, &mut |n| notes.push(n.to_string())).unwrap();
        let path = format!("scenes/{}.toml", kind.name());
        assert_eq!(shipped.scene_file.as_deref(), Some(path.as_str()));
        assert!(notes.iter().any(|n| n.contains(&format!("the shipped {path}"))), "{notes:?}");
        // The built-in generator stepped alongside: the same tissue at every frame's step.
        let mut builtin = CpuWorld::new(Scene::new(config.scene).unwrap().world().unwrap()).unwrap();
        let mut done = 0;
        for f in &shipped.frames {
            while done < f.step {
                builtin.step().unwrap();
                done += 1;
            }
            let tissue = &builtin.world.bodies[0];
            let moved =
                tissue.pos.iter().zip(&tissue.rest_pos).map(|(p, r)| p.distance(*r)).fold(0.0, f32::max);
            assert_eq!(
                moved.to_bits(),
                f.max_tissue_displacement.to_bits(),
                "{} frame {}",
                kind.name(),
                f.frame
            );
            assert_eq!(
                builtin.reports[0].colliding_b.len(),
                f.colliding,
                "{} frame {}",
                kind.name(),
                f.frame
            );
        }
        let other = RunConfig { scene: SceneConfig { steps: 100, ..config.scene }, ..config.clone() };
        let s = run(&other, &mut |_| {}, &mut |_| {}).unwrap();
        assert_eq!(s.scene_file, None);
        std::fs::remove_dir_all(&config.out).unwrap();
    }
}
