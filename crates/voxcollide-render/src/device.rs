//! Drawing meshes whose positions live on the device: a simulation's own buffers (as
//! `voxcollide_sim::GpuWorld` keeps a body's, one `vec4<f32>` per vertex) are read by the vertex
//! stage (`shaders/render_device.wgsl`), so a frame never brings them back to the host.
//!
//! A [`DeviceMesh`] binds the caller's position buffer once, with the mesh's triangles and where
//! its vertices started (uploaded once: they do not change). [`Renderer::draw_device`] records
//! the meshes into a texture view the caller gives, in the caller's encoder, with nothing read
//! back; [`Renderer::render_device`] draws into the renderer's own target and returns the
//! picture (for a PNG, or a test). Faces are flat-shaded and coloured as the host path colours
//! them, the colour-map coordinate being how far each vertex has moved from its start.

use glam::{DVec3, Vec3};
use wgpu::{
    BindGroup, BindGroupLayout, Buffer, BufferUsages, CommandEncoder, Device, TextureFormat, TextureView,
};

use crate::{BACKGROUND, Camera, GpuRenderParams, Renderer, checked_view, depth_view, mesh_pipeline};
use voxcollide::Error;
use voxcollide::gpu::scoped;

/// The device path's WGSL: `shaders/render.wgsl` (its fragment stage) and the vertex stage that
/// reads the meshes' buffers, `vs_device`.
pub const DEVICE_SHADER: &str =
    concat!(include_str!("../shaders/render.wgsl"), include_str!("../shaders/render_device.wgsl"));

/// A mesh's uniform. Keep in sync with `MeshParams` in `shaders/render_device.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuMeshParams {
    color: [f32; 4],
    /// `(lo, 1 / (hi − lo) or 0, 1 to colour by displacement, unused)`.
    scalar: [f32; 4],
}

/// A mesh drawn from a buffer of positions on the device: the caller's buffer, bound once with
/// the mesh's triangles and where its vertices started, and read by the vertex stage at each
/// [`Renderer::draw_device`] or [`Renderer::render_device`].
#[derive(Debug)]
pub struct DeviceMesh {
    params: Buffer,
    _start: Buffer,
    _corners: Buffer,
    bind_group: BindGroup,
    triangles: u32,
    /// Where the vertices started: what a camera frames.
    framed: Vec<DVec3>,
    base_color: [f32; 3],
    displacement: bool,
}

/// What to draw from the device and from where: the device path's [`Scene`](crate::Scene).
#[derive(Clone, Copy, Debug)]
pub struct DeviceView {
    /// `(lo, hi)`: each vertex's distance from its start is mapped to the colour map as the host
    /// path maps its scalars ([`Scene::scalar_range`](crate::Scene::scalar_range)).
    pub scalar_range: (f32, f32),
    /// `(point, normal)`: only where `dot(p - point, normal) >= 0` is drawn (the cut-away).
    pub clip: Option<(Vec3, Vec3)>,
    /// The direction the camera looks along (any length but zero).
    pub view_dir: Vec3,
    /// Which way is up in the picture.
    pub up: Vec3,
    /// Where the camera is; `None` frames where the meshes started.
    pub eye: Option<Vec3>,
}

/// The device path's pipeline parts, built on first use.
#[derive(Debug)]
pub(crate) struct DeviceParts {
    mesh_layout: BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    module: wgpu::ShaderModule,
    /// A pipeline per (target format, samples), and a depth target per size for
    /// [`Renderer::draw_device`].
    pipelines: Vec<((TextureFormat, u32), wgpu::RenderPipeline)>,
    depth: Option<((u32, u32), TextureView)>,
}

