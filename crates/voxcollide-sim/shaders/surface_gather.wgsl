// The surface contact's forces on one body's vertices (docs/contacts.md, "The search on the
// device"), after both sides' searches and shaders/surface_forces.wgsl: each vertex's own push
// (its hit as a probe of the partner's surface) and the reactions of the partner's pushes on
// the triangles at it (by barycentric weight), summed in the order the CPU's
// `SurfaceContact::step` sums them: the side of `b` probing `a` first, then `a` probing `b`,
// each in probe order and, within a push, corner order. Zero where the vertex is held.

struct Gather {
    n: u32,
    own_first: u32,   // 1 for body b: its own pushes are summed first
    starts_at: u32,   // where the other side's starts per vertex begin in its scratch
    keys_at: u32,     // and its keys (3·probe + corner)
    stiffness: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}


@group(0) @binding(0) var<uniform> gather: Gather;
@group(0) @binding(1) var<storage, read> own: array<SurfaceHit>;
@group(0) @binding(2) var<storage, read> other: array<SurfaceHit>;
@group(0) @binding(3) var<storage, read> lists: array<u32>;
@group(0) @binding(4) var<storage, read> free: array<u32>;
@group(0) @binding(5) var<storage, read_write> force: array<vec4<f32>>;

// A push's force, `k · depth · n` (the scalar first, as the CPU's `p.stiffness * h.depth * h.normal`).
fn push_force(h: SurfaceHit) -> vec3<f32> {
    return (gather.stiffness * h.normal.w) * h.normal.xyz;
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let v = item_index(gid, nwg);
    if v >= gather.n {
        return;
    }
    var f = vec3<f32>(0.0);
    let h = own[v];
    let pushed = h.found == 1u && h.normal.w > 0.0;
    if gather.own_first == 1u && pushed {
        f = f + 1.0 * push_force(h);
    }
    // The reactions in ascending key: each round the least key above the last.
    let start = lists[gather.starts_at + v];
    let end = lists[gather.starts_at + v + 1u];
    var last = 0u;
    var any = false;
    for (var round = start; round < end; round++) {
        var least = 0xffffffffu;
        for (var e = start; e < end; e++) {
            let key = lists[gather.keys_at + e];
            if (!any || key > last) && key < least {
                least = key;
            }
        }
        last = least;
        any = true;
        let r = other[least / 3u];
        // (A hit within the margin is listed for the implicit solve's couplings: no force.)
        if r.normal.w > 0.0 {
            f = f - r.weights[least % 3u] * push_force(r);
        }
    }
    if gather.own_first == 0u && pushed {
        f = f + 1.0 * push_force(h);
    }
    if free[v] == 0u {
        f = vec3<f32>(0.0);
    }
    force[v] = vec4<f32>(f, 0.0);
}
