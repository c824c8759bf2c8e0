//! Offscreen pictures of the simulated bodies with wgpu: shaded, colour-mapped, cut away, as PNG.
//!
//! One render pipeline (`shaders/render.wgsl`) draws every mesh of a [`Scene`] into a 4× MSAA
//! target, which is resolved and read back as sRGB-encoded RGBA8. Triangles are expanded on the
//! CPU into three vertices each that carry the triangle's face normal (flat shading, so any
//! mesh reads as its true facets) and the colour-map coordinate of each corner. A perspective
//! camera frames what is drawn; the clip plane is applied per fragment, so a cut body shows its
//! inside (back faces, drawn darker). It runs on any adapter, Mesa's lavapipe included: no
//! optional feature, and only formats WebGPU guarantees for rendering and multisampling.
//!
//! ```no_run
//! use voxcollide::glam::Vec3;
//! use voxcollide_cli::render::{Renderer, Scene, SceneMesh};
//! let ctx = voxcollide::GpuContext::new()?;
//! let positions = [Vec3::ZERO, Vec3::X, Vec3::Y];
//! let scene = Scene {
//!     meshes: vec![SceneMesh {
//!         positions: &positions,
//!         triangles: &[[0, 1, 2]],
//!         scalars: Some(&[0.0, 0.5, 1.0]),
//!         base_color: [0.8, 0.8, 0.8],
//!     }],
//!     scalar_range: (0.0, 1.0),
//!     clip: None,
//!     view_dir: Vec3::NEG_Z,
//!     up: Vec3::Y,
//! };
//! let mut renderer = Renderer::new(&ctx, 640, 480)?;
//! renderer.render_png(&scene, std::path::Path::new("triangle.png"))?;
//! # Ok::<(), voxcollide::Error>(())
//! ```

use std::path::Path;

use glam::{DMat4, DVec3, DVec4, Vec3};
use wgpu::{Buffer, BufferUsages, Device, Texture, TextureFormat, TextureUsages, TextureView};

use voxcollide::gpu::scoped;
use voxcollide::{Error, GpuContext};

/// The renderer's WGSL (vertex `vs_main`, fragment `fs_main`), for validating it without a GPU.
pub const SHADER: &str = include_str!("../shaders/render.wgsl");

/// The colour target: sRGB-encoded, so the shader works in linear light and the PNG gets
/// display-ready bytes. WebGPU guarantees it renders, resolves and multisamples.
const COLOR_FORMAT: TextureFormat = TextureFormat::Rgba8UnormSrgb;
const DEPTH_FORMAT: TextureFormat = TextureFormat::Depth32Float;
/// MSAA samples: 4 is the count WebGPU guarantees for both formats.
const SAMPLES: u32 = 4;
/// Light grey (linear 0.8, sRGB byte 231): neutral behind the colour map and the grey insides.
const BACKGROUND: wgpu::Color = wgpu::Color { r: 0.8, g: 0.8, b: 0.8, a: 1.0 };
/// Vertical field of view: narrow enough that the perspective does not distort the shapes.
const FOV_Y: f64 = 30.0 * std::f64::consts::PI / 180.0;
/// Empty space kept around the framed geometry, as a fraction of the field of view.
const MARGIN: f64 = 0.08;
/// A first vertex buffer large enough for small scenes (64 triangles); it grows by powers of two.
const MIN_VERTEX_BYTES: u64 = 64 * 3 * VERTEX_BYTES;
const VERTEX_BYTES: u64 = std::mem::size_of::<GpuVertex>() as u64;

/// One triangle mesh of a scene.
#[derive(Clone, Copy, Debug)]
pub struct SceneMesh<'a> {
    /// The vertices.
    pub positions: &'a [Vec3],
    /// Indices into `positions`, counter-clockwise seen from outside (that side is drawn lit,
    /// the other darker). Triangles with a non-finite or repeated corner are skipped.
    pub triangles: &'a [[u32; 3]],
    /// A value per vertex (`len == positions.len()`) drawn through the colour map; `None` draws
    /// the mesh in `base_color`. A triangle with a non-finite value is drawn in `base_color`.
    pub scalars: Option<&'a [f32]>,
    /// Linear RGB in `0..=1` (clamped), for meshes without scalars.
    pub base_color: [f32; 3],
}