impl DeviceMesh {
    /// Binds `positions` (the mesh's current positions: one `vec4<f32>` per vertex, xyz, in a
    /// buffer with `STORAGE` usage on the renderer's device) with the mesh's `triangles` and
    /// where its vertices started, `start` (one per vertex: the colour map shows how far each
    /// has moved from there). `displacement: false` draws the mesh in `base_color` (linear RGB).
    ///
    /// # Errors
    /// [`Error::Invalid`] for a buffer without `STORAGE` usage or smaller than `start`'s
    /// vertices, a triangle index out of range, a non-finite start or base colour, or an
    /// adapter whose vertex stage cannot read storage buffers (some GL drivers);
    /// [`Error::Gpu`] when the device rejects a resource.
    pub fn new(
        renderer: &mut Renderer,
        positions: &Buffer,
        start: &[Vec3],
        triangles: &[[u32; 3]],
        base_color: [f32; 3],
        displacement: bool,
    ) -> Result<DeviceMesh, Error> {
        let invalid =
            |what: &'static str, value: String, rule: &str| Error::Invalid { what, value, rule: rule.into() };
        if !positions.usage().contains(BufferUsages::STORAGE) {
            return Err(invalid("positions", format!("{:?}", positions.usage()), "needs STORAGE usage"));
        }
        let n = start.len();
        if positions.size() < 16 * n as u64 {
            return Err(invalid(
                "positions",
                format!("{} bytes", positions.size()),
                &format!("must hold a vec4<f32> for each of the {n} vertices"),
            ));
        }
        if let Some(i) = triangles.iter().flatten().find(|&&i| i as usize >= n) {
            return Err(invalid("triangle index", i.to_string(), &format!("must be less than {n}")));
        }
        if let Some(p) = start.iter().find(|p| !p.is_finite()) {
            return Err(invalid("start", p.to_string(), "must be finite"));
        }
        if !base_color.iter().all(|c| c.is_finite()) {
            return Err(invalid("base_color", format!("{base_color:?}"), "must be finite"));
        }
        let device = renderer.ctx.device().clone();
        let parts = renderer.device_parts()?;
        scoped(&device, || {
            use wgpu::util::DeviceExt as _;
            let init = |label, contents: &[u8], usage| {
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    // A binding is never empty.
                    contents: if contents.is_empty() { &[0; 16] } else { contents },
                    usage,
                })
            };
            let params = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("voxcollide device mesh params"),
                size: std::mem::size_of::<GpuMeshParams>() as u64,
                usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let starts: Vec<[f32; 4]> = start.iter().map(|p| p.extend(1.0).to_array()).collect();
            let start_buffer =
                init("voxcollide device mesh start", bytemuck::cast_slice(&starts), BufferUsages::STORAGE);
            let corners = init(
                "voxcollide device mesh triangles",
                bytemuck::cast_slice(triangles),
                BufferUsages::STORAGE,
            );
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("voxcollide device mesh"),
                layout: &parts.mesh_layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: positions.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: start_buffer.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: corners.as_entire_binding() },
                ],
            });
            DeviceMesh {
                params,
                _start: start_buffer,
                _corners: corners,
                bind_group,
                triangles: triangles.len() as u32,
                framed: start.iter().map(|p| p.as_dvec3()).collect(),
                base_color: base_color.map(|c| c.clamp(0.0, 1.0)),
                displacement,
            }
        })
    }
}

impl Renderer {
    /// The device path's parts, built on first use.
    fn device_parts(&mut self) -> Result<&DeviceParts, Error> {
        if self.device.is_none() {
            // Known for a context that chose its adapter; an app's own device is taken at its
            // word (a failure then surfaces as the device's error).
            let flags = self.ctx.downlevel_flags().unwrap_or(wgpu::DownlevelFlags::all());
            if !flags.contains(wgpu::DownlevelFlags::VERTEX_STORAGE) {
                return Err(Error::Invalid {
                    what: "adapter",
                    value: self.ctx.adapter_info().map_or_else(|| "this adapter".into(), |i| i.name.clone()),
                    rule: "drawing from device buffers needs a vertex stage that reads storage buffers \
                           (wgpu's VERTEX_STORAGE); draw from host positions instead"
                        .into(),
                });
            }
            let device = self.ctx.device().clone();
            let parts = scoped(&device, || build_parts(&device, &self.params_layout))?;
            self.device = Some(parts);
        }
        Ok(self.device.as_ref().expect("built above"))
    }

