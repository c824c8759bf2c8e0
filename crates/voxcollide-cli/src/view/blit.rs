//! The live view's last pass: the renderer's picture (drawn on the device, never read back)
//! with the overlay composed over it (the legend and heads-up lines, drawn on the CPU and
//! uploaded), onto the window's surface by one screen-covering triangle (`shaders/blit.wgsl`).
//! A screenshot is the same pass into a texture of its own, read back once.

use voxcollide::{Error, GpuContext};

/// The blit's WGSL (`vs_main`, `fs_main`).
pub const BLIT_SHADER: &str = include_str!("../../shaders/blit.wgsl");

/// The overlay's format: sRGB-encoded bytes, premultiplied, read as they are.
const OVERLAY_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// Composes a frame onto the window.
pub(super) struct Blit {
    /// Onto the window's surface.
    pipeline: wgpu::RenderPipeline,
    /// Into a screenshot's texture ([`OVERLAY_FORMAT`]: the composed bytes as they are).
    shot_pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    overlay: wgpu::Texture,
    bind_group: wgpu::BindGroup,
}

fn pipeline(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    format: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    let constants = [("SRGB_TARGET", if format.is_srgb() { 1.0 } else { 0.0 })];
    let options = wgpu::PipelineCompilationOptions { constants: &constants, ..Default::default() };
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("voxcollide view blit"),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_main"),
            compilation_options: options.clone(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: None,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fs_main"),
            compilation_options: options,
            targets: &[Some(wgpu::ColorTargetState {
                format,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

fn texture_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

impl Blit {
    /// The pass onto a surface of `target` format, composing `picture` (the renderer's, of
    /// `size`) with an overlay of that size.
    pub(super) fn new(
        device: &wgpu::Device,
        target: wgpu::TextureFormat,
        picture: &wgpu::TextureView,
        size: (u32, u32),
    ) -> Blit {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("voxcollide view blit"),
            entries: &[texture_entry(0), texture_entry(1)],
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("voxcollide view blit"),
            source: wgpu::ShaderSource::Wgsl(BLIT_SHADER.into()),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("voxcollide view blit"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let (overlay, bind_group) = Blit::overlay(device, &layout, picture, size);
        Blit {
            pipeline: pipeline(device, &pipeline_layout, &module, target),
            shot_pipeline: pipeline(device, &pipeline_layout, &module, OVERLAY_FORMAT),
            layout,
            overlay,
            bind_group,
        }
    }

    fn overlay(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        picture: &wgpu::TextureView,
        (width, height): (u32, u32),
    ) -> (wgpu::Texture, wgpu::BindGroup) {
        let overlay = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("voxcollide view overlay"),
            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: OVERLAY_FORMAT,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let view = overlay.create_view(&wgpu::TextureViewDescriptor::default());
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("voxcollide view blit"),
            layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(picture) },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&view) },
            ],
        });
        (overlay, bind_group)
    }

    /// After the window's (and the renderer's) size changed: the new `picture`, of `size`.
    pub(super) fn resize(&mut self, device: &wgpu::Device, picture: &wgpu::TextureView, size: (u32, u32)) {
        (self.overlay, self.bind_group) = Blit::overlay(device, &self.layout, picture, size);
    }

    /// Uploads `overlay` (premultiplied sRGB bytes, the window's size) and composes it over the
    /// renderer's picture onto `target`.
    pub(super) fn draw(&self, ctx: &GpuContext, overlay: &[u8], target: &wgpu::TextureView) {
        let size = self.overlay.size();
        ctx.queue().write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &self.overlay,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            overlay,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * size.width),
                rows_per_image: Some(size.height),
            },
            size,
        );
        let mut encoder = ctx
            .device()
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("voxcollide view blit") });
        self.compose(&mut encoder, &self.pipeline, target);
        ctx.queue().submit([encoder.finish()]);
    }

    fn compose(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        target: &wgpu::TextureView,
    ) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("voxcollide view blit"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            ..Default::default()
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }

    /// The frame last composed, as the window shows it: the same pass into a texture of its
    /// own, read back (RGBA8, sRGB-encoded, top row first).
    ///
    /// # Errors
    /// [`Error::Gpu`] or [`Error::DeviceLost`] when the device fails.
    pub(super) fn screenshot(&self, ctx: &GpuContext) -> Result<Vec<u8>, Error> {
        let device = ctx.device();
        let size = self.overlay.size();
        let shot = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("voxcollide view screenshot"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: OVERLAY_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let row = (4 * size.width).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let bytes = u64::from(row) * u64::from(size.height);
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("voxcollide view screenshot"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("voxcollide view screenshot"),
        });
        self.compose(
            &mut encoder,
            &self.shot_pipeline,
            &shot.create_view(&wgpu::TextureViewDescriptor::default()),
        );
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &shot,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: Some(size.height),
                },
            },
            size,
        );
        ctx.queue().submit([encoder.finish()]);
        let padded = voxcollide::gpu::map_read(ctx, &readback, bytes)?;
        let width = 4 * size.width as usize;
        Ok(padded
            .chunks(row as usize)
            .take(size.height as usize)
            .flat_map(|r| r[..width].iter().copied())
            .collect())
    }
}
