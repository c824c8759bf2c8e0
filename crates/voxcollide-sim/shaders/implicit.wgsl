// The implicit integrator's passes (docs/design.md §12, `integrator = "implicit"`) for a world of
// bodies of springs or tetrahedra, with the voxel model's contacts (their `k·nnᵀ` in
// SLOT_KC0/1) or a surface contact's couplings (their terms gathered into SLOT_C by
// couple_gather.wgsl, their own blocks in SLOT_E0/1 from the host): backward Euler
// linearised once per step and solved matrix-free by a block-Jacobi preconditioned conjugate
// gradient over every body at once, as the CPU does it (src/implicit.rs,
// `integrate_implicit_together`), term by term. One shader, built once per pass with the
// pipeline-overridable constant `PASS`; every pass shares one binding layout.
//
// Every per-vertex vector of a body's solve lives in its `work`, `n` entries per slot (SLOT_*).
// Dot products are summed per workgroup (a tree over its 64 lanes) into `red`'s columns of
// `groups` partials, and the partials by one workgroup (PASS_SCALARS_*) into `red`'s scalars: a
// fixed order, so the same answer every time on one device (not the CPU's `f64` sums: the two
// agree to the solve's tolerance, not bit for bit). `red` is the world's: each body's partials
// are its range of every column (from `base`, `own` of them), so the solve's scalars (S_*) are
// the joint system's; a body's own (B_*: its fill's products, its residual) follow them.

override PASS: u32;

const PASS_PREPARE: u32 = 0u;       // forces, floor rows, fill gradient, held Δv, residual terms
const PASS_FLOOR: u32 = 1u;         // floor rows' vertical speed to 0; g·v and g·Δv_held
const PASS_RHS: u32 = 2u;           // K·v, A·Δv_held, the right-hand side, the preconditioner, the guess
const PASS_GUESS: u32 = 3u;         // b − A·x from the guess
const PASS_START: u32 = 4u;         // r, z = P·r, p = z
const PASS_GP: u32 = 5u;            // g·p (a fill's rank-one term)
const PASS_APPLY: u32 = 6u;         // A·p and p·A·p
const PASS_UPDATE: u32 = 7u;        // x += α·p, r −= α·A·p, z = P·r, r·r, r·z
const PASS_DIRECTION: u32 = 8u;     // p = z + β·p
const PASS_FARTHEST: u32 = 9u;      // the new velocity and the farthest move
const PASS_MOVE: u32 = 10u;         // the update, the modes, the floor, the contacts' inelastic push
const PASS_TANGENT: u32 = 11u;      // per tetrahedron: its projected stiffness at the step's start
const PASS_PRODUCT_RHS: u32 = 12u;  // per tetrahedron: its −K·v and −K·Δv_held
const PASS_PRODUCT_P: u32 = 13u;    // per tetrahedron: its −K·p
const PASS_PRODUCT_X: u32 = 14u;    // per tetrahedron: its −K·x (the guess)
const PASS_SCALARS_A: u32 = 20u;    // g·v, g·Δv_held, the residual's sums
const PASS_SCALARS_B: u32 = 21u;    // |b|, |b − A·x|, whether the guess is used
const PASS_SCALARS_C: u32 = 22u;    // r·z at the start
const PASS_SCALARS_GP: u32 = 23u;   // g·p
const PASS_SCALARS_ALPHA: u32 = 24u; // α, or done
const PASS_SCALARS_BETA: u32 = 25u; // β, |r|, the iteration count
const PASS_SCALARS_FAR: u32 = 26u;  // the farthest move

// The slots of `work` (SLOT_*) are implicit_slots.wgsl's.

const COL_GP: u32 = 0u;
const COL_PAP: u32 = 1u;
const COL_RR: u32 = 2u;
const COL_RZ: u32 = 3u;
const COL_NET: u32 = 4u;
const COL_GROSS: u32 = 5u;
const COL_FAR: u32 = 6u;
const COL_LEFT: u32 = 7u;
const COLUMNS: u32 = 8u;

// The joint solve's scalars (slots 0–2 and 10–11 unused: a body's own below).
const S_ALPHA: u32 = 3u;
const S_BETA: u32 = 4u;
const S_RR: u32 = 5u;
const S_RZ: u32 = 6u;
const S_DONE: u32 = 7u;
const S_ITERATIONS: u32 = 8u;
const S_NORM_B2: u32 = 9u;
const S_FARTHEST: u32 = 12u;
const S_LEFT2: u32 = 13u;
const S_USE_GUESS: u32 = 14u;
const S_TARGET: u32 = 15u;
const SCALARS: u32 = 16u;
// Each body's own scalars, after the joint ones (`BODY_SCALARS` per body).
const B_GV: u32 = 0u;
const B_GHELD: u32 = 1u;
const B_GP: u32 = 2u;
const B_NET2: u32 = 3u;
const B_GROSS2: u32 = 4u;
const BODY_SCALARS: u32 = 8u;

