//! The viewer's state that does not need a window: the orbiting camera, the keys' actions,
//! the scripted drag and the steps a frame may take. Unit-tested here; `live.rs` feeds it
//! winit's events.

use glam::Vec3;

use voxcollide_render::FOV_Y_DEGREES;

/// A camera orbiting a target point, z up: where it is and where it looks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    /// The point looked at and orbited.
    pub target: Vec3,
    /// The eye's distance from the target.
    pub distance: f32,
    /// Azimuth of the eye about the target, radians from +x towards +y.
    pub yaw: f32,
    /// Elevation of the eye above the target's horizontal plane, radians.
    pub pitch: f32,
}

/// How far the camera may tilt from the horizontal: short of straight up or down, where z-up
/// would be parallel to the view.
const MAX_PITCH: f32 = 1.45;
/// Radians of orbit per pixel dragged.
const ORBIT_PER_PIXEL: f32 = 0.006;
/// The distance's factor per wheel line.
const ZOOM_PER_LINE: f32 = 0.9;

impl Orbit {
    /// The orbit whose eye is at `eye` looking along `view_dir` at the point of that line
    /// nearest `centre` (the scene's middle).
    #[must_use]
    pub fn from_eye(eye: Vec3, view_dir: Vec3, centre: Vec3) -> Orbit {
        let forward = view_dir.normalize_or(Vec3::NEG_Y);
        let depth = (centre - eye).dot(forward).max(1e-6 * (centre - eye).length().max(1e-12));
        let back = -forward;
        Orbit {
            target: eye + forward * depth,
            distance: depth,
            yaw: back.y.atan2(back.x),
            pitch: back.z.clamp(-1.0, 1.0).asin().clamp(-MAX_PITCH, MAX_PITCH),
        }
    }

    /// The unit vector from the target to the eye.
    #[must_use]
    pub fn back(&self) -> Vec3 {
        Vec3::new(self.pitch.cos() * self.yaw.cos(), self.pitch.cos() * self.yaw.sin(), self.pitch.sin())
    }

    /// Where the eye is.
    #[must_use]
    pub fn eye(&self) -> Vec3 {
        self.target + self.distance * self.back()
    }

    /// The direction the camera looks along.
    #[must_use]
    pub fn view_dir(&self) -> Vec3 {
        -self.back()
    }

    /// The camera's right and up on the screen.
    #[must_use]
    pub fn screen_axes(&self) -> (Vec3, Vec3) {
        let forward = self.view_dir();
        let right = forward.cross(Vec3::Z).normalize_or(Vec3::X);
        (right, right.cross(forward))
    }

    /// World units per pixel at `depth` in front of the eye, for a window `height` pixels high.
    #[must_use]
    pub fn units_per_pixel(&self, depth: f32, height: u32) -> f32 {
        let half = (0.5 * FOV_Y_DEGREES as f32).to_radians();
        2.0 * depth.max(0.0) * half.tan() / height.max(1) as f32
    }

    /// Turns the camera about the target by a drag of `(dx, dy)` pixels.
    pub fn rotate(&mut self, dx: f32, dy: f32) {
        self.yaw -= dx * ORBIT_PER_PIXEL;
        self.pitch = (self.pitch + dy * ORBIT_PER_PIXEL).clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// Moves the target (and the eye with it) so that what was under the cursor follows a drag
    /// of `(dx, dy)` pixels in a window `height` pixels high.
    pub fn pan(&mut self, dx: f32, dy: f32, height: u32) {
        let (right, up) = self.screen_axes();
        let s = self.units_per_pixel(self.distance, height);
        self.target += s * (-dx * right + dy * up);
    }

    /// Moves the eye towards the target (positive `lines`, a wheel turned forward) or away.
    pub fn zoom(&mut self, lines: f32) {
        self.distance = (self.distance * ZOOM_PER_LINE.powf(lines)).max(1e-6);
    }

    /// The window pixel `(x, y)` (from the top left) where `p` is seen in a `width × height`
    /// window, and its depth in front of the eye; `None` behind the eye.
    #[must_use]
    pub fn project(&self, p: Vec3, width: u32, height: u32) -> Option<(f32, f32, f32)> {
        let (right, up) = self.screen_axes();
        let d = p - self.eye();
        let depth = d.dot(self.view_dir());
        if depth <= 0.0 {
            return None;
        }
        let s = self.units_per_pixel(depth, height);
        let x = 0.5 * width as f32 + d.dot(right) / s;
        let y = 0.5 * height as f32 - d.dot(up) / s;
        Some((x, y, depth))
    }

    /// The move in the world, across the view at `depth`, of a drag of `(dx, dy)` pixels.
    #[must_use]
    pub fn drag_in_view_plane(&self, dx: f32, dy: f32, depth: f32, height: u32) -> Vec3 {
        let (right, up) = self.screen_axes();
        self.units_per_pixel(depth, height) * (dx * right - dy * up)
    }
}

/// What a key does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Space: pause or go on.
    TogglePause,
    /// `.` or `s`: one step (pausing first).
    Step,
    /// `r`: back to the first step, the camera kept.
    Reset,
    /// `c`: the next colouring.
    CycleColouring,
    /// `f`: the camera back to framing the scene.
    Frame,
    /// Escape or `q`: close.
    Close,
}

