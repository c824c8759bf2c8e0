//! The offscreen renderer on real meshes: a colour-mapped, shaded sphere, cut-aways, a dented
//! tissue slab under a cylinder written as PNG, and bad inputs as typed errors; and the colour
//! legend drawn over a picture on the CPU (those tests need no adapter).

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod common;

use std::path::PathBuf;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use voxcollide::Error;
use voxcollide::glam::Vec3;
use voxcollide_render::{
    Legend, PixelRect, Renderer, SHADER, Scene, SceneMesh, draw_legend, legend_panel, write_png,
};

/// The background, sRGB-encoded: linear 0.8.
const BACKGROUND: u8 = 231;

/// A closed triangle mesh with a scalar per vertex, built so that every triangle is
/// counter-clockwise seen from outside.
#[derive(Default)]
struct Body {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    scalars: Vec<f32>,
}

impl Body {
    fn vertex(&mut self, p: Vec3, s: f32) -> u32 {
        self.positions.push(p);
        self.scalars.push(s);
        (self.positions.len() - 1) as u32
    }

    /// Adds the triangle wound so that its normal points along `outward`; drops it if it has no
    /// area (the poles of a UV sphere).
    fn triangle(&mut self, t: [u32; 3], outward: Vec3) {
        let [a, b, c] = t.map(|i| self.positions[i as usize]);
        let n = (b - a).cross(c - a);
        if n.length() < 1e-9 {
            return;
        }
        self.triangles.push(if n.dot(outward) >= 0.0 { t } else { [t[0], t[2], t[1]] });
    }

    fn mesh(&self, scalars: bool, base_color: [f32; 3]) -> SceneMesh<'_> {
        SceneMesh {
            positions: &self.positions,
            triangles: &self.triangles,
            scalars: scalars.then_some(&self.scalars[..]),
            base_color,
        }
    }
}

/// A UV sphere; the scalar is the x coordinate relative to the centre.
fn sphere(centre: Vec3, radius: f32, stacks: u32, slices: u32) -> Body {
    let mut body = Body::default();
    let mut ring = Vec::new();
    for i in 0..=stacks {
        let theta = std::f32::consts::PI * i as f32 / stacks as f32;
        let row: Vec<u32> = (0..slices)
            .map(|j| {
                let phi = std::f32::consts::TAU * j as f32 / slices as f32;
                let d = Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
                body.vertex(centre + radius * d, d.x * radius)
            })
            .collect();
        ring.push(row);
    }
    for i in 0..stacks as usize {
        for j in 0..slices as usize {
            let k = (j + 1) % slices as usize;
            let (a, b, c, d) = (ring[i][j], ring[i][k], ring[i + 1][k], ring[i + 1][j]);
            for t in [[a, b, c], [a, c, d]] {
                let mid = t.iter().map(|&v| body.positions[v as usize]).sum::<Vec3>() / 3.0;
                body.triangle(t, mid - centre);
            }
        }
    }
    body
}

/// The depth of the dent a cylinder of radius 0.6 presses into the slab, at (x, z).
fn dent(x: f32, z: f32) -> f32 {
    0.35 * (-(x * x + z * z) / 0.45).exp()
}

/// A tissue slab over [-2, 2]² (top at y = 0, bottom at y = -0.8), its top dented; the scalar
/// is the displacement (0 off the top surface).
fn slab(n: usize) -> Body {
    let mut body = Body::default();
    let coord = |i: usize| -2.0 + 4.0 * i as f32 / (n - 1) as f32;
    let mut top = vec![vec![0; n]; n];
    let mut bottom = vec![vec![0; n]; n];
    for i in 0..n {
        for k in 0..n {
            let (x, z) = (coord(i), coord(k));
            top[i][k] = body.vertex(Vec3::new(x, -dent(x, z), z), dent(x, z));
            bottom[i][k] = body.vertex(Vec3::new(x, -0.8, z), 0.0);
        }
    }
    for i in 0..n - 1 {
        for k in 0..n - 1 {
            for (grid, up) in [(&top, Vec3::Y), (&bottom, Vec3::NEG_Y)] {
                let (a, b, c, d) = (grid[i][k], grid[i + 1][k], grid[i + 1][k + 1], grid[i][k + 1]);
                body.triangle([a, b, c], up);
                body.triangle([a, c, d], up);
            }
        }
    }
    // The four sides: walk the boundary of the grid.
    let mut ring: Vec<(usize, usize)> = (0..n).map(|i| (i, 0)).collect();
    ring.extend((1..n).map(|k| (n - 1, k)));
    ring.extend((0..n - 1).rev().map(|i| (i, n - 1)));
    ring.extend((0..n - 1).rev().map(|k| (0, k)));
    for w in ring.windows(2) {
        let ((i0, k0), (i1, k1)) = (w[0], w[1]);
        let (a, b, c, d) = (top[i0][k0], top[i1][k1], bottom[i1][k1], bottom[i0][k0]);
        let mid = (body.positions[a as usize] + body.positions[c as usize]) / 2.0;
        let out = Vec3::new(mid.x, 0.0, mid.z);
        body.triangle([a, b, c], out);
        body.triangle([a, c, d], out);
    }
    body
}

/// A closed cylinder along y with its bottom cap at `bottom`.
fn cylinder(bottom: Vec3, radius: f32, height: f32, slices: u32) -> Body {
    let mut body = Body::default();
    let lo_c = body.vertex(bottom, 0.0);
    let hi_c = body.vertex(bottom + Vec3::Y * height, 0.0);
    let rim = |body: &mut Body, y: f32| -> Vec<u32> {
        (0..slices)
            .map(|j| {
                let phi = std::f32::consts::TAU * j as f32 / slices as f32;
                body.vertex(bottom + Vec3::new(radius * phi.cos(), y, radius * phi.sin()), 0.0)
            })
            .collect()
    };
    let (lo, hi) = (rim(&mut body, 0.0), rim(&mut body, height));
    for j in 0..slices as usize {
        let k = (j + 1) % slices as usize;
        let mid = (body.positions[lo[j] as usize] + body.positions[hi[k] as usize]) / 2.0 - bottom;
        let out = Vec3::new(mid.x, 0.0, mid.z);
        body.triangle([lo[j], lo[k], hi[k]], out);
        body.triangle([lo[j], hi[k], hi[j]], out);
        body.triangle([lo_c, lo[k], lo[j]], Vec3::NEG_Y);
        body.triangle([hi_c, hi[j], hi[k]], Vec3::Y);
    }
    body
}

/// A scene of `meshes` seen along `view_dir` with y up, scalars over `range`.
fn scene<'a>(meshes: Vec<SceneMesh<'a>>, range: (f32, f32), view_dir: Vec3) -> Scene<'a> {
    Scene { meshes, scalar_range: range, clip: None, view_dir, up: Vec3::Y }
}

/// The RGBA pixel at column `x`, row `y` (top row 0).
fn pixel(rgba: &[u8], width: u32, x: u32, y: u32) -> [u8; 4] {
    let i = 4 * (y * width + x) as usize;
    [rgba[i], rgba[i + 1], rgba[i + 2], rgba[i + 3]]
}

fn is_background(p: [u8; 4]) -> bool {
    p[..3].iter().all(|&c| c.abs_diff(BACKGROUND) <= 1) && p[3] == 255
}

fn brightness(p: [u8; 4]) -> u32 {
    p[..3].iter().map(|&c| u32::from(c)).sum()
}

