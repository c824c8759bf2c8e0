//! Offscreen pictures of the simulated bodies with wgpu: shaded, colour-mapped, cut away, as PNG.
//! A library an app can use: it takes the app's [`GpuContext`] (its device and queue) and has no
//! argument parser, window or progress bar; `voxcollide`'s command and its live view draw with it.
//!
//! One render pipeline (`shaders/render.wgsl`) draws every mesh of a [`Scene`] into a 4× MSAA
//! target, which is resolved and read back as sRGB-encoded RGBA8. Triangles are expanded on the
//! CPU into three vertices each that carry the triangle's face normal (flat shading, so any
//! mesh reads as its true facets) and the colour-map coordinate of each corner. A perspective
//! camera frames what is drawn; the clip plane is applied per fragment, so a cut body shows its
//! inside (back faces, drawn darker). It runs on any adapter, Mesa's lavapipe included: no
//! optional feature, and only formats WebGPU guarantees for rendering and multisampling.
//!
//! A [`Legend`] (the colour map as a labelled bar under a title) is drawn over the read-back
//! picture on the CPU by [`draw_legend`], with the shader's colour map reproduced there.
//!
//! **Drawing from the device.** A simulation that keeps its bodies on the GPU (`voxcollide-sim`'s
//! `GpuWorld`, whose `positions(body)` is each body's buffer) is drawn without reading them
//! back: a [`DeviceMesh`] binds such a buffer once, with the mesh's triangles and where its
//! vertices started; [`Renderer::draw_device`] records the meshes into a texture view the app
//! gives (a window's surface, say), in the app's encoder, and reads nothing back, and
//! [`Renderer::render_device`] returns the picture for a file. The vertex stage
//! (`shaders/render_device.wgsl`) reads each triangle's corners, takes its face normal and
//! colours each vertex by how far it has moved, so a frame looks as the host path draws it
//! (`tests/render.rs` compares the two). It needs a vertex stage that reads storage buffers,
//! which every Vulkan, Metal and DX12 adapter has, and Mesa's GL; where an adapter lacks it,
//! [`DeviceMesh::new`] says so.
//!
//! ```no_run
//! use voxcollide::glam::Vec3;
//! use voxcollide_render::{Legend, Renderer, Scene, SceneMesh};
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
//! let legend = Legend::new("displacement (mm)", scene.scalar_range);
//! let mut renderer = Renderer::new(&ctx, 640, 480)?;
//! renderer.render_png_with_legend(&scene, Some(&legend), std::path::Path::new("triangle.png"))?;
//! # Ok::<(), voxcollide::Error>(())
//! ```

#![deny(missing_docs)]

use std::path::Path;

use glam::{DMat4, DVec3, DVec4, Vec3};
use wgpu::{Buffer, BufferUsages, Device, Texture, TextureFormat, TextureUsages, TextureView};

use voxcollide::gpu::scoped;
use voxcollide::{Error, GpuContext};

mod device;
pub use device::{DEVICE_SHADER, DeviceMesh, DeviceView};

/// The renderer's WGSL (vertex `vs_main`, fragment `fs_main`), for validating it without a GPU.
pub const SHADER: &str = include_str!("../shaders/render.wgsl");

/// The format of the renderer's own picture ([`Renderer::picture_view`]): sRGB-encoded, so
/// the shader works in linear light and the PNG gets display-ready bytes. WebGPU guarantees it
/// renders, resolves and multisamples.
pub const COLOR_FORMAT: TextureFormat = TextureFormat::Rgba8UnormSrgb;
const DEPTH_FORMAT: TextureFormat = TextureFormat::Depth32Float;
/// MSAA samples: 4 is the count WebGPU guarantees for both formats.
const SAMPLES: u32 = 4;
/// Light grey (linear 0.8, sRGB byte 231): neutral behind the colour map and the grey insides.
const BACKGROUND: wgpu::Color = wgpu::Color { r: 0.8, g: 0.8, b: 0.8, a: 1.0 };
/// Vertical field of view in degrees: narrow enough that the perspective does not distort the
/// shapes.
pub const FOV_Y_DEGREES: f64 = 30.0;
const FOV_Y: f64 = FOV_Y_DEGREES * std::f64::consts::PI / 180.0;
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

