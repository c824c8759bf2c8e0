//! Gravity and the shape as scanned (docs/design.md §13): a column hanging under its own weight
//! against the closed form, on both integrators' paths and both backends; a body with nothing
//! acting at rest at once; and the unloaded shape recovered from a loaded one, round trip, the
//! scan staying where it was scanned under its own gravity and moving in another posture.

#[path = "../../voxcollide/tests/common/adapter.rs"]
mod common;

use voxcollide::glam::Vec3;
use voxcollide_sim::build::{Built, Recoveries, build_world, build_world_reusing};
use voxcollide_sim::reference::{self, set_rest_shape};
use voxcollide_sim::scene_file::SceneFile;
use voxcollide_sim::{CpuWorld, MassSpring, Mode, simulation};

/// A column's material and size: Young's modulus (kPa), lattice spacing and length (mm),
/// Poisson's ratio.
#[derive(Clone, Copy)]
struct Column {
    young: f64,
    spacing: f64,
    poisson: f64,
    length: f64,
}

/// The column of E = 100 kPa, ν = 0.3, `length` long at `spacing`.
fn column(length: f64, spacing: f64, integrator: &str) -> Built {
    hanging(Column { young: 100.0, spacing, poisson: 0.3, length }, integrator)
}

/// A 10 × 10 × `length` mm column of Neo-Hookean tissue (1000 kg/m³) held at its top, hanging
/// along −z under 9.81 m/s².
fn hanging(c: Column, integrator: &str) -> Built {
    let Column { young, spacing, poisson, length } = c;
    let text = format!(
        r#"
units = "mm"
[time]
duration = 0.5
integrator = "{integrator}"
[world]
gravity = [0, 0, -9.81]
[[body]]
name = "column"
kind = "soft"
shape = {{ box = [10, 10, {length}] }}
spacing = {spacing}
material = {{ model = "neo-hookean", young_kpa = {young}, poisson = {poisson}, density = 1000, damping = 0.5 }}
fixed = [{{ above = {{ z = {top} }} }}]
"#,
        top = 0.5 * length - 0.1 * spacing
    );
    build_world(&SceneFile::parse("column.toml", &text).unwrap()).unwrap()
}

/// The mean downward displacement of the body's lowest vertices.
fn sag(body: &MassSpring) -> f32 {
    let bottom = body.rest_pos.iter().map(|p| p.z).fold(f32::MAX, f32::min);
    let (sum, n) = body
        .rest_pos
        .iter()
        .zip(&body.pos)
        .filter(|(r, _)| r.z <= bottom + 1e-3)
        .fold((0.0, 0), |(s, n), (r, p)| (s + (r.z - p.z), n + 1));
    sum / n as f32
}

/// ρ g L² / (2E) in mm, for the column above.
fn closed_form(length: f64) -> f64 {
    let (rho, g, e) = (1000.0, 9.81, 100e3);
    let l = length * 1e-3;
    rho * g * l * l / (2.0 * e) * 1e3
}

#[test]
fn a_column_hanging_under_its_own_weight_stretches_by_rho_g_l2_over_2e() {
    for length in [60.0, 100.0] {
        let built = column(length, 2.5, "implicit");
        let mut body = built.world.bodies[0].clone();
        // Its weight is its density times its volume, whatever the lattice lumps for inertia.
        let volume = 10.0 * 10.0 * length * 1e-9;
        assert!((body.total_mass() / (1000.0 * volume) - 1.0).abs() < 1e-5, "mass {}", body.total_mass());
        let steps = reference::settle(&mut body, Vec3::new(0.0, 0.0, -9810.0)).unwrap();
        let (got, want) = (f64::from(sag(&body)), closed_form(length));
        eprintln!("{length} mm: sag {got:.4} mm, closed form {want:.4} mm ({steps} steps)");
        assert!((got / want - 1.0).abs() < 0.02, "{length} mm column: sag {got} mm, closed form {want} mm");
    }
}