fn temp_png(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("voxcollide_render_{}_{name}.png", std::process::id()))
}

/// Decodes a PNG written by `write_png`: (width, height, RGBA bytes).
fn decode(path: &PathBuf) -> (u32, u32, Vec<u8>) {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut reader = png::Decoder::new(file).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.color_type, info.bit_depth), (png::ColorType::Rgba, png::BitDepth::Eight));
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

#[test]
fn the_shader_parses_and_validates_with_default_capabilities() {
    let module = naga::front::wgsl::parse_str(SHADER)
        .unwrap_or_else(|e| panic!("render.wgsl: {}", e.emit_to_string(SHADER)));
    let mut validator = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    );
    if let Err(e) = validator.validate(&module) {
        panic!("render.wgsl does not validate: {}", e.emit_to_string(SHADER));
    }
    let names: Vec<&str> = module.entry_points.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(names, ["vs_main", "fs_main"]);
}

#[test]
fn write_png_round_trips_and_rejects_bad_input() {
    let (w, h) = (7, 5);
    let rgba: Vec<u8> = (0..w * h * 4).map(|i| (i * 37 % 256) as u8).collect();
    let path = temp_png("round_trip");
    write_png(&path, w, h, &rgba).unwrap();
    assert_eq!(decode(&path), (w, h, rgba.clone()));

    let short = write_png(&path, w, h, &rgba[4..]);
    assert!(matches!(short, Err(Error::Invalid { what: "rgba length", .. })), "{short:?}");
    let empty = write_png(&path, 0, h, &[]);
    assert!(matches!(empty, Err(Error::Invalid { what: "width", .. })), "{empty:?}");
    let dir = std::env::temp_dir().join("voxcollide_render_no_such_dir").join("x.png");
    let io = write_png(&dir, w, h, &rgba);
    assert!(
        matches!(&io, Err(Error::Io { path, .. }) if path.contains("voxcollide_render_no_such_dir")),
        "{io:?}"
    );
}

#[test]
fn a_sphere_with_a_gradient_is_shaded_and_colour_mapped() {
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (240, 200);
    let mut renderer = Renderer::new(&ctx, w, h).unwrap();
    assert_eq!(renderer.size(), (w, h));
    let ball = sphere(Vec3::new(3.0, -1.0, 2.0), 1.0, 32, 64);
    let rgba = renderer.render(&scene(vec![ball.mesh(true, [1.0; 3])], (-1.0, 1.0), Vec3::NEG_Z)).unwrap();
    assert_eq!(rgba.len(), (w * h * 4) as usize);
    write_png(&temp_png("sphere_gradient"), w, h, &rgba).unwrap();

    let corner = pixel(&rgba, w, 0, 0);
    let centre = pixel(&rgba, w, w / 2, h / 2);
    assert!(is_background(corner), "corner {corner:?} is not the background");
    assert!(!is_background(centre), "centre {centre:?} shows no sphere");
    assert!(rgba.chunks(4).all(|p| p[3] == 255), "the picture is opaque");
    let drawn = rgba.chunks(4).filter(|p| !is_background([p[0], p[1], p[2], p[3]])).count();
    // A sphere framed with a small margin covers about pi/4 of the picture's height squared.
    let share = drawn as f64 / f64::from(h * h);
    assert!((0.55..0.85).contains(&share), "the sphere covers {share} of h²");

    // The scalar is x: low (viridis violet-blue) on the left, high (green-yellow) on the right.
    let left = pixel(&rgba, w, w / 2 - h / 5, h / 2);
    let right = pixel(&rgba, w, w / 2 + h / 5, h / 2);
    assert!(left[2] > left[1] + 20, "left {left:?} is not the map's low end");
    assert!(right[1] > right[2] + 40, "right {right:?} is not the map's high end");
    assert!(right[1] > left[1] && left[2] > right[2], "left {left:?} right {right:?}");
    // Along the middle row the map runs from low to high: blue over green turns to green over
    // blue, in the mean of each quarter of the sphere's width.
    let row: Vec<i32> = (0..w)
        .map(|x| pixel(&rgba, w, x, h / 2))
        .filter(|&p| !is_background(p))
        .map(|p| i32::from(p[2]) - i32::from(p[1]))
        .collect();
    assert!(row.len() > 100, "the middle row crosses {} sphere pixels", row.len());
    let quarter = row.len() / 4;
    let mean = |s: &[i32]| s.iter().sum::<i32>() / s.len() as i32;
    let (first, last) = (mean(&row[..quarter]), mean(&row[row.len() - quarter..]));
    assert!(first > last + 60, "blue minus green: {first} in the left quarter, {last} in the right");
}

#[test]
fn a_plain_sphere_is_lit_by_a_headlight() {
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (160, 160);
    let mut renderer = Renderer::new(&ctx, w, h).unwrap();
    let ball = sphere(Vec3::ZERO, 1.0, 24, 48);
    let grey = [0.7, 0.7, 0.7];
    let rgba = renderer.render(&scene(vec![ball.mesh(false, grey)], (0.0, 1.0), Vec3::NEG_Z)).unwrap();
    let centre = pixel(&rgba, w, w / 2, h / 2);
    let limb = pixel(&rgba, w, w / 2 + 2 * w / 5, h / 2);
    assert!(!is_background(limb), "{limb:?} should be near the right edge of the sphere");
    assert!(brightness(centre) > brightness(limb) + 60, "centre {centre:?} limb {limb:?}: not Lambert-lit");
    // Without scalars every pixel is the base colour, shaded: a grey.
    for p in rgba.chunks(4) {
        let spread = p[..3].iter().max().unwrap() - p[..3].iter().min().unwrap();
        assert!(spread <= 2, "pixel {p:?} is not grey");
    }
    // Deterministic: the same scene gives the same bytes.
    let again = renderer.render(&scene(vec![ball.mesh(false, grey)], (0.0, 1.0), Vec3::NEG_Z)).unwrap();
    assert!(rgba == again, "a second render differs");
}

#[test]
fn a_clip_facing_the_camera_shows_the_inside() {
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (160, 120);
    let mut renderer = Renderer::new(&ctx, w, h).unwrap();
    let ball = sphere(Vec3::ZERO, 1.0, 24, 48);
    let mut s = scene(vec![ball.mesh(true, [1.0; 3])], (-1.0, 1.0), Vec3::NEG_Z);
    let whole = renderer.render(&s).unwrap();
    // Keep z <= 0, the far half: the near half, the front face the camera saw, is cut away.
    s.clip = Some((Vec3::ZERO, Vec3::NEG_Z));
    let cut = renderer.render(&s).unwrap();
    write_png(&temp_png("sphere_front_cut"), w, h, &cut).unwrap();

    let (before, after) = (pixel(&whole, w, w / 2, h / 2), pixel(&cut, w, w / 2, h / 2));
    assert!(!is_background(after), "the inside {after:?} should show through the cut");
    // The inside is drawn darker and greyer than the outside, so it reads as inside.
    let spread = |p: [u8; 4]| p[..3].iter().max().unwrap() - p[..3].iter().min().unwrap();
    assert!(
        brightness(after) * 10 < brightness(before) * 9 && spread(after) * 2 < spread(before),
        "centre {before:?} before the cut, {after:?} after: the inside should be darker and greyer"
    );
    // The outline stays where it was: the far half has the same silhouette.
    for x in [w / 2 - h / 3, w / 2 + h / 3] {
        let (b, a) = (pixel(&whole, w, x, h / 2), pixel(&cut, w, x, h / 2));
        assert_eq!(is_background(b), is_background(a), "column {x}: {b:?} vs {a:?}");
    }
}