/// What to draw and from where.
#[derive(Clone, Debug)]
pub struct Scene<'a> {
    /// The meshes, drawn with a shared depth buffer.
    pub meshes: Vec<SceneMesh<'a>>,
    /// `(lo, hi)`: scalars are mapped to the colour map (viridis) by `(s - lo) / (hi - lo)`,
    /// clamped to `0..=1`; `lo > hi` reverses the map and `lo == hi` draws every scalar in the
    /// map's low end.
    pub scalar_range: (f32, f32),
    /// `(point, normal)`: only where `dot(p - point, normal) >= 0` is drawn, so the bodies are
    /// cut open there (the cut-away). `None` draws everything.
    pub clip: Option<(Vec3, Vec3)>,
    /// The direction the camera looks along (any length but zero).
    pub view_dir: Vec3,
    /// Which way is up in the picture; when it is parallel to `view_dir` (or not finite), some
    /// direction perpendicular to `view_dir` is taken instead.
    pub up: Vec3,
}

/// The uniform of `shaders/render.wgsl`. Keep in sync with `Params` there.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuRenderParams {
    /// World to clip space, column-major.
    view_proj: [[f32; 4]; 4],
    /// Unit vector towards the light; w unused.
    light_dir: [f32; 4],
    /// `(n, d)`: keep where `dot(n, p) + d >= 0`; zero when there is no clip.
    clip_plane: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<GpuRenderParams>() == 96);

/// One corner of a drawn triangle. Keep in sync with `VertexIn` in `shaders/render.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuVertex {
    /// xyz; w = 1.
    position: [f32; 4],
    /// xyz: the triangle's unit face normal; w: colour-map coordinate in `0..=1`, or -1 for the
    /// base colour.
    normal_t: [f32; 4],
    /// Linear base colour; a unused.
    color: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<GpuVertex>() == 48);

/// An offscreen renderer of a fixed size. The pipeline, targets and readback buffer are built
/// once; each [`render`](Self::render) uploads the scene's vertices (the vertex buffer grows
/// as needed and is reused) and reads the picture back.
#[derive(Debug)]
pub struct Renderer {
    ctx: GpuContext,
    width: u32,
    height: u32,
    /// Bytes per row in `readback`: `4 * width` rounded up to wgpu's copy alignment.
    padded_row: u32,
    max_buffer_size: u64,
    pipeline: wgpu::RenderPipeline,
    params: Buffer,
    bind_group: wgpu::BindGroup,
    msaa: TextureView,
    depth: TextureView,
    resolved: Texture,
    resolved_view: TextureView,
    readback: Buffer,
    vertices: Option<Buffer>,
    /// The expanded triangles of the last scene, kept to reuse the allocation.
    scratch: Vec<GpuVertex>,
    /// The points the camera frames: drawn vertices and where edges meet the clip plane.
    framed: Vec<DVec3>,
}

impl Renderer {
    /// A renderer of `width × height` pictures on `ctx`'s device.
    ///
    /// # Errors
    /// [`Error::Invalid`] when a side is 0 or above the device's `max_texture_dimension_2d`, or
    /// the readback buffer would exceed `max_buffer_size`; [`Error::Gpu`] when the device
    /// rejects a resource (e.g. out of memory).
    pub fn new(ctx: &GpuContext, width: u32, height: u32) -> Result<Renderer, Error> {
        let device = ctx.device();
        let limits = device.limits();
        let max = limits.max_texture_dimension_2d;
        for (what, side) in [("width", width), ("height", height)] {
            if side == 0 || side > max {
                return Err(Error::Invalid {
                    what,
                    value: side.to_string(),
                    rule: format!("must be between 1 and {max} (the device's max_texture_dimension_2d)"),
                });
            }
        }
        let padded_row = (4 * width).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let readback_size = u64::from(padded_row) * u64::from(height);
        if readback_size > limits.max_buffer_size {
            return Err(Error::Invalid {
                what: "width × height",
                value: format!("{width} × {height}"),
                rule: format!(
                    "the readback needs {readback_size} bytes; the device's max_buffer_size is {}",
                    limits.max_buffer_size
                ),
            });
        }
        let built = scoped(device, || build(device, width, height, readback_size))?;
        Ok(Renderer {
            ctx: ctx.clone(),
            width,
            height,
            padded_row,
            max_buffer_size: limits.max_buffer_size,
            pipeline: built.pipeline,
            params: built.params,
            bind_group: built.bind_group,
            msaa: built.msaa,
            depth: built.depth,
            resolved_view: built.resolved.create_view(&wgpu::TextureViewDescriptor::default()),
            resolved: built.resolved,
            readback: built.readback,
            vertices: None,
            scratch: Vec::new(),
            framed: Vec::new(),
        })
    }