// Per tetrahedron in `tet_work`: its Tangent (9), then two products (3 each).
const TET_WORK: u32 = 15u;
const TET_PRODUCT: u32 = 9u;

// Keep in sync with GpuImplicitParams in src/gpu_implicit.rs.
struct ImplicitParams {
    h: f32,
    fill_k: f32,             // B / V* (0: no fill)
    guess_scale: f32,        // h / the last step's h (0: no guess)
    tolerance: f32,
    scale: f32,              // the velocity's scale (PASS_MOVE)
    max_iterations: f32,
    groups: u32,             // partials per column, over every body
    base: u32,               // this body's first partial in each column
    own: u32,                // this body's partials
    body: u32,               // this body's index (its own scalars)
    bodies: u32,
    coupled: u32,            // 1: a surface contact couples this body (SLOT_C, SLOT_E0/1)
}

@group(0) @binding(0) var<uniform> sim: SimParams;
@group(0) @binding(1) var<uniform> ip: ImplicitParams;
@group(0) @binding(2) var<storage, read_write> pos: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> vel: array<vec4<f32>>;     // w: 1 / mass
@group(0) @binding(4) var<storage, read> info: array<vec4<f32>>;          // xyz: rest, w: mode
@group(0) @binding(5) var<storage, read> offsets: array<vec2<u32>>;
@group(0) @binding(6) var<storage, read> adjacency: array<u32>;
@group(0) @binding(7) var<storage, read> springs: array<vec2<f32>>;       // (rest, k)
@group(0) @binding(8) var<storage, read> triangles: array<vec4<u32>>;
@group(0) @binding(9) var<storage, read> contact: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> fill: array<f32>;                // [0]: the fill's pressure
@group(0) @binding(11) var<storage, read_write> work: array<vec4<f32>>;
@group(0) @binding(12) var<storage, read_write> red: array<f32>;
@group(0) @binding(13) var<storage, read_write> status: array<atomic<u32>, 2>;
@group(0) @binding(14) var<storage, read> tet_index: array<u32>;          // elements.wgsl
@group(0) @binding(15) var<storage, read> tet_rest: array<vec4<f32>>;
@group(0) @binding(16) var<storage, read_write> tet_work: array<vec4<f32>>;
@group(0) @binding(17) var<storage, read> mass: array<f32>;                // what gravity pulls

var<workgroup> lanes: array<f32, 64>;

fn slot(s: u32, i: u32) -> u32 {
    return s * sim.n + i;
}

fn vget(s: u32, i: u32) -> vec3<f32> {
    return work[slot(s, i)].xyz;
}

fn vput(s: u32, i: u32, v: vec3<f32>) {
    work[slot(s, i)] = vec4<f32>(v, 0.0);
}

// `red` holds the joint scalars first (read back from offset 0), then each body's own, then
// the columns of partials.
fn scalar(k: u32) -> f32 {
    return red[k];
}

fn set_scalar(k: u32, v: f32) {
    red[k] = v;
}

fn body_scalar(k: u32) -> f32 {
    return red[SCALARS + BODY_SCALARS * ip.body + k];
}

fn set_body_scalar(k: u32, v: f32) {
    red[SCALARS + BODY_SCALARS * ip.body + k] = v;
}

// Partial `j` of a column, counted over every body.
fn part_at(column: u32, j: u32) -> u32 {
    return SCALARS + BODY_SCALARS * ip.bodies + column * ip.groups + j;
}

// This body's workgroup `wg`'s partial.
fn part(column: u32, wg: u32) -> u32 {
    return part_at(column, ip.base + wg);
}

fn is_free(i: u32) -> bool {
    return u32(info[i].w) == MODE_FREE;
}

fn on_floor(i: u32) -> bool {
    return work[slot(SLOT_F, i)].w != 0.0;
}

// The floor's rows are not solved for (the CPU's `Joint::filter`).
fn filtered(i: u32, v: vec3<f32>) -> vec3<f32> {
    if on_floor(i) {
        return vec3<f32>(v.x, v.y, 0.0);
    }
    return v;
}

// `value` over the workgroup's lanes, summed (or the largest, `maximum`) pairwise, halving:
// the total, on every lane (all lanes call it, in uniform control flow).
fn lanes_total(lane: u32, value: f32, maximum: bool) -> f32 {
    lanes[lane] = value;
    workgroupBarrier();
    for (var half = 32u; half > 0u; half /= 2u) {
        if lane < half {
            if maximum {
                lanes[lane] = max(lanes[lane], lanes[lane + half]);
            } else {
                lanes[lane] += lanes[lane + half];
            }
        }
        workgroupBarrier();
    }
    let total = lanes[0];
    workgroupBarrier();
    return total;
}

