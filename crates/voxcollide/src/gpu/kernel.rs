//! A compute kernel: one WGSL pass with its explicit bind-group layout and pipeline, built once
//! from `&Device`, and its dispatch over any number of items.
//!
//! The collision's passes are built from it, and so are other crates' passes that run beside
//! them on the same device (the simulator's `forces` and `integrate`). A kernel's shader has one
//! bind group of storage or uniform buffers, an entry point (`main`, or one named) with
//! `@workgroup_size(64)` ([`super::WORKGROUP_SIZE`]), and finds its item as
//! `gid.x + gid.y * num_workgroups.x * 64`, so that [`Kernel::dispatch`] can cover more than
//! `65535 * 64` items in rows.

use wgpu::{
    BindGroup, BindGroupLayout, BindingType, Buffer, BufferBindingType, ComputePass, ComputePipeline, Device,
    ShaderStages,
};

use super::WORKGROUP_SIZE;

/// What a binding of a kernel holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slot {
    /// A uniform buffer (`var<uniform>`).
    Uniform,
    /// A read-only storage buffer (`var<storage, read>`).
    Read,
    /// A read-write storage buffer (`var<storage, read_write>`).
    ReadWrite,
}

/// One compute pass's immutable GPU state: its bind-group layout and pipeline.
#[derive(Debug)]
pub struct Kernel {
    label: &'static str,
    layout: BindGroupLayout,
    pipeline: ComputePipeline,
}

impl Kernel {
    /// Builds the pass of WGSL `source` (entry point `main`) whose bindings `0..` hold `slots`,
    /// all visible to the compute stage. Wrap it in [`scoped`](super::scoped) to turn a shader
    /// the device rejects into an error.
    #[must_use]
    pub fn new(device: &Device, label: &'static str, source: &str, slots: &[Slot]) -> Kernel {
        Kernel::with_constants(device, label, source, slots, &[])
    }

    /// As [`new`](Self::new), with values for the shader's pipeline-overridable constants.
    #[must_use]
    pub fn with_constants(
        device: &Device,
        label: &'static str,
        source: &str,
        slots: &[Slot],
        constants: &[(&str, f64)],
    ) -> Kernel {
        Kernel::build(device, label, source, slots, "main", constants)
    }

    /// As [`new`](Self::new), for the entry point `entry` of a source that holds several passes
    /// (each with the kernel's workgroup size and item indexing).
    #[must_use]
    pub fn entry(device: &Device, label: &'static str, source: &str, slots: &[Slot], entry: &str) -> Kernel {
        Kernel::build(device, label, source, slots, entry, &[])
    }

    fn build(
        device: &Device,
        label: &'static str,
        source: &str,
        slots: &[Slot],
        entry: &str,
        constants: &[(&str, f64)],
    ) -> Kernel {
        let entries: Vec<wgpu::BindGroupLayoutEntry> = slots
            .iter()
            .enumerate()
            .map(|(i, slot)| wgpu::BindGroupLayoutEntry {
                binding: i as u32,
                visibility: ShaderStages::COMPUTE,
                ty: BindingType::Buffer {
                    ty: match slot {
                        Slot::Uniform => BufferBindingType::Uniform,
                        Slot::Read => BufferBindingType::Storage { read_only: true },
                        Slot::ReadWrite => BufferBindingType::Storage { read_only: false },
                    },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            })
            .collect();
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some(entry),
            compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
            cache: None,
        });
        Kernel { label, layout, pipeline }
    }

    /// A bind group of `buffers`, in binding order (whole buffers).
    pub fn bind(&self, device: &Device, buffers: &[&Buffer]) -> BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(self.label),
            layout: &self.layout,
            entries: &entries,
        })
    }

    /// Dispatches enough workgroups for `items` invocations, in rows of at most `max_per_dim`
    /// workgroups (the shaders index items as `gid.x + gid.y * row_width`).
    pub fn dispatch(&self, pass: &mut ComputePass<'_>, bind_group: &BindGroup, items: u32, max_per_dim: u32) {
        if items == 0 {
            return;
        }
        let (x, y) = workgroups(items, max_per_dim);
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.dispatch_workgroups(x, y, 1);
    }

    /// Dispatches a single workgroup.
    pub fn dispatch_one(&self, pass: &mut ComputePass<'_>, bind_group: &BindGroup) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.dispatch_workgroups(1, 1, 1);
    }
}

/// The 2D grid of workgroups for `items` invocations: `x` per row (at most `max_per_dim`), `y`
/// rows. The last row may run past `items`; the shaders check.
#[must_use]
pub fn workgroups(items: u32, max_per_dim: u32) -> (u32, u32) {
    let groups = items.div_ceil(WORKGROUP_SIZE);
    let x = groups.min(max_per_dim.max(1));
    (x, groups.div_ceil(x))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_dispatches_wrap_into_rows() {
        assert_eq!(workgroups(1, 65535), (1, 1));
        assert_eq!(workgroups(64 * 65535, 65535), (65535, 1));
        assert_eq!(workgroups(64 * 65535 + 1, 65535), (65535, 2));
        // 8M items: 131072 workgroups in 3 rows of 65535.
        assert_eq!(workgroups(8 << 20, 65535), (65535, 3));
        // Every item is covered: x * y * 64 >= items, and the row index formula stays in u32.
        let (x, y) = workgroups(u32::MAX, 65535);
        assert!(u64::from(x) * u64::from(y) * 64 >= u64::from(u32::MAX));
    }
}