    /// The pipeline for `format` at `samples`, built on first use.
    fn device_pipeline(&mut self, format: TextureFormat, samples: u32) -> Result<usize, Error> {
        let device = self.ctx.device().clone();
        let parts = self.device.as_mut().expect("device_parts first");
        if let Some(k) = parts.pipelines.iter().position(|(key, _)| *key == (format, samples)) {
            return Ok(k);
        }
        let pipeline = scoped(&device, || build_pipeline(&device, parts, format, samples))?;
        parts.pipelines.push(((format, samples), pipeline));
        Ok(parts.pipelines.len() - 1)
    }

    /// The uniforms of `view` over `meshes`, for a target of `aspect`, written to the queue.
    fn device_params(&mut self, meshes: &[&DeviceMesh], view: &DeviceView, aspect: f64) -> Result<(), Error> {
        let plane = checked_view(view.view_dir, view.scalar_range, view.clip)?;
        let forward = view.view_dir.as_dvec3().normalize();
        let (lo, hi) = view.scalar_range;
        if let Some(e) = view.eye
            && !e.is_finite()
        {
            return Err(Error::Invalid { what: "eye", value: e.to_string(), rule: "must be finite".into() });
        }
        self.framed.clear();
        for m in meshes {
            self.framed.extend_from_slice(&m.framed);
        }
        let up = view.up.as_dvec3();
        let camera = match view.eye {
            None => Camera::framing(&self.framed, forward, up, aspect),
            Some(eye) => Camera::looking(eye.as_dvec3(), &self.framed, forward, up, aspect),
        };
        let params = GpuRenderParams {
            view_proj: camera.view_proj.as_mat4().to_cols_array_2d(),
            light_dir: camera.light.as_vec3().extend(0.0).to_array(),
            clip_plane: plane.map_or([0.0; 4], |pl| pl.as_vec4().to_array()),
        };
        let span = f64::from(hi) - f64::from(lo);
        let inverse = if span == 0.0 { 0.0 } else { (1.0 / span) as f32 };
        let queue = self.ctx.queue();
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        for m in meshes {
            let [r, g, b] = m.base_color;
            let mesh = GpuMeshParams {
                color: [r, g, b, 1.0],
                scalar: [lo, inverse, if m.displacement { 1.0 } else { 0.0 }, 0.0],
            };
            queue.write_buffer(&m.params, 0, bytemuck::bytes_of(&mesh));
        }
        Ok(())
    }

