// A coupled body's lists of the couplings at each of its vertices, built on the device
// (src/gpu/implicit.rs, `Couplings`, where the surface contact's search runs there too), for
// couple_gather.wgsl: its own coupling as a probe (weight 1) and the other side's couplings on
// its triangles (minus each corner's barycentric weight), in coupling order as the host lists
// them; and the couplings' own blocks `Σ (h²k + h·d)·w²·nnᵀ` for the preconditioner, summed in
// the same order as the CPU's `coupling_blocks`. One invocation per vertex of the body.

struct Lists {
    n: u32,            // the body's vertices
    own_first: u32,    // 1 for b: its own couplings (the first side's) come before the others
    own: u32,          // the coupling of its vertex 0 as a probe
    other: u32,        // the other side's first coupling
    starts_at: u32,    // in the other side's scratch: per vertex, where its listed hits start
    keys_at: u32,      // and their keys, 3·probe + corner
    h: f32,
    _pad: u32,
}

// Keep in sync with `Coupling` in couple.wgsl.
struct Coupling {
    normal: vec4<f32>,
    terms: vec4<f32>,
    range: vec4<u32>,
}

@group(0) @binding(0) var<uniform> lists: Lists;
@group(0) @binding(1) var<storage, read> other_hits: array<SurfaceHit>;
@group(0) @binding(2) var<storage, read> scratch: array<u32>;
@group(0) @binding(3) var<storage, read> couplings: array<Coupling>;
@group(0) @binding(4) var<storage, read_write> offsets: array<u32>;
@group(0) @binding(5) var<storage, read_write> items: array<vec2<u32>>;   // (coupling, ±weight's bits)
@group(0) @binding(6) var<storage, read_write> work: array<vec4<f32>>;

var<private> block_a: vec4<f32>;   // xx, yy, zz, xy
var<private> block_b: vec2<f32>;   // xz, yz

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

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let v = item_index(gid, nwg);
    if v >= lists.n {
        return;
    }
    let start = scratch[lists.starts_at + v];
    let end = scratch[lists.starts_at + v + 1u];
    // Every vertex probes: before v's items, v own couplings and the others' listed before it.
    var at = start + v;
    offsets[v] = at;
    if v + 1u == lists.n {
        offsets[lists.n] = end + lists.n;
    }
    block_a = vec4<f32>(0.0);
    block_b = vec2<f32>(0.0);
    if lists.own_first == 1u {
        add(at, lists.own + v, 1.0);
        at++;
    }
    // The others in ascending key (probe, then corner): each round the least key above the last.
    var last = 0u;
    var any = false;
    for (var round = start; round < end; round++) {
        var least = 0xffffffffu;
        for (var e = start; e < end; e++) {
            let key = scratch[lists.keys_at + e];
            if (!any || key > last) && key < least {
                least = key;
            }
        }
        last = least;
        any = true;
        let probe = least / 3u;
        add(at, lists.other + probe, -other_hits[probe].weights[least % 3u]);
        at++;
    }
    if lists.own_first == 0u {
        add(at, lists.own + v, 1.0);
    }
    work[SLOT_E0 * lists.n + v] = block_a;
    work[SLOT_E1 * lists.n + v] = vec4<f32>(block_b, 0.0, 0.0);
}
