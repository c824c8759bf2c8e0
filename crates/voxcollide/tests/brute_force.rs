//! Independent brute-force check of the CPU reference (docs/design.md §2).
//!
//! Everything below re-implements docs/design.md §2 ("Semantics (normative)") from the spec alone, the
//! slow and obvious way: for every B vertex, every A vertex is looked at (no voxel hash), voxels
//! are computed here with this file's own `floor((p - origin) * inv)`, and the forces are built
//! in the f32 order the spec fixes. The result is compared with `CpuCollision` bit for bit, for
//! each of the 8 combinations of `Search` × `Direction` × `Anchor`, on seeded random inputs built
//! to reach every branch (coincident vertices, the grid center, collinear plane triples, too few
//! plane candidates, ties, non-finite and out-of-grid vertices, moved steps).

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use voxcollide::glam::{UVec3, Vec3};
use voxcollide::{
    Anchor, Collision, ContactParams, ContactReport, CpuCollision, Direction, Initializer, Search, VoxelGrid,
};

// ---------------------------------------------------------------------------------------------
// f32 arithmetic, spelled out: left to right, componentwise, no FMA.

fn add(u: Vec3, v: Vec3) -> Vec3 {
    Vec3::new(u.x + v.x, u.y + v.y, u.z + v.z)
}

fn sub(u: Vec3, v: Vec3) -> Vec3 {
    Vec3::new(u.x - v.x, u.y - v.y, u.z - v.z)
}

fn dot(u: Vec3, v: Vec3) -> f32 {
    u.x * v.x + u.y * v.y + u.z * v.z
}

fn cross(u: Vec3, v: Vec3) -> Vec3 {
    Vec3::new(u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x)
}

fn mul(s: f32, v: Vec3) -> Vec3 {
    Vec3::new(s * v.x, s * v.y, s * v.z)
}

fn div(v: Vec3, s: f32) -> Vec3 {
    Vec3::new(v.x / s, v.y / s, v.z / s)
}

fn neg(v: Vec3) -> Vec3 {
    Vec3::new(-v.x, -v.y, -v.z)
}

fn finite(p: Vec3) -> bool {
    p.x.is_finite() && p.y.is_finite() && p.z.is_finite()
}

fn comp(p: Vec3) -> [f32; 3] {
    [p.x, p.y, p.z]
}

// ---------------------------------------------------------------------------------------------
// The brute force.

/// How often the brute force went down each branch.
#[derive(Clone, Copy, Debug, Default)]
struct Counters {
    /// Colliding B vertices.
    contacts: u64,
    /// Pairwise forces with `d2 < 1e-12` (direction from the grid center, or +z).
    coincident: u64,
    /// ... of which the grid-center direction was degenerate too (+z).
    coincident_plus_z: u64,
    /// Plane-normal forces actually along a plane normal.
    plane: u64,
    /// Plane-normal fallbacks to Pairwise: fewer than three plane candidates.
    plane_fallback_few: u64,
    /// Plane-normal fallbacks to Pairwise: `|cross| < 1e-12` (collinear or repeated points).
    plane_fallback_collinear: u64,
    /// ... of which the cross product was not exactly zero.
    plane_fallback_tiny_cross: u64,
    /// Partners chosen among several candidates at the same smallest `d2` (the index tie rule).
    partner_ties: u64,
    /// A vertices binned / discarded, over all steps.
    binned_a: u64,
    discarded_a: u64,
    /// B vertices that were finite but outside the grid.
    b_outside: u64,
    /// Steps run.
    steps: u64,
}

/// The grid as placed for one step.
struct StepGrid {
    center: Vec3,
    origin: Vec3,
    inv: f32,
    dims: UVec3,
}

/// Per-axis min and max over the finite vertices, or `None`.
fn finite_bounds(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let mut out: Option<(Vec3, Vec3)> = None;
    for &p in points.iter().filter(|&&p| finite(p)) {
        out = Some(match out {
            None => (p, p),
            Some((mut lo, mut hi)) => {
                if p.x < lo.x {
                    lo.x = p.x;
                }
                if p.y < lo.y {
                    lo.y = p.y;
                }
                if p.z < lo.z {
                    lo.z = p.z;
                }
                if p.x > hi.x {
                    hi.x = p.x;
                }
                if p.y > hi.y {
                    hi.y = p.y;
                }
                if p.z > hi.z {
                    hi.z = p.z;
                }
                (lo, hi)
            }
        });
    }
    out
}

