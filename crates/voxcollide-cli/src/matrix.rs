//! The contact test matrix (issue "Contacts that hold"): an implant filled under a tissue layer
//! for every combination of the parameters a user changes — the gap to the chest wall, the
//! shell's stiffness, the volume on one base, the tissue's spacing and modulus — each cell a
//! `compare` of its volumes, judged by what a planner relies on: every contact held
//! (docs/design.md §11), the volume within 2 %, and the apex lift rising with the volume.
//!
//! Nothing here is tuned to one geometry: the scene is written from the axes alone, and a cell
//! the model cannot build (an implant shape that cannot hold its volume on the base, say) is
//! refused by name before anything runs.

use std::path::{Path, PathBuf};

use crate::backend::Backend;
use crate::compare::{CandidateResult, CompareConfig, Progress, compare};
use voxcollide::Error;
use voxcollide_sim::scene_file::IntegratorSpec;

/// The base every volume of the matrix stands on, in mm.
pub const BASE_MM: f64 = 140.0;

/// The axes of the matrix.
#[derive(Clone, Debug, PartialEq)]
pub struct Axes {
    /// Gaps between the chest wall and the tissue's underside, mm.
    pub gaps: Vec<f64>,
    /// Shell moduli, kPa.
    pub shells: Vec<f64>,
    /// Implant volumes on [`BASE_MM`], mL.
    pub volumes: Vec<f64>,
    /// Tissue lattice spacings (and the shell's edge), mm.
    pub spacings: Vec<f64>,
    /// Tissue moduli, kPa.
    pub tissues: Vec<f64>,
}

impl Axes {
    /// The issue's axes: gaps {0, 2, 10, 24} mm, shells {30, 500, 3000} kPa, volumes
    /// {200, 400, 800} mL, spacings {4, 6} mm, tissue {1, 3, 30} kPa.
    #[must_use]
    pub fn full() -> Axes {
        Axes {
            gaps: vec![0.0, 2.0, 10.0, 24.0],
            shells: vec![30.0, 500.0, 3000.0],
            volumes: vec![200.0, 400.0, 800.0],
            spacings: vec![4.0, 6.0],
            tissues: vec![1.0, 3.0, 30.0],
        }
    }
}

/// One group of the matrix: everything but the volume fixed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Group {
    /// Gap to the chest wall, mm.
    pub gap: f64,
    /// Shell modulus, kPa.
    pub shell: f64,
    /// Spacing, mm.
    pub spacing: f64,
    /// Tissue modulus, kPa.
    pub tissue: f64,
}

/// One cell's outcome.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    /// Its group.
    pub group: Group,
    /// Its volume, mL.
    pub volume: f64,
    /// Its candidate's result; `None` when the group was refused.
    pub result: Option<CandidateResult>,
    /// Why it failed or was refused; `None` when it passed.
    pub failure: Option<String>,
}

/// The projection of an implant of `volume_ml` on [`BASE_MM`]: its volume as 0.6 of the
/// cylinder of the base (a dome's share), in mm.
#[must_use]
pub fn projection_mm(volume_ml: f64) -> f64 {
    let r = 0.5 * BASE_MM;
    volume_ml * 1e3 / (0.6 * std::f64::consts::PI * r * r)
}

/// The scene of `group`: a 20 mm layer of tissue held at its rim `gap` above the chest wall,
/// and an implant shell on the chest wall under it.
#[must_use]
pub fn scene_text(group: &Group, max_steps: u64, integrator: IntegratorSpec) -> String {
    let Group { gap, shell, spacing, tissue } = *group;
    format!(
        r#"# A cell group of the contact test matrix (voxcollide_cli::matrix), written from its axes.
units = "mm"

[time]
duration = 0.4
settle = true
max_steps = {max_steps}
integrator = "{integrator}"

[[body]]
name = "tissue"
kind = "soft"
shape = {{ box = [200, 200, 20] }}
spacing = {spacing}
position = [0, 0, {z}]
material = {{ young_kpa = {tissue}, density = 950.0, damping = 0.5 }}
fixed = [{{ rim = 1 }}]
floor = 0.0

[[body]]
name = "implant"
kind = "shell"
shape = {{ implant = {{ volume_ml = 300, base_mm = {BASE_MM}, projection_mm = {p}, style = "round" }} }}
spacing = {spacing}
position = [0, 0, 0]
material = {{ young_kpa = {shell}, density = 1000.0, damping = 0.5 }}
floor = 0.0
inflate = {{ volume_ml = 300, ramp = 0.3, ease = "smooth" }}

[[contact]]
a = "implant"
b = "tissue"
direction = "plane-normal"

[output]
frames = 2
images = false
vtk = false
"#,
        z = gap + 10.0,
        p = projection_mm(300.0),
        integrator = integrator.name(),
    )
}

