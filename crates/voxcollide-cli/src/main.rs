//! The `voxcollide` command: runs the paper's scenarios and writes what they did.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use voxcollide_cli::backend::Backend;
use voxcollide_cli::scenario::{RunConfig, run};
use voxcollide_cli::scene_run::{FileRunConfig, run_file as run_file_with};
use voxcollide_sim::{Kind, SceneConfig};

/// Collision between soft tissue and foreign bodies with a modified voxel model (Nikolaev, 2013).
#[derive(Parser, Debug)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run one of the paper's scenarios: pictures (PNG), ParaView files (VTK) and summary.json.
    Run(RunArgs),
    /// Time every backend on docs/design.md §7's workloads (lattice, z_fastest, shuffled, paper, paper_shuffled, and moving: lattice's bodies stepped 20 times in a row, B moving, its figure the mean step), each against a baseline that answers its question (kiddo k-d tree, voxel hash map), with each figure's distance to the memory-bandwidth floor.
    Bench(BenchArgs),
    /// Choose an implant: run a scene once per candidate of a catalogue (docs/design.md §9), the named
    /// shell replaced by each and filled to its volume, then settled; write report.html,
    /// compare.json, compare.csv and a folder per candidate. Exits with status 2 (after
    /// writing them) when a candidate failed a contact or did not finish (short of its volume
    /// by more than 2 %, or not at rest by max_steps): its numbers are not a result.
    Compare(CompareArgs),
    /// The contact test matrix: an implant filled under a tissue layer for every gap, shell
    /// stiffness, volume, spacing and tissue modulus given; each cell passes when its contacts
    /// held (docs/design.md §11), its volume is within 2 % and its lift rises with volume. Prints the
    /// table (Markdown) and exits non-zero when a cell fails.
    Matrix(MatrixArgs),
    /// Watch a scene live in a window (docs/design.md §10): orbit, pan and zoom; pause, step and reset;
    /// cycle the colouring; drag an instrument with the mouse while the tissue responds.
    View(ViewArgs),
}

#[derive(clap::Args, Debug)]
#[command(after_help = format!("Controls: {}", voxcollide_cli::view::HELP))]
struct ViewArgs {
    /// A scene file, or a shipped scene: implant, cylinder, indentation, expander,
    /// breast-implant, breast-compare.
    scene: String,
    /// Where the simulation steps (the window is drawn on an adapter either way).
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendArg,
    /// The window's size, WIDTHxHEIGHT.
    #[arg(long, default_value = "960x640", value_parser = parse_size)]
    size: (u32, u32),
    /// Draw this many frames, then close (and print the frame rate).
    #[arg(long)]
    frames: Option<u64>,
    /// Write the last frame as PNG (with --frames).
    #[arg(long, requires = "frames")]
    screenshot: Option<PathBuf>,
    /// A scripted drag: "x0,y0 -> x1,y1 over N frames [from frame K]" (window pixels from the
    /// top left; it starts at frame 1 unless told).
    #[arg(long, value_parser = voxcollide_cli::view::ScriptedDrag::parse)]
    drag: Option<voxcollide_cli::view::ScriptedDrag>,
    /// Take this many steps a frame instead of keeping real time (repeatable runs).
    #[arg(long)]
    steps_per_frame: Option<u64>,
    /// Write what the view did as JSON here at the end.
    #[arg(long)]
    report: Option<PathBuf>,
    /// What the bodies are coloured by at first (the c key cycles it).
    #[arg(long, value_enum, default_value = "displacement")]
    colouring: voxcollide_cli::view::Colouring,
}

#[derive(clap::Args, Debug)]
struct CompareArgs {
    /// The scene file (docs/design.md §8), e.g. scenes/breast-implant.toml.
    scene: PathBuf,
    /// The scene's shell body that each candidate replaces.
    #[arg(long)]
    body: String,
    /// The catalogue: [[candidate]] tables with `name` and `shape` or `mesh`.
    #[arg(long)]
    candidates: PathBuf,
    /// The output folder.
    #[arg(long, default_value = "out/compare")]
    out: PathBuf,
    /// Where to run.
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendArg,
    /// Picture size, WIDTHxHEIGHT.
    #[arg(long, default_value = "640x420", value_parser = parse_size)]
    image: (u32, u32),
    /// Candidates run at a time; 0: one per core on the CPU backend (each on one thread), else
    /// one.
    #[arg(long, default_value_t = 0)]
    jobs: usize,
    /// Choose from the catalogue by her breast's base width (between the tissue's landmarks
    /// `medial` and `lateral`): only implants no wider than it and at most MM narrower.
    #[arg(long, value_name = "MM", num_args = 0..=1, default_missing_value = "20")]
    fit_base: Option<f64>,
}