/// The center the step uses: the built one (Fixed, or FollowA with no finite A vertex), or
/// `0.5 * (lo + hi)` over A's finite vertices (FollowA).
fn step_center(grid: &VoxelGrid, anchor: Anchor, a: &[Vec3]) -> Vec3 {
    match (anchor, finite_bounds(a)) {
        (Anchor::FollowA, Some((lo, hi))) => {
            Vec3::new(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), 0.5 * (lo.z + hi.z))
        }
        _ => grid.center(),
    }
}

fn step_grid(grid: &VoxelGrid, anchor: Anchor, a: &[Vec3]) -> StepGrid {
    let center = step_center(grid, anchor, a);
    let dims = grid.dims();
    let half = grid.voxel_size() * 0.5;
    let origin = Vec3::new(
        center.x - half * dims.x as f32,
        center.y - half * dims.y as f32,
        center.z - half * dims.z as f32,
    );
    StepGrid { center, origin, inv: 1.0 / grid.voxel_size(), dims }
}

/// `floor((p - origin) * inv)` per axis, when `p` is finite and the voxel is inside.
fn voxel(g: &StepGrid, p: Vec3) -> Option<[i64; 3]> {
    if !finite(p) {
        return None;
    }
    let (p, o, d) = (comp(p), comp(g.origin), [g.dims.x, g.dims.y, g.dims.z]);
    let mut q = [0i64; 3];
    for k in 0..3 {
        let f = ((p[k] - o[k]) * g.inv).floor();
        if !(f >= 0.0 && f < d[k] as f32) {
            return None;
        }
        q[k] = f as i64;
    }
    Some(q)
}

/// `(d2, index)` order: nearer first, ties to the smaller index.
fn nearer(x: &(f32, usize), y: &(f32, usize)) -> std::cmp::Ordering {
    x.0.partial_cmp(&y.0).expect("finite d2").then(x.1.cmp(&y.1))
}

/// The Pairwise direction from A vertex `a` to B vertex `b`.
fn pairwise_dir(a: Vec3, b: Vec3, center: Vec3, ctr: &mut Counters) -> Vec3 {
    let e = sub(b, a);
    let d2 = dot(e, e);
    if d2 >= 1e-12 {
        return div(e, d2.sqrt());
    }
    ctr.coincident += 1;
    let e = sub(b, center);
    let e2 = dot(e, e);
    if e2 >= 1e-12 {
        div(e, e2.sqrt())
    } else {
        ctr.coincident_plus_z += 1;
        Vec3::new(0.0, 0.0, 1.0)
    }
}