// Sums `value` over the workgroup into its partial of `column`.
fn partial_sum(column: u32, wg: u32, lane: u32, value: f32) {
    let total = lanes_total(lane, value, false);
    if lane == 0u {
        red[part(column, wg)] = total;
    }
}

// The largest `value` over the workgroup, into its partial of `column`.
fn partial_max(column: u32, wg: u32, lane: u32, value: f32) {
    let total = lanes_total(lane, value, true);
    if lane == 0u {
        red[part(column, wg)] = total;
    }
}

// A column's partials over every body summed by one workgroup (lane j takes partials j,
// j + 64, …, then the lanes pairwise): the total, on every lane.
fn column_sum(column: u32, lane: u32) -> f32 {
    var s = 0.0;
    for (var j = lane; j < ip.groups; j += 64u) {
        s += red[part_at(column, j)];
    }
    return lanes_total(lane, s, false);
}

// This body's partials of a column alone, summed as above.
fn own_sum(column: u32, lane: u32) -> f32 {
    var s = 0.0;
    for (var j = lane; j < ip.own; j += 64u) {
        s += red[part(column, j)];
    }
    return lanes_total(lane, s, false);
}

// The largest of a column's partials over every body.
fn column_max(column: u32, lane: u32) -> f32 {
    var s = 0.0;
    for (var j = lane; j < ip.groups; j += 64u) {
        s = max(s, red[part_at(column, j)]);
    }
    return lanes_total(lane, s, true);
}

// A spring's blocks at the start of the step, from vertex i to j: its direction and
// (across, along): `−K`'s block is across·I + along·uuᵀ (CPU: MassSpring::system).
struct Blocks {
    u: vec3<f32>,
    across: f32,
    along: f32,
}

fn blocks(i: u32, j: u32, s: vec2<f32>) -> Blocks {
    let d = pos[j].xyz - pos[i].xyz;
    let len = sqrt(dot3(d, d));
    if len < 1e-12 {
        return Blocks(vec3<f32>(0.0), 0.0, 0.0);
    }
    let u = d / len;
    let rest = s.x * sim.rest_scale;
    let tension = spring_tension_at(len, rest, s.y);
    let tangent = spring_tangent_at(len, rest, s.y);
    let across = max(tension, 0.0) / len;
    return Blocks(u, across, tangent - across);
}

fn outer(u: vec3<f32>) -> mat3x3<f32> {
    return mat3x3<f32>(u * u.x, u * u.y, u * u.z);
}

fn symmetric(s0: u32, s1: u32, i: u32) -> mat3x3<f32> {
    let a = work[slot(s0, i)];
    let b = work[slot(s1, i)];
    return mat3x3<f32>(vec3<f32>(a.x, a.w, b.x), vec3<f32>(a.w, a.y, b.y), vec3<f32>(b.x, b.y, a.z));
}

fn contact_k(i: u32) -> mat3x3<f32> {
    return symmetric(SLOT_KC0, SLOT_KC1, i);
}

// The couplings' terms gathered at vertex i (0 where no surface contact couples the body).
fn coupling(i: u32) -> vec3<f32> {
    if ip.coupled != 0u {
        return vget(SLOT_C, i);
    }
    return vec3<f32>(0.0);
}

// The contacts' critical damping along their push: 2·√(m/k)·kc with k = trace(kc).
fn contact_damping(i: u32, kc: mat3x3<f32>) -> mat3x3<f32> {
    let k = kc[0].x + kc[1].y + kc[2].z;
    if k > 0.0 {
        return (2.0 * sqrt(1.0 / (vel[i].w * k))) * kc;
    }
    return mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
}

// `A·u` on free row i (`A = M − h·D − h²·K`), `gu` = g·u; or `−K·u` on any row when `stiff`.
fn apply_row(i: u32, s_u: u32, gu: f32, stiff: bool) -> vec3<f32> {
    let h = ip.h;
    let ui = vget(s_u, i);
    var r = vec3<f32>(0.0);
    if !stiff {
        r = (1.0 / vel[i].w + h * sim.damping) * ui;
    }
    let range = vec2<u32>(offsets[i].x, offsets[i + 1u].x);
    for (var e = range.x; e < range.y; e++) {
        let j = adjacency[2u * e];
        let b = blocks(i, j, springs[adjacency[2u * e + 1u]]);
        var a = b.across;
        var c = b.along;
        if !stiff {
            a = h * h * b.across;
            c = h * h * b.along + h * sim.spring_damping;
        }
        let d = ui - vget(s_u, j);
        r += a * d + (c * dot3(b.u, d)) * b.u;
    }
    let kc = contact_k(i);
    if stiff {
        r += kc * ui;
    } else {
        r += (h * h * kc + h * contact_damping(i, kc)) * ui;
    }
    if sim.tets > 0u {
        // The tetrahedra's −K·u, their products made per tetrahedron by PASS_PRODUCT_*.
        var h2 = h * h;
        if stiff {
            h2 = 1.0;
        }
        r += h2 * gather_product(i, 0u);
    }
    if ip.fill_k > 0.0 {
        var h2 = h * h;
        if stiff {
            h2 = 1.0;
        }
        r += (h2 * ip.fill_k * gu) * vget(SLOT_G, i);
    }
    return r;
}