#[test]
fn a_side_clip_removes_the_cut_half() {
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (160, 120);
    let mut renderer = Renderer::new(&ctx, w, h).unwrap();
    let ball = sphere(Vec3::ZERO, 1.0, 24, 48);
    let mut s = scene(vec![ball.mesh(true, [1.0; 3])], (-1.0, 1.0), Vec3::new(0.3, -0.2, -1.0));
    // The low scalars are at x < 0: blue-dominant pixels (viridis below about 0.45).
    let low = |p: &[u8]| p[2] > p[1] + 10;
    let whole = renderer.render(&s).unwrap();
    assert!(whole.chunks(4).filter(|p| low(p)).count() > 1000, "the whole sphere shows its low half");
    s.clip = Some((Vec3::ZERO, Vec3::X));
    let cut = renderer.render(&s).unwrap();
    write_png(&temp_png("sphere_side_cut"), w, h, &cut).unwrap();
    let left = cut.chunks(4).filter(|p| low(p)).count();
    assert_eq!(left, 0, "{left} pixels of the cut-away half (x < 0) are still drawn");
    let drawn = cut.chunks(4).filter(|p| !is_background([p[0], p[1], p[2], p[3]])).count();
    // The kept half is framed: it fills the picture about as the whole sphere did.
    assert!(drawn > (w * h / 4) as usize, "only {drawn} pixels of the kept half are drawn");
}

#[test]
fn a_dented_slab_under_a_cylinder_cut_away_is_written_as_png() {
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (640, 400);
    let mut renderer = Renderer::new(&ctx, w, h).unwrap();
    let tissue = slab(61);
    let tool = cylinder(Vec3::new(0.0, -dent(0.0, 0.0), 0.0), 0.6, 1.6, 48);
    let mut s = scene(
        vec![tissue.mesh(true, [0.8, 0.6, 0.5]), tool.mesh(false, [0.35, 0.45, 0.6])],
        (0.0, dent(0.0, 0.0)),
        Vec3::new(-0.5, -0.6, -1.0),
    );
    // Cut both bodies open through the contact: keep z <= 0, facing the camera.
    s.clip = Some((Vec3::ZERO, Vec3::NEG_Z));
    let path = temp_png("slab_cylinder_cut");
    renderer.render_png(&s, &path).unwrap();
    let (dw, dh, rgba) = decode(&path);
    assert_eq!((dw, dh), (w, h));
    assert_eq!(rgba, renderer.render(&s).unwrap(), "the file holds the rendered bytes");
    let drawn = rgba.chunks(4).filter(|p| !is_background([p[0], p[1], p[2], p[3]])).count();
    assert!(drawn > (w * h / 4) as usize, "only {drawn} pixels drawn");
    // The dent's bottom maps to the high end (yellow: red and green well over blue) somewhere.
    let yellow = rgba.chunks(4).filter(|p| is_yellow([p[0], p[1], p[2], p[3]])).count();
    assert!(yellow > 50, "{yellow} pixels show the deepest part of the dent");
    // The cylinder is drawn in its own blue-grey.
    let tool_px = rgba.chunks(4).filter(|p| p[2] > p[0] + 15 && p[1] > p[0] && p[2] > p[1]).count();
    assert!(tool_px > 200, "{tool_px} pixels show the cylinder");
}

#[test]
fn equal_range_ends_draw_one_colour() {
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (96, 96);
    let mut renderer = Renderer::new(&ctx, w, h).unwrap();
    let ball = sphere(Vec3::ZERO, 1.0, 16, 32);
    let rgba = renderer.render(&scene(vec![ball.mesh(true, [1.0; 3])], (0.25, 0.25), Vec3::NEG_Z)).unwrap();
    // One hue everywhere: viridis' low end, violet (blue over red over green), only shaded.
    for p in rgba.chunks(4).filter(|p| !is_background([p[0], p[1], p[2], p[3]])) {
        assert!(p[2] >= p[0] && p[0] >= p[1], "pixel {p:?} is not the low-end violet");
    }
}

#[test]
fn broken_vertices_lose_their_triangles_not_the_picture() {
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (96, 96);
    let mut renderer = Renderer::new(&ctx, w, h).unwrap();
    let mut ball = sphere(Vec3::ZERO, 1.0, 16, 32);
    ball.positions[40] = Vec3::NAN;
    ball.positions[41] = Vec3::new(f32::INFINITY, 0.0, 0.0);
    ball.scalars[100] = f32::NAN;
    let rgba =
        renderer.render(&scene(vec![ball.mesh(true, [1.0, 0.0, 0.0])], (-1.0, 1.0), Vec3::NEG_Z)).unwrap();
    assert!(!is_background(pixel(&rgba, w, w / 2, h / 2)), "the sphere is still drawn");

    // Nothing finite, or nothing at all, to draw: the background alone.
    let nan = [Vec3::NAN; 3];
    let broken = SceneMesh { positions: &nan, triangles: &[[0, 1, 2]], scalars: None, base_color: [0.0; 3] };
    for meshes in [vec![broken], vec![]] {
        let rgba = renderer.render(&scene(meshes, (0.0, 1.0), Vec3::NEG_Z)).unwrap();
        assert!(rgba.chunks(4).all(|p| is_background([p[0], p[1], p[2], p[3]])), "not all background");
    }
}

#[test]
fn a_growing_scene_reuses_the_renderer() {
    let Some(ctx) = common::gpu() else { return };
    let mut renderer = Renderer::new(&ctx, 64, 48).unwrap();
    for stacks in [4, 64, 8, 128] {
        let ball = sphere(Vec3::ZERO, 1.0, stacks, 2 * stacks);
        let rgba = renderer.render(&scene(vec![ball.mesh(true, [1.0; 3])], (-1.0, 1.0), Vec3::Y)).unwrap();
        assert!(!is_background(pixel(&rgba, 64, 32, 24)), "{stacks} stacks: no sphere");
    }
}