impl Scene<'_> {
    /// The largest scalar of any mesh, or 0 (what [`Legend::above`] compares with its top).
    #[must_use]
    pub fn largest_scalar(&self) -> f32 {
        self.meshes.iter().flat_map(|m| m.scalars.unwrap_or_default().iter().copied()).fold(0.0, f32::max)
    }
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
    /// The layout of `params`' bind group (group 0), which the device path shares.
    params_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    /// Samples per pixel of the renderer's own picture.
    samples: u32,
    /// The multisampled target, resolved into `resolved`; `None` at one sample, drawn
    /// straight into `resolved`.
    msaa: Option<TextureView>,
    depth: TextureView,
    resolved: Texture,
    resolved_view: TextureView,
    /// The device path's pipelines ([`DeviceMesh`]), built on first use.
    device: Option<device::DeviceParts>,
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
        Renderer::with_samples(ctx, width, height, SAMPLES)
    }

    /// A renderer that draws without multisampling: edges are not smoothed, and a software
    /// adapter draws several times faster (a live view's frames, not a paper's pictures).
    ///
    /// # Errors
    /// As [`new`](Self::new).
    pub fn fast(ctx: &GpuContext, width: u32, height: u32) -> Result<Renderer, Error> {
        Renderer::with_samples(ctx, width, height, 1)
    }

    fn with_samples(ctx: &GpuContext, width: u32, height: u32, samples: u32) -> Result<Renderer, Error> {
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
        let built = scoped(device, || build(device, width, height, readback_size, samples))?;
        Ok(Renderer {
            ctx: ctx.clone(),
            width,
            height,
            padded_row,
            max_buffer_size: limits.max_buffer_size,
            pipeline: built.pipeline,
            params: built.params,
            params_layout: built.layout,
            bind_group: built.bind_group,
            samples,
            msaa: built.msaa,
            depth: built.depth,
            resolved_view: built.resolved.create_view(&wgpu::TextureViewDescriptor::default()),
            resolved: built.resolved,
            readback: built.readback,
            device: None,
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

    /// Draws `scene` (the camera at `eye`, or framing it) into the renderer's own picture and
    /// submits, reading nothing back: the picture stays on the device, where
    /// [`picture_view`](Self::picture_view) shows it to an app's own passes (a live view's
    /// compositing onto a window) and [`read_picture`](Self::read_picture) fetches it.
    ///
    /// # Errors
    /// As [`render_from`](Self::render_from).
    pub fn draw_picture(&mut self, scene: &Scene, eye: Option<Vec3>) -> Result<(), Error> {
        self.draw_clear_of(scene, eye, 0)
    }

    /// The renderer's own picture on the device, as the last draw left it: `width × height`,
    /// [`COLOR_FORMAT`] (sampled, its texels read as linear light), one sample.
    #[must_use]
    pub fn picture_view(&self) -> &TextureView {
        &self.resolved_view
    }

    /// Reads the renderer's own picture back, as the last draw left it ([`render`](Self::render)'s
    /// bytes). Blocks until the device is done.
    ///
    /// # Errors
    /// [`Error::Gpu`] or [`Error::DeviceLost`] when the device fails.
    pub fn read_picture(&self) -> Result<Vec<u8>, Error> {
        let device = self.ctx.device();
        scoped(device, || {
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("voxcollide render read"),
            });
            self.copy_to_readback(&mut encoder);
            self.ctx.queue().submit([encoder.finish()]);
        })?;
        self.read_back()
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
        self.render_from(scene, None)
    }

    /// [`render`](Self::render) with the camera at `eye`, looking along the scene's
    /// `view_dir`, instead of framing what is drawn (`None` frames it): a live view's orbit,
    /// pan and zoom keep the camera where the user put it while the bodies move.
    ///
    /// # Errors
    /// As [`render`](Self::render), and [`Error::Invalid`] for an `eye` that is not finite.
    pub fn render_from(&mut self, scene: &Scene, eye: Option<Vec3>) -> Result<Vec<u8>, Error> {
        self.render_clear_of(scene, eye, 0)
    }

    /// [`render`](Self::render)s `scene` with [`draw_legend`]'s `legend` over it, the bodies
    /// framed in the part of the picture left of the legend's panel so that it never covers
    /// them (where the legend does not fit, it is not drawn and the bodies take the whole
    /// picture).
    ///
    /// # Errors
    /// As [`render`](Self::render) and [`draw_legend`] (a non-finite legend range).
    pub fn render_with_legend(&mut self, scene: &Scene, legend: &Legend) -> Result<Vec<u8>, Error> {
        let clear = legend_panel(self.width, self.height, legend)?.map_or(0, |p| self.width - p.x);
        let mut rgba = self.render_clear_of(scene, None, clear)?;
        draw_legend(&mut rgba, self.width, self.height, legend)?;
        Ok(rgba)
    }

    /// [`render_from`](Self::render_from), a framed picture keeping the rightmost `clear`
    /// pixels free of the bodies.
    fn render_clear_of(&mut self, scene: &Scene, eye: Option<Vec3>, clear: u32) -> Result<Vec<u8>, Error> {
        self.draw_clear_of(scene, eye, clear)?;
        self.read_picture()
    }

    /// [`draw_picture`](Self::draw_picture), a framed picture keeping the rightmost `clear`
    /// pixels free of the bodies.
    fn draw_clear_of(&mut self, scene: &Scene, eye: Option<Vec3>, clear: u32) -> Result<(), Error> {
        if let Some(e) = eye
            && !e.is_finite()
        {
            return Err(Error::Invalid { what: "eye", value: e.to_string(), rule: "must be finite".into() });
        }
        let aspect = f64::from(self.width) / f64::from(self.height);
        let keep = f64::from(self.width.saturating_sub(clear).max(1)) / f64::from(self.width);
        let params = prepare(scene, aspect, eye, keep, &mut self.scratch, &mut self.framed)?;
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
        scoped(&device, || self.submit(&device, &params, bytes))
    }

    /// [`render`](Self::render)s `scene` and writes it to `path` as an RGBA PNG.
    ///
    /// # Errors
    /// As [`render`](Self::render), and [`Error::Io`] when the file cannot be written.
    pub fn render_png(&mut self, scene: &Scene, path: &Path) -> Result<(), Error> {
        self.render_png_with_legend(scene, None, path)
    }

    /// [`render`](Self::render)s `scene`, [`draw_legend`]s `legend` over it (where the picture
    /// is large enough), and writes it to `path` as an RGBA PNG. `None` is
    /// [`render_png`](Self::render_png).
    ///
    /// # Errors
    /// As [`render`](Self::render) and [`draw_legend`] (a non-finite legend range), and
    /// [`Error::Io`] when the file cannot be written.
    pub fn render_png_with_legend(
        &mut self,
        scene: &Scene,
        legend: Option<&Legend>,
        path: &Path,
    ) -> Result<(), Error> {
        let rgba = match legend {
            Some(legend) => self.render_with_legend(scene, legend)?,
            None => self.render(scene)?,
        };
        write_png(path, self.width, self.height, &rgba)
    }

    /// Uploads the prepared vertices and `params`, records the pass, and submits. Run inside
    /// error scopes: a device error surfaces there.
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
            let mut pass = self.begin_own_pass(&mut encoder);
            if let Some(buffer) = vertices {
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &self.bind_group, &[]);
                pass.set_vertex_buffer(0, buffer.slice(..bytes));
                pass.draw(0..self.scratch.len() as u32, 0..1);
            }
        }
        queue.submit([encoder.finish()]);
    }

    /// A render pass into the renderer's own picture (multisampled and resolved where it has
    /// samples), cleared to the background.
    fn begin_own_pass<'e>(&self, encoder: &'e mut wgpu::CommandEncoder) -> wgpu::RenderPass<'e> {
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("voxcollide render"),
            color_attachments: &[Some(match &self.msaa {
                Some(msaa) => wgpu::RenderPassColorAttachment {
                    view: msaa,
                    depth_slice: None,
                    resolve_target: Some(&self.resolved_view),
                    // Only the resolved picture is needed afterwards.
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(BACKGROUND),
                        store: wgpu::StoreOp::Discard,
                    },
                },
                None => wgpu::RenderPassColorAttachment {
                    view: &self.resolved_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(BACKGROUND),
                        store: wgpu::StoreOp::Store,
                    },
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
        })
    }

    /// Copies the resolved picture into the readback buffer.
    fn copy_to_readback(&self, encoder: &mut wgpu::CommandEncoder) {
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
    check_rgba(rgba, width, height)?;
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

// The colour legend: drawn on the CPU over the read-back picture, so it costs no pipeline.

/// A colour legend: the colour map as a vertical bar, labelled at `lo`, the middle and `hi`,
/// under a title. Give it the scene's [`scalar_range`](Scene::scalar_range), so that the bar's
/// colours are the bodies' (shading aside).
#[derive(Clone, Debug, PartialEq)]
pub struct Legend {
    /// What the colours show, with its unit: e.g. `"displacement (mm)"`. Characters the font
    /// lacks are drawn as `?`; a title too wide for the picture is shortened, ending in `..`.
    pub title: String,
    /// The value at the map's low end, the bar's bottom: the scene's `scalar_range.0`.
    pub lo: f32,
    /// The value at the map's high end, the bar's top: the scene's `scalar_range.1`. Equal to
    /// `lo`, the bar is one swatch of the low end with one label, as the bodies are drawn.
    pub hi: f32,
    /// Whether the picture holds values above `hi`, drawn in `hi`'s colour: the top label then
    /// ends in `+` (see [`Legend::above`]).
    pub beyond: bool,
}

impl Legend {
    /// A legend titled `title` for the range `(lo, hi)`, as [`Scene::scalar_range`] takes it.
    #[must_use]
    pub fn new(title: impl Into<String>, (lo, hi): (f32, f32)) -> Legend {
        Legend { title: title.into(), lo, hi, beyond: false }
    }

    /// The legend of a picture whose largest value is `max`: where that is above `hi`, the
    /// colours are clipped there, and the top label says so (`0.96+`).
    #[must_use]
    pub fn above(mut self, max: f32) -> Legend {
        self.beyond = max > self.hi;
        self
    }

    /// The tick labels [`draw_legend`] draws, bottom to top: `lo`, the middle and `hi` to 3
    /// significant figures (more where 3 would make two of them read the same), `hi`'s ending
    /// in `+` where the picture holds values beyond it, or `lo` alone when `lo == hi`.
    #[must_use]
    pub fn tick_labels(&self) -> Vec<String> {
        let (lo, hi) = (f64::from(self.lo), f64::from(self.hi));
        if lo == hi || !lo.is_finite() || !hi.is_finite() {
            return vec![format_sig(lo, 3)];
        }
        let values = [lo, (lo + hi) / 2.0, hi];
        // f32 carries 9 significant digits: by then the three differ, as the values do.
        let mut labels = Vec::new();
        for sig in 3..=9 {
            labels = values.map(|v| format_sig(v, sig)).to_vec();
            if labels[0] != labels[1] && labels[1] != labels[2] && labels[0] != labels[2] {
                break;
            }
        }
        if self.beyond
            && let Some(top) = labels.last_mut()
        {
            top.push('+');
        }
        labels
    }
}

/// Where [`draw_legend`] drew, in pixels from the picture's top-left corner.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct PixelRect {
    /// The left column.
    pub x: u32,
    /// The top row.
    pub y: u32,
    /// Columns covered.
    pub width: u32,
    /// Rows covered.
    pub height: u32,
}