/// One step of docs/design.md §2, O(|A|·|B|).
fn brute_force(
    grid: &VoxelGrid,
    params: &ContactParams,
    a: &[Vec3],
    b: &[Vec3],
    ctr: &mut Counters,
) -> ContactReport {
    let g = step_grid(grid, params.anchor, a);
    if g.center == grid.center() {
        // Our own origin must be the grid's (same formula, same f32 order).
        for k in 0..3 {
            assert_eq!(comp(g.origin)[k].to_bits(), comp(grid.origin())[k].to_bits(), "origin");
        }
    }
    let m = params.magnitude;
    let to_count = 65536.0f32 / m;
    let from_count = m / 65536.0f32;

    let qa: Vec<Option<[i64; 3]>> = a.iter().map(|&p| voxel(&g, p)).collect();
    let binned = qa.iter().filter(|q| q.is_some()).count();

    let mut totals = vec![[0i64; 3]; a.len()];
    let mut force_b = vec![Vec3::ZERO; b.len()];
    let mut colliding_b = Vec::new();
    let push_a = |i: usize, f: Vec3, totals: &mut Vec<[i64; 3]>| {
        for (k, fk) in comp(f).into_iter().enumerate() {
            let c = (fk * to_count).round_ties_even();
            assert!(c.abs() < 2.0e9, "a single contribution {c} would not fit i32");
            totals[i][k] += i64::from(c as i32);
        }
    };

    for (j, &pb) in b.iter().enumerate() {
        let Some(qb) = voxel(&g, pb) else {
            if finite(pb) {
                ctr.b_outside += 1;
            }
            continue;
        };
        // `search`: the candidates that decide the collision and the partner; `plane`: the
        // plane-normal candidates.
        let mut search: Vec<(f32, usize)> = Vec::new();
        let mut plane: Vec<(f32, usize)> = Vec::new();
        for (i, &pa) in a.iter().enumerate() {
            let Some(q) = qa[i] else { continue };
            if (0..3).any(|k| (q[k] - qb[k]).abs() > 1) {
                continue;
            }
            let e = sub(pb, pa);
            let d2 = dot(e, e);
            match params.search {
                Search::Voxel => {
                    if q == qb {
                        search.push((d2, i));
                    }
                    plane.push((d2, i));
                }
                Search::Neighbours { radius } => {
                    if d2 < radius * radius {
                        search.push((d2, i));
                        plane.push((d2, i));
                    }
                }
            }
        }
        if search.is_empty() {
            continue;
        }
        ctr.contacts += 1;
        colliding_b.push(j as u32);
        let partner = *search.iter().min_by(|x, y| nearer(x, y)).unwrap();
        if search.iter().filter(|c| c.0 == partner.0).count() > 1 {
            ctr.partner_ties += 1;
        }

        let mut done = false;
        if params.direction == Direction::PlaneNormal {
            plane.sort_by(nearer);
            if plane.len() < 3 {
                ctr.plane_fallback_few += 1;
            } else {
                let (i0, i1, i2) = (plane[0].1, plane[1].1, plane[2].1);
                let (a0, a1, a2) = (a[i0], a[i1], a[i2]);
                let c = cross(sub(a1, a0), sub(a2, a0));
                let len = dot(c, c).sqrt();
                if len < 1e-12 {
                    ctr.plane_fallback_collinear += 1;
                    if len > 0.0 {
                        ctr.plane_fallback_tiny_cross += 1;
                    }
                } else {
                    ctr.plane += 1;
                    let mut n = div(c, len);
                    let centroid = div(add(add(a0, a1), a2), 3.0);
                    if dot(n, sub(centroid, g.center)) < 0.0 {
                        n = neg(n);
                    }
                    let f = mul(m, n);
                    force_b[j] = f;
                    let share = div(neg(f), 3.0);
                    for i in [i0, i1, i2] {
                        push_a(i, share, &mut totals);
                    }
                    done = true;
                }
            }
        }
        if !done {
            let i = partner.1;
            let d = pairwise_dir(a[i], pb, g.center, ctr);
            let f = mul(m, d);
            force_b[j] = f;
            push_a(i, neg(f), &mut totals);
        }
    }

    let force_a = totals
        .iter()
        .map(|t| {
            let back = |c: i64| {
                assert!(i64::from(i32::MIN) <= c && c <= i64::from(i32::MAX), "overflow {c}");
                (c as i32) as f32 * from_count
            };
            Vec3::new(back(t[0]), back(t[1]), back(t[2]))
        })
        .collect();

    ctr.steps += 1;
    ctr.binned_a += binned as u64;
    ctr.discarded_a += (a.len() - binned) as u64;
    ContactReport {
        force_a,
        force_b,
        colliding_b,
        binned_a: binned as u32,
        discarded_a: (a.len() - binned) as u32,
        grid_center: g.center,
    }
}

// ---------------------------------------------------------------------------------------------
// Bit-for-bit comparison.

fn vec_bits_differ(x: Vec3, y: Vec3) -> Option<&'static str> {
    if x.x.to_bits() != y.x.to_bits() {
        Some("x")
    } else if x.y.to_bits() != y.y.to_bits() {
        Some("y")
    } else if x.z.to_bits() != y.z.to_bits() {
        Some("z")
    } else {
        None
    }
}

fn assert_vecs_bits(ctx: &str, field: &str, expected: &[Vec3], actual: &[Vec3]) {
    assert_eq!(expected.len(), actual.len(), "{ctx}: {field}.len() differs");
    for (i, (&e, &a)) in expected.iter().zip(actual).enumerate() {
        if let Some(axis) = vec_bits_differ(e, a) {
            panic!(
                "{ctx}: {field}[{i}].{axis} differs: brute force {e:?} (bits {:?}), \
                 CpuCollision {a:?} (bits {:?})",
                comp(e).map(f32::to_bits),
                comp(a).map(f32::to_bits),
            );
        }
    }
}

