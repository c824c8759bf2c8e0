//! The shipped scene files `scenes/implant.toml` and `scenes/cylinder.toml` are the paper's two
//! built-in scenes (at their defaults) written as files: their worlds are the same to the bit,
//! and they run the same trajectories, step for step.

use voxcollide::glam::Vec3;
use voxcollide_sim::build::build_world;
use voxcollide_sim::scene_file::SceneFile;
use voxcollide_sim::*;

fn bits(v: &[Vec3]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

#[test]
fn the_shipped_files_are_the_paper_scenes_to_the_bit() {
    for (kind, file) in [(Kind::Implant, "implant.toml"), (Kind::Cylinder, "cylinder.toml")] {
        let scene = Scene::new(SceneConfig::new(kind)).unwrap();
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(file);
        let built = build_world(&SceneFile::read(&path).unwrap()).unwrap();
        assert_eq!((built.dt.to_bits(), built.steps), (scene.dt.to_bits(), scene.config.steps), "{file}");
        let mut paper = CpuWorld::new(scene.world().unwrap()).unwrap();
        let mut shipped = CpuWorld::new(built.world).unwrap();
        for k in 0..2 {
            let (a, b) = (&paper.world.bodies[k], &shipped.world.bodies[k]);
            assert_eq!(bits(&a.pos), bits(&b.pos), "{file}: body {k} positions");
            assert_eq!(a.mode, b.mode, "{file}: body {k} held and driven vertices");
            assert_eq!(a.springs, b.springs, "{file}: body {k} springs");
            assert_eq!(a.material, b.material, "{file}: body {k} material");
            assert_eq!(a.inv_mass, b.inv_mass, "{file}: body {k} masses");
        }
        let (pc, sc) = (paper.world.contacts[0], shipped.world.contacts[0]);
        assert_eq!(
            (pc.params, pc.grid.voxel_size(), pc.grid.center()),
            (sc.params, sc.grid.voxel_size(), sc.grid.center())
        );
        for step in 0..scene.config.steps {
            assert_eq!(
                (paper.world.schedule)(step),
                (shipped.world.schedule)(step),
                "{file}: inputs at step {step}"
            );
        }
        for step in 1..=scene.config.steps {
            paper.step().unwrap();
            shipped.step().unwrap();
            if step % 200 == 0 || step == scene.config.steps {
                for k in 0..2 {
                    assert_eq!(
                        bits(&paper.world.bodies[k].pos),
                        bits(&shipped.world.bodies[k].pos),
                        "{file}: body {k} at step {step}"
                    );
                }
                assert_eq!(paper.reports[0], shipped.reports[0], "{file}: contacts at step {step}");
            }
        }
    }
}

/// Every shipped scene file reads and builds, and every catalogue (`*implants.toml`, and the
/// product lines in `scenes/catalogues/`) reads;
/// the patient and posture scenes recover their unloaded shapes to a hundredth of a spacing.
#[test]
fn every_shipped_scene_builds() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut built = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        if path.file_name().is_some_and(|n| n.to_string_lossy().ends_with("implants.toml")) {
            voxcollide_sim::catalogue::Catalogue::read(&path).unwrap_or_else(|e| panic!("{e}"));
            continue;
        }
        let b = build_world(&SceneFile::read(&path).unwrap())
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        for note in &b.notes {
            if let Some(r) = note.reference {
                assert!(r.residual <= 0.01 * r.spacing + 1e-3, "{}: {r:?}", path.display());
            }
        }
        built += 1;
    }
    assert!(built >= 8, "{built} scenes");
    // The product lines in scenes/catalogues/ read whole.
    let mut lines = 0;
    for entry in std::fs::read_dir(dir.join("catalogues")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let c = voxcollide_sim::catalogue::Catalogue::read(&path).unwrap_or_else(|e| panic!("{e}"));
            assert!(
                c.candidates.iter().all(|k| k.manufacturer.is_some() && k.line.is_some()),
                "{}",
                path.display()
            );
            lines += 1;
        }
    }
    assert!(lines >= 1, "{lines} product lines");
}
