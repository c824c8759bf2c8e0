// A surface contact's couplings built on the device (src/gpu/implicit.rs, `Couplings`, where
// its search runs there too): one side's hits (shaders/surface_search.wgsl, confirmed by
// surface_forces.wgsl) as couplings, as the CPU's `Coupling::of_push` and `coupling_damping`
// make them of its pushes. One invocation per probe of the side: every probe has its coupling,
// in the CPU's order (b's points probing a's surface, then a's probing b's), and one that found
// no triangle within the margin has no stiffness, no entries and a depth no solve reaches, so
// it adds nothing anywhere.
//
// A point is its body's vertex (weight 1) or, where the body carries the surface it was made
// from, a point of that surface: its cell's kept corners in their weights (the CPU's stencil).

struct Build {
    n_probes: u32,     // the side's probes: every point of the probing body
    first: u32,        // the side's first coupling
    of_a: u32,         // 1 where the probes are a's (the triangles then b's)
    stiffness: f32,
    stride: u32,       // entries a coupling
    probe_n: u32,      // the probing body's vertices (its points from here on are carried)
    partner_n: u32,    // the partner's
    carries: u32,      // bit 0: the probing body carries its surface; bit 1: the partner
}

@group(0) @binding(0) var<uniform> build: Build;
@group(0) @binding(1) var<storage, read> hits: array<SurfaceHit>;
@group(0) @binding(2) var<storage, read> topology: array<u32>;        // the partner's triangles
@group(0) @binding(3) var<storage, read> vel_probe: array<vec4<f32>>;   // w: the inverse mass
@group(0) @binding(4) var<storage, read> vel_partner: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> couplings: array<Coupling>;
@group(0) @binding(6) var<storage, read_write> entries: array<vec2<u32>>;   // `stride` a coupling
@group(0) @binding(7) var<storage, read_write> in_solve: array<u32>;
@group(0) @binding(8) var<storage, read> probe_carried: array<Carried>;
@group(0) @binding(9) var<storage, read> partner_carried: array<Carried>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = item_index(gid, nwg);
    if i >= build.n_probes {
        return;
    }
    let k = build.first + i;
    let start = build.stride * k;
    let h = hits[i];
    if h.found != 1u {
        couplings[k] = Coupling(
            vec4<f32>(0.0),
            vec4<f32>(0.0, -3.0e38, 0.0, 0.0),
            vec4<u32>(start, start, start, build.of_a),
        );
        in_solve[k] = 0u;
        return;
    }
    // The pushed point, and its mass (`coupling_damping`'s sums, in its order).
    var at = start;
    var m = 0.0;
    if (build.carries & 1u) != 0u && i >= build.probe_n {
        let c = probe_carried[i - build.probe_n];
        for (var j = 0u; j < 8u; j++) {
            let e = corner_of(c, j);
            if e.x != 0xffffffffu {
                entries[at] = e;
                m = m + bitcast<f32>(e.y) * (1.0 / vel_probe[e.x].w);
                at++;
            }
        }
    } else {
        entries[at] = vec2<u32>(i, bitcast<u32>(1.0));
        m = m + 1.0 * (1.0 / vel_probe[i].w);
        at++;
    }
    let middle = at;
    // The nearest point: each corner's stencil scaled by its barycentric weight.
    var point = 0.0;
    for (var c = 0u; c < 3u; c++) {
        let p = topology[3u * h.triangle + c];
        let w = h.weights[c];
        if (build.carries & 2u) != 0u && p >= build.partner_n {
            let carried = partner_carried[p - build.partner_n];
            for (var j = 0u; j < 8u; j++) {
                let e = corner_of(carried, j);
                if e.x != 0xffffffffu {
                    let wu = w * bitcast<f32>(e.y);
                    entries[at] = vec2<u32>(e.x, bitcast<u32>(wu));
                    point = point + wu * (1.0 / vel_partner[e.x].w);
                    at++;
                }
            }
        } else {
            let wu = w * 1.0;
            entries[at] = vec2<u32>(p, bitcast<u32>(wu));
            point = point + wu * (1.0 / vel_partner[p].w);
            at++;
        }
    }
    var reduced = m;
    if point > 0.0 {
        reduced = m * point / (m + point);
    }
    let damping = 2.0 * sqrt(build.stiffness * reduced);
    let depth = h.normal.w;
    couplings[k] = Coupling(
        vec4<f32>(h.normal.xyz, build.stiffness),
        vec4<f32>(damping, depth, 0.0, 0.0),
        vec4<u32>(start, middle, at, build.of_a),
    );
    in_solve[k] = select(0u, 1u, depth > 0.0);
}
