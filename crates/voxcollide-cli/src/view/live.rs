//! The window: winit's event loop, a wgpu surface on an adapter that can present to it, the
//! simulation stepped on that adapter (or the CPU), and each frame drawn offscreen, annotated
//! and copied onto the window.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use glam::Vec3;
use voxcollide::{ContactReport, Error, GpuContext};
use voxcollide_sim::build::Built;
use voxcollide_sim::geometry::{ClosedSurface, penetration};
use voxcollide_sim::scene_file::{BodyKind, SceneFile};
use voxcollide_sim::{Mode, World};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{Key, ModifiersState, NamedKey};
use winit::window::{Window, WindowId};

use super::blit::Blit;
use super::controls::{Action, Colouring, HELP, Orbit};
use super::stepper::{Snapshot, Stepper};
use super::{ViewConfig, ViewReport};
use crate::backend::{OnSoftware, place};
use crate::scene_run::{contact_forces, meshes, shown_and_moved};
use voxcollide_render::{
    DeviceMesh, DeviceView, Legend, Renderer, Scene as RenderScene, draw_caption, draw_legend, framing_eye,
    legend_panel, write_png,
};
use voxcollide_sim::simulation;

/// The frame time aimed at: 40 frames a second, a margin over the 30 a live view needs. The
/// simulation steps on its own thread meanwhile (`super::stepper`).
const FRAME_TARGET: f64 = 1.0 / 40.0;
/// The farthest a dragged body moves in one step, as a share of the scene's size: far below
/// the speed a blow-up is taken at (a tenth of the scene a step).
const DRAG_PER_STEP: f32 = 0.002;
/// The first view: the run's pictures' (from the front, a little to the side, from above).
const FIRST_VIEW: Vec3 = Vec3::new(0.3, 1.0, -0.35);
/// Body colours where they are not colour-mapped, as in the run's pictures.
const COLOURS: [[f32; 3]; 4] = [[0.95, 0.6, 0.25], [0.45, 0.55, 0.7], [0.6, 0.8, 0.5], [0.8, 0.5, 0.7]];
/// Wall seconds between the states the window takes while it draws the bodies from the
/// device (the heads-up numbers' refresh; on the GPU backend, its read-backs).
const SNAPSHOT_EVERY: f64 = 0.1;

/// Why the view could not go on.
pub(super) enum Failure {
    /// No display to open a window on.
    NoDisplay(String),
    /// Anything else.
    Error(Error),
}

/// Runs the window until it closes.
pub(super) fn run(
    config: &ViewConfig,
    file: &SceneFile,
    built: Built,
    note: &mut dyn FnMut(&str),
) -> Result<ViewReport, Failure> {
    let event_loop = EventLoop::new().map_err(|e| Failure::NoDisplay(e.to_string()))?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut app = App { config, file, built: Some(built), note, live: None, outcome: None };
    event_loop.run_app(&mut app).map_err(|e| {
        Failure::Error(Error::Invalid {
            what: "window",
            value: e.to_string(),
            rule: "the event loop failed".into(),
        })
    })?;
    match app.outcome {
        Some(Ok(report)) => Ok(report),
        Some(Err(e)) => Err(Failure::Error(e)),
        None => Err(Failure::Error(Error::Invalid {
            what: "window",
            value: "closed".into(),
            rule: "the event loop ended before the window opened".into(),
        })),
    }
}

struct App<'a> {
    config: &'a ViewConfig,
    file: &'a SceneFile,
    built: Option<Built>,
    note: &'a mut dyn FnMut(&str),
    live: Option<Live>,
    outcome: Option<Result<ViewReport, Error>>,
}

impl App<'_> {
    /// Ends the view with `outcome` (the report, or an error).
    fn finish(&mut self, event_loop: &ActiveEventLoop, outcome: Result<ViewReport, Error>) {
        if self.outcome.is_none() {
            self.outcome = Some(outcome);
        }
        // The window closes as `live` drops (its surface first).
        self.live = None;
        event_loop.exit();
    }
}

