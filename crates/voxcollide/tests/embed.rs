//! The embedding API: an app's own device, buffers and encoder; and the device-side failures
//! (a device with too small limits, a lost device) come back as errors.

mod common;

use common::{all_params, bodies, compare, gpu};
use voxcollide::glam::{Vec3, Vec4};
use voxcollide::wgpu;
use voxcollide::*;

/// A device the way an app makes one: its own instance, the default adapter, `limits`.
fn app_device(limits: wgpu::Limits) -> Option<(wgpu::Device, wgpu::Queue)> {
    gpu()?; // skips (or fails under VOXCOLLIDE_REQUIRE_GPU=1) when there is no adapter at all
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapter =
        pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default())).unwrap();
    let desc = wgpu::DeviceDescriptor { label: Some("app"), required_limits: limits, ..Default::default() };
    Some(pollster::block_on(adapter.request_device(&desc)).unwrap())
}

fn positions(points: &[Vec3]) -> Vec<Vec4> {
    points.iter().map(|p| p.extend(1.0)).collect()
}

fn app_buffer(device: &wgpu::Device, label: &str, len: usize, usage: wgpu::BufferUsages) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: 16 * len as u64,
        usage,
        mapped_at_creation: false,
    })
}

/// Reads `n` vec4s from `buffer` the way an app would: a copy into its own mappable buffer.
fn app_read(device: &wgpu::Device, queue: &wgpu::Queue, buffer: &wgpu::Buffer, n: usize) -> Vec<Vec4> {
    let staging =
        app_buffer(device, "app staging", n, wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, 16 * n as u64);
    queue.submit([encoder.finish()]);
    staging.slice(..).map_async(wgpu::MapMode::Read, |r| r.unwrap());
    device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let out = bytemuck::pod_collect_to_vec(&staging.slice(..).get_mapped_range().unwrap());
    staging.unmap();
    out
}

#[test]
fn app_device_buffers_and_encoder_drive_the_passes() {
    let Some((device, queue)) = app_device(wgpu::Limits::default()) else { return };
    let (a, mut b, voxel, grid) = bodies(31, 20_000);
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST;
    let a_buf = app_buffer(&device, "app A", a.len(), usage);
    let b_buf = app_buffer(&device, "app B", b.len(), usage);
    queue.write_buffer(&a_buf, 0, bytemuck::cast_slice(&positions(&a)));

    let ctx = GpuContext::from_device(device.clone(), queue.clone());
    for params in all_params(2.0, 0.9 * voxel) {
        let mut gpu = GpuCollision::new(&ctx, grid, params).unwrap();
        let mut cpu = CpuCollision::new(grid, params).unwrap();
        for frame in 0..4 {
            // The app moves B a little each frame.
            b.iter_mut().for_each(|p| *p += Vec3::new(0.01, -0.02, 0.015) * voxel);
            queue.write_buffer(&b_buf, 0, bytemuck::cast_slice(&positions(&b)));
            let mut encoder =
                device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("app frame") });
            gpu.record(&mut encoder, &a_buf, a.len() as u32, &b_buf, b.len() as u32).unwrap();
            queue.submit([encoder.finish()]);

            let expected = cpu.step(&a, &b).unwrap();
            let report = gpu.read_report().unwrap();
            compare(&format!("frame {frame} {params:?}"), &expected, &report, 1e-5 * 2.0);
            // The forces stay on the device where the app can bind them: B's w flags the contacts.
            if frame == 3 {
                let force_b = app_read(&device, &queue, gpu.force_b_buffer().unwrap(), b.len());
                let flagged: Vec<u32> =
                    (0..b.len() as u32).filter(|&j| force_b[j as usize].w == 1.0).collect();
                assert_eq!(flagged, expected.colliding_b);
                let force_a = app_read(&device, &queue, gpu.force_a_buffer().unwrap(), a.len());
                assert_eq!(force_a.iter().map(|f| f.truncate()).collect::<Vec<_>>(), report.force_a);
            }
        }
        // Same buffers, same sizes: the bind groups were built once.
        assert_eq!(gpu.bind_group_builds(), 1, "{params:?}");
    }
}

#[test]
fn app_buffers_that_cannot_hold_or_bind_the_counts_are_errors() {
    let Some((device, _queue)) = app_device(wgpu::Limits::default()) else { return };
    let grid = Initializer::new(1.0).build(&[Vec3::ZERO]).unwrap();
    let ctx = GpuContext::from_device(device.clone(), _queue);
    let mut gpu = GpuCollision::new(&ctx, grid, all_params(1.0, 1.0)[0]).unwrap();
    let storage = app_buffer(&device, "ok", 100, wgpu::BufferUsages::STORAGE);
    let vertex_only = app_buffer(&device, "vertex", 100, wgpu::BufferUsages::VERTEX);
    let mut encoder = device.create_command_encoder(&Default::default());

    let err = gpu.record(&mut encoder, &storage, 101, &storage, 10).unwrap_err();
    assert_eq!(err, Error::BufferTooSmall { body: Body::A, len: 101, size: 1600, needed: 1616 });
    assert!(err.to_string().contains("1600 bytes"), "{err}");
    let err = gpu.record(&mut encoder, &storage, 10, &vertex_only, 10).unwrap_err();
    assert_eq!(err, Error::BufferUsage { body: Body::B });
    assert!(err.to_string().contains("STORAGE"), "{err}");
    assert_eq!(
        gpu.record(&mut encoder, &storage, 0, &storage, 10).unwrap_err(),
        Error::EmptyBody { body: Body::A }
    );
    let err = gpu.record(&mut encoder, &storage, 10, &storage, u32::MAX).unwrap_err();
    assert!(matches!(err, Error::DeviceLimit { body: Body::B, .. }), "{err:?}");
    // read_report before any step is an error too, not a panic.
    assert!(matches!(gpu.read_report().unwrap_err(), Error::Gpu { .. }));
}

