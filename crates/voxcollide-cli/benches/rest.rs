//! Time to rest (issue 21, item 5): how long the command takes, wall clock on the CPU, to bring
//! the scenes in `benches/rest/` to rest, under each integrator:
//!
//! - `press`: a 9 mm ball driven 12 mm into a soft dome, a lattice of 3,926 vertices made
//!   from a closed surface (`voxcollide run benches/rest/press.toml`);
//! - `compare`: three implants (200, 300 and 400 mL on a 140 mm base, 500 kPa shells) under a
//!   30 mm layer of 3 kPa tissue at a 6 mm spacing, each filled and settled
//!   (`voxcollide compare benches/rest/compare.toml --candidates benches/rest/candidates.toml`);
//! - `bunny` and `bunny-nh`: a 1.5 cm ball driven 2.5 cm into the Stanford bunny (3,019
//!   vertices), as springs and as Neo-Hookean tetrahedra at ν = 0.49, under the implicit
//!   integrator (issue 42: nearly incompressible tissue within 3× the springs' time); the
//!   table is followed by their ratio;
//! - `patient`: six Mentor implants planned on the MakeHuman patient, standing, her breast at
//!   a 6 mm spacing (`scenes/patient-plan.toml` at 6 mm instead of its 7, with
//!   `scenes/patient-implants.toml`; docs/patient.md, "Speed"): the plan's time against its
//!   goal of 60 s on 2 cores. A candidate that fails there is counted in `held`, not an error.
//!
//! ```text
//! cargo bench -p voxcollide-cli --bench rest -- [--runs N] [--only press|compare|bunny|patient] [--explicit-compare]
//! ```
//!
//! Each case runs `--runs` times (default 3) through the built `voxcollide` binary with
//! `--backend cpu`; the table gives the median and the range of the wall times, with the steps,
//! and whether the run came to rest and its contacts held (a run that did not is no answer,
//! however quick). The compare case under the explicit integrator takes minutes, so it runs
//! only with `--explicit-compare`. Threads: rayon's, all cores unless `RAYON_NUM_THREADS` says.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// One case: a scene file, how it is run, under which integrator.
struct Case {
    name: &'static str,
    scene: &'static str,
    compare: bool,
    integrator: &'static str,
}

/// What one run gave.
struct Outcome {
    seconds: f64,
    steps: u64,
    settled: bool,
    held: bool,
}

fn main() {
    let mut runs = 3usize;
    let (mut only, mut explicit_compare) = (None, false);
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--runs" => runs = args.next().and_then(|v| v.parse().ok()).expect("--runs needs a count"),
            "--only" => only = args.next(),
            "--explicit-compare" => explicit_compare = true,
            // cargo bench passes `--bench`; criterion's own flags mean nothing here.
            _ => {}
        }
    }
    let here = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/rest");
    let threads = std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .filter(|n| *n > 0)
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from));
    let mut cases = Vec::new();
    for integrator in ["implicit", "explicit"] {
        cases.push(Case { name: "press", scene: "press.toml", compare: false, integrator });
        if integrator == "implicit" || explicit_compare {
            cases.push(Case { name: "compare", scene: "compare.toml", compare: true, integrator });
        }
        if integrator == "implicit" {
            cases.push(Case { name: "bunny", scene: "bunny.toml", compare: false, integrator });
            cases.push(Case {
                name: "bunny-nh",
                scene: "bunny-neo-hookean.toml",
                compare: false,
                integrator,
            });
        }
    }
    cases.push(Case { name: "patient", scene: "patient-plan.toml", compare: true, integrator: "implicit" });
    cases.retain(|c| only.as_deref().is_none_or(|o| c.name == o || c.name.strip_prefix(o) == Some("-nh")));
    let work = std::env::temp_dir().join(format!("voxcollide-rest-{}", std::process::id()));
    println!("time to rest, {runs} runs a case, CPU backend, {threads} threads\n");
    println!("| case | integrator | median s | range s | steps | at rest | held |");
    println!("| --- | --- | ---: | ---: | ---: | --- | --- |");
    let (mut bunny, mut patient) = ([None, None], None);
    for case in &cases {
        let outcomes: Vec<Outcome> =
            (0..runs).map(|k| run(&here, &work.join(format!("{}-{k}", case.name)), case)).collect();
        let mut seconds: Vec<f64> = outcomes.iter().map(|o| o.seconds).collect();
        seconds.sort_by(f64::total_cmp);
        match case.name {
            "bunny" => bunny[0] = Some(seconds[seconds.len() / 2]),
            "bunny-nh" => bunny[1] = Some(seconds[seconds.len() / 2]),
            "patient" => patient = Some(seconds[seconds.len() / 2]),
            _ => {}
        }
        let last = &outcomes[outcomes.len() - 1];
        println!(
            "| {} | {} | {:.2} | {:.2}–{:.2} | {} | {} | {} |",
            case.name,
            case.integrator,
            seconds[seconds.len() / 2],
            seconds[0],
            seconds[seconds.len() - 1],
            last.steps,
            if outcomes.iter().all(|o| o.settled) { "yes" } else { "NO" },
            if outcomes.iter().all(|o| o.held) { "yes" } else { "NO" },
        );
    }
    if let [Some(springs), Some(elements)] = bunny {
        println!(
            "\nbunny: Neo-Hookean at ν = 0.49 over springs, medians: {:.2}× (goal ≤ 3×)",
            elements / springs
        );
    }
    if let Some(plan) = patient {
        println!("\npatient: six candidates planned at 6 mm, median {plan:.1} s (goal ≤ 60 s on 2 cores)");
    }
    let _ = std::fs::remove_dir_all(&work);
}

