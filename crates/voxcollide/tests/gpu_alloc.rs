//! What a warm GPU embedding step allocates on the recording thread. `GpuCollision::record`
//! creates no buffer or bind group once warm (tests/embed.rs) and allocates nothing of its own:
//! exactly as many allocations as wgpu alone makes recording the same commands (clears, one pass,
//! one pipeline and bind group per dispatch) into a fresh encoder — wgpu 30 cannot record into
//! an encoder without allocating. Counted per thread, so the driver's worker threads do not blur
//! the count.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use common::gpu;
use voxcollide::glam::Vec4;
use voxcollide::*;

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    // `try_with`: the slot may be gone while the thread shuts down.
    let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
}

fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

// SAFETY: forwards to the system allocator, only counting.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn a_warm_record_allocates_only_what_wgpu_allocates_for_its_commands() {
    let Some(ctx) = gpu() else { return };
    let (device, queue) = (ctx.device(), ctx.queue());
    let w = workload::lattice(20_000, 3).unwrap();
    let upload = |points: &[glam::Vec3]| {
        let data: Vec<Vec4> = points.iter().map(|p| p.extend(1.0)).collect();
        wgpu::util::DeviceExt::create_buffer_init(
            device,
            &wgpu::util::BufferInitDescriptor {
                label: Some("positions"),
                contents: bytemuck::cast_slice(&data),
                usage: wgpu::BufferUsages::STORAGE,
            },
        )
    };
    let (a, b) = (upload(&w.a), upload(&w.b));
    let (n_a, n_b) = (w.a.len() as u32, w.b.len() as u32);
    for anchor in [Anchor::Fixed, Anchor::FollowA] {
        let mut backend = GpuCollision::new(&ctx, w.grid, ContactParams { anchor, ..w.params }).unwrap();
        let mut recorded = Vec::new();
        for step in 0..6 {
            let mut encoder = device.create_command_encoder(&Default::default());
            let before = allocations();
            backend.record(&mut encoder, &a, n_a, &b, n_b).unwrap();
            let during = allocations() - before;
            queue.submit([encoder.finish()]);
            device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
            if step >= 2 {
                recorded.push(during);
            }
        }
        // The same commands recorded with wgpu alone: six buffer clears, one compute pass with
        // one dispatch per pass (thirteen; the bounds pass too under FollowA).
        let dispatches = if anchor == Anchor::FollowA { 14 } else { 13 };
        let bare = bare_recording(device, 6, dispatches);
        eprintln!("{anchor:?}: allocations in record() of warm steps {recorded:?}, by wgpu alone {bare}");
        assert!(recorded.iter().all(|&n| n == recorded[0]), "{anchor:?}: {recorded:?}");
        assert!(recorded[0] <= bare, "{anchor:?}: record() {} > wgpu alone {bare}", recorded[0]);
        assert_eq!(backend.bind_group_builds(), 1);
        assert!(backend.read_report().unwrap().colliding_b.len() > 10_000);
    }
}

/// Allocations on this thread while wgpu alone records `clears` buffer clears and a labelled
/// compute pass of `dispatches` dispatches, each with its own pipeline and bind group, into a
/// fresh encoder (warm: measured on the third of three).
fn bare_recording(device: &wgpu::Device, clears: usize, dispatches: usize) -> usize {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: None,
        source: wgpu::ShaderSource::Wgsl(
            "@group(0) @binding(0) var<storage, read_write> x: array<u32>;
             @compute @workgroup_size(64) fn main(@builtin(global_invocation_id) g: vec3<u32>) {
                 if g.x < arrayLength(&x) { x[g.x] += 1u; }
             }"
            .into(),
        ),
    });
    let pipelines: Vec<wgpu::ComputePipeline> = (0..dispatches)
        .map(|_| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: None,
                layout: None,
                module: &module,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                cache: None,
            })
        })
        .collect();
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 4096,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let bind_groups: Vec<wgpu::BindGroup> = pipelines
        .iter()
        .map(|pipeline| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout: &pipeline.get_bind_group_layout(0),
                entries: &[wgpu::BindGroupEntry { binding: 0, resource: buffer.as_entire_binding() }],
            })
        })
        .collect();
    let mut during = 0;
    for _ in 0..3 {
        let mut encoder = device.create_command_encoder(&Default::default());
        let before = allocations();
        for _ in 0..clears {
            encoder.clear_buffer(&buffer, 0, Some(1024));
        }
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("bare"),
                timestamp_writes: None,
            });
            for (pipeline, bind_group) in pipelines.iter().zip(&bind_groups) {
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, bind_group, &[]);
                pass.dispatch_workgroups(16, 1, 1);
            }
        }
        during = allocations() - before;
        drop(encoder);
    }
    during
}