impl PixelRect {
    /// Whether the pixel at column `x`, row `y` lies inside.
    #[must_use]
    pub fn contains(&self, x: u32, y: u32) -> bool {
        x >= self.x && x - self.x < self.width && y >= self.y && y - self.y < self.height
    }
}

/// Where [`draw_legend`] would draw `legend` in a `width × height` picture (`None`: it does
/// not fit, and nothing would be drawn).
///
/// # Errors
/// [`Error::Invalid`] for a non-finite legend range.
pub fn legend_panel(width: u32, height: u32, legend: &Legend) -> Result<Option<PixelRect>, Error> {
    Ok(LegendLayout::of(width, height, legend)?.map(|l| l.panel))
}

/// Draws `legend` into the top-right corner of `rgba` (RGBA8, sRGB-encoded, top row first, as
/// [`Renderer::render`] returns it) and returns the panel it covers; pixels outside it are
/// untouched. The bar holds the shader's colour map, sampled as the shader samples it and
/// sRGB-encoded as the render target is, from `lo` at the bottom to `hi` at the top; labels
/// and title are in an 8×8 bitmap font, on a light panel (85 % opaque) that reads over any
/// background. Font, bar and margins scale with the picture: 1× below 720 rows or columns,
/// 2× at 1280 × 720, 3× at 1920 × 1080. The pixels under the panel are assumed opaque (the
/// renderer's are): their colour is blended with the panel's, their alpha composited under it.
///
/// Returns `Ok(None)`, drawing nothing, when the picture is too small for the legend even at
/// 1× with its title shortened: with labels of up to 5 characters, narrower than 74 or lower
/// than 62 pixels.
///
/// ```
/// use voxcollide_render::{Legend, draw_legend};
/// let (width, height) = (320, 200);
/// let mut rgba = vec![231; 4 * width * height];
/// let legend = Legend::new("displacement (mm)", (0.0, 0.35));
/// let panel = draw_legend(&mut rgba, width as u32, height as u32, &legend)?.expect("it fits");
/// assert_eq!(panel.x + panel.width + 6, 320, "6 pixels from the right edge");
/// # Ok::<(), voxcollide::Error>(())
/// ```
///
/// # Errors
/// [`Error::Invalid`] when `rgba` is not `width * height * 4` bytes, or `lo` or `hi` is not
/// finite.
pub fn draw_legend(
    rgba: &mut [u8],
    width: u32,
    height: u32,
    legend: &Legend,
) -> Result<Option<PixelRect>, Error> {
    check_rgba(rgba, width, height)?;
    let labels = legend.tick_labels();
    let Some(layout) = LegendLayout::of(width, height, legend)? else {
        return Ok(None);
    };
    let mut canvas = Canvas { rgba, width, height };
    let LegendLayout { scale, panel, title, bar, fill } = layout;

    canvas.blend_rect(panel, PANEL_COLOR, PANEL_ALPHA);
    let (left, top) = (panel.x + LEGEND_PAD * scale, panel.y + LEGEND_PAD * scale);
    canvas.text(left, top, scale, &title);
    canvas.blend_rect(bar, OUTLINE_COLOR, 1.0);
    // Row r of the fill, from the top, shows t = 1 - r / (rows - 1): the ends are exactly the
    // map's ends, so the bar's bottom is lo's colour and its top hi's.
    let single = labels.len() == 1;
    for r in 0..fill.height {
        let t = if single { 0.0 } else { 1.0 - r as f32 / (fill.height - 1) as f32 };
        let row = PixelRect { y: fill.y + r, height: 1, ..fill };
        canvas.blend_rect(row, viridis_srgb8(t), 1.0);
    }
    // Each label is centred on the row its value is drawn in (the swatch's middle for one).
    let glyph = GLYPH * scale;
    let x = bar.x + bar.width + LEGEND_GAP * scale;
    for (k, label) in labels.iter().enumerate() {
        let centre = if single {
            fill.y + fill.height / 2
        } else {
            let from_top = (fill.height - 1) * (labels.len() - 1 - k) as u32 / (labels.len() - 1) as u32;
            fill.y + from_top
        };
        canvas.text(x, centre.saturating_sub(glyph / 2), scale, label);
    }
    Ok(Some(panel))
}

