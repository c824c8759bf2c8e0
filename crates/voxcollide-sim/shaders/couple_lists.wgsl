// A coupled body's lists of the couplings at each of its vertices, built on the device
// (src/gpu/implicit.rs, `Couplings`, where the surface contact's search runs there too), for
// couple_gather.wgsl; and the couplings' own blocks `Σ (h²k + h·d)·w²·nnᵀ` for the
// preconditioner. A vertex's couplings are those of its points as probes (itself and, where
// the body carries a surface, the carried points in its cells: its weight in each) and those of
// the partner's probes on the triangles at those points (minus the corner's barycentric weight
// times its own), in coupling order as the host lists them (the first side's couplings first,
// each in probe order, then corner order); the blocks are summed in that order, as the CPU's
// `coupling_blocks`. A body in several surface contacts has each contact's couplings after
// the one's before (they are numbered in contact order), and its blocks summed on. Three
// passes, one invocation per vertex but the scan:
//   `count`  each vertex's couplings of the contact, into (or onto) `offsets`;
//   `scan`   the counts into their starts, in place (n + 1 of them, the last the total), once
//            after every contact's count;
//   `fill`   the lists and the blocks, each contact's after the ones before (`cursor`).

struct Lists {
    n: u32,            // the body's vertices
    own_first: u32,    // 1 for b: its own couplings (the first side's) come before the others
    own: u32,          // the coupling of its point 0 as a probe
    other: u32,        // the other side's first coupling
    starts_at: u32,    // in the other side's scratch: per point, where its listed hits start
    keys_at: u32,      // and their keys, 3·probe + corner
    h: f32,
    carried: u32,      // 1 where the body carries its surface: each vertex's points in `points`
    after: u32,        // 1 where this is not the body's first surface contact
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> lists: Lists;
@group(0) @binding(1) var<storage, read> other_hits: array<SurfaceHit>;
@group(0) @binding(2) var<storage, read> scratch: array<u32>;
@group(0) @binding(3) var<storage, read> couplings: array<Coupling>;
@group(0) @binding(4) var<storage, read_write> offsets: array<u32>;
@group(0) @binding(5) var<storage, read_write> items: array<vec2<u32>>;   // (coupling, ±weight's bits)
@group(0) @binding(6) var<storage, read_write> work: array<vec4<f32>>;
// Per vertex, its points and its weight in each (surface_gather.wgsl's `points`).
@group(0) @binding(7) var<storage, read> points: array<u32>;
// Per vertex, how many of its couplings the contacts before this one have filled in.
@group(0) @binding(8) var<storage, read_write> cursor: array<u32>;

var<private> block_a: vec4<f32>;   // xx, yy, zz, xy
var<private> block_b: vec2<f32>;   // xz, yz

// Vertex v's points: its range in `points`' pairs (v itself where the body carries none).
fn point_range(v: u32) -> vec2<u32> {
    if lists.carried == 0u {
        return vec2<u32>(0u, 1u);
    }
    return vec2<u32>(points[v], points[v + 1u]);
}

// Entry e of vertex v's points: (point, weight's bits).
fn point_at(v: u32, e: u32) -> vec2<u32> {
    if lists.carried == 0u {
        return vec2<u32>(v, bitcast<u32>(1.0));
    }
    let at = lists.n + 1u + 2u * e;
    return vec2<u32>(points[at], points[at + 1u]);
}

fn reactions_at(p: u32) -> u32 {
    return scratch[lists.starts_at + p + 1u] - scratch[lists.starts_at + p];
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn count(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let v = item_index(gid, nwg);
    if v >= lists.n {
        return;
    }
    let r = point_range(v);
    var total = r.y - r.x;
    for (var e = r.x; e < r.y; e++) {
        total += reactions_at(point_at(v, e).x);
    }
    if lists.after == 1u {
        offsets[v] += total;
    } else {
        offsets[v] = total;
        if v == 0u {
            offsets[lists.n] = 0u;
        }
    }
}

var<workgroup> chunk_sums: array<u32, WORKGROUP_SIZE>;

// The counts into their starts, in place (an exclusive prefix sum over n + 1 entries, the last
// the total), by one workgroup: each invocation a run of them.
@compute @workgroup_size(WORKGROUP_SIZE)
fn scan(@builtin(local_invocation_index) lid: u32) {
    let n = lists.n + 1u;
    let per = (n + WORKGROUP_SIZE - 1u) / WORKGROUP_SIZE;
    let start = min(lid * per, n);
    let end = min(start + per, n);
    var total = 0u;
    for (var i = start; i < end; i++) {
        total += offsets[i];
    }
    chunk_sums[lid] = total;
    workgroupBarrier();
    var before = 0u;
    for (var l = 0u; l < lid; l++) {
        before += chunk_sums[l];
    }
    for (var i = start; i < end; i++) {
        let c = offsets[i];
        offsets[i] = before;
        before += c;
    }
}

// Coupling k at the vertex with weight w: its item at `at`, and its block added.
fn add(at: u32, k: u32, w: f32) {
    items[at] = vec2<u32>(k, bitcast<u32>(w));
    let c = couplings[k];
    let n = c.normal.xyz;
    let s = lists.h * lists.h * c.normal.w + lists.h * c.terms.x;
    let ww = w * w;
    block_a = block_a + ww * vec4<f32>(s * (n.x * n.x), s * (n.y * n.y), s * (n.z * n.z), s * (n.y * n.x));
    block_b = block_b + ww * vec2<f32>(s * (n.z * n.x), s * (n.z * n.y));
}

// Its points' own couplings, in point order, from `at`; the next free place.
fn own_couplings(v: u32, r: vec2<u32>, at0: u32) -> u32 {
    var at = at0;
    for (var e = r.x; e < r.y; e++) {
        let pu = point_at(v, e);
        add(at, lists.own + pu.x, bitcast<f32>(pu.y));
        at++;
    }
    return at;
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn fill(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let v = item_index(gid, nwg);
    if v >= lists.n {
        return;
    }
    let r = point_range(v);
    var at = offsets[v];
    block_a = vec4<f32>(0.0);
    block_b = vec2<f32>(0.0);
    if lists.after == 1u {
        at += cursor[v];
        block_a = work[SLOT_E0 * lists.n + v];
        block_b = work[SLOT_E1 * lists.n + v].xy;
    }
    if lists.own_first == 1u {
        at = own_couplings(v, r, at);
    }
    // The others in ascending key (probe, then corner) over all its points: each round the
    // least key above the last (a key is one corner of one push, so it lies at one point).
    var total = 0u;
    for (var e = r.x; e < r.y; e++) {
        total += reactions_at(point_at(v, e).x);
    }
    var last = 0u;
    var any = false;
    for (var round = 0u; round < total; round++) {
        var least = 0xffffffffu;
        var u = 0.0;
        for (var e = r.x; e < r.y; e++) {
            let pu = point_at(v, e);
            let start = scratch[lists.starts_at + pu.x];
            let stop = scratch[lists.starts_at + pu.x + 1u];
            for (var k = start; k < stop; k++) {
                let key = scratch[lists.keys_at + k];
                if (!any || key > last) && key < least {
                    least = key;
                    u = bitcast<f32>(pu.y);
                }
            }
        }
        last = least;
        any = true;
        let probe = least / 3u;
        add(at, lists.other + probe, -(other_hits[probe].weights[least % 3u] * u));
        at++;
    }
    if lists.own_first == 0u {
        at = own_couplings(v, r, at);
    }
    cursor[v] = at - offsets[v];
    work[SLOT_E0 * lists.n + v] = block_a;
    work[SLOT_E1 * lists.n + v] = vec4<f32>(block_b, 0.0, 0.0);
}