impl ApplicationHandler for App<'_> {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        let Some(built) = self.built.take() else { return };
        match Live::new(event_loop, self.config, self.file, built, self.note) {
            Ok(live) => {
                (self.note)(HELP);
                live.window.request_redraw();
                self.live = Some(live);
            }
            Err(e) => self.finish(event_loop, Err(e)),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        let Some(live) = self.live.as_mut() else { return };
        match event {
            WindowEvent::CloseRequested | WindowEvent::Destroyed => {
                let report = live.report();
                self.finish(event_loop, Ok(report));
            }
            WindowEvent::Resized(size) => live.resize(size),
            WindowEvent::ModifiersChanged(m) => live.modifiers = m.state(),
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                let text = match &event.logical_key {
                    Key::Character(c) => c.to_string(),
                    Key::Named(NamedKey::Space) => " ".into(),
                    Key::Named(NamedKey::Escape) => "escape".into(),
                    Key::Named(NamedKey::ArrowRight) => ".".into(),
                    _ => String::new(),
                };
                match Action::of_key(&text) {
                    Some(Action::Close) => {
                        let report = live.report();
                        self.finish(event_loop, Ok(report));
                    }
                    Some(action) => live.act(action),
                    None => {}
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                live.pointer_to(position.x as f32, position.y as f32)
            }
            WindowEvent::MouseInput { state, button, .. } => {
                live.button(button, state == ElementState::Pressed);
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                live.orbit.zoom(lines);
            }
            WindowEvent::RedrawRequested => match live.frame() {
                Ok(true) => {
                    let done = live.screenshot().map(|()| live.report());
                    self.finish(event_loop, done);
                }
                Ok(false) => live.window.request_redraw(),
                Err(e) => self.finish(event_loop, Err(e)),
            },
            _ => {}
        }
    }

    fn about_to_wait(&mut self, _: &ActiveEventLoop) {
        if let Some(live) = &self.live {
            live.window.request_redraw();
        }
    }
}

/// Offsets the user has dragged bodies by: where each should be (`target`) and where it is
/// (`now`, which follows the target by at most `per_step` a step).
#[derive(Debug)]
struct Drags {
    target: Vec<Vec3>,
    now: Vec<Vec3>,
    per_step: f32,
}

/// `world` with its schedule's drives offset by `drags`, each body's offset catching up with
/// its target by at most `per_step` a step.
fn draggable(mut world: World, drags: &Arc<Mutex<Drags>>) -> World {
    let base = world.schedule.clone();
    let drags = drags.clone();
    world.schedule = Arc::new(move |step| {
        let mut inputs = base(step);
        let Ok(mut d) = drags.lock() else { return inputs };
        let d = &mut *d;
        for ((input, now), target) in inputs.iter_mut().zip(d.now.iter_mut()).zip(&d.target) {
            let to_go = *target - *now;
            let length = to_go.length();
            *now += if length > d.per_step { to_go * (d.per_step / length) } else { to_go };
            input.drive += *now;
        }
        inputs
    });
    world
}

/// A body held by the pointer: which, at what depth, and where the pointer was.
#[derive(Clone, Copy, Debug)]
struct Grab {
    body: usize,
    depth: f32,
    last: (f32, f32),
}

/// The open window and everything it shows.
struct Live {
    // The surface is declared (and dropped) before the window it draws into.
    surface: wgpu::Surface<'static>,
    window: Arc<Window>,
    surface_config: wgpu::SurfaceConfiguration,
    ctx: GpuContext,
    adapter: String,
    renderer: Renderer,
    blit: Blit,
    scene_name: String,
    units: String,
    /// The world at its first step (with draggable drives), for a reset.
    first: World,
    /// The simulation, stepping on its own thread.
    stepper: Stepper,
    /// The state last drawn (what a press picks from, and what is drawn again while stopped).
    shown: Option<Snapshot>,
    backend: &'static str,
    soft: Vec<bool>,
    /// Bodies with driven vertices: what a drag can move.
    movable: Vec<bool>,
    drags: Arc<Mutex<Drags>>,
    dragged: f32,
    /// Where each movable body's centre was drawn in the first frame.
    instruments: Vec<(String, [f32; 2])>,
    /// The scene's extent at rest.
    size: f32,
    orbit: Orbit,
    framed: Orbit,
    paused: bool,
    step_once: bool,
    colouring: Colouring,
    force_scale: f32,
    steps_per_frame: Option<u64>,
    pointer: (f32, f32),
    left: bool,
    right: bool,
    modifiers: ModifiersState,
    grab: Option<Grab>,
    frames: u64,
    frames_wanted: Option<u64>,
    script: Option<super::ScriptedDrag>,
    started: Option<Instant>,
    /// The states read from the run when the first frame started, and when the last ended.
    states_at: (u64, u64),
    last_frame: Option<Instant>,
    behind_frames: u64,
    behind: bool,
    fps: f64,
    sps: f64,
    stepped_since: (Instant, u64),
    /// Simulated seconds per wall second lately, and where that was last measured from.
    realtime: f64,
    timed_since: (Instant, f64),
    steps: u64,
    /// Simulated seconds since the start or the last reset.
    time: f64,
    /// A blow-up's message, shown until a reset.
    broken: Option<Error>,
    /// Something else the heads-up line should say (a size it cannot draw).
    notice: Option<String>,
    /// Whether the renderer's picture holds a frame (shown again, with the message, while
    /// stopped), and the legend it was drawn with.
    drawn: bool,
    legend: Option<Legend>,
    /// The overlay's bytes (legend and heads-up lines), kept to reuse the allocation.
    overlay: Vec<u8>,
    /// On the GPU backend: each body's positions on the device, for drawing them where they
    /// are; and the meshes bound to them (made on first use, again after a reset or resize).
    buffers: Vec<wgpu::Buffer>,
    device_meshes: Option<Vec<DeviceMesh>>,
    /// Whether the adapter cannot draw from device buffers (its vertex stage reads no storage
    /// buffers): frames are then drawn from the read-back positions.
    device_refused: bool,
    /// Frames whose bodies were drawn from their positions on the device.
    frames_from_device: u64,
    /// Whether the screenshot was written.
    shot: bool,
    /// Steps over the whole view, resets included.
    steps_total: u64,
    /// When the last frame was done.
    ended: Option<Instant>,
    /// The last frame's measures: contacts, deepest penetration, largest displacement per body.
    contacts: usize,
    penetration: f32,
    displacement: Vec<f32>,
    displacement_centre: Vec<[f32; 3]>,
    /// Seconds a frame's measuring and drawing took lately (a running mean).
    draw_time: f64,
    screenshot: Option<std::path::PathBuf>,
}

