// A surface contact's couplings in the implicit solve (src/gpu/implicit.rs, `Couplings`; the
// CPU's `Coupling`): each a spring of stiffness k along n between a point of one body and the
// nearest point of the other's surface, both as weights of their bodies' vertices. Two shaders:
//
// This one (a pipeline per MODE_*), one invocation per coupling of one contact:
// `rel = n·(Σ w·u_point − Σ w·u_from)` of a vector `u` of both bodies, and from it the
// coupling's scalar σ, stored as σ·n in `push`; or, MODE_ARRIVE, whether the solve ends it
// within the gap (its `in_solve` flag).
// couple_gather.wgsl, one invocation per vertex of one body: Σ ±w·σ·n over the couplings at
// it, in coupling order, into its `work` slot SLOT_C, which the implicit passes add.

override MODE: u32;

const MODE_P: u32 = 0u;       // A·p: σ = (h²k + h·d)·rel(p) where active
const MODE_X: u32 = 1u;       // A·x (the guess): the same of x
const MODE_RHS: u32 = 2u;     // the right-hand side's terms, from v and the held Δv
const MODE_ARRIVE: u32 = 3u;  // the new velocity: which couplings the solve ends within the gap

// Not a slot: the velocities, in `vel_a` and `vel_b`.
const VELOCITY: u32 = 99u;

@group(0) @binding(0) var<uniform> rp: RelativeParams;
@group(0) @binding(1) var<storage, read> couplings: array<Coupling>;
@group(0) @binding(2) var<storage, read> entries: array<vec2<u32>>;   // (vertex, weight's bits)
@group(0) @binding(3) var<storage, read> work_a: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> work_b: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> vel_a: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> vel_b: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> push: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> in_solve: array<u32>;
@group(0) @binding(9) var<storage, read_write> changed: array<atomic<u32>, 1>;
// The solve's joint scalars (implicit_solve.wgsl's `red`): the arrival test runs only once the
// solve is done, so that it may be recorded after every batch and read with the solve's scalars.
@group(0) @binding(10) var<storage, read> red: array<f32>;

// `S_DONE` in implicit_solve.wgsl: 0 while the solve runs, 1 once it is done.
const DONE: u32 = 7u;

// Vertex v's vector in `slot` of body a (`on_a`) or b, or its velocity (VELOCITY).
fn value(on_a: bool, slot: u32, v: u32) -> vec3<f32> {
    if slot == VELOCITY {
        if on_a {
            return vel_a[v].xyz;
        }
        return vel_b[v].xyz;
    }
    if on_a {
        return work_a[slot * rp.n_a + v].xyz;
    }
    return work_b[slot * rp.n_b + v].xyz;
}

// n·(Σ w·u_point − Σ w·u_from), as the CPU's `Coupling::relative`.
fn relative(c: Coupling, slot: u32) -> f32 {
    let point_on_a = c.range.w != 0u;
    var d = vec3<f32>(0.0);
    for (var e = c.range.x; e < c.range.y; e++) {
        d += bitcast<f32>(entries[e].y) * value(point_on_a, slot, entries[e].x);
    }
    for (var e = c.range.y; e < c.range.z; e++) {
        d -= bitcast<f32>(entries[e].y) * value(!point_on_a, slot, entries[e].x);
    }
    return dot3(c.normal.xyz, d);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = item_index(gid, nwg);
    if i >= rp.count {
        return;
    }
    let k = rp.first + i;
    let c = couplings[k];
    let h = rp.h;
    let stiffness = c.normal.w;
    let damping = c.terms.x;
    let depth = c.terms.y;
    let is_active = in_solve[k] != 0u;
    if MODE == MODE_ARRIVE {
        if red[DONE] <= 0.0 {
            return;
        }
        // Where the new velocity ends it within the gap (the CPU's rounds in
        // `integrate_implicit_together`): after the first round pairs only join.
        let arrives = h * relative(c, SLOT_T) < depth;
        if arrives != is_active && (rp.round == 1u || arrives) {
            in_solve[k] = select(0u, 1u, arrives);
            atomicOr(&changed[0], 1u);
        }
        return;
    }
    var sigma = 0.0;
    let s = h * h * stiffness + h * damping;
    if MODE == MODE_P {
        if is_active {
            sigma = s * relative(c, SLOT_P);
        }
    } else if MODE == MODE_X {
        if is_active {
            sigma = s * relative(c, SLOT_X);
        }
    } else {
        // b's terms (the CPU's `rhs_of`): −h²·K_c·v, −A_c·Δv_held, the damping of the relative
        // velocity, and an arriving pair's pull; a pair pushed now that leaves within the step
        // has its push taken out of the forces.
        let touching = depth > 0.0;
        if is_active {
            let rv = relative(c, VELOCITY);
            sigma = -(h * h * stiffness) * rv - s * relative(c, SLOT_HELD) - h * damping * rv;
            if !touching {
                sigma += h * stiffness * depth;
            }
        } else if touching {
            sigma = -h * stiffness * depth;
        }
    }
    push[k] = vec4<f32>(sigma * c.normal.xyz, sigma);
}