#[test]
fn gravity_pulls_alike_on_the_cpu_and_the_gpu() {
    let Some(ctx) = common::gpu() else { return };
    // Explicit: the same bits on both backends.
    let w = column(40.0, 2.5, "explicit").world;
    let mut cpu = simulation(None, w.clone()).unwrap();
    let mut gpu = simulation(Some(&ctx), w).unwrap();
    for _ in 0..300 {
        cpu.step().unwrap();
        gpu.step().unwrap();
    }
    let (a, b) = (cpu.frame().unwrap().0.bodies[0].pos.clone(), gpu.frame().unwrap().0.bodies[0].pos.clone());
    assert!(sag(&cpu.world().bodies[0]) > 1e-4, "the column did not fall");
    assert_eq!(a, b, "explicit steps under gravity differ between the CPU and the GPU");
    // Implicit: the GPU's solve to its tolerance, at the same rest as the CPU's.
    let w = column(40.0, 2.5, "implicit").world;
    let mut runs = [simulation(None, w.clone()).unwrap(), simulation(Some(&ctx), w).unwrap()];
    let mut sags = Vec::new();
    for run in &mut runs {
        run.accelerate(64.0);
        for _ in 0..150 {
            run.step().unwrap();
        }
        sags.push(sag(&run.frame().unwrap().0.bodies[0]));
    }
    let want = closed_form(40.0) as f32;
    eprintln!("implicit sag: cpu {} gpu {} closed form {want}", sags[0], sags[1]);
    for s in sags {
        assert!((s / want - 1.0).abs() < 0.03, "sag {s} against {want}");
    }
}

#[test]
fn a_body_with_nothing_acting_is_at_rest_at_once() {
    let text = r#"
units = "mm"
[time]
integrator = "implicit"
[[body]]
name = "block"
kind = "soft"
shape = { box = [60, 40, 30] }
spacing = 5
material = { model = "neo-hookean", young_kpa = 3, poisson = 0.45 }
fixed = [{ below = { z = -14 } }]
"#;
    let built = build_world(&SceneFile::parse("block.toml", text).unwrap()).unwrap();
    let mut w = CpuWorld::new(built.world).unwrap();
    w.step().unwrap();
    let r = w.residual;
    assert!(r.relative() <= 1e-3, "nothing acting, yet a residual of {:.2e} ({r:?})", r.relative());
    // Under its own weight it is not at rest at the start.
    let text = text.replace("[[body]]", "[world]\ngravity = [0, 0, -9.81]\n[[body]]");
    let mut w =
        CpuWorld::new(build_world(&SceneFile::parse("block.toml", &text).unwrap()).unwrap().world).unwrap();
    w.step().unwrap();
    assert!(w.residual.relative() > 0.5, "weight unbalanced at the start: {:.2e}", w.residual.relative());
}

/// A breast-like mound: a half-ellipsoid of tissue (E = 3 kPa, ν = 0.45) on a held chest wall
/// (its base, z = 0), as a scene in millimetres.
fn mound(reference: Option<[f64; 3]>, gravity: [f64; 3]) -> Built {
    build_world(&mound_scene(reference, gravity, 7)).unwrap()
}

/// The scene of [`mound`], at `spacing`.
fn mound_scene(reference: Option<[f64; 3]>, gravity: [f64; 3], spacing: u32) -> SceneFile {
    let reference = reference.map_or(String::new(), |g| format!("reference = {{ gravity = {g:?} }}\n"));
    let text = format!(
        r#"
units = "mm"
[time]
integrator = "implicit"
[world]
gravity = {gravity:?}
[[body]]
name = "breast"
kind = "soft"
shape = {{ ellipsoid = [60, 55, 45] }}
spacing = {spacing}
material = {{ model = "neo-hookean", young_kpa = 3, poisson = 0.45, density = 1000, damping = 0.5 }}
fixed = [{{ below = {{ z = 1 }} }}]
{reference}"#
    );
    SceneFile::parse("mound.toml", &text).unwrap()
}

/// The mound scanned standing and seen lying, at `spacing`.
fn mound_scanned(spacing: u32) -> SceneFile {
    mound_scene(Some(STANDING), [0.0, 0.0, -9.81], spacing)
}

