// The surface contact's forces on one body's vertices (docs/contacts.md, "The search on the
// device"), after both sides' searches and shaders/surface_forces.wgsl: each vertex's own push
// (its hit as a probe of the partner's surface) and the reactions of the partner's pushes on
// the triangles at it (by barycentric weight); where the body carries a surface, those of the
// points whose stencils hold the vertex, by its weight in each; summed in the order the CPU's
// `SurfaceContact::step` sums them: the side of `b` probing `a` first, then `a` probing `b`,
// each in probe order and, within a push, corner order. Zero where the vertex is held.

struct Gather {
    n: u32,           // the body's vertices
    own_first: u32,   // 1 for body b: its own pushes are summed first
    starts_at: u32,   // where the other side's starts per point begin in its scratch
    keys_at: u32,     // and its keys (3·probe + corner)
    stiffness: f32,
    carried: u32,     // 1 where the body carries the surface it shows: each vertex's points in `points`
    _pad1: u32,
    _pad2: u32,
}


@group(0) @binding(0) var<uniform> gather: Gather;
@group(0) @binding(1) var<storage, read> own: array<SurfaceHit>;
@group(0) @binding(2) var<storage, read> other: array<SurfaceHit>;
@group(0) @binding(3) var<storage, read> lists: array<u32>;
@group(0) @binding(4) var<storage, read> free: array<u32>;
@group(0) @binding(5) var<storage, read_write> force: array<vec4<f32>>;
// Where the body carries a surface: per vertex, the points whose stencils hold it (itself, then
// the carried surface's in ascending order) and its weight in each, as offsets (n + 1) followed
// by (point, weight's bits) pairs.
@group(0) @binding(6) var<storage, read> points: array<u32>;

// A push's force, `k · depth · n` (the scalar first, as the CPU's `p.stiffness * h.depth * h.normal`).
fn push_force(h: SurfaceHit) -> vec3<f32> {
    return (gather.stiffness * h.normal.w) * h.normal.xyz;
}

// Vertex v's points: the first and the end in `points`' pairs, or v itself (end = first + 1 and
// first = NONE) where the body shows its own surface.
fn point_at(v: u32, e: u32) -> vec2<u32> {
    if gather.carried == 0u {
        return vec2<u32>(v, bitcast<u32>(1.0));
    }
    let at = gather.n + 1u + 2u * e;
    return vec2<u32>(points[at], points[at + 1u]);
}

// The vertex's share of its points' own pushes, in point order (the CPU's `f_probe[v] += u * f`).
fn own_pushes(f0: vec3<f32>, first: u32, end: u32, v: u32) -> vec3<f32> {
    var f = f0;
    for (var e = first; e < end; e++) {
        let pu = point_at(v, e);
        let h = own[pu.x];
        if h.found == 1u && h.normal.w > 0.0 {
            f = f + bitcast<f32>(pu.y) * push_force(h);
        }
    }
    return f;
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let v = item_index(gid, nwg);
    if v >= gather.n {
        return;
    }
    var first = 0u;
    var end = 1u;
    if gather.carried == 1u {
        first = points[v];
        end = points[v + 1u];
    }
    var f = vec3<f32>(0.0);
    if gather.own_first == 1u {
        f = own_pushes(f, first, end, v);
    }
    // The reactions on the triangles at its points, in ascending key over all of them (a key
    // is one corner of one push, so it lies at one point): each round the least key above the
    // last, its weight the corner's times the vertex's in that point.
    var total = 0u;
    for (var e = first; e < end; e++) {
        let p = point_at(v, e).x;
        total += lists[gather.starts_at + p + 1u] - lists[gather.starts_at + p];
    }
    var last = 0u;
    var any = false;
    for (var round = 0u; round < total; round++) {
        var least = 0xffffffffu;
        var u = 0.0;
        for (var e = first; e < end; e++) {
            let pu = point_at(v, e);
            let start = lists[gather.starts_at + pu.x];
            let stop = lists[gather.starts_at + pu.x + 1u];
            for (var k = start; k < stop; k++) {
                let key = lists[gather.keys_at + k];
                if (!any || key > last) && key < least {
                    least = key;
                    u = bitcast<f32>(pu.y);
                }
            }
        }
        last = least;
        any = true;
        let r = other[least / 3u];
        // (A hit within the margin is listed for the implicit solve's couplings: no force.)
        if r.normal.w > 0.0 {
            f = f - (r.weights[least % 3u] * u) * push_force(r);
        }
    }
    if gather.own_first == 0u {
        f = own_pushes(f, first, end, v);
    }
    if free[v] == 0u {
        f = vec3<f32>(0.0);
    }
    force[v] = vec4<f32>(f, 0.0);
}