    /// `(width, height)` of the pictures.
    #[must_use]
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Draws `scene` and returns its picture: RGBA8, sRGB-encoded, `width * height * 4` bytes,
    /// top row first. Blocks until the device is done.
    ///
    /// # Errors
    /// [`Error::Invalid`] for a mesh whose scalars do not match its positions, a triangle index
    /// out of range, a non-finite base colour, scalar range, clip or up, a zero view direction
    /// or clip normal, or more triangles than one vertex buffer of the device holds;
    /// [`Error::Gpu`] or [`Error::DeviceLost`] when the device fails.
    pub fn render(&mut self, scene: &Scene) -> Result<Vec<u8>, Error> {
        let aspect = f64::from(self.width) / f64::from(self.height);
        let params = prepare(scene, aspect, &mut self.scratch, &mut self.framed)?;
        let bytes = VERTEX_BYTES * self.scratch.len() as u64;
        if bytes > self.max_buffer_size || self.scratch.len() > u32::MAX as usize {
            return Err(Error::Invalid {
                what: "drawn triangles",
                value: (self.scratch.len() / 3).to_string(),
                rule: format!(
                    "at {VERTEX_BYTES} bytes per corner they need {bytes} bytes; the device's \
                     max_buffer_size is {}",
                    self.max_buffer_size
                ),
            });
        }
        if self.ctx.is_lost() {
            return Err(Error::DeviceLost { message: "the device was lost before this render".into() });
        }
        let device = self.ctx.device().clone();
        scoped(&device, || self.submit(&device, &params, bytes))?;
        self.read_back()
    }

    /// [`render`](Self::render)s `scene` and writes it to `path` as an RGBA PNG.
    ///
    /// # Errors
    /// As [`render`](Self::render), and [`Error::Io`] when the file cannot be written.
    pub fn render_png(&mut self, scene: &Scene, path: &Path) -> Result<(), Error> {
        let rgba = self.render(scene)?;
        write_png(path, self.width, self.height, &rgba)
    }

    /// Uploads the prepared vertices and `params`, records the pass and the copy into the
    /// readback buffer, and submits. Run inside error scopes: a device error surfaces there.
    fn submit(&mut self, device: &Device, params: &GpuRenderParams, bytes: u64) {
        let queue = self.ctx.queue();
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let fits = self.vertices.as_ref().is_some_and(|b| b.size() >= bytes);
        if !fits {
            // Powers of two, so a growing scene (a refined mesh) reallocates only a few times.
            let size = bytes.next_power_of_two().max(MIN_VERTEX_BYTES).min(self.max_buffer_size);
            self.vertices = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("voxcollide render vertices"),
                size,
                usage: BufferUsages::VERTEX | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
        let vertices = self.vertices.as_ref().filter(|_| bytes > 0);
        if let Some(buffer) = vertices {
            queue.write_buffer(buffer, 0, bytemuck::cast_slice(&self.scratch));
        }

        let mut encoder = device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("voxcollide render") });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("voxcollide render"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &self.msaa,
                    depth_slice: None,
                    resolve_target: Some(&self.resolved_view),
                    // Only the resolved picture is needed afterwards.
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(BACKGROUND),
                        store: wgpu::StoreOp::Discard,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &self.depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            if let Some(buffer) = vertices {
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &self.bind_group, &[]);
                pass.set_vertex_buffer(0, buffer.slice(..bytes));
                pass.draw(0..self.scratch.len() as u32, 0..1);
            }
        }
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.resolved,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &self.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.padded_row),
                    rows_per_image: Some(self.height),
                },
            },
            wgpu::Extent3d { width: self.width, height: self.height, depth_or_array_layers: 1 },
        );
        queue.submit([encoder.finish()]);
    }

    /// Maps the readback buffer, waits for the device, and strips the row padding.
    fn read_back(&self) -> Result<Vec<u8>, Error> {
        let padded = voxcollide::gpu::map_read(&self.ctx, &self.readback, self.readback.size())?;
        let row = 4 * self.width as usize;
        let mut rgba = Vec::with_capacity(row * self.height as usize);
        for line in padded.chunks(self.padded_row as usize).take(self.height as usize) {
            rgba.extend_from_slice(&line[..row]);
        }
        Ok(rgba)
    }
}