/// The font's cell: 8 × 8 pixels at 1×.
const GLYPH: u32 = 8;
/// Empty space between the panel and the picture's edges, at 1×.
const LEGEND_MARGIN: u32 = 6;
/// Empty space inside the panel around its content, at 1×.
const LEGEND_PAD: u32 = 4;
/// Between the title and the bar, and between the bar and its labels, at 1×.
const LEGEND_GAP: u32 = 4;
/// The bar's width, outline included, at 1×; also the swatch's height when `lo == hi`.
const BAR_WIDTH: u32 = 10;
/// The bar's outline, at 1×.
const BAR_OUTLINE: u32 = 1;
/// The bar's target height: this share of the picture's, within what fits.
const BAR_SHARE: f32 = 0.3;
/// Pictures this many pixels (the shorter side) per step of the legend's scale: 1× up to
/// 719, 2× at 720 (1280 × 720), 3× at 1080 (1920 × 1080); 4× at most.
const SCALE_STEP: u32 = 360;
const MAX_SCALE: u32 = 4;
/// Near white, 85 % opaque: dark text reads on it over a black picture (where the panel is
/// sRGB 211) as over a white one.
const PANEL_COLOR: [u8; 3] = [248, 248, 248];
const PANEL_ALPHA: f32 = 0.85;
const TEXT_COLOR: [u8; 3] = [20, 20, 20];
/// Mid grey: it bounds the bar's yellow top against the light panel without reading as text.
const OUTLINE_COLOR: [u8; 3] = [110, 110, 110];

