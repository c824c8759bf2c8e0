//! `voxcollide view` (docs/design.md §10): a scene run live in a window (winit and a wgpu surface),
//! drawn each frame as the run's pictures are, with a camera to orbit, pan and zoom, pause,
//! step and reset, a colouring to cycle with its legend, a heads-up line, and instruments to
//! drag with the mouse while the tissue responds (the paper's virtual operation).
//!
//! The simulation steps on its own thread in real time while the window draws the latest
//! state it published (`stepper`); the heads-up line shows the real-time factor and says when
//! it falls behind. `--frames N --screenshot PATH` draws N frames,
//! writes the last as PNG and exits; `--drag` scripts a drag; `--steps-per-frame` makes a run
//! repeatable (a fixed number of steps a frame instead of real time). Each frame is drawn by
//! [`Renderer`](voxcollide_render::Renderer) on the device (from the bodies' positions there,
//! where they step on the GPU), its legend and heads-up lines drawn on the CPU as an overlay,
//! and the two composed onto the window: no picture is read back, and on the GPU backend no
//! position either, but for a few states a second for the heads-up numbers. The screenshot is
//! the same composition, read back once.

mod blit;
mod controls;
mod live;
mod stepper;

use std::path::{Path, PathBuf};

use serde::Serialize;
use voxcollide::Error;
use voxcollide_sim::scene_file::SceneFile;

pub use blit::BLIT_SHADER;
pub use controls::{Action, Colouring, HELP, Orbit, Pacing, ScriptedDrag};

use crate::backend::Backend;

/// The scenes `view` knows by name (the files under `scenes/` that need no mesh file), built in.
pub const SHIPPED: [(&str, &str); 6] = [
    ("implant", include_str!("../../../../scenes/implant.toml")),
    ("cylinder", include_str!("../../../../scenes/cylinder.toml")),
    ("indentation", include_str!("../../../../scenes/indentation.toml")),
    ("expander", include_str!("../../../../scenes/expander.toml")),
    ("breast-implant", include_str!("../../../../scenes/breast-implant.toml")),
    ("breast-compare", include_str!("../../../../scenes/breast-compare.toml")),
];

/// What to view, and how.
#[derive(Clone, Debug)]
pub struct ViewConfig {
    /// A scene file, or the name of a shipped scene ([`SHIPPED`]).
    pub scene: String,
    /// Where the simulation steps (drawing needs an adapter either way).
    pub backend: Backend,
    /// The window's inner size in pixels.
    pub size: (u32, u32),
    /// Draw this many frames, then close.
    pub frames: Option<u64>,
    /// Write the last frame here as PNG.
    pub screenshot: Option<PathBuf>,
    /// A scripted drag.
    pub drag: Option<ScriptedDrag>,
    /// Steps per frame instead of real time (repeatable runs).
    pub steps_per_frame: Option<u64>,
    /// Write the [`ViewReport`] here as JSON at the end.
    pub report: Option<PathBuf>,
    /// The colouring to start with (`c` cycles it).
    pub colouring: Colouring,
}

/// What a view did, printed at the end (and written as JSON with `--report`).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ViewReport {
    /// The scene.
    pub scene: String,
    /// Where it stepped: `"gpu"` or `"cpu"`.
    pub backend: String,
    /// The adapter that drew it (and stepped it, on the GPU backend).
    pub adapter: String,
    /// The window's size at the end.
    pub size: (u32, u32),
    /// Frames drawn.
    pub frames: u64,
    /// Wall seconds from the first frame to the last.
    pub seconds: f64,
    /// Frames per second over the view.
    pub frames_per_second: f64,
    /// Steps run.
    pub steps: u64,
    /// Steps per wall second.
    pub steps_per_second: f64,
    /// Simulated seconds at the end.
    pub simulated_time: f64,
    /// Frames drawn while the stepping fell behind real time.
    pub behind_frames: u64,
    /// Per body at the end: its name and its largest vertex displacement (scene units).
    pub max_displacement: Vec<(String, f32)>,
    /// Per body at the end: its name and where it is displaced, the mean of its vertices'
    /// rest positions weighted by how far each moved (its rest centre when none moved):
    /// where a dent is, to follow it as an instrument is dragged (scene units).
    pub displacement_centre: Vec<(String, [f32; 3])>,
    /// Contacts (colliding vertices) at the end.
    pub contacts: usize,
    /// The deepest a vertex is inside another body at the end (scene units).
    pub max_penetration: f32,
    /// The scene's length unit.
    pub units: String,
    /// How far instruments were dragged, in all (scene units).
    pub dragged: f32,
    /// The bodies a drag can move (those with driven vertices: rigid instruments, driven
    /// parts), each with a window pixel in the first frame where a press takes hold of it:
    /// the driven vertex on the side facing the camera that shows nearest its centre (where a
    /// scripted drag can start).
    pub instruments: Vec<(String, [f32; 2])>,
    /// The screenshot written, if any.
    pub screenshot: Option<PathBuf>,
    /// Whether it was paused at the end.
    pub paused: bool,
    /// Frames whose bodies were drawn from their positions on the device, where they step
    /// (the GPU backend, coloured by displacement): nothing read back to draw them.
    pub frames_from_device: u64,
    /// States of the run handed to the window while it drew its frames (from the first frame's
    /// start to the last one's end, as `seconds`): the heads-up numbers, picking, the report's
    /// figures. On the GPU backend each is read back from the device, a few a second while the
    /// bodies are drawn from the device, after every batch of steps otherwise.
    pub states_read: u64,
    /// The colouring at the end: `"displacement"` or `"force"`.
    pub colouring: String,
    /// The camera at the end: its yaw and pitch (radians) and its distance from what it orbits.
    pub camera: [f32; 3],
}

