//! The simulation: the CPU and GPU backends follow the same trajectory over the first steps,
//! and bad set-ups and blow-ups are errors.

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod common;

use voxcollide::glam::Vec3;
use voxcollide_sim::*;

fn same_bits(a: &[Vec3], b: &[Vec3]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(x, y)| x.to_array().map(f32::to_bits) == y.to_array().map(f32::to_bits))
}

fn max_diff(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (*x - *y).abs().max_element()).fold(0.0, f32::max)
}

#[test]
fn gpu_and_cpu_trajectories_agree_over_the_first_steps() {
    let Some(ctx) = common::gpu() else { return };
    let exact = ctx.adapter_name().contains("llvmpipe");
    for kind in [Kind::Cylinder, Kind::Implant] {
        let config = SceneConfig { resolution: 10, steps: 200, ..SceneConfig::new(kind) };
        let scene = Scene::new(config).unwrap();
        let mut cpu = CpuWorld::new(scene.world().unwrap()).unwrap();
        let mut gpu = GpuWorld::new(&ctx, scene.world().unwrap()).unwrap();
        let mut contacts = 0;
        for step in 1..=120 {
            cpu.step().unwrap();
            gpu.step().unwrap();
            if step % 20 == 0 {
                let report = gpu.sync().unwrap().swap_remove(0);
                // The paper's two bodies: the tissue (0) and the foreign body (1).
                let ([c_tissue, c_foreign], [g_tissue, g_foreign]) =
                    (&cpu.world.bodies[..], &gpu.world.bodies[..])
                else {
                    panic!("a paper scene has two bodies")
                };
                contacts += cpu.reports[0].colliding_b.len();
                let dt = max_diff(&c_tissue.pos, &g_tissue.pos);
                let df = max_diff(&c_foreign.pos, &g_foreign.pos);
                eprintln!(
                    "{kind:?} step {step}: tissue {dt:e} foreign {df:e} contacts cpu {} gpu {}",
                    cpu.reports[0].colliding_b.len(),
                    report.colliding_b.len()
                );
                if exact {
                    // Bit-identical on llvmpipe (Vulkan and GL): the README says so.
                    assert!(
                        same_bits(&c_tissue.pos, &g_tissue.pos)
                            && same_bits(&c_foreign.pos, &g_foreign.pos)
                            && same_bits(&c_tissue.vel, &g_tissue.vel),
                        "{kind:?} step {step}: trajectories differ by {dt:e} / {df:e}"
                    );
                    assert_eq!(cpu.reports[0], report, "{kind:?} step {step}: contact reports");
                } else {
                    // Elsewhere fused multiply-adds may round differently: a small drift.
                    assert!(
                        dt <= 1e-3 && df <= 1e-3,
                        "{kind:?} step {step}: trajectories differ by {dt:e} / {df:e}"
                    );
                }
            }
        }
        assert!(contacts > 0, "{kind:?}: the bodies never touched in the compared steps");
    }
}