fn inverse3(m: mat3x3<f32>) -> mat3x3<f32> {
    // glam's Mat3::inverse: the columns' cross products over the determinant, transposed.
    let t0 = cross3(m[1], m[2]);
    let t1 = cross3(m[2], m[0]);
    let t2 = cross3(m[0], m[1]);
    let inv_det = 1.0 / dot3(m[2], t2);
    return transpose(mat3x3<f32>(t0, t1, t2)) * inv_det;
}

fn finite3(v: vec3<f32>) -> bool {
    return is_finite_f32(v.x) && is_finite_f32(v.y) && is_finite_f32(v.z);
}

fn store_tangent(k: u32, t: Tangent) {
    let b = TET_WORK * k;
    tet_work[b] = vec4<f32>(t.u[0], t.a.x);
    tet_work[b + 1u] = vec4<f32>(t.u[1], t.a.y);
    tet_work[b + 2u] = vec4<f32>(t.u[2], t.a.z);
    tet_work[b + 3u] = vec4<f32>(t.w[0], t.b.x);
    tet_work[b + 4u] = vec4<f32>(t.w[1], t.b.y);
    tet_work[b + 5u] = vec4<f32>(t.w[2], t.b.z);
    tet_work[b + 6u] = vec4<f32>(t.stretch[0], 0.0);
    tet_work[b + 7u] = vec4<f32>(t.stretch[1], 0.0);
    tet_work[b + 8u] = vec4<f32>(t.stretch[2], 0.0);
}

fn load_tangent(k: u32) -> Tangent {
    let b = TET_WORK * k;
    let w = array<vec4<f32>, 9>(
        tet_work[b], tet_work[b + 1u], tet_work[b + 2u], tet_work[b + 3u], tet_work[b + 4u],
        tet_work[b + 5u], tet_work[b + 6u], tet_work[b + 7u], tet_work[b + 8u],
    );
    return Tangent(
        mat3x3<f32>(w[0].xyz, w[1].xyz, w[2].xyz),
        mat3x3<f32>(w[3].xyz, w[4].xyz, w[5].xyz),
        mat3x3<f32>(w[6].xyz, w[7].xyz, w[8].xyz),
        vec3<f32>(w[0].w, w[1].w, w[2].w),
        vec3<f32>(w[3].w, w[4].w, w[5].w),
    );
}

// Product `which` (0 or 1) of tetrahedron k.
fn store_product(k: u32, which: u32, m: mat3x3<f32>) {
    let b = TET_WORK * k + TET_PRODUCT + 3u * which;
    tet_work[b] = vec4<f32>(m[0], 0.0);
    tet_work[b + 1u] = vec4<f32>(m[1], 0.0);
    tet_work[b + 2u] = vec4<f32>(m[2], 0.0);
}

// Vertex i's share of its tetrahedra's products `which`, in adjacency order: their −K·u.
fn gather_product(i: u32, which: u32) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    let range = tet_range(i);
    for (var e = range.x; e < range.y; e++) {
        let kc = tet_index[e];
        let b = TET_WORK * (kc / 4u) + TET_PRODUCT + 3u * which;
        let h = mat3x3<f32>(tet_work[b].xyz, tet_work[b + 1u].xyz, tet_work[b + 2u].xyz);
        sum += corner_of(h, kc % 4u);
    }
    return sum;
}

// The per-tetrahedron passes.
fn pass_tetrahedron(k: u32) {
    let t = tet_corners(k);
    if PASS == PASS_TANGENT {
        store_tangent(k, tangent_at(deformation(k, pos[t.x].xyz, pos[t.y].xyz, pos[t.z].xyz, pos[t.w].xyz), k));
        return;
    }
    let tangent = load_tangent(k);
    if PASS == PASS_PRODUCT_RHS {
        store_product(k, 0u, stiffness_product(tangent, vel[t.x].xyz, vel[t.y].xyz, vel[t.z].xyz, vel[t.w].xyz));
        store_product(k, 1u, stiffness_product(
            tangent, vget(SLOT_HELD, t.x), vget(SLOT_HELD, t.y), vget(SLOT_HELD, t.z), vget(SLOT_HELD, t.w)));
    } else {
        var s = SLOT_P;
        if PASS == PASS_PRODUCT_X {
            s = SLOT_X;
        }
        store_product(k, 0u, stiffness_product(tangent, vget(s, t.x), vget(s, t.y), vget(s, t.z), vget(s, t.w)));
    }
}