/// Where the parts of a legend go in a picture.
struct LegendLayout {
    scale: u32,
    panel: PixelRect,
    /// The title as drawn: shortened to fit, or empty.
    title: String,
    /// The bar with its outline.
    bar: PixelRect,
    /// The colours inside the outline.
    fill: PixelRect,
}

impl LegendLayout {
    /// The layout of `legend` in a `width × height` picture ([`LegendLayout::fit`]).
    ///
    /// # Errors
    /// [`Error::Invalid`] for a non-finite legend range.
    fn of(width: u32, height: u32, legend: &Legend) -> Result<Option<LegendLayout>, Error> {
        if !legend.lo.is_finite() || !legend.hi.is_finite() {
            return Err(Error::Invalid {
                what: "legend range",
                value: format!("({}, {})", legend.lo, legend.hi),
                rule: "both ends must be finite".into(),
            });
        }
        Ok(LegendLayout::fit(width, height, &legend.title, &legend.tick_labels()))
    }

    /// The largest layout, at most at the picture's scale, that fits `width × height` with its
    /// margins; `None` when none does. `labels` are the tick labels, bottom to top.
    fn fit(width: u32, height: u32, title: &str, labels: &[String]) -> Option<LegendLayout> {
        let top_scale = (width.min(height) / SCALE_STEP).clamp(1, MAX_SCALE);
        (1..=top_scale).rev().find_map(|scale| LegendLayout::at(scale, width, height, title, labels))
    }

    fn at(scale: u32, width: u32, height: u32, title: &str, labels: &[String]) -> Option<LegendLayout> {
        let [glyph, margin, pad, gap, bar_w, outline] =
            [GLYPH, LEGEND_MARGIN, LEGEND_PAD, LEGEND_GAP, BAR_WIDTH, BAR_OUTLINE].map(|u| u * scale);
        let inner_w = width.checked_sub(2 * (margin + pad))?;
        let inner_h = height.checked_sub(2 * (margin + pad))?;
        let chars = |s: &str| s.chars().count() as u32;
        let label_w = labels.iter().map(|l| chars(l)).max().unwrap_or(0) * glyph;
        let body_w = bar_w + gap + label_w;
        if body_w > inner_w {
            return None;
        }
        // The title, shortened to the width there is ("displacem.."), or dropped below 3 glyphs.
        let room = (inner_w / glyph) as usize;
        let title: String = if title.chars().count() <= room {
            title.into()
        } else if room >= 3 {
            title.chars().take(room - 2).chain("..".chars()).collect()
        } else {
            String::new()
        };
        let title_h = if title.is_empty() { 0 } else { glyph + gap };

        let single = labels.len() <= 1;
        // Labels are centred on the bar's top and bottom rows: half a glyph sticks out at each
        // end. Three labels need the fill's half-height to exceed a glyph, by 2 pixels at 1×.
        let (overhang, min_fill) =
            if single { (0, bar_w - 2 * outline) } else { (glyph / 2, 2 * glyph + 4 * scale) };
        let room_h = inner_h.checked_sub(title_h + 2 * overhang)?;
        let target = ((height as f32 * BAR_SHARE) as u32).max(min_fill + 2 * outline);
        let bar_h = if single { bar_w } else { target.min(room_h) };
        if bar_h < min_fill + 2 * outline || bar_h > room_h {
            return None;
        }

        let content_w = body_w.max(chars(&title) * glyph);
        let panel_w = content_w + 2 * pad;
        let panel_h = title_h + 2 * overhang + bar_h + 2 * pad;
        let panel = PixelRect { x: width - margin - panel_w, y: margin, width: panel_w, height: panel_h };
        let bar = PixelRect {
            x: panel.x + pad,
            y: panel.y + pad + title_h + overhang,
            width: bar_w,
            height: bar_h,
        };
        let fill = PixelRect {
            x: bar.x + outline,
            y: bar.y + outline,
            width: bar_w - 2 * outline,
            height: bar_h - 2 * outline,
        };
        Some(LegendLayout { scale, panel, title, bar, fill })
    }
}

/// An RGBA8 picture being drawn on; every write is clipped to it.
struct Canvas<'a> {
    rgba: &'a mut [u8],
    width: u32,
    height: u32,
}