impl Action {
    /// The action of a key by the text it types (winit's logical key), if any.
    #[must_use]
    pub fn of_key(text: &str) -> Option<Action> {
        match text.to_lowercase().as_str() {
            " " | "space" => Some(Action::TogglePause),
            "." | "s" => Some(Action::Step),
            "r" => Some(Action::Reset),
            "c" => Some(Action::CycleColouring),
            "f" => Some(Action::Frame),
            "q" | "escape" => Some(Action::Close),
            _ => None,
        }
    }
}

/// The controls as one line, for the terminal and `--help`.
pub const HELP: &str = "drag: orbit (or move an instrument under the cursor) · right-drag or shift-drag: pan · wheel: zoom · space: pause · s: step · r: reset · c: colouring · f: frame · q: close";

/// What the bodies are coloured by.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Colouring {
    /// How far each vertex is from where it started.
    #[default]
    Displacement,
    /// The magnitude of the contact force on each vertex.
    #[value(name = "force")]
    ContactForce,
}

impl Colouring {
    /// The next one, round.
    #[must_use]
    pub fn next(self) -> Colouring {
        match self {
            Colouring::Displacement => Colouring::ContactForce,
            Colouring::ContactForce => Colouring::Displacement,
        }
    }
}

/// A scripted drag: the pointer pressed at `from`, moved in a straight line to `to` over
/// `frames` frames, and released. Written `"x0,y0 -> x1,y1 over N frames"` (window pixels from
/// the top left).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScriptedDrag {
    /// Where the pointer is pressed.
    pub from: (f32, f32),
    /// Where it is released.
    pub to: (f32, f32),
    /// Frames the move takes (at least 1).
    pub frames: u64,
    /// The frame at which it is pressed (from 0).
    pub start: u64,
}

impl ScriptedDrag {
    /// Parses `"x0,y0 -> x1,y1 over N frames"`, optionally followed by `" from frame K"`
    /// (default 1: after the first frame is drawn).
    ///
    /// # Errors
    /// A message saying what the form is.
    pub fn parse(s: &str) -> Result<ScriptedDrag, String> {
        let form = || format!("{s:?}: expected \"x0,y0 -> x1,y1 over N frames [from frame K]\"");
        let point = |p: &str| -> Result<(f32, f32), String> {
            let (x, y) = p.trim().split_once(',').ok_or_else(form)?;
            let (x, y) = (x.trim().parse::<f32>(), y.trim().parse::<f32>());
            match (x, y) {
                (Ok(x), Ok(y)) if x.is_finite() && y.is_finite() => Ok((x, y)),
                _ => Err(form()),
            }
        };
        let (from, rest) = s.split_once("->").ok_or_else(form)?;
        let (to, rest) = rest.split_once("over").ok_or_else(form)?;
        let words: Vec<&str> = rest.split_whitespace().collect();
        let (frames, start) = match words.as_slice() {
            [n, "frames" | "frame"] => (n, None),
            [n, "frames" | "frame", "from", "frame", k] => (n, Some(k)),
            _ => return Err(form()),
        };
        let frames: u64 = frames.parse().map_err(|_| form())?;
        let start: u64 = start.map_or(Ok(1), |k| k.parse()).map_err(|_| form())?;
        if frames == 0 {
            return Err(format!("{s:?}: the drag needs at least 1 frame"));
        }
        if start.checked_add(frames).is_none() {
            return Err(format!("{s:?}: the drag would end after the last frame there can be"));
        }
        Ok(ScriptedDrag { from: point(from)?, to: point(to)?, frames, start })
    }