fn pass_prepare(i: u32) -> vec2<f32> {
    let x = pos[i].xyz;
    let v = vel[i].xyz;
    let free = is_free(i);
    var pressure = sim.pressure;
    if sim.fill_volume > 0.0 {
        pressure = fill[0];
    }
    // The forces (CPU: MassSpring::forces), and the residual's at rest (MassSpring::residual).
    var f = contact[i].xyz - sim.damping * v;
    var rest_f = contact[i].xyz;
    var gross = sqrt(dot3(contact[i].xyz, contact[i].xyz));
    var outside = gross;      // contact, pressure and weight: the loads (under gravity)
    let range = vec2<u32>(offsets[i].x, offsets[i + 1u].x);
    for (var e = range.x; e < range.y; e++) {
        let j = adjacency[2u * e];
        let s = springs[adjacency[2u * e + 1u]];
        let y = pos[j].xyz;
        f += spring_force(x, v, y, vel[j].xyz, s.x * sim.rest_scale, s.y);
        let t = spring_tension(x, y, s);
        rest_f += t;
        gross += sqrt(dot3(t, t));
    }
    if sim.tets > 0u {
        var fe = vec3<f32>(0.0);
        let tets = tet_range(i);
        for (var e = tets.x; e < tets.y; e++) {
            let kc = tet_index[e];
            let t = tet_corner_force(kc / 4u, kc % 4u);
            fe += t;
            gross += sqrt(dot3(t, t));
        }
        f += fe;
        rest_f += fe;
    }
    var g = vec3<f32>(0.0);
    let tris = vec2<u32>(offsets[i].y, offsets[i + 1u].y);
    for (var e = tris.x; e < tris.y; e++) {
        let t = triangles[adjacency[sim.tri_base + e]];
        let c = (1.0 / 6.0) * cross3(pos[t.y].xyz - pos[t.x].xyz, pos[t.z].xyz - pos[t.x].xyz);
        g += c;
        if pressure != 0.0 {
            let p = (pressure / 6.0) * cross3(pos[t.y].xyz - pos[t.x].xyz, pos[t.z].xyz - pos[t.x].xyz);
            f += p;
            rest_f += p;
            gross += sqrt(dot3(p, p));
            outside += sqrt(dot3(p, p));
        }
    }
    if sim.gravity.w != 0.0 {
        let w = mass[i] * sim.gravity.xyz;
        f += w;
        rest_f += w;
        gross += sqrt(dot3(w, w));
        outside += sqrt(dot3(w, w));
    }
    if x.z <= sim.floor && rest_f.z < 0.0 {
        rest_f.z = 0.0;
    }
    let floor_row = free && x.z <= sim.floor && f.z < 0.0;
    work[slot(SLOT_F, i)] = vec4<f32>(f, select(0.0, 1.0, floor_row));
    vput(SLOT_G, i, g);
    let mode = u32(info[i].w);
    var held = vec3<f32>(0.0);
    if mode == MODE_PINNED {
        held = -v;
    } else if mode == MODE_DRIVEN {
        held = (driven_target(info[i].xyz) - x) / ip.h - v;
    }
    vput(SLOT_HELD, i, held);
    // Under gravity the residual is judged against the loads that act: each free vertex's
    // contact, pressure and weight, and each held one's reaction (CPU: MassSpring::residual).
    if sim.gravity.w != 0.0 {
        if free {
            return vec2<f32>(dot3(rest_f, rest_f), outside * outside);
        }
        return vec2<f32>(0.0, dot3(rest_f, rest_f));
    }
    if free {
        return vec2<f32>(dot3(rest_f, rest_f), gross * gross);
    }
    return vec2<f32>(0.0);
}