impl Canvas<'_> {
    /// Blends `color` over `rect` (clipped to the picture) with opacity `alpha`, in sRGB bytes
    /// as a viewer composites.
    fn blend_rect(&mut self, rect: PixelRect, color: [u8; 3], alpha: f32) {
        let x_end = rect.x.saturating_add(rect.width).min(self.width);
        let y_end = rect.y.saturating_add(rect.height).min(self.height);
        for y in rect.y.min(y_end)..y_end {
            let row = 4 * (y as usize * self.width as usize);
            for x in rect.x.min(x_end)..x_end {
                let px = &mut self.rgba[row + 4 * x as usize..][..4];
                for (c, &s) in px[..3].iter_mut().zip(&color) {
                    *c = (f32::from(*c) + (f32::from(s) - f32::from(*c)) * alpha).round() as u8;
                }
                px[3] = (f32::from(px[3]) + (255.0 - f32::from(px[3])) * alpha).round() as u8;
            }
        }
    }

    /// Draws `text` with its top-left corner at `(x, y)`, each font pixel `scale × scale`.
    fn text(&mut self, x: u32, y: u32, scale: u32, text: &str) {
        for (i, c) in text.chars().enumerate() {
            let left = x.saturating_add((i as u32).saturating_mul(GLYPH * scale));
            for (row, bits) in glyph(c).iter().enumerate() {
                for col in 0..GLYPH {
                    // The font's rows are bytes with the leftmost pixel in the lowest bit.
                    if bits & (1 << col) != 0 {
                        let cell = PixelRect {
                            x: left.saturating_add(col * scale),
                            y: y.saturating_add(row as u32 * scale),
                            width: scale,
                            height: scale,
                        };
                        self.blend_rect(cell, TEXT_COLOR, 1.0);
                    }
                }
            }
        }
    }
}

/// The 8×8 bitmap of `c`: ASCII, Latin-1 (`µ`, `²`, `°`) and Greek, else `?`.
fn glyph(c: char) -> [u8; 8] {
    use font8x8::{BASIC_FONTS, GREEK_FONTS, LATIN_FONTS, UnicodeFonts};
    BASIC_FONTS
        .get(c)
        .or_else(|| LATIN_FONTS.get(c))
        .or_else(|| GREEK_FONTS.get(c))
        .or_else(|| BASIC_FONTS.get('?'))
        .unwrap_or_default()
}

/// `v` to `sig` significant figures, trailing zeros dropped: `0.35`, `-1.2`, `1000`, and
/// `1.5e-5` or `2.5e6` outside 0.001..100000.
fn format_sig(v: f64, sig: usize) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 { "0".into() } else { v.to_string() };
    }
    let trim = |s: String| {
        if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
    };
    let exponent = v.abs().log10().floor() as i32;
    if (-3..5).contains(&exponent) {
        let decimals = (sig as i32 - 1 - exponent).max(0) as usize;
        trim(format!("{v:.decimals$}"))
    } else {
        let s = format!("{v:.prec$e}", prec = sig.saturating_sub(1));
        match s.split_once('e') {
            Some((mantissa, exp)) => format!("{}e{exp}", trim(mantissa.to_string())),
            None => s,
        }
    }
}

/// The coefficients of `viridis` in `shaders/render.wgsl`, `c0` to `c6` (keep in sync: a test
/// reads them from the shader and compares).
#[allow(clippy::excessive_precision, reason = "the shader's digits, as written there")]
const VIRIDIS: [[f32; 3]; 7] = [
    [0.2777273272234177, 0.005407344544966578, 0.3340998053353061],
    [0.1050930431085774, 1.404613529898575, 1.384590162594685],
    [-0.3308618287255563, 0.214847559468213, 0.09509516302823659],
    [-4.634230498983486, -5.799100973351585, -19.33244095627987],
    [6.228269936347081, 14.17993336680509, 56.69055260068105],
    [4.776384997670288, -13.74514537774601, -65.35303263337234],
    [-5.435455855934631, 4.645852612178535, 26.3124352495832],
];

/// The shader's colour map at `t` (clamped to `0..=1`) as the picture holds it: `viridis` in
/// f32, evaluated in the same (Horner) order, clamped, and sRGB-encoded to bytes. The shader
/// decodes the map's sRGB to linear and the target encodes it back; that round trip is the
/// identity but for rounding.
fn viridis_srgb8(t: f32) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    let [c0, c1, c2, c3, c4, c5, c6] = VIRIDIS;
    std::array::from_fn(|i| {
        let v = c0[i] + t * (c1[i] + t * (c2[i] + t * (c3[i] + t * (c4[i] + t * (c5[i] + t * c6[i])))));
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    })
}

/// The GPU objects of a [`Renderer`], built inside one error scope.
struct Built {
    pipeline: wgpu::RenderPipeline,
    params: Buffer,
    layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    /// The multisampled target, resolved into `resolved`; `None` at one sample, drawn
    /// straight into `resolved`.
    msaa: Option<TextureView>,
    depth: TextureView,
    resolved: Texture,
    readback: Buffer,
}

fn build(device: &Device, width: u32, height: u32, readback_size: u64, samples: u32) -> Built {
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
    let buffers = [Some(wgpu::VertexBufferLayout {
        array_stride: VERTEX_BYTES,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &attributes,
    })];
    let pipeline =
        mesh_pipeline(device, &pipeline_layout, &module, ("vs_main", &buffers), COLOR_FORMAT, samples);
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
        layout,
        bind_group,
        msaa: (samples > 1).then(|| {
            view(texture("voxcollide render msaa", samples, COLOR_FORMAT, TextureUsages::RENDER_ATTACHMENT))
        }),
        depth: depth_view(device, width, height, samples),
        resolved: texture(
            "voxcollide render resolved",
            1,
            COLOR_FORMAT,
            // Copied out for a read back; sampled by an app that composes it on the device.
            TextureUsages::RENDER_ATTACHMENT | TextureUsages::COPY_SRC | TextureUsages::TEXTURE_BINDING,
        ),
        readback: device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("voxcollide render readback"),
            size: readback_size,
            usage: BufferUsages::MAP_READ | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        }),
    }
}