    /// The pointer at `frame`: `Some((x, y, pressed))` while the script acts (pressed from
    /// `start` to `start + frames - 1`, released at `start + frames`), else `None`.
    #[must_use]
    pub fn at(&self, frame: u64) -> Option<(f32, f32, bool)> {
        if frame < self.start || frame > self.start + self.frames {
            return None;
        }
        let u = ((frame - self.start) as f32 / self.frames as f32).min(1.0);
        let x = self.from.0 + (self.to.0 - self.from.0) * u;
        let y = self.from.1 + (self.to.1 - self.from.1) * u;
        Some((x, y, frame < self.start + self.frames))
    }
}

/// How many steps a frame takes to keep the simulation in real time, within a budget of
/// stepping time per frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pacing {
    /// Simulated seconds per step.
    pub dt: f64,
    /// The longest a frame may spend stepping, seconds (the rest is drawing).
    pub budget: f64,
    /// Seconds a step took lately (a running mean); 0 before the first measure.
    pub per_step: f64,
    /// Simulated seconds still owed to real time.
    pub owed: f64,
}

impl Pacing {
    /// Pacing for steps of `dt` seconds, spending at most `budget` seconds a frame stepping.
    #[must_use]
    pub fn new(dt: f64, budget: f64) -> Pacing {
        Pacing { dt, budget, per_step: 0.0, owed: 0.0 }
    }

    /// The steps to take in a frame that comes `elapsed` seconds of real time after the last,
    /// and whether that falls behind real time (the budget cannot pay what is owed). What
    /// cannot be paid is dropped, not carried: a slow machine runs slower than real time
    /// instead of ever further behind.
    pub fn steps(&mut self, elapsed: f64) -> (u64, bool) {
        // A stall (a dragged window, a breakpoint) is not owed.
        self.owed += elapsed.clamp(0.0, 0.25);
        let wanted = (self.owed / self.dt).floor().max(0.0) as u64;
        let affordable = if self.per_step > 0.0 { (self.budget / self.per_step).floor() as u64 } else { 1 };
        let n = wanted.min(affordable.max(1));
        let short = wanted > n;
        self.owed = if short { 0.0 } else { self.owed - n as f64 * self.dt };
        // Before a step is timed, one step is a measurement, not a verdict.
        (n, short && self.per_step > 0.0)
    }