#[derive(clap::Args, Debug)]
struct MatrixArgs {
    /// Gaps between the chest wall and the tissue, mm, comma-separated.
    #[arg(long, default_value = "0,2,10,24", value_delimiter = ',')]
    gaps: Vec<f64>,
    /// Shell moduli, kPa.
    #[arg(long, default_value = "30,500,3000", value_delimiter = ',')]
    shells: Vec<f64>,
    /// Implant volumes on one 140 mm base, mL.
    #[arg(long, default_value = "200,400,800", value_delimiter = ',')]
    volumes: Vec<f64>,
    /// Tissue spacings (and shell edges), mm.
    #[arg(long, default_value = "4,6", value_delimiter = ',')]
    spacings: Vec<f64>,
    /// Tissue moduli, kPa.
    #[arg(long, default_value = "1,3,30", value_delimiter = ',')]
    tissues: Vec<f64>,
    /// Each run's step cap.
    #[arg(long, default_value_t = 60000)]
    max_steps: u64,
    /// The integrator every cell runs under: explicit (the paper's) or implicit.
    #[arg(long, value_enum, default_value = "explicit")]
    integrator: IntegratorArg,
    /// Where the cells' scenes and runs go.
    #[arg(long, default_value = "out/matrix")]
    out: PathBuf,
    /// Where to run.
    #[arg(long, value_enum, default_value = "cpu")]
    backend: BackendArg,
    /// Reuse the groups an earlier run with the same settings finished in `--out` (judged
    /// again), and run only the rest: the whole matrix can be run in pieces.
    #[arg(long)]
    resume: bool,
}

/// `--integrator`.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum IntegratorArg {
    Explicit,
    Implicit,
}

#[derive(clap::Args, Debug)]
struct BenchArgs {
    /// Vertices per body, comma-separated; k and M suffixes allowed.
    #[arg(long, default_value = "10k,100k,1M", value_parser = parse_sizes)]
    sizes: Sizes,
    /// Timed steps per case (after a warm-up step), the backends taking turns, one step each; medians are reported, and each ratio's spread step by step.
    #[arg(long, default_value_t = 5)]
    samples: usize,
    /// Skip the GPU even when there is an adapter.
    #[arg(long)]
    no_gpu: bool,
    /// Skip the single-threaded CPU reference (slow at 1M).
    #[arg(long)]
    no_reference: bool,
    /// Also time each GPU pass of the resident step (timestamp queries, where the adapter has
    /// them), in extra steps after the whole-step timing.
    #[arg(long)]
    passes: bool,
    /// Where to write the table as JSON.
    #[arg(long, default_value = "out/bench.json")]
    json: PathBuf,
}

#[derive(Clone, Debug)]
struct Sizes(Vec<usize>);