#[test]
fn bad_inputs_are_typed_errors() {
    let Some(ctx) = common::gpu() else { return };
    let max = ctx.device().limits().max_texture_dimension_2d;
    for (w, h, what) in [(0, 10, "width"), (10, 0, "height"), (max + 1, 10, "width"), (10, max + 1, "height")]
    {
        let e = Renderer::new(&ctx, w, h).unwrap_err();
        assert!(matches!(&e, Error::Invalid { what: got, .. } if *got == what), "{w}×{h}: {e}");
    }

    let mut renderer = Renderer::new(&ctx, 32, 32).unwrap();
    let ball = sphere(Vec3::ZERO, 1.0, 8, 16);
    let invalid = |renderer: &mut Renderer, s: &Scene, expected: &str| {
        let e = renderer.render(s).unwrap_err();
        assert!(matches!(&e, Error::Invalid { what, .. } if *what == expected), "expected {expected}: {e}");
        println!("{e}");
    };
    let short = &ball.scalars[1..];
    let mesh = SceneMesh { scalars: Some(short), ..ball.mesh(true, [1.0; 3]) };
    invalid(&mut renderer, &scene(vec![mesh], (0.0, 1.0), Vec3::NEG_Z), "scalars length");

    let mut triangles = ball.triangles.clone();
    triangles[5][1] = ball.positions.len() as u32;
    let mesh = SceneMesh { triangles: &triangles, ..ball.mesh(true, [1.0; 3]) };
    invalid(&mut renderer, &scene(vec![mesh], (0.0, 1.0), Vec3::NEG_Z), "triangle index");

    let ok = || ball.mesh(true, [1.0; 3]);
    invalid(&mut renderer, &scene(vec![ok()], (0.0, 1.0), Vec3::ZERO), "view_dir");
    invalid(&mut renderer, &scene(vec![ok()], (0.0, f32::NAN), Vec3::NEG_Z), "scalar_range");
    invalid(
        &mut renderer,
        &scene(vec![ball.mesh(false, [f32::NAN; 3])], (0.0, 1.0), Vec3::NEG_Z),
        "base_color",
    );
    let mut s = scene(vec![ok()], (0.0, 1.0), Vec3::NEG_Z);
    for clip in [(Vec3::ZERO, Vec3::ZERO), (Vec3::NAN, Vec3::X), (Vec3::ZERO, Vec3::splat(f32::INFINITY))] {
        s.clip = Some(clip);
        invalid(&mut renderer, &s, "clip");
    }

    // The renderer still works after rejecting input, and an up parallel to the view is fixed.
    let mut s = scene(vec![ok()], (0.0, 1.0), Vec3::NEG_Z);
    s.up = Vec3::Z;
    let rgba = renderer.render(&s).unwrap();
    assert!(!is_background(pixel(&rgba, 32, 16, 16)));

    let mut failing = Renderer::new(&ctx, 8, 8).unwrap();
    let path = std::env::temp_dir().join("voxcollide_render_no_such_dir").join("x.png");
    let e = failing.render_png(&s, &path).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
}

// The legend.

/// The picture sizes the legend is made for, from the smallest to full HD.
const LEGEND_SIZES: [(u32, u32); 4] = [(320, 200), (640, 400), (1280, 720), (1920, 1080)];

fn displacement(range: (f32, f32)) -> Legend {
    Legend::new("displacement (mm)", range)
}

/// A picture of one colour.
fn filled(width: u32, height: u32, rgb: [u8; 3]) -> Vec<u8> {
    [rgb[0], rgb[1], rgb[2], 255].repeat((width * height) as usize)
}

/// The coefficients `c0`..`c6` of `viridis`, read from the shader's source.
fn shader_viridis_coefficients() -> Vec<[f64; 3]> {
    let body = SHADER.split("fn viridis(").nth(1).expect("render.wgsl has fn viridis");
    let body = &body[..body.find("\n}").expect("fn viridis ends")];
    let coefficients: Vec<[f64; 3]> = (0..)
        .map_while(|k| {
            let line = body.lines().find(|l| l.trim_start().starts_with(&format!("let c{k} =")))?;
            let args = line.split_once("vec3<f32>(")?.1.split_once(')')?.0;
            let v: Vec<f64> = args.split(',').map(|a| a.trim().parse().unwrap()).collect();
            Some([v[0], v[1], v[2]])
        })
        .collect();
    assert_eq!(coefficients.len(), 7, "viridis in render.wgsl: {body}");
    coefficients
}

/// The shader's colour map at `t` as the render target stores it: sRGB-encoded bytes.
fn shader_viridis(c: &[[f64; 3]], t: f64) -> [u8; 3] {
    std::array::from_fn(|i| {
        let v = c.iter().rev().fold(0.0, |acc, ck| acc * t + ck[i]);
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    })
}

/// The largest difference of two colours in any channel.
fn colour_diff(a: [u8; 4], b: [u8; 3]) -> u8 {
    (0..3).map(|i| a[i].abs_diff(b[i])).max().unwrap()
}

/// Saturated: the bar's colours, never the panel's, the text's or the outline's greys.
fn is_colourful(p: [u8; 4]) -> bool {
    p[..3].iter().max().unwrap() - p[..3].iter().min().unwrap() > 40
}

/// The text's near-black grey.
fn is_dark_grey(p: [u8; 4]) -> bool {
    p[..3].iter().all(|&c| c < 64) && p[..3].iter().max().unwrap() - p[..3].iter().min().unwrap() < 8
}