#[test]
fn a_recovered_shape_is_reused_only_for_the_same_body() {
    // `voxcollide compare` builds one world per candidate around the same scanned patient:
    // her unloaded shape is recovered by the first build and reused by the others, which
    // then build the same world, bit for bit. Another body (another spacing) recovers its own.
    let recoveries = Recoveries::default();
    let alone = build_world(&mound_scanned(9)).unwrap();
    let first = build_world_reusing(&mound_scanned(9), &recoveries).unwrap();
    assert_eq!(recoveries.len(), 1);
    let again = build_world_reusing(&mound_scanned(9), &recoveries).unwrap();
    assert_eq!(recoveries.len(), 1, "the same body recovered again");
    for built in [&first, &again] {
        let (b, a) = (&built.world.bodies[0], &alone.world.bodies[0]);
        assert!(b.pos == a.pos && b.rest_pos == a.rest_pos && b.started == a.started);
        assert_eq!(built.notes[0].reference, alone.notes[0].reference);
    }
    assert!(
        alone.world.bodies[0].rest_pos != alone.world.bodies[0].pos,
        "the scan is loaded: its rest shape differs"
    );
    let other = build_world_reusing(&mound_scanned(10), &recoveries).unwrap();
    assert_eq!(recoveries.len(), 2);
    assert!(other.world.bodies[0].pos.len() != first.world.bodies[0].pos.len());
}

/// The mound's base is its chest wall (z = 0, held) and its apex points +z, as a patient's
/// breast does lying on her back (gravity along −z); standing, gravity runs along −y.
const STANDING: [f64; 3] = [0.0, -9.81, 0.0];

/// The largest distance between two shapes' free vertices.
fn farthest(a: &[Vec3], b: &[Vec3], mode: &[Mode]) -> f32 {
    a.iter()
        .zip(b)
        .zip(mode)
        .filter(|(_, m)| **m == Mode::Free)
        .map(|((p, q), _)| p.distance(*q))
        .fold(0.0, f32::max)
}

#[test]
fn the_unloaded_shape_is_recovered_from_a_loaded_one_round_trip() {
    let built = mound(None, [0.0; 3]);
    let original = built.world.bodies[0].clone();
    let spacing = 7.0;
    // Load the known unloaded mound standing: its loaded shape is the "scan".
    let mut loaded = original.clone();
    reference::settle(&mut loaded, Vec3::new(0.0, -9810.0, 0.0)).unwrap();
    let moved = farthest(&loaded.pos, &original.pos, &original.mode);
    assert!(moved > 0.5 * spacing, "standing moves the mound by {moved} mm, less than half a spacing");
    // The scan as a body at rest in it, then its unloaded shape recovered.
    let mut scan = loaded.clone();
    set_rest_shape(&mut scan, &loaded.pos).unwrap();
    let recovered = reference::unload(&mut scan, Vec3::new(0.0, -9810.0, 0.0)).unwrap();
    let back = farthest(&scan.rest_pos, &original.rest_pos, &original.mode);
    eprintln!(
        "moved {moved:.2} mm standing; recovered in {} iterations, residual {:.4} mm; unloaded shape within {back:.4} mm of the original",
        recovered.iterations, recovered.residual
    );
    assert!(recovered.is_valid() && recovered.residual <= 0.01 * spacing + 1e-3, "{recovered:?}");
    assert!(back <= 0.1 * spacing, "recovered unloaded shape {back} mm from the original");
    // It stands where it was scanned.
    assert!(farthest(&scan.pos, &loaded.pos, &original.mode) <= recovered.residual + 1e-4);
}

