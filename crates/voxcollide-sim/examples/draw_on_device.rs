//! An app that steps a `GpuWorld` and draws it from the world's own buffers: the positions never
//! come back to the host. `scenes/indentation.toml` (a ball pressed into a block) with the voxel
//! model's penalty, whose explicit step stays on the device; each frame is recorded into the
//! app's own texture, and the run ends by saying how many times a step waited for the device
//! (0) and writing one picture read back for the file.
//!
//! ```text
//! cargo run --release -p voxcollide-sim --example draw_on_device [-- out.png]
//! ```

use std::error::Error;
use std::path::PathBuf;

use voxcollide::GpuContext;
use voxcollide::glam::Vec3;
use voxcollide_render::{DeviceMesh, DeviceView, Legend, Renderer, draw_legend, write_png};
use voxcollide_sim::GpuWorld;
use voxcollide_sim::build::build_world;
use voxcollide_sim::scene_file::SceneFile;

fn main() -> Result<(), Box<dyn Error>> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let out = std::env::args().nth(1).map_or_else(|| root.join("out/draw_on_device.png"), PathBuf::from);
    let path = root.join("scenes/indentation.toml");
    let text =
        std::fs::read_to_string(&path)?.replace("b = \"block\"", "b = \"block\"\nresponse = \"penalty\"");
    let built = build_world(&SceneFile::parse(&path, &text)?)?;
    let ctx = match GpuContext::new() {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("{e}: this example draws on a GPU, and there is none here");
            return Ok(());
        }
    };
    println!("adapter: {}", ctx.adapter_name());
    let start: Vec<Vec<Vec3>> = built.world.bodies.iter().map(|b| b.pos.clone()).collect();
    let mut gpu = GpuWorld::new(&ctx, built.world)?;

    // One mesh per body, bound once to the body's position buffer.
    let (width, height) = (800, 500);
    let mut renderer = Renderer::new(&ctx, width, height)?;
    let colours = [[0.8, 0.6, 0.5], [0.35, 0.45, 0.6]];
    let mut meshes = Vec::new();
    for (k, body) in gpu.world.bodies.iter().enumerate() {
        let positions = gpu.positions(k).expect("a buffer per body");
        let soft = k == 0;
        meshes.push(DeviceMesh::new(
            &mut renderer,
            positions,
            &start[k],
            &body.surface.triangles,
            colours[k % 2],
            soft,
        )?);
    }
    let meshes: Vec<&DeviceMesh> = meshes.iter().collect();
    // Cut through the ball's centre, the far half kept; coloured up to 3 mm of motion (the
    // world's lengths are the file's, millimetres).
    let view = DeviceView {
        scalar_range: (0.0, 3.0),
        clip: Some((Vec3::ZERO, Vec3::Y)),
        view_dir: Vec3::new(0.4, 1.0, -0.5),
        up: Vec3::Z,
        eye: None,
    };

    // The app's own target (a window's surface texture would do as well).
    let format = wgpu::TextureFormat::Rgba8UnormSrgb;
    let target = ctx.device().create_texture(&wgpu::TextureDescriptor {
        label: Some("app target"),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        view_formats: &[],
    });
    let target = target.create_view(&wgpu::TextureViewDescriptor::default());
    let mut frames = 0;
    for step in 1..=built.steps {
        gpu.step()?;
        if step % 50 == 0 {
            let mut encoder = ctx.device().create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
            renderer.draw_device(&mut encoder, &target, format, (width, height), &meshes, &view)?;
            ctx.queue().submit([encoder.finish()]);
            frames += 1;
        }
    }
    println!(
        "{} steps, {frames} frames drawn into the app's texture, {} waits for the device",
        built.steps,
        gpu.host_waits()
    );
    let mut picture = renderer.render_device(&meshes, &view)?;
    draw_legend(&mut picture, width, height, &Legend::new("displacement (mm)", view.scalar_range))?;
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir)?;
    }
    write_png(&out, width, height, &picture)?;
    println!("written: {}", out.display());
    Ok(())
}
