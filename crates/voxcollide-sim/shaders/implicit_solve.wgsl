// The implicit integrator's solve (docs/design.md §12, `integrator = "implicit"`) for a world of
// bodies of springs or tetrahedra, with the voxel model's contacts (their `k·nnᵀ` in
// SLOT_KC0/1) or a surface contact's couplings (their terms gathered into SLOT_C by
// couple_gather.wgsl, their own blocks in SLOT_E0/1 from the host): backward Euler
// linearised once per step and solved matrix-free by a block-Jacobi preconditioned conjugate
// gradient over every body at once, as the CPU does it
// (src/integrator/implicit.rs, `integrate_implicit_together`), term by term.
//
// This file is what the solve's passes share: their one binding layout, the slots and scalars,
// the workgroup sums and the system's rows. The passes are entry points of the stems composed
// after it (src/gpu/implicit.rs, `ImplicitKernels`):
// - implicit_tetrahedra.wgsl: per tetrahedron, its stiffness and its products;
// - implicit_system.wgsl: the forces, the floor's rows, the right-hand side and preconditioner;
// - implicit_cg.wgsl: the conjugate gradient's per-vertex steps;
// - implicit_move.wgsl: the new velocity, the farthest move and the update;
// - implicit_scalars.wgsl: the partials summed into the solve's scalars (one workgroup).
//
// Every per-vertex vector of a body's solve lives in its `work`, `n` entries per slot (SLOT_*).
// Dot products are summed per workgroup (a tree over its 64 lanes) into `red`'s columns of
// `groups` partials, and the partials by one workgroup (implicit_scalars.wgsl) into `red`'s
// scalars: a fixed order, so the same answer every time on one device (not the CPU's `f64`
// sums: the two agree to the solve's tolerance, not bit for bit). `red` is the world's: each
// body's partials are its range of every column (from `base`, `own` of them), so the solve's
// scalars (S_*) are the joint system's; a body's own (B_*: its fill's products, its residual)
// follow them.

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

// Keep in sync with GpuImplicitParams in src/gpu/implicit.rs.
struct ImplicitParams {
    h: f32,
    fill_k: f32,             // B / V* (0: no fill)
    guess_scale: f32,        // h / the last step's h (0: no guess)
    tolerance: f32,
    scale: f32,              // the velocity's scale (implicit_move.wgsl)
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

// `A·u` on free row i (`A = M − h·D − h²·K`), `gu` = g·u; or `−K·u` on any row when `stiff`:
// the diagonal, the materials (springs, then tetrahedra), the contacts, then the fill, as the
// CPU sums them (src/integrator/implicit.rs, `System::apply`).
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
    if sim.tets > 0u {
        // The tetrahedra's −K·u, their products made per tetrahedron by implicit_tetrahedra.wgsl.
        var h2 = h * h;
        if stiff {
            h2 = 1.0;
        }
        r += h2 * gather_product(i, 0u);
    }
    let kc = contact_k(i);
    if stiff {
        r += kc * ui;
    } else {
        r += (h * h * kc + h * contact_damping(i, kc)) * ui;
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

// The preconditioner: the inverse of the diagonal block of A, times r.
fn precondition(i: u32, r: vec3<f32>) -> vec3<f32> {
    let m = mat3x3<f32>(vget(SLOT_P0, i), vget(SLOT_P1, i), vget(SLOT_P2, i));
    return filtered(i, m * r);
}

// Where an invocation is: its vertex (or tetrahedron), its workgroup and its lane.
struct Invocation {
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
}

fn item(at: Invocation) -> u32 {
    return item_index(at.gid, at.nwg);
}

fn group_index(at: Invocation) -> u32 {
    return at.wid.x + at.wid.y * at.nwg.x;
}