/// Writes `rgba` (RGBA8, sRGB-encoded, top row first) to `path` as a PNG.
///
/// # Errors
/// [`Error::Invalid`] when a side is 0 or `rgba` is not `width * height * 4` bytes;
/// [`Error::Io`] when the file cannot be created or written.
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<(), Error> {
    for (what, side) in [("width", width), ("height", height)] {
        if side == 0 {
            return Err(Error::Invalid {
                what,
                value: "0".into(),
                rule: "a PNG needs at least one pixel".into(),
            });
        }
    }
    let needed = 4 * u64::from(width) * u64::from(height);
    if rgba.len() as u64 != needed {
        return Err(Error::Invalid {
            what: "rgba length",
            value: rgba.len().to_string(),
            rule: format!("must be width × height × 4 = {needed} for {width} × {height}"),
        });
    }
    let io = |message: String| Error::Io { path: path.display().to_string(), message };
    let file = std::fs::File::create(path).map_err(|e| io(e.to_string()))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    // Say so: the bytes are sRGB-encoded, as viewers assume anyway.
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    let mut writer = encoder.write_header().map_err(|e| io(e.to_string()))?;
    writer.write_image_data(rgba).map_err(|e| io(e.to_string()))?;
    writer.finish().map_err(|e| io(e.to_string()))
}

/// The GPU objects of a [`Renderer`], built inside one error scope.
struct Built {
    pipeline: wgpu::RenderPipeline,
    params: Buffer,
    bind_group: wgpu::BindGroup,
    msaa: TextureView,
    depth: TextureView,
    resolved: Texture,
    readback: Buffer,
}

fn build(device: &Device, width: u32, height: u32, readback_size: u64) -> Built {
    let label = Some("voxcollide render");
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label,
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: wgpu::BufferSize::new(std::mem::size_of::<GpuRenderParams>() as u64),
            },
            count: None,
        }],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label,
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label,
        source: wgpu::ShaderSource::Wgsl(SHADER.into()),
    });
    let attributes = wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4, 2 => Float32x4];
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label,
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: VERTEX_BYTES,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &attributes,
            })],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            front_face: wgpu::FrontFace::Ccw,
            // Two-sided: a cut body shows its inside faces.
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState { count: SAMPLES, mask: !0, alpha_to_coverage_enabled: false },
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: COLOR_FORMAT,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    });
    let params = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("voxcollide render params"),
        size: std::mem::size_of::<GpuRenderParams>() as u64,
        usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label,
        layout: &layout,
        entries: &[wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() }],
    });
    let size = wgpu::Extent3d { width, height, depth_or_array_layers: 1 };
    let texture = |label: &str, samples: u32, format: TextureFormat, usage: TextureUsages| {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size,
            mip_level_count: 1,
            sample_count: samples,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    };
    let view = |t: Texture| t.create_view(&wgpu::TextureViewDescriptor::default());
    Built {
        pipeline,
        params,
        bind_group,
        msaa: view(texture(
            "voxcollide render msaa",
            SAMPLES,
            COLOR_FORMAT,
            TextureUsages::RENDER_ATTACHMENT,
        )),
        depth: view(texture(
            "voxcollide render depth",
            SAMPLES,
            DEPTH_FORMAT,
            TextureUsages::RENDER_ATTACHMENT,
        )),
        resolved: texture(
            "voxcollide render resolved",
            1,
            COLOR_FORMAT,
            TextureUsages::RENDER_ATTACHMENT | TextureUsages::COPY_SRC,
        ),
        readback: device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("voxcollide render readback"),
            size: readback_size,
            usage: BufferUsages::MAP_READ | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        }),
    }
}