fn assert_reports_bits(ctx: &str, expected: &ContactReport, actual: &ContactReport) {
    if expected.colliding_b != actual.colliding_b {
        let first = expected
            .colliding_b
            .iter()
            .zip(&actual.colliding_b)
            .position(|(e, a)| e != a)
            .unwrap_or(expected.colliding_b.len().min(actual.colliding_b.len()));
        panic!(
            "{ctx}: colliding_b differs at position {first}: brute force {:?}, CpuCollision {:?} \
             (lengths {} vs {})",
            expected.colliding_b.get(first),
            actual.colliding_b.get(first),
            expected.colliding_b.len(),
            actual.colliding_b.len(),
        );
    }
    assert_eq!(expected.binned_a, actual.binned_a, "{ctx}: binned_a differs");
    assert_eq!(expected.discarded_a, actual.discarded_a, "{ctx}: discarded_a differs");
    if let Some(axis) = vec_bits_differ(expected.grid_center, actual.grid_center) {
        panic!(
            "{ctx}: grid_center.{axis} differs: brute force {:?}, CpuCollision {:?}",
            expected.grid_center, actual.grid_center
        );
    }
    assert_vecs_bits(ctx, "force_b", &expected.force_b, &actual.force_b);
    assert_vecs_bits(ctx, "force_a", &expected.force_a, &actual.force_a);
}

// ---------------------------------------------------------------------------------------------
// Inputs.

/// One seeded scenario: a built grid and a few steps run on one `CpuCollision`.
struct Case {
    label: String,
    grid: VoxelGrid,
    magnitude: f32,
    /// The neighbour radius as a fraction of the voxel size (1.0: radius == voxel size).
    radius_factor: f32,
    steps: Vec<(Vec<Vec3>, Vec<Vec3>)>,
}

const SEEDS: u64 = 16;

fn shuffle<T>(v: &mut [T], rng: &mut ChaCha8Rng) {
    for i in (1..v.len()).rev() {
        let j = rng.random_range(0..=i);
        v.swap(i, j);
    }
}

fn uniform(rng: &mut ChaCha8Rng, lo: Vec3, hi: Vec3) -> Vec3 {
    Vec3::new(rng.random_range(lo.x..hi.x), rng.random_range(lo.y..hi.y), rng.random_range(lo.z..hi.z))
}

fn axis_vec(axis: usize, len: f32) -> Vec3 {
    let mut v = Vec3::ZERO;
    v[axis] = len;
    v
}

/// The next f32 up from `x` (one ulp).
fn next_up(x: f32) -> f32 {
    if x >= 0.0 { f32::from_bits(x.to_bits() + 1) } else { f32::from_bits(x.to_bits() - 1) }
}

/// Adds to `a` an A vertex exactly at `center` and a collinear pair beyond it along x, and to
/// `b` B vertices at `center` and one ulp off it (coincident with A and with the grid center:
/// the `+z` branch).
fn add_center_specials(a: &mut Vec<Vec3>, b: &mut Vec<Vec3>, center: Vec3, vs: f32) {
    let h = 0.03 * vs;
    a.push(center);
    a.push(add(center, axis_vec(0, h)));
    a.push(add(center, axis_vec(0, 2.0 * h)));
    b.push(center);
    // One ulp off the center: near a small center both `d2` and `|b - center|^2` are tiny but
    // not zero (still the +z branch); near a large one they pass 1e-12.
    b.push(Vec3::new(next_up(center.x), center.y, center.z));
}