/// The bounding box of the colourful pixels inside `panel`: the bar's colours.
fn find_fill(rgba: &[u8], width: u32, panel: PixelRect) -> PixelRect {
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for y in panel.y..panel.y + panel.height {
        for x in panel.x..panel.x + panel.width {
            if is_colourful(pixel(rgba, width, x, y)) {
                (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
            }
        }
    }
    assert!(x0 <= x1, "no bar in the panel {panel:?}");
    PixelRect { x: x0, y: y0, width: x1 - x0 + 1, height: y1 - y0 + 1 }
}

#[test]
fn the_legend_bar_is_the_shaders_colour_map_from_lo_to_hi() {
    let c = shader_viridis_coefficients();
    for (w, h) in LEGEND_SIZES {
        let mut rgba = filled(w, h, [BACKGROUND; 3]);
        let panel = draw_legend(&mut rgba, w, h, &displacement((0.0, 0.35))).unwrap().expect("it fits");
        let fill = find_fill(&rgba, w, panel);
        assert!(fill.height > 3 * fill.width && fill.width >= 6, "{w}×{h}: the bar {fill:?} is not vertical");
        // Every pixel of the bar's fill is the map, the bottom row lo (t = 0), the top hi (t = 1).
        for r in 0..fill.height {
            let t = 1.0 - f64::from(r) / f64::from(fill.height - 1);
            let expected = shader_viridis(&c, t);
            for x in fill.x..fill.x + fill.width {
                let got = pixel(&rgba, w, x, fill.y + r);
                assert!(
                    colour_diff(got, expected) <= 1 && got[3] == 255,
                    "{w}×{h}: bar row {r} of {} (t = {t:.3}), column {x}: {got:?}, the shader's map gives {expected:?}",
                    fill.height
                );
            }
        }
        write_png(&temp_png(&format!("legend_{w}x{h}")), w, h, &rgba).unwrap();
        let bottom = pixel(&rgba, w, fill.x, fill.y + fill.height - 1);
        let top = pixel(&rgba, w, fill.x, fill.y);
        println!("{w}×{h}: panel {panel:?}, bar {fill:?}, bottom {bottom:?}, top {top:?}");
        // The ends are viridis' violet and yellow (#440154 and #fde725 but for the fit's error).
        assert!(colour_diff(bottom, [68, 1, 84]) <= 4, "{w}×{h}: bottom {bottom:?}");
        assert!(colour_diff(top, [253, 231, 37]) <= 4, "{w}×{h}: top {top:?}");
    }
}

#[test]
fn the_legend_labels_and_title_are_dark_text_on_a_light_panel() {
    for (w, h) in LEGEND_SIZES {
        for background in [[0, 0, 0], [255, 255, 255], [BACKGROUND; 3], [40, 200, 90]] {
            let mut rgba = filled(w, h, background);
            let panel = draw_legend(&mut rgba, w, h, &displacement((-0.35, 0.35))).unwrap().expect("it fits");
            let fill = find_fill(&rgba, w, panel);
            let dark = |x0: u32, x1: u32, y0: u32, y1: u32| {
                let mut n = 0;
                for y in y0..y1 {
                    for x in x0..x1 {
                        n += usize::from(is_dark_grey(pixel(&rgba, w, x, y)));
                    }
                }
                n
            };
            let right = panel.x + panel.width;
            // Labels right of the bar (its outline aside), about its top, middle and bottom rows;
            // the title above it.
            let band =
                |centre: u32| dark(fill.x + fill.width + 2, right, centre - fill.width, centre + fill.width);
            let (top, middle, bottom) =
                (band(fill.y), band(fill.y + fill.height / 2), band(fill.y + fill.height - 1));
            let title = dark(panel.x, right, panel.y, fill.y - fill.width);
            let at = format!("{w}×{h} on {background:?}");
            assert!(
                top > 20 && middle > 20 && bottom > 20,
                "{at}: dark label pixels {top} {middle} {bottom}"
            );
            assert!(title > 100, "{at}: {title} dark title pixels");
            // The panel's background is light whatever lies under it.
            let light = (panel.y..panel.y + panel.height)
                .flat_map(|y| (panel.x..right).map(move |x| (x, y)))
                .map(|(x, y)| pixel(&rgba, w, x, y))
                .filter(|p| !is_colourful(*p) && !is_dark_grey(*p))
                .filter(|p| p[..3].iter().all(|&c| c > 200))
                .count();
            let area = (panel.width * panel.height) as usize;
            assert!(light * 10 > area * 6, "{at}: only {light} of {area} panel pixels are light");
        }
    }
}

#[test]
fn the_legend_leaves_the_picture_outside_its_panel_untouched() {
    let seed = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_nanos() as u64;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut heights = Vec::new();
    for (w, h) in LEGEND_SIZES {
        let before: Vec<u8> = (0..w * h * 4).map(|_| rng.random::<u8>()).collect();
        let mut rgba = before.clone();
        let panel = draw_legend(&mut rgba, w, h, &displacement((0.0, 0.35))).unwrap().expect("it fits");
        let at = format!("{w}×{h} (seed {seed})");
        // In the top-right corner, a few pixels off the edges; a small share of the picture.
        assert!(panel.x + panel.width <= w && panel.y + panel.height <= h, "{at}: {panel:?} is outside");
        assert!(
            w - (panel.x + panel.width) <= w / 40 + 6 && panel.y <= h / 40 + 6,
            "{at}: {panel:?} is not in the corner"
        );
        assert!(panel.x > w / 2, "{at}: {panel:?} reaches the left half");
        let share = f64::from(panel.width * panel.height) / f64::from(w * h);
        assert!((0.01..0.25).contains(&share), "{at}: {panel:?} covers {share} of the picture");
        let mut changed = 0;
        for y in 0..h {
            for x in 0..w {
                let (a, b) = (pixel(&before, w, x, y), pixel(&rgba, w, x, y));
                if panel.contains(x, y) {
                    changed += usize::from(a != b);
                } else {
                    assert_eq!(a, b, "{at}: pixel ({x}, {y}) outside the panel {panel:?} changed");
                }
            }
        }
        assert!(
            changed * 10 > (panel.width * panel.height) as usize * 9,
            "{at}: {changed} panel pixels changed"
        );
        heights.push(panel.height);
    }
    // Scaled with the picture: taller at each size, and the font larger at full HD.
    assert!(heights.windows(2).all(|p| p[0] < p[1]), "panel heights {heights:?}");
    assert!(heights[3] > 3 * heights[0], "panel heights {heights:?}");
}

#[test]
fn equal_range_ends_draw_one_swatch_with_one_label() {
    let c = shader_viridis_coefficients();
    let legend = displacement((0.25, 0.25));
    assert_eq!(legend.tick_labels(), ["0.25"]);
    let (w, h) = (320, 200);
    let mut rgba = filled(w, h, [BACKGROUND; 3]);
    let panel = draw_legend(&mut rgba, w, h, &legend).unwrap().expect("it fits");
    let fill = find_fill(&rgba, w, panel);
    assert!(fill.height <= fill.width + 1, "one value is a swatch, not a bar: {fill:?}");
    let low = shader_viridis(&c, 0.0);
    for y in fill.y..fill.y + fill.height {
        for x in fill.x..fill.x + fill.width {
            let p = pixel(&rgba, w, x, y);
            assert!(colour_diff(p, low) <= 1, "({x}, {y}): {p:?}, the map's low end is {low:?}");
        }
    }
}

#[test]
fn tick_labels_read_to_three_significant_figures() {
    let cases: [((f32, f32), &[&str]); 9] = [
        ((0.0, 0.35), &["0", "0.175", "0.35"]),
        ((-1.0, 1.0), &["-1", "0", "1"]),
        ((0.0, 12.3456), &["0", "6.17", "12.3"]),
        ((0.0, 2.5e-5), &["0", "1.25e-5", "2.5e-5"]),
        ((1.0e6, 3.0e6), &["1e6", "2e6", "3e6"]),
        ((0.35, 0.0), &["0.35", "0.175", "0"]),
        // Three figures would read 1000, 1000, 1000: as many as tell them apart.
        ((1000.0, 1000.5), &["1000", "1000.2", "1000.5"]),
        ((0.001, 0.002), &["0.001", "0.0015", "0.002"]),
        ((7.0, 7.0), &["7"]),
    ];
    for (range, expected) in cases {
        assert_eq!(displacement(range).tick_labels(), expected, "range {range:?}");
    }
}

#[test]
fn a_legend_whose_picture_holds_values_beyond_its_top_says_so() {
    // The colours stop at `hi`; a picture that moved farther shows its top label as `hi+`, and
    // a picture within the range does not.
    let within = displacement((0.0, 0.96)).above(0.5);
    assert_eq!(within.tick_labels(), ["0", "0.48", "0.96"]);
    let beyond = displacement((0.0, 0.96)).above(2.44);
    assert_eq!(beyond.tick_labels(), ["0", "0.48", "0.96+"]);
    assert_eq!(displacement((0.0, 0.96)).above(0.96).tick_labels(), within.tick_labels());
    let (w, h) = (320, 200);
    let (mut plain, mut marked) = (filled(w, h, [BACKGROUND; 3]), filled(w, h, [BACKGROUND; 3]));
    let a = draw_legend(&mut plain, w, h, &within).unwrap().unwrap();
    let b = draw_legend(&mut marked, w, h, &beyond).unwrap().unwrap();
    assert!(b.width >= a.width, "{a:?} {b:?}");
    assert_ne!(plain, marked, "the + was not drawn");
}

#[test]
fn bad_legend_inputs_are_typed_errors() {
    let (w, h) = (320, 200);
    let mut rgba = filled(w, h, [BACKGROUND; 3]);
    let short = draw_legend(&mut rgba[4..], w, h, &displacement((0.0, 1.0)));
    assert!(matches!(short, Err(Error::Invalid { what: "rgba length", .. })), "{short:?}");
    let long = draw_legend(&mut rgba, w, h - 1, &displacement((0.0, 1.0)));
    assert!(matches!(long, Err(Error::Invalid { what: "rgba length", .. })), "{long:?}");
    for range in [(f32::NAN, 1.0), (0.0, f32::INFINITY), (f32::NEG_INFINITY, f32::NAN)] {
        let e = draw_legend(&mut rgba, w, h, &displacement(range));
        assert!(matches!(e, Err(Error::Invalid { what: "legend range", .. })), "{range:?}: {e:?}");
    }
    assert!(rgba == filled(w, h, [BACKGROUND; 3]), "a rejected legend drew something");
}

#[test]
fn tiny_pictures_skip_or_shrink_the_legend_without_panicking() {
    let legend = displacement((0.0, 0.35));
    let mut tiny = filled(16, 16, [BACKGROUND; 3]);
    assert_eq!(draw_legend(&mut tiny, 16, 16, &legend).unwrap(), None);
    assert!(tiny == filled(16, 16, [BACKGROUND; 3]), "a skipped legend drew something");
    assert_eq!(draw_legend(&mut [], 0, 0, &legend).unwrap(), None);
    assert_eq!(draw_legend(&mut [], 0, 100, &legend).unwrap(), None);

    // Every size from a pixel to a small picture, strips included, with titles short, long and
    // outside the font: what is drawn stays inside the picture and the reported panel.
    let long = "the displacement of the tissue under the implant, normal to its surface (µm²·°)";
    let sides = [1, 2, 5, 16, 40, 60, 64, 75, 80, 90, 100, 120, 200, 320];
    let mut drawn = 0;
    for title in ["", "x", "displacement (mm)", long, "变形 (mm)"] {
        for range in [(0.0, 0.35), (-1.5e-7, 2.5e9), (3.0, 3.0)] {
            for w in sides {
                for h in sides {
                    let before = filled(w, h, [BACKGROUND; 3]);
                    let mut rgba = before.clone();
                    let legend = Legend::new(title, range);
                    let Some(panel) = draw_legend(&mut rgba, w, h, &legend).unwrap() else {
                        assert!(rgba == before, "{w}×{h}: a skipped legend drew something");
                        continue;
                    };
                    drawn += 1;
                    assert!(panel.x + panel.width <= w && panel.y + panel.height <= h, "{w}×{h}: {panel:?}");
                    for (i, (a, b)) in before.chunks(4).zip(rgba.chunks(4)).enumerate() {
                        let (x, y) = (i as u32 % w, i as u32 / w);
                        assert!(
                            a == b || panel.contains(x, y),
                            "{w}×{h} {title:?}: ({x}, {y}) outside {panel:?}"
                        );
                    }
                }
            }
        }
    }
    assert!(drawn > 100, "only {drawn} of the sizes got a legend");
    // At the smallest picture size meant for it the long title is shortened, not the legend lost.
    let mut rgba = filled(320, 200, [BACKGROUND; 3]);
    let panel = draw_legend(&mut rgba, 320, 200, &Legend::new(long, (0.0, 0.35))).unwrap();
    assert!(panel.is_some_and(|p| p.width <= 320 - 12), "{panel:?}");
}

#[test]
fn render_png_with_legend_writes_the_picture_with_its_legend() {
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (320, 200);
    let mut renderer = Renderer::new(&ctx, w, h).unwrap();
    let ball = sphere(Vec3::ZERO, 1.0, 24, 48);
    let s = scene(vec![ball.mesh(true, [1.0; 3])], (-1.0, 1.0), Vec3::NEG_Z);
    let legend = Legend::new("x (m)", s.scalar_range);
    let plain = renderer.render(&s).unwrap();

    let path = temp_png("sphere_legend");
    renderer.render_png_with_legend(&s, Some(&legend), &path).unwrap();
    let (dw, dh, rgba) = decode(&path);
    assert_eq!((dw, dh), (w, h));
    assert!(rgba == renderer.render_with_legend(&s, &legend).unwrap(), "the file is not render_with_legend");
    assert!(rgba != plain, "no legend was drawn");
    let panel = legend_panel(w, h, &legend).unwrap().expect("it fits");
    assert_clear_under(&rgba, w, h, &legend, panel);

    let path = temp_png("sphere_no_legend");
    renderer.render_png_with_legend(&s, None, &path).unwrap();
    assert_eq!(decode(&path).2, plain, "without a legend it is render_png");
    let bad = renderer.render_png_with_legend(&s, Some(&Legend::new("x", (0.0, f32::NAN))), &path);
    assert!(matches!(bad, Err(Error::Invalid { what: "legend range", .. })), "{bad:?}");
}

/// Every pixel of `rgba` under the legend's `panel` is what the legend draws over the bare
/// background: no body shows through its translucent panel.
fn assert_clear_under(rgba: &[u8], w: u32, h: u32, legend: &Legend, panel: PixelRect) {
    let mut bare = filled(w, h, [BACKGROUND; 3]);
    draw_legend(&mut bare, w, h, legend).unwrap();
    for y in panel.y..panel.y + panel.height {
        for x in panel.x..panel.x + panel.width {
            assert_eq!(pixel(rgba, w, x, y), pixel(&bare, w, x, y), "a body under the legend at ({x}, {y})");
        }
    }
}

#[test]
fn the_legend_stays_clear_of_the_bodies_that_fill_the_picture() {
    // A slab seen from above fills the picture from edge to edge, as a tissue layer does in
    // `run implant`'s frames: framed alone it runs under the legend's corner; framed with its
    // legend, it keeps to the left of the panel, and still fills the picture's height or the
    // room left of the panel.
    let Some(ctx) = common::gpu() else { return };
    for (w, h) in [(320, 200), (640, 360), (200, 320)] {
        let mut renderer = Renderer::new(&ctx, w, h).unwrap();
        let body = slab(24);
        let s = scene(vec![body.mesh(true, [1.0; 3])], (0.0, 0.5), Vec3::new(0.0, -0.6, -1.0));
        let legend = Legend::new("displacement (mm)", s.scalar_range);
        let panel = legend_panel(w, h, &legend).unwrap().expect("it fits");
        let plain = renderer.render(&s).unwrap();
        let under = (panel.y..panel.y + panel.height)
            .flat_map(|y| (panel.x..panel.x + panel.width).map(move |x| (x, y)))
            .filter(|&(x, y)| !is_background(pixel(&plain, w, x, y)))
            .count();
        assert!(
            under > 0,
            "{w}×{h}: the slab framed alone should reach under the legend (the test's premise)"
        );
        let rgba = renderer.render_with_legend(&s, &legend).unwrap();
        assert_clear_under(&rgba, w, h, &legend, panel);
        // Framed in the room there is: it reaches near the room's left and right, or its top
        // and bottom.
        let covered: Vec<(u32, u32)> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| !panel.contains(x, y) && !is_background(pixel(&rgba, w, x, y)))
            .collect();
        let (x0, x1) =
            (covered.iter().map(|p| p.0).min().unwrap(), covered.iter().map(|p| p.0).max().unwrap());
        let (y0, y1) =
            (covered.iter().map(|p| p.1).min().unwrap(), covered.iter().map(|p| p.1).max().unwrap());
        let fills_width = x0 < w / 8 && x1 + w / 8 > panel.x;
        let fills_height = y0 < h / 8 && y1 + h / 8 > h;
        assert!(
            fills_width || fills_height,
            "{w}×{h}: the slab spans x {x0}..{x1}, y {y0}..{y1}, the panel starts at x {}",
            panel.x
        );
        assert!(x1 < panel.x, "{w}×{h}: the slab reaches x {x1}, the panel starts at {}", panel.x);
    }
}