fn pass_rhs(i: u32) -> f32 {
    let h = ip.h;
    let free = is_free(i);
    // The preconditioner's block: the diagonal of A.
    let kc = contact_k(i);
    let cd = contact_damping(i, kc);
    let diagonal = 1.0 / vel[i].w + h * sim.damping;
    var b = mat3x3<f32>(vec3<f32>(diagonal, 0.0, 0.0), vec3<f32>(0.0, diagonal, 0.0), vec3<f32>(0.0, 0.0, diagonal));
    b += h * h * kc + h * cd;
    let range = vec2<u32>(offsets[i].x, offsets[i + 1u].x);
    for (var e = range.x; e < range.y; e++) {
        let j = adjacency[2u * e];
        let s = blocks(i, j, springs[adjacency[2u * e + 1u]]);
        let a = h * h * s.across;
        let c = h * h * s.along + h * sim.spring_damping;
        b += mat3x3<f32>(vec3<f32>(a, 0.0, 0.0), vec3<f32>(0.0, a, 0.0), vec3<f32>(0.0, 0.0, a)) + c * outer(s.u);
    }
    if ip.fill_k > 0.0 {
        b += (h * h * ip.fill_k) * outer(vget(SLOT_G, i));
    }
    if sim.tets > 0u {
        let tets = tet_range(i);
        for (var e = tets.x; e < tets.y; e++) {
            let kc = tet_index[e];
            b += (h * h) * diagonal_block(load_tangent(kc / 4u), kc % 4u);
        }
    }
    if ip.coupled != 0u {
        b += symmetric(SLOT_E0, SLOT_E1, i);
    }
    var inv = inverse3(b);
    if !(finite3(inv[0]) && finite3(inv[1]) && finite3(inv[2])) {
        let d = 1.0 / diagonal;
        inv = mat3x3<f32>(vec3<f32>(d, 0.0, 0.0), vec3<f32>(0.0, d, 0.0), vec3<f32>(0.0, 0.0, d));
    }
    vput(SLOT_P0, i, inv[0]);
    vput(SLOT_P1, i, inv[1]);
    vput(SLOT_P2, i, inv[2]);
    // b = h·(f − C_c·v − h·(−K)·v) − A·Δv_held on the free rows (velocities as the floor left them).
    var rhs = vec3<f32>(0.0);
    var x = vec3<f32>(0.0);
    if free {
        // −K·v: the stiff product of the velocities (they live in `vel`, not `work`: gathered here).
        let v = vel[i].xyz;
        var kv = kc * v;
        var a_held = vec3<f32>(0.0);
        let hi = vget(SLOT_HELD, i);
        for (var e = range.x; e < range.y; e++) {
            let j = adjacency[2u * e];
            let s = blocks(i, j, springs[adjacency[2u * e + 1u]]);
            let d = v - vel[j].xyz;
            kv += s.across * d + (s.along * dot3(s.u, d)) * s.u;
            let dh = hi - vget(SLOT_HELD, j);
            let a = h * h * s.across;
            let c = h * h * s.along + h * sim.spring_damping;
            a_held += a * dh + (c * dot3(s.u, dh)) * s.u;
        }
        a_held += (1.0 / vel[i].w + h * sim.damping) * hi + (h * h * kc + h * cd) * hi;
        if sim.tets > 0u {
            kv += gather_product(i, 0u);
            a_held += (h * h) * gather_product(i, 1u);
        }
        if ip.fill_k > 0.0 {
            kv += (ip.fill_k * body_scalar(B_GV)) * vget(SLOT_G, i);
            a_held += (h * h * ip.fill_k * body_scalar(B_GHELD)) * vget(SLOT_G, i);
        }
        rhs = h * (vget(SLOT_F, i) - cd * v - h * kv) - a_held + coupling(i);
        if ip.guess_scale > 0.0 {
            x = filtered(i, ip.guess_scale * vget(SLOT_X, i));
        }
    }
    vput(SLOT_B, i, rhs);
    vput(SLOT_X, i, x);
    let r = filtered(i, rhs);
    return dot3(r, r);
}

fn precondition(i: u32, r: vec3<f32>) -> vec3<f32> {
    let m = mat3x3<f32>(vget(SLOT_P0, i), vget(SLOT_P1, i), vget(SLOT_P2, i));
    return filtered(i, m * r);
}