/// The dense core of a case: A and B overlapping in a small box, with collinear triples,
/// symmetric ties, duplicates, coincident and near-coincident B vertices, an outpost of two A
/// vertices far from the rest (fewer than three plane candidates), non-finite vertices.
fn bodies(rng: &mut ChaCha8Rng, base: Vec3, half: f32, vs: f32) -> (Vec<Vec3>, Vec<Vec3>) {
    let lo = sub(base, Vec3::splat(half));
    let hi = add(base, Vec3::splat(half));
    let n_a = rng.random_range(50..=320);
    let n_b = rng.random_range(50..=320);
    let mut a: Vec<Vec3> = (0..n_a).map(|_| uniform(rng, lo, hi)).collect();
    // B spills out of the box, some of it out of any grid.
    let (blo, bhi) = (sub(base, Vec3::splat(1.7 * half)), add(base, Vec3::splat(1.7 * half)));
    let mut b: Vec<Vec3> = (0..n_b).map(|_| uniform(rng, blo, bhi)).collect();
    let inner = |rng: &mut ChaCha8Rng| {
        uniform(rng, sub(base, Vec3::splat(0.8 * half)), add(base, Vec3::splat(0.8 * half)))
    };

    // Collinear triples along an axis: the cross product is exactly zero.
    for t in 0..4 {
        let p0 = inner(rng);
        let axis = rng.random_range(0..3usize);
        let h = 0.03 * vs;
        a.extend([p0, add(p0, axis_vec(axis, h)), add(p0, axis_vec(axis, 2.0 * h))]);
        // B exactly on p0 (coincident and collinear) or just before it on the same line.
        b.push(if t % 2 == 0 { p0 } else { sub(p0, axis_vec(axis, 0.01 * vs)) });
    }
    // Nearly collinear: where the box reaches y = 0, a triple whose cross product is tiny but
    // not zero (|cross| < 1e-12 still falls back).
    if (base.y - 0.8 * half) < 0.0 && 0.0 < (base.y + 0.8 * half) {
        let p = inner(rng);
        let h = 0.03 * vs;
        let p0 = Vec3::new(p.x, 1e-20, p.z);
        a.extend([p0, add(p0, axis_vec(0, h)), add(p0, Vec3::new(2.0 * h, 1e-15, 0.0))]);
        b.push(sub(p0, axis_vec(0, 0.01 * vs)));
    }
    // Symmetric ties: four A vertices at exactly the same distance from a B vertex.
    for _ in 0..3 {
        let q = vs / 64.0;
        let p = inner(rng);
        let c = Vec3::new((p.x / q).round() * q, (p.y / q).round() * q, (p.z / q).round() * q);
        let t = vs / 16.0;
        a.extend([
            add(c, axis_vec(0, t)),
            sub(c, axis_vec(0, t)),
            add(c, axis_vec(1, t)),
            sub(c, axis_vec(1, t)),
        ]);
        b.push(c);
    }
    // Duplicated A vertices (ties at d2 = 0 when a B vertex sits on them).
    for _ in 0..5 {
        let i = rng.random_range(0..n_a);
        a.push(a[i]);
        b.push(a[i]);
    }
    // Coincident (d2 = 0) and near-coincident (one ulp) B vertices.
    for _ in 0..8 {
        let i = rng.random_range(0..n_a);
        b.push(a[i]);
    }
    for _ in 0..6 {
        let i = rng.random_range(0..n_a);
        let mut p = a[i];
        let axis = rng.random_range(0..3usize);
        p[axis] = next_up(p[axis]);
        b.push(p);
    }
    // B vertices near (within radius 0.35 * vs of) random A vertices.
    for _ in 0..20 {
        let i = rng.random_range(0..n_a);
        let off = uniform(rng, Vec3::splat(-0.15 * vs), Vec3::splat(0.15 * vs));
        b.push(add(a[i], off));
    }
    // An outpost: two A vertices with no other A vertex within two voxels, and B vertices on
    // them: at most two plane candidates.
    let outpost = add(base, Vec3::new(half + 2.5 * vs, 0.3 * half, -0.2 * half));
    a.extend([outpost, add(outpost, Vec3::new(0.1 * vs, 0.0, 0.0))]);
    b.extend([
        add(outpost, Vec3::new(0.02 * vs, 0.03 * vs, 0.01 * vs)),
        add(outpost, Vec3::new(0.12 * vs, -0.02 * vs, 0.0)),
        outpost,
    ]);
    // Non-finite vertices in both bodies.
    let nan = f32::NAN;
    let inf = f32::INFINITY;
    for (k, bad) in [
        Vec3::new(nan, 0.25, 0.5),
        Vec3::new(base.x, inf, base.z),
        Vec3::new(base.x, base.y, -inf),
        Vec3::splat(nan),
    ]
    .into_iter()
    .enumerate()
    {
        let i = rng.random_range(0..n_a);
        a[i] = bad;
        let j = rng.random_range(0..n_b);
        b[j] = if k == 1 { Vec3::new(inf, -inf, nan) } else { bad };
    }
    (a, b)
}

