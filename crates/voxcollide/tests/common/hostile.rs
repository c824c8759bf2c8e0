//! The hostile-input harness: seeded cases of the kind a careless or malicious caller makes —
//! coordinates that are NaN, ±inf, ±0, subnormal, ±f32::MAX or 1e30, one stray vertex far from
//! the rest of its body, margins and dims up to `MAX_DIM` (powers of two among them), many
//! vertices in one voxel, empty and one-vertex bodies, bad and extreme parameters — each run
//! through every backend there is and checked:
//!
//! - no backend panics (a panic is caught and reported with the case's seed);
//! - the backends agree: the reference's report, exactly, from the parallel backend; from the GPU
//!   the same `colliding_b`, counts and center, and forces bit for bit where the adapter's `sqrt`
//!   is correctly rounded (Mesa's llvmpipe, on Vulkan and on GL), within `1e-5 * m` elsewhere
//!   (docs/design.md §2); or the same `Error` variant from every backend;
//! - the reference's report keeps its invariants: the lengths, `binned_a + discarded_a == |A|`,
//!   `colliding_b` ascending and in range, finite forces, `force_b` zero exactly where B does not
//!   collide and of length `m` (to f32 rounding) where it does, and a net force within the
//!   fixed-point rounding of the contributions.
//!
//! Used by `tests/fuzz.rs` (a seeded run inside `cargo test`, and every case ever found kept as a
//! regression) and `examples/fuzz.rs` (the long run: `cargo run --release --example fuzz`).
//! No `rand` here: a case is a pure function of its seed (splitmix64), on every platform.
#![allow(dead_code)]

use std::mem::discriminant;
use std::panic::{AssertUnwindSafe, catch_unwind};

use voxcollide::glam::{UVec3, Vec3};
use voxcollide::grid::MAX_DIM;
use voxcollide::workload::SplitMix64;
use voxcollide::*;

/// The cases' random numbers: the workloads' SplitMix64, the seed scrambled first so that
/// seeds 0, 1, 2, ... start far apart.
#[derive(Clone, Debug)]
pub struct Rng(SplitMix64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(SplitMix64::new(seed ^ 0x005e_ed0f_c011_1de5))
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in `0..n` (`n > 0`).
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }

    /// Uniform in `lo..=hi`.
    pub fn range(&mut self, lo: i64, hi: i64) -> i64 {
        lo + self.below((hi - lo + 1) as u64) as i64
    }

    /// Uniform in `[0, 1)`.
    pub fn unit(&mut self) -> f32 {
        self.0.unit()
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f32) -> bool {
        self.unit() < p
    }

    pub fn pick<T: Copy>(&mut self, xs: &[T]) -> T {
        xs[self.below(xs.len() as u64) as usize]
    }
}

/// The hostile coordinate values.
pub const SPECIALS: [f32; 16] = [
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    0.0,
    -0.0,
    1e-40,  // subnormal
    -1e-40, // subnormal
    1.4e-45,
    f32::MIN_POSITIVE,
    f32::MAX,
    -f32::MAX,
    1e30,
    -1e30,
    3.0e38,
    16_777_216.0,
    -16_777_217.0,
];

/// How a case's grid is made.
#[derive(Clone, Copy, Debug)]
pub enum GridSpec {
    /// `VoxelGrid::new(center, voxel_size, dims)`.
    Direct { center: Vec3, voxel_size: f32, dims: UVec3 },
    /// `Initializer::new(voxel_size).margin(margin)` (`.contact_half(toward)`), built over A.
    Init { voxel_size: f32, margin: u32, toward: Option<Vec3> },
}

/// One hostile case: two bodies, a grid and contact params.
#[derive(Clone, Debug)]
pub struct Case {
    pub seed: u64,
    pub a: Vec<Vec3>,
    pub b: Vec<Vec3>,
    pub grid: GridSpec,
    pub params: ContactParams,
    /// The contact response every backend is given (`with_response`).
    pub response: Response,
}