/// The pipeline that draws triangles (two-sided, depth-tested) with `module`'s vertex stage
/// `vertex` and its fragment stage `fs_main` into `format` at `samples`: the host path's and the
/// device path's ([`DeviceMesh`]).
fn mesh_pipeline(
    device: &Device,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    (vertex, buffers): (&str, &[Option<wgpu::VertexBufferLayout<'_>>]),
    format: TextureFormat,
    samples: u32,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("voxcollide render"),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(vertex),
            compilation_options: Default::default(),
            buffers,
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
        multisample: wgpu::MultisampleState { count: samples, mask: !0, alpha_to_coverage_enabled: false },
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
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

/// A depth target of `width × height` at `samples`.
fn depth_view(device: &Device, width: u32, height: u32, samples: u32) -> TextureView {
    device
        .create_texture(&wgpu::TextureDescriptor {
            label: Some("voxcollide render depth"),
            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: samples,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        })
        .create_view(&wgpu::TextureViewDescriptor::default())
}

/// Checks a view's direction, scalar range and clip, and returns the clip as a plane `(n, d)`
/// with unit `n` (in `f64`, so huge coordinates cannot overflow the test).
fn checked_view(
    view_dir: Vec3,
    (lo, hi): (f32, f32),
    clip: Option<(Vec3, Vec3)>,
) -> Result<Option<DVec4>, Error> {
    let invalid =
        |what: &'static str, value: String, rule: &str| Error::Invalid { what, value, rule: rule.into() };
    let forward = view_dir.as_dvec3();
    if !forward.is_finite() || forward == DVec3::ZERO {
        return Err(invalid("view_dir", format!("{view_dir}"), "must be finite and non-zero"));
    }
    if !lo.is_finite() || !hi.is_finite() {
        return Err(invalid("scalar_range", format!("({lo}, {hi})"), "both ends must be finite"));
    }
    match clip {
        None => Ok(None),
        Some((point, normal)) => {
            let n = normal.as_dvec3().normalize_or_zero();
            if !point.is_finite() || n == DVec3::ZERO {
                return Err(invalid(
                    "clip",
                    format!("(point {point}, normal {normal})"),
                    "the point must be finite and the normal finite and non-zero",
                ));
            }
            Ok(Some(n.extend(-n.dot(point.as_dvec3()))))
        }
    }
}

/// Checks `scene`, expands its drawn triangles into `vertices`, collects the points to frame
/// into `framed`, and returns the uniform: camera, light and clip plane.
fn prepare(
    scene: &Scene,
    aspect: f64,
    eye: Option<Vec3>,
    keep: f64,
    vertices: &mut Vec<GpuVertex>,
    framed: &mut Vec<DVec3>,
) -> Result<GpuRenderParams, Error> {
    let invalid =
        |what: &'static str, value: String, rule: &str| Error::Invalid { what, value, rule: rule.into() };
    let plane = checked_view(scene.view_dir, scene.scalar_range, scene.clip)?;
    let view_dir = scene.view_dir.as_dvec3();
    let (lo, hi) = scene.scalar_range;
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

    let camera = match eye {
        // Framed in the left `keep` of the picture: for that part's aspect, then moved there
        // (x' = keep·x + (keep − 1)·w in clip space).
        None if keep < 1.0 => {
            let mut c = Camera::framing(framed, view_dir.normalize(), scene.up.as_dvec3(), aspect * keep);
            let squeeze = DMat4::from_cols(
                DVec4::new(keep, 0.0, 0.0, 0.0),
                DVec4::Y,
                DVec4::Z,
                DVec4::new(keep - 1.0, 0.0, 0.0, 1.0),
            );
            c.view_proj = squeeze * c.view_proj;
            c
        }
        None => Camera::framing(framed, view_dir.normalize(), scene.up.as_dvec3(), aspect),
        Some(eye) => {
            Camera::looking(eye.as_dvec3(), framed, view_dir.normalize(), scene.up.as_dvec3(), aspect)
        }
    };
    Ok(GpuRenderParams {
        view_proj: camera.view_proj.as_mat4().to_cols_array_2d(),
        light_dir: camera.light.as_vec3().extend(0.0).to_array(),
        clip_plane: plane.map_or([0.0; 4], |pl| pl.as_vec4().to_array()),
    })
}

/// A perspective camera that frames a set of points.
struct Camera {
    view_proj: DMat4,
    /// Where it is.
    eye: DVec3,
    /// Unit vector towards the light.
    light: DVec3,
}

impl Camera {
    /// Looks along `forward` (unit) with `up`, from where every point of `points` is in view
    /// with [`MARGIN`] to spare. The camera is centred on the points' extent across the view and
    /// backed off until the nearest-to-the-edge point fits, which frames a shape more tightly
    /// than a bounding sphere would.
    fn framing(points: &[DVec3], forward: DVec3, up: DVec3, aspect: f64) -> Camera {
        let (right, up, light) = Camera::axes(forward, up);
        if points.is_empty() {
            // Nothing to draw: any valid matrix does.
            return Camera { view_proj: DMat4::IDENTITY, eye: DVec3::ZERO, light };
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
        let eye = right * centre.x + up * centre.y + forward * eye_z;
        Camera { view_proj: DMat4::from_cols(x, y, z, w).transpose(), eye, light }
    }

    /// The camera's right and up (unit, perpendicular to `forward`), and the light.
    fn axes(forward: DVec3, up: DVec3) -> (DVec3, DVec3, DVec3) {
        let right = forward.cross(up).normalize_or_zero();
        let right = if right == DVec3::ZERO { forward.any_orthonormal_vector() } else { right };
        let up = right.cross(forward);
        // The headlight sits a little above and left of the eye, so that faces facing the
        // viewer squarely still differ in brightness from their neighbours.
        let light = (-forward + 0.35 * up - 0.25 * right).normalize();
        (right, up, light)
    }

    /// At `eye`, looking along `forward` (unit) with `up`; the near and far planes bound the
    /// points in front of the eye (those behind it are clipped).
    fn looking(eye: DVec3, points: &[DVec3], forward: DVec3, up: DVec3, aspect: f64) -> Camera {
        let (right, up, light) = Camera::axes(forward, up);
        let depths = points.iter().map(|p| (*p - eye).dot(forward));
        let (lo, hi) =
            depths.fold(
                (f64::INFINITY, 0.0f64),
                |(lo, hi), d| {
                    if d > 0.0 { (lo.min(d), hi.max(d)) } else { (lo, hi) }
                },
            );
        let far = if hi > 0.0 { 1.05 * hi } else { 1.0 };
        let near = if lo.is_finite() { (0.5 * lo).max(1e-4 * far) } else { 1e-3 * far };
        let f = 1.0 / (FOV_Y / 2.0).tan();
        let (a, b) = (far / (far - near), -near * far / (far - near));
        let row = |axis: DVec3, scale: f64| (axis * scale).extend(-eye.dot(axis) * scale);
        let (x, y, w) = (row(right, f / aspect), row(up, f), row(forward, 1.0));
        let z = w * a + DVec4::new(0.0, 0.0, 0.0, b);
        Camera { view_proj: DMat4::from_cols(x, y, z, w).transpose(), eye, light }
    }
}

/// Where [`Renderer::render`] puts the camera to frame `points` looking along `view_dir` with
/// `up`, for a picture of aspect `width / height`: a live view starts there and orbits from it.
#[must_use]
pub fn framing_eye(points: &[Vec3], view_dir: Vec3, up: Vec3, aspect: f32) -> Option<Vec3> {
    let forward = view_dir.as_dvec3().normalize_or_zero();
    if points.is_empty() || forward == DVec3::ZERO {
        return None;
    }
    let points: Vec<DVec3> = points.iter().map(|p| p.as_dvec3()).filter(|p| p.is_finite()).collect();
    let camera = Camera::framing(&points, forward, up.as_dvec3(), f64::from(aspect));
    (!points.is_empty() && camera.eye.is_finite()).then(|| camera.eye.as_vec3())
}

/// [`Error::Invalid`] unless `rgba` is `width * height * 4` bytes.
fn check_rgba(rgba: &[u8], width: u32, height: u32) -> Result<(), Error> {
    let needed = 4 * u64::from(width) * u64::from(height);
    if rgba.len() as u64 != needed {
        return Err(Error::Invalid {
            what: "rgba length",
            value: rgba.len().to_string(),
            rule: format!("must be width × height × 4 = {needed} for {width} × {height}"),
        });
    }
    Ok(())
}

/// Draws `lines` of text in the top-left corner of `rgba` (RGBA8, sRGB-encoded, as
/// [`Renderer::render`] returns it) on the legend's light panel, in its 8×8 font at its scale
/// for the picture's size; a line too long is cut at the picture's edge. Returns the panel, or
/// `None` when nothing fits.
///
/// # Errors
/// [`Error::Invalid`] when `rgba` is not `width * height * 4` bytes.
pub fn draw_caption(
    rgba: &mut [u8],
    width: u32,
    height: u32,
    lines: &[String],
) -> Result<Option<PixelRect>, Error> {
    check_rgba(rgba, width, height)?;
    let scale = (width.min(height) / SCALE_STEP).clamp(1, MAX_SCALE);
    let [glyph, margin, pad] = [GLYPH, LEGEND_MARGIN, LEGEND_PAD].map(|u| u * scale);
    let Some(room) = width.checked_sub(2 * (margin + pad)).map(|w| (w / glyph) as usize) else {
        return Ok(None);
    };
    let lines: Vec<String> = lines.iter().map(|l| l.chars().take(room).collect()).collect();
    let widest = lines.iter().map(|l| l.chars().count() as u32).max().unwrap_or(0);
    let line_h = glyph + glyph / 2;
    let panel_h = lines.len() as u32 * line_h + 2 * pad;
    if widest == 0 || room == 0 || panel_h + 2 * margin > height {
        return Ok(None);
    }
    let panel = PixelRect { x: margin, y: margin, width: widest * glyph + 2 * pad, height: panel_h };
    let mut canvas = Canvas { rgba, width, height };
    canvas.blend_rect(panel, PANEL_COLOR, PANEL_ALPHA);
    for (k, line) in lines.iter().enumerate() {
        canvas.text(panel.x + pad, panel.y + pad + k as u32 * line_h + glyph / 4, scale, line);
    }
    Ok(Some(panel))
}