    /// Records `meshes` (their positions as they are on the device when the encoder runs) into
    /// `target`, a `width × height` view of `format` with one sample (a window's surface
    /// texture, or the app's own), cleared first, in the caller's `encoder`: nothing is read
    /// back and nothing is submitted. The colour is linear light: an `…Srgb` format encodes it
    /// for display. The renderer keeps a depth target of that size.
    ///
    /// # Errors
    /// As [`DeviceMesh::new`] for the adapter, [`Error::Invalid`] for a zero size, a
    /// non-finite view or a zero view direction, [`Error::Gpu`] when the device rejects the
    /// format (not renderable) or a resource.
    #[allow(clippy::too_many_arguments)]
    pub fn draw_device(
        &mut self,
        encoder: &mut CommandEncoder,
        target: &TextureView,
        format: TextureFormat,
        (width, height): (u32, u32),
        meshes: &[&DeviceMesh],
        view: &DeviceView,
    ) -> Result<(), Error> {
        if width == 0 || height == 0 {
            return Err(Error::Invalid {
                what: "target size",
                value: format!("{width} × {height}"),
                rule: "both sides must be positive".into(),
            });
        }
        self.device_parts()?;
        let k = self.device_pipeline(format, 1)?;
        self.device_params(meshes, view, f64::from(width) / f64::from(height))?;
        let device = self.ctx.device().clone();
        let parts = self.device.as_mut().expect("built above");
        if parts.depth.as_ref().is_none_or(|(size, _)| *size != (width, height)) {
            let depth = scoped(&device, || depth_view(&device, width, height, 1))?;
            parts.depth = Some(((width, height), depth));
        }
        let parts = self.device.as_ref().expect("built above");
        let depth = &parts.depth.as_ref().expect("made above").1;
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("voxcollide device render"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(BACKGROUND), store: wgpu::StoreOp::Store },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            ..Default::default()
        });
        record(&mut pass, &parts.pipelines[k].1, &self.bind_group, meshes);
        Ok(())
    }

    /// Draws `meshes` from their device buffers into the renderer's own picture, as
    /// [`render`](Self::render) draws a host scene, and returns it (RGBA8, sRGB-encoded, top row
    /// first): for a PNG of a world that stays on the device. Blocks until the device is done.
    ///
    /// # Errors
    /// As [`draw_device`](Self::draw_device), and [`Error::DeviceLost`] when the device fails.
    pub fn render_device(&mut self, meshes: &[&DeviceMesh], view: &DeviceView) -> Result<Vec<u8>, Error> {
        self.draw_picture_device(meshes, view)?;
        self.read_picture()
    }

    /// Draws `meshes` from their device buffers into the renderer's own picture and submits,
    /// reading nothing back, as [`draw_picture`](Self::draw_picture) draws a host scene: the
    /// picture stays on the device ([`picture_view`](Self::picture_view),
    /// [`read_picture`](Self::read_picture)).
    ///
    /// # Errors
    /// As [`draw_device`](Self::draw_device), and [`Error::DeviceLost`] when the device is lost.
    pub fn draw_picture_device(&mut self, meshes: &[&DeviceMesh], view: &DeviceView) -> Result<(), Error> {
        self.device_parts()?;
        let k = self.device_pipeline(crate::COLOR_FORMAT, self.samples)?;
        self.device_params(meshes, view, f64::from(self.width) / f64::from(self.height))?;
        if self.ctx.is_lost() {
            return Err(Error::DeviceLost { message: "the device was lost before this render".into() });
        }
        let device = self.ctx.device().clone();
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("voxcollide device render"),
        });
        {
            let parts = self.device.as_ref().expect("built above");
            let mut pass = self.begin_own_pass(&mut encoder);
            record(&mut pass, &parts.pipelines[k].1, &self.bind_group, meshes);
        }
        scoped(&device, || self.ctx.queue().submit([encoder.finish()]))?;
        Ok(())
    }
}

/// Draws each mesh's triangles (three vertices each, no vertex buffer).
fn record(
    pass: &mut wgpu::RenderPass<'_>,
    pipeline: &wgpu::RenderPipeline,
    params: &BindGroup,
    meshes: &[&DeviceMesh],
) {
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, params, &[]);
    for m in meshes.iter().filter(|m| m.triangles > 0) {
        pass.set_bind_group(1, &m.bind_group, &[]);
        pass.draw(0..3 * m.triangles, 0..1);
    }
}

fn build_parts(device: &Device, params_layout: &BindGroupLayout) -> DeviceParts {
    let storage = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let mesh_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("voxcollide device mesh"),
        entries: &[
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: wgpu::BufferSize::new(std::mem::size_of::<GpuMeshParams>() as u64),
                },
                count: None,
            },
            storage(1),
            storage(2),
            storage(3),
        ],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("voxcollide device render"),
        bind_group_layouts: &[Some(params_layout), Some(&mesh_layout)],
        immediate_size: 0,
    });
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("voxcollide device render"),
        source: wgpu::ShaderSource::Wgsl(DEVICE_SHADER.into()),
    });
    DeviceParts { mesh_layout, pipeline_layout, module, pipelines: Vec::new(), depth: None }
}

fn build_pipeline(
    device: &Device,
    parts: &DeviceParts,
    format: TextureFormat,
    samples: u32,
) -> wgpu::RenderPipeline {
    mesh_pipeline(device, &parts.pipeline_layout, &parts.module, ("vs_device", &[]), format, samples)
}