impl Case {
    pub fn build_grid(&self) -> Result<VoxelGrid, Error> {
        match self.grid {
            GridSpec::Direct { center, voxel_size, dims } => VoxelGrid::new(center, voxel_size, dims),
            GridSpec::Init { voxel_size, margin, toward } => {
                let init = Initializer::new(voxel_size).margin(margin);
                let init = match toward {
                    Some(t) => init.contact_half(t),
                    None => init,
                };
                init.build(&self.a)
            }
        }
    }
}

fn special(r: &mut Rng) -> f32 {
    r.pick(&SPECIALS)
}

/// A point of the body's cloud: `base + size * u`, `u` in `[0, 1)^3`.
fn cloud(r: &mut Rng, base: Vec3, size: f32) -> Vec3 {
    base + size * Vec3::new(r.unit(), r.unit(), r.unit())
}

/// A body of `n` vertices around `base` in voxels of `vs`.
fn body(r: &mut Rng, n: usize, base: Vec3, vs: f32) -> Vec<Vec3> {
    match r.below(5) {
        // A jittered lattice of spacing vs/2, vs or 2 vs, x fastest.
        0 | 1 => {
            let spacing = vs * r.pick(&[0.5f32, 1.0, 2.0]);
            let k = ((n as f32).cbrt().ceil() as usize).max(1);
            let jitter = r.pick(&[0.0f32, 0.1, 0.45]) * spacing;
            (0..n)
                .map(|i| {
                    let q = Vec3::new((i % k) as f32, (i / k % k) as f32, (i / (k * k)) as f32);
                    base + spacing * q + jitter * (2.0 * Vec3::new(r.unit(), r.unit(), r.unit()) - 1.0)
                })
                .collect()
        }
        // A uniform cloud a few voxels wide.
        2 | 3 => {
            let size = vs * r.range(1, 12) as f32;
            (0..n).map(|_| cloud(r, base, size)).collect()
        }
        // Everything in one voxel (or on one point).
        _ => {
            let size = vs * r.pick(&[0.0f32, 0.001, 0.999]);
            (0..n).map(|_| cloud(r, base, size)).collect()
        }
    }
}

/// Replaces a few coordinates by hostile values, and maybe adds one stray vertex far away.
fn poison(r: &mut Rng, points: &mut Vec<Vec3>, vs: f32) {
    if points.is_empty() {
        return;
    }
    if r.chance(0.3) {
        for _ in 0..r.range(1, 3) {
            let i = r.below(points.len() as u64) as usize;
            let axis = r.below(4) as usize;
            let v = special(r);
            if axis == 3 {
                points[i] = Vec3::splat(v);
            } else {
                points[i][axis] = v;
            }
        }
    }
    if r.chance(0.1) {
        let far = r.pick(&[1e3f32, 1e6, 1e9, 1e30]) * vs.max(1.0);
        let sign = if r.chance(0.5) { 1.0 } else { -1.0 };
        let stray = points[0] + sign * far * Vec3::new(r.unit(), r.unit(), r.unit());
        let at = r.below(points.len() as u64 + 1) as usize;
        points.insert(at, stray);
    }
}

fn size(r: &mut Rng) -> usize {
    match r.below(50) {
        0 => 0,
        1..=5 => 1,
        6..=15 => r.range(2, 8) as usize,
        16..=47 => r.range(9, 300) as usize,
        _ => r.range(301, 1500) as usize,
    }
}

fn dim(r: &mut Rng) -> u32 {
    match r.below(10) {
        0..=5 => r.range(1, 40) as u32,
        _ => r.pick(&[
            1 << 16,
            1 << 21,
            1 << 22,
            (1 << 22) + 1,
            1 << 23,
            3_000_000,
            MAX_DIM - 1,
            MAX_DIM,
            MAX_DIM + 1, // rejected: Error::Dims everywhere
            0,           // rejected too
        ]),
    }
}