impl Live {
    fn new(
        event_loop: &ActiveEventLoop,
        config: &ViewConfig,
        file: &SceneFile,
        built: Built,
        note: &mut dyn FnMut(&str),
    ) -> Result<Live, Error> {
        let attributes = Window::default_attributes()
            .with_title(format!("voxcollide view: {}", config.scene))
            .with_inner_size(PhysicalSize::new(config.size.0, config.size.1));
        let window = Arc::new(event_loop.create_window(attributes).map_err(|e| Error::Invalid {
            what: "window",
            value: e.to_string(),
            rule: "the display refused to open one".into(),
        })?);
        let (surface, adapter) = surface_and_adapter(event_loop, window.clone())?;
        let info = adapter.get_info();
        let adapter_name = format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("voxcollide view"),
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| Error::NoAdapter {
            message: format!("could not open a device on {adapter_name}: {e}"),
        })?;
        let ctx = GpuContext::from_adapter(&adapter, device, queue);
        let size = window.inner_size();
        let (width, height) = (size.width.max(1), size.height.max(1));
        let mut surface_config = surface.get_default_config(&adapter, width, height).ok_or_else(|| {
            Error::NoAdapter { message: format!("{adapter_name} cannot present to this window") }
        })?;
        surface_config.present_mode = wgpu::PresentMode::AutoNoVsync;
        surface.configure(ctx.device(), &surface_config);
        let renderer = Renderer::fast(&ctx, width, height)?;
        let blit = Blit::new(ctx.device(), surface_config.format, renderer.picture_view(), (width, height));

