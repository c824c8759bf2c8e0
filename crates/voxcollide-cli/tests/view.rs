//! `voxcollide view` (docs/design.md §10) in a real window: an X server in memory (Xvfb, Debian's
//! `xvfb`, which `.ci/run` installs) and the adapter there is (lavapipe in CI). The screenshot
//! shows the bodies with their legend and heads-up line; a scripted drag of an instrument moves
//! the dent it makes, in the picture and in the reported displacement; closing the window as a
//! window manager does ends the view cleanly; and with no display it says so in one line.
//!
//! Without Xvfb the window tests skip, unless `VOXCOLLIDE_REQUIRE_DISPLAY=1` (CI).

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

/// An X server of its own for a test, stopped when dropped.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    /// A fresh Xvfb on a free display; `None` (a skip) without Xvfb or an adapter, unless
    /// `VOXCOLLIDE_REQUIRE_DISPLAY=1`.
    fn start() -> Option<Xvfb> {
        let required = std::env::var("VOXCOLLIDE_REQUIRE_DISPLAY").as_deref() == Ok("1");
        let Some(binary) =
            ["/usr/bin/Xvfb", "/usr/local/bin/Xvfb"].into_iter().find(|p| Path::new(p).is_file())
        else {
            assert!(!required, "VOXCOLLIDE_REQUIRE_DISPLAY=1 but there is no Xvfb (Debian's xvfb)");
            eprintln!("skipped: no Xvfb");
            return None;
        };
        common::gpu()?;
        // Xvfb picks a free display itself and writes its number to our pipe (-displayfd 1); it
        // keeps running as one view ends and the next connects (-noreset: no reset in between).
        let mut child = Command::new(binary)
            .args(["-displayfd", "1", "-screen", "0", "1280x1024x24", "-nolisten", "tcp", "-noreset"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("Xvfb starts");
        let mut line = String::new();
        let stdout = child.stdout.take().expect("piped");
        std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line).expect("Xvfb's display");
        let n: u32 = line.trim().parse().unwrap_or_else(|_| panic!("Xvfb wrote {line:?} for its display"));
        Some(Xvfb { child, display: format!(":{n}") })
    }

    /// `voxcollide view SCENE --report REPORT` running interactively (only a close ends it),
    /// and a connection to the display to steer it.
    fn interactive(
        &self,
        scene: &str,
        report: &Path,
    ) -> (Child, x11rb::rust_connection::RustConnection, usize) {
        let child = self
            .view(&[scene, "--report"])
            .arg(report)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (conn, screen) = x11rb::connect(Some(&self.display)).unwrap();
        (child, conn, screen)
    }

    /// `voxcollide view` on this display, with a runtime folder of its own.
    fn view(&self, args: &[&str]) -> Command {
        let mut c = Command::new(env!("CARGO_BIN_EXE_voxcollide"));
        c.arg("view").args(args).env("DISPLAY", &self.display).env_remove("WAYLAND_DISPLAY");
        c.env("XDG_RUNTIME_DIR", std::env::temp_dir());
        c
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("voxcollide-view-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn ok(output: Output) -> String {
    let (out, err) = (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "{}\n{out}\n{err}", output.status);
    out.into_owned()
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// RGBA rows of a PNG, and its size.
fn png(path: &Path) -> (Vec<[u8; 4]>, u32, u32) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgba);
    let pixels = buf[..info.buffer_size()].chunks(4).map(|p| [p[0], p[1], p[2], p[3]]).collect();
    (pixels, info.width, info.height)
}

/// A pixel of the colour map's middle and upper half (greens and yellows): a dent's colours.
fn dent(p: [u8; 4]) -> bool {
    let [r, g, b, _] = p.map(u16::from);
    g > 120 && g > r + 30 && g > b
}

/// A pixel of the colour map's blue-greens (teal, a dent of about half the scale's range), never
/// the grey-blue of a plain body or the violet of no displacement.
fn teal(p: [u8; 4]) -> bool {
    let [r, g, b, _] = p.map(u16::from);
    g > 80 && g > r + 30 && b > 100 && b > r + 40
}

#[test]
fn the_screenshot_shows_the_bodies_their_legend_and_the_heads_up_line() {
    let Some(x) = Xvfb::start() else { return };
    let d = dir("shot");
    let (shot, report) = (d.join("implant.png"), d.join("report.json"));
    // The paper's implant scene, its implant filled over 4 s: 20 frames of 40 steps (3.9 s),
    // stepped on the GPU (`auto` steps on the CPU when the adapter is a software one).
    let out = ok(x
        .view(&[
            "implant",
            "--backend",
            "gpu",
            "--size",
            "640x420",
            "--frames",
            "20",
            "--steps-per-frame",
            "40",
        ])
        .args(["--screenshot".as_ref(), shot.as_os_str(), "--report".as_ref(), report.as_os_str()])
        .output()
        .unwrap());
    assert!(out.contains("20 frames in") && out.contains("frames/s"), "{out}");
    let r = json(&report);
    assert_eq!((r["frames"].as_u64(), r["steps"].as_u64()), (Some(20), Some(800)), "{r}");
    assert_eq!(r["backend"], "gpu");
    assert!(r["frames_per_second"].as_f64().unwrap() > 0.0);
    let tissue = r["max_displacement"][0][1].as_f64().unwrap();
    assert!(tissue > 0.05, "the implant lifted the tissue {tissue} m");

    let (pixels, w, h) = png(&shot);
    assert_eq!((w, h), (640, 420));
    let colours: std::collections::HashSet<[u8; 4]> = pixels.iter().copied().collect();
    assert!(colours.len() > 200, "{} colours: a blank or flat picture", colours.len());
    let at = |x: u32, y: u32| pixels[(y * w + x) as usize];
    // The background is the renderer's light grey; the bodies cover a good part of the middle.
    let background = at(w / 2, 2);
    let middle: Vec<[u8; 4]> = (h / 4..3 * h / 4)
        .flat_map(|y| (w / 4..3 * w / 4).map(move |x| (x, y)))
        .map(|(x, y)| at(x, y))
        .collect();
    let covered = middle.iter().filter(|p| **p != background).count() as f64 / middle.len() as f64;
    assert!(covered > 0.3, "{covered}: the bodies cover little of the middle");
    // The lifted tissue shows the colour map's greens; the heads-up line's dark text sits on
    // its light panel at the top left, the legend's bar (its yellow top) at the top right.
    assert!(pixels.iter().filter(|p| dent(**p)).count() > 200, "no lifted tissue in the colour map's greens");
    let text = (8..30).flat_map(|y| (8..200).map(move |x| (x, y))).filter(|&(x, y)| at(x, y)[0] < 60).count();
    assert!(text > 100, "{text}: no heads-up text at the top left");
    let yellow = (0..h / 2)
        .flat_map(|y| (w / 2..w).map(move |x| (x, y)))
        .filter(|&(x, y)| at(x, y)[0] > 200 && at(x, y)[1] > 200 && at(x, y)[2] < 80)
        .count();
    assert!(yellow > 5, "no legend bar at the top right");

    // Coloured by contact force instead: the legend says so, the picture changes.
    let force = d.join("force.png");
    ok(x.view(&[
        "implant",
        "--size",
        "640x420",
        "--frames",
        "20",
        "--steps-per-frame",
        "40",
        "--colouring",
        "force",
    ])
    .args(["--screenshot".as_ref(), force.as_os_str()])
    .output()
    .unwrap());
    let (other, _, _) = png(&force);
    let differ = other.iter().zip(&pixels).filter(|(a, b)| a != b).count();
    assert!(differ > 1000, "{differ} pixels differ between the colourings");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_dragged_instrument_moves_the_dent_in_the_picture_and_the_numbers() {
    let Some(x) = Xvfb::start() else { return };
    let d = dir("drag");
    // scenes/indentation.toml with its ball pressed 5 mm into the block instead of 3, so that
    // the dent shows around the ball and not only under it.
    let scenes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let text = std::fs::read_to_string(scenes.join("indentation.toml")).unwrap();
    // Under the explicit integrator: the motion between rests is what the view is for.
    let deeper = text
        .replace("{ t = 0.2, position = [0, 0, 10] }", "{ t = 0.2, position = [0, 0, 8] }")
        .replace("max_steps = 8000", "max_steps = 8000\nintegrator = \"explicit\"");
    assert_ne!(deeper, text);
    let scene = d.join("indentation.toml");
    std::fs::write(&scene, deeper).unwrap();
    let scene = scene.to_str().unwrap();
    // Where the ball (the scene's rigid instrument) is drawn at first: after the first frame's
    // fixed steps, as in the runs below, and not after however many steps real time allowed
    // (a loaded machine's press landed elsewhere on the ball, and dragged it further).
    let (first, first_shot) = (d.join("first.json"), d.join("first.png"));
    ok(x.view(&[scene, "--frames", "1", "--steps-per-frame", "20", "--report"])
        .arg(&first)
        .args(["--screenshot".as_ref(), first_shot.as_os_str()])
        .output()
        .unwrap());
    let r = json(&first);
    assert_eq!(r["instruments"][0][0], "ball", "{r}");
    let (bx, by) = (r["instruments"][0][1][0].as_f64().unwrap(), r["instruments"][0][1][1].as_f64().unwrap());
    // Well inside the ball as drawn: the plain body's grey-blue all around it, not the
    // background or the tissue (the shell's vertex nearest its centre in space, any of them,
    // once gave a point on its rim).
    let (pixels, w, h) = png(&first_shot);
    assert!(bx >= 6.0 && by >= 6.0 && bx + 6.0 < f64::from(w) && by + 6.0 < f64::from(h), "({bx}, {by})");
    let around = (-6..=6).flat_map(|dy| (-6..=6).map(move |dx| (bx as i32 + dx, by as i32 + dy)));
    for (px, py) in around {
        let [r, g, b, _] = pixels[(py as u32 * w + px as u32) as usize].map(i32::from);
        assert!(b >= r + 20 && g >= r + 8 && r > 120, "({px}, {py}) is not the ball: {r} {g} {b}");
    }
    // The same 80 frames of 20 steps, the ball pressed into the block; once left alone, once
    // dragged 120 pixels to the right over 40 frames.
    let run = |name: &str, drag: Option<String>| {
        let (shot, report) = (d.join(format!("{name}.png")), d.join(format!("{name}.json")));
        let mut c = x.view(&[scene, "--frames", "80", "--steps-per-frame", "20"]);
        c.args(["--screenshot".as_ref(), shot.as_os_str(), "--report".as_ref(), report.as_os_str()]);
        if let Some(drag) = drag {
            c.args(["--drag", &drag]);
        }
        ok(c.output().unwrap());
        (png(&shot), json(&report))
    };
    let ((still, w, h), r_still) = run("still", None);
    let ((dragged, _, _), r_drag) =
        run("dragged", Some(format!("{bx},{by} -> {},{by} over 40 frames", bx + 120.0)));
    assert_eq!(r_still["dragged"].as_f64(), Some(0.0));
    let moved = r_drag["dragged"].as_f64().unwrap();
    assert!(moved > 5.0, "dragged {moved} mm");
    // The numbers: the ball moved with the pointer, and the block's dent followed it to the
    // right of the screen (the first view's right is +x, a little −y).
    let ball = |r: &Value| r["max_displacement"][1][1].as_f64().unwrap();
    assert!(ball(&r_drag) > ball(&r_still) + 0.5 * moved, "{} vs {}", ball(&r_drag), ball(&r_still));
    let centre = |r: &Value| -> [f64; 3] {
        let c = &r["displacement_centre"][0];
        assert_eq!(c[0], "block");
        [0, 1, 2].map(|k| c[1][k].as_f64().unwrap())
    };
    let (a, b) = (centre(&r_still), centre(&r_drag));
    assert!(b[0] - a[0] > 3.0, "the dent moved {:.2} mm in x", b[0] - a[0]);
    assert!(r_drag["contacts"].as_u64().unwrap() > 0, "the ball still presses the block");
    // The picture: the dent's colours moved right on the screen. The ball hides most of the
    // dent, and what shows is a ring around it whose left and right arcs weigh differently as
    // the ball moves (their mean once moved 19 pixels for a ball dragged further than here):
    // the middle of the dent's extent across the screen, from its 5th to its 95th percentile
    // of x, moves with the ring as a whole.
    let dent_x = |pixels: &[[u8; 4]]| {
        let mut xs: Vec<u32> = pixels
            .iter()
            .enumerate()
            // Below the legend's colour bar (at the top right), whose greens would weigh in.
            .filter(|(i, p)| (dent(**p) || teal(**p)) && *i as u32 / w > h * 2 / 5)
            .map(|(i, _)| i as u32 % w)
            .collect();
        assert!(xs.len() > 50, "no dent in the picture");
        xs.sort_unstable();
        let at = |q: f64| f64::from(xs[(q * (xs.len() - 1) as f64).round() as usize]);
        0.5 * (at(0.05) + at(0.95))
    };
    let (sx, dx) = (dent_x(&still), dent_x(&dragged));
    // (About 95 pixels for the 120 the pointer moved.)
    assert!(
        dx - sx > 50.0,
        "the dent moved {:.0} pixels on the screen ({sx:.0} → {dx:.0}) in a {w}×{h} picture; the ball \
         was first drawn at ({bx:.1}, {by:.1}) and dragged {moved:.2} mm; the dent's centre moved from \
         {a:?} to {b:?}",
        dx - sx
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// The first top-level window whose name says `voxcollide view`, once it has drawn for a while.
fn find_window(conn: &impl x11rb::connection::Connection, root: u32, child: &mut Child) -> u32 {
    use x11rb::protocol::xproto::{AtomEnum, ConnectionExt};
    let since = Instant::now();
    loop {
        assert!(since.elapsed() < Duration::from_secs(90), "no window appeared");
        assert!(child.try_wait().unwrap().is_none(), "the view ended before its window was closed");
        let found = conn.query_tree(root).unwrap().reply().unwrap().children.into_iter().find(|&w| {
            conn.get_property(false, w, AtomEnum::WM_NAME, AtomEnum::ANY, 0, 256)
                .ok()
                .and_then(|c| c.reply().ok())
                .is_some_and(|p| String::from_utf8_lossy(&p.value).contains("voxcollide view"))
        });
        // Once it has drawn: the window shows the bodies and the heads-up text (many colours),
        // not its blank background. A fixed wait was not enough on a loaded machine, where
        // the device and the run take longer to set up after the window opens.
        if let Some(w) = found
            && drawn(conn, w)
        {
            // And a few frames more.
            std::thread::sleep(Duration::from_millis(500));
            return w;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// Whether `window` shows a drawn frame: at least three colours in its top left 200 × 40
/// pixels (the heads-up line's dark text on its light panel, over the background), where a
/// window not drawn yet shows one.
fn drawn(conn: &impl x11rb::connection::Connection, window: u32) -> bool {
    use x11rb::protocol::xproto::{ConnectionExt, ImageFormat};
    let Some(image) =
        conn.get_image(ImageFormat::Z_PIXMAP, window, 0, 0, 200, 40, !0).ok().and_then(|c| c.reply().ok())
    else {
        return false;
    };
    let colours: std::collections::HashSet<&[u8]> = image.data.chunks(4).collect();
    colours.len() >= 3
}

/// Asks `window` to close as a window manager does when its close button is pressed, and waits
/// for the view to end cleanly: its stdout.
fn close(conn: &impl x11rb::connection::Connection, window: u32, mut child: Child) -> String {
    use x11rb::protocol::xproto::{ClientMessageEvent, ConnectionExt, EventMask};
    let atom = |name: &[u8]| conn.intern_atom(false, name).unwrap().reply().unwrap().atom;
    let (protocols, delete) = (atom(b"WM_PROTOCOLS"), atom(b"WM_DELETE_WINDOW"));
    let event = ClientMessageEvent::new(32, window, protocols, [delete, 0, 0, 0, 0]);
    conn.send_event(false, window, EventMask::NO_EVENT, event).unwrap();
    conn.flush().unwrap();
    let since = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        assert!(
            since.elapsed() < Duration::from_secs(60),
            "the view did not end after its window was closed"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    let output = child.wait_with_output().unwrap();
    let out = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(status.success(), "{status}\n{out}\n{}", String::from_utf8_lossy(&output.stderr));
    out
}

#[test]
fn keys_and_the_mouse_steer_the_view() {
    use x11rb::connection::Connection;
    use x11rb::protocol::xproto::{BUTTON_PRESS_EVENT, BUTTON_RELEASE_EVENT, ConnectionExt, KEY_PRESS_EVENT};
    use x11rb::protocol::xproto::{InputFocus, KEY_RELEASE_EVENT, MOTION_NOTIFY_EVENT};
    use x11rb::protocol::xtest::ConnectionExt as _;

    let Some(x) = Xvfb::start() else { return };
    let d = dir("keys");
    let (report, first) = (d.join("report.json"), d.join("first.json"));
    // The camera it starts with.
    ok(x.view(&["implant", "--frames", "1", "--report"]).arg(&first).output().unwrap());
    let start = json(&first)["camera"].clone();
    let (mut child, conn, screen) = x.interactive("implant", &report);
    let root = conn.setup().roots[screen].root;
    let window = find_window(&conn, root, &mut child);
    let corner = conn.translate_coordinates(window, root, 0, 0).unwrap().reply().unwrap();
    let (cx, cy) = (corner.dst_x + 480, corner.dst_y + 320);
    let (min, max) = (conn.setup().min_keycode, conn.setup().max_keycode);
    let map = conn.get_keyboard_mapping(min, max - min + 1).unwrap().reply().unwrap();
    let per = usize::from(map.keysyms_per_keycode);
    let keycode = |keysym: u32| {
        let i = map.keysyms.iter().position(|&k| k == keysym).expect("the key is mapped");
        min + (i / per) as u8
    };
    let fake = |kind: u8, detail: u8, x: i16, y: i16| {
        conn.xtest_fake_input(kind, detail, 0, root, x, y, 0).unwrap();
        conn.flush().unwrap();
        std::thread::sleep(Duration::from_millis(150));
    };
    // The pointer into the window, and the keyboard's focus on it (a window manager's job).
    fake(MOTION_NOTIFY_EVENT, 0, cx, cy);
    conn.set_input_focus(InputFocus::PARENT, window, x11rb::CURRENT_TIME).unwrap();
    conn.flush().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    // c: colouring by contact force; space: pause.
    for key in [0x63, 0x20] {
        fake(KEY_PRESS_EVENT, keycode(key), 0, 0);
        fake(KEY_RELEASE_EVENT, keycode(key), 0, 0);
    }
    // A drag (the implant scene has no instrument, so it orbits), then the wheel (zoom in).
    fake(BUTTON_PRESS_EVENT, 1, 0, 0);
    for step in 1..=5 {
        fake(MOTION_NOTIFY_EVENT, 0, cx + 30 * step, cy + 6 * step);
    }
    fake(BUTTON_RELEASE_EVENT, 1, 0, 0);
    for _ in 0..3 {
        fake(BUTTON_PRESS_EVENT, 4, 0, 0);
        fake(BUTTON_RELEASE_EVENT, 4, 0, 0);
    }
    std::thread::sleep(Duration::from_millis(500));
    close(&conn, window, child);
    let r = json(&report);
    assert_eq!((r["colouring"].as_str(), r["paused"].as_bool()), (Some("force"), Some(true)), "{r}");
    let camera = &r["camera"];
    let at = |c: &Value, k: usize| c[k].as_f64().unwrap();
    assert!((at(camera, 0) - at(&start, 0)).abs() > 0.3, "the drag did not orbit: {camera} from {start}");
    assert!((at(camera, 1) - at(&start, 1)).abs() > 0.05, "{camera} from {start}");
    assert!(at(camera, 2) < 0.8 * at(&start, 2), "the wheel did not zoom in: {camera} from {start}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn closing_the_window_ends_the_view_cleanly() {
    let Some(x) = Xvfb::start() else { return };
    let d = dir("close");
    let report = d.join("report.json");
    // Interactive: no --frames, so only a close ends it.
    let (mut child, conn, screen) = x.interactive("implant", &report);
    let root = x11rb::connection::Connection::setup(&conn).roots[screen].root;
    let window = find_window(&conn, root, &mut child);
    let out = close(&conn, window, child);
    assert!(out.contains("frames/s"), "{out}");
    let r = json(&report);
    assert!(r["frames"].as_u64().unwrap() > 0 && r["steps"].as_u64().unwrap() > 0, "{r}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn without_a_display_it_says_so_in_one_line_and_points_to_run() {
    let output = Command::new(env!("CARGO_BIN_EXE_voxcollide"))
        .args(["view", "implant", "--frames", "1"])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    assert!(!output.status.success());
    let err = String::from_utf8_lossy(&output.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("no display") && err.contains("voxcollide run implant"), "{err}");
    assert!(output.stdout.is_empty());
}

#[test]
fn a_bad_scene_or_drag_is_named_before_any_window() {
    // Neither a file nor a shipped name; a drag that does not parse: errors, no window needed.
    let output = Command::new(env!("CARGO_BIN_EXE_voxcollide"))
        .args(["view", "no-such-scene", "--frames", "1"])
        .env("DISPLAY", ":12345")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&output.stderr);
    assert!(
        !output.status.success() && err.contains("shipped scene") && err.contains("indentation"),
        "{err}"
    );
    let output = Command::new(env!("CARGO_BIN_EXE_voxcollide"))
        .args(["view", "implant", "--drag", "1,2 -> 3 over 2 frames"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && err.contains("x0,y0 -> x1,y1 over N frames"), "{err}");
}

#[test]
fn a_blow_up_ends_a_run_of_frames_with_its_error_on_either_backend() {
    // A step far above the stability bound, and a ball pressed in: the block blows up within
    // its first steps. A run of --frames ends with the simulation's error (not a hang, not a
    // panic, no screenshot).
    let Some(x) = Xvfb::start() else { return };
    let d = dir("blow-up");
    let scene = d.join("unstable.toml");
    std::fs::write(
        &scene,
        "units = \"mm\"\n[time]\nduration = 10\ndt = 0.05\n[[body]]\nname = \"block\"\nkind = \"soft\"\nshape = { box = [40, 40, 10] }\nspacing = 5\nmaterial = { young_kpa = 50 }\nfixed = [{ below = { z = -4 } }]\n[[body]]\nname = \"ball\"\nkind = \"rigid\"\nshape = { sphere = 8 }\nspacing = 2\nmotion = [{ t = 0.0, position = [0, 0, 14] }, { t = 1, position = [0, 0, 0] }]\n[[contact]]\na = \"ball\"\nb = \"block\"\nresponse = \"penalty\"\n",
    )
    .unwrap();
    for backend in ["gpu", "cpu"] {
        let shot = d.join(format!("{backend}.png"));
        let output = x
            .view(&[
                scene.to_str().unwrap(),
                "--backend",
                backend,
                "--frames",
                "30",
                "--steps-per-frame",
                "20",
            ])
            .args(["--screenshot".as_ref(), shot.as_os_str()])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{backend}: {err}");
        assert!(err.contains("simulation failed") && err.contains("block"), "{backend}: {err}");
        assert_eq!(err.matches("simulation failed").count(), 1, "{backend}: {err}");
        assert!(!shot.exists(), "{backend}: a screenshot of a failed run");
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn the_implicit_integrator_steps_in_the_window_on_the_gpu() {
    let Some(x) = Xvfb::start() else { return };
    let d = dir("implicit");
    // scenes/indentation.toml under the implicit integrator with its surface contact: the WGSL
    // passes, the contact's couplings among them, asked for by --backend gpu.
    let scenes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let text = std::fs::read_to_string(scenes.join("indentation.toml")).unwrap();
    let implicit = text.replace("max_steps = 8000", "max_steps = 8000\nintegrator = \"implicit\"");
    assert!(implicit.contains("integrator") && !implicit.contains("response"));
    let scene = d.join("implicit.toml");
    std::fs::write(&scene, implicit).unwrap();
    let report = d.join("report.json");
    let out = ok(x
        .view(&[scene.to_str().unwrap(), "--backend", "gpu", "--frames", "8", "--steps-per-frame", "10"])
        .args(["--report".as_ref(), report.as_os_str()])
        .output()
        .unwrap());
    assert!(out.contains("on the gpu backend"), "{out}");
    let r = json(&report);
    assert_eq!((r["backend"].as_str(), r["steps"].as_u64()), (Some("gpu"), Some(80)), "{r}");
    let block = r["max_displacement"][0][1].as_f64().unwrap();
    assert!(block > 0.5, "the ball pressed the block {block} mm");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn on_the_gpu_the_bodies_are_drawn_where_they_step_and_read_back_a_few_times_a_second() {
    let Some(x) = Xvfb::start() else { return };
    let d = dir("device");
    let run = |name: &str, args: &[&str]| -> (Value, Vec<[u8; 4]>) {
        let (report, shot) = (d.join(format!("{name}.json")), d.join(format!("{name}.png")));
        let mut all = vec!["implant", "--size", "480x320"];
        all.extend_from_slice(args);
        ok(x.view(&all)
            .args(["--report".as_ref(), report.as_os_str(), "--screenshot".as_ref(), shot.as_os_str()])
            .output()
            .unwrap());
        (json(&report), png(&shot).0)
    };
    // Repeatable (fixed steps a frame): the same frames drawn from the device on the GPU
    // backend as from the read-back positions on the CPU's, to within the edges' rasterising.
    let fixed = ["--frames", "12", "--steps-per-frame", "50"];
    let (gpu, gpu_shot) = run("gpu", &[&["--backend", "gpu"][..], &fixed[..]].concat());
    let (cpu, cpu_shot) = run("cpu", &[&["--backend", "cpu"][..], &fixed[..]].concat());
    assert_eq!(
        (gpu["backend"].as_str(), gpu["frames_from_device"].as_u64()),
        (Some("gpu"), Some(12)),
        "{gpu}"
    );
    assert_eq!(
        (cpu["backend"].as_str(), cpu["frames_from_device"].as_u64()),
        (Some("cpu"), Some(0)),
        "{cpu}"
    );
    let differ = gpu_shot
        .iter()
        .zip(&cpu_shot)
        .filter(|(a, b)| a.iter().zip(*b).any(|(p, q)| p.abs_diff(*q) > 24))
        .count();
    // The heads-up line's figures (steps/s, frames/s) differ; the bodies do not.
    assert!(differ < gpu_shot.len() / 50, "{differ} of {} pixels differ", gpu_shot.len());
    assert!(gpu_shot.iter().filter(|p| dent(**p)).count() > 50, "no lifted tissue drawn from the device");
    // In real time the window takes a state (a read-back on the GPU) at most ten times a second
    // while it draws the bodies from the device.
    let (live, _) = run("live", &["--backend", "gpu", "--frames", "30"]);
    let (frames, states, seconds) = (
        live["frames_from_device"].as_u64().unwrap(),
        live["states_read"].as_u64().unwrap(),
        live["seconds"].as_f64().unwrap(),
    );
    assert_eq!(frames, 30, "{live}");
    // (At least one once the frames took a few tenths of a second: a fast device could draw
    // all 30 within one tenth.)
    assert!(
        (states >= 1 || seconds < 0.3) && (states as f64) <= 10.0 * seconds + 3.0,
        "{states} states in {seconds} s: {live}"
    );
    // Coloured by contact force, the frames come from the read-back states.
    let (force, _) = run("force", &[&["--backend", "gpu", "--colouring", "force"][..], &fixed[..]].concat());
    assert_eq!(force["frames_from_device"].as_u64(), Some(0), "{force}");
    std::fs::remove_dir_all(&d).unwrap();
}