/// The case of `seed`.
pub fn generate(seed: u64) -> Case {
    let r = &mut Rng::new(seed);
    let k = match r.below(10) {
        0..=6 => r.range(-2, 2),
        7 => r.range(-10, 10),
        8 => r.pick(&[-24i64, -23, 20, 24]),
        _ => r.pick(&[-25i64, 25, 0]), // -25 and 25 are rejected: Error::VoxelSize
    } as i32;
    let mut vs = 2f32.powi(k);
    if r.chance(0.01) {
        vs = r.pick(&[0.75f32, 0.0, -1.0, f32::NAN, f32::INFINITY]);
    }
    let unit = if vs.is_finite() && vs > 0.0 { vs } else { 1.0 };
    let base = match r.below(10) {
        0..=5 => Vec3::ZERO,
        6 => Vec3::splat(-3.5 * unit),
        7 => Vec3::new(1e6, -1e6, 1e3) * unit,
        8 => Vec3::splat(r.pick(&[1e30f32, -1e30, 3.0e38, -3.0e38, 1e-40])),
        _ => Vec3::new(r.unit(), r.unit(), r.unit()) * 1e4 * unit,
    };
    let (na, nb) = (size(r), size(r));
    let mut a = body(r, na, base, unit);
    let shift = unit * r.pick(&[0.0f32, 0.1, 0.3, 0.5, 0.999, 1.0, 1.5]);
    let mut b = match r.below(3) {
        // A's shape, shifted (coincident at shift 0).
        0 if !a.is_empty() => {
            (0..nb).map(|j| a[j % a.len()] + Vec3::new(shift, 0.7 * shift, 0.4 * shift)).collect()
        }
        1 => body(r, nb, base + Vec3::splat(shift), unit),
        _ => {
            let size = unit * r.range(1, 16) as f32;
            (0..nb).map(|_| cloud(r, base - Vec3::splat(size * 0.25), size)).collect()
        }
    };
    poison(r, &mut a, unit);
    poison(r, &mut b, unit);
    // Rarely, a pile-up on one A vertex: past the i32 fixed-point total, or just short of it.
    if r.chance(0.004) {
        a = vec![base + Vec3::splat(0.5 * unit)];
        let n = r.pick(&[32_767usize, 32_768, 32_769, 40_000]);
        b = vec![base + Vec3::new(0.75, 0.5, 0.5) * unit; n];
    }

    let grid = if r.chance(0.6) {
        let margin = match r.below(20) {
            0 => r.pick(&[1u32 << 22, (1 << 23) - 1, 1 << 23, u32::MAX]),
            _ => r.range(0, 3) as u32,
        };
        let toward = r.chance(0.2).then(|| match r.below(8) {
            0 => Vec3::splat(special(r)),
            1 => Vec3::ZERO,
            _ => Vec3::new(r.unit() - 0.5, r.unit() - 0.5, r.unit() - 0.5),
        });
        GridSpec::Init { voxel_size: vs, margin, toward }
    } else {
        let center = match r.below(6) {
            0 => Vec3::splat(special(r)),
            1 => base + Vec3::splat(1e4 * unit),
            _ => base + Vec3::new(r.unit(), r.unit(), r.unit()) * 8.0 * unit,
        };
        let dims = if r.chance(0.5) { UVec3::splat(dim(r)) } else { UVec3::new(dim(r), dim(r), dim(r)) };
        GridSpec::Direct { center, voxel_size: vs, dims }
    };

    let magnitude = match r.below(20) {
        0 => r.pick(&[0.0f32, -1.0, f32::NAN, f32::INFINITY]),
        1 => r.pick(&[1e-30f32, 1e30, f32::MAX, f32::MIN_POSITIVE, 1e-40]),
        2..=9 => 1.0,
        _ => 2f32.powi(r.range(-10, 10) as i32) * (0.5 + r.unit()),
    };
    let search = if r.chance(0.5) {
        Search::Voxel
    } else {
        let radius = match r.below(20) {
            0 => r.pick(&[0.0f32, -1.0, f32::NAN, 2.0 * unit, 1.000_001 * unit]),
            1 => r.pick(&[1e-30f32 * unit, 1e-40]),
            2..=5 => unit,
            _ => unit * (0.05 + 0.95 * r.unit()),
        };
        Search::Neighbours { radius }
    };
    let direction = if r.chance(0.5) { Direction::Pairwise } else { Direction::PlaneNormal };
    let anchor = if r.chance(0.5) { Anchor::Fixed } else { Anchor::FollowA };
    // Half the cases respond with a penalty, some of whose constants are refused.
    let response = if r.chance(0.5) {
        Response::Constant
    } else {
        let stiffness = match r.below(20) {
            0 => r.pick(&[0.0f32, -1.0, f32::NAN, f32::INFINITY]),
            1 => r.pick(&[1e-30f32, 1e30, f32::MAX, f32::MIN_POSITIVE, 1e-40]),
            _ => 2f32.powi(r.range(-6, 12) as i32) * (0.5 + r.unit()) / unit.max(f32::MIN_POSITIVE),
        };
        let gap = match r.below(20) {
            0 => r.pick(&[-1.0f32, f32::NAN, f32::INFINITY, 2.0 * vs]),
            1..=6 => 0.0,
            7 => vs,
            _ => vs * r.unit(),
        };
        Response::Penalty { stiffness, gap }
    };
    Case { seed, a, b, grid, params: ContactParams { magnitude, search, direction, anchor }, response }
}