#[test]
fn a_scan_stays_where_it_was_scanned_under_its_own_gravity_and_moves_in_another_posture() {
    // The scan: the mound as loaded standing.
    let mut scan = mound(None, [0.0; 3]).world.bodies[0].clone();
    reference::settle(&mut scan, Vec3::new(0.0, -9810.0, 0.0)).unwrap();
    let scanned = scan.pos.clone();
    let mode = scan.mode.clone();
    // Its unloaded shape recovered from it, as a scene file's `reference` does.
    let recovered_from_scan = || {
        let mut body = mound(None, [0.0; 3]).world.bodies[0].clone();
        set_rest_shape(&mut body, &scanned).unwrap();
        body.pos.clone_from(&scanned);
        let r = reference::unload(&mut body, Vec3::new(0.0, -9810.0, 0.0)).unwrap();
        assert!(r.is_valid(), "{r:?}");
        body
    };
    for (posture, gravity, moves) in [("standing", STANDING, false), ("lying", [0.0, 0.0, -9.81], true)] {
        let mut body = recovered_from_scan();
        let g = Vec3::new(gravity[0] as f32, gravity[1] as f32, gravity[2] as f32) * 1e3;
        reference::settle(&mut body, g).unwrap();
        let off = farthest(&body.pos, &scanned, &mode);
        eprintln!("{posture}: {off:.3} mm from the scan");
        if moves {
            assert!(off > 3.0, "{posture}: only {off} mm from the scan standing");
            // Lying, the mound flattens: its apex comes down.
            let apex = |p: &[Vec3]| p.iter().map(|q| q.z).fold(f32::MIN, f32::max);
            assert!(apex(&body.pos) < apex(&scanned) - 1.0, "lying, the apex did not come down");
        } else {
            assert!(off <= 0.07, "{posture}: {off} mm from the scan");
        }
    }
}

#[test]
fn a_scene_file_recovers_its_body_and_says_how_well() {
    let built = mound(Some(STANDING), STANDING);
    let r = built.notes[0].reference.expect("recovered");
    assert!(r.iterations >= 1 && r.is_valid(), "{r:?}");
    let body = &built.world.bodies[0];
    // It starts at the shape given (to the residual), resting in another.
    let given = mound(None, [0.0; 3]).world.bodies[0].pos.clone();
    assert!(farthest(&body.pos, &given, &body.mode) <= r.residual + 1e-4);
    assert!(farthest(&body.rest_pos, &given, &body.mode) > 1.0);
}

#[test]
fn bad_gravity_and_reference_keys_are_named() {
    let base = "[[body]]\nname = \"b\"\nkind = \"soft\"\nshape = { box = [10, 10, 10] }\nspacing = 2\n";
    for (text, key) in [
        (format!("[world]\ngravity = [0, nan, 0]\n{base}"), "world.gravity"),
        (format!("[world]\nup = \"w\"\n{base}"), "world.up"),
        (format!("[world]\ngravity = [0, 0]\n{base}"), "world.gravity"),
        (format!("[world]\nwind = 3\n{base}"), "world"),
        (format!("{base}reference = {{ gravity = [0, 0, inf] }}\n"), "body[0].reference"),
        (format!("{base}reference = {{ g = [0, 0, 1] }}\n"), "body[0].reference"),
        (
            "[[body]]\nname = \"r\"\nkind = \"rigid\"\nshape = { sphere = 5 }\nspacing = 2\nreference = { gravity = [0, 0, -9.81] }\n"
                .to_string(),
            "body[0].reference",
        ),
    ] {
        let e = SceneFile::parse("bad.toml", &text).unwrap_err().to_string();
        assert!(e.contains("bad.toml") && e.contains(key), "{key}: {e}");
    }
}