/// The catalogue of `volumes` on [`BASE_MM`].
#[must_use]
pub fn catalogue_text(volumes: &[f64]) -> String {
    volumes
        .iter()
        .map(|v| {
            format!(
                "[[candidate]]\nname = \"{v} mL\"\nshape = {{ implant = {{ volume_ml = {v}, base_mm = {BASE_MM}, projection_mm = {:.3}, style = \"round\" }} }}\n",
                projection_mm(*v)
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Runs `group` over `volumes` in `out` (its own folder), on `backend`: each volume's cell,
/// judged, with `compare`'s `progress` and `note`. A group that cannot be built is refused, every cell naming why.
///
/// # Errors
/// File errors writing the scene; a failed run is a failed cell, not an error.
#[allow(clippy::too_many_arguments)] // compare's settings and its two callbacks, each its own
pub fn run_group(
    group: &Group,
    volumes: &[f64],
    max_steps: u64,
    integrator: IntegratorSpec,
    out: &Path,
    backend: Backend,
    progress: &mut dyn FnMut(Progress<'_>),
    note: &mut dyn FnMut(&str),
) -> Result<Vec<Cell>, Error> {
    let io =
        |p: &Path, e: std::io::Error| Error::Io { path: p.display().to_string(), message: e.to_string() };
    std::fs::create_dir_all(out).map_err(|e| io(out, e))?;
    let scene = out.join("scene.toml");
    std::fs::write(&scene, scene_text(group, max_steps, integrator)).map_err(|e| io(&scene, e))?;
    let candidates = out.join("candidates.toml");
    std::fs::write(&candidates, catalogue_text(volumes)).map_err(|e| io(&candidates, e))?;
    let config = CompareConfig {
        scene,
        body: "implant".into(),
        candidates,
        out: out.join("run"),
        backend,
        image: (320, 200),
        jobs: 0,
        fit_base: None,
    };
    let cells = match compare(&config, progress, note) {
        Err(e) => volumes
            .iter()
            .map(|&volume| Cell {
                group: *group,
                volume,
                result: None,
                failure: Some(format!("refused: {e}")),
            })
            .collect(),
        Ok(c) => judge(group, volumes, c.candidates),
    };
    Ok(cells)
}

/// The cells of a group that an earlier `matrix` already ran in `out`, judged again: `None`
/// unless `out` holds the very scene and catalogue this group would be written as (the same
/// axes, step cap and integrator) and that run's `compare.json` with a result for every volume.
/// A matrix of hours can so be run in pieces (`voxcollide matrix --resume`): an interrupted
/// group, or one whose scene differs, runs again. Whether the program changed in between is
/// not known here: after a change, run without resuming.
#[must_use]
pub fn resumed(
    group: &Group,
    volumes: &[f64],
    max_steps: u64,
    integrator: IntegratorSpec,
    out: &Path,
) -> Option<Vec<Cell>> {
    let same = |name: &str, text: String| std::fs::read_to_string(out.join(name)).is_ok_and(|t| t == text);
    if !same("scene.toml", scene_text(group, max_steps, integrator))
        || !same("candidates.toml", catalogue_text(volumes))
    {
        return None;
    }
    let json = std::fs::read_to_string(out.join("run").join("compare.json")).ok()?;
    let comparison: crate::compare::Comparison = serde_json::from_str(&json).ok()?;
    (comparison.candidates.len() == volumes.len()).then(|| judge(group, volumes, comparison.candidates))
}

/// The cells of a group's results: each passes when its contacts held and its volume is within
/// 2 % of its own, and the group's lifts rise with the volume.
#[must_use]
pub fn judge(group: &Group, volumes: &[f64], results: Vec<CandidateResult>) -> Vec<Cell> {
    let mut cells: Vec<Cell> = volumes
        .iter()
        .zip(results)
        .map(|(&volume, r)| {
            let mut why = Vec::new();
            if !r.held {
                why.push(r.failure.clone().unwrap_or_else(|| "a contact did not hold".into()));
            }
            let error = (r.volume_ml - volume).abs() / volume;
            if error > 0.02 {
                why.push(format!("volume {:.1} mL, {:.1} % from {volume} mL", r.volume_ml, 100.0 * error));
            }
            // An implant taller than the gap must lift the tissue: one that does not has gone
            // through it, though a thin layer leaves no vertex deeper than the bound at the end.
            let above = projection_mm(volume) - group.gap;
            if above > 1.0 && f64::from(r.apex_lift) < 0.1 * above {
                why.push(format!(
                    "apex lift {:.2} mm though the implant stands {above:.1} mm above the gap: it went through the tissue",
                    r.apex_lift
                ));
            }
            let failure = (!why.is_empty()).then(|| why.join("; "));
            Cell { group: *group, volume, result: Some(r), failure }
        })
        .collect();
    for k in 1..cells.len() {
        let (lo, hi) = (cells[k - 1].result.as_ref(), cells[k].result.as_ref());
        if let (Some(lo), Some(hi)) = (lo, hi)
            && cells[k].volume > cells[k - 1].volume
            && hi.apex_lift <= lo.apex_lift
        {
            let what = format!(
                "apex lift {:.2} mm, not above the {:.2} mm of {} mL",
                hi.apex_lift,
                lo.apex_lift,
                cells[k - 1].volume
            );
            let f = &mut cells[k].failure;
            *f = Some(f.take().map_or(what.clone(), |f| format!("{f}; {what}")));
        }
    }
    cells
}

/// The cells as a Markdown table.
#[must_use]
pub fn table(cells: &[Cell]) -> String {
    let mut s = String::from(
        "| gap mm | shell kPa | spacing mm | tissue kPa | volume mL | filled mL | apex lift mm | max penetration mm | held | settled | pass |\n| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | --- | --- |\n",
    );
    for c in cells {
        let g = &c.group;
        let (filled, lift, pen, held, settled): (String, String, String, String, String) = c
            .result
            .as_ref()
            .map_or(("–".into(), "–".into(), "–".into(), "–".into(), "–".into()), |r| {
                (
                    format!("{:.1}", r.volume_ml),
                    format!("{:.2}", r.apex_lift),
                    format!("{:.2}", r.max_penetration),
                    if r.held { "yes".into() } else { "no".into() },
                    r.settled.to_string(),
                )
            });
        let pass = match &c.failure {
            None => "pass".to_string(),
            Some(f) => format!("FAIL: {f}"),
        };
        s += &format!(
            "| {} | {} | {} | {} | {} | {filled} | {lift} | {pen} | {held} | {settled} | {pass} |\n",
            g.gap, g.shell, g.spacing, g.tissue, c.volume
        );
    }
    s
}

/// Every group of `axes`, in order (gap slowest, tissue fastest).
#[must_use]
pub fn groups(axes: &Axes) -> Vec<Group> {
    let mut out = Vec::new();
    for &gap in &axes.gaps {
        for &shell in &axes.shells {
            for &spacing in &axes.spacings {
                for &tissue in &axes.tissues {
                    out.push(Group { gap, shell, spacing, tissue });
                }
            }
        }
    }
    out
}

/// A group's folder under `out`.
#[must_use]
pub fn group_dir(out: &Path, g: &Group) -> PathBuf {
    out.join(format!("gap{}_shell{}_h{}_e{}", g.gap, g.shell, g.spacing, g.tissue))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::Comparison;

    fn result(volume: f64, lift: f32) -> CandidateResult {
        CandidateResult { volume_ml: volume, apex_lift: lift, held: true, ..CandidateResult::default() }
    }

    #[test]
    fn a_finished_group_is_judged_again_and_a_different_or_unfinished_one_runs() {
        let dir = std::env::temp_dir().join(format!("voxcollide-matrix-resume-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let g = Group { gap: 10.0, shell: 500.0, spacing: 6.0, tissue: 3.0 };
        let volumes = [200.0, 400.0];
        let implicit = IntegratorSpec::Implicit;
        assert!(resumed(&g, &volumes, 3000, implicit, &dir).is_none(), "nothing ran yet");
        std::fs::create_dir_all(dir.join("run")).unwrap();
        std::fs::write(dir.join("scene.toml"), scene_text(&g, 3000, implicit)).unwrap();
        std::fs::write(dir.join("candidates.toml"), catalogue_text(&volumes)).unwrap();
        assert!(resumed(&g, &volumes, 3000, implicit, &dir).is_none(), "interrupted: no compare.json");
        // The second lifts less than the first: judged again, it fails.
        let comparison = Comparison {
            candidates: vec![result(200.0, 12.0), result(399.0, 11.0)],
            ..Comparison::default()
        };
        std::fs::write(dir.join("run/compare.json"), serde_json::to_string(&comparison).unwrap()).unwrap();
        let cells = resumed(&g, &volumes, 3000, implicit, &dir).expect("finished");
        assert_eq!(cells.len(), 2);
        assert!(cells[0].failure.is_none(), "{:?}", cells[0].failure);
        assert!(
            cells[1].failure.as_deref().is_some_and(|f| f.contains("not above")),
            "{:?}",
            cells[1].failure
        );
        // Another step cap or integrator is another scene: it runs again.
        assert!(resumed(&g, &volumes, 6000, implicit, &dir).is_none());
        assert!(resumed(&g, &volumes, 3000, IntegratorSpec::Explicit, &dir).is_none());
        assert!(resumed(&g, &[200.0, 800.0], 3000, implicit, &dir).is_none());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
