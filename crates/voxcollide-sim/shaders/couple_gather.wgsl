// The couplings' terms gathered per vertex of one body (couple.wgsl): Σ ±w·σ·n over the
// couplings at the vertex, in coupling order, into its `work` slot SLOT_C (0 where none).

struct GatherParams {
    n: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> gp: GatherParams;
@group(0) @binding(1) var<storage, read> push: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> offsets: array<u32>;
@group(0) @binding(3) var<storage, read> items: array<vec2<u32>>;      // (coupling, ±weight's bits)
@group(0) @binding(4) var<storage, read_write> work: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = item_index(gid, nwg);
    if i >= gp.n {
        return;
    }
    var sum = vec3<f32>(0.0);
    for (var e = offsets[i]; e < offsets[i + 1u]; e++) {
        let it = items[e];
        sum += bitcast<f32>(it.y) * push[it.x].xyz;
    }
    work[SLOT_C * gp.n + i] = vec4<f32>(sum, 0.0);
}
