// A surface contact's couplings built on the device (src/gpu/implicit.rs, `Couplings`, where
// its search runs there too): one side's hits (shaders/surface_search.wgsl, confirmed by
// surface_forces.wgsl) as couplings, as the CPU's `Coupling::of_push` and `coupling_damping`
// make them of its pushes. One invocation per probe of the side: every probe has its coupling,
// in the CPU's order (b's probes of a's surface, then a's of b's), and one that found no
// triangle within the margin has no stiffness, no entries and a depth no solve reaches, so it
// adds nothing anywhere.

struct Build {
    n_probes: u32,
    first: u32,        // the side's first coupling
    of_a: u32,         // 1 where the probes are a's (the triangles then b's)
    stiffness: f32,
}

// Keep in sync with `Coupling` in couple.wgsl.
struct Coupling {
    normal: vec4<f32>,
    terms: vec4<f32>,
    range: vec4<u32>,
}

@group(0) @binding(0) var<uniform> build: Build;
@group(0) @binding(1) var<storage, read> hits: array<SurfaceHit>;
@group(0) @binding(2) var<storage, read> topology: array<u32>;        // the partner's triangles
@group(0) @binding(3) var<storage, read> vel_probe: array<vec4<f32>>;   // w: the inverse mass
@group(0) @binding(4) var<storage, read> vel_partner: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> couplings: array<Coupling>;
@group(0) @binding(6) var<storage, read_write> entries: array<vec2<u32>>;   // 4 a coupling
@group(0) @binding(7) var<storage, read_write> in_solve: array<u32>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = item_index(gid, nwg);
    if i >= build.n_probes {
        return;
    }
    let k = build.first + i;
    let at = 4u * k;
    let h = hits[i];
    if h.found != 1u {
        couplings[k] = Coupling(vec4<f32>(0.0), vec4<f32>(0.0, -3.0e38, 0.0, 0.0), vec4<u32>(at, at, at, build.of_a));
        in_solve[k] = 0u;
        return;
    }
    entries[at] = vec2<u32>(i, bitcast<u32>(1.0));
    // The critical damping 2√(k·m) in the reduced mass of the vertex and the triangle's point
    // (`coupling_damping`, its sums in the CPU's order).
    let m = 1.0 * (1.0 / vel_probe[i].w);
    var point = 0.0;
    for (var c = 0u; c < 3u; c++) {
        let v = topology[3u * h.triangle + c];
        let w = h.weights[c];
        entries[at + 1u + c] = vec2<u32>(v, bitcast<u32>(w));
        point = point + w * (1.0 / vel_partner[v].w);
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
        vec4<u32>(at, at + 1u, at + 4u, build.of_a),
    );
    in_solve[k] = select(0u, 1u, depth > 0.0);
}