/// The scene `name` names: a file if one is there, else a shipped scene; its implants placed
/// on a patient start deflated, as `run` starts them ([`crate::compare::start_placed_deflated`]).
///
/// # Errors
/// The file's errors; [`Error::Invalid`] naming the shipped scenes when it is neither.
pub fn scene_named(name: &str) -> Result<SceneFile, Error> {
    let path = Path::new(name);
    if path.is_file() {
        let mut scene = SceneFile::read(path)?;
        crate::compare::start_placed_deflated(&mut scene)?;
        return Ok(scene);
    }
    match SHIPPED.iter().find(|(n, _)| *n == name) {
        Some((n, text)) => SceneFile::parse(format!("scenes/{n}.toml"), text),
        None => Err(Error::Invalid {
            what: "scene",
            value: name.to_string(),
            rule: format!(
                "is neither a file nor a shipped scene ({})",
                SHIPPED.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
            ),
        }),
    }
}

/// Why there is no display to open a window on, if there is none: on Linux and the BSDs
/// neither `DISPLAY` (X11) nor `WAYLAND_DISPLAY` is set.
#[must_use]
pub fn no_display() -> Option<String> {
    if cfg!(all(unix, not(target_os = "macos"), not(target_os = "android"), not(target_os = "ios"))) {
        let set = |v: &str| std::env::var_os(v).is_some_and(|s| !s.is_empty());
        if !set("DISPLAY") && !set("WAYLAND_DISPLAY") {
            return Some("neither DISPLAY nor WAYLAND_DISPLAY is set".into());
        }
    }
    None
}

/// The error of a machine with no display: one line that points to `run`.
fn headless(why: &str, scene: &str) -> Error {
    Error::Invalid {
        what: "display",
        value: why.to_string(),
        rule: format!(
            "`view` needs a window; on a machine without a display, `voxcollide run {scene}` runs it and writes pictures"
        ),
    }
}

/// Opens the window and runs `config`'s scene live until it is closed (or its `frames` are
/// drawn), calling `note` with what is worth saying; returns what it did.
///
/// # Errors
/// The scene's errors, before any window opens; [`Error::Invalid`] with `what: "display"` on
/// a machine without a display (one line, pointing to `run`); [`Error::NoAdapter`] when no
/// adapter can draw into the window (or, for `Backend::Gpu`, step the scene);
/// [`Error::Simulation`] when the scene blows up in a run with `frames` (an interactive view
/// shows it and waits for a reset); [`Error::Io`] for the screenshot and report.
pub fn view(config: &ViewConfig, note: &mut dyn FnMut(&str)) -> Result<ViewReport, Error> {
    let file = scene_named(&config.scene)?;
    let built = voxcollide_sim::build::build_world(&file)?;
    for n in &built.notes {
        for r in &n.remarks {
            note(&format!("{}: {r}", n.name));
        }
    }
    if let Some(why) = no_display() {
        return Err(headless(&why, &config.scene));
    }
    for (what, side) in [("width", config.size.0), ("height", config.size.1)] {
        if side == 0 {
            return Err(Error::Invalid { what, value: "0".into(), rule: "the window needs a size".into() });
        }
    }
    let report = live::run(config, &file, built, note).map_err(|e| match e {
        live::Failure::NoDisplay(why) => headless(&why, &config.scene),
        live::Failure::Error(e) => e,
    })?;
    if let Some(path) = &config.report {
        let json = serde_json::to_string_pretty(&report)
            .map_err(|e| Error::Io { path: path.display().to_string(), message: e.to_string() })?;
        std::fs::write(path, json + "\n")
            .map_err(|e| Error::Io { path: path.display().to_string(), message: e.to_string() })?;
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_blit_shader_parses_and_validates_with_default_capabilities() {
        let module = naga::front::wgsl::parse_str(BLIT_SHADER).expect("blit.wgsl parses");
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&module)
        .expect("blit.wgsl validates");
        for entry in ["vs_main", "fs_main"] {
            assert!(module.entry_points.iter().any(|e| e.name == entry), "{entry}");
        }
    }

    #[test]
    fn every_shipped_scene_reads_and_builds() {
        for (name, _) in SHIPPED {
            let file = scene_named(name).unwrap_or_else(|e| panic!("{name}: {e}"));
            voxcollide_sim::build::build_world(&file).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        let e = scene_named("no-such-scene").unwrap_err().to_string();
        assert!(e.contains("implant, cylinder, indentation"), "{e}");
    }
}
