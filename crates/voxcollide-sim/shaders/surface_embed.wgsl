// A lattice's points as its surface contact sees them, where it carries the surface it was made
// from (src/gpu/surface.rs, `DeviceSurface`; the CPU's `View` in src/contact/surface.rs): its
// vertices, then the carried surface's points, each its rest position moved by its cell's kept
// corners' displacements in their trilinear weights, summed in the CPU's order
// (`Embedding::positions`). One invocation per point.

struct Embed {
    n: u32,   // the lattice's vertices
    m: u32,   // the carried surface's points
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> embed: Embed;
@group(0) @binding(1) var<storage, read> pos: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> carried: array<Carried>;
@group(0) @binding(4) var<storage, read_write> view: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = item_index(gid, nwg);
    if i >= embed.n + embed.m {
        return;
    }
    if i < embed.n {
        view[i] = pos[i];
        return;
    }
    let c = carried[i - embed.n];
    var d = vec3<f32>(0.0);
    for (var j = 0u; j < 8u; j++) {
        let e = corner_of(c, j);
        if e.x != 0xffffffffu {
            d = d + bitcast<f32>(e.y) * (pos[e.x].xyz - rest[e.x].xyz);
        }
    }
    view[i] = vec4<f32>(c.rest.xyz + d, 0.0);
}