/// Seed `seed`'s scenario, with the center specials placed for `anchor`.
fn make_case(seed: u64, anchor: Anchor) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(0xB0F0_5EED_0000 + seed);
    let vs = [0.5f32, 1.0, 2.0][(seed % 3) as usize];
    let magnitude = [1.0f32, 3.7, 1e-3][((seed / 3) % 3) as usize];
    let radius_factor = [1.0f32, 0.6, 1.0, 0.35][(seed % 4) as usize];
    let negative = (seed / 2) % 2 == 1;
    let base = if negative {
        uniform(&mut rng, Vec3::splat(-60.0), Vec3::splat(-20.0))
    } else {
        uniform(&mut rng, Vec3::splat(-2.0), Vec3::splat(2.0))
    };
    let k = rng.random_range(3..=5) as f32;
    let half = 0.5 * k * vs;
    let (mut a0, mut b0) = bodies(&mut rng, base, half, vs);

    // The grid: smaller than A so that some A vertices are discarded, but reaching the outpost.
    let explicit = seed % 2 == 1;
    let grid = if explicit {
        let x_lo = base.x - 0.5 * half;
        let x_hi = base.x + half + 3.5 * vs;
        let dims = UVec3::new(
            ((x_hi - x_lo) / vs).ceil() as u32,
            rng.random_range(2..=(k as u32 - 1)),
            rng.random_range(2..=(k as u32 + 1)),
        );
        let jitter = uniform(&mut rng, Vec3::splat(-0.3 * vs), Vec3::splat(0.3 * vs));
        let center = add(Vec3::new(0.5 * (x_lo + x_hi), base.y, base.z), jitter);
        VoxelGrid::new(center, vs, dims).expect("grid")
    } else {
        // The A vertices away from the -x side (the outpost included): the cube misses the
        // rest of that side.
        let subset: Vec<Vec3> =
            a0.iter().copied().filter(|p| finite(*p) && p.x > base.x - 0.2 * half).collect();
        Initializer::new(vs).margin(0).build(&subset).expect("grid")
    };

    let center0 = step_center(&grid, anchor, &a0);
    add_center_specials(&mut a0, &mut b0, center0, vs);
    shuffle(&mut a0, &mut rng);
    shuffle(&mut b0, &mut rng);
    assert_eq!(step_center(&grid, anchor, &a0), center0, "center specials moved the center");

    // A moved step: A translated (some vertices jittered too), most of B with it.
    let off = uniform(&mut rng, Vec3::splat(-2.5 * vs), Vec3::splat(2.5 * vs));
    let mut a1: Vec<Vec3> = a0
        .iter()
        .map(|&p| {
            let p = add(p, off);
            if rng.random::<f32>() < 0.2 {
                add(p, uniform(&mut rng, Vec3::splat(-0.1 * vs), Vec3::splat(0.1 * vs)))
            } else {
                p
            }
        })
        .collect();
    let mut b1: Vec<Vec3> =
        b0.iter().map(|&p| if rng.random::<f32>() < 0.8 { add(p, off) } else { p }).collect();
    let center1 = step_center(&grid, anchor, &a1);
    add_center_specials(&mut a1, &mut b1, center1, vs);
    shuffle(&mut a1, &mut rng);
    shuffle(&mut b1, &mut rng);
    assert_eq!(step_center(&grid, anchor, &a1), center1, "center specials moved the center");

    // A step where A has no finite vertex at all: FollowA keeps the built grid.
    let a2 = vec![
        Vec3::splat(f32::NAN),
        Vec3::new(f32::INFINITY, 0.0, 0.0),
        Vec3::new(base.x, f32::NEG_INFINITY, base.z),
    ];

    let label = format!(
        "seed {seed}: vs {vs}, magnitude {magnitude}, radius {radius_factor} * vs, base {base}, \
         {} grid center {} dims {}",
        if explicit { "explicit" } else { "initializer" },
        grid.center(),
        grid.dims()
    );
    Case {
        label,
        grid,
        magnitude,
        radius_factor,
        steps: vec![(a0.clone(), b0.clone()), (a1, b1), (a2, b0.clone()), (a0, b0)],
    }
}