/// Checks `scene`, expands its drawn triangles into `vertices`, collects the points to frame
/// into `framed`, and returns the uniform: camera, light and clip plane.
fn prepare(
    scene: &Scene,
    aspect: f64,
    vertices: &mut Vec<GpuVertex>,
    framed: &mut Vec<DVec3>,
) -> Result<GpuRenderParams, Error> {
    let invalid =
        |what: &'static str, value: String, rule: &str| Error::Invalid { what, value, rule: rule.into() };
    let view_dir = scene.view_dir.as_dvec3();
    if !view_dir.is_finite() || view_dir == DVec3::ZERO {
        return Err(invalid("view_dir", format!("{}", scene.view_dir), "must be finite and non-zero"));
    }
    let (lo, hi) = scene.scalar_range;
    if !lo.is_finite() || !hi.is_finite() {
        return Err(invalid("scalar_range", format!("({lo}, {hi})"), "both ends must be finite"));
    }
    // The plane as (n, d) with unit n, in f64 so huge coordinates cannot overflow the test.
    let plane = match scene.clip {
        None => None,
        Some((point, normal)) => {
            let n = normal.as_dvec3().normalize_or_zero();
            if !point.is_finite() || n == DVec3::ZERO {
                return Err(invalid(
                    "clip",
                    format!("(point {point}, normal {normal})"),
                    "the point must be finite and the normal finite and non-zero",
                ));
            }
            Some(n.extend(-n.dot(point.as_dvec3())))
        }
    };
    let side = |p: DVec3| plane.map_or(0.0, |pl| pl.truncate().dot(p) + pl.w);

    vertices.clear();
    framed.clear();
    // `(s - lo) / (hi - lo)` in f64: the span of two finite f32 cannot overflow there.
    let span = f64::from(hi) - f64::from(lo);
    let to_t =
        |s: f32| if span == 0.0 { 0.0 } else { ((f64::from(s) - f64::from(lo)) / span).clamp(0.0, 1.0) };
    for (m, mesh) in scene.meshes.iter().enumerate() {
        let n = mesh.positions.len();
        if let Some(s) = mesh.scalars
            && s.len() != n
        {
            return Err(invalid(
                "scalars length",
                format!("{} (mesh {m})", s.len()),
                &format!("must equal the mesh's number of positions, {n}"),
            ));
        }
        if !mesh.base_color.iter().all(|c| c.is_finite()) {
            return Err(invalid("base_color", format!("{:?} (mesh {m})", mesh.base_color), "must be finite"));
        }
        let [r, g, b] = mesh.base_color.map(|c| c.clamp(0.0, 1.0));
        for (t, tri) in mesh.triangles.iter().enumerate() {
            if let Some(&i) = tri.iter().find(|&&i| i as usize >= n) {
                return Err(invalid(
                    "triangle index",
                    format!("{i} (mesh {m}, triangle {t})"),
                    &format!("must be less than the mesh's number of positions, {n}"),
                ));
            }
            let p = tri.map(|i| mesh.positions[i as usize].as_dvec3());
            if !p.iter().all(|q| q.is_finite()) {
                continue; // a broken vertex (a blown-up simulation) loses its triangles, not the picture
            }
            let normal = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            if normal == DVec3::ZERO {
                continue; // no area, nothing to draw
            }
            let d = p.map(side);
            if d.iter().all(|&x| x < 0.0) {
                continue; // wholly cut away
            }
            // Frame the kept part: kept corners, and where the triangle's edges cross the plane.
            for k in 0..3 {
                let (a, b) = (k, (k + 1) % 3);
                if d[a] >= 0.0 {
                    framed.push(p[a]);
                }
                if (d[a] < 0.0) != (d[b] < 0.0) {
                    framed.push(p[a] + (p[b] - p[a]) * (d[a] / (d[a] - d[b])));
                }
            }
            let ts = match mesh.scalars {
                Some(s) if tri.iter().all(|&i| s[i as usize].is_finite()) => {
                    tri.map(|i| to_t(s[i as usize]) as f32)
                }
                _ => [-1.0; 3],
            };
            let nf = normal.as_vec3();
            for k in 0..3 {
                let q = p[k].as_vec3();
                vertices.push(GpuVertex {
                    position: [q.x, q.y, q.z, 1.0],
                    normal_t: [nf.x, nf.y, nf.z, ts[k]],
                    color: [r, g, b, 1.0],
                });
            }
        }
    }

    let camera = Camera::framing(framed, view_dir.normalize(), scene.up.as_dvec3(), aspect);
    Ok(GpuRenderParams {
        view_proj: camera.view_proj.as_mat4().to_cols_array_2d(),
        light_dir: camera.light.as_vec3().extend(0.0).to_array(),
        clip_plane: plane.map_or([0.0; 4], |pl| pl.as_vec4().to_array()),
    })
}