/// The backends a case runs on.
pub struct Backends {
    pub gpu: Option<GpuContext>,
    /// Whether the GPU's forces must equal the reference's bit for bit (llvmpipe: a correctly
    /// rounded `sqrt`), rather than within `1e-5 * m`.
    pub gpu_exact: bool,
}

impl Backends {
    pub fn new(gpu: Option<GpuContext>) -> Backends {
        let gpu_exact = gpu.as_ref().is_some_and(|c| c.adapter_name().contains("llvmpipe"));
        Backends { gpu, gpu_exact }
    }
}

/// What one case did, for the tallies.
#[derive(Clone, Debug, Default)]
pub struct Outcome {
    /// The reference's error variant's name, or "ok".
    pub result: String,
    pub contacts: usize,
    pub gpu_ran: bool,
    /// The grid itself was refused (before any backend ran).
    pub grid_error: bool,
}

fn variant(e: &Error) -> String {
    format!("{e:?}").split([' ', '{', '(']).next().unwrap_or("?").to_string()
}

thread_local! {
    /// Set while a backend runs under [`guarded`]: its panic is reported as a failure of the
    /// case, with the seed, so the default hook's message would only repeat it.
    static GUARDED: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Installs (once) a panic hook that stays quiet for panics [`guarded`] catches and defers to
/// the previous hook for every other.
fn quiet_guarded_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !GUARDED.with(std::cell::Cell::get) {
                previous(info);
            }
        }));
    });
}

/// Runs `f`, turning a panic into an `Err` naming the backend and where it panicked.
fn guarded<T>(backend: &str, f: impl FnOnce() -> T) -> Result<T, String> {
    quiet_guarded_panics();
    GUARDED.with(|g| g.set(true));
    let result = catch_unwind(AssertUnwindSafe(f));
    GUARDED.with(|g| g.set(false));
    result.map_err(|p| {
        let msg = p
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default();
        format!("{backend} panicked: {msg}")
    })
}

/// Runs `case` on every backend and checks it; `Err` describes the first failure.
pub fn check(case: &Case, backends: &Backends) -> Result<Outcome, String> {
    let grid = match guarded("grid", || case.build_grid())? {
        Ok(g) => g,
        Err(e) => return Ok(Outcome { result: variant(&e), grid_error: true, ..Outcome::default() }),
    };
    let (a, b, params, response) = (&case.a, &case.b, case.params, case.response);
    let reference = guarded("CpuCollision", || {
        CpuCollision::new(grid, params).and_then(|c| c.with_response(response)).and_then(|mut c| c.step(a, b))
    })?;
    // Each fast backend steps twice: a warm step reuses its buffers (the parallel one its
    // report's vectors too) and must give the same report again.
    let parallel = guarded("ParallelCpuCollision", || {
        ParallelCpuCollision::new(grid, params).and_then(|c| c.with_response(response)).map(|mut c| {
            let first = c.step(a, b);
            let mut again = first.clone().unwrap_or_default();
            let second = c.step_into(a, b, &mut again).map(|()| again);
            (first, second)
        })
    })?;
    let parallel = warm("ParallelCpuCollision", parallel, params.magnitude)?;
    agree("ParallelCpuCollision", &reference, &parallel, params.magnitude, true)?;
    let mut outcome = Outcome::default();
    if let Some(ctx) = &backends.gpu {
        let gpu = guarded("GpuCollision", || {
            GpuCollision::new(ctx, grid, params).and_then(|g| g.with_response(response)).map(|mut g| {
                let first = g.step(a, b);
                (first, g.step(a, b))
            })
        })?;
        let gpu = warm("GpuCollision", gpu, params.magnitude)?;
        agree("GpuCollision", &reference, &gpu, params.magnitude, backends.gpu_exact)?;
        outcome.gpu_ran = true;
    }
    match &reference {
        Ok(report) => {
            let constant = response == Response::Constant;
            invariants(report, a, b, params.magnitude, constant).map_err(|e| format!("CpuCollision: {e}"))?;
            outcome.result = "ok".into();
            outcome.contacts = report.colliding_b.len();
        }
        Err(e) => outcome.result = variant(e),
    }
    Ok(outcome)
}