@compute @workgroup_size(64)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let i = item_index(gid, nwg);
    let wg = wid.x + wid.y * nwg.x;
    let live = i < sim.n;
    if PASS >= PASS_TANGENT && PASS <= PASS_PRODUCT_X {
        // One invocation per tetrahedron.
        if i < sim.tets {
            pass_tetrahedron(i);
        }
    } else if PASS == PASS_PREPARE {
        var terms = vec2<f32>(0.0);
        if live {
            terms = pass_prepare(i);
        }
        partial_sum(COL_NET, wg, lane, terms.x);
        partial_sum(COL_GROSS, wg, lane, terms.y);
    } else if PASS == PASS_FLOOR {
        var gv = 0.0;
        var gh = 0.0;
        if live {
            if on_floor(i) {
                vel[i] = vec4<f32>(vel[i].x, vel[i].y, 0.0, vel[i].w);
            }
            let g = vget(SLOT_G, i);
            gv = dot3(g, vel[i].xyz);
            gh = dot3(g, vget(SLOT_HELD, i));
        }
        partial_sum(COL_GP, wg, lane, gv);
        partial_sum(COL_PAP, wg, lane, gh);
    } else if PASS == PASS_RHS {
        var bb = 0.0;
        if live {
            bb = pass_rhs(i);
        }
        partial_sum(COL_RR, wg, lane, bb);
    } else if PASS == PASS_GUESS {
        // Needs g·x for a fill: taken as the body's B_GP, written by PASS_SCALARS_GP over x.
        var left2 = 0.0;
        if live {
            var ax = vec3<f32>(0.0);
            if is_free(i) {
                ax = filtered(i, apply_row(i, SLOT_X, body_scalar(B_GP), false) + coupling(i));
            }
            let left = filtered(i, vget(SLOT_B, i)) - ax;
            vput(SLOT_R, i, left);
            left2 = dot3(left, left);
        }
        partial_sum(COL_LEFT, wg, lane, left2);
    } else if PASS == PASS_START {
        var rz = 0.0;
        if live {
            var r = filtered(i, vget(SLOT_B, i));
            if scalar(S_USE_GUESS) != 0.0 {
                r = vget(SLOT_R, i);
            } else {
                vput(SLOT_X, i, vec3<f32>(0.0));
            }
            vput(SLOT_R, i, r);
            let z = precondition(i, r);
            vput(SLOT_Z, i, z);
            vput(SLOT_P, i, z);
            rz = dot3(r, z);
        }
        partial_sum(COL_RZ, wg, lane, rz);
    } else if PASS == PASS_GP {
        // g·p, or g·x for PASS_GUESS (the vector in slot `ip` names: P unless guessing).
        var gp = 0.0;
        if live {
            var s = SLOT_P;
            if scalar(S_DONE) < 0.0 {
                s = SLOT_X;
            }
            gp = dot3(vget(SLOT_G, i), vget(s, i));
        }
        partial_sum(COL_GP, wg, lane, gp);
    } else if PASS == PASS_APPLY {
        var pap = 0.0;
        if live {
            var ap = vec3<f32>(0.0);
            if is_free(i) {
                ap = filtered(i, apply_row(i, SLOT_P, body_scalar(B_GP), false) + coupling(i));
            }
            vput(SLOT_AP, i, ap);
            pap = dot3(vget(SLOT_P, i), ap);
        }
        partial_sum(COL_PAP, wg, lane, pap);
    } else if PASS == PASS_UPDATE {
        var rr = 0.0;
        var rz = 0.0;
        // Done: nothing moves (where a NaN curvature stopped it, `0·p` would not be 0).
        if live && scalar(S_DONE) == 0.0 {
            let alpha = scalar(S_ALPHA);
            vput(SLOT_X, i, vget(SLOT_X, i) + alpha * vget(SLOT_P, i));
            let r = vget(SLOT_R, i) - alpha * vget(SLOT_AP, i);
            vput(SLOT_R, i, r);
            let z = precondition(i, r);
            vput(SLOT_Z, i, z);
            rr = dot3(r, r);
            rz = dot3(r, z);
        }
        partial_sum(COL_RR, wg, lane, rr);
        partial_sum(COL_RZ, wg, lane, rz);
    } else if PASS == PASS_DIRECTION {
        if live && scalar(S_DONE) == 0.0 {
            vput(SLOT_P, i, vget(SLOT_Z, i) + scalar(S_BETA) * vget(SLOT_P, i));
        }
    } else if PASS == PASS_FARTHEST {
        var far = 0.0;
        if live {
            var dv = vget(SLOT_HELD, i);
            if is_free(i) {
                dv = vget(SLOT_X, i);
            }
            let v = vel[i].xyz + dv;
            vput(SLOT_T, i, v);
            if is_free(i) {
                far = ip.h * sqrt(dot3(v, v));
            }
        }
        partial_max(COL_FAR, wg, lane, far);
    } else if PASS == PASS_MOVE {
        if live {
            pass_move(i);
        }
    } else {
        scalars(lane);
    }
}

