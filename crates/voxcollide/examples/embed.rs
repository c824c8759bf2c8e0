//! An app that owns its wgpu device and buffers embeds voxcollide: each frame it records the
//! collision passes into its own encoder, then its own compute pass that moves body B (a ball)
//! down onto body A (a plate) and pushes it back by the contact force — with no readback until it
//! chooses to look. Each ball vertex moves on its own (a soft ball, no springs), so the ball
//! settles onto the plate and spreads: the contact count grows while no vertex sinks in.
//!
//! Run: `cargo run --release --example embed`

use voxcollide::glam::{Vec3, Vec4};
use voxcollide::wgpu::{self, util::DeviceExt};
use voxcollide::{Anchor, ContactParams, Direction, GpuCollision, GpuContext, Initializer, Search};

/// The app's own pass: `pos_b += velocity + force_b * gain` (w of `motion` is the gain).
const MOVE_B: &str = r"
@group(0) @binding(0) var<storage, read_write> pos_b: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read> force_b: array<vec4<f32>>;
@group(0) @binding(2) var<uniform> motion: vec4<f32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let j = gid.x;
    if j >= arrayLength(&pos_b) {
        return;
    }
    pos_b[j] = vec4<f32>(pos_b[j].xyz + motion.xyz + force_b[j].xyz * motion.w, 1.0);
}
";

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The app's device, made the app's way.
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let Ok(adapter) = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
    else {
        println!(
            "no GPU adapter (install Mesa's lavapipe: apt-get install mesa-vulkan-drivers); nothing to embed into"
        );
        return Ok(());
    };
    let info = adapter.get_info();
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor::default()))?;
    println!("app device: {} ({:?})", info.name, info.backend);

    // Body A: a plate 10 × 10 × 0.5; body B: a ball of radius 1 above it.
    let h = 0.125;
    let plate: Vec<Vec4> = (0..80 * 80 * 5)
        .map(|i| Vec4::new((i % 80) as f32 * h, (i / 80 % 80) as f32 * h, -((i / 6400) as f32) * h, 1.0))
        .collect();
    let ball: Vec<Vec4> =
        fibonacci_sphere(2000).map(|p| (p + Vec3::new(5.0, 5.0, 1.3)).extend(1.0)).collect();
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST;
    let init = |label, contents: &[Vec4]| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::cast_slice(contents),
            usage,
        })
    };
    let (a_buf, b_buf) = (init("plate", &plate), init("ball", &ball));

    // voxcollide on the app's device, over the plate's top half.
    let a3: Vec<Vec3> = plate.iter().map(|p| p.truncate()).collect();
    let grid = Initializer::new(h).margin(2).contact_half(Vec3::Z).build(&a3)?;
    let params = ContactParams {
        magnitude: 1.0,
        search: Search::Neighbours { radius: h },
        direction: Direction::Pairwise,
        anchor: Anchor::Fixed,
    };
    let mut collision =
        GpuCollision::new(&GpuContext::from_device(device.clone(), queue.clone()), grid, params)?;
    let (n_a, n_b) = (plate.len() as u32, ball.len() as u32);

    // The app's move pass, bound to voxcollide's force buffer (it exists after the first record).
    let motion = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("motion"),
        contents: bytemuck::bytes_of(&Vec4::new(0.0, 0.0, -0.01, 0.02)),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("move B"),
        source: wgpu::ShaderSource::Wgsl(MOVE_B.into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("move B"),
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let mut move_b: Option<wgpu::BindGroup> = None;

    for frame in 1..=150 {
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") });
        collision.record(&mut encoder, &a_buf, n_a, &b_buf, n_b)?;
        let bind = move_b.get_or_insert_with(|| {
            let force_b = collision.force_b_buffer().expect("recorded");
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("move B"),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: b_buf.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: force_b.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: motion.as_entire_binding() },
                ],
            })
        });
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &*bind, &[]);
            pass.dispatch_workgroups(n_b.div_ceil(64), 1, 1);
        }
        queue.submit([encoder.finish()]);
        if frame % 30 == 0 {
            // The app looks now and then; every other frame stays on the device.
            let report = collision.read_report()?;
            println!("frame {frame:3}: {:4} ball vertices in contact", report.colliding_b.len());
        }
    }
    let report = collision.read_report()?;
    println!("\nlast frame:\n{report}");
    println!("bind groups built: {} (for 150 frames)", collision.bind_group_builds());
    Ok(())
}

/// `n` points spread evenly on the unit sphere.
fn fibonacci_sphere(n: usize) -> impl Iterator<Item = Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n).map(move |i| {
        let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
        let r = (1.0 - z * z).sqrt();
        let t = golden * i as f32;
        Vec3::new(r * t.cos(), r * t.sin(), z)
    })
}