    /// Records that `n` steps took `seconds`.
    pub fn took(&mut self, n: u64, seconds: f64) {
        if n == 0 || !(seconds.is_finite() && seconds >= 0.0) {
            return;
        }
        let each = seconds / n as f64;
        self.per_step = if self.per_step > 0.0 { 0.7 * self.per_step + 0.3 * each } else { each };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn the_orbit_starts_where_the_eye_is_and_projects_the_target_to_the_middle() {
        let eye = Vec3::new(0.0, -10.0, 5.0);
        let dir = Vec3::new(0.0, 1.0, -0.5).normalize();
        let o = Orbit::from_eye(eye, dir, Vec3::ZERO);
        assert!((o.eye() - eye).length() < 1e-4, "{} vs {eye}", o.eye());
        assert!((o.view_dir() - dir).length() < 1e-5);
        let (x, y, depth) = o.project(o.target, 800, 600).unwrap();
        assert_relative_eq!(x, 400.0, epsilon = 1e-3);
        assert_relative_eq!(y, 300.0, epsilon = 1e-3);
        assert_relative_eq!(depth, o.distance, epsilon = 1e-4);
        // Right on the screen is right in the picture, up is up.
        let (right, up) = o.screen_axes();
        let (xr, _, _) = o.project(o.target + right, 800, 600).unwrap();
        let (_, yu, _) = o.project(o.target + up, 800, 600).unwrap();
        assert!(xr > 400.0 && yu < 300.0);
        assert!(o.project(eye - dir, 800, 600).is_none(), "behind the eye");
    }

    #[test]
    fn a_drag_moves_what_is_under_the_cursor_with_it() {
        let o = Orbit { target: Vec3::new(1.0, 2.0, 3.0), distance: 20.0, yaw: 0.7, pitch: 0.4 };
        let p = o.target + Vec3::new(0.5, -0.3, 0.2);
        let (x, y, depth) = o.project(p, 640, 480).unwrap();
        let moved = p + o.drag_in_view_plane(37.0, -12.0, depth, 480);
        let (x2, y2, _) = o.project(moved, 640, 480).unwrap();
        assert_relative_eq!(x2 - x, 37.0, epsilon = 0.05);
        assert_relative_eq!(y2 - y, -12.0, epsilon = 0.05);
        // Panning by a drag moves the picture with the cursor, so the target slides the other way.
        let mut panned = o;
        panned.pan(50.0, 0.0, 480);
        let (xt, _, _) = panned.project(o.target, 640, 480).unwrap();
        assert_relative_eq!(xt - 320.0, 50.0, epsilon = 0.05);
    }

    #[test]
    fn orbit_and_zoom_keep_the_target_and_stay_off_the_poles() {
        let mut o = Orbit { target: Vec3::ZERO, distance: 10.0, yaw: 0.0, pitch: 0.0 };
        o.rotate(100.0, 10_000.0);
        assert_eq!(o.pitch, MAX_PITCH);
        assert!((o.eye() - o.target).length() - 10.0 < 1e-4);
        o.zoom(2.0);
        assert_relative_eq!(o.distance, 8.1, epsilon = 1e-4);
        o.zoom(-2.0);
        assert_relative_eq!(o.distance, 10.0, epsilon = 1e-4);
        let (right, up) = o.screen_axes();
        assert!(right.is_normalized() && up.is_normalized() && right.dot(up).abs() < 1e-5);
    }

    #[test]
    fn keys_do_what_the_help_says() {
        assert_eq!(Action::of_key(" "), Some(Action::TogglePause));
        assert_eq!(Action::of_key("S"), Some(Action::Step));
        assert_eq!(Action::of_key("r"), Some(Action::Reset));
        assert_eq!(Action::of_key("c"), Some(Action::CycleColouring));
        assert_eq!(Action::of_key("Escape"), Some(Action::Close));
        assert_eq!(Action::of_key("x"), None);
        assert_eq!(Colouring::Displacement.next().next(), Colouring::Displacement);
        assert_ne!(Colouring::Displacement.next(), Colouring::Displacement);
    }

    #[test]
    fn a_scripted_drag_reads_and_plays() {
        let d = ScriptedDrag::parse("100,200 -> 300, 150 over 4 frames").unwrap();
        assert_eq!(d, ScriptedDrag { from: (100.0, 200.0), to: (300.0, 150.0), frames: 4, start: 1 });
        assert_eq!(d.at(0), None);
        assert_eq!(d.at(1), Some((100.0, 200.0, true)));
        assert_eq!(d.at(3), Some((200.0, 175.0, true)));
        assert_eq!(d.at(5), Some((300.0, 150.0, false)), "released at the end");
        assert_eq!(d.at(6), None);
        let late = ScriptedDrag::parse("1,2 -> 3,4 over 2 frames from frame 10").unwrap();
        assert!(ScriptedDrag::parse("1,2 -> 3,4 over 2 frames from frame 18446744073709551615").is_err());
        assert_eq!(late.start, 10);
        for bad in [
            "",
            "1,2 -> 3,4",
            "1,2 -> 3 over 2 frames",
            "1,2 -> 3,4 over 0 frames",
            "a,b -> 3,4 over 2 frames",
            "1,2 -> 3,4 over 2 seconds",
            "nan,2 -> 3,4 over 2 frames",
        ] {
            assert!(ScriptedDrag::parse(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn pacing_keeps_real_time_within_its_budget_and_says_when_it_cannot() {
        let mut p = Pacing::new(0.001, 0.020);
        // Unmeasured: one step, to learn its cost (not yet "behind").
        assert_eq!(p.steps(1.0 / 60.0), (1, false));
        // Cheap steps: real time, 16 or 17 steps a 60 Hz frame, none owed beyond a step.
        p.took(1, 0.0001);
        let mut total = 0;
        for _ in 0..60 {
            let (n, behind) = p.steps(1.0 / 60.0);
            assert!(!behind);
            total += n;
        }
        assert!((999..=1000).contains(&total), "{total} steps in a second of 1 ms steps");
        // Dear steps: the budget buys 10 a frame, and that is behind.
        p.took(1, 0.002);
        p.took(1, 0.002);
        p.took(1, 0.002);
        p.took(1, 0.002);
        p.took(1, 0.002);
        p.took(1, 0.002);
        p.took(1, 0.002);
        p.took(1, 0.002);
        let (n, behind) = p.steps(1.0 / 30.0);
        assert!(behind && (9..=10).contains(&n), "{n}");
        assert_eq!(p.owed, 0.0, "what cannot be paid is dropped");
        // A stall of seconds is not owed.
        let mut q = Pacing::new(0.001, 10.0);
        q.took(1, 1e-6);
        assert_eq!(q.steps(5.0).0, 250);
    }
}