/// The parameters a user would change: the stiffness, the spacing, Poisson's ratio and the
/// length of the hanging column, each within 3 % of ρgL²/(2E) (the top, held, keeps its
/// lateral contraction: shorter and more nearly incompressible columns feel it most).
#[test]
fn the_hanging_column_holds_across_stiffness_spacing_and_poisson() {
    for (young, spacing, poisson, length) in [
        (30.0, 2.5, 0.3, 100.0),
        (300.0, 2.5, 0.3, 100.0),
        (100.0, 5.0, 0.3, 100.0),
        (100.0, 2.0, 0.3, 80.0),
        (100.0, 2.5, 0.45, 100.0),
    ] {
        let built = hanging(Column { young, spacing, poisson, length }, "implicit");
        let mut body = built.world.bodies[0].clone();
        reference::settle(&mut body, Vec3::new(0.0, 0.0, -9810.0)).unwrap();
        let l = length * 1e-3;
        let want = 1000.0 * 9.81 * l * l / (2.0 * young * 1e3) * 1e3;
        let got = f64::from(sag(&body));
        eprintln!(
            "E {young} kPa, h {spacing}, ν {poisson}, L {length}: sag {got:.4} mm, closed form {want:.4} mm"
        );
        assert!((got / want - 1.0).abs() < 0.03, "E {young}, h {spacing}, ν {poisson}: {got} against {want}");
    }
}

/// A half-ellipsoid mound of `young` kPa (60 × 55 × 45 mm, 9 mm spacing) loaded standing, its
/// loaded shape taken as the scan and its unloaded shape recovered: how far it sagged, the
/// recovery, and how far the recovered shape ends from the original (both in mm).
fn mound_recovered(young: f64) -> (f32, reference::Recovered, f32) {
    let text = format!(
        r#"
units = "mm"
[time]
integrator = "implicit"
[[body]]
name = "breast"
kind = "soft"
shape = {{ ellipsoid = [60, 55, 45] }}
spacing = 9
material = {{ model = "neo-hookean", young_kpa = {young}, poisson = 0.45, density = 1000, damping = 0.5 }}
fixed = [{{ below = {{ z = 1 }} }}]
"#
    );
    let original =
        build_world(&SceneFile::parse("mound.toml", &text).unwrap()).unwrap().world.bodies[0].clone();
    let g = Vec3::new(0.0, -9810.0, 0.0);
    let mut scan = original.clone();
    reference::settle(&mut scan, g).unwrap();
    let moved = farthest(&scan.pos, &original.pos, &original.mode);
    let loaded = scan.pos.clone();
    set_rest_shape(&mut scan, &loaded).unwrap();
    let r = reference::unload(&mut scan, g).unwrap();
    let back = farthest(&scan.rest_pos, &original.rest_pos, &original.mode);
    eprintln!(
        "E {young} kPa: sags {moved:.2} mm; {} iterations, residual {:.4} mm, {back:.4} mm from the original",
        r.iterations, r.residual
    );
    (moved, r, back)
}

/// The recovery across stiffness: a stiffer mound sags less and is recovered as well; a
/// softer one sags more (more nonlinear) and still comes back within a tenth of its spacing.
#[test]
fn the_unloaded_shape_is_recovered_across_stiffness() {
    for young in [1.5, 3.0, 10.0] {
        let (_, r, back) = mound_recovered(young);
        assert!(r.is_valid() && back <= 0.1 * 9.0, "E {young}: {r:?}, {back} mm from the original");
    }
}

/// A soft mound sags so far that moving the unloaded shape by the whole miss turns it inside
/// out: the recovery takes shorter moves and still comes back, loaded again, within a tenth of
/// its spacing (before, the 0.5 kPa mound was refused outright: "the reference gravity is more
/// than the material can have held", though the original is a shape it held). So soft a body's
/// recovery is ill-conditioned: its unloaded shape ends a millimetre or two from the original
/// while loaded it misses by a tenth of that. A softer one still, sagging 55 mm, is not
/// recovered: it is said to be no result, after a few iterations, not the forty allowed.
#[test]
fn a_soft_mound_is_recovered_by_shorter_moves_and_a_softer_one_is_no_result() {
    for (young, recovered) in [(0.7, true), (0.5, true), (0.3, false)] {
        let (moved, r, back) = mound_recovered(young);
        assert!(moved > 20.0, "E {young}: sags only {moved} mm");
        if recovered {
            assert!(r.is_valid() && back <= 0.25 * 9.0, "E {young}: {r:?}, {back} mm from the original");
        } else {
            assert!(!r.is_valid() && r.iterations < reference::MAX_ITERATIONS / 2, "E {young}: {r:?}");
        }
    }
}