/// Runs `case` once in `dir`; panics (naming the case) where the command fails.
fn run(here: &Path, dir: &Path, case: &Case) -> Outcome {
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).expect("a scratch folder");
    // The shipped scenes, beside the crates.
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let patient = case.name == "patient";
    let (text, candidates) = if patient {
        let text = std::fs::read_to_string(scenes.join(case.scene)).expect("the patient's scene");
        assert!(text.contains("spacing = 7\n"), "scenes/patient-plan.toml no longer plans at 7 mm");
        let makehuman = format!("\"{}/", scenes.join("makehuman").display());
        (
            text.replacen("spacing = 7\n", "spacing = 6\n", 1).replace("\"makehuman/", &makehuman),
            scenes.join("patient-implants.toml"),
        )
    } else {
        (
            std::fs::read_to_string(here.join(case.scene)).expect("the bench's scene"),
            here.join("candidates.toml"),
        )
    };
    let scene = dir.join(case.scene);
    let bunny = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bunny.obj");
    std::fs::write(
        &scene,
        text.replace("integrator = \"implicit\"", &format!("integrator = \"{}\"", case.integrator))
            .replace("\"BUNNY\"", &format!("{:?}", bunny.display().to_string())),
    )
    .expect("the scene written");
    let out = dir.join("out");
    let mut command = Command::new(env!("CARGO_BIN_EXE_voxcollide"));
    if case.compare {
        command.args(["compare", "--body", "implant", "--candidates"]).arg(candidates);
    } else {
        command.arg("run");
    }
    command.arg(&scene).args(["--backend", "cpu", "--out"]).arg(&out);
    let start = Instant::now();
    let output = command.output().expect("the voxcollide binary runs");
    let seconds = start.elapsed().as_secs_f64();
    // A comparison with a failed or unfinished candidate exits with 2 after writing its files:
    // that candidate is counted below, not an error of the bench.
    let written = case.compare && output.status.code() == Some(2) && out.join("compare.json").exists();
    assert!(
        output.status.success() || written,
        "{} ({}) failed:\n{}\n{}",
        case.name,
        case.integrator,
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    let read = |p: PathBuf| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(&p).expect("the run's JSON")).expect("valid JSON")
    };
    if case.compare {
        let c = read(out.join("compare.json"));
        let candidates = c["candidates"].as_array().expect("candidates");
        Outcome {
            seconds,
            steps: candidates.iter().map(|c| c["steps"].as_u64().unwrap_or(0)).sum(),
            settled: candidates.iter().all(|c| c["settled"] == true),
            held: candidates.iter().all(|c| c["held"] == true),
        }
    } else {
        let s = read(out.join("summary.json"));
        Outcome {
            seconds,
            steps: s["steps"].as_u64().unwrap_or(0),
            settled: s["settled"] == true,
            held: s["held"] == true,
        }
    }
}