        let world = &built.world;
        let extent = world
            .bodies
            .iter()
            .flat_map(|b| b.pos.iter())
            .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        let scene_size = (extent.1 - extent.0).max_element().max(f32::MIN_POSITIVE);
        let centre = 0.5 * (extent.0 + extent.1);
        let drags = Arc::new(Mutex::new(Drags {
            target: vec![Vec3::ZERO; world.bodies.len()],
            now: vec![Vec3::ZERO; world.bodies.len()],
            per_step: DRAG_PER_STEP * scene_size,
        }));
        let first = draggable(built.world.clone(), &drags);
        // A software adapter only draws here: the frames compete with the steps for its cores.
        let placed = place(config.backend, Some(&ctx), "", first.clone(), OnSoftware::Draws, note)?;
        let on_gpu = placed.backend == "gpu";
        let buffers = device_buffers(&*placed.run, world.bodies.len());
        let stepper = Stepper::start(placed.run, f64::from(built.dt), config.steps_per_frame.is_some())?;
        // Drawn from the device from the first frame on (the GPU backend, coloured by
        // displacement): a state a few times a second will do from the start, not after every
        // batch until that frame has drawn.
        if on_gpu && config.colouring == Colouring::Displacement {
            stepper.set_snapshot_every(SNAPSHOT_EVERY);
        }
        let points: Vec<Vec3> = world.bodies.iter().flat_map(|b| b.pos.iter().copied()).collect();
        // Framed left of the legend's panel, so that it covers none of the bodies: framed for
        // the window's width less the panel's, and the camera moved right by half the panel.
        let legend = Legend::new(format!("displacement ({})", file.units.symbol()), (0.0, scene_size));
        let clear = legend_panel(width, height, &legend)?.map_or(0, |p| width - p.x);
        let clear = if 2 * clear < width { clear } else { 0 };
        let framed = framing_eye(&points, FIRST_VIEW, Vec3::Z, (width - clear) as f32 / height as f32)
            .unwrap_or(centre - FIRST_VIEW.normalize() * 3.0 * scene_size);
        let forward = FIRST_VIEW.normalize();
        let depth = (centre - framed).dot(forward);
        let per_pixel =
            2.0 * depth * (0.5 * voxcollide_render::FOV_Y_DEGREES as f32).to_radians().tan() / height as f32;
        let eye = framed + forward.cross(Vec3::Z).normalize() * (0.5 * clear as f32 * per_pixel);
        let orbit = Orbit::from_eye(eye, FIRST_VIEW, centre);
        let backend = if on_gpu { "gpu" } else { "cpu" };
        note(&format!("{} on the {backend} backend, drawn on {adapter_name}", config.scene));
        let now = Instant::now();
        Ok(Live {
            surface,
            window,
            surface_config,
            adapter: adapter_name,
            renderer,
            blit,
            scene_name: config.scene.clone(),
            units: file.units.symbol().to_string(),
            soft: file.bodies.iter().map(|b| b.kind == BodyKind::Soft).collect(),
            movable: world.bodies.iter().map(|b| b.mode.contains(&Mode::Driven)).collect(),
            first,
            stepper,
            shown: None,
            backend,
            drags,
            dragged: 0.0,
            instruments: Vec::new(),
            size: scene_size,
            orbit,
            framed: orbit,
            paused: false,
            step_once: false,
            colouring: config.colouring,
            force_scale: 0.0,
            draw_time: 0.0,
            steps_per_frame: config.steps_per_frame,
            pointer: (0.0, 0.0),
            left: false,
            right: false,
            modifiers: ModifiersState::empty(),
            grab: None,
            frames: 0,
            frames_wanted: config.frames,
            script: config.drag,
            started: None,
            states_at: (0, 0),
            last_frame: None,
            behind_frames: 0,
            behind: false,
            fps: 0.0,
            sps: 0.0,
            stepped_since: (now, 0),
            realtime: 0.0,
            timed_since: (now, 0.0),
            steps: 0,
            time: 0.0,
            broken: None,
            notice: None,
            drawn: false,
            legend: None,
            overlay: Vec::new(),
            buffers,
            device_meshes: None,
            device_refused: false,
            frames_from_device: 0,
            shot: false,
            steps_total: 0,
            ended: None,
            contacts: 0,
            penetration: 0.0,
            displacement: vec![0.0; world.bodies.len()],
            displacement_centre: vec![[0.0; 3]; world.bodies.len()],
            screenshot: config.screenshot.clone(),
            ctx,
        })
    }

    /// Follows the window to `size`. A size the device cannot draw (beyond its largest
    /// texture) keeps the last one, and the heads-up line says why.
    fn resize(&mut self, size: PhysicalSize<u32>) {
        let (width, height) = (size.width.max(1), size.height.max(1));
        if (width, height) == (self.surface_config.width, self.surface_config.height) {
            return;
        }
        let largest = self.ctx.device().limits().max_texture_dimension_2d;
        if width > largest || height > largest {
            self.notice = Some(format!(
                "{width}x{height} is beyond the device's {largest} pixels: drawn at the last size"
            ));
            return;
        }
        match Renderer::fast(&self.ctx, width, height) {
            Ok(r) => self.renderer = r,
            Err(e) => {
                self.notice = Some(format!("drawn at the last size: {e}"));
                return;
            }
        }
        self.notice = None;
        self.surface_config.width = width;
        self.surface_config.height = height;
        self.surface.configure(self.ctx.device(), &self.surface_config);
        self.blit.resize(self.ctx.device(), self.renderer.picture_view(), (width, height));
        // The meshes were bound to the old renderer, and its picture is gone.
        self.device_meshes = None;
        self.drawn = false;
    }

    fn act(&mut self, action: Action) {
        match action {
            Action::TogglePause => {
                self.paused = !self.paused;
                self.stepper.set_paused(self.paused);
            }
            Action::Step => {
                self.paused = true;
                self.stepper.set_paused(true);
                self.step_once = true;
            }
            Action::Reset => {
                if let Ok(mut d) = self.drags.lock() {
                    let d = &mut *d;
                    d.target.iter_mut().chain(d.now.iter_mut()).for_each(|v| *v = Vec3::ZERO);
                }
                let on_gpu = self.backend == "gpu";
                match simulation(on_gpu.then_some(&self.ctx), self.first.clone()) {
                    Ok(sim) => {
                        self.buffers = device_buffers(&*sim, self.first.bodies.len());
                        self.device_meshes = None;
                        self.stepper.reset(sim);
                        self.steps = 0;
                        self.time = 0.0;
                        self.timed_since = (Instant::now(), 0.0);
                        self.broken = None;
                        self.force_scale = 0.0;
                    }
                    Err(e) => self.broken = Some(e),
                }
            }
            Action::CycleColouring => self.colouring = self.colouring.next(),
            Action::Frame => self.orbit = self.framed,
            Action::Close => {}
        }
    }

    fn pointer_to(&mut self, x: f32, y: f32) {
        let (dx, dy) = (x - self.pointer.0, y - self.pointer.1);
        self.pointer = (x, y);
        let height = self.surface_config.height;
        if let Some(g) = self.grab.as_mut() {
            let moved = self.orbit.drag_in_view_plane(x - g.last.0, y - g.last.1, g.depth, height);
            g.last = (x, y);
            if let Ok(mut d) = self.drags.lock() {
                d.target[g.body] += moved;
            }
            self.dragged += moved.length();
        } else if self.right || (self.left && self.modifiers.shift_key()) {
            self.orbit.pan(dx, dy, height);
        } else if self.left {
            self.orbit.rotate(dx, dy);
        }
    }

    fn button(&mut self, button: MouseButton, pressed: bool) {
        match button {
            MouseButton::Left => {
                self.left = pressed;
                self.grab = if pressed && !self.modifiers.shift_key() { self.pick() } else { None };
            }
            MouseButton::Right => self.right = pressed,
            _ => {}
        }
    }

    /// The movable body under the pointer (a driven vertex within 24 pixels of it; of several,
    /// the nearest the camera: the surface seen there, not the hidden side behind it), to drag
    /// at that vertex's depth.
    fn pick(&mut self) -> Option<Grab> {
        let (w, h) = (self.surface_config.width, self.surface_config.height);
        let (x, y) = self.pointer;
        let world = &self.shown.as_ref()?.world;
        let mut best: Option<(usize, f32)> = None;
        for (k, b) in world.bodies.iter().enumerate().filter(|(k, _)| self.movable[*k]) {
            for (p, m) in b.pos.iter().zip(&b.mode) {
                if *m != Mode::Driven {
                    continue;
                }
                if let Some((px, py, depth)) = self.orbit.project(*p, w, h) {
                    let d2 = (px - x).powi(2) + (py - y).powi(2);
                    if d2 < 24.0 * 24.0 && best.is_none_or(|(_, nearest)| depth < nearest) {
                        best = Some((k, depth));
                    }
                }
            }
        }
        best.map(|(body, depth)| Grab { body, depth, last: (x, y) })
    }

    /// Steps, draws and presents one frame; `Ok(true)` when the frames asked for are drawn.
    fn frame(&mut self) -> Result<bool, Error> {
        // The scripted pointer acts as the mouse would, before the frame's steps.
        if let Some(script) = self.script
            && let Some((x, y, pressed)) = script.at(self.frames)
        {
            if pressed && !self.left {
                self.pointer = (x, y);
                self.button(MouseButton::Left, true);
            } else {
                self.pointer_to(x, y);
                if !pressed {
                    self.button(MouseButton::Left, false);
                }
            }
        }
        self.frame_with()
    }

    fn frame_with(&mut self) -> Result<bool, Error> {
        let now = Instant::now();
        if self.started.is_none() {
            self.started = Some(now);
            self.states_at.0 = self.stepper.snapshots();
        }
        let elapsed = self.last_frame.map_or(0.0, |t| now.duration_since(t).as_secs_f64());
        self.last_frame = Some(now);
        if elapsed > 0.0 {
            self.fps = if self.fps > 0.0 { 0.9 * self.fps + 0.1 / elapsed } else { 1.0 / elapsed };
        }

        // Steps: the thread's, in real time; or the fixed count, waited for; or one while
        // paused.
        if self.broken.is_none() {
            match (self.paused, self.steps_per_frame) {
                (true, _) => {
                    if std::mem::take(&mut self.step_once) {
                        self.stepper.step_once();
                    }
                }
                (false, Some(n)) => self.stepper.step_and_wait(n),
                (false, None) => {}
            }
        }
        let (steps_total, behind, broken) = self.stepper.status();
        if broken.is_some() {
            self.broken = broken;
        }
        self.behind = behind && !self.paused;
        self.behind_frames += u64::from(self.behind);
        self.steps_total = steps_total;
        // A state not seen before is measured once; frames drawn from it again reuse its figures.
        let fresh = match self.stepper.take_latest() {
            Some(latest) => {
                self.steps = latest.steps;
                self.time = latest.time;
                self.shown = Some(latest);
                true
            }
            None => false,
        };
        let shown = if self.broken.is_some() { None } else { self.shown.take() };
        let since = now.duration_since(self.stepped_since.0).as_secs_f64();
        if since >= 0.5 {
            self.sps = (self.steps_total.saturating_sub(self.stepped_since.1)) as f64 / since;
            self.stepped_since = (now, self.steps_total);
            self.realtime = (self.time - self.timed_since.1).max(0.0) / since;
            self.timed_since = (now, self.time);
        }
        // A run of --frames ends with the error; an interactive one shows it until a reset.
        if let (Some(e), Some(_)) = (&self.broken, self.frames_wanted) {
            return Err(e.clone());
        }
        let drawing = Instant::now();
        match shown {
            Some(snapshot) => {
                if fresh || self.frames == 0 {
                    self.measure(&snapshot.world, &snapshot.reports);
                }
                if self.frames == 0 {
                    self.locate_instruments(&snapshot.world);
                }
                let drawn = self.draw(&snapshot.world, &snapshot.reports);
                self.shown = Some(snapshot);
                drawn?;
                self.show()?;
            }
            // Stopped: the last frame again, with the message.
            None => self.show()?,
        }
        let took = drawing.elapsed().as_secs_f64();
        self.draw_time = if self.draw_time > 0.0 { 0.8 * self.draw_time + 0.2 * took } else { took };
        self.frames += 1;
        self.ended = Some(Instant::now());
        self.states_at.1 = self.stepper.snapshots();
        let done = self.frames_wanted.is_some_and(|n| self.frames >= n);
        // Interactive, at most the frame rate aimed at: a fast GPU need not spin a core. A run
        // of --frames goes as fast as it can, to measure it.
        if self.frames_wanted.is_none() {
            let spent = now.elapsed().as_secs_f64();
            if spent < FRAME_TARGET {
                std::thread::sleep(std::time::Duration::from_secs_f64(FRAME_TARGET - spent));
            }
        }
        Ok(done)
    }

    /// Where each instrument is drawn: the window pixel of the driven vertex that shows
    /// nearest its centre on the screen, among those on the side facing the camera (the near
    /// half of their depths: a shell's far side projects near its centre too, hidden), where
    /// a press takes hold of it.
    fn locate_instruments(&mut self, world: &World) {
        let (w, h) = (self.surface_config.width, self.surface_config.height);
        for (k, b) in world.bodies.iter().enumerate().filter(|(k, _)| self.movable[*k]) {
            let driven: Vec<Vec3> =
                b.pos.iter().zip(&b.mode).filter(|(_, m)| **m == Mode::Driven).map(|(p, _)| *p).collect();
            let centre = driven.iter().copied().sum::<Vec3>() / driven.len().max(1) as f32;
            let Some((cx, cy, _)) = self.orbit.project(centre, w, h) else { continue };
            let shown: Vec<(f32, f32, f32)> =
                driven.iter().filter_map(|p| self.orbit.project(*p, w, h)).collect();
            let (near, far) = shown.iter().fold((f32::MAX, f32::MIN), |(a, b), p| (a.min(p.2), b.max(p.2)));
            let facing = shown.iter().filter(|p| p.2 <= 0.5 * (near + far));
            let at = |p: &&(f32, f32, f32)| (p.0 - cx).powi(2) + (p.1 - cy).powi(2);
            if let Some((x, y, _)) = facing.min_by(|p, q| at(p).total_cmp(&at(q))) {
                self.instruments.push((world.names[k].clone(), [*x, *y]));
            }
        }
    }

    fn measure(&mut self, world: &World, reports: &[ContactReport]) {
        self.contacts = reports.iter().map(|r| r.colliding_b.len()).sum();
        self.displacement = world
            .bodies
            .iter()
            .map(|b| b.pos.iter().zip(b.start()).map(|(p, r)| p.distance(*r)).fold(0.0, f32::max))
            .collect();
        self.displacement_centre = world
            .bodies
            .iter()
            .map(|b| {
                let (mut sum, mut weight) = (glam::DVec3::ZERO, 0.0f64);
                for (p, r) in b.pos.iter().zip(b.start()) {
                    let w = f64::from(p.distance(*r));
                    sum += w * r.as_dvec3();
                    weight += w;
                }
                let centre = if weight > 0.0 {
                    sum / weight
                } else {
                    b.rest_pos.iter().map(|r| r.as_dvec3()).sum::<glam::DVec3>() / b.len().max(1) as f64
                };
                centre.as_vec3().to_array()
            })
            .collect();
        // The deepest vertex of b inside a's closed surface (a's shown surface), over the pairs.
        self.penetration = world
            .contacts
            .iter()
            .filter_map(|pair| {
                let (positions, mesh) = crate::scene_run::shown_surface(&world.bodies[pair.a]);
                let surface = ClosedSurface::new(&positions, mesh).ok()?;
                Some(penetration(&surface, &world.bodies[pair.b].pos).max_depth)
            })
            .fold(0.0, f32::max);
    }

    /// Draws the frame's bodies in their colouring into the renderer's picture, on the
    /// device: from their positions there where they step on the GPU (coloured by
    /// displacement, each drawn by its own surface), else from `world`'s. Nothing is read back.
    fn draw(&mut self, world: &World, reports: &[ContactReport]) -> Result<(), Error> {
        let eye = Some(self.orbit.eye());
        let (range, title) = match self.colouring {
            Colouring::Displacement => ((0.0, 0.1 * self.size), format!("displacement ({})", self.units)),
            Colouring::ContactForce => ((0.0, 0.0), "contact force (N)".to_string()),
        };
        let from_device = self.colouring == Colouring::Displacement && self.device_meshes_ready(world);
        // Drawn from the device, a state read back serves only the heads-up numbers: a few a
        // second will do.
        self.stepper.set_snapshot_every(if from_device { SNAPSHOT_EVERY } else { 0.0 });
        let range = if from_device {
            let meshes: Vec<&DeviceMesh> = self.device_meshes.iter().flatten().collect();
            let view = DeviceView {
                scalar_range: range,
                clip: None,
                view_dir: self.orbit.view_dir(),
                up: Vec3::Z,
                eye,
            };
            self.renderer.draw_picture_device(&meshes, &view)?;
            self.frames_from_device += 1;
            range
        } else {
            let mut shown = shown_and_moved(world);
            let range = match self.colouring {
                Colouring::Displacement => range,
                Colouring::ContactForce => {
                    for (k, (_, values)) in shown.iter_mut().enumerate() {
                        *values = contact_force(world, reports, k);
                    }
                    let top = shown.iter().flat_map(|s| s.1.iter()).fold(0.0f32, |a, &b| a.max(b));
                    // The scale only grows, so that colours compare across frames.
                    self.force_scale = self.force_scale.max(top).max(f32::MIN_POSITIVE);
                    (0.0, self.force_scale)
                }
            };
            let soft = &self.soft;
            let scene = RenderScene {
                meshes: meshes(world, &shown, |k| soft[k], |k| COLOURS[k % COLOURS.len()]),
                scalar_range: range,
                clip: None,
                view_dir: self.orbit.view_dir(),
                up: Vec3::Z,
            };
            self.renderer.draw_picture(&scene, eye)?;
            range
        };
        self.legend = Some(Legend::new(title, range));
        self.drawn = true;
        Ok(())
    }

    /// Whether the bodies can be drawn from their positions on the device: they step on the
    /// GPU, each is drawn by its own surface (a user's surface carried by the lattice is
    /// interpolated on the host, and so is a scanned skin), and the adapter draws from storage buffers. Binds the meshes
    /// the first time.
    fn device_meshes_ready(&mut self, world: &World) -> bool {
        if self.device_refused
            || self.buffers.len() != world.bodies.len()
            || world.bodies.iter().any(|b| b.embedded.is_some() || b.skin.is_some())
        {
            return false;
        }
        if self.device_meshes.is_none() {
            let made: Result<Vec<DeviceMesh>, Error> = self
                .first
                .bodies
                .iter()
                .zip(&self.buffers)
                .enumerate()
                .map(|(k, (b, buffer))| {
                    let colour = COLOURS[k % COLOURS.len()];
                    DeviceMesh::new(
                        &mut self.renderer,
                        buffer,
                        b.start(),
                        &b.surface.triangles,
                        colour,
                        self.soft[k],
                    )
                })
                .collect();
            match made {
                Ok(m) => self.device_meshes = Some(m),
                Err(_) => {
                    self.device_refused = true;
                    return false;
                }
            }
        }
        true
    }

    /// Draws the legend (where a frame is drawn; a grey field before the first) and the
    /// heads-up lines into the overlay and composes it over the renderer's picture onto the
    /// window.
    fn show(&mut self) -> Result<(), Error> {
        let (width, height) = (self.surface_config.width, self.surface_config.height);
        let mut overlay = std::mem::take(&mut self.overlay);
        overlay.clear();
        overlay.resize((4 * width * height) as usize, 0);
        if !self.drawn {
            overlay.chunks_mut(4).for_each(|p| p.copy_from_slice(&[200, 200, 200, 255]));
        }
        let caption = draw_caption(&mut overlay, width, height, &self.hud())?;
        // The legend below the heads-up lines, so that neither covers the other.
        if let Some(legend) = self.legend.as_ref().filter(|_| self.drawn) {
            let top = caption.map_or(0, |p| p.y + p.height);
            let row = 4 * width as usize;
            let below = &mut overlay[top as usize * row..];
            draw_legend(below, width, height - top, legend)?;
        }
        match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(frame) | wgpu::CurrentSurfaceTexture::Suboptimal(frame) => {
                let view = frame.texture.create_view(&wgpu::TextureViewDescriptor::default());
                self.blit.draw(&self.ctx, &overlay, &view);
                self.window.pre_present_notify();
                self.ctx.queue().present(frame);
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(self.ctx.device(), &self.surface_config);
            }
            _ => {}
        }
        self.overlay = overlay;
        Ok(())
    }

    /// The heads-up lines.
    fn hud(&self) -> Vec<String> {
        let u = &self.units;
        let mut first = format!(
            "{:.0} steps/s  {:.2}x real time  {:.1} frames/s  contacts {}  max penetration {:.3} {u}  t = {:.3} s",
            self.sps, self.realtime, self.fps, self.contacts, self.penetration, self.time
        );
        if self.paused {
            first += "  [paused]";
        }
        let mut lines = vec![first];
        if let Some(message) = &self.broken {
            lines.push(format!("stopped: {message} (r resets)"));
        } else if self.behind {
            lines.push(format!("behind real time: {:.2}x", self.realtime));
        }
        if self.grab.is_some() {
            lines.push(format!("dragging {:.3} {u}", self.dragged));
        }
        if let Some(notice) = &self.notice {
            lines.push(notice.clone());
        }
        lines
    }

    /// Writes the last frame as PNG, if one was asked for.
    fn screenshot(&mut self) -> Result<(), Error> {
        if let Some(path) = &self.screenshot {
            // The last frame as it was composed onto the window, read back once.
            let rgba = self.blit.screenshot(&self.ctx)?;
            write_png(path, self.surface_config.width, self.surface_config.height, &rgba)?;
            self.shot = true;
        }
        Ok(())
    }

    fn report(&self) -> ViewReport {
        // From the first frame's start to the last one's end.
        let seconds = self.started.zip(self.ended).map_or(0.0, |(a, b)| b.duration_since(a).as_secs_f64());
        ViewReport {
            scene: self.scene_name.clone(),
            backend: self.backend.into(),
            adapter: self.adapter.clone(),
            size: (self.surface_config.width, self.surface_config.height),
            frames: self.frames,
            seconds,
            frames_per_second: if seconds > 0.0 { self.frames as f64 / seconds } else { 0.0 },
            steps: self.steps_total,
            steps_per_second: if seconds > 0.0 { self.steps_total as f64 / seconds } else { 0.0 },
            simulated_time: self.time,
            behind_frames: self.behind_frames,
            max_displacement: self
                .first
                .names
                .iter()
                .cloned()
                .zip(self.displacement.iter().copied())
                .collect(),
            displacement_centre: self
                .first
                .names
                .iter()
                .cloned()
                .zip(self.displacement_centre.iter().copied())
                .collect(),
            contacts: self.contacts,
            max_penetration: self.penetration,
            units: self.units.clone(),
            dragged: self.dragged,
            instruments: self.instruments.clone(),
            paused: self.paused,
            frames_from_device: self.frames_from_device,
            states_read: self.states_at.1.saturating_sub(self.states_at.0),
            colouring: match self.colouring {
                Colouring::Displacement => "displacement".into(),
                Colouring::ContactForce => "force".into(),
            },
            camera: [self.orbit.yaw, self.orbit.pitch, self.orbit.distance],
            screenshot: self.screenshot.clone().filter(|_| self.shot),
        }
    }
}