/// A shell filled to a volume weighs its fill (a 300 mL gel implant about 300 g), shared over
/// its vertices by area; one inflated by pressure weighs its wall, as thick as its edge.
#[test]
fn a_filled_implant_weighs_its_fill() {
    let text = |inflate: &str| {
        format!(
            r#"
units = "mm"
[world]
gravity = [0, 0, -9.81]
[[body]]
name = "implant"
kind = "shell"
shape = {{ implant = {{ volume_ml = 300, base_mm = 115, profile = "moderate" }} }}
spacing = 6
material = {{ young_kpa = 500, density = 1000 }}
inflate = {inflate}
"#
        )
    };
    let filled =
        build_world(&SceneFile::parse("i.toml", &text("{ volume_ml = 300, ramp = 0.3 }")).unwrap()).unwrap();
    let pressed =
        build_world(&SceneFile::parse("i.toml", &text("{ pressure_kpa = 2, ramp = 0.3 }")).unwrap()).unwrap();
    let (wall, whole) = (pressed.world.bodies[0].total_mass(), filled.world.bodies[0].total_mass());
    eprintln!("wall {wall:.4} kg, filled {whole:.4} kg");
    assert!((whole / 0.3 - 1.0).abs() < 1e-4, "the filled implant weighs {whole} kg");
    assert!(wall > 0.0);
    // Shared by area: no vertex carries more than its share of a few triangles.
    let b = &filled.world.bodies[0];
    let most = b.mass.iter().copied().fold(0.0f32, f32::max);
    assert!(f64::from(most) < 0.01 * whole, "one vertex carries {most} kg of {whole}");
}

/// A large deformation under gravity against the energy's own uniaxial solution: a soft column
/// (E = 3 kPa, ν = 0.3) hangs 16 % longer by small-strain theory. Each cross-section at `X`
/// below the held top carries the weight under it, so its stretch `λ(X)` solves
/// `P(λ) = ρ g (L − X)` with `P` the Neo-Hookean energy's nominal stress in uniaxial tension
/// (`validation::LargeStretch::closed_form`, lateral faces free), and the sag is
/// `∫ (λ − 1) dX`. The column comes within 3 % of it.
#[test]
fn a_soft_column_hangs_as_the_energys_uniaxial_solution_says() {
    use voxcollide_sim::validation::LargeStretch;
    let (young, nu, length) = (3.0, 0.3, 100.0);
    let built = hanging(Column { young, spacing: 2.5, poisson: nu, length }, "implicit");
    let mut body = built.world.bodies[0].clone();
    reference::settle(&mut body, Vec3::new(0.0, 0.0, -9810.0)).unwrap();
    let got = f64::from(sag(&body));
    // The uniaxial solution, in SI units: E·P₁(λ) = ρ g (L − X), P₁ the nominal stress at E = 1.
    let bar = LargeStretch { nu, ..LargeStretch::standard() };
    let e = young * 1e3;
    let stretch_under = |load: f64| {
        let (mut lo, mut hi) = (1.0, 3.0);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if e * bar.closed_form(mid).1 < load { lo = mid } else { hi = mid }
        }
        0.5 * (lo + hi)
    };
    let l = length * 1e-3;
    let n = 2000;
    let want: f64 = (0..n)
        .map(|k| {
            let x = (f64::from(k) + 0.5) / f64::from(n) * l;
            (stretch_under(1000.0 * 9.81 * (l - x)) - 1.0) * l / f64::from(n)
        })
        .sum::<f64>()
        * 1e3;
    let small = 1000.0 * 9.81 * l * l / (2.0 * e) * 1e3;
    eprintln!(
        "sag {got:.3} mm; the energy's uniaxial solution {want:.3} mm; small-strain theory {small:.3} mm"
    );
    assert!(want > 1.05 * small || want < 0.95 * small, "not a large deformation: {want} against {small}");
    assert!((got / want - 1.0).abs() < 0.03, "sag {got} mm against {want} mm");
}
