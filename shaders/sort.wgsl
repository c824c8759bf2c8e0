// Pass 2e: every binned A vertex to its place in slot order, with its index in w, so that the
// vertices of consecutive slots (a block row's voxels) are one contiguous range for the probe.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> pos_a: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> place: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read> start: array<u32>;
@group(0) @binding(4) var<storage, read_write> sorted: array<vec4<u32>>; // (position bits, index)

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = item_index(gid, nwg);
    if i >= params.n_a {
        return;
    }
    let at = place[i];
    if at.x != NOT_BINNED {
        sorted[start[at.x] + at.y] = vec4<u32>(bitcast<vec3<u32>>(pos_a[i].xyz), i);
    }
}