type Two = (Result<ContactReport, Error>, Result<ContactReport, Error>);

/// A backend's first step, after checking that its warm second step gave the same bits.
fn warm(who: &str, steps: Result<Two, Error>, m: f32) -> Result<Result<ContactReport, Error>, String> {
    match steps {
        Ok((first, second)) => {
            agree(&format!("{who} (warm step)"), &first, &second, m, true)?;
            Ok(first)
        }
        Err(e) => Ok(Err(e)),
    }
}

/// `actual` agrees with the reference: the same error variant (and for a force overflow the same
/// accumulator and total), or the same report (forces bit for bit when `exact`).
fn agree(
    who: &str,
    expected: &Result<ContactReport, Error>,
    actual: &Result<ContactReport, Error>,
    m: f32,
    exact: bool,
) -> Result<(), String> {
    match (expected, actual) {
        (Err(e), Err(g)) => {
            if discriminant(e) != discriminant(g) {
                return Err(format!("{who}: error {g:?}, the reference's is {e:?}"));
            }
            if matches!(e, Error::ForceOverflow { .. }) && e != g {
                return Err(format!("{who}: {g:?}, the reference's is {e:?}"));
            }
            Ok(())
        }
        (Ok(_), Err(g)) => Err(format!("{who}: error {g:?} where the reference reports")),
        (Err(e), Ok(r)) => Err(format!(
            "{who}: a report ({} contacts) where the reference fails with {e:?}",
            r.colliding_b.len()
        )),
        (Ok(e), Ok(g)) => {
            if e.colliding_b != g.colliding_b {
                let first = e.colliding_b.iter().zip(&g.colliding_b).position(|(x, y)| x != y);
                return Err(format!(
                    "{who}: {} contacts where the reference has {} (first difference at {first:?})",
                    g.colliding_b.len(),
                    e.colliding_b.len()
                ));
            }
            if (e.binned_a, e.discarded_a) != (g.binned_a, g.discarded_a) {
                return Err(format!(
                    "{who}: binned/discarded {:?}, the reference's {:?}",
                    (g.binned_a, g.discarded_a),
                    (e.binned_a, e.discarded_a)
                ));
            }
            if e.grid_center.to_array().map(f32::to_bits) != g.grid_center.to_array().map(f32::to_bits) {
                return Err(format!(
                    "{who}: grid center {}, the reference's {}",
                    g.grid_center, e.grid_center
                ));
            }
            for (name, fe, fg) in [("force_a", &e.force_a, &g.force_a), ("force_b", &e.force_b, &g.force_b)] {
                if fe.len() != fg.len() {
                    return Err(format!(
                        "{who}: {name} has {} entries, the reference's {}",
                        fg.len(),
                        fe.len()
                    ));
                }
                for (i, (x, y)) in fe.iter().zip(fg).enumerate() {
                    let same = if exact {
                        x.to_array().map(f32::to_bits) == y.to_array().map(f32::to_bits)
                    } else {
                        (*x - *y).abs().max_element() <= 1e-5 * m
                    };
                    if !same {
                        return Err(format!(
                            "{who}: {name}[{i}] = {y}, the reference's {x} (exact: {exact})"
                        ));
                    }
                }
            }
            Ok(())
        }
    }
}