// ---------------------------------------------------------------------------------------------
// The driver.

fn check(search_kind: &str, direction: Direction, anchor: Anchor) -> Counters {
    let mut ctr = Counters::default();
    for seed in 0..SEEDS {
        let case = make_case(seed, anchor);
        let search = match search_kind {
            "voxel" => Search::Voxel,
            _ => Search::Neighbours { radius: case.radius_factor * case.grid.voxel_size() },
        };
        let params = ContactParams { magnitude: case.magnitude, search, direction, anchor };
        let mut cpu = CpuCollision::new(case.grid, params).expect("CpuCollision::new");
        for (s, (a, b)) in case.steps.iter().enumerate() {
            let ctx = format!("{:?}, {}, step {s} (|A| {}, |B| {})", params, case.label, a.len(), b.len());
            let expected = brute_force(&case.grid, &params, a, b, &mut ctr);
            let actual = cpu.step(a, b).unwrap_or_else(|e| panic!("{ctx}: step failed: {e}"));
            assert_reports_bits(&ctx, &expected, &actual);
            if s == 0 {
                assert!(!expected.colliding_b.is_empty(), "{ctx}: no contact at all");
                let non_finite = a.iter().filter(|p| !finite(**p)).count() as u32;
                assert!(expected.discarded_a > non_finite, "{ctx}: no finite A vertex discarded");
            }
        }
    }
    eprintln!("{search_kind} {direction:?} {anchor:?}: {ctr:?}");
    assert!(ctr.contacts >= 100 * SEEDS, "too few contacts: {ctr:?}");
    assert!(ctr.b_outside > 0, "no B vertex outside the grid: {ctr:?}");
    assert!(ctr.partner_ties > 0, "the partner tie rule was never exercised: {ctr:?}");
    // Coincident contacts reach the Pairwise rule directly, or through the plane fallback.
    assert!(ctr.coincident > 0, "coincident branch never taken: {ctr:?}");
    assert!(ctr.coincident_plus_z > 0, "+z branch never taken: {ctr:?}");
    if direction == Direction::PlaneNormal {
        assert!(ctr.plane > 0, "plane branch never taken: {ctr:?}");
        assert!(ctr.plane_fallback_few > 0, "too-few-candidates fallback never taken: {ctr:?}");
        assert!(ctr.plane_fallback_collinear > 0, "collinear fallback never taken: {ctr:?}");
        assert!(ctr.plane_fallback_tiny_cross > 0, "0 < |cross| < 1e-12 never seen: {ctr:?}");
    }
    ctr
}

#[test]
fn brute_force_matches_reference_voxel_pairwise_fixed() {
    check("voxel", Direction::Pairwise, Anchor::Fixed);
}

#[test]
fn brute_force_matches_reference_voxel_pairwise_follow_a() {
    check("voxel", Direction::Pairwise, Anchor::FollowA);
}

#[test]
fn brute_force_matches_reference_voxel_plane_normal_fixed() {
    check("voxel", Direction::PlaneNormal, Anchor::Fixed);
}

#[test]
fn brute_force_matches_reference_voxel_plane_normal_follow_a() {
    check("voxel", Direction::PlaneNormal, Anchor::FollowA);
}

#[test]
fn brute_force_matches_reference_neighbours_pairwise_fixed() {
    check("neighbours", Direction::Pairwise, Anchor::Fixed);
}

#[test]
fn brute_force_matches_reference_neighbours_pairwise_follow_a() {
    check("neighbours", Direction::Pairwise, Anchor::FollowA);
}

#[test]
fn brute_force_matches_reference_neighbours_plane_normal_fixed() {
    check("neighbours", Direction::PlaneNormal, Anchor::Fixed);
}

#[test]
fn brute_force_matches_reference_neighbours_plane_normal_follow_a() {
    check("neighbours", Direction::PlaneNormal, Anchor::FollowA);
}