/// The magnitude of the contact force on each shown vertex of body `k` (its user surface's,
/// interpolated from the lattice, where it has one).
/// On the GPU backend, each of `bodies` bodies' positions on the device (`run`'s buffers);
/// none on the CPU.
fn device_buffers(run: &dyn voxcollide_sim::Simulation, bodies: usize) -> Vec<wgpu::Buffer> {
    (0..bodies).map_while(|k| run.positions_buffer(k)).collect()
}

fn contact_force(world: &World, reports: &[ContactReport], k: usize) -> Vec<f32> {
    let force = contact_forces(world, reports, k);
    world.bodies[k].shown_values(&force).iter().map(|f| f.length()).collect()
}

/// A surface on `window` and an adapter that can present to it and draw: the native backends
/// first (or `WGPU_BACKEND`'s), then the others.
fn surface_and_adapter(
    event_loop: &ActiveEventLoop,
    window: Arc<Window>,
) -> Result<(wgpu::Surface<'static>, wgpu::Adapter), Error> {
    let searches = match wgpu::Backends::from_env() {
        Some(b) => vec![b],
        None => vec![wgpu::Backends::PRIMARY, wgpu::Backends::all()],
    };
    let mut why = Vec::new();
    for backends in searches {
        // The display connection, which GL (EGL) needs to present on X11 and Wayland.
        let display = Box::new(event_loop.owned_display_handle());
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends,
            ..wgpu::InstanceDescriptor::new_with_display_handle_from_env(display)
        });
        let surface = match instance.create_surface(window.clone()) {
            Ok(s) => s,
            Err(e) => {
                why.push(format!("{backends:?}: no surface: {e}"));
                continue;
            }
        };
        let wanted =
            std::env::var("WGPU_ADAPTER_NAME").ok().filter(|s| !s.is_empty()).map(|s| s.to_lowercase());
        let adapters = pollster::block_on(instance.enumerate_adapters(backends));
        let fits = |a: &wgpu::Adapter| {
            a.is_surface_supported(&surface)
                && wanted.as_ref().is_none_or(|w| a.get_info().name.to_lowercase().contains(w))
        };
        // A discrete GPU before an integrated one before the rest, as the collision library picks.
        let rank = |a: &wgpu::Adapter| match a.get_info().device_type {
            wgpu::DeviceType::DiscreteGpu => 0,
            wgpu::DeviceType::IntegratedGpu => 1,
            wgpu::DeviceType::VirtualGpu => 2,
            wgpu::DeviceType::Other => 3,
            wgpu::DeviceType::Cpu => 4,
        };
        if let Some(adapter) = adapters.into_iter().filter(fits).min_by_key(rank) {
            return Ok((surface, adapter));
        }
        why.push(format!("{backends:?}: no adapter presents to the window"));
    }
    Err(Error::NoAdapter {
        message: format!(
            "no adapter can draw into the window ({}); install a Vulkan driver such as Mesa's lavapipe (mesa-vulkan-drivers)",
            why.join("; ")
        ),
    })
}