/// A perspective camera that frames a set of points.
struct Camera {
    view_proj: DMat4,
    /// Unit vector towards the light.
    light: DVec3,
}

impl Camera {
    /// Looks along `forward` (unit) with `up`, from where every point of `points` is in view
    /// with [`MARGIN`] to spare. The camera is centred on the points' extent across the view and
    /// backed off until the nearest-to-the-edge point fits, which frames a shape more tightly
    /// than a bounding sphere would.
    fn framing(points: &[DVec3], forward: DVec3, up: DVec3, aspect: f64) -> Camera {
        let right = forward.cross(up).normalize_or_zero();
        let right = if right == DVec3::ZERO { forward.any_orthonormal_vector() } else { right };
        let up = right.cross(forward);
        // The headlight sits a little above and left of the eye, so that faces facing the
        // viewer squarely still differ in brightness from their neighbours.
        let light = (-forward + 0.35 * up - 0.25 * right).normalize();
        if points.is_empty() {
            // Nothing to draw: any valid matrix does.
            return Camera { view_proj: DMat4::IDENTITY, light };
        }

        // The points in camera axes: across (x right, y up) and depth (z forward).
        let axes = |p: DVec3| DVec3::new(p.dot(right), p.dot(up), p.dot(forward));
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for &p in points {
            let q = axes(p);
            lo = lo.min(q);
            hi = hi.max(q);
        }
        let centre = (lo + hi) / 2.0;
        // A zero extent (everything cut away but a point) still needs a finite view volume.
        let extent = (hi - lo).max_element().max(1e-6 * centre.abs().max_element()).max(f64::MIN_POSITIVE);
        let tan_y = (FOV_Y / 2.0).tan() / (1.0 + MARGIN);
        let tan_x = tan_y * aspect;
        // The eye's depth: in front of every point by at least a little, and far enough back
        // that each point is inside the field of view.
        let mut eye_z = lo.z - 0.05 * extent;
        for &p in points {
            let q = axes(p);
            eye_z = eye_z.min(q.z - (q.x - centre.x).abs() / tan_x).min(q.z - (q.y - centre.y).abs() / tan_y);
        }
        let near = 0.5 * (lo.z - eye_z);
        let far = (hi.z - eye_z) + 0.05 * extent;

        // Rows of view × projection (depth 0 at `near`, 1 at `far`, as wgpu expects), written
        // in the camera axes: x' = (x - cx) f / aspect, y' = (y - cy) f, w' = z - eye_z.
        let f = 1.0 / (FOV_Y / 2.0).tan();
        let (a, b) = (far / (far - near), -near * far / (far - near));
        let row = |axis: DVec3, offset: f64, scale: f64| (axis * scale).extend(-offset * scale);
        let x = row(right, centre.x, f / aspect);
        let y = row(up, centre.y, f);
        let w = row(forward, eye_z, 1.0);
        let z = w * a + DVec4::new(0.0, 0.0, 0.0, b);
        Camera { view_proj: DMat4::from_cols(x, y, z, w).transpose(), light }
    }
}