fn pass_move(i: u32) {
    let h = ip.h;
    let mode = u32(info[i].w);
    var x = pos[i].xyz;
    var v = vel[i].xyz;
    if mode == MODE_FREE {
        v = ip.scale * vget(SLOT_T, i);
        x += h * v;
        // A voxel-model contact's push is inelastic: no speed left away from what pushes.
        let push = sqrt(dot3(contact[i].xyz, contact[i].xyz));
        let kc = contact_k(i);
        if push > 0.0 && kc[0].x + kc[1].y + kc[2].z > 0.0 {
            let n = contact[i].xyz / push;
            let away = dot3(v, n);
            if away > 0.0 {
                v -= away * n;
            }
        }
        let m = onto_floor(x, v);
        x = m.x;
        v = m.v;
    } else {
        let m = move_held(mode, info[i].xyz, x, h);
        x = m.x;
        v = m.v;
    }
    pos[i] = vec4<f32>(x, 1.0);
    vel[i] = vec4<f32>(v, vel[i].w);
    if !finite3(x) || !finite3(v) || sqrt(dot3(v, v)) > sim.v_max {
        atomicMax(&status[0], ~sim.step);
        atomicMax(&status[1], ~i);
    }
}

// The single-workgroup passes: the partials summed into the solve's scalars. PASS_SCALARS_A
// and PASS_SCALARS_GP sum one body's partials into its own scalars (run per body); the others
// sum every body's into the joint solve's (run once).
fn scalars(lane: u32) {
    if PASS == PASS_SCALARS_A {
        let gv = own_sum(COL_GP, lane);
        let gh = own_sum(COL_PAP, lane);
        let net = own_sum(COL_NET, lane);
        let gross = own_sum(COL_GROSS, lane);
        if lane == 0u {
            set_body_scalar(B_GV, gv);
            set_body_scalar(B_GHELD, gh);
            set_body_scalar(B_NET2, net);
            set_body_scalar(B_GROSS2, gross);
            // PASS_GP reads x while S_DONE is negative (the guess's g·x).
            set_scalar(S_DONE, -1.0);
        }
    } else if PASS == PASS_SCALARS_B {
        let bb = column_sum(COL_RR, lane);
        let left = column_sum(COL_LEFT, lane);
        if lane == 0u {
            set_scalar(S_NORM_B2, bb);
            set_scalar(S_LEFT2, left);
            // From the guess where it leaves less to solve than 0 does.
            set_scalar(S_USE_GUESS, select(0.0, 1.0, ip.guess_scale > 0.0 && left < bb));
            // |r| against tol·|b| unsquared, as the CPU compares them (tol²·|b|² would leave
            // f32's normal range near rest in small units).
            set_scalar(S_TARGET, ip.tolerance * sqrt(bb));
            // The first iteration always runs, as on the CPU (|r| is taken as |b| at the start).
            set_scalar(S_RR, bb);
            set_scalar(S_ITERATIONS, 0.0);
            set_scalar(S_DONE, select(0.0, 1.0, bb == 0.0));
            set_scalar(S_ALPHA, 0.0);
            set_scalar(S_BETA, 0.0);
        }
    } else if PASS == PASS_SCALARS_C {
        let rz = column_sum(COL_RZ, lane);
        if lane == 0u {
            set_scalar(S_RZ, rz);
        }
    } else if PASS == PASS_SCALARS_GP {
        let gp = own_sum(COL_GP, lane);
        if lane == 0u {
            set_body_scalar(B_GP, gp);
        }
    } else if PASS == PASS_SCALARS_ALPHA {
        let pap = column_sum(COL_PAP, lane);
        if lane == 0u {
            var alpha = 0.0;
            var done = scalar(S_DONE);
            if done == 0.0 {
                // The CPU's loop test (iterations left, residual above the target), then a
                // positive curvature (a NaN stops it too).
                if scalar(S_ITERATIONS) >= ip.max_iterations || sqrt(scalar(S_RR)) <= scalar(S_TARGET) || !(pap > 0.0) {
                    done = 1.0;
                } else {
                    alpha = scalar(S_RZ) / pap;
                }
            }
            set_scalar(S_DONE, done);
            set_scalar(S_ALPHA, alpha);
        }
    } else if PASS == PASS_SCALARS_BETA {
        let rr = column_sum(COL_RR, lane);
        let rz = column_sum(COL_RZ, lane);
        if lane == 0u && scalar(S_DONE) == 0.0 {
            set_scalar(S_RR, rr);
            set_scalar(S_BETA, rz / scalar(S_RZ));
            set_scalar(S_RZ, rz);
            let iterations = scalar(S_ITERATIONS) + 1.0;
            set_scalar(S_ITERATIONS, iterations);
            // The CPU's loop test, at once (so that the host sees a finished solve in the batch
            // it finished in); a curvature that is not positive is ALPHA's to find.
            if iterations >= ip.max_iterations || sqrt(rr) <= scalar(S_TARGET) {
                set_scalar(S_DONE, 1.0);
            }
        }
    } else if PASS == PASS_SCALARS_FAR {
        let far = column_max(COL_FAR, lane);
        if lane == 0u {
            set_scalar(S_FARTHEST, far);
        }
    }
}