#[test]
fn a_fixed_eye_at_the_framing_eye_draws_the_framed_picture_and_moves_with_it() {
    // A live view starts its camera where `render` frames the scene: the same picture (within
    // the depth range's rounding at a few edge pixels). Moving the eye back shrinks the sphere;
    // one sample draws the same shapes without smoothed edges.
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (240, 200);
    let ball = sphere(Vec3::new(3.0, -1.0, 2.0), 1.0, 32, 64);
    let view_dir = Vec3::new(0.3, 1.0, -0.4);
    let s = scene(vec![ball.mesh(true, [1.0; 3])], (-1.0, 1.0), view_dir);
    let mut renderer = Renderer::new(&ctx, w, h).unwrap();
    let framed = renderer.render(&s).unwrap();
    let eye =
        voxcollide_render::framing_eye(&ball.positions, view_dir, Vec3::Y, w as f32 / h as f32).unwrap();
    let fixed = renderer.render_from(&s, Some(eye)).unwrap();
    let differ = framed
        .chunks(4)
        .zip(fixed.chunks(4))
        .filter(|(a, b)| a.iter().zip(*b).any(|(x, y)| x.abs_diff(*y) > 2))
        .count();
    assert!(differ < 100, "{differ} pixels differ between the framed camera and its eye");
    let covered = |rgba: &[u8]| rgba.chunks(4).filter(|p| !is_background([p[0], p[1], p[2], p[3]])).count();
    let back = renderer.render_from(&s, Some(eye - 2.0 * (Vec3::new(3.0, -1.0, 2.0) - eye))).unwrap();
    assert!(covered(&back) * 4 < covered(&fixed), "{} vs {}", covered(&back), covered(&fixed));
    let mut fast = Renderer::fast(&ctx, w, h).unwrap();
    let one = fast.render_from(&s, Some(eye)).unwrap();
    let (a, b) = (covered(&one) as f64, covered(&fixed) as f64);
    assert!((a / b - 1.0).abs() < 0.03, "{a} vs {b} pixels covered");
    assert!(matches!(renderer.render_from(&s, Some(Vec3::NAN)), Err(Error::Invalid { what: "eye", .. })));
}