/// The invariants of docs/design.md §2 that a report keeps whatever its inputs.
/// `constant`: every contact's force has the magnitude `m` (the paper's response); otherwise at
/// most `m` (a penalty).
pub fn invariants(r: &ContactReport, a: &[Vec3], b: &[Vec3], m: f32, constant: bool) -> Result<(), String> {
    if r.force_a.len() != a.len() || r.force_b.len() != b.len() {
        return Err(format!(
            "lengths {} / {} for bodies of {} / {}",
            r.force_a.len(),
            r.force_b.len(),
            a.len(),
            b.len()
        ));
    }
    if r.binned_a as usize + r.discarded_a as usize != a.len() {
        return Err(format!("binned {} + discarded {} != |A| {}", r.binned_a, r.discarded_a, a.len()));
    }
    if r.binned_a as usize > a.iter().filter(|p| p.is_finite()).count() {
        return Err(format!("{} binned, more than A's finite vertices", r.binned_a));
    }
    if r.colliding_b.windows(2).any(|w| w[0] >= w[1]) {
        return Err("colliding_b is not strictly ascending".into());
    }
    if r.colliding_b.last().is_some_and(|&j| j as usize >= b.len()) {
        return Err("colliding_b out of range".into());
    }
    if !r.grid_center.is_finite() {
        return Err(format!("grid center {}", r.grid_center));
    }
    if let Some(i) = r.force_a.iter().position(|f| !f.is_finite()) {
        return Err(format!("force_a[{i}] = {} is not finite", r.force_a[i]));
    }
    let mut colliding = vec![false; b.len()];
    for &j in &r.colliding_b {
        colliding[j as usize] = true;
        if !b[j as usize].is_finite() {
            return Err(format!("B vertex {j} collides but is not finite: {}", b[j as usize]));
        }
    }
    for (j, f) in r.force_b.iter().enumerate() {
        if !f.is_finite() {
            return Err(format!("force_b[{j}] = {f} is not finite"));
        }
        if colliding[j] {
            let len = f64::from(f.x).hypot(f64::from(f.y)).hypot(f64::from(f.z));
            if constant && (len - f64::from(m)).abs() > 4e-6 * f64::from(m) {
                return Err(format!("|force_b[{j}]| = {len}, not the magnitude {m}"));
            }
            if !constant && len > f64::from(m) * (1.0 + 4e-6) {
                return Err(format!("|force_b[{j}]| = {len}, above the penalty's largest force {m}"));
            }
        } else if *f != Vec3::ZERO {
            return Err(format!("force_b[{j}] = {f} on a B vertex that does not collide"));
        }
    }
    if r.colliding_b.is_empty() && r.force_a.iter().any(|f| *f != Vec3::ZERO) {
        return Err("a force on A without a contact".into());
    }
    // Newton's third law, to the rounding: each contact's shares (at most 3) round by half a
    // fixed-point unit per component; each A total converts back to f32 with a relative 2^-24;
    // the shares -f_b / 3 sum to -f_b within a few ulps of m.
    let unit = f64::from(m) / 65536.0;
    let mut net = [0.0f64; 3];
    let mut slack = [0.0f64; 3];
    for f in r.force_a.iter().chain(&r.force_b) {
        for k in 0..3 {
            net[k] += f64::from(f[k]);
        }
    }
    for f in &r.force_a {
        for k in 0..3 {
            slack[k] += f64::from(f[k]).abs() * 2f64.powi(-23);
        }
    }
    let per_contact = 3.0 * 0.5 * unit + 4.0 * f64::from(m) * 2f64.powi(-23);
    for k in 0..3 {
        let bound = r.colliding_b.len() as f64 * per_contact + slack[k] + 1e-30;
        if net[k].abs() > bound {
            return Err(format!("net force {:?} on axis {k} beyond the rounding bound {bound}", net));
        }
    }
    Ok(())
}
