//! The Neo-Hookean tetrahedra against closed forms (issue 21, item 4; docs/validation.md):
//! a cantilever against beam theory at three refinements, and a bar stretched by half its
//! length against the energy's own uniaxial solution. Each is a static answer: the implicit
//! integrator stepped until the residual force is gone.
//!
//! `examples/validation.rs` runs the same cases and draws docs/validation.svg.

use voxcollide_sim::validation::{Cantilever, HeavyElastica, LargeStretch, SelfWeight};

#[test]
fn a_cantilevers_tip_load_converges_to_beam_theorys_under_refinement() {
    let mut errors = Vec::new();
    for across in [2, 4, 8] {
        let c = Cantilever { across, ..Cantilever::standard() };
        let r = c.solve().unwrap();
        eprintln!(
            "{across} across ({} vertices, {} steps, residual {:.1e}): tip load {:.5e}, beam theory {:.5e}, ratio {:.4}; tip moment {:.2e} of F·L",
            r.vertices,
            r.steps,
            r.residual,
            r.load,
            r.theory,
            r.load / r.theory,
            r.moment / (r.load * f64::from(c.length)).abs()
        );
        assert!(r.residual < 2e-3, "not at rest: residual {}", r.residual);
        // The tip is carried to the slope a tip load gives: what holds it there is that load
        // alone, its moment about the tip small against F·L.
        assert!((r.moment / (r.load * f64::from(c.length))).abs() < 0.05, "tip moment {}", r.moment);
        errors.push((r.load / r.theory - 1.0).abs());
    }
    // Linear tetrahedra are too stiff in bending by a share that falls with the square of the
    // spacing (shear locking): a quarter at 4 across, 6 % at 8. Extrapolated from the two
    // finest (Richardson, second order), the continuum's answer is beam theory's.
    assert!(errors[0] > 3.0 * errors[1] && errors[1] > 3.0 * errors[2], "not second order: {errors:?}");
    assert!(errors[2] < 0.07, "8 across: {:.1} % from beam theory", 100.0 * errors[2]);
    let extrapolated = errors[2] - (errors[1] - errors[2]) / 3.0;
    assert!(extrapolated.abs() < 0.02, "extrapolated: {:.1} % from beam theory", 100.0 * extrapolated);
}

/// Under its own weight (docs/gravity.md): the tip deflection of a cantilever against
/// `qL⁴/(8EI)` (with Timoshenko's shear term), its weight its density times its volume.
#[test]
fn a_cantilever_bends_under_its_own_weight_as_beam_theory_says() {
    let mut errors = Vec::new();
    for across in [4, 8] {
        let c = SelfWeight { across, ..SelfWeight::standard() };
        let r = c.solve().unwrap();
        eprintln!(
            "{across} across ({} vertices, {} steps, residual {:.1e}): tip {:.5e}, beam theory {:.5e}, ratio {:.4}",
            r.vertices,
            r.steps,
            r.residual,
            r.deflection,
            r.theory,
            r.deflection / r.theory
        );
        assert!((r.weight - 1.0).abs() < 1e-5, "weighs {} of its density times its volume", r.weight);
        // Its weight, a few millionths of its stiffness per vertex, is balanced only as finely
        // as single-precision positions resolve: 2.4e-2 of it at 8 across (the tip's deflection
        // then still within 2 % of beam theory's).
        assert!(r.residual < 5e-2, "not at rest: residual {}", r.residual);
        errors.push(1.0 - r.deflection / r.theory);
    }
    // Too stiff by shear locking, less so as the spacing falls: 16 % at 4 across, 1.7 % at 8
    // (measured), within 5 % of beam theory at the refinement docs/gravity.md shows.
    assert!(errors.iter().all(|e| *e > -0.02), "more flexible than beam theory: {errors:?}");
    assert!(errors[0] > 3.0 * errors[1], "not converging: {errors:?}");
    assert!(errors[1] < 0.05, "8 across: {:.1} % from beam theory", 100.0 * errors[1]);
}