#[test]
fn a_caption_draws_its_lines_on_a_panel_at_the_top_left() {
    let (w, h) = (320u32, 200u32);
    let mut rgba = vec![BACKGROUND; (4 * w * h) as usize];
    let lines = ["120 steps/s  30.0 frames/s".to_string(), "behind real time: 0.50x".to_string()];
    let panel = voxcollide_render::draw_caption(&mut rgba, w, h, &lines).unwrap().expect("it fits");
    assert_eq!((panel.x, panel.y), (6, 6));
    assert_eq!(panel.width, 8 * lines[0].len() as u32 + 8, "the longer line's glyphs and the padding");
    let dark =
        (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).filter(|&(x, y)| pixel(&rgba, w, x, y)[0] < 60);
    let dark: Vec<(u32, u32)> = dark.collect();
    assert!(dark.len() > 200, "{} text pixels", dark.len());
    assert!(dark.iter().all(|&(x, y)| panel.contains(x, y)), "text outside its panel");
    // A long line is cut at the picture's edge; a picture too small for one glyph gets nothing.
    let long = vec!["x".repeat(500)];
    let cut = voxcollide_render::draw_caption(&mut rgba, w, h, &long).unwrap().unwrap();
    assert!(cut.x + cut.width <= w);
    let mut tiny = vec![0u8; 4 * 10 * 10];
    assert_eq!(voxcollide_render::draw_caption(&mut tiny, 10, 10, &long).unwrap(), None);
    assert!(voxcollide_render::draw_caption(&mut tiny, 11, 10, &long).is_err(), "a wrong length is an error");
}

/// A buffer on the device holding `positions` as a simulation keeps them: one `vec4<f32>` each.
fn device_positions(ctx: &voxcollide::GpuContext, positions: &[Vec3]) -> wgpu::Buffer {
    use wgpu::util::DeviceExt as _;
    let data: Vec<[f32; 4]> = positions.iter().map(|p| p.extend(1.0).to_array()).collect();
    ctx.device().create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("test positions"),
        contents: bytemuck::cast_slice(&data),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
    })
}

/// The colour map's high end: red and green well over blue (in `u16`: a light grey's blue
/// plus 60 would wrap in `u8`).
fn is_yellow(p: [u8; 4]) -> bool {
    let [r, g, b] = [p[0], p[1], p[2]].map(u16::from);
    r > b + 60 && g > b + 60
}

/// The share of pixels where two pictures differ by more than `tolerance` in some channel.
fn differing(a: &[u8], b: &[u8], tolerance: u8) -> f64 {
    assert_eq!(a.len(), b.len());
    let n = a
        .chunks(4)
        .zip(b.chunks(4))
        .filter(|(p, q)| p.iter().zip(*q).any(|(x, y)| x.abs_diff(*y) > tolerance))
        .count();
    n as f64 / (a.len() / 4) as f64
}