#[test]
fn a_device_whose_limits_are_too_small_is_a_gpu_error() {
    // The probe pass binds eight storage buffers; a device that allows four rejects the
    // pipeline, and the validation error is caught and returned.
    let limits =
        wgpu::Limits { max_storage_buffers_per_shader_stage: 4, ..wgpu::Limits::downlevel_defaults() };
    let Some((device, queue)) = app_device(limits) else { return };
    let grid = Initializer::new(1.0).build(&[Vec3::ZERO]).unwrap();
    let err = GpuCollision::new(&GpuContext::from_device(device, queue), grid, all_params(1.0, 1.0)[0])
        .unwrap_err();
    assert!(matches!(err, Error::Gpu { .. }), "{err:?}");
    assert!(err.to_string().to_lowercase().contains("storage"), "{err}");
}

#[test]
fn a_readback_beyond_the_largest_buffer_is_a_device_limit() {
    // A device whose largest buffer is its binding size (1 MiB): each body fits its binding
    // (A up to 32768 vertices, B up to 65536), but both at once cannot be read back through one
    // buffer, 16 bytes a vertex of each. That is DeviceLimit naming max_buffer_size, before
    // anything is submitted; sizes that fit step as usual.
    let mib = 1 << 20;
    let limits = wgpu::Limits {
        max_buffer_size: mib,
        max_storage_buffer_binding_size: mib,
        ..wgpu::Limits::default()
    };
    let Some((device, queue)) = app_device(limits) else { return };
    let ctx = GpuContext::from_device(device, queue);
    let a: Vec<Vec3> =
        (0..32_768).map(|i| Vec3::new((i % 32) as f32, (i / 32 % 32) as f32, (i / 1024) as f32)).collect();
    let grid = Initializer::new(1.0).margin(1).build(&a).unwrap();
    let params = all_params(1.0, 1.0)[0];
    let mut gpu = GpuCollision::new(&ctx, grid, params).unwrap();
    assert_eq!((gpu.max_vertices_of(Body::A), gpu.max_vertices_of(Body::B)), (32_768, 65_536));
    let b = vec![Vec3::splat(0.25); 40_000];
    let err = gpu.step(&a, &b).unwrap_err();
    let max = (mib as usize - 96) / 16 - a.len();
    assert_eq!(
        err,
        Error::DeviceLimit {
            body: Body::B,
            len: 40_000,
            max,
            limit: "max_buffer_size",
            bytes: mib,
            per_vertex: 16
        }
    );
    let report = gpu.step(&a, &b[..max]).unwrap();
    assert_eq!(report.colliding_b.len(), max);
}

#[test]
fn a_lost_device_is_an_error() {
    let Some(ctx) = gpu() else { return };
    let (a, b, voxel, grid) = bodies(41, 1000);
    let mut gpu = GpuCollision::new(&ctx, grid, all_params(1.0, voxel)[0]).unwrap();
    gpu.step(&a, &b).unwrap();
    ctx.device().destroy();
    let err = gpu.step(&a, &b).unwrap_err();
    assert!(matches!(err, Error::DeviceLost { .. } | Error::Gpu { .. }), "{err:?}");
    eprintln!("after destroy: {err}");
}

#[test]
fn an_app_device_wrapped_with_its_adapter_reports_the_adapter_and_steps() {
    if gpu().is_none() {
        return;
    }
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapter =
        pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default())).unwrap();
    let desc = wgpu::DeviceDescriptor { label: Some("app"), ..Default::default() };
    let (device, queue) = pollster::block_on(adapter.request_device(&desc)).unwrap();
    let info = adapter.get_info();
    let ctx = GpuContext::from_adapter(&adapter, device.clone(), queue.clone());
    assert_eq!(ctx.adapter_info().map(|i| (&i.name, i.device_type)), Some((&info.name, info.device_type)));
    assert_eq!(ctx.downlevel_flags(), Some(adapter.get_downlevel_capabilities().flags));
    assert!(ctx.adapter_name().contains(&info.name), "{}", ctx.adapter_name());
    // Without the adapter, the same device says only that it is the app's.
    let bare = GpuContext::from_device(device, queue);
    assert_eq!((bare.adapter_info(), bare.downlevel_flags()), (None, None));
    assert_eq!(bare.adapter_name(), "app-provided device");
    let (a, b, voxel, grid) = bodies(43, 2000);
    let params = all_params(1.0, voxel)[0];
    let report = GpuCollision::new(&ctx, grid, params).unwrap().step(&a, &b).unwrap();
    assert_eq!(report, CpuCollision::new(grid, params).unwrap().step(&a, &b).unwrap());
}