/// The heavy elastica's own small-load limits: beam theory's drop `α/8` and tip slope `α/6`,
/// the tip's reach the whole length; and under a large load, less drop than beam theory says.
#[test]
fn the_heavy_elastica_is_beam_theory_under_a_small_load_and_falls_short_of_it_under_a_large_one() {
    let small = HeavyElastica::solve(0.08);
    assert!((small.drop / 0.01 - 1.0).abs() < 1e-3, "{small:?}");
    assert!((small.tip_slope / (0.08 / 6.0) - 1.0).abs() < 1e-3, "{small:?}");
    assert!(1.0 - small.reach < 1e-4, "{small:?}");
    let large = HeavyElastica::solve(6.0);
    assert!(large.drop < 0.8 * 6.0 / 8.0 && large.drop > 0.5, "{large:?}");
    assert!((large.drop.powi(2) + large.reach.powi(2)).sqrt() < 1.0, "the tip beyond the length: {large:?}");
    let none = HeavyElastica::solve(0.0);
    assert!(none.drop == 0.0 && none.tip_slope == 0.0 && (none.reach - 1.0).abs() < 1e-12, "{none:?}");
}

/// Under its own weight through a large deflection (docs/gravity.md): the cantilever of
/// [`a_cantilever_bends_under_its_own_weight_as_beam_theory_says`], 75 times heavier
/// (`qL³/(EI)` = 6: beam theory's tip drop would be three quarters of its length), against
/// the heavy elastica, at two refinements. Linear tetrahedra lock in bending as under a small
/// load; extrapolated from the two (second order), the drop is the elastica's.
#[test]
fn a_cantilever_bends_under_a_large_weight_as_the_heavy_elastica_says() {
    let alpha = 6.0;
    let elastica = HeavyElastica::solve(alpha);
    let (drop, shortening) = (10.0 * elastica.drop, 10.0 * (1.0 - elastica.reach));
    let mut errors = Vec::new();
    for across in [3, 6] {
        let c = SelfWeight { across, gravity: (alpha / 12_000.0) as f32, ..SelfWeight::standard() };
        let r = c.solve().unwrap();
        eprintln!(
            "{across} across ({} vertices, {} steps, residual {:.1e}): drop {:.4} (elastica {drop:.4}, beam theory {:.4}), shortening {:.4} (elastica {shortening:.4})",
            r.vertices,
            r.steps,
            r.residual,
            r.deflection,
            10.0 * alpha / 8.0,
            r.shortening
        );
        assert!(r.residual < 5e-3, "not at rest: residual {}", r.residual);
        errors.push((1.0 - r.deflection / drop, 1.0 - r.shortening / shortening));
    }
    let [(d3, s3), (d6, s6)] = errors[..] else { unreachable!() };
    // Measured: the drop 20.7 % and 5.6 % short, the tip's shortening 40.6 % and 13.7 % short.
    assert!(d3 > 3.0 * d6 && d6 > 0.0 && d6 < 0.07, "drop errors {d3} {d6}");
    assert!(s3 > 2.5 * s6 && s6 > 0.0 && s6 < 0.2, "shortening errors {s3} {s6}");
    let (drop_extrapolated, shortening_extrapolated) = (d6 - (d3 - d6) / 3.0, s6 - (s3 - s6) / 3.0);
    assert!(
        drop_extrapolated.abs() < 0.02,
        "extrapolated drop {:.1} % from the elastica",
        100.0 * drop_extrapolated
    );
    assert!(
        shortening_extrapolated.abs() < 0.06,
        "extrapolated shortening {:.1} % from the elastica",
        100.0 * shortening_extrapolated
    );
}

#[test]
fn a_bar_stretched_by_half_follows_the_energys_closed_form() {
    for nu in [0.3, 0.45] {
        let s = LargeStretch { nu, ..LargeStretch::standard() };
        let r = s.solve().unwrap();
        let (lateral, stress) = s.closed_form(r.stretch);
        eprintln!(
            "ν {nu}: stretch {:.4}, lateral {:.4} (closed form {lateral:.4}), nominal stress {:.4} (closed form {stress:.4}), residual {:.1e}",
            r.stretch, r.lateral, r.stress, r.residual
        );
        assert!(r.residual < 1e-4, "not at rest: residual {}", r.residual);
        assert!(
            (r.stretch / f64::from(s.stretch) - 1.0).abs() < 0.05,
            "middle stretched {} for {}",
            r.stretch,
            s.stretch
        );
        assert!(
            ((1.0 - r.lateral) / (1.0 - lateral) - 1.0).abs() < 0.05,
            "lateral {} against {lateral}",
            r.lateral
        );
        assert!((r.stress / stress - 1.0).abs() < 0.05, "stress {} against {stress}", r.stress);
    }
}