#[test]
fn meshes_drawn_from_device_buffers_look_as_drawn_from_the_host() {
    use voxcollide_render::{DeviceMesh, DeviceView};
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (480, 320);
    let mut renderer = Renderer::new(&ctx, w, h).unwrap();
    // The dented slab and the cylinder in it, as the host path draws them; on the device the
    // slab started flat, so that each vertex's distance from its start is the host's scalar.
    let tissue = slab(41);
    let tool = cylinder(Vec3::new(0.0, -dent(0.0, 0.0), 0.0), 0.6, 1.6, 32);
    let flat: Vec<Vec3> =
        tissue.positions.iter().map(|p| if p.y > -0.5 { Vec3::new(p.x, 0.0, p.z) } else { *p }).collect();
    let range = (0.0, dent(0.0, 0.0));
    let view_dir = Vec3::new(-0.5, -0.6, -1.0);
    let mut host =
        scene(vec![tissue.mesh(true, [0.8, 0.6, 0.5]), tool.mesh(false, [0.35, 0.45, 0.6])], range, view_dir);
    host.clip = Some((Vec3::ZERO, Vec3::NEG_Z));
    let eye =
        voxcollide_render::framing_eye(&tissue.positions, view_dir, Vec3::Y, w as f32 / h as f32).unwrap();
    let expected = renderer.render_from(&host, Some(eye)).unwrap();

    let tissue_buffer = device_positions(&ctx, &tissue.positions);
    let tool_buffer = device_positions(&ctx, &tool.positions);
    let t = DeviceMesh::new(&mut renderer, &tissue_buffer, &flat, &tissue.triangles, [0.8, 0.6, 0.5], true)
        .unwrap();
    let c = DeviceMesh::new(
        &mut renderer,
        &tool_buffer,
        &tool.positions,
        &tool.triangles,
        [0.35, 0.45, 0.6],
        false,
    )
    .unwrap();
    let view = DeviceView { scalar_range: range, clip: host.clip, view_dir, up: Vec3::Y, eye: Some(eye) };
    let drawn = renderer.render_device(&[&t, &c], &view).unwrap();
    let off = differing(&expected, &drawn, 12);
    assert!(off < 0.01, "{:.2} % of the pixels differ from the host's picture", 100.0 * off);
    let yellow = drawn.chunks(4).filter(|p| is_yellow([p[0], p[1], p[2], p[3]])).count();
    assert!(yellow > 50, "{yellow} pixels show the dent's deepest part");

    // The positions change on the device (a simulation's step): the next frame follows them,
    // with nothing read back. Flat again, the slab moved nowhere: no yellow, and the host's
    // picture of the flat slab.
    ctx.queue().write_buffer(
        &tissue_buffer,
        0,
        bytemuck::cast_slice(&flat.iter().map(|p| p.extend(1.0).to_array()).collect::<Vec<_>>()),
    );
    let moved = renderer.render_device(&[&t, &c], &view).unwrap();
    let yellow = moved.chunks(4).filter(|p| is_yellow([p[0], p[1], p[2], p[3]])).count();
    assert_eq!(yellow, 0, "the flat slab has not moved");
    let flat_body =
        Body { positions: flat.clone(), triangles: tissue.triangles.clone(), scalars: vec![0.0; flat.len()] };
    host.meshes[0] = flat_body.mesh(true, [0.8, 0.6, 0.5]);
    let off = differing(&renderer.render_from(&host, Some(eye)).unwrap(), &moved, 12);
    assert!(off < 0.01, "{:.2} % of the pixels differ from the host's flat slab", 100.0 * off);

    // Into the app's own texture, in its own encoder: the same picture as the renderer's own
    // target at one sample, to the byte.
    let mut fast = Renderer::fast(&ctx, w, h).unwrap();
    let t =
        DeviceMesh::new(&mut fast, &tissue_buffer, &flat, &tissue.triangles, [0.8, 0.6, 0.5], true).unwrap();
    let own = fast.render_device(&[&t], &view).unwrap();
    let format = wgpu::TextureFormat::Rgba8UnormSrgb;
    let texture = ctx.device().create_texture(&wgpu::TextureDescriptor {
        label: Some("app target"),
        size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let target = texture.create_view(&wgpu::TextureViewDescriptor::default());
    let mut encoder = ctx.device().create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    fast.draw_device(&mut encoder, &target, format, (w, h), &[&t], &view).unwrap();
    let row = (4 * w).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let readback = ctx.device().create_buffer(&wgpu::BufferDescriptor {
        label: Some("test readback"),
        size: u64::from(row * h),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(h),
            },
        },
        wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
    );
    ctx.queue().submit([encoder.finish()]);
    let padded = voxcollide::gpu::map_read(&ctx, &readback, readback.size()).unwrap();
    let app: Vec<u8> = padded.chunks(row as usize).flat_map(|r| r[..4 * w as usize].to_vec()).collect();
    assert_eq!(app, own, "the app's texture holds the renderer's picture");
}

#[test]
fn bad_device_meshes_are_typed_errors() {
    use voxcollide_render::{DeviceMesh, DeviceView};
    let Some(ctx) = common::gpu() else { return };
    let mut renderer = Renderer::new(&ctx, 64, 64).unwrap();
    let body = sphere(Vec3::ZERO, 1.0, 8, 12);
    let good = device_positions(&ctx, &body.positions);
    let invalid = |r: Result<DeviceMesh, Error>, what: &str| match r {
        Err(Error::Invalid { what: w, .. }) => assert_eq!(w, what),
        other => panic!("{what}: {other:?}"),
    };
    let uniform = ctx.device().create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 16 * body.positions.len() as u64,
        usage: wgpu::BufferUsages::UNIFORM,
        mapped_at_creation: false,
    });
    invalid(
        DeviceMesh::new(&mut renderer, &uniform, &body.positions, &body.triangles, [1.0; 3], true),
        "positions",
    );
    let short = device_positions(&ctx, &body.positions[..3]);
    invalid(
        DeviceMesh::new(&mut renderer, &short, &body.positions, &body.triangles, [1.0; 3], true),
        "positions",
    );
    let mut tris = body.triangles.clone();
    tris[0][1] = body.positions.len() as u32;
    invalid(DeviceMesh::new(&mut renderer, &good, &body.positions, &tris, [1.0; 3], true), "triangle index");
    let mut start = body.positions.clone();
    start[2] = Vec3::NAN;
    invalid(DeviceMesh::new(&mut renderer, &good, &start, &body.triangles, [1.0; 3], true), "start");
    invalid(
        DeviceMesh::new(&mut renderer, &good, &body.positions, &body.triangles, [f32::NAN; 3], true),
        "base_color",
    );
    let mesh =
        DeviceMesh::new(&mut renderer, &good, &body.positions, &body.triangles, [1.0; 3], true).unwrap();
    let view =
        DeviceView { scalar_range: (0.0, 1.0), clip: None, view_dir: Vec3::ZERO, up: Vec3::Y, eye: None };
    match renderer.render_device(&[&mesh], &view) {
        Err(Error::Invalid { what, .. }) => assert_eq!(what, "view_dir"),
        other => panic!("{:?}", other.map(|p| p.len())),
    }
    let view = DeviceView { view_dir: Vec3::NEG_Z, scalar_range: (0.0, f32::INFINITY), ..view };
    assert!(matches!(
        renderer.render_device(&[&mesh], &view),
        Err(Error::Invalid { what: "scalar_range", .. })
    ));
    // A NaN in the buffer (a blown-up simulation) loses its triangles, not the picture.
    let mut broken: Vec<[f32; 4]> = body.positions.iter().map(|p| p.extend(1.0).to_array()).collect();
    broken[5] = [f32::NAN; 4];
    ctx.queue().write_buffer(&good, 0, bytemuck::cast_slice(&broken));
    let view = DeviceView { scalar_range: (0.0, 1.0), ..view };
    let rgba = renderer.render_device(&[&mesh], &view).unwrap();
    assert!(rgba.chunks(4).filter(|p| !is_background([p[0], p[1], p[2], p[3]])).count() > 500);
}

#[test]
fn a_picture_drawn_and_kept_on_the_device_reads_back_as_rendered() {
    use voxcollide_render::{DeviceMesh, DeviceView};
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (320, 200);
    let mut renderer = Renderer::fast(&ctx, w, h).unwrap();
    let ball = sphere(Vec3::ZERO, 1.0, 24, 48);
    let view_dir = Vec3::new(0.2, -0.3, -1.0);
    let host = scene(vec![ball.mesh(true, [0.8, 0.6, 0.5])], (0.0, 1.0), view_dir);
    let eye =
        voxcollide_render::framing_eye(&ball.positions, view_dir, Vec3::Y, w as f32 / h as f32).unwrap();
    // Drawn and kept: the picture on the device, sampled by an app's pass, read back only when
    // asked, equal to the bytes render_from returns.
    renderer.draw_picture(&host, Some(eye)).unwrap();
    let kept = renderer.read_picture().unwrap();
    assert_eq!(kept, renderer.render_from(&host, Some(eye)).unwrap());
    assert!(kept.chunks(4).filter(|p| !is_background([p[0], p[1], p[2], p[3]])).count() > 5000);
    let size = renderer.picture_view().texture().size();
    assert_eq!((size.width, size.height), (w, h));
    assert_eq!(renderer.picture_view().texture().format(), voxcollide_render::COLOR_FORMAT);
    assert!(renderer.picture_view().texture().usage().contains(wgpu::TextureUsages::TEXTURE_BINDING));
    // The same from device buffers.
    let buffer = device_positions(&ctx, &ball.positions);
    let mesh =
        DeviceMesh::new(&mut renderer, &buffer, &ball.positions, &ball.triangles, [0.3, 0.5, 0.7], false)
            .unwrap();
    let view = DeviceView { scalar_range: (0.0, 1.0), clip: None, view_dir, up: Vec3::Y, eye: Some(eye) };
    renderer.draw_picture_device(&[&mesh], &view).unwrap();
    let kept = renderer.read_picture().unwrap();
    assert_eq!(kept, renderer.render_device(&[&mesh], &view).unwrap());
    assert_ne!(kept, renderer.render_from(&host, Some(eye)).unwrap(), "a plain ball, not the coloured one");
}