fn parse_sizes(s: &str) -> Result<Sizes, String> {
    s.split(',')
        .map(|part| {
            let part = part.trim();
            let (digits, mul) = match part.chars().last() {
                Some('k' | 'K') => (&part[..part.len() - 1], 1_000),
                Some('m' | 'M') => (&part[..part.len() - 1], 1_000_000),
                _ => (part, 1),
            };
            match digits.parse::<usize>() {
                Ok(n) if n > 0 => n.checked_mul(mul).ok_or_else(|| format!("{part:?} is too large a size")),
                _ => Err(format!("{part:?} is not a size such as 10k, 100000 or 1M")),
            }
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Sizes)
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Scenario {
    /// A stiff cylinder pressed into a tissue layer whose base is held (the paper's Fig. 5).
    Cylinder,
    /// An implant inflating on the chest wall under a tissue layer held at its rim (Fig. 6).
    Implant,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum BackendArg {
    /// The GPU if there is an adapter (software ones included), else the CPU.
    Auto,
    /// The GPU; fails without an adapter.
    Gpu,
    /// The CPU reference path.
    Cpu,
}

#[derive(clap::Args, Debug)]
struct RunArgs {
    /// A paper scenario (`implant`, `cylinder`: at the defaults below, the shipped
    /// `scenes/implant.toml` and `scenes/cylinder.toml`, built into the command; other values
    /// of --steps, --resolution, --stiffness, --pressure, --magnitude or --voxel-size run the
    /// built-in generator) or a scene file (`FILE.toml`, docs/design.md §8; the options below but
    /// --backend, --out and --image are the paper scenarios' own).
    scene: String,
    /// Where to run.
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendArg,
    /// Time steps.
    #[arg(long, default_value_t = 1200)]
    steps: u64,
    /// Output directory.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Frames written after the initial one (pictures, VTK files, measurements).
    #[arg(long, default_value_t = 12)]
    frames: u32,
    /// Tissue lattice cells across the layer (the simulation's resolution).
    #[arg(long, default_value_t = 24)]
    resolution: u32,
    /// Picture size, WIDTHxHEIGHT.
    #[arg(long, default_value = "960x600", value_parser = parse_size)]
    image: (u32, u32),
    /// Write no pictures.
    #[arg(long)]
    no_images: bool,
    /// Write no VTK files.
    #[arg(long)]
    no_vtk: bool,
    /// Penalty force per contact [default: 4 × stiffness × lattice spacing].
    #[arg(long)]
    magnitude: Option<f32>,
    /// Voxel size, a power of two [default: the coarser lattice spacing, rounded up to one].
    #[arg(long)]
    voxel_size: Option<f32>,
    /// Tissue spring stiffness (the foreign body's is 4× as stiff).
    #[arg(long, default_value_t = 40.0)]
    stiffness: f32,
    /// Final internal pressure of the implant.
    #[arg(long, default_value_t = 80.0)]
    pressure: f32,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once('x').ok_or_else(|| format!("{s:?} is not WIDTHxHEIGHT, e.g. 960x600"))?;
    let parse = |v: &str| v.trim().parse::<u32>().map_err(|e| format!("{v:?} in {s:?}: {e}"));
    Ok((parse(w)?, parse(h)?))
}

/// On a machine without a display, Mesa's Vulkan device-select layer (an implicit layer the
/// loader adds to every instance) tries to connect to a Wayland compositor while the adapters
/// are enumerated, and libwayland prints `error: XDG_RUNTIME_DIR is invalid or not set` to stderr
/// on a run that works. The layer only orders adapters by the display they drive, which means
/// nothing offscreen: with no display, turn it off (its own switch, `NODEVICE_SELECT=1`) before
/// any adapter is looked for. A value the user set is kept.
fn keep_offscreen_work_away_from_the_display() {
    let display = ["WAYLAND_DISPLAY", "DISPLAY"].iter().any(|v| std::env::var_os(v).is_some());
    if !display && std::env::var_os("NODEVICE_SELECT").is_none() {
        // SAFETY: called first thing in main, before any other thread exists (nothing reads
        // the environment concurrently).
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
}

fn main() -> ExitCode {
    keep_offscreen_work_away_from_the_display();
    let args = match Cli::parse().command {
        Command::Run(args) => args,
        Command::Bench(args) => return bench(&args),
        Command::Compare(args) => return compare(&args),
        Command::View(args) => return view(&args),
        Command::Matrix(args) => return matrix(&args),
    };
    let backend = match args.backend {
        BackendArg::Auto => Backend::Auto,
        BackendArg::Gpu => Backend::Gpu,
        BackendArg::Cpu => Backend::Cpu,
    };
    let kind = match Scenario::from_str(&args.scene, true) {
        Ok(Scenario::Cylinder) => Kind::Cylinder,
        Ok(Scenario::Implant) => Kind::Implant,
        Err(_) => return run_file(&args, backend),
    };
    let config = RunConfig {
        scene: SceneConfig {
            kind,
            resolution: args.resolution,
            steps: args.steps,
            stiffness: args.stiffness,
            magnitude: args.magnitude,
            voxel_size: args.voxel_size,
            pressure: args.pressure,
        },
        backend,
        out: args.out.clone(),
        frames: args.frames,
        image: (!args.no_images).then_some(args.image),
        vtk: !args.no_vtk,
    };
    let bar = ProgressBar::new(args.steps);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{bar:40}] {pos}/{len} steps  {per_sec}  eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    // indicatif drops println when the bar is hidden (stderr not a terminal): notes go to
    // stderr directly then, so a log still says why the run fell back to the CPU.
    let result = run(&config, &mut |done| bar.set_position(done), &mut |line| {
        if bar.is_hidden() { eprintln!("{line}") } else { bar.println(line) }
    });
    bar.finish_and_clear();
    match result {
        Ok(s) => {
            let last = s.frames.last().cloned().unwrap_or_default();
            println!("{:<28} {}", "scenario", s.scenario);
            println!("{:<28} {} ({})", "backend", s.backend, s.adapter);
            println!("{:<28} {} tissue (B), {} {} (A)", "vertices", s.vertices_b, s.vertices_a, s.scenario);
            println!(
                "{:<28} {} × dt {:.2e}, {:.0} steps/s, {:.3} simulated time per second",
                "steps",
                s.steps,
                s.dt,
                s.steps_per_second,
                s.steps_per_second * f64::from(s.dt)
            );
            if let Some(w) = s.host_waits_per_step {
                println!("{:<28} {w:.2} a step (frames excluded)", "waits for the device");
            }
            println!("{:<28} {:.3} (voxel size {})", "max penetration", s.max_penetration, s.voxel_size);
            for c in s.contacts.iter().filter_map(|c| c.failure.as_ref()) {
                println!("{:<28} {c}: these numbers are not a result", "warning:");
            }
            println!("{:<28} {:.2} %", "penetrating tissue", 100.0 * s.penetrating_fraction);
            println!(
                "{:<28} {:.3} ({:.0} % of the layer's {:.3})",
                "max tissue displacement",
                s.max_tissue_displacement,
                100.0 * s.max_tissue_displacement / s.layer_thickness,
                s.layer_thickness
            );
            println!("{:<28} {}", "contacts at the end", last.colliding);
            println!("{:<28} {} files in {}", "written", s.files.len(), args.out.display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// `voxcollide run FILE.toml`.
fn run_file(args: &RunArgs, backend: Backend) -> ExitCode {
    let path = PathBuf::from(&args.scene);
    if !path.is_file() {
        eprintln!(
            "error: {:?} is neither a paper scenario (implant, cylinder) nor a scene file that exists",
            args.scene
        );
        return ExitCode::FAILURE;
    }
    let config = FileRunConfig { path, backend, out: args.out.clone(), image: args.image };
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{bar:40}] {pos}/{len} steps  {per_sec}  eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let result = run_file_with(
        &config,
        &mut |done, planned| {
            bar.set_length(planned);
            bar.set_position(done);
        },
        &mut |line| {
            if bar.is_hidden() { eprintln!("{line}") } else { bar.println(line) }
        },
    );
    bar.finish_and_clear();
    match result {
        Ok(s) => {
            println!("{:<28} {}", "scene", s.scenario);
            println!("{:<28} {} ({})", "backend", s.backend, s.adapter);
            println!(
                "{:<28} {} × dt {:.2e} s = {:.3} s simulated, {:.0} steps/s, {:.3} simulated s per s",
                "steps", s.steps, s.dt, s.simulated_time, s.steps_per_second, s.realtime_factor
            );
            if let Some(w) = s.host_waits_per_step {
                println!("{:<28} {w:.2} a step (frames excluded)", "waits for the device");
            }
            if let (Some(split), Some(parts)) = (s.split_steps, s.most_parts)
                && split > 0
            {
                println!(
                    "{:<28} {split} steps taken in parts (up to {parts}): a vertex would have moved farther in one than a contact may miss",
                    "split steps"
                );
            }
            for b in &s.bodies {
                println!(
                    "{:<28} {} vertices, moved up to {:.3} {}{}",
                    format!("body {} ({})", b.name, b.kind),
                    b.vertices,
                    b.max_displacement,
                    s.units,
                    match (b.volume_ml, b.volume) {
                        (Some(start), _) if let Some(end) = b.volume_ml_end => {
                            format!(
                                ", {start:.1} mL of tissue at the start, {end:.1} mL at the end ({})",
                                volume_change(start, end)
                            )
                        }
                        (Some(ml), _) => format!(", {ml:.1} mL inside at the end"),
                        (None, Some(v)) => format!(", {v:.4} cubic {} inside at the end", s.units),
                        (None, None) => String::new(),
                    }
                );
            }
            for l in &s.landmarks {
                let f = |p: [f32; 3]| format!("[{:.1}, {:.1}, {:.1}]", p[0], p[1], p[2]);
                println!(
                    "{:<28} {} to {} {}",
                    format!("landmark {}.{}", l.body, l.name),
                    f(l.start),
                    f(l.end),
                    s.units
                );
            }
            for c in &s.contacts {
                println!(
                    "{:<28} max penetration {:.3} {}, {:.2} % inside, {} in contact at the end; {}",
                    format!("contact {} – {}", c.a, c.b),
                    c.max_penetration,
                    s.units,
                    100.0 * c.penetrating_fraction,
                    c.contacts_at_end,
                    if c.held {
                        format!(
                            "held (within {:.3} {u}, at rest {:.3} {u})",
                            c.bound,
                            c.rest_bound,
                            u = s.units
                        )
                    } else {
                        "did NOT hold".into()
                    }
                );
                if let Some(f) = &c.failure {
                    println!("{:<28} {f}: these numbers are not a result", "warning:");
                }
            }
            let stalled = s.criterion.starts_with("stalled");
            println!(
                "{:<28} {} (over the last {:.3} s a vertex moved at most {:.3} of its spacing; at rest: {}{})",
                "settled",
                s.settled,
                s.rest_window,
                s.rest_motion,
                voxcollide_cli::scene_run::REST_TOLERANCE,
                if stalled {
                    " for all but a hundredth of the soft bodies' vertices, the residual having stalled"
                } else {
                    ""
                }
            );
            if let Some(r) = s.residual {
                let floor = s.residual_floor.map_or(String::new(), |f| {
                    format!(", or as finely as single precision resolves it: {f:.1e}")
                });
                println!(
                    "{:<28} implicit; residual force {r:.2e} of the largest load (at rest: {:.0e}{floor}); rest judged by {}",
                    "integrator",
                    voxcollide_cli::scene_run::RESIDUAL_TOLERANCE,
                    s.criterion
                );
            }
            println!("{:<28} {} files in {}", "written", s.files.len(), args.out.display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn matrix(args: &MatrixArgs) -> ExitCode {
    use voxcollide_cli::matrix::{Axes, group_dir, groups, resumed, run_group, table};
    use voxcollide_sim::scene_file::IntegratorSpec;
    let axes = Axes {
        gaps: args.gaps.clone(),
        shells: args.shells.clone(),
        volumes: args.volumes.clone(),
        spacings: args.spacings.clone(),
        tissues: args.tissues.clone(),
    };
    let groups = groups(&axes);
    let mut cells = Vec::new();
    for (k, g) in groups.iter().enumerate() {
        eprintln!(
            "group {}/{}: gap {} mm, shell {} kPa, spacing {} mm, tissue {} kPa",
            k + 1,
            groups.len(),
            g.gap,
            g.shell,
            g.spacing,
            g.tissue
        );
        let integrator = match args.integrator {
            IntegratorArg::Explicit => IntegratorSpec::Explicit,
            IntegratorArg::Implicit => IntegratorSpec::Implicit,
        };
        if args.resume
            && let Some(c) = resumed(g, &axes.volumes, args.max_steps, integrator, &group_dir(&args.out, g))
        {
            eprintln!("  finished by an earlier run: its results judged again");
            cells.extend(c);
            continue;
        }
        let bars = CandidateBars::new();
        let (mut running, mut finished) = (std::collections::HashMap::new(), 0u64);
        let result = run_group(
            g,
            &axes.volumes,
            args.max_steps,
            integrator,
            &group_dir(&args.out, g),
            backend_of(args.backend),
            &mut |p| bars.show(&mut running, &mut finished, p),
            &mut |_| {},
        );
        bars.finish(&running);
        match result {
            Ok(c) => cells.extend(c),
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    print!("{}", table(&cells));
    let failed = cells.iter().filter(|c| c.failure.is_some()).count();
    println!("{} of {} cells pass", cells.len() - failed, cells.len());
    if failed == 0 { ExitCode::SUCCESS } else { ExitCode::from(2) }
}

fn backend_of(arg: BackendArg) -> Backend {
    match arg {
        BackendArg::Auto => Backend::Auto,
        BackendArg::Gpu => Backend::Gpu,
        BackendArg::Cpu => Backend::Cpu,
    }
}

fn view(args: &ViewArgs) -> ExitCode {
    if let Some(why) = voxcollide_cli::view::no_display() {
        eprintln!(
            "voxcollide view: no display here ({why}); `voxcollide run {}` runs the scene without one and writes its pictures",
            args.scene
        );
        return ExitCode::FAILURE;
    }
    let config = voxcollide_cli::view::ViewConfig {
        scene: args.scene.clone(),
        backend: backend_of(args.backend),
        size: args.size,
        frames: args.frames,
        screenshot: args.screenshot.clone(),
        drag: args.drag,
        steps_per_frame: args.steps_per_frame,
        report: args.report.clone(),
        colouring: args.colouring,
    };
    match voxcollide_cli::view::view(&config, &mut |line| eprintln!("{line}")) {
        Ok(r) => {
            let realtime = if r.seconds > 0.0 { r.simulated_time / r.seconds } else { 0.0 };
            println!(
                "{} frames in {:.2} s: {:.1} frames/s at {}x{}; {} steps, {:.0} steps/s ({realtime:.2}x real time{}) on the {} backend ({})",
                r.frames,
                r.seconds,
                r.frames_per_second,
                r.size.0,
                r.size.1,
                r.steps,
                r.steps_per_second,
                if r.behind_frames > 0 {
                    format!(", behind in {} frames", r.behind_frames)
                } else {
                    String::new()
                },
                r.backend,
                r.adapter
            );
            let moved: Vec<String> =
                r.max_displacement.iter().map(|(n, d)| format!("{n} {d:.4} {}", r.units)).collect();
            println!(
                "at the end: max displacement {}; {} contacts; max penetration {:.4} {}",
                moved.join(", "),
                r.contacts,
                r.max_penetration,
                r.units
            );
            if let Some(p) = &r.screenshot {
                println!("wrote {}", p.display());
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// A comparison's progress on a terminal: a bar for the whole and one per running candidate
/// (several at once with `--jobs`); hidden, its notes go to standard error line by line.
struct CandidateBars {
    multi: indicatif::MultiProgress,
    whole: ProgressBar,
}

impl CandidateBars {
    fn style(template: &str) -> ProgressStyle {
        ProgressStyle::with_template(template)
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> ")
    }

    fn new() -> CandidateBars {
        let multi = indicatif::MultiProgress::new();
        let whole = multi.add(ProgressBar::new(0));
        whole.set_style(Self::style("{prefix:>12} [{bar:30}] {pos}/{len} candidates  {elapsed}"));
        whole.set_prefix("all");
        CandidateBars { multi, whole }
    }

    /// Shows `p`: `running` holds the bars of the candidates running, `finished` counts those
    /// done.
    fn show(
        &self,
        running: &mut std::collections::HashMap<usize, ProgressBar>,
        finished: &mut u64,
        p: voxcollide_cli::compare::Progress<'_>,
    ) {
        self.whole.set_length(p.count as u64);
        let bar = running.entry(p.index).or_insert_with(|| {
            let bar = self.multi.add(ProgressBar::new(1));
            bar.set_style(Self::style("{prefix:>12} [{bar:30}] {pos}/{len} steps  {per_sec}  {msg}"));
            bar.set_prefix(format!("{}/{}", p.index + 1, p.count));
            bar.set_message(p.name.to_string());
            bar
        });
        bar.set_length(p.planned.max(p.done));
        bar.set_position(p.done);
        if p.finished {
            if let Some(bar) = running.remove(&p.index) {
                bar.finish_and_clear();
                self.multi.remove(&bar);
            }
            *finished += 1;
            self.whole.set_position(*finished);
            if self.whole.is_hidden() {
                eprintln!("  {}/{} {}: {} steps", p.index + 1, p.count, p.name, p.done);
            }
        }
    }

    fn println(&self, line: &str) {
        if self.whole.is_hidden() {
            eprintln!("{line}");
        } else {
            self.multi.println(line).ok();
        }
    }

    fn finish(&self, running: &std::collections::HashMap<usize, ProgressBar>) {
        self.whole.finish_and_clear();
        for bar in running.values() {
            bar.finish_and_clear();
        }
    }
}

fn compare(args: &CompareArgs) -> ExitCode {
    let config = voxcollide_cli::compare::CompareConfig {
        scene: args.scene.clone(),
        body: args.body.clone(),
        candidates: args.candidates.clone(),
        out: args.out.clone(),
        backend: backend_of(args.backend),
        image: args.image,
        jobs: args.jobs,
        fit_base: args.fit_base,
    };
    let bars = CandidateBars::new();
    let mut running = std::collections::HashMap::new();
    let mut finished = 0u64;
    let result = voxcollide_cli::compare::compare(
        &config,
        &mut |p| bars.show(&mut running, &mut finished, p),
        &mut |line| bars.println(line),
    );
    bars.finish(&running);
    match result {
        Ok(c) => {
            let w = c.candidates.iter().map(|r| r.name.chars().count()).max().unwrap_or(0).max(9);
            println!(
                "{:<w$} {:>9} {:>10} {:>12} {:>10} {:>12} {:>8} {:>10}",
                "candidate",
                "volume mL",
                format!("lift {}", c.units),
                format!("max disp {}", c.units),
                "peak kPa",
                format!("area {}²", c.units),
                "settled",
                "result"
            );
            for r in &c.candidates {
                if let Some(step) = r.blew_up_at_step {
                    println!("{:<w$} FAILED: its run blew up at step {step}", r.name);
                    continue;
                }
                println!(
                    "{:<w$} {:>9.1} {:>10.2} {:>12.2} {:>10.2} {:>12.0} {:>8} {:>10}",
                    r.name,
                    r.volume_ml,
                    r.apex_lift,
                    r.max_tissue_displacement,
                    r.peak_contact_pressure_kpa,
                    r.contact_area,
                    r.settled,
                    if !r.held {
                        "FAILED"
                    } else if !r.finished {
                        "UNFINISHED"
                    } else {
                        "yes"
                    }
                );
            }
            println!("written: {}/report.html, compare.json, compare.csv", args.out.display());
            for r in c.candidates.iter().filter(|r| !r.is_result()) {
                eprintln!(
                    "warning: candidate {:?} {}, its numbers are not a result: {}",
                    r.name,
                    if r.held { "is UNFINISHED" } else { "FAILED" },
                    r.not_a_result().unwrap_or_default()
                );
            }
            for r in &c.candidates {
                if let Some(w) = &r.warning {
                    eprintln!("warning: candidate {:?}: {w}", r.name);
                }
            }
            let failed = c.candidates.iter().filter(|r| !r.held).count();
            let unfinished = c.candidates.iter().filter(|r| r.held && !r.finished).count();
            if failed > 0 {
                eprintln!("error: {failed} of {} candidates failed (docs/design.md §11)", c.candidates.len());
            }
            if unfinished > 0 {
                eprintln!(
                    "error: {unfinished} of {} candidates did not finish (short of their volume or not at rest: raise [time] max_steps, or use integrator = \"implicit\")",
                    c.candidates.len()
                );
            }
            if failed == 0 && unfinished == 0 { ExitCode::SUCCESS } else { ExitCode::from(2) }
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn bench(args: &BenchArgs) -> ExitCode {
    let config = voxcollide_cli::bench::BenchConfig {
        sizes: args.sizes.0.clone(),
        samples: args.samples,
        gpu: !args.no_gpu,
        reference: !args.no_reference,
        passes: args.passes,
    };
    println!("{}", voxcollide_cli::bench::table(&[]).trim_end());
    let result = voxcollide_cli::bench::run(&config, &mut |row| {
        print!(
            "{}",
            voxcollide_cli::bench::table(std::slice::from_ref(row))
                .lines()
                .skip(1)
                .map(|l| format!("{l}\n"))
                .collect::<String>()
        )
    });
    match result {
        Ok(rows) => {
            let written = args
                .json
                .parent()
                .map_or(Ok(()), |dir| {
                    if dir.as_os_str().is_empty() { Ok(()) } else { std::fs::create_dir_all(dir) }
                })
                .and_then(|()| {
                    std::fs::write(&args.json, serde_json::to_string_pretty(&rows).unwrap_or_default() + "\n")
                });
            match written {
                Ok(()) => {
                    println!("written: {}", args.json.display());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("error: {}: {e}", args.json.display());
                    ExitCode::FAILURE
                }
            }
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// How a patient's tissue changed in volume, as `run` prints it: "302.8 mL added" by an implant,
/// "16.1 mL less" where it lost some (settled lying with no implant, ν below 1/2).
fn volume_change(start: f64, end: f64) -> String {
    if end >= start { format!("{:.1} mL added", end - start) } else { format!("{:.1} mL less", start - end) }
}

#[cfg(test)]
mod volume_tests {
    #[test]
    fn a_volume_lost_is_said_as_less_not_as_a_negative_addition() {
        assert_eq!(super::volume_change(1052.5, 1355.3), "302.8 mL added");
        assert_eq!(super::volume_change(1098.9, 1082.8), "16.1 mL less");
        assert_eq!(super::volume_change(10.0, 10.0), "0.0 mL added");
    }
}
